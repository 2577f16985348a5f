"""
Gyro errors against a drifting attitude reference (Tkachenko 1983, paper 000): the estimator.

From quaternion increments of a strapdown gyro triad and of a gyrostabilizer whose basis drifts
slowly away from the inertial one, least squares estimate x = [w0, c, d]: the initial attitude
error w0, the gyro errors c and the drift of the reference d, then refine the attitude.  The
normal equations are accumulated row by row (000 (5.8)).  The model (error structures, the
reference, the computed attitude) is in :mod:`strapdown_ros.calibration.drifting_reference_model`,
the rank tests of 000 §3–§4 in :mod:`strapdown_ros.calibration.drifting_reference_observability`.
Conventions, the measurement equation (2.7), the corrections to the print and the choice of
coefficients are derived in doc/drifting_reference.md; the §6 experiment is
:mod:`strapdown_ros.reproductions.tkachenko1983`.  No ROS; numpy only.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import time as _time

import numpy as np

from strapdown_ros.attitude.coning import get_algorithm
from strapdown_ros.calibration.drifting_reference_model import (ErrorStructure,
                                                                integrate_attitude, psi_matrix,
                                                                QUADRATURES,
                                                                SCALE_MISALIGNMENT_BIAS,
                                                                theta_quadrature)
from strapdown_ros.estimation.observability import analyze_information, ObservabilityReport
from strapdown_ros.rotation import (quat_conjugate, quat_multiply, quat_normalize, quat_to_dcm,
                                    rotvec_to_quat, skew)
from strapdown_ros.sensors import increment_correction

__all__ = ['COEFFICIENTS', 'MODES', 'DriftingReferenceSolution', 'NormalEquations',
           'error_at_epochs', 'estimate', 'measurement_rows', 'predicted_reference_increments',
           'quantization_covariance', 'quantization_weight']

MODES = ('raw', 'centred', 'corrected')


# ------------------------------------------------------------------ normal equations (5.8)
class NormalEquations:
    """
    Recursive least-squares accumulation of 000 (5.8), one scalar row at a time.

    ``(UᵀU)_s = (UᵀU)_{s−1} + u_sᵀu_s``, ``(UᵀZ)_s = (UᵀZ)_{s−1} + u_sᵀz_s``; no row is
    stored.  A weighted block (``weight`` = R⁻¹, 3×3) is first whitened with the Cholesky
    factor of R⁻¹, so its three rows are again added one by one.

    Parameters
    ----------
    size : int
        Number of unknowns.

    """

    def __init__(self, size: int):
        self.size = int(size)
        self.UtU = np.zeros((size, size))
        self.UtZ = np.zeros(size)
        self.ZtZ = 0.0
        self.rows = 0

    def add_row(self, u: np.ndarray, z: float) -> None:
        """
        Add one scalar equation u·x = z.

        Parameters
        ----------
        u : (size,) ndarray
            Coefficient row.
        z : float
            Right-hand side.

        """
        u = np.asarray(u, dtype=float)
        self.UtU += np.outer(u, u)
        self.UtZ += u * z
        self.ZtZ += z * z
        self.rows += 1

    def add(self, U: np.ndarray, z: np.ndarray, weight: np.ndarray | None = None) -> None:
        """
        Add a block of equations U·x = z, optionally weighted.

        Parameters
        ----------
        U : (k, size) ndarray
            Coefficient rows.
        z : (k,) ndarray
            Right-hand sides.
        weight : (k, k) ndarray, optional
            R⁻¹ of the block (positive definite).

        """
        U = np.atleast_2d(np.asarray(U, dtype=float))
        z = np.atleast_1d(np.asarray(z, dtype=float))
        if weight is not None:
            L = np.linalg.cholesky(np.asarray(weight, dtype=float))      # W = L Lᵀ
            U, z = L.T @ U, L.T @ z
        for u_s, z_s in zip(U, z):
            self.add_row(u_s, z_s)

    def solve(self, rcond: float = 1e-13) -> np.ndarray:
        """
        Solve ``UᵀU x = UᵀZ`` with column equilibration (the columns differ in units).

        Minimum-norm (pseudo-inverse) when the matrix is singular — an unobservable problem,
        which the observability report flags.

        Parameters
        ----------
        rcond : float
            Relative singular-value cut-off of the equilibrated matrix.

        Returns
        -------
        (size,) ndarray
            x.

        """
        s = np.sqrt(np.maximum(np.diag(self.UtU), 1e-300))
        Ns = self.UtU / np.outer(s, s)
        return np.linalg.lstsq(Ns, self.UtZ / s, rcond=rcond)[0] / s

    def residual_ss(self, x: np.ndarray) -> float:
        """
        Return ``|Ux − Z|²`` from the accumulated sums (no rows needed).

        Parameters
        ----------
        x : (size,) ndarray
            A solution.

        Returns
        -------
        float
            The residual sum of squares.

        """
        x = np.asarray(x, dtype=float)
        return float(max(self.ZtZ - 2.0 * x @ self.UtZ + x @ self.UtU @ x, 0.0))


# ------------------------------------------------------------------ equations
#: Where the coefficients of the first-order equations are evaluated (doc/drifting_reference.md).
COEFFICIENTS = ('identity', 'printed')


def measurement_rows(p_ref: np.ndarray, theta: np.ndarray, psi: np.ndarray,
                     psi0: np.ndarray | None = None,
                     p_computed: np.ndarray | None = None) -> np.ndarray:
    """
    Return the coefficient block of 000 (2.7)/(5.7) for one epoch.

    ``[2Φ(p), ΓΘ, ΓΨ]`` with Γ = ½(p0E3 − Φ(p)).  With ``p_computed`` the coefficients are
    evaluated where the exact quaternion identity puts them ('identity' coefficients): the w0
    columns at the mean ``2Φ(½(p + p*))``, the c columns at ``Γ(p*)``, the d columns at
    ``Γ(p)``.  Without it, everything at the reference p, as printed in 000.  The two agree to
    first order (doc/drifting_reference.md).

    Parameters
    ----------
    p_ref : (4,) ndarray
        The reference increment P, scalar first.
    theta : (3, 3m) ndarray
        Θ(t) at the epoch, s.
    psi : (3, 3n) ndarray
        Ψ(t, t0) at the epoch, s.
    psi0 : (3, 3n) ndarray, optional
        Ψ(t0, t*) when t* < t0: adds ``−Φ(p)Ψ(t0, t*)`` to the d columns.
    p_computed : (4,) ndarray, optional
        The computed increment P*, scalar first.

    Returns
    -------
    (3, 3(1 + m + n)) ndarray
        The three rows of the epoch.

    """
    p0, p = p_ref[0], p_ref[1:]
    F = skew(p)
    gamma = 0.5 * (p0 * np.eye(3) - F)
    dcols = gamma @ psi
    if p_computed is None:
        F_w, gamma_c = F, gamma
    else:
        F_w = skew(0.5 * (p + p_computed[1:]))
        gamma_c = 0.5 * (p_computed[0] * np.eye(3) - skew(p_computed[1:]))
    if psi0 is not None:
        dcols = dcols - F_w @ psi0
    return np.hstack([2.0 * F_w, gamma_c @ theta, dcols])


def quantization_covariance(p_ref: np.ndarray, quantum: float,
                            angle_noise: float = 0.0) -> np.ndarray:
    """
    Return ``R(δz)`` of one equation.

    ``σ²/48·(E3 − ppᵀ)`` (000 §5, corrected; checked by Monte Carlo in the tests) plus a rough
    isotropic term ``½·angle_noise²·E3`` for white noise of the aircraft angles (half-angle
    errors of the two epochs; the t0 part, common to all equations, is not modelled).

    Parameters
    ----------
    p_ref : (4,) ndarray
        The reference increment P, scalar first.
    quantum : float
        Pulse weight σ of the gyro, rad.
    angle_noise : float
        1σ white noise of the aircraft angles, rad.

    Returns
    -------
    (3, 3) ndarray
        R(δz), rad² (half-angle units).

    """
    p = p_ref[1:]
    R = quantum ** 2 / 48.0 * (np.eye(3) - np.outer(p, p))
    if angle_noise > 0:
        R = R + 0.5 * angle_noise ** 2 * np.eye(3)
    return R


def quantization_weight(p_ref: np.ndarray, quantum: float, angle_noise: float = 0.0,
                        min_p0: float = 1e-3) -> np.ndarray:
    """
    Return the weight ``R(δz)⁻¹`` of one equation.

    For pure quantization ``48/σ²·(E3 + ppᵀ/p0²)`` (Sherman–Morrison).

    Parameters
    ----------
    p_ref : (4,) ndarray
        The reference increment P, scalar first.
    quantum : float
        Pulse weight σ of the gyro, rad.
    angle_noise : float
        1σ white noise of the aircraft angles, rad.
    min_p0 : float
        Floor of |p0| in the closed form.

    Returns
    -------
    (3, 3) ndarray
        R(δz)⁻¹.

    """
    p0, p = p_ref[0], p_ref[1:]
    if angle_noise <= 0:
        return 48.0 / quantum ** 2 * (np.eye(3) + np.outer(p, p) / max(p0 * p0, min_p0 ** 2))
    return np.linalg.inv(quantization_covariance(p_ref, quantum, angle_noise))


def _align(P: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Flip quaternions of P onto the hemisphere of ref (both describe the same rotation)."""
    s = np.sign(np.sum(P * ref, axis=-1))
    s[s == 0] = 1.0
    return P * s[..., None]


