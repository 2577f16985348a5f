"""
The attitude filter's per-fix numerics as compiled loops (optional, with numba).

:class:`~strapdown_ros.estimation.attitude_filter.AttitudeFilter` spends a fix cycle on small
arrays (the error state has 6 to a few tens of components), where numpy's call overhead, not
the arithmetic, is the cost.  With numba (the ``bench`` extra brings it; compiled by the
package's one optional compiler :func:`~strapdown_ros.attitude.kernel.njit_optional`) two
calls do the numerics of a cycle; without it, or with ``STRAPDOWN_KERNEL=numpy``
(:func:`~strapdown_ros.attitude.kernel.kernels_allowed`), the filter runs its vectorised numpy
path.  Both compute the same mathematics, the running sums in the same order of accumulation,
equal to round-off (the tests run both on the same fixes and compare them; a filter's closed
loop carries the round-off of its attitude, ~1e-16 rad, into residuals of ~1e-5 rad, so a
residual agrees to 1e-15 rad, not to 1e-12 of itself).  The equations are those of
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

:func:`update` — at a fix (or a block's length), the block committed to the square-root
factor: ``P ← ΦPΦᵀ + Q`` as the QR factorisation of ``[ΦS, Q^½]ᵀ`` (Q^½ = V diag(√λ₊) of
Q's eigen-decomposition, :func:`~.filter_support.psd_factor`; S ← Rᵀ,
:func:`~.filter_support.triangular_factor`); then the measurement update: the residual
``z = log(q_fixᵀ ⊗ q ⊗ q_bv)``, ``P = SSᵀ``, ``S_z = ½(HPHᵀ + R + (…)ᵀ)``, ``S_z⁻¹[z, HP]`` in
one solve, ``NIS = zᵀS_z⁻¹z``, ``K = PHᵀS_z⁻¹``, ``δx = Kz``, the Joseph form
``P ← (I − KH)P(I − KH)ᵀ + KRKᵀ`` as the QR factorisation of ``[(I − KH)S, K R^½]ᵀ`` (R^½ the
Cholesky factor) and the resets ``q ← q ⊗ exp(−δε)``, ``q_bv ← q_bv ⊗ exp(−δη)`` (doc:
Update).

The small linear algebra is written out (a few loops each, no LAPACK call: the kernels load
from numba's cache in a few tens of ms and run cold in microseconds): Householder QR as LAPACK's
unblocked ``dgeqr2`` (β = −sign(α)‖x‖, numpy's ``qr``), Q^½ by cyclic Jacobi rotations (the QR
of ``[ΦS, B]ᵀ`` depends on B only through BBᵀ = Q), the 3×3 solve by LU with partial pivoting
(``dgesv``), R^½ by Cholesky.  Each kernel is compiled (or loaded from numba's cache) at its
first use.  No ROS imports.
"""
from __future__ import annotations

import math

import numpy as np

from strapdown_ros.attitude.kernel import kernels_allowed, njit_optional

__all__ = ['available', 'push_block', 'update']


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


def _lumped_py(A, h, E, alpha, beta, gamma, tw, s, lam, markov, noisy, u, grow, D):
    """Add one update (A = C J, length h, middle u from the block start) to the sums in place."""
    q = E.shape[1]
    for j in range(q):
        grow[j] = math.exp(u * lam[j]) if markov else 1.0
    for i in range(3):
        for j in range(q):
            E[i, j] += A[i, j] / grow[j] if markov else A[i, j]
    if not noisy:
        return
    for i in range(3):
        for j in range(q):
            D[i, j] = (E[i, j] * grow[j] if markov else E[i, j]) - 0.5 * A[i, j]
    for j in range(q):
        w = s[j] * h
        wg = w * grow[j] if markov else w
        alpha[j] += wg * grow[j] if markov else w
        for i in range(3):
            beta[i, j] += D[i, j] * wg
    for i in range(3):
        for j in range(3):
            a = 0.0
            b = 0.0
            for v in range(q):
                w = s[v] * h
                a += D[i, v] * w * D[j, v]
                b += A[i, v] * w * A[j, v]
            gamma[i, j] += a
            tw[i, j] += b / 12.0


