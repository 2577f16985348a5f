"""
Increment pairs over a whole recording, vectorised.

Attitude increments from the gyro and the camera between consecutive fixes, their residual
(004 eq. 5–6) and the signatures of the effects, for the discrepancy workflow and the gyro
calibration.  This is the same computation as
:func:`strapdown_ros.calibration.boresight_increments.gyro_increment` (one-sample products of
exp(ρ_k) with 004's in-interval polynomial at both ends), done once for all pairs:
the gyro attitude ``A(t)`` is integrated over the whole record (one parallel-prefix scan), the
attitude at a fix epoch τ inside interval k is ``A_{k−1} ⊗ r_k(x)``, x = fraction of interval
k before τ, and ``ΔS_imu = A(τ_s)* ⊗ A(τ_e)``.

Signatures.  A change δρ_k = D_k θ of the increments changes ΔS_imu by a right rotation
``ε = C_eᵀ Σ_k w_k C_k D_k θ`` (MF axes at τ_e; C_k the DCM of A at the end of interval k,
w_k the fraction of interval k inside the pair), and the residual by ``Cᵀ ε`` (VF axes), so
the column of θ is ``Cᵀ C_eᵀ Σ_k w_k C_k D_k``.  A shift of both epochs by −τ changes ΔS_imu
by ``ε = (ΔSᵀ ω_s − ω_e)(−τ)`` with ω the body rate at the epochs.  No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.calibration.boresight import increment_residuals
from strapdown_ros.calibration.boresight_increments import r_partial
from strapdown_ros.rotation import (quat_conjugate, quat_cumprod, quat_multiply, quat_normalize,
                                    quat_to_dcm, rotvec_to_quat)

__all__ = ['ANGLE_LIMIT', 'GyroRecord', 'PairSet', 'build_pairs', 'pair_integral',
           'pair_residuals']

ANGLE_LIMIT = np.pi * 0.999          # increments beyond this are not formed (ambiguous rotation)


@dataclass
class GyroRecord:
    """
    Compensated gyro increments of a record, integrated into an attitude once.

    Attributes
    ----------
    stamps : (n,) ndarray
        End stamps of the increments, s.
    rho : (n, 3) ndarray
        Increments, rad.
    period : (n − 1,) ndarray
        Length T_k of interval k ≥ 1, s (derived).
    attitude : (n, 4) ndarray
        Gyro attitude A at the end of each interval, scalar first (derived).

    """

    stamps: np.ndarray
    rho: np.ndarray

    def __post_init__(self):
        self.stamps = np.asarray(self.stamps, dtype=float)
        self.rho = np.asarray(self.rho, dtype=float).reshape(-1, 3)
        self.period = np.diff(self.stamps)                         # T_k of interval k ≥ 1
        q = quat_cumprod(np.array([1.0, 0.0, 0.0, 0.0]), _exp(self.rho))
        self.attitude = q                                          # A at the end of interval k
        self._dcm = None

    @property
    def dcm(self) -> np.ndarray:
        """Return the DCMs of :attr:`attitude` (computed once)."""
        if self._dcm is None:
            self._dcm = quat_to_dcm(self.attitude)
        return self._dcm

    def locate(self, tau: np.ndarray):
        """
        Locate epochs on the gyro grid.

        Parameters
        ----------
        tau : (m,) ndarray
            Epochs on the IMU clock, s.

        Returns
        -------
        tuple
            Interval index k (t_{k−1} < τ ≤ t_k), fraction x of the interval before τ, and a
            mask of the epochs the gyro covers (one increment before the interval).

        """
        k = np.searchsorted(self.stamps, tau, side='left')
        valid = (k >= 2) & (k < len(self.stamps))
        k = np.clip(k, 2, len(self.stamps) - 1)
        T = self.stamps[k] - self.stamps[k - 1]
        x = (tau - self.stamps[k - 1]) / T
        return k, x, valid

    def attitude_at(self, k, x) -> np.ndarray:
        """
        Return the gyro attitude ``A_{k−1} ⊗ r_k(x)`` inside interval k.

        Parameters
        ----------
        k : int ndarray
            Interval indices (:meth:`locate`).
        x : ndarray
            Fractions of the intervals.

        Returns
        -------
        (m, 4) ndarray
            The attitude, scalar first.

        """
        rho, drho = self.rho[k], self.rho[k] - self.rho[k - 1]
        part = quat_normalize(r_partial(rho, drho, x))
        return quat_normalize(quat_multiply(self.attitude[k - 1], part))

    def rate_at(self, k, window: float = 0.025) -> np.ndarray:
        """
        Return the body rate around interval k.

        The mean over ±``window`` s (at least ±2 increments), so that one quantised or noisy
        increment does not stand for the rate.

        Parameters
        ----------
        k : int ndarray
            Interval indices.
        window : float
            Half-width of the mean, s.

        Returns
        -------
        (m, 3) ndarray
            Body rate, rad/s.

        """
        k = np.asarray(k)
        n = len(self.stamps)
        T = float(np.median(self.period)) if len(self.period) else 1.0
        w = max(2, int(round(window / T)))
        lo = np.clip(k - w, 1, n - 1)
        hi = np.clip(k + w, 1, n - 1)
        if not hasattr(self, '_cum'):
            self._cum = np.vstack([np.zeros((1, 3)), np.cumsum(self.rho, axis=0)])
        total = self._cum[hi + 1] - self._cum[lo]
        return total / (self.stamps[hi] - self.stamps[lo - 1])[:, None]


def _exp(rho):
    return rotvec_to_quat(rho)


@dataclass
class PairSet:
    """
    Pairs of consecutive usable fixes (indices into the fix arrays) and their increments.

    Attributes
    ----------
    fix_start, fix_end : (N,) int ndarray
        Indices of the first and the second fix.
    t_start, t_end : (N,) ndarray
        IMU-clock epochs τ (stamp − time offset), s.
    dq_imu : (N, 4) ndarray
        ΔS_imu, MF(τ_e) → MF(τ_s), scalar first.
    dq_cam : (N, 4) ndarray
        ΔS_avu, VF(t_e) → VF(t_s), scalar first.
    k_start, x_start, k_end, x_end : (N,) ndarray
        Gyro interval and fraction of each epoch.
    duration : (N,) ndarray
        τ_e − τ_s, s.

    """

    fix_start: np.ndarray
    fix_end: np.ndarray
    t_start: np.ndarray
    t_end: np.ndarray
    dq_imu: np.ndarray
    dq_cam: np.ndarray
    k_start: np.ndarray
    x_start: np.ndarray
    k_end: np.ndarray
    x_end: np.ndarray
    duration: np.ndarray

    def __len__(self):
        return len(self.fix_start)

    @property
    def adjacent(self) -> np.ndarray:
        """Return (N−1,) True where pair n+1 starts at the fix where pair n ends (shared)."""
        return self.fix_start[1:] == self.fix_end[:-1]

    def subset(self, mask) -> 'PairSet':
        """
        Return the pairs selected by a mask.

        Parameters
        ----------
        mask : (N,) bool ndarray or index array
            The pairs to keep.

        Returns
        -------
        PairSet
            The selected pairs.

        """
        return PairSet(*(getattr(self, f)[mask] for f in self.__dataclass_fields__))


def build_pairs(gyro: GyroRecord, fix_stamps, fix_q, time_offset: float = 0.0, gaps=()) -> PairSet:
    """
    Build the pairs (n−1, n) of consecutive fixes that the gyro covers without a gap.

    The gyro must cover both epochs (one increment before the first epoch's interval, as
    004's polynomial needs) and the span must hold no gyro gap.

    Parameters
    ----------
    gyro : GyroRecord
        The compensated gyro increments.
    fix_stamps : (M,) array_like
        Camera stamps, s.
    fix_q : (M, 4) array_like
        Camera attitudes q_GCRS_VF, scalar first.
    time_offset : float
        Camera time offset, s: τ = stamp − time_offset.
    gaps : sequence of (float, float)
        Gyro gaps (start, end), s.

    Returns
    -------
    PairSet
        The pairs.

    """
    tau = np.asarray(fix_stamps, dtype=float) - float(time_offset)
    k, x, valid = gyro.locate(tau)
    att = gyro.attitude_at(k, x)
    idx = np.arange(len(tau))
    s, e = idx[:-1], idx[1:]
    ok = valid[:-1] & valid[1:] & (tau[1:] > tau[:-1])
    if len(gaps):
        h = 1.5 * float(np.median(gyro.period)) if len(gyro.period) else 0.0
        for a, b in gaps:                                         # a pair may not span a gap
            ok &= ~((tau[:-1] - h < b) & (a < tau[1:] + h))
    s, e = s[ok], e[ok]
    dq_imu = quat_normalize(quat_multiply(quat_conjugate(att[s]), att[e]))
    q = np.asarray(fix_q, dtype=float)
    dq_cam = quat_normalize(quat_multiply(quat_conjugate(q[s]), q[e]))
    return PairSet(s, e, tau[s], tau[e], dq_imu, dq_cam, k[s], x[s], k[e], x[e], tau[e] - tau[s])


def pair_residuals(C: np.ndarray, pairs: PairSet) -> np.ndarray:
    """
    Return the residuals f_n of 004 (5)–(6), VF axes: the skew part of ΔS_avuᵀ Cᵀ ΔS_imu C.

    Parameters
    ----------
    C : (3, 3) ndarray
        C_MF^VF.
    pairs : PairSet
        The pairs.

    Returns
    -------
    (N, 3) ndarray
        f_n, rad.

    """
    return increment_residuals(C, quat_to_dcm(pairs.dq_imu), quat_to_dcm(pairs.dq_cam))


def pair_integral(gyro: GyroRecord, pairs: PairSet, jacobian, chunk: int = 100_000) -> np.ndarray:
    """
    Return the ε-signature per pair, MF axes at τ_e: ``C_eᵀ Σ_k w_k C_k D_k``.

    Parameters
    ----------
    gyro : GyroRecord
        The gyro increments.
    pairs : PairSet
        The pairs.
    jacobian : callable
        ``jacobian(rho, T, index_slice)`` returns D_k (m, 3, p) for a slice of intervals; it
        is called chunk by chunk, so memory stays bounded on recordings of hours.
    chunk : int
        Intervals per call of ``jacobian``.

    Returns
    -------
    (N, 3, p) ndarray
        The signatures.

    """
    n = len(gyro.stamps)
    Ks, Ke = pairs.k_start, pairs.k_end
    # running sums Z[k] = Σ_{i ≤ k} C_i D_i, read only where pairs need them (chunk by chunk:
    # memory bounded by the chunk and the pairs, never by the whole record)
    need_z = np.concatenate([Ks, Ke - 1])
    need_y = np.concatenate([Ks, Ke])
    Z_need = Y_need = None
    carry = None
    for lo in range(1, n, chunk):
        hi = min(n, lo + chunk)
        sl = np.arange(lo, hi)
        D = jacobian(gyro.rho[sl], gyro.stamps[sl] - gyro.stamps[sl - 1], sl)
        Cm = gyro.dcm[sl]
        Y = np.einsum('kij,kjp->kip', Cm, D)
        Z = np.cumsum(Y, axis=0)
        if carry is not None:
            Z += carry
        carry = Z[-1].copy()
        if Z_need is None:
            Z_need = np.zeros((len(need_z),) + Y.shape[1:])
            Y_need = np.zeros((len(need_y),) + Y.shape[1:])
        sel = (need_z >= lo) & (need_z < hi)
        Z_need[sel] = Z[need_z[sel] - lo]
        sel = (need_y >= lo) & (need_y < hi)
        Y_need[sel] = Y[need_y[sel] - lo]
    if Z_need is None:                                 # no interval: no pair can use one
        Z_need = np.zeros((len(need_z), 3, 0))
        Y_need = np.zeros((len(need_y), 3, 0))
    N = len(Ks)
    Zs, Ze = Z_need[:N], Z_need[N:]
    Ys, Ye = Y_need[:N], Y_need[N:]
    total = Ze - Zs + (1.0 - pairs.x_start)[:, None, None] * Ys + pairs.x_end[:, None, None] * Ye
    Cend = quat_to_dcm(gyro.attitude_at(Ke, pairs.x_end))
    return np.einsum('nji,njp->nip', Cend, total)
