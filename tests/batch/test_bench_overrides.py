"""The benchmark's scenario overrides load and mean what they say."""

from __future__ import annotations

from testbench.batch.bench import oracle_swarm_overrides
from testbench.config.loader import load_scenario
from testbench.sim.bench import SCENARIOS_DIR


def test_oracle_swarm_overrides_turn_off_pixels_and_the_led_offset():
    scn = load_scenario(SCENARIOS_DIR / "paper_swarm_relnav.yaml", list(oracle_swarm_overrides())).scenario
    assert len(scn.vehicles) == 10
    for veh in scn.vehicles:
        cams = [s for s in veh.sensors if s.type == "camera"]
        assert len(cams) == 3 and all(s.params["render_image"] is False for s in cams)
        aid = next(a for a in veh.aids if a.type == "relnav")
        assert aid.params["detector"]["type"] == "oracle"
        # The oracle reports the vehicle's centre, not the LED centroid the LED detector sees.
        assert list(aid.params["target_offset_b_m"]) == [0.0, 0.0, 0.0]
        assert aid.params.get("target_offset_by_chip_b_m") is None


def test_a_centre_detector_with_an_led_offset_is_refused(tmp_path, capsys):
    """The oracle reports the vehicle's centre: the LED detector's target offset left on would
    bias every bearing, so the run refuses it (exit 2) and names the keys."""
    from testbench.cli import main

    sets = ["duration_s=0.5", "vehicles.uav1.aids.relnav.detector={type: oracle, params: {sigma_px: 0.5}}"]
    args = ["run", str(SCENARIOS_DIR / "paper_swarm_relnav.yaml"), "--no-report", "--out", str(tmp_path / "run")]
    for s in sets:
        args += ["--set", s]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "target_offset_b_m" in err and "'oracle' reports the vehicle's centre" in err
