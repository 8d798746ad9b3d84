"""Fixes confirmed by the fixes after them while the estimate is too uncertain for the
filter's gate (navigation/fix_confirmation.py): held until min_fixes in a row agree through
the INS's displacement, a false match breaking the chain, a long gap ending it, and every fix
passed at once once the estimate is good."""

from __future__ import annotations

import numpy as np
import pytest

from testbench.core.messages import NavEstimate, PositionFix
from testbench.navigation.fix_confirmation import ConfirmationParams, FixConfirmation, horizontal_sigma_m

V_NED_MPS = np.array([25.0, 0.0, 0.0])
EST_OFF_M = np.array([700.0, -400.0, 0.0])  # the estimate's error: far beyond any fix's claim


def estimate(t_s: float, sigma_h_m: float = 1000.0) -> NavEstimate:
    """The INS's estimate at t_s: off the truth by EST_OFF_M, but flown with the true velocity
    (its displacement over seconds is good), horizontal sigma sigma_h_m, velocity sigma 0.2 m/s."""
    pos = truth(t_s) + EST_OFF_M
    cov_pos = np.diag([sigma_h_m ** 2, (0.5 * sigma_h_m) ** 2, 4.0])
    return NavEstimate(t_s, pos, V_NED_MPS.copy(), np.array([1.0, 0, 0, 0]), np.zeros(3), np.zeros(3),
                       cov_pos, np.eye(3) * 0.04, np.eye(3) * 1e-6)


def truth(t_s: float) -> np.ndarray:
    return np.array([-1200.0, -110.0, -800.0]) + V_NED_MPS * t_s


def fix(t_s: float, offset_m=(0.0, 0.0, 0.0), noise_m=(0.0, 0.0, 0.0)) -> PositionFix:
    """A fix of the truth at t_s (1 m per axis claimed), moved by offset_m (a false match)."""
    return PositionFix(t_s, truth(t_s) + np.asarray(offset_m, float) + np.asarray(noise_m, float), np.eye(3), 0.6)


def reason(c: FixConfirmation, fix_: PositionFix, est: NavEstimate) -> str:
    """The offer's reason ("" delivered), checking that a delivered fix comes back and a held one does not."""
    out, why = c.offer(fix_, est)
    assert (out is None) == bool(why)
    return why


def test_the_horizontal_sigma_is_the_larger_axis_of_the_ellipse():
    assert horizontal_sigma_m(estimate(0.0, 1000.0)) == pytest.approx(1000.0)


def test_true_fixes_are_held_until_three_agree_and_the_third_goes_through():
    c = FixConfirmation(ConfirmationParams(min_fixes=3))
    rng = np.random.default_rng(4)
    reasons = [reason(c, fix(t, noise_m=rng.normal(0, 1.0, 3)), estimate(t)) for t in (1.0, 2.0, 3.0)]
    assert reasons[0].startswith("held for confirmation") and "first of a chain" in reasons[0]
    assert "agrees with the fix of t=1.00 s" in reasons[1] and "2 of 3" in reasons[1]
    assert reasons[2] == ""
    # The confirmed fix goes with its claim widened to acquired_sigma_m per axis, its
    # position as the matcher gave it.
    c = FixConfirmation(ConfirmationParams(min_fixes=2, acquired_sigma_m=5.0))
    c.offer(fix(1.0), estimate(1.0))
    f = fix(2.0)
    out, _ = c.offer(f, estimate(2.0))
    np.testing.assert_allclose(np.diag(out.cov_ned_m2), [25.0, 25.0, 25.0])
    np.testing.assert_array_equal(out.pos_ned_m, f.pos_ned_m)
    assert out.cov_given_att_ned_m2 is None
    # A new chain starts after a delivery: the next fix is held again while the estimate is poor.
    assert reason(c, fix(4.0), estimate(4.0)) != ""


def test_a_false_match_breaks_the_chain_and_only_agreeing_true_fixes_confirm():
    c = FixConfirmation(ConfirmationParams(min_fixes=3))
    offsets = {1.0: (0, 0, 0), 2.0: (-350.0, 1200.0, 0.0), 3.0: (0, 0, 0), 4.0: (0, 0, 0), 5.0: (0, 0, 0)}
    reasons = {t: reason(c, fix(t, off), estimate(t)) for t, off in offsets.items()}
    assert "disagrees with the fix of t=1.00 s" in reasons[2.0]
    assert "disagrees with the fix of t=2.00 s" in reasons[3.0]  # the chain restarts at the false one's successor
    assert reasons[4.0] != "" and reasons[5.0] == ""
    # Fixes that all lie 30 m off by the same error agree with each other: the test is the
    # fixes' consistency with the INS, not their truth (a match locked on a false peak that
    # moves with the vehicle passes, a false peak jumping with the frame's content does not).
    c = FixConfirmation(ConfirmationParams(min_fixes=2))
    assert reason(c, fix(1.0, (30.0, 0, 0)), estimate(1.0)) != ""
    assert reason(c, fix(2.0, (30.0, 0, 0)), estimate(2.0)) == ""


def test_a_height_error_alone_breaks_the_chain():
    # The false peaks of a wide search give a pose whose scale, and so height, is wrong too.
    c = FixConfirmation(ConfirmationParams(min_fixes=2))
    reason(c, fix(1.0), estimate(1.0))
    assert "disagrees" in reason(c, fix(2.0, (0.0, 0.0, 15.0)), estimate(2.0))


def test_a_gap_longer_than_max_gap_s_starts_a_new_chain():
    c = FixConfirmation(ConfirmationParams(min_fixes=2, max_gap_s=5.0))
    reason(c, fix(1.0), estimate(1.0))
    assert "first of a chain" in reason(c, fix(7.0), estimate(7.0))
    assert reason(c, fix(8.0), estimate(8.0)) == ""


def test_below_above_sigma_m_every_fix_goes_through_at_once():
    c = FixConfirmation(ConfirmationParams(above_sigma_m=20.0))
    f = fix(0.0)
    assert c.offer(f, estimate(0.0, sigma_h_m=5.0))[0] is f  # untouched
    assert reason(c, fix(1.0, (500.0, 0, 0)), estimate(1.0, sigma_h_m=5.0)) == ""  # the gate's business now
    reason(c, fix(2.0), estimate(2.0, sigma_h_m=1000.0))
    assert reason(c, fix(3.0), estimate(3.0, sigma_h_m=5.0)) == ""  # and a held chain is dropped
    assert "first of a chain" in reason(c, fix(4.0), estimate(4.0, sigma_h_m=1000.0))


def test_bad_params_are_refused():
    with pytest.raises(ValueError):
        ConfirmationParams(min_fixes=1)
    with pytest.raises(ValueError):
        ConfirmationParams(above_sigma_m=-1.0)
    with pytest.raises(ValueError, match="acquired_sigma_m"):
        ConfirmationParams(above_sigma_m=10.0, acquired_sigma_m=10.0)
