"""The georeference error of a reference map a vehicle carries.

An orthophoto is only as well placed as its control points and the DEM it was orthorectified
over: an aerial orthophoto programme such as NAIP specifies its accuracy in metres, and a drone
orthophoto without ground control errs by metres as a whole. Scene matching then places the camera where the map
says the ground it sees lies, so the map's error passes into every fix, and no filter can see
it: the fixes agree with each other, not with the truth.

`DisplacedMap` wraps the map source vehicles carry (world.reference_map) and displaces its
content by d(g) = shift_ne_m + a smooth random field of sigma_m per axis (north and east each a
`DemErrorField`: Gaussian nodes through cubic splines, correlation exp(-1/2) at correlation_m).
Convention: ground that truly lies at local point g appears in the carried map at g + d(g); the
carried map at x shows the true content at x - d(x) (to first order in the field's gradient,
below 1e-2 for sigma_m / correlation_m below 1e-2). So a fix from it errs by about +d over the
ground matched. Cameras render the world's imagery, never the displaced map.

Local north/east metres at the scenario origin; the field is drawn once from its generator.
"""

from __future__ import annotations

import hashlib
import math

import cv2
import numpy as np

from testbench.world.dem_error import DemErrorField
from testbench.world.raster import LocalRaster

_DEFAULT_HALF_SPAN_M = 20_000.0  # a map source without a footprint: a 40 km square
_FIELD_SAMPLES_PER_CORRELATION = 16  # the field is evaluated this densely, then interpolated linearly


class MapDisplacement:
    """d(north, east) (m): the constant shift_ne_m (2,) plus, with sigma_m > 0, a smooth random
    field of sigma_m RMS per axis (correlation_m) over bounds (north_min, north_max, east_min,
    east_max, m), its two components drawn in turn from rng."""

    def __init__(self, shift_ne_m, sigma_m: float, correlation_m: float, bounds_ne_m, rng: np.random.Generator):
        self.shift_ne_m = np.asarray(shift_ne_m, float).reshape(2)
        self.sigma_m = float(sigma_m)
        self.correlation_m = float(correlation_m)
        self._fields = ((DemErrorField(sigma_m, correlation_m, bounds_ne_m, rng),
                         DemErrorField(sigma_m, correlation_m, bounds_ne_m, rng)) if self.sigma_m > 0 else None)
        # The largest |d| per axis (for the reads' margins), measured on a grid 4x finer than
        # the field's nodes (cubic splines overshoot their nodes a little), with 20 % to spare.
        peak = 0.0
        if self._fields is not None:
            n0, n1, e0, e1 = (float(x) for x in bounds_ne_m)
            step = self._fields[0].spacing_m / 4.0
            nn, ee = np.meshgrid(np.arange(n0, n1 + step, step), np.arange(e0, e1 + step, step), indexing="ij")
            peak = 1.2 * max(float(np.max(np.abs(f.at(nn, ee)))) for f in self._fields)
        self.max_abs_m = float(np.max(np.abs(self.shift_ne_m))) + peak
        digest = hashlib.sha1(self.shift_ne_m.tobytes())
        for f in self._fields or ():
            digest.update(f.nodes.tobytes())
        self.key = ("map-displacement", self.sigma_m, self.correlation_m, digest.hexdigest())

    @property
    def has_field(self) -> bool:
        """Whether d varies over the map (sigma_m > 0), not only the shift."""
        return self._fields is not None

    def at(self, north_m, east_m) -> tuple[np.ndarray, np.ndarray]:
        """(d_north_m, d_east_m) at local (north_m, east_m) (arrays broadcast together)."""
        n, e = np.broadcast_arrays(np.asarray(north_m, float), np.asarray(east_m, float))
        if self._fields is None:
            return np.full(n.shape, self.shift_ne_m[0]), np.full(n.shape, self.shift_ne_m[1])
        return self._fields[0].at(n, e) + self.shift_ne_m[0], self._fields[1].at(n, e) + self.shift_ne_m[1]


