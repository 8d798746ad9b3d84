"""The truth world of one run (maps, terrain, obstacles) and the per-tick views sensors get.

`RunWorld` opens what the scenario's `world:` names: `imagery` (what cameras render),
`elevation` (terrain relief, flat when absent), `magnetic_anomaly` (the crust's field over the
WMM, which magnetometers sense), and, for the vehicles' onboard use,
`reference_map` / `reference_elevation` (what a vehicle carries: handed to navigation aids,
never the truth imagery unless the scenario says so, in which case the run is labelled
same-raster).
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from testbench.config.schema import World
from testbench.core.errors import InputError
from testbench.core.interfaces import GeodeticOrigin
from testbench.core.messages import TruthState
from testbench.core.rng import RngStreams
from testbench.world.magnetic import NT_TO_T, CrustalAnomaly
from testbench.world.spec import is_procedural, parse_spec
from testbench.world.sun import noon_sun_deg, sun_ned

log = logging.getLogger(__name__)


def default_cache_dir() -> Path:
    """Where procedural worlds are generated once and reused (TESTBENCH_CACHE or ~/.cache)."""
    env = os.environ.get("TESTBENCH_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "testbench" / "worlds"


class RunWorld:
    """Maps and terrain of a run, opened lazily (a run without cameras never reads imagery)."""

    def __init__(self, world: World, origin: GeodeticOrigin, cache_dir: Path | None = None,
                 streams: RngStreams | None = None, epoch_year: float = 2025.5):
        """streams: the run's random streams, which draw what the world draws per run (its
        magnetic anomaly when the scenario gives that no seed of its own); epoch_year: the
        scenario's date (decimal year), which places a real map's sun."""
        self.spec = world
        self.origin = origin
        self.epoch_year = float(epoch_year)
        self.cache_dir = cache_dir or default_cache_dir()
        self._streams = streams
        self._magnetic_anomaly: CrustalAnomaly | None = None
        self._clouds = None  # world.clouds.CloudLayer, drawn on first use
        self._imagery = None
        self._reference = None
        self._elevation = None
        self._reference_elevation = None
        self.obstacles = tuple(o.obstacle(f"obstacle {i}") for i, o in enumerate(world.obstacles, start=1))
        self.looks: dict[str, Any] = {}  # vehicle id -> sim.appearance.Look (set by the runner)
        self._imagery_windows: dict[int, Any] = {}
        self._elevation_window = None

    @property
    def same_raster(self) -> bool:
        """True when vehicles carry the very raster the cameras render (an optimistic test)."""
        w = self.spec
        return w.imagery is not None and (w.reference_map is None or w.reference_map == w.imagery)

    @property
    def same_dem(self) -> bool:
        """True when vehicles carry the very terrain model the world is made of, without an
        error (world.reference_elevation_error): terrain-aided navigation then meets no DEM
        error but what its dem_sigma_m says, an optimistic test."""
        w = self.spec
        no_error = w.reference_elevation_error is None or w.reference_elevation_error.rms_m == 0
        return w.elevation is not None and no_error and (w.reference_elevation is None or w.reference_elevation == w.elevation)

    def imagery(self):
        """MapSource of what cameras see (None if the scenario has no imagery)."""
        if self._imagery is None and self.spec.imagery:
            from testbench.world import open_world_imagery

            self._imagery = open_world_imagery(self.spec.imagery, self.origin, self.cache_dir, what="world.imagery")
        return self._imagery

    def reference_map(self):
        """MapSource a vehicle carries onboard (defaults to the imagery: same-raster), off its
        georeference (world/map_error.DisplacedMap) when world.reference_map_error says so."""
        if self._reference is None:
            spec = self.spec.reference_map or self.spec.imagery
            if spec:
                from testbench.world import open_world_imagery

                what = "world.reference_map" if self.spec.reference_map else "world.imagery (the reference map too)"
                self._reference = open_world_imagery(spec, self.origin, self.cache_dir, what=what)
                err = self.spec.reference_map_error
                if err is not None and (err.sigma_m > 0 or err.shift_ne_m != (0.0, 0.0)):
                    from testbench.world.map_error import DisplacedMap

                    self._reference = DisplacedMap.over(self._reference, err.shift_ne_m, err.sigma_m, err.correlation_m,
                                                        self._world_rng("reference_map_error", err.seed))
        return self._reference

    def map_displacement_ne_m(self, north_m, east_m) -> tuple[np.ndarray, np.ndarray] | None:
        """The carried map's displacement (d_north_m, d_east_m) at local points (arrays broadcast
        together): TRUTH, for scoring only. None without a map error."""
        disp = getattr(self.reference_map(), "displacement", None)
        return None if disp is None else disp.at(north_m, east_m)

    def _world_rng(self, key: str, seed: int | None) -> np.random.Generator:
        """The generator of what world.<key> draws: its own seed's stream (the same in every
        run), else the run's (each run of a batch draws anew)."""
        stream = {"magnetic_anomaly": "magnetic_anomaly", "reference_elevation_error": "dem_error", "clouds": "clouds",
                  "reference_map_error": "map_error"}[key]
        if seed is not None:
            return RngStreams(seed).generator("world", stream)
        if self._streams is None:
            raise ValueError(f"world.{key} has no seed and this RunWorld was given no run streams")
        return self._streams.generator("world", stream)

    def magnetic_anomaly(self) -> CrustalAnomaly | None:
        """The crust's field over the WMM (None when the scenario gives none), drawn once."""
        spec = self.spec.magnetic_anomaly
        if spec is None or self._magnetic_anomaly is not None:
            return self._magnetic_anomaly
        rng = self._world_rng("magnetic_anomaly", spec.seed)
        self._magnetic_anomaly = CrustalAnomaly(spec.rms_nT, spec.source_depth_m, rng, n_waves=spec.waves)
        return self._magnetic_anomaly

    def cloud_layer(self):
        """The cloud layer (world.clouds.CloudLayer; None when the sky is clear), drawn once.
        It drifts with the world's steady wind unless the scenario gives its own drift."""
        spec = self.spec.clouds
        if spec is None or self._clouds is not None:
            return self._clouds
        from testbench.world.clouds import CloudLayer, CoverageWindow

        drift = spec.drift_ne_mps
        if drift is None:
            drift = self.spec.wind.velocity_ned_mps()[:2] if self.spec.wind is not None else (0.0, 0.0)
        windows = [CoverageWindow(w.start_s, w.end_s, w.coverage) for w in spec.windows]
        sun = None if spec.shadow_light >= 1.0 else sun_ned(*self.sun_deg())
        self._clouds = CloudLayer(spec.base_m, spec.coverage, windows, spec.cell_m, spec.opacity, drift,
                                  self._world_rng("clouds", spec.seed), sun_ned=sun,
                                  shadow_light=spec.shadow_light)
        return self._clouds

    def sun_deg(self) -> tuple[float, float]:
        """(azimuth_deg, elevation_deg) of the sun that lights the rendered world: the clouds'
        own where the scenario gives it, else a procedural imagery's, else the sun at local
        solar noon at the origin on the scenario's date (world/sun.py)."""
        clouds = self.spec.clouds
        if clouds is not None and clouds.sun_elevation_deg is not None:
            return float(clouds.sun_azimuth_deg), float(clouds.sun_elevation_deg)
        if is_procedural(self.spec.imagery):
            season = parse_spec(self.spec.imagery).appearance()
            return math.degrees(season.sun_azimuth_rad), math.degrees(season.sun_elevation_rad)
        try:
            return noon_sun_deg(math.degrees(self.origin.lat_rad), self.epoch_year)
        except ValueError as exc:
            raise InputError(f"world.clouds: {exc}") from None

    def elevation(self):
        """Truth terrain model, or None for flat ground at the origin altitude."""
        if self._elevation is None and self.spec.elevation:
            from testbench.world import open_elevation

            self._elevation = open_elevation(self.spec.elevation, self.origin, self.cache_dir, what="world.elevation")
        return self._elevation

    def reference_elevation(self):
        """Terrain model a vehicle carries (defaults to the truth terrain), with its error
        (world.reference_elevation_error) when the scenario gives one."""
        if self._reference_elevation is None:
            spec = self.spec.reference_elevation or self.spec.elevation
            err = self.spec.reference_elevation_error
            if spec:
                from testbench.world import open_elevation

                what = ("world.reference_elevation" if self.spec.reference_elevation
                        else "world.elevation (the reference elevation too)")
                self._reference_elevation = open_elevation(spec, self.origin, self.cache_dir, what=what)
            if err is not None and err.rms_m > 0:
                from testbench.world.dem_error import ErroredElevation
                from testbench.world.elevation import FlatElevation

                rng = self._world_rng("reference_elevation_error", err.seed)
                base = self._reference_elevation if self._reference_elevation is not None else FlatElevation(0.0)
                self._reference_elevation = ErroredElevation(base, err.rms_m, err.correlation_m, rng)
        return self._reference_elevation

    # Cameras ask for imagery under their footprint at every frame. Reading a GeoTIFF window
    # costs ~100 ms, so the world keeps one large window per power-of-two ground sample and
    # serves every camera from it while their footprints stay inside it.
    _WHOLE_MAP_MAX_PX = 5000
    _MARGIN = 0.75

    def imagery_for(self, bounds_ne_m, gsd_m: float):
        """LocalRaster of the truth imagery covering bounds (n0, n1, e0, e1) at about gsd_m
        (the next finer power-of-two multiple of the map's own sample); None without imagery."""
        src = self.imagery()
        if src is None:
            return None
        native = float(getattr(src, "native_gsd_m", 1.0))
        level = max(0, int(np.floor(np.log2(max(gsd_m, native) / native) + 1e-9)))
        gsd = native * 2.0**level
        fp = src.footprint
        # Off the map there is nothing to read: a banked or oblique camera's footprint reaches
        # kilometres past the map (to its far clip), and reading all of it as no-data took
        # 16856 x 18571 px windows (GBs) on a 10 km map. The renderer treats what lies
        # outside the window as no-data too, so a window clipped to the map (plus a few
        # pixels of no-data for the bilinear taps) renders the same view.
        pad = 4.0 * gsd
        n0, n1, e0, e1 = _clamp_to_footprint(bounds_ne_m, fp, pad, gsd)
        cached = self._imagery_windows.get(level)
        if cached is not None and _contains(cached, n0, n1, e0, e1):
            return cached
        # Forget the window this read replaces first: two windows of up to ~200 MB each need
        # not coexist while the new one is reprojected.
        cached = None
        self._imagery_windows.pop(level, None)
        if max(fp.north_max_m - fp.north_min_m, fp.east_max_m - fp.east_min_m) / gsd <= self._WHOLE_MAP_MAX_PX:
            n0, n1, e0, e1 = fp.north_min_m, fp.north_max_m, fp.east_min_m, fp.east_max_m
        else:
            # The margin lets the next frames be served from this window, but the window stays
            # within _WHOLE_MAP_MAX_PX a side unless the footprint itself is larger: with the
            # full margin a banked camera's km-wide footprint took a whole 10 km map at 1 m
            # (100 Mpx, ~0.9 GB with its RGBA pyramid) next to the windows of coarser levels.
            ext = max(n1 - n0, e1 - e0)
            m = max(0.0, min(self._MARGIN * ext, 0.5 * (self._WHOLE_MAP_MAX_PX * gsd - ext)))
            n0, n1, e0, e1 = _clamp_to_footprint((n0 - m, n1 + m, e0 - m, e1 + m), fp, pad, gsd)
        raster = src.read_local(n0, n1, e0, e1, gsd)
        self._imagery_windows[level] = raster
        return raster

    def elevation_for(self, bounds_ne_m):
        """LocalRaster of terrain heights over bounds, or None on flat ground.

        Bounds are clamped to the DEM (plus a cell, at least 4 cells across): a horizontal
        camera's footprint reaches its far clip, kilometres past a small DEM, and the ray caster
        extends the DEM's edges anyway.
        """
        elev = self.elevation()
        if elev is None or not hasattr(elev, "read_local") or type(elev).__name__ == "FlatElevation":
            return None
        gsd = float(getattr(elev, "native_gsd_m", 10.0) or 10.0)
        n0, n1, e0, e1 = _clamp_to_footprint(bounds_ne_m, getattr(elev, "footprint", None), gsd, 4.0 * gsd)
        cached = self._elevation_window
        if cached is not None and _contains(cached, n0, n1, e0, e1):
            return cached
        m = self._MARGIN * max(n1 - n0, e1 - e0)
        n0, n1, e0, e1 = _clamp_to_footprint((n0 - m, n1 + m, e0 - m, e1 + m), getattr(elev, "footprint", None), gsd, 4.0 * gsd)
        self._elevation_window = elev.read_local(n0, n1, e0, e1, gsd)
        return self._elevation_window

    def terrain_fn(self) -> Callable[[float, float], float] | None:
        """Scalar terrain height (m above the origin altitude) for the dynamics, or None."""
        elev = self.elevation()
        if elev is None:
            return None
        return elev.height_at

    def terrain_height_m(self, north_m, east_m):
        """Vectorised terrain height above the origin altitude (m); zeros on flat ground."""
        elev = self.elevation()
        if elev is None:
            return np.zeros(np.broadcast(np.asarray(north_m), np.asarray(east_m)).shape)
        return elev.height_m(np.asarray(north_m, float), np.asarray(east_m, float))


