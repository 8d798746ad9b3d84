"""`testbench run --check`: the scenario is built (vehicles, maps, initial state) but not flown;
the resolved scenario goes to stdout, nothing is written, bad input still exits 2."""

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import rasterio
import yaml
from rasterio.errors import NotGeoreferencedWarning

REPO = Path(__file__).resolve().parents[2]
SCENARIOS = REPO / "scenarios"


def _run(*args):
    return subprocess.run([sys.executable, str(REPO / "cli.py"), "run", *args], capture_output=True, text=True,
                          cwd=REPO, timeout=120)


def _write_plain_tif(path: Path) -> None:
    """An 8 x 8 GeoTIFF without CRS or transform (a map without georeference)."""
    with rasterio.open(path, "w", driver="GTiff", width=8, height=8, count=1, dtype="uint8") as dst:
        dst.write(np.zeros((1, 8, 8), np.uint8))


def test_check_prints_the_resolved_scenario_and_writes_nothing(tmp_path):
    proc = _run(str(SCENARIOS / "fixedwing_racetrack.yaml"), "--check", "--set", "duration_s=7",
                "--set", "vehicles.uav0.mission.altitude_agl_m=300", "--out", str(tmp_path / "o"))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("# fixedwing_racetrack: valid; 1 vehicle built")
    resolved = yaml.safe_load(proc.stdout)
    assert resolved["duration_s"] == 7
    assert resolved["vehicles"][0]["id"] == "uav0"
    assert resolved["vehicles"][0]["mission"]["params"]["altitude_agl_m"] == 300
    assert not (tmp_path / "o").exists()


def test_check_opens_maps_a_run_would_open_only_later(tmp_path):
    # The racetrack has no camera, so a run would never read its imagery; the check does.
    tif = tmp_path / "plain.tif"
    with warnings.catch_warnings():  # rasterio warns that what it writes has no georeference: the point
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        _write_plain_tif(tif)
    proc = _run(str(SCENARIOS / "fixedwing_racetrack.yaml"), "--check", "--set", f"world.imagery={tif}")
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "no georeference" in proc.stderr and "Traceback" not in proc.stderr


def test_check_sets_the_initial_state(tmp_path):
    proc = _run(str(SCENARIOS / "multirotor_waypoints.yaml"), "--check", "--set", "vehicles.quad0.initial.altitude_m=-50")
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "below the terrain" in proc.stderr and "Traceback" not in proc.stderr


def test_check_refuses_a_start_inside_an_obstacle(tmp_path):
    proc = _run(str(SCENARIOS / "multirotor_waypoints.yaml"), "--check", "--set",
                "world.obstacles=[{name: mast, min_ned_m: [-5, -5, -200], max_ned_m: [5, 5, 0]}]")
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "inside obstacle 'mast'" in proc.stderr and "Traceback" not in proc.stderr


def test_check_refuses_boresight_states_without_an_image_pose():
    """camera_boresight on the navigator needs a scene matcher whose fixes carry the image-only
    pose: without pipeline.pose_from_image the check names both; with it the scenario builds."""
    scenario = str(SCENARIOS / "paper_ismn_800m.yaml")
    states = "vehicles.uav0.navigation.params.camera_boresight={sigma_deg: 0.5}"
    proc = _run(scenario, "--check", "--set", states)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "camera_boresight" in proc.stderr and "pose_from_image" in proc.stderr and "Traceback" not in proc.stderr
    ok = _run(scenario, "--check", "--set", states, "--set", "vehicles.uav0.aids.ismn.pipeline.pose_from_image=true",
              "--set", "vehicles.uav0.sensors.down.mount_error_sigma_deg=0.5")
    assert ok.returncode == 0, ok.stderr


def test_check_refuses_clouds_whose_sun_does_not_rise():
    """Shadows over a map that is not procedural are cast by the noon sun of the scenario's date;
    where that sun does not rise (a polar night) the check says so and names the key that gives
    one; with a sun given, or the shadows off, the scenario builds."""
    scenario = str(SCENARIOS / "fixedwing_racetrack.yaml")
    arctic = ["--set", "world.origin.lat_deg=80.0", "--set", "epoch_year=2025.97",
              "--set", "world.clouds={base_m: 500.0, coverage: 0.3}"]
    proc = _run(scenario, "--check", *arctic)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "does not rise" in proc.stderr and "sun_elevation_deg" in proc.stderr and "Traceback" not in proc.stderr
    for fix in ("world.clouds.shadow_light=1.0", "world.clouds={base_m: 500.0, sun_azimuth_deg: 180.0, sun_elevation_deg: 5.0}"):
        ok = _run(scenario, "--check", *arctic, "--set", fix)
        assert ok.returncode == 0, ok.stderr


def test_check_refuses_replayed_late_fixes_beside_the_spoofing_monitor():
    """Late fixes replayed (delayed_fixes replay, the default) and the spoofing monitor's rewinds
    would replay the same inputs twice: the check names the key and what to use instead."""
    scenario = str(SCENARIOS / "paper_ismn_800m.yaml")
    both = ["--set", "vehicles.uav0.aids.ismn.latency_s=0.5", "--set", "vehicles.uav0.navigation.params.gnss_monitor={}"]
    proc = _run(scenario, "--check", *both)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "delayed_fixes" in proc.stderr and "'carry'" in proc.stderr and "Traceback" not in proc.stderr
    ok = _run(scenario, "--check", *both, "--set", "vehicles.uav0.navigation.params.delayed_fixes=carry")
    assert ok.returncode == 0, ok.stderr


def test_check_refuses_map_error_states_without_a_scene_matcher():
    """Only scene-matching fixes see the map's error: the states without an ismn aid are refused
    by name; with one they build."""
    key = "vehicles.uav0.navigation.params.map_error={sigma_m: 2.5}"
    proc = _run(str(SCENARIOS / "ins_only_800m.yaml"), "--check", "--set", key)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "map_error" in proc.stderr and "ismn" in proc.stderr and "Traceback" not in proc.stderr
    ok = _run(str(SCENARIOS / "paper_ismn_800m.yaml"), "--check", "--set", key)
    assert ok.returncode == 0, ok.stderr


@pytest.mark.parametrize("key, value", [("camera_time_offset", "{sigma_s: 0.03}"),
                                        ("camera_intrinsics", "{principal_point_sigma_px: 1.0}")])
def test_check_refuses_camera_states_without_one_scene_matcher(key, value):
    """The camera time offset and intrinsics states are learnt from one ismn aid's fixes: without
    a scene matcher, or beside the boresight states, the check names the key; with the main
    job's one aid it builds."""
    offset = f"vehicles.uav0.navigation.params.{key}={value}"
    proc = _run(str(SCENARIOS / "ins_only_800m.yaml"), "--check", "--set", offset)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert key in proc.stderr and "ismn" in proc.stderr and "Traceback" not in proc.stderr
    scenario = str(SCENARIOS / "paper_ismn_800m.yaml")
    both = _run(scenario, "--check", "--set", offset, "--set", "vehicles.uav0.navigation.params.camera_boresight={sigma_deg: 0.5}",
                "--set", "vehicles.uav0.aids.ismn.pipeline.pose_from_image=true")
    assert both.returncode == 2 and "camera_boresight" in both.stderr, both.stderr
    ok = _run(scenario, "--check", "--set", offset)
    assert ok.returncode == 0, ok.stderr