def _keep_py(row, c, T, E, alpha, beta, gamma, tw, back):
    """Copy a set of sums into a flat row (``back``: from the row into the arrays)."""
    q = E.shape[1]
    o = 0
    for i in range(3):
        for j in range(3):
            if back:
                c[i, j], gamma[i, j], tw[i, j] = row[o], row[o + 9], row[o + 18]
            else:
                row[o], row[o + 9], row[o + 18] = c[i, j], gamma[i, j], tw[i, j]
            o += 1
    o = 27
    for i in range(3):
        for j in range(q):
            if back:
                E[i, j], beta[i, j] = row[o], row[o + 3 * q]
            else:
                row[o], row[o + 3 * q] = E[i, j], beta[i, j]
            o += 1
    o = 27 + 6 * q
    for j in range(q):
        if back:
            alpha[j] = row[o + j]
        else:
            row[o + j] = alpha[j]
    if back:
        return row[27 + 7 * q]
    row[27 + 7 * q] = T
    return T


def _push_py(att, J, h, bias_only, c_prev, T, E, alpha, beta, gamma, tw, s, lam, markov,
             noisy, c0, marks, t, p, n_new, q_before, rests, done, c_v, A_v, h_v, S, sigma_v):
    m = h.shape[0]
    q = E.shape[1]
    K = marks.shape[0]
    n = S.shape[0]
    k = 3 + q
    q_out = np.empty((K, 4))
    if not rests:                   # the updates each mark comes after; none inside an update?
        done = np.empty(K, dtype=np.int64)
        for r in range(K):
            w = p + np.searchsorted(t, marks[r])          # work index of the mark
            done[r] = (w + 1) // n_new
            if done[r] * n_new < w + 1:                  # a lumped rest: the caller's, first
                return T, c_prev, np.empty((0, n, n)), q_out, True
    for r in range(K):
        for a in range(4):
            q_out[r, a] = q_before[a] if done[r] == 0 else att[done[r] - 1, a]
    C = c_prev.copy()
    A = np.empty((3, q))
    grow = np.empty(q)
    D = np.empty((3, q))
    kept = np.empty((K, 28 + 7 * q))                     # the sums at each mark
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
            _lumped(A, hj, E, alpha, beta, gamma, tw, s, lam, markov, noisy, T - 0.5 * hj,
                    grow, D)
        while r < K and done[r] == j:                    # marks after j updates of this push
            _keep(kept[r], C, T, E, alpha, beta, gamma, tw, False)
            r += 1
    # the reports: the transition at each mark (one lumped update more where h_v > 0)
    P = np.empty((K, n, n))
    phi = np.empty((k, k))
    Qk = np.empty((k, k))
    F = np.empty((n, n))
    cr = np.empty((3, 3))
    Er = np.empty((3, q))
    ar = np.empty(q)
    br = np.empty((3, q))
    gr = np.empty((3, 3))
    wr = np.empty((3, 3))
    for r in range(K):
        Tr = _keep(kept[r], cr, 0.0, Er, ar, br, gr, wr, True)
        if rests and h_v[r] > 0:
            for a in range(3):
                for b in range(3):
                    cr[a, b] = c_v[r, a, b]
                for b in range(q):
                    A[a, b] = A_v[r, a, b]
            _lumped(A, h_v[r], Er, ar, br, gr, wr, s, lam, markov, noisy, Tr + 0.5 * h_v[r],
                    grow, D)
            Tr = Tr + h_v[r]
        _transition(c0, cr, Tr, Er, ar, br, gr, wr, lam, markov, noisy, sigma_v, phi, Qk)
        _propagated(phi, S, F)
        for a in range(n):
            for b in range(a, n):
                acc = 0.0
                for v in range(n):
                    acc += F[a, v] * F[b, v]
                if a < k and b < k:
                    acc = 0.5 * ((acc + Qk[a, b]) + (acc + Qk[b, a]))
                P[r, a, b] = acc
                P[r, b, a] = acc
    return T, C, P, q_out, False


def _propagated_py(phi, S, out):
    """Fill the first n columns of out with S whose first 3 + q rows are propagated by Φ."""
    k = phi.shape[0]
    n = S.shape[0]
    for a in range(n):
        for b in range(n):
            if a < k:
                acc = 0.0
                for v in range(k):
                    acc += phi[a, v] * S[v, b]
                out[a, b] = acc
            else:
                out[a, b] = S[a, b]


