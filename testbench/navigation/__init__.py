"""Navigation: INS/EKF (ins), scene matching (ismn), terrain-aided navigation (tan), relative
navigation (relative), and the aids that connect them to the engine.

Importing this package registers the built-in navigators ("truth_passthrough", "ins_ekf"),
matchers ("ncc", "phase", "orb", "sift"), detectors ("led", "oracle", "cnn") and aids
("ismn", "tan", "relnav").
"""

from testbench.navigation import ins, ismn, ismn_aid, passthrough, relative, tan, tan_aid  # noqa: F401
