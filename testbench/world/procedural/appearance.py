"""Appearance of the procedural worlds: seasons, sun, hillshade, cast shadows, camera finish.

The season changes only appearance: colours, crop state, water level, sun azimuth/elevation
(so shadow directions) and global brightness/contrast. Layout never reads these.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from testbench.core.errors import InputError

SEASONS = ("summer", "autumn", "winter", "spring")


@dataclass(frozen=True)
class Season:
    """Appearance parameters of one season.

    sun_azimuth_rad: from north, clockwise (east = pi/2); sun_elevation_rad above horizon.
    water_level: -1 (low, dry) .. +1 (high); green: vegetation vigour 0..1; snow: 0..1 cover.
    crop_stage: 0 bare soil, 1 young rows, 2 full canopy, 3 ripe/harvested stubble.
    """

    name: str
    index: int
    sun_azimuth_rad: float
    sun_elevation_rad: float
    water_level: float
    green: float
    snow: float
    brightness: float
    contrast: float
    haze: float


_TABLE = {
    "summer": (150.0, 62.0, 0.0, 1.0, 0.0, 1.00, 1.00, 0.05),
    "autumn": (205.0, 33.0, -0.6, 0.35, 0.0, 0.97, 1.06, 0.08),
    "winter": (168.0, 20.0, -0.3, 0.0, 0.7, 1.02, 0.85, 0.10),
    "spring": (118.0, 45.0, 0.8, 0.6, 0.0, 1.03, 0.95, 0.07),
}


def season_from(value) -> Season:
    """Season from a name (summer, autumn/fall, winter, spring) or an int (0..3, wraps)."""
    if isinstance(value, Season):
        return value
    if isinstance(value, (int, np.integer)) or (isinstance(value, str) and value.isdigit()):
        name = SEASONS[int(value) % 4]
    else:
        name = {"fall": "autumn"}.get(str(value).lower(), str(value).lower())
    if name not in _TABLE:
        raise InputError(f"season '{value}': expected one of {', '.join(SEASONS)} or 0..3")
    az, el, wl, green, snow, br, ct, hz = _TABLE[name]
    return Season(name, SEASONS.index(name), np.radians(az), np.radians(el), wl, green, snow,
                  br, ct, hz)


def hillshade(z: np.ndarray, gsd_m: float, season: Season, exaggeration: float = 1.0):
    """Lambertian shading of a height field (H, W) (m, rows to the south), float32 in [0, 1].

    Returns cos(angle between the surface normal and the sun) clipped at 0.
    """
    dz_de = cv2.Sobel(z, cv2.CV_32F, 1, 0, ksize=3) / np.float32(8.0 * gsd_m) * exaggeration
    dz_dn = -cv2.Sobel(z, cv2.CV_32F, 0, 1, ksize=3) / np.float32(8.0 * gsd_m) * exaggeration
    az, el = season.sun_azimuth_rad, season.sun_elevation_rad
    sn, se, su = np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)
    # normal ~ (-dz/dn, -dz/de, 1) in (north, east, up)
    num = -dz_dn * np.float32(sn) - dz_de * np.float32(se) + np.float32(su)
    return np.clip(num / np.sqrt(1.0 + dz_dn * dz_dn + dz_de * dz_de), 0.0, 1.0)


def shadow_offset_px(height_m: float, gsd_m: float, season: Season) -> tuple[float, float]:
    """Image (drow, dcol) of the shadow tip of an object of height_m (away from the sun)."""
    length_px = height_m / np.tan(season.sun_elevation_rad) / gsd_m
    az = season.sun_azimuth_rad
    # Shadow points away from the sun: north component -cos(az), east -sin(az); rows grow south.
    return float(length_px * np.cos(az)), float(-length_px * np.sin(az))


def cast_shadow(mask: np.ndarray, height_m: float, gsd_m: float, season: Season,
                steps: int = 6) -> np.ndarray:
    """Shadow (H, W) float32 0..1 cast by objects `mask` (H, W, bool/uint8) of height_m.

    The object footprint swept along the shadow direction, minus the object itself, blurred a
    little (penumbra).
    """
    dr, dc = shadow_offset_px(height_m, gsd_m, season)
    m = mask.astype(np.uint8)
    acc = np.zeros_like(m)
    h, w = m.shape
    for k in range(1, steps + 1):
        f = k / steps
        M = np.float32([[1, 0, dc * f], [0, 1, dr * f]])
        acc = np.maximum(acc, cv2.warpAffine(m, M, (w, h), flags=cv2.INTER_NEAREST))
    acc[m > 0] = 0
    sh = acc.astype(np.float32)
    return cv2.GaussianBlur(sh, (0, 0), 0.7)


def terrain_shadow(z: np.ndarray, gsd_m: float, season: Season, max_len_px: int = 200) -> np.ndarray:
    """Cast shadows of a height field (H, W): 1 where the sun is hidden by terrain, float32.

    Marches towards the sun; meant for coarse grids (upsample the result).
    """
    az, el = season.sun_azimuth_rad, season.sun_elevation_rad
    # towards the sun in image coordinates (rows grow south)
    dr, dc = -np.cos(az), np.sin(az)
    h, w = z.shape
    shadow = np.zeros((h, w), bool)
    rise = np.float32(np.tan(el) * gsd_m)
    k = 1
    while k <= max_len_px:
        M = np.float32([[1, 0, -dc * k], [0, 1, -dr * k]])
        zs = cv2.warpAffine(z, M, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        shadow |= zs > z + rise * k
        k = k + max(1, k // 8)
    return shadow.astype(np.float32)


def tone(rgb: np.ndarray, season: Season, gsd_m: float) -> None:
    """Camera finish, in place on (H, W, 3) float32 0..1: desaturation towards luminance,
    brightness/contrast, haze and a little optical blur (reach ~3 px)."""
    # real aerial imagery is far less saturated than a palette: pull towards luminance
    lum = rgb.mean(axis=2, keepdims=True)
    rgb *= np.float32(0.72)
    lum *= np.float32(0.28)
    rgb += lum
    del lum
    c = np.float32(season.contrast)
    haze = np.float32(season.haze)
    # (x - 0.35) * c + 0.35 * brightness, then haze: one affine map per channel
    gain = c * (1 - haze)
    bias = ((np.float32(0.35 * season.brightness) - np.float32(0.35) * c) * (1 - haze)
            + haze * np.array([0.62, 0.66, 0.72], np.float32))
    rgb *= gain
    rgb += bias
    sigma = 0.55 if gsd_m < 2 else 0.35
    cv2.GaussianBlur(rgb, (0, 0), sigma, dst=rgb)


def grain(rgb: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Sensor noise and quantisation: (H, W, 3) float32 0..1 (modified) -> uint8 (H, W, 3)."""
    noise = rng.standard_normal(rgb.shape[:2], dtype=np.float32)
    noise *= np.float32(0.012 * 255.0)
    rgb *= np.float32(255.0)
    rgb += noise[..., None]
    np.clip(rgb, 0, 255, out=rgb)
    return rgb.astype(np.uint8)


def finish(rgb: np.ndarray, season: Season, rng: np.random.Generator, gsd_m: float) -> np.ndarray:
    """tone + grain of a whole image (H, W, 3) float32 (modified); returns uint8."""
    tone(rgb, season, gsd_m)
    return grain(rgb, rng)


def tint(base: np.ndarray, mask: np.ndarray, color, amount=1.0) -> None:
    """Blend `color` (3,) into base (H, W, 3) float32 where mask (H, W) (float weight or bool)."""
    col = np.asarray(color, np.float32)
    if mask.dtype == bool:
        base[mask] = base[mask] * (1 - np.float32(amount)) + col * np.float32(amount)
    else:
        wgt = (mask.astype(np.float32) * np.float32(amount))[..., None]
        base *= 1 - wgt
        base += wgt * col
