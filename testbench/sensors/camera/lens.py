"""Projection and lens distortion (OpenCV model) for the renderer.

Normalised coordinates are (x, y) = (X_c / Z_c, Y_c / Z_c) in the camera frame (OpenCV: x right,
y down, z optical axis). The OpenCV model distorts them to (x_d, y_d) and maps u = fx x_d + cx,
v = fy y_d + cy. Rendering with distortion first renders an ideal pinhole image (same focal
length, enlarged to cover the distorted field of view) and then resamples it at the undistorted
position of every distorted pixel, through a cv2.remap map computed once per camera.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from testbench.core.camera_geometry import PinholeCamera


def project_points(camera: PinholeCamera, centre_ned_m, R_nc, points_ned_m) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (n, 2) of NED points (n, 3) through cv2.projectPoints, and their depth z_c (n,).

    R_nc: camera->NED; the world->camera rotation handed to OpenCV is R_cn = R_nc^T.
    Points behind the camera (z_c <= 0) get pixels too (meaningless); check the depth.
    """
    P = np.asarray(points_ned_m, float).reshape(-1, 3)
    R_cn = np.asarray(R_nc, float).T
    t = -R_cn @ np.asarray(centre_ned_m, float)
    z = P @ R_cn[2] + t[2]
    if len(P) == 0:
        return np.zeros((0, 2)), z
    rvec, _ = cv2.Rodrigues(R_cn)
    uv, _ = cv2.projectPoints(P, rvec, t, camera.K, np.asarray(camera.dist, float))
    return uv.reshape(-1, 2), z


def distort_normalized(dist, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV distortion of normalised coordinates (k1, k2, p1, p2, k3)."""
    k1, k2, p1, p2, k3 = dist
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return xd, yd


def undistort_pixels(camera: PinholeCamera, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Undistorted normalised coordinates (x, y) of distorted pixels (u, v), any equal shapes.

    Starts from cv2.undistortPointsIter and polishes with Newton steps on the exact OpenCV
    forward model, so re-projecting gives back (u, v) to ~1e-9 px.
    """
    shape = np.shape(u)
    xd = (np.ravel(u).astype(float) - camera.cx) / camera.fx
    yd = (np.ravel(v).astype(float) - camera.cy) / camera.fy
    if not camera.has_distortion:
        return xd.reshape(shape), yd.reshape(shape)
    pts = np.stack([np.ravel(u), np.ravel(v)], axis=1).astype(np.float64).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)
    und = cv2.undistortPointsIter(pts, camera.K, np.asarray(camera.dist, float), None, None, crit)
    x, y = und[:, 0, 0].copy(), und[:, 0, 1].copy()
    k1, k2, p1, p2, k3 = camera.dist
    for _ in range(4):
        fx_, fy_ = distort_normalized(camera.dist, x, y)
        ex, ey = fx_ - xd, fy_ - yd
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        drad = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r2
        a = radial + 2.0 * x * x * drad + 2.0 * p1 * y + 6.0 * p2 * x   # d xd / dx
        b = 2.0 * x * y * drad + 2.0 * p1 * x + 2.0 * p2 * y            # d xd / dy
        c = 2.0 * x * y * drad + 2.0 * p1 * x + 2.0 * p2 * y            # d yd / dx
        d = radial + 2.0 * y * y * drad + 6.0 * p1 * y + 2.0 * p2 * x   # d yd / dy
        det = a * d - b * c
        x = x - (d * ex - b * ey) / det
        y = y - (-c * ex + a * ey) / det
    return x.reshape(shape), y.reshape(shape)


@lru_cache(maxsize=8)
def normalized_grid(camera: PinholeCamera) -> np.ndarray:
    """(H, W, 2) float64 undistorted normalised coordinates of every pixel centre (cached)."""
    v, u = np.mgrid[0 : camera.height_px, 0 : camera.width_px].astype(np.float64)
    x, y = undistort_pixels(camera, u, v)
    out = np.stack([x, y], axis=-1)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class DistortionRemap:
    """An ideal pinhole camera covering the distorted frame, and the cv2.remap maps that
    resample its image into the distorted frame (fixed point, 1/32 px, for speed)."""

    ideal: PinholeCamera
    map1: np.ndarray
    map2: np.ndarray


@lru_cache(maxsize=8)
def distortion_remap(camera: PinholeCamera) -> DistortionRemap:
    """Cached remap from the ideal render to `camera`'s distorted frame."""
    grid = normalized_grid(camera)
    x, y = grid[..., 0], grid[..., 1]
    # The ideal image keeps the focal length and grows to hold every undistorted pixel + 2 px.
    u_min = np.floor(camera.fx * x.min() - 2.0)
    u_max = np.ceil(camera.fx * x.max() + 2.0)
    v_min = np.floor(camera.fy * y.min() - 2.0)
    v_max = np.ceil(camera.fy * y.max() + 2.0)
    ideal = PinholeCamera(int(u_max - u_min) + 1, int(v_max - v_min) + 1, camera.fx, camera.fy,
                          float(-u_min), float(-v_min))
    mx = (camera.fx * x + ideal.cx).astype(np.float32)
    my = (camera.fy * y + ideal.cy).astype(np.float32)
    map1, map2 = cv2.convertMaps(mx, my, cv2.CV_16SC2)
    return DistortionRemap(ideal, map1, map2)


def roi_camera(camera: PinholeCamera, roi: tuple[int, int, int, int]) -> PinholeCamera:
    """The camera that renders only pixels u0 <= u < u1, v0 <= v < v1 of `camera`: the same
    lens with the principal point shifted (the OpenCV model distorts before adding cx, cy)."""
    u0, v0, u1, v1 = roi
    return PinholeCamera(u1 - u0, v1 - v0, camera.fx, camera.fy, camera.cx - u0, camera.cy - v0,
                         tuple(camera.dist))
