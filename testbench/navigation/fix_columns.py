"""The columns an aid's event row gives a position fix (events/ismn.parquet, events/tan.parquet),
so that every fix table reads alike for scoring and reports."""

from __future__ import annotations

import math

from testbench.core.messages import PositionFix

_NAN = float("nan")


def position_fix_columns(fix: PositionFix | None) -> dict[str, float]:
    """fix_{north,east,down}_m (local NED, m) and sigma_{north,east,down}_m (the square roots of
    the claim's diagonal, m) of `fix`; NaN throughout without a fix."""
    if fix is None:
        return dict(fix_north_m=_NAN, fix_east_m=_NAN, fix_down_m=_NAN, sigma_north_m=_NAN, sigma_east_m=_NAN,
                    sigma_down_m=_NAN)
    p, cov = fix.pos_ned_m, fix.cov_ned_m2
    return dict(fix_north_m=float(p[0]), fix_east_m=float(p[1]), fix_down_m=float(p[2]),
                sigma_north_m=math.sqrt(cov[0, 0]), sigma_east_m=math.sqrt(cov[1, 1]), sigma_down_m=math.sqrt(cov[2, 2]))
