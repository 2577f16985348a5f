"""
The attitude filter's per-fix numerics as compiled loops (optional, with numba).

:class:`~strapdown_ros.estimation.attitude_filter.AttitudeFilter` spends a fix cycle on small
arrays (the error state has 6 to a few tens of components), where numpy's call overhead, not
the arithmetic, is the cost.  With numba (the ``bench`` extra brings it; compiled by the
package's one optional compiler :func:`~strapdown_ros.attitude.kernel.njit_optional`) three
calls do the numerics of a cycle; without it, or with ``STRAPDOWN_KERNEL=numpy``
(:func:`~strapdown_ros.attitude.kernel.kernels_allowed`), the filter runs its vectorised numpy
path.  Both compute the same mathematics in the same order of accumulation, equal to round-off
(the tests run both on the same fixes and compare them).  The equations are those of
:mod:`.error_model` and doc/attitude_filter.md (Propagation; Blocks, running sums, outputs;
Update); general in the number q of gyro states and the size n of the error state.

:func:`push_block` — the running sums of a block (:class:`~.error_model.BlockSums`) over m
updates, with ``A_j = C_j J_j`` (``h_j C_j`` for the bias alone), u_j the middle of update j
from the block's start, ``e_j = e^{−λu_j}``, ``w_j = s h_j``::

    E_k = E_{k−1} + A_k e_k,   D_k = e^{λu_k} E_k − ½A_k,   α_k = α_{k−1} + w_k e^{2λu_k},
    β_k = β_{k−1} + D_k diag(w_k e^{λu_k}),   Γ_k = Γ_{k−1} + D_k diag(w_k) D_kᵀ,
    Λ_k = Λ_{k−1} + A_k diag(w_k) A_kᵀ / 12,

then, at K marks (the sums after some update, optionally with one lumped update more), the
transition from the block's start (:meth:`~.error_model.BlockSums.transition`)::

    Φ_εε = C_kᵀC_0,  Φ_εc = −C_kᵀE_k,  Φ_cc = diag(e^{−λT_k}),
    Q_ee = σ_v²T_k I + C_kᵀ(E_k diag(α_k)E_kᵀ − E_kβ_kᵀ − β_kE_kᵀ + Γ_k + Λ_k)C_k,
    Q_ec = −C_kᵀ(E_k diag(α_k) − β_k) diag(e^{−λT_k}),  Q_cc = diag(α_k e^{−2λT_k}),

and the covariance reported there, ``P = ½(F Fᵀ + (F Fᵀ)ᵀ) + [Q 0; 0 0]`` with F the factor S
whose first 3 + q rows are propagated by Φ.

:func:`commit_block` — the block committed to the square-root factor: ``P ← ΦPΦᵀ + Q`` as the
QR factorisation of ``[ΦS, Q^½]ᵀ`` (Q^½ = V diag(√λ₊) from the eigen-decomposition of Q,
:func:`~.filter_support.psd_factor`; S ← Rᵀ, :func:`~.filter_support.triangular_factor`).

:func:`fix_update` — the measurement update: ``P = ½(SSᵀ + (SSᵀ)ᵀ)``, ``S_z = ½(HPHᵀ + R +
(…)ᵀ)``, ``S_z⁻¹[z, HP]`` in one solve, ``NIS = zᵀS_z⁻¹z``, ``K = PHᵀS_z⁻¹``, ``δx = Kz`` and
the Joseph form ``P ← (I − KH)P(I − KH)ᵀ + KRKᵀ`` as the QR factorisation of
``[(I − KH)S, K R^½]ᵀ`` (R^½ the Cholesky factor).

Each kernel is compiled (or loaded from numba's cache) at its first use.  No ROS imports.
"""
from __future__ import annotations

import math

import numpy as np

from strapdown_ros.attitude.kernel import kernels_allowed, njit_optional

__all__ = ['available', 'push_block', 'commit_block', 'fix_update']


