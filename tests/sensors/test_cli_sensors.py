"""`testbench sensors record|allan` handlers on a short record."""

import argparse
import json

import pytest

from testbench.commands import sensors
from testbench.core.errors import InputError


def _parse(argv):
    p = argparse.ArgumentParser()
    sensors.register(p.add_subparsers(dest="cmd"))
    return p.parse_args(argv)


def test_record_then_allan(tmp_path):
    out = tmp_path / "imu.parquet"
    a = _parse(["sensors", "record", "--preset", "paper", "--duration", "300", "--rate", "50", "--out", str(out)])
    assert a.handler(a) == 0
    b = _parse(["sensors", "allan", str(out), "--out", str(tmp_path / "allan")])
    assert b.handler(b) == 0
    summary = json.loads((tmp_path / "allan" / "allan.json").read_text())
    assert summary["preset"] == "paper"
    assert summary["channels"]["gyro_x_rad_s"]["ratio"]["white_density"] == pytest.approx(1.0, abs=0.1)
    assert (tmp_path / "allan" / "allan.png").stat().st_size > 1000


def test_allan_bad_input(tmp_path):
    a = _parse(["sensors", "allan", str(tmp_path / "missing.parquet"), "--out", str(tmp_path)])
    with pytest.raises(InputError, match="missing.parquet"):
        a.handler(a)
