"""Optical-flow sensor: a small downward camera and the chip that measures how far the ground
moved between its last two frames (PX4Flow, PMW3901 and their kind, or a companion computer
running the same on a camera's frames).

Each sample renders the frame the camera sees from the TRUE pose with the project's camera
renderer (the world's imagery, its relief, the camera's noise), turns it grey, and measures the
translation from the previous frame (sensors.image_shift: phase correlation, then Lucas-Kanade
to a hundredth of a pixel, with the fit's covariance). The output is the ground's move in
normalised image coordinates, translation and rotation together, as a flow chip gives it:
removing the vehicle's own rotation (from its gyros) and scaling by the distance to the ground
(from a rangefinder) is the navigator's job. With each sample comes how the fit read the flow
fields of a rotation and of a translation over tilted ground (rotation_c, moments_c: weighted
by that frame's own texture), so that the navigator can predict the reading it gets. Over
ground without texture (water, bare fields, the sky) the fit has nothing to hold on to and the
sensor says so: a small texture_dn2, a wide covariance, or no sample.

Before the fit each frame is smoothed by a Gaussian of blur_sigma_px (the lens's blur and the
chip's pre-filter): a rendered frame of a 1 m map holds detail up to its pixels' own size
(crop rows two pixels apart), which a real lens does not pass, and on which the fit's
linearisation errs by a shift that depends on the sub-pixel phase (0.012-0.033 px at shifts of
0.1-0.8 px, 64 px over 30 deg at 100 m; 0.002-0.012 px with 1 px of blur over 45 deg: 100
pairs of frames a shift, docs/measurements.md).

Defaults: 64 x 64 px over 45 deg (1.3 m/px at 100 m above the ground, a little coarser than
the 1 m procedural maps), 20 Hz, looking straight down with the image top towards the nose;
the camera's usual noise of 2 DN. A frame whose shift exceeds max_shift_px (the chip's
largest flow rate) gives no sample.

A frame that sees ground off the map (no-data, which the renderer draws black) gives no sample
either, nor does the frame after it: the map's edge stays put in the image while the ground
moves, and the fit reads a blend of the two (64 px over 45 deg at 50 m, 0.3 m north in 0.05 s:
+57 % with 11 % of the view off the map, -68 % with 36 %, each claimed to 3e-5 rad).
A real camera has ground everywhere; a simulated one past its map has nothing honest to say.
"""

from __future__ import annotations

import logging
from typing import Any

import cv2
import numpy as np
import pydantic

from testbench.core.interfaces import BuildContext
from testbench.core.messages import FLOW_MOMENT_FIELDS, OpticalFlowSample, TruthState
from testbench.core.registry import ParamsModel, register
from testbench.sensors.base import CachedSensor, check_rate
from testbench.sensors.camera.sensor import CameraParams, CameraSensor
from testbench.sensors.image_shift import image_shift

log = logging.getLogger(__name__)


class OpticalFlowParams(ParamsModel):
    """rate_hz (frames per second: one sample per frame after the first); width_px, height_px,
    hfov_deg: the flow camera; noise_std: its pixel noise (DN, 1 sigma); mount_*_deg and
    lever_arm_b_m: its mounting (core.camera_geometry; pitch -90 looks straight down);
    blur_sigma_px: the lens's and pre-filter's blur (Gaussian sigma, px; 0: none);
    max_shift_px: the largest shift between frames the chip reports (larger: no sample);
    far_m: the camera's far clip (m)."""

    rate_hz: float = pydantic.Field(20.0, gt=0)
    width_px: int = pydantic.Field(64, ge=16, le=512)
    height_px: int = pydantic.Field(64, ge=16, le=512)
    hfov_deg: float = pydantic.Field(45.0, gt=1, lt=120)
    noise_std: float = pydantic.Field(2.0, ge=0)
    blur_sigma_px: float = pydantic.Field(1.0, ge=0)
    mount_roll_deg: float = 0.0
    mount_pitch_deg: float = -90.0
    mount_yaw_deg: float = 0.0
    lever_arm_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    max_shift_px: float = pydantic.Field(8.0, gt=0)
    far_m: float = pydantic.Field(5000.0, gt=0)


