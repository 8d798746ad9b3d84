"""Maps and elevation on the scenario's local north-east grid; procedural worlds.

Public API: MapSource, ElevationModel, FlatElevation, LocalRaster, sample_bilinear,
open_world_imagery, open_elevation, make_world (testbench.world.procedural).
"""

from testbench.world.elevation import ElevationModel, FlatElevation
from testbench.world.geotiff import Footprint
from testbench.world.imagery import MapSource
from testbench.world.raster import LocalRaster, sample_bilinear
from testbench.world.spec import open_elevation, open_world_imagery, parse_spec

__all__ = ["MapSource", "Footprint", "ElevationModel", "FlatElevation", "LocalRaster",
           "sample_bilinear", "open_world_imagery", "open_elevation", "parse_spec"]
