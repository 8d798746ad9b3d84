"""WGS-84 geodesy: geodetic <-> ECEF <-> local NED, radii of curvature, gravity, Earth rate.

Conventions
- Geodetic coordinates are (lat_rad, lon_rad, h_m): latitude, longitude, height above the
  WGS-84 ellipsoid. The testbench treats mean sea level as the ellipsoid (no geoid model).
- ECEF is the WGS-84 Earth-centred Earth-fixed frame, metres.
- Local NED is North-East-Down at a fixed origin (the scenario origin), metres; the tangent
  plane is fixed at the origin (it does not follow the vehicle).

All functions are vectorised: scalars or arrays that broadcast together; vector arguments
have their 3 components on the last axis, shape (..., 3).
"""

from __future__ import annotations

import math

import numpy as np

A_M = 6378137.0
"""WGS-84 semi-major axis a (m)."""
F = 1.0 / 298.257223563
"""WGS-84 flattening f."""
E2 = 2.0 * F - F * F
"""First eccentricity squared e^2 = 2f - f^2."""
B_M = A_M * (1.0 - F)
"""Semi-minor axis b (m)."""
OMEGA_IE_RPS = 7.292115e-5
"""Earth rotation rate w_ie (rad/s), WGS-84."""
GM_M3PS2 = 3.986004418e14
"""Earth gravitational constant (m^3/s^2), WGS-84."""

# Somigliana normal-gravity constants (WGS-84).
_G_EQUATOR_MPS2 = 9.7803253359
_SOMIGLIANA_K = 0.00193185265241
_M_RATIO = OMEGA_IE_RPS**2 * A_M**2 * B_M / GM_M3PS2


def radii_of_curvature(lat_rad):
    """Meridian R_M and prime-vertical (transverse) R_N radii of curvature (m).

    R_N = a / sqrt(1 - e^2 sin^2 L);  R_M = R_N (1 - e^2) / (1 - e^2 sin^2 L).
    Returns (R_M, R_N) with the shape of lat_rad.
    """
    s2 = np.sin(lat_rad) ** 2
    w2 = 1.0 - E2 * s2
    r_n = A_M / np.sqrt(w2)
    r_m = r_n * (1.0 - E2) / w2
    return r_m, r_n


def geodetic_to_ecef(lat_rad, lon_rad, h_m):
    """Geodetic (rad, rad, m) -> ECEF position (m), shape (..., 3)."""
    lat_rad, lon_rad, h_m = np.broadcast_arrays(
        np.asarray(lat_rad, float), np.asarray(lon_rad, float), np.asarray(h_m, float)
    )
    _, r_n = radii_of_curvature(lat_rad)
    cl = np.cos(lat_rad)
    x = (r_n + h_m) * cl * np.cos(lon_rad)
    y = (r_n + h_m) * cl * np.sin(lon_rad)
    z = (r_n * (1.0 - E2) + h_m) * np.sin(lat_rad)
    return np.stack([x, y, z], axis=-1)


def ecef_to_geodetic(r_ecef_m):
    """ECEF position (m), shape (..., 3) -> (lat_rad, lon_rad, h_m).

    Closed-form solution of Zhu (1994) / Heikkinen, exact to well below a millimetre for
    any point outside the Earth's core region.
    """
    r = np.asarray(r_ecef_m, float)
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    ep2 = (A_M**2 - B_M**2) / B_M**2
    p = np.hypot(x, y)
    big_f = 54.0 * B_M**2 * z**2
    big_g = p**2 + (1.0 - E2) * z**2 - E2 * (A_M**2 - B_M**2)
    c = E2**2 * big_f * p**2 / big_g**3
    s = np.cbrt(1.0 + c + np.sqrt(c**2 + 2.0 * c))
    k = s + 1.0 + 1.0 / s
    big_p = big_f / (3.0 * k**2 * big_g**2)
    q = np.sqrt(1.0 + 2.0 * E2**2 * big_p)
    r0 = -big_p * E2 * p / (1.0 + q) + np.sqrt(
        np.maximum(
            0.5 * A_M**2 * (1.0 + 1.0 / q)
            - big_p * (1.0 - E2) * z**2 / (q * (1.0 + q))
            - 0.5 * big_p * p**2,
            0.0,
        )
    )
    u = np.sqrt((p - E2 * r0) ** 2 + z**2)
    v = np.sqrt((p - E2 * r0) ** 2 + (1.0 - E2) * z**2)
    z0 = B_M**2 * z / (A_M * v)
    h = u * (1.0 - B_M**2 / (A_M * v))
    lat = np.arctan2(z + ep2 * z0, p)
    lon = np.arctan2(y, x)
    return lat, lon, h


