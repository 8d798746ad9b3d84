"""Geodesy: round trips, cross-checks against pyproj and pymap3d, gravity and radii."""

import numpy as np
import pymap3d
import pytest
from pyproj import Transformer

from testbench.core import geodesy as g

RNG = np.random.default_rng(7)
LAT = np.radians(RNG.uniform(-85, 85, 200))
LON = np.radians(RNG.uniform(-180, 180, 200))
H = RNG.uniform(-400, 12000, 200)


def test_geodetic_ecef_matches_pyproj():
    tr = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    x, y, z = tr.transform(np.degrees(LON), np.degrees(LAT), H)
    ours = g.geodetic_to_ecef(LAT, LON, H)
    np.testing.assert_allclose(ours, np.column_stack([x, y, z]), atol=1e-6)


def test_ecef_geodetic_round_trip():
    lat, lon, h = g.ecef_to_geodetic(g.geodetic_to_ecef(LAT, LON, H))
    np.testing.assert_allclose(lat, LAT, atol=1e-11)
    np.testing.assert_allclose(lon, LON, atol=1e-11)
    np.testing.assert_allclose(h, H, atol=1e-5)


def test_ned_matches_pymap3d_and_round_trips():
    lat0, lon0, h0 = np.radians(47.1), np.radians(-99.3), 512.0
    lat = lat0 + RNG.normal(0, 0.02, 50)
    lon = lon0 + RNG.normal(0, 0.02, 50)
    h = h0 + RNG.normal(0, 300, 50)
    ned = g.geodetic_to_ned(lat, lon, h, lat0, lon0, h0)
    n, e, d = pymap3d.geodetic2ned(np.degrees(lat), np.degrees(lon), h, np.degrees(lat0), np.degrees(lon0), h0)
    np.testing.assert_allclose(ned, np.column_stack([n, e, d]), atol=1e-6)
    lat2, lon2, h2 = g.ned_to_geodetic(ned, lat0, lon0, h0)
    np.testing.assert_allclose([lat2, lon2], [lat, lon], atol=1e-12)
    np.testing.assert_allclose(h2, h, atol=1e-6)


def test_scalar_local_frame_matches_vectorised():
    f = g.LocalTangentFrame(np.radians(35.7), np.radians(-120.7), 300.0)
    lat, lon, h = np.radians(35.71), np.radians(-120.69), 1200.0
    np.testing.assert_allclose(f.geodetic_to_ned(lat, lon, h), g.geodetic_to_ned(lat, lon, h, f.lat_rad, f.lon_rad, f.h_m), atol=1e-7)


def test_radii_of_curvature_limits():
    rm, rn = g.radii_of_curvature(np.array([0.0, np.pi / 2]))
    assert rn[0] == pytest.approx(g.A_M)
    assert rm[0] == pytest.approx(g.A_M * (1 - g.E2))
    assert rn[1] == pytest.approx(rm[1])  # at the pole both equal a^2/b
    assert rn[1] == pytest.approx(g.A_M**2 / g.B_M)


def test_normal_gravity_known_values():
    # WGS-84 normal gravity on the ellipsoid: 9.7803253359 at the equator, 9.8321849378 at the poles.
    assert g.normal_gravity_mps2(0.0, 0.0) == pytest.approx(9.7803253359, abs=1e-9)
    assert g.normal_gravity_mps2(np.pi / 2, 0.0) == pytest.approx(9.8321849378, abs=1e-8)
    # free-air gradient about -3.086e-6 s^-2
    grad = (g.normal_gravity_mps2(0.8, 1000.0) - g.normal_gravity_mps2(0.8, 0.0)) / 1000.0
    assert grad == pytest.approx(-3.086e-6, rel=0.01)


def test_earth_and_transport_rates():
    w = g.earth_rate_ned_rps(np.radians(45.0))
    assert np.linalg.norm(w) == pytest.approx(g.OMEGA_IE_RPS)
    assert w[1] == 0.0 and w[2] < 0.0
    # flying east at the equator turns the NED frame about north at v / (R_N + h)
    wen = g.transport_rate_ned_rps(0.0, 0.0, np.array([0.0, 100.0, 0.0]))
    assert wen[0] == pytest.approx(100.0 / g.A_M)
