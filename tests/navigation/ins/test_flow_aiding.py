"""The optical-flow fusion's bookkeeping (navigation/ins/flow_aiding.py): the camera's rotation
taken out with the filter's own gyros over the sample's interval, the depth from the range,
and the samples it cannot fuse."""

from __future__ import annotations

import math

import numpy as np
import pytest

from testbench.core.camera_geometry import mount_rotation
from testbench.core.messages import OpticalFlowSample, RadarAltSample
from testbench.core.rotations import euler_to_quat
from testbench.navigation.ins.ekf import ErrorStateEKF
from testbench.navigation.ins.flow_aiding import FlowVelocityAiding
from testbench.navigation.ins.imu_noise import imu_noise_from_datasheet
from testbench.navigation.ins.flow_settings import OpticalFlowAiding

R_BC = mount_rotation(0.0, -90.0, 0.0)  # looking down, image top to the nose
ROTATION_C = np.array([[0.0, -1.05, 0.0], [1.05, 0.0, 0.0]])  # a frame reads 5 % more than its centre


def _filter(vel_ned_mps=(0.0, 0.0, 0.0)):
    ekf = ErrorStateEKF(imu_noise_from_datasheet(0.15, 7.0, 0.02, 14.0), flow_bias_sigma_rps=0.005, flow_bias_tau_s=20.0)
    ekf.initialize(0.0, math.radians(47.0), math.radians(-99.0), 530.0, np.array(vel_ned_mps, float),
                   euler_to_quat(np.zeros(3)), np.eye(ekf.n) * 1e-4)
    return ekf, FlowVelocityAiding(OpticalFlowAiding())


def _fly(ekf, flow, omega_eb_b, t1_s, dt=0.01):
    """Hover level, heading north (specific force against gravity), turning at omega_eb_b
    (rad/s) relative to the Earth, up to t1_s: the gyros read that plus the Earth's rate."""
    lat = ekf.ins.lat_rad
    earth_b = 7.292115e-5 * np.array([math.cos(lat), 0.0, -math.sin(lat)])  # level, heading 0: body = NED
    while ekf.t_s < t1_s - 1e-9:
        t_prev = ekf.t_s
        ekf.propagate(round(t_prev + dt, 6), np.asarray(omega_eb_b, float) + earth_b, np.array([0.0, 0.0, -9.806]))
        flow.accumulate(ekf, t_prev)


def _sample(t_s, dt_s, flow_c_rad):
    return OpticalFlowSample(t_s=t_s, dt_s=dt_s, flow_c_rad=np.asarray(flow_c_rad, float), cov_c_rad2=np.eye(2) * 1e-8,
                             texture_dn2=5.0, residual_dn=2.0, R_bc=R_BC, lever_arm_b_m=np.zeros(3), rotation_c=ROTATION_C)


def test_the_cameras_own_rotation_is_taken_out_as_the_sensor_reads_it():
    ekf, flow = _filter()
    omega_b = np.array([0.2, -0.1, 0.05])
    _fly(ekf, flow, np.zeros(3), 0.95)
    _fly(ekf, flow, omega_b, 1.0)  # turning over the sample's interval only
    flow.take_range(RadarAltSample(1.0, 30.0, 0.0))
    # The ground does not move: all the image's motion over the last 0.05 s is the rotation,
    # as the sensor's fit reads it (rotation_c) about the camera's axes.
    rot_c = R_BC.T @ (omega_b * 0.05)
    info = flow.correct(ekf, _sample(1.0, 0.05, ROTATION_C @ rot_c))
    assert info is not None and info.kind == "optical_flow"
    # Of a rotational flow of 0.2 rad/s, what is left is the velocity the 10 mrad tilt built
    # over the interval (2 mm/s at 30 m).
    assert np.abs(info.innovation).max() < 2e-4 and flow.skipped == 0


def test_a_translation_over_the_depth_is_the_velocity_the_filter_is_told():
    ekf, flow = _filter(vel_ned_mps=(2.0, 0.0, 0.0))
    _fly(ekf, flow, np.zeros(3), 0.5)
    flow.take_range(RadarAltSample(0.5, 40.0, 0.0))
    # Flying north at 2 m/s, 40 m up: the ground moves towards the image's bottom (camera +y,
    # the tail) at 2 / 40 rad/s; a flow of 3 / 40 says the filter's velocity is 1 m/s short.
    info = flow.correct(ekf, _sample(0.5, 0.05, [0.0, 3.0 / 40.0 * 0.05]))
    np.testing.assert_allclose(info.innovation, [0.0, 1.0 / 40.0], atol=1e-5)


