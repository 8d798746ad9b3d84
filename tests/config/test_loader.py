"""Scenario loading: overrides address vehicles by id, ${VAR} expansion, one-line errors."""

from pathlib import Path

import pytest

from testbench.config.loader import apply_override, load_scenario, parse_yaml
from testbench.core.errors import InputError

REPO = Path(__file__).resolve().parents[2]
RACETRACK = REPO / "scenarios" / "fixedwing_racetrack.yaml"


def test_override_addresses_vehicle_by_id_and_component_params():
    loaded = load_scenario(RACETRACK, ["vehicles.uav0.mission.altitude_agl_m=300", "duration_s=12.5"])
    assert loaded.scenario.duration_s == 12.5
    assert loaded.scenario.vehicle("uav0").mission.params["altitude_agl_m"] == 300
    assert loaded.data["vehicles"][0]["mission"]["params"]["altitude_agl_m"] == 300


def test_override_sensor_by_name_and_index():
    data = {"vehicles": [{"id": "a", "sensors": [{"type": "imu", "params": {}}, {"name": "cam", "type": "camera"}]}]}
    apply_override(data, "vehicles.a.sensors.imu.preset=tactical", "x")
    apply_override(data, "vehicles.0.sensors.cam.rate_hz=5", "x")
    assert data["vehicles"][0]["sensors"][0]["params"]["preset"] == "tactical"
    assert data["vehicles"][0]["sensors"][1]["params"]["rate_hz"] == 5


def test_override_unknown_vehicle_names_the_choices():
    with pytest.raises(InputError, match="no item 'uav9'.*uav0"):
        load_scenario(RACETRACK, ["vehicles.uav9.mission.altitude_agl_m=300"])


def test_env_expansion_and_unset_variable(tmp_path, monkeypatch):
    text = RACETRACK.read_text().replace("world:\n", "world:\n  imagery: ${TB_TEST_MAPS}/map.tif\n", 1)
    p = tmp_path / "s.yaml"
    p.write_text(text)
    monkeypatch.setenv("TB_TEST_MAPS", "/data/maps")
    assert load_scenario(p).scenario.world.imagery == "/data/maps/map.tif"
    monkeypatch.delenv("TB_TEST_MAPS")
    with pytest.raises(InputError, match=r"world.imagery: environment variable \$\{TB_TEST_MAPS\} is not set"):
        load_scenario(p)


@pytest.mark.parametrize(
    "override, message",
    [
        ("vehicles.uav0.initial.altitude_ft=800", r"vehicles\[uav0\]\.initial\.altitude_ft: unknown key"),
        ("duration_s='10 min'", r"duration_s: .*write a plain number in seconds"),
        ("vehicles.uav0.aircraft=no_such_plane", r"unknown aircraft 'no_such_plane'; available: .*tb_fixedwing"),
        ("vehicles.uav0.control.no_such_gain=1", r"vehicles\[uav0\]\.control\.params\.no_such_gain: unknown key"),
        ("vehicles.uav0.sensors.ideal_state.rate_hz=7", r"7 Hz .*divide"),
    ],
)
def test_bad_input_messages(override, message):
    with pytest.raises(InputError, match=message):
        loaded = load_scenario(RACETRACK, [override])
        from testbench.sim.runner import build_engine

        build_engine(loaded)


def test_yaml_syntax_error_gives_line_and_column():
    with pytest.raises(InputError, match=r"bad.yaml: YAML syntax error at line 2, column 9: mapping values"):
        parse_yaml("name: x\nworld: a: b\n", "bad.yaml")


def test_missing_file():
    with pytest.raises(InputError, match="scenario file not found"):
        load_scenario("/nonexistent/dir/s.yaml")


def test_yaml_anchors_in_x_keys_are_shared_then_unshared(tmp_path):
    text = RACETRACK.read_text().replace("vehicles:\n", "x-sensors: &s\n  - {type: ideal_state, params: {rate_hz: 40}}\nvehicles:\n", 1)
    text = text.replace("    sensors:\n      - {type: ideal_state, params: {rate_hz: 40}}\n", "    sensors: *s\n")
    p = tmp_path / "s.yaml"
    p.write_text(text)
    loaded = load_scenario(p, ["vehicles.uav0.sensors.ideal_state.rate_hz=20"])
    assert loaded.scenario.vehicles[0].sensors[0].params["rate_hz"] == 20
    assert "x-sensors" not in loaded.data


def test_additive_override_offsets_the_scenario_value():
    base = load_scenario(RACETRACK).scenario.vehicle("uav0").initial.east_m
    loaded = load_scenario(RACETRACK, ["vehicles.uav0.initial.east_m+=250.5"])
    assert loaded.scenario.vehicle("uav0").initial.east_m == base + 250.5


@pytest.mark.parametrize("item, message", [
    ("vehicles.uav0.initial.pitch_deg+=3", "no value at vehicles.uav0.initial.pitch_deg"),
    ("vehicles.uav0.aircraft+=1", "adds numbers only"),
    ("vehicles.uav0.initial.east_m+=abc", "adds numbers only"),
])
def test_additive_override_needs_numbers_on_both_sides(item, message):
    with pytest.raises(InputError, match=message):
        load_scenario(RACETRACK, [item])


def test_flat_elevation_is_kept_and_a_dem_named_flat_is_a_path(tmp_path):
    """'flat' / 'flat:H' on the elevation keys is flat ground, not a file next to the scenario;
    a DEM whose file name starts with 'flat' is still a path, made absolute."""
    text = RACETRACK.read_text().replace(
        "world:\n", "world:\n  elevation: flat:25\n  reference_elevation: Flat\n  reference_map: flat_map.tif\n", 1)
    p = tmp_path / "s.yaml"
    p.write_text(text)
    world = load_scenario(p).scenario.world
    assert (world.elevation, world.reference_elevation) == ("flat:25", "Flat")
    assert world.reference_map == str(tmp_path / "flat_map.tif")  # imagery is never flat ground
    world = load_scenario(p, ["world.elevation=flat_dem.tif"]).scenario.world
    assert world.elevation == str(tmp_path / "flat_dem.tif")
