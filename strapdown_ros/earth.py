"""
Normal gravity in the Earth-fixed frame and geodetic conversions.

The Earth model of the package (Aksyonenko 2014; paper 003, §1.5.2), one room above the base:
the motion profiles, the navigation channel and the parameter tables use it.

Conventions: ECEF = the PZ-90 Greenwich rectangular frame (REP-105 frame ``earth``), Earth
rotation +Z, SI units (m, m/s², rad).  "Gravity" is gravitation + centrifugal, the vector a
plumb line feels (roughly −r̂, magnitude ≈ 9.78…9.83 m/s²).  Vectorised functions take
arrays of shape (..., 3) and return float64 arrays of the same shape.

The 003 ("traditional") formula is the first-order-in-flattening form of the J2 field.
With U = GM/R·(1 − J2 (a/R)² P2(sinφ)) + ½Ω²R²cos²φ (φ geocentric):
    up:    g_r = −GM/R²·[1 + 1.5 J2 (a/R)² (1 − 3 sin²φ)] + Ω²R cos²φ
    north: g_n = −[3 J2 GM a²/R⁴ + Ω²R] sinφ cosφ
and with 3 J2 ≈ e² − η, GM/a² ≈ g_e (1 − ½e² + 3/2 η) (Clairaut, first order; η = aΩ²/g_e)
these become the printed g3 (= g_r) and g2 (= g_n); (g_r, g_n) → ECEF is the rotation
g_X = (g_r cosφ − g_n sinφ) X/m, g_Y = (…) Y/m, g_Z = g_r sinφ + g_n cosφ.
See doc/navigation_gravity.md for the derivation and the numbers (``python -m
strapdown_ros.earth`` prints them).
"""
from collections import namedtuple
from functools import partial
import math

import numpy as np

# --- constants -------------------------------------------------------------------------
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

#: Misprints of the printed formula (003 lines 1163-1176), each shown numerically in the doc.
MISPRINTS = {
    'g2_centrifugal_sign': 'g2 = (−g_e(e²−η)(a/R)⁴ + Ω²R) sinφcosφ: the centrifugal term must be '
                           '−Ω²R (J2 and centrifugal both pull toward the equator); with it '
                           'as printed the direction is off by up to 722″ (vs 3.2″ corrected).',
    'gZ_sign': 'g_Z = g3 sinφ − g2 cosφ is not a rotation of (g3, g2) together with '
               'g_X = (g3 cosφ − g2 sinφ)X/m (rows (c,−s),(s,−c) are not orthonormal); '
               'g_Z = g3 sinφ + g2 cosφ (as printed: 902″ and 3260 mGal off).',
    'e2_digits': "'0066934' lacks '0.': read 0.0066934 (kept). PZ-90 e² = 0.0066943662 (two "
                 'digits swapped?) is not proven: it moves the fit only 3.20″→3.11″, 34.7→33.5 '
                 'mGal, and e² = 0.0067 fits better still - the first-order truncation dominates.',
}


# --- the 003 formula (scalar, pure math: numba.njit-able) -------------------------------
def printed_gravity_xyz(x, y, z):
    """
    Return 003's normal gravity, corrected, at one ECEF position.

    Pure ``math`` on scalars so that ``numba.njit(printed_gravity_xyz)`` compiles.  As printed
    except the two proven sign misprints (:data:`MISPRINTS`); e² = 0.0066934, η = 0.00346775,
    g_e = 9.780318 as printed.  On the Z axis (m = 0) g_X = g_Y = 0.

    Parameters
    ----------
    x, y, z : float
        ECEF position, m.

    Returns
    -------
    (float, float, float)
        ECEF gravity (g_X, g_Y, g_Z), m/s².

    """
    m = math.sqrt(x * x + y * y)
    r = math.sqrt(x * x + y * y + z * z)
    s = z / r
    c = m / r
    k2 = (A / r) * (A / r)
    w2r = OMEGA * OMEGA * r
    g2 = (-GE * (E2_003 - ETA_003) * k2 * k2 - w2r) * s * c
    g3 = (-GE * k2 * (1.0 - 0.5 * E2_003 + 1.5 * ETA_003
                      + 0.5 * (E2_003 - ETA_003) * (1.0 - 3.0 * s * s) * k2) + w2r * c * c)
    hor = g3 * c - g2 * s
    if m > 0.0:
        return hor * x / m, hor * y / m, g3 * s + g2 * c
    return 0.0, 0.0, g3 * s + g2 * c


