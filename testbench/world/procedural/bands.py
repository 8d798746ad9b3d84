"""Band-by-band generation of the procedural worlds.

A terrain is a `Terrain` subclass: its constructor lays out everything global once (paths,
objects, coarse fields, noise keys; all small) and `rows(a, b)` paints the rows [a, b) of the
image before the camera finish (float32 RGB) and of the relief. `generate` calls it on bands of
rows widened by a halo (shadows, blurs and distance fields reach across band edges), keeps the
band's own rows and applies the finish: the world never sits in memory at full resolution as
float32, and every pixel's value depends only on its position, so the bands join seamlessly.
The band layout depends only on the world's shape: same inputs, bit-identical output.
"""

from __future__ import annotations

import itertools
import os
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from typing import Iterator

import numpy as np

from testbench.core.errors import InputError
from testbench.world.procedural.appearance import Season, grain, tone
from testbench.world.procedural.noise import CoarseGrid, grid_coords, stream

BAND_PIXELS = 2_000_000  # ~ pixels per band (a few tens of MB of float32 working arrays)
COARSE_K = 4  # coarse grid factor for large-scale noise and distance fields


class Terrain:
    """Base of the terrains. Subclasses set `name`, `halo_m` and implement rows()."""

    name = "terrain"
    halo_m = 40.0  # longest cast shadow or other reach across rows (m)

    def __init__(self, seed: int, shape: tuple[int, int], gsd_m: float, season: Season):
        self.seed, self.shape, self.gsd_m, self.season = int(seed), tuple(shape), float(gsd_m), season
        self.halo = int(np.ceil(self.halo_m / self.gsd_m)) + 8
        m = -(-self.halo // COARSE_K) * COARSE_K + 4 * COARSE_K
        self.grid = CoarseGrid(self.shape, self.gsd_m, COARSE_K, m)

    def coords(self, a: int, b: int):
        """east (1, W), north (b-a, 1) of rows [a, b) (m)."""
        return grid_coords(self.shape, self.gsd_m, a, b)

    def rows(self, a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
        """Rows [a, b) (may extend beyond 0..H): RGB float32 (b-a, W, 3) 0..1, z float32 (m)."""
        raise NotImplementedError


def band_rows(h: int, w: int, halo: int) -> list[tuple[int, int]]:
    """Bands [r0, r1) covering 0..h: multiples of 256 rows (whole GeoTIFF blocks)."""
    step = max(256, 4 * halo, int(round(BAND_PIXELS / max(w, 1))))
    step = -(-step // 256) * 256
    return [(r0, min(h, r0 + step)) for r0 in range(0, h, step)]


def _band(gen: Terrain, r0: int, r1: int) -> tuple[int, np.ndarray, np.ndarray]:
    """(r0, rgb uint8 (r1-r0, W, 3), z float32 (r1-r0, W)) of the band [r0, r1)."""
    a, b = r0 - gen.halo, r1 + gen.halo
    rgb, z = gen.rows(a, b)
    tone(rgb, gen.season, gen.gsd_m)
    band = rgb[r0 - a:r1 - a]
    rng = stream(gen.seed, f"{gen.name}-grain-{gen.season.name}-{r0}")
    return r0, grain(band, rng), np.ascontiguousarray(z[r0 - a:r1 - a], dtype=np.float32)


def generation_threads() -> int:
    """Threads that paint a world's bands: $TESTBENCH_WORLD_THREADS, else the cores this
    process may run on, at most 4 (each band in flight holds a few hundred MB of float32)."""
    env = os.environ.get("TESTBENCH_WORLD_THREADS")
    if env:
        n = int(env) if env.strip().isdigit() else 0
        if n < 1:
            raise InputError(f"TESTBENCH_WORLD_THREADS={env!r}: expected a whole number of threads >= 1")
        return n
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, min(4, cores))


def generate(gen: Terrain, threads: int | None = None) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
    """Yield (r0, rgb uint8 (n, W, 3), z float32 (n, W)) for consecutive bands of `gen`.

    threads (default generation_threads()): bands painted at once. A band's pixels depend only
    on their position, and numpy and OpenCV release the GIL over whole arrays, so threads give
    the same bands, in order, sooner; at most threads + 1 bands are held at a time.
    """
    bands = band_rows(*gen.shape, gen.halo)
    n = generation_threads() if threads is None else max(1, int(threads))
    if n == 1 or len(bands) == 1:
        for r0, r1 in bands:
            yield _band(gen, r0, r1)
        return
    with ThreadPoolExecutor(max_workers=n, thread_name_prefix="world-band") as pool:
        todo = iter(bands)
        pending = deque(pool.submit(_band, gen, r0, r1) for r0, r1 in itertools.islice(todo, n))
        try:
            while pending:
                done = pending.popleft().result()
                nxt = next(todo, None)
                if nxt is not None:
                    pending.append(pool.submit(_band, gen, *nxt))
                yield done  # n bands in the threads meanwhile, this one with the caller
        finally:  # the caller stopped early (an error writing): do not paint the rest
            for f in pending:
                f.cancel()
