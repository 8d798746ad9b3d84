"""The truth world of one run (maps, terrain, obstacles) and the per-tick views sensors get.

`RunWorld` opens what the scenario's `world:` names: `imagery` (what cameras render),
`elevation` (terrain relief, flat when absent), and, for the vehicles' onboard use,
`reference_map` / `reference_elevation` (what a vehicle carries: handed to navigation aids,
never the truth imagery unless the scenario says so, in which case the run is labelled
same-raster).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from testbench.config.schema import World
from testbench.core.interfaces import GeodeticOrigin
from testbench.core.messages import TruthState

log = logging.getLogger(__name__)


def default_cache_dir() -> Path:
    """Where procedural worlds are generated once and reused (TESTBENCH_CACHE or ~/.cache)."""
    env = os.environ.get("TESTBENCH_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "testbench" / "worlds"


class RunWorld:
    """Maps and terrain of a run, opened lazily (a run without cameras never reads imagery)."""

    def __init__(self, world: World, origin: GeodeticOrigin, cache_dir: Path | None = None):
        self.spec = world
        self.origin = origin
        self.cache_dir = cache_dir or default_cache_dir()
        self._imagery = None
        self._reference = None
        self._elevation = None
        self._reference_elevation = None
        self.obstacles = tuple(world.obstacles)

    @property
    def same_raster(self) -> bool:
        """True when vehicles carry the very raster the cameras render (an optimistic test)."""
        w = self.spec
        return w.imagery is not None and (w.reference_map is None or w.reference_map == w.imagery)

    def imagery(self):
        """MapSource of what cameras see (None if the scenario has no imagery)."""
        if self._imagery is None and self.spec.imagery:
            from testbench.world import open_world_imagery

            self._imagery = open_world_imagery(self.spec.imagery, self.origin, self.cache_dir)
        return self._imagery

    def reference_map(self):
        """MapSource a vehicle carries onboard (defaults to the imagery: same-raster)."""
        if self._reference is None:
            spec = self.spec.reference_map or self.spec.imagery
            if spec:
                from testbench.world import open_world_imagery

                self._reference = open_world_imagery(spec, self.origin, self.cache_dir)
        return self._reference

    def elevation(self):
        """Truth terrain model, or None for flat ground at the origin altitude."""
        if self._elevation is None and self.spec.elevation:
            from testbench.world import open_elevation

            self._elevation = open_elevation(self.spec.elevation, self.origin, self.cache_dir)
        return self._elevation

    def reference_elevation(self):
        """Terrain model a vehicle carries (defaults to the truth terrain)."""
        if self._reference_elevation is None:
            spec = self.spec.reference_elevation or self.spec.elevation
            if spec:
                from testbench.world import open_elevation

                self._reference_elevation = open_elevation(spec, self.origin, self.cache_dir)
        return self._reference_elevation

    def terrain_fn(self) -> Callable[[float, float], float] | None:
        """Scalar terrain height (m above the origin altitude) for the dynamics, or None."""
        elev = self.elevation()
        if elev is None:
            return None
        return lambda n, e: float(elev.height_m(np.array([n]), np.array([e]))[0])

    def terrain_height_m(self, north_m, east_m):
        """Vectorised terrain height above the origin altitude (m); zeros on flat ground."""
        elev = self.elevation()
        if elev is None:
            return np.zeros(np.broadcast(np.asarray(north_m), np.asarray(east_m)).shape)
        return elev.height_m(np.asarray(north_m, float), np.asarray(east_m, float))


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

    def __init__(self, world: RunWorld, t_s: float, self_id: str, truths: Mapping[str, TruthState], extras: dict[str, Any] | None = None):
        self.world = world
        self.t_s = t_s
        self.origin = world.origin
        self.self_id = self_id
        self.vehicles = truths
        self.obstacles = world.obstacles
        self.extras = extras or {}

    def terrain_height_m(self, north_m, east_m):
        return self.world.terrain_height_m(north_m, east_m)
