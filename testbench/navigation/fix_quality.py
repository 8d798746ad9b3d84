"""How a scene-matching fix's quality scales the error its tiles share.

PositionFix.quality (the NCC-weighted share of agreeing tiles times the pose solve's inlier
share) falls as the map's date and the image's disagree more (shadows that moved). Both the
ISMN pipeline's white appearance term (IsmnParams.appearance_sigma_m) and the INS/EKF's
appearance states (InsEkfParams.fix_appearance_sigma_m) scale their sigma by the same gain.
"""

from __future__ import annotations

import math


def appearance_gain(quality: float, ref_quality: float, exponent: float, max_gain: float = math.inf) -> float:
    """g = min(max_gain, ((1 - q) / (1 - ref_quality)) ** exponent), q clipped to [0, 1]
    (dimensionless): 1 at the reference quality, 0 at quality 1."""
    q = min(max(float(quality), 0.0), 1.0)
    return min(((1.0 - q) / (1.0 - ref_quality)) ** exponent, max_gain)
