"""A broken cloud layer between the cameras and the ground (`world.clouds`).

Clouds are what most often takes scene matching away from a real flight: the camera sees
cloud tops instead of the ground it carries a map of, for a while or in patches. The layer is
a thin horizontal sheet at `base_m` above the origin's altitude (NED down = -base_m), whose
optical density d(n, e, t) in [0, 1] is a seeded random field:

    n(x)  a periodic Gaussian random field of unit variance, power spectrum
          P(k) ~ (k0^2 + |k|^2)^(-11/6) (a von Karman spectrum, as observed cloud fields
          follow a -5/3 power law over the inertial range), k0 = 2 pi / cell_m, so the
          cloud cells are about cell_m across, with ragged edges;
    d = clip(0.5 + (n(x - drift t) - q(1 - c(t))) / (2 s), 0, 1),

q the field's own quantile, c(t) the coverage at t (the share of the sky where d >= 0.5) and
s = 0.1 the edge's softness in the field's sigmas. The field moves with the drift velocity
(by default the world's steady wind: clouds move with the air). A ray that crosses the sheet
takes alpha = opacity * d of the cloud's colour (camera/clouds.py); coverage 0 is no cloud
at all, coverage 1 an overcast sheet (d = 1 everywhere).

Shadows: the ground under a cloud's shadow gets the diffuse skylight alone. A ground point G
(NED) looks toward the sun along the unit vector s (NED, s_down < 0); the ray crosses the
sheet at G + lambda s, lambda = (down_sheet - G_down) / s_down, and the direct sun that passes
is 1 - alpha there. The ground's light is then

    L = diffuse + (1 - diffuse) (1 - alpha),

`diffuse` the share of a clear day's light that is skylight (about 0.2-0.4 in linear
radiance). The shadows move with the clouds, so they move over the ground the camera sees.

What is not modelled: the layer's thickness (a vehicle inside a cloud sees through it), light
the clouds scatter onto the ground beside them, and the clouds' effect on UWB, GNSS or the
magnetometer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import cv2
import numpy as np

EDGE_SOFTNESS_SIGMA = 0.1
"""Width of a cloud's edge, from clear to opaque, in sigmas of the field (2 s in the formula)."""

_TILE_PX = 512
_CELL_PX = 16  # field pixels per cell_m: the tile spans 32 cells before it repeats


@dataclass(frozen=True)
class CoverageWindow:
    """Coverage `coverage` (0-1) over [start_s, end_s) of simulated time."""

    start_s: float
    end_s: float
    coverage: float


class CloudLayer:
    """The world's cloud sheet: its height, its coverage over time and its density field.

    base_m: the sheet's height above the origin's altitude (m; NED down = -base_m);
    coverage: the share of the sky under cloud outside the windows (0-1);
    windows: CoverageWindow sequence (non-overlapping) that set another coverage for a while;
    cell_m: the typical cloud's size (m); opacity: alpha of an optically thick cloud (0-1];
    drift_ne_mps: (2,) the field's velocity over the ground, north and east (m/s);
    rng: the generator the field is drawn from (once, here);
    sun_ned: (3,) unit vector toward the sun (NED), or None: no shadows on the ground;
    shadow_light: the share of the ground's light left in a thick cloud's shadow (the
    diffuse skylight, linear radiance, 0-1; 1: no shadows)."""

    def __init__(self, base_m: float, coverage: float, windows: Sequence[CoverageWindow], cell_m: float,
                 opacity: float, drift_ne_mps: tuple[float, float], rng: np.random.Generator, *,
                 sun_ned: Sequence[float] | None = None, shadow_light: float = 1.0):
        self.base_m = float(base_m)
        self.down_m = -self.base_m
        self.coverage = float(coverage)
        self.windows = tuple(windows)
        self.cell_m = float(cell_m)
        self.opacity = float(opacity)
        self.drift_ne_mps = (float(drift_ne_mps[0]), float(drift_ne_mps[1]))
        self.px_m = self.cell_m / _CELL_PX
        self.field = _von_karman_field(_TILE_PX, _CELL_PX, rng)
        """(512, 512) float32 unit-variance field, rows north, columns east, periodic."""
        self._sorted = np.sort(self.field, axis=None)
        self.sun_ned = None
        if sun_ned is not None and shadow_light < 1.0:
            sun = np.asarray(sun_ned, float)
            norm = float(np.linalg.norm(sun))
            if not (norm > 0.0 and sun[2] < 0.0):
                raise ValueError(f"sun_ned {sun.tolist()} does not point above the horizon (expected a NED vector "
                                 f"with a negative down component)")
            self.sun_ned = sun / norm
        self.shadow_light = float(shadow_light)

    def coverage_at(self, t_s: float) -> float:
        """The share of the sky under cloud at t_s (0-1)."""
        for w in self.windows:
            if w.start_s <= t_s < w.end_s:
                return w.coverage
        return self.coverage

    def at(self, t_s: float) -> "CloudView":
        """The layer as a camera sees it at t_s."""
        return CloudView(self, t_s, self.coverage_at(t_s))


