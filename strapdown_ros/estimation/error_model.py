"""
Error-state transition of the attitude filter over a block of integrator updates.

The attitude error ε (body axes, ``C_est = C_true(I + [ε×])``) and the errors δc of the gyro
states (bias first, then the registry effects the filter carries) obey, per update j of length
h_j with attitude C_j (reference ← body) and partials J_j = ∂ρ̃/∂c,
``ε_j = ΔC_jᵀ ε_{j−1} − J_j δc_j + w_j``.  In reference axes e = C ε the recursion is a sum,
``e_m = e_0 − Σ_j A_j δc(u_j) + Σ_j C_j w_j`` with ``A_j = C_j J_j`` and u_j the middle of
update j; δc is a random walk (``dδc = dη``, density s) or first-order Gauss–Markov
(``dδc = −λ δc dt + dη``, λ = 1/τ).  ``doc/attitude_filter.md`` writes out Φ and Q.

Every term of Φ and Q is a running sum over the updates (:class:`BlockSums`): the transition
from the block's start to the end of *any* update of it costs a few 3×3 products, whatever the
block's length.  The filter keeps the sums of its open block, reads its state at any increment
stamp from them (the outputs) and commits the block to its covariance factor only at fixes and
at a stated block length; how the increments arrive (one at a time or a whole recording) does
not change a number, because the sums are accumulated in the same order either way.
"""
from __future__ import annotations

import numpy as np

__all__ = ['block_transition', 'BlockSums']


