"""The attitude and covariance recursion of :class:`~strapdown_ros.integrator.AttitudeIntegrator`
as one compiled loop — optional.

With numba installed (the ``bench`` extra brings it; it is not a runtime requirement) the
recursion over the m updates of a block runs compiled; otherwise, or with
``STRAPDOWN_KERNEL=numpy``, the integrator uses its vectorised numpy path.  Both compute the same
mathematics (the tests run both and compare them with each other and with exact truth):

    q_k      = normalise(q_{k−1} ⊗ exp(φ_k))                       003 eq. 1.64
    C_k      = C(q_k)                                              reference ← body
    P_k      = P_{k−1} + C_k Q_k C_kᵀ   (Q_k = q_k I: P_k = P_{k−1} + q_k I)
    J_k      = J_{k−1} + C_k ∂ρ_k/∂x                               gyro constants x (3 × 12)
    cov_k    = C_kᵀ (P_k + J_k diag(var) J_kᵀ) C_k                 body axes

The coning term φ_k, the white part Q_k and the Jacobians ∂ρ_k/∂x stay vectorised in numpy
(they have no recursion).  No ROS imports.
"""
from __future__ import annotations

import math
import os

import numpy as np

__all__ = ["available", "recursion", "warm_up", "kernels_allowed", "njit_optional"]

ENV = "STRAPDOWN_KERNEL"


def _recursion_py(q0, phi, p_ref0, j0, var, q_iso, q_white, jac, use_iso, use_const):
    m = phi.shape[0]
    q_out = np.empty((m, 4))
    cov = np.empty((m, 3, 3))
    w, x, y, z = q0[0], q0[1], q0[2], q0[3]
    P = p_ref0.copy()
    J = j0.copy()
    C = np.empty((3, 3))
    T = np.empty((3, 3))
    for k in range(m):
        f0, f1, f2 = phi[k, 0], phi[k, 1], phi[k, 2]
        a = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
        s = math.sin(0.5 * a) / a if a > 1e-8 else 0.5 - a * a / 48.0
        dw, dx, dy, dz = math.cos(0.5 * a), f0 * s, f1 * s, f2 * s
        w, x, y, z = (w * dw - x * dx - y * dy - z * dz, w * dx + x * dw + y * dz - z * dy,
                      w * dy - x * dz + y * dw + z * dx, w * dz + x * dy - y * dx + z * dw)
        r = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w * r, x * r, y * r, z * r
        q_out[k, 0], q_out[k, 1], q_out[k, 2], q_out[k, 3] = w, x, y, z
        C[0, 0], C[0, 1], C[0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
        C[1, 0], C[1, 1], C[1, 2] = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
        C[2, 0], C[2, 1], C[2, 2] = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
        if use_iso:
            for i in range(3):
                P[i, i] += q_iso[k]
        else:
            for i in range(3):
                for j in range(3):
                    acc = 0.0
                    for u in range(3):
                        for v in range(3):
                            acc += C[i, u] * q_white[k, u, v] * C[j, v]
                    P[i, j] += acc
        if use_const:
            for i in range(3):
                for c in range(12):
                    acc = 0.0
                    for u in range(3):
                        acc += C[i, u] * jac[k, u, c]
                    J[i, c] += acc
        for i in range(3):                              # T = P + J diag(var) Jᵀ
            for j in range(3):
                acc = P[i, j]
                for c in range(12):
                    acc += J[i, c] * var[c] * J[j, c]
                T[i, j] = acc
        for i in range(3):                              # cov = Cᵀ T C
            for j in range(3):
                acc = 0.0
                for u in range(3):
                    for v in range(3):
                        acc += C[u, i] * T[u, v] * C[v, j]
                cov[k, i, j] = acc
    return q_out, cov, P, J


_compiled = None


def kernels_allowed() -> bool:
    """False when ``STRAPDOWN_KERNEL=numpy`` switches every compiled loop of the package off."""
    return os.environ.get(ENV, "auto").strip().lower() != "numpy"


def njit_optional(*functions):
    """``numba.njit(cache=True)`` of each function (a tuple), or None without numba.  The one home
    of the optional compilation used by this module and the navigation loops."""
    try:
        import numba
        return tuple(numba.njit(cache=True)(f) for f in functions)
    except Exception:                                    # noqa: BLE001 - no numba, or it cannot compile
        return None


def available() -> bool:
    """True when the compiled recursion is in use (numba importable, not switched off)."""
    global _compiled
    if not kernels_allowed():
        return False
    if _compiled is None:
        got = njit_optional(_recursion_py)
        _compiled = got[0] if got else False
    return _compiled is not False


def warm_up() -> None:
    """Compile (or load from numba's cache) before the first real block, so that a node does not
    stall on its first messages."""
    if available():
        recursion(np.array([1.0, 0.0, 0.0, 0.0]), np.zeros((1, 3)), np.zeros((3, 3)), np.zeros((3, 12)),
                  np.zeros(12), q_iso=np.zeros(1), jac=np.zeros((1, 3, 12)))
        recursion(np.array([1.0, 0.0, 0.0, 0.0]), np.zeros((1, 3)), np.zeros((3, 3)), np.zeros((3, 12)),
                  np.zeros(12), q_white=np.zeros((1, 3, 3)))


def recursion(q0, phi, p_ref0, j0, var, q_iso=None, q_white=None, jac=None):
    """Run the recursion (compiled when :func:`available`, else the same loop in Python — slow,
    for tests).  Returns q (m, 4), cov (m, 3, 3) before symmetrisation, and the final P and J."""
    m = len(phi)
    use_iso = q_iso is not None
    use_const = jac is not None
    args = (np.ascontiguousarray(q0, dtype=float), np.ascontiguousarray(phi, dtype=float),
            np.ascontiguousarray(p_ref0, dtype=float), np.ascontiguousarray(j0, dtype=float),
            np.ascontiguousarray(var, dtype=float),
            np.ascontiguousarray(q_iso if use_iso else np.zeros(m), dtype=float),
            np.ascontiguousarray(q_white if q_white is not None else np.zeros((m, 3, 3)), dtype=float),
            np.ascontiguousarray(jac if use_const else np.zeros((m, 3, 12)), dtype=float),
            use_iso, use_const)
    fn = _compiled if available() else _recursion_py
    return fn(*args)
