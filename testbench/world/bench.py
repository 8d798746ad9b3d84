"""World benchmarks: procedural generation time, window reads from a 10 km x 10 km 1 m map.

run_benchmarks() -> {"world.make_map_6km_1m_s", "world.make_map_6km_1m_cpu_s",
"world.make_map_6km_1m_peak_rss_mb", "world.make_map_6km_1m_threaded_s",
"world.make_map_6km_1m_threads", "world.make_map_6km_1m_threaded_peak_rss_mb",
"world.read_local_10km_window_ms", "world.read_local_10km_coarse_ms",
"world.read_local_10km_peak_mb"}.
make_map is what `testbench make-map --terrain farmland --size-km 6 --gsd-m 1` does (generate
and write both GeoTIFFs), run in a child process so that its peak RSS is its own: once on one
thread, once with the bands painted by generation_threads() threads (the `_threaded` figures;
the same files).
Peak memory of the read is the traced (tracemalloc) peak of numpy/Python allocations.
"""

from __future__ import annotations

import math
import os
import tempfile
import time
import tracemalloc

import cv2
import numpy as np

from testbench.core.interfaces import GeodeticOrigin

_ORIGIN = GeodeticOrigin(math.radians(47.0), math.radians(-99.0), 500.0)


def _write_10km_map(path: str) -> None:
    """A 10 km x 10 km, 1 m GeoTIFF (10000^2 RGB): a 2.5 m procedural world upsampled in row
    strips, so that writing it never holds the full-resolution image."""
    import rasterio
    from rasterio.enums import ColorInterp, Resampling

    from testbench.world.procedural import make_world
    from testbench.world.procedural.writer import _profile

    rgb, _, _ = make_world("farmland", 10.0, 2.5, 1, "summer")
    n = 10000
    prof = _profile(_ORIGIN, (n, n), 1.0, 3, "uint8", 2)
    with rasterio.open(path, "w", **prof) as dst:
        strip = 1000
        for r0 in range(0, n, strip):
            src = rgb[int(r0 / 2.5):int((r0 + strip) / 2.5)]
            up = cv2.resize(src, (n, strip), interpolation=cv2.INTER_LINEAR)
            dst.write(np.moveaxis(up, -1, 0), window=rasterio.windows.Window(0, r0, n, strip))
        dst.colorinterp = [ColorInterp.red, ColorInterp.green, ColorInterp.blue]
        dst.build_overviews([2, 4, 8, 16, 32, 64], Resampling.average)


_CHILD = """
import json, math, os, resource, sys, time
os.environ.setdefault("OMP_NUM_THREADS", "1")
import cv2
cv2.setNumThreads(1)
from testbench.core.interfaces import GeodeticOrigin
from testbench.world.procedural.writer import write_world_streamed
size, out, result = float(sys.argv[1]), sys.argv[2], sys.argv[3]
t0, c0 = time.perf_counter(), time.process_time()
write_world_streamed(out, "farmland", size, 1.0, 7, "summer",
                     GeodeticOrigin(math.radians(47.0), math.radians(-99.0), 500.0))
with open(result, "w") as fh:
    json.dump([time.perf_counter() - t0, time.process_time() - c0,
               resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0], fh)
"""


def _make_map(size_km: float, out_dir: str, threads: int = 1) -> tuple[float, float, float]:
    """(wall s, CPU s, peak RSS MB) of generating and writing a farmland world with its bands
    painted by `threads` threads, in a child (its own peak memory), which writes them as JSON
    next to the world."""
    import json
    import subprocess
    import sys

    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", TESTBENCH_WORLD_THREADS=str(threads))
    result = os.path.join(out_dir, "make_map_figures.json")
    subprocess.run([sys.executable, "-c", _CHILD, str(size_km), out_dir, result], env=env,
                   capture_output=True, text=True, check=True)
    with open(result, encoding="utf-8") as fh:
        wall, cpu, rss = (float(x) for x in json.load(fh))
    return wall, cpu, rss


def run_benchmarks(quick: bool = False) -> dict[str, float]:
    from testbench.world.imagery import MapSource
    from testbench.world.procedural.bands import generation_threads

    out: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as d:
        size = 2.0 if quick else 6.0
        wall, cpu, rss = _make_map(size, os.path.join(d, "w6"))
        out[f"world.make_map_{size:g}km_1m_s"] = wall
        out[f"world.make_map_{size:g}km_1m_cpu_s"] = cpu
        out[f"world.make_map_{size:g}km_1m_peak_rss_mb"] = rss
        threads = generation_threads()
        wall, _, rss = _make_map(size, os.path.join(d, "w6t"), threads)
        out[f"world.make_map_{size:g}km_1m_threaded_s"] = wall
        out[f"world.make_map_{size:g}km_1m_threads"] = float(threads)
        out[f"world.make_map_{size:g}km_1m_threaded_peak_rss_mb"] = rss
        path = os.path.join(d, "big.tif")
        _write_10km_map(path)
        m = MapSource(path, _ORIGIN)
        # footprint of a 1920x1080, 120 deg camera at 800 m: ~2.8 x 1.6 km; read at 1 m
        tracemalloc.start()
        t0 = time.perf_counter()
        r = m.read_local(-800, 800, -1400, 1400, 1.0)
        out["world.read_local_10km_window_ms"] = (time.perf_counter() - t0) * 1e3
        out["world.read_local_10km_peak_mb"] = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
        assert r.valid.all()
        t0 = time.perf_counter()
        r = m.read_local(-5000, 5000, -5000, 5000, 10.0)  # whole map, coarse: overviews
        out["world.read_local_10km_coarse_ms"] = (time.perf_counter() - t0) * 1e3
        m.close()
    return out
