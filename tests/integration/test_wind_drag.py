"""Wind end to end (scenarios/multirotor_wind_drag.yaml): the drag-aided INS learns the wind
while GNSS is there; turbulent runs are bit-identical for a seed; the record has the wind
columns only where there is wind or an estimate of it."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from tests.conftest import run_scenario


def _run(out: Path, *sets: str) -> int:
    return run_scenario("multirotor_wind_drag", out, *sets)


def test_drag_aided_ins_learns_a_steady_wind(tmp_path):
    assert _run(tmp_path / "r", "duration_s=55", "world.wind.turbulence=null") == 0
    tel = pq.read_table(tmp_path / "r" / "telemetry.parquet").to_pandas()
    # Trimmed into the wind and started bumplessly, it sets off north without being blown
    # east (level and from a zero integrator: 1.8 m east by 5 s).
    assert abs(tel.loc[(tel.t_s - 5.0).abs().idxmin(), "truth_east_m"]) < 0.5
    np.testing.assert_allclose(tel[["truth_wind_n_mps", "truth_wind_e_mps"]].to_numpy(), 4.2426, atol=1e-3)
    last = tel[tel.t_s > 45.0]
    err = np.hypot(last.nav_wind_n_mps - last.truth_wind_n_mps, last.nav_wind_e_mps - last.truth_wind_e_mps)
    # It starts from calm (0 +- 3 m/s per axis) and meets 6 m/s.
    assert err.max() < 0.3
    assert (last.nav_sigma_wind_n_mps < 0.5).all()
    nav = json.loads((tmp_path / "r" / "metrics.json").read_text())["nav"]
    assert nav["wind_error_mps"]["n"] == len(tel)
    assert nav["nees"]["wind"]["mean"] > 0.0


# Without wind states the scenario's gate on nav.wind_error_mps has no metric to read: exit 3.
WITHOUT_WIND_STATES = "vehicles.quad0.navigation.params.drag_aiding.wind_states=false"


def test_without_wind_states_the_record_has_the_truth_wind_only(tmp_path):
    assert _run(tmp_path / "r", "duration_s=5", WITHOUT_WIND_STATES) == 3
    tel = pq.read_table(tmp_path / "r" / "telemetry.parquet").to_pandas()
    assert tel.truth_wind_e_mps.abs().max() > 0.0 and tel.nav_wind_n_mps.isna().all()
    assert "wind_error_mps" not in json.loads((tmp_path / "r" / "metrics.json").read_text())["nav"]


def test_calm_air_records_keep_their_columns(tmp_path):
    assert _run(tmp_path / "r", "duration_s=3", "world.wind=null", WITHOUT_WIND_STATES) == 3
    cols = pq.read_schema(tmp_path / "r" / "telemetry.parquet").names
    assert not [c for c in cols if "wind" in c]


def test_turbulent_runs_are_bit_identical(tmp_path):
    digests = []
    for name in ("a", "b"):
        assert _run(tmp_path / name, "duration_s=8") == 0
        digests.append(hashlib.sha256((tmp_path / name / "telemetry.parquet").read_bytes()).hexdigest())
    assert digests[0] == digests[1]
    assert _run(tmp_path / "c", "duration_s=8", "seed=2") == 0
    other = pq.read_table(tmp_path / "c" / "telemetry.parquet").to_pandas()
    first = pq.read_table(tmp_path / "a" / "telemetry.parquet").to_pandas()
    assert not np.allclose(other.truth_wind_n_mps, first.truth_wind_n_mps)
