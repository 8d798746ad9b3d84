"""Static check: relative navigation and control never reach another vehicle's truth.

No module in testbench/navigation/relative or testbench/control (flight code) imports
testbench.dynamics, testbench.world or testbench.sim, or names TruthState. The control
package's offline design and evaluation tools (they fly JSBSim from truth on purpose, outside
the engine) and the CNN detector's training-data tools are listed explicitly.
"""

import ast
from pathlib import Path

import testbench

ROOT = Path(testbench.__file__).parent
FORBIDDEN_MODULES = ("testbench.dynamics", "testbench.world", "testbench.sim")
FORBIDDEN_NAMES = {"TruthState", "WorldView"}
OFFLINE_TOOLS = {"control/design.py", "control/evaluate.py", "control/evaluate_multirotor.py",
                 # CNN detector training/evaluation data come from the renderer and worlds.
                 "navigation/relative/cnn/dataset.py", "navigation/relative/cnn/train.py",
                 "navigation/relative/cnn/evaluate.py", "navigation/relative/cnn/bench.py",
                 # Offline scene simulation for relnav benchmarks and tests (renders, owns truth).
                 "navigation/relative/bench.py"}


def _violations(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    out = []
    for node in ast.walk(tree):
        mods = []
        if isinstance(node, ast.Import):
            mods = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            mods = [node.module]
            out += [f"imports {a.name}" for a in node.names if a.name in FORBIDDEN_NAMES]
        out += [f"imports {m}" for m in mods if m.startswith(FORBIDDEN_MODULES)]
        if isinstance(node, ast.Name) and node.id in FORBIDDEN_NAMES:
            out.append(f"uses {node.id} (line {node.lineno})")
        if isinstance(node, ast.Attribute) and node.attr in FORBIDDEN_NAMES:
            out.append(f"uses .{node.attr} (line {node.lineno})")
    return out


def test_relative_navigation_and_control_read_no_truth():
    files = sorted((ROOT / "navigation" / "relative").rglob("*.py")) + sorted((ROOT / "control").rglob("*.py"))
    assert files
    bad = {}
    for f in files:
        rel = f.relative_to(ROOT).as_posix()
        if rel in OFFLINE_TOOLS:
            continue
        v = _violations(f)
        if v:
            bad[rel] = v
    assert not bad, f"modules reaching truth: {bad}"


def test_the_scan_catches_a_violation(tmp_path):
    p = tmp_path / "m.py"
    p.write_text("from testbench.dynamics.jsbsim_adapter import JSBSimDynamics\nfrom testbench.core.messages import TruthState\n")
    assert len(_violations(p)) >= 2
