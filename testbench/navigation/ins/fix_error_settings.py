"""Settings of the filter states that carry what a scene-matching fix errs by beyond its own
claim: the camera's boresight, time offset and intrinsics, and the reference map's georeference
(`navigation.params.camera_boresight`, `camera_time_offset`, `camera_intrinsics`, `map_error`;
fields of settings.InsEkfParams)."""

from __future__ import annotations

import pydantic

from testbench.core.registry import ParamsModel


class CameraBoresight(ParamsModel):
    """The scene-matching camera's boresight error as three filter states (ErrorStateEKF.i_cam,
    body axes): the camera's true mounting differs from its calibration by a fixed small
    rotation (a camera sensor's mount_error_deg), which turns every fix's view of the ground
    alike. Until the boresight is learnt (handover_sigma_deg) the filter fuses each fix's
    image-only pose (ismn pose_from_image: position and attitude with their joint covariance)
    instead of its MAP position, and the image's attitude against the INS attitude shows the
    boresight: while GNSS holds the position and the manoeuvres the heading, the tilt part
    settles within a few fixes; the yaw part, which only the heading separates from the INS's
    own yaw error, more slowly. Where the heading
    stays uncertain for long (a magnetic anomaly, paper_ismn_anomaly) the yaw part and the
    attitude come out overconfident (attitude NEES 7-9 against 3.45 without the states;
    docs/measurements.md, "A camera off its calibration").

    sigma_deg: 1-sigma per body axis of the boresight before any fix (a mount known from the
    drawing, not calibrated: 0.5-1 deg; after a calibration flight: 0.02-0.05 deg).

    handover_sigma_deg: once the boresight's largest 1-sigma (the largest eigenvalue of its
    covariance, square-rooted) is below this, the fixes are fused as MAP positions with their
    attitude coupling (position_ned with the boresight columns, as a fix without the image pose)
    instead of the image-only pose. The image pose learns b fast (0.1 deg within a fix or two)
    but its position errs together with its attitude over the same ground, which the shared-error
    states do not carry: on 20 runs of paper_ismn_boresight the position NEES was 3.81 (3 dof)
    with it throughout and 2.80 with the handover at 0.1 deg, the navigation mean 0.44 against
    0.41 m. The MAP fixes keep refining b through their coupling (to 0.04 deg), not as far as
    the image pose (0.007 deg). None: the image pose throughout (a calibration flight's
    setting, when b itself is the result)."""

    sigma_deg: float = pydantic.Field(0.5, gt=0.0, le=10.0)
    handover_sigma_deg: float | None = pydantic.Field(0.1, gt=0.0)


class CameraTimeOffsetParams(ParamsModel):
    """`navigation.params.camera_time_offset`: the scene-matching camera's time offset (its
    frames' stamp minus their true exposure: a camera clock not synchronised with the IMU's) as
    one filter state, a random constant (ErrorStateEKF camera_time_offset_sigma_s)."""

    sigma_s: float = pydantic.Field(0.03, gt=0.0, le=0.25)
    """Its prior 1-sigma (s): what the camera's and the IMU's clocks may differ by before a
    calibration (an unsynchronised USB or network camera: tens of milliseconds)."""


class CameraIntrinsicsParams(ParamsModel):
    """`navigation.params.camera_intrinsics`: the scene-matching camera's intrinsics error (its
    principal point, the true one minus the calibrated one, px; its focal length, relative) as
    three filter states, random constants (ErrorStateEKF camera_intrinsics_sigma)."""

    principal_point_sigma_px: float = pydantic.Field(1.0, ge=0.0, le=20.0)
    """The principal point's prior 1-sigma per axis (px): what a lens's principal point is
    known to after a laboratory calibration (0.5-2 px for a wide-angle lens; the principal
    point is the intrinsic a calibration pins worst)."""
    focal_sigma_rel: float = pydantic.Field(0.002, ge=0.0, le=0.05)
    """The focal length's prior 1-sigma, relative (0.1-0.3 % after a laboratory calibration;
    the lens's focus and temperature move it too)."""

    @pydantic.model_validator(mode="after")
    def _some(self) -> "CameraIntrinsicsParams":
        if self.principal_point_sigma_px == 0.0 and self.focal_sigma_rel == 0.0:
            raise ValueError("give principal_point_sigma_px or focal_sigma_rel > 0 (or leave camera_intrinsics out)")
        return self

    def sigmas(self) -> tuple[float, float, float]:
        """(u px, v px, focal relative) prior 1-sigmas, the states' order."""
        return (self.principal_point_sigma_px, self.principal_point_sigma_px, self.focal_sigma_rel)


class MapErrorParams(ParamsModel):
    """`navigation.params.map_error`: the reference map's georeference error (north, east) as
    two filter states that every scene-matching fix sees whole (ErrorStateEKF map_error_*).
    The map's local scale (a smooth displacement field of sigma s and correlation length L
    stretches it by about s / (1.4 L)) moves each fix's height by that times the height: these
    states do not carry it; the shared fix error's down axis (fix_error_sigma_down_m) must."""

    sigma_m: float = pydantic.Field(gt=0.0, le=100.0)
    """1-sigma per axis (m): the map's stated accuracy (a CE95 of 6 m is about 2.5 m per axis)."""
    correlation_m: float = pydantic.Field(2000.0, gt=0.0)
    """The distance flown over which the error decorrelates by exp(-1) (m)."""