def _transition_py(c0, c, T, E, alpha, beta, gamma, tw, lam, markov, noisy, sigma_v, phi, Q):
    """Fill Φ and Q (3 + q square) of one set of sums (``BlockSums.transition``)."""
    q = E.shape[1]
    k = 3 + q
    for i in range(k):
        for j in range(k):
            phi[i, j] = 0.0
            Q[i, j] = 0.0
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for v in range(3):
                acc += c[v, i] * c0[v, j]
            phi[i, j] = acc                                 # C_kᵀ C_0
        for j in range(q):
            acc = 0.0
            for v in range(3):
                acc += c[v, i] * E[v, j]
            phi[i, 3 + j] = -acc                            # −C_kᵀ E_k
    decay = np.ones(q)
    if markov:
        for j in range(q):
            decay[j] = math.exp(-(T * lam[j]))
    for j in range(q):
        phi[3 + j, 3 + j] = decay[j]
    white = sigma_v ** 2 * T
    Q[0, 0] = white
    Q[1, 1] = white
    Q[2, 2] = white
    if not noisy:
        return                                              # Q diagonal: symmetric as it is
    Ea = np.empty((3, q))
    for i in range(3):
        for j in range(q):
            Ea[i, j] = E[i, j] * alpha[j]
    qee = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            a = 0.0
            b = 0.0
            for v in range(q):
                a += Ea[i, v] * E[j, v]
                b += E[i, v] * beta[j, v]
            qee[i, j] = a - b                               # eb = Ea Eᵀ − E βᵀ
    ee = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            a = 0.0
            for v in range(q):
                a += Ea[i, v] * E[j, v]
            ee[i, j] = a
    full = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            full[i, j] = qee[i, j] + qee[j, i] - ee[i, j] + gamma[i, j] + tw[i, j]
    left = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            a = 0.0
            for v in range(3):
                a += c[v, i] * full[v, j]
            left[i, j] = a                                  # C_kᵀ q_ee
    for i in range(3):
        for j in range(3):
            a = 0.0
            for v in range(3):
                a += left[i, v] * c[v, j]
            Q[i, j] += a                                    # (C_kᵀ q_ee) C_k
    for i in range(3):
        for j in range(q):
            a = 0.0
            for v in range(3):
                a += c[v, i] * ((Ea[v, j] - beta[v, j]) * decay[j])
            Q[i, 3 + j] = -a
            Q[3 + j, i] = -a
    for j in range(q):
        Q[3 + j, 3 + j] = alpha[j] * decay[j] * decay[j]
    for i in range(k):
        for j in range(i + 1, k):
            a = 0.5 * (Q[i, j] + Q[j, i])
            Q[i, j] = a
            Q[j, i] = a                                     # (the diagonal: as it is)


