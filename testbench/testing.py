"""Conformance checks a user runs on their own component before plugging it into a scenario.

DESIGN.md, Interfaces: every swappable part has a reference implementation and a check here
that a user's class passes the way the reference does: outputs of the promised shapes and
types, covariances symmetric and positive semi-definite, the same seed giving the same output,
and the interface's own rules (a sensor asked twice for one sample time does not walk its noise
twice; a detector does not write into the frame it was given). Each check of a component takes
a factory that builds a fresh one, so that it can compare two of them fed alike (a metric, a
plain function, is passed itself), and raises ConformanceError naming the rule broken and what
was expected.

    from testbench.testing import check_sensor
    check_sensor(lambda: MyBarometer(MyBarometer.Params(), ctx=context))

Every interface of DESIGN.md has its check: check_dynamics, check_sensor, check_navigator,
check_scene_matcher, check_detector, check_controller and check_metric. The project's own tests
run each on the reference implementations and on a broken component of each kind
(tests/test_conformance.py).
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable, Sequence

import numpy as np

from testbench.core.interfaces import Controller, Detector, Navigator, SceneMatcher, Sensor
from testbench.core.messages import NavEstimate, TruthState

# Each check imports the parts of the package it needs when it runs (fakes, detection types,
# scoring), so that importing this module to check one sensor loads no matcher or scorer.


class ConformanceError(AssertionError):
    """A component breaks a rule of its interface (the message names the rule)."""


def check_sensor(make: Callable[[], Sensor], truths: Sequence[TruthState] | None = None, world: Any = None,
                 seed: int = 0) -> None:
    """A Sensor: rate_hz > 0 (its name is the scenario's, set when a vehicle is assembled);
    the same truths and seed give the same measurements; asking again for one sample time
    returns that sample and does not walk the noise (the next sample is as if it had been
    asked once). truths: samples at the sensor's rate (default: a
    vehicle at rest 100 m up, 2 s); world: its WorldView (default: an empty FakeWorld)."""
    from testbench.sensors.fakes import FakeWorld, make_truth

    a, b = make(), make()
    if not (np.isfinite(a.rate_hz) and a.rate_hz > 0):
        raise ConformanceError(f"sensor rate_hz must be a positive number of samples per second, got {a.rate_hz!r}")
    if truths is None:
        truths = [make_truth(k / a.rate_hz, pos_ned_m=(0.0, 0.0, -100.0)) for k in range(int(2 * a.rate_hz) + 1)]

    def view(t: TruthState) -> Any:
        return world if world is not None else FakeWorld(t.t_s)

    rng_a, rng_b = np.random.default_rng(seed), np.random.default_rng(seed)
    for i, t in enumerate(truths):
        m_a = a.measure(t, view(t), rng_a)
        again = a.measure(t, view(t), rng_a)
        if not _same(m_a, again):
            raise ConformanceError(f"sensor asked twice at t={t.t_s} s gave two different measurements; expected the "
                                   "cached sample (noise state evolves once per sample time)")
        m_b = b.measure(t, view(t), rng_b)
        if not _same(m_a, m_b):
            raise ConformanceError(f"sample {i} (t={t.t_s} s): two sensors asked once / twice per sample time with the "
                                   "same seed differ; expected the second ask to change nothing")


def check_navigator(make: Callable[[], Navigator], initial: NavEstimate, imu_samples: Sequence[Any],
                    corrections: Sequence[Any] = ()) -> None:
    """A Navigator: after initialize(initial), every predict(imu) and correct(m) leaves an
    estimate with finite state, a unit attitude quaternion, and symmetric positive
    semi-definite covariances, its time never going back; two navigators fed alike give the
    same estimates. corrections: aiding measurements, each used after the IMU sample of its
    time."""
    a, b = make(), make()
    for nav in (a, b):
        nav.initialize(initial.t_s, initial)
    events = sorted([(float(m.t_s), 0, m) for m in imu_samples] + [(float(m.t_s), 1, m) for m in corrections],
                    key=lambda e: (e[0], e[1]))
    last_t = initial.t_s
    for t, kind, m in events:
        for nav in (a, b):
            nav.predict(m) if kind == 0 else nav.correct(m)
        ea, eb = a.estimate(), b.estimate()
        _check_estimate(ea, f"after the {'IMU sample' if kind == 0 else type(m).__name__} at t={t} s")
        if ea.t_s < last_t - 1e-9:
            raise ConformanceError(f"estimate time went back from {last_t} s to {ea.t_s} s")
        last_t = ea.t_s
        if not _same(ea, eb):
            raise ConformanceError(f"two navigators fed the same measurements differ at t={t} s; expected the same "
                                   "estimate (determinism)")


def check_detector(make: Callable[[], Detector], images: Sequence[np.ndarray]) -> None:
    """A Detector: centre_reference "vehicle_centre" or "led_centroid"; detect(image) returns a
    list of Detection whose centres and boxes are finite, boxes ordered (u0 <= u1, v0 <= v1)
    and scores in [0, 1]; the image it was given is unchanged; the same image gives the same
    detections, from this detector and from a second one."""
    from testbench.navigation.relative.types import Detection

    a, b = make(), make()
    if a.centre_reference not in ("vehicle_centre", "led_centroid"):
        raise ConformanceError(f"detector centre_reference must be 'vehicle_centre' or 'led_centroid', "
                               f"got {a.centre_reference!r}")
    for k, image in enumerate(images):
        before = np.array(image, copy=True)
        found = a.detect(image)
        if not np.array_equal(before, image):
            raise ConformanceError(f"detector wrote into image {k}: expected the frame left as given "
                                   "(the other detectors and the recorder share it)")
        if not isinstance(found, list) or not all(isinstance(d, Detection) for d in found):
            raise ConformanceError(f"image {k}: detect must return a list of Detection, got {type(found).__name__}")
        for d in found:
            u0, v0, u1, v1 = d.bbox_px
            if not (np.all(np.isfinite(d.bbox_px)) and np.all(np.isfinite(d.centre_px))):
                raise ConformanceError(f"image {k}: detection with a non-finite box or centre: {d}")
            if u0 > u1 or v0 > v1:
                raise ConformanceError(f"image {k}: box {d.bbox_px} not ordered (expected u0 <= u1, v0 <= v1)")
            if not 0.0 <= d.score <= 1.0:
                raise ConformanceError(f"image {k}: score {d.score} outside [0, 1]")
        if not _same(found, a.detect(image)) or not _same(found, b.detect(image)):
            raise ConformanceError(f"image {k}: the same image gave different detections (expected determinism)")


def check_controller(make: Callable[[], Controller], estimates: Sequence[NavEstimate],
                     reference: Any = None) -> None:
    """A Controller: update(t, estimate) returns a command (not None) whose numbers are
    finite; status() is None or a GuidanceStatus; it does not change the estimate it was
    given; two controllers fed alike command alike."""
    from testbench.core.messages import GuidanceStatus

    a, b = make(), make()
    for est in estimates:
        arrays = {f.name: np.array(getattr(est, f.name), copy=True) for f in dataclasses.fields(est)
                  if isinstance(getattr(est, f.name), np.ndarray)}
        ca = a.update(est.t_s, est, reference)
        cb = b.update(est.t_s, est, reference)
        if ca is None:
            raise ConformanceError(f"update at t={est.t_s} s returned None; expected a command")
        if not all(np.array_equal(arrays[k], getattr(est, k)) for k in arrays):
            raise ConformanceError(f"update at t={est.t_s} s changed the estimate it was given")
        values = np.asarray(_numbers(ca), float)
        if values.size and not np.all(np.isfinite(values)):
            raise ConformanceError(f"command at t={est.t_s} s has non-finite values: {ca}")
        if not _same(ca, cb):
            raise ConformanceError(f"two controllers fed the same estimates commanded differently at t={est.t_s} s")
        status = a.status()
        if status is not None and not isinstance(status, GuidanceStatus):
            raise ConformanceError(f"status() must be None or a GuidanceStatus, got {type(status).__name__}")


def check_scene_matcher(make: Callable[[], SceneMatcher], ortho: np.ndarray, map_window: np.ndarray, prior: Any,
                        expected_offset_px: Sequence[float] | None = None, tolerance_px: float = 1.0) -> None:
    """A SceneMatcher: match(ortho, map_window, prior) returns None or a MatchResult whose
    offset_px is 2 finite numbers, quality in [0, 1], cov_px2 a finite symmetric positive
    definite (2, 2) matrix, and correspondences both None or both (N, 2) finite arrays of one
    length; the inputs are unchanged; the same inputs give the same result, from this matcher
    and from a second one. ortho (H, W) uint8 grey (a matcher with accepts_ortho_frame gets
    it as an OrthoFrame made from the array, as the pipeline gives one); prior: a
    navigation.ismn.types.MatchPrior. expected_offset_px: where the ortho frame truly lies
    against prior.origin_px (d_col, d_row), when the caller made the pair so: the result must
    then exist and lie within tolerance_px of it."""
    from testbench.navigation.ismn.types import MatchResult, OrthoFrame

    a, b = make(), make()
    ortho = np.asarray(ortho)
    keep = (ortho.copy(), np.array(map_window, copy=True))

    def frame() -> Any:
        if not getattr(a, "accepts_ortho_frame", False):
            return ortho
        valid = prior.ortho_valid if prior.ortho_valid is not None else np.ones(ortho.shape, bool)
        return OrthoFrame(ortho.shape, 0.0, 0.0, float(prior.gsd_m), tuple(int(round(x)) for x in prior.origin_px),
                          np.eye(3), image=ortho, valid=valid)

    res = a.match(frame(), map_window, prior)
    if not (np.array_equal(keep[0], ortho) and np.array_equal(keep[1], map_window)):
        raise ConformanceError("matcher wrote into the ortho frame or the map window: expected them left as given "
                               "(the pipeline caches and reuses both)")
    if res is None:
        if expected_offset_px is not None:
            raise ConformanceError(f"no match, where the ortho frame lies at offset {tuple(expected_offset_px)} px")
    else:
        if not isinstance(res, MatchResult):
            raise ConformanceError(f"match must return a MatchResult or None, got {type(res).__name__}")
        off = np.asarray(res.offset_px, float)
        if off.shape != (2,) or not np.all(np.isfinite(off)):
            raise ConformanceError(f"offset_px must be 2 finite numbers (d_col, d_row), got {res.offset_px}")
        if not 0.0 <= float(res.quality) <= 1.0:
            raise ConformanceError(f"quality {res.quality} outside [0, 1]")
        C = np.asarray(res.cov_px2, float)
        if C.shape != (2, 2) or not np.all(np.isfinite(C)) or not np.allclose(C, C.T) or np.linalg.eigvalsh(C).min() <= 0:
            raise ConformanceError(f"cov_px2 must be a finite symmetric positive definite (2, 2) matrix, got {C}")
        if (res.ortho_px is None) != (res.map_px is None):
            raise ConformanceError("ortho_px and map_px must both be correspondences or both None")
        if res.ortho_px is not None:
            o, m = np.asarray(res.ortho_px, float), np.asarray(res.map_px, float)
            if o.ndim != 2 or o.shape[1] != 2 or o.shape != m.shape or not (np.all(np.isfinite(o)) and np.all(np.isfinite(m))):
                raise ConformanceError(f"correspondences must be two finite (N, 2) arrays of one N, got {o.shape} and {m.shape}")
        if expected_offset_px is not None:
            miss = float(np.hypot(*(off - np.asarray(expected_offset_px, float))))
            if miss > tolerance_px:
                raise ConformanceError(f"offset {tuple(off)} px is {miss:.2f} px from the true {tuple(expected_offset_px)} "
                                       f"(expected within {tolerance_px} px)")
    if not _same(res, a.match(frame(), map_window, prior)) or not _same(res, b.match(frame(), map_window, prior)):
        raise ConformanceError("the same frame, map window and prior gave different matches (expected determinism)")


def check_metric(fn: Callable[[Any], Any], record: Any) -> None:
    """A Metric: fn(record) returns a (nested) dict of numbers, as scoring.run_metric accepts
    it; it leaves the record's telemetry and event tables as they were; called twice it gives
    the same figures (a pure function of the record). record: a scoring RunRecord (e.g.
    scoring.load_run(DIR) of a run, or of scoring.synthetic.make_synthetic_run)."""
    from testbench.core.errors import InputError
    from testbench.scoring.registry import run_metric

    tables = {"telemetry": record.telemetry.copy(deep=True)}
    events = getattr(record, "events", None) or {}
    tables.update({f"events/{k}": v.copy(deep=True) for k, v in events.items() if v is not None})
    try:
        first = run_metric("metric", fn, record)
    except InputError as exc:
        raise ConformanceError(f"{exc} (expected a dict of floats, nested dicts allowed)") from None
    if not record.telemetry.equals(tables["telemetry"]) or any(
            not events[k[len("events/"):]].equals(v) for k, v in tables.items() if k.startswith("events/")):
        raise ConformanceError("metric changed the run record it was given; expected a pure function of the record")
    if not _same(first, run_metric("metric", fn, record)):
        raise ConformanceError("metric gave different figures for the same record (expected a pure function)")


def check_dynamics(make: Callable[[], Any], initial: Any, commands: Sequence[Any], dt_s: float) -> None:
    """A Dynamics: reset(initial) gives a TruthState at t = 0; each step(command, dt_s) gives
    one dt_s later, every field finite and the attitude quaternion a unit one; two models reset
    and commanded alike give the same truths (the flight dynamics are deterministic)."""
    a, b = make(), make()
    ta, tb = a.reset(initial), b.reset(initial)
    for k, cmd in enumerate([None, *commands]):
        if k:
            ta, tb = a.step(cmd, dt_s), b.step(cmd, dt_s)
        if not isinstance(ta, TruthState):
            raise ConformanceError(f"{'reset' if k == 0 else 'step'} must return a TruthState, got {type(ta).__name__}")
        if abs(ta.t_s - k * dt_s) > 1e-6 * max(1.0, k * dt_s):
            raise ConformanceError(f"after {k} steps of {dt_s} s the truth is at t={ta.t_s} s, expected {k * dt_s} s")
        for name in ("pos_ned_m", "vel_ned_mps", "rpy_rad", "omega_eb_b_rps", "omega_ib_b_rps", "f_b_mps2", "wind_ned_mps"):
            v = np.asarray(getattr(ta, name), float)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise ConformanceError(f"t={ta.t_s} s: {name} must be 3 finite numbers, got {v}")
        scalars = (ta.lat_rad, ta.lon_rad, ta.alt_m, ta.airspeed_mps, ta.height_agl_m, ta.pressure_pa, ta.temperature_k)
        if not all(np.isfinite(scalars)):
            raise ConformanceError(f"t={ta.t_s} s: non-finite position, airspeed, height or atmosphere: {scalars}")
        q = np.asarray(ta.q_nb_wxyz, float)
        if q.shape != (4,) or not abs(np.linalg.norm(q) - 1.0) < 1e-6:
            raise ConformanceError(f"t={ta.t_s} s: q_nb_wxyz must be a unit quaternion, got {q}")
        if not _same(ta, tb):
            raise ConformanceError(f"two models reset and commanded alike differ at t={ta.t_s} s (expected determinism)")


# -- helpers ----------------------------------------------------------------------------------


def _check_estimate(e: NavEstimate, where: str) -> None:
    for name in ("pos_ned_m", "vel_ned_mps", "rpy_rad", "omega_b_rps"):
        v = np.asarray(getattr(e, name), float)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ConformanceError(f"{where}: {name} must be 3 finite numbers, got {v}")
    q = np.asarray(e.q_nb_wxyz, float)
    if q.shape != (4,) or not abs(np.linalg.norm(q) - 1.0) < 1e-6:
        raise ConformanceError(f"{where}: q_nb_wxyz must be a unit quaternion (4,), got {q}")
    for name in ("cov_pos_ned_m2", "cov_vel_ned_m2s2", "cov_att_rad2"):
        P = np.asarray(getattr(e, name), float)
        if P.shape != (3, 3) or not np.all(np.isfinite(P)):
            raise ConformanceError(f"{where}: {name} must be a finite (3, 3) matrix, got shape {P.shape}")
        if not np.allclose(P, P.T, rtol=1e-9, atol=1e-12 * max(1.0, float(np.abs(P).max()))):
            raise ConformanceError(f"{where}: {name} is not symmetric")
        if np.linalg.eigvalsh(0.5 * (P + P.T)).min() < -1e-9 * max(1.0, float(np.abs(P).max())):
            raise ConformanceError(f"{where}: {name} is not positive semi-definite (eigenvalues "
                                   f"{np.linalg.eigvalsh(0.5 * (P + P.T))})")


def _numbers(x: Any) -> list[float]:
    """Every number inside a command (dataclass fields, tuples, arrays), flattened."""
    if dataclasses.is_dataclass(x):
        return [v for f in dataclasses.fields(x) for v in _numbers(getattr(x, f.name))]
    if isinstance(x, (list, tuple)):
        return [v for item in x for v in _numbers(item)]
    if isinstance(x, np.ndarray):
        return [float(v) for v in x.ravel()] if x.dtype.kind in "fiu" else []
    if isinstance(x, (bool, np.bool_)):
        return []
    if isinstance(x, (int, float, np.integer, np.floating)):
        return [float(x)]
    return []


def _same(x: Any, y: Any) -> bool:
    """Deep equality of measurements, estimates and commands (arrays exactly, nan equal nan)."""
    if type(x) is not type(y):
        return False
    if dataclasses.is_dataclass(x):
        return all(_same(getattr(x, f.name), getattr(y, f.name)) for f in dataclasses.fields(x))
    if isinstance(x, (list, tuple)):
        return len(x) == len(y) and all(_same(p, q) for p, q in zip(x, y))
    if isinstance(x, dict):
        return x.keys() == y.keys() and all(_same(x[k], y[k]) for k in x)
    if isinstance(x, np.ndarray):
        return x.shape == y.shape and bool(np.array_equal(x, y, equal_nan=x.dtype.kind in "fc"))
    if isinstance(x, float):
        return x == y or (np.isnan(x) and np.isnan(y))
    return bool(x == y)
