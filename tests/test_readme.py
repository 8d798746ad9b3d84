"""The README's commands are the ones CI runs, and every scenario file is listed in it."""

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_ci_runs_the_readme_test_command():
    readme = (REPO / "README.md").read_text()
    ci = (REPO / ".ci" / "run").read_text()
    m = re.search(r"README_TEST_COMMAND='([^']+)'", ci)
    assert m, ".ci/run must define README_TEST_COMMAND"
    assert m.group(1) in readme, "the README must show exactly the command .ci/run executes"


def test_readme_lists_every_scenario():
    readme = (REPO / "README.md").read_text()
    for p in sorted((REPO / "scenarios").glob("*.yaml")):
        assert p.name in readme, f"README does not describe scenarios/{p.name}"
