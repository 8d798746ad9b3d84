"""Clouds in a rendered frame: the world's cloud sheet (world/clouds.py) over what lies beyond it.

Each pixel's ray (through the full lens model) that meets the sheet before it meets the
ground takes alpha = opacity x density of the cloud's colour there: the bright tops seen from
above, the grey base from below. The density is smooth over tens of metres, so it is sampled
every `STEP` pixels and interpolated (at 800 m above the ground, with the sheet 300 m below,
a 120 deg 1080p camera's 8 pixels span about 4 m of the sheet).

Where the world's sun is given (world.clouds.CloudLayer.sun_ned), the clouds also cast their
shadows on the ground the frame sees (sampled on the same grid), darkening it to the diffuse
skylight, before the clouds themselves are painted over it.

Nothing in a frame says which pixels are cloud or shadow: navigation sees only the pixels, as
a real camera's user does.
"""

from __future__ import annotations

from dataclasses import dataclass
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


GAMMA = 2.2
"""The frames' pixel values are display-referred (sRGB-like): a linear light factor f scales
them by about f^(1/2.2)."""


@dataclass(frozen=True)
class RayGrid:
    """A frame's rays sampled every STEP pixels (the cloud field is smooth at that scale).

    shape: (h, w) samples; d_ned: (h, w, 3) each ray's NED direction per metre of camera
    depth; t_ground: (h, w) the camera depth (m) where it meets the ground, inf where it
    does not; centre_ned_m: (3,) the camera; size_px: (W, H) of the frame (region)."""

    centre_ned_m: np.ndarray
    d_ned: np.ndarray
    t_ground: np.ndarray
    size_px: tuple[int, int]

    def upsample(self, grid: np.ndarray) -> np.ndarray:
        """(H, W) float32 of an (h, w) grid, linearly interpolated to the frame's pixels."""
        h, w = grid.shape
        W, H = self.size_px
        return cv2.resize(grid.astype(np.float32, copy=False), (w * STEP, h * STEP),
                          interpolation=cv2.INTER_LINEAR)[:H, :W]


def ray_grid(cam: PinholeCamera, centre_ned_m: np.ndarray, R_nc: np.ndarray,
             ground_depth: Callable[[np.ndarray, np.ndarray], np.ndarray] | None,
             ground_down_m: float) -> RayGrid:
    """The rays of `cam` (a region camera for a region, through the full lens model) every
    STEP pixels. centre_ned_m (3,), R_nc (3, 3 camera->NED): the true camera pose;
    ground_depth(u, v): the camera depth (m) of the terrain seen at region pixels (arrays; inf
    where sky), or None for flat ground at NED down ground_down_m."""
    W, H = cam.width_px, cam.height_px
    us = np.minimum(np.arange(STEP // 2, W + STEP // 2, STEP), W - 1).astype(float)
    vs = np.minimum(np.arange(STEP // 2, H + STEP // 2, STEP), H - 1).astype(float)
    U, V = np.meshgrid(us, vs)
    x, y = undistort_pixels(cam, U, V)
    d = np.stack([x, y, np.ones_like(x)], axis=-1) @ np.asarray(R_nc, float).T  # NED ray per unit camera depth
    C = np.asarray(centre_ned_m, float)
    if ground_depth is None:
        with np.errstate(divide="ignore", invalid="ignore"):
            t_ground = np.where(d[..., 2] > 0.0, (ground_down_m - C[2]) / d[..., 2], np.inf)
    else:
        t_ground = np.asarray(ground_depth(U, V), float)
    return RayGrid(C, d, t_ground, (W, H))


def cloud_alpha(grid: RayGrid, view) -> tuple[np.ndarray, np.ndarray] | None:
    """(alpha, depth), each (H, W) float32 over the frame's pixels: the cloud's alpha and how
    deep inside its cloud the ray meets the sheet (world.clouds.CloudView.sample); None where
    no ray meets a cloud. view: the sheet now (world.clouds.CloudView). A ray takes the cloud
    where it meets the sheet nearer than the ground."""
    if view is None or view.clear:
        return None
    C, d = grid.centre_ned_m, grid.d_ned
    with np.errstate(divide="ignore", invalid="ignore"):
        t_sheet = (view.down_m - C[2]) / d[..., 2]
        meets = np.isfinite(t_sheet) & (t_sheet > 0.0) & (t_sheet < grid.t_ground)
    if not meets.any():
        return None
    north = np.where(meets, C[0] + t_sheet * d[..., 0], 0.0)
    east = np.where(meets, C[1] + t_sheet * d[..., 1], 0.0)
    density, depth = view.sample(north, east)
    alpha = np.where(meets, view.layer.opacity * density, 0.0).astype(np.float32)
    if not alpha.any():
        return None
    return grid.upsample(alpha), grid.upsample(depth)


def shadow_gain(grid: RayGrid, view) -> np.ndarray | None:
    """(H, W) float32 factor on the pixel values of the ground the frame sees: the light the
    clouds' shadows leave there (world.clouds.CloudView.ground_light), through GAMMA; 1 on the
    sky. None where no shadow falls in the frame."""
    if view is None or not view.casts_shadows:
        return None
    C, d, t = grid.centre_ned_m, grid.d_ned, grid.t_ground
    ground = np.isfinite(t)
    if not ground.any():
        return None
    tg = np.where(ground, t, 0.0)[..., None]
    g = C + tg * d  # (h, w, 3) NED ground points
    light = np.where(ground, view.ground_light(g[..., 0], g[..., 1], g[..., 2]), 1.0)
    if light.min() >= 1.0:
        return None
    return grid.upsample(np.power(light, 1.0 / GAMMA))


def half_shadow_gain(view) -> float:
    """The pixel factor (shadow_gain) where a cloud cuts half the direct sun: below it a pixel
    counts as in shadow (RenderedFrame.shadow_fraction)."""
    light = view.layer.shadow_light
    return float((light + 0.5 * (1.0 - light)) ** (1.0 / GAMMA))


def apply_shadows(rgb: np.ndarray, gain: np.ndarray, keep: np.ndarray | None = None) -> None:
    """Darken rgb (H, W, 3) uint8 in place by gain (H, W), except where keep (H, W bool: pixels
    the shadow does not reach, such as an obstacle's, whose ground point is not theirs)."""
    if keep is not None:
        gain = np.where(keep, np.float32(1.0), gain)
    rows = np.flatnonzero(gain.min(axis=1) < 1.0)
    if rows.size == 0:
        return
    r0, r1 = int(rows[0]), int(rows[-1]) + 1
    g = np.ascontiguousarray(gain[r0:r1])
    rgb[r0:r1] = cv2.multiply(np.ascontiguousarray(rgb[r0:r1]), cv2.merge([g, g, g]), dtype=cv2.CV_8U)


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