def _lower_factor_py(M):
    """
    Return L (n, n) lower triangular with L Lᵀ = M Mᵀ: Rᵀ of the QR factorisation of Mᵀ.

    Householder reflections as LAPACK's unblocked ``dgeqr2`` (``dlarfg``: β = −sign(α)‖x‖),
    numpy's ``qr`` of :func:`~.filter_support.triangular_factor`.
    """
    n, c = M.shape
    A = np.empty((c, n))
    for i in range(c):
        for j in range(n):
            A[i, j] = M[j, i]
    for j in range(n):
        alpha = A[j, j]
        xn = 0.0
        for i in range(j + 1, c):
            xn += A[i, j] * A[i, j]
        if xn == 0.0:
            continue                                      # H = I, R_jj = α
        beta = -math.copysign(math.sqrt(alpha * alpha + xn), alpha)
        tau = (beta - alpha) / beta
        scale = 1.0 / (alpha - beta)
        for i in range(j + 1, c):
            A[i, j] *= scale                             # v, with v_j = 1
        A[j, j] = beta
        for col in range(j + 1, n):
            d = A[j, col]
            for i in range(j + 1, c):
                d += A[i, j] * A[i, col]
            d *= tau
            A[j, col] -= d
            for i in range(j + 1, c):
                A[i, col] -= d * A[i, j]
    L = np.zeros((n, n))
    for a in range(n):
        for b in range(a, n):
            L[b, a] = A[a, b]
    return L


def _psd_root_py(Q, B):
    """
    Fill B with V diag(√λ₊) of a symmetric positive semi-definite Q (cyclic Jacobi).

    Eigenvalues below zero by round-off are taken as zero (:func:`~.filter_support.psd_factor`).
    """
    k = Q.shape[0]
    A = np.empty((k, k))
    V = np.zeros((k, k))
    scale = 0.0
    for a in range(k):
        V[a, a] = 1.0
        for b in range(k):
            A[a, b] = 0.5 * (Q[a, b] + Q[b, a])
            scale += A[a, b] * A[a, b]
    for sweep in range(60):
        off = 0.0
        for a in range(k):
            for b in range(a + 1, k):
                off += A[a, b] * A[a, b]
        if off <= 1e-36 * scale:                          # off-diagonal far below round-off
            break
        for a in range(k):
            for b in range(a + 1, k):
                if A[a, b] == 0.0:
                    continue
                theta = (A[b, b] - A[a, a]) / (2.0 * A[a, b])
                if abs(theta) > 1e150:
                    t = 0.5 / theta
                else:
                    t = math.copysign(1.0, theta) / (abs(theta) + math.sqrt(theta * theta + 1.0))
                cs = 1.0 / math.sqrt(t * t + 1.0)
                sn = t * cs
                for v in range(k):                         # A ← Jᵀ A J, V ← V J
                    x, y = A[v, a], A[v, b]
                    A[v, a], A[v, b] = cs * x - sn * y, sn * x + cs * y
                for v in range(k):
                    x, y = A[a, v], A[b, v]
                    A[a, v], A[b, v] = cs * x - sn * y, sn * x + cs * y
                for v in range(k):
                    x, y = V[v, a], V[v, b]
                    V[v, a], V[v, b] = cs * x - sn * y, sn * x + cs * y
                A[a, b] = 0.0                               # (zero by the choice of the angle)
                A[b, a] = 0.0
    for b in range(k):
        root = math.sqrt(A[b, b]) if A[b, b] > 0.0 else 0.0
        for a in range(k):
            B[a, b] = V[a, b] * root


def _committed_py(S, c0, c, T, E, alpha, beta, gamma, tw, lam, markov, noisy, sigma_v):
    """Return the factor S propagated over a block: the QR of ``[ΦS, Q^½]ᵀ``."""
    n = S.shape[0]
    q = E.shape[1]
    k = 3 + q
    phi = np.empty((k, k))
    Q = np.empty((k, k))
    _transition(c0, c, T, E, alpha, beta, gamma, tw, lam, markov, noisy, sigma_v, phi, Q)
    M = np.zeros((n, n + k))                             # [ΦS, Q^½] (Q^½ zero below row k)
    _propagated(phi, S, M)
    B = np.empty((k, k))
    _psd_root(Q, B)
    for a in range(k):
        for b in range(k):
            M[a, n + b] = B[a, b]
    return _lower_factor(M)


