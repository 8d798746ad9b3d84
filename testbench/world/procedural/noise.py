"""Seeded noise fields for the procedural worlds (vectorised, deterministic, band by band).

Every random draw comes from `stream(seed, name)`: a numpy Generator keyed by the world seed
and a stable name, so that the LAYOUT streams do not depend on the season (appearance streams
add the season to the name) and adding a feature does not reshuffle the others.

Worlds are generated in row bands (see bands.py). A `Field` gives any rows [r0, r1) of a
full-resolution (H, W) field, r0 < 0 or r1 > H included (halo rows beyond the edge): the value
of a pixel depends only on its absolute (row, col), never on the band it was asked in, so a
banded world is seamless. Two kinds:
- `ValueNoise`: a random lattice whose rows are drawn lazily in blocks keyed by (key, block),
  bicubically interpolated (fine noise, evaluated at full resolution per band);
- `Coarse`: an array on a coarse grid (k x coarser, with a margin of rows beyond the world edge)
  interpolated per band (large-scale noise octaves, distance fields, eroded relief).
"""

from __future__ import annotations

import threading
import zlib

import cv2
import numpy as np

SIGMA_VALUE_NOISE = 0.245  # std of one bicubic value-noise octave (uniform lattice, clipped)
_BLOCK = 64  # lattice rows per lazily drawn block
_A = -0.75  # OpenCV's bicubic kernel parameter


def stream(seed: int, name: str) -> np.random.Generator:
    """Independent Generator for (seed, name); stable across runs and platforms."""
    return np.random.default_rng([int(seed) & 0xFFFFFFFF, zlib.crc32(name.encode())])


def _cubic_weights(t: np.ndarray) -> np.ndarray:
    """(n,) fractions in [0, 1) -> (n, 4) float32 weights of samples i-1, i, i+1, i+2."""
    x = t.astype(np.float64)
    w0 = ((_A * (x + 1) - 5 * _A) * (x + 1) + 8 * _A) * (x + 1) - 4 * _A
    w1 = ((_A + 2) * x - (_A + 3)) * x * x + 1
    y = 1 - x
    w2 = ((_A + 2) * y - (_A + 3)) * y * y + 1
    return np.stack([w0, w1, w2, 1 - w0 - w1 - w2], axis=1).astype(np.float32)


class Field:
    """A full-resolution (H, W) float32 field produced by rows."""

    width: int

    def rows(self, r0: int, r1: int) -> np.ndarray:
        raise NotImplementedError


class _Interp(Field):
    """Separable interpolation of a source grid: x by cv2.resize of whole source rows to wbig
    columns cropped at ox, y by explicit weights at source row (r + oy + 0.5) * sy - 0.5."""

    def __init__(self, width: int, sy: float, oy: float, wbig: int, ox: int, cubic: bool):
        self.width, self.sy, self.oy, self.wbig, self.ox, self.cubic = width, sy, oy, wbig, ox, cubic

    def _src(self, lo: int, hi: int) -> np.ndarray:  # source rows [lo, hi), float32
        raise NotImplementedError

    def rows(self, r0: int, r1: int) -> np.ndarray:
        ys = (np.arange(r0, r1, dtype=np.float64) + self.oy + 0.5) * self.sy - 0.5
        i = np.floor(ys).astype(np.int64)
        t = ys - i
        taps = 4 if self.cubic else 2
        lo = int(i[0]) - (1 if self.cubic else 0)
        hi = int(i[-1]) + (3 if self.cubic else 2)
        src = self._src(lo, hi)
        interp = cv2.INTER_CUBIC if self.cubic else cv2.INTER_LINEAR
        if self.wbig == src.shape[1] and self.ox == 0:
            xs = src
        else:
            xs = cv2.resize(src, (self.wbig, src.shape[0]), interpolation=interp)
        xs = xs[:, self.ox:self.ox + self.width]
        rel = i - lo
        if not self.cubic:
            a = xs[rel]
            out = xs[rel + 1] - a
            out *= t.astype(np.float32)[:, None]
            out += a
            return out
        w = _cubic_weights(t)
        rel -= 1  # taps i-1 .. i+2
        out = xs[rel] * w[:, 0:1]
        for k in range(1, taps):
            out += xs[rel + k] * w[:, k:k + 1]
        return out


