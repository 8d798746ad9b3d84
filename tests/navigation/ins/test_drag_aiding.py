"""Rotor-drag velocity aiding (navigator drag_aiding) on the JSBSim quadrotor without GNSS.

tb_quad's rotors drag -c omega_i v in body x and y, so its accelerometers measure its body
velocity (mu = 0.365 1/s). With the aiding on, the INS velocity stays within centimetres per
second after GNSS is jammed; without it, it drifts by metres per second within a minute of a turn.
"""

from __future__ import annotations

import textwrap

import numpy as np
import pyarrow.parquet as pq
import pytest

from testbench.cli import main
from testbench.core.rotor_drag import momentum_drag_per_s

pytest.importorskip("jsbsim")

SCENARIO = textwrap.dedent("""\
    name: drag_aiding_check
    seed: 3
    duration_s: 90
    physics_rate_hz: 200
    record_rate_hz: 10
    world:
      origin: {lat_deg: 47.0, lon_deg: -99.0, alt_m: 500.0}
    vehicles:
      - id: q0
        aircraft: AIRCRAFT
        initial: {north_m: 0.0, east_m: 0.0, altitude_m: 100.0, heading_deg: 0.0}
        mission:
          type: waypoints
          params:
            altitude_agl_m: 100.0
            speed_mps: 4.0
            points: [{north_m: 200, east_m: 0}, {north_m: 200, east_m: 200}]
        sensors:
          - {type: imu, params: {preset: paper, rate_hz: 100}}
          - {type: barometer, params: {rate_hz: 20}}
          - {type: magnetometer, params: {rate_hz: 20}}
          - {type: gnss, params: {rate_hz: 5, denial: [{type: jamming, start_s: 10.0}]}}
        navigation: {type: ins_ekf, params: {imu_preset: paper}}
        control: {type: multirotor, params: {max_speed_mps: 4.0}}
        rates: {control_hz: 50}
    """)


def _velocity_error(tmp_path, name: str, *sets: str) -> np.ndarray:
    path = tmp_path / "quad.yaml"
    path.write_text(SCENARIO.replace("AIRCRAFT", "tb_quad"))
    out = tmp_path / name
    args = ["run", str(path), "--out", str(out), "--no-report", "--quiet"]
    for s in sets:
        args += ["--set", s]
    assert main(args) == 0
    d = pq.read_table(out / "telemetry.parquet").to_pandas()
    late = d.t_s.to_numpy() > 60.0  # 50 s into the outage, after the corner
    return np.hypot(d.nav_vn_mps - d.truth_vn_mps, d.nav_ve_mps - d.truth_ve_mps).to_numpy()[late]


def test_drag_aiding_holds_the_velocity_without_gnss(tmp_path):
    aided = _velocity_error(tmp_path, "on", "vehicles.q0.navigation.params.drag_aiding={}")
    free = _velocity_error(tmp_path, "off")
    assert np.sqrt(np.mean(aided**2)) < 0.1  # measured 0.04 m/s
    assert np.sqrt(np.mean(free**2)) > 10 * np.sqrt(np.mean(aided**2))  # measured 2.8 m/s


def test_thrust_scaled_drag_coefficient_follows_the_rotor_speed(tmp_path):
    """In level flight at 4 m/s tb_quad holds 0.988 of its weight on thrust (the tilted rotor
    drag lifts the rest), so its rotors turn slower than at hover and drag 0.6 % less per m/s;
    with mu scaled by sqrt(-f_bz / g) the drag-aided velocity errs by half as much
    (measured 0.031 -> 0.015 m/s RMS, 50-80 s into the outage)."""
    hover = _velocity_error(tmp_path, "hover", "vehicles.q0.navigation.params.drag_aiding={}")
    scaled = _velocity_error(tmp_path, "scaled", "vehicles.q0.navigation.params.drag_aiding={thrust_scaled: true}")
    assert np.sqrt(np.mean(scaled**2)) < 0.75 * np.sqrt(np.mean(hover**2))


