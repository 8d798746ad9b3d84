"""Monte Carlo: local pool, failure isolation, resume, and a loopback Dask cluster giving the
same per-run metrics as the local pool."""

import json
import shutil
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from testbench.batch import BatchPlan, Vary, run_batch
from testbench.core.errors import InputError

REPO = Path(__file__).resolve().parents[2]
SCENARIO = str(REPO / "scenarios" / "fixedwing_racetrack.yaml")
SHORT = ("duration_s=6",)
WALL_DEPENDENT = {"real_time_factor", "wall_time_s", "worker_wall_s"}


def _metrics(row):
    return {k: v for k, v in row.items() if k not in WALL_DEPENDENT and isinstance(v, float)}


@pytest.fixture(scope="module")
def local_batch(tmp_path_factory):
    out = tmp_path_factory.mktemp("mc") / "local"
    # run 1 draws an impossible initial altitude (below ground) and must fail alone.
    plan = BatchPlan(SCENARIO, 3, 4, SHORT, (Vary.parse("vehicles.uav0.initial.altitude_m=choice(800, -5)"),))
    return plan, out, run_batch(plan, out, workers=2, report=True)


def test_failed_run_is_recorded_and_others_finish(local_batch):
    plan, out, result = local_batch
    status = {r["run"]: r["status"] for r in result.rows}
    alts = {r["run"]: r["vary.vehicles.uav0.initial.altitude_m"] for r in result.rows}
    assert len(result.rows) == 3
    for run, alt in alts.items():
        if alt < 0:
            assert status[run] == "error"
            assert "below the terrain" in next(r["error"] for r in result.rows if r["run"] == run)
        else:
            assert status[run] == "passed"
    assert any(a < 0 for a in alts.values()) and any(a > 0 for a in alts.values()), "draws should cover both cases"
    table = pq.read_table(out / "runs.parquet").to_pandas()
    assert list(table["run"]) == [0, 1, 2]
    assert {"seed_entropy", "status", "error", "control.altitude_error_m.rms"} <= set(table.columns)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["runs_done"] == 3 and summary["status_counts"].get("error") == sum(a < 0 for a in alts.values())
    assert (out / "report.html").stat().st_size > 1000


def test_resume_skips_finished_runs_and_reproduces(local_batch, tmp_path):
    plan, out, result = local_batch
    copy = tmp_path / "resume"
    shutil.copytree(out, copy)
    good = next(r for r in result.rows if r["status"] == "passed")
    shutil.rmtree(copy / "runs" / f"run_{good['run']:05d}")  # as if killed mid-run
    again = run_batch(plan, copy, workers=1, report=False)
    assert again.skipped == 2
    redone = next(r for r in again.rows if r["run"] == good["run"])
    assert _metrics(redone) == _metrics(good)


def test_resume_refuses_a_different_batch(local_batch):
    plan, out, _ = local_batch
    other = BatchPlan(plan.scenario, plan.runs, plan.seed + 1, plan.overrides, plan.vary)
    with pytest.raises(InputError, match="different batch"):
        run_batch(other, out, workers=1, report=False)


def test_dask_loopback_cluster_matches_local_pool(local_batch, tmp_path):
    from distributed import LocalCluster

    plan, _, result = local_batch
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None) as cluster:
        dask = run_batch(plan, tmp_path / "dask", scheduler=cluster.scheduler_address, report=False)
    assert [r["status"] for r in dask.rows] == [r["status"] for r in result.rows]
    for a, b in zip(dask.rows, result.rows):
        assert _metrics(a) == _metrics(b)


def test_vary_offset_moves_tied_keys_by_one_draw():
    """`k1,k2+=DIST`: both keys move by the same draw about their own scenario values."""
    from testbench.config.loader import load_scenario

    v = Vary.parse("vehicles.uav0.initial.east_m, vehicles.uav0.mission.params.center.east_m+=uniform(-900, 900)")
    assert v.offset and v.key.count(",") == 1
    plan = BatchPlan(SCENARIO, 4, 3, SHORT, (v,))
    base = load_scenario(SCENARIO)
    e0 = base.scenario.vehicle("uav0").initial.east_m
    c0 = base.data["vehicles"][0]["mission"]["params"]["center"]["east_m"]
    shifts = []
    for spec in plan.run_specs():
        loaded = load_scenario(SCENARIO, list(spec.overrides))
        d_init = loaded.scenario.vehicle("uav0").initial.east_m - e0
        d_centre = loaded.data["vehicles"][0]["mission"]["params"]["center"]["east_m"] - c0
        assert d_init == pytest.approx(d_centre) and -900 <= d_init <= 900
        shifts.append(d_init)
    assert len(set(shifts)) == 4, "each run draws its own shift"
    with pytest.raises(InputError, match="adds numbers"):
        Vary.parse("vehicles.uav0.aircraft+=choice(a, b)")


