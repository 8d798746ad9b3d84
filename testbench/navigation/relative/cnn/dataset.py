"""Training and evaluation crops for the CNN detector, rendered by our own camera renderer.

Each sample is a region of interest (ROI) of a 1920 x 1080, 120 deg camera: an observer flies
over a procedural world (flat ground, farmland / grassland / desert / canyon / urban imagery,
several seasons) with a random attitude and a front, left or right camera; other vehicles
(quadrotors ~0.5 m, fixed wings ~2.9 m span) are placed along the rays of chosen pixels at
20-200 m, with random attitude, body colour, LED layout, LED on/off states; exposure gain, sensor
noise, haze and small motion blur vary per sample. Only the ROI is rendered (the renderer's `roi`
argument), so a sample costs a few milliseconds.

Everything is drawn from a numpy Generator seeded by the caller: same settings + seed -> the
same bytes. Frames: NED local metres, body FRD, camera OpenCV; pixels full-frame (u right,
v down, integers at pixel centres) in the truth, ROI-relative in the returned targets.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, field

import numpy as np

from testbench.core.camera_geometry import CameraMount, PinholeCamera, camera_pose_ned, mount_rotation
from testbench.core.rotations import euler_to_dcm
from testbench.world.raster import LocalRaster

log = logging.getLogger(__name__)

FRAME_W, FRAME_H, HFOV_DEG = 1920, 1080, 120.0
RANGE_BINS_M = ((20.0, 50.0), (50.0, 100.0), (100.0, 150.0), (150.0, 200.0))


@dataclass(frozen=True)
class WorldVariant:
    """One procedural world: terrain name, season name, generator seed."""

    terrain: str
    season: str
    seed: int


TRAIN_WORLDS = tuple(WorldVariant(t, s, 11 + i) for i, (t, s) in enumerate([
    ("farmland", "summer"), ("farmland", "autumn"), ("grassland", "spring"), ("desert", "summer"),
    ("urban", "summer"), ("urban", "winter"), ("canyon", "autumn"), ("grassland", "winter")]))
# Held out: other seeds (other layouts) and other terrain/season pairs.
EVAL_WORLDS = tuple(WorldVariant(t, s, 101 + i) for i, (t, s) in enumerate([
    ("farmland", "spring"), ("desert", "autumn"), ("urban", "autumn"), ("canyon", "summer"),
    ("grassland", "summer"), ("farmland", "winter")]))


@dataclass(frozen=True)
class DataSettings:
    """What a sample set looks like.

    crop_px: side of the square ROI; worlds: world variants drawn from; world_size_km,
    world_gsd_m: procedural world size and resolution; range_m: (min, max) target range;
    p_negative: share of crops with no vehicle; p_second: share with a second vehicle;
    p_fixed_wing: share of vehicles that are fixed wings; p_leds_off: share of vehicles with all
    LEDs off (the rest blink each LED on with probability 0.6); altitude_m: observer height
    above ground range; noise_std_max: upper bound of the per-sample pixel noise (DN).
    """

    crop_px: int = 96
    worlds: tuple[WorldVariant, ...] = TRAIN_WORLDS
    world_size_km: float = 3.0
    world_gsd_m: float = 1.5
    range_m: tuple[float, float] = (20.0, 200.0)
    p_negative: float = 0.2
    p_second: float = 0.15
    p_fixed_wing: float = 0.35
    p_leds_off: float = 0.2
    altitude_m: tuple[float, float] = (20.0, 300.0)
    noise_std_max: float = 4.0

    def to_dict(self) -> dict:
        d = asdict(self)
        d["worlds"] = [f"procedural:{w.terrain}?seed={w.seed}&season={w.season}" for w in self.worlds]
        return d


@dataclass
class Sample:
    """One ROI: image (h, w, 3) uint8 RGB; centres_px (n, 2) and sizes_px (n, 2) (box width,
    height) of the visible vehicles whose centre lies in the ROI, ROI pixel coordinates;
    ranges_m (n,); roi (u0, v0, u1, v1) in the full frame; kind: 'quad'/'fixed_wing' per vehicle."""

    image: np.ndarray
    centres_px: np.ndarray
    sizes_px: np.ndarray
    ranges_m: np.ndarray
    roi: tuple[int, int, int, int]
    kinds: list[str] = field(default_factory=list)


_WORLD_CACHE: dict[tuple, LocalRaster] = {}


def world_raster(w: WorldVariant, size_km: float, gsd_m: float) -> LocalRaster:
    """The imagery of a procedural world as a LocalRaster centred on the origin (cached)."""
    key = (w, size_km, gsd_m)
    if key not in _WORLD_CACHE:
        from testbench.world.procedural import make_world

        rgb, _z, valid = make_world(w.terrain, size_km, gsd_m, w.seed, w.season)
        half = 0.5 * rgb.shape[0] * gsd_m
        _WORLD_CACHE[key] = LocalRaster(rgb, valid, half, -half, gsd_m)
        log.info("world %s ready", w)
    return _WORLD_CACHE[key]


def camera() -> PinholeCamera:
    """The paper's camera: 1920 x 1080, 120 deg horizontal field of view (f ~ 554 px)."""
    return PinholeCamera.from_hfov(FRAME_W, FRAME_H, HFOV_DEG)


