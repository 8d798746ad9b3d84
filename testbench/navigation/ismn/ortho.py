"""Inertial-aided orthorectification (DESIGN.md eq. 6-10).

The oblique camera frame is warped into a north-up virtual nadir view on the reference map's
grid, using the ESTIMATED pose. For a flat ground at down = d_g the map from ortho pixel
(col, row) to the ground point P_n, and on to the camera, is linear in homogeneous coordinates:

    P_n - c_n = M [col, row, 1]^T,  M = [[0, -g, N0 - g/2 - c_N], [g, 0, E0 + g/2 - c_E],
                                         [0, 0, d_g - c_D]]
    [u, v, 1]^T ~ K R_cn M [col, row, 1]^T

which is the homography H = K_v R K^-1 of eq. 10 written from the ortho side (R_cn = R_nc^T,
R_nc = R_nb R_bc, K_v = the virtual nadir camera scaled to g metres per pixel, north up).
Over relief every ortho pixel is projected through its own terrain height (cv2.remap).
"""

from __future__ import annotations

from typing import Callable

import cv2
import numpy as np

from testbench.core.camera_geometry import PinholeCamera
from testbench.navigation.ismn.types import OrthoFrame

HeightFn = Callable[[np.ndarray, np.ndarray], np.ndarray]  # (north_m, east_m) -> down_m


def to_grey_u8(frame: np.ndarray) -> np.ndarray:
    """(H, W) or (H, W, 3|4) RGB(A) uint8/float -> (H, W) uint8 grey."""
    img = np.asarray(frame)
    if img.dtype != np.uint8:
        scale = 255.0 if img.dtype.kind == "f" and float(np.nanmax(img)) <= 1.0 else 1.0
        img = np.clip(img * scale, 0, 255).astype(np.uint8)
    if img.ndim == 3:
        img = cv2.cvtColor(img[..., :3], cv2.COLOR_RGB2GRAY)
    return img


