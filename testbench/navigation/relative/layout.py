"""The formation layout as a plausibility check on where a neighbour estimate may START.

Every vehicle of a formation flight carries the mission's slot table (the same one its
formation controller flies), so it knows roughly where each neighbour should be: at
R(chi) (s_peer - s_self), slots s (forward_m, right_m, down_m) in the formation frame and chi
the formation's course. A neighbour filter started from a track under a wrong ID puts the
neighbour where another vehicle is, typically a slot or more away: in the paper's arrowhead,
uav0 started its estimate of uav5 from a track of uav3 decoded as uav5 (both 200 m from it,
mirrored about its course, so uav5's UWB range agreed) and kept it 200 m off for 4 s
(paper_swarm_relnav, 300 s, LED). The layout refuses such a start; it never touches the fusion
of a running estimate, which follows the real neighbour wherever it flies.

The course chi is this vehicle's own: by default its estimated yaw (`course_from: yaw`): a
formation follower keeps its nose on the formation course it estimates even while it slides
sideways towards its slot, when its ground course says nothing of the formation's (swarm_cnn,
uav7 at 5.7 s: ground course -52 deg at 1.05 m/s, nose 0.2 deg; taken from the velocity, the
layout turned by -52 deg let a track of uav2 decoded as uav9, both 200 m away, start uav7's
estimate of uav9 200 m off). `course_from: velocity` takes the estimated ground course above
`min_speed_mps`, else the yaw (for a fixed wing crabbing in wind). The follower's course still
differs from the formation's while it turns, so the check allows `course_allowance_deg` of
rotation (a distance-proportional margin) on top of `tolerance_m` for slot errors.
The formation's `leader` takes its ground course whatever course_from says: the formation's
course is the leader's ground track by definition, and a multirotor leader flying waypoints
keeps its nose where it was (swarm_cnn, 295 s: the leader's nose at 0.5 deg, its course 62 deg;
turned by its nose, the layout put uav1's slot where uav2 flew, the arrowhead being symmetric
under 60 deg turns, and let a track of uav2 decoded as uav1 start the leader's estimate of uav1
100 m off).
Nothing here reads another vehicle's state: the slots are mission data, the course our own.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
import pydantic

from testbench.core.registry import ParamsModel
from testbench.core.rotations import rot_z


class LayoutParams(ParamsModel):
    """slots: vehicle id -> (forward_m, right_m, down_m) in the formation frame (forward along
    the formation course); tolerance_m: how far a neighbour may be from its slot-predicted
    relative position (horizontal) and still start an estimate; course_allowance_deg: rotation
    of the layout allowed on top (margin = tolerance_m + sin(allowance) x slot distance);
    course_from: the own course the layout is turned by, "yaw" or "velocity" (module
    docstring); min_speed_mps: with "velocity", below this ground speed the yaw is taken;
    leader: the formation's leader, whose layout is turned by its ground course (as with
    "velocity") whatever course_from says (None: no such vehicle)."""

    slots: dict[str, tuple[float, float, float]]
    leader: str | None = None
    tolerance_m: float = pydantic.Field(40.0, gt=0)
    course_allowance_deg: float = pydantic.Field(10.0, ge=0, le=90)
    course_from: Literal["yaw", "velocity"] = "yaw"
    min_speed_mps: float = pydantic.Field(1.0, ge=0)


def own_course_rad(vel_ned_mps, yaw_rad: float, min_speed_mps: float) -> float:
    """Course (rad from north) from the own estimated velocity (3,) NED m/s, or yaw_rad when
    the horizontal speed is below min_speed_mps."""
    v = np.asarray(vel_ned_mps, float)
    if math.hypot(v[0], v[1]) >= min_speed_mps:
        return math.atan2(v[1], v[0])
    return float(yaw_rad)


def expected_relative_ned_m(p: LayoutParams, self_id: str, peer_id: str, course_rad: float) -> np.ndarray | None:
    """Slot-predicted position of peer relative to self (3,) NED m, or None when either has no
    slot. R(chi) maps formation (forward, right, down) to NED."""
    if self_id not in p.slots or peer_id not in p.slots:
        return None
    d = np.asarray(p.slots[peer_id], float) - np.asarray(p.slots[self_id], float)
    return rot_z(course_rad) @ d


def start_fits_layout(p: LayoutParams, self_id: str, peer_id: str, r_ned_m, vel_ned_mps, yaw_rad: float) -> bool:
    """Whether a neighbour estimate may start at relative position r_ned_m (3,) NED m: its
    horizontal distance from the slot-predicted position within tolerance_m + sin(allowance)
    x slot distance. True when the layout does not name both vehicles."""
    by_yaw = p.course_from == "yaw" and self_id != p.leader
    course = float(yaw_rad) if by_yaw else own_course_rad(vel_ned_mps, yaw_rad, p.min_speed_mps)
    exp = expected_relative_ned_m(p, self_id, peer_id, course)
    if exp is None:
        return True
    r = np.asarray(r_ned_m, float)
    miss = math.hypot(r[0] - exp[0], r[1] - exp[1])
    margin = p.tolerance_m + math.sin(math.radians(p.course_allowance_deg)) * math.hypot(exp[0], exp[1])
    return miss <= margin
