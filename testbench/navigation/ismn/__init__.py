"""Inertial-aided scene-matching navigation (ISMN): absolute position fixes from a downward
camera, the INS-predicted pose and an onboard reference map (paper section 2.1).

Importing this package registers the matchers "ncc", "phase", "orb" and "sift".
"""

from testbench.navigation.ismn.area import NccMatcher, PhaseMatcher
from testbench.navigation.ismn.feature_match import OrbMatcher, SiftMatcher
from testbench.navigation.ismn.pipeline import IsmnParams, IsmnPipeline
from testbench.navigation.ismn.types import IsmnDiagnostics, MatchPrior, MatchResult, OrthoFrame, SearchWindow

__all__ = [
    "IsmnDiagnostics", "IsmnParams", "IsmnPipeline", "MatchPrior", "MatchResult", "NccMatcher",
    "OrbMatcher", "OrthoFrame", "PhaseMatcher", "SearchWindow", "SiftMatcher",
]