class BlockSums:
    """
    The running sums of one block of updates, from which Φ and Q follow at any update's end.

    With a_j = A_j, e_j = e^{−λu_j} (per gyro state), w_j = s h_j (the variance of the kick
    of update j), and

    * E_k = Σ_{j≤k} a_j e_j,  D_j = e^{λu_j} E_j − ½ a_j,
    * α_k = Σ_{j≤k} w_j e^{2λu_j},  β_k = Σ_{j≤k} D_j diag(w_j e^{λu_j}),
    * Γ_k = Σ_{j≤k} D_j diag(w_j) D_jᵀ,  Λ_k = Σ_{j≤k} a_j diag(w_j) a_jᵀ / 12,

    the kick of update i reaches the angle at the end of update k through
    ``G_i = Σ_{i<j≤k} a_j e^{−λ(u_j−u_i)} + ½a_i = e^{λu_i} E_k − D_i``, so
    ``Σ_i G_i diag(w_i) G_iᵀ = E_k diag(α_k) E_kᵀ − E_k β_kᵀ − β_k E_kᵀ + Γ_k`` and
    ``Σ_i G_i diag(w_i e^{−λ(T_k−u_i)}) = (E_k diag(α_k) − β_k) diag(e^{−λT_k})``: the block
    formulas of :func:`block_transition` at every k from sums.

    Parameters
    ----------
    c0 : ndarray (3, 3)
        Attitude C (reference ← body) at the start of the block.
    q : int
        Number of gyro states.
    density : ndarray (q,)
        White-noise density driving each gyro state (0: a random constant).
    tau : ndarray (q,)
        Correlation time of each gyro state, s (inf: a random walk or constant).

    """

    def __init__(self, c0: np.ndarray, q: int, density, tau):
        self.c0 = np.asarray(c0, dtype=float)
        self.q = int(q)
        self.s = np.asarray(density, dtype=float).reshape(self.q)
        self.lam = 1.0 / np.asarray(tau, dtype=float).reshape(self.q)        # 0 where τ = inf
        self.markov = bool(np.any(self.lam > 0))
        self.noisy = bool(np.any(self.s > 0))
        self._diagonal = np.arange(3, 3 + self.q)        # the gyro states' diagonal in Φ, Q
        self.restart(self.c0)

    def restart(self, c0: np.ndarray) -> None:
        """
        Start a new block (the same states) at attitude ``c0``.

        Parameters
        ----------
        c0 : ndarray (3, 3)
            Attitude C (reference ← body) at the start of the block.

        """
        self.c0 = np.asarray(c0, dtype=float)
        self.m = 0
        self.c_end = self.c0
        self.T = 0.0
        self.E = np.zeros((3, self.q))
        self.alpha = np.zeros(self.q)
        self.beta = np.zeros((3, self.q))
        self.gamma = np.zeros((3, 3))
        self.twelfth = np.zeros((3, 3))

    def state(self) -> tuple:
        """
        Return the sums after the last update added (for :meth:`transition`).

        Returns
        -------
        tuple
            ``(c_end, T, E, α, β, Γ, Λ)``, each with a leading axis of length 1.

        """
        return (self.c_end[None], np.array([self.T]), self.E[None], self.alpha[None],
                self.beta[None], self.gamma[None], self.twelfth[None])

    def add(self, c: np.ndarray, A: np.ndarray, h: np.ndarray, running: bool = False):
        """
        Add m updates (in order) to the sums.

        Parameters
        ----------
        c : ndarray (m, 3, 3)
            Attitude at the end of each update.
        A : ndarray (m, 3, q)
            ``C_j J_j``, reference axes.
        h : ndarray (m,)
            Update lengths, s.
        running : bool
            Also return the sums before the first update and after every update.

        Returns
        -------
        tuple or None
            With ``running``: ``(c, T, E, α, β, Γ, Λ)`` before the m updates (row 0, the
            sums :meth:`state` gave) and after each of them (rows 1…m), leading axis m + 1;
            without gyro-state noise α, β, Γ, Λ are None (zero, and never read).

        """
        m = len(h)
        if m == 0:
            return None
        h = np.asarray(h, dtype=float)
        # every running sum is a sequential accumulation that starts from the previous total
        # (row 0), so adding updates in pieces gives the same numbers as adding them at once
        T = np.cumsum(np.concatenate(([self.T], h)))
        if self.markov:
            u = T[1:] - 0.5 * h
            grow = np.exp(np.outer(u, self.lam))                       # e^{λu}, (m, q)
            weighted = A / grow[:, None, :]
        else:
            grow = None
            weighted = A
        E = np.cumsum(np.concatenate((self.E[None], weighted)), axis=0)
        out = None
        if self.noisy:
            w = self.s[None, :] * h[:, None]                             # (m, q)
            D = (E[1:] * grow[:, None, :] if self.markov else E[1:]) - 0.5 * A
            wg = w * grow if self.markov else w
            alpha = np.cumsum(np.concatenate((self.alpha[None],
                                              wg * grow if self.markov else w)), axis=0)
            beta = np.cumsum(np.concatenate((self.beta[None], D * wg[:, None, :])), axis=0)
            gamma = np.cumsum(np.concatenate((self.gamma[None],
                                              np.einsum('mic,mc,mjc->mij', D, w, D))),
                              axis=0)
            tw = np.cumsum(np.concatenate((self.twelfth[None],
                                           np.einsum('mic,mc,mjc->mij', A, w, A) / 12.0)),
                           axis=0)
            if running:
                out = (np.concatenate((self.c_end[None], c)), T, E, alpha, beta, gamma, tw)
            self.alpha, self.beta = alpha[-1], beta[-1]
            self.gamma, self.twelfth = gamma[-1], tw[-1]
        elif running:
            out = (np.concatenate((self.c_end[None], c)), T, E, None, None, None, None)
        self.m += m
        self.c_end = c[-1]
        self.T = float(T[-1])
        self.E = E[-1]
        return out

    def extended(self, sums: tuple, c_v: np.ndarray, A_v: np.ndarray, h_v: np.ndarray) -> tuple:
        """
        Return sums with one more (lumped) update after each, without changing the block.

        Parameters
        ----------
        sums : tuple
            K sets of sums (:meth:`state` or rows of :meth:`add`'s running output; α, β, Γ, Λ
            may be None without gyro-state noise).
        c_v : ndarray (K, 3, 3)
            Attitude at the end of each extra update.
        A_v : ndarray (K, 3, q)
            Its ``C J``.
        h_v : ndarray (K,)
            Its length, s (0: no extra update for that row).

        Returns
        -------
        tuple
            The K extended sums.

        """
        _, T, E, alpha, beta, gamma, tw = sums
        h_v = np.asarray(h_v, dtype=float)
        T2 = T + h_v
        if self.markov:
            grow = np.exp(np.outer(T + 0.5 * h_v, self.lam))
            E2 = E + A_v / grow[:, None, :]
        else:
            grow = None
            E2 = E + A_v
        if self.noisy:
            w = self.s[None, :] * h_v[:, None]
            D = (E2 * grow[:, None, :] if self.markov else E2) - 0.5 * A_v
            wg = w * grow if self.markov else w
            alpha = alpha + (wg * grow if self.markov else w)
            beta = beta + D * wg[:, None, :]
            gamma = gamma + np.einsum('mic,mc,mjc->mij', D, w, D)
            tw = tw + np.einsum('mic,mc,mjc->mij', A_v, w, A_v) / 12.0
        return (c_v, T2, E2, alpha, beta, gamma, tw)

    def transition(self, sums: tuple, sigma_v: float):
        """
        Return Φ, Q and the decay of [ε, δc] from the block's start to the end of each set of sums.

        Parameters
        ----------
        sums : tuple
            K sets of sums (leading axis K; α, β, Γ, Λ are read only with gyro-state noise).
        sigma_v : float
            Angle random walk, rad/√s.

        Returns
        -------
        phi : ndarray (K, 3 + q, 3 + q)
            Transitions (body axes at the block's start and at each end).
        Q : ndarray (K, 3 + q, 3 + q)
            Process noise accumulated.
        decay : ndarray (K, q)
            ``e^{−T/τ}`` over each length T (1 for random walks and constants).

        """
        c, T, E, alpha, beta, gamma, tw = sums
        K, q = len(T), self.q
        ce = np.swapaxes(c, -1, -2)                                      # (K, 3, 3): body ← ref
        phi = np.zeros((K, 3 + q, 3 + q))
        phi[:, :3, :3] = ce @ self.c0
        phi[:, :3, 3:] = -(ce @ E)
        decay = np.exp(-np.outer(T, self.lam)) if self.markov else np.ones((K, q))
        idx = self._diagonal
        phi[:, idx, idx] = decay
        Q = np.zeros((K, 3 + q, 3 + q))
        Q[:, 0, 0] = Q[:, 1, 1] = Q[:, 2, 2] = sigma_v ** 2 * T
        if self.noisy:
            Ea = E * alpha[:, None, :]
            eb = Ea @ np.swapaxes(E, -1, -2) - E @ np.swapaxes(beta, -1, -2)
            q_ee = eb + np.swapaxes(eb, -1, -2) - Ea @ np.swapaxes(E, -1, -2) + gamma + tw
            Q[:, :3, :3] += ce @ q_ee @ c
            q_ec = -(ce @ ((Ea - beta) * decay[:, None, :]))
            Q[:, :3, 3:] = q_ec
            Q[:, 3:, :3] = np.swapaxes(q_ec, -1, -2)
            Q[:, idx, idx] = alpha * decay * decay
            Q = 0.5 * (Q + np.swapaxes(Q, -1, -2))
        # (without the gyro noise Q is diagonal: symmetric as it is)
        return phi, Q, decay


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
    sums = BlockSums(c0, A.shape[2], density, tau)
    sums.add(np.asarray(c, dtype=float), np.asarray(A, dtype=float), np.asarray(h, dtype=float))
    phi, Q, decay = sums.transition(sums.state(), sigma_v)
    return phi[0], Q[0], decay[0]
