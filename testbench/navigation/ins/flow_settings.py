"""The optical-flow aiding's settings (InsEkfParams.optical_flow): how a navigator fuses a
downward flow sensor with a rangefinder (OpticalFlowAiding, fused by flow_aiding.py) and when
it holds the flow out (FlowHoldout). Kept apart from settings.py, which holds the other aids'
parameters and the navigator's own."""

from __future__ import annotations

import pydantic

from testbench.core.registry import ParamsModel


class FlowHoldout(ParamsModel):
    """Holding the optical flow out while the gate refuses much of it (OpticalFlowAiding.holdout).

    A flow sensor that reads something else than the ground's motion (a cloud's shadow drifting
    with the wind over a bare field, ripples on water) is refused by the gate most of the time,
    and the samples the gate lets through are the same wrong reading that happens to fall
    inside it: they pull the velocity. When max_refused or more of the last `window` samples
    were refused, the flow is only checked, not fused, for hold_s seconds (kind
    "optical_flow:held" in the corrections); the checks keep filling the window, so the hold
    ends once the flow agrees with the filter again."""

    window: int = pydantic.Field(20, ge=2)
    max_refused: int = pydantic.Field(5, ge=1)
    hold_s: float = pydantic.Field(3.0, gt=0)

    @pydantic.model_validator(mode="after")
    def _fits(self):
        if self.max_refused > self.window:
            raise ValueError(f"max_refused {self.max_refused} exceeds window {self.window} (expected at most the "
                             f"window's samples)")
        return self


class OpticalFlowAiding(ParamsModel):
    """Optical-flow velocity aiding (the flow fusion of PX4's EKF2, EKF2_OF_CTRL): a downward
    flow sensor (sensor type optical_flow) measures how far the ground moved in its image over
    an interval, its rotation and its translation over the distance to the ground together;
    the filter takes the rotation out with its own bias-corrected gyros integrated over the
    same interval, scales by the distance along the camera's axis from a downward pencil-beam
    rangefinder (a radar_altimeter with beam_half_angle_deg at most max_beam_half_angle_deg,
    its beam along body z; flat ground between the two footprints), and fuses the rest as the
    camera's velocity over the ground (measurements.optical_flow). It measures the velocity
    over the ground, where rotor drag and a pitot measure it through the air: in wind and
    turbulence it is what keeps the velocity, and so the position, from drifting."""

    sigma_scale: float = pydantic.Field(4.0, gt=0)
    """The sensor's claimed covariance (its fit's, which takes the residuals as white) is
    scaled by sigma_scale^2: the renderer's interpolation and the lens's blur correlate
    neighbouring pixels. Calibrated on the sensor's defaults (64 x 64 px over 45 deg, 1 px of
    blur), 200 pairs of rendered frames each: the NEES median 16.9 for 2 dof at 30 m over the
    0.25 m farmland, 28.3 at 100 m over the 1 m farmland, i.e. a scale of 3.5 / 4.5 on the
    median (the mean, 61 / 154, is the tails', which the gate takes)."""
    perspective: bool = True
    """Predict the flow as the sensor's fit reads it over tilted ground (the sample's
    moments_c: the ground nearer on one side of the image moves faster there, and the
    texture weighs the sides), not the image centre's flow alone (False: PX4's model). At 20
    deg of tilt the centre's model is 2-4 % off, with 3-7 % of spread from frame to frame
    over the Kampala orthophoto; the fit's reading, within 1 % and 1.4-1.6 %, as level
    (docs/measurements.md, "Optical flow")."""
    sigma_floor_rad_s: float = pydantic.Field(0.002, ge=0)
    """Added in quadrature per axis to the flow rate's sigma (rad/s): what the model of the
    reading leaves out, such as relief (and, with perspective False, the tilt's perspective),
    which make the flow differ over the image."""
    rotation_sigma_fraction: float = pydantic.Field(0.03, ge=0)
    """Share of the camera's own rotational flow (as the sensor reads it, and as the gyros
    give it) left after it is taken out, per axis, 1 sigma: the sensor's first-order reading
    of a rotating frame (1-3 % off over 45 deg, tests/sensors/camera/test_flow_sensor.py) and
    the gyros' timing against the frames'."""
    depth_sigma_fraction: float = pydantic.Field(0.02, ge=0)
    """Relative error of the distance to the ground along the camera's axis: the
    rangefinder's noise and the ground's slope between the two footprints."""
    min_texture_dn2: float = pydantic.Field(0.05, ge=0)
    """Samples whose image is textured less than this along its weakest direction (the
    sensor's texture_dn2, DN^2/px^2) are not fused: bare fields and water."""
    bias_sigma_rps: float = pydantic.Field(0.003, ge=0)
    """1-sigma of the flow's slowly varying error (rad/s per camera axis), carried as two filter
    states (ErrorStateEKF.i_flow; 0: none): the sensor's reading of sub-pixel shifts errs by
    an amount that follows the ground in its view, 1.5-2.5 % of the flow from frame to frame
    over the Kampala orthophoto and the farmland (0.003 rad/s at 5 m/s 30 m up)."""
    bias_correlation_rad: float = pydantic.Field(0.8, gt=0)
    """How far the ground moves through the view (rad of image angle, the translation's flow
    integrated) before that error decorrelates: about the view's width (0.79 rad over 45 deg),
    when the view holds other ground. 4.8 s at 5 m/s 30 m up, 13 s at 6 m/s 100 m up."""
    bias_tau_s: float = pydantic.Field(60.0, gt=0)
    """Its correlation time besides (s): hovering over the same ground, the light and the
    attitude still change what the fit reads."""
    max_range_age_s: float = pydantic.Field(0.25, gt=0)
    """The latest range may be at most this old (s)."""
    max_beam_half_angle_deg: float = pydantic.Field(3.0, ge=0, le=10)
    """The widest rangefinder beam taken for the distance along the camera's axis (a wider
    beam ranges the nearest ground in it, not the ground on its axis)."""
    min_depth_m: float = pydantic.Field(1.0, gt=0)
    """Below this distance to the ground (m: on the ground, landing) nothing is fused."""
    holdout: FlowHoldout | None = pydantic.Field(default_factory=FlowHoldout)
    """Hold the flow out while the gate refuses much of it (FlowHoldout); None: every sample
    goes through the gate on its own. Under a broken cloud layer's drifting shadows
    (multirotor_flow_wind, 40 % cover, seeds 1-3) it took the navigation mean from 37.0 /
    24.0 / 27.8 m to 13.7 / 17.4 / 6.0 m; under a clear sky it changed it by 0.1 m or less
    (docs/measurements.md, "Cloud shadows")."""