# ------------------------------------------------------------------ the estimator
@dataclass
class DriftingReferenceSolution:
    """
    The estimate of :func:`estimate`: x = [w0, c, d], its covariance and the refined attitude.

    Attributes
    ----------
    x : ndarray
        [w0, c, d]: half-angle vector (reference axes), gyro errors, reference drift.
    structure : ErrorStructure
        The error structure of x.
    normal : ndarray
        UᵀU of the last linearisation (weighted if weighted).
    covariance : ndarray
        Of x: σ̂²(UᵀU)⁻¹ (unweighted) or (UᵀU)⁻¹ (weighted).
    residual_rms : float
        RMS of z − Ux at the solution, per scalar equation.
    iterations : int
        Gauss–Newton iterations (1 without ``iterate``).
    steps : list of float
        |step|∞ of each iteration.
    observability : ObservabilityReport or None
        Observability of x.
    epochs : (J,) int ndarray
        Sample indices of the equations.
    refined_attitude : (J, 4) ndarray
        Λ̂ at the epochs, scalar first.
    w_epochs : (J, 3) ndarray
        ŵ(t_j), the first-order attitude error at the epochs (zero when iterated).
    equations : int
        Epochs used.
    skipped : int
        Epochs left out (|p0| < min_p0).
    elapsed : float
        Wall time of the estimate, s.

    """

    x: np.ndarray
    structure: ErrorStructure
    normal: np.ndarray
    covariance: np.ndarray
    residual_rms: float
    iterations: int
    steps: list = field(default_factory=list)
    observability: ObservabilityReport | None = None
    epochs: np.ndarray = field(default_factory=lambda: np.zeros(0))
    refined_attitude: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    w_epochs: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    equations: int = 0
    skipped: int = 0
    elapsed: float = 0.0

    @property
    def w0(self):
        """Return w0, the initial attitude error: half-angle vector, reference axes."""
        return self.structure.split(self.x)[0]

    @property
    def c(self):
        """Return the gyro errors c."""
        return self.structure.split(self.x)[1]

    @property
    def d(self):
        """Return the drift coefficients d of the reference."""
        return self.structure.split(self.x)[2]