def C_en(lat_rad, lon_rad):
    """Rotation matrix C_en that maps NED vectors to ECEF vectors (nav -> ECEF).

    Shape (..., 3, 3); its columns are the north, east and down unit vectors in ECEF.
    """
    sl, cl = np.sin(lat_rad), np.cos(lat_rad)
    so, co = np.sin(lon_rad), np.cos(lon_rad)
    sl, cl, so, co = np.broadcast_arrays(sl, cl, so, co)
    out = np.empty(sl.shape + (3, 3))
    out[..., 0, 0] = -sl * co
    out[..., 1, 0] = -sl * so
    out[..., 2, 0] = cl
    out[..., 0, 1] = -so
    out[..., 1, 1] = co
    out[..., 2, 1] = 0.0
    out[..., 0, 2] = -cl * co
    out[..., 1, 2] = -cl * so
    out[..., 2, 2] = -sl
    return out


def ecef_to_ned(r_ecef_m, origin_lat_rad, origin_lon_rad, origin_h_m):
    """ECEF positions (..., 3) -> local NED (..., 3) at the given geodetic origin (m)."""
    r0 = geodetic_to_ecef(origin_lat_rad, origin_lon_rad, origin_h_m)
    c_ne = np.swapaxes(C_en(origin_lat_rad, origin_lon_rad), -1, -2)  # ECEF -> NED
    d = np.asarray(r_ecef_m, float) - r0
    return np.einsum("...ij,...j->...i", c_ne, d)


def ned_to_ecef(pos_ned_m, origin_lat_rad, origin_lon_rad, origin_h_m):
    """Local NED (..., 3) at the geodetic origin -> ECEF positions (..., 3) (m)."""
    r0 = geodetic_to_ecef(origin_lat_rad, origin_lon_rad, origin_h_m)
    c_en = C_en(origin_lat_rad, origin_lon_rad)  # NED -> ECEF
    return r0 + np.einsum("...ij,...j->...i", c_en, np.asarray(pos_ned_m, float))


def geodetic_to_ned(lat_rad, lon_rad, h_m, origin_lat_rad, origin_lon_rad, origin_h_m):
    """Geodetic -> local NED at the origin (m), shape (..., 3)."""
    return ecef_to_ned(
        geodetic_to_ecef(lat_rad, lon_rad, h_m), origin_lat_rad, origin_lon_rad, origin_h_m
    )


def ned_to_geodetic(pos_ned_m, origin_lat_rad, origin_lon_rad, origin_h_m):
    """Local NED (..., 3) at the origin -> (lat_rad, lon_rad, h_m)."""
    return ecef_to_geodetic(ned_to_ecef(pos_ned_m, origin_lat_rad, origin_lon_rad, origin_h_m))


def normal_gravity_mps2(lat_rad, h_m):
    """Magnitude of WGS-84 normal gravity (m/s^2) at latitude and height above the ellipsoid.

    Somigliana's formula on the ellipsoid with the second-order free-air correction
    (Groves, Principles of GNSS, Inertial and Multisensor Navigation, 2nd ed., eq. 2.134).
    Gravity (gravitation plus centrifugal) points down along the ellipsoid normal, so in NED
    the gravity vector is (0, 0, g) to this accuracy.
    """
    s2 = np.sin(lat_rad) ** 2
    g0 = _G_EQUATOR_MPS2 * (1.0 + _SOMIGLIANA_K * s2) / np.sqrt(1.0 - E2 * s2)
    h = np.asarray(h_m, float)
    return g0 * (
        1.0
        - 2.0 / A_M * (1.0 + F + _M_RATIO - 2.0 * F * s2) * h
        + 3.0 / A_M**2 * h**2
    )


