"""Relative navigation of a swarm without communication: detect neighbours in the onboard
cameras (LED blob, oracle or CNN detectors), track them in the image, decode their LED blink
IDs, and fuse each one's line of sight with the UWB range of the same ID in a per-neighbour
EKF (DESIGN.md eq. 17-19). Importing this package registers the detectors "led" and "oracle"
and the navigation aid "relnav" (and the CNN detector in `cnn/` when it exists).
"""

import importlib
import importlib.util

from testbench.navigation.relative import aid, detectors  # noqa: F401  (registration)
from testbench.navigation.relative.types import Detection, NeighbourTable, RelativeEstimate

_spec = importlib.util.find_spec("testbench.navigation.relative.cnn")
if _spec is not None and _spec.origin is not None:
    importlib.import_module("testbench.navigation.relative.cnn")

__all__ = ["Detection", "RelativeEstimate", "NeighbourTable"]
