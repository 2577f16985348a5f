"""
Steady-state (constant-gain) Kalman filter of a stationary linear system, numpy only.

001 (Vavilov 1982) §4.1 proposes a *stationary asymptotic filter* for the ship case (4.6).
Here it is the steady-state Kalman filter of the sampled system

    y_{k+1} = Φ y_k + w_k,   w_k ~ N(0, Q),      σ_k = H y_k + r_k,   r_k ~ N(0, R),

with Φ = e^{A h} and Q = ∫₀ʰ e^{As} Q_c e^{Aᵀs} ds (Van Loan), gain K from the discrete
algebraic Riccati equation.  Because the gain is constant from the first sample on, the filter is
not optimal during the transient; its *actual* error covariance is propagated exactly by the Joseph
recursion (:func:`constant_gain_covariance`), which is the covariance a Monte Carlo must match. No
ROS imports.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.estimation.observability import expm, observability_matrix

__all__ = ['discretize', 'steady_state_gain', 'constant_gain_covariance',
           'simulate_constant_gain', 'pole_placement_gain']


def discretize(A: np.ndarray, Qc: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return Φ = e^{Ah} and the exact process-noise covariance Q of white noise of intensity Qc.

    Parameters
    ----------
    A : ndarray (n, n)
        Continuous system matrix.
    Qc : ndarray (n, n)
        Intensity of the white process noise.
    h : float
        Sampling interval.

    Returns
    -------
    Phi : ndarray (n, n)
        Transition over h.
    Q : ndarray (n, n)
        Process noise over h (Van Loan).

    """
    n = A.shape[0]
    m = np.zeros((2 * n, 2 * n))
    m[:n, :n] = -A
    m[:n, n:] = Qc
    m[n:, n:] = A.T
    e = expm(m * h)
    Phi = e[n:, n:].T
    Q = Phi @ e[:n, n:]
    return Phi, 0.5 * (Q + Q.T)


def steady_state_gain(Phi, H, Q, R, tol: float = 1e-14, max_iter: int = 200):
    """
    Solve the filter's discrete algebraic Riccati equation for its steady state.

        P = Φ P Φᵀ − Φ P Hᵀ (H P Hᵀ + R)⁻¹ H P Φᵀ + Q = Φ P (I + HᵀR⁻¹H P)⁻¹ Φᵀ + Q,

    solved by the structure-preserving doubling algorithm (Chu, Fan, Lin 2005) with
    A₀ = Φᵀ, G₀ = HᵀR⁻¹H, H₀ = Q; H_k → P quadratically (each step doubles the horizon).

    Parameters
    ----------
    Phi : ndarray (n, n)
        Transition.
    H : ndarray (m, n)
        Measurement rows.
    Q : ndarray (n, n)
        Process noise.
    R : ndarray (m, m)
        Measurement noise.
    tol : float
        Relative change of P that ends the iteration.
    max_iter : int
        Most doubling steps.

    Returns
    -------
    P : ndarray (n, n)
        Steady-state prior covariance.
    K : ndarray (n, m)
        Gain.
    P_post : ndarray (n, n)
        Posterior covariance.

    Raises
    ------
    RuntimeError
        The iteration did not converge.

    """
    H = np.atleast_2d(H)
    R = np.atleast_2d(R)
    n = Phi.shape[0]
    A = Phi.T.copy()
    G = H.T @ np.linalg.solve(R, H)
    X = Q.copy()
    eye = np.eye(n)
    for _ in range(max_iter):
        W = np.linalg.inv(eye + G @ X)
        A_new = A @ W @ A
        G = G + A @ W @ G @ A.T
        X_new = X + A.T @ X @ W @ A
        X_new = 0.5 * (X_new + X_new.T)
        G = 0.5 * (G + G.T)
        done = np.linalg.norm(X_new - X) <= tol * np.linalg.norm(X_new)
        A, X = A_new, X_new
        if done:
            break
    else:
        raise RuntimeError('doubling iteration for the Riccati equation did not converge')
    S = H @ X @ H.T + R
    K = X @ H.T @ np.linalg.inv(S)
    return X, K, (eye - K @ H) @ X


