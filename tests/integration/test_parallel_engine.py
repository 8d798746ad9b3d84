"""`testbench run --processes N`: the vehicles' stacks in worker processes give the record of a
single-process run, byte for byte; a worker's failure ends the run with the worker's message."""

import hashlib
import subprocess
import sys
from pathlib import Path

import pytest

from testbench.config.loader import load_scenario
from testbench.core.errors import InputError, SimulationAborted
from testbench.sim.parallel import WorkerError
from testbench.sim.runner import build_engine

REPO = Path(__file__).resolve().parents[2]
SWARM = REPO / "scenarios" / "paper_swarm_relnav.yaml"


def _digests(run_dir: Path) -> dict[str, str]:
    files = [run_dir / "telemetry.parquet", *sorted((run_dir / "events").glob("*.parquet"))]
    return {f.name: hashlib.sha256(f.read_bytes()).hexdigest() for f in files}


def test_worker_processes_give_the_single_process_record(tmp_path):
    """The LED swarm for 1.5 s (cameras rendering, blob detection, tracking, UWB, ten INS/EKFs,
    formation control) in one process and in three workers: every table identical."""
    outs = {}
    for n in (1, 3):
        out = tmp_path / f"p{n}"
        proc = subprocess.run(
            [sys.executable, str(REPO / "cli.py"), "run", str(SWARM), "--set", "duration_s=1.5", "--out", str(out),
             "--no-report", "--quiet", "--processes", str(n)],
            capture_output=True, text=True, timeout=600,
        )
        assert proc.returncode in (0, 3), proc.stderr  # 3: the 1.5 s run misses the 300 s gates
        outs[n] = _digests(out)
    assert "relnav.parquet" in outs[1] and "formation.parquet" in outs[1]
    assert outs[1] == outs[3]


def _swarm_engine(processes: int):
    loaded = load_scenario(SWARM, ["duration_s=0.5"])
    engine, _, _ = build_engine(loaded, processes=processes)
    return engine


def test_a_workers_exception_ends_the_run_with_its_traceback():
    engine = _swarm_engine(2)

    def boom(*args, **kwargs):
        raise ZeroDivisionError("boom in a controller")

    engine.vehicles[3].controller.update = boom  # set before the fork: the worker inherits it
    result = engine.run()
    assert isinstance(result.aborted, WorkerError)
    assert "boom in a controller" in str(result.aborted) and "ZeroDivisionError" in str(result.aborted)


def test_a_flight_abort_in_a_worker_is_the_runs_abort():
    engine = _swarm_engine(2)

    def diverged(*args, **kwargs):
        raise SimulationAborted("navigation diverged", t_s=0.25, vehicle_id="uav3")

    engine.vehicles[3].controller.update = diverged
    result = engine.run()
    assert isinstance(result.aborted, SimulationAborted)
    assert result.aborted.vehicle_id == "uav3" and result.aborted.reason == "navigation diverged"
    assert str(result.aborted).startswith("vehicle uav3, t=0.250 s: navigation diverged")


def test_worker_processes_refuse_a_frame_sink():
    loaded = load_scenario(SWARM, ["duration_s=0.5"])
    with pytest.raises(InputError, match="--save-frames"):
        build_engine(loaded, processes=2, frame_sink=lambda *a: None)


def test_cli_refuses_zero_processes(tmp_path):
    proc = subprocess.run(
        [sys.executable, str(REPO / "cli.py"), "run", str(SWARM), "--processes", "0", "--out", str(tmp_path / "x")],
        capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 2
    assert "--processes 0: expected a positive integer" in proc.stderr


def _dynamics_fail_at(engine, vehicle_index: int, t_fail_s: float) -> None:
    """Make one vehicle's dynamics end the flight once they step past t_fail_s (set before the
    fork, so that a worker process has it too)."""
    v = engine.vehicles[vehicle_index]
    advance = v.dynamics.advance
    state = {"t_s": 0.0}

    def failing(command, n_steps):
        state["t_s"] += n_steps * engine.dt_s
        if state["t_s"] > t_fail_s:
            raise SimulationAborted("NaN in the flight dynamics state", t_s=state["t_s"], vehicle_id=v.id)
        advance(command, n_steps)

    v.dynamics.advance = failing


@pytest.mark.parametrize("vehicle_index", [3, 4])  # of the worker's group / of the main group
def test_a_dynamics_abort_keeps_the_single_process_record(vehicle_index):
    """A flight ended by a vehicle's dynamics (NaN, the ground) keeps the record a
    single-process run keeps (every table up to and including the failing tick), whichever
    process flies that vehicle's stack."""
    tables = {}
    for n in (1, 2):
        loaded = load_scenario(SWARM, ["duration_s=1.5"])
        engine, _, recorder = build_engine(loaded, processes=n)
        _dynamics_fail_at(engine, vehicle_index, 1.2)  # after the first relnav rows (1.0 s)
        result = engine.run()
        assert isinstance(result.aborted, SimulationAborted)
        assert result.aborted.vehicle_id == f"uav{vehicle_index}"
        tables[n] = (result.ticks, recorder.telemetry_table(), recorder.event_tables())
    (ticks1, tel1, ev1), (ticks2, tel2, ev2) = tables[1], tables[2]
    assert ticks1 == ticks2 and tel1.num_rows > 0
    assert tel1.to_pandas().equals(tel2.to_pandas())  # pandas: NaN equals NaN (not so in pyarrow)
    assert ev1.keys() == ev2.keys() and "relnav" in ev1
    assert all(ev1[name].to_pandas().equals(ev2[name].to_pandas()) for name in ev1)
