"""
Boresight of a star camera (VF) relative to the IMU (MF) from attitude increments.

Vasilyuk et al. 2024 (paper 004), §4–§5, on the increment pairs of
:mod:`strapdown_ros.calibration.boresight_increments`: :func:`solve_boresight` runs
Gauss–Newton on β = (ψ, ϑ, γ) with the residual of (5)–(6) (§4), weighted by E_imu and E_avu
(the weighting 004 names as future work); :func:`imu_attitude_from_camera` gives the IMU
attitude from a camera fix (§5, eq. (8)).  Conventions: ``C = C_MF^VF`` maps VF coordinates
to MF coordinates (ypr_to_dcm(β)); ΔS_imu maps MF at t_n to MF at t_{n−1}; errors are
right-perturbations in the local axes.  Remarks on the printed formulas and the measured
figures: doc/calibration.md.  No ROS; numpy only.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from strapdown_ros.calibration.boresight_observability import judge_observability
from strapdown_ros.calibration.pair_covariance import band_covariance, Whitener
from strapdown_ros.estimation.chi_square import chi2_band
from strapdown_ros.estimation.observability import ObservabilityReport
from strapdown_ros.rotation import (dcm_to_quat, dcm_to_ypr, quat_conjugate, quat_multiply,
                                    quat_normalize, quat_to_dcm, quat_to_rotvec,
                                    ypr_error_to_rotation, ypr_to_dcm)
from strapdown_ros.sensors import SensorSigmas
from strapdown_ros.sensors.covariance import constant_variances

__all__ = ['CORRELATED_MAX_PAIRS', 'WEIGHTINGS', 'BoresightSolution', 'ChainedCovariance',
           'axis_alignment', 'axis_alignment_quat', 'check_observability',
           'imu_attitude_from_camera', 'increment_residuals', 'pair_arrays', 'solve_boresight']


# ---------------------------------------------------------------------- §4 the estimate
@dataclass
class BoresightSolution:
    """
    The boresight estimate of :func:`solve_boresight`, or why there is none.

    Attributes
    ----------
    observable : bool
        The boresight is observable from the pairs.
    message : str
        'observable', a convergence note, or why not.
    beta : (3,) ndarray or None
        (ψ, ϑ, γ), rad.
    c_mf_vf : (3, 3) ndarray or None
        C_MF^VF.
    covariance_beta : (3, 3) ndarray or None
        P_β, rad² (the one published).
    covariance_beta_residual : (3, 3) ndarray or None
        004 §4.3's sandwich from the residuals.
    covariance_beta_model : (3, 3) ndarray or None
        (Hᵀ W H)⁻¹ from E_imu, E_avu.
    rotation_covariance_mf : (3, 3) ndarray or None
        P^clb = D2 P_β D2ᵀ, MF axes, rad².
    weighted : bool
        Any weighting other than 'unit'.
    weighting : str
        'unit', 'pairwise' or 'correlated'.
    iterations : int
        Gauss–Newton iterations.
    converged : bool
        The iteration converged.
    residual_rms : float
        RMS of the residual components, rad.
    chi2_per_dof : float
        Σ fᵀ W f / dof with the stated noise, any weighting.
    dof : int
        3n − 3.
    chi2_band : tuple of float
        ``chi2_band(dof)``, the two-sided band of χ²/dof.
    fit_consistent : bool or None
        χ²/dof inside its band: the stated noise explains the residuals.  False: the stated
        noise is wrong or the model lacks an effect, and covariance_beta is scaled by χ²/dof
        when > 1.
    covariance_beta_stated : (3, 3) ndarray or None
        P_β from the stated noise alone (unscaled).
    pairs : int
        Number of increment pairs.
    observability : ObservabilityReport or None
        The observability report.
    unobservable_axes : list of str
        Named unobservable rotation axes.
    whitened_residual : (n, 3) ndarray or None
        The residuals at the solution whitened by the chained covariance (shared fixes; the
        gyro constants' estimate removed with the correlated weighting): unit variance and
        white when the stated noise is right.  Their autocorrelation says how far apart fixes
        must be for their errors to be independent
        (:mod:`strapdown_ros.calibration.reference_spacing`).

    """

    observable: bool
    message: str
    beta: np.ndarray | None = None
    c_mf_vf: np.ndarray | None = None
    covariance_beta: np.ndarray | None = None
    covariance_beta_residual: np.ndarray | None = None
    covariance_beta_model: np.ndarray | None = None
    rotation_covariance_mf: np.ndarray | None = None
    weighted: bool = False
    weighting: str = 'unit'
    iterations: int = 0
    converged: bool = False
    residual_rms: float = float('nan')
    chi2_per_dof: float = float('nan')
    dof: int = 0
    chi2_band: tuple = (float('nan'), float('nan'))
    fit_consistent: bool | None = None
    covariance_beta_stated: np.ndarray | None = None
    pairs: int = 0
    observability: ObservabilityReport | None = None
    unobservable_axes: list = field(default_factory=list)
    whitened_residual: np.ndarray | None = None

    @property
    def q_mf_vf(self) -> np.ndarray:
        """Return C_MF^VF as a quaternion, scalar first."""
        return dcm_to_quat(self.c_mf_vf)


def _stack(pairs):
    A_imu = quat_to_dcm(np.array([p.dq_imu for p in pairs]))
    A_cam = quat_to_dcm(np.array([p.dq_cam for p in pairs]))
    E_imu = np.array([p.cov_imu for p in pairs])
    E_cam = np.array([p.cov_cam for p in pairs])
    return A_imu, A_cam, E_imu, E_cam


def increment_residuals(C: np.ndarray, A_imu: np.ndarray, A_cam: np.ndarray) -> np.ndarray:
    """
    Return the residuals f_n of 004 (5)–(6): the skew part of ΔS_avuᵀ Cᵀ ΔS_imu C − I.

    Parameters
    ----------
    C : (3, 3) ndarray
        C_MF^VF.
    A_imu : (n, 3, 3) ndarray
        ΔS_imu as DCMs.
    A_cam : (n, 3, 3) ndarray
        ΔS_avu as DCMs.

    Returns
    -------
    (n, 3) ndarray
        f_n, rad.

    """
    F = np.swapaxes(A_cam, 1, 2) @ (C.T @ A_imu @ C)
    return 0.5 * np.stack([F[:, 2, 1] - F[:, 1, 2], F[:, 0, 2] - F[:, 2, 0],
                           F[:, 1, 0] - F[:, 0, 1]], axis=1)


def axis_alignment(A_imu, A_cam) -> np.ndarray:
    """
    Return the closed-form C that aligns the rotation vectors of the increments.

    min Σ |log ΔS_imu − C log ΔS_avu|² over rotations C: Wahba's problem, solved by SVD.

    Parameters
    ----------
    A_imu : (n, 3, 3) ndarray
        ΔS_imu as DCMs.
    A_cam : (n, 3, 3) ndarray
        ΔS_avu as DCMs.

    Returns
    -------
    (3, 3) ndarray
        C_MF^VF.

    """
    return axis_alignment_quat(dcm_to_quat(A_imu), dcm_to_quat(A_cam))


def axis_alignment_quat(dq_imu, dq_cam) -> np.ndarray:
    """
    Return :func:`axis_alignment` from the increments as quaternions (no DCM round trip).

    Parameters
    ----------
    dq_imu : (n, 4) ndarray
        ΔS_imu, scalar first.
    dq_cam : (n, 4) ndarray
        ΔS_avu, scalar first.

    Returns
    -------
    (3, 3) ndarray
        C_MF^VF.

    """
    u = quat_to_rotvec(np.asarray(dq_imu, dtype=float))
    v = quat_to_rotvec(np.asarray(dq_cam, dtype=float))
    B = u.T @ v
    U, _, Vt = np.linalg.svd(B)
    d = np.sign(np.linalg.det(U @ Vt))
    return U @ np.diag([1.0, 1.0, d]) @ Vt


def pair_arrays(pairs, c_mf_vf: np.ndarray | None = None):
    """
    Return the arrays of the chained-pair covariance from a list of pairs.

    Parameters
    ----------
    pairs : sequence of IncrementPair
        The pairs (or objects with ``dq_cam``, ``cov_cam``, ``cov_imu`` and optionally
        ``t_start``, ``t_end``, ``cov_fix_start``, ``cov_fix_end``, ``cov_imu_white``).
    c_mf_vf : (3, 3) ndarray, optional
        C_MF^VF, to take the gyro covariance into VF axes (default: its mean variance on
        every axis, which no rotation changes).

    Returns
    -------
    dq_cam : (N, 4) ndarray
        Camera increments.
    fix_P : (N, 2, 3, 3) ndarray
        Covariances of the start and end fix of each pair (0 and E_avu when the pairs do not
        carry them: each pair then stands alone, its start the reference of its increment).
    adjacent : (N−1,) bool ndarray
        Pairs n, n+1 share a fix (their stamps meet and both carry fix covariances).
    white : (N, 3, 3) ndarray
        White gyro covariance of each pair, VF axes (E_imu when no white part is given).

    """
    dq_cam = np.array([p.dq_cam for p in pairs], dtype=float)
    have_fix = all(getattr(p, 'cov_fix_start', None) is not None
                   and getattr(p, 'cov_fix_end', None) is not None for p in pairs)
    if have_fix:
        fix_P = np.array([[p.cov_fix_start, p.cov_fix_end] for p in pairs], dtype=float)
        t0 = np.array([getattr(p, 't_start', np.nan) for p in pairs], dtype=float)
        t1 = np.array([getattr(p, 't_end', np.nan) for p in pairs], dtype=float)
        adjacent = np.abs(t0[1:] - t1[:-1]) < 1e-9
    else:
        E_cam = np.array([p.cov_cam for p in pairs], dtype=float)
        fix_P = np.stack([np.zeros_like(E_cam), E_cam], axis=1)
        adjacent = np.zeros(max(len(pairs) - 1, 0), dtype=bool)
    E = np.array([p.cov_imu_white if getattr(p, 'cov_imu_white', None) is not None
                  else p.cov_imu for p in pairs], dtype=float)
    if c_mf_vf is not None:
        C = np.asarray(c_mf_vf, dtype=float)
        white = C.T[None] @ E @ C[None]
    else:
        white = (np.trace(E, axis1=1, axis2=2) / 3.0)[:, None, None] * np.eye(3)
    return dq_cam, fix_P, adjacent, white


def check_observability(pairs, c_mf_vf: np.ndarray | None = None,
                        weights: np.ndarray | None = None,
                        min_rotation: float = np.radians(0.5),
                        axis_tolerance: float = np.radians(2.0),
                        max_sigma: float = 1e-3) -> ObservabilityReport:
    """
    Judge the observability of the boresight from the information of all the pairs together.

    The rule of :func:`strapdown_ros.calibration.boresight_observability.judge_observability`,
    O(N): the Fisher information of a VF rotation of C from all the pairs (consecutive pairs
    share a camera fix), every direction's predicted σ at most ``max_sigma``; and the camera
    attitudes turning about two axes by at least ``min_rotation`` (between two fixes of the
    recording) and well above the fix noise (004 §4.1, over the recording, not pair by pair).

    Parameters
    ----------
    pairs : sequence of IncrementPair
        The pairs.
    c_mf_vf : (3, 3) ndarray, optional
        C_MF^VF, to take E_imu into VF axes (default: its mean variance per axis).
    weights : (n, 3, 3) ndarray, optional
        W_n: when given, the information is Σ (I − R_n) W_n (I − R_nᵀ) with these weights
        (independent pairs) instead of that of the chained covariance.
    min_rotation : float
        Smallest rotation about the motion's second principal axis (between two fixes of a
        chain) that counts, rad.
    axis_tolerance : float
        Not used any more (the axes are judged by their spread against the noise); kept so
        that existing calls work.
    max_sigma : float
        Directions whose predicted σ exceeds it (rad) are unobservable.

    Returns
    -------
    ObservabilityReport
        In VF rotation axes, the unobservable axes named.

    """
    dq_cam, fix_P, adjacent, white = pair_arrays(pairs, c_mf_vf)
    info = None
    if weights is not None:
        H = np.eye(3)[None] - np.swapaxes(quat_to_dcm(dq_cam), 1, 2)
        info = np.einsum('nji,njk,nkl->il', H, np.asarray(weights, dtype=float), H)
    return judge_observability(dq_cam, fix_P, adjacent, white, min_rotation=min_rotation,
                               max_sigma=max_sigma, information=info)


WEIGHTINGS = ('unit', 'pairwise', 'correlated', 'auto')
#: "auto" uses the correlated (dense) solution up to this many pairs, pairwise weights beyond
#: the name of the former limit of the dense correlated solution; the correlated solution is
#: banded now (O(n) time and memory), so 'auto' uses it at any number of pairs
CORRELATED_MAX_PAIRS = 10 ** 12


class ChainedCovariance:
    """
    The covariance of the stacked residuals f_n ≈ Cᵀε_imu,n − ε_avu,n of chained pairs, in O(n).

    Σ = B + U P_x Uᵀ: B block tridiagonal (:mod:`strapdown_ros.calibration.pair_covariance`:
    diagonal Cᵀ E_imu,white C + E_avu, and −P_n R_{n+1} between pairs that share camera fix n,
    since ε_avu,n = θ_n − R_nᵀ θ_{n−1}, 004 §3.3); U_n = Cᵀ G_n the sensitivity to the gyro
    constants x = [b, vec M], common to all pairs, with P_x their prior variances.  Σ⁻¹ is
    applied through the banded factor of B and the Woodbury identity on the 12 constants: no
    3n×3n matrix is formed.

    Parameters
    ----------
    pairs : sequence of IncrementPair
        The pairs, in time order.
    A_cam : (n, 3, 3) ndarray
        Their camera increments as DCMs.
    gyro : SensorSigmas, optional
        Gyro sigmas: the constants' prior (needs pairs with ``imu_sensitivity``); None: no
        common constants, and E_imu whole (not only its white part) on the diagonal.

    """

    def __init__(self, pairs, A_cam: np.ndarray, gyro: SensorSigmas | None = None):
        _, self.fix_P, self.adjacent, _ = pair_arrays(pairs)
        self.A_cam = A_cam
        with_constants = gyro is not None
        self.E_white = np.array([p.cov_imu_white if with_constants else p.cov_imu
                                 for p in pairs], dtype=float)
        if with_constants:
            self.G = np.array([p.imu_sensitivity for p in pairs], dtype=float)
            var = constant_variances(gyro)
            self.keep = var > 0
            self.sqrt_var = np.sqrt(var[self.keep])
        else:
            self.G = None

    def at(self, C: np.ndarray) -> dict:
        """
        Return the factors of Σ at the boresight C.

        Parameters
        ----------
        C : (3, 3) ndarray
            C_MF^VF.

        Returns
        -------
        dict
            The whitening of B, the whitened scaled constant columns and the Cholesky factor
            of I + VᵀV.

        """
        white = C.T[None] @ self.E_white @ C[None]
        W = Whitener(band_covariance(self.fix_P, self.A_cam, self.adjacent, white))
        ctx = {'W': W, 'V': None}
        if self.G is not None and np.any(self.keep):
            U = np.einsum('ji,njk->nik', C, self.G[:, :, self.keep]).reshape(-1, int(
                np.sum(self.keep)))
            V = W.apply(U * self.sqrt_var)
            ctx['V'] = V
            ctx['M'] = np.linalg.cholesky(np.eye(V.shape[1]) + V.T @ V)
        return ctx

    @staticmethod
    def _project(ctx, X):
        """Return Σ^(−1/2)-whitened columns: L⁻¹X less their part the constants explain."""
        A = ctx['W'].apply(X)
        V = ctx['V']
        if V is None:
            return A, A
        from scipy.linalg import cho_solve
        return A, A - V @ cho_solve((ctx['M'], True), V.T @ A)

    def normal(self, ctx, H: np.ndarray, f: np.ndarray):
        """
        Return Hᵀ Σ⁻¹ H, Hᵀ Σ⁻¹ f and fᵀ Σ⁻¹ f.

        Parameters
        ----------
        ctx : dict
            The factors of :meth:`at`.
        H : (n, 3, 3) ndarray
            The Jacobian of every pair's residual.
        f : (n, 3) ndarray
            The residuals.

        Returns
        -------
        tuple
            (3×3 normal matrix, 3-vector gradient, cost).

        """
        X = np.hstack([H.reshape(-1, 3), f.reshape(-1, 1)])
        A, P = self._project(ctx, X)                 # Σ⁻¹ = L⁻ᵀ (I − V M⁻¹ Vᵀ) L⁻¹
        G = A.T @ P
        return G[:3, :3], G[:3, 3], float(G[3, 3])

    def cost(self, ctx, f: np.ndarray) -> float:
        """
        Return fᵀ Σ⁻¹ f.

        Parameters
        ----------
        ctx : dict
            The factors of :meth:`at`.
        f : (n, 3) ndarray
            The residuals.

        Returns
        -------
        float
            The cost.

        """
        A, P = self._project(ctx, f.reshape(-1, 1))
        return float(A[:, 0] @ P[:, 0])

    def whitened(self, ctx, f: np.ndarray) -> np.ndarray:
        """
        Return the whitened residuals, the gyro constants' estimate removed.

        Parameters
        ----------
        ctx : dict
            The factors of :meth:`at`.
        f : (n, 3) ndarray
            The residuals.

        Returns
        -------
        (n, 3) ndarray
            L⁻¹(f − U x̂): unit variance and white when the stated noise is right.

        """
        _, P = self._project(ctx, f.reshape(-1, 1))
        return P[:, 0].reshape(-1, 3)


def solve_boresight(pairs, beta0=(0.0, 0.0, 0.0), weighted: bool = True, init: str = 'axes',
                    max_iterations: int = 50, tolerance: float = 1e-9, dx: float = 1e-7,
                    max_sigma: float = 1e-3, min_rotation: float = np.radians(0.5),
                    common_rotation_sigma: float = 0.0, weighting: str | None = None,
                    gyro: SensorSigmas | None = None) -> BoresightSolution:
    """
    Estimate β and its covariance from increment pairs (004 §4), or report why not.

    Parameters
    ----------
    pairs : sequence of IncrementPair
        The increment pairs.
    beta0 : (3,) array_like
        Start of Gauss–Newton with ``init='given'``, rad.
    weighted : bool
        Default weighting: 'pairwise' if true, else 'unit'.
    init : {'axes', 'given'}
        'axes' starts Gauss–Newton from the closed-form :func:`axis_alignment` (independent
        of β0, 1–2 iterations); 'given' starts from ``beta0`` exactly as 004 §4.2.
    max_iterations : int
        Limit of Gauss–Newton iterations.
    tolerance : float
        Convergence threshold of |Δβ|, rad.
    dx : float
        Central-difference step of the Jacobian, rad.
    max_sigma : float
        Predicted σ above which a direction is unobservable, rad.
    min_rotation : float
        Smallest rotation about the motion's second principal axis (between two fixes of a
        chain) that counts, rad (:func:`check_observability`).
    common_rotation_sigma : float
        σ (rad, per axis) of a rotation of the gyro triad common to all pairs: the
        antisymmetric part of the gyro misalignment rotates every ΔS_imu alike, so it is
        indistinguishable from the boresight and never averages out (σ_φ/√2 per axis for
        independent off-diagonal misalignments of σ_φ).  Added to the published covariance
        (MF axes: σ²I; β: D2⁻¹σ²D2⁻ᵀ), except with the correlated weighting, which contains
        it already.
    weighting : {'unit', 'pairwise', 'correlated', 'auto'}, optional
        'unit' (004); 'pairwise' (each pair by Cᵀ E_imu C + E_avu, independent pairs);
        'correlated' (generalised least squares with the full residual covariance: shared
        camera fixes and gyro constants common to all pairs; needs ``gyro`` and pairs with
        sensitivities; banded, O(n): :class:`ChainedCovariance`); 'auto' (correlated when
        possible, else pairwise).
    gyro : SensorSigmas, optional
        Gyro error sigmas, for the correlated weighting.

    Returns
    -------
    BoresightSolution
        β, C_MF^VF and their covariances, or ``observable=False`` with the reason.

    Raises
    ------
    ValueError
        An unknown weighting or init, or 'correlated' without what it needs.

    """
    pairs = list(pairs)
    n = len(pairs)
    if weighting is None:
        weighting = 'pairwise' if weighted else 'unit'
    if weighting not in WEIGHTINGS:
        raise ValueError(f"weighting must be one of {', '.join(WEIGHTINGS)}, got {weighting!r}")
    can_correlate = gyro is not None and all(p.imu_sensitivity is not None for p in pairs)
    if weighting == 'auto':
        weighting = 'correlated' if can_correlate and n <= CORRELATED_MAX_PAIRS else 'pairwise'
    if weighting == 'correlated' and not can_correlate:
        raise ValueError("weighting='correlated' needs gyro sigmas and pairs with imu_sensitivity")
    weighted = weighting != 'unit'
    if n < 2:
        return BoresightSolution(False, f'{n} increment pair(s): need at least 2', pairs=n)
    A_imu, A_cam, E_imu, E_cam = _stack(pairs)
    C_axes = axis_alignment_quat([p.dq_imu for p in pairs], [p.dq_cam for p in pairs])
    rep = check_observability(pairs, c_mf_vf=C_axes, min_rotation=min_rotation,
                              max_sigma=max_sigma)
    if not rep.observable:
        return BoresightSolution(False, rep.message, pairs=n, observability=rep,
                                 unobservable_axes=list(rep.unobservable))
    chained = ChainedCovariance(pairs, A_cam, gyro) if weighting == 'correlated' else None
    beta = np.asarray(beta0, dtype=float).copy()
    if init == 'axes':
        beta = dcm_to_ypr(C_axes)
    elif init != 'given':
        raise ValueError(f"init must be 'axes' or 'given', got {init!r}")

    def weights(C):
        if not weighted:
            return np.broadcast_to(np.eye(3), (n, 3, 3))
        cov = np.swapaxes(C, 0, 1)[None] @ E_imu @ C[None] + E_cam
        return np.linalg.inv(cov + 1e-30 * np.eye(3))

    def jacobian(b):
        H = np.empty((n, 3, 3))
        for j in range(3):
            d = np.zeros(3)
            d[j] = dx
            H[:, :, j] = (increment_residuals(ypr_to_dcm(*(b + 0.5 * d)), A_imu, A_cam)
                          - increment_residuals(ypr_to_dcm(*(b - 0.5 * d)), A_imu, A_cam)) / dx
        return H

    def linearise(b):
        """Residuals, Jacobian, weights, normal matrix Hᵀ W H and gradient Hᵀ W f at β = b."""
        C = ypr_to_dcm(*b)
        H = jacobian(b)
        f = increment_residuals(C, A_imu, A_cam)
        if weighting == 'correlated':
            ctx = chained.at(C)
            N, g, cost = chained.normal(ctx, H, f)
            return C, f, H, ctx, None, N, g, cost
        W = weights(C)
        HtW = np.einsum('nji,njk->nik', H, W)
        g = np.einsum('nij,nj->i', HtW, f)
        N = np.einsum('nij,njk->ik', HtW, H)
        return C, f, H, W, HtW, N, g, float(np.einsum('ni,nij,nj->', f, W, f))

    def frozen_cost(lin, f_t):
        """Return fᵀ W f of f_t with the weights of ``lin`` (the cost its step descends)."""
        if weighting == 'correlated':
            return chained.cost(lin[3], f_t)
        return float(np.einsum('ni,nij,nj->', f_t, lin[3], f_t))

    converged = False
    it = 0
    lin = linearise(beta)
    for it in range(1, max_iterations + 1):
        N, g, cost = lin[5], lin[6], lin[7]
        step = -np.linalg.solve(N, g)
        # converged: the step is below ``tolerance``, or below 1e-4 of the residual-scaled σ of β —
        # with large residuals the finite-difference Jacobian cannot resolve 1e-9 rad
        scale = cost / max(3 * n - 3, 1)            # residual variance per unit weight
        if np.linalg.norm(step) <= tolerance or float(step @ N @ step) <= 1e-8 * scale:
            beta = beta + step
            lin = linearise(beta)
            converged = True
            break
        # Gauss–Newton step; halved while it raises the weighted cost (large residuals, e.g. a
        # stated σ far too small, make the full step overshoot and oscillate)
        for _ in range(30):
            f_t = increment_residuals(ypr_to_dcm(*(beta + step)), A_imu, A_cam)
            if frozen_cost(lin, f_t) <= cost * (1.0 + 1e-12):
                break
            step = 0.5 * step
        beta = beta + step
        lin = linearise(beta)
    C, f, H, W, HtW, N, g, wss = lin
    # 004 §4.3: residual block P_S from the residuals, the same for every pair
    P_S = f.T @ f / max(n - 1, 1)
    Hu = H.reshape(-1, 3)
    Ninv_u = np.linalg.inv(Hu.T @ Hu)
    P_res = Ninv_u @ np.einsum('nji,jk,nkl->il', H, P_S, H) @ Ninv_u
    P_model = np.linalg.inv(N) if weighted else None
    dof = 3 * n - 3
    if not weighted:                                 # 004's unit weights: χ² with the stated noise
        cov = np.swapaxes(C, 0, 1)[None] @ E_imu @ C[None] + E_cam
        ok_cov = np.all(np.linalg.eigvalsh(cov) > 0)
        wss = float(np.einsum('ni,nij,nj->', f, np.linalg.inv(cov), f)) if ok_cov else float('nan')
    chi2 = wss / max(dof, 1)
    band = chi2_band(dof)
    consistent = bool(band[0] <= chi2 <= band[1]) if np.isfinite(chi2) and dof >= 1 else None
    if weighted:
        P = P_model * max(1.0, chi2)                 # inflate if the residuals exceed the model
    else:
        P = P_res
    # P^clb = D2 P_β D2ᵀ in MF axes (004 eq. 8)
    _, D2 = ypr_error_to_rotation(*beta)
    if common_rotation_sigma > 0 and weighting != 'correlated':
        D2i = np.linalg.inv(D2)
        P = P + common_rotation_sigma ** 2 * D2i @ D2i.T
    beta_wrapped = dcm_to_ypr(C)                     # canonical angles of the same rotation
    if weighting == 'correlated':
        white = chained.whitened(W, f)
    else:                                            # the chained covariance without constants
        plain = ChainedCovariance(pairs, A_cam)
        white = plain.whitened(plain.at(C), f)
    sol = BoresightSolution(
        observable=True,
        message='observable' if converged else f'not converged after {it} iterations',
        beta=beta_wrapped, c_mf_vf=C, covariance_beta=P, covariance_beta_residual=P_res,
        covariance_beta_model=P_model, rotation_covariance_mf=D2 @ P @ D2.T, weighted=weighted,
        weighting=weighting, iterations=it, converged=converged,
        residual_rms=float(np.sqrt(np.mean(f ** 2))), chi2_per_dof=chi2, dof=dof,
        chi2_band=band, fit_consistent=consistent, covariance_beta_stated=P_model, pairs=n,
        observability=rep, whitened_residual=white)
    return sol


def imu_attitude_from_camera(q_gcrs_vf: np.ndarray, P_avu: np.ndarray, sol: BoresightSolution):
    """
    Return the IMU attitude from a camera fix and the boresight (004 §5, eq. (8)).

    S_GCRS^MF = S_GCRS^VF (C_MF^VF)ᵀ and P^mfa = C P^avu Cᵀ + D2 P_β D2ᵀ, MF axes.

    Parameters
    ----------
    q_gcrs_vf : (4,) ndarray
        The camera attitude S_GCRS^VF, scalar first.
    P_avu : (3, 3) ndarray
        Its covariance, VF axes, rad².
    sol : BoresightSolution
        An observable boresight.

    Returns
    -------
    tuple
        q_GCRS_MF (scalar first) and P^mfa (3×3, MF axes, rad²).

    """
    q = quat_normalize(quat_multiply(q_gcrs_vf, quat_conjugate(sol.q_mf_vf)))
    C = sol.c_mf_vf
    return q, C @ np.asarray(P_avu) @ C.T + sol.rotation_covariance_mf
