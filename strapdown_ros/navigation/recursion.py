"""
Velocity and position recursion in the Earth-fixed frame E (PZ-90).

003 (1.93), (1.99)–(1.100) (Aksyonenko 2014; paper 003); run by the :mod:`.navigator`.

Inputs per step k (``[t_{k−1}, t_k]``, length h): the specific-force integrals
``Δv_E = V_{k−1} Δv``
and ``Δr_E = V_{k−1} Δr`` (:mod:`.update`, rotated by the attitude ``V_{k−1}`` = C_E_B at
``t_{k−1}``).  State: ECEF position R and ECEF velocity W = Ṙ.

``"exact"`` scheme (default; derived in doc/navigation.md)
    The step is integrated in the inertial frame I that coincides with E at ``t_{k−1}``.  There
    ``r̈ = C f + G(r)`` with gravitation ``G = g + Ω×(Ω×r)`` (normal gravity g minus the
    centrifugal part): no Coriolis term, and the Earth's rotation enters only through the
    frame change at the end, ``x_E(t_k) = D_h x_I``, ``D_h = R_z(−Ωh)`` (exact)::

        v_I = W + Ω×R
        v_I' = v_I + Δv_E + h (G₀ + G₁)/2                       trapezoid in G
        r_I' = R + v_I h + Δr_E + h² (G₀/3 + G₁/6)              its double integral
        R_k = D_h r_I',   W_k = D_h v_I' − Ω×R_k

    with G₀ = G(R), G₁ = G at the predicted end position (rotated back into I).  The gravity
    quadrature error is of order h³ G̈ per step (10⁻¹⁵ m/s for a point at rest at 100 Hz).  R is
    kept as a fixed origin plus an offset so that the round-off of a 6.4·10⁶ m vector does not
    enter each step.
``"printed"`` scheme
    003 (1.99)/(1.100) as printed, with only the dimensional misprints repaired so that it runs
    (−2Ω×W and g carry the factor h in (1.99); the Coriolis term of (1.100) is −Ω×W h², not
    −2Ω×W h): first-order Coriolis and gravity from the values at ``t_{k−1}``, and the whole
    specific-force increment rotated by ``D(t_k) U(t_{k−1}) = D_h V_{k−1}``.

Both loops are plain Python over ``math``; with numba present the exact loop runs compiled
(``STRAPDOWN_KERNEL=numpy`` forces Python).  No ROS imports.
"""
from __future__ import annotations

import math
import types

import numpy as np

from strapdown_ros import earth as _gravity
from strapdown_ros.attitude.kernel import kernels_allowed, njit_optional
from strapdown_ros.earth import DEFAULT_GRAVITY_MODEL

__all__ = ['SCHEMES', 'run', 'OMEGA']

SCHEMES = ('exact', 'printed')
OMEGA = _gravity.OMEGA


def _model_gravity_xyz(model, x, y, z):
    """Return the gravity of a compiled model: 1 the exact normal field, else 003's formula."""
    if model == 1:
        return _normal_exact_xyz(x, y, z)
    return _gravity_xyz(x, y, z)


#: the models the compiled loop has built in, by the integer it is given
COMPILED_MODELS = {'pz90_003': 0, 'normal_exact': 1}


