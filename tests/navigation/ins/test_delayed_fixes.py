"""Position fixes that reach the ins_ekf navigator late (a scene matcher's processing time):
replay gives the estimate a fix without delay gives, carry comes close, and a fix fused as a
measurement of now (as_current) is the along-track error the delay makes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ins_sim import turning_flight

from testbench.core import geodesy
from testbench.core.interfaces import BuildContext, GeodeticOrigin
from testbench.core.messages import ImuSample, NavEstimate, PositionFix
from testbench.core.registry import build

LAT0, LON0, H0 = math.radians(47.0), math.radians(-97.0), 800.0
ORIGIN = GeodeticOrigin(LAT0, LON0, 300.0)
DT_S = 0.01
SPEED_MPS = 25.0
FIX_COV = np.diag([0.25, 0.25, 0.25])


def _navigator(mode: str):
    ctx = BuildContext("uav0", ("uav0",), ORIGIN, epoch_utc_year=2025.5)
    params = dict(use_baro=False, use_mag=False, delayed_fixes=mode,
                  initial_sigma=dict(pos_m=3.0, vel_mps=0.3, tilt_deg=0.5, heading_deg=2.0))
    return build("navigator", "ins_ekf", params, "vehicles.uav0.navigation", ctx=ctx)


def _flight(n_steps=600):
    """A 6 s flight north at 25 m/s with a turn in its middle: truth per step, clean IMU."""
    return turning_flight(LAT0, LON0, H0, SPEED_MPS, DT_S, n_steps, turn_rate_rps=0.1, turn_window=(0.3, 0.7))


def _true_ned(state) -> np.ndarray:
    lat, lon, h, _, _ = state
    return np.asarray(geodesy.geodetic_to_ned(lat, lon, h, ORIGIN.lat_rad, ORIGIN.lon_rad, ORIGIN.alt_m), float)


def _start(nav, states, offset_ned_m=(2.0, -1.5, 0.5)):
    """The navigator initialised 2.5 m off the truth (so a fix has something to correct)."""
    _, _, _, v, q = states[0]
    nan = np.full((3, 3), np.nan)
    pos = _true_ned(states[0]) + np.asarray(offset_ned_m)
    nav.initialize(0.0, NavEstimate(0.0, pos, np.asarray(v, float), np.asarray(q, float), np.zeros(3), np.zeros(3),
                                    nan, nan, nan))


def _fix(states, k, source="ismn", error_ned_m=(0.3, -0.2, 0.1)):
    return PositionFix(k * DT_S, _true_ned(states[k]) + np.asarray(error_ned_m), FIX_COV, 0.9, source=source)


def _fly(nav, states, ws, fs, captures, arrivals, extra=()):
    """Step the IMU through the flight. captures {step: fix}: at that step the fix is taken
    (nav.expect when it comes later); arrivals {step: [fix, ...]}: when each reaches nav.
    extra {step: fix}: fixes of other sources fused at once. Returns the fixes' infos by
    capture time."""
    infos = {}
    for k in range(len(ws)):
        nav.predict(ImuSample((k + 1) * DT_S, ws[k], fs[k]))
        step = k + 1
        if step in captures and captures[step] not in arrivals.get(step, []):
            nav.expect(captures[step].t_s)
        if step in dict(extra):
            nav.correct(dict(extra)[step])
        for fix in arrivals.get(step, []):
            infos[round(fix.t_s, 6)] = nav.correct(fix)
    return infos


def _state(nav) -> np.ndarray:
    e = nav.estimate()
    return np.concatenate([e.pos_ned_m, e.vel_ned_mps, e.q_nb_wxyz, np.ravel(nav.covariance())])


@pytest.mark.parametrize("latencies", [(60, 60), (20, 150), (150, 20)],
                         ids=["in-order", "two-in-flight-in-order", "the-later-one-first"])
def test_replay_gives_the_estimate_of_fixes_without_delay(latencies):
    """Two fixes (steps 200 and 300) whose processing takes the given steps; a third source's
    fix comes at once at step 320, between captures and arrivals. Replayed, the navigator ends
    exactly where the same fixes fused at their capture give, whatever the order they come in."""
    states, ws, fs = _flight()
    f1, f2 = _fix(states, 200), _fix(states, 300, error_ned_m=(-0.2, 0.4, 0.0))
    other = {320: _fix(states, 320, source="tan", error_ned_m=(0.1, 0.1, 0.1))}
    now = _navigator("replay")
    _start(now, states)
    at_once = _fly(now, states, ws, fs, {200: f1, 300: f2}, {200: [f1], 300: [f2]}, other.items())
    late = _navigator("replay")
    _start(late, states)
    arrivals = {}
    for cap, fix, lat in ((200, f1, latencies[0]), (300, f2, latencies[1])):
        arrivals.setdefault(cap + lat, []).append(fix)
    delayed = _fly(late, states, ws, fs, {200: f1, 300: f2}, arrivals, other.items())
    np.testing.assert_allclose(_state(late), _state(now), rtol=0, atol=1e-9)
    for t in at_once:
        assert delayed[t].accepted and at_once[t].accepted
    # The first fix's verdict is the one it had at once. The second's too, unless it came
    # first: then it was tested without the first, which the replay fuses before it later.
    t1, t2 = sorted(at_once)
    assert delayed[t1].nis == pytest.approx(at_once[t1].nis, rel=1e-9)
    assert (delayed[t2].nis == pytest.approx(at_once[t2].nis, rel=1e-9)) == (latencies[1] + 100 > latencies[0])


def test_a_late_fix_fused_as_current_is_an_along_track_error_and_carry_mends_it():
    """A fix 0.6 s late at 25 m/s is 15 m behind the vehicle. Fused as a measurement of now,
    its NIS is far beyond the gate's; carried on the filter's motion it is fused with the
    innovation it had when taken, and the estimate ends within centimetres of the replay's."""
    states, ws, fs = _flight()
    fix = _fix(states, 200)
    runs = {}
    for mode in ("replay", "carry", "as_current"):
        nav = _navigator(mode)
        _start(nav, states)
        info = _fly(nav, states, ws, fs, {200: fix}, {260: [fix]})[round(fix.t_s, 6)]
        err = float(np.hypot(*(nav.estimate().pos_ned_m - _true_ned(states[-1]))[:2]))
        runs[mode] = (info, err)
    (replay, e_replay), (carry, e_carry), (naive, _) = runs["replay"], runs["carry"], runs["as_current"]
    assert replay.accepted and carry.accepted
    assert naive.nis > 20.0 * replay.nis and not naive.accepted  # 15 m against a ~3 m claim
    assert float(np.linalg.norm(naive.innovation[:2])) > 12.0
    assert carry.nis == pytest.approx(replay.nis, rel=0.2)
    assert e_replay < 0.8 and abs(e_carry - e_replay) < 0.1


def test_a_late_fix_without_notice_is_fused_as_current():
    """A navigator that was not told a fix is coming (no expect) cannot replay it: it fuses it
    as a measurement of now, as as_current does."""
    states, ws, fs = _flight()
    fix = _fix(states, 200)
    results = []
    for mode, captures in (("replay", {}), ("as_current", {200: fix})):
        nav = _navigator(mode)
        _start(nav, states)
        results.append(_fly(nav, states, ws, fs, captures, {260: [fix]})[round(fix.t_s, 6)])
    assert results[0].nis == pytest.approx(results[1].nis, rel=1e-12)
