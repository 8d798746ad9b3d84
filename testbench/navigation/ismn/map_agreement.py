"""How well two reference maps agree in georeference: the displacement between them, tile by
tile, measured with the scene matcher's own appearance-robust correlation.

Two orthophotos of one place (two years of NAIP, a drone map against the aerial programme's)
disagree by where each shows the ground: their control and orthorectification differed. What
they disagree by is a lower bound on what a map a vehicle carries errs by against the truth,
and it sets world.reference_map_error (sigma per axis, correlation length) and a navigator's
map_error for a scenario over them.

Both maps are read on one local north-east grid (raster.LocalRaster convention) at one ground
sample. The grid is cut into square tiles; each of map A's tiles (its gradient-magnitude image,
features.robust_image) is searched for in map B within search_m by normalised cross-correlation
(cv2.TM_CCOEFF_NORMED), refined to a sub-pixel peak (tiles.subpixel_peak), and kept when its
peak is distinct (area.distinctiveness), high enough and inside the search. offset_ne_m (north,
east, m) is where map B shows a tile's ground minus where map A shows it. Tiles that lie partly
off either map are not used; the summary leaves out the tiles far from the others' median
(MapAgreement.inliers: ground that changed between the maps matches elsewhere).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from testbench.navigation.ismn.area import distinctiveness, peak_and_second
from testbench.navigation.ismn.features import robust_image
from testbench.navigation.ismn.ortho import to_grey_u8
from testbench.navigation.ismn.tiles import subpixel_peak

_EXP_HALF = math.exp(-0.5)  # a Gaussian correlation function's value at its length


@dataclass(frozen=True)
class MapAgreement:
    """The displacement of map B against map A over their common ground.

    centre_ne_m (n, 2): the kept tiles' centres (local north, east, m); offset_ne_m (n, 2): where
    B shows each tile's ground minus where A shows it (north, east, m); peak (n,): the tiles'
    correlation peaks; tiles_tried: tiles wholly on both maps; tile_m, gsd_m, search_m: the
    settings measured with."""

    centre_ne_m: np.ndarray
    offset_ne_m: np.ndarray
    peak: np.ndarray
    tiles_tried: int
    tile_m: float
    gsd_m: float
    search_m: float

    def inliers(self) -> np.ndarray:
        """(n,) bool: the tiles within 3 robust sigmas (1.4826 MAD per axis) of the median
        offset. A tile whose ground changed (a field ploughed, a lake's shore moved) matches
        elsewhere; those are not the maps' georeference."""
        d = self.offset_ne_m
        if len(d) == 0:
            return np.zeros(0, bool)
        med = np.median(d, axis=0)
        sigma = np.maximum(1.4826 * np.median(np.abs(d - med), axis=0), 0.1 * self.gsd_m)
        return np.all(np.abs(d - med) <= 3.0 * sigma, axis=1)

    def summary(self) -> dict:
        """The figures a scenario's map error is set from, over the inlier tiles: the mean offset
        (the maps' shift), the RMS per axis about it (the field's sigma, with the tiles' own
        matching noise in it), the largest offset, and the correlation length of the offsets
        about the mean (correlation_length_m)."""
        keep = self.inliers()
        d = self.offset_ne_m[keep]
        out = {"tiles_tried": self.tiles_tried, "tiles_matched": int(len(self.offset_ne_m)), "tiles_inliers": int(len(d)),
               "tile_m": self.tile_m, "gsd_m": self.gsd_m, "search_m": self.search_m}
        if len(d) == 0:
            return out
        dev = d - d.mean(axis=0)
        out.update(mean_offset_ne_m=[float(x) for x in d.mean(axis=0)],
                   rms_about_mean_ne_m=[float(x) for x in np.sqrt(np.mean(dev**2, axis=0))],
                   max_offset_m=float(np.max(np.hypot(*d.T))),
                   correlation_length_m=correlation_length_m(self.centre_ne_m[keep], dev, self.tile_m))
        return out


def map_agreement(map_a, map_b, bounds_ne_m, gsd_m: float, tile_m: float = 400.0, search_m: float = 25.0,
                  min_peak: float = 0.3, min_quality: float = 0.2) -> MapAgreement:
    """MapAgreement of map_b against map_a (map sources with read_local on one local frame) over
    bounds (north_min, north_max, east_min, east_max, m) at gsd_m (m per px)."""
    n0, n1, e0, e1 = (float(x) for x in bounds_ne_m)
    pad = gsd_m * math.ceil(search_m / gsd_m + 4.0)  # whole pixels: both grids' pixels coincide
    a = map_a.read_local(n0, n1, e0, e1, gsd_m)
    b = map_b.read_local(n0 - pad, n1 + pad, e0 - pad, e1 + pad, gsd_m)
    fa, va = robust_image(to_grey_u8(a.data), np.asarray(a.valid, bool))
    fb, vb = robust_image(to_grey_u8(b.data), np.asarray(b.valid, bool))
    t_px = max(8, int(round(tile_m / gsd_m)))
    s_px = int(math.ceil(search_m / gsd_m))
    # Map A's pixel (r, c) lies at map B's (r + dr, c + dc): B's grid starts pad further north and west.
    dr, dc = int(round((b.north0_m - a.north0_m) / gsd_m)), int(round((a.east0_m - b.east0_m) / gsd_m))
    centres, offsets, peaks, tried = [], [], [], 0
    for r in range(0, a.shape[0] - t_px + 1, t_px):
        for c in range(0, a.shape[1] - t_px + 1, t_px):
            rb, cb = r + dr - s_px, c + dc - s_px
            win_b = (slice(rb, rb + t_px + 2 * s_px), slice(cb, cb + t_px + 2 * s_px))
            if rb < 0 or cb < 0 or rb + t_px + 2 * s_px > fb.shape[0] or cb + t_px + 2 * s_px > fb.shape[1]:
                continue
            if not (va[r:r + t_px, c:c + t_px].all() and vb[win_b].all()):
                continue
            tried += 1
            res = cv2.matchTemplate(fb[win_b], fa[r:r + t_px, c:c + t_px], cv2.TM_CCOEFF_NORMED)
            x, y, peak, second = peak_and_second(res, exclusion_px=3)
            # A peak on the search's edge is where the search stopped, not a match.
            on_edge = x in (0, res.shape[1] - 1) or y in (0, res.shape[0] - 1)
            if on_edge or peak < min_peak or distinctiveness(peak, second) < min_quality:
                continue
            sx, sy = subpixel_peak(res, x, y)
            # Found s px east (sx - s_px) and south (sy - s_px) of where A has it.
            offsets.append(((s_px - sy) * gsd_m, (sx - s_px) * gsd_m))
            centres.append((a.north0_m - (r + 0.5 * t_px) * gsd_m, a.east0_m + (c + 0.5 * t_px) * gsd_m))
            peaks.append(peak)
    return MapAgreement(np.array(centres, float).reshape(-1, 2), np.array(offsets, float).reshape(-1, 2),
                        np.array(peaks, float), tried, float(tile_m), float(gsd_m), float(search_m))


def correlation_length_m(centres_ne_m: np.ndarray, dev_ne_m: np.ndarray, spacing_m: float) -> float | None:
    """The lag (m) at which the correlation of the offsets' deviations dev (n, 2) between tiles
    at centres (n, 2) falls to exp(-1/2), by linear interpolation between lags binned at the
    tiles' spacing (both axes pooled); None when it never falls that far over the map, or the
    offsets do not vary. Below one spacing, the correlation at lag 0 (1) and at the first bin
    are interpolated, so a field white at the tiles' spacing reads as a fraction of it."""
    var = float(np.mean(dev_ne_m**2))
    if len(dev_ne_m) < 3 or var <= 0.0:
        return None
    diff = centres_ne_m[:, None, :] - centres_ne_m[None, :, :]
    lag = np.hypot(diff[..., 0], diff[..., 1])
    prod = np.sum(dev_ne_m[:, None, :] * dev_ne_m[None, :, :], axis=2) / 2.0  # per axis, pooled
    upper = np.triu(np.ones(lag.shape, bool), k=1)
    bins = np.round(lag[upper] / spacing_m).astype(int)
    rho_prev, lag_prev = 1.0, 0.0
    for k in range(1, int(bins.max()) + 1 if bins.size else 1):
        sel = bins == k
        if sel.sum() < 3:
            continue
        rho = float(np.mean(prod[upper][sel])) / var
        if rho <= _EXP_HALF:
            lag_k = k * spacing_m
            return float(lag_prev + (rho_prev - _EXP_HALF) / (rho_prev - rho) * (lag_k - lag_prev))
        rho_prev, lag_prev = rho, k * spacing_m
    return None


def agreement_figure(result: MapAgreement, map_a_grey=None, extent_ne_m=None):
    """A matplotlib Figure of the tiles' offsets as arrows at their centres (the kept tiles dark,
    the others grey), over map A's grey image (map_a_grey (H, W) with extent_ne_m (north_min,
    north_max, east_min, east_max)) when given; east right, north up, arrows scaled so that the
    largest kept offset spans most of a tile."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.0, 6.0), dpi=100, layout="constrained")
    ax = fig.subplots()
    if map_a_grey is not None and extent_ne_m is not None:
        n0, n1, e0, e1 = extent_ne_m
        ax.imshow(map_a_grey, cmap="gray", extent=(e0, e1, n0, n1), origin="upper", alpha=0.6)
    keep = result.inliers()
    d = result.offset_ne_m
    largest = float(np.max(np.hypot(*d[keep].T))) if keep.any() else 1.0
    scale = 0.8 * result.tile_m / max(largest, 1e-6)  # plot metres per metre of offset
    for sel, colour, label in ((keep, "C0", "kept"), (~keep, "0.5", "left out (ground changed)")):
        if sel.any():
            ax.quiver(result.centre_ne_m[sel, 1], result.centre_ne_m[sel, 0], d[sel, 1] * scale, d[sel, 0] * scale,
                      angles="xy", scale_units="xy", scale=1.0, color=colour, width=0.004, label=label)
    ax.set_aspect("equal")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_title(f"where map B shows each {result.tile_m:g} m tile minus where map A does\n"
                 f"(arrows x{scale:.0f}: the longest kept is {largest:.1f} m)", fontsize=9)
    ax.legend(fontsize=8, loc="lower right")
    return fig

