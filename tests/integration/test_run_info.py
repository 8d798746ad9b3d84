"""run.json facts the report and scoring rely on."""


from testbench.config.schema import Vehicle
from testbench.sim.runner import _gnss_denial_windows, _gnss_denied_windows


def _vehicle(sensors):
    return Vehicle.model_validate({"id": "uav0", "aircraft": "tb_quad", "initial": {"altitude_m": 100.0, "north_m": 0.0, "east_m": 0.0},
                                   "control": {"type": "multirotor"},
                                   "sensors": sensors})


def test_gnss_denied_windows_from_jamming_only():
    v = _vehicle([{"type": "gnss", "params": {"denial": [
        {"type": "spoofing", "start_s": 10.0, "end_s": 20.0},
        {"type": "jamming", "start_s": 60.0},
        {"type": "jamming", "start_s": 30.0, "end_s": 40.0},
        {"type": "jamming", "start_s": 500.0},
    ]}}])
    assert _gnss_denied_windows(v, 300.0) == [[30.0, 40.0], [60.0, 300.0]]
    assert _gnss_denial_windows(v, 300.0, "spoofing") == [[10.0, 20.0]]  # run.json gnss_spoofed_windows


def test_no_receiver_means_denied_throughout():
    assert _gnss_denied_windows(_vehicle([{"type": "imu"}]), 12.5) == [[0.0, 12.5]]
    assert _gnss_denied_windows(_vehicle([{"type": "gnss"}]), 5.0) == []
