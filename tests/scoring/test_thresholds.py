import json
import math

import numpy as np
import pytest

from scoring_helpers import record_of, straight_telemetry
from testbench.core.errors import InputError
from testbench.scoring import check_thresholds, score_record, write_metrics_json


METRICS = {"a.b": 1.5, "a.c": 10.0, "a.nan": float("nan"), "a.s": "completed"}


def test_pass_fail_and_inclusive_bounds():
    r = check_thresholds(METRICS, {"a.b": {"max": 1.5}, "a.c": {"min": 2.0, "max": 5.0}})
    assert r.passed == ["a.b"]
    assert len(r.failed) == 1
    f = r.failed[0]
    assert (f["key"], f["value"], f["bound"], f["kind"]) == ("a.c", 10.0, 5.0, "max")
    assert "a.c" in f["reason"] and not r.ok


def test_both_bounds_violated_report_each():
    r = check_thresholds({"x": 0.0}, {"x": {"min": 1.0}})
    assert r.failed[0]["kind"] == "min"


def test_missing_key_fails_naming_it():
    r = check_thresholds(METRICS, {"ismn.smooth.horizontal_error_m.mean": {"max": 1.5}, "a": {"max": 1}})
    assert r.passed == []
    assert [f["kind"] for f in r.failed] == ["missing", "missing"]
    assert "ismn.smooth.horizontal_error_m.mean" in r.failed[0]["reason"]


def test_nan_and_strings_fail():
    r = check_thresholds(METRICS, {"a.nan": {"max": 1.0}, "a.s": {"min": 0.0}})
    assert [f["kind"] for f in r.failed] == ["not_a_number", "not_a_number"]


@pytest.mark.parametrize("bad", [{"k": {"maximum": 1}}, {"k": {"max": "x"}}, {"k": {}}, {"k": 3.0}, {"k": {"min": 2, "max": 1}}, [1]])
def test_malformed_thresholds_are_input_errors(bad):
    with pytest.raises(InputError):
        check_thresholds(METRICS, bad)


def test_metrics_json_has_thresholds_and_strict_json(tmp_path):
    res = score_record(record_of(straight_telemetry()), metrics=[])
    thr = check_thresholds(res.flatten(), {"nav.horizontal_error_m.rms": {"max": 4.0}, "nope.x": {"min": 0}})
    path = write_metrics_json(tmp_path, res, thr)
    doc = json.loads(path.read_text())
    assert doc["thresholds"]["passed"] == []
    assert {f["key"] for f in doc["thresholds"]["failed"]} == {"nav.horizontal_error_m.rms", "nope.x"}
    assert doc["nav"]["horizontal_error_m"]["rms"] == pytest.approx(5.0)
    assert doc["real_time_factor"] == 2.0
    assert "NaN" not in path.read_text()


def test_write_metrics_json_checks_run_json_thresholds_when_none_given(tmp_path):
    (tmp_path / "run.json").write_text(json.dumps({"thresholds": {"nav.position_error_m.max": {"max": 20.0}}}))
    res = score_record(record_of(straight_telemetry()), metrics=[])
    doc = json.loads(write_metrics_json(tmp_path, res).read_text())
    assert doc["thresholds"] == {"passed": ["nav.position_error_m.max"], "failed": []}
