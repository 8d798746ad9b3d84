"""The map error states (navigation.params.map_error): they forget the map's error over the
distance flown, never over time alone, and a fix that disagrees with a known position goes into
them, not into the position."""

from __future__ import annotations

import math

import numpy as np

from testbench.core import geodesy
from testbench.core.interfaces import GeodeticOrigin
from testbench.navigation.ins import measurements as meas
from testbench.navigation.ins.ekf import ErrorStateEKF
from testbench.navigation.ins.error_model import IP, N_NO_WIND
from testbench.navigation.ins.imu_noise import imu_noise_from_datasheet

ORIGIN = GeodeticOrigin(math.radians(47.0), math.radians(-99.0), 500.0)


def _ekf(speed_mps: float) -> ErrorStateEKF:
    ekf = ErrorStateEKF(imu_noise_from_datasheet(0.15, 7.0, 0.02, 14.0), map_error_sigma_m=2.5,
                        map_error_correlation_m=4000.0)
    P0 = np.eye(ekf.n) * 1e-4
    P0[ekf.i_map, ekf.i_map] = 0.0  # the map's error known exactly at the start
    ekf.initialize(0.0, ORIGIN.lat_rad, ORIGIN.lon_rad, 1300.0, [speed_mps, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], P0)
    return ekf


def _fly(ekf: ErrorStateEKF, seconds: float) -> None:
    """Level flight north (body axes NED) at 100 Hz: the gyros read the Earth's and the transport
    rate, the accelerometers gravity."""
    v = np.array(ekf.ins.vel)
    w = geodesy.earth_rate_ned_rps(ORIGIN.lat_rad) + geodesy.transport_rate_ned_rps(ORIGIN.lat_rad, 1300.0, v)
    f = -geodesy.gravity_ned_mps2(ORIGIN.lat_rad, 1300.0)
    for k in range(int(seconds * 100)):
        ekf.propagate((k + 1) * 0.01, tuple(w), tuple(f))
    ekf.flush()


def test_the_map_error_decorrelates_over_the_distance_flown_not_over_time():
    hovering, flying = _ekf(0.0), _ekf(25.0)
    _fly(hovering, 160.0)
    _fly(flying, 160.0)  # 4 km: one correlation distance
    var_hover = np.diag(hovering.P[hovering.i_map, hovering.i_map])
    var_fly = np.diag(flying.P[flying.i_map, flying.i_map])
    np.testing.assert_allclose(var_hover, 0.0, atol=1e-6)  # (a metre flown would give 1.6e-3)
    # x <- a x + w over 4 km: var = (1 - exp(-2)) sigma^2
    np.testing.assert_allclose(var_fly, (1.0 - math.exp(-2.0)) * 2.5**2, rtol=2e-3)


def test_a_map_fix_against_a_known_position_teaches_the_map_error():
    """Position known to a centimetre, the map error to 2.5 m: a fix 2 m north and 1 m west of
    the position moves the map error states, not the position."""
    ekf = ErrorStateEKF(imu_noise_from_datasheet(0.15, 7.0, 0.02, 14.0), map_error_sigma_m=2.5)
    P0 = np.eye(ekf.n) * 1e-4
    P0[ekf.i_map, ekf.i_map] = 2.5**2 * np.eye(2)
    ekf.initialize(0.0, ORIGIN.lat_rad, ORIGIN.lon_rad, 1300.0, [0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], P0)
    assert ekf.n == N_NO_WIND + 2
    pos = meas.nominal_pos_ned(ekf, ORIGIN) + [2.0, -1.0, 0.0]
    y, H, R = meas.position_ned(ekf, pos, np.eye(3) * 0.04, ORIGIN, from_map=True)
    info = ekf.update("position_fix:ismn", 0.0, y, H, R)
    assert info.accepted
    np.testing.assert_allclose(ekf.b_map, [2.0, -1.0], atol=0.02)
    np.testing.assert_allclose(meas.nominal_pos_ned(ekf, ORIGIN)[:2], pos[:2] - [2.0, -1.0], atol=0.02)
    assert float(np.sqrt(ekf.P[IP, IP][0, 0])) < 0.011