def _correct_increments(meas, c, structure: ErrorStructure, h: float, t0: float, iters: int = 6):
    """Gyro increments with the error ``D(ω, t)c`` removed: ``θ = θ* − D(θ/h, t_mid)c·h``."""
    if not np.any(c):
        return np.array(meas, dtype=float, copy=True)
    t_mid = t0 + h * (np.arange(len(meas)) + 0.5)
    th = np.array(meas, dtype=float, copy=True)
    for _ in range(iters):           # contraction |c| ~ 1e-3 per pass
        new = meas - np.einsum('nij,j->ni', structure.D(th / h, t_mid), c) * h
        done = np.max(np.abs(new - th)) <= 1e-18
        th = new
        if done:
            break
    return th


def predicted_reference_increments(x, M0, meas, h: float, epochs, structure: ErrorStructure,
                                   algorithm: str = '2', t0: float = 0.0,
                                   t_star: float | None = None):
    """
    Predict the reference increments P at the epochs by the exact nonlinear model.

    ``P̂ = exp(Ψ(t,t*)d)*⊗Λ̂(t)⊗Λ̂(t0)*⊗exp(Ψ(t0,t*)d)`` with Λ̂ integrated from
    ``normalize([1, w0])⊗M(t0)`` with the increments corrected by c.

    Parameters
    ----------
    x : ndarray
        The unknowns [w0, c, d].
    M0 : (4,) ndarray
        The computed attitude M(t0), scalar first.
    meas : (N, 3) ndarray
        Measured increments θ*, rad.
    h : float
        Sample period, s.
    epochs : (J,) int ndarray
        Sample indices of the equations.
    structure : ErrorStructure
        The error structure of x.
    algorithm : str
        Coning algorithm name.
    t0 : float
        Time of the first sample boundary, s.
    t_star : float, optional
        Time at which L is aligned with I, s (default t0).

    Returns
    -------
    P : (J, 4) ndarray
        Predicted reference increments, scalar first.
    Lam : (N + 1, 4) ndarray
        Λ̂ at every sample boundary.
    th : (N, 3) ndarray
        The corrected increments, rad.

    """
    w0, c, d = structure.split(x)
    ts = t0 if t_star is None else t_star
    th = _correct_increments(meas, c, structure, h, t0)
    L0 = quat_multiply(quat_normalize(np.concatenate([[1.0], w0])), M0)
    Lam = integrate_attitude(L0, th, h, algorithm, epochs)
    ep = np.asarray(epochs, dtype=int)
    t_ep = t0 + h * ep
    V = rotvec_to_quat(psi_matrix(structure, t_ep, ts) @ d)
    V0 = rotvec_to_quat(psi_matrix(structure, np.array(t0), ts) @ d)
    computed = quat_multiply(Lam[ep], quat_conjugate(Lam[0]))
    P = quat_multiply(quat_conjugate(V), quat_multiply(computed, V0))
    return P, Lam, th


