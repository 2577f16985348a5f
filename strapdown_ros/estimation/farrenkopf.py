"""
Farrenkopf's analytic steady state of the single-axis gyro-bias attitude filter.

The reference the attitude filter's tests and ``filter_bench`` compare it with.  The model
(Farrenkopf 1978; Markley & Crassidis 2014, *Fundamentals of Spacecraft Attitude Determination
and Control*, ch. 6 (the steady-state analysis of the MEKF); Crassidis & Junkins, *Optimal
Estimation of Dynamic Systems*, 2nd ed., ch. 7): one axis, angle θ, gyro output
``ω̃ = ω + b + η_v`` with white angle noise of density σ_v² (angle random walk, rad/√s) and
a bias random walk ``ḃ = η_u`` of density σ_u² (rad/s/√s); an angle measurement
``y_k = θ_k + n_k`` with white noise of variance σ_n² every Δt.  With the dimensionless

    S_v = σ_v √Δt / σ_n,       S_u = σ_u Δt^{3/2} / σ_n,

the steady-state one-step prediction (pre-update) and filtered (post-update) angle variances
are

    γ = ¼ (S_u + √(16 + 4 S_v² + S_u²/3)),       ξ = γ + √(γ² − 1),
    P_θ(−) = σ_n² (ξ² − 1),       P_θ(+) = σ_n² (1 − ξ⁻²).

The derivation (the second difference of the measurements as a moving average of order 2 and
its spectral factor) is in doc/attitude_filter.md.  :func:`riccati_steady_state` iterates the
discrete Riccati equation of the same model as an independent check
(``test/estimation/test_attitude_filter.py``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.estimation.steady_filter import discretize, steady_state_gain

__all__ = ['SteadyState', 'farrenkopf_steady_state', 'riccati_steady_state', 'bias_filter_model']


@dataclass(frozen=True)
class SteadyState:
    """
    Steady-state 1σ of the single-axis filter, rad (attitude) and rad/s (bias).

    Parameters
    ----------
    attitude_pre : float
        Attitude σ before a measurement update (one-step prediction), rad.
    attitude_post : float
        Attitude σ after it, rad.
    bias_pre, bias_post : float, optional
        Bias σ before and after, rad/s.

    """

    attitude_pre: float
    attitude_post: float
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

    Raises
    ------
    ValueError
        A σ negative or not finite, or dt or sigma_n not positive.

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


def bias_filter_model(sigma_v: float, sigma_u: float,
                      dt: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the exact discrete model of one axis over dt.

    x = [θ error, bias error] with ``θ̇ = −b + η_v``, ``ḃ = η_u``, from the continuous model by
    Van Loan's method (:func:`strapdown_ros.estimation.steady_filter.discretize`); Q equals
    ``[[σ_v²Δt + σ_u²Δt³/3, −σ_u²Δt²/2], [−σ_u²Δt²/2, σ_u²Δt]]``.

    Parameters
    ----------
    sigma_v : float
        Angle random walk, rad/√s.
    sigma_u : float
        Bias random walk, rad/s/√s.
    dt : float
        Interval, s.

    Returns
    -------
    phi : ndarray (2, 2)
        Transition.
    Q : ndarray (2, 2)
        Process noise.

    """
    A = np.array([[0.0, -1.0], [0.0, 0.0]])
    return discretize(A, np.diag([sigma_v ** 2, sigma_u ** 2]), dt)


def riccati_steady_state(sigma_n: float, sigma_v: float, sigma_u: float,
                         dt: float) -> SteadyState:
    """
    Return the steady state of the same single-axis model from the discrete Riccati equation.

    Numerical (:func:`strapdown_ros.estimation.steady_filter.steady_state_gain`), independent
    of the closed form.

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