class Orthorectifier:
    """Warps frames of one camera into north-up ortho views; caches the undistortion maps.

    camera: full-resolution intrinsics and distortion; max_off_nadir_rad: ground farther from
    straight down than this is masked (grazing views and the sky are not ground).
    """

    def __init__(self, camera: PinholeCamera, max_off_nadir_rad: float = np.radians(70.0)):
        self.camera = camera
        self.max_off_nadir_rad = float(max_off_nadir_rad)
        self._undistort_cache: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}

    def scaled_K(self, width: int, height: int) -> np.ndarray:
        """Intrinsics of the frame resized to width x height (pixel centres at integers)."""
        cam = self.camera
        sx, sy = width / cam.width_px, height / cam.height_px
        return np.array([[cam.fx * sx, 0, (cam.cx + 0.5) * sx - 0.5],
                         [0, cam.fy * sy, (cam.cy + 0.5) * sy - 0.5], [0, 0, 1.0]])

    def prepare(self, frame: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray]:
        """Grey, downsampled (INTER_AREA, anti-aliased) and undistorted frame plus its K.

        Grey levels are clipped to >= 1 so that 0 marks "outside the frame" after warping.
        """
        grey = to_grey_u8(frame)
        cam = self.camera
        if grey.shape != (cam.height_px, cam.width_px):
            raise ValueError(f"frame shape {grey.shape} != camera {(cam.height_px, cam.width_px)}")
        # Downsample only when it matters: near 1 the warp's bilinear sampling is enough, and
        # INTER_AREA at non-integer factors close to 1 costs more than the warp itself.
        scale = 1.0 if scale > 0.8 else float(scale)
        w, h = max(8, round(cam.width_px * scale)), max(8, round(cam.height_px * scale))
        small = grey if (w, h) == (cam.width_px, cam.height_px) else cv2.resize(grey, (w, h), interpolation=cv2.INTER_AREA)
        K_s = self.scaled_K(w, h)
        if cam.has_distortion:
            maps = self._undistort_cache.get((w, h))
            if maps is None:
                maps = cv2.initUndistortRectifyMap(K_s, np.asarray(cam.dist, float), None, K_s, (w, h), cv2.CV_16SC2)
                self._undistort_cache[(w, h)] = maps
            small = cv2.remap(small, maps[0], maps[1], cv2.INTER_LINEAR, borderValue=0)
        if small is grey or small is frame:
            small = cv2.max(small, 1)  # a new array: the caller's frame is left as it was
        else:
            np.maximum(small, 1, out=small)
        return small, K_s

    def rectify(
        self,
        small: np.ndarray,
        K_s: np.ndarray,
        centre_ned_m: np.ndarray,
        R_nc: np.ndarray,
        north0_m: float,
        east0_m: float,
        gsd_m: float,
        shape: tuple[int, int],
        origin_px: tuple[int, int],
        ground_down_m: float,
        height_fn: HeightFn | None = None,
    ) -> OrthoFrame:
        """Warp a prepared frame onto the ortho grid (north0_m, east0_m, gsd_m, shape (H, W)).

        centre_ned_m, R_nc: ESTIMATED camera centre and camera->NED rotation. With height_fn
        (relief) each pixel uses its own ground height, else the plane down = ground_down_m.
        """
        H_o, W_o = shape
        g = gsd_m
        R_cn = R_nc.T
        c = np.asarray(centre_ned_m, float)
        M = np.array([[0.0, -g, north0_m - 0.5 * g - c[0]], [g, 0.0, east0_m + 0.5 * g - c[1]],
                      [0.0, 0.0, ground_down_m - c[2]]])
        H_small = K_s @ R_cn @ M  # ortho px -> small undistorted camera px (plane)
        if height_fn is None:
            ortho = cv2.warpPerspective(small, H_small, (W_o, H_o), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                        borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        else:
            map_x, map_y = self._relief_maps(K_s, c, R_cn, north0_m, east0_m, g, shape, height_fn)
            ortho = cv2.remap(small, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        valid = ortho > 0
        geometry_ok = self._geometry_mask(c, R_cn, north0_m, east0_m, g, shape, ground_down_m)
        if geometry_ok is not None:
            valid &= geometry_ok
        K_full = self.camera.K

        def cam_xy_full(cols, rows, _h=height_fn):
            """Full-resolution undistorted camera px of ortho pixels (ground under the estimate)."""
            north = north0_m - (np.asarray(rows, float) + 0.5) * g
            east = east0_m + (np.asarray(cols, float) + 0.5) * g
            down = np.full_like(north, ground_down_m) if _h is None else _h(north, east)
            xc = R_cn @ (np.vstack([north, east, down]) - c[:, None])
            uv = (K_full @ xc)[:2] / xc[2]
            return uv.T

        # u_s + 0.5 = s (u + 0.5): fold the half-pixel shift into the scale matrix inverse.
        Ssx, Ssy = K_s[0, 0] / K_full[0, 0], K_s[1, 1] / K_full[1, 1]
        S = np.array([[Ssx, 0, 0.5 * Ssx - 0.5], [0, Ssy, 0.5 * Ssy - 0.5], [0, 0, 1.0]])
        S_inv = np.linalg.inv(S)
        return OrthoFrame(ortho, valid, float(north0_m), float(east0_m), float(g), (int(origin_px[0]), int(origin_px[1])),
                          S_inv @ H_small, cam_xy_full, ground_down_m)

    def _relief_maps(self, K_s, c, R_cn, north0, east0, g, shape, height_fn, step=8):
        """Per-pixel camera coordinates over relief, projected on a coarse grid and upsampled."""
        H_o, W_o = shape
        nr, nc = -(-H_o // step), -(-W_o // step)
        rows = (np.arange(nr) + 0.5) * step - 0.5
        cols = (np.arange(nc) + 0.5) * step - 0.5
        cc, rr = np.meshgrid(cols, rows)
        north = north0 - (rr.ravel() + 0.5) * g
        east = east0 + (cc.ravel() + 0.5) * g
        down = height_fn(north, east)
        xc = R_cn @ (np.vstack([north, east, down]) - c[:, None])
        front = xc[2] > 1e-3
        z = np.where(front, xc[2], 1.0)
        u = np.where(front, K_s[0, 0] * xc[0] / z + K_s[0, 2], -1e5).reshape(nr, nc).astype(np.float32)
        v = np.where(front, K_s[1, 1] * xc[1] / z + K_s[1, 2], -1e5).reshape(nr, nc).astype(np.float32)
        map_x = cv2.resize(u, (nc * step, nr * step), interpolation=cv2.INTER_LINEAR)[:H_o, :W_o]
        map_y = cv2.resize(v, (nc * step, nr * step), interpolation=cv2.INTER_LINEAR)[:H_o, :W_o]
        return map_x, map_y

    def _geometry_mask(self, c, R_cn, north0, east0, g, shape, ground_down_m, step=16):
        """(H, W) bool, True where the ground is in front of the camera and within max_off_nadir
        of nadir; None when that is the whole grid.

        Both conditions are convex in the ortho plane, so all-true corners mean all-true (None:
        no 2 Mpx mask to make and apply); else they are evaluated on a coarse grid and upsampled
        (nearest)."""
        H_o, W_o = shape
        height = ground_down_m - c[2]
        r_max = height * np.tan(self.max_off_nadir_rad)

        def ok(cols, rows):
            north = north0 - (rows + 0.5) * g
            east = east0 + (cols + 0.5) * g
            d = np.vstack([north - c[0], east - c[1], np.full_like(north, height)])
            z = (R_cn @ d)[2]
            return (z > 1e-3 * height) & (np.hypot(d[0], d[1]) <= r_max)

        corners = ok(np.array([0.0, W_o - 1, 0, W_o - 1]), np.array([0.0, 0, H_o - 1, H_o - 1]))
        if corners.all():
            return None
        nr, nc = -(-H_o // step), -(-W_o // step)
        cc, rr = np.meshgrid((np.arange(nc) + 0.5) * step - 0.5, (np.arange(nr) + 0.5) * step - 0.5)
        m = ok(cc.ravel(), rr.ravel()).reshape(nr, nc).astype(np.uint8)
        return cv2.resize(m, (nc * step, nr * step), interpolation=cv2.INTER_NEAREST)[:H_o, :W_o].astype(bool)
