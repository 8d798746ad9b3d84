"""Terrain-aided navigation: a point-mass filter over a radar altimeter's terrain profile
(pmf). The engine-facing aid is testbench.navigation.tan_aid ("tan")."""

from testbench.navigation.tan.pmf import PmfPosterior, TerrainPmf

__all__ = ["PmfPosterior", "TerrainPmf"]
