"""The world's magnetic field: the Earth's main field (WMM) plus an optional crustal anomaly.

A magnetometer samples this field; the navigator carries only the WMM
(navigation/ins/magnetic.py). Without an anomaly the two agree exactly, which no real vehicle
enjoys: the crust's magnetisation adds fields of tens to thousands of nT that the WMM (degree
12, wavelengths above ~3000 km) does not hold, and they are most of the WMM's quoted
declination uncertainty (about 0.3-0.5 deg, 1 sigma). A horizontal anomaly dB across the
horizontal main field H turns the magnetic heading by about dB / H (100 nT against H = 15 000
nT: 6.7 mrad, 0.38 deg).

The anomaly (`CrustalAnomaly`) is a seeded random potential field: a sum of N plane waves,

    V(n, e, z) = sum_j c_j cos(k_j . (n, e) + phi_j) exp(-|k_j| z),      B = -grad V,

so that it is what a real anomaly is above its sources: curl-free and divergence-free, and
smoother the higher one flies (each wave decays as exp(-|k| z), upward continuation). z is the
height above the origin's altitude. The wavenumbers |k| are drawn from the radial spectrum of
random sources at a depth d below that datum, P(|k|) ~ exp(-2 |k| d) (Spector & Grant, 1970),
i.e. |k| ~ Gamma(2, 1 / (2 d)); directions and phases uniform; all waves of one field
amplitude a = rms sqrt(2 / N). Then at the datum the vertical anomaly and the magnitude of
the horizontal one both have RMS `rms_nT`, and at a height z both have RMS
rms_nT / (1 + z / d) (the mean of exp(-2 |k| z) over that spectrum). The field's correlation
length at the datum is about 2 d.
"""

from __future__ import annotations

import math

import numpy as np
from pygeomag import GeoMag

from testbench.core.errors import SimulationAborted

NT_TO_T = 1e-9


def wmm_field_ned_nT(lat_deg: float, lon_deg: float, alt_m: float, year: float) -> np.ndarray:
    """WMM main field (X north, Y east, Z down) in nT at a geodetic point and decimal year."""
    gm = _geomag_for(year)
    lon = (lon_deg + 180.0) % 360.0 - 180.0
    r = gm.calculate(glat=lat_deg, glon=lon, alt=alt_m / 1000.0, time=year, allow_date_outside_lifespan=True)
    return np.array([r.x, r.y, r.z])


_GEOMAG: dict[int, GeoMag] = {}


def _geomag_for(year: float) -> GeoMag:
    base = 2025 if year >= 2025 else 2020 if year >= 2020 else 2015
    if base not in _GEOMAG:
        _GEOMAG[base] = GeoMag(base_year=base)
    return _GEOMAG[base]


class CrustalAnomaly:
    """A seeded crustal anomaly field on the scenario's local frame (see the module's text).

    rms_nT: RMS of the vertical anomaly (and of the horizontal one's magnitude) at the
    origin's altitude; source_depth_m: depth d of the random sources below that datum, which
    sets the wavelengths (correlation length about 2 d); rng: the generator that draws the
    waves (the run's stream, or the scenario's fixed seed); n_waves: how many plane waves.
    """

    def __init__(self, rms_nT: float, source_depth_m: float, rng: np.random.Generator, n_waves: int = 256):
        if not (rms_nT >= 0.0 and math.isfinite(rms_nT)):
            raise ValueError(f"rms_nT must be finite and >= 0, got {rms_nT!r}")
        if not (source_depth_m > 0.0 and math.isfinite(source_depth_m)):
            raise ValueError(f"source_depth_m must be finite and > 0, got {source_depth_m!r}")
        self.rms_nT = float(rms_nT)
        self.source_depth_m = float(source_depth_m)
        k_rad_per_m = rng.gamma(2.0, 1.0 / (2.0 * self.source_depth_m), n_waves)
        azimuth_rad = rng.uniform(0.0, 2.0 * math.pi, n_waves)
        self._phase_rad = rng.uniform(0.0, 2.0 * math.pi, n_waves)
        self._k_rad_per_m = k_rad_per_m
        self._k_ne_rad_per_m = np.stack([k_rad_per_m * np.cos(azimuth_rad), k_rad_per_m * np.sin(azimuth_rad)], axis=1)
        self._unit_ne = self._k_ne_rad_per_m / k_rad_per_m[:, None]
        self._amplitude_nT = self.rms_nT * math.sqrt(2.0 / n_waves)

    def rms_at_height_nT(self, height_m: float) -> float:
        """The field's RMS (vertical, and horizontal magnitude) at height_m above the datum."""
        return self.rms_nT / (1.0 + height_m / self.source_depth_m)

    def field_ned_nT(self, north_m, east_m, height_m) -> np.ndarray:
        """Anomaly (north, east, down) in nT at local positions: inputs broadcast to shape S,
        output S + (3,); height_m above the origin's altitude (up positive).

        Raises SimulationAborted below half the source depth, where the sources would lie
        near or above the point and the model no longer holds."""
        n, e, z = np.broadcast_arrays(np.asarray(north_m, float), np.asarray(east_m, float), np.asarray(height_m, float))
        if np.any(z <= -0.5 * self.source_depth_m):
            raise SimulationAborted(
                f"magnetic anomaly: a point {float(-np.min(z)):.0f} m below the origin's altitude lies within "
                f"half the anomaly's source depth ({self.source_depth_m:.0f} m); give world.magnetic_anomaly a "
                f"source_depth_m of more than twice the lowest flight below the origin"
            )
        theta = (n[..., None] * self._k_ne_rad_per_m[:, 0] + e[..., None] * self._k_ne_rad_per_m[:, 1]
                 + self._phase_rad)
        decay = self._amplitude_nT * np.exp(-self._k_rad_per_m * z[..., None])
        s = decay * np.sin(theta)
        return np.stack([s @ self._unit_ne[:, 0], s @ self._unit_ne[:, 1], -(decay * np.cos(theta)).sum(-1)], axis=-1)


__all__ = ["CrustalAnomaly", "NT_TO_T", "wmm_field_ned_nT"]