def _clamp_to_footprint(bounds_ne_m, fp, pad_m: float, min_size_m: float):
    """(n0, n1, e0, e1) with each bound clamped into a raster footprint grown by pad_m, at
    least min_size_m across (a request wholly off the map becomes a thin strip at its edge:
    no data, as the request, but no large read); unchanged without a footprint."""
    n0, n1, e0, e1 = bounds_ne_m
    if fp is None:
        return n0, n1, e0, e1
    lo_n, hi_n = fp.north_min_m - pad_m, fp.north_max_m + pad_m
    lo_e, hi_e = fp.east_min_m - pad_m, fp.east_max_m + pad_m
    n0, n1 = min(max(n0, lo_n), hi_n), min(max(n1, lo_n), hi_n)
    e0, e1 = min(max(e0, lo_e), hi_e), min(max(e1, lo_e), hi_e)
    if n1 - n0 < min_size_m:
        n0, n1 = (n0, n0 + min_size_m) if n0 < hi_n else (n1 - min_size_m, n1)
    if e1 - e0 < min_size_m:
        e0, e1 = (e0, e0 + min_size_m) if e0 < hi_e else (e1 - min_size_m, e1)
    return n0, n1, e0, e1


def _contains(r, n0: float, n1: float, e0: float, e1: float) -> bool:
    h, w = r.shape
    return r.north0_m >= n1 and r.north0_m - h * r.gsd_m <= n0 and r.east0_m <= e0 and r.east0_m + w * r.gsd_m >= e1