def printed_gravity_as_printed(x, y, z):
    """
    Return 003's normal gravity literally as printed, at one ECEF position.

    e² = 0.0066934, +Ω²R in g2, −g2 cosφ in g_Z (the misprint study's reference).

    Parameters
    ----------
    x, y, z : float
        ECEF position, m.

    Returns
    -------
    (float, float, float)
        ECEF gravity (g_X, g_Y, g_Z), m/s².

    """
    m = math.sqrt(x * x + y * y)
    r = math.sqrt(x * x + y * y + z * z)
    s = z / r
    c = m / r
    k2 = (A / r) * (A / r)
    w2r = OMEGA * OMEGA * r
    g2 = (-GE * (E2_003 - ETA_003) * k2 * k2 + w2r) * s * c
    g3 = (-GE * k2 * (1.0 - 0.5 * E2_003 + 1.5 * ETA_003
                      + 0.5 * (E2_003 - ETA_003) * (1.0 - 3.0 * s * s) * k2) + w2r * c * c)
    hor = g3 * c - g2 * s
    if m > 0.0:
        return hor * x / m, hor * y / m, g3 * s - g2 * c
    return 0.0, 0.0, g3 * s - g2 * c


def printed_gravity_variant(r, e2=E2_003, g2_omega_sign=-1.0, gz_sign=1.0, ge=GE, eta=ETA_003):
    """
    Return 003's gravity formula, vectorised, with the disputed pieces as parameters.

    The defaults are the corrected formula (:func:`printed_gravity_xyz`).

    Parameters
    ----------
    r : array_like (..., 3)
        ECEF positions, m.
    e2 : float
        First eccentricity squared.
    g2_omega_sign : float
        Sign of the Ω²R term in g2 (+1 as printed, −1 corrected).
    gz_sign : float
        Sign of the g2 cosφ term in g_Z (−1 as printed, +1 corrected).
    ge : float
        Equatorial gravity, m/s².
    eta : float
        η = aΩ²/g_e.

    Returns
    -------
    ndarray (..., 3)
        ECEF gravity, m/s².

    """
    r = np.asarray(r, dtype=np.float64)
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    m = np.sqrt(x * x + y * y)
    rr = np.sqrt(x * x + y * y + z * z)
    s, c = z / rr, m / rr
    k2 = (A / rr) * (A / rr)
    w2r = OMEGA * OMEGA * rr
    g2 = (-ge * (e2 - eta) * k2 * k2 + g2_omega_sign * w2r) * s * c
    g3 = -ge * k2 * (1.0 - 0.5 * e2 + 1.5 * eta + 0.5 * (e2 - eta) * (1.0 - 3.0 * s * s) * k2) \
        + w2r * c * c
    hor = g3 * c - g2 * s
    safe = np.where(m > 0.0, m, 1.0)
    out = np.empty(r.shape)
    out[..., 0] = np.where(m > 0.0, hor * x / safe, 0.0)
    out[..., 1] = np.where(m > 0.0, hor * y / safe, 0.0)
    out[..., 2] = g3 * s + gz_sign * g2 * c
    return out


def _pz90_003(r):
    return printed_gravity_variant(r)


