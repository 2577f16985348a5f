"""
One block of the attitude integrator as one compiled loop (optional, with numba).

The block of :class:`~strapdown_ros.attitude.integrator.AttitudeIntegrator`: coning term,
attitude and covariance recursion.  The module also holds the package's one switch for
compiled loops (:func:`kernels_allowed`) and its one optional compiler (:func:`njit_optional`),
used by the navigation loops too.

With numba installed (the ``bench`` extra brings it; it is not a runtime requirement) a block of
m updates runs as a single compiled call; otherwise, or with ``STRAPDOWN_KERNEL=numpy``, the
integrator uses its vectorised numpy path.  Both compute the same mathematics (the tests run
both, for every coning algorithm and covariance model, and compare them with each other and
with exact truth).  For update k, with the window w = the ``history`` previous and the
``samples`` new increments:

    φ_k      = Σ_i lin_i w_i + Σ_p k_p w_{i_p} × w_{j_p}                the algorithm's table
                                                                       (coning.bilinear_form)
    ρ_k, h_k = Σ new increments, Σ their intervals                     mean rate ρ_k / h_k
    q_k      = normalise(q_{k−1} ⊗ exp(φ_k))                           003 eq. 1.64
    C_k      = C(q_k)                                                  reference ← body
    P_k      = P_{k−1} + C_k Q_k C_kᵀ   (Q_k = σ_w² h_k I: P_k = P_{k−1} + σ_w² h_k I)
    J_k      = J_{k−1} + C_k ∂ρ_k/∂x,   ∂ρ_k/∂x = Σ_l u_l E_l, u = [ρ_k, h_k]
                                        (E: covariance.constant_jacobian_basis, sparse)
    cov_k    = C_kᵀ (P_k + J_k diag(var) J_kᵀ) C_k                     body axes, symmetric

The time spent per block outside the loop is a few array allocations, so a node's short
blocks (10 increments at 1 kHz) cost little more than their arithmetic.  No ROS imports.
"""
from __future__ import annotations

import math
import os

import numpy as np

from strapdown_ros.sensors.covariance import constant_jacobian_basis

__all__ = ['available', 'block_update', 'warm_up', 'kernels_allowed', 'njit_optional',
           'jitable_optional']

ENV = 'STRAPDOWN_KERNEL'


