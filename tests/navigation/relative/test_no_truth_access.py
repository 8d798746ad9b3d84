"""Static check: relative navigation and control never reach another vehicle's truth.

No module in testbench/navigation/relative or testbench/control (flight code) imports
testbench.dynamics, testbench.world or testbench.sim, or names TruthState. The control
offline tools (benchmarks, controller design/evaluation, CNN training data) are excluded by
file name (OFFLINE_NAMES); a test checks that the flight modules do not import them.
"""

import ast
from pathlib import Path

import testbench

ROOT = Path(testbench.__file__).parent
FORBIDDEN_MODULES = ("testbench.dynamics", "testbench.world", "testbench.sim")
FORBIDDEN_NAMES = {"TruthState", "WorldView"}
# Offline tools by file name: benchmarks (`bench.py`, they build the scenes they time),
# controller design and evaluation (fly JSBSim from truth outside the engine), and the CNN
# detector's training/evaluation data (rendered from worlds). Flight code never imports them.
OFFLINE_NAMES = {"bench.py", "design.py", "evaluate.py", "evaluate_multirotor.py", "dataset.py", "train.py"}


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
        if f.name in OFFLINE_NAMES:
            continue
        v = _violations(f)
        if v:
            bad[rel] = v
    assert not bad, f"modules reaching truth: {bad}"


def test_the_scan_catches_a_violation(tmp_path):
    p = tmp_path / "m.py"
    p.write_text("from testbench.dynamics.jsbsim_adapter import JSBSimDynamics\nfrom testbench.core.messages import TruthState\n")
    assert len(_violations(p)) >= 2


def test_flight_modules_do_not_import_offline_tools():
    files = sorted((ROOT / "navigation" / "relative").rglob("*.py")) + sorted((ROOT / "control").rglob("*.py"))
    # design.py may be imported: the fixed-wing autopilot designs gains from the aircraft MODEL
    # (JSBSim linearisation at start-up), which reads no vehicle's state.
    offline = {n[:-3] for n in OFFLINE_NAMES} - {"design"}
    for f in files:
        if f.name in OFFLINE_NAMES:
            continue
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("testbench."):
                assert node.module.rsplit(".", 1)[-1] not in offline, f"{f}: imports offline tool {node.module}"