def _dcm_py(q, C):
    """Fill C (3, 3) with the DCM of the unit quaternion q (``rotation.quat_to_dcm``)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    C[0, 0] = 1 - 2 * (y * y + z * z)
    C[0, 1] = 2 * (x * y - w * z)
    C[0, 2] = 2 * (x * z + w * y)
    C[1, 0] = 2 * (x * y + w * z)
    C[1, 1] = 1 - 2 * (x * x + z * z)
    C[1, 2] = 2 * (y * z - w * x)
    C[2, 0] = 2 * (x * z - w * y)
    C[2, 1] = 2 * (y * z + w * x)
    C[2, 2] = 1 - 2 * (x * x + y * y)


def _lumped_py(A, h, E, alpha, beta, gamma, tw, s, lam, markov, noisy, u):
    """Add one update (A = C J, length h, middle u from the block start) to the sums in place."""
    q = E.shape[1]
    grow = np.ones(q)
    if markov:
        for j in range(q):
            grow[j] = math.exp(u * lam[j])
    for i in range(3):
        for j in range(q):
            E[i, j] += A[i, j] / grow[j] if markov else A[i, j]
    if not noisy:
        return
    w = np.empty(q)
    for j in range(q):
        w[j] = s[j] * h
    D = np.empty((3, q))
    for i in range(3):
        for j in range(q):
            D[i, j] = (E[i, j] * grow[j] if markov else E[i, j]) - 0.5 * A[i, j]
    for j in range(q):
        wg = w[j] * grow[j] if markov else w[j]
        alpha[j] += wg * grow[j] if markov else w[j]
        for i in range(3):
            beta[i, j] += D[i, j] * wg
    for i in range(3):
        for j in range(3):
            a = 0.0
            b = 0.0
            for v in range(q):
                a += D[i, v] * w[v] * D[j, v]
                b += A[i, v] * w[v] * A[j, v]
            gamma[i, j] += a
            tw[i, j] += b / 12.0


def _push_py(att, J, h, bias_only, c_prev, T, E, alpha, beta, gamma, tw, s, lam, markov,
             noisy, c0, done, c_v, A_v, h_v, S, sigma_v):
    m = h.shape[0]
    q = E.shape[1]
    K = done.shape[0]
    n = S.shape[0]
    k = 3 + q
    # the sums at the marks (after done[r] updates of this push)
    cK = np.empty((K, 3, 3))
    TK = np.empty(K)
    EK = np.empty((K, 3, q))
    aK = np.empty((K, q))
    bK = np.empty((K, 3, q))
    gK = np.empty((K, 3, 3))
    wK = np.empty((K, 3, 3))
    C = np.empty((3, 3))
    c_end = c_prev.copy()
    A = np.empty((3, q))
    r = 0
    for j in range(m + 1):
        if j > 0:
            _dcm(att[j - 1], C)
            hj = h[j - 1]
            for a in range(3):
                for b in range(q):
                    if bias_only:
                        A[a, b] = C[a, b] * hj
                    else:
                        acc = 0.0
                        for v in range(3):
                            acc += C[a, v] * J[j - 1, v, b]
                        A[a, b] = acc
            T = T + hj
            _lumped(A, hj, E, alpha, beta, gamma, tw, s, lam, markov, noisy, T - 0.5 * hj)
            c_end[:, :] = C
        while r < K and done[r] == j:
            cK[r] = c_end
            TK[r] = T
            EK[r] = E
            aK[r] = alpha
            bK[r] = beta
            gK[r] = gamma
            wK[r] = tw
            r += 1
    # the reports: the transition at each mark (one lumped update more where h_v > 0)
    P = np.empty((K, n, n))
    phi = np.empty((k, k))
    Qk = np.empty((k, k))
    F = np.empty((n, n))
    for r in range(K):
        if h_v[r] > 0:
            cK[r] = c_v[r]
            _lumped(A_v[r], h_v[r], EK[r], aK[r], bK[r], gK[r], wK[r], s, lam,
                    markov, noisy, TK[r] + 0.5 * h_v[r])
            TK[r] = TK[r] + h_v[r]
        _transition(c0, cK[r], TK[r], EK[r], aK[r], bK[r], gK[r], wK[r], lam, markov, noisy,
                    sigma_v, phi, Qk)
        for a in range(k):
            for b in range(n):
                acc = 0.0
                for v in range(k):
                    acc += phi[a, v] * S[v, b]
                F[a, b] = acc
        F[k:] = S[k:]
        _symmetric_product(F, P[r])
        for a in range(k):
            for b in range(k):
                P[r, a, b] += Qk[a, b]
        for a in range(n):
            for b in range(a + 1, n):
                x = 0.5 * (P[r, a, b] + P[r, b, a])
                P[r, a, b] = x
                P[r, b, a] = x
    return T, c_end, P


def _symmetric_product_py(F, out):
    """Fill out with F Fᵀ."""
    n = F.shape[0]
    for a in range(n):
        for b in range(n):
            acc = 0.0
            for v in range(F.shape[1]):
                acc += F[a, v] * F[b, v]
            out[a, b] = acc


def _lower_factor_py(M):
    """Return Rᵀ (lower triangular) of the QR factorisation of Mᵀ (``triangular_factor``)."""
    n = M.shape[0]
    R = np.linalg.qr(np.ascontiguousarray(M.T))[1]
    L = np.zeros((n, n))
    for a in range(min(n, R.shape[0])):
        for b in range(a, n):
            L[b, a] = R[a, b]
    return L


def _commit_py(c0, c, T, E, alpha, beta, gamma, tw, lam, markov, noisy, sigma_v, S):
    n = S.shape[0]
    q = E.shape[1]
    k = 3 + q
    phi = np.empty((k, k))
    Q = np.empty((k, k))
    _transition(c0, c, T, E, alpha, beta, gamma, tw, lam, markov, noisy, sigma_v, phi, Q)
    M = np.zeros((n, n + k))                             # [ΦS, Q^½] (Q^½ zero below row k)
    for a in range(n):
        for b in range(n):
            if a < k:
                acc = 0.0
                for v in range(k):
                    acc += phi[a, v] * S[v, b]
                M[a, b] = acc
            else:
                M[a, b] = S[a, b]
    Qs = np.empty((k, k))
    for a in range(k):
        for b in range(k):
            Qs[a, b] = 0.5 * (Q[a, b] + Q[b, a])
    lam_q, V = np.linalg.eigh(Qs)
    for b in range(k):
        r = math.sqrt(lam_q[b]) if lam_q[b] > 0.0 else 0.0
        for a in range(k):
            M[a, n + b] = V[a, b] * r
    return _lower_factor(M)


def _fix_py(S, H, R, z):
    n = S.shape[0]
    P = np.empty((n, n))
    _symmetric_product(S, P)
    for a in range(n):
        for b in range(a + 1, n):
            x = 0.5 * (P[a, b] + P[b, a])
            P[a, b] = x
            P[b, a] = x
    HP = np.empty((3, n))
    for a in range(3):
        for b in range(n):
            acc = 0.0
            for v in range(n):
                acc += H[a, v] * P[v, b]
            HP[a, b] = acc
    Sz = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            acc = 0.0
            for v in range(n):
                acc += HP[a, v] * H[b, v]
            Sz[a, b] = acc + R[a, b]
    for a in range(3):
        for b in range(a + 1, 3):
            x = 0.5 * (Sz[a, b] + Sz[b, a])
            Sz[a, b] = x
            Sz[b, a] = x
    rhs = np.empty((3, n + 1))
    for a in range(3):
        rhs[a, 0] = z[a]
        for b in range(n):
            rhs[a, b + 1] = HP[a, b]
    gain = np.full((n, 3), np.nan)
    dx = np.full(n, np.nan)
    if not np.isfinite(Sz).all():                        # (numpy's solve gives NaN there)
        return np.nan, Sz, gain, dx, S.copy()
    solved = np.linalg.solve(Sz, rhs)
    nis = z[0] * solved[0, 0] + z[1] * solved[1, 0] + z[2] * solved[2, 0]
    for a in range(n):
        for b in range(3):
            gain[a, b] = solved[b, a + 1]
    for a in range(n):
        dx[a] = gain[a, 0] * z[0] + gain[a, 1] * z[1] + gain[a, 2] * z[2]
    if not (np.isfinite(gain).all() and np.isfinite(dx).all()):
        return nis, Sz, gain, dx, S.copy()                # the caller refuses the update
    L = np.linalg.cholesky(R)
    M = np.zeros((n, n + 3))                             # [(I − KH)S, K R^½]
    IKH = np.empty((n, n))
    for a in range(n):
        for b in range(n):
            kh = gain[a, 0] * H[0, b] + gain[a, 1] * H[1, b] + gain[a, 2] * H[2, b]
            IKH[a, b] = (1.0 if a == b else 0.0) - kh
    for a in range(n):
        for b in range(n):
            acc = 0.0
            for v in range(n):
                acc += IKH[a, v] * S[v, b]
            M[a, b] = acc
        for b in range(3):
            M[a, n + b] = gain[a, 0] * L[0, b] + gain[a, 1] * L[1, b] + gain[a, 2] * L[2, b]
    return nis, Sz, gain, dx, _lower_factor(M)


_transition = _transition_py
_dcm = _dcm_py
_lumped = _lumped_py
_symmetric_product = _symmetric_product_py
_lower_factor = _lower_factor_py
_push = _push_py
_commit = _commit_py
_fix = _fix_py
_compiled = None


def available() -> bool:
    """
    Tell whether the filter's compiled kernels are in use.

    Returns
    -------
    bool
        True when numba is importable, compiles them and ``STRAPDOWN_KERNEL`` allows it.

    """
    global _compiled, _transition, _dcm, _lumped, _symmetric_product, _lower_factor, \
        _push, _commit, _fix
    if not kernels_allowed():
        return False
    if _compiled is None:
        got = njit_optional(_transition_py, _dcm_py, _lumped_py, _symmetric_product_py,
                            _lower_factor_py, _push_py, _commit_py, _fix_py)
        if got:
            (_transition, _dcm, _lumped, _symmetric_product, _lower_factor, _push, _commit,
             _fix) = got
        _compiled = bool(got)
    return _compiled


def push_block(attitude, partials, h, bias_only, block, done, c_v, A_v, h_v, S, sigma_v):
    """
    Add m updates to a block's running sums and report the covariance at K marks.

    Parameters
    ----------
    attitude : ndarray (m, 4)
        Attitude ``q_ref_body`` at the end of each update.
    partials : ndarray (m, 3, q)
        The partials ``J_j`` of each update (read unless ``bias_only``).
    h : ndarray (m,)
        Update lengths, s.
    bias_only : bool
        The bias is the only gyro state: ``J_j = h_j I``.
    block : BlockSums
        The open block; its sums are advanced in place (``T``, ``c_end`` and ``m`` too).
    done : ndarray (K,) of int
        Updates of this push each mark comes after (0: before the first), non-decreasing.
    c_v, A_v, h_v : ndarray (K, 3, 3), (K, 3, q), (K,)
        One lumped update more at each mark whose ``h_v`` > 0: attitude, ``C J``, length.
    S : ndarray (n, n)
        The square-root factor of the covariance at the block's start.
    sigma_v : float
        Angle random walk, rad/√s.

    Returns
    -------
    ndarray (K, n, n)
        The covariance at each mark.

    """
    T, c_end, P = _push(attitude, partials, h, bias_only, block.c_end, block.T, block.E,
                        block.alpha, block.beta, block.gamma, block.twelfth, block.s, block.lam,
                        block.markov, block.noisy, block.c0, done, c_v, A_v, h_v, S, sigma_v)
    block.T, block.c_end = T, c_end
    block.m += len(h)
    return P


def commit_block(block, S, sigma_v):
    """
    Return the square-root factor propagated over a block: P ← ΦPΦᵀ + Q.

    Parameters
    ----------
    block : BlockSums
        The block (its sums after its last update).
    S : ndarray (n, n)
        The square-root factor at the block's start.
    sigma_v : float
        Angle random walk, rad/√s.

    Returns
    -------
    ndarray (n, n)
        The lower triangular factor at the block's end.

    """
    return _commit(block.c0, block.c_end, block.T, block.E, block.alpha, block.beta,
                   block.gamma, block.twelfth, block.lam, block.markov, block.noisy, sigma_v, S)


def fix_update(S, H, R, z):
    """
    Return the measurement update of one fix.

    Parameters
    ----------
    S : ndarray (n, n)
        Square-root factor of the covariance.
    H : ndarray (3, n)
        The fix Jacobian.
    R : ndarray (3, 3)
        The fix covariance, symmetric positive definite.
    z : ndarray (3,)
        The residual.

    Returns
    -------
    nis : float
        zᵀ S_z⁻¹ z (NaN when S_z is not finite).
    Sz : ndarray (3, 3)
        The innovation covariance.
    gain : ndarray (n, 3)
        K.
    dx : ndarray (n,)
        K z.
    factor : ndarray (n, n)
        The factor after the update in Joseph form (S itself when the gain is not finite).

    """
    nis, Sz, gain, dx, factor = _fix(S, H, R, z)
    return float(nis), Sz, gain, dx, factor
