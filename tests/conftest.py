"""Shared fixtures: the repository root, the real-data folder (TESTBENCH_DATA), a clean
scenario-path helper and a quiet in-process `testbench run` of a shipped scenario."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SCENARIOS = REPO / "scenarios"


def run_scenario(name: str, out: Path, *sets: str) -> int:
    """`testbench run scenarios/NAME.yaml --out OUT --no-report --quiet --set ...` in this
    process; returns its exit status."""
    from testbench.cli import main

    args = ["run", str(SCENARIOS / f"{name}.yaml"), "--out", str(out), "--no-report", "--quiet"]
    for s in sets:
        args += ["--set", s]
    return main(args)


def data_dir() -> Path | None:
    """The real geodata folder from TESTBENCH_DATA, or None when unset or absent."""
    env = os.environ.get("TESTBENCH_DATA")
    if not env:
        return None
    p = Path(env)
    if not p.is_absolute():
        p = (REPO / p).resolve()
    return p if p.is_dir() else None


def use_data_if_scenario_needs_it(path: Path, monkeypatch) -> None:
    """For a scenario that names ${TESTBENCH_DATA}: point the variable at the real-data folder,
    or skip the test (with the reason) when it is absent."""
    if "${TESTBENCH_DATA}" not in path.read_text():
        return
    d = data_dir()
    if d is None:
        pytest.skip(f"{path.name} needs the real geodata: set TESTBENCH_DATA to the shared data folder")
    monkeypatch.setenv("TESTBENCH_DATA", str(d))


@pytest.fixture
def realdata() -> Path:
    """Skip (with the reason) unless the real geodata of ../shared/data is available."""
    d = data_dir()
    if d is None:
        pytest.skip("real geodata not available: set TESTBENCH_DATA to the shared data folder (e.g. ../shared/data)")
    return d
