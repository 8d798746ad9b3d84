"""How much a scene-matching fix follows the estimate it was given (open loop, recorded frames).

A filter fuses a fix as independent of its own state, except for what the fix declares:
PositionFix.att_sensitivity_m_per_rad, M = d fix / d (prior attitude), the pose solve's own
lean on the INS attitude. Anything else the fix inherits from the prior (the ortho view is
built at the estimated pose, the tiles are matched in it) is correlation the filter cannot
know, and makes it overconfident. This tool measures it: for each chosen frame of a recorded
run it renders the camera at the true pose (as `testbench ismn replay`), hands the pipeline the
TRUE pose as the estimate with the recorded sigmas, then moves that estimate by small amounts
and takes central differences of the fix:

- tilt about north and about east, and heading: rad, the NED small-angle rotation of the prior
  attitude (R_nb -> Exp(phi) R_nb); compared with the declared M of the unmoved prior;
- north and east position: m. An ideal matcher reads the scene against the map whatever the
  prior, so d fix / d prior position is zero; a sub-pixel estimator biased towards whole
  pixels ("peak locking") makes the fix follow the prior by its bias. The ortho frame is built
  on the map's pixel grid, so a shift of a whole working pixel (gsd) changes nothing: choose
  --shift-m well under the working ground sample (default 0.3 m, a fifth of 1.5 m).

    testbench ismn sensitivity scenarios/paper_ismn_800m.yaml RUN_DIR --t0 40 --t1 50 --step 1 \
        [--tilt-mrad 1 --shift-m 0.3] [--sweep-steps 16 --sweep-m 1.5] [--pipeline '{"n_sigma": 3}']
        [--matcher '{"max_tiles": 24}'] [--frames-dir /tmp/frames]

Output (JSON): per quantity the mean and standard deviation over frames of the measured
Jacobian d fix (N, E, D, m) / d prior (tilt N, tilt E, heading: m/rad; north, east: m/m), the
mean declared M (m/rad) and the excess (measured - declared). The standard deviation holds the
matcher's re-matching noise divided by twice the step: it shrinks with larger steps, the mean
does not.

A central difference cannot tell a smooth lean on the prior from a jump: moving the prior by a
fraction of a pixel can move the grid the tiles are cut on by a whole pixel, so that other
tiles are averaged and the fix jumps (measured on paper_ismn_800m frames: up to 0.3-0.4 m for
0.1 m of prior shift; a resampled sub-pixel peak did not change it, so it is not the parabola's
peak locking). `--sweep-steps N` therefore also moves the prior along a line 20 deg east of
north over `--sweep-m` (about one working pixel) in N steps and reports, over frames, the RMS
of the fix's standard deviation along the sweep (north, east), the median of its largest jump
between neighbouring steps (horizontal), and the RMS fix error at the unmoved prior. An ideal
matcher has no spread: what the sweep shows is error that depends on where the prior places the
grid, and averages down with more tiles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from testbench.core.messages import NavEstimate
from testbench.core.rotations import dcm_to_quat, quat_to_dcm, quat_to_euler, rotvec_to_quat

#: The prior's perturbed quantities, in the order of the Jacobian's columns.
INPUTS = ("tilt_north_rad", "tilt_east_rad", "heading_rad", "north_m", "east_m")


@dataclass(frozen=True)
class FrameSensitivity:
    """One frame: t_s; jacobian (3, 5) d fix NED (m) / d INPUTS; declared (3, 3) the fix's own
    M = d fix / d prior attitude (m/rad, NED small angles) at the unmoved prior."""

    t_s: float
    jacobian: np.ndarray
    declared: np.ndarray


def _moved(est: NavEstimate, k: int, step: float) -> NavEstimate:
    """The estimate with INPUTS[k] moved by `step` (rad or m)."""
    if k < 3:
        rot = np.zeros(3)
        rot[k] = step
        R_nb = quat_to_dcm(rotvec_to_quat(rot)) @ quat_to_dcm(est.q_nb_wxyz)
        q = dcm_to_quat(R_nb)
        return replace(est, q_nb_wxyz=q, rpy_rad=quat_to_euler(q))
    pos = np.array(est.pos_ned_m, float)
    pos[k - 3] += step
    return replace(est, pos_ned_m=pos)


def frame_sensitivity(pipe, image: np.ndarray, t_s: float, estimate: NavEstimate, tilt_rad: float,
                      shift_m: float) -> FrameSensitivity | None:
    """Central differences of pipe.process's fix around `estimate` (None: some fix failed)."""
    fix0, _ = pipe.process(image, t_s, estimate)
    if fix0 is None or fix0.att_sensitivity_m_per_rad is None:
        return None
    J = np.empty((3, len(INPUTS)))
    for k in range(len(INPUTS)):
        step = tilt_rad if k < 3 else shift_m
        fixes = [pipe.process(image, t_s, _moved(estimate, k, s))[0] for s in (-step, step)]
        if fixes[0] is None or fixes[1] is None:
            return None
        J[:, k] = (fixes[1].pos_ned_m - fixes[0].pos_ned_m) / (2.0 * step)
    return FrameSensitivity(t_s, J, np.array(fix0.att_sensitivity_m_per_rad, float))


#: The sweep's direction (north, east): 20 deg east of north, so that both grid axes change phase.
SWEEP_DIRECTION_NE = (math.cos(math.radians(20.0)), math.sin(math.radians(20.0)))


