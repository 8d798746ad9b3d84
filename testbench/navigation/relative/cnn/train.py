"""Training of the CNN detector on rendered crops, reproducible from a seed on CPU.

`train(seed, out_path, ...)` renders the training set (dataset.make_samples, numpy seed),
trains TinyCenterNet with AdamW and a cosine schedule for a fixed number of steps (torch seed,
deterministic algorithms, fixed thread count: the same seed on the same machine type gives the
same weights), validates on held-out worlds and writes the weights and a JSON card beside them.
"""

from __future__ import annotations

import json
import logging
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch

from testbench.navigation.relative.cnn import dataset
from testbench.navigation.relative.cnn.model import TinyCenterNet, detection_loss, encode_targets, save_weights, to_tensor

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TrainSettings:
    """n_train: rendered crops; steps, batch, lr: optimisation; widths: network channels;
    threads: torch CPU threads (fixed for reproducibility); val_frames: validation crops per
    range bin; data: the DataSettings of the training crops."""

    n_train: int = 16000
    steps: int = 4000
    batch: int = 32
    lr: float = 3e-3
    weight_decay: float = 1e-4
    widths: tuple[int, int, int] = (12, 24, 32)
    threads: int = 2
    val_frames: int = 100
    data: dataset.DataSettings = dataset.DataSettings(crop_px=64)


def _seed_everything(seed: int, threads: int) -> torch.Generator:
    torch.manual_seed(seed)
    torch.set_num_threads(threads)
    torch.use_deterministic_algorithms(True, warn_only=True)
    return torch.Generator().manual_seed(seed)


def train(seed: int, out_path, minutes: float | None = None, settings: TrainSettings = TrainSettings(),
          progress=None) -> dict:
    """Train, validate and save; returns the card (also written to out_path with .json).

    minutes: optional wall-clock cap on the optimisation loop (the run then stops early and the
    card says so; a capped run is not reproducible). progress(step, loss): optional callback.
    """
    t0 = time.perf_counter()
    gen = _seed_everything(seed, settings.threads)
    samples = dataset.make_samples(settings.n_train, seed, settings.data)
    images = torch.from_numpy(dataset.stack(samples))  # (N, c, c, 3) uint8
    centres = [s.centres_px for s in samples]
    sizes = [s.sizes_px for s in samples]
    t_data = time.perf_counter() - t0
    log.info("rendered %d crops in %.0f s", len(samples), t_data)

    model = TinyCenterNet(settings.widths)
    opt = torch.optim.AdamW(model.parameters(), lr=settings.lr, weight_decay=settings.weight_decay)
    warm = max(1, settings.steps // 20)

    def lr_at(step: int) -> float:
        if step < warm:
            return (step + 1) / warm
        return 0.5 * (1 + math.cos(math.pi * (step - warm) / max(1, settings.steps - warm)))

    sched = torch.optim.lr_scheduler.LambdaLR(opt, lr_at)
    c = settings.data.crop_px
    n = len(samples)
    t1 = time.perf_counter()
    stopped_early = False
    losses = []
    step = 0
    model.train()
    while step < settings.steps:
        perm = torch.randperm(n, generator=gen)
        for b in range(0, n - settings.batch + 1, settings.batch):
            if step >= settings.steps:
                break
            if minutes is not None and time.perf_counter() - t0 > 60.0 * minutes:
                stopped_early = True
                break
            idx = perm[b: b + settings.batch]
            x = to_tensor(images[idx].numpy())
            cs = [centres[i].copy() for i in idx.tolist()]
            ss = [sizes[i] for i in idx.tolist()]
            # Horizontal mirror of half the batch (a mirrored world is as plausible).
            flip = (torch.rand(len(cs), generator=gen) < 0.5).tolist()
            for k, f in enumerate(flip):
                if f:
                    x[k] = torch.flip(x[k], dims=[2])
                    if len(cs[k]):
                        cs[k][:, 0] = (c - 1) - cs[k][:, 0]
            heat, reg, mask = encode_targets(cs, ss, c, c)
            out = model(x)
            loss, _, _ = detection_loss(out, heat, reg, mask)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            sched.step()
            losses.append(loss.item())
            step += 1
            if progress is not None and step % 50 == 0:
                progress(step, float(np.mean(losses[-50:])))
        if stopped_early:
            break
    t_train = time.perf_counter() - t1
    model.eval()

    from testbench.navigation.relative.cnn.detector import CnnDetector
    from testbench.navigation.relative.cnn.evaluate import EvalSettings, evaluate

    det = CnnDetector.from_model(model)
    val = evaluate(det, seed + 1, EvalSettings(frames_per_bin=settings.val_frames))
    out_path = Path(out_path)
    card = {
        "seed": seed,
        "steps_done": step,
        "stopped_early_by_time_cap": stopped_early,
        "train_settings": {k: v for k, v in settings.__dict__.items() if k != "data"},
        "data_settings": settings.data.to_dict(),
        "time_s": {"data": round(t_data, 1), "optimisation": round(t_train, 1),
                   "total": round(time.perf_counter() - t0, 1)},
        "final_loss": float(np.mean(losses[-100:])) if losses else None,
        "torch": torch.__version__,
        "parameters": int(sum(p.numel() for p in model.parameters())),
        "validation": val,
    }
    save_weights(model, out_path, {"seed": seed, "steps": step})
    card["weights_bytes"] = out_path.stat().st_size
    out_path.with_suffix(".json").write_text(json.dumps(card, indent=2, default=_jsonable))
    return card


def _jsonable(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, tuple):
        return list(x)
    return str(x)


def quick_settings(**kw) -> TrainSettings:
    """TrainSettings with some fields replaced (for tests and experiments)."""
    return replace(TrainSettings(), **kw)