def estimate(meas, h: float, M0, ref_q0, ref_q, epochs,
             structure: ErrorStructure = SCALE_MISALIGNMENT_BIAS, algorithm: str = '2',
             quadrature: str = 'exact', mode: str = 'raw', quantum: float = 0.0,
             iterate: bool = False, weighted: bool = False, t0: float = 0.0,
             t_star: float | None = None, tol: float = 1e-13, max_iter: int = 12,
             angle_noise: float = 0.0, min_p0: float = 0.05, noise_sigma: float | None = None,
             coefficients: str = 'identity') -> DriftingReferenceSolution:
    """
    Estimate x = [w0, c, d] (000 §2–§5) from gyro increments and reference quaternions.

    Parameters
    ----------
    meas : (N, 3) ndarray
        Measured increments θ* on the grid t0 + k·h (quantized or not), rad.
    h : float
        Sample period, s.
    M0 : (4,) ndarray
        The computed attitude M(t0) (with its unknown error w0), scalar first.
    ref_q0 : (4,) ndarray
        N(φ(t0)), the reference quaternion at t0.
    ref_q : (J, 4) ndarray
        N(φ(t_j)) at the epochs.
    epochs : (J,) int ndarray
        Sample indices of the equations.
    structure : ErrorStructure
        The error structure D, G.
    algorithm : str
        Coning algorithm of the computed attitude.
    quadrature : {'exact', 'trapezoid'}
        Rule for Θ (:func:`~strapdown_ros.calibration.drifting_reference_model.theta_quadrature`).
    mode : {'raw', 'centred', 'corrected'}
        000 (5.4), the centring (5.5), or (5.6) with the increments corrected before use.
    quantum : float
        Pulse weight σ of the gyro, rad (0: not quantized).
    iterate : bool
        Gauss–Newton on the full model (re-integration about the current estimate).
    weighted : bool
        Weight the equations by R(δz)⁻¹ (needs quantum > 0 or angle_noise > 0).
    t0 : float
        Time of the first sample boundary, s.
    t_star : float, optional
        Time at which L is aligned with I, s (default t0).
    tol : float
        Gauss–Newton stops when |step|∞ falls below it.
    max_iter : int
        Limit of Gauss–Newton iterations.
    angle_noise : float
        1σ white noise of the aircraft angles, rad.
    min_p0 : float
        Epochs with |p0| below it are left out.
    noise_sigma : float, optional
        σ of z for the observability report of an unweighted solution (default: the
        quantization σ/√48, else the a-posteriori residual RMS).
    coefficients : {'identity', 'printed'}
        'identity' evaluates the coefficients of (2.7) where the exact identity
        ``p° − q = w0 × (p° + q)`` puts them, 'printed' at the reference increment p as 000
        prints (5.7).  Same cost, same first order; 'printed' leaves the w0² term in z
        (doc/drifting_reference.md).  With ``iterate`` both converge to the same solution.

    Returns
    -------
    DriftingReferenceSolution
        x, its covariance and observability, and the refined attitude at the epochs.

    Raises
    ------
    ValueError
        An unknown mode, quadrature or coefficients, or a mode or weighting that needs noise
        that is not given.

    """
    t_start = _time.perf_counter()
    if mode not in MODES:
        raise ValueError(f"unknown mode {mode!r}; valid: {', '.join(MODES)}")
    if quadrature not in QUADRATURES:
        raise ValueError(f"unknown quadrature {quadrature!r}; valid: {', '.join(QUADRATURES)}")
    if coefficients not in COEFFICIENTS:
        raise ValueError(f'unknown coefficients {coefficients!r}; '
                         f"valid: {', '.join(COEFFICIENTS)}")
    if mode != 'raw' and not quantum > 0:
        raise ValueError(f'mode {mode!r} needs quantum > 0')
    if weighted and not (quantum > 0 or angle_noise > 0):
        raise ValueError('weighted=True needs quantum > 0 or angle_noise > 0 (R(δz) would be 0)')
    meas = np.asarray(meas, dtype=float)
    epochs = np.asarray(epochs, dtype=int)
    ts = t0 if t_star is None else float(t_star)
    per = get_algorithm(algorithm).samples
    if mode == 'corrected':
        meas_used, _ = increment_correction(meas, quantum)
    else:
        meas_used = meas
    t_ep = t0 + h * epochs
    psi = psi_matrix(structure, t_ep, t0)
    psi0 = psi_matrix(structure, np.array(t0), ts) if ts < t0 else None
    # reference increments P (sign: the hemisphere of the computed increment)
    N0 = np.asarray(ref_q0, dtype=float)
    P_ref = quat_multiply(np.asarray(ref_q, dtype=float), quat_conjugate(N0))
    signs = np.sign(meas[np.clip(epochs - 1, 0, len(meas) - 1)])      # ρ*: sign θ*_{i,k} at t_j
    p = structure.size
    x = np.zeros(p)
    steps = []
    ne = None
    it = 0
    keep = np.abs(P_ref[:, 0]) >= min_p0
    while True:
        P_hat, Lam, th = predicted_reference_increments(x, M0, meas_used, h, epochs, structure,
                                                        algorithm, t0, ts)
        P = _align(P_ref, P_hat)
        Theta = theta_quadrature(Lam, th, h, structure, quadrature, per, t0)
        C_ep = quat_to_dcm(Lam[epochs])
        ne = NormalEquations(p)
        for j in range(len(epochs)):
            if not keep[j]:
                continue
            U = measurement_rows(P[j], Theta[epochs[j]], psi[j], psi0,
                                 P_hat[j] if coefficients == 'identity' else None)
            z = P_hat[j, 1:] - P[j, 1:]
            if mode == 'centred':
                p0j, pj = P[j, 0], P[j, 1:]
                z = z + 0.25 * quantum * (p0j * np.eye(3) - skew(pj)) @ C_ep[j] @ signs[j]
            W = quantization_weight(P[j], quantum, angle_noise) if weighted else None
            ne.add(U, z, W)
        step = ne.solve()
        x = x + step
        it += 1
        steps.append(float(np.max(np.abs(step))))
        diverging = it > 2 and steps[-1] >= steps[-2]
        if not iterate or steps[-1] < tol or it >= max_iter or diverging:
            break
    # refined attitude at the epochs
    w0, c, d = structure.split(x)
    if iterate:
        _, Lam_hat, _ = predicted_reference_increments(x, M0, meas_used, h, epochs, structure,
                                                       algorithm, t0, ts)
        refined = Lam_hat[epochs]
        w_ep = np.zeros((len(epochs), 3))
    else:
        # 000 (2.4): Λ ≈ (1 + w(t))∘M(t), w(t) = w0 − ½Θ(t)c, first order, unrefined pass
        w_ep = w0 - 0.5 * np.einsum('nij,j->ni', Theta[epochs], c)
        M_ep = Lam[epochs]
        if mode == 'centred':
            # the same model as the centred residual: M ≈ (1 + ¼σBᵀρ*)M*
            cq = 0.25 * quantum * np.einsum('nij,nj->ni', C_ep, signs)
            q_cq = quat_normalize(np.concatenate([np.ones((len(cq), 1)), cq], 1))
            M_ep = quat_multiply(q_cq, M_ep)
        q_w = quat_normalize(np.concatenate([np.ones((len(w_ep), 1)), w_ep], 1))
        refined = quat_multiply(q_w, M_ep)
    # statistics of the last linearisation (about the final estimate when iterated)
    rss = ne.residual_ss(step)
    dof = max(ne.rows - p, 1)
    inv = np.linalg.pinv(ne.UtU, rcond=1e-15, hermitian=True)
    if weighted:
        cov = inv
        info = ne.UtU
    else:
        s2 = rss / dof
        if noise_sigma is not None:
            sz2 = noise_sigma ** 2
        elif quantum > 0:
            sz2 = quantum ** 2 / 48.0
        else:
            sz2 = max(s2, 1e-32)
        cov = s2 * inv
        info = ne.UtU / sz2
    rep = analyze_information(info, labels=structure.labels)
    return DriftingReferenceSolution(
        x=x, structure=structure, normal=ne.UtU, covariance=cov,
        residual_rms=float(np.sqrt(rss / max(ne.rows, 1))), iterations=it, steps=steps,
        observability=rep, epochs=epochs, refined_attitude=refined, w_epochs=w_ep,
        equations=int(keep.sum()), skipped=int((~keep).sum()),
        elapsed=_time.perf_counter() - t_start)


def error_at_epochs(refined: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """
    Return the error w⁰ of a refined attitude: the vector part of ``Λ⊗Λ̂*`` with scalar ≥ 0.

    Parameters
    ----------
    refined : (..., 4) ndarray
        The refined attitude Λ̂, scalar first.
    truth : (..., 4) ndarray
        The true attitude Λ, scalar first.

    Returns
    -------
    (..., 3) ndarray
        w⁰, half-angle vector in reference axes.

    """
    e = quat_multiply(truth, quat_conjugate(refined))
    e = np.where(e[..., :1] < 0, -e, e)
    return e[..., 1:]