@register("sensor", "optical_flow")
class OpticalFlowSensor(CachedSensor):
    """Returns OpticalFlowSample from the second frame on, or None where the flow cannot be
    measured (the first frame, no texture, a shift beyond max_shift_px, a frame or the one
    before it looking off the map)."""

    Params = OpticalFlowParams

    def __init__(self, params: OpticalFlowParams, *, ctx: BuildContext, **_: Any):
        super().__init__()
        p = params
        self.params = p
        self.name = "optical_flow"
        self.rate_hz = check_rate(p.rate_hz, ctx, "optical_flow")
        # The frames come from the project's camera model and renderer; other vehicles are not
        # drawn (a flow camera looks at the ground under it).
        self._camera = CameraSensor(CameraParams(
            rate_hz=p.rate_hz, width_px=p.width_px, height_px=p.height_px, hfov_deg=p.hfov_deg,
            noise_std=p.noise_std, far_m=p.far_m, mount_roll_deg=p.mount_roll_deg,
            mount_pitch_deg=p.mount_pitch_deg, mount_yaw_deg=p.mount_yaw_deg, lever_arm_b_m=p.lever_arm_b_m,
            render_vehicles=False), ctx=ctx)
        cam = self._camera.camera
        self._px_to_rad = np.array([1.0 / cam.fx, 1.0 / cam.fy])
        # The fit reads each of these fields as it reads the ground's flow (image_shift): the
        # camera's rotation about its three axes, then the monomial fields of moments_c.
        self._fields_px = np.concatenate([_rotation_fields_px(cam), _moment_fields_px(cam)])
        self._prev: tuple[float, np.ndarray] | None = None  # (t_s, grey frame) of the last frame
        self._warned_offmap = False

    @property
    def camera(self):
        """The flow camera's PinholeCamera (intrinsics)."""
        return self._camera.camera

    @property
    def mount(self):
        """The flow camera's CameraMount (R_bc camera -> body, lever arm)."""
        return self._camera.mount

    def _sample(self, truth: TruthState, world: Any, rng: np.random.Generator) -> OpticalFlowSample | None:
        # Its own name, so that the world serves it no region another aid asked of a camera.
        self._camera.name = self.name
        frame = self._camera.measure(truth, world, rng)
        image = None if frame is None else frame.image
        prev, self._prev = self._prev, None
        if image is None:
            return None
        if frame.offmap_fraction > 0.0:
            if not self._warned_offmap:
                log.warning("optical-flow sensor %s at t=%.1f s: %.1f %% of its view is off the map (no-data); "
                            "no flow is measured while any of it is (fly over the map, or use a larger one)",
                            self.name, truth.t_s, 100.0 * frame.offmap_fraction)
                self._warned_offmap = True
            return None
        grey = cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2GRAY).astype(np.float32)
        if self.params.blur_sigma_px > 0:
            grey = cv2.GaussianBlur(grey, (0, 0), self.params.blur_sigma_px)
        self._prev = (truth.t_s, grey)
        if prev is None:
            return None
        shift = image_shift(prev[1], grey, fields=self._fields_px)
        if shift is None or float(np.abs(shift.shift_px).max()) > self.params.max_shift_px:
            return None
        k = self._px_to_rad
        mount = self._camera.mount
        return OpticalFlowSample(
            t_s=truth.t_s, dt_s=truth.t_s - prev[0], flow_c_rad=shift.shift_px * k,
            cov_c_rad2=shift.cov_px2 * np.outer(k, k), texture_dn2=shift.texture_dn2,
            residual_dn=shift.residual_dn, R_bc=np.asarray(mount.R_bc, float).copy(),
            lever_arm_b_m=np.asarray(mount.lever_arm_b_m, float).copy(),
            rotation_c=(shift.field_response_px[:3] * k).T,
            moments_c=(shift.field_response_px[3:] * k).T,
        )


def _normalised_grid(cam) -> tuple[np.ndarray, np.ndarray]:
    """(h, w) normalised image coordinates x = (u - cx) / fx, y = (v - cy) / fy of every pixel."""
    u, v = np.meshgrid(np.arange(cam.width_px, dtype=float), np.arange(cam.height_px, dtype=float))
    return (u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy


def _moment_fields_px(cam) -> np.ndarray:
    """(8, h, w, 2): the flow fields of core.messages.FLOW_MOMENT_FIELDS in pixels (a field of
    one normalised unit along x is fx px along u). A camera tilted over flat ground sees its
    translation's flow vary over the image as a quadratic in (x, y) (the ground nearer on one
    side); the fit's reading of these fields lets the navigator predict what the fit reads of it."""
    x, y = _normalised_grid(cam)
    monomial = {"x": x, "y": y, "xx": x * x, "xy": x * y, "yy": y * y}
    out = np.zeros((len(FLOW_MOMENT_FIELDS),) + x.shape + (2,))
    for i, (axis, name) in enumerate(FLOW_MOMENT_FIELDS):
        out[i, ..., axis] = (cam.fx, cam.fy)[axis] * monomial[name]
    return out


def _rotation_fields_px(cam) -> np.ndarray:
    """(3, h, w, 2): the image motion (px) of a static scene per rad of the camera's rotation
    about its x, y and z axes, pixel by pixel (the rotational part of the image Jacobian in
    normalised coordinates (x, y): x-axis (x y, 1 + y^2), y-axis (-(1 + x^2), -x y), z-axis
    (y, -x)), scaled by fx, fy."""
    x, y = _normalised_grid(cam)
    per_axis = [(x * y, 1.0 + y * y), (-(1.0 + x * x), -x * y), (y, -x)]
    return np.stack([np.stack([cam.fx * du, cam.fy * dv], axis=-1) for du, dv in per_axis])
