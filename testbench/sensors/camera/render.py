"""The camera renderer: what a camera at a true pose sees of a mapped world.

`render(camera, mount, pos_ned_m, R_nb, imagery, elevation, ...)` is a pure function (caches
aside: map pyramids per raster, lens maps per camera) with no engine dependency.

Flat ground (elevation None): exact plane homography, mip-mapped cv2.warpPerspective of an
ideal pinhole image, then lens distortion by a cached cv2.remap. Relief: rays cast against the
elevation raster through the full lens model, cv2.remap of the map. Then other vehicles, then
the effects (motion blur, vignetting, gain, noise).
"""

from __future__ import annotations

from typing import Sequence

import cv2
import numpy as np

from testbench.core.camera_geometry import CameraMount, PinholeCamera, camera_pose_ned
from testbench.core.obstacles import Obstacle
from testbench.sensors.camera.clouds import (apply_shadows, blend_clouds, cloud_alpha, half_shadow_gain, ray_grid,
                                             shadow_gain)
from testbench.sensors.camera.effects import apply_effects
from testbench.sensors.camera.flat import render_plane
from testbench.sensors.camera.lens import distortion_remap, normalized_grid, roi_camera
from testbench.sensors.camera.obstacles import draw_obstacles
from testbench.sensors.camera.pyramid import dem_sampler_for, pyramid_for
from testbench.sensors.camera.relief import render_relief
from testbench.sensors.camera.types import RenderedFrame, RenderOptions, VehicleAppearance
from testbench.sensors.camera.vehicles import draw_vehicles
from testbench.world.raster import LocalRaster

_DEFAULT_OPTIONS = RenderOptions()


def _check_roi(camera: PinholeCamera, roi) -> tuple[int, int, int, int]:
    if roi is None:
        return (0, 0, camera.width_px, camera.height_px)
    u0, v0, u1, v1 = (int(round(x)) for x in roi)
    u0, v0 = max(u0, 0), max(v0, 0)
    u1, v1 = min(u1, camera.width_px), min(v1, camera.height_px)
    if u1 <= u0 or v1 <= v0:
        raise ValueError(f"roi {roi} does not overlap the {camera.width_px}x{camera.height_px} frame")
    return (u0, v0, u1, v1)


