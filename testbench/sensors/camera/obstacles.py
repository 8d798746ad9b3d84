"""The world's obstacles (core.obstacles.Obstacle boxes) in a camera frame.

`draw_obstacles` paints every face of every box that the camera sees, far faces first, each a
flat grey shaded by the same fixed sun as the vehicles (Lambert plus ambient), over the ground
the renderer has drawn, and returns the mask of the pixels they cover (not ground: the caller
takes them out of the frame's `valid` and `sky`). Faces are clipped at the near plane and a
little outside the view, so a camera next to a building sees its wall fill the view, and their
edges are cut into short segments before the lens model maps them, so that straight walls bend
as the lens bends the ground under them. (The vehicles behind a box are hidden where they are
drawn: vehicles.draw_vehicles.)

Over relief, the terrain hides the parts of a box behind it, pixel by pixel against the
renderer's coarse terrain depths (those edges are not smoothed). Not modelled: a box's shadow
on the ground.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Callable, Sequence

import cv2
import numpy as np

from testbench.core.camera_geometry import PinholeCamera
from testbench.core.obstacles import Obstacle
from testbench.sensors.camera.lens import distort_normalized, undistort_pixels
from testbench.sensors.camera.vehicles import SUN_NED

_ALBEDO_RGB = np.array([150.0, 146.0, 140.0])  # weathered concrete
_AMBIENT = 0.45
_EDGE_SEGMENTS = 8  # straight segments per face edge before the lens maps them
_SHIFT = 4  # sub-pixel bits for cv2 drawing
_VIEW_MARGIN = 0.1  # side planes this share of the view wider on each side


def draw_obstacles(img: np.ndarray, camera: PinholeCamera, C: np.ndarray, R_nc: np.ndarray,
                   obstacles: Sequence[Obstacle], near_m: float, far_m: float,
                   ground_depth: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> np.ndarray:
    """Paint the faces of `obstacles` that camera `camera` (its pixel grid is img's: for a
    region, the region's camera) at C (3,) NED m with attitude R_nc (3, 3, camera -> NED)
    sees; returns the (h, w) bool mask of the pixels they cover. Faces wholly beyond far_m
    are not drawn (the ground there is haze and sky). ground_depth(cols, rows) -> camera depth
    (m) of the terrain seen at those pixels of img (inf where none): where given (relief), a
    face's pixels behind the terrain are left to it (a hill in front of a building)."""
    h, w = img.shape[:2]
    mask = np.zeros((h, w), np.uint8)
    C = np.asarray(C, float)
    R_cn = np.asarray(R_nc, float).T
    faces = []  # (distance of the face's centre m, polygon px (k, 2), RGB, its plane (n_c (3,), d_c m))
    for ob in obstacles:
        for corners_ned, axis, sign in ob.faces_seen_from(C):
            normal = np.zeros(3)
            normal[axis] = sign
            shade = _AMBIENT + (1.0 - _AMBIENT) * max(0.0, float(normal @ SUN_NED))
            poly_c = _clip_to_view((_subdivide(corners_ned) - C) @ R_cn.T, camera, near_m)
            if len(poly_c) < 3 or np.all(poly_c[:, 2] > far_m):
                continue
            plane_c = (R_cn @ normal, float(normal @ (corners_ned[0] - C)))  # n_c . X = d_c, camera frame
            faces.append((float(np.linalg.norm(corners_ned.mean(axis=0) - C)), _to_pixels(camera, poly_c),
                          tuple(float(x) for x in np.clip(_ALBEDO_RGB * shade, 0, 255)), plane_c))
    faces.sort(key=lambda f: -f[0])  # far first: nearer faces paint over them
    scale = 1 << _SHIFT
    for _, px, rgb, plane_c in faces:
        pts = np.round(px * scale).astype(np.int32)
        if ground_depth is not None:
            face = np.zeros((h, w), np.uint8)
            cv2.fillPoly(face, [pts], 1, lineType=cv2.LINE_8, shift=_SHIFT)
            rows, cols = np.nonzero(face)
            hidden = _behind_terrain(camera, cols, rows, plane_c, ground_depth)
            if hidden.any():  # part of the face is behind the terrain: paint the rest, unsmoothed
                keep = ~hidden
                img[rows[keep], cols[keep]] = np.round(rgb).astype(img.dtype)
                mask[rows[keep], cols[keep]] = 1
                continue
        cv2.fillPoly(img, [pts], rgb, lineType=cv2.LINE_AA, shift=_SHIFT)
        cv2.fillPoly(mask, [pts], 1, lineType=cv2.LINE_8, shift=_SHIFT)
    return mask.astype(bool)


def _behind_terrain(camera: PinholeCamera, cols: np.ndarray, rows: np.ndarray, plane_c: tuple[np.ndarray, float],
                    ground_depth: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> np.ndarray:
    """(n,) bool: which pixels (cols, rows) of a face on the plane n_c . X = d_c (camera frame)
    see the terrain nearer than the face (camera depths compared along each pixel's ray)."""
    if cols.size == 0:
        return np.zeros(0, bool)
    x, y = undistort_pixels(camera, cols.astype(float), rows.astype(float))
    n_c, d_c = plane_c
    with np.errstate(divide="ignore", invalid="ignore"):
        z_face = d_c / (n_c[0] * x + n_c[1] * y + n_c[2])
    return np.asarray(ground_depth(cols, rows), float) < z_face


def _subdivide(corners: np.ndarray) -> np.ndarray:
    """(4 * _EDGE_SEGMENTS, 3): the face's outline (corners (4, 3) in order) cut into equal
    straight pieces."""
    s = np.arange(_EDGE_SEGMENTS)[:, None] / _EDGE_SEGMENTS
    nxt = np.roll(corners, -1, axis=0)
    return np.concatenate([a + s * (b - a) for a, b in zip(corners, nxt)])


def _clip_to_view(poly_c: np.ndarray, camera: PinholeCamera, near_m: float) -> np.ndarray:
    """The part of the closed polygon poly_c (k, 3, camera frame m) in front of the near plane
    and within the view's side planes (_view_bounds; Sutherland-Hodgman, plane by plane);
    (m, 3), empty when none of it is. The side planes keep the lens polynomial where it holds:
    far outside the view a barrel lens's polynomial folds points back into the image."""
    x0, x1, y0, y1 = _view_bounds(camera)
    planes = (  # (a, b): inside where a . p >= b
        (np.array([0.0, 0.0, 1.0]), near_m),
        (np.array([1.0, 0.0, -x0]), 0.0),
        (np.array([-1.0, 0.0, x1]), 0.0),
        (np.array([0.0, 1.0, -y0]), 0.0),
        (np.array([0.0, -1.0, y1]), 0.0),
    )
    for a, b in planes:
        if len(poly_c) == 0:
            break
        d = poly_c @ a - b
        out = []
        k = len(poly_c)
        for i in range(k):
            j = (i + 1) % k
            if d[i] >= 0.0:
                out.append(poly_c[i])
            if (d[i] >= 0.0) != (d[j] >= 0.0):
                out.append(poly_c[i] + d[i] / (d[i] - d[j]) * (poly_c[j] - poly_c[i]))
        poly_c = np.array(out).reshape(-1, 3)
    return poly_c


@lru_cache(maxsize=16)
def _view_bounds(camera: PinholeCamera) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1): undistorted normalised image coordinates a little (_VIEW_MARGIN)
    beyond those of the frame's border, but within the radius where the lens polynomial
    still grows (r * radial(r) increasing), so that every point inside maps to one pixel."""
    n = 32
    u = np.r_[np.linspace(0, camera.width_px, n), np.full(n, camera.width_px), np.linspace(0, camera.width_px, n), np.zeros(n)]
    v = np.r_[np.zeros(n), np.linspace(0, camera.height_px, n), np.full(n, camera.height_px), np.linspace(0, camera.height_px, n)]
    x, y = undistort_pixels(camera, u - 0.5, v - 0.5)
    if not np.isfinite(x).any():  # the lens reaches no border pixel: its pinhole extent
        x, y = (u - 0.5 - camera.cx) / camera.fx, (v - 0.5 - camera.cy) / camera.fy
    x0, x1, y0, y1 = (float(f(a)) for f, a in ((np.nanmin, x), (np.nanmax, x), (np.nanmin, y), (np.nanmax, y)))
    wx, wy = _VIEW_MARGIN * (x1 - x0), _VIEW_MARGIN * (y1 - y0)
    bounds = np.array([x0 - wx, x1 + wx, y0 - wy, y1 + wy])
    if camera.has_distortion:
        k1, k2, _, _, k3 = camera.dist
        r = np.linspace(0.0, float(np.hypot(np.abs(bounds[:2]).max(), np.abs(bounds[2:]).max())), 512)
        rd = r * (1.0 + r**2 * (k1 + r**2 * (k2 + r**2 * k3)))
        falling = np.flatnonzero(np.diff(rd) <= 0.0)
        if falling.size:  # the polynomial folds inside the corners: stay within it
            r_fold = r[falling[0]]
            bounds = np.clip(bounds, -r_fold / np.sqrt(2.0), r_fold / np.sqrt(2.0))
    return tuple(float(b) for b in bounds)


def _to_pixels(camera: PinholeCamera, pts_c: np.ndarray) -> np.ndarray:
    """(k, 2) pixels of camera-frame points (k, 3) in front of the camera, through the lens."""
    x, y = pts_c[:, 0] / pts_c[:, 2], pts_c[:, 1] / pts_c[:, 2]
    if any(camera.dist):
        x, y = distort_normalized(camera.dist, x, y)
    return np.stack([camera.fx * x + camera.cx, camera.fy * y + camera.cy], axis=1)
