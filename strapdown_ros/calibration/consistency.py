"""
Consistency of camera-derived and inertial attitudes (Vasilyuk et al. 2024, paper 004, §5–§6).

After the boresight β (C = C_MF^VF, VF → MF) has been estimated with covariance P_β, each star
camera fix S_GCRS^VF gives an IMU attitude S̃_GCRS^MF = S_GCRS^VF Cᵀ with covariance
P^mfa = C P^avu Cᵀ + D2 P_β D2ᵀ (eq. (8), :func:`camera_imu_attitude`, :func:`d_matrices`).
The SINS attitude S_GCRS^MF (gyro integration, :func:`sins_from_camera`) at the same epoch
differs from it by the small rotation θ^diff, (S_GCRS^MF)ᵀ S̃_GCRS^MF = exp([θ^diff×]) (004 §6,
Fig. 3); :func:`theta_diff_check` returns θ^diff per epoch, its predicted covariance and the
NEES with a χ² acceptance band.  The corrections to the printed formulas are in
doc/calibration.md.  Numpy only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.estimation.chi_square import chi2_interval
from strapdown_ros.rotation import (dcm_to_quat, quat_conjugate, quat_multiply, quat_normalize,
                                    quat_to_dcm, quat_to_rotvec, ypr_to_dcm)

__all__ = ['COVARIANCE_FORMS', 'ThetaDiffCheck', 'camera_imu_attitude',
           'd1_finite_difference', 'd_matrices', 'sins_from_camera', 'theta_diff_check']

COVARIANCE_FORMS = ('derived', 'printed')


def _vee_skew(A: np.ndarray) -> np.ndarray:
    """Vector of the skew part of A (…, 3, 3)."""
    return 0.5 * np.stack([A[..., 2, 1] - A[..., 1, 2], A[..., 0, 2] - A[..., 2, 0],
                           A[..., 1, 0] - A[..., 0, 1]], -1)


def d_matrices(beta, form: str = 'derived') -> tuple[np.ndarray, np.ndarray]:
    """
    Return 004 §5's D1 (θ^clb = D1 δβ, VF axes) and D2 = C D1 (MF axes) at β = (ψ, ϑ, γ).

    Parameters
    ----------
    beta : (3,) array_like
        The boresight angles (ψ, ϑ, γ), rad.
    form : {'derived', 'printed'}
        'derived': D2 from the Euler sequence R_z(−ψ) R_x(ϑ) R_y(γ) (columns: the MF axes of
        the three rotations, −z, R_z(−ψ)x, R_z(−ψ)R_x(ϑ)y) and D1 = Cᵀ D2; 'printed': the two
        matrices entry by entry as 004 prints them (β̆_γ read as β_γ).

    Returns
    -------
    tuple of two (3, 3) ndarray
        D1 and D2.

    """
    psi, th, ga = (float(v) for v in np.asarray(beta, dtype=float).reshape(3))
    sy, cy, sp, cp = np.sin(psi), np.cos(psi), np.sin(th), np.cos(th)
    sr, cr = np.sin(ga), np.cos(ga)
    if form == 'printed':
        D1 = np.array([[sr * cp, cr, 0.0], [-sp, 0.0, 1.0], [-cr * cp, sr, 0.0]])
        D2 = np.array([[0.0, cy, cp * sy], [0.0, -sy, cp * cy], [-1.0, 0.0, sp]])
        return D1, D2
    if form != 'derived':
        raise ValueError(f"form must be 'derived' or 'printed', got {form!r}")
    Rz = np.array([[cy, sy, 0.0], [-sy, cy, 0.0], [0.0, 0.0, 1.0]])          # R_z(−ψ)
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
    D2 = np.column_stack([[0.0, 0.0, -1.0], Rz[:, 0], (Rz @ Rx)[:, 1]])
    C = ypr_to_dcm(psi, th, ga)
    return C.T @ D2, D2


def d1_finite_difference(beta, h: float = 1e-6) -> np.ndarray:
    """
    Return the exact-truth reference for D1: central differences of C(β) = C(β̆)(I + [θ×]).

    Parameters
    ----------
    beta : (3,) array_like
        The boresight angles, rad.
    h : float
        Difference step, rad.

    Returns
    -------
    (3, 3) ndarray
        D1 with θ = D1 δβ, VF axes.

    """
    b = np.asarray(beta, dtype=float).reshape(3)
    C = ypr_to_dcm(*b)
    cols = []
    for j in range(3):
        d = np.zeros(3)
        d[j] = h
        cols.append(_vee_skew(C.T @ (ypr_to_dcm(*(b + d)) - ypr_to_dcm(*(b - d)))) / (2 * h))
    return np.column_stack(cols)


def camera_imu_attitude(q_gcrs_vf, P_avu, beta, P_beta, d_form: str = 'derived'):
    """
    Return the camera-derived IMU attitude and its covariance (004 §5, eq. (8)).

    S̃_GCRS^MF = S_GCRS^VF Cᵀ and P^mfa = C P^avu Cᵀ + D2 P_β D2ᵀ, MF axes.

    Parameters
    ----------
    q_gcrs_vf : (N, 4) ndarray
        Camera fixes, scalar first.
    P_avu : (N, 3, 3) or (3, 3) ndarray
        Their covariance, VF axes, rad².
    beta : (3,) array_like
        The boresight angles, rad.
    P_beta : (3, 3) ndarray
        Covariance of β, rad².
    d_form : {'derived', 'printed'}
        Form of D2 (:func:`d_matrices`).

    Returns
    -------
    tuple
        q_GCRS_MF (N, 4), scalar first, and P^mfa (N, 3, 3), MF axes, rad².

    """
    q = np.atleast_2d(np.asarray(q_gcrs_vf, dtype=float))
    P_avu = np.broadcast_to(np.asarray(P_avu, dtype=float), (len(q), 3, 3))
    C = ypr_to_dcm(*np.asarray(beta, dtype=float))
    _, D2 = d_matrices(beta, d_form)
    q_mf = quat_normalize(quat_multiply(q, quat_conjugate(dcm_to_quat(C))[None]))
    P = C[None] @ P_avu @ C.T[None] + (D2 @ np.asarray(P_beta, dtype=float) @ D2.T)[None]
    return q_mf, 0.5 * (P + np.swapaxes(P, 1, 2))


def sins_from_camera(q_gcrs_vf, beta, dq_imu, E_imu=None, align_at: int = 0, sensitivity=None,
                     white=None, constant_variances=None, printed_alignment: bool = False,
                     return_sensitivity: bool = False):
    """
    Run the SINS of 004 §6: aligned from a camera fix through C, then S_n = S_{n−1} ΔS_n.

    Gyro covariance P^gyro_n (MF_n axes, zero at the alignment epoch) by the interval
    recursion P_n = ΔS_nᵀ P_{n−1} ΔS_n + E_n (the interval analogue of 004 §6's recursion), or
    — when the per-interval sensitivities, white parts and the constants' variances are
    given — with the gyro constants common to all intervals: ε_n = ΔS_nᵀ ε_{n−1} + G_n x + w_n.

    Parameters
    ----------
    q_gcrs_vf : (N, 4) ndarray
        Camera fixes, scalar first.
    beta : (3,) array_like
        The boresight angles, rad.
    dq_imu : (N−1, 4) ndarray
        ΔS_imu of the interval ending at fix n (MF_n → MF_{n−1}), n = 1…N−1.
    E_imu : (N−1, 3, 3) ndarray, optional
        Their covariances, rad² (zero if None).
    align_at : int
        Index of the alignment fix.
    sensitivity : (N−1, 3, 12) ndarray, optional
        Per-interval G_n, the sensitivity to the gyro constants x = [b, vec M].
    white : (N−1, 3, 3) ndarray, optional
        Per-interval white parts of E_imu.
    constant_variances : (12,) or (12, 12) array_like, optional
        Variances (or covariance) of x.
    printed_alignment : bool
        Align as printed, S_1^MF = S_1^VF (no boresight).
    return_sensitivity : bool
        Also return J (N, 3, 12), ε_n's sensitivity to the constants, for the joint covariance
        of :func:`theta_diff_check` (``imu_sensitivity``).

    Returns
    -------
    tuple
        q_GCRS_MF (N, 4) and P_gyro (N, 3, 3); epochs before ``align_at`` are NaN.  With
        ``return_sensitivity`` also J.

    Raises
    ------
    ValueError
        The number of increments is not N − 1.

    """
    q_vf = np.atleast_2d(np.asarray(q_gcrs_vf, dtype=float))
    dq = np.atleast_2d(np.asarray(dq_imu, dtype=float))
    n = len(q_vf)
    if len(dq) != n - 1:
        raise ValueError(f'need {n - 1} increments for {n} fixes, got {len(dq)}')
    C = ypr_to_dcm(*np.asarray(beta, dtype=float))
    q = np.full((n, 4), np.nan)
    P = np.full((n, 3, 3), np.nan)
    q[align_at] = q_vf[align_at] if printed_alignment else quat_normalize(
        quat_multiply(q_vf[align_at], quat_conjugate(dcm_to_quat(C))))
    P[align_at] = 0.0
    coherent = sensitivity is not None
    J, W = np.zeros((3, 12)), np.zeros((3, 3))
    Js = np.zeros((n, 3, 12))
    for k in range(align_at + 1, n):
        q[k] = quat_normalize(quat_multiply(q[k - 1], dq[k - 1]))
        R = quat_to_dcm(dq[k - 1])
        if coherent:
            J = R.T @ J + sensitivity[k - 1]
            W = R.T @ W @ R + white[k - 1]
            Pc = np.asarray(constant_variances, dtype=float)
            P[k] = W + (J @ Pc @ J.T if Pc.ndim == 2 else (J * Pc) @ J.T)
            Js[k] = J
        else:
            E = np.zeros((3, 3)) if E_imu is None else np.asarray(E_imu[k - 1])
            P[k] = R.T @ P[k - 1] @ R + E
    return (q, P, Js) if return_sensitivity else (q, P)


@dataclass
class ThetaDiffCheck:
    """
    The result of :func:`theta_diff_check`.

    Attributes
    ----------
    theta : (N, 3) ndarray
        θ^diff per epoch, MF axes, rad.
    P_mfa : (N, 3, 3) ndarray
        Eq. (8), rad².
    P_diff : (N, 3, 3) ndarray
        Predicted covariance of θ^diff, rad².
    nees : (N,) ndarray
        θᵀ P_diff⁻¹ θ per epoch (NaN where excluded).
    used : (N,) bool ndarray
        Epochs in the statistic.
    mean_nees : float
        Mean of the per-epoch NEES (3 expected).
    joint_nees : float
        NEES of all used epochs stacked, with their cross-covariances.
    nees_band : tuple of float
        Two-sided χ²(3m) band of joint_nees (m epochs used).
    within_3sigma : float
        Fraction of components with |θ_i| ≤ 3σ_i (0.9973 expected).
    consistent : bool
        Joint NEES ≤ the band's upper end.
    covariance : str
        'derived' or 'printed'.
    sigma_diff : (N,) ndarray
        √tr P_diff (004's σ^diff), rad.
    sigma_mfa : (N,) ndarray
        √tr P_mfa, rad.
    sigma_avu : (N,) ndarray
        √tr P_avu, rad.

    """

    theta: np.ndarray
    P_mfa: np.ndarray
    P_diff: np.ndarray
    nees: np.ndarray
    used: np.ndarray
    mean_nees: float
    joint_nees: float
    nees_band: tuple
    within_3sigma: float
    consistent: bool
    covariance: str
    sigma_diff: np.ndarray
    sigma_mfa: np.ndarray
    sigma_avu: np.ndarray

    def as_dict(self) -> dict:
        """Return the summary statistics as plain JSON values."""
        return {'mean_nees': self.mean_nees, 'joint_nees': self.joint_nees,
                'nees_band': list(self.nees_band), 'within_3sigma': self.within_3sigma,
                'consistent': bool(self.consistent), 'covariance': self.covariance,
                'epochs_used': int(self.used.sum())}


def theta_diff_check(q_gcrs_vf, P_avu, beta, P_beta, q_gcrs_mf_sins, P_imu=None,
                     aligned_at: int | None = 0, covariance: str = 'derived', log: str = 'exact',
                     d_form: str = 'derived', prob: float = 0.95, imu_sensitivity=None,
                     imu_constants_cov=None) -> ThetaDiffCheck:
    """
    Check θ^diff between the SINS and the camera-derived IMU attitude (004 Fig. 3).

    The epochs of one run share δβ (and, aligned, the alignment fix and the carried gyro
    error), so per-epoch NEES are correlated; the test statistic is the joint NEES with those
    cross-covariances (χ²(3m) if the model holds; with ``covariance='printed'`` the blocks are
    taken independent, as 004 implies).  The gyro cross term assumes P_imu grows as a random
    walk unless the constants' part is given, when cov(ε_i, ε_j) = W_i R_iᵀ R_j + J_i P_c J_jᵀ
    with W = P_imu − J P_c Jᵀ.  Epochs with NaN SINS attitudes and the alignment epoch
    (θ^diff = 0 there) are left out of the statistic.

    Parameters
    ----------
    q_gcrs_vf : (N, 4) ndarray
        Camera fixes, scalar first.
    P_avu : (N, 3, 3) or (3, 3) ndarray
        Their covariance, VF axes, rad².
    beta : (3,) array_like
        The boresight estimate, rad.
    P_beta : (3, 3) ndarray
        Its covariance, rad².
    q_gcrs_mf_sins : (N, 4) ndarray
        SINS attitudes at the exposure epochs, scalar first.
    P_imu : (N, 3, 3) ndarray, optional
        The SINS's own (gyro) error covariance, MF axes (zero if None).
    aligned_at : int or None
        The epoch at which the SINS was aligned from the camera through the same C (None:
        aligned independently).
    covariance : {'derived', 'printed'}
        The correlated form (doc/calibration.md) or P^imu + P^mfa (004 §6).
    log : {'exact', 'printed'}
        θ^diff as the exact rotation vector or the skew part of Sᵀ S̃ − I.
    d_form : {'derived', 'printed'}
        Form of D2 (:func:`d_matrices`).
    prob : float
        Probability inside the χ² band.
    imu_sensitivity : (N, 3, 12) ndarray, optional
        J from :func:`sins_from_camera`.
    imu_constants_cov : (12, 12) or (12,) array_like, optional
        Covariance (or variances) of the gyro constants.

    Returns
    -------
    ThetaDiffCheck
        θ^diff, its covariances and the consistency statistics.

    Raises
    ------
    ValueError
        An unknown covariance or log form, or SINS attitudes of the wrong shape.

    """
    if covariance not in COVARIANCE_FORMS:
        raise ValueError(f'covariance must be one of {COVARIANCE_FORMS}, got {covariance!r}')
    if log not in ('exact', 'printed'):
        raise ValueError(f"log must be 'exact' or 'printed', got {log!r}")
    q_vf = np.atleast_2d(np.asarray(q_gcrs_vf, dtype=float))
    q_ins = np.atleast_2d(np.asarray(q_gcrs_mf_sins, dtype=float))
    n = len(q_vf)
    if q_ins.shape != (n, 4):
        raise ValueError(f'q_gcrs_mf_sins must be ({n}, 4), got {q_ins.shape}')
    P_avu = np.broadcast_to(np.asarray(P_avu, dtype=float), (n, 3, 3))
    if P_imu is None:
        P_imu = np.zeros((n, 3, 3))
    else:
        P_imu = np.nan_to_num(np.broadcast_to(np.asarray(P_imu, dtype=float), (n, 3, 3)))
    q_cam, P_mfa = camera_imu_attitude(q_vf, P_avu, beta, P_beta, d_form)
    valid = np.all(np.isfinite(q_ins), axis=1)
    qi = np.where(valid[:, None], q_ins, np.array([1.0, 0.0, 0.0, 0.0]))
    dq = quat_normalize(quat_multiply(quat_conjugate(qi), q_cam))          # Sᵀ S̃
    theta = quat_to_rotvec(dq) if log == 'exact' else _vee_skew(quat_to_dcm(dq))
    C = ypr_to_dcm(*np.asarray(beta, dtype=float))
    _, D2 = d_matrices(beta, d_form)
    P_clb = D2 @ np.asarray(P_beta, dtype=float) @ D2.T
    a = 0 if aligned_at is None else aligned_at
    R = quat_to_dcm(quat_normalize(quat_multiply(quat_conjugate(qi[a])[None], qi)))  # MF_n → MF_a
    Rt = np.swapaxes(R, 1, 2)
    CPC = C[None] @ P_avu @ C.T[None]
    if covariance == 'printed' or aligned_at is None:
        P_diff = P_imu + P_mfa
        A = -np.broadcast_to(np.eye(3), (n, 3, 3))     # θ^diff ∋ −D2 δβ, shared by all epochs
    else:
        A = np.eye(3)[None] - Rt                               # θ^diff ∋ −(I − Rᵀ) D2 δβ
        P_diff = CPC + Rt @ CPC[a][None] @ R + A @ P_clb[None] @ np.swapaxes(A, 1, 2) + P_imu
        P_diff[a] = P_imu[a]                                   # θ^diff_a = C θ_a − C θ_a = 0
    P_diff = 0.5 * (P_diff + np.swapaxes(P_diff, 1, 2))
    used = valid.copy()
    if aligned_at is not None:
        used[aligned_at] = False
    idx = np.flatnonzero(used)
    m = len(idx)
    nees = np.full(n, np.nan)
    if m:
        whitened = np.linalg.solve(P_diff[idx], theta[idx][..., None])[..., 0]
        nees[idx] = np.einsum('ni,ni->n', theta[idx], whitened)
    # joint covariance of all used epochs: the shared boresight error, the shared alignment fix
    # and the gyro error carried from epoch i to j > i (ε_j = R_jᵀ R_i ε_i + later terms)
    Ai, Ri, Rti, Pi = A[idx], R[idx], Rt[idx], P_imu[idx]
    blocks = np.zeros((m, m, 3, 3))
    if covariance != 'printed':
        blocks = np.einsum('iab,jcb->ijac', Ai @ P_clb[None], Ai)
        if aligned_at is not None:
            blocks = blocks + np.einsum('iab,jbc->ijac', Rti @ CPC[a][None], Ri)
            if imu_sensitivity is not None:
                Pc = np.asarray(imu_constants_cov, dtype=float)
                Pc = Pc if Pc.ndim == 2 else np.diag(Pc)
                Ji = np.asarray(imu_sensitivity, dtype=float)[idx]
                blocks = blocks + np.einsum('iab,jcb->ijac', Ji @ Pc[None], Ji)
                Pi = Pi - Ji @ Pc[None] @ np.swapaxes(Ji, 1, 2)          # the white part
            # cov(ε_i, ε_j) = P_i R_iᵀ R_j for j > i
            later = (idx[:, None] < idx[None, :])[..., None, None]
            blocks = blocks + np.where(later, np.einsum('iab,jbc->ijac', Pi @ Rti, Ri),
                                       np.einsum('iab,jbc->ijac', Rti, Ri @ Pi))
    blocks[np.arange(m), np.arange(m)] = P_diff[idx]
    joint = blocks.transpose(0, 2, 1, 3).reshape(3 * m, 3 * m)
    joint = 0.5 * (joint + joint.T)
    x = theta[idx].reshape(-1)
    joint_nees = float(x @ np.linalg.solve(joint, x)) if m else float('nan')
    mean_nees = float(np.mean(nees[idx])) if m else float('nan')
    lo, hi = chi2_interval(3 * m, prob) if m else (float('nan'), float('nan'))
    sig = np.sqrt(np.einsum('nii->ni', P_diff))
    within = float(np.mean(np.abs(theta[idx]) <= 3 * sig[idx])) if m else float('nan')

    def tr(P):
        return np.sqrt(np.einsum('nii->n', P))
    return ThetaDiffCheck(theta=np.where(valid[:, None], theta, np.nan), P_mfa=P_mfa,
                          P_diff=P_diff, nees=nees, used=used, mean_nees=mean_nees,
                          joint_nees=joint_nees, nees_band=(lo, hi), within_3sigma=within,
                          consistent=bool(m and joint_nees <= hi), covariance=covariance,
                          sigma_diff=tr(P_diff), sigma_mfa=tr(P_mfa), sigma_avu=tr(P_avu))
