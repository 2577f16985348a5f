"""
The normal gravity field of a level ellipsoid: exact closed form, Somigliana, and the J2 field.

Independent references for the printed formula of paper 003, and the default model of the
package (``normal_exact``), also in a scalar form that numba compiles into the navigation
loop.  ECEF axes, SI units.
"""
import math

import numpy as np

from strapdown_ros.earth.ellipsoid import A, F, GM, J2, OMEGA, PZ90_11


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


def j2_gravity(r, gm=GM, j2=J2, a=A, omega=OMEGA):
    """
    Return the analytic gradient of :func:`j2_potential` (model ``j2``).

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
    ndarray (..., 3)
        ECEF gravity (gravitation + centrifugal), m/s².

    """
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