def _qmul_py(pw, px, py, pz, qw, qx, qy, qz):
    """Return p ⊗ q (``rotation.quat_multiply``)."""
    return (pw * qw - px * qx - py * qy - pz * qz, pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx, pw * qz + px * qy - py * qx + pz * qw)


def _corrected_py(q, e0, e1, e2):
    """Return normalise(q ⊗ exp(−e)) (rotation: rotvec_to_quat, quat_multiply, quat_normalize)."""
    x, y, z = -e0, -e1, -e2
    a = math.sqrt(x * x + y * y + z * z)
    u = math.pi * (a / (2.0 * math.pi)) if a else math.pi * 1e-20      # (np.sinc's argument)
    half_sinc = 0.5 * (math.sin(u) / u)
    w, x, y, z = _qmul(q[0], q[1], q[2], q[3], math.cos(0.5 * a), x * half_sinc, y * half_sinc,
                       z * half_sinc)
    r = math.sqrt(w * w + x * x + y * y + z * z)
    out = np.empty(4)
    out[0], out[1], out[2], out[3] = w / r, x / r, y / r, z / r
    return out


def _update_py(S, commit, c0, c, T, E, alpha, beta, gamma, tw, lam, markov, noisy, sigma_v,
               fix, H, R, q, bv, fq, bore):
    n = S.shape[0]
    if commit:
        S = _committed(S, c0, c, T, E, alpha, beta, gamma, tw, lam, markov, noisy, sigma_v)
    Sz = np.zeros((3, 3))
    gain = np.zeros((n, 3))
    dx = np.zeros(n)
    z = np.zeros(3)
    cn = np.empty((3, 3))
    if not fix:
        return S, 0, np.nan, z, Sz, gain, dx, S, q, bv, cn
    # z = log(q_fixᵀ ⊗ q ⊗ q_bv) (rotation.quat_to_rotvec)
    pw, px, py, pz = _qmul(q[0], q[1], q[2], q[3], bv[0], bv[1], bv[2], bv[3])
    w, x, y, e = _qmul(fq[0], -fq[1], -fq[2], -fq[3], pw, px, py, pz)
    if w < 0.0:
        w, x, y, e = -w, -x, -y, -e
    s = math.sqrt(x * x + y * y + e * e)
    if s > 1e-12:
        f = 2.0 * math.atan2(s, w) / s
    elif w > 0.0:
        f = 2.0 / w * (1.0 + s * s / (3.0 * (w * w)))
    else:
        f = np.nan
    z[0], z[1], z[2] = x * f, y * f, e * f
    P = np.empty((n, n))                                 # P = S Sᵀ (symmetric as computed)
    for a in range(n):
        for b in range(a, n):
            acc = 0.0
            for v in range(n):
                acc += S[a, v] * S[b, v]
            P[a, b] = acc
            P[b, a] = acc
    HP = np.empty((3, n))
    for a in range(3):
        for b in range(n):
            acc = 0.0
            for v in range(n):
                acc += H[a, v] * P[v, b]
            HP[a, b] = acc
    finite = True
    for a in range(3):
        for b in range(3):
            acc = 0.0
            for v in range(n):
                acc += HP[a, v] * H[b, v]
            Sz[a, b] = acc + R[a, b]
    for a in range(3):
        for b in range(a, 3):
            x = 0.5 * (Sz[a, b] + Sz[b, a])
            Sz[a, b] = x
            Sz[b, a] = x
            finite = finite and math.isfinite(x)
    if not finite:
        return S, 1, np.nan, z, Sz, gain, dx, S, q, bv, cn    # (numpy's solve: NaN)
    # S_z⁻¹ [z, HP]: LU with partial pivoting (LAPACK's dgesv)
    LU = Sz.copy()
    X = np.empty((3, n + 1))
    for a in range(3):
        X[a, 0] = z[a]
        for b in range(n):
            X[a, b + 1] = HP[a, b]
    for j in range(3):
        piv = j
        for i in range(j + 1, 3):
            if abs(LU[i, j]) > abs(LU[piv, j]):
                piv = i
        if LU[piv, j] == 0.0:
            return S, 2, np.nan, z, Sz, gain, dx, S, q, bv, cn    # singular
        if piv != j:
            for b in range(3):
                LU[j, b], LU[piv, b] = LU[piv, b], LU[j, b]
            for b in range(n + 1):
                X[j, b], X[piv, b] = X[piv, b], X[j, b]
        for i in range(j + 1, 3):
            f = LU[i, j] / LU[j, j]
            for b in range(j + 1, 3):
                LU[i, b] -= f * LU[j, b]
            for b in range(n + 1):
                X[i, b] -= f * X[j, b]
    for b in range(n + 1):
        for i in range(2, -1, -1):
            acc = X[i, b]
            for v in range(i + 1, 3):
                acc -= LU[i, v] * X[v, b]
            X[i, b] = acc / LU[i, i]
    nis = z[0] * X[0, 0] + z[1] * X[1, 0] + z[2] * X[2, 0]
    finite = True
    for a in range(n):
        for b in range(3):
            gain[a, b] = X[b, a + 1]
        dx[a] = gain[a, 0] * z[0] + gain[a, 1] * z[1] + gain[a, 2] * z[2]
        finite = finite and math.isfinite(dx[a]) and math.isfinite(gain[a, 0]) \
            and math.isfinite(gain[a, 1]) and math.isfinite(gain[a, 2])
    if not finite:
        return S, 3, nis, z, Sz, gain, dx, S, q, bv, cn   # the caller refuses the update
    L = np.zeros((3, 3))                                 # R^½: Cholesky, lower
    for a in range(3):
        for b in range(a + 1):
            acc = R[a, b]
            for v in range(b):
                acc -= L[a, v] * L[b, v]
            L[a, b] = math.sqrt(acc) if a == b else acc / L[b, b]
    M = np.empty((n, n + 3))                             # [(I − KH)S, K R^½]
    for a in range(n):
        for b in range(n):
            acc = 0.0
            for v in range(n):
                kh = gain[a, 0] * H[0, v] + gain[a, 1] * H[1, v] + gain[a, 2] * H[2, v]
                acc += ((1.0 if a == v else 0.0) - kh) * S[v, b]
            M[a, b] = acc
        for b in range(3):
            M[a, n + b] = gain[a, 0] * L[0, b] + gain[a, 1] * L[1, b] + gain[a, 2] * L[2, b]
    # the reset of the attitude (and of the boresight when it is a state)
    q_new = _corrected(q, dx[0], dx[1], dx[2])
    _dcm(q_new, cn)
    bv_new = bv if bore < 0 else _corrected(bv, dx[bore], dx[bore + 1], dx[bore + 2])
    return S, 0, nis, z, Sz, gain, dx, _lower_factor(M), q_new, bv_new, cn


