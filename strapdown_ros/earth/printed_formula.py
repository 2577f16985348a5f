"""
The normal gravity formula of paper 003 (Aksyonenko 2014, §1.5.2), corrected and as printed.

The 003 ("traditional") formula is the first-order-in-flattening form of the J2 field.
With U = GM/R·(1 − J2 (a/R)² P2(sinφ)) + ½Ω²R²cos²φ (φ geocentric):
    up:    g_r = −GM/R²·[1 + 1.5 J2 (a/R)² (1 − 3 sin²φ)] + Ω²R cos²φ
    north: g_n = −[3 J2 GM a²/R⁴ + Ω²R] sinφ cosφ
and with 3 J2 ≈ e² − η, GM/a² ≈ g_e (1 − ½e² + 3/2 η) (Clairaut, first order; η = aΩ²/g_e)
these become the printed g3 (= g_r) and g2 (= g_n); (g_r, g_n) → ECEF is the rotation
g_X = (g_r cosφ − g_n sinφ) X/m, g_Y = (…) Y/m, g_Z = g_r sinφ + g_n cosφ.
See doc/navigation_gravity.md for the derivation and the numbers (``python -m
strapdown_ros.earth`` prints them).  Vectorised functions take arrays of shape (..., 3) and
return float64 arrays of the same shape.
"""
from functools import partial
import math

import numpy as np

from strapdown_ros.earth.ellipsoid import A, E2, E2_003, ETA_003, GE, OMEGA
from strapdown_ros.earth.normal_field import somigliana

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


def printed_gravity(r):
    """
    Return 003's normal gravity, corrected (model ``pz90_003``), vectorised.

    Parameters
    ----------
    r : array_like (..., 3)
        ECEF positions, m.

    Returns
    -------
    ndarray (..., 3)
        ECEF gravity, m/s².

    """
    return printed_gravity_variant(r)


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
