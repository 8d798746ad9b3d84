"""Synthetic truth and world views for sensor tests and benchmarks (no dynamics needed)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np

from testbench.core.geodesy import earth_rate_ned_rps, ned_to_geodetic, normal_gravity_mps2
from testbench.core.interfaces import GeodeticOrigin
from testbench.core.messages import TruthState
from testbench.core.rotations import euler_to_quat, quat_to_dcm

ORIGIN = GeodeticOrigin(np.deg2rad(45.0), np.deg2rad(7.0), 300.0)


def make_truth(
    t_s: float,
    pos_ned_m=(0.0, 0.0, 0.0),
    vel_ned_mps=(0.0, 0.0, 0.0),
    rpy_rad=(0.0, 0.0, 0.0),
    origin: GeodeticOrigin = ORIGIN,
    airspeed_mps: float = 0.0,
    omega_eb_b_rps=(0.0, 0.0, 0.0),
) -> TruthState:
    """A TruthState at rest (or moving uniformly) with consistent gravity and Earth rate.

    Specific force is -gravity rotated into body; the gyro truth adds the Earth rate.
    Pressure and temperature follow the ISA at the altitude.
    """
    pos = np.asarray(pos_ned_m, float)
    lat, lon, alt = (float(v) for v in ned_to_geodetic(pos, origin.lat_rad, origin.lon_rad, origin.alt_m))
    q = euler_to_quat(np.asarray(rpy_rad, float))
    R_bn = quat_to_dcm(q).T  # NED -> body
    g = float(normal_gravity_mps2(lat, alt))
    from testbench.sensors.barometer import isa_pressure_pa

    return TruthState(
        t_s=float(t_s), lat_rad=lat, lon_rad=lon, alt_m=alt, pos_ned_m=pos,
        vel_ned_mps=np.asarray(vel_ned_mps, float), q_nb_wxyz=q, rpy_rad=np.asarray(rpy_rad, float),
        omega_eb_b_rps=np.asarray(omega_eb_b_rps, float),
        omega_ib_b_rps=np.asarray(omega_eb_b_rps, float) + R_bn @ earth_rate_ned_rps(lat),
        f_b_mps2=R_bn @ np.array([0.0, 0.0, -g]), airspeed_mps=float(airspeed_mps), height_agl_m=alt - origin.alt_m,
        pressure_pa=float(isa_pressure_pa(alt)), temperature_k=288.15 - 0.0065 * alt, wind_ned_mps=np.zeros(3),
    )


def flat_terrain(north_m, east_m):
    return np.zeros(np.shape(north_m))


@dataclass
class FakeWorld:
    """A WorldView: other vehicles' truth, a terrain function and optional obstacles."""

    t_s: float = 0.0
    self_id: str = "uav0"
    vehicles: Mapping[str, TruthState] = field(default_factory=dict)
    origin: GeodeticOrigin = ORIGIN
    terrain: Callable[[Any, Any], Any] = flat_terrain
    obstacles: tuple = ()
    magnetic_anomaly: Callable[[TruthState], Any] | None = None  # truth -> (3,) NED tesla

    def terrain_height_m(self, north_m, east_m):
        return self.terrain(north_m, east_m)

    def magnetic_anomaly_ned_T(self, truth):
        return None if self.magnetic_anomaly is None else self.magnetic_anomaly(truth)
