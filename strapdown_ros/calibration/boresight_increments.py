"""
Attitude increments of the IMU and of the star camera between two exposures (paper 004).

The data of the boresight estimate (Vasilyuk et al. 2024, §2–§3): :func:`gyro_increment` gives
ΔS_imu between two camera epochs from asynchronous gyro increments, with 004's in-interval
polynomial at both ends (:func:`r_partial`), and its covariance E_imu by the recursion (2);
:func:`camera_increment` gives ΔS_avu and E_avu; :class:`IncrementPair` holds both, and
:func:`angle_consistency` judges a pair by its rotation angles alone.  Solved by
:mod:`strapdown_ros.calibration.boresight`.  No ROS; numpy only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.rotation import (quat_conjugate, quat_cumprod, quat_multiply, quat_normalize,
                                    quat_to_dcm, quat_to_rotvec)
from strapdown_ros.sensors import SensorSigmas
from strapdown_ros.sensors.covariance import constant_jacobian, get_covariance_model

__all__ = ['IncrementPair', 'angle_consistency', 'camera_increment', 'gyro_increment',
           'r_partial']


# ------------------------------------------------------------------ §2.2 ΔS_imu
def r_partial(rho: np.ndarray, drho: np.ndarray, x: np.ndarray) -> np.ndarray:
    """
    Return 004 §2.2's quaternion of the rotation over the first fraction x = τ/T of an interval.

    Unnormalised, from a rate linear in time over the IMU interval with increment ρ.

    Parameters
    ----------
    rho : (3,) or (K, 3) ndarray
        Gyro increment ρ of the interval, rad.
    drho : (3,) or (K, 3) ndarray
        Δρ = ρ − ρ_prev, rad.
    x : float or (K,) ndarray
        Fraction τ/T of the interval.

    Returns
    -------
    (K, 4) ndarray
        r(τ), scalar first, not normalised.

    """
    rho, drho = np.atleast_2d(rho), np.atleast_2d(drho)
    x = np.asarray(x, dtype=float).reshape(-1, 1)
    r2 = np.sum(rho * rho, axis=1, keepdims=True)
    rd = np.sum(rho * drho, axis=1, keepdims=True)
    r0 = 1.0 - r2 / 8.0 * x ** 2 - rd / 8.0 * (x ** 3 - x ** 2)
    rv = (rho / 2.0 * (x - r2 / 24.0 * x ** 3) + drho / 4.0 * (x ** 2 - x)
          + np.cross(rho, drho) / 24.0 * x ** 3)
    return np.concatenate([r0, rv], axis=1)


def gyro_increment(stamps: np.ndarray, delta_theta: np.ndarray, t_start: float, t_end: float,
                   gyro: SensorSigmas | None = None, covariance_model: str = 'random_constant',
                   sensitivity: bool = False):
    """
    Return ΔS_imu over [t_start, t_end] and its covariance E_imu (004 §2.2–§2.3).

    Needs the increment whose interval contains ``t_end``.  The interval length T of each
    increment is the difference of its stamps.

    Parameters
    ----------
    stamps : (n,) ndarray
        End times of the increments, s, sorted.
    delta_theta : (n, 3) ndarray
        Gyro increments, rad.
    t_start, t_end : float
        The camera epochs, s.
    gyro : SensorSigmas, optional
        Gyro error sigmas; without them E_imu is zero.
    covariance_model : str
        Name of the gyro covariance model (:mod:`strapdown_ros.sensors.covariance`).
    sensitivity : bool
        Also return the sensitivity G and the white part of E_imu.

    Returns
    -------
    tuple or None
        ``(dq, E_imu)``: ΔS_imu as a quaternion (MF(t_end) → MF(t_start)), scalar first, and
        E_imu (3×3, MF axes at t_end, rad²).  With ``sensitivity`` also G (3×12), the
        sensitivity of ε_imu to the gyro constants x = [b (3), vec M (9, column-major)], and
        the white part of E_imu (random walk only), which let the estimator treat the
        constants as common to all pairs.  None while the increment containing ``t_end``
        has not arrived.

    """
    stamps = np.asarray(stamps, dtype=float)
    dth = np.asarray(delta_theta, dtype=float)
    if len(stamps) < 2 or t_end <= t_start:
        return None
    # k0: first increment ending after t_start; k1: first ending at or after t_end
    k0 = int(np.searchsorted(stamps, t_start, side='right'))
    k1 = int(np.searchsorted(stamps, t_end, side='left'))
    if k0 < 1 or k1 >= len(stamps):
        return None                     # need one increment before, one after
    T = np.diff(stamps)[k0 - 1:k1]      # lengths of intervals k0..k1
    rho = dth[k0:k1 + 1]
    drho = rho - dth[k0 - 1:k1]
    x_start = (t_start - (stamps[k0] - T[0])) / T[0]
    x_end = (t_end - (stamps[k1] - T[-1])) / T[-1]
    full = quat_normalize(r_partial(rho, drho, np.ones(len(rho))))
    head = quat_normalize(r_partial(rho[0], drho[0], x_start)[0])
    tail = quat_normalize(r_partial(rho[-1], drho[-1], x_end)[0])
    if k0 == k1:
        dq = quat_multiply(quat_conjugate(head), tail)
        chain = dq[None]
    else:
        first = quat_multiply(quat_conjugate(head), full[0])
        factors = np.vstack([first[None], full[1:-1], tail[None]])
        chain = quat_cumprod(np.array([1.0, 0.0, 0.0, 0.0]), factors)
        dq = chain[-1]
    cov = np.zeros((3, 3))
    G = np.zeros((3, 12))
    white = np.zeros((3, 3))
    if gyro is not None:
        # eq. (2) over the whole IMU intervals k0..k1 from E = 0 (004: E(t_En) ≈ E(t_I,K−1)),
        # evaluated as a sum in the axes of MF(t_start): C_k = attitude after interval k
        C = quat_to_dcm(quat_cumprod(np.array([1.0, 0.0, 0.0, 0.0]), full))
        model = get_covariance_model(covariance_model)
        W = np.einsum('kij,kjl,kml->im', C, model.white(rho, T, gyro), C)   # Σ C_k Q_k C_kᵀ
        var = model.constant_variances(gyro)
        if np.any(var > 0) or sensitivity:
            J = np.einsum('kij,kjl->il', C, constant_jacobian(rho, T))   # Σ C_k ∂ρ_k/∂x
        P = W + ((J * var) @ J.T if np.any(var > 0) else 0.0)
        Cend = C[-1]
        cov = Cend.T @ P @ Cend
        cov = 0.5 * (cov + cov.T)
        if sensitivity:
            # ε = C_endᵀ Σ_k C_k (∂ρ_k/∂x · x + w_k): linear in the constants x = [b, vec M]
            G = Cend.T @ J
            white = Cend.T @ W @ Cend
    if sensitivity:
        return quat_normalize(dq), cov, G, white
    return quat_normalize(dq), cov


def camera_increment(q_prev: np.ndarray, P_prev: np.ndarray, q_next: np.ndarray,
                     P_next: np.ndarray):
    """
    Return ΔS_avu = S_{n−1}ᵀ S_n and E_avu = P_n + ΔSᵀ P_{n−1} ΔS (004 §3.3).

    Parameters
    ----------
    q_prev, q_next : (4,) ndarray
        Camera fixes S_{n−1}, S_n (q_GCRS_VF), scalar first.
    P_prev, P_next : (3, 3) ndarray
        Their covariances, VF axes, rad².

    Returns
    -------
    tuple
        ΔS_avu as a quaternion (VF(t_n) → VF(t_{n−1})), scalar first, and E_avu (3×3, rad²).

    """
    dq = quat_normalize(quat_multiply(quat_conjugate(q_prev), q_next))
    dS = quat_to_dcm(dq)
    return dq, np.asarray(P_next) + dS.T @ np.asarray(P_prev) @ dS


@dataclass
class IncrementPair:
    """
    The IMU and camera attitude increments between two camera epochs.

    Attributes
    ----------
    t_start, t_end : float
        The camera epochs, s.
    dq_imu : (4,) ndarray
        ΔS_imu, scalar first.
    dq_cam : (4,) ndarray
        ΔS_avu, scalar first.
    cov_imu : (3, 3) ndarray
        E_imu, MF axes, rad².
    cov_cam : (3, 3) ndarray
        E_avu, VF axes, rad².
    imu_sensitivity : (3, 12) ndarray or None
        For ``weighting='correlated'``: the sensitivity G of ε_imu to the gyro constants.
    cov_imu_white : (3, 3) ndarray or None
        The white part of E_imu.
    cov_fix_start, cov_fix_end : (3, 3) ndarray or None
        Covariances of the two camera fixes (adjacent pairs share a fix).

    """

    t_start: float
    t_end: float
    dq_imu: np.ndarray
    dq_cam: np.ndarray
    cov_imu: np.ndarray
    cov_cam: np.ndarray
    imu_sensitivity: np.ndarray | None = None
    cov_imu_white: np.ndarray | None = None
    cov_fix_start: np.ndarray | None = None
    cov_fix_end: np.ndarray | None = None

    @property
    def angle(self) -> float:
        """Return the rotation angle of the camera increment, rad."""
        return float(np.linalg.norm(quat_to_rotvec(self.dq_cam)))


def angle_consistency(pair: IncrementPair) -> tuple[float, float]:
    """
    Return φ_avu − φ_imu of a pair and its predicted σ.

    Rotation angles do not depend on the boresight, so this judges a pair before (and
    whatever) the boresight fit says (004 Fig. 2a).  σ² = k_avuᵀ E_avu k_avu + k_imuᵀ E_imu
    k_imu with k the unit rotation axes (the angle error is the error component along the
    axis); below 1e-9 rad the mean diagonal stands in.

    Parameters
    ----------
    pair : IncrementPair
        The pair.

    Returns
    -------
    tuple of float
        The angle difference and its σ, rad.

    """
    out, var = [], 0.0
    for dq, E in ((pair.dq_cam, pair.cov_cam), (pair.dq_imu, pair.cov_imu)):
        rv = quat_to_rotvec(dq)
        a = float(np.linalg.norm(rv))
        out.append(a)
        var += float(rv @ E @ rv) / a ** 2 if a > 1e-9 else float(np.trace(E)) / 3.0
    return out[0] - out[1], float(np.sqrt(max(var, 0.0)))