def constant_gain_covariance(Phi, H, Q, R, K, P0, steps: int) -> np.ndarray:
    """
    Return the exact posterior error covariances of the filter with constant gain K.

    e⁺_k = (I − KH)(Φ e⁺_{k−1} + w) − K r, so
    P_k = (I−KH)(ΦP_{k−1}Φᵀ + Q)(I−KH)ᵀ + K R Kᵀ (Joseph).

    Parameters
    ----------
    Phi, H, Q, R : ndarray
        The sampled system (as :func:`steady_state_gain`).
    K : ndarray (n, m)
        The gain.
    P0 : ndarray (n, n)
        Initial error covariance.
    steps : int
        Samples.

    Returns
    -------
    ndarray (steps+1, n, n)
        P_0 … P_steps.

    """
    H = np.atleast_2d(H)
    L = np.eye(len(P0)) - K @ H
    out = np.empty((steps + 1,) + P0.shape)
    out[0] = P0
    P = P0
    for k in range(steps):
        P = L @ (Phi @ P @ Phi.T + Q) @ L.T + K @ np.atleast_2d(R) @ K.T
        out[k + 1] = P
    return out


def simulate_constant_gain(Phi, H, Q, R, K, P0, steps: int, runs: int,
                           rng: np.random.Generator):
    """
    Simulate the constant-gain filter by Monte Carlo, all runs vectorised.

    Each run draws y0 ~ N(0, P0) (the estimate starts at 0), process and measurement noise.

    Parameters
    ----------
    Phi, H, Q, R : ndarray
        The sampled system (scalar measurement).
    K : ndarray (n, 1)
        The gain.
    P0 : ndarray (n, n)
        Initial error covariance.
    steps : int
        Samples.
    runs : int
        Monte Carlo runs.
    rng : numpy.random.Generator
        Source of the draws.

    Returns
    -------
    ndarray (runs, steps+1, n)
        The errors, estimate minus truth.

    """
    H = np.atleast_2d(H)
    n = Phi.shape[0]
    cq = np.linalg.cholesky(Q + 1e-300 * np.eye(n)) if np.any(Q) else np.zeros((n, n))
    cp = np.linalg.cholesky(P0)
    rr = np.sqrt(np.atleast_2d(R)[0, 0])
    y = rng.standard_normal((runs, n)) @ cp.T
    est = np.zeros((runs, n))
    err = np.empty((runs, steps + 1, n))
    err[:, 0] = est - y
    for k in range(steps):
        y = y @ Phi.T + rng.standard_normal((runs, n)) @ cq.T
        meas = y @ H.T + rr * rng.standard_normal((runs, 1))
        pred = est @ Phi.T
        est = pred + (meas - pred @ H.T) @ K.T
        err[:, k + 1] = est - y
    return err


def pole_placement_gain(A: np.ndarray, H: np.ndarray, poles) -> np.ndarray:
    """
    Return the gain L of the asymptotic observer ŷ' = Aŷ + L(σ − Hŷ) with given poles.

    The eigenvalues of A − LH are ``poles``.  Ackermann's formula for a single output:
    L = p(A) O⁻¹ eₙ, p the desired characteristic polynomial, O the observability matrix.  This
    is the "stationary asymptotic filter" of 001 §4.1 (its ref. [5]); since O⁻¹ carries 1/m for
    a variable of measure m, the gains of weakly observable variables grow like 1/m — 001's
    remark that they are ∝ 1/(μ sin φ).

    Parameters
    ----------
    A : ndarray (n, n)
        System matrix.
    H : ndarray (1, n)
        Measurement row.
    poles : sequence of complex
        The desired eigenvalues.

    Returns
    -------
    ndarray (n,)
        L.

    """
    A = np.asarray(A, float)
    n = A.shape[0]
    coeffs = np.real(np.poly(np.asarray(poles)))          # p(s) = s^n + a1 s^(n-1) + ... + an
    pA = np.zeros_like(A)
    for a in coeffs:
        pA = pA @ A + a * np.eye(n)
    obs = observability_matrix(A, H)
    e_n = np.zeros(n)
    e_n[-1] = 1.0
    return pA @ np.linalg.solve(obs, e_n)