def _led_layout(rng: np.random.Generator, kind: str):
    """LED positions in body FRD, divided by the vehicle size (scaled later)."""
    if kind == "quad":
        tips = [(0.233 * c, 0.233 * s, -0.02) for c, s in ((1, 1), (-1, 1), (-1, -1), (1, -1))]
        n = int(rng.integers(2, 5))
        return tips[:n]
    pts = [(0.05, 0.5, -0.05), (0.05, -0.5, -0.05), (-0.27, 0.0, -0.16), (0.3, 0.0, 0.0)]
    n = int(rng.integers(2, 5))
    return pts[:n]


_LED_COLOURS = ((255, 40, 40), (40, 255, 60), (60, 90, 255), (255, 255, 255), (255, 200, 40))


def random_vehicle(rng: np.random.Generator, vid: str, pos_ned_m: np.ndarray, s: DataSettings):
    """A VehicleAppearance with random shape, size, attitude, colour and LED states."""
    from testbench.sensors.camera.types import VehicleAppearance

    kind = "fixed_wing" if rng.random() < s.p_fixed_wing else "quad"
    size = float(rng.uniform(2.0, 3.2) if kind == "fixed_wing" else rng.uniform(0.4, 0.7))
    rpy = np.array([rng.normal(0, 0.3), rng.normal(0, 0.2), rng.uniform(-np.pi, np.pi)])
    R_nb = euler_to_dcm(np.clip(rpy, [-0.8, -0.6, -np.pi], [0.8, 0.6, np.pi]))
    grey = rng.uniform(20, 220)
    colour = tuple(int(np.clip(grey * rng.uniform(0.8, 1.2), 0, 255)) for _ in range(3))
    layout = _led_layout(rng, kind)
    n = len(layout)
    colours = tuple(_LED_COLOURS[int(i)] for i in rng.integers(0, len(_LED_COLOURS), n))
    if rng.random() < s.p_leds_off:
        on = (False,) * n
    else:
        on = tuple(bool(x) for x in rng.random(n) < 0.6)
    return VehicleAppearance(vid, np.asarray(pos_ned_m, float), R_nb, kind, size, colour,
                             tuple(tuple(size * np.asarray(p)) for p in layout), colours, on,
                             float(rng.uniform(0.02, 0.06)))


def _observer(rng: np.random.Generator, s: DataSettings):
    """Observer position (NED m), attitude R_nb and camera mount."""
    alt = rng.uniform(*s.altitude_m)
    pos = np.array([rng.uniform(-300, 300), rng.uniform(-300, 300), -alt])
    rpy = np.clip([rng.normal(0, 0.15), rng.normal(0, 0.12), rng.uniform(-np.pi, np.pi)], -0.6, 0.6)
    rpy[2] = rng.uniform(-np.pi, np.pi)
    R_nb = euler_to_dcm(np.asarray(rpy))
    yaw = float(rng.choice([0.0, 90.0, -90.0]))
    mount = CameraMount(mount_rotation(0.0, float(rng.uniform(-20.0, 5.0)), yaw), np.zeros(3))
    return pos, R_nb, mount


