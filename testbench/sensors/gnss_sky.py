"""Which GNSS satellites a receiver sees, and the geometry (DOP) of those it does.

A receiver at the foot of a building, in a street or in a canyon sees only part of the sky:
the walls hide the satellites low over them, fewer remain, their geometry weakens (the dilution
of precision grows, most across the street), and below four there is no fix at all. The GNSS
sensor (gnss.py, params `sky`) asks `SkyModel.visible` which satellites clear the elevation
mask and every obstruction of the world (world.obstacles boxes, the terrain), and scales its
errors by the DOP against the open sky's at that place and time, so that its configured sigmas
stay the open-sky figures.

The constellation is a Walker delta pattern (satellites / planes / phasing) at GPS's orbit
radius (26 559.7 km, a half sidereal day) and inclination (55 deg): the shape of the GPS
constellation's geometry, not its almanac (real satellites are not evenly spaced). The default
30 / 5 / 2, near the 31 GPS satellites in orbit, gives at 47 deg N over a sidereal day 7-11
satellites above a 10 deg mask and HDOP 0.79 / 0.99 / 1.34 (min / median / max), comparable
with GPS's open-sky geometry. Five planes, not GPS's six: the six-plane patterns of 30 either
put two satellites in one place at times (30 / 6 / 1, 30 / 6 / 5) or give a weaker geometry
(30 / 6 / 4: HDOP median 1.18, up to 2.02); 24 / 6 / 1 gives 5-8 satellites, HDOP median 1.09. Earth rotation turns the sky
over the receiver as the run goes on; `epoch_s` picks where in the sidereal day the run starts.

Not modelled: signals that reach the receiver reflected (NLOS multipath, which a real
receiver in a street tracks with metres of extra range), diffraction round edges, foliage.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from testbench.core.geodesy import OMEGA_IE_RPS, C_en, geodetic_to_ecef
from testbench.core.obstacles import segment_below_terrain

GPS_ORBIT_RADIUS_M = 26_559_700.0
GPS_PERIOD_S = 43_082.0  # half a sidereal day


@dataclass(frozen=True)
class Dop:
    """Dilution of precision of one set of satellites (dimensionless): ned (3,) per axis
    (north, east, down: sqrt of the position cofactor's diagonal), hdop, vdop, pdop."""

    ned: tuple[float, float, float]

    @property
    def hdop(self) -> float:
        return math.hypot(self.ned[0], self.ned[1])

    @property
    def vdop(self) -> float:
        return self.ned[2]

    @property
    def pdop(self) -> float:
        return math.sqrt(sum(x * x for x in self.ned))


def walker_constellation(n_sats: int, n_planes: int, phasing: int) -> tuple[np.ndarray, np.ndarray]:
    """Walker delta pattern n_sats / n_planes / phasing: (right ascension of each satellite's
    ascending node (n,), its argument of latitude at epoch (n,)), rad."""
    if n_sats % n_planes:
        raise ValueError(f"Walker pattern: {n_sats} satellites do not split into {n_planes} planes")
    per_plane = n_sats // n_planes
    k = np.arange(n_sats)
    plane, slot = k // per_plane, k % per_plane
    raan = 2.0 * math.pi * plane / n_planes
    u0 = 2.0 * math.pi * slot / per_plane + 2.0 * math.pi * phasing * plane / n_sats
    return raan, u0


def satellites_ecef_m(raan_rad: np.ndarray, u0_rad: np.ndarray, inclination_rad: float, t_s: float) -> np.ndarray:
    """(n, 3) ECEF positions (m) of circular-orbit satellites at time t_s (s from the
    constellation's epoch, when ECI and ECEF coincide)."""
    u = u0_rad + 2.0 * math.pi * t_s / GPS_PERIOD_S
    node = raan_rad - OMEGA_IE_RPS * t_s  # the node's longitude: the Earth turns under the orbit
    ci, si = math.cos(inclination_rad), math.sin(inclination_rad)
    cu, su = np.cos(u), np.sin(u)
    cn, sn = np.cos(node), np.sin(node)
    x = cn * cu - sn * su * ci
    y = sn * cu + cn * su * ci
    z = su * si
    return GPS_ORBIT_RADIUS_M * np.stack([x, y, z], axis=1)


def dop(los_ned: np.ndarray) -> Dop | None:
    """DOP of satellites along unit lines of sight los_ned (k, 3) NED from the receiver, or
    None with fewer than four or a singular geometry. Position and clock: rows [-u, 1]."""
    if len(los_ned) < 4:
        return None
    G = np.hstack([-np.asarray(los_ned, float), np.ones((len(los_ned), 1))])
    try:
        Q = np.linalg.inv(G.T @ G)
    except np.linalg.LinAlgError:
        return None
    d = np.diag(Q)
    if np.any(d[:3] <= 0) or not np.all(np.isfinite(d)):
        return None
    return Dop((float(math.sqrt(d[0])), float(math.sqrt(d[1])), float(math.sqrt(d[2]))))


class SkyModel:
    """The constellation and the rules of what a receiver sees of it.

    n_sats, n_planes, phasing: the Walker pattern; inclination_deg; mask_deg: elevation mask;
    epoch_s: constellation time at the run's t = 0; ray_m, terrain_step_m: obstructions are
    sought along each line of sight up to ray_m, the terrain sampled every terrain_step_m."""

    def __init__(self, n_sats: int = 30, n_planes: int = 5, phasing: int = 2, inclination_deg: float = 55.0,
                 mask_deg: float = 10.0, epoch_s: float = 0.0, ray_m: float = 3000.0, terrain_step_m: float = 10.0):
        self.raan, self.u0 = walker_constellation(n_sats, n_planes, phasing)
        self.inclination = math.radians(inclination_deg)
        self.sin_mask = math.sin(math.radians(mask_deg))
        self.epoch_s = float(epoch_s)
        self.ray_m = float(ray_m)
        self.terrain_step_m = float(terrain_step_m)

    def lines_of_sight(self, t_s: float, lat_rad: float, lon_rad: float, alt_m: float) -> np.ndarray:
        """(k, 3) unit NED lines of sight to the satellites above the elevation mask at t_s."""
        sats = satellites_ecef_m(self.raan, self.u0, self.inclination, self.epoch_s + t_s)
        d = sats - geodetic_to_ecef(lat_rad, lon_rad, alt_m)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        los = d @ np.asarray(C_en(lat_rad, lon_rad))  # ECEF -> NED, row by row
        return los[-los[:, 2] >= self.sin_mask]

    def visible(self, los_ned: np.ndarray, pos_ned_m, world) -> np.ndarray:
        """(k,) bool: which lines of sight los_ned (k, 3) from pos_ned_m (3,) NED m no box of
        world.obstacles and no terrain (world.terrain_height_m) cuts within ray_m."""
        p0 = np.asarray(pos_ned_m, float)
        obstacles = tuple(getattr(world, "obstacles", ()) or ())
        terrain = getattr(world, "terrain_height_m", None)
        out = np.ones(len(los_ned), bool)
        for i, u in enumerate(los_ned):
            p1 = p0 + self.ray_m * u
            if any(ob.hits_segment(p0, p1) for ob in obstacles) or (
                    terrain is not None and segment_below_terrain(p0, p1, terrain, self.terrain_step_m)):
                out[i] = False
        return out
