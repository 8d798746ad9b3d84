"""Unit conversions used at the edges (YAML *_deg keys, the JSBSim adapter).

Inside the testbench everything is SI and radians.
"""

from __future__ import annotations

import math

FT_TO_M = 0.3048
M_TO_FT = 1.0 / FT_TO_M
SLUG_TO_KG = 14.593902937206364
SLUGFT2_TO_KGM2 = SLUG_TO_KG * FT_TO_M**2
LBF_TO_N = 4.4482216152605
KT_TO_MPS = 1852.0 / 3600.0
MPS_TO_KT = 1.0 / KT_TO_MPS
PSF_TO_PA = LBF_TO_N / FT_TO_M**2
RANKINE_TO_KELVIN = 5.0 / 9.0
DEG_TO_RAD = math.pi / 180.0
RAD_TO_DEG = 180.0 / math.pi
STANDARD_GRAVITY_MPS2 = 9.80665
"""Standard gravity g0 (m/s^2), used to convert load factors and datasheet 'g' units."""
