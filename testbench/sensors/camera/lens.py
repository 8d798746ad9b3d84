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
from scipy.interpolate import RectBivariateSpline

from testbench.core.camera_geometry import PinholeCamera


def project_points(camera: PinholeCamera, centre_ned_m, R_nc, points_ned_m) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (n, 2) of NED points (n, 3) through the camera's OpenCV model, and their depth z_c (n,).

    R_nc: camera->NED. The same model as cv2.projectPoints (distort_normalized; the two agree
    to 1e-12 px: test_camera_geometry_render), evaluated in numpy: cv2.projectPoints also builds its
    (2n, 15) Jacobian on every call, 7x the cost for a swarm frame's 2400 vertices.
    Points behind the camera (z_c <= 0) get pixels too (meaningless); check the depth.
    """
    P = np.asarray(points_ned_m, float).reshape(-1, 3)
    R_cn = np.asarray(R_nc, float).T
    Xc = (P - np.asarray(centre_ned_m, float)) @ R_cn.T
    z = Xc[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        x, y = Xc[:, 0] / z, Xc[:, 1] / z
    if any(camera.dist):
        x, y = distort_normalized(camera.dist, x, y)
    return np.stack([camera.fx * x + camera.cx, camera.fy * y + camera.cy], axis=1), z


def distort_normalized(dist, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV distortion of normalised coordinates (k1, k2, p1, p2, k3)."""
    k1, k2, p1, p2, k3 = dist
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return xd, yd


def _newton_undistort(dist, xd, yd, x, y, iterations: int):
    """Newton steps solving distort(x, y) = (xd, yd) from the guess (x, y)."""
    k1, k2, p1, p2, k3 = dist
    for _ in range(iterations):
        fx_, fy_ = distort_normalized(dist, x, y)
        ex, ey = fx_ - xd, fy_ - yd
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        drad = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r2
        a = radial + 2.0 * x * x * drad + 2.0 * p1 * y + 6.0 * p2 * x   # d xd / dx
        b = 2.0 * x * y * drad + 2.0 * p1 * x + 2.0 * p2 * y            # d xd / dy
        c = b                                                            # d yd / dx
        d = radial + 2.0 * y * y * drad + 6.0 * p1 * y + 2.0 * p2 * x   # d yd / dy
        det = a * d - b * c
        x = x - (d * ex - b * ey) / det
        y = y - (-c * ex + a * ey) / det
    return x, y


def _mark_unsolved(dist, xd, yd, x, y, fx: float):
    """nan where the lens polynomial has no inverse (it folds back past its valid field)."""
    ex, ey = distort_normalized(dist, x, y)
    bad = ~(np.hypot(ex - xd, ey - yd) * fx < 1e-4)
    x = np.where(bad, np.nan, x)
    y = np.where(bad, np.nan, y)
    return x, y


