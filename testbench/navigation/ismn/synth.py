"""Test helpers for scene matching: an in-memory map source, a plane-warp camera renderer,
procedural two-season worlds and photometric changes.

These stand in for testbench.world and testbench.sensors.camera in unit tests and benchmarks
(they are not the simulator's renderer). Randomness only from an injected numpy Generator.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from testbench.core.camera_geometry import CameraMount, PinholeCamera, camera_pose_ned
from testbench.world.raster import LocalRaster


class RasterMapSource:
    """Adapter giving an in-memory LocalRaster the MapSource method `read_local`.

    read_local returns the window north_max..north_min, east_min..east_max resampled to gsd_m
    (north0 = north_max, east0 = east_min, size rounded up), invalid outside the raster.
    """

    def __init__(self, raster: LocalRaster):
        self.raster = raster
        self.gsd_m = raster.gsd_m

    def read_local(self, north_min, north_max, east_min, east_max, gsd_m=None) -> LocalRaster:
        r = self.raster
        g = float(gsd_m or r.gsd_m)
        W = max(1, math.ceil((east_max - east_min) / g - 1e-9))
        H = max(1, math.ceil((north_max - north_min) / g - 1e-9))
        src, valid, gs = r.data, r.valid.astype(np.uint8), r.gsd_m
        if g > 1.25 * gs:  # anti-alias before resampling down
            f = gs / g
            size = (max(1, round(src.shape[1] * f)), max(1, round(src.shape[0] * f)))
            src = cv2.resize(src, size, interpolation=cv2.INTER_AREA)
            valid = cv2.resize(valid, size, interpolation=cv2.INTER_NEAREST)
            gs = r.gsd_m * r.data.shape[1] / size[0]
        k = g / gs
        A = np.array([[k, 0.0, (east_min + 0.5 * g - r.east0_m) / gs - 0.5],
                      [0.0, k, (r.north0_m - north_max + 0.5 * g) / gs - 0.5]])
        flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
        data = cv2.warpAffine(src, A, (W, H), flags=flags, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        ok = cv2.warpAffine(valid, A, (W, H), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                            borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        return LocalRaster(data, ok.astype(bool), float(north_max), float(east_min), g)


def render_plane_frame(raster: LocalRaster, camera: PinholeCamera, pos_ned_m, R_nb, mount: CameraMount,
                       ground_down_m: float = 0.0, sky_value: int = 200) -> np.ndarray:
    """Render what `camera` sees of `raster` draped on the plane down = ground_down_m.

    A plane homography (camera px <- raster px) applied with cv2.warpPerspective; pixels whose
    ray does not reach the ground get sky_value. Returns (H, W[, C]) uint8 like raster.data.
    No lens distortion (apply distort_frame for that).
    """
    c, R_nc = camera_pose_ned(pos_ned_m, R_nb, mount)
    g = raster.gsd_m
    M = np.array([[0.0, -g, raster.north0_m - 0.5 * g - c[0]], [g, 0.0, raster.east0_m + 0.5 * g - c[1]],
                  [0.0, 0.0, ground_down_m - c[2]]])
    H_r2c = camera.K @ R_nc.T @ M
    W, H = camera.width_px, camera.height_px
    frame = cv2.warpPerspective(raster.data, H_r2c, (W, H), flags=cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    # Rays pointing at or above the horizon: their ground intersection is behind the camera.
    Kinv = np.linalg.inv(camera.K)
    a = (R_nc @ Kinv)[2]  # down component of the ray, linear in (u, v)
    uu, vv = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
    sky = (a[0] * uu + a[1] * vv + a[2]) <= 1e-6
    frame[sky] = sky_value
    return frame


def distort_frame(frame: np.ndarray, camera: PinholeCamera) -> np.ndarray:
    """Apply the camera's lens distortion to an ideal pinhole frame (for tests)."""
    W, H = camera.width_px, camera.height_px
    uu, vv = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    # For every distorted pixel find the ideal pixel: undistortPoints inverts the lens model.
    pts = np.stack([uu.ravel(), vv.ravel()], -1)[:, None, :]
    ideal = cv2.undistortPoints(pts, camera.K, np.asarray(camera.dist, float), P=camera.K)[:, 0, :]
    mx = ideal[:, 0].reshape(H, W).astype(np.float32)
    my = ideal[:, 1].reshape(H, W).astype(np.float32)
    return cv2.remap(frame, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def procedural_seasons(rng: np.random.Generator, size_px: int, gsd_m: float, n_fields: int = 300,
                       north0_m: float | None = None, east0_m: float | None = None):
    """Two seasons of one farmland-like world: fields (random polygons), roads, texture.

    The field layout and roads are shared; field brightness, texture noise and contrast differ
    between the seasons (some fields invert), as real imagery of another season does.
    Returns (summer, winter) LocalRasters (size_px x size_px, grey replicated to 3 channels),
    centred on the origin unless north0_m/east0_m are given.
    """
    n = size_px
    a = np.zeros((n, n), np.float32)
    b = np.zeros((n, n), np.float32)
    for _ in range(n_fields):
        cx, cy = rng.uniform(0, n, 2)
        w, h = rng.uniform(0.03, 0.15, 2) * n
        ang = rng.uniform(0, 180)
        box = cv2.boxPoints(((float(cx), float(cy)), (float(w), float(h)), float(ang))).astype(np.int32)
        va = rng.uniform(0.2, 0.9)
        vb = va if rng.random() < 0.5 else rng.uniform(0.2, 0.9)  # half the fields change
        cv2.fillPoly(a, [box], float(va))
        cv2.fillPoly(b, [box], float(vb))
    for _ in range(max(4, n // 150)):  # roads, in both seasons
        p0, p1 = rng.uniform(0, n, 2), rng.uniform(0, n, 2)
        t = max(1, int(round(6.0 / gsd_m)))
        cv2.line(a, tuple(int(v) for v in p0), tuple(int(v) for v in p1), 0.1, t)
        cv2.line(b, tuple(int(v) for v in p0), tuple(int(v) for v in p1), 0.15, t)

    def texture(scale_px):
        z = rng.standard_normal((n, n)).astype(np.float32)
        return cv2.GaussianBlur(z, (0, 0), scale_px)

    common = texture(max(1.0, 4.0 / gsd_m)) * 8.0  # trees, soil patches seen in both seasons
    a = a + 0.10 * common + 0.04 * texture(1.0) * 3
    b = 0.8 * b + 0.1 + 0.10 * common + 0.04 * texture(1.0) * 3
    n0 = n * gsd_m / 2 if north0_m is None else north0_m
    e0 = -n * gsd_m / 2 if east0_m is None else east0_m

    def pack(x):
        u8 = np.clip(x * 255, 0, 255).astype(np.uint8)
        return LocalRaster(np.repeat(u8[..., None], 3, axis=2), np.ones((n, n), bool), n0, e0, gsd_m)

    return pack(a), pack(b)


def photometric_change(image: np.ndarray, rng: np.random.Generator, gain=1.25, gamma=0.8,
                       offset=-10.0, noise_sigma=4.0, blur_sigma=0.8) -> np.ndarray:
    """Same scene under other light and another sensor: gain, gamma, offset, blur, noise (uint8)."""
    x = image.astype(np.float32) / 255.0
    x = np.power(np.clip(x, 0, 1), gamma) * gain * 255.0 + offset
    if blur_sigma > 0:
        x = cv2.GaussianBlur(x, (0, 0), blur_sigma)
    x = x + rng.normal(0.0, noise_sigma, x.shape).astype(np.float32)
    return np.clip(x, 0, 255).astype(np.uint8)
