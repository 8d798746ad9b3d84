"""Renderer benchmarks (issue 3 targets), single core (cv2.setNumThreads(1)).

run_benchmarks() -> {
  "render.frame_nadir_ms", "render.frame_oblique_ms": 1920 x 1080 RGB over flat ground, 90 deg
      horizontal field of view, 300 m above ground, camera straight down / 45 deg off nadir,
      with the camera sensor's defaults (pixel noise std 2 from a seeded generator, no haze);
  "render.frame_ms": the worse of the two;
  "render.frame_haze_ms": the oblique frame with aerial perspective on (40 km visibility, as
      the swarm scenarios' cameras), for the cost of that opt-in effect;
  "render.warp_rgb_ms", "render.warp_rgba_ms": a bare cv2.warpPerspective (INTER_LINEAR) of the
      same size and the same nadir homography from the same map raster, as RGB and as RGBA
      (OpenCV's 4-channel path is about twice as fast as its 3-channel one);
  "render.warp_ms": the faster of the two, the floor of any renderer;
  "render.warp_oblique_ms": the same bare warp (faster of RGB/RGBA) with the oblique homography;
  "render.ratio_to_warp_nadir", "render.ratio_to_warp_oblique": each frame over the bare warp
      of its own pose (same run); "render.ratio_to_warp": the worse of the two;
  "render.dem_frame_ms": 1920 x 1080 over a DEM with 150 m hills (worse of nadir and 45 deg);
  "render.horizontal_full_frame_ms": a forward-looking camera (level) at 100 m: half sky;
  "render.roi_96px_ms": a 96 x 96 region of interest of the oblique frame (detector windows)}.
Every figure is the median of `repeats` timed calls after one warm-up call (caches built).
"""

from __future__ import annotations

import time

import cv2
import numpy as np

from testbench.core.camera_geometry import CameraMount, PinholeCamera, camera_pose_ned, mount_rotation
from testbench.core.rotations import euler_to_dcm
from testbench.sensors.camera.render import render
from testbench.sensors.camera.types import RenderOptions
from testbench.world.raster import LocalRaster

MAP_PX = 4096
MAP_GSD_M = 1.0
DEM_GSD_M = 8.0


def synthetic_map(seed: int = 0, n: int = MAP_PX, gsd_m: float = MAP_GSD_M) -> LocalRaster:
    """An n x n RGB texture with structure at every scale (octaves of smoothed noise), centred
    on the origin (north-up local grid)."""
    rng = np.random.default_rng(seed)
    acc = np.zeros((n, n, 3), np.float32)
    for octave in range(7):
        m = max(4, n >> (7 - octave))
        small = rng.normal(0.0, 1.0, (m, m, 3)).astype(np.float32)
        acc += cv2.resize(small, (n, n), interpolation=cv2.INTER_CUBIC) * (0.6 ** (6 - octave))
    acc = (acc - acc.mean()) / acc.std()
    img = np.clip(110.0 + 40.0 * acc, 0, 255).astype(np.uint8)
    half = 0.5 * n * gsd_m
    return LocalRaster(img, np.ones((n, n), bool), half, -half, gsd_m)


def synthetic_dem(n: int = MAP_PX * MAP_GSD_M / DEM_GSD_M, gsd_m: float = DEM_GSD_M,
                  relief_m: float = 150.0, seed: int = 1) -> LocalRaster:
    """Rolling hills (smoothed noise scaled to `relief_m` peak to peak) on the same area."""
    n = int(n)
    rng = np.random.default_rng(seed)
    small = rng.normal(0.0, 1.0, (12, 12)).astype(np.float32)
    h = cv2.resize(small, (n, n), interpolation=cv2.INTER_CUBIC)
    h = (h - h.min()) / (h.max() - h.min()) * relief_m
    half = 0.5 * n * gsd_m
    return LocalRaster(h.astype(np.float32), np.ones((n, n), bool), half, -half, gsd_m)


