"""Summary statistics shared by the benchmark commands: medians with their min–max over runs,
χ² bands, and the posterior Cramér–Rao bounds of a linear-Gaussian model (filter_bench)."""
from __future__ import annotations

import math
import statistics

import numpy as np

__all__ = ["stats", "median_range", "chi2_band", "pcrb_filter_smoother"]


def stats(values) -> dict:
    """Median, min, max and count of the finite values (None and NaN are left out)."""
    v = [x for x in values if x is not None and math.isfinite(x)]
    if not v:
        return {"median": math.nan, "min": math.nan, "max": math.nan, "n": 0}
    return {"median": statistics.median(v), "min": min(v), "max": max(v), "n": len(v)}


def median_range(s: dict, fmt: str) -> str:
    """``median (min–max)`` of a :func:`stats` result, formatted with ``fmt``."""
    if s["n"] == 0:
        return "not measured"
    return f"{format(s['median'], fmt)} ({format(s['min'], fmt)}–{format(s['max'], fmt)})"


def chi2_band(dof: int, probability: float = 0.95) -> tuple[float, float]:
    """Two-sided band of a χ² variable with ``dof`` degrees of freedom (Wilson–Hilferty; for
    dof ≥ 30 within 0.1 % of the exact quantiles).

    Parameters
    ----------
    dof : int
        Degrees of freedom (a sum of dof squared unit normals).
    probability : float
        Probability inside the band (0.95: the 2.5 % and 97.5 % quantiles).

    Returns
    -------
    (float, float)
        Lower and upper quantile.
    """
    z = statistics.NormalDist().inv_cdf(0.5 + 0.5 * probability)
    c = 2.0 / (9.0 * dof)
    return (dof * (1.0 - c - z * math.sqrt(c)) ** 3, dof * (1.0 - c + z * math.sqrt(c)) ** 3)


def pcrb_filter_smoother(phi, q, p0, h, r, fixes: int):
    """Posterior Cramér–Rao bounds of a linear-Gaussian state-space model measured at each step.

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
