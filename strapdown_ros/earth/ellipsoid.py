"""
The PZ-90.11 and WGS-84 ellipsoids, the constants of paper 003, and geodetic conversions.

The bottom of the Earth room: the gravity models and the navigation use these.
Conventions: ECEF = the PZ-90 Greenwich rectangular frame (REP-105 frame ``earth``), Earth
rotation +Z, SI units (m, m/s², rad).
"""
from collections import namedtuple

import numpy as np

A = 6378136.0                  # PZ-90 semi-major axis, m (003 and PZ-90.11)
F = 1.0 / 298.25784            # PZ-90.11 flattening
E2 = F * (2.0 - F)             # 0.0066943662 (PZ-90.11); geodesy helpers use this one
E2_003 = 0.0066934             # 003 prints "0066934": used only inside the printed formula
GE = 9.780318                  # 003 equatorial gravity, m/s²
OMEGA = 7.292115e-5            # Earth rotation rate, rad/s, about +Z
ETA_003 = 0.00346775           # 003's printed η = aΩ²/g_e (recomputed 0.0034677503)
GM = 398600.4418e9             # PZ-90.11 geocentric gravitational constant, m³/s²
J2 = 1082.62575e-6             # PZ-90.11 second zonal harmonic of the normal field

Ellipsoid = namedtuple('Ellipsoid', 'a f gm omega')
PZ90_11 = Ellipsoid(A, F, GM, OMEGA)
WGS84 = Ellipsoid(6378137.0, 1.0 / 298.257223563, 3986004.418e8, 7.292115e-5)


def geodetic_to_ecef(lat, lon, h, a=A, f=F):
    """
    Convert geodetic coordinates to ECEF positions.

    Parameters
    ----------
    lat, lon : float or array_like
        Geodetic latitude and longitude, rad.
    h : float or array_like
        Height above the ellipsoid, m.
    a : float
        Equatorial radius, m.
    f : float
        Flattening.

    Returns
    -------
    ndarray (..., 3)
        ECEF positions, m.

    """
    lat, lon, h = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (lat, lon, h)))
    e2 = f * (2.0 - f)
    sl = np.sin(lat)
    n = a / np.sqrt(1.0 - e2 * sl * sl)
    return np.stack([(n + h) * np.cos(lat) * np.cos(lon), (n + h) * np.cos(lat) * np.sin(lon),
                     (n * (1.0 - e2) + h) * sl], axis=-1)


def ecef_to_geodetic(r, a=A, f=F):
    """
    Convert ECEF positions to geodetic coordinates (Bowring iteration, 4 steps).

    Four steps give < 1e-15 rad and < 1e-8 m.

    Parameters
    ----------
    r : array_like (..., 3)
        ECEF positions, m.
    a : float
        Equatorial radius, m.
    f : float
        Flattening.

    Returns
    -------
    (ndarray, ndarray, ndarray)
        Latitude and longitude, rad, and height, m.

    """
    r = np.asarray(r, dtype=np.float64)
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    e2 = f * (2.0 - f)
    b = a * (1.0 - f)
    ep2 = e2 / (1.0 - e2)
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1.0 - e2))
    for _ in range(4):
        beta = np.arctan2((1.0 - f) * np.sin(lat), np.cos(lat))     # reduced latitude
        lat = np.arctan2(z + ep2 * b * np.sin(beta) ** 3, p - e2 * a * np.cos(beta) ** 3)
    sl, cl = np.sin(lat), np.cos(lat)
    h = p * cl + z * sl - a * np.sqrt(1.0 - e2 * sl * sl)
    return lat, np.arctan2(y, x), h


def enu_rotation(lat, lon):
    """
    Return ``C_ecef_enu``: its columns are east, north and up expressed in ECEF.

    Parameters
    ----------
    lat, lon : float or array_like
        Geodetic latitude and longitude, rad.

    Returns
    -------
    ndarray (..., 3, 3)
        ``C_ecef_enu``, mapping ENU coordinates to ECEF.

    """
    lat, lon = np.broadcast_arrays(np.asarray(lat, dtype=np.float64),
                                   np.asarray(lon, dtype=np.float64))
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    z = np.zeros_like(sl)
    east = np.stack([-so, co, z], axis=-1)
    north = np.stack([-sl * co, -sl * so, cl], axis=-1)
    up = np.stack([cl * co, cl * so, sl], axis=-1)
    return np.stack([east, north, up], axis=-1)
