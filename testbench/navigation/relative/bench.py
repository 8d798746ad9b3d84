"""Offline scene simulation and benchmarks of relative navigation (not flight code: it builds
the truth it scores against, and renders with the camera renderer).

`simulate_relnav(...)`: one observer with front/left/right cameras and neighbours flying the
same velocity at formation offsets; frames rendered with LED states from led_code, UWB ranges
with noise and NLOS outliers, an attitude estimate with a small error; the "relnav" aid runs
on it (regions from its render_requests, or full frames). Returns errors, ID statistics and
timings. `run_benchmarks()` gives the figures for `testbench bench`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from testbench.core import led_code
from testbench.core.camera_geometry import CameraMount, PinholeCamera, mount_rotation
from testbench.core.interfaces import BuildContext, GeodeticOrigin
from testbench.core.messages import NavEstimate, UwbRange
from testbench.core.rotations import euler_to_dcm, euler_to_quat
from testbench.navigation.relative.aid import RelnavAid
from testbench.sensors.camera import RenderOptions, VehicleAppearance, render
from testbench.world.raster import LocalRaster

ORIGIN = GeodeticOrigin(np.radians(34.0), np.radians(-117.0), 300.0)
# Anchor LED 0 (always on, green) on top; data LEDs (red) at the arm tips: the detector's
# data_hue_deg = 0 tells the chips apart by colour even when the LEDs overlap at 200 m.
QUAD_LEDS_B_M = ((0.0, 0.0, -0.20), (0.165, 0.165, -0.03), (0.165, -0.165, -0.03), (-0.165, -0.165, -0.03), (-0.165, 0.165, -0.03))
LED_RGB = ((40, 255, 40),) + ((255, 40, 40),) * 4
# The LED detector's centre over the CG (body z, m), per blink chip: the top anchor alone
# (chip 0, 0.20 m up: -0.21 to -0.23 measured) and all five LEDs (chip 1, brightness-weighted:
# the four arm LEDs pull it down to -0.04 to +0.02), on rendered quads at 60-250 m; and their
# mean, used before a track's chips are read.
LED_CENTROID_BY_CHIP_B_M = ((0.0, 0.0, -0.22), (0.0, 0.0, -0.02))
LED_CENTROID_B_M = (0.0, 0.0, -0.12)
LED_DETECTOR = {"type": "led", "params": {"data_hue_deg": 0.0}}
MOUNTS = {"front": 0.0, "left": -90.0, "right": 90.0}


@dataclass(frozen=True)
class _Camera:
    """What the aid reads from a camera sensor."""

    camera: PinholeCamera
    mount: CameraMount
    rate_hz: float = 10.0


@dataclass(frozen=True)
class _Uwb:
    lever: tuple = (0.0, 0.0, 0.0)
    rate_hz: float = 100.0


@dataclass(frozen=True)
class SimFrame:
    """A camera frame as the aid accepts it: named camera, rendered regions with truth."""

    t_s: float
    camera_name: str
    regions: tuple


@dataclass
class SimResult:
    errors_m: list = field(default_factory=list)        # |est - truth| per neighbour per frame (after settling)
    sigmas_m: list = field(default_factory=list)        # the estimate's claimed sigma_m, same order (nan: none)
    frame_ms: list = field(default_factory=list)        # aid time per camera frame
    render_ms: list = field(default_factory=list)       # renderer time per camera frame
    render_px: list = field(default_factory=list)       # rendered pixels per camera frame
    counters: dict = field(default_factory=dict)
    table: dict = field(default_factory=dict)


def ground_raster(seed: int = 0, size_px: int = 1024, gsd_m: float = 1.0) -> LocalRaster:
    """A smooth random green-brown texture centred on the origin."""
    rng = np.random.default_rng(seed)
    import cv2

    base = rng.normal(0.0, 1.0, (size_px // 16, size_px // 16)).astype(np.float32)
    fine = rng.normal(0.0, 1.0, (size_px, size_px)).astype(np.float32)
    t = cv2.resize(base, (size_px, size_px), interpolation=cv2.INTER_CUBIC) + 0.3 * cv2.GaussianBlur(fine, (0, 0), 2.0)
    t = (t - t.min()) / (t.max() - t.min())
    img = np.stack([90 + 60 * t, 110 + 50 * t, 70 + 40 * t], axis=-1).astype(np.uint8)
    half = size_px * gsd_m / 2
    return LocalRaster(img, np.ones(img.shape[:2], bool), half, -half, gsd_m)


def simulate_relnav(offsets_ned_m, duration_s: float = 4.0, width_px: int = 960, height_px: int = 540,
                    hfov_deg: float = 120.0, detector: dict | None = None, roi: bool = True, seed: int = 0,
                    att_error_deg: float = 0.05, nlos_every: int = 0, settle_s: float = 2.0,
                    cameras=("front", "left", "right"), aid_params: dict | None = None,
                    offset_rates_ned_mps=None) -> SimResult:
    """Run the aid on rendered frames of neighbours at NED offsets (m) from the observer,
    offsets_ned_m (n, 3) at t = 0 moving at offset_rates_ned_mps (n, 3; default still).

    The whole group flies north at 5 m/s 60 m above flat ground; the observer rolls/pitches
    slightly (3 deg, 0.2 Hz). nlos_every: every n-th UWB range gets a +2..10 m NLOS excess.
    res.errors_m holds, per frame after settle_s, each neighbour's error in turn (nan while
    the aid reports no estimate of it)."""
    rng = np.random.default_rng(seed)
    ids = ("self",) + tuple(f"n{i}" for i in range(len(offsets_ned_m)))
    ctx = BuildContext("self", ids, ORIGIN, physics_rate_hz=100.0)
    cam = PinholeCamera.from_hfov(width_px, height_px, hfov_deg)
    sensors = {name: _Camera(cam, CameraMount(mount_rotation(0.0, 0.0, MOUNTS[name]), np.array([0.1, 0.0, 0.0])))
               for name in cameras}
    sensors["uwb"] = _Uwb()
    params = dict(cameras=list(cameras), detector=detector or LED_DETECTOR, roi={"enabled": roi},
                  target_offset_b_m=LED_CENTROID_B_M if detector is None else (0.0, 0.0, 0.0),
                  target_offset_by_chip_b_m=LED_CENTROID_BY_CHIP_B_M if detector is None else None)
    params.update(aid_params or {})
    aid = RelnavAid(RelnavAid.Params(**params), ctx=ctx, sensors=sensors, rng=np.random.default_rng(seed + 1))
    imagery = ground_raster(seed)
    opts = RenderOptions(noise_std=2.0, haze_visibility_m=40000.0)  # as the swarm scenarios' cameras
    offs0 = np.asarray(offsets_ned_m, float)
    rates = np.zeros_like(offs0) if offset_rates_ned_mps is None else np.asarray(offset_rates_ned_mps, float)
    vel = np.array([5.0, 0.0, 0.0])
    res = SimResult()
    n_range = 0
    for k in range(int(round(duration_s * 10))):
        t = 0.1 * k
        offs = offs0 + rates * t
        # UWB: one TDMA cycle (every peer once) in the 100 ms before the frame.
        for j, off in enumerate(offs):
            n_range += 1
            rho = np.linalg.norm(off) + rng.normal(0.0, 0.1)
            if nlos_every and n_range % nlos_every == 0:
                rho += rng.uniform(2.0, 10.0)
            aid.process(UwbRange(t - 0.1 + 0.01 * (j + 1), ids[j + 1], float(rho), -80.0), _estimate(t, vel, rng, 0.0))
        rpy = np.radians([3.0 * np.sin(0.4 * np.pi * t), 2.0 * np.cos(0.4 * np.pi * t), 0.0])
        R_nb = euler_to_dcm(rpy)
        pos = np.array([0.0, 0.0, -60.0]) + vel * t
        est = _estimate(t, vel, rng, att_error_deg, rpy, pos)
        fi = led_code.frame_index(t, 10.0)
        vehicles = [VehicleAppearance(ids[j + 1], pos + off, np.eye(3), "quad", 0.5, led_positions_b_m=QUAD_LEDS_B_M,
                                      led_colours=LED_RGB, led_on=led_code.led_states(j + 1, fi, len(QUAD_LEDS_B_M)), led_radius_m=0.03)
                    for j, off in enumerate(offs)]
        requests = aid.render_requests(t)
        for name in cameras:
            c = sensors[name]
            t0 = time.perf_counter()
            if not requests[name]:
                continue  # nothing to look at in this camera this frame
            regions = tuple(render(cam, c.mount, pos, R_nb, imagery, vehicles=vehicles, rng=rng,
                                   roi=None if r == (0, 0, cam.width_px, cam.height_px) else r, options=opts)
                            for r in requests[name])
            t1 = time.perf_counter()
            aid.process(SimFrame(t, name, regions), est)
            t2 = time.perf_counter()
            res.render_ms.append(1e3 * (t1 - t0))
            res.frame_ms.append(1e3 * (t2 - t1))
            res.render_px.append(sum(r.image.shape[0] * r.image.shape[1] for r in regions))
        if t >= settle_s:
            table = aid.controller_input(t)
            for j, off in enumerate(offs):
                e = table.get(ids[j + 1])
                res.errors_m.append(np.nan if e is None else float(np.linalg.norm(e.pos_ned_m - off)))
                res.sigmas_m.append(np.nan if e is None else float(e.sigma_m))
    res.counters = aid.all_counters()
    res.table = aid.controller_input()
    return res


def _estimate(t, vel, rng, att_error_deg, rpy=(0.0, 0.0, 0.0), pos=(0.0, 0.0, -60.0)) -> NavEstimate:
    err = np.radians(att_error_deg) * rng.normal(0.0, 1.0, 3) if att_error_deg > 0 else np.zeros(3)
    r = np.asarray(rpy, float) + err
    cov_att = np.eye(3) * np.radians(max(att_error_deg, 1e-3)) ** 2
    Z = np.zeros((3, 3))
    return NavEstimate(t, np.asarray(pos, float), np.asarray(vel, float), euler_to_quat(r), r, np.zeros(3), Z, Z, cov_att)


ARROWHEAD_FROM_4_M = [  # relative to vehicle 4 (row 2 centre) of the paper's arrowhead, 100 m lattice
    (173.2, 0.0, 0.0), (86.6, -50.0, 0.0), (86.6, 50.0, 0.0), (0.0, -100.0, 0.0), (0.0, 100.0, 0.0),
    (-86.6, -150.0, 0.0), (-86.6, -50.0, 0.0), (-86.6, 50.0, 0.0), (-86.6, 150.0, 0.0)]


def run_benchmarks() -> dict[str, float]:
    """Relative navigation figures at paper settings (1920 x 1080, 120 deg, LED detector),
    vehicle 4 of the arrowhead seeing its 9 neighbours for 6 s (full frame every 10)."""
    from testbench.navigation.relative.detectors import LedDetector

    out: dict[str, float] = {}
    res = simulate_relnav(ARROWHEAD_FROM_4_M, duration_s=6.0, width_px=1920, height_px=1080, settle_s=3.0)
    e = np.asarray(res.errors_m, float)
    out["relnav.error_m.mean"] = float(np.nanmean(e))
    out["relnav.error_m.max"] = float(np.nanmax(e))
    out["relnav.coverage"] = float(np.mean(np.isfinite(e)))
    c = res.counters
    out["relnav.id_wrong_fraction"] = c["id_wrong"] / max(c["id_checks"], 1)
    out["relnav.aid_ms_per_frame.mean"] = float(np.mean(res.frame_ms))
    out["relnav.render_ms_per_frame.mean"] = float(np.mean(res.render_ms))
    out["relnav.rendered_fraction.mean"] = float(np.mean(res.render_px) / (1920 * 1080))
    res_o = simulate_relnav(ARROWHEAD_FROM_4_M, duration_s=4.0, width_px=1920, height_px=1080, settle_s=2.0,
                            detector={"type": "oracle", "params": {"sigma_px": 0.5}})
    e = np.asarray(res_o.errors_m, float)
    out["relnav.oracle.error_m.mean"] = float(np.nanmean(e))
    out["relnav.oracle.error_m.max"] = float(np.nanmax(e))
    out["relnav.oracle.aid_ms_per_frame.mean"] = float(np.mean(res_o.frame_ms))
    # LED detector alone on a 96 x 96 region and on a full frame.
    img = np.full((1080, 1920, 3), 100, np.uint8)
    det = LedDetector()
    for name, im in (("roi96", img[:96, :96]), ("full", img)):
        t0 = time.perf_counter()
        for _ in range(5):
            det.detect(im)
        out[f"relnav.led_detect_ms.{name}"] = 1e3 * (time.perf_counter() - t0) / 5
    return out