class _LazyTruths(Mapping):
    """vehicle id -> TruthState at this tick, built only for the vehicles a sensor asks about."""

    def __init__(self, getters: dict[str, Callable[[], TruthState]]):
        self._getters = getters

    def __getitem__(self, key: str) -> TruthState:
        return self._getters[key]()

    def __iter__(self) -> Iterator[str]:
        return iter(self._getters)

    def __len__(self) -> int:
        return len(self._getters)


class TickWorldView:
    """What one vehicle's sensors may see at one tick (satisfies core.interfaces.WorldView)."""

    def __init__(self, world: RunWorld, t_s: float, self_id: str, truths: Mapping[str, TruthState],
                 requests: Callable[[], dict[str, list] | None] | dict[str, list] | None = None):
        """requests: the aids' render wishes per camera name, or a callable giving them, asked
        only when a camera renders (most ticks sample only the IMU)."""
        self.world = world
        self.t_s = t_s
        self.origin = world.origin
        self.self_id = self_id
        self.vehicles = truths
        self.obstacles = world.obstacles
        self._requests = requests
        self._appearances: tuple[float, tuple] | None = None  # (t_s, the other vehicles' looks)

    def terrain_height_m(self, north_m, east_m):
        return self.world.terrain_height_m(north_m, east_m)

    def magnetic_anomaly_ned_T(self, truth: TruthState) -> np.ndarray | None:
        """The crust's field (3,) NED tesla at the vehicle, or None where the world has none."""
        anomaly = self.world.magnetic_anomaly()
        if anomaly is None:
            return None
        n_m, e_m, d_m = truth.pos_ned_m
        return anomaly.field_ned_nT(n_m, e_m, -d_m) * NT_TO_T

    def imagery_for(self, bounds_ne_m, gsd_m: float):
        return self.world.imagery_for(bounds_ne_m, gsd_m)

    def clouds(self):
        """The cloud sheet now (world.clouds.CloudView), or None under a clear sky."""
        layer = self.world.cloud_layer()
        return None if layer is None else layer.at(self.t_s)

    def elevation_for(self, bounds_ne_m):
        return self.world.elevation_for(bounds_ne_m)

    def appearances(self, t_s: float):
        """The other vehicles as cameras see them now (true pose, LED states of the instant);
        made once per time for all of this vehicle's cameras."""
        from testbench.core.rotations import quat_to_dcm

        if self._appearances is not None and self._appearances[0] == t_s:
            return self._appearances[1]
        out = []
        for vid, look in self.world.looks.items():
            if vid == self.self_id:
                continue
            tr = self.vehicles[vid]
            out.append(look.appearance(vid, tr.pos_ned_m, quat_to_dcm(tr.q_nb_wxyz), t_s))
        self._appearances = (t_s, tuple(out))
        return self._appearances[1]

    def render_requests(self, camera_name: str):
        """Regions an aid asked this camera to render (None: the whole frame)."""
        if callable(self._requests):
            self._requests = self._requests()
        if self._requests is None:
            return None
        return self._requests.get(camera_name)