class ValueNoise(_Interp):
    """Smooth noise in [0, 1] with feature size ~cell_px (bicubic random lattice), lazily drawn.

    The lattice rows are drawn in blocks of 64 from a Generator keyed by (key, block index), the
    key drawn once from `rng`: any band of rows, inside or beyond the world, is reproducible.
    """

    def __init__(self, rng: np.random.Generator, shape: tuple[int, int], cell_px: float):
        h, w = shape
        cell = max(float(cell_px), 1.0)
        gw = int(np.ceil(w / cell)) + 3
        wbig = int(round(gw * cell))
        o = int(round(cell))
        super().__init__(w, gw / wbig, o, wbig, o, True)
        self.gw = gw
        self.key = [int(k) for k in rng.integers(0, 2**32, 2)]
        self._cache: dict[int, np.ndarray] = {}
        self._lock = threading.Lock()  # bands are painted in threads (bands.generate)

    def _block(self, b: int) -> np.ndarray:
        with self._lock:
            blk = self._cache.get(b)
        if blk is None:
            # Drawn outside the lock: a block is the same whichever thread draws it first.
            g = np.random.default_rng(self.key + [b & 0xFFFFFFFF])
            blk = g.random((_BLOCK, self.gw), dtype=np.float32)
            with self._lock:
                if len(self._cache) > 8:
                    self._cache.pop(next(iter(self._cache)))
                self._cache[b] = blk
        return blk

    def _src(self, lo, hi):
        b0, b1 = lo // _BLOCK, (hi - 1) // _BLOCK
        blocks = np.concatenate([self._block(b) for b in range(b0, b1 + 1)], axis=0)
        return blocks[lo - b0 * _BLOCK:hi - b0 * _BLOCK]

    def rows(self, r0, r1):
        out = super().rows(r0, r1)
        return np.clip(out, 0.0, 1.0, out=out)


