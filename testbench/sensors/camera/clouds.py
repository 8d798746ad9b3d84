"""Clouds in a rendered frame: the world's cloud sheet (world/clouds.py) over what lies beyond it.

Each pixel's ray (through the full lens model) that meets the sheet before it meets the
ground takes alpha = opacity x density of the cloud's colour there: the bright tops seen from
above, the grey base from below. The density is smooth over tens of metres, so it is sampled
every `STEP` pixels and interpolated (at 800 m above the ground, with the sheet 300 m below,
a 120 deg 1080p camera's 8 pixels span about 4 m of the sheet).

Nothing in a frame says which pixels are cloud: navigation sees only the pixels, as a real
camera's user does.
"""

from __future__ import annotations

from typing import Callable

import cv2
import numpy as np

from testbench.core.camera_geometry import PinholeCamera
from testbench.sensors.camera.lens import undistort_pixels

STEP = 8
TOP_RGB = np.array([238.0, 240.0, 244.0], np.float32)
"""Sunlit cloud tops seen from above (a thick cloud's; thinner parts a little greyer)."""
BASE_RGB = np.array([150.0, 154.0, 164.0], np.float32)
"""A cloud's base seen from below (a thick cloud's; thinner parts a little lighter)."""


def cloud_alpha(cam: PinholeCamera, centre_ned_m: np.ndarray, R_nc: np.ndarray, view,
                ground_depth: Callable[[np.ndarray, np.ndarray], np.ndarray] | None,
                ground_down_m: float) -> tuple[np.ndarray, np.ndarray] | None:
    """(alpha, depth), each (H, W) float32 over the pixels of `cam` (a region camera for a
    region): the cloud's alpha and how deep inside its cloud the ray meets the sheet
    (world.clouds.CloudView.sample); None where no ray meets a cloud.

    centre_ned_m (3,), R_nc (3, 3 camera->NED): the true camera pose; view: the sheet now
    (world.clouds.CloudView); ground_depth(u, v): the camera depth (m) of the terrain seen at
    region pixels (arrays; inf where sky), or None for flat ground at NED down ground_down_m.
    A ray takes the cloud where it meets the sheet nearer than the ground."""
    if view is None or view.clear:
        return None
    W, H = cam.width_px, cam.height_px
    us = np.minimum(np.arange(STEP // 2, W + STEP // 2, STEP), W - 1).astype(float)
    vs = np.minimum(np.arange(STEP // 2, H + STEP // 2, STEP), H - 1).astype(float)
    U, V = np.meshgrid(us, vs)
    x, y = undistort_pixels(cam, U, V)
    d = np.stack([x, y, np.ones_like(x)], axis=-1) @ np.asarray(R_nc, float).T  # NED ray per unit camera depth
    C = np.asarray(centre_ned_m, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_sheet = (view.down_m - C[2]) / d[..., 2]
        if ground_depth is None:
            t_ground = np.where(d[..., 2] > 0.0, (ground_down_m - C[2]) / d[..., 2], np.inf)
        else:
            t_ground = ground_depth(U, V)
        meets = np.isfinite(t_sheet) & (t_sheet > 0.0) & (t_sheet < t_ground)
    if not meets.any():
        return None
    north = np.where(meets, C[0] + t_sheet * d[..., 0], 0.0)
    east = np.where(meets, C[1] + t_sheet * d[..., 1], 0.0)
    density, depth = view.sample(north, east)
    alpha = np.where(meets, view.layer.opacity * density, 0.0).astype(np.float32)
    if not alpha.any():
        return None
    h, w = alpha.shape
    size = (w * STEP, h * STEP)
    return (cv2.resize(alpha, size, interpolation=cv2.INTER_LINEAR)[:H, :W],
            cv2.resize(depth.astype(np.float32), size, interpolation=cv2.INTER_LINEAR)[:H, :W])


def blend_clouds(rgb: np.ndarray, alpha: np.ndarray, depth: np.ndarray, from_above: bool) -> None:
    """Paint the clouds into rgb (H, W, 3) uint8 in place: out = (1 - a) rgb + a colour, the
    colour the tops' (from_above) or the base's, shaded by how deep in its cloud each ray
    meets the sheet (depth 0-1: a top's fringe 20 % darker than its core, a base's core 25 %
    darker than its fringe)."""
    rows = np.flatnonzero(alpha.max(axis=1) > 0.0)
    if rows.size == 0:
        return
    r0, r1 = int(rows[0]), int(rows[-1]) + 1
    a = np.ascontiguousarray(alpha[r0:r1])
    k = depth[r0:r1]
    if from_above:
        level, colour = 0.8 + 0.2 * k, TOP_RGB
    else:
        level, colour = 1.1 - 0.25 * k, BASE_RGB
    # In OpenCV (a numpy expression over the 6 Mpx of a 1080p frame took 170 ms, these 10 ms).
    cloud = cv2.merge([cv2.convertScaleAbs(level, alpha=float(c)) for c in colour])
    rgb[r0:r1] = cv2.blendLinear(np.ascontiguousarray(rgb[r0:r1]), cloud, 1.0 - a, a)