def _exact_loop(origin, offset0, w0, dv, dr, h, omega, out_off, out_w, model):
    """Run the exact scheme with the gravity of ``model`` (:data:`COMPILED_MODELS`) inside."""
    ox, oy, oz = origin[0], origin[1], origin[2]
    px, py, pz = offset0[0], offset0[1], offset0[2]
    wx, wy, wz = w0[0], w0[1], w0[2]
    w2 = omega * omega
    rx, ry, rz = ox + px, oy + py, oz + pz
    gx, gy, gz = _model_gravity_xyz(model, rx, ry, rz)
    # gravitation G = g + Ω×(Ω×r) = g − Ω²(x, y, 0)
    g0x, g0y = gx - w2 * rx, gy - w2 * ry
    g0z = gz
    for k in range(dv.shape[0]):
        hk = h[k]
        vx, vy, vz = wx - omega * ry, wy + omega * rx, wz       # v_I = W + Ω×R
        # predicted end position (inertial frame of t_{k-1}), rotated into E of t_k
        # D_h − I: c1 = cos − 1
        s, c1 = math.sin(omega * hk), -2.0 * math.sin(0.5 * omega * hk) ** 2
        qx = rx + vx * hk + dr[k, 0] + 0.5 * g0x * hk * hk
        qy = ry + vy * hk + dr[k, 1] + 0.5 * g0y * hk * hk
        qz = rz + vz * hk + dr[k, 2] + 0.5 * g0z * hk * hk
        ex, ey = qx + c1 * qx + s * qy, qy - s * qx + c1 * qy
        gx, gy, gz = _model_gravity_xyz(model, ex, ey, qz)
        gx, gy = gx - w2 * ex, gy - w2 * ey                     # gravitation at the end, E axes
        g1x, g1y, g1z = gx + c1 * gx - s * gy, gy + s * gx + c1 * gy, gz     # back to I: D_hᵀ
        # increments in I
        ivx = dv[k, 0] + 0.5 * hk * (g0x + g1x)
        ivy = dv[k, 1] + 0.5 * hk * (g0y + g1y)
        ivz = dv[k, 2] + 0.5 * hk * (g0z + g1z)
        h2 = hk * hk
        # the step's displacement in I apart from the Earth-rate carriage (Ω×R) h
        qx = wx * hk + dr[k, 0] + h2 * (g0x / 3.0 + g1x / 6.0)
        qy = wy * hk + dr[k, 1] + h2 * (g0y / 3.0 + g1y / 6.0)
        qz = wz * hk + dr[k, 2] + h2 * (g0z / 3.0 + g1z / 6.0)
        # R_k = D_h (R + (Ω×R) h + q) = R + M_h R + D_h q with M_h = D_h (I + h[Ω×]) − I, which is
        # O((Ωh)²): the 6.4e6 m vector R never passes through a rotation whose round-off would
        # add a systematic 1e-10 m per step (the vertical channel amplifies that ~300× in an hour).
        # In the x-y plane M_h is the complex factor m = e^{−iθ}(1 + iθ) − 1, θ = Ωh, by series.
        th = omega * hk
        t2 = th * th
        mr = t2 * (0.5 - t2 * (1.0 / 8.0 - t2 / 144.0))
        mi = -th * t2 * (1.0 / 3.0 - t2 / 30.0)
        bx, by = qx + c1 * qx + s * qy, qy - s * qx + c1 * qy         # D_h q
        px = px + (mr * rx - mi * ry) + bx
        py = py + (mr * ry + mi * rx) + by
        pz = pz + qz
        # W_k = D_h v_I' − Ω×R_k = D_h (W + iv − Ω×((Ω×R) h + q)): no Ω×R (hundreds of m/s) cancels
        ax = wx + ivx + omega * omega * rx * hk + omega * qy
        ay = wy + ivy + omega * omega * ry * hk - omega * qx
        az = wz + ivz
        wx = ax + c1 * ax + s * ay
        wy = ay - s * ax + c1 * ay
        wz = az
        rx, ry, rz = ox + px, oy + py, oz + pz
        # gravitation at R_k for the next step (fresh, not the predicted one)
        gx, gy, gz = _model_gravity_xyz(model, rx, ry, rz)
        g0x, g0y, g0z = gx - w2 * rx, gy - w2 * ry, gz
        out_off[k, 0], out_off[k, 1], out_off[k, 2] = px, py, pz
        out_w[k, 0], out_w[k, 1], out_w[k, 2] = wx, wy, wz


_gravity_xyz = _gravity.printed_gravity_xyz
_normal_exact_xyz = _gravity.normal_exact_xyz
_compiled = None


def available() -> bool:
    """
    Tell whether the exact loop runs compiled.

    Returns
    -------
    bool
        True when numba is present, allowed and able to compile the loop.

    """
    global _compiled, _gravity_xyz, _normal_exact_xyz, _model_gravity_xyz
    if not kernels_allowed():
        return False
    if _compiled is None:
        got = njit_optional(_gravity.printed_gravity_xyz, _gravity.normal_exact_xyz)
        if got:
            _gravity_xyz, _normal_exact_xyz = got
            got = njit_optional(_model_gravity_xyz)
        if got:
            _model_gravity_xyz = got[0]
            got = njit_optional(_exact_loop)
        _compiled = got[0] if got else False
    return _compiled is not False