# --- independent references ------------------------------------------------------------
def j2_potential(r, gm=GM, j2=J2, a=A, omega=OMEGA):
    """
    Return the J2 gravity potential plus the centrifugal potential.

    GM/R·(1 − J2 (a/R)² P2(sinφ)) + ½Ω²(X²+Y²).

    Parameters
    ----------
    r : array_like (..., 3)
        ECEF positions, m.
    gm : float
        Gravitational parameter, m³/s².
    j2 : float
        Second zonal coefficient.
    a : float
        Equatorial radius, m.
    omega : float
        Earth rate, rad/s.

    Returns
    -------
    ndarray (...)
        Potential, m²/s².

    """
    r = np.asarray(r, dtype=np.float64)
    rr2 = np.sum(r * r, axis=-1)
    rr = np.sqrt(rr2)
    s2 = r[..., 2] ** 2 / rr2
    return gm / rr * (1.0 - j2 * a * a / rr2 * 0.5 * (3.0 * s2 - 1.0)) \
        + 0.5 * omega ** 2 * (r[..., 0] ** 2 + r[..., 1] ** 2)


def _j2(r, gm=GM, j2=J2, a=A, omega=OMEGA):
    """Analytic gradient of :func:`j2_potential`."""
    r = np.asarray(r, dtype=np.float64)
    rr2 = np.sum(r * r, axis=-1)
    s2 = r[..., 2] ** 2 / rr2
    k = gm / rr2 ** 1.5
    q = 1.5 * j2 * a * a / rr2
    out = np.empty(r.shape)
    out[..., 0] = -k * r[..., 0] * (1.0 + q * (1.0 - 5.0 * s2)) + omega ** 2 * r[..., 0]
    out[..., 1] = -k * r[..., 1] * (1.0 + q * (1.0 - 5.0 * s2)) + omega ** 2 * r[..., 1]
    out[..., 2] = -k * r[..., 2] * (1.0 + q * (3.0 - 5.0 * s2))
    return out


def _q(u, e):
    """
    q(u) = ½[(1 + 3u²/E²) atan(E/u) − 3u/E] (Heiskanen & Moritz 2-57) and dq/du.

    For x = E/u ≤ ½ the series q = Σ_{k≥1} (−1)^{k+1} 2k x^{2k+1}/((2k+1)(2k+3)) (30 terms)
    avoids the cancellation of the closed form (~1e-11 relative at the Earth's surface).
    """
    u = np.asarray(u, dtype=np.float64)
    x = e / u
    xs = np.minimum(x, 0.5)
    x2 = xs * xs
    sq = np.zeros_like(x2)
    sd = np.zeros_like(x2)
    for k in range(30, 0, -1):
        sgn = 1.0 if k % 2 else -1.0
        sq = sgn * 2.0 * k / ((2.0 * k + 1.0) * (2.0 * k + 3.0)) + x2 * sq
        sd = sgn * 2.0 * k / (2.0 * k + 3.0) + x2 * sd
    at = np.arctan(x)
    q_cf = 0.5 * ((1.0 + 3.0 / (x * x)) * at - 3.0 / x)
    dq_cf = 0.5 * (6.0 * u / (e * e) * at
                   - (e * e + 3.0 * u * u) / (e * (u * u + e * e)) - 3.0 / e)
    q = np.where(x <= 0.5, xs ** 3 * sq, q_cf)
    dq = np.where(x <= 0.5, -xs ** 3 * sd / u, dq_cf)          # dq/du = −(x/u) dq/dx
    return q, dq


def _ellipsoidal(r, ell):
    """(u, sinβ, E², E, b): ellipsoidal-harmonic X,Y = √(u²+E²)cosβ(cosλ,sinλ), Z = u sinβ."""
    r = np.asarray(r, dtype=np.float64)
    b = ell.a * (1.0 - ell.f)
    e2l = ell.a ** 2 - b * b
    p2 = r[..., 0] ** 2 + r[..., 1] ** 2
    d = p2 + r[..., 2] ** 2 - e2l
    u = np.sqrt(0.5 * (d + np.sqrt(d * d + 4.0 * e2l * r[..., 2] ** 2)))
    return u, r[..., 2] / u, e2l, math.sqrt(e2l), b