def test_cli_checks_the_scenario_before_any_run(tmp_path):
    """A bad map path is one clear error (exit 2) before workers start, not N failed runs."""
    import subprocess
    import sys

    out = tmp_path / "batch"
    proc = subprocess.run(
        [sys.executable, str(REPO / "cli.py"), "montecarlo", SCENARIO, "--runs", "3", "--workers", "1", "--out", str(out),
         "--set", "duration_s=2", "--set", f"world.imagery={tmp_path / 'missing.tif'}"],
        capture_output=True, text=True, cwd=REPO, timeout=120)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "missing.tif': no such file" in proc.stderr and "Traceback" not in proc.stderr
    assert not out.exists()


def test_vary_sequence_of_tuples_gives_each_key_its_own_value_per_run():
    # Worlds that belong together (imagery and reference map of one world) are drawn together,
    # and a sequence walks its values in run order, cycling.
    v = Vary.parse("world.imagery, world.reference_map=sequence([procedural:farmland?seed=1&season=summer, "
                   "procedural:farmland?seed=1&season=autumn], [a.tif, b.tif])")
    draws = v.draw(3, np.random.default_rng(0))
    assert draws == [("procedural:farmland?seed=1&season=summer", "procedural:farmland?seed=1&season=autumn"),
                     ("a.tif", "b.tif"), ("procedural:farmland?seed=1&season=summer", "procedural:farmland?seed=1&season=autumn")]
    assert v.overrides(draws[1]) == ('world.imagery="a.tif"', 'world.reference_map="b.tif"')
    assert Vary.parse("seed=sequence(3, 4)").draw(3, np.random.default_rng(0)) == [3, 4, 3]


@pytest.mark.parametrize("text, expected", [
    ("a,b=sequence([1, 2], [3])", "one value per key"),
    ("a=choice([1, 2])", "one value per key"),
    ("a,b=uniform([1, 2], [3, 4])", "one value per key"),
    ("a,b=choice([1, [2]], [3, 4])", "unbalanced brackets|do not nest"),
    ("a,b=sequence([1, 2)", "unbalanced brackets"),
])
def test_vary_rejects_tuples_that_do_not_fit_the_keys(text, expected):
    with pytest.raises(InputError, match=expected):
        Vary.parse(text)


@pytest.mark.parametrize("text, expected", [
    ("a=uniform(2, 1)", r"uniform\(a, b\) needs a <= b"),
    ("a=normal(0, -1)", r"sigma >= 0"),
    ("a=uniform(0, inf)", "finite numbers"),
    ("a+=linspace(nan, 1)", "finite numbers"),
])
def test_vary_rejects_distributions_numpy_cannot_draw(text, expected):
    """Found as internal errors (numpy's ValueError, a traceback) before any run started."""
    with pytest.raises(InputError, match=expected):
        Vary.parse(text)
    assert Vary.parse("a=uniform(1, 1)").draw(2, np.random.default_rng(0)) == [1.0, 1.0]


def test_plan_records_a_tuple_draw_under_each_key():
    plan = BatchPlan(SCENARIO, 2, 4, SHORT, (Vary.parse("world.imagery,world.reference_map=sequence([a.tif, b.tif], [c.tif, d.tif])"),))
    specs = plan.run_specs()
    assert [s.varied for s in specs] == [{"world.imagery": "a.tif", "world.reference_map": "b.tif"},
                                         {"world.imagery": "c.tif", "world.reference_map": "d.tif"}]
    assert specs[1].overrides[-2:] == ('world.imagery="c.tif"', 'world.reference_map="d.tif"')


def test_report_plots_only_numeric_varied_values():
    from testbench.batch.report import _values

    rows = [{"vary.aircraft": "c172x", "vary.h": 800}, {"vary.aircraft": "tb_fixedwing", "vary.h": None}, {}]
    assert np.isnan(_values(rows, "vary.aircraft")).all()
    np.testing.assert_array_equal(_values(rows, "vary.h"), [800.0, np.nan, np.nan])
