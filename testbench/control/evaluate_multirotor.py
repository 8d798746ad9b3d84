"""Closed-loop evaluation of the multirotor waypoint controller on JSBSim (see evaluate.py).

Waypoints at 100 m above the origin; the quad starts hovering over the origin. Scores:
- reach_m[i]: closest 3-D approach to waypoint i while it was the active one (must be <= 1 m:
  the controller only moves on inside the acceptance radius);
- overshoot_m[i]: the largest distance from the path around waypoint i (the incoming leg and the
  outgoing leg, or the point itself for the last one) from reaching i until reaching i + 1:
  how far the vehicle flew past or wide of the corner (target: <= 3 m);
- leg_cross_track_max_m: largest horizontal distance from the active leg line.
"""

from __future__ import annotations

import numpy as np

from testbench.control.evaluate import fly, make_context, make_dynamics

WAYPOINTS_NE_M = [(120.0, 0.0), (120.0, 120.0), (0.0, 160.0), (-90.0, 60.0), (-60.0, -90.0), (60.0, -110.0), (0.0, 0.0)]


def waypoint_mission(ctx, altitude_m: float = 100.0, at_end: str = "hold", points=WAYPOINTS_NE_M):
    from testbench.control.missions import WaypointMission

    p = WaypointMission.Params(points=[{"north_m": n, "east_m": e} for n, e in points], altitude_m=altitude_m,
                               acceptance_radius_m=1.0, at_end=at_end)
    return WaypointMission(p, ctx=ctx)


def multirotor_metrics(tr, waypoints: np.ndarray, start: np.ndarray) -> dict:
    idx = np.array([s.leg_index for s in tr.status])
    pos = np.array([x.pos_ned_m for x in tr.truth])
    n = len(waypoints)
    reach, overshoot = [], []
    prev = start
    for i in range(n):
        active = idx == i
        if not np.any(active):
            break
        reach.append(float(np.min(np.linalg.norm(pos[active] - waypoints[i], axis=1))))
        # From the last tick with i active (reached) to the last tick with i + 1 active.
        t_reach = np.nonzero(active)[0][-1]
        later = np.nonzero(idx == i + 1)[0]
        t_end = later[-1] if len(later) else len(idx) - 1
        seg_pts = [prev, waypoints[i]] + ([waypoints[i + 1]] if i + 1 < n else [])
        overshoot.append(float(max(_dist_to_polyline(q, seg_pts) for q in pos[t_reach:t_end + 1])))
        prev = waypoints[i]
    xt = [abs(s.cross_track_est_m) for s in tr.status if s.on_leg and np.isfinite(s.cross_track_est_m)]
    return {
        "waypoints_reached": len(reach) if tr.status[-1].on_leg is False else max(0, len(reach) - 1),
        "reach_m": [round(r, 3) for r in reach],
        "reach_max_m": max(reach),
        "overshoot_m": [round(o, 3) for o in overshoot],
        "overshoot_max_m": max(overshoot),
        "leg_cross_track_max_m": float(max(xt)) if xt else 0.0,
        "final_position_error_m": float(np.linalg.norm(pos[-1] - waypoints[-1])),
    }


def _dist_to_polyline(q: np.ndarray, pts: list) -> float:
    best = float(np.linalg.norm(q - pts[-1]))
    for a, b in zip(pts[:-1], pts[1:]):
        d = b - a
        L2 = float(d @ d)
        s = 0.0 if L2 == 0 else min(1.0, max(0.0, float((q - a) @ d) / L2))
        best = min(best, float(np.linalg.norm(q - (a + s * d))))
    return best


def evaluate_multirotor(duration_s: float = 300.0, aircraft: str = "tb_quad", control_rate_hz: float = 100.0) -> dict:
    from testbench.control.multirotor import MultirotorController
    from testbench.dynamics.jsbsim_adapter import InitialCondition

    ctx = make_context("quad0", physics_rate_hz=200.0)
    mission = waypoint_mission(ctx)
    dyn = make_dynamics(aircraft, physics_rate_hz=200.0)
    truth = dyn.reset(InitialCondition(pos_ned_m=(0.0, 0.0, -100.0), heading_rad=0.0, airspeed_mps=0.0))
    ctl = MultirotorController(MultirotorController.Params(), ctx=ctx, mission=mission, aircraft=dyn.aircraft_meta)
    tr = fly(dyn, ctl, duration_s, control_rate_hz, truth, with_airspeed=False)
    return multirotor_metrics(tr, mission.waypoints_ned_m, np.array([0.0, 0.0, -100.0]))
