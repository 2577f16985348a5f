"""
Boresight of a star camera (VF) relative to the IMU (MF) from attitude increments
(Vasilyuk et al. 2024; paper 004).

Pipeline (004 §2–§5):

1. :func:`gyro_increment` — ΔS_imu over [t_{E,n−1}, t_{E,n}] from asynchronous gyro increments
   with the in-interval polynomial r_k(τ) at both ends (§2.2), and its covariance E_imu by
   the recursion (2) (§2.3).
2. :func:`camera_increment` — ΔS_avu = (S_{n−1})ᵀ S_n and E_avu = P_n + ΔSᵀ P_{n−1} ΔS (§3.3).
3. :func:`solve_boresight` — Gauss–Newton on β = (ψ, ϑ, γ) with the residual of (5)–(6) and a
   central-difference Jacobian (§4.2), stopping at |Δβ| ≤ 1e-9 rad; covariance P_β from the
   residuals (§4.3) or, weighted, from E_imu and E_avu (the weighting 004 names as future work).
4. :func:`imu_attitude_from_camera` — S_GCRS^MF = S_GCRS^VF (C_MF^VF)ᵀ and P^mfa of eq. (8).

Conventions: ``C = C_MF^VF`` maps VF coordinates to MF coordinates (ypr_to_dcm(β)); ΔS_imu
maps MF at t_n to MF at t_{n−1}; errors are right-perturbations in the local axes.

Two remarks on the printed formulas, with evidence in ``test/calibration/test_boresight.py``:

* §2.2 r_0k(τ): the ρ·Δρ term is ``−(ρ·Δρ)/8 (τ³/T³ − τ²/T²)`` (from |θ(τ)|²/8 with
  θ(τ) = ρτ/T + Δρ/2 (τ²/T² − τ/T)); the printed /4 enlarges the partial-interval error
  (``test/calibration/test_boresight.py`` measures by how much).
* §4.2 starts Gauss–Newton from a given β0 (``init="given"``); ``test/calibration/test_boresight.py`` checks
  its convergence from β0 = 0 over random boresights, including pitch near ±90°, and
  ``reproduce_seeds`` records the iteration counts (doc/seeds/reproduce_seeds.md, 004).  By default the
  solver first aligns the rotation axes in closed form (the rotation vectors satisfy
  log ΔS_imu = C log ΔS_avu; least squares over C is Wahba's problem, solved by SVD), which needs
  no β0 at all and leaves Gauss–Newton only the small nonlinear remainder.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from strapdown_ros.estimation.chi_square import chi2_band, FIT_LEVEL
from strapdown_ros.estimation.observability import analyze_information, ObservabilityReport
from strapdown_ros.rotation import (dcm_to_quat, dcm_to_ypr, quat_conjugate, quat_cumprod,
                                    quat_multiply, quat_normalize, quat_to_dcm, quat_to_rotvec,
                                    ypr_error_to_rotation, ypr_to_dcm)
from strapdown_ros.sensors import SensorSigmas
from strapdown_ros.sensors.covariance import (constant_jacobian, constant_variances,
                                              get_covariance_model)

__all__ = ['IncrementPair', 'angle_consistency',
           'gyro_increment', 'camera_increment', 'BoresightSolution', 'solve_boresight',
           'check_observability', 'imu_attitude_from_camera', 'r_partial']



# --------------------------------------------------------------------------- §2.2 ΔS_imu
def r_partial(rho: np.ndarray, drho: np.ndarray, x: np.ndarray) -> np.ndarray:
    """
    004 §2.2: unnormalised quaternion of the rotation over the first fraction x = τ/T of an
    IMU interval with increment ρ (Δρ = ρ − ρ_prev), from a rate linear in time.
    """
    rho, drho = np.atleast_2d(rho), np.atleast_2d(drho)
    x = np.asarray(x, dtype=float).reshape(-1, 1)
    r2 = np.sum(rho * rho, axis=1, keepdims=True)
    rd = np.sum(rho * drho, axis=1, keepdims=True)
    r0 = 1.0 - r2 / 8.0 * x ** 2 - rd / 8.0 * (x ** 3 - x ** 2)
    rv = rho / 2.0 * (x - r2 / 24.0 * x ** 3) + drho / 4.0 * (x ** 2 - x) + np.cross(rho, drho) / 24.0 * x ** 3
    return np.concatenate([r0, rv], axis=1)


def gyro_increment(stamps: np.ndarray, delta_theta: np.ndarray, t_start: float, t_end: float,
                   gyro: SensorSigmas | None = None, covariance_model: str = 'random_constant',
                   sensitivity: bool = False):
    """
    ΔS_imu (quaternion, MF(t_end) → MF(t_start)) and E_imu (3×3, MF axes at t_end).

    With ``sensitivity=True`` (and ``gyro`` given) two more items are returned: G (3×12), the
    sensitivity of the error ε_imu to the gyro constants x = [b (3), vec M (9, column-major)]
    (MF axes at t_end), and the white part of E_imu (random walk only).  They let the
    estimator treat the constants as common to all pairs (``weighting="correlated"``).

    ``stamps`` are the end times of the increments ``delta_theta`` (sorted).  Needs the
    increment whose interval contains ``t_end``; returns None when it has not arrived.
    The interval length T of each increment is the difference of its stamps.
    """
    stamps = np.asarray(stamps, dtype=float)
    dth = np.asarray(delta_theta, dtype=float)
    if len(stamps) < 2 or t_end <= t_start:
        return None
    k0 = int(np.searchsorted(stamps, t_start, side='right'))       # first increment ending after t_start
    k1 = int(np.searchsorted(stamps, t_end, side='left'))          # first increment ending at/after t_end
    if k0 < 1 or k1 >= len(stamps):
        return None                                                 # need one increment before, one after
    T = np.diff(stamps)[k0 - 1:k1]                                  # lengths of intervals k0..k1
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
        factors = np.vstack([quat_multiply(quat_conjugate(head), full[0])[None], full[1:-1], tail[None]])
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
        W = np.einsum('kij,kjl,kml->im', C, model.white(rho, T, gyro), C)      # Σ C_k Q_k C_kᵀ
        var = model.constant_variances(gyro)
        if np.any(var > 0) or sensitivity:
            J = np.einsum('kij,kjl->il', C, constant_jacobian(rho, T))         # Σ C_k ∂ρ_k/∂x
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


def camera_increment(q_prev: np.ndarray, P_prev: np.ndarray, q_next: np.ndarray, P_next: np.ndarray):
    """ΔS_avu = S_{n−1}ᵀ S_n (VF(t_n) → VF(t_{n−1})) and E_avu = P_n + ΔSᵀ P_{n−1} ΔS (004 §3.3)."""
    dq = quat_normalize(quat_multiply(quat_conjugate(q_prev), q_next))
    dS = quat_to_dcm(dq)
    return dq, np.asarray(P_next) + dS.T @ np.asarray(P_prev) @ dS


@dataclass
class IncrementPair:
    t_start: float
    t_end: float
    dq_imu: np.ndarray          # ΔS_imu
    dq_cam: np.ndarray          # ΔS_avu
    cov_imu: np.ndarray         # E_imu, MF axes
    cov_cam: np.ndarray         # E_avu, VF axes
    # optional, for weighting="correlated": gyro constants' sensitivity G (3×12) and the white
    # part of E_imu, and the covariances of the two camera fixes (adjacent pairs share a fix)
    imu_sensitivity: np.ndarray | None = None
    cov_imu_white: np.ndarray | None = None
    cov_fix_start: np.ndarray | None = None
    cov_fix_end: np.ndarray | None = None

    @property
    def angle(self) -> float:
        return float(np.linalg.norm(quat_to_rotvec(self.dq_cam)))


def angle_consistency(pair: IncrementPair) -> tuple[float, float]:
    """
    φ_avu − φ_imu of a pair and its predicted σ (rad).  Rotation angles do not depend on the
    boresight, so this judges a pair before (and whatever) the boresight fit says (004 Fig. 2a).
    σ² = k_avuᵀ E_avu k_avu + k_imuᵀ E_imu k_imu with k the unit rotation axes (the angle error
    is the error component along the axis); below 1e-9 rad the mean diagonal stands in.
    """
    out, var = [], 0.0
    for dq, E in ((pair.dq_cam, pair.cov_cam), (pair.dq_imu, pair.cov_imu)):
        rv = quat_to_rotvec(dq)
        a = float(np.linalg.norm(rv))
        out.append(a)
        var += float(rv @ E @ rv) / a ** 2 if a > 1e-9 else float(np.trace(E)) / 3.0
    return out[0] - out[1], float(np.sqrt(max(var, 0.0)))


# ---------------------------------------------------------------------- §4 the estimate
@dataclass
class BoresightSolution:
    observable: bool
    message: str
    beta: np.ndarray | None = None                 # (ψ, ϑ, γ), rad
    c_mf_vf: np.ndarray | None = None
    covariance_beta: np.ndarray | None = None      # P_β, rad² (the one published)
    covariance_beta_residual: np.ndarray | None = None   # 004 §4.3 sandwich
    covariance_beta_model: np.ndarray | None = None      # (Hᵀ W H)⁻¹ from E_imu, E_avu
    rotation_covariance_mf: np.ndarray | None = None     # P^clb = D2 P_β D2ᵀ (MF axes)
    weighted: bool = False
    weighting: str = 'unit'
    iterations: int = 0
    converged: bool = False
    residual_rms: float = float('nan')             # rad, RMS of the residual components
    chi2_per_dof: float = float('nan')             # Σ fᵀ W f / dof, stated noise, any weighting
    dof: int = 0                                   # 3n − 3
    chi2_band: tuple = (float('nan'), float('nan'))   # chi2_band(dof, FIT_LEVEL)
    #: χ²/dof inside its band: the stated noise explains the residuals.  False: the stated noise
    #: is wrong or the model lacks an effect, and covariance_beta is scaled by χ²/dof when > 1
    fit_consistent: bool | None = None
    covariance_beta_stated: np.ndarray | None = None   # P_β from the stated noise alone (unscaled)
    pairs: int = 0
    observability: ObservabilityReport | None = None
    unobservable_axes: list = field(default_factory=list)

    @property
    def q_mf_vf(self) -> np.ndarray:
        return dcm_to_quat(self.c_mf_vf)


def _stack(pairs):
    A_imu = quat_to_dcm(np.array([p.dq_imu for p in pairs]))
    A_cam = quat_to_dcm(np.array([p.dq_cam for p in pairs]))
    E_imu = np.array([p.cov_imu for p in pairs])
    E_cam = np.array([p.cov_cam for p in pairs])
    return A_imu, A_cam, E_imu, E_cam


def increment_residuals(C: np.ndarray, A_imu: np.ndarray, A_cam: np.ndarray) -> np.ndarray:
    """f_n of 004 (5)–(6): the skew part of ΔS_avuᵀ Cᵀ ΔS_imu C − I, (n, 3)."""
    F = np.swapaxes(A_cam, 1, 2) @ (C.T @ A_imu @ C)
    return 0.5 * np.stack([F[:, 2, 1] - F[:, 1, 2], F[:, 0, 2] - F[:, 2, 0], F[:, 1, 0] - F[:, 0, 1]], axis=1)


def axis_alignment(A_imu, A_cam) -> np.ndarray:
    """Closed-form C from the rotation vectors: min Σ |log ΔS_imu − C log ΔS_avu|² (Wahba/SVD)."""
    u = quat_to_rotvec(dcm_to_quat(A_imu))
    v = quat_to_rotvec(dcm_to_quat(A_cam))
    B = u.T @ v
    U, _, Vt = np.linalg.svd(B)
    d = np.sign(np.linalg.det(U @ Vt))
    return U @ np.diag([1.0, 1.0, d]) @ Vt


def check_observability(pairs, c_mf_vf: np.ndarray | None = None, weights: np.ndarray | None = None,
                        min_rotation: float = np.radians(0.5), axis_tolerance: float = np.radians(2.0),
                        max_sigma: float = 1e-3) -> ObservabilityReport:
    """
    004 §4.1 and the conditioning of the normal matrix, in VF rotation axes.

    Near the solution the residual of pair n responds to a small rotation δ of C (VF axes)
    as f_n = (I − R_nᵀ) δ with R_n = ΔS_avu,n; the normal matrix is Σ (I − R_n) W_n (I − R_nᵀ)
    = Σ 2(1 − cos φ_n)(I − k_n k_nᵀ) for unit weights: a rotation about an axis k_n says
    nothing about rotations of C about k_n.  Reported unobservable: directions whose
    predicted σ exceeds ``max_sigma`` (rad) or whose eigenvalue vanishes.
    """
    _, A_cam, E_imu, E_cam = _stack(pairs)
    I3 = np.eye(3)
    H = I3 - np.swapaxes(A_cam, 1, 2)
    if weights is None:
        W = np.broadcast_to(I3, H.shape)
        scale = max(np.sqrt(np.mean([np.trace(e) / 3 for e in E_cam])), 1e-12)   # noise scale for σ
        W = W / scale ** 2
    else:
        W = weights
    N = np.einsum('nji,njk,nkl->il', H, W, H)

    def describe(v):
        v = v * np.sign(v[np.argmax(np.abs(v))])
        return f'rotation about VF axis ({v[0]:.2f}, {v[1]:.2f}, {v[2]:.2f})'
    rep = analyze_information(N, describe=describe, sigma_limit=max_sigma)
    # the necessary condition of 004 §4.1, in words
    rv = quat_to_rotvec(np.array([p.dq_cam for p in pairs]))
    ang = np.linalg.norm(rv, axis=1)
    big = ang >= min_rotation
    if not np.any(big):
        why = f'no rotation above {np.degrees(min_rotation):.2g}° between exposures (static motion)'
    else:
        k = rv[big] / ang[big, None]
        spread = np.max(np.arccos(np.clip(np.abs(k @ k.T), -1, 1)))
        why = 'all increments share one axis' if spread < axis_tolerance else ''
    if why and rep.observable:
        # the conditioning may pass on noise alone; the necessary condition still fails
        rep.observable = False
        rep.unobservable = [describe(rep.directions[:, 0])]
    if not rep.observable:
        if why.startswith('no rotation'):
            rep.message = f'boresight not observable: {why}; weakest: {rep.unobservable[0]}'
        else:
            rep.message = f'{rep.unobservable[0]} not observable' + (f': {why}' if why else
                                                                     f': predicted σ {rep.predicted_sigma[0]:.2g} rad')
    return rep


WEIGHTINGS = ('unit', 'pairwise', 'correlated', 'auto')
#: "auto" uses the correlated (dense) solution up to this many pairs, pairwise weights beyond
CORRELATED_MAX_PAIRS = 200       # a warm update stays under ~30 ms (dense 600×600 solve)


def _correlated_covariance(C, pairs, A_cam, E_cam, gyro: SensorSigmas) -> np.ndarray:
    """
    Covariance (3n×3n) of the stacked residuals f_n ≈ Cᵀε_imu,n − ε_avu,n.

    * diagonal blocks: Cᵀ E_imu,white C + E_avu;
    * adjacent pairs sharing a camera fix θ_n: cov(f_n, f_{n+1}) = −P_n R_{n+1}, since
      ε_avu,n = θ_n − R_nᵀ θ_{n−1} (004 §3.3) and R_{n+1} = ΔS_avu,n+1;
    * the gyro constants x = [b, vec M], common to all pairs: U P_x Uᵀ with U_n = Cᵀ G_n.
    """
    n = len(pairs)
    Sig = np.zeros((3 * n, 3 * n))
    U = np.zeros((3 * n, 12))
    for k, p in enumerate(pairs):
        sl = slice(3 * k, 3 * k + 3)
        Sig[sl, sl] = C.T @ p.cov_imu_white @ C + E_cam[k]
        U[sl] = C.T @ p.imu_sensitivity
        if k + 1 < n and p.cov_fix_end is not None and abs(pairs[k + 1].t_start - p.t_end) < 1e-9:
            cross = -p.cov_fix_end @ A_cam[k + 1]
            Sig[sl, 3 * k + 3:3 * k + 6] = cross
            Sig[3 * k + 3:3 * k + 6, sl] = cross.T
    return Sig + (U * constant_variances(gyro)) @ U.T


def solve_boresight(pairs, beta0=(0.0, 0.0, 0.0), weighted: bool = True, init: str = 'axes',
                    max_iterations: int = 50, tolerance: float = 1e-9, dx: float = 1e-7,
                    max_sigma: float = 1e-3, min_rotation: float = np.radians(0.5),
                    common_rotation_sigma: float = 0.0, weighting: str | None = None,
                    gyro: SensorSigmas | None = None) -> BoresightSolution:
    """
    Estimate β and its covariance from increment pairs (004 §4), or report why not.

    init: ``"axes"`` starts Gauss–Newton from the closed-form axis alignment (independent of
    β0, 1–2 iterations); ``"given"`` starts from ``beta0`` exactly as 004 §4.2.
    common_rotation_sigma: σ (rad, per axis) of a rotation of the gyro triad common to all
    pairs.  The antisymmetric part of the gyro misalignment matrix rotates the whole triad
    relative to MF; every ΔS_imu turns with it, so it is indistinguishable from the boresight
    and never averages out.  For independent off-diagonal misalignments of σ_φ it is
    σ_φ/√2 per axis.  It is added to the published covariance (MF axes: σ²I; β: D2⁻¹σ²D2⁻ᵀ);
    without it the weighted covariance is overconfident (boresight_bench: mean NEES 5.1 → 2.95).
    weighting: ``"unit"`` (004), ``"pairwise"`` (each pair by Cᵀ E_imu C + E_avu, independent
    pairs), ``"correlated"`` (generalised least squares with the full residual covariance of
    :func:`_correlated_covariance`: shared camera fixes and gyro constants common to all pairs;
    needs ``gyro`` and pairs carrying sensitivities, O(n³)), or ``"auto"`` (correlated when
    possible and n ≤ CORRELATED_MAX_PAIRS, else pairwise).  Default: pairwise if ``weighted``
    else unit.  The correlated covariance contains the gyro-triad rotation itself, so
    ``common_rotation_sigma`` is not added to it.
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
    rep = check_observability(pairs, min_rotation=min_rotation, max_sigma=max_sigma)
    if not rep.observable:
        return BoresightSolution(False, rep.message, pairs=n, observability=rep,
                                 unobservable_axes=[u for u in rep.unobservable])
    beta = np.asarray(beta0, dtype=float).copy()
    if init == 'axes':
        beta = dcm_to_ypr(axis_alignment(A_imu, A_cam))
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
            Sig = _correlated_covariance(C, pairs, A_cam, E_cam, gyro)
            Hs = H.reshape(-1, 3)
            WH_Wf = np.linalg.solve(Sig, np.hstack([Hs, f.reshape(-1, 1)]))
            N = Hs.T @ WH_Wf[:, :3]
            g = Hs.T @ WH_Wf[:, 3]
            return C, f, H, Sig, None, N, g, float(f.reshape(-1) @ WH_Wf[:, 3])
        W = weights(C)
        HtW = np.einsum('nji,njk->nik', H, W)
        g = np.einsum('nij,nj->i', HtW, f)
        return C, f, H, W, HtW, np.einsum('nij,njk->ik', HtW, H), g, float(np.einsum('ni,nij,nj->', f, W, f))

    def frozen_cost(lin, f_t):
        """
        fᵀ W f of residuals f_t with the weights of the linearisation ``lin`` (the cost the
        Gauss–Newton step of ``lin`` descends).
        """
        if weighting == 'correlated':
            return float(f_t.reshape(-1) @ np.linalg.solve(lin[3], f_t.reshape(-1)))
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
    sol = BoresightSolution(
        observable=True, message='observable' if converged else f'not converged after {it} iterations',
        beta=beta_wrapped, c_mf_vf=C, covariance_beta=P, covariance_beta_residual=P_res,
        covariance_beta_model=P_model, rotation_covariance_mf=D2 @ P @ D2.T, weighted=weighted,
        weighting=weighting,
        iterations=it, converged=converged, residual_rms=float(np.sqrt(np.mean(f ** 2))), chi2_per_dof=chi2,
        dof=dof, chi2_band=band, fit_consistent=consistent, covariance_beta_stated=P_model,
        pairs=n, observability=rep)
    return sol


def imu_attitude_from_camera(q_gcrs_vf: np.ndarray, P_avu: np.ndarray, sol: BoresightSolution):
    """004 §5: S_GCRS^MF = S_GCRS^VF (C_MF^VF)ᵀ and P^mfa = C P^avu Cᵀ + D2 P_β D2ᵀ (eq. 8), MF axes."""
    q = quat_normalize(quat_multiply(q_gcrs_vf, quat_conjugate(sol.q_mf_vf)))
    C = sol.c_mf_vf
    return q, C @ np.asarray(P_avu) @ C.T + sol.rotation_covariance_mf
