"""Motor mixer (control allocation) of a multirotor from its sidecar geometry.

Each motor i at r_i = (x_i, y_i, z_i) (body FRD, m, from the CG) pushes T_i >= 0 along -z_b and
reacts a yaw torque -spin_i k_M T_i about +z_b (spin +1 = clockwise seen from above; k_M =
yaw_torque_per_thrust_m). The wrench w = (T, L, M, N) (total thrust N; roll, pitch, yaw
moments N m, FRD) is w = E t with t = (T_1..T_n) and

    E = [[1, ..., 1], [-y_i ...], [x_i ...], [-spin_i k_M ...]]

(the moment of (0, 0, -T_i) at r_i is (-y_i T_i, x_i T_i, 0)). Allocation is t = pinv(E) w;
when that asks a motor for less than 0 or more than T_max, the yaw moment is reduced first
and then the roll/pitch moments, keeping the total thrust: attitude before yaw, as in PX4.
Commands are t / T_max (the models' motor command is the normalised thrust, see
aircraft/tb_quad/tb_quad.xml).
"""

from __future__ import annotations

import numpy as np


class Mixer:
    """Thrust/moment allocation for n motors (see module docstring).

    motors: list of {position_b_m: (3,), spin: +-1}; max_thrust_n: per motor;
    yaw_torque_per_thrust_m: k_M.
    """

    def __init__(self, motors: list[dict], max_thrust_n: float, yaw_torque_per_thrust_m: float):
        pos = np.array([m["position_b_m"] for m in motors], float)
        spin = np.array([m["spin"] for m in motors], float)
        self.n = len(motors)
        self.max_thrust_n = float(max_thrust_n)
        self.effectiveness = np.vstack([np.ones(self.n), -pos[:, 1], pos[:, 0], -spin * yaw_torque_per_thrust_m])
        self.allocation = np.linalg.pinv(self.effectiveness)
        # Rows of the allocation matrix as float tuples: allocation runs every control tick on
        # 4-vectors, where numpy's per-call overhead dwarfs the arithmetic.
        self._allocation_rows = [tuple(float(a) for a in row) for row in self.allocation]

    def wrench(self, thrusts_n: np.ndarray) -> np.ndarray:
        """Forward map: motor thrusts (n,) N -> (T, L, M, N)."""
        return self.effectiveness @ np.asarray(thrusts_n, float)

    def allocate(self, thrust_n: float, moments_b_nm: np.ndarray) -> np.ndarray:
        """Motor thrusts (n,) N within [0, T_max] for the wanted thrust and moments (3,)."""
        return np.array(self.allocate_floats(thrust_n, moments_b_nm))

    def allocate_floats(self, thrust_n: float, moments_b_nm) -> list[float]:
        """allocate() as a list of floats; moments_b_nm: (L, M, N) N m, any sequence."""
        l_nm, m_nm, n_nm = (float(x) for x in moments_b_nm[:3])
        hi = self.max_thrust_n
        rows = self._allocation_rows
        base = [row[0] * thrust_n for row in rows]
        rp = [row[1] * l_nm + row[2] * m_nm for row in rows]
        yaw = [row[3] * n_nm for row in rows]
        base_rp = [b + r for b, r in zip(base, rp)]
        t = [b + y for b, y in zip(base_rp, yaw)]
        if _all_within(t, 0.0, hi):
            return t
        # Scale the yaw part, then the roll/pitch part, into the feasible box.
        k_yaw = _max_scale(base_rp, yaw, hi)
        t = [b + k_yaw * y for b, y in zip(base_rp, yaw)]
        if _all_within(t, -1e-9, hi + 1e-9):
            return [_clip(x, 0.0, hi) for x in t]
        k_rp = _max_scale(base, rp, hi)
        return [_clip(b + k_rp * r, 0.0, hi) for b, r in zip(base, rp)]

    def commands(self, thrust_n: float, moments_b_nm) -> tuple[float, ...]:
        """Normalised motor commands in [0, 1] (thrust / T_max)."""
        hi = self.max_thrust_n
        return tuple(t / hi for t in self.allocate_floats(thrust_n, moments_b_nm))


def _all_within(values: list[float], lo: float, hi: float) -> bool:
    """lo <= v <= hi for every v (False for nan)."""
    for v in values:
        if not lo <= v <= hi:
            return False
    return True


def _clip(x: float, lo: float, hi: float) -> float:
    return lo if x < lo else hi if x > hi else x


def _max_scale(base, part, hi: float) -> float:
    """Largest k in [0, 1] with 0 <= base + k part <= hi element-wise (base assumed inside)."""
    k = 1.0
    for b, p in zip(base, part):
        if p > 0 and b + p > hi:
            k = min(k, max(0.0, (hi - b) / p))
        elif p < 0 and b + p < 0:
            k = min(k, max(0.0, -b / p))
    return k
