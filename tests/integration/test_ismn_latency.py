"""Scene matching with an onboard processing time, end to end (paper_ismn_800m shortened to 36 s,
GNSS on): each fix reaches the navigator latency_s after its frame, stamped with the frame's
time; frames that come while one is in processing are skipped; the last fix, still in
processing when the run ends, is recorded as never fused. With the delay replayed, the flight
is the one without it within the fixes' own noise.

Measured on 300 s flights (docs/measurements.md, "Scene matching with a processing time")."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from testbench.cli import main

REPO = Path(__file__).resolve().parents[2]
SCENARIO = str(REPO / "scenarios" / "paper_ismn_800m.yaml")


def _run(tmp_path: Path, name: str, *sets: str) -> tuple[dict, pd.DataFrame, pd.DataFrame]:
    out = tmp_path / name
    args = ["run", SCENARIO, "--set", "duration_s=36", "--out", str(out), "--no-report", "--quiet"]
    for s in sets:
        args += ["--set", s]
    code = main(args)
    assert code in (0, 3), code  # 36 s hold no GNSS-denied time and no turn to score
    m = json.loads((out / "metrics.json").read_text())
    return m, pd.read_parquet(out / "events" / "ismn.parquet"), pd.read_parquet(out / "events" / "corrections.parquet")


def test_fixes_come_late_frames_in_processing_are_skipped_and_the_replay_keeps_the_estimate(tmp_path):
    m, ismn, corr = _run(tmp_path, "late", "vehicles.uav0.aids.ismn.latency_s=1.5")
    t = ismn["t_s"].to_numpy()
    assert np.all(np.diff(t) > 0), "ismn rows out of frame order"
    fixes = ismn[ismn["fix"]]
    delivered = fixes["delivered_t_s"].to_numpy()
    # Every fix but the last reached the filter 1.5 s after its frame; the last was in flight.
    np.testing.assert_allclose(delivered[:-1] - fixes["t_s"].to_numpy()[:-1], 1.5, atol=1e-6)
    assert np.isnan(delivered[-1]) and fixes["reason"].iloc[-1] == "in flight at the end of the run"
    assert not fixes["accepted"].iloc[-1] and fixes["accepted"].iloc[:-1].all()
    # At 1 Hz a 1.5 s processor takes every other frame once matching starts.
    matching = ismn[ismn["t_s"] >= fixes["t_s"].iloc[0]]
    busy = matching["reason"].str.startswith("busy").to_numpy()
    assert busy[1::2].all() and not busy[0::2].any()
    assert m["ismn"]["busy_frames"] == int(busy.sum()) >= 5
    assert m["ismn"]["delivery_delay_s"] == 1.5 or abs(m["ismn"]["delivery_delay_s"] - 1.5) < 1e-6
    assert m["ismn"]["accept_rate"] == 1.0 and m["ismn"]["fix_rate"] == 1.0
    # The navigator's verdicts are stamped with the frames' times.
    fused = corr[corr["kind"] == "position_fix:ismn"]["t_s"].to_numpy()
    np.testing.assert_allclose(fused, fixes["t_s"].to_numpy()[:-1])

    # The same fixes, half of them, fused at once: the replayed flight navigates as well.
    base, _, _ = _run(tmp_path, "at_once", "vehicles.uav0.aids.ismn.every_n_frames=2")
    err, err0 = m["nav"]["horizontal_error_m"]["mean"], base["nav"]["horizontal_error_m"]["mean"]
    assert abs(err - err0) < 0.15, (err, err0)
    assert base["ismn"]["delivery_delay_s"] == 0.0 and base["ismn"]["busy_frames"] == 0