def _point_on_ray(cam: PinholeCamera, C, R_nc, u: float, v: float, r: float) -> np.ndarray:
    d = np.array([(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0])
    return C + r * (R_nc @ (d / np.linalg.norm(d)))


def make_sample(rng: np.random.Generator, s: DataSettings, range_m: tuple[float, float] | None = None,
                negative: bool | None = None) -> Sample:
    """Render one ROI sample (see the module docstring). range_m overrides the settings'
    range for the first vehicle; negative forces (True) or forbids (False) an empty crop."""
    from testbench.sensors.camera.render import render
    from testbench.sensors.camera.types import RenderOptions

    cam = camera()
    c = s.crop_px
    world = s.worlds[int(rng.integers(len(s.worlds)))]
    imagery = world_raster(world, s.world_size_km, s.world_gsd_m)
    pos, R_nb, mount = _observer(rng, s)
    C, R_nc = camera_pose_ned(pos, R_nb, mount)
    neg = (rng.random() < s.p_negative) if negative is None else negative
    lo, hi = range_m or s.range_m
    vehicles = []
    u = v = None
    if not neg:
        for _ in range(50):
            u, v = rng.uniform(8, FRAME_W - 8), rng.uniform(8, FRAME_H - 8)
            p = _point_on_ray(cam, C, R_nc, u, v, rng.uniform(lo, hi))
            if -p[2] > 3.0:  # above the ground with some clearance
                vehicles.append(random_vehicle(rng, "v0", p, s))
                break
    if u is None or not vehicles:
        u, v = rng.uniform(0, FRAME_W), rng.uniform(0, FRAME_H)
    u0 = int(np.clip(round(u - rng.uniform(6, c - 6)), 0, FRAME_W - c))
    v0 = int(np.clip(round(v - rng.uniform(6, c - 6)), 0, FRAME_H - c))
    roi = (u0, v0, u0 + c, v0 + c)
    if vehicles and rng.random() < s.p_second:
        u2, v2 = rng.uniform(u0 + 4, u0 + c - 4), rng.uniform(v0 + 4, v0 + c - 4)
        p = _point_on_ray(cam, C, R_nc, u2, v2, rng.uniform(*s.range_m))
        if -p[2] > 3.0:
            vehicles.append(random_vehicle(rng, "v1", p, s))
    # far_m is a camera depth: at the ROI corners of a 120 deg lens the range is ~2.2x the depth,
    # so this keeps every drawn ground point inside the world (observer within 300 m of its
    # centre; 500 m for the 3 km world) and the rest becomes haze/sky instead of black no-data.
    far_m = max(100.0, (500.0 * s.world_size_km - 300.0) / 2.4)
    opts = RenderOptions(
        far_m=far_m, gain=float(rng.uniform(0.6, 1.4)), noise_std=float(rng.uniform(0.0, s.noise_std_max)),
        haze_visibility_m=float(rng.uniform(2000.0, 40000.0)),
        motion_blur_px=tuple(float(x) for x in (rng.normal(0, 0.6, 2) if rng.random() < 0.3 else (0.0, 0.0))),
        sky_zenith_rgb=tuple(int(x) for x in np.clip(np.array([78, 128, 196]) + rng.normal(0, 15, 3), 0, 255)),
        sky_horizon_rgb=tuple(int(x) for x in np.clip(np.array([196, 212, 228]) + rng.normal(0, 12, 3), 0, 255)),
    )
    noise_rng = np.random.default_rng(rng.integers(2**63))
    frame = render(cam, mount, pos, R_nb, imagery, None, vehicles=vehicles, rng=noise_rng, roi=roi, options=opts)
    cs, ss, rs, ks = [], [], [], []
    for t, veh in zip(frame.vehicles, vehicles):
        cu, cv_ = float(t.centre_px[0]) - u0, float(t.centre_px[1]) - v0
        if t.visible and 0 <= cu < c and 0 <= cv_ < c:
            cs.append((cu, cv_))
            ss.append((t.bbox_px[2] - t.bbox_px[0], t.bbox_px[3] - t.bbox_px[1]))
            rs.append(t.range_m)
            ks.append(veh.shape)
    return Sample(frame.image, np.array(cs, float).reshape(-1, 2), np.array(ss, float).reshape(-1, 2),
                  np.array(rs, float), roi, ks)


def make_samples(n: int, seed: int, s: DataSettings, range_m=None, negative=None) -> list[Sample]:
    """n samples drawn from numpy.random.default_rng(seed) (bit-identical for a seed)."""
    rng = np.random.default_rng(seed)
    return [make_sample(rng, s, range_m, negative) for _ in range(n)]


def stack(samples: list[Sample]) -> np.ndarray:
    """(N, h, w, 3) uint8 of the samples' images."""
    return np.stack([x.image for x in samples])