class Coarse(_Interp):
    """A coarse array seen at full resolution.

    arr (Hc, Wc): coarse pixel (j, i) is centred on full-resolution pixel coordinates
    ((j + 0.5) * k - margin - 0.5, (i + 0.5) * k - 0.5); rows beyond the array repeat its edge.
    """

    def __init__(self, arr: np.ndarray, k: int, margin: int, width: int, cubic: bool = False):
        super().__init__(width, 1.0 / k, margin, arr.shape[1] * k, 0, cubic)
        self.arr = np.ascontiguousarray(arr, dtype=np.float32)
        self.k, self.margin = k, margin

    def _src(self, lo, hi):
        idx = np.clip(np.arange(lo, hi), 0, self.arr.shape[0] - 1)
        return self.arr[idx]

    def nearest(self, r0: int, r1: int) -> np.ndarray:
        """Rows [r0, r1) by nearest neighbour (labels)."""
        j = np.clip((np.arange(r0, r1) + self.margin) // self.k, 0, self.arr.shape[0] - 1)
        cols = np.minimum(np.arange(self.width) // self.k, self.arr.shape[1] - 1)
        return self.arr[j][:, cols]


class CoarseGrid:
    """A coarse grid k x coarser than a world (H, W), with `margin` full-res rows beyond the
    north and south edges: shape, and east/north (m) of its pixel centres."""

    def __init__(self, shape: tuple[int, int], gsd_m: float, k: int, margin: int):
        h, w = shape
        self.k, self.margin, self.width, self.gsd_m = int(k), int(margin), w, gsd_m
        self.shape = (int(np.ceil((h + 2 * margin) / k)) + 1, int(np.ceil(w / k)))
        jc = np.arange(self.shape[0], dtype=np.float64)
        ic = np.arange(self.shape[1], dtype=np.float64)
        self.north = ((h / 2 - (jc + 0.5) * k + margin) * gsd_m).astype(np.float32)[:, None]
        self.east = (((ic + 0.5) * k - w / 2) * gsd_m).astype(np.float32)[None, :]

    def to_px(self, col_row: np.ndarray) -> np.ndarray:
        """Full-resolution (col, row) pixel coordinates (N, 2) -> coarse ones."""
        p = np.asarray(col_row, np.float64)
        return np.stack([(p[:, 0] + 0.5) / self.k - 0.5,
                         (p[:, 1] + self.margin + 0.5) / self.k - 0.5], axis=1)

    def field(self, arr: np.ndarray, cubic: bool = False) -> Coarse:
        return Coarse(arr, self.k, self.margin, self.width, cubic)


def value_noise(rng: np.random.Generator, shape: tuple[int, int], cell_px: float) -> np.ndarray:
    """Whole-array smooth noise in [0, 1] (for coarse grids): a random lattice, bicubically
    resized; float32 (H, W)."""
    h, w = shape
    cell = max(float(cell_px), 1.0)
    gh, gw = int(np.ceil(h / cell)) + 3, int(np.ceil(w / cell)) + 3
    grid = rng.random((gh, gw), dtype=np.float32)
    if cell <= 1.0:
        return grid[:h, :w].copy()
    big = cv2.resize(grid, (int(round(gw * cell)), int(round(gh * cell))),
                     interpolation=cv2.INTER_CUBIC)
    o = int(round(cell))
    out = big[o:o + h, o:o + w]
    return np.clip(out, 0.0, 1.0)


def _octaves(cell_px, octaves, gain, lacunarity, min_cell_px):
    amp, cell = 1.0, float(cell_px)
    for _ in range(octaves):
        if cell < min_cell_px:
            break
        yield amp, cell
        amp *= gain
        cell /= lacunarity


def fbm(rng: np.random.Generator, shape: tuple[int, int], cell_px: float, octaves: int = 5,
        gain: float = 0.5, lacunarity: float = 2.0, min_cell_px: float = 1.5) -> np.ndarray:
    """Whole-array fractal (fBm) value noise, float32 (H, W), zero mean, unit std (approx.)."""
    out = np.zeros(shape, np.float32)
    norm = 0.0
    for amp, cell in _octaves(cell_px, octaves, gain, lacunarity, min_cell_px):
        out += np.float32(amp) * (value_noise(rng, shape, cell) - np.float32(0.5))
        norm += amp * amp
    if norm > 0:
        out *= np.float32(1.0 / (SIGMA_VALUE_NOISE * np.sqrt(norm)))
    return out


class Fbm(Field):
    """Fractal value noise by rows, zero mean and unit std (analytic normalisation).

    Octaves with cells of at least 4 coarse pixels are summed once on `grid` (a CoarseGrid)
    and interpolated bicubically; finer octaves are ValueNoise at full resolution.
    """

    def __init__(self, rng: np.random.Generator, grid: CoarseGrid, shape: tuple[int, int],
                 cell_px: float, octaves: int = 5, gain: float = 0.5, lacunarity: float = 2.0,
                 min_cell_px: float = 1.5):
        self.width = shape[1]
        coarse = None
        self.fine: list[tuple[float, ValueNoise]] = []
        norm = 0.0
        for amp, cell in _octaves(cell_px, octaves, gain, lacunarity, min_cell_px):
            norm += amp * amp
            if cell >= 4 * grid.k:
                v = value_noise(rng, grid.shape, cell / grid.k) - np.float32(0.5)
                coarse = v * np.float32(amp) if coarse is None else coarse + np.float32(amp) * v
            else:
                self.fine.append((amp, ValueNoise(rng, shape, cell)))
        self.scale = np.float32(1.0 / (SIGMA_VALUE_NOISE * np.sqrt(max(norm, 1e-12))))
        self.coarse = grid.field(coarse * self.scale, cubic=True) if coarse is not None else None

    def rows(self, r0, r1):
        if self.coarse is not None:
            out = self.coarse.rows(r0, r1)
        else:
            out = np.zeros((r1 - r0, self.width), np.float32)
        for amp, vn in self.fine:
            v = vn.rows(r0, r1)
            v -= np.float32(0.5)
            v *= np.float32(amp) * self.scale
            out += v
        return out


def smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    """Hermite step from 0 at e0 to 1 at e1 (float32)."""
    t = np.clip((x - np.float32(e0)) / np.float32(e1 - e0), 0.0, 1.0)
    return t * t * (np.float32(3.0) - np.float32(2.0) * t)


def grid_coords(shape: tuple[int, int], gsd_m: float, r0: int = 0, r1: int | None = None):
    """Local east (1, W) and north (r1-r0, 1) coordinates (m) of pixel centres of rows
    [r0, r1) (default all), world centred at 0."""
    h, w = shape
    r1 = h if r1 is None else r1
    east = ((np.arange(w, dtype=np.float64) + 0.5 - w / 2) * gsd_m).astype(np.float32)[None, :]
    north = ((h / 2 - np.arange(r0, r1, dtype=np.float64) - 0.5) * gsd_m).astype(np.float32)[:, None]
    return east, north


def resize_to(a: np.ndarray, shape: tuple[int, int], interp=cv2.INTER_LINEAR) -> np.ndarray:
    """Resize a 2-D/3-D array to (H, W) with OpenCV."""
    return cv2.resize(a, (shape[1], shape[0]), interpolation=interp)