def gravity_ned_mps2(lat_rad, h_m):
    """Gravity vector in NED (m/s^2), shape (..., 3): (0, 0, g(lat, h))."""
    g = np.asarray(normal_gravity_mps2(lat_rad, h_m))
    out = np.zeros(g.shape + (3,))
    out[..., 2] = g
    return out


def earth_rate_ned_rps(lat_rad):
    """Earth rotation w_ie resolved in NED (rad/s): (w cos L, 0, -w sin L), shape (..., 3)."""
    lat = np.asarray(lat_rad, float)
    out = np.zeros(lat.shape + (3,))
    out[..., 0] = OMEGA_IE_RPS * np.cos(lat)
    out[..., 2] = -OMEGA_IE_RPS * np.sin(lat)
    return out


def transport_rate_ned_rps(lat_rad, h_m, vel_ned_mps):
    """Transport rate w_en in NED (rad/s): rotation of NED relative to ECEF as the vehicle moves.

    w_en = (v_E / (R_N + h), -v_N / (R_M + h), -v_E tan L / (R_N + h)).
    """
    v = np.asarray(vel_ned_mps, float)
    r_m, r_n = radii_of_curvature(lat_rad)
    h = np.asarray(h_m, float)
    out = np.empty(np.broadcast_shapes(v.shape, np.shape(h) + (3,)))
    out[..., 0] = v[..., 1] / (r_n + h)
    out[..., 1] = -v[..., 0] / (r_m + h)
    out[..., 2] = -v[..., 1] * np.tan(lat_rad) / (r_n + h)
    return out


def nav_frame_rate_ned_scalar(lat_rad: float, h_m: float, vn_mps: float, ve_mps: float) -> tuple[float, float, float]:
    """w_in = w_ie + w_en (rad/s, NED) at one point, as Python floats: the scalar twin of
    earth_rate_ned_rps + transport_rate_ned_rps for per-sample use (same formulas)."""
    sl, cl = math.sin(lat_rad), math.cos(lat_rad)
    w2 = 1.0 - E2 * sl * sl
    r_n = A_M / math.sqrt(w2)
    r_m = r_n * (1.0 - E2) / w2
    return (OMEGA_IE_RPS * cl + ve_mps / (r_n + h_m),
            -vn_mps / (r_m + h_m),
            -OMEGA_IE_RPS * sl - ve_mps * sl / cl / (r_n + h_m))


class LocalTangentFrame:
    """A fixed local NED frame at a geodetic origin, with scalar fast paths.

    The vectorised functions above are right for arrays; this class serves the per-tick,
    one-point conversions of the engine without numpy overhead (same formulas).
    """

    def __init__(self, lat_rad: float, lon_rad: float, h_m: float):
        self.lat_rad, self.lon_rad, self.h_m = float(lat_rad), float(lon_rad), float(h_m)
        self._r0 = tuple(float(x) for x in geodetic_to_ecef(lat_rad, lon_rad, h_m))
        c_ne = np.asarray(C_en(lat_rad, lon_rad)).T  # ECEF -> NED
        self._c_ne = tuple(tuple(float(x) for x in row) for row in c_ne)

    def geodetic_to_ned(self, lat_rad: float, lon_rad: float, h_m: float) -> tuple[float, float, float]:
        """One geodetic point -> (north_m, east_m, down_m) in this frame."""
        sl, cl = math.sin(lat_rad), math.cos(lat_rad)
        r_n = A_M / math.sqrt(1.0 - E2 * sl * sl)
        dx = (r_n + h_m) * cl * math.cos(lon_rad) - self._r0[0]
        dy = (r_n + h_m) * cl * math.sin(lon_rad) - self._r0[1]
        dz = (r_n * (1.0 - E2) + h_m) * sl - self._r0[2]
        c = self._c_ne
        return (
            c[0][0] * dx + c[0][1] * dy + c[0][2] * dz,
            c[1][0] * dx + c[1][1] * dy + c[1][2] * dz,
            c[2][0] * dx + c[2][1] * dy + c[2][2] * dz,
        )
