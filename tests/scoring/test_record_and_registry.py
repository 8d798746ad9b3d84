import json
import sys
import types

import numpy as np
import pytest

from scoring_helpers import record_of, straight_telemetry
from testbench.core.errors import InputError
from testbench.scoring import load_run, register_metric, score_record, score_run, unregister_metric
from testbench.scoring.synthetic import write_record


def test_load_run_round_trip(tmp_path):
    tel = straight_telemetry(n=30)
    write_record(tmp_path, tel, {"scenario_name": "x", "vehicles": [{"id": "a"}]}, scenario_text="name: x\n")
    rec = load_run(tmp_path)
    assert rec.vehicle_ids == ["a"] and len(rec.telemetry) == 30
    assert rec.scenario_text == "name: x\n" and rec.event("ismn") is None
    assert score_run(tmp_path).nav.horizontal_error_m.rms == pytest.approx(5.0)


def test_load_run_errors_name_the_file(tmp_path):
    with pytest.raises(InputError, match="not a run directory"):
        load_run(tmp_path / "nope")
    with pytest.raises(InputError, match="run.json"):
        load_run(tmp_path)
    (tmp_path / "run.json").write_text("{bad")
    with pytest.raises(InputError, match="not valid JSON"):
        load_run(tmp_path)
    (tmp_path / "run.json").write_text("{}")
    with pytest.raises(InputError, match="telemetry.parquet"):
        load_run(tmp_path)
    straight_telemetry().drop(columns="nav_down_m").to_parquet(tmp_path / "telemetry.parquet")
    with pytest.raises(InputError, match="nav_down_m"):
        load_run(tmp_path)


def test_registered_metric_lands_under_its_name():
    @register_metric("test_climb")
    def climb(record):
        return {"max_alt_m": float(-record.telemetry["truth_down_m"].min()), "nested": {"k": 1}}

    try:
        flat = score_record(record_of(straight_telemetry())).flatten()
        assert flat["test_climb.max_alt_m"] == 100.0
        assert flat["test_climb.nested.k"] == 1.0
    finally:
        unregister_metric("test_climb")
    assert "test_climb.max_alt_m" not in score_record(record_of(straight_telemetry())).flatten()


def test_metric_named_in_run_json_by_module_path(monkeypatch):
    mod = types.ModuleType("user_metrics_mod")
    mod.span = lambda record: {"t_span_s": float(np.ptp(record.telemetry["t_s"]))}
    monkeypatch.setitem(sys.modules, "user_metrics_mod", mod)
    flat = score_record(record_of(straight_telemetry(n=11), metrics=["user_metrics_mod:span"])).flatten()
    assert flat["span.t_span_s"] == pytest.approx(1.0)


def test_bad_metric_output_is_an_input_error():
    with pytest.raises(InputError, match="expected a dict"):
        score_record(record_of(straight_telemetry()), metrics=[lambda r: 3.0])
    with pytest.raises(ValueError):
        register_metric("nav")
