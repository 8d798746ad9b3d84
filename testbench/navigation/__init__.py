"""Navigation: INS/EKF (ins), scene matching (ismn), relative navigation (relative).

Importing this package registers the built-in navigators.
"""

import importlib
import importlib.util

from testbench.navigation import ins  # noqa: F401  (registers `ins_ekf`)

# Optional parts written alongside this package: import them when they exist.
for _name in ("testbench.navigation.passthrough", "testbench.navigation.ismn"):
    _spec = importlib.util.find_spec(_name)
    if _spec is not None and _spec.origin is not None:  # a module or a package with __init__.py
        importlib.import_module(_name)
