"""The scene-matching aid "ismn": frames of a downward camera + the INS estimate + the onboard
reference map -> position fixes for the navigator (paper section 2.1).

It wraps `ismn.IsmnPipeline` for the engine: it takes the camera's intrinsics and mounting from
the camera sensor, the reference map and elevation the vehicle carries (never the imagery the
camera renders, unless the scenario says so and is labelled same-raster), and reports each
attempt as a row of events/ismn.parquet. Truth columns of those rows are left as placeholders
that the engine fills, but these: truth_cloud_fraction, the share of the ground in view that
clouds hide, truth_shadow_fraction, the share that shows in their shadows, and
truth_exposure_{north,east,down}_m, where the frame was truly taken from (its exposure: the
tick's position unless the camera's clock is off), are copied from the renderer's frame
(CameraFrame.cloud_fraction, shadow_fraction, exposure_pos_ned_m) for scoring; the pipeline is
given the pixels alone.

Onboard processing time (`latency_s`): a fix reaches the navigator latency_s after the frame's
exposure, stamped with the exposure time; the engine holds it until then (Engine._deliver) and
the navigator fuses it as a delayed measurement (InsEkfParams.delayed_fixes). One processor:
a frame that comes while the one before is still being processed is not taken ("busy").

Acquisition (`acquisition`): while the estimate is too uncertain for the filter's gate to
tell a false match (a launch without GNSS, a long outage), a fix goes to the navigator only
once the fixes after it agree with it through the INS's displacement (fix_confirmation.py);
the fixes held meanwhile are recorded with the reason, never delivered.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
import pydantic

from testbench.core.errors import InputError
from testbench.core.interfaces import BuildContext, NavigationAid
from testbench.core.messages import NavEstimate, PositionFix
from testbench.core.registry import ParamsModel, build, register
from testbench.core.rotations import quat_multiply, quat_to_euler, rotvec_to_quat
from testbench.navigation.fix_columns import position_fix_columns
from testbench.navigation.fix_confirmation import ConfirmationParams, FixConfirmation
from testbench.navigation.ismn import IsmnDiagnostics, IsmnParams, IsmnPipeline
from testbench.navigation.ismn.pipeline import with_camera_readout

_NAN = float("nan")


class MatcherSpec(ParamsModel):
    type: str = "ncc"
    params: dict = {}


@dataclass
class IsmnAttempt:
    """One frame's outcome, turned into recorder rows after the navigator has seen the fix."""

    t_s: float
    fix: PositionFix | None
    diag: Any
    same_raster: bool
    keep_example: bool
    cloud_fraction: float = 0.0  # the renderer's (truth), for the record only
    shadow_fraction: float = 0.0  # the same
    exposure_pos_ned_m: np.ndarray | None = None  # the same: where the frame was taken from
    deliver_t_s: float | None = None
    """When the fix reaches the navigator (s; None: at t_s). The engine holds it until then."""
    held_reason: str = ""
    """Why the fix was held back and never delivered (acquisition: waiting for confirmation);
    "" for a fix that went to the navigator."""

    def event_rows(self, vehicle_id: str) -> list[tuple[str, dict]]:
        d = self.diag
        lat = d.latency_ms
        fix = self.fix
        row = dict(
            t_s=self.t_s, vehicle_id=vehicle_id, attempted=bool(getattr(d, "attempted", True)),
            fix=fix is not None, accepted=None, **position_fix_columns(fix),
            quality=float(fix.quality) if fix is not None else float(getattr(d, "peak_quality", 0.0)),
            latency_ms=float(lat.get("ortho_to_fix", lat.get("total", _NAN))),
            total_ms=float(lat.get("total", _NAN)),
            reason=self.held_reason or str(getattr(d, "reason", "")),
            same_raster=self.same_raster,
            truth_north_m=_NAN, truth_east_m=_NAN, truth_down_m=_NAN, truth_roll_rad=_NAN, truth_height_agl_m=_NAN,
            truth_cloud_fraction=float(self.cloud_fraction),
            truth_shadow_fraction=float(self.shadow_fraction),
            **_exposure_columns(self.exposure_pos_ned_m),
            **_footprint_columns(getattr(d, "window", None)),
            delivered_t_s=float(self.deliver_t_s if self.deliver_t_s is not None else self.t_s)
            if fix is not None and not self.held_reason else _NAN,
        )
        return [("ismn", row)]

    def artifacts(self) -> list[tuple[str, dict[str, np.ndarray]]]:
        """Images for the report's ISMN examples (camera thumbnail, ortho, map window)."""
        d = self.diag
        if not self.keep_example or getattr(d, "ortho", None) is None:
            return []
        arrays = {"camera": d.frame_thumb, "ortho": d.ortho, "map_window": d.map_window, "t_s": np.array(self.t_s)}
        return [(f"ismn_examples/t{self.t_s:08.2f}", {k: v for k, v in arrays.items() if v is not None})]