def normal_potential(r, ell=PZ90_11):
    """
    Return the exact normal potential of the level ellipsoid (H&M 2-126) plus centrifugal.

    Parameters
    ----------
    r : array_like (..., 3)
        ECEF positions, m.
    ell : Ellipsoid
        The level ellipsoid (default PZ-90.11).

    Returns
    -------
    ndarray (...)
        Potential, m²/s².

    """
    r = np.asarray(r, dtype=np.float64)
    u, sb, _, e, b = _ellipsoidal(r, ell)
    q, _ = _q(u, e)
    q0, _ = _q(b, e)
    w2 = ell.omega ** 2
    return ell.gm / e * np.arctan(e / u) + 0.5 * w2 * ell.a ** 2 * q / q0 * (sb * sb - 1.0 / 3.0) \
        + 0.5 * w2 * (r[..., 0] ** 2 + r[..., 1] ** 2)


def normal_gravity_exact(r, ell=PZ90_11):
    """
    Return the analytic gradient of :func:`normal_potential`; exact at any height.

    Parameters
    ----------
    r : array_like (..., 3)
        ECEF positions, m.
    ell : Ellipsoid
        The level ellipsoid (default PZ-90.11).

    Returns
    -------
    ndarray (..., 3)
        ECEF gravity (gravitation + centrifugal), m/s².

    """
    r = np.asarray(r, dtype=np.float64)
    u, sb, e2l, e, b = _ellipsoidal(r, ell)
    q, dq = _q(u, e)
    q0, _ = _q(b, e)
    w2a2 = ell.omega ** 2 * ell.a ** 2
    vu = -ell.gm / (u * u + e2l) + 0.5 * w2a2 * dq / q0 * (sb * sb - 1.0 / 3.0)   # ∂V/∂u
    vb = w2a2 * q / q0                                   # ∂V/∂β = vb·sinβ cosβ
    den = u * u + e2l * sb * sb                          # h_β² = u² + E² sin²β
    cu, cb = vu / den, vb / den
    cb2 = 1.0 - sb * sb
    out = np.empty(r.shape)
    for i in (0, 1):
        out[..., i] = cu * u * r[..., i] - cb * sb * sb * r[..., i] + ell.omega ** 2 * r[..., i]
    out[..., 2] = cu * (u * u + e2l) * sb + cb * u * sb * cb2
    return out


def somigliana(lat, ell=PZ90_11):
    """
    Return the normal gravity magnitude on the ellipsoid (Somigliana, closed form).

    Parameters
    ----------
    lat : float or array_like
        Geodetic latitude, rad.
    ell : Ellipsoid
        The level ellipsoid (default PZ-90.11).

    Returns
    -------
    float or ndarray
        Gravity magnitude on the ellipsoid surface, m/s².

    """
    b = ell.a * (1.0 - ell.f)
    e = math.sqrt(ell.a ** 2 - b * b)
    ep = e / b
    mm = ell.omega ** 2 * ell.a ** 2 * b / ell.gm
    q0 = _q(b, e)[0]
    q0p = 3.0 * (1.0 + b * b / (e * e)) * (1.0 - b / e * math.atan(e / b)) - 1.0
    ge = ell.gm / (ell.a * b) * (1.0 - mm - mm * ep * q0p / (6.0 * q0))
    gp = ell.gm / ell.a ** 2 * (1.0 + mm * ep * q0p / (3.0 * q0))
    c2, s2 = np.cos(lat) ** 2, np.sin(lat) ** 2
    return (ell.a * ge * c2 + b * gp * s2) / np.sqrt(ell.a ** 2 * c2 + b * b * s2)


