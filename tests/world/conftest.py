import math

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from testbench.core.interfaces import GeodeticOrigin


@pytest.fixture
def origin():
    return GeodeticOrigin(math.radians(47.05), math.radians(-99.15), 500.0)