def test_samples_it_cannot_fuse_are_counted_not_fused():
    ekf, flow = _filter()
    _fly(ekf, flow, np.zeros(3), 0.3)
    assert flow.correct(ekf, _sample(0.3, 0.05, [0.0, 0.0])) is None  # no range yet
    flow.take_range(RadarAltSample(0.3, 30.0, math.radians(20.0)))  # a wide beam: not a range along the axis
    assert flow.correct(ekf, _sample(0.3, 0.05, [0.0, 0.0])) is None
    flow.take_range(RadarAltSample(0.3, 30.0, 0.0))
    assert flow.correct(ekf, _sample(0.3, 5.0, [0.0, 0.0])) is None  # an interval the gyro history does not cover
    weak = OpticalFlowSample(0.3, 0.05, np.zeros(2), np.eye(2), 0.0, 2.0, R_BC, np.zeros(3), ROTATION_C)
    assert flow.correct(ekf, weak) is None  # no texture
    assert flow.skipped == 4
    assert flow.correct(ekf, _sample(0.3, 0.05, [0.0, 0.0])) is not None


def test_the_flows_slow_error_decorrelates_with_the_ground_its_view_passes():
    def decay(view_rate_rps):
        ekf = ErrorStateEKF(imu_noise_from_datasheet(0.15, 7.0, 0.02, 14.0), flow_bias_sigma_rps=0.003,
                            flow_bias_tau_s=60.0, flow_bias_correlation_rad=0.8)
        ekf.initialize(0.0, math.radians(47.0), math.radians(-99.0), 530.0, np.zeros(3),
                       euler_to_quat(np.zeros(3)), np.eye(ekf.n) * 1e-4)
        ekf.b_flow_rps = np.array([0.002, -0.001])
        ekf.flow_view_rate_rps = view_rate_rps
        _fly(ekf, FlowVelocityAiding(OpticalFlowAiding()), np.zeros(3), 2.0)
        return ekf.b_flow_rps[0] / 0.002

    # Hovering over the same ground it holds (time alone, 60 s); at 0.2 rad/s of flow (5 m/s
    # 25 m up) the view passes 0.4 rad of ground in 2 s, half its correlation.
    # (to the covariance interval: the last few ms of the 2 s wait for the next step)
    assert decay(0.0) == pytest.approx(math.exp(-2.0 / 60.0), rel=2e-3)
    # the rates of decay: 1 / 60 s against 1 / 60 + 0.2 / 0.8 per second
    assert math.log(decay(0.2)) / math.log(decay(0.0)) == pytest.approx(16.0, rel=1e-9)


def test_the_fusion_tells_the_filter_how_fast_its_view_passes_the_ground():
    ekf, flow = _filter(vel_ned_mps=(2.0, 0.0, 0.0))
    _fly(ekf, flow, np.zeros(3), 0.5)
    flow.take_range(RadarAltSample(0.5, 40.0, 0.0))
    flow.correct(ekf, _sample(0.5, 0.05, [0.0, 2.0 / 40.0 * 0.05]))
    assert ekf.flow_view_rate_rps == pytest.approx(2.0 / 40.0)


def test_a_flow_the_gate_keeps_refusing_is_held_out_until_it_agrees_again():
    """With a hold-out (settings.FlowHoldout): after max_refused of the last `window` samples
    were refused, the flow is only checked ("optical_flow:held"), so a wrong reading that falls
    inside the gate now and then no longer pulls the velocity; once the flow agrees again the
    hold ends. Without one, each sample is gated on its own."""
    import pydantic

    from testbench.navigation.ins.flow_settings import FlowHoldout

    with pytest.raises(pydantic.ValidationError, match="exceeds window"):
        FlowHoldout(window=5, max_refused=6)

    def hover(holdout):
        ekf, _ = _filter()
        flow = FlowVelocityAiding(OpticalFlowAiding(holdout=holdout))
        return ekf, flow

    def step(ekf, flow, t, ground_mps):
        _fly(ekf, flow, np.zeros(3), t)
        flow.take_range(RadarAltSample(t, 30.0, 0.0))
        return flow.correct(ekf, _sample(t, 0.05, [0.0, ground_mps / 30.0 * 0.05]))

    for holdout in (None, FlowHoldout(window=10, max_refused=3, hold_s=1.0)):
        ekf, flow = hover(holdout)
        t = 0.0
        kinds = []
        # A shadow drifting at 6 m/s: the flow reads 6 m/s (far outside the gate) with, every
        # fourth sample, a reading of 0.3 m/s, off by a little but inside the gate.
        for i in range(40):
            t = round(t + 0.05, 6)
            info = step(ekf, flow, t, 0.3 if i % 4 == 3 else 6.0)
            kinds.append((info.kind, info.accepted))
        took_wrong = sum(1 for k, a in kinds if k == "optical_flow" and a)
        if holdout is None:
            assert took_wrong == 10  # every reading inside the gate was fused
        else:
            assert took_wrong < 4 and any(k == "optical_flow:held" for k, _ in kinds)
            assert not any(a for k, a in kinds if k == "optical_flow:held")  # checked, never fused
            # The ground's true flow (hovering: none) for long enough: the hold ends.
            for _ in range(40):
                t = round(t + 0.05, 6)
                info = step(ekf, flow, t, 0.0)
            assert info.kind == "optical_flow" and info.accepted