def level_ellipsoid_j2(ell=PZ90_11):
    """
    Return the J2 implied by (a, f, GM, ω) of a level ellipsoid: e²/3·(1 − 2 m e′/(15 q0)).

    Parameters
    ----------
    ell : Ellipsoid
        The level ellipsoid (default PZ-90.11).

    Returns
    -------
    float
        J2.

    """
    b = ell.a * (1.0 - ell.f)
    e = math.sqrt(ell.a ** 2 - b * b)
    mm = ell.omega ** 2 * ell.a ** 2 * b / ell.gm
    return (e / ell.a) ** 2 / 3.0 * (1.0 - 2.0 * mm * (e / b) / (15.0 * _q(b, e)[0]))


# --- the exact normal field, scalar (pure math: numba.njit-able) -----------------------------
_B = A * (1.0 - F)                                    # PZ-90.11 semi-minor axis, m
_E2L = A * A - _B * _B                                # linear eccentricity squared E², m²
_EL = math.sqrt(_E2L)
_Q0 = float(_q(_B, _EL)[0])                          # q at the ellipsoid (u = b)


def normal_exact_xyz(x, y, z):
    """
    Return the exact normal gravity at one ECEF position, scalar form.

    The exact normal gravity of the PZ-90.11 level ellipsoid (:func:`normal_gravity_exact`) at one
    ECEF position (m) → (g_X, g_Y, g_Z), m/s²; pure ``math`` on scalars (the series and closed
    form of :func:`_q` inlined) so that numba compiles it into the navigation loop
    (``recursion.run``).

    Parameters
    ----------
    x, y, z : float
        ECEF position (PZ-90), m.

    Returns
    -------
    tuple of float
        (g_X, g_Y, g_Z): gravitation + centrifugal, ECEF axes, m/s².

    """
    d = x * x + y * y + z * z - _E2L
    u = math.sqrt(0.5 * (d + math.sqrt(d * d + 4.0 * _E2L * z * z)))
    sb = z / u
    t = _EL / u                                       # q(u) and dq/du as in _q
    if t <= 0.5:
        t2 = t * t
        sq = 0.0
        sd = 0.0
        for k in range(30, 0, -1):
            sgn = 1.0 if k % 2 else -1.0
            sq = sgn * 2.0 * k / ((2.0 * k + 1.0) * (2.0 * k + 3.0)) + t2 * sq
            sd = sgn * 2.0 * k / (2.0 * k + 3.0) + t2 * sd
        q, dq = t ** 3 * sq, -t ** 3 * sd / u
    else:
        at = math.atan(t)
        q = 0.5 * ((1.0 + 3.0 / (t * t)) * at - 3.0 / t)
        dq = 0.5 * (6.0 * u / _E2L * at - (_E2L + 3.0 * u * u) / (_EL * (u * u + _E2L))
                    - 3.0 / _EL)
    w2a2 = OMEGA * OMEGA * A * A
    vu = -GM / (u * u + _E2L) + 0.5 * w2a2 * dq / _Q0 * (sb * sb - 1.0 / 3.0)
    vb = w2a2 * q / _Q0
    den = u * u + _E2L * sb * sb
    cu, cb = vu / den, vb / den
    radial = cu * u - cb * sb * sb + OMEGA * OMEGA
    return radial * x, radial * y, cu * (u * u + _E2L) * sb + cb * u * sb * (1.0 - sb * sb)


#: the default normal-gravity model of the whole package (core functions, node and tool
#: parameters): the exact normal gravity of the level ellipsoid; "pz90_003" (003's formula,
#: corrected) stays selectable by name
DEFAULT_GRAVITY_MODEL = 'normal_exact'

GRAVITY_MODELS = {'pz90_003': _pz90_003, 'normal_exact': normal_gravity_exact, 'j2': _j2}
#: scalar forms of the models (numba-compilable) that the navigation loop can run compiled
SCALAR_GRAVITY = {'pz90_003': printed_gravity_xyz, 'normal_exact': normal_exact_xyz}