class CloudView:
    """The cloud sheet at one instant: `alpha(north_m, east_m)` and where it lies (down_m)."""

    def __init__(self, layer: CloudLayer, t_s: float, coverage: float):
        self.layer = layer
        self.t_s = float(t_s)
        self.coverage = float(coverage)
        self.down_m = layer.down_m
        if 0.0 < coverage < 1.0:
            s = layer._sorted
            self._threshold = float(s[min(int(round((1.0 - coverage) * (s.size - 1))), s.size - 1)])

    @property
    def clear(self) -> bool:
        """True when there is no cloud at all at this instant (coverage 0 or opacity 0)."""
        return self.coverage <= 0.0 or self.layer.opacity <= 0.0

    @property
    def casts_shadows(self) -> bool:
        """True when the clouds darken the ground now (a sun above the horizon and clouds)."""
        return self.layer.sun_ned is not None and not self.clear

    def ground_light(self, north_m, east_m, down_m) -> np.ndarray:
        """The share of a clear day's light (linear, float32 in [shadow_light, 1], the inputs'
        shape) that reaches NED ground points (m): the diffuse skylight plus the direct sun
        the sheet lets pass on the way to the sun. 1 where no shadow falls (no sun, a clear
        sky, ground above the sheet)."""
        n = np.asarray(north_m, float)
        if not self.casts_shadows:
            return np.ones(n.shape, np.float32)
        e = np.asarray(east_m, float)
        d = np.asarray(down_m, float)
        s = self.layer.sun_ned
        lam = (self.down_m - d) / s[2]  # metres toward the sun to the sheet (> 0 below it)
        below = lam > 0.0
        a = self.alpha(np.where(below, n + lam * s[0], 0.0), np.where(below, e + lam * s[1], 0.0))
        diffuse = np.float32(self.layer.shadow_light)
        light = diffuse + (np.float32(1.0) - diffuse) * (np.float32(1.0) - a)
        return np.where(below, light, np.float32(1.0)).astype(np.float32, copy=False)

    def density(self, north_m, east_m) -> np.ndarray:
        """Optical density d in [0, 1] (float32, the shape of the inputs) at NED north / east
        points of the sheet (m)."""
        return self.sample(north_m, east_m)[0]

    def sample(self, north_m, east_m) -> tuple[np.ndarray, np.ndarray]:
        """(density d, depth) at NED north / east points of the sheet (m), float32 arrays of
        the inputs' shape. depth in [0, 1]: how far inside its cloud a point lies, in sigmas of
        the field beyond the edge (0 at the edge, 1 a sigma in; 1 everywhere under overcast),
        which shades the tops (a cloud's core is thicker and brighter than its fringe)."""
        n = np.asarray(north_m, float)
        e = np.asarray(east_m, float)
        if self.coverage <= 0.0:
            return np.zeros(n.shape, np.float32), np.zeros(n.shape, np.float32)
        lay = self.layer
        if self.coverage >= 1.0:
            ones = np.ones(n.shape, np.float32)
            return ones, ones
        # The point's place in the tile the wind has moved, wrapped there in float64 first (a
        # float32 map loses the pixel's fraction tens of kilometres out).
        period = _TILE_PX * lay.px_m
        rows = np.mod(n - lay.drift_ne_mps[0] * self.t_s, period) / lay.px_m
        cols = np.mod(e - lay.drift_ne_mps[1] * self.t_s, period) / lay.px_m
        value = _sample_wrapped(lay.field, rows, cols).reshape(n.shape)
        above = value - np.float32(self._threshold)
        d = np.clip(0.5 + above / np.float32(2.0 * EDGE_SOFTNESS_SIGMA), 0.0, 1.0)
        return d.astype(np.float32, copy=False), np.clip(above, 0.0, 1.0).astype(np.float32, copy=False)

    def alpha(self, north_m, east_m) -> np.ndarray:
        """How much of a ray crossing the sheet the cloud takes (opacity x density), float32."""
        return self.layer.opacity * self.density(north_m, east_m)

    def crossing_ne(self, origin_ned_m: np.ndarray, point_ned_m: np.ndarray) -> np.ndarray | None:
        """(2,) north, east where the segment from origin to point (NED m, (3,)) crosses the
        sheet, or None when both lie on one side of it."""
        a = float(origin_ned_m[2]) - self.down_m
        b = float(point_ned_m[2]) - self.down_m
        if a * b > 0.0 or a == b:
            return None
        s = a / (a - b)
        return np.asarray(origin_ned_m[:2], float) + s * (np.asarray(point_ned_m[:2], float) - np.asarray(origin_ned_m[:2], float))

    def hides(self, origin_ned_m: np.ndarray, point_ned_m: np.ndarray) -> bool:
        """True when the sheet between origin and point (NED m) takes at least half the light."""
        ne = self.crossing_ne(origin_ned_m, point_ned_m)
        if ne is None or self.clear:
            return False
        return bool(self.alpha(ne[0], ne[1]) >= 0.5)


def _sample_wrapped(field: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """(N,) bilinear samples of the periodic `field` at fractional (rows, cols), any shape
    (N points), through cv2.remap, whose maps are at most 32767 a side: the points go in rows
    of 1024."""
    n = rows.size
    width = 1024 if n > 1024 else max(n, 1)
    pad = (-n) % width
    r = np.pad(rows.ravel(), (0, pad)).astype(np.float32).reshape(-1, width)
    c = np.pad(cols.ravel(), (0, pad)).astype(np.float32).reshape(-1, width)
    return cv2.remap(field, c, r, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP).ravel()[:n]


def _von_karman_field(size_px: int, cell_px: float, rng: np.random.Generator) -> np.ndarray:
    """(size_px, size_px) float32 periodic Gaussian field of zero mean and unit variance with
    the power spectrum (k0^2 + k^2)^(-11/6), k0 = 2 pi / cell_px (k in rad per pixel)."""
    white = rng.standard_normal((size_px, size_px))
    k = 2.0 * math.pi * np.fft.fftfreq(size_px)
    k2 = k[:, None] ** 2 + k[None, :] ** 2
    k0 = 2.0 * math.pi / cell_px
    amplitude = (k0 * k0 + k2) ** (-11.0 / 12.0)
    field = np.fft.ifft2(np.fft.fft2(white) * amplitude).real
    field -= field.mean()
    field /= field.std()
    return field.astype(np.float32)
