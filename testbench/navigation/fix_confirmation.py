"""Confirming absolute fixes while the estimate is too uncertain for the filter's gate.

A navigator's chi-square gate tells a false fix (a match at the wrong place) by its distance
from the estimate in units of the innovation's covariance. When the estimate is uncertain by
far more than the fix claims, as after a launch without GNSS from a position known to a
kilometre, or after a long outage of the aid, the innovation covariance is the estimate's own,
and every match in the search window passes the gate: the first fix, true or false, is taken
whole, with the fix's small covariance, and a false one leaves the filter confident at the
wrong place, refusing the true fixes that follow.

The INS knows its displacement over a few seconds far better than its position: two fixes of
the same ground from frames a second apart must differ by what the INS flew between them,
within their claims. Matches at false places do not agree that way (a false peak moves with
the frame's content, not with the vehicle), true ones do. So while the estimate's horizontal
sigma exceeds `above_sigma_m`, a fix is held until `min_fixes` fixes in a row agree, each with
the one before it, through the INS's displacement; the last of them is fused, its claim widened to at least
`acquired_sigma_m` per axis: a fix made from a prior kilometres off had its ortho view and its
tiles placed on other ground than it found, and may err by several times its claim (3 km prior:
5.9 m against 1.5 m claimed), which, taken whole, leaves the filter sure of that error and
refusing the good fixes after it. The next fixes, searched about the acquired position, refine
it. Below above_sigma_m every fix passes at once, as before, and the filter's gate does the work.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import pydantic
from scipy.stats import chi2

from testbench.core.messages import NavEstimate, PositionFix
from testbench.core.registry import ParamsModel

__all__ = ["ConfirmationParams", "FixConfirmation", "horizontal_sigma_m", "widened"]


class ConfirmationParams(ParamsModel):
    """When and how fixes are confirmed by the fixes after them (FixConfirmation).

    above_sigma_m: confirmation applies while the estimate's horizontal position sigma (the
    larger axis of its north-east ellipse, m) exceeds this; at 20 m, ten times what a
    scene-matching fix claims at 800 m, the gate still refuses a false peak beyond about 75 m.
    min_fixes: fixes in a row that must agree (2: a fix and the next; 3: two agreements).
    gate_probability: the chi-square probability (3 dof) of the agreement test.
    max_gap_s: a held fix older than this no longer confirms anything (the INS's displacement
    over a long gap is itself uncertain, and the frames see other ground).
    acquired_sigma_m: the confirmed fix's claim is widened to at least this per axis (m); below
    above_sigma_m, so that the fixes after it are not held again.
    """

    above_sigma_m: float = pydantic.Field(20.0, gt=0)
    min_fixes: int = pydantic.Field(3, ge=2, le=10)
    gate_probability: float = pydantic.Field(0.999, gt=0.5, lt=1.0)
    max_gap_s: float = pydantic.Field(5.0, gt=0)
    acquired_sigma_m: float = pydantic.Field(5.0, ge=0)

    @pydantic.model_validator(mode="after")
    def _acquired_below_threshold(self) -> "ConfirmationParams":
        if self.acquired_sigma_m >= self.above_sigma_m:
            raise ValueError(f"acquired_sigma_m ({self.acquired_sigma_m:g} m) must be below above_sigma_m "
                             f"({self.above_sigma_m:g} m), or the fixes after the confirmed one are held again")
        return self


def horizontal_sigma_m(estimate: NavEstimate) -> float:
    """The estimate's horizontal position sigma (m): the square root of the larger eigenvalue
    of its north-east covariance."""
    cov = np.asarray(estimate.cov_pos_ned_m2, float)[:2, :2]
    return math.sqrt(max(float(np.linalg.eigvalsh(cov).max()), 0.0))


def widened(fix: PositionFix, sigma_m: float) -> PositionFix:
    """The fix with each axis's variance raised to at least sigma_m^2 (the same addition to
    its covariance given the attitude, which a navigator modelling the coupling fuses)."""
    cov = np.asarray(fix.cov_ned_m2, float)
    add = np.diag(np.maximum(sigma_m ** 2 - np.diag(cov), 0.0))
    given = None if fix.cov_given_att_ned_m2 is None else np.asarray(fix.cov_given_att_ned_m2, float) + add
    return dataclasses.replace(fix, cov_ned_m2=cov + add, cov_given_att_ned_m2=given)


@dataclass(frozen=True)
class _Held:
    """A fix waiting for confirmation, with the estimate's position when it was made."""

    t_s: float
    fix_pos_ned_m: np.ndarray  # (3,)
    fix_cov_ned_m2: np.ndarray  # (3, 3)
    est_pos_ned_m: np.ndarray  # (3,)


class FixConfirmation:
    """The chain of held fixes of one aid (one vehicle, one camera).

    offer(fix, estimate) -> (fix to deliver or None, reason): the fix itself while the estimate
    is good, the confirmed fix with its claim widened, or None and why it is held. The estimate
    is the one the fix was made with (the prior at the frame's time).
    """

    def __init__(self, params: ConfirmationParams):
        self.params = params
        self._gate = float(chi2.ppf(params.gate_probability, 3))
        self._chain: list[_Held] = []

    def offer(self, fix: PositionFix, estimate: NavEstimate) -> tuple[PositionFix | None, str]:
        p = self.params
        sigma_h = horizontal_sigma_m(estimate)
        if sigma_h <= p.above_sigma_m:
            self._chain.clear()
            return fix, ""
        held = _Held(float(fix.t_s), np.asarray(fix.pos_ned_m, float).copy(),
                     np.asarray(fix.cov_ned_m2, float).copy(), np.asarray(estimate.pos_ned_m, float).copy())
        last = self._chain[-1] if self._chain else None
        if last is not None and held.t_s - last.t_s > p.max_gap_s:
            self._chain.clear()
            last = None
        if last is not None:
            nis = self._disagreement(last, held, estimate)
            if nis > self._gate:
                self._chain.clear()
                why = f"disagrees with the fix of t={last.t_s:.2f} s (NIS {nis:.1f} > {self._gate:.1f})"
            else:
                why = f"agrees with the fix of t={last.t_s:.2f} s (NIS {nis:.1f})"
        else:
            why = "first of a chain"
        self._chain.append(held)
        if len(self._chain) >= p.min_fixes:
            self._chain.clear()
            return widened(fix, p.acquired_sigma_m), ""
        return None, (f"held for confirmation: horizontal sigma {sigma_h:.0f} m > {p.above_sigma_m:g} m, "
                       f"{why}, {len(self._chain)} of {p.min_fixes} in a row")

    @staticmethod
    def _disagreement(a: _Held, b: _Held, estimate: NavEstimate) -> float:
        """NIS (3 dof) of (fix b - fix a) - (estimate at b - estimate at a): the two fixes
        against the INS's displacement between them. Covariance: both fixes' claims (taken as
        independent: conservative, since they share the attitude's and the map's errors, which
        cancel in the difference) and the estimate's velocity error over the interval."""
        dt = b.t_s - a.t_s
        d = (b.fix_pos_ned_m - a.fix_pos_ned_m) - (b.est_pos_ned_m - a.est_pos_ned_m)
        s = a.fix_cov_ned_m2 + b.fix_cov_ned_m2 + dt * dt * np.asarray(estimate.cov_vel_ned_m2s2, float)
        return float(d @ np.linalg.solve(s, d))
