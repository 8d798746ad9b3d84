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
from testbench.navigation.ismn.rolling import RowMotion
from testbench.navigation.ismn.types import OrthoFrame

#: The coarse level is warped this many levels finer and reduced (OrthoFrame.coarse).
COARSE_OVERSAMPLE_LEVELS = 1

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

    def prepare(self, frame: np.ndarray, scale: float, nodata: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Grey, downsampled (INTER_AREA, anti-aliased) and undistorted frame plus its K.

        Grey levels are clipped to >= 1 so that 0 marks "outside the frame" after warping;
        nodata (H, W) bool marks frame pixels to treat so as well (clouds: ismn.cloud_mask),
        and a reduced pixel that covers any of them is 0.
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
        if nodata is not None and nodata.any():
            m = nodata.view(np.uint8) * np.uint8(255)
            if m.shape != small.shape:
                m = cv2.resize(m, (w, h), interpolation=cv2.INTER_AREA)  # > 0 where any masked pixel fell
            if cam.has_distortion:
                m = cv2.remap(m, maps[0], maps[1], cv2.INTER_NEAREST, borderValue=0)
            small[m > 0] = 0
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
        motion: RowMotion | None = None,
    ) -> OrthoFrame:
        """The ortho view of a prepared frame on the grid (north0_m, east0_m, gsd_m, shape (H, W)).

        centre_ned_m, R_nc: ESTIMATED camera centre and camera->NED rotation (with a rolling
        shutter, the middle row's). With height_fn (relief) each pixel uses its own ground
        height, else the plane down = ground_down_m. motion: a rolling shutter's row motion
        (ismn.rolling; None: a global shutter): each ground point is then taken from the row
        that saw it, and the warp is a remap as over relief.
        Nothing is warped here: the OrthoFrame warps the regions and levels a matcher asks for.
        """
        H_o, W_o = shape
        g = gsd_m
        R_cn = R_nc.T
        c = np.asarray(centre_ned_m, float)
        M = np.array([[0.0, -g, north0_m - 0.5 * g - c[0]], [g, 0.0, east0_m + 0.5 * g - c[1]],
                      [0.0, 0.0, ground_down_m - c[2]]])
        H_small = K_s @ R_cn @ M  # ortho px -> small undistorted camera px (plane)
        geometry = self._geometry_grid(c, R_cn, north0_m, east0_m, g, shape, ground_down_m)
        if motion is not None:
            relief = self._rolling_grid(K_s, motion, c, R_nc, north0_m, east0_m, g, shape, ground_down_m, height_fn)
        else:
            relief = None if height_fn is None else self._relief_grid(K_s, c, R_cn, north0_m, east0_m, g, shape, height_fn)
        warp = _FrameWarp(small, H_small, shape, geometry, relief)
        K_full = self.camera.K

        def cam_xy_full(cols, rows, _h=height_fn):
            """Full-resolution undistorted camera px of ortho pixels (ground under the estimate)."""
            north = north0_m - (np.asarray(rows, float) + 0.5) * g
            east = east0_m + (np.asarray(cols, float) + 0.5) * g
            down = np.full_like(north, ground_down_m) if _h is None else _h(north, east)
            if motion is not None:
                return motion.project(c, R_nc, np.c_[north, east, down])
            xc = R_cn @ (np.vstack([north, east, down]) - c[:, None])
            uv = (K_full @ xc)[:2] / xc[2]
            return uv.T

        # u_s + 0.5 = s (u + 0.5): fold the half-pixel shift into the scale matrix inverse.
        Ssx, Ssy = K_s[0, 0] / K_full[0, 0], K_s[1, 1] / K_full[1, 1]
        S = np.array([[Ssx, 0, 0.5 * Ssx - 0.5], [0, Ssy, 0.5 * Ssy - 0.5], [0, 0, 1.0]])
        S_inv = np.linalg.inv(S)
        return OrthoFrame((H_o, W_o), float(north0_m), float(east0_m), float(g), (int(origin_px[0]), int(origin_px[1])),
                          S_inv @ H_small, cam_xy_full, ground_down_m, render=warp.render,
                          render_coarse=warp.render_coarse, surely_valid=warp.surely_valid)

    def _relief_grid(self, K_s, c, R_cn, north0, east0, g, shape, height_fn, step=8):
        """(u, v, step): camera coordinates (small frame px, float32 (nr, nc)) of the ortho
        points (k + 1/2) step - 1/2 over relief; -1e5 behind the camera."""
        north, east, (nr, nc) = _grid_points(north0, east0, g, shape, step)
        down = height_fn(north, east)
        xc = R_cn @ (np.vstack([north, east, down]) - c[:, None])
        front = xc[2] > 1e-3
        z = np.where(front, xc[2], 1.0)
        u = np.where(front, K_s[0, 0] * xc[0] / z + K_s[0, 2], -1e5).reshape(nr, nc).astype(np.float32)
        v = np.where(front, K_s[1, 1] * xc[1] / z + K_s[1, 2], -1e5).reshape(nr, nc).astype(np.float32)
        return u, v, step

    def _rolling_grid(self, K_s, motion: RowMotion, c, R_nc, north0, east0, g, shape, ground_down_m, height_fn, step=8):
        """(u, v, step) as _relief_grid, the ground (the plane ground_down_m, or height_fn's)
        projected through the rolling shutter's rows (RowMotion.project)."""
        north, east, (nr, nc) = _grid_points(north0, east0, g, shape, step)
        down = np.full_like(north, ground_down_m) if height_fn is None else height_fn(north, east)
        uv = motion.project(c, R_nc, np.c_[north, east, down])
        sx, sy = K_s[0, 0] / self.camera.fx, K_s[1, 1] / self.camera.fy
        behind = ~np.isfinite(uv[:, 0])
        u = np.where(behind, -1e5, sx * (np.nan_to_num(uv[:, 0]) + 0.5) - 0.5).reshape(nr, nc).astype(np.float32)
        v = np.where(behind, -1e5, sy * (np.nan_to_num(uv[:, 1]) + 0.5) - 0.5).reshape(nr, nc).astype(np.float32)
        return u, v, step

    def _geometry_grid(self, c, R_cn, north0, east0, g, shape, ground_down_m, step=16):
        """(ok (nr, nc) bool, step): whether the ground is in front of the camera and within
        max_off_nadir of nadir, at the centres of step x step blocks of the grid (a pixel takes
        its block's value); None when that holds on the whole grid.

        Both conditions are convex in the ortho plane, so all-true corners mean all-true (None:
        no mask to make and apply)."""
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
        return ok(cc.ravel(), rr.ravel()).reshape(nr, nc), step


