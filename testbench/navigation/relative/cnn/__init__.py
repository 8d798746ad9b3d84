"""CNN detector of other vehicles (TinyCenterNet, torch CPU), trained on our own renders.

Importing this package registers `detector: cnn` (CnnDetector); torch is imported only when a
detector is built. Modules: model (network, targets, loss, decoding, NMS), dataset (rendered
crops), train, evaluate, detector, bench. Packaged weights: weights.pt (+ weights.json card).
"""

from testbench.navigation.relative.cnn.detector import CnnDetector, packaged_weights_path

__all__ = ["CnnDetector", "packaged_weights_path"]
