"""Procedural worlds: farmland, grassland, desert, canyon, urban (see world.make_world)."""

from testbench.world.procedural.appearance import SEASONS, Season, season_from
from testbench.world.procedural.world import TERRAINS, make_world

__all__ = ["make_world", "TERRAINS", "SEASONS", "Season", "season_from"]