class DisplacedMap:
    """A map source (read_local, footprint, native_gsd_m, memo_key) whose content is displaced
    by a MapDisplacement: what a vehicle carries when its map is off its georeference."""

    def __init__(self, base, displacement: MapDisplacement):
        self.base = base
        self.displacement = displacement

    footprint = property(lambda self: getattr(self.base, "footprint", None))
    native_gsd_m = property(lambda self: getattr(self.base, "native_gsd_m", None))

    @classmethod
    def over(cls, base, shift_ne_m, sigma_m: float, correlation_m: float, rng: np.random.Generator) -> "DisplacedMap":
        """base displaced by a field drawn over its footprint (plus a correlation length), or
        over a 40 km square about the origin when it has none."""
        fp = getattr(base, "footprint", None)
        pad = float(correlation_m)
        bounds = ((fp.north_min_m - pad, fp.north_max_m + pad, fp.east_min_m - pad, fp.east_max_m + pad)
                  if fp is not None else
                  (-_DEFAULT_HALF_SPAN_M, _DEFAULT_HALF_SPAN_M, -_DEFAULT_HALF_SPAN_M, _DEFAULT_HALF_SPAN_M))
        return cls(base, MapDisplacement(shift_ne_m, sigma_m, correlation_m, bounds, rng))

    def memo_key(self, north_min_m: float, north_max_m: float, east_min_m: float, east_max_m: float,
                 gsd_m: float) -> tuple | None:
        key_fn = getattr(self.base, "memo_key", None)
        base_key = None if key_fn is None else key_fn(north_min_m, north_max_m, east_min_m, east_max_m, gsd_m)
        return None if base_key is None else ("displaced", base_key, self.displacement.key)

    def read_local(self, north_min_m: float, north_max_m: float, east_min_m: float, east_max_m: float,
                   gsd_m: float, memoise: bool = True) -> LocalRaster:
        """The carried map on the local grid of the box at gsd_m (the base's grid convention:
        north0 = north_max, east0 = east_min, ceil(extent / gsd) pixels): the base read over the
        box grown by the largest displacement, resampled (bilinear) at x - d(x). valid where
        all four taps were."""
        g = float(gsd_m)
        pad = g * math.ceil(self.displacement.max_abs_m / g + 2.0)
        extra = {"memoise": memoise} if hasattr(self.base, "memo_key") else {}
        src = self.base.read_local(north_min_m - pad, north_max_m + pad, east_min_m - pad, east_max_m + pad, g, **extra)
        h = max(1, int(math.ceil((north_max_m - north_min_m) / g - 1e-9)))
        w = max(1, int(math.ceil((east_max_m - east_min_m) / g - 1e-9)))
        d_n, d_e = self._displacement_px(north_max_m, east_min_m, g, h, w)
        # Output pixel (r, c), at x, shows the base's content at x - d(x): base row
        # r + (pad + d_n) / g, column c + (pad - d_e) / g (the base grid starts pad further
        # north and further west; north is up the rows, east along the columns).
        dr = (src.north0_m - north_max_m) / g
        dc = (east_min_m - src.east0_m) / g
        map_row = np.arange(h, dtype=np.float32)[:, None] + np.float32(dr) + d_n
        map_col = np.arange(w, dtype=np.float32)[None, :] + np.float32(dc) - d_e
        data = cv2.remap(np.ascontiguousarray(src.data), map_col, map_row, cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        valid8 = cv2.remap(np.asarray(src.valid, np.uint8) * np.uint8(255), map_col, map_row, cv2.INTER_LINEAR,
                           borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        return LocalRaster(data, valid8 == 255, float(north_max_m), float(east_min_m), g)

    def _displacement_px(self, north0_m: float, east0_m: float, g: float, h: int, w: int):
        """(d_north, d_east) in pixels (float32 (h, w)) at the pixel centres of the grid whose
        north-west corner is (north0_m, east0_m): evaluated every `step` pixels (a sixteenth of
        the correlation length: the field is smooth) and interpolated linearly between."""
        disp = self.displacement
        if not disp.has_field:
            return (np.full((h, w), disp.shift_ne_m[0] / g, np.float32),
                    np.full((h, w), disp.shift_ne_m[1] / g, np.float32))
        step = max(1, int(disp.correlation_m / _FIELD_SAMPLES_PER_CORRELATION / g))
        rows = np.arange(0, h - 1 + step, step, dtype=float)
        cols = np.arange(0, w - 1 + step, step, dtype=float)
        d_n, d_e = disp.at(north0_m - (rows[:, None] + 0.5) * g, east0_m + (cols[None, :] + 0.5) * g)
        coarse_r = (np.arange(h, dtype=np.float32) / step)[:, None] * np.ones((1, w), np.float32)
        coarse_c = (np.arange(w, dtype=np.float32) / step)[None, :] * np.ones((h, 1), np.float32)
        out = [cv2.remap((d / g).astype(np.float32), coarse_c, coarse_r, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
               for d in (d_n, d_e)]
        return out[0], out[1]

    def close(self) -> None:
        close = getattr(self.base, "close", None)
        if close is not None:
            close()
