"""CnnDetector: the trained TinyCenterNet behind the `Detector` interface.

Runs on regions of interest around predicted tracks (`detect(image, rois=[...])`, the cheap
path: ~256 x 256 px each) or on whole frames in overlapping tiles (the lower-rate search).
Detections come back in the pixel coordinates of the image passed in (full-frame when the
image is the full frame), as testbench.navigation.relative.types.Detection.
"""

from __future__ import annotations

import importlib.resources
from typing import Any, Sequence

import numpy as np
import pydantic

from testbench.core.interfaces import BuildContext, Detector
from testbench.core.registry import ParamsModel, register
from testbench.navigation.relative.types import Detection

PACKAGED_WEIGHTS = "weights.pt"


def packaged_weights_path():
    """Traversable of the weights file shipped in this package."""
    return importlib.resources.files("testbench.navigation.relative.cnn").joinpath(PACKAGED_WEIGHTS)


def led_level(image: np.ndarray, box, v_min: int = 215, s_min: int = 60) -> float:
    """Summed value/255 of bright saturated (LED-like) pixels inside `box` grown by 2 px:
    rises with the number of lit LEDs, for blink decoding (same definition as the LED
    detector's led_level)."""
    h, w = image.shape[:2]
    u0, v0 = max(int(np.floor(box[0])) - 2, 0), max(int(np.floor(box[1])) - 2, 0)
    u1, v1 = min(int(np.ceil(box[2])) + 3, w), min(int(np.ceil(box[3])) + 3, h)
    if u1 <= u0 or v1 <= v0:
        return 0.0
    px = image[v0:v1, u0:u1].astype(np.float32)
    mx, mn = px.max(axis=2), px.min(axis=2)
    sat = np.where(mx > 0, 255.0 * (mx - mn) / np.maximum(mx, 1.0), 0.0)
    m = (mx >= v_min) & (sat >= s_min)
    return float(mx[m].sum() / 255.0)


