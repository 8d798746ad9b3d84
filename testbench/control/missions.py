"""Missions: waypoints, racetrack and orbit, given in local metres or latitude/longitude.

A point is given either as `north_m`/`east_m` (local NED at the scenario origin) or as
`lat_deg`/`lon_deg` (WGS-84; converted to local north-east with core.geodesy at the origin's
height). Altitudes are `altitude_m`: metres above the scenario origin, up positive (the
scenario origin lies on the ground). `altitude_agl_m` is accepted as a synonym meaning height
above the origin's ground, i.e. the same number on flat ground; give one or the other.

Every mission exposes
- `altitude_m` (float, above the origin) and `airspeed_mps` (float | None: None = the
  aircraft's cruise airspeed from its sidecar);
- `path(airspeed_mps) -> tuple[Segment, ...]` and `closed` for fixed-wing path following
  (racetrack and orbit radii may depend on the commanded airspeed and bank);
- `waypoints_ned_m` (N, 3) for waypoint sequencing (multirotor, fixed-wing waypoints),
  `acceptance_radius_m` and `at_end` ("loop" or "hold").

Racetrack geometry (direction cw, heading psi, centre C, leg length L, turn radius R):
t = (cos psi, sin psi), n = (-sin psi, cos psi) (right of t). Leg 0 runs along t on the left of
C (C - L/2 t - R n -> C + L/2 t - R n), arc 1 turns right about C + L/2 t through 180 deg, leg 2
runs back along -t on the right of C, arc 3 turns right about C - L/2 t. ccw mirrors n.
R defaults to V^2 / (g tan(turn_bank)) with V the commanded airspeed (coordinated level turn).
turn_bank defaults to 28 deg: 2 deg below the paper's 30 deg bank limit, so that the L1 law keeps
authority to correct on the arc (the aircraft needs about 0.6 deg more than the ideal
coordinated-turn bank); the peak bank in the turns then reaches the 30 deg limit. With
turn_bank = limit the bank saturates on the arc and the aircraft drifts ~14 m outwards.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
import pydantic

from testbench.core.errors import InputError
from testbench.core.geodesy import geodetic_to_ned
from testbench.core.interfaces import BuildContext
from testbench.core.registry import ParamsModel, register
from testbench.core.units import DEG_TO_RAD, STANDARD_GRAVITY_MPS2
from testbench.control.paths import ArcSegment, LineSegment, Segment, bearing


class PointSpec(ParamsModel):
    """A horizontal point (north_m, east_m) or (lat_deg, lon_deg), optional altitude."""

    north_m: float | None = None
    east_m: float | None = None
    lat_deg: float | None = None
    lon_deg: float | None = None
    altitude_m: float | None = None
    altitude_agl_m: float | None = None

    @pydantic.model_validator(mode="after")
    def _one_form(self) -> "PointSpec":
        local = self.north_m is not None and self.east_m is not None
        geo = self.lat_deg is not None and self.lon_deg is not None
        if local == geo:
            raise ValueError("give either north_m and east_m, or lat_deg and lon_deg")
        if self.altitude_m is not None and self.altitude_agl_m is not None:
            raise ValueError("give altitude_m or altitude_agl_m, not both")
        return self

    def ne_m(self, ctx: BuildContext) -> np.ndarray:
        """(north_m, east_m) in the local frame at ctx.origin."""
        if self.north_m is not None:
            return np.array([self.north_m, self.east_m], float)
        o = ctx.origin
        ned = geodetic_to_ned(
            self.lat_deg * DEG_TO_RAD, self.lon_deg * DEG_TO_RAD, o.alt_m, o.lat_rad, o.lon_rad, o.alt_m
        )
        return np.asarray(ned, float)[:2]

    def alt(self) -> float | None:
        return self.altitude_m if self.altitude_m is not None else self.altitude_agl_m


def _altitude(altitude_m: float | None, altitude_agl_m: float | None, where: str) -> float:
    if altitude_m is not None and altitude_agl_m is not None:
        raise InputError(f"{where}: give altitude_m or altitude_agl_m, not both")
    alt = altitude_m if altitude_m is not None else altitude_agl_m
    if alt is None:
        raise InputError(f"{where}: missing required key altitude_m (or altitude_agl_m)")
    return float(alt)


class _MissionBase:
    """Shared attributes; see the module docstring."""

    closed: bool = True
    acceptance_radius_m: float = 1.0
    at_end: str = "loop"
    altitude_m: float
    airspeed_mps: float | None
    waypoints_ned_m: np.ndarray

    def path(self, airspeed_mps: float) -> tuple[Segment, ...]:
        raise NotImplementedError


@register("mission", "racetrack")
class RacetrackMission(_MissionBase):
    """Two straight legs of leg_length_m joined by two 180-degree turns (see module docstring)."""

    class Params(ParamsModel):
        center: PointSpec
        leg_length_m: float = pydantic.Field(gt=0.0)
        turn_radius_m: float | None = pydantic.Field(default=None, gt=0.0)
        turn_bank_deg: float = pydantic.Field(default=28.0, gt=0.0, lt=80.0)
        heading_deg: float = 0.0
        direction: Literal["cw", "ccw"] = "cw"
        altitude_m: float | None = None
        altitude_agl_m: float | None = None
        airspeed_mps: float | None = pydantic.Field(default=None, gt=0.0)

    closed = True

    def __init__(self, params: "RacetrackMission.Params", *, ctx: BuildContext, **_: object):
        self.params = params
        self.center_ne_m = params.center.ne_m(ctx)
        self.altitude_m = _altitude(params.altitude_m, params.altitude_agl_m, "mission.params")
        self.airspeed_mps = params.airspeed_mps
        self.heading_rad = params.heading_deg * DEG_TO_RAD
        self.direction = 1 if params.direction == "cw" else -1
        self.waypoints_ned_m = np.zeros((0, 3))

    def turn_radius_m(self, airspeed_mps: float) -> float:
        """Turn radius (m): given, or V^2 / (g tan(turn_bank)) for a level coordinated turn."""
        if self.params.turn_radius_m is not None:
            return float(self.params.turn_radius_m)
        bank = self.params.turn_bank_deg * DEG_TO_RAD
        return airspeed_mps**2 / (STANDARD_GRAVITY_MPS2 * math.tan(bank))

    def path(self, airspeed_mps: float) -> tuple[Segment, ...]:
        """(leg 0, arc 1, leg 2, arc 3), a closed loop; legs are straight, arcs 180 deg."""
        r = self.turn_radius_m(airspeed_mps)
        half = 0.5 * self.params.leg_length_m
        c = self.center_ne_m
        t = np.array([math.cos(self.heading_rad), math.sin(self.heading_rad)])
        n = self.direction * np.array([-t[1], t[0]])  # towards the turn centres' side
        a0, a1 = c - half * t - r * n, c + half * t - r * n
        b0, b1 = c + half * t + r * n, c - half * t + r * n
        c1, c2 = c + half * t, c - half * t
        return (
            LineSegment(a0, a1),
            ArcSegment(c1, r, bearing(a1 - c1), math.pi, self.direction),
            LineSegment(b0, b1),
            ArcSegment(c2, r, bearing(b1 - c2), math.pi, self.direction),
        )


@register("mission", "orbit")
class OrbitMission(_MissionBase):
    """A circle about `center` of `radius_m` flown cw or ccw at constant altitude."""

    class Params(ParamsModel):
        center: PointSpec
        radius_m: float = pydantic.Field(gt=0.0)
        direction: Literal["cw", "ccw"] = "cw"
        altitude_m: float | None = None
        altitude_agl_m: float | None = None
        airspeed_mps: float | None = pydantic.Field(default=None, gt=0.0)

    closed = True

    def __init__(self, params: "OrbitMission.Params", *, ctx: BuildContext, **_: object):
        self.params = params
        self.center_ne_m = params.center.ne_m(ctx)
        self.altitude_m = _altitude(params.altitude_m, params.altitude_agl_m, "mission.params")
        self.airspeed_mps = params.airspeed_mps
        self.direction = 1 if params.direction == "cw" else -1
        self.waypoints_ned_m = np.zeros((0, 3))

    def path(self, airspeed_mps: float) -> tuple[Segment, ...]:
        return (ArcSegment(self.center_ne_m, float(self.params.radius_m), 0.0, 2.0 * math.pi, self.direction),)


@register("mission", "waypoints")
class WaypointMission(_MissionBase):
    """A list of points visited in order; `at_end`: "loop" back to the first or "hold" at the
    last (a multirotor hovers there; a fixed wing orbits it at `loiter_radius_m`).

    Each point may carry its own altitude; points without one use the mission's altitude.
    A point counts as reached within `acceptance_radius_m` (3-D distance).
    """

    class Params(ParamsModel):
        points: list[PointSpec] = pydantic.Field(min_length=1)
        altitude_m: float | None = None
        altitude_agl_m: float | None = None
        acceptance_radius_m: float = pydantic.Field(default=1.0, gt=0.0)
        at_end: Literal["loop", "hold"] = "hold"
        airspeed_mps: float | None = pydantic.Field(default=None, gt=0.0)
        speed_mps: float | None = pydantic.Field(default=None, gt=0.0)
        loiter_radius_m: float = pydantic.Field(default=150.0, gt=0.0)

    def __init__(self, params: "WaypointMission.Params", *, ctx: BuildContext, **_: object):
        self.params = params
        base_alt = None
        if params.altitude_m is not None or params.altitude_agl_m is not None:
            base_alt = _altitude(params.altitude_m, params.altitude_agl_m, "mission.params")
        rows = []
        for i, pt in enumerate(params.points):
            alt = pt.alt() if pt.alt() is not None else base_alt
            if alt is None:
                raise InputError(f"mission.params.points.{i}: no altitude_m and no mission altitude_m")
            ne = pt.ne_m(ctx)
            rows.append([ne[0], ne[1], -alt])
        self.waypoints_ned_m = np.array(rows, float)
        self.altitude_m = float(-self.waypoints_ned_m[0, 2])
        self.airspeed_mps = params.airspeed_mps
        self.speed_mps = params.speed_mps
        self.acceptance_radius_m = float(params.acceptance_radius_m)
        self.at_end = params.at_end
        self.closed = params.at_end == "loop"

    def path(self, airspeed_mps: float) -> tuple[Segment, ...]:
        """Lines between consecutive points (closing line when looping); with "hold" the
        path ends in a loiter circle about the last point."""
        ne = self.waypoints_ned_m[:, :2]
        segs: list[Segment] = [LineSegment(ne[i], ne[i + 1]) for i in range(len(ne) - 1)]
        if self.closed and len(ne) > 1:
            segs.append(LineSegment(ne[-1], ne[0]))
        if not self.closed or len(ne) == 1:
            r = float(self.params.loiter_radius_m)
            last = ne[-1]
            d = segs[-1].tangent_at_end() if segs else np.array([1.0, 0.0])
            centre = last + r * np.array([-d[1], d[0]])  # loiter turning right
            segs.append(ArcSegment(centre, r, bearing(last - centre), 2.0 * math.pi, 1))
        return tuple(segs)

    def segment_altitude_m(self, index: int) -> float:
        """Altitude (m above origin) commanded on path segment `index` (that of its end point)."""
        n = len(self.waypoints_ned_m)
        k = (index + 1) % n if self.closed else min(index + 1, n - 1)
        return float(-self.waypoints_ned_m[k, 2])