def get_gravity_model(name):
    """
    Return the vectorised gravity function registered under ``name``.

    Parameters
    ----------
    name : str
        A key of :data:`GRAVITY_MODELS`.

    Returns
    -------
    callable
        r (..., 3) ECEF, m → g (..., 3) ECEF, m/s².

    Raises
    ------
    ValueError
        For an unknown name, listing the valid ones.

    """
    try:
        return GRAVITY_MODELS[name]
    except KeyError:
        raise ValueError(
            f'unknown gravity model {name!r}; valid: {sorted(GRAVITY_MODELS)}') from None


def normal_gravity(r, model=DEFAULT_GRAVITY_MODEL):
    """
    Return the ECEF gravity vector (gravitation + centrifugal) at ECEF positions.

    Parameters
    ----------
    r : array_like (..., 3)
        ECEF positions, m.
    model : str
        A key of :data:`GRAVITY_MODELS`.

    Returns
    -------
    ndarray (..., 3)
        Gravity, m/s², ECEF axes.

    """
    return get_gravity_model(model)(np.asarray(r, dtype=np.float64))


# --- geodesy (PZ-90.11 ellipsoid) -------------------------------------------------------
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


# --- comparison -------------------------------------------------------------------------
def _angle_arcsec(g1, g2):
    cr = np.linalg.norm(np.cross(g1, g2), axis=-1)
    return np.degrees(np.arctan2(cr, np.sum(g1 * g2, axis=-1))) * 3600.0


def compare_models(test='pz90_003', reference='normal_exact', heights=(0.0, 1e3, 1e4, 2e4, 1e5),
                   lat_step_deg=5.0, lon_deg=(0.0, 37.0, 143.0, -100.0)):
    """
    Return the differences of ``test`` against ``reference`` on a geodetic grid, per height.

    Parameters
    ----------
    test, reference : str or callable
        Registry names or callables r (..., 3) → g (..., 3).
    heights : sequence of float
        Heights above the ellipsoid, m.
    lat_step_deg : float
        Latitude step of the grid, degrees.
    lon_deg : sequence of float
        Longitudes of the grid, degrees.

    Returns
    -------
    dict
        {h: {"max_mag", "rms_mag" (m/s²), "max_mag_mgal", "rms_mag_mgal", "max_dir_arcsec",
        "rms_dir_arcsec", "worst_lat_deg"}}.

    """
    ft = get_gravity_model(test) if isinstance(test, str) else test
    fr = get_gravity_model(reference) if isinstance(reference, str) else reference
    lat = np.radians(np.arange(-90.0, 90.0 + 1e-9, lat_step_deg))
    lon = np.radians(np.asarray(lon_deg, dtype=np.float64))
    out = {}
    for h in heights:
        la, lo = np.meshgrid(lat, lon, indexing='ij')
        r = geodetic_to_ecef(la, lo, h)
        gt, gr = ft(r), fr(r)
        dm = np.linalg.norm(gt, axis=-1) - np.linalg.norm(gr, axis=-1)
        da = _angle_arcsec(gt, gr)
        out[float(h)] = {
            'max_mag': float(np.max(np.abs(dm))), 'rms_mag': float(np.sqrt(np.mean(dm ** 2))),
            'max_mag_mgal': float(np.max(np.abs(dm))) * 1e5,
            'rms_mag_mgal': float(np.sqrt(np.mean(dm ** 2))) * 1e5,
            'max_dir_arcsec': float(np.max(da)),
            'rms_dir_arcsec': float(np.sqrt(np.mean(da ** 2))),
            'worst_lat_deg': float(np.degrees(la.ravel()[np.argmax(np.abs(dm).ravel())])),
        }
    return out


