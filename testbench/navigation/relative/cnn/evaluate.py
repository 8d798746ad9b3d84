"""Precision and recall of a detector by range on a freshly rendered, held-out set.

Per range bin, `frames_per_bin` ROI crops (crop_px square, default 256) each hold one vehicle
at a range inside the bin, rendered over the EVAL_WORLDS (terrain/season/seed pairs that the
training never saw) from a seed different from training; a further set of empty crops
measures false alarms. Matching criterion (3-px targets make IoU meaningless): a detection is
a true positive when its centre lies within max(3 px, 0.5 * max(box width, height)) of an
unmatched truth centre (greedy, best score first); unmatched detections are false positives,
unmatched truths misses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from testbench.navigation.relative.cnn import dataset

CRITERION = "centre within max(3 px, 0.5 * max(truth box w, h)) of the truth centre (CoG projection)"


@dataclass(frozen=True)
class EvalSettings:
    """frames_per_bin: crops per range bin; bins: (lo, hi) ranges (m), with two narrow bins
    around 100 m and 200 m added for the targets; negatives: empty crops for false alarms."""

    frames_per_bin: int = 200
    crop_px: int = 256
    bins: tuple[tuple[float, float], ...] = dataset.RANGE_BINS_M + ((90.0, 110.0), (180.0, 200.0))
    negatives: int | None = None  # default: frames_per_bin
    worlds: tuple[dataset.WorldVariant, ...] = dataset.EVAL_WORLDS


def match(dets_uv: np.ndarray, truth_uv: np.ndarray, truth_wh: np.ndarray) -> tuple[int, int, int]:
    """(true positives, false positives, misses) of detections (m, 2) (best first) against
    truths (n, 2) with box sizes (n, 2), by the module's centre-distance criterion."""
    dets_uv = np.asarray(dets_uv, float).reshape(-1, 2)
    truth_uv = np.asarray(truth_uv, float).reshape(-1, 2)
    tol = np.maximum(3.0, 0.5 * np.asarray(truth_wh, float).reshape(-1, 2).max(axis=1, initial=0.0))
    used = np.zeros(len(truth_uv), bool)
    tp = 0
    for d in dets_uv:
        if not len(truth_uv):
            break
        dist = np.hypot(*(truth_uv - d).T)
        dist[used | (dist > tol)] = np.inf
        k = int(np.argmin(dist))
        if np.isfinite(dist[k]):
            used[k] = True
            tp += 1
    return tp, len(dets_uv) - tp, int((~used).sum())


def _pr(tp: int, fp: int, fn: int) -> dict:
    return {"precision": tp / (tp + fp) if tp + fp else float("nan"),
            "recall": tp / (tp + fn) if tp + fn else float("nan"), "tp": tp, "fp": fp, "fn": fn}


def evaluate_samples(detector, samples) -> tuple[int, int, int]:
    """Summed (tp, fp, fn) of `detector.detect` over rendered samples."""
    tp = fp = fn = 0
    for s in samples:
        dets = sorted(detector.detect(s.image), key=lambda d: -d.score)
        a, b, c = match(np.array([d.centre_px for d in dets]), s.centres_px, s.sizes_px)
        tp, fp, fn = tp + a, fp + b, fn + c
    return tp, fp, fn


def evaluate(detector, seed: int, settings: EvalSettings = EvalSettings()) -> dict:
    """{'criterion', 'bins': {'LO-HI': {precision, recall, tp, fp, fn}}, 'negatives':
    {crops, false_alarms, per_crop}} for `detector` (any object with detect(image))."""
    ds = dataset.DataSettings(crop_px=settings.crop_px, worlds=settings.worlds, p_second=0.0,
                              p_negative=0.0)
    out = {"criterion": CRITERION, "crop_px": settings.crop_px, "seed": seed, "bins": {}}
    for k, (lo, hi) in enumerate(settings.bins):
        samples = dataset.make_samples(settings.frames_per_bin, seed * 1000 + k, ds, range_m=(lo, hi))
        out["bins"][f"{lo:g}-{hi:g}"] = _pr(*evaluate_samples(detector, samples))
    n_neg = settings.frames_per_bin if settings.negatives is None else settings.negatives
    negs = dataset.make_samples(n_neg, seed * 1000 + 999, ds, negative=True)
    _, fp, _ = evaluate_samples(detector, negs)
    out["negatives"] = {"crops": n_neg, "false_alarms": fp, "per_crop": fp / max(n_neg, 1)}
    return out


def format_table(res: dict) -> str:
    """Human-readable table of an `evaluate` result."""
    lines = [f"criterion: {res['criterion']}; {res['crop_px']} px crops, seed {res['seed']}",
             f"{'range_m':>10} {'precision':>9} {'recall':>7} {'tp':>5} {'fp':>5} {'fn':>5}"]
    for name, r in res["bins"].items():
        lines.append(f"{name:>10} {r['precision']:9.3f} {r['recall']:7.3f} {r['tp']:5d} {r['fp']:5d} {r['fn']:5d}")
    n = res["negatives"]
    lines.append(f"empty crops: {n['false_alarms']} false alarms in {n['crops']} ({n['per_crop']:.3f} per crop)")
    return "\n".join(lines)