def _median_ms(fn, repeats: int) -> float:
    fn()  # warm-up: pyramids, lens maps, noise field
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def run_benchmarks(repeats: int = 9, seed: int = 0) -> dict[str, float]:
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        imagery = synthetic_map(seed)
        dem = synthetic_dem()
        cam = PinholeCamera.from_hfov(1920, 1080, 90.0)
        nadir = CameraMount(mount_rotation(0.0, -90.0, 0.0), np.zeros(3))
        oblique = CameraMount(mount_rotation(0.0, -45.0, 0.0), np.zeros(3))
        forward = CameraMount(mount_rotation(0.0, 0.0, 0.0), np.zeros(3))
        R_nb = euler_to_dcm(np.radians([0.0, 0.0, 30.0]))
        pos = np.array([0.0, 0.0, -300.0])
        opts = RenderOptions(noise_std=2.0)
        rng = np.random.default_rng(seed)
        out: dict[str, float] = {}

        def frame(mount, elevation=None, p=pos, roi=None):
            return lambda: render(cam, mount, p, R_nb, imagery, elevation, rng=rng, roi=roi, options=opts)

        out["render.frame_nadir_ms"] = _median_ms(frame(nadir), repeats)
        out["render.frame_oblique_ms"] = _median_ms(frame(oblique), repeats)
        out["render.frame_ms"] = max(out["render.frame_nadir_ms"], out["render.frame_oblique_ms"])
        hazy = RenderOptions(noise_std=2.0, haze_visibility_m=40000.0)
        out["render.frame_haze_ms"] = _median_ms(
            lambda: render(cam, oblique, pos, R_nb, imagery, None, rng=rng, options=hazy), repeats)

        # The bare warp: same output size, same nadir homography (ground NE -> map pixels).
        from testbench.sensors.camera.flat import plane_view

        A = np.linalg.inv(imagery.affine_ne_from_colrow())
        rgb = np.ascontiguousarray(imagery.data)
        rgba = cv2.cvtColor(rgb, cv2.COLOR_RGB2RGBA)  # OpenCV warps 4 channels faster than 3

        def warp(src, mount):
            view = plane_view(cam, *camera_pose_ned(pos, R_nb, mount), 0.0, A, opts.near_m, opts.far_m)
            return lambda: cv2.warpPerspective(src, view.H_map, (cam.width_px, cam.height_px),
                                               flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                               borderMode=cv2.BORDER_CONSTANT)

        out["render.warp_rgb_ms"] = _median_ms(warp(rgb, nadir), repeats)
        out["render.warp_rgba_ms"] = _median_ms(warp(rgba, nadir), repeats)
        out["render.warp_ms"] = min(out["render.warp_rgb_ms"], out["render.warp_rgba_ms"])
        # The oblique homography samples the map more sparsely (more cache misses): its own floor.
        out["render.warp_oblique_ms"] = min(_median_ms(warp(rgba, oblique), repeats),
                                            _median_ms(warp(rgb, oblique), repeats))
        out["render.ratio_to_warp_nadir"] = out["render.frame_nadir_ms"] / out["render.warp_ms"]
        out["render.ratio_to_warp_oblique"] = out["render.frame_oblique_ms"] / out["render.warp_oblique_ms"]
        out["render.ratio_to_warp"] = max(out["render.ratio_to_warp_nadir"], out["render.ratio_to_warp_oblique"])

        dem_pos = np.array([0.0, 0.0, -450.0])  # 300 m above the highest hills
        out["render.dem_frame_nadir_ms"] = _median_ms(frame(nadir, dem, dem_pos), max(3, repeats // 2))
        out["render.dem_frame_oblique_ms"] = _median_ms(frame(oblique, dem, dem_pos), max(3, repeats // 2))
        out["render.dem_frame_ms"] = max(out["render.dem_frame_nadir_ms"], out["render.dem_frame_oblique_ms"])

        out["render.horizontal_full_frame_ms"] = _median_ms(frame(forward, None, np.array([0.0, 0.0, -100.0])), repeats)
        u0, v0 = 1200, 300
        out["render.roi_96px_ms"] = _median_ms(frame(oblique, roi=(u0, v0, u0 + 96, v0 + 96)), 5 * repeats)
        return out
    finally:
        cv2.setNumThreads(threads)
