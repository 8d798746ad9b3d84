"""Airspeed aiding (navigator airspeed_aiding): true airspeed and zero sideslip against the
velocity through the air, v - w, with the horizontal wind w as two filter states.

The wind is learnt while GNSS gives the velocity (a unit test with a crosswind, since the
simulated air is calm); on the JSBSim fixed wing without GNSS the aided INS holds its velocity
and position far better than the free-inertial one, through a turn.
"""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pyarrow.parquet as pq
import pytest

from testbench.cli import main
from testbench.core.rotations import euler_to_quat
from testbench.navigation.ins import measurements as meas
from testbench.navigation.ins.ekf import ErrorStateEKF
from testbench.navigation.ins.error_model import IA, IBA, IBG, IP, IV, IW, N_STATES
from testbench.navigation.ins.imu_noise import imu_noise_from_datasheet


def _crabbing_ekf():
    """EKF of a wing flying north at 22 m/s over the ground in a wind of (3, -2) m/s: through
    the air it flies (19, 2, 0) m/s, nose 6 deg right of north (zero sideslip). The nominal
    state is the truth but for the wind, which starts at 0 with a 3 m/s sigma."""
    ekf = ErrorStateEKF(imu_noise_from_datasheet(0.15, 7.0, 0.02, 14.0), wind_states=True, wind_rw_mps_sqrt_s=0.05)
    d = np.zeros(N_STATES)
    d[IP], d[IV], d[IA] = 1.0, 0.3, 1e-3
    d[IBG], d[IBA] = 1e-5, 1.4e-4
    d[IW] = 3.0
    yaw = math.atan2(2.0, 19.0)
    ekf.initialize(0.0, 0.82, -1.73, 600.0, [22.0, 0.0, 0.0], euler_to_quat(np.array([0.0, 0.0, yaw])),
                   np.diag(d**2 + 1e-30))
    return ekf, math.hypot(19.0, 2.0)


def test_wind_is_learnt_from_gnss_velocity_and_airspeed():
    ekf, tas = _crabbing_ekf()
    for _ in range(50):
        ekf.update("gnss_vel", 0.0, *meas.gnss_velocity(ekf, [22.0, 0.0, 0.0], [0.05] * 3))
        y, H, R = meas.true_airspeed(ekf, tas, 0.2)
        yb, Hb, Rb = meas.zero_sideslip(ekf, math.radians(0.5))
        ekf.update("airspeed", 0.0, np.r_[y, yb], np.vstack([H, Hb]), np.diag([R[0, 0], Rb[0, 0]]))
    sigma = np.sqrt(np.diag(ekf.P)[IW])
    np.testing.assert_allclose(ekf.wind_ne_mps, [3.0, -2.0], atol=0.05)
    assert np.all(sigma < 0.05)
    # The crab angle: the air velocity the filter now holds points along the nose.
    assert abs(meas.zero_sideslip(ekf, 0.01)[0][0]) < 0.02


def test_airspeed_alone_cannot_tell_the_crosswind():
    """Without the sideslip measurement the speed through the air fixes only the wind along
    it: the crosswind stays as uncertain as it started, whatever is fused."""
    ekf, tas = _crabbing_ekf()
    for _ in range(50):
        ekf.update("gnss_vel", 0.0, *meas.gnss_velocity(ekf, [22.0, 0.0, 0.0], [0.05] * 3))
        ekf.update("airspeed", 0.0, *meas.true_airspeed(ekf, tas, 0.2))
    # Along the air velocity (nearly north) learnt; across it (nearly east) not.
    assert np.sqrt(ekf.P[IW, IW][0, 0]) < 0.1
    assert np.sqrt(ekf.P[IW, IW][1, 1]) > 2.0


pytest.importorskip("jsbsim")

SCENARIO = textwrap.dedent("""\
    name: airspeed_aiding_check
    seed: 2
    duration_s: 110
    physics_rate_hz: 200
    record_rate_hz: 10
    world:
      origin: {lat_deg: 47.0, lon_deg: -99.0, alt_m: 500.0}
    vehicles:
      - id: w0
        aircraft: tb_fixedwing
        initial: {north_m: -1000.0, east_m: 0.0, altitude_m: 300.0, heading_deg: 0.0, airspeed_mps: 22.0}
        mission:
          type: racetrack
          params: {center: {north_m: 0.0, east_m: 560.0}, leg_length_m: 1400.0, heading_deg: 0.0,
                   direction: cw, turn_bank_deg: 5.0, altitude_agl_m: 300.0, airspeed_mps: 22.0}
        sensors:
          - {type: imu, params: {preset: paper, rate_hz: 100}}
          - {type: barometer, params: {rate_hz: 20}}
          - {type: magnetometer, params: {rate_hz: 20}}
          - {type: airspeed, params: {rate_hz: 20}}
          - {type: gnss, params: {rate_hz: 5, denial: [{type: jamming, start_s: 20.0}]}}
        navigation: {type: ins_ekf, params: {imu_preset: paper}}
        control: {type: fixed_wing, params: {max_bank_deg: 30.0}}
        rates: {control_hz: 50}
    """)


def _run(tmp_path, name: str, *sets: str):
    path = tmp_path / "wing.yaml"
    path.write_text(SCENARIO)
    out = tmp_path / name
    args = ["run", str(path), "--out", str(out), "--no-report", "--quiet"]
    for s in sets:
        args += ["--set", s]
    assert main(args) == 0
    d = pq.read_table(out / "telemetry.parquet").to_pandas()
    late = d.t_s.to_numpy() > 60.0  # 40 s into the outage, through the first turn
    dv = np.hypot(d.nav_vn_mps - d.truth_vn_mps, d.nav_ve_mps - d.truth_ve_mps).to_numpy()[late]
    dp = np.hypot(d.nav_north_m - d.truth_north_m, d.nav_east_m - d.truth_east_m).to_numpy()
    steps = np.abs(np.diff(dp))[late[1:]]  # how far the estimate jumps against truth per record
    return float(np.sqrt(np.mean(dv**2))), float(dp[-1]), float(np.sqrt(np.mean(steps**2)))


def test_airspeed_aiding_holds_a_fixed_wing_without_gnss(tmp_path):
    dv_on, dp_on, step_on = _run(tmp_path, "on", "vehicles.w0.navigation.params.airspeed_aiding={}")
    dv_off, dp_off, step_off = _run(tmp_path, "off")
    assert dv_on < 0.5 * dv_off  # measured 0.20 against 0.72 m/s RMS
    assert dp_on < 0.5 * dp_off  # measured 2.5 against 18.3 m at 110 s
    assert step_on < 0.5 * step_off  # measured 0.27 against 1.37 m RMS per 0.1 s
