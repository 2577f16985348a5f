"""
Farrenkopf's analytic steady state of the single-axis gyro-bias attitude filter.

The model (Farrenkopf 1978; Markley & Crassidis 2014, *Fundamentals of Spacecraft Attitude
Determination and Control*, ch. 6 (the steady-state analysis of the MEKF); Crassidis & Junkins,
*Optimal Estimation of Dynamic Systems*, 2nd ed., ch. 7): one axis, angle θ, gyro output
``ω̃ = ω + b + η_v`` with white angle noise of density σ_v² (angle random walk, rad/√s) and
a bias random walk ``ḃ = η_u`` of density σ_u² (rad/s/√s); an angle measurement
``y_k = θ_k + n_k`` with white noise of variance σ_n² every Δt.  With the dimensionless

    S_v = σ_v √Δt / σ_n,       S_u = σ_u Δt^{3/2} / σ_n,

the steady-state one-step prediction (pre-update) and filtered (post-update) angle variances are

    γ = ¼ (S_u + √(16 + 4 S_v² + S_u²/3)),       ξ = γ + √(γ² − 1),
    P_θ(−) = σ_n² (ξ² − 1),       P_θ(+) = σ_n² (1 − ξ⁻²).

Derivation (``doc/attitude_filter.md`` gives it in full): the second difference of the
measurements is a moving average of order 2, ``Δ²y_k = (1 − r₁z)(1 − r₂z) ν_k``, with
autocovariances (units σ_n²) ``c₀ = 6 + 2S_v² + ⅔S_u²``, ``c₁ = −4 − S_v² + S_u²/6``,
``c₂ = 1``; the innovation variance of the steady-state filter is that of the spectral factor,
``σ_ν² = c₂ / (r₁r₂) = P_θ(−) + σ_n²``.  Writing ``r_i = e^{−λ_i}``, the factorisation gives
``4 sinh²(λ₁/2) · 4 sinh²(λ₂/2) = S_u²`` and ``4 sinh²(λ₁/2) + 4 sinh²(λ₂/2) = S_v² − S_u²/6``,
from which ``cosh((λ₁ + λ₂)/2) = γ`` and ``1/(r₁r₂) = ξ²``.  The post-update variance follows
from the scalar gain ``K = P(−) / (P(−) + σ_n²)``: ``P(+) = P(−) σ_n² / (P(−) + σ_n²)``.
:func:`riccati_steady_state` iterates the discrete Riccati equation of the same model as an
independent check (``test/estimation/test_attitude_filter.py``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.estimation.steady_filter import discretize, steady_state_gain

__all__ = ['SteadyState', 'farrenkopf_steady_state', 'riccati_steady_state', 'bias_filter_model']


@dataclass(frozen=True)
class SteadyState:
    """Steady-state 1σ of the single-axis filter, rad (attitude) and rad/s (bias)."""
    attitude_pre: float          # before a measurement update (one-step prediction)
    attitude_post: float         # after it
    bias_pre: float | None = None
    bias_post: float | None = None


def farrenkopf_steady_state(sigma_n: float, sigma_v: float, sigma_u: float,
                            dt: float) -> SteadyState:
    """
    Analytic steady-state attitude σ of the bias-only filter (Farrenkopf 1978).

    Parameters
    ----------
    sigma_n : float
        1σ of the angle measurement per axis, rad.
    sigma_v : float
        Angle random walk of the gyro, rad/√s.
    sigma_u : float
        Bias (rate) random walk of the gyro, rad/s/√s.
    dt : float
        Interval between measurements, s.

    Returns
    -------
    SteadyState
        ``attitude_pre`` and ``attitude_post`` σ, rad (the bias fields are None here).
    """
    for name, v in (('sigma_n', sigma_n), ('sigma_v', sigma_v), ('sigma_u', sigma_u)):
        if not (np.isfinite(v) and v >= 0):
            raise ValueError(f'{name} must be finite and >= 0, got {v}')
    if not (np.isfinite(dt) and dt > 0) or not sigma_n > 0:
        raise ValueError('dt and sigma_n must be > 0')
    s_v = sigma_v * np.sqrt(dt) / sigma_n
    s_u = sigma_u * dt ** 1.5 / sigma_n
    gamma = 0.25 * (s_u + np.sqrt(16.0 + 4.0 * s_v ** 2 + s_u ** 2 / 3.0))
    xi = gamma + np.sqrt(gamma ** 2 - 1.0)
    return SteadyState(attitude_pre=float(sigma_n * np.sqrt(xi ** 2 - 1.0)),
                       attitude_post=float(sigma_n * np.sqrt(1.0 - xi ** -2)))


def bias_filter_model(sigma_v: float, sigma_u: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Exact discrete model of one axis over dt: transition Φ (2, 2) and process noise Q (2, 2)
    of x = [θ error, bias error] with ``θ̇ = −b + η_v``, ``ḃ = η_u``, from the continuous model
    by Van Loan's method (:func:`strapdown_ros.estimation.steady_filter.discretize`); equal to
    ``Q = [[σ_v²Δt + σ_u²Δt³/3, −σ_u²Δt²/2], [−σ_u²Δt²/2, σ_u²Δt]]``.
    """
    A = np.array([[0.0, -1.0], [0.0, 0.0]])
    return discretize(A, np.diag([sigma_v ** 2, sigma_u ** 2]), dt)


def riccati_steady_state(sigma_n: float, sigma_v: float, sigma_u: float, dt: float) -> SteadyState:
    """
    Steady state of the same single-axis model from the discrete algebraic Riccati equation
    (:func:`strapdown_ros.estimation.steady_filter.steady_state_gain`: numerical, independent of
    the closed form).

    Parameters
    ----------
    sigma_n, sigma_v, sigma_u, dt : float
        As :func:`farrenkopf_steady_state` (sigma_u > 0: with a random-constant bias the
        steady state has a bias variance of zero and the doubling iteration does not end).

    Returns
    -------
    SteadyState
        Attitude and bias σ before and after the update.
    """
    phi, q = bias_filter_model(sigma_v, sigma_u, dt)
    m, _, p = steady_state_gain(phi, np.array([[1.0, 0.0]]), q, np.array([[sigma_n ** 2]]))
    return SteadyState(float(np.sqrt(m[0, 0])), float(np.sqrt(p[0, 0])),
                       float(np.sqrt(m[1, 1])), float(np.sqrt(p[1, 1])))