def _block_py(q0, seq, dt, n_new, hist, lin, pairs, p_ref0, j0, var, rw2, use_iso, q_white,
              use_const, basis, with_cov):
    m = dt.shape[0] // n_new
    width = hist + n_new
    q_out = np.empty((m, 4))
    cov = np.empty((m, 3, 3))
    phi = np.empty((m, 3))
    rate = np.empty((m, 3))
    h = np.empty(m)
    w, x, y, z = q0[0], q0[1], q0[2], q0[3]
    P = p_ref0.copy()
    J = j0.copy()
    C = np.empty((3, 3))
    T = np.empty((3, 3))
    U = np.empty((3, 3))
    u = np.empty(4)
    use_var = False                                     # any constant with a prior variance
    for c in range(12):
        if var[c] != 0.0:
            use_var = True
    for k in range(m):
        b = k * n_new
        # the coning term from the algorithm's table
        f0 = f1 = f2 = 0.0
        for i in range(width):
            c = lin[i]
            if c != 0.0:
                f0 += c * seq[b + i, 0]
                f1 += c * seq[b + i, 1]
                f2 += c * seq[b + i, 2]
        for p in range(pairs.shape[0]):
            i, j, c = b + int(pairs[p, 0]), b + int(pairs[p, 1]), pairs[p, 2]
            a0, a1, a2 = seq[i, 0], seq[i, 1], seq[i, 2]
            c0, c1, c2 = seq[j, 0], seq[j, 1], seq[j, 2]
            f0 += c * (a1 * c2 - a2 * c1)
            f1 += c * (a2 * c0 - a0 * c2)
            f2 += c * (a0 * c1 - a1 * c0)
        phi[k, 0], phi[k, 1], phi[k, 2] = f0, f1, f2
        r0 = r1 = r2 = hk = 0.0
        for i in range(n_new):
            r0 += seq[b + hist + i, 0]
            r1 += seq[b + hist + i, 1]
            r2 += seq[b + hist + i, 2]
            hk += dt[b + i]
        h[k] = hk
        rate[k, 0], rate[k, 1], rate[k, 2] = r0 / hk, r1 / hk, r2 / hk
        # attitude
        a = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
        s = math.sin(0.5 * a) / a if a > 1e-8 else 0.5 - a * a / 48.0
        dw, dx, dy, dz = math.cos(0.5 * a), f0 * s, f1 * s, f2 * s
        w, x, y, z = (w * dw - x * dx - y * dy - z * dz, w * dx + x * dw + y * dz - z * dy,
                      w * dy - x * dz + y * dw + z * dx, w * dz + x * dy - y * dx + z * dw)
        r = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w * r, x * r, y * r, z * r
        q_out[k, 0], q_out[k, 1], q_out[k, 2], q_out[k, 3] = w, x, y, z
        if not with_cov:                                # attitude only: the covariance is NaN
            for i in range(3):
                for j in range(3):
                    cov[k, i, j] = math.nan
            continue
        C[0, 0] = 1 - 2 * (y * y + z * z)
        C[0, 1] = 2 * (x * y - w * z)
        C[0, 2] = 2 * (x * z + w * y)
        C[1, 0] = 2 * (x * y + w * z)
        C[1, 1] = 1 - 2 * (x * x + z * z)
        C[1, 2] = 2 * (y * z - w * x)
        C[2, 0] = 2 * (x * z - w * y)
        C[2, 1] = 2 * (y * z + w * x)
        C[2, 2] = 1 - 2 * (x * x + y * y)
        # white part
        if use_iso:
            qk = rw2 * hk
            for i in range(3):
                P[i, i] += qk
        else:
            for i in range(3):
                for j in range(3):
                    acc = 0.0
                    for v in range(3):
                        acc += q_white[k, i, v] * C[j, v]
                    U[i, j] = acc                       # U = Q Cᵀ
            for i in range(3):
                for j in range(3):
                    acc = 0.0
                    for v in range(3):
                        acc += C[i, v] * U[v, j]
                    P[i, j] += acc
        # random constants: J += C Σ_l u_l E_l, E sparse (l, row, column, value)
        if use_const:
            u[0], u[1], u[2], u[3] = r0, r1, r2, hk
            for e in range(basis.shape[0]):
                f = basis[e, 3] * u[int(basis[e, 0])]
                rr, cc = int(basis[e, 1]), int(basis[e, 2])
                J[0, cc] += C[0, rr] * f
                J[1, cc] += C[1, rr] * f
                J[2, cc] += C[2, rr] * f
        # T = P + J diag(var) Jᵀ (symmetric): one pass over the columns of J
        t00, t01, t02, t11, t12, t22 = P[0, 0], P[0, 1], P[0, 2], P[1, 1], P[1, 2], P[2, 2]
        for c in range(12 if use_var else 0):
            j0c, j1c, j2c = J[0, c], J[1, c], J[2, c]
            v0 = var[c] * j0c
            v1 = var[c] * j1c
            t00 += v0 * j0c
            t01 += v0 * j1c
            t02 += v0 * j2c
            t11 += v1 * j1c
            t12 += v1 * j2c
            t22 += var[c] * j2c * j2c
        T[0, 0], T[0, 1], T[0, 2], T[1, 1], T[1, 2], T[2, 2] = t00, t01, t02, t11, t12, t22
        T[1, 0], T[2, 0], T[2, 1] = T[0, 1], T[0, 2], T[1, 2]
        # cov = Cᵀ T C, written symmetric
        for i in range(3):
            for j in range(3):
                acc = 0.0
                for v in range(3):
                    acc += T[i, v] * C[v, j]
                U[i, j] = acc                           # U = T C
        for i in range(3):
            for j in range(i, 3):
                acc = 0.0
                for v in range(3):
                    acc += C[v, i] * U[v, j]
                cov[k, i, j] = acc
                cov[k, j, i] = acc
    return q_out, cov, phi, rate, h, P, J


_compiled = None


def kernels_allowed() -> bool:
    """
    Tell whether compiled loops may be used.

    Returns
    -------
    bool
        False when ``STRAPDOWN_KERNEL=numpy`` switches every compiled loop of the package off.

    """
    return os.environ.get(ENV, 'auto').strip().lower() != 'numpy'


def njit_optional(*functions):
    """
    Compile functions with ``numba.njit(cache=True)`` when numba is there.

    The one home of the optional compilation, used by this module and the navigation loops.

    Parameters
    ----------
    *functions : callable
        Plain-Python functions numba can compile.

    Returns
    -------
    tuple of callable, or None
        The compiled functions, in order; None without numba or when it cannot compile them.

    """
    try:
        import numba
        return tuple(numba.njit(cache=True)(f) for f in functions)
    except Exception:                                    # no numba, or it cannot compile
        return None


