"""testbench.testing: the conformance checks pass the reference implementations and catch a
component that breaks each rule."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from testbench.core import registry
from testbench.core.interfaces import BuildContext, Controller, Detector, Navigator, Sensor
from testbench.core.messages import NavEstimate
from testbench.dynamics.catalog import aircraft_meta
from testbench.sensors.fakes import ORIGIN, FakeWorld, make_truth
from testbench.testing import (ConformanceError, check_controller, check_detector, check_dynamics, check_metric,
                               check_navigator, check_scene_matcher, check_sensor)

CTX = BuildContext("uav0", ("uav0", "uav1"), ORIGIN)


def _sensor(kind: str, **params) -> Sensor:
    return registry.build("sensor", kind, params, f"test.{kind}", ctx=CTX)


@pytest.mark.parametrize("kind", ["imu", "barometer", "magnetometer", "gnss", "radar_altimeter"])
def test_reference_sensors_conform(kind):
    check_sensor(lambda: _sensor(kind))


class _WalksTwice(Sensor):
    """A barometer whose bias walks on every ask, not once per sample time."""

    rate_hz = 10.0

    def __init__(self):
        self.bias_m = 0.0

    def measure(self, truth, world, rng):
        self.bias_m += 0.1 * rng.standard_normal()
        return -truth.pos_ned_m[2] + self.bias_m


def test_a_sensor_that_walks_on_every_ask_fails():
    with pytest.raises(ConformanceError, match="asked twice"):
        check_sensor(_WalksTwice)


def _initial() -> NavEstimate:
    t = make_truth(0.0, pos_ned_m=(0.0, 0.0, -100.0))
    I3 = np.eye(3)
    return NavEstimate(0.0, t.pos_ned_m.copy(), t.vel_ned_mps.copy(), t.q_nb_wxyz.copy(), np.zeros(3), np.zeros(3),
                       I3 * 4.0, I3 * 0.01, I3 * 1e-4)


def _imu_and_baro(seconds: float = 2.0):
    imu, baro = _sensor("imu", preset="paper", rate_hz=100.0), _sensor("barometer")
    rng = np.random.default_rng(1)
    samples, fixes = [], []
    for k in range(1, int(100 * seconds) + 1):
        t = make_truth(k / 100.0, pos_ned_m=(0.0, 0.0, -100.0))
        samples.append(imu.measure(t, FakeWorld(t.t_s), rng))
        if k % 5 == 0:
            fixes.append(baro.measure(t, FakeWorld(t.t_s), rng))
    return samples, [f for f in fixes if f is not None]


def _ekf() -> Navigator:
    return registry.build("navigator", "ins_ekf", {"imu_preset": "paper"}, "test.navigation", ctx=CTX,
                          aircraft={}, rng=np.random.default_rng(5))


def test_the_reference_navigator_conforms():
    imu, baro = _imu_and_baro()
    check_navigator(_ekf, _initial(), imu, baro)


class _Lopsided(Navigator):
    """Dead reckoning on the first IMU sample that claims a non-symmetric position covariance."""

    def initialize(self, t_s, initial):
        self.e = initial

    def predict(self, imu):
        P = self.e.cov_pos_ned_m2.copy()
        P[0, 1] += 0.5
        self.e = dataclasses.replace(self.e, t_s=imu.t_s, cov_pos_ned_m2=P)

    def correct(self, measurement):
        return None

    def estimate(self):
        return self.e


def test_a_navigator_with_an_asymmetric_covariance_fails():
    imu, _ = _imu_and_baro(0.1)
    with pytest.raises(ConformanceError, match="cov_pos_ned_m2 is not symmetric"):
        check_navigator(_Lopsided, _initial(), imu)


def _frames():
    """A dark frame with two lit LED markers (red, saturated) and an empty one."""
    img = np.full((120, 160, 3), 40, np.uint8)
    for u, v in ((40, 30), (110, 80)):
        img[v - 1:v + 2, u - 1:u + 2] = (255, 40, 40)
        img[v, u] = (255, 255, 255)
    return [img, np.full((120, 160, 3), 40, np.uint8)]


def test_the_reference_detectors_conform():
    for kind in ("led", "cnn", "oracle"):  # the oracle finds nothing without truth annotations
        check_detector(lambda: registry.build("detector", kind, {}, "test.detector"), _frames())
    d = registry.build("detector", "led", {}, "test.detector")
    assert len(d.detect(_frames()[0])) == 2  # the check ran on frames with something to find


class _Scribbler(Detector):
    """Marks what it finds in the frame it was given."""

    def detect(self, image):
        image[0, 0] = 255
        return []


def test_a_detector_that_writes_into_the_frame_fails():
    with pytest.raises(ConformanceError, match="wrote into image 0"):
        check_detector(_Scribbler, _frames())


def _estimates():
    e0 = _initial()
    return [dataclasses.replace(e0, t_s=k * 0.02, pos_ned_m=e0.pos_ned_m + [0.01 * k, 0.0, 0.0]) for k in range(50)]


def test_the_reference_controller_conforms():
    def make() -> Controller:
        mission = registry.build("mission", "waypoints", {"altitude_agl_m": 100.0, "points": [{"north_m": 100.0, "east_m": 0.0}]},
                                 "test.mission", ctx=CTX)
        return registry.build("controller", "multirotor", {}, "test.control", ctx=CTX, mission=mission,
                              aircraft=aircraft_meta("tb_quad"))
    check_controller(make, _estimates())


class _Runaway(Controller):
    """Integrates forever: its throttle is infinite after the first step."""

    def update(self, t_s, estimate, reference=None):
        from testbench.core.messages import SurfaceCommand

        return SurfaceCommand(throttle=float("inf") if t_s > 0 else 0.5)


def test_a_controller_with_a_non_finite_command_fails():
    with pytest.raises(ConformanceError, match="non-finite"):
        check_controller(_Runaway, _estimates())


def _scene_pair():
    """A map window of one season and an ortho frame of the other, placed (6.3, -4.6) px from
    the predicted (60, 70)."""
    import cv2

    from testbench.navigation.ismn.synth import procedural_seasons
    from testbench.navigation.ismn.types import MatchPrior

    summer, winter = procedural_seasons(np.random.default_rng(7), 700, 4.0, n_fields=120)
    A = np.array([[1.0, 0.0, 60 + 6.3], [0.0, 1.0, 70 - 4.6]])
    ortho = cv2.warpAffine(summer.data[:, :, 0], A, (560, 440), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)
    return ortho, winter.data[:600, :700, 0].copy(), MatchPrior((60, 70), 20.0)


@pytest.mark.parametrize("name", ["ncc", "phase"])
def test_the_reference_matchers_conform(name):
    ortho, window, prior = _scene_pair()
    check_scene_matcher(lambda: registry.build("matcher", name, None, "test.matcher", ctx=None), ortho, window, prior,
                        expected_offset_px=(6.3, -4.6), tolerance_px=0.5)


class _HalfPixelOff:
    """Reports the placement half a pixel off in columns; with certain=True it also claims no
    uncertainty at all (a zero covariance)."""

    accepts_ortho_frame = False

    def __init__(self, certain: bool = False):
        self.cov = np.zeros((2, 2)) if certain else np.eye(2) * 0.04

    def match(self, ortho, window, prior):
        from testbench.navigation.ismn.types import MatchResult

        return MatchResult(np.array([6.8, -4.6]), None, None, 0.9, self.cov)


def test_a_matcher_off_the_true_placement_or_claiming_no_uncertainty_fails():
    ortho, window, prior = _scene_pair()
    check_scene_matcher(_HalfPixelOff, ortho, window, prior, expected_offset_px=(6.3, -4.6), tolerance_px=0.6)
    with pytest.raises(ConformanceError, match="0.50 px from the true"):
        check_scene_matcher(_HalfPixelOff, ortho, window, prior, expected_offset_px=(6.3, -4.6), tolerance_px=0.25)
    with pytest.raises(ConformanceError, match="positive definite"):
        check_scene_matcher(lambda: _HalfPixelOff(certain=True), ortho, window, prior)


def test_the_reference_dynamics_conform():
    from testbench.core.messages import RotorCommand
    from testbench.dynamics.jsbsim_adapter import InitialCondition, JSBSimDynamics

    def make():
        return JSBSimDynamics("tb_quad", ORIGIN, 200.0, vehicle_id="q")

    hover = aircraft_meta("tb_quad")["hover_throttle_norm"]
    check_dynamics(make, InitialCondition(pos_ned_m=(0.0, 0.0, -50.0)), [RotorCommand(motors=(hover,) * 4)] * 20, 0.05)


class _Clockless:
    """A point mass that forgets to advance its clock."""

    def reset(self, initial):
        self.t = make_truth(0.0, pos_ned_m=initial.pos_ned_m)
        return self.t

    def step(self, command, dt_s):
        return self.t


def test_dynamics_whose_time_stands_still_fail():
    from testbench.dynamics.jsbsim_adapter import InitialCondition

    with pytest.raises(ConformanceError, match="expected 0.05 s"):
        check_dynamics(_Clockless, InitialCondition(pos_ned_m=(0.0, 0.0, -50.0)), [None] * 3, 0.05)


def _record(tmp_path):
    from testbench.scoring import load_run
    from testbench.scoring.synthetic import make_synthetic_run

    d = make_synthetic_run(tmp_path, np.random.default_rng(1), n_vehicles=1, duration_s=10.0, rate_hz=5.0,
                           with_events=True, with_images=False)
    return load_run(d)


def test_a_pure_metric_conforms_and_one_that_edits_the_record_fails(tmp_path):
    record = _record(tmp_path)

    def climb(rec):
        return {"max_rate_mps": float((-rec.telemetry["truth_vd_mps"]).max()), "by": {"n": len(rec.telemetry)}}

    check_metric(climb, record)

    def sloppy(rec):
        rec.telemetry["truth_vd_mps"] -= 0.5  # takes off a "bias" in place
        return {"max_rate_mps": float((-rec.telemetry["truth_vd_mps"]).max())}

    with pytest.raises(ConformanceError, match="changed the run record"):
        check_metric(sloppy, _record(tmp_path / "b"))
    with pytest.raises(ConformanceError, match="expected a number"):
        check_metric(lambda rec: {"label": "fast"}, record)
