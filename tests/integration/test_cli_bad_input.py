"""Bad input through the real command line: one clear line on stderr, exit status 2, no
traceback, and nothing written to the output folder."""

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
RACETRACK = REPO / "scenarios" / "fixedwing_racetrack.yaml"


def _run(*args, cwd=REPO):
    return subprocess.run([sys.executable, str(REPO / "cli.py"), *args], capture_output=True, text=True, cwd=cwd, timeout=120)


def _check(proc, pattern):
    import re

    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert re.search(pattern, lines[0]), lines[0]


def test_missing_file(tmp_path):
    _check(_run("run", str(tmp_path / "nope.yaml"), "--out", str(tmp_path / "o")), r"nope\.yaml: scenario file not found")
    assert not (tmp_path / "o").exists()


def test_yaml_syntax_error_names_line_and_column(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text("name: x\nduration_s: 10\nworld: {origin: {lat_deg: 1, lon_deg: 2}\nvehicles: []\n")
    _check(_run("run", str(p), "--out", str(tmp_path / "o")), r"bad\.yaml: YAML syntax error at line \d+, column \d+")


def test_unknown_key_names_its_path(tmp_path):
    text = RACETRACK.read_text().replace("heading_deg: 0.0, airspeed_mps", "heading_deg: 0.0, speed_kts: 50, airspeed_mps")
    p = tmp_path / "s.yaml"
    p.write_text(text)
    _check(_run("run", str(p), "--out", str(tmp_path / "o")), r"vehicles\[uav0\]\.initial\.speed_kts: unknown key")


@pytest.mark.parametrize(
    "override, pattern",
    [
        ("duration_s=abc", r"duration_s: Input should be a valid number.*'abc'"),
        ("vehicles.uav0.initial.altitude_m=800ft", r"altitude_m: .*plain number in metres"),
        ("physics_rate_hz=-5", r"physics_rate_hz: Input should be greater than 0"),
        ("world.magnetic_anomaly={rms_nT: -5, source_depth_m: 1000}",
         r"world\.magnetic_anomaly\.rms_nT: Input should be greater than or equal to 0"),
        ("world.obstacles=[{name: mast, min_ned_m: [20, -5, -60], max_ned_m: [10, 5, 0]}]",
         r"world\.obstacles\[mast\]: .*north: 20\.0 is not below 10\.0 \(expected \[north, east, down\]"),
        ("world.obstacles=[{min_ned_m: [0, 0, -60], max_ned_m: [1, 1, 0], height_m: 60}]",
         r"world\.obstacles\[0\]\.height_m: unknown key"),
    ],
)
def test_wrong_type_or_unit_names_key_and_expected(tmp_path, override, pattern):
    _check(_run("run", str(RACETRACK), "--set", override, "--out", str(tmp_path / "o")), pattern)


def test_unknown_aircraft_lists_available(tmp_path):
    _check(
        _run("run", str(RACETRACK), "--set", "vehicles.uav0.aircraft=cessna999", "--out", str(tmp_path / "o")),
        r"unknown aircraft 'cessna999'; available: tb_fixedwing, tb_quad, .*c172x",
    )


TAN = REPO / "scenarios" / "tan_radalt_300m.yaml"


@pytest.mark.parametrize(
    "scenario, overrides, pattern",
    [
        (TAN, ["world.elevation=null", "world.reference_elevation_error=null"],
         r"aids\[tan\]: terrain-aided navigation needs a DEM onboard: world\.reference_elevation or world\.elevation"),
        (TAN, ["world.reference_elevation_error={rms_m: 2, correlation_m: -300}"],
         r"world\.reference_elevation_error\.correlation_m: Input should be greater than 0"),
        (TAN, ["vehicles.uav0.aids.tan.cells=60"], r"aids\[0\]\.params\.cells: .*must be odd"),
        (RACETRACK, ["vehicles.uav0.aids=[{type: tan}]"],
         r"aids\[tan\]\.params\.sensor: no sensor named 'radar_altimeter' on this vehicle \(have: ideal_state\)"),
        (TAN, ["vehicles.uav0.navigation.params.imu.flicker_fit_band_s=[100, 5]"],
         r"navigation\.params\.imu: .*flicker_fit_band_s \[100\.0, 5\.0\]: expected \[shortest, longest\]"),
        (TAN, ["vehicles.uav0.navigation.params.imu_bias_model=gauss_markov"],
         r"navigation\.params: .*imu\.flicker_fit_band_s fits the bias random walk of imu_bias_model random_walk"),
    ],
)
def test_terrain_aided_navigation_misconfigured(tmp_path, scenario, overrides, pattern):
    args = [a for o in overrides for a in ("--set", o)]
    _check(_run("run", str(scenario), "--out", str(tmp_path / "o"), *args), pattern)
    assert not (tmp_path / "o").exists()