@dataclass(frozen=True)
class FrameSweep:
    """One frame: t_s; fix_error_ned_m (steps, 3): fix minus truth with the prior moved by
    k * span_m / steps along SWEEP_DIRECTION_NE (k = 0 .. steps - 1; k = 0 is the unmoved prior)."""

    t_s: float
    fix_error_ned_m: np.ndarray


def frame_sweep(pipe, image: np.ndarray, t_s: float, estimate: NavEstimate, true_pos_ned_m: np.ndarray,
                span_m: float, steps: int) -> FrameSweep | None:
    """The fix's error as the prior moves over span_m in `steps` steps (None: some fix failed)."""
    truth = np.asarray(true_pos_ned_m, float)
    errors = np.empty((steps, 3))
    for k in range(steps):
        d = k * span_m / steps
        pos = np.array(estimate.pos_ned_m, float)
        pos[:2] += d * np.asarray(SWEEP_DIRECTION_NE)
        fix, _ = pipe.process(image, t_s, replace(estimate, pos_ned_m=pos))
        if fix is None:
            return None
        errors[k] = np.asarray(fix.pos_ned_m, float) - truth
    return FrameSweep(t_s, errors)


def summarise_sweeps(sweeps: list[FrameSweep], n_tried: int, span_m: float) -> dict:
    """Over frames: RMS of the per-frame SD of the fix along the sweep (N, E, m), median of the
    largest horizontal jump between neighbouring steps (m), RMS error at the unmoved prior (N, E,
    m), and the following slope: the fix's move along the sweep per metre the prior moved, the
    least-squares slope over all frames' steps (0: the fix ignores the prior; 1: it copies it;
    a filter fusing such fixes as independent counts that share of its own error twice)."""
    out: dict = dict(n_frames=n_tried, n_used=len(sweeps))
    if not sweeps:
        return out
    E = np.array([s.fix_error_ned_m for s in sweeps])  # (frames, steps, 3)
    steps = E.shape[1]
    jumps = np.linalg.norm(np.diff(E[:, :, :2], axis=1), axis=2).max(axis=1)
    along = E[:, :, :2] @ np.asarray(SWEEP_DIRECTION_NE)  # (frames, steps) m along the sweep
    d = np.arange(steps) * span_m / steps
    dc = d - d.mean()
    slopes = (along - along.mean(axis=1, keepdims=True)) @ dc / float(dc @ dc)  # (frames,)
    out.update(sd_along_sweep_ne_m=np.sqrt((E[:, :, :2].std(axis=1) ** 2).mean(axis=0)).round(3).tolist(),
               largest_jump_median_m=round(float(np.median(jumps)), 3),
               error_at_prior_rms_ne_m=np.sqrt((E[:, 0, :2] ** 2).mean(axis=0)).round(3).tolist(),
               following_slope=round(float(slopes.mean()), 3),
               following_slope_sd=round(float(slopes.std()), 3))
    return out


def summarise(frames: list[FrameSensitivity], n_tried: int) -> dict:
    """Mean and sd over frames of the measured Jacobian, the declared M and their difference."""
    out: dict = dict(n_frames=n_tried, n_used=len(frames), rows=["north_m", "east_m", "down_m"], inputs=list(INPUTS))
    if not frames:
        return out
    J = np.array([f.jacobian for f in frames])
    M = np.array([f.declared for f in frames])
    out.update(measured_mean=J.mean(0).round(3).tolist(), measured_sd=J.std(0).round(3).tolist(),
               declared_att_mean=M.mean(0).round(3).tolist(),
               excess_att_mean=(J[:, :, :3] - M).mean(0).round(3).tolist())
    return out


def run(args) -> dict:
    """`testbench ismn sensitivity`: the frames of args.run_dir between t0 and t1 every step."""
    import json

    import cv2

    from testbench.navigation.ismn.harness import build, estimate_of, frame_for, recorded_rows, truth_of

    cv2.setNumThreads(1)
    sensor, pipe, world = build(args.scenario, args.set or (), json.loads(args.pipeline or "{}"),
                                json.loads(args.matcher or "{}"))
    frames, sweeps, n = [], [], 0
    for row in recorded_rows(args.run_dir, args.t0, args.t1, args.step):
        n += 1
        truth = truth_of(row)
        # The true pose with the recorded sigmas: the differences are taken where the fix is
        # right, so that they measure the matcher, not the run's estimation error.
        est = replace(estimate_of(row), pos_ned_m=np.array(truth.pos_ned_m, float),
                      q_nb_wxyz=np.array(truth.q_nb_wxyz, float), rpy_rad=np.array(truth.rpy_rad, float))
        img = frame_for(sensor, world, row, args.frames_dir)
        fs = frame_sensitivity(pipe, img, float(row.t_s), est, args.tilt_mrad * 1e-3, args.shift_m)
        if fs is not None:
            frames.append(fs)
        if args.sweep_steps:
            sw = frame_sweep(pipe, img, float(row.t_s), est, truth.pos_ned_m, args.sweep_m, args.sweep_steps)
            if sw is not None:
                sweeps.append(sw)
    out = summarise(frames, n)
    if args.sweep_steps:
        out["sweep"] = summarise_sweeps(sweeps, n, args.sweep_m)
    return out