@register("aid", "ismn")
class IsmnAid(NavigationAid):
    """Scene-matching position fixes from the frames of one camera sensor.

    Params: camera (the sensor's name), matcher ({type, params}: ncc, phase, orb, sift or
    "module:Class"), pipeline (IsmnParams: window sigma, working gsd, quality floor ...),
    every_n_frames (use one frame in N), example_every_s (keep images for the report),
    latency_s (the onboard processing time, s: each fix reaches the navigator that long after its
    frame's exposure, and frames that come while one is in processing are skipped as "busy"; 0:
    at once, the default, as the pipeline's own 35-50 ms on a desktop core would be),
    acquisition (ConfirmationParams: while the estimate's horizontal sigma exceeds above_sigma_m,
    a fix is delivered only when min_fixes in a row agree; None: every fix at once, the default).
    """

    class Params(ParamsModel):
        camera: str
        matcher: MatcherSpec = MatcherSpec()
        pipeline: dict = {}
        every_n_frames: int = pydantic.Field(1, ge=1)
        example_every_s: float = pydantic.Field(60.0, gt=0)
        latency_s: float = pydantic.Field(0.0, ge=0, le=10.0)
        acquisition: ConfirmationParams | None = None

    def __init__(self, params: Params, *, ctx: BuildContext, sensors: dict, onboard: dict, **_: Any):
        self.params = params
        where = f"vehicles[{ctx.vehicle_id}].aids[ismn]"
        sensor = sensors.get(params.camera)
        if sensor is None:
            raise InputError(f"{where}.params.camera: no sensor named {params.camera!r} on this vehicle (have: {', '.join(sensors) or 'none'})")
        cam, mount = getattr(sensor, "camera", None), getattr(sensor, "mount", None)
        if cam is None or mount is None:
            raise InputError(f"{where}.params.camera: sensor {params.camera!r} is not a camera")
        reference = onboard["reference_map"]()
        if reference is None:
            raise InputError(f"{where}: scene matching needs world.reference_map (or world.imagery)")
        try:
            pipe_params = IsmnParams.model_validate(params.pipeline)
        except pydantic.ValidationError as exc:
            from testbench.core.registry import format_validation_error

            raise InputError(format_validation_error(exc, f"{where}.params.pipeline")) from None
        pipe_params = with_camera_readout(pipe_params, sensor)  # the rolling shutter, as its datasheet gives it
        matcher = build("matcher", params.matcher.type, params.matcher.params, f"{where}.params.matcher", ctx=ctx)
        self.pipeline = IsmnPipeline(cam, mount, reference, onboard["reference_elevation"](), matcher, pipe_params)
        self.same_raster = bool(onboard.get("same_raster", False))
        self._n = 0
        self._next_example_t = 0.0
        self._busy_until_s = -float("inf")
        """Exposure time + latency_s of the last frame the processor took (s)."""
        self._confirmation = FixConfirmation(params.acquisition) if params.acquisition is not None else None

    @property
    def offers_image_pose(self) -> bool:
        """Whether its fixes carry the image-only pose (pipeline.pose_from_image), which a
        navigator with camera boresight states needs."""
        return self.pipeline.p.pose_from_image

    def accepts(self, measurement: Any) -> bool:
        return getattr(measurement, "camera_name", None) == self.params.camera and hasattr(measurement, "image")

    def process(self, measurement: Any, estimate: NavEstimate) -> tuple[list, IsmnAttempt | None]:
        self._n += 1
        if (self._n - 1) % self.params.every_n_frames:
            return [], None
        t_s = float(measurement.t_s)
        latency = self.params.latency_s
        if t_s < self._busy_until_s - 1e-9:
            # The processor is still on an earlier frame: this one is not taken (nor counted as
            # an attempt: the fix rate is the matcher's).
            diag = IsmnDiagnostics(t_s, {}, reason=f"busy: the frame of t={self._busy_until_s - latency:.2f} s "
                                                   f"is still in processing ({latency:g} s)", attempted=False)
            return [], IsmnAttempt(t_s, None, diag, self.same_raster, False)
        prior = prior_at_exposure(estimate)
        fix, diag = self.pipeline.process(measurement.image, t_s, prior)
        if latency > 0 and getattr(diag, "attempted", True):
            self._busy_until_s = t_s + latency
        held_reason = ""
        if fix is not None and self._confirmation is not None:
            confirmed, held_reason = self._confirmation.offer(fix, prior)
            fix = confirmed if confirmed is not None else fix  # the row records the fix as delivered (its claim widened) or as held
        keep = measurement.t_s >= self._next_example_t and getattr(diag, "ortho", None) is not None
        if keep:
            self._next_example_t = measurement.t_s + self.params.example_every_s
        out = [fix] if fix is not None and not held_reason else []
        return out, IsmnAttempt(measurement.t_s, fix, diag, self.same_raster, keep,
                                                               float(getattr(measurement, "cloud_fraction", 0.0)),
                                                               float(getattr(measurement, "shadow_fraction", 0.0)),
                                                               deliver_t_s=t_s + latency if latency > 0 else None,
                                                               exposure_pos_ned_m=getattr(measurement, "exposure_pos_ned_m", None),
                                                               held_reason=held_reason)