def jitable_optional(*functions) -> bool:
    """
    Let compiled loops call plain-Python functions (numba's ``register_jitable``).

    The functions stay what they are for Python callers; a loop compiled afterwards by
    :func:`njit_optional` compiles them into itself.  (numba's cache does not see a change of
    such a function in another file: the loop's own file must change too, or its cache go.)

    Parameters
    ----------
    *functions : callable
        Plain-Python functions numba can compile.

    Returns
    -------
    bool
        True when they are registered; False without numba.

    """
    try:
        from numba.extending import register_jitable
        for f in functions:
            register_jitable(f)
        return True
    except Exception:                                    # no numba
        return False


def available() -> bool:
    """
    Tell whether the compiled block kernel is in use.

    Returns
    -------
    bool
        True when numba is importable, can compile the block and is not switched off.

    """
    global _compiled
    if not kernels_allowed():
        return False
    if _compiled is None:
        got = njit_optional(_block_py)
        _compiled = got[0] if got else False
    return _compiled is not False


def _sparse_basis() -> np.ndarray:
    """Return the nonzeros of the basis E (4, 3, 12) as rows (l, row, column, value)."""
    global _BASIS
    if _BASIS is None:
        e = constant_jacobian_basis()
        nz = np.nonzero(e)
        _BASIS = np.ascontiguousarray(np.column_stack(nz + (e[nz],)), dtype=float)
    return _BASIS


_BASIS = None
_NO_WHITE = np.zeros((1, 3, 3))


def warm_up() -> None:
    """
    Compile the kernel (or load it from numba's cache) before the first real block.

    So that a node does not stall on its first messages.
    """
    if available():
        for iso in (True, False):
            block_update(np.array([1.0, 0.0, 0.0, 0.0]), np.zeros((2, 3)), np.ones(1), 1, 1,
                         (np.array([0.0, 1.0]), np.array([[0.0, 1.0, 0.1]])),
                         np.zeros((3, 3)), np.zeros((3, 12)), np.zeros(12), 0.0 if iso else None,
                         q_white=None if iso else np.zeros((1, 3, 3)), constants=True)


def block_update(q0, seq, dt, n_new, hist, table, p_ref0, j0, var, rw2=None, q_white=None,
                 constants=False, compiled=None, covariance=True):
    """
    Run one block of attitude updates.

    Compiled when :func:`available`, else the same loop in Python (slow, for tests).  Every
    array float64, C-contiguous (another layout is still right, numba just compiles it once
    more).

    Parameters
    ----------
    q0 : (4,) ndarray
        Attitude before the block, ``q_ref_body``, scalar first.
    seq : (hist + m·n_new, 3) ndarray
        The ``hist`` previous increments, then the new ones, rad.
    dt : (m·n_new,) ndarray
        Intervals of the new increments, s.
    n_new, hist : int
        Samples and history of the coning algorithm.
    table : tuple of ndarray
        ``(lin, pairs)`` from :func:`strapdown_ros.attitude.coning.bilinear_form`.
    p_ref0 : (3, 3) ndarray
        White and initial part of the covariance, reference axes, rad².
    j0 : (3, 12) ndarray
        Jacobian of the reference-axis error on the random constants [b, vec M].
    var : (12,) ndarray
        Prior variances of the random constants.
    rw2 : float or None
        Isotropic white part: ``rw2``·h·I per update, rad²/s.
    q_white : (m, 3, 3) ndarray or None
        White part per update, body axes, when not isotropic.
    constants : bool
        Propagate J.
    compiled : bool or None
        The caller's :func:`available` (None: asked here).
    covariance : bool
        False: the attitude alone (cov NaN, P and J returned unchanged).

    Returns
    -------
    tuple
        q (m, 4), cov (m, 3, 3) body axes, φ (m, 3), mean rate (m, 3), h (m,), and the final
        P (3, 3) and J (3, 12).

    """
    use_iso = q_white is None
    fn = _compiled if (available() if compiled is None else compiled) else _block_py
    return fn(q0, seq, dt, n_new, hist, table[0], table[1], p_ref0, j0, var,
              0.0 if rw2 is None else rw2, use_iso, _NO_WHITE if use_iso else q_white, constants,
              _sparse_basis(), bool(covariance))
