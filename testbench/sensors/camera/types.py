"""Frozen dataclasses of the camera renderer: options in, frame and truth out.

Frames: NED local metres at the scenario origin; body FRD; camera OpenCV (x right, y down,
z along the optical axis). Pixel coordinates are full-frame (u right, v down, integer values at
pixel centres) even when only a region of interest is rendered.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class RenderOptions:
    """How a frame is rendered (the image-formation part of the camera model).

    near_m, far_m: clip planes on the camera depth z_c (m), as in a rasteriser; ground beyond
        far_m is replaced by sky/haze.
    ground_height_m: height of the flat ground plane above the origin (up positive) when no
        elevation raster is given.
    noise_mean, noise_std: additive Gaussian pixel noise in digital numbers (0-255 scale).
    gain: exposure/gain multiplier on the scene radiance (1 = as mapped), saturating at 255.
    vignetting: strength in [0, 1] of the cos^4 fall-off (0 = none, 1 = full cos^4).
    motion_blur_px: (du, dv) image motion during the exposure (pixels); a linear blur kernel.
    haze_visibility_m: distance (m) at which aerial perspective blends 63 % towards the horizon
        colour; None (the default) disables haze. An opt-in effect like vignetting: the paper's
        camera model has none, it changes a downward view at 800 m by a few per cent, and it is
        a third of the cost of a 1080p frame (about 5 ms); cameras that look at the horizon
        (the swarm scenarios') set it.
    sky_zenith_rgb, sky_horizon_rgb: sky gradient end colours.
    lod_bias: added to log2(map pixels per image pixel) before rounding to a pyramid level
        (positive = blurrier, never shimmers; negative = sharper, may alias).
    relief_cell_px: spacing (pixels, a power of two <= 32) of the coarse ray-cast grid over a DEM.
    """

    near_m: float = 0.1
    far_m: float = 20000.0
    ground_height_m: float = 0.0
    noise_mean: float = 0.0
    noise_std: float = 0.0
    gain: float = 1.0
    vignetting: float = 0.0
    motion_blur_px: tuple[float, float] = (0.0, 0.0)
    haze_visibility_m: float | None = None
    sky_zenith_rgb: tuple[int, int, int] = (78, 128, 196)
    sky_horizon_rgb: tuple[int, int, int] = (196, 212, 228)
    lod_bias: float = 0.0
    relief_cell_px: int = 8


@dataclass(frozen=True)
class VehicleAppearance:
    """Another vehicle as a camera sees it.

    id: vehicle id; pos_ned_m (3,): centre of gravity in local NED (m); R_nb (3, 3): body->NED;
    shape: "quad" | "fixed_wing" | "box"; size_m: overall span (m): wingspan of a fixed wing,
    motor-to-motor diagonal plus rotors of a quad, edge of a box; colour_rgb: body colour;
    led_positions_b_m: (n, 3) LED positions in body FRD (m); led_colours: n RGB triples;
    led_on: n booleans, the LED state at this instant (an input: the caller blinks them);
    led_radius_m: physical radius of an LED's glow (m).
    """

    id: str
    pos_ned_m: np.ndarray
    R_nb: np.ndarray
    shape: str = "quad"
    size_m: float = 0.5
    colour_rgb: tuple[int, int, int] = (60, 60, 66)
    led_positions_b_m: tuple[tuple[float, float, float], ...] = ()
    led_colours: tuple[tuple[int, int, int], ...] = ()
    led_on: tuple[bool, ...] = ()
    led_radius_m: float = 0.03


@dataclass(frozen=True)
class VehicleTruth:
    """Ground truth of one other vehicle in a rendered frame (full-frame pixel coordinates).

    bbox_px: (u0, v0, u1, v1) of its projected shape clipped to the frame (empty if not seen);
    centre_px (2,): projection of its centre (may lie outside the frame); led_px (n, 2): LED
    projections; led_on: the states drawn; led_in_frame: LED projected inside the frame and in
    front of the camera; visible: drawn with at least one pixel in the frame and not hidden by
    terrain; range_m: distance from the optical centre to its centre.
    """

    id: str
    bbox_px: tuple[float, float, float, float]
    centre_px: np.ndarray
    led_px: np.ndarray
    led_on: tuple[bool, ...]
    led_in_frame: tuple[bool, ...]
    visible: bool
    range_m: float


@dataclass(frozen=True)
class RenderedFrame:
    """One rendered camera frame.

    image (h, w, 3) uint8 RGB; valid (h, w) bool: the pixel shows ground that the map covers;
    sky (h, w) bool: the ray meets no ground within the far plane; offmap_fraction: share of
    the frame's pixels that show ground the map does not cover (no-data, drawn black);
    vehicles: truth of the other vehicles; roi: (u0, v0, u1, v1) of the rendered region in the
    full frame (the whole frame when None); ground_points_ned_m (h, w, 3) NED of each pixel's
    ground point (nan where sky), only when asked for; cloud_fraction: share of the pixels
    that look at the ground (not sky) whose ray a cloud takes half the light of or more;
    shadow_fraction: share of those pixels that show ground (not hidden so) lying in a
    cloud's shadow, half its direct sun or more cut (both truth, for scoring: nothing in the
    pixels says which they are). The masks are read-only (frames that are all ground share
    one constant pair): copy them to modify.
    """

    image: np.ndarray
    valid: np.ndarray
    sky: np.ndarray
    offmap_fraction: float
    vehicles: tuple[VehicleTruth, ...] = ()
    roi: tuple[int, int, int, int] | None = None
    ground_points_ned_m: np.ndarray | None = field(default=None, repr=False)
    cloud_fraction: float = 0.0
    shadow_fraction: float = 0.0