def _footprint_columns(window) -> dict[str, float]:
    """footprint_{north,east}_{min,max}_m of a row: the footprint the INS predicted (the search
    window's, DESIGN.md eq. 3-5; NaN when the attempt had no window). Onboard information; the
    engine scores the map's error over it (Engine._fill_truth)."""
    fp = (_NAN,) * 4 if window is None else tuple(float(x) for x in window.footprint_ne_m)
    return dict(footprint_north_min_m=fp[0], footprint_north_max_m=fp[1], footprint_east_min_m=fp[2],
                footprint_east_max_m=fp[3])


def _exposure_columns(pos_ned_m) -> dict[str, float]:
    """truth_exposure_{north,east,down}_m of a row: where the frame was truly taken from (NaN
    when the frame does not say)."""
    p = (_NAN, _NAN, _NAN) if pos_ned_m is None else tuple(float(x) for x in pos_ned_m)
    return dict(truth_exposure_north_m=p[0], truth_exposure_east_m=p[1], truth_exposure_down_m=p[2])


def prior_at_exposure(estimate: NavEstimate) -> NavEstimate:
    """The estimate carried back to the frame's exposure when the navigator estimates the
    camera's time offset td (NavEstimate.camera_time_offset_s: the stamp minus the exposure):
    the position by -v td, the attitude by the body rate over -td (covariances as they are);
    otherwise the estimate itself. The scene matcher's prior is then the pose the image was
    taken from, as the navigator knows it (measurements.TimeOffsetTerms)."""
    td = estimate.camera_time_offset_s
    if not td:
        return estimate
    q = quat_multiply(np.asarray(estimate.q_nb_wxyz, float), rotvec_to_quat(-td * np.asarray(estimate.omega_b_rps, float)))
    return dataclasses.replace(estimate, pos_ned_m=np.asarray(estimate.pos_ned_m, float) - td * np.asarray(estimate.vel_ned_mps, float),
                               q_nb_wxyz=q, rpy_rad=quat_to_euler(q))