def undistort_pixels(camera: PinholeCamera, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Undistorted normalised coordinates (x, y) of distorted pixels (u, v), any equal shapes.

    Starts from OpenCV's iterative undistortion and polishes with Newton steps on the exact
    OpenCV forward model, so re-projecting gives back (u, v) to ~1e-9 px. Pixels the lens
    model cannot reach (the polynomial folds back) get nan.
    """
    shape = np.shape(u)
    xd = (np.ravel(u).astype(float) - camera.cx) / camera.fx
    yd = (np.ravel(v).astype(float) - camera.cy) / camera.fy
    if not camera.has_distortion:
        return xd.reshape(shape), yd.reshape(shape)
    pts = np.stack([np.ravel(u), np.ravel(v)], axis=1).astype(np.float64).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)
    K, dist = camera.K, np.asarray(camera.dist, float)
    if hasattr(cv2, "undistortPointsIter"):  # OpenCV 4
        und = cv2.undistortPointsIter(pts, K, dist, None, None, crit)
    else:  # OpenCV 5 folded the criteria into undistortPoints
        und = cv2.undistortPoints(pts, K, dist, R=None, P=None, criteria=crit)
    with np.errstate(all="ignore"):
        x, y = _newton_undistort(camera.dist, xd, yd, und[:, 0, 0].copy(), und[:, 0, 1].copy(), 4)
        x, y = _mark_unsolved(camera.dist, xd, yd, x, y, camera.fx)
    return x.reshape(shape), y.reshape(shape)


@lru_cache(maxsize=8)
def normalized_grid(camera: PinholeCamera) -> np.ndarray:
    """(H, W, 2) float64 undistorted normalised coordinates of every pixel centre (cached;
    nan where the lens model has no inverse).

    Solved exactly every 8 pixels, interpolated with a bicubic spline and polished by one
    Newton step per pixel (the spline alone is good to ~1e-6 px on a smooth lens).
    """
    W, H = camera.width_px, camera.height_px
    if not camera.has_distortion or W * H <= 256 * 256:
        v, u = np.mgrid[0:H, 0:W].astype(np.float64)
        x, y = undistort_pixels(camera, u, v)
    else:
        step = 8
        cu = np.unique(np.append(np.arange(0, W, step), W - 1)).astype(float)
        cv_ = np.unique(np.append(np.arange(0, H, step), H - 1)).astype(float)
        U, V = np.meshgrid(cu, cv_)
        xc, yc = undistort_pixels(camera, U, V)
        if not (np.isfinite(xc).all() and np.isfinite(yc).all()):
            v, u = np.mgrid[0:H, 0:W].astype(np.float64)
            x, y = undistort_pixels(camera, u, v)
        else:
            uu, vv = np.arange(W, dtype=float), np.arange(H, dtype=float)
            x = RectBivariateSpline(cv_, cu, xc)(vv, uu)
            y = RectBivariateSpline(cv_, cu, yc)(vv, uu)
            xd = (uu[None, :] - camera.cx) / camera.fx + 0.0 * vv[:, None]
            yd = (vv[:, None] - camera.cy) / camera.fy + 0.0 * uu[None, :]
            with np.errstate(all="ignore"):
                x, y = _newton_undistort(camera.dist, xd, yd, x, y, 1)
                x, y = _mark_unsolved(camera.dist, xd, yd, x, y, camera.fx)
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
    # A lens model pushed past its valid field (the polynomial folds back) would ask for an
    # enormous ideal image: cap it at twice the frame each way; pixels beyond show nothing.
    ok = np.isfinite(x) & np.isfinite(y)
    W, H = camera.width_px, camera.height_px
    u_min = max(np.floor(camera.fx * x[ok].min() - 2.0), -camera.cx - W / 2)
    u_max = min(np.ceil(camera.fx * x[ok].max() + 2.0), W - camera.cx + W / 2)
    v_min = max(np.floor(camera.fy * y[ok].min() - 2.0), -camera.cy - H / 2)
    v_max = min(np.ceil(camera.fy * y[ok].max() + 2.0), H - camera.cy + H / 2)
    ideal = PinholeCamera(int(u_max - u_min) + 1, int(v_max - v_min) + 1, camera.fx, camera.fy,
                          float(-u_min), float(-v_min))
    mx = np.where(ok, camera.fx * x + ideal.cx, -10.0).astype(np.float32)
    my = np.where(ok, camera.fy * y + ideal.cy, -10.0).astype(np.float32)
    map1, map2 = cv2.convertMaps(mx, my, cv2.CV_16SC2)
    return DistortionRemap(ideal, map1, map2)


def roi_camera(camera: PinholeCamera, roi: tuple[int, int, int, int]) -> PinholeCamera:
    """The camera that renders only pixels u0 <= u < u1, v0 <= v < v1 of `camera`: the same
    lens with the principal point shifted (the OpenCV model distorts before adding cx, cy)."""
    u0, v0, u1, v1 = roi
    return PinholeCamera(u1 - u0, v1 - v0, camera.fx, camera.fy, camera.cx - u0, camera.cy - v0,
                         tuple(camera.dist))