class _FrameWarp:
    """Warps one prepared frame onto regions and reduced levels of an ortho grid (what an
    OrthoFrame asks for).

    small (h, w) uint8: the prepared frame (grey >= 1, 0 meaning outside); H_small (3, 3):
    ortho px -> small-frame px over the ground plane; shape (H, W) of the grid; geometry:
    (block grid, step) of Orthorectifier._geometry_grid or None (all ground usable); relief:
    (u, v, step) of Orthorectifier._relief_grid or None (the plane).
    """

    def __init__(self, small: np.ndarray, H_small: np.ndarray, shape: tuple[int, int], geometry, relief):
        self.small, self.H_small, self.shape = small, H_small, shape
        self.geometry, self.relief = geometry, relief
        self._frame_levels = None  # area.Pyramid of the frame (no mask), made when first asked
        # The homography's entries as Python floats, for surely_valid's corner tests.
        self._h = H_small.tolist()

    def frame_level(self, level: int) -> np.ndarray:
        """The prepared frame reduced 2^level times (area.Pyramid: 2 x 2 means)."""
        if self._frame_levels is None:
            from testbench.navigation.ismn.area import Pyramid

            self._frame_levels = Pyramid(self.small, None, 8)
        return self._frame_levels[level][0]

    def render(self, x0: int, y0: int, w: int, h: int) -> tuple[np.ndarray, np.ndarray]:
        """(grey (h, w) uint8, valid bool) of full-resolution columns x0:x0+w, rows y0:y0+h."""
        if self.relief is None:
            T = np.array([[1.0, 0.0, x0], [0.0, 1.0, y0], [0.0, 0.0, 1.0]])
            img = cv2.warpPerspective(self.small, self.H_small @ T, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                      borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        else:
            map_x, map_y = _relief_maps(self.relief, x0, y0, w, h, self.shape)
            img = cv2.remap(self.small, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        valid = img > 0
        if self.geometry is not None:
            valid &= _grid_crop(self.geometry, x0, y0, w, h)
        return img, valid

    def surely_valid(self, x0: int, y0: int, w: int, h: int) -> bool:
        """True when every pixel of the region is valid, from its corners alone (plane case):
        the pixels seen in the frame's interior (a sample between four frame pixels, all >= 1)
        are the projective preimage of a rectangle, which is convex, so the region lies in it
        when its corners do; and the geometry mask is constant on its blocks. False: not known."""
        if self.relief is not None:
            return False
        if self.geometry is not None:
            grid, step = self.geometry
            if not grid[y0 // step:(y0 + h - 1) // step + 1, x0 // step:(x0 + w - 1) // step + 1].all():
                return False
        (h00, h01, h02), (h10, h11, h12), (h20, h21, h22) = self._h
        h_small, w_small = self.small.shape[:2]
        for x in (x0, x0 + w - 1):  # Python floats: ~80 candidate tiles a frame ask
            for y in (y0, y0 + h - 1):
                z = h20 * x + h21 * y + h22
                if not z > 0:
                    return False
                u, v = (h00 * x + h01 * y + h02) / z, (h10 * x + h11 * y + h12) / z
                if not (0.0 <= u <= w_small - 1 and 0.0 <= v <= h_small - 1):
                    return False
        return True

    def render_level(self, level: int) -> tuple[np.ndarray, np.ndarray]:
        """(grey, valid) of the whole grid reduced 2^level times, warped from the frame reduced
        as much: pixel (X, Y) is the ortho point (s X + (s - 1) / 2, s Y + (s - 1) / 2), and
        pixel u of the reduced frame is (u + 1/2) / s - 1/2 of the prepared one."""
        s = 2**level
        h, w = self.shape[0] >> level, self.shape[1] >> level
        src = self.frame_level(level)
        S = np.array([[1.0 / s, 0.0, 0.5 / s - 0.5], [0.0, 1.0 / s, 0.5 / s - 0.5], [0.0, 0.0, 1.0]])
        if self.relief is None:
            T = np.array([[s, 0.0, 0.5 * (s - 1)], [0.0, s, 0.5 * (s - 1)], [0.0, 0.0, 1.0]])
            img = cv2.warpPerspective(src, S @ self.H_small @ T, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                      borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        else:
            map_x, map_y = _relief_maps(self.relief, 0, 0, w, h, self.shape, level)
            img = cv2.remap(src, map_x / s + (0.5 / s - 0.5), map_y / s + (0.5 / s - 0.5), cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        # A reduced pixel is valid when all it covers is: at the frame's edge the warp mixes in
        # the black outside over one reduced pixel, so one is eroded away (the grid's outer ring
        # too, where the frame may end inside the last reduced pixel).
        valid = cv2.erode((img > 0).view(np.uint8), np.ones((3, 3), np.uint8),
                          borderType=cv2.BORDER_CONSTANT, borderValue=0).view(bool)
        if self.geometry is not None:
            grid, step = self.geometry
            rows, cols = np.arange(h) * s, np.arange(w) * s
            ok = np.ones((h, w), bool)
            for r in (rows, rows + s - 1):  # a reduced pixel's corner blocks
                for q in (cols, cols + s - 1):
                    ok &= grid[np.ix_(r // step, q // step)]
            valid &= ok
        return img, valid

    def render_coarse(self, level: int) -> tuple[np.ndarray, np.ndarray]:
        """(grey, valid) of the grid reduced 2^level times: warped COARSE_OVERSAMPLE_LEVELS
        finer from the frame reduced as much (render_level), then halved as area.Pyramid halves.
        Warped at the level itself, the far side of an oblique view, where a frame pixel covers
        several ortho pixels, comes out blurred twice over (a 640 x 360 frame at 12 deg roll and
        8 deg pitch, level 3: 11.8 grey levels from the reduced whole warp on average; 5.5 one
        level finer; 1.6 two levels finer, for four times the warp)."""
        from testbench.navigation.ismn.area import pyramid

        sub = max(0, level - COARSE_OVERSAMPLE_LEVELS)
        if sub == 0:
            return pyramid(*self.render(0, 0, self.shape[1], self.shape[0]), level)[level]
        return pyramid(*self.render_level(sub), level - sub)[level - sub]


def _grid_points(north0: float, east0: float, g: float, shape: tuple[int, int], step: int):
    """(north (n,), east (n,), (nr, nc)): NED north / east (m) of the ortho points
    (k + 1/2) step - 1/2 of a grid of shape (H, W) from (north0, east0) at g m per pixel,
    row-major over the (nr, nc) blocks."""
    H_o, W_o = shape
    nr, nc = -(-H_o // step), -(-W_o // step)
    cc, rr = np.meshgrid((np.arange(nc) + 0.5) * step - 0.5, (np.arange(nr) + 0.5) * step - 0.5)
    return north0 - (rr.ravel() + 0.5) * g, east0 + (cc.ravel() + 0.5) * g, (nr, nc)


def _grid_crop(grid_step: tuple[np.ndarray, int], x0: int, y0: int, w: int, h: int) -> np.ndarray:
    """(h, w) bool: the block grid's value at full-resolution pixels x0:x0+w, y0:y0+h (each
    pixel its block's: a nearest-neighbour upsampling by the block size)."""
    grid, step = grid_step
    ra, ca = y0 // step, x0 // step
    sub = grid[ra:(y0 + h - 1) // step + 1, ca:(x0 + w - 1) // step + 1].astype(np.uint8)
    up = cv2.resize(sub, (sub.shape[1] * step, sub.shape[0] * step), interpolation=cv2.INTER_NEAREST)
    return up[y0 - ra * step:y0 - ra * step + h, x0 - ca * step:x0 - ca * step + w].astype(bool)


def _relief_maps(relief, x0: int, y0: int, w: int, h: int, shape: tuple[int, int], level: int = 0):
    """(map_x, map_y) float32 (h, w): small-frame coordinates of the pixels x0:x0+w, y0:y0+h of
    the ortho grid reduced 2^level times, bilinear in the relief grid (as an INTER_LINEAR
    upsampling of it by its step: pixel x at grid coordinate (x + 1/2) / step - 1/2)."""
    u, v, step = relief
    s = 2**level
    if level == 0 and x0 == 0 and y0 == 0 and (h, w) == tuple(shape):
        H_o, W_o = shape
        size = (u.shape[1] * step, u.shape[0] * step)
        return (cv2.resize(u, size, interpolation=cv2.INTER_LINEAR)[:H_o, :W_o],
                cv2.resize(v, size, interpolation=cv2.INTER_LINEAR)[:H_o, :W_o])
    # Full-resolution coordinate of a reduced pixel's centre: s x + (s - 1) / 2.
    gx = ((s * (np.arange(x0, x0 + w) + 0.5)) / step - 0.5).astype(np.float32)
    gy = ((s * (np.arange(y0, y0 + h) + 0.5)) / step - 0.5).astype(np.float32)
    mx, my = np.broadcast_to(gx, (h, w)), np.broadcast_to(gy[:, None], (h, w))
    mx, my = np.ascontiguousarray(mx), np.ascontiguousarray(my)
    return (cv2.remap(u, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE),
            cv2.remap(v, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE))