#: Variants of the printed formula (misprint study): name → r (...,3) → g (...,3).
_pv = printed_gravity_variant
PRINTED_VARIANTS = {
    'as printed (e²=0.0066934, +Ω²R in g2, −g2·cosφ in g_Z)':
        partial(_pv, g2_omega_sign=1.0, gz_sign=-1.0),
    'g2 fixed only': partial(_pv, gz_sign=-1.0),
    'g_Z fixed only': partial(_pv, g2_omega_sign=1.0),
    'both signs fixed (pz90_003)': _pv,
    'both fixed, e²=0.0066943662': partial(_pv, e2=E2),
    'both fixed, e²=0.0066943662, g_e=Somigliana PZ-90.11':
        partial(_pv, e2=E2, ge=float(somigliana(0.0))),
}


def report(heights=(0.0, 1e3, 1e4, 2e4, 1e5)):
    """
    Return the Markdown tables of :func:`compare_models` (quoted in doc/navigation_gravity.md).

    Parameters
    ----------
    heights : sequence of float
        Heights above the ellipsoid, m.

    Returns
    -------
    str
        The constants, the model comparisons and the printed-formula variants.

    """
    ge_pz, gp_pz = float(somigliana(0.0)), float(somigliana(np.pi / 2))
    ge_w, gp_w = float(somigliana(0.0, WGS84)), float(somigliana(np.pi / 2, WGS84))
    c0, c1 = GE * (1 - 0.5 * E2_003 + 1.5 * ETA_003), GE * (E2_003 - ETA_003)
    lines = ['### Constants', '',
             f'* Somigliana PZ-90.11: γ_e = {ge_pz:.10f}, γ_p = {gp_pz:.10f} m/s² '
             f'(003 g_e = {GE}); WGS-84: γ_e = {ge_w:.10f}, γ_p = {gp_w:.10f}',
             f'* J2 of the PZ-90.11 level ellipsoid = {level_ellipsoid_j2():.10e} '
             f'(published {J2:.10e})',
             f'* η = aΩ²/g_e = {A * OMEGA ** 2 / GE:.10f} (003 prints {ETA_003})',
             f'* first-order coefficients: g_e(1 − ½e² + 3/2η) = {c0:.6f} '
             f'vs GM/a² = {GM / A ** 2:.6f}; '
             f'g_e(e² − η) = {c1:.6f} vs 3·J2·GM/a² = {3 * J2 * GM / A ** 2:.6f} m/s²', '']
    head = '| h, km | max abs Δ‖g‖, mGal | RMS Δ‖g‖, mGal | max angle, ″ | RMS angle, ″ |'
    for test, ref in (('pz90_003', 'normal_exact'), ('j2', 'normal_exact'), ('pz90_003', 'j2')):
        lines += [f'### {test} vs {ref}', '', head, '|---|---|---|---|---|']
        for h, d in compare_models(test, ref, heights).items():
            lines.append(f"| {h / 1e3:g} | {d['max_mag_mgal']:.3g} | {d['rms_mag_mgal']:.3g} | "
                         f"{d['max_dir_arcsec']:.3g} | {d['rms_dir_arcsec']:.3g} |")
        lines.append('')
    lines += ['### Printed-formula variants vs normal_exact, h = 0 … 20 km (worst over heights)',
              '', '| variant | max abs Δ‖g‖, mGal | max angle, ″ | RMS angle, ″ |',
              '|---|---|---|---|']
    for name, fn in PRINTED_VARIANTS.items():
        c = compare_models(fn, 'normal_exact', (0.0, 1e4, 2e4)).values()
        worst = [max(d[k] for d in c)
                 for k in ('max_mag_mgal', 'max_dir_arcsec', 'rms_dir_arcsec')]
        lines.append(f'| {name} | ' + ' | '.join(f'{v:.3g}' for v in worst) + ' |')
    return '\n'.join(lines)


if __name__ == '__main__':
    print(report())