def _flat(cam: PinholeCamera, C, R_nc, pyr, ground_down_m: float, opts, want_points: bool):
    """Flat-ground render of `cam` (lens distortion included)."""
    if not cam.has_distortion:
        rgb, valid, sky, view, complete = render_plane(cam, C, R_nc, pyr, ground_down_m, opts)
    else:
        dr = distortion_remap(cam)
        rgb_i, valid_i, sky_i, view, _ = render_plane(dr.ideal, C, R_nc, pyr, ground_down_m, opts)
        complete = False  # the remap's border: count
        rgb = cv2.remap(rgb_i, dr.map1, dr.map2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
        flags = valid_i.view(np.uint8) | (sky_i.view(np.uint8) << 1)
        flags = cv2.remap(flags, dr.map1, dr.map2, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT)
        valid, sky = (flags & 1).astype(bool), (flags & 2).astype(bool)
        nodata = ~(valid | sky)
        if nodata.any():
            rgb[nodata] = 0  # the linear resampling blurs black no-data into its border
    # Camera depth of the ground at a pixel, for hiding vehicles below the horizon of terrain.
    r_down = np.asarray(R_nc, float)[2]  # down component of a camera-frame ray
    h = view.h_m

    def ground_depth(u: float, v: float) -> float:
        x, y = normalized_grid(cam)[int(round(v)), int(round(u))] if cam.has_distortion else (
            (u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy)
        w = r_down @ np.array([x, y, 1.0])
        return h / w if (h > 0 and w * opts.far_m > h) else np.inf

    points = None
    if want_points:
        xy = normalized_grid(cam)
        d = np.concatenate([xy, np.ones(xy.shape[:-1] + (1,))], axis=-1) @ np.asarray(R_nc).T
        with np.errstate(divide="ignore", invalid="ignore"):
            t = h / d[..., 2]
        points = np.asarray(C, float) + t[..., None] * d
        points[sky | ~(t > 0)] = np.nan
    return rgb, valid, sky, ground_depth, points, complete


def render(camera: PinholeCamera, mount: CameraMount, pos_ned_m, R_nb, imagery: LocalRaster,
           elevation: LocalRaster | None = None, *, vehicles: Sequence[VehicleAppearance] = (),
           rng: np.random.Generator | None = None, want_ground_points: bool = False,
           roi: tuple[int, int, int, int] | None = None,
           options: RenderOptions = _DEFAULT_OPTIONS, obstacles: Sequence[Obstacle] = (),
           clouds=None) -> RenderedFrame:
    """Render what `camera`, mounted by `mount` on a vehicle at pos_ned_m (3,) NED m with
    attitude R_nb (3, 3, body->NED), sees of `imagery` over `elevation` (None: flat ground at
    options.ground_height_m).

    vehicles: other vehicles to draw (with their LED states); rng: noise generator (no noise
    without it); want_ground_points: also return each pixel's NED ground point;
    roi: (u0, v0, u1, v1) full-frame pixel box to render (u1, v1 exclusive), for detectors
    that look around predicted tracks; obstacles: the world's boxes (core.obstacles), drawn
    over the ground and hiding the vehicles behind them, their pixels neither `valid` nor
    `sky`; clouds: the world's cloud sheet at this instant (world.clouds.CloudView, None:
    clear), drawn over the ground, sky and obstacles beyond it, its shadows darkening the
    ground (where the layer has a sun; the vehicles and obstacles are not shaded); a vehicle
    beyond it is hidden where it takes half the light or more (else drawn whole). Returns a
    RenderedFrame; parts of the view that the map does not cover are black, masked out of
    `valid` and counted in `offmap_fraction`.
    """
    roi_box = _check_roi(camera, roi)
    cam = camera if roi is None else roi_camera(camera, roi_box)
    C, R_nc = camera_pose_ned(pos_ned_m, R_nb, mount)
    pyr = pyramid_for(imagery)
    points = None
    if elevation is None:
        rgb, valid, sky, ground_depth_roi, points, complete = _flat(
            cam, C, R_nc, pyr, -float(options.ground_height_m), options, want_ground_points)
    else:
        dem = dem_sampler_for(elevation)
        rgb, valid, sky, points_fn, (t2, k) = render_relief(cam, C, R_nc, pyr, dem, options)
        complete = False

        def ground_depth_roi(u: float, v: float) -> float:
            return float(t2[min(int(round(v / k)), t2.shape[0] - 1), min(int(round(u / k)), t2.shape[1] - 1)])

        if want_ground_points:
            points = points_fn()
    u0, v0 = roi_box[0], roi_box[1]
    covered = None  # pixels an obstacle covers: neither ground nor sky
    if obstacles:
        terrain_depth = None
        if elevation is not None:
            def terrain_depth(cols: np.ndarray, rows: np.ndarray) -> np.ndarray:  # region px -> camera depth m
                return t2[np.minimum(np.round(rows / k).astype(int), t2.shape[0] - 1),
                          np.minimum(np.round(cols / k).astype(int), t2.shape[1] - 1)]
        covered = draw_obstacles(rgb, cam, C, R_nc, obstacles, options.near_m, options.far_m, terrain_depth)
        valid, sky = valid & ~covered, sky & ~covered
        if points is not None:
            points[covered] = np.nan
    cloud_fraction = shadow_fraction = 0.0
    if clouds is not None and not clouds.clear:
        if elevation is None:
            depth_fn = None
        else:
            def depth_fn(cols: np.ndarray, rows: np.ndarray) -> np.ndarray:  # region px -> camera depth m
                return t2[np.minimum(np.round(rows / k).astype(int), t2.shape[0] - 1),
                          np.minimum(np.round(cols / k).astype(int), t2.shape[1] - 1)]
        rays = ray_grid(cam, C, R_nc, depth_fn, -float(options.ground_height_m))
        gain = shadow_gain(rays, clouds)
        if gain is not None:  # the shadows first: the clouds in front hide the shadowed ground
            apply_shadows(rgb, gain, covered)
        cover = cloud_alpha(rays, clouds)
        if cover is not None:
            blend_clouds(rgb, cover[0], cover[1], bool(C[2] < clouds.down_m))
        # The shares of the ground in view (and of what hides it) that the clouds hide, and that
        # shows in their shadows.
        ground = ~sky
        n_ground = max(int(np.count_nonzero(ground)), 1)
        hidden = np.zeros_like(ground) if cover is None else cover[0] >= 0.5
        cloud_fraction = float(np.count_nonzero(hidden & ground)) / n_ground
        if gain is not None:
            shaded = gain <= np.float32(half_shadow_gain(clouds))
            if covered is not None:
                shaded &= ~covered
            shadow_fraction = float(np.count_nonzero(shaded & ground & ~hidden)) / n_ground
    truths = ()
    if vehicles:
        def ground_depth(u: float, v: float) -> float:  # full-frame pixel -> region pixel
            ur = min(max(u - u0, 0), cam.width_px - 1)
            vr = min(max(v - v0, 0), cam.height_px - 1)
            return ground_depth_roi(ur, vr)

        truths = draw_vehicles(rgb, camera, (u0, v0), C, R_nc, vehicles, options.near_m,
                               options.far_m, ground_depth, obstacles,
                               None if clouds is None else clouds.hides)
    rgb = apply_effects(rgb, cam, options, rng)
    # Off-map share: pixels neither sky nor ground with data nor an obstacle (valid and sky
    # never overlap).
    seen = valid | sky if covered is None else valid | sky | covered
    offmap = 0.0 if complete else 1.0 - float(np.count_nonzero(seen)) / valid.size
    return RenderedFrame(rgb, valid, sky, offmap, truths, None if roi is None else roi_box, points, cloud_fraction,
                         shadow_fraction)