_transition = _transition_py
_dcm = _dcm_py
_lumped = _lumped_py
_keep = _keep_py
_propagated = _propagated_py
_lower_factor = _lower_factor_py
_psd_root = _psd_root_py
_qmul = _qmul_py
_corrected = _corrected_py
_committed = _committed_py
_push = _push_py
_update = _update_py
_compiled = None


def available() -> bool:
    """
    Tell whether the filter's compiled kernels are in use.

    Returns
    -------
    bool
        True when numba is importable, compiles them and ``STRAPDOWN_KERNEL`` allows it.

    """
    global _compiled, _transition, _dcm, _lumped, _keep, _propagated, _lower_factor, \
        _psd_root, _qmul, _corrected, _committed, _push, _update
    if not kernels_allowed():
        return False
    if _compiled is None:
        got = njit_optional(_transition_py, _dcm_py, _lumped_py, _keep_py, _propagated_py,
                            _lower_factor_py, _psd_root_py, _qmul_py, _corrected_py,
                            _committed_py, _push_py, _update_py)
        if got:
            (_transition, _dcm, _lumped, _keep, _propagated, _lower_factor, _psd_root, _qmul,
             _corrected, _committed, _push, _update) = got
        _compiled = bool(got)
    return _compiled


def push_block(attitude, partials, h, bias_only, block, marks, t, p, n_new, q_before, S,
               sigma_v, rests=None):
    """
    Add m updates to a block's running sums and report the state at K marks.

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
    marks : ndarray (K,)
        Stamps to report at, increasing, among the push's piece stamps ``t``.
    t : ndarray (pieces,)
        The stamps of the push's pieces (after ``p`` pieces of an unfinished update).
    p : int
        Pieces of the unfinished update before the push.
    n_new : int
        Pieces per update.
    q_before : ndarray (4,)
        The attitude before the push.
    S : ndarray (n, n)
        The square-root factor of the covariance at the block's start.
    sigma_v : float
        Angle random walk, rad/√s.
    rests : tuple, optional
        ``(done, c_v, A_v, h_v)``: the updates each mark comes after and one lumped update
        more at the marks inside an update (``h_v`` > 0: attitude, ``C J``, length).

    Returns
    -------
    tuple or None
        ``(P, q)``: the covariance (K, n, n) and attitude (K, 4) at each mark; None when a mark
        is inside an update and ``rests`` is not given (nothing added then).

    """
    given = rests is not None
    done, c_v, A_v, h_v = rests if given else _NO_RESTS
    T, c_end, P, q_out, need = _push(
        attitude, partials, h, bias_only, block.c_end, block.T, block.E, block.alpha, block.beta,
        block.gamma, block.twelfth, block.s, block.lam, block.markov, block.noisy, block.c0,
        marks, t, p, n_new, q_before, given, done, np.ascontiguousarray(c_v),
        np.ascontiguousarray(A_v), h_v, S, sigma_v)
    if need:
        return None
    block.T, block.c_end = T, c_end
    block.m += len(h)
    return P, q_out