def test_momentum_drag_coefficient_from_the_sidecar():
    from testbench.dynamics.catalog import aircraft_meta

    assert momentum_drag_per_s(aircraft_meta("tb_quad"), "test") == pytest.approx(0.365, abs=0.001)


def test_drag_aiding_on_an_aircraft_without_rotor_drag_is_bad_input(tmp_path, capsys):
    path = tmp_path / "fw.yaml"
    text = SCENARIO.replace("AIRCRAFT", "tb_fixedwing").replace("imu_preset: paper}", "imu_preset: paper, drag_aiding: {}}")
    path.write_text(text)
    assert main(["run", str(path), "--out", str(tmp_path / "o"), "--no-report", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "drag_aiding" in err and "rotor drag" in err


# ---- the drag scale state (error_model dsd): the slow part of mu's error ------------------------

def _level_ekf(scale_sigma: float):
    """EKF flying north at 4 m/s, level, its nominal at the truth; P0 from small sigmas."""
    from testbench.navigation.ins.ekf import ErrorStateEKF
    from testbench.navigation.ins.error_model import IA, IBA, IBG, IDS, IP, IV, N_NO_WIND
    from testbench.navigation.ins.imu_noise import imu_noise_from_datasheet

    ekf = ErrorStateEKF(imu_noise_from_datasheet(0.15, 7.0, 0.02, 14.0), drag_scale_sigma=scale_sigma,
                        drag_scale_tau_s=60.0)
    d = np.zeros(N_NO_WIND)
    d[IP], d[IV], d[IA] = 1.0, 0.3, 1e-3
    d[IBG], d[IBA] = 1e-5, 1.4e-4
    d[IDS] = scale_sigma
    ekf.initialize(0.0, 0.82, -1.73, 600.0, [4.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], np.diag(d**2 + 1e-30))
    return ekf, IV, IDS


def _fuse_drag(ekf, true_scale: float, n: int, gnss_velocity: bool) -> None:
    from testbench.navigation.ins import measurements as meas

    mu = 0.365
    v_b = np.array([4.0, 0.0])  # level, nose north: body x = north
    for _ in range(n):
        y, H, R = meas.drag_specific_force(ekf, -mu * (1.0 + true_scale) * v_b, v_b, mu, 0.05)
        ekf.update("drag", 0.0, y, H, R)
        if gnss_velocity:
            ekf.update("gnss_vel", 0.0, *meas.gnss_velocity(ekf, [4.0, 0.0, 0.0], [0.02] * 3))


def test_drag_scale_is_learnt_while_the_velocity_is_known():
    """mu read 0.8 % low: with GNSS velocity the filter puts the difference in the scale (not in
    the velocity or the accelerometer bias) and brings its sigma down from 1 %."""
    ekf, IV, IDS = _level_ekf(0.01)
    _fuse_drag(ekf, 0.008, 150, gnss_velocity=True)
    sigma = float(np.sqrt(ekf.P[IDS, IDS]))
    assert ekf.drag_scale == pytest.approx(0.008, abs=3 * sigma)
    assert sigma < 0.004  # 0.0027
    assert abs(ekf.ins.vel[0] - 4.0) < 0.01


def test_drag_aided_velocity_claims_no_better_than_the_scale_allows():
    """Without GNSS the drag aiding cannot tell speed from scale: the along-track velocity sigma
    stays near sigma_s |v| (0.04 m/s at 1 %, 4 m/s) however many samples are fused; with the
    scale taken as exact the same samples claim millimetres per second."""
    with_scale, IV, _ = _level_ekf(0.01)
    _fuse_drag(with_scale, 0.0, 300, gnss_velocity=False)
    exact, _, _ = _level_ekf(0.0)
    _fuse_drag(exact, 0.0, 300, gnss_velocity=False)
    s_with = float(np.sqrt(with_scale.P[IV.start, IV.start]))
    s_exact = float(np.sqrt(exact.P[IV.start, IV.start]))
    assert 0.025 < s_with < 0.045
    assert s_exact < 0.012  # 0.008 (with the scale: 0.040)