@register("detector", "cnn")
class CnnDetector(Detector):
    """Single-stage CNN detector (see cnn/model.py).

    Params: weights: path of a weights file (None: the packaged weights.pt); score_min:
    heatmap threshold; nms_iou / nms_centre_px: suppression of duplicates (IoU above, or
    centres closer than); tile_px / tile_overlap_px: full-frame tiling; threads: torch CPU
    threads, process-wide (None: leave torch's setting, one per core); device: only "cpu" is
    supported.

    One thread by default: the regions a run asks for (96-544 px) are too small for torch's
    intra-op threads to pay (a 256 px region: a median 28.5 ms on one thread, 30.2 ms on two),
    and a second thread spins on the core that a --processes worker, a batch worker (which runs
    with OMP_NUM_THREADS=1 for the same reason) or another test wants: swarm_cnn, 2 s, took 74 s
    of CPU on two threads and 47 s on one, for the same record bit for bit
    (docs/measurements.md, "The CNN detector's threads").

    `model` is the TinyCenterNet as loaded (or given); detection runs an inference copy of it
    made at construction (cnn.model.inference_copy), so later changes to `model` are not seen.
    """

    class Params(ParamsModel):
        weights: str | None = None
        score_min: float = pydantic.Field(0.55, gt=0.0, lt=1.0)
        nms_iou: float = pydantic.Field(0.4, gt=0.0, le=1.0)
        nms_centre_px: float = pydantic.Field(4.0, ge=0.0)
        tile_px: int = pydantic.Field(544, ge=64)
        tile_overlap_px: int = pydantic.Field(32, ge=0)
        threads: int | None = pydantic.Field(1, ge=1)
        device: str = "cpu"

        @pydantic.field_validator("device")
        @classmethod
        def _cpu_only(cls, v: str) -> str:
            if v != "cpu":
                raise ValueError("only 'cpu' is supported")
            return v

    def __init__(self, params: "CnnDetector.Params | None" = None, *, ctx: BuildContext | None = None,
                 model: Any = None, **_: Any):
        import torch

        from testbench.navigation.relative.cnn.model import inference_copy, load_weights

        self.params = params or self.Params()
        if self.params.threads is not None:
            torch.set_num_threads(self.params.threads)
        if model is not None:
            self.model = model.eval()
        elif self.params.weights is None:
            with packaged_weights_path().open("rb") as f:
                self.model = load_weights(f)
        else:
            from pathlib import Path

            from testbench.core.errors import InputError

            p = Path(self.params.weights).expanduser()
            if ctx is not None and not p.is_absolute():
                p = Path(ctx.scenario_dir) / p
            if not p.is_file():
                raise InputError(f"detector weights '{self.params.weights}': file not found")
            self.model = load_weights(p)
        self._net = inference_copy(self.model)  # what detect() runs: BN folded, channels-last

    @classmethod
    def from_model(cls, model, params: "CnnDetector.Params | None" = None) -> "CnnDetector":
        """A detector around an in-memory TinyCenterNet (training, tests)."""
        return cls(params, model=model)

    def _raw(self, image: np.ndarray) -> np.ndarray:
        """(m, 5) [u, v, w, h, score] in `image` pixels, before NMS."""
        import torch

        from testbench.navigation.relative.cnn.model import STRIDE, decode, to_tensor

        h, w = image.shape[:2]
        ph, pw = (-h) % STRIDE, (-w) % STRIDE
        if ph or pw:  # pad by edge replication to whole cells
            image = np.pad(image, ((0, ph), (0, pw), (0, 0)), mode="edge")
        with torch.inference_mode():
            out = self._net(to_tensor(image))
        d = decode(out, self.params.score_min)[0]
        return d[(d[:, 0] < w) & (d[:, 1] < h)]

    def _tiles(self, h: int, w: int):
        t, o = self.params.tile_px, self.params.tile_overlap_px
        if h <= t and w <= t:
            return [(0, 0, w, h)]
        step = max(t - 2 * o, STRIDE_MIN)
        us = list(range(0, max(w - t, 0) + 1, step))
        vs = list(range(0, max(h - t, 0) + 1, step))
        if us[-1] + t < w:
            us.append(w - t)
        if vs[-1] + t < h:
            vs.append(h - t)
        return [(u, v, min(u + t, w), min(v + t, h)) for v in vs for u in us]

    def _frame(self, image: np.ndarray) -> np.ndarray:
        h, w = image.shape[:2]
        o = self.params.tile_overlap_px
        parts = []
        for u0, v0, u1, v1 in self._tiles(h, w):
            d = self._raw(image[v0:v1, u0:u1])
            # Keep only centres in the tile's core (edge cells see padding, a neighbour sees them whole).
            lo_u, lo_v = (o if u0 > 0 else -1), (o if v0 > 0 else -1)
            hi_u, hi_v = (u1 - u0 - o if u1 < w else np.inf), (v1 - v0 - o if v1 < h else np.inf)
            keep = (d[:, 0] >= lo_u) & (d[:, 0] < hi_u) & (d[:, 1] >= lo_v) & (d[:, 1] < hi_v)
            d = d[keep]
            d[:, 0] += u0
            d[:, 1] += v0
            parts.append(d)
        return np.concatenate(parts) if parts else np.zeros((0, 5))

    def _to_detections(self, image: np.ndarray, d: np.ndarray, du: float = 0.0, dv: float = 0.0) -> list[Detection]:
        from testbench.navigation.relative.cnn.model import nms

        boxes = np.stack([d[:, 0] - d[:, 2] / 2, d[:, 1] - d[:, 3] / 2,
                          d[:, 0] + d[:, 2] / 2, d[:, 1] + d[:, 3] / 2], axis=1) if len(d) else np.zeros((0, 4))
        keep = nms(boxes, d[:, 4], self.params.nms_iou, self.params.nms_centre_px) if len(d) else []
        out = []
        for i in keep:
            b = boxes[i]
            out.append(Detection((b[0] + du, b[1] + dv, b[2] + du, b[3] + dv), (d[i, 0] + du, d[i, 1] + dv),
                                 float(d[i, 4]), "vehicle", led_level=led_level(image, b)))
        return out

    def detect(self, image: np.ndarray, rois: Sequence[tuple[int, int, int, int]] | None = None) -> list[Detection]:
        """Detections in `image` (H, W, 3) uint8 RGB, best first, pixel coordinates of `image`.

        rois: (u0, v0, u1, v1) regions of `image` (u1, v1 exclusive) to search instead of the
        whole image (overlapping regions are fine: duplicates are suppressed)."""
        image = np.asarray(image)
        if rois is None:
            return self._to_detections(image, self._frame(image))
        parts = []
        for r in rois:
            u0, v0 = max(int(r[0]), 0), max(int(r[1]), 0)
            u1, v1 = min(int(r[2]), image.shape[1]), min(int(r[3]), image.shape[0])
            if u1 <= u0 or v1 <= v0:
                continue
            d = self._raw(image[v0:v1, u0:u1])
            d[:, 0] += u0
            d[:, 1] += v0
            parts.append(d)
        d = np.concatenate(parts) if parts else np.zeros((0, 5))
        return self._to_detections(image, d)


STRIDE_MIN = 16
