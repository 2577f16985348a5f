"""
Summary statistics shared by the benchmark commands.

Medians with their min–max over runs and χ² bands; for ``filter_bench`` the posterior
Cramér–Rao bounds of a linear-Gaussian model, the multiplicative RTS smoother and the exact
gyro-error sampler.
"""
from __future__ import annotations

import math
import statistics

import numpy as np

from strapdown_ros.rotation import quat_conjugate, quat_multiply, quat_to_rotvec, rotvec_to_quat

__all__ = ['stats', 'median_range', 'pcrb_filter_smoother',
           'simulate_increments', 'rts_smooth']


def stats(values) -> dict:
    """
    Return the median, min, max and count of the finite values (None and NaN are left out).

    Parameters
    ----------
    values : iterable of float or None
        The values of the runs.

    Returns
    -------
    dict
        ``median``, ``min``, ``max`` (NaN when none is finite) and ``n``.

    """
    v = [x for x in values if x is not None and math.isfinite(x)]
    if not v:
        return {'median': math.nan, 'min': math.nan, 'max': math.nan, 'n': 0}
    return {'median': statistics.median(v), 'min': min(v), 'max': max(v), 'n': len(v)}


def median_range(s: dict, fmt: str) -> str:
    """
    Format a :func:`stats` result as ``median (min–max)``.

    Parameters
    ----------
    s : dict
        Result of :func:`stats`.
    fmt : str
        Format specification of each number, e.g. ``'.3f'``.

    Returns
    -------
    str
        The text, or 'not measured' when there is no value.

    """
    if s['n'] == 0:
        return 'not measured'
    return f"{format(s['median'], fmt)} ({format(s['min'], fmt)}–{format(s['max'], fmt)})"


def pcrb_filter_smoother(phi, q, p0, h, r, fixes: int):
    """
    Return the posterior Cramér–Rao bounds of a linear-Gaussian model measured at each step.

    For ``x_k = Φ x_{k−1} + w``, ``y_k = H x_k + v`` with x_0 ~ N(0, P0), the PCRB of the causal
    estimate of x_k from y_1..y_k is the Kalman filter's covariance, and that of the estimate
    from y_1..y_N the Rauch–Tung–Striebel smoother's (Tichavský, Muravchik & Nehorai 1998: the
    Fisher-information recursion reduces to the Riccati equation for linear-Gaussian models).

    Parameters
    ----------
    phi, q : ndarray (n, n)
        Transition and process noise of one step.
    p0 : ndarray (n, n)
        Prior covariance at step 0.
    h : ndarray (m, n)
        Measurement matrix.
    r : ndarray (m, m)
        Measurement noise covariance.
    fixes : int
        Number N of measured steps.

    Returns
    -------
    filtered, smoothed, predicted : list of ndarray (n, n)
        Bounds after each measurement (causal, fixed-interval) and before it.

    """
    post, pre, P = [], [], p0
    for _ in range(fixes):
        M = phi @ P @ phi.T + q
        K = np.linalg.solve(h @ M @ h.T + r, h @ M).T
        IKH = np.eye(len(M)) - K @ h
        P = IKH @ M @ IKH.T + K @ r @ K.T
        pre.append(M)
        post.append(0.5 * (P + P.T))
    smooth = [None] * fixes
    smooth[-1] = post[-1]
    for k in range(fixes - 2, -1, -1):
        G = np.linalg.solve(pre[k + 1], phi @ post[k]).T
        S = post[k] + G @ (smooth[k + 1] - pre[k + 1]) @ G.T
        smooth[k] = 0.5 * (S + S.T)
    return post, smooth, pre


def simulate_increments(rng, T, n, sigma_v, sigma_u, b0):
    """
    Draw gyro increment errors and the true bias from the exact law of a random-walk bias.

    The errors are ∫b dt over each interval plus white angle noise σ_v²T, and b at its end;
    b is a Wiener process of density σ_u² from b0, sampled from the exact joint law of
    (b(t+T) − b(t), ∫(t+T−s) db(s)) (as ``test/estimation/test_attitude_filter.py``).

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the draws.
    T : float
        Increment interval, s.
    n : int
        Number of increments.
    sigma_v : float
        Angle random walk, rad/√s.
    sigma_u : float
        Bias random walk, rad/s/√s.
    b0 : ndarray (3,)
        Bias at the start, rad/s.

    Returns
    -------
    errors : ndarray (n, 3)
        Gyro increment errors (add the exact increments of the motion), rad.
    bias : ndarray (n, 3)
        True bias at the end of each interval, rad/s.

    """
    cov = sigma_u ** 2 * np.array([[T, T * T / 2.0], [T * T / 2.0, T ** 3 / 3.0]])
    L = np.linalg.cholesky(cov) if sigma_u > 0 else np.zeros((2, 2))
    u = np.einsum('ij,njk->nik', L, rng.normal(size=(n, 2, 3)))
    b_end = b0 + np.cumsum(u[:, 0], axis=0)
    b_start = np.vstack([b0[None], b_end[:-1]])
    return T * b_start + u[:, 1] + rng.normal(0.0, sigma_v * np.sqrt(T), (n, 3)), b_end


def rts_smooth(pre, post, P_pre, P_post, Phi):
    """
    Smooth the filter's output at the fixes with the multiplicative RTS smoother.

    With ``G_k = P⁺_k Φᵀ (P⁻_{k+1})⁻¹`` and Δ the error state "estimate minus smoothed":
    ``Δ_k = G_k Δ⁻_{k+1}``, ``q^s_k = q̂⁺_k ⊗ exp(−Δ_ε)``, ``b^s_k = b̂⁺_k − Δ_b``.

    Parameters
    ----------
    pre, post : list of (q (4,), b (3,))
        The filter's estimates before and after each update.
    P_pre, P_post : list of ndarray (6, 6)
        Its covariances there.
    Phi : ndarray (6, 6)
        Error-state transition between fixes.

    Returns
    -------
    list of (q, b)
        Smoothed attitude and bias at each fix.

    """
    out = [None] * len(post)
    out[-1] = post[-1]
    for k in range(len(post) - 2, -1, -1):
        q_s, b_s = out[k + 1]
        d_next = np.concatenate([
            quat_to_rotvec(quat_multiply(quat_conjugate(q_s), pre[k + 1][0])), pre[k + 1][1] - b_s
        ])
        G = np.linalg.solve(P_pre[k + 1], Phi @ P_post[k]).T
        d = G @ d_next
        out[k] = (quat_multiply(post[k][0], rotvec_to_quat(-d[:3])), post[k][1] - d[3:])
    return out