def exact_generic_step(origin, offset, w, dv, dr, h, model):
    """
    Run the exact scheme with any gravity model of the registry.

    The same loop, run by Python with that model's gravity (slow; the compiled loop has only
    :data:`COMPILED_MODELS` built in).

    Parameters
    ----------
    origin : (3,) ndarray
        Fixed part of the ECEF position, m.
    offset : (3,) ndarray
        Position minus origin at the start, m.
    w : (3,) ndarray
        ECEF velocity at the start, m/s.
    dv, dr : (K, 3) ndarray
        Specific-force integrals rotated into E at each step's start, m/s and m.
    h : (K,) ndarray
        Step lengths, s.
    model : str
        Name in the gravity registry of :mod:`strapdown_ros.earth`.

    Returns
    -------
    tuple of ndarray
        ``(offset (K, 3), velocity (K, 3))`` after each step.

    """
    def grav(_model, x, y, z):
        g = _gravity.normal_gravity(np.array([x, y, z]), model)
        return float(g[0]), float(g[1]), float(g[2])
    loop = types.FunctionType(_exact_loop.__code__, {**globals(), '_model_gravity_xyz': grav})
    out_off = np.empty_like(dv)
    out_w = np.empty_like(dv)
    loop(origin, offset, w, dv, dr, h, OMEGA, out_off, out_w, -1)
    return out_off, out_w


def _printed(origin, offset, w, dv, dr, h, model):
    """003 (1.99)/(1.100) with the dimensional misprints repaired (see module docstring)."""
    om = np.array([0.0, 0.0, OMEGA])
    out_off = np.empty_like(dv)
    out_w = np.empty_like(dv)
    for k in range(len(dv)):
        hk = h[k]
        s, c = math.sin(OMEGA * hk), math.cos(OMEGA * hk)
        d = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
        g = _gravity.normal_gravity(origin + offset, model)
        cor = np.cross(om, w)
        new_w = w - 2.0 * cor * hk + g * hk + d @ dv[k]
        offset = offset + w * hk - cor * hk * hk + 0.5 * g * hk * hk + d @ dr[k]
        w = new_w
        out_off[k], out_w[k] = offset, w
    return out_off, out_w


def run(origin, offset, velocity, dv_e, dr_e, h, scheme: str = 'exact',
        gravity_model: str = DEFAULT_GRAVITY_MODEL):
    """
    Run K navigation steps of the velocity and position recursion.

    Parameters
    ----------
    origin : (3,) array_like
        Fixed part of the ECEF position, m.
    offset : (3,) array_like
        Position minus origin at the start, m.
    velocity : (3,) array_like
        ECEF velocity at the start, m/s.
    dv_e, dr_e : (K, 3) array_like
        Specific-force integrals already rotated into E axes at ``t_{k−1}``, m/s and m.
    h : (K,) array_like
        Step lengths, s.
    scheme : str
        One of :data:`SCHEMES`.
    gravity_model : str
        Name in the gravity registry of :mod:`strapdown_ros.earth`.

    Returns
    -------
    tuple of ndarray
        ``(offset (K, 3), velocity (K, 3))`` after each step; position = origin + offset.

    Raises
    ------
    ValueError
        For an unknown scheme.

    """
    if scheme not in SCHEMES:
        raise ValueError(f"unknown navigation scheme {scheme!r}; valid: {', '.join(SCHEMES)}")
    args = [np.ascontiguousarray(x, dtype=float)
            for x in (origin, offset, velocity, dv_e, dr_e, h)]
    if scheme == 'printed':
        return _printed(*args, gravity_model)
    if gravity_model not in COMPILED_MODELS:
        return exact_generic_step(*args, gravity_model)
    out_off = np.empty_like(args[3])
    out_w = np.empty_like(args[3])
    fn = _compiled if available() else _exact_loop
    fn(*args, OMEGA, out_off, out_w, COMPILED_MODELS[gravity_model])
    return out_off, out_w


def warm_up() -> None:
    """Compile (or load numba's cache) before the first real block."""
    z = np.zeros((1, 3))
    run(np.array([6378136.0, 0.0, 0.0]), np.zeros(3), np.zeros(3), z, z, np.array([0.01]))
