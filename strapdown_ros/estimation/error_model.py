"""
Error-state transition of the attitude filter over a block of integrator updates.

The attitude error ε (body axes, ``C_est = C_true(I + [ε×])``) and the errors δc of the gyro
states (bias first, then the registry effects the filter carries) obey, per update j of length
h_j with attitude C_j (reference ← body) and partials J_j = ∂ρ̃/∂c,
``ε_j = ΔC_jᵀ ε_{j−1} − J_j δc_j + w_j``.  In reference axes e = C ε the recursion is a sum,
``e_m = e_0 − Σ_j A_j δc(u_j) + Σ_j C_j w_j`` with ``A_j = C_j J_j`` and u_j the middle of
update j; δc is a random walk (``dδc = dη``, density s) or first-order Gauss–Markov
(``dδc = −λ δc dt + dη``, λ = 1/τ).  ``doc/attitude_filter.md`` writes out Φ and Q.
"""
from __future__ import annotations

import numpy as np

__all__ = ['block_transition']


def block_transition(c0: np.ndarray, c: np.ndarray, A: np.ndarray, h: np.ndarray,
                     sigma_v: float, density: np.ndarray, tau: np.ndarray):
    """
    Return the transition and process noise of [ε, δc] over m integrator updates.

    Parameters
    ----------
    c0 : ndarray (3, 3)
        Attitude C (reference ← body) at the start of the block.
    c : ndarray (m, 3, 3)
        Attitude at the end of each update.
    A : ndarray (m, 3, q)
        ``C_j J_j``: the partials of the update increments with respect to the q gyro states,
        in reference axes.
    h : ndarray (m,)
        Update lengths, s.
    sigma_v : float
        Angle random walk, rad/√s.
    density : ndarray (q,)
        White-noise density driving each gyro state (0: a random constant).
    tau : ndarray (q,)
        Correlation time of each gyro state, s (inf: a random walk or constant).

    Returns
    -------
    phi : ndarray (3 + q, 3 + q)
        Transition of [ε, δc] over the block (body axes at its start and end).
    Q : ndarray (3 + q, 3 + q)
        Process noise accumulated over the block.
    decay : ndarray (q,)
        ``e^{−T/τ}`` over the block length T (1 for random walks and constants).

    """
    m, _, q = A.shape
    lam = 1.0 / np.asarray(tau, dtype=float)            # 0 where τ = inf
    s = np.asarray(density, dtype=float)
    total = float(h.sum())
    u = np.cumsum(h) - 0.5 * h                           # middle of each update
    markov = bool(np.any(lam > 0))
    ce = c[-1].T
    phi = np.eye(3 + q)
    phi[:3, :3] = ce @ c0
    if markov:
        phi[:3, 3:] = -ce @ (A * np.exp(-u[:, None] * lam)[:, None, :]).sum(0)
        decay = np.exp(-total * lam)
        phi[3:, 3:] = np.diag(decay)
        to_end = np.exp(-(total - u)[:, None] * lam)    # (m, q): a kick at u_i seen at the end
    else:
        phi[:3, 3:] = -ce @ A.sum(0)
        decay = np.ones(q)
        to_end = np.ones((m, q))
    Q = np.zeros((3 + q, 3 + q))
    Q[:3, :3] = sigma_v ** 2 * total * np.eye(3)
    if np.any(s > 0):
        sh = s[None, :] * h[:, None]                     # (m, q): variance of each kick
        # G_i = Σ_{j>i} A_j e^{−λ(u_j − u_i)} + ½ A_i: the kick of update i on the angle (half
        # of its own update); with the 1/12 term below the per-step integral is exact (h³/3,
        # −h²/2)
        if markov:
            G = np.empty_like(A)
            acc = np.zeros((3, q))
            for i in range(m - 1, -1, -1):
                if i < m - 1:
                    acc = (acc + A[i + 1]) * np.exp(-(u[i + 1] - u[i]) * lam)
                G[i] = acc + 0.5 * A[i]
        else:
            G = np.cumsum(A[::-1], axis=0)[::-1] - 0.5 * A
        Q_ee = (np.einsum('mik,mk,mjk->ij', G, sh, G)
                + np.einsum('mik,mk,mjk->ij', A, sh, A) / 12.0)
        Q_ec = -np.einsum('mik,mk->ik', G, sh * to_end)
        Q[:3, :3] += ce @ Q_ee @ ce.T
        Q[:3, 3:] = ce @ Q_ec
        Q[3:, :3] = Q[:3, 3:].T
        Q[3:, 3:] = np.diag((sh * to_end ** 2).sum(0))
    return phi, Q, decay
