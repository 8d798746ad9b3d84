"""A small single-stage detector for tiny aircraft (CenterNet-style centre heatmap).

Why a centre heatmap and not YOLO anchors: a quadrotor at 100 m is ~3 px across; anchors and
IoU-based assignment are ill-defined at that size, whereas a centre heatmap with a sub-cell
offset localises a 1-3 px target as well as a 50 px one. The backbone keeps one layer at full
resolution (LED glows and 1-2 px silhouettes survive), then two stride-2 stages and dilated
3x3 convolutions for context (sky vs ground, horizon) at stride 4.

Outputs at stride 4 (cell (i, j) covers pixels u in [4j, 4j + 4), v in [4i, 4i + 4)):
  channel 0: centre logit; 1, 2: centre offset (du, dv) in cells within the cell, in [0, 1);
  3, 4: log box width and height in pixels.
Pixel coordinates: integers at pixel centres; u = (j + du) * 4 - 0.5.
"""

from __future__ import annotations

import copy

import numpy as np
import torch
from torch import nn
import torch.nn.functional as F

STRIDE = 4


def _cbr(cin: int, cout: int, stride: int = 1, dilation: int = 1) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 3, stride, padding=dilation, dilation=dilation, bias=False),
                         nn.BatchNorm2d(cout), nn.ReLU(inplace=True))


class TinyCenterNet(nn.Module):
    """widths = (full-resolution, stride 2, stride 4) channel counts."""

    def __init__(self, widths: tuple[int, int, int] = (12, 24, 32)):
        super().__init__()
        w0, w1, w2 = widths
        self.widths = tuple(int(w) for w in widths)
        self.backbone = nn.Sequential(
            _cbr(3, w0),
            _cbr(w0, w1, stride=2), _cbr(w1, w1),
            _cbr(w1, w2, stride=2), _cbr(w2, w2), _cbr(w2, w2, dilation=2), _cbr(w2, w2, dilation=4),
        )
        self.head = nn.Sequential(nn.Conv2d(w2, w2, 3, padding=1), nn.ReLU(inplace=True), nn.Conv2d(w2, 5, 1))
        # Focal-loss prior: start with ~1 % objectness so the empty background does not swamp it.
        nn.init.constant_(self.head[-1].bias, 0.0)
        with torch.no_grad():
            self.head[-1].bias[0] = -4.6

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """x (N, 3, H, W) float in [0, 1] -> (N, 5, ceil(H/4), ceil(W/4)) raw outputs."""
        return self.head(self.backbone(x - 0.5))


def inference_copy(model: TinyCenterNet) -> nn.Module:
    """A copy of `model` for inference only, the same function to float rounding (~1e-5 on
    the logits): each eval-mode BatchNorm folded into the convolution before it
    (torch.nn.utils.fusion), weights in channels-last layout, parameters frozen. `model` is
    left untouched (training goes on with it).

    Why: a folded BatchNorm is one pass less over each activation, and with weights and
    inputs both channels-last oneDNN runs the convolutions without reordering either; on one
    CPU core a forward pass runs 1.15-1.25x faster than the model as loaded (96-544 px
    crops, docs/measurements.md). Its inputs should be channels-last, as `to_tensor` makes them."""
    from torch.nn.utils.fusion import fuse_conv_bn_eval

    m = copy.deepcopy(model).eval()
    for block in m.backbone:  # each block is _cbr's (Conv2d, BatchNorm2d, ReLU)
        block[0] = fuse_conv_bn_eval(block[0], block[1])
        block[1] = nn.Identity()
    m = m.to(memory_format=torch.channels_last)
    for p in m.parameters():
        p.requires_grad_(False)
    return m


def to_tensor(images: np.ndarray) -> torch.Tensor:
    """(N, H, W, 3) or (H, W, 3) uint8 RGB -> (N, 3, H, W) float32 in [0, 1], its memory in
    the image's own NHWC order (channels-last strides, the layout `inference_copy` wants)."""
    a = np.asarray(images)
    if a.ndim == 3:
        a = a[None]
    # The permuted view has NHWC strides; float() preserves them (memory_format=preserve_format).
    return torch.from_numpy(np.ascontiguousarray(a)).permute(0, 3, 1, 2).float().div_(255.0)


