"""The camera as a sensor in the loop: renders what it sees from the TRUE pose at its rate.

`CameraSensor` (registered as sensor type "camera") holds the camera model of the paper's
table 1 (size, intrinsics or field of view, lens distortion, noise, clipping, mounting angles
and lever arm, frame rate, exposure/gain, vignetting, motion blur). What navigation is given
can differ from what renders:
- the mounting as calibrated (`.mount`) from the true one (`.true_mount`) by a boresight error
  (`mount_error_deg`, `mount_error_sigma_deg`);
- the intrinsics as calibrated (`.camera`) from the true ones (`.true_camera`) by a focal
  length and a principal point error (`focal_error_rel`, `principal_point_error_px` and their
  sigmas);
- the frame's stamp from its exposure by a clock offset (`time_offset_s`: the frame is seen
  from the pose of its exposure);
- a rolling shutter (`readout_s`) exposes the rows one after another, each band of rows
  rendered from the pose of its own time (rolling_shutter.py).
At each frame it asks the world for the imagery (and elevation) under its footprint at a
suitable ground sample, the other vehicles in view with their LED states, and which regions to
render (a relative-navigation aid may ask for regions around its tracks only); then it calls
the pure renderer.

The world object it reads is the engine's tick view (`CameraWorld` protocol below).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any, Protocol, Sequence

import numpy as np
import pydantic

from testbench.core.camera_geometry import CameraMount, PinholeCamera, camera_pose_ned, mount_rotation
from testbench.core.errors import InputError
from testbench.core.interfaces import BuildContext, Sensor
from testbench.core.messages import TruthState
from testbench.core.registry import ParamsModel, register
from testbench.core.rotations import quat_to_dcm
from testbench.sensors.camera.departures import exposure_pose, misaligned, miscalibrated
from testbench.sensors.camera.render import render
from testbench.sensors.camera.rolling_shutter import render_rolling
from testbench.sensors.camera.types import RenderedFrame, RenderOptions, VehicleAppearance, VehicleTruth
from testbench.sensors.camera.vehicles import draw_vehicles
from testbench.world.raster import LocalRaster

log = logging.getLogger(__name__)


class CameraWorld(Protocol):
    """What the camera needs from the world at a tick (the engine's TickWorldView)."""

    t_s: float
    self_id: str

    def imagery_for(self, bounds_ne_m: tuple[float, float, float, float], gsd_m: float) -> LocalRaster | None:
        """Imagery covering (north_min, north_max, east_min, east_max) at about gsd_m."""

    def elevation_for(self, bounds_ne_m: tuple[float, float, float, float]) -> LocalRaster | None:
        """Terrain heights (m above the origin) over the bounds, None on flat ground."""

    def appearances(self, t_s: float) -> Sequence[VehicleAppearance]:
        """Every other vehicle as a camera would see it now (LED states set)."""

    def render_requests(self, camera_name: str) -> list[tuple[int, int, int, int]] | None:
        """Regions to render for this camera (None: the whole frame; []: nothing)."""

    def clouds(self):
        """The cloud sheet now (world.clouds.CloudView), None under a clear sky (optional)."""


@dataclass(frozen=True)
class CameraFrame:
    """One camera frame (the message a camera sensor produces).

    t_s; camera_name; image (H, W, 3) uint8 RGB of the whole frame, or None when only regions
    were rendered; regions: the rendered parts (RenderedFrame, each with its roi and the truth of
    the vehicles it shows); vehicles: truth annotations (full-frame pixels) of the other vehicles;
    offmap_fraction: share of the rendered pixels that look at ground off the map (no-data);
    camera, mount: the camera model (K, distortion) and the mounting as calibrated (R_bc
    camera->body, lever arm: CameraSensor.camera and .mount, not the true ones when the camera
    has an intrinsics or a boresight error), which is what navigation may use; cloud_fraction: share of the rendered
    pixels looking at the ground that a cloud takes half the light of or more;
    shadow_fraction: share of them that show ground in a cloud's shadow (RenderedFrame; both
    truth, for scoring alone, as offmap_fraction); exposure_pos_ned_m (3,): where the vehicle
    truly was at the exposure (NED m at the origin: the tick's position unless the camera's clock
    is off, CameraParams.time_offset_s), truth as well; None from a frame not rendered.
    """

    t_s: float
    camera_name: str
    image: np.ndarray | None
    regions: tuple[RenderedFrame, ...]
    vehicles: tuple[VehicleTruth, ...]
    offmap_fraction: float
    camera: PinholeCamera | None = None
    mount: CameraMount | None = None
    cloud_fraction: float = 0.0
    shadow_fraction: float = 0.0
    exposure_pos_ned_m: np.ndarray | None = None


class CameraParams(ParamsModel):
    """The camera model (paper table 1); angles in degrees, lengths in metres, rates in Hz."""

    rate_hz: float = pydantic.Field(2.0, gt=0)
    width_px: int = pydantic.Field(1920, ge=16)
    height_px: int = pydantic.Field(1080, ge=16)
    hfov_deg: float | None = pydantic.Field(120.0, gt=1, lt=179)
    fx: float | None = pydantic.Field(None, gt=0)
    fy: float | None = pydantic.Field(None, gt=0)
    cx: float | None = None
    cy: float | None = None
    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    noise_mean: float = 0.0
    noise_std: float = pydantic.Field(2.0, ge=0)
    near_m: float = pydantic.Field(0.1, gt=0)
    far_m: float = pydantic.Field(20000.0, gt=0)
    mount_roll_deg: float = 0.0
    mount_pitch_deg: float = -90.0
    mount_yaw_deg: float = 0.0
    lever_arm_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mount_error_deg: tuple[float, float, float] = pydantic.Field(
        (0.0, 0.0, 0.0), description="boresight error: the true mounting turned from the calibrated one by these "
        "roll, pitch, yaw angles about the body's x, y, z axes (deg; Z-Y-X); navigation knows only the calibrated one")
    mount_error_sigma_deg: float = pydantic.Field(
        0.0, ge=0, description="a random boresight error on top of mount_error_deg, drawn per axis once per run "
        "(deg, 1 sigma) from the run's seeded streams when the vehicle is built")
    time_offset_s: float = pydantic.Field(
        0.0, ge=-0.25, le=0.25, description="the frame's time stamp minus its true exposure time (s): a camera clock "
        "not synchronised with the IMU's; positive, the frame was taken that long before its stamp. Navigation sees "
        "only the stamp")
    time_offset_sigma_s: float = pydantic.Field(
        0.0, ge=0, le=0.1, description="a random time offset on top of time_offset_s, drawn once per run (s, 1 sigma) "
        "from the run's seeded streams when the vehicle is built")
    focal_error_rel: float = pydantic.Field(
        0.0, ge=-0.05, le=0.05, description="the true focal length's error relative to the calibrated one: the lens "
        "renders with fx (1 + e), fy (1 + e); navigation knows only the calibrated intrinsics")
    focal_error_sigma_rel: float = pydantic.Field(
        0.0, ge=0, le=0.02, description="a random focal length error on top of focal_error_rel, drawn once per run "
        "(relative, 1 sigma) from the run's seeded streams when the vehicle is built")
    principal_point_error_px: tuple[float, float] = pydantic.Field(
        (0.0, 0.0), description="the true principal point minus the calibrated one (px: u right, v down); navigation "
        "knows only the calibrated one")
    principal_point_error_sigma_px: float = pydantic.Field(
        0.0, ge=0, le=20.0, description="a random principal point error on top of principal_point_error_px, drawn once "
        "per run (px per axis, 1 sigma)")
    readout_s: float = pydantic.Field(
        0.0, ge=0, le=0.1, description="rolling shutter: the time from the first row's exposure to the last's (s; 0: a "
        "global shutter). The stamp and time_offset_s refer to the middle row; row v is exposed readout_s * "
        "((v + 0.5) / height_px - 0.5) after it. Less than the frame interval")
    readout_bands: int = pydantic.Field(
        24, ge=2, le=1080, description="a rolling-shutter frame is rendered in this many bands of rows, each at the true "
        "pose of its middle row (the seams are the pose's change over readout_s / readout_bands)")
    gain: float = pydantic.Field(1.0, gt=0)
    vignetting: float = pydantic.Field(0.0, ge=0, le=1)
    exposure_s: float = pydantic.Field(0.0, ge=0, description="motion blur from body rates over the exposure")
    haze_visibility_m: float | None = pydantic.Field(None, gt=0, description="aerial perspective: 63 % towards the horizon colour at this range (m); None: no haze")
    max_window_px: int = pydantic.Field(4096, ge=256, description="largest map window side read per frame")
    render_vehicles: bool = True
    render_image: bool = pydantic.Field(True, description="False: no pixels (black frames at no cost), only the other vehicles' truth annotations (oracle detector studies)")

    @pydantic.model_validator(mode="after")
    def _intrinsics(self) -> "CameraParams":
        if self.fx is None and self.hfov_deg is None:
            raise ValueError("give hfov_deg or fx (and fy, cx, cy)")
        if self.readout_s * self.rate_hz >= 1.0:
            raise ValueError(f"readout_s {self.readout_s:g} s must be shorter than the frame interval 1 / rate_hz = "
                             f"{1.0 / self.rate_hz:g} s (a sensor reads one frame out before it starts the next)")
        return self


@register("sensor", "camera")
class CameraSensor(Sensor):
    """A camera rendering frames of the world from the vehicle's true pose."""

    Params = CameraParams

    def __init__(self, params: CameraParams, *, ctx: BuildContext, **_: Any):
        p = params
        self.params = p
        self.name = "camera"
        self.rate_hz = float(p.rate_hz)
        ratio = ctx.physics_rate_hz / self.rate_hz
        if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
            raise InputError(f"camera.rate_hz: {self.rate_hz:g} Hz must divide the physics rate {ctx.physics_rate_hz:g} Hz")
        dist = (p.k1, p.k2, p.p1, p.p2, p.k3)
        if p.fx is not None:
            fy = p.fy if p.fy is not None else p.fx
            cx = p.cx if p.cx is not None else (p.width_px - 1) / 2.0
            cy = p.cy if p.cy is not None else (p.height_px - 1) / 2.0
            self.camera = PinholeCamera(p.width_px, p.height_px, p.fx, fy, cx, cy, dist)
        else:
            self.camera = PinholeCamera.from_hfov(p.width_px, p.height_px, p.hfov_deg, dist)
        # Camera -> body from the mounting angles (core.camera_geometry convention): the mounting
        # as calibrated, which is all navigation is given. The true one renders; it differs by
        # the boresight error, whose random part draw_constant_errors adds.
        self.mount = CameraMount(mount_rotation(p.mount_roll_deg, p.mount_pitch_deg, p.mount_yaw_deg), np.asarray(p.lever_arm_b_m, float))
        self.boresight_error_deg = np.asarray(p.mount_error_deg, float)
        """(3,) the true mounting's turn from the calibrated one (roll, pitch, yaw about body x, y, z; deg)."""
        self.true_mount = misaligned(self.mount, self.boresight_error_deg)
        self.time_offset_s = float(p.time_offset_s)
        """The frame's stamp minus its true exposure time (s; time_offset_s plus the run's draw)."""
        # The intrinsics as calibrated (.camera, what navigation is given) and the true ones that
        # render: they differ by the calibration error, whose random part draw_constant_errors adds.
        self.intrinsics_error = (float(p.focal_error_rel), *(float(x) for x in p.principal_point_error_px))
        """(focal length relative error, principal point error u, v (px)): the true intrinsics'
        departure from the calibrated ones."""
        self.true_camera = miscalibrated(self.camera, self.intrinsics_error)
        self._options = RenderOptions(
            near_m=p.near_m, far_m=p.far_m, noise_mean=p.noise_mean, noise_std=p.noise_std, gain=p.gain,
            vignetting=p.vignetting, haze_visibility_m=p.haze_visibility_m,
        )
        self._last: tuple[float, CameraFrame | None] | None = None
        self._warned_offmap = False
        # Unit rays of the frame's border (camera frame), for the ground footprint.
        self._border_rays_c = _border_rays(self.true_camera)

    # -- Sensor ---------------------------------------------------------------------------
    def measure(self, truth: TruthState, world: Any, rng: np.random.Generator) -> CameraFrame | None:
        if self._last is not None and self._last[0] == truth.t_s:
            return self._last[1]
        frame = self._render(truth, world, rng)
        self._last = (truth.t_s, frame)
        return frame

    # -- internals ------------------------------------------------------------------------
    def draw_constant_errors(self, rng: np.random.Generator) -> None:
        """Draw the run's random boresight error (mount_error_sigma_deg per axis, on top of
        mount_error_deg), then its random time offset (time_offset_sigma_s, on top of
        time_offset_s), then its random intrinsics error (focal_error_sigma_rel, then
        principal_point_error_sigma_px per axis), from rng, a stream of its own (the engine's vehicle builder calls it
        once, before the run: so the record holds them, whichever process renders). Nothing is
        drawn without a sigma."""
        p = self.params
        if p.mount_error_sigma_deg > 0.0:
            self.boresight_error_deg = np.asarray(p.mount_error_deg, float) + p.mount_error_sigma_deg * rng.standard_normal(3)
            self.true_mount = misaligned(self.mount, self.boresight_error_deg)
            log.info("camera %s: boresight error %.4f / %.4f / %.4f deg (roll / pitch / yaw, body axes)",
                     self.name, *self.boresight_error_deg)
        if p.time_offset_sigma_s > 0.0:
            self.time_offset_s = float(np.clip(p.time_offset_s + p.time_offset_sigma_s * rng.standard_normal(), -0.25, 0.25))
            log.info("camera %s: time offset %.4f s (stamp minus exposure)", self.name, self.time_offset_s)
        if p.focal_error_sigma_rel > 0.0 or p.principal_point_error_sigma_px > 0.0:
            focal, du, dv = self.intrinsics_error
            if p.focal_error_sigma_rel > 0.0:
                focal = float(np.clip(focal + p.focal_error_sigma_rel * rng.standard_normal(), -0.05, 0.05))
            if p.principal_point_error_sigma_px > 0.0:
                du, dv = (float(x) for x in (du, dv) + p.principal_point_error_sigma_px * rng.standard_normal(2))
            self.intrinsics_error = (focal, du, dv)
            self.true_camera = miscalibrated(self.camera, self.intrinsics_error)
            self._border_rays_c = _border_rays(self.true_camera)
            log.info("camera %s: focal length error %.5f, principal point error %.3f / %.3f px", self.name, focal, du, dv)

    def _render(self, truth: TruthState, world: Any, rng: np.random.Generator) -> CameraFrame | None:
        # The true pose at the exposure (the tick's, unless the camera's clock is off).
        pos, R_nb = exposure_pose(truth, self.time_offset_s)
        requests = world.render_requests(self.name) if hasattr(world, "render_requests") else None
        if requests is not None and len(requests) == 0:
            return None  # the aid asked for nothing this frame: nothing to render
        centre, R_nc = camera_pose_ned(pos, R_nb, self.true_mount)
        if not self.params.render_image:
            return self._annotations_only(truth, world, centre, R_nc, requests)
        imagery = None
        elevation = None
        bounds_gsd = self._footprint(centre, R_nc, world)
        if bounds_gsd is not None and self.params.readout_s > 0.0:
            bounds_gsd = self._with_readout_footprints(bounds_gsd, truth, world)
        if bounds_gsd is not None:
            bounds, gsd = bounds_gsd
            imagery = world.imagery_for(bounds, gsd)
            elevation = world.elevation_for(bounds)
        if imagery is None:  # no imagery in this world (or the camera sees no ground): sky only
            imagery = _BLANK
        vehicles = tuple(world.appearances(truth.t_s)) if self.params.render_vehicles and hasattr(world, "appearances") else ()
        opts = self._options
        if self.params.exposure_s > 0.0:
            opts = _with_motion_blur(opts, self.true_camera, R_nc, truth, self.params.exposure_s)
        obstacles = tuple(getattr(world, "obstacles", ()) or ())
        clouds = world.clouds() if hasattr(world, "clouds") else None
        rois = [None] if requests is None else list(requests)
        cam = self.true_camera
        readout = self.params.readout_s

        def render_box(box, pos_ned_m, R_nb_):
            """The region box (u0, v0, u1, v1; None: the whole frame) seen from the true pose."""
            return render(cam, self.true_mount, pos_ned_m, R_nb_, imagery, elevation, vehicles=vehicles, rng=rng,
                          roi=box, options=opts, obstacles=obstacles, clouds=clouds)

        def render_band(box, delay_s):
            """A band of rows exposed delay_s after the middle row (rolling shutter)."""
            whole_band = box == (0, 0, cam.width_px, cam.height_px)
            return render_box(None if whole_band else box, *exposure_pose(truth, self.time_offset_s - delay_s))

        parts = []
        for roi in rois:
            full = roi is None or tuple(roi) == (0, 0, cam.width_px, cam.height_px)
            box = (0, 0, cam.width_px, cam.height_px) if full else _clip_roi(cam, roi)
            if readout > 0.0 and box[2] > box[0] and box[3] > box[1]:  # (an empty box: the renderer's error)
                parts.append(render_rolling(box, cam.height_px, readout, self.params.readout_bands, render_band,
                                            _merge_truths, full))
            else:
                parts.append(render_box(None if full else roi, pos, R_nb))
        whole = next((p for p in parts if p.roi is None), None)
        truths = _merge_truths(parts)
        n_px = sum(p.valid.size for p in parts)
        offmap = sum(p.offmap_fraction * p.valid.size for p in parts) / max(n_px, 1)
        n_ground = [int(p.valid.size - np.count_nonzero(p.sky)) for p in parts]
        clouded = sum(p.cloud_fraction * n for p, n in zip(parts, n_ground)) / max(sum(n_ground), 1)
        shadowed = sum(p.shadow_fraction * n for p, n in zip(parts, n_ground)) / max(sum(n_ground), 1)
        if offmap > 0.5 and not self._warned_offmap:
            log.warning("camera %s at t=%.1f s: %.0f %% of the view is off the map (no-data, drawn black; a camera far_m "
                        "short of the map's edge draws haze and sky there instead, or use a larger map)",
                        self.name, truth.t_s, 100 * offmap)
            self._warned_offmap = True
        return CameraFrame(truth.t_s, self.name, None if whole is None else whole.image, tuple(parts), truths, offmap,
                           self.camera, self.mount, clouded, shadowed, np.asarray(pos, float))

    def _annotations_only(self, truth: TruthState, world: Any, centre: np.ndarray, R_nc: np.ndarray, requests) -> CameraFrame:
        """A frame without pixels: zero-stride black images of the requested regions, with the
        truth of the other vehicles (projected, nothing drawn; hidden by obstacles and clouds,
        not by terrain)."""
        cam = self.true_camera
        vehicles = tuple(world.appearances(truth.t_s)) if self.params.render_vehicles and hasattr(world, "appearances") else ()
        scratch = np.zeros((1, 1, 3), np.uint8)
        far = (-(10**7), -(10**7))  # the scratch region lies off every vehicle: nothing is drawn
        obstacles = tuple(getattr(world, "obstacles", ()) or ())
        clouds = world.clouds() if hasattr(world, "clouds") else None
        truths = draw_vehicles(scratch, cam, far, centre, R_nc, vehicles, self.params.near_m, self.params.far_m, None,
                               obstacles, None if clouds is None else clouds.hides) if vehicles else ()
        parts = []
        for roi in [None] if requests is None else list(requests):
            box = (0, 0, cam.width_px, cam.height_px) if roi is None else tuple(int(x) for x in roi)
            full = box == (0, 0, cam.width_px, cam.height_px)
            h, w = box[3] - box[1], box[2] - box[0]
            if h <= 0 or w <= 0:
                continue
            img = np.broadcast_to(np.zeros((1, 1, 3), np.uint8), (h, w, 3))
            flags = np.broadcast_to(np.zeros((1, 1), bool), (h, w))
            parts.append(RenderedFrame(img, flags, flags, 0.0, truths, None if full else box))
        whole = next((p for p in parts if p.roi is None), None)
        return CameraFrame(truth.t_s, self.name, None if whole is None else whole.image, tuple(parts), truths, 0.0,
                           self.camera, self.mount)

    def _with_readout_footprints(self, bounds_gsd, truth: TruthState, world: Any):
        """(bounds, gsd) of the middle row's footprint grown to hold the footprints seen from the
        poses of the first and the last rows (a rolling shutter), so that the map read holds
        every band's ground."""
        (n0, n1, e0, e1), gsd = bounds_gsd
        for delay_s in (-0.5 * self.params.readout_s, 0.5 * self.params.readout_s):
            pose = exposure_pose(truth, self.time_offset_s - delay_s)
            other = self._footprint(*camera_pose_ned(*pose, self.true_mount), world)
            if other is not None:
                (a0, a1, b0, b1), _ = other
                n0, n1, e0, e1 = min(n0, a0), max(n1, a1), min(e0, b0), max(e1, b1)
        return (n0, n1, e0, e1), gsd

    def _footprint(self, centre: np.ndarray, R_nc: np.ndarray, world: Any):
        """NE bounds of the ground the frame can see and the window's ground sample (m/px),
        or None when no border ray meets the ground within the far plane."""
        ground_down = -_ground_height(world, centre)
        h = ground_down - centre[2]  # height above the ground plane (m)
        if h <= 0:
            return None
        d = self._border_rays_c @ R_nc.T  # rays in NED
        far = self.params.far_m
        pts = []
        for ray in d:
            if ray[2] > 1e-6:
                t = min(h / ray[2], far)
            else:  # at or above the horizon: clip at the far plane
                t = far
            pts.append(centre[:2] + t * ray[:2])
        pts = np.asarray(pts)
        n0, e0 = pts.min(axis=0)
        n1, e1 = pts.max(axis=0)
        # Finest useful ground sample: a pixel's footprint straight below (or nearest point).
        gsd_near = h / max(self.true_camera.fx, self.true_camera.fy)
        extent = max(n1 - n0, e1 - e0)
        gsd = max(gsd_near, extent / self.params.max_window_px)
        return (float(n0), float(n1), float(e0), float(e1)), float(gsd)


def _ground_height(world: Any, centre: np.ndarray) -> float:
    try:
        return float(np.asarray(world.terrain_height_m(np.array([centre[0]]), np.array([centre[1]])))[0])
    except (AttributeError, TypeError):
        return 0.0


def _border_rays(cam: PinholeCamera, n: int = 8) -> np.ndarray:
    """(4n, 3) camera-frame rays through the frame border (ideal pinhole, normalised)."""
    us = np.linspace(0, cam.width_px - 1, n)
    vs = np.linspace(0, cam.height_px - 1, n)
    uv = np.concatenate([
        np.c_[us, np.zeros(n)], np.c_[us, np.full(n, cam.height_px - 1)],
        np.c_[np.zeros(n), vs], np.c_[np.full(n, cam.width_px - 1), vs],
    ])
    rays = np.c_[(uv[:, 0] - cam.cx) / cam.fx, (uv[:, 1] - cam.cy) / cam.fy, np.ones(len(uv))]
    return rays / np.linalg.norm(rays, axis=1, keepdims=True)


def _with_motion_blur(opts: RenderOptions, cam: PinholeCamera, R_nc, truth: TruthState, exposure_s: float) -> RenderOptions:
    """Image motion over the exposure from the body rates (rotation dominates at altitude)."""
    from dataclasses import replace

    omega_b = truth.omega_eb_b_rps
    R_nb = quat_to_dcm(truth.q_nb_wxyz)
    R_cb = (R_nb.T @ R_nc).T  # body -> camera
    w = R_cb @ omega_b
    # A rotation about camera y moves the image along u, about x along v (small angles).
    du = cam.fx * w[1] * exposure_s
    dv = -cam.fy * w[0] * exposure_s
    return replace(opts, motion_blur_px=(float(du), float(dv)))


def _clip_roi(cam: PinholeCamera, roi) -> tuple[int, int, int, int]:
    """A requested region (u0, v0, u1, v1) rounded to whole pixels and clipped to the frame (as
    the renderer clips it), so that its bands cover what a single render would."""
    u0, v0, u1, v1 = (int(round(x)) for x in roi)
    return (max(u0, 0), max(v0, 0), min(u1, cam.width_px), min(v1, cam.height_px))


def _merge_truths(parts: Sequence[RenderedFrame]) -> tuple[VehicleTruth, ...]:
    seen: dict[str, VehicleTruth] = {}
    for p in parts:
        for v in p.vehicles:
            if v.id not in seen or (v.visible and not seen[v.id].visible):
                seen[v.id] = v
    return tuple(seen.values())


# A 16 x 16 all-no-data raster: the renderer draws sky and black no-data ground over it.
_BLANK = LocalRaster(np.zeros((16, 16, 3), np.uint8), np.zeros((16, 16), bool), 8.0, -8.0, 1.0)


def save_frame_png(frame: CameraFrame, path) -> None:
    """Write a frame (its whole image, or its first region) as PNG."""
    import cv2

    img = frame.image if frame.image is not None else (frame.regions[0].image if frame.regions else None)
    if img is None:
        return
    cv2.imwrite(str(path), np.ascontiguousarray(img[..., ::-1]))
