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

__all__ = ['IncrementPair', 'angle_consistencies', 'angle_consistency', 'camera_increment',
           'camera_increments',
           'gyro_increment', 'gyro_increments', 'r_partial']


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


def gyro_increments(stamps: np.ndarray, delta_theta: np.ndarray, t_start, t_end,
                    gyro: SensorSigmas | None = None, covariance_model: str = 'random_constant'):
    """
    Return :func:`gyro_increment` for many pairs of epochs at once, in O(n + m).

    The same quantities by the same formulas (004 §2.2–§2.3): the product of the interval
    rotations between the epochs, the in-interval polynomial at both ends, E_imu summed over the
    whole intervals the pair touches.  The products and the sums are taken as prefix products
    and prefix sums over the record, differences of them per pair, instead of one loop per
    pair; they agree with :func:`gyro_increment` to rounding (≈1e-13 relative over 10⁵
    intervals).

    Parameters
    ----------
    stamps : (n,) ndarray
        End times of the increments, s, sorted.
    delta_theta : (n, 3) ndarray
        Gyro increments, rad.
    t_start, t_end : (m,) array_like
        The camera epochs of each pair, s.
    gyro : SensorSigmas, optional
        Gyro error sigmas; without them E_imu, G and the white part are zero.
    covariance_model : str
        Name of the gyro covariance model.

    Returns
    -------
    valid : (m,) bool ndarray
        Pairs the record covers (one increment before t_start's interval, the one containing
        t_end) with t_end > t_start; the other rows are NaN.
    dq : (m, 4) ndarray
        ΔS_imu, scalar first.
    cov : (m, 3, 3) ndarray
        E_imu.
    G : (m, 3, 12) ndarray
        The sensitivity to the gyro constants.
    white : (m, 3, 3) ndarray
        The white part of E_imu.

    """
    stamps = np.asarray(stamps, dtype=float)
    dth = np.asarray(delta_theta, dtype=float).reshape(-1, 3)
    t_start = np.atleast_1d(np.asarray(t_start, dtype=float))
    t_end = np.atleast_1d(np.asarray(t_end, dtype=float))
    m, n = len(t_start), len(stamps)
    dq = np.full((m, 4), np.nan)
    cov = np.zeros((m, 3, 3))
    G = np.zeros((m, 3, 12))
    white = np.zeros((m, 3, 3))
    if n < 2 or m == 0:
        return np.zeros(m, dtype=bool), dq, cov, G, white
    k0 = np.searchsorted(stamps, t_start, side='right')
    k1 = np.searchsorted(stamps, t_end, side='left')
    valid = (t_end > t_start) & (k0 >= 1) & (k1 < n)
    k0, k1 = np.where(valid, k0, 1), np.where(valid, k1, 1)
    k1 = np.maximum(k1, k0)
    T = np.diff(stamps)                                   # T[k − 1]: interval k ≥ 1
    rho, drho = dth[1:], dth[1:] - dth[:-1]               # of interval k at index k − 1
    full = quat_normalize(r_partial(rho, drho, np.ones(n - 1)))
    head = quat_normalize(r_partial(rho[k0 - 1], drho[k0 - 1],
                                    (t_start - (stamps[k0] - T[k0 - 1])) / T[k0 - 1]))
    tail = quat_normalize(r_partial(rho[k1 - 1], drho[k1 - 1],
                                    (t_end - (stamps[k1] - T[k1 - 1])) / T[k1 - 1]))
    one = np.array([1.0, 0.0, 0.0, 0.0])
    Gq = np.vstack([one, quat_cumprod(one, full)])        # Gq[k]: product of intervals 1..k
    mid = quat_multiply(quat_conjugate(Gq[k0]), Gq[k1 - 1])  # intervals k0+1 .. k1−1
    same = k0 == k1
    first = quat_multiply(quat_conjugate(head), full[k0 - 1])
    chain = quat_multiply(quat_multiply(first, mid), tail)
    d = np.where(same[:, None], quat_multiply(quat_conjugate(head), tail), chain)
    dq[valid] = quat_normalize(d[valid])
    if gyro is not None:
        model = get_covariance_model(covariance_model)
        A = quat_to_dcm(Gq[1:])                            # attitude after interval k (index k−1)
        Q = np.asarray(model.white(rho, T, gyro), dtype=float).reshape(-1, 3, 3)
        SW = np.concatenate([np.zeros((1, 3, 3)),
                             np.cumsum(A @ Q @ np.swapaxes(A, 1, 2), axis=0)])
        SJ = np.concatenate([np.zeros((1, 3, 12)),
                             np.cumsum(A @ constant_jacobian(rho, T), axis=0)])
        var = model.constant_variances(gyro)
        Wg = SW[k1] - SW[k0 - 1]                           # Σ over intervals k0..k1, global axes
        Jg = SJ[k1] - SJ[k0 - 1]
        Aend = A[k1 - 1]                                    # the axes of MF at the end of k1
        AendT = np.swapaxes(Aend, 1, 2)
        W = AendT @ Wg @ Aend
        Gs = AendT @ Jg
        P = W + (Gs * var) @ np.swapaxes(Gs, 1, 2)
        P = 0.5 * (P + np.swapaxes(P, 1, 2))
        cov[valid], G[valid], white[valid] = P[valid], Gs[valid], W[valid]
    return valid, dq, cov, G, white


def camera_increments(q_prev: np.ndarray, P_prev: np.ndarray, q_next: np.ndarray,
                      P_next: np.ndarray):
    """
    Return :func:`camera_increment` for many pairs of fixes at once.

    Parameters
    ----------
    q_prev, q_next : (m, 4) ndarray
        Camera fixes S_{n−1}, S_n, scalar first.
    P_prev, P_next : (m, 3, 3) ndarray
        Their covariances, VF axes, rad².

    Returns
    -------
    tuple
        ΔS_avu (m, 4) and E_avu (m, 3, 3).

    """
    dq = quat_normalize(quat_multiply(quat_conjugate(q_prev), q_next))
    dS = quat_to_dcm(dq)
    return dq, np.asarray(P_next) + np.swapaxes(dS, 1, 2) @ np.asarray(P_prev) @ dS


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


def angle_consistencies(dq_cam: np.ndarray, cov_cam: np.ndarray, dq_imu: np.ndarray,
                        cov_imu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """
    Return :func:`angle_consistency` for many pairs at once.

    Parameters
    ----------
    dq_cam, dq_imu : (m, 4) ndarray
        ΔS_avu and ΔS_imu, scalar first.
    cov_cam, cov_imu : (m, 3, 3) ndarray
        E_avu and E_imu.

    Returns
    -------
    tuple of ndarray
        φ_avu − φ_imu and its σ per pair, rad.

    """
    angles, var = [], 0.0
    for dq, E in ((dq_cam, cov_cam), (dq_imu, cov_imu)):
        rv = quat_to_rotvec(np.asarray(dq, dtype=float).reshape(-1, 4))
        a = np.linalg.norm(rv, axis=1)
        angles.append(a)
        E = np.asarray(E, dtype=float).reshape(-1, 3, 3)
        along = np.einsum('ni,nij,nj->n', rv, E, rv) / np.where(a > 1e-9, a * a, 1.0)
        var = var + np.where(a > 1e-9, along, np.trace(E, axis1=1, axis2=2) / 3.0)
    return angles[0] - angles[1], np.sqrt(np.maximum(var, 0.0))
