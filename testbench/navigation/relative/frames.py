"""Reading camera frames and camera sensors without depending on their exact classes.

Relative navigation needs from a camera frame: its time (`t_s`), the camera's name, and one
or more image parts, each with its full-frame region (None: the whole frame) and the truth
annotations (VehicleTruth) that the renderer attached, if any. Accepted shapes, in order:
- `frame.regions`: a sequence of RenderedFrame-like parts (`.image`, `.roi`, `.vehicles`);
- `frame.rendered`: one RenderedFrame-like part;
- the frame itself with `.image` (and optional `.roi`, `.vehicles`).
The camera's intrinsics and mounting come from its sensor object: `.camera` (PinholeCamera)
and `.mount` (CameraMount).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from testbench.core.camera_geometry import CameraMount, PinholeCamera
from testbench.core.errors import InputError

_NAME_FIELDS = ("camera_name", "sensor_name", "camera", "sensor", "name")


@dataclass(frozen=True)
class FramePart:
    """An image part: image (h, w, 3) uint8 RGB whose top-left pixel is full-frame origin_uv;
    full: it covers the whole frame; truths: VehicleTruth annotations (may be empty)."""

    image: np.ndarray
    origin_uv: tuple[int, int]
    full: bool
    truths: tuple


def frame_camera_name(frame: Any) -> str | None:
    """Name of the camera that took `frame` (first string among the usual field names)."""
    for f in _NAME_FIELDS:
        v = getattr(frame, f, None)
        if isinstance(v, str):
            return v
    return None


def is_camera_frame(m: Any) -> bool:
    return hasattr(m, "t_s") and (hasattr(m, "image") or hasattr(m, "regions") or hasattr(m, "rendered"))


def _part(p: Any) -> FramePart:
    roi = getattr(p, "roi", None)
    origin = (0, 0) if roi is None else (int(roi[0]), int(roi[1]))
    return FramePart(np.asarray(p.image), origin, roi is None, tuple(getattr(p, "vehicles", ()) or ()))


def frame_parts(frame: Any, width_px: int, height_px: int) -> list[FramePart]:
    """The image parts of a camera frame (see module docstring)."""
    regions = getattr(frame, "regions", None)
    if regions is not None:
        parts = [_part(p) for p in regions]
    elif getattr(frame, "rendered", None) is not None:
        parts = [_part(frame.rendered)]
    else:
        parts = [_part(frame)]
    out = []
    for p in parts:
        h, w = p.image.shape[:2]
        full = p.full or (p.origin_uv == (0, 0) and w >= width_px and h >= height_px)
        out.append(FramePart(p.image, p.origin_uv, full, p.truths))
    return out


def camera_model(sensor: Any, name: str) -> tuple[PinholeCamera, CameraMount]:
    """(PinholeCamera, CameraMount) of a camera sensor."""
    cam = getattr(sensor, "camera", None)
    mount = getattr(sensor, "mount", None)
    if not isinstance(cam, PinholeCamera) or not isinstance(mount, CameraMount):
        raise InputError(f"relnav.cameras: sensor {name!r} is not a camera (needs .camera PinholeCamera and .mount CameraMount)")
    return cam, mount
