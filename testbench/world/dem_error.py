"""The error of a DEM a vehicle carries against the terrain it flies over.

A real onboard DEM is another product than the ground: SRTM and Copernicus GLO-30 err by a
few metres RMS, in patches hundreds of metres across (radar penetration, vegetation, voids
filled, co-registration). `ErroredElevation` wraps the world's terrain model and adds such a
field: Gaussian white noise on a grid of nodes, interpolated by cubic splines
(scipy.ndimage.map_coordinates) and scaled to rms_m over the grid. correlation_m is the lag at
which the error's correlation falls to exp(-1/2), as for a Gaussian correlation function
exp(-d^2 / (2 L^2)) of length L (what terrain-aided navigation assumes, navigation/tan): the
splines' correlation falls so at 0.57 node spacings, so the nodes lie correlation_m / 0.57
apart. It is drawn once from its own generator, so that the same seed gives the same onboard
DEM in every run.

Heights are metres above the origin's altitude (world/elevation.py), north/east local metres.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import map_coordinates

from testbench.world.raster import LocalRaster

_DEFAULT_HALF_SPAN_M = 20_000.0  # a terrain model without a footprint (flat ground): 40 km square
_SPLINE_LAG_AT_EXP_HALF = 0.57  # cubic splines through white nodes: correlation exp(-1/2) at this many spacings


class DemErrorField:
    """A smooth random height error (m) over bounds (north_min, north_max, east_min, east_max, m)."""

    def __init__(self, rms_m: float, correlation_m: float, bounds_ne_m, rng: np.random.Generator):
        n0, n1, e0, e1 = (float(x) for x in bounds_ne_m)
        self.spacing_m = float(correlation_m) / _SPLINE_LAG_AT_EXP_HALF
        # Two nodes of margin beyond the bounds, so that cubic splines have support at the edges.
        self.north_max_m = n1 + 2.0 * self.spacing_m
        self.east_min_m = e0 - 2.0 * self.spacing_m
        rows = int(np.ceil((self.north_max_m - (n0 - 2.0 * self.spacing_m)) / self.spacing_m)) + 1
        cols = int(np.ceil((e1 + 2.0 * self.spacing_m - self.east_min_m) / self.spacing_m)) + 1
        self.nodes = rng.standard_normal((rows, cols))
        # Scale to rms_m as interpolated (splines smooth the nodes' variance away): measured on
        # a grid four times finer than the nodes.
        r = np.arange(0.0, rows - 1.0, 0.25)
        c = np.arange(0.0, cols - 1.0, 0.25)
        R, C = np.meshgrid(r, c, indexing="ij")
        raw = map_coordinates(self.nodes, [R.ravel(), C.ravel()], order=3, mode="nearest")
        self.nodes *= float(rms_m) / max(float(np.sqrt(np.mean(raw**2))), 1e-12)

    def at(self, north_m, east_m) -> np.ndarray:
        """The error (m) at local (north_m, east_m) (arrays broadcast together)."""
        n, e = np.broadcast_arrays(np.asarray(north_m, float), np.asarray(east_m, float))
        row = (self.north_max_m - n) / self.spacing_m
        col = (e - self.east_min_m) / self.spacing_m
        out = map_coordinates(self.nodes, [row.ravel(), col.ravel()], order=3, mode="nearest")
        return out.reshape(n.shape)


class ErroredElevation:
    """A terrain model (FlatElevation or ElevationModel) plus a DemErrorField: the DEM a
    vehicle carries. Same interface: height_m, height_and_valid, read_local, footprint,
    native_gsd_m, close."""

    def __init__(self, base, rms_m: float, correlation_m: float, rng: np.random.Generator):
        self.base = base
        fp = getattr(base, "footprint", None)
        bounds = ((fp.north_min_m, fp.north_max_m, fp.east_min_m, fp.east_max_m) if fp is not None
                  else (-_DEFAULT_HALF_SPAN_M, _DEFAULT_HALF_SPAN_M, -_DEFAULT_HALF_SPAN_M, _DEFAULT_HALF_SPAN_M))
        self.error = DemErrorField(rms_m, correlation_m, bounds, rng)

    footprint = property(lambda self: getattr(self.base, "footprint", None))
    native_gsd_m = property(lambda self: getattr(self.base, "native_gsd_m", None))

    def height_m(self, north_m, east_m) -> np.ndarray:
        return self.base.height_m(north_m, east_m) + self.error.at(north_m, east_m)

    def height_and_valid(self, north_m, east_m):
        h, ok = self.base.height_and_valid(north_m, east_m)
        return h + self.error.at(north_m, east_m), ok

    def read_local(self, north_min_m, north_max_m, east_min_m, east_max_m, gsd_m) -> LocalRaster:
        r = self.base.read_local(north_min_m, north_max_m, east_min_m, east_max_m, gsd_m)
        h, w = r.shape
        north = r.north0_m - (np.arange(h) + 0.5) * r.gsd_m
        east = r.east0_m + (np.arange(w) + 0.5) * r.gsd_m
        err = self.error.at(north[:, None], east[None, :]).astype(np.float32)
        return LocalRaster(r.data + err, r.valid, r.north0_m, r.east0_m, r.gsd_m)

    def close(self) -> None:
        self.base.close()