def encode_targets(centres_px: list[np.ndarray], sizes_px: list[np.ndarray], h: int, w: int):
    """Training targets for a batch of crops of h x w pixels.

    centres_px[k] (n, 2) (u, v) and sizes_px[k] (n, 2) (width, height) of crop k's vehicles.
    Returns heat (N, 1, hc, wc) Gaussian peaks (1 at each centre cell), reg (N, 4, hc, wc)
    (offset du, dv, log w, log h at centre cells), mask (N, 1, hc, wc) 1 at centre cells.
    """
    hc, wc = -(-h // STRIDE), -(-w // STRIDE)
    n = len(centres_px)
    heat = np.zeros((n, 1, hc, wc), np.float32)
    reg = np.zeros((n, 4, hc, wc), np.float32)
    mask = np.zeros((n, 1, hc, wc), np.float32)
    jj, ii = np.meshgrid(np.arange(wc), np.arange(hc))
    for k, (cs, ss) in enumerate(zip(centres_px, sizes_px)):
        for (u, v), (bw, bh) in zip(np.asarray(cs).reshape(-1, 2), np.asarray(ss).reshape(-1, 2)):
            x, y = (u + 0.5) / STRIDE, (v + 0.5) / STRIDE  # continuous cell coordinates
            j, i = int(np.clip(np.floor(x), 0, wc - 1)), int(np.clip(np.floor(y), 0, hc - 1))
            # Peak spread grows with the target (CenterNet's size-adaptive radius), >= ~1 cell.
            sigma = max(0.7, 0.15 * max(bw, bh) / STRIDE)
            g = np.exp(-((jj - j) ** 2 + (ii - i) ** 2) / (2 * sigma**2)).astype(np.float32)
            heat[k, 0] = np.maximum(heat[k, 0], g)
            reg[k, :, i, j] = (x - j, y - i, np.log(max(bw, 1.0)), np.log(max(bh, 1.0)))
            mask[k, 0, i, j] = 1.0
    return torch.from_numpy(heat), torch.from_numpy(reg), torch.from_numpy(mask)


def detection_loss(out: torch.Tensor, heat: torch.Tensor, reg: torch.Tensor, mask: torch.Tensor):
    """CenterNet loss: penalty-reduced focal loss on the heatmap (alpha 2, beta 4) plus L1 on
    offset and log-size at centre cells. Returns (total, focal, regression) scalars."""
    logit = out[:, :1]
    p = torch.sigmoid(logit).clamp(1e-4, 1 - 1e-4)
    pos = heat.eq(1.0).float()
    neg = 1.0 - pos
    pos_loss = -torch.log(p) * (1 - p) ** 2 * pos
    neg_loss = -torch.log(1 - p) * p**2 * (1 - heat) ** 4 * neg
    n_pos = pos.sum().clamp(min=1.0)
    focal = (pos_loss.sum() + neg_loss.sum()) / n_pos
    off = torch.sigmoid(out[:, 1:3])
    l1 = (torch.abs(off - reg[:, :2]) * mask).sum() + 0.2 * (torch.abs(out[:, 3:5] - reg[:, 2:]) * mask).sum()
    regl = l1 / mask.sum().clamp(min=1.0)
    return focal + regl, focal, regl


def decode(out: torch.Tensor, score_min: float, max_det: int = 50) -> list[np.ndarray]:
    """Raw outputs (N, 5, hc, wc) -> per image an (m, 5) array [u, v, w, h, score] of local
    heatmap maxima (3x3) with score >= score_min, pixel coordinates of the input, best first."""
    heat = torch.sigmoid(out[:, :1])
    peaks = heat * (F.max_pool2d(heat, 3, 1, 1) == heat)
    res = []
    for k in range(out.shape[0]):
        s = peaks[k, 0].flatten()
        idx = torch.nonzero(s >= score_min).flatten()
        if idx.numel() > max_det:
            idx = idx[torch.topk(s[idx], max_det).indices]
        wc = out.shape[-1]
        i, j = idx // wc, idx % wc
        off = torch.sigmoid(out[k, 1:3, i, j])
        u = (j.float() + off[0]) * STRIDE - 0.5
        v = (i.float() + off[1]) * STRIDE - 0.5
        wh = torch.exp(out[k, 3:5, i, j].clamp(-2, 8))
        d = torch.stack([u, v, wh[0], wh[1], s[idx]], dim=1).numpy().astype(np.float64)
        res.append(d[np.argsort(-d[:, 4], kind="stable")])
    return res


def nms(boxes: np.ndarray, scores: np.ndarray, iou_max: float = 0.4, centre_px: float = 3.0,
        centre_frac: float = 0.5) -> np.ndarray:
    """Greedy non-maximum suppression.

    boxes (n, 4) (u0, v0, u1, v1), scores (n,). A box is suppressed by a better-scoring kept box
    when their IoU > iou_max OR their centres lie within max(centre_px, centre_frac * the kept
    box's larger side) (IoU alone is meaningless for 2-px boxes, and a badly sized box on a
    large wing would escape it). Returns the kept indices, best first.
    """
    boxes = np.asarray(boxes, float).reshape(-1, 4)
    order = np.argsort(-np.asarray(scores, float), kind="stable")
    area = np.clip(boxes[:, 2] - boxes[:, 0], 0, None) * np.clip(boxes[:, 3] - boxes[:, 1], 0, None)
    cu, cv = 0.5 * (boxes[:, 0] + boxes[:, 2]), 0.5 * (boxes[:, 1] + boxes[:, 3])
    keep: list[int] = []
    while order.size:
        i = order[0]
        keep.append(int(i))
        rest = order[1:]
        iw = np.clip(np.minimum(boxes[i, 2], boxes[rest, 2]) - np.maximum(boxes[i, 0], boxes[rest, 0]), 0, None)
        ih = np.clip(np.minimum(boxes[i, 3], boxes[rest, 3]) - np.maximum(boxes[i, 1], boxes[rest, 1]), 0, None)
        inter = iw * ih
        union = area[i] + area[rest] - inter
        iou = np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)
        reach = max(centre_px, centre_frac * max(boxes[i, 2] - boxes[i, 0], boxes[i, 3] - boxes[i, 1]))
        near = np.hypot(cu[rest] - cu[i], cv[rest] - cv[i]) <= reach
        order = rest[(iou <= iou_max) & ~near]
    return np.array(keep, int)


def save_weights(model: TinyCenterNet, path, meta: dict | None = None) -> None:
    """Half-precision state dict + architecture (a few hundred KB)."""
    sd = {k: (v.half() if v.is_floating_point() else v) for k, v in model.state_dict().items()}
    torch.save({"widths": model.widths, "state_dict": sd, "meta": meta or {}}, path)


def load_weights(path_or_file) -> TinyCenterNet:
    """A TinyCenterNet in eval mode from `save_weights` output (path or binary file object)."""
    blob = torch.load(path_or_file, map_location="cpu", weights_only=True)
    model = TinyCenterNet(tuple(blob["widths"]))
    model.load_state_dict({k: (v.float() if v.is_floating_point() else v) for k, v in blob["state_dict"].items()})
    return model.eval()