_NO_RESTS = (np.zeros(0, dtype=np.int64), np.zeros((1, 3, 3)), np.zeros((1, 3, 1)),
             np.zeros(0))


def update(S, block, sigma_v, commit, fix=None):
    """
    Commit the open block to the factor and apply a fix: one compiled call.

    Parameters
    ----------
    S : ndarray (n, n)
        The square-root factor at the block's start.
    block : BlockSums
        The open block (its sums after its last update).
    sigma_v : float
        Angle random walk, rad/√s.
    commit : bool
        Commit the block (``P ← ΦPΦᵀ + Q``) first; else S is the factor at the fix.
    fix : tuple, optional
        ``(H, R, q, q_bv, q_fix, boresight)``: the fix Jacobian (3, n), its covariance (3, 3)
        (symmetric positive definite), the attitude ``q_ref_body``, the boresight ``q_MF_VF``,
        the fix ``q_GCRS_VF`` and the index of the boresight states (−1: none).  None: the
        commit alone.

    Returns
    -------
    tuple
        ``(committed, nis, z, Sz, gain, dx, finite, factor, q, q_bv, c)``: the factor at the
        fix before it (S when not committing), zᵀS_z⁻¹z (NaN when S_z is not finite or there
        is no fix), the residual z, S_z = HPHᵀ + R, K, δx = Kz, whether K and δx are finite,
        the factor after the fix in Joseph form (``committed`` when the gain is not finite),
        the attitude and boresight reset with δx and the attitude's DCM (read when the fix is
        applied).

    Raises
    ------
    numpy.linalg.LinAlgError
        S_z is singular (as numpy's ``solve`` says).

    """
    if fix is None:
        fix = _NO_FIX
    out = _update(S, commit, block.c0, block.c_end, block.T, block.E, block.alpha, block.beta,
                  block.gamma, block.twelfth, block.lam, block.markov, block.noisy, sigma_v,
                  fix is not _NO_FIX, *fix)
    if out[1] == 2:
        raise np.linalg.LinAlgError('Singular matrix')     # (numpy's solve says so)
    return (out[0], float(out[2])) + out[3:7] + (out[1] != 3,) + out[7:]


_NO_FIX = (np.zeros((3, 1)), np.eye(3), np.array([1.0, 0.0, 0.0, 0.0]),
           np.array([1.0, 0.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0, 0.0]), -1)
