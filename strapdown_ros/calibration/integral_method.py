"""
Integral method of gyro calibration from star-tracker attitudes (Ilyushenko 2009, paper 002).

Sensor model s = B·w + s0 (12 parameters; for the package's integrating gyro B = I + M and
s0 = b).  Averaged over K ≥ 4 intervals the model gives B·w̄_i + s0 = s̄_i, solved here by
least squares with the covariance and observability of the 12 parameters; the interval means
come from :mod:`strapdown_ros.calibration.interval_means`.
:func:`calibrate_from_measurements` runs the whole chain on raw gyro increments and camera
fixes.  Derivations and measured properties: doc/integral_method.md.  No ROS; numpy only.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from strapdown_ros.calibration.interval_means import (camera_rate_covariance, gyro_nodes,
                                                      gyro_rate_covariance, IntervalMeans,
                                                      mean_measured_rate, mean_true_rate)
from strapdown_ros.calibration.star_tracker_increments import relative_quaternions
from strapdown_ros.estimation.observability import analyze_information, ObservabilityReport
from strapdown_ros.rotation import (quat_conjugate, quat_multiply, quat_normalize, quat_to_dcm,
                                    quat_to_rotvec)
from strapdown_ros.sensors import SensorErrorModel

__all__ = ['PARAMETER_LABELS', 'IntegralResult', 'aligned_basis', 'calibrate_from_measurements',
           'design_matrix', 'integral_calibration']

#: parameter order of x, covariance and sigma: B row by row, then s0
PARAMETER_LABELS = (tuple(f'B{i}{j}' for i in (1, 2, 3) for j in (1, 2, 3))
                    + ('s0_1', 's0_2', 's0_3'))


@dataclass
class IntegralResult:
    """
    The result of the integral calibration: B, s0, their covariance and observability.

    Attributes
    ----------
    observable : bool
        Every one of the 12 parameters is observable.
    message : str
        The observability verdict in words.
    B : (3, 3) ndarray
        Gyro matrix of s = B·w + s0.
    s0 : (3,) ndarray
        Gyro bias, rad/s.
    covariance : (12, 12) ndarray
        The published covariance, in :data:`PARAMETER_LABELS` order.
    sigma : (12,) ndarray
        √diag of the covariance; inf for unobservable parameters.
    weighting : str
        'residual', 'pooled' or 'model'.
    residuals : (K, 3) ndarray
        s̄ − B w̄ − s0, rad/s.
    residual_rms : float
        RMS of the residuals, rad/s.
    chi2_per_dof : float
        χ²/dof of the model weighting (nan for the others).
    dof : int
        Degrees of freedom of the residuals.
    intervals : IntervalMeans
        The data solved.
    observability : ObservabilityReport
        Observability of the parameters, s0 in units of ``rate_scale``.
    covariance_residual : (12, 12) ndarray or None
        002's σ²(AᵀA)⁻¹ per axis (when K > 4).
    covariance_model : (12, 12) ndarray or None
        (HᵀR⁻¹H)⁻¹ (when the noise is known).
    rate_scale : float
        RMS |w̄| used to scale s0 for the observability report, rad/s.
    unobservable_parameters : list of str
        Labels lying wholly in the unobservable subspace.
    labels : tuple of str
        :data:`PARAMETER_LABELS`.
    extra : dict
        Diagnostics of the chain (errors of w̄ against a known profile, orders used).

    """

    observable: bool
    message: str
    B: np.ndarray
    s0: np.ndarray
    covariance: np.ndarray
    sigma: np.ndarray
    weighting: str
    residuals: np.ndarray
    residual_rms: float
    chi2_per_dof: float
    dof: int
    intervals: IntervalMeans
    observability: ObservabilityReport
    covariance_residual: np.ndarray | None = None
    covariance_model: np.ndarray | None = None
    rate_scale: float = 1.0
    unobservable_parameters: list = field(default_factory=list)
    labels: tuple = PARAMETER_LABELS
    extra: dict = field(default_factory=dict)

    @property
    def x(self) -> np.ndarray:
        """Return the 12 parameters: B row by row, then s0."""
        return np.concatenate([self.B.ravel(), self.s0])

    @property
    def M(self) -> np.ndarray:
        """Return B − I: scale factors on the diagonal, misalignments off it."""
        return self.B - np.eye(3)

    @property
    def bias(self) -> np.ndarray:
        """Return the bias s0, rad/s."""
        return self.s0

    def to_error_model(self):
        """
        Return the estimate as a :class:`~strapdown_ros.sensors.SensorErrorModel`.

        Returns
        -------
        SensorErrorModel
            M = B − I, b = s0.

        """
        M = self.M
        return SensorErrorModel(bias=self.s0.copy(), scale_factor=np.diag(M).copy(),
                                misalignment=M - np.diag(np.diag(M)))

    def correct(self, delta_theta: np.ndarray, period) -> np.ndarray:
        """
        Apply the calibration to increments: u = B⁻¹(Δθ − s0·T).

        Parameters
        ----------
        delta_theta : (n, 3) ndarray
            Gyro increments, rad.
        period : float or (n,) ndarray
            Length T of each increment, s.

        Returns
        -------
        (n, 3) ndarray
            Corrected increments u, rad.

        """
        d = np.asarray(delta_theta, dtype=float)
        T = np.asarray(period, dtype=float)
        biased = d - np.multiply.outer(T, self.s0) if T.ndim else d - self.s0 * T
        return biased @ np.linalg.inv(self.B).T


def design_matrix(w_bar: np.ndarray) -> np.ndarray:
    """
    Return the design matrix H of 002's system.

    Parameters
    ----------
    w_bar : (K, 3) ndarray
        Mean true rates, rad/s.

    Returns
    -------
    (3K, 12) ndarray
        Row 3i+j is s̄_ij = B_j·w̄_i + s0_j in :data:`PARAMETER_LABELS` order.

    """
    w = np.asarray(w_bar, dtype=float).reshape(-1, 3)
    K = len(w)
    H = np.zeros((K, 3, 12))
    for j in range(3):
        H[:, j, 3 * j:3 * j + 3] = w
        H[:, j, 9 + j] = 1.0
    return H.reshape(3 * K, 12)


_AXIS_PARAMS = [np.array([3 * j, 3 * j + 1, 3 * j + 2, 9 + j]) for j in range(3)]


def aligned_basis(V: np.ndarray) -> np.ndarray:
    """
    Return an orthonormal basis of span(V) aligned greedily with the parameter axes.

    Each vector is the normalised projection of the parameter that the remaining subspace
    holds best, so a wholly unobservable parameter comes out as itself (e.g. ``+1.00·B12``).

    Parameters
    ----------
    V : (p, m) ndarray
        Orthonormal columns spanning a subspace of the parameter space.

    Returns
    -------
    (p, m) ndarray
        The aligned basis, sorted by the parameter each vector holds most.

    """
    rest = V.copy()
    out = []
    for _ in range(V.shape[1]):
        P = rest @ rest.T
        i = int(np.argmax(np.diag(P)))
        v = P[:, i] / np.sqrt(P[i, i])
        out.append(v)
        rest = rest - np.outer(v, v @ rest)
        U, S, _ = np.linalg.svd(rest, full_matrices=False)
        rest = U[:, S > 1e-8]
    out.sort(key=lambda v: int(np.argmax(np.abs(v))))
    return np.array(out).T


def _describe(v: np.ndarray) -> str:
    v = v * np.sign(v[np.argmax(np.abs(v))])
    terms = [f'{c:+.2f}·{n}' for c, n in zip(v, PARAMETER_LABELS) if abs(c) >= 0.005]
    return ' '.join(terms) if terms else '0'


def integral_calibration(data: IntervalMeans, weighting: str = 'auto', inflate: bool = True,
                         sigma_limit: float = 1e-2, rel_tol: float = 1e-9,
                         B_nominal: np.ndarray | None = None) -> IntegralResult:
    """
    Solve 002's system B·w̄_i + s0 = s̄_i over K ≥ 4 intervals by least squares.

    Unobservable combinations (``analyze_information`` on the parameters with s0 in units of
    the RMS rate) are left at the nominal value (B = ``B_nominal`` or I, s0 = 0) by a
    minimum-norm solution; their σ is inf.

    Parameters
    ----------
    data : IntervalMeans
        Mean true and measured rates, with their covariances if known.
    weighting : {'auto', 'residual', 'pooled', 'model'}
        'residual': per axis j, A = [w̄ᵀ 1] (K × 4), unweighted least squares, covariance
        σ_j²(AᵀA)⁻¹ with σ_j² = RSS_j/(K − 4) (needs K > 4); 'pooled': the same with one
        σ² = ΣRSS/(3K − 12); 'model': generalised least squares with the full covariance
        R = R_gyro + B R_cam Bᵀ (needs a covariance), covariance (HᵀR⁻¹H)⁻¹; 'auto': model
        when a covariance is present, else residual.
    inflate : bool
        Multiply the model covariance by max(1, χ²/dof).
    sigma_limit : float
        Predicted σ above which a direction counts as unobservable (scaled parameters).
    rel_tol : float
        Relative eigenvalue below which a direction counts as unobservable.
    B_nominal : (3, 3) ndarray, optional
        Nominal B (default I).

    Returns
    -------
    IntegralResult
        B, s0, covariance, residuals and observability; NaN with a message when K < 4.

    """
    w = np.asarray(data.w_bar, dtype=float).reshape(-1, 3)
    s = np.asarray(data.s_bar, dtype=float).reshape(-1, 3)
    K = len(w)
    has_model = data.camera_covariance is not None or data.gyro_covariance is not None
    if weighting == 'auto':
        weighting = 'model' if has_model else 'residual'
    if weighting not in ('residual', 'pooled', 'model'):
        raise ValueError("weighting must be 'auto', 'residual', 'pooled' or 'model', "
                         f'got {weighting!r}')
    if weighting == 'model' and not has_model:
        raise ValueError("weighting='model' needs the camera or gyro covariance "
                         'of the interval means')
    Bn = np.eye(3) if B_nominal is None else np.asarray(B_nominal, dtype=float)
    x_nom = np.concatenate([Bn.ravel(), np.zeros(3)])
    H = design_matrix(w)
    y = s.ravel() - H @ x_nom
    rate_scale = float(np.sqrt(np.mean(np.sum(w * w, axis=1)))) if K else 1.0
    rate_scale = rate_scale if rate_scale > 0 else 1.0
    D = np.concatenate([np.ones(9), np.full(3, rate_scale)])       # x = D·x_scaled

    def nan_result(msg):
        nan12 = np.full(12, np.nan)
        rep = analyze_information(np.zeros((12, 12)), labels=PARAMETER_LABELS)
        return IntegralResult(False, msg, Bn.copy(), np.zeros(3), np.full((12, 12), np.nan),
                              nan12, weighting, np.full((K, 3), np.nan), float('nan'),
                              float('nan'), 0, data, rep, rate_scale=rate_scale)

    if K < 4:
        return nan_result(f'{K} interval(s): 002 needs at least 4')

    A = np.hstack([w, np.ones((K, 1))])
    AtA = A.T @ A
    # --- per-axis residual variance of the unweighted system (002 as printed)
    rss = np.zeros(3)
    for j in range(3):
        r = y[j::3] - A @ np.linalg.lstsq(A, y[j::3], rcond=None)[0]
        rss[j] = r @ r
    var_res = None
    if K > 4:
        var_res = rss / (K - 4) if weighting != 'pooled' else np.full(3, rss.sum() / (3 * K - 12))
        floor = (1e-15 * max(float(np.max(np.abs(s))), 1e-300)) ** 2     # noise-free data
        var_res = np.maximum(var_res, floor)
    # --- whitened system for the chosen weighting
    info_model = None
    if has_model:
        R = np.zeros((3 * K, 3 * K))
        if data.gyro_covariance is not None:
            R += data.gyro_covariance
        if data.camera_covariance is not None:
            # e_i = n_i − B·δw̄_i: the camera part is rotated by B (of the unweighted solution)
            B_est = Bn.copy()
            for j in range(3):
                B_est[j] += np.linalg.lstsq(A, y[j::3], rcond=None)[0][:3]
            BB = np.kron(np.eye(K), B_est)
            R += BB @ data.camera_covariance @ BB.T
        scale = np.sqrt(np.maximum(np.diag(R), 0.0))
        scale = np.where(scale > 0, scale, max(float(scale.max()), 1e-300))
        Hs, ys = H / scale[:, None], y / scale
        X = np.linalg.solve(R / np.outer(scale, scale) + 1e-12 * np.eye(3 * K),
                            np.column_stack([Hs, ys]))
        info_model, g_model = Hs.T @ X[:, :12], Hs.T @ X[:, 12]
        info_model = 0.5 * (info_model + info_model.T)
        yRy_model = float(ys @ X[:, 12])
    if weighting == 'model':
        info, g, yRy = info_model, g_model, yRy_model
    else:
        if var_res is None:
            return nan_result(f'{K} intervals: the residual weighting needs more than 4 '
                              '(no residual degrees of freedom); '
                              "use weighting='model' with the noise known")
        sd = np.tile(np.sqrt(var_res), K)
        Hw, yw = H / sd[:, None], y / sd
        info, g, yRy = Hw.T @ Hw, Hw.T @ yw, float(yw @ yw)
    # --- observability on the scaled parameters (s0 in units of the RMS rate)
    info_scaled = D[:, None] * info * D[None, :]
    rep = analyze_information(info_scaled, labels=PARAMETER_LABELS, rel_tol=rel_tol,
                              sigma_limit=sigma_limit)
    lam, vec = rep.eigenvalues, rep.directions
    bad = (lam <= rel_tol * max(float(lam[-1]), 0.0)) | (rep.predicted_sigma > sigma_limit)
    good = vec[:, ~bad]
    Pg = good @ np.diag(1.0 / lam[~bad]) @ good.T      # pseudo-inverse on the observable subspace
    dx = D * (Pg @ (D * g))                                 # minimum-norm step from the nominal
    chi2_sum = max(yRy - 2.0 * float(dx @ g) + float(dx @ info @ dx), 0.0)   # weighted RSS
    dof = 3 * K - int(np.sum(~bad))
    cov = D[:, None] * Pg * D[None, :]
    if weighting != 'model':
        cov_res = cov.copy()
    elif var_res is not None:          # 002's unweighted σ²(AᵀA)⁻¹, for comparison
        cov_res = np.zeros((12, 12))
        AtA_pinv = np.linalg.pinv(AtA)
        for j in range(3):
            cov_res[np.ix_(_AXIS_PARAMS[j], _AXIS_PARAMS[j])] = var_res[j] * AtA_pinv
    else:
        cov_res = None
    cov_model = None
    if weighting == 'model':
        chi2 = chi2_sum / dof if dof > 0 else float('nan')
        cov_model = cov.copy()
        if inflate and dof > 0:
            cov = cov * max(1.0, chi2)
    else:
        chi2 = float('nan')
        if info_model is not None:
            cov_model = np.linalg.pinv(info_model)
    x = x_nom + dx
    B, s0 = x[:9].reshape(3, 3), x[9:]
    resid = s - w @ B.T - s0
    sigma = np.sqrt(np.maximum(np.diag(cov), 0.0))
    if np.any(bad):
        touched = np.any(np.abs(vec[:, bad]) > 1e-3, axis=1)
    else:
        touched = np.zeros(12, dtype=bool)
    sigma = np.where(touched, np.inf, sigma)
    unobs_params = []
    if np.any(bad):
        # name the unobservable subspace in a parameter-aligned basis
        # (eigh mixes degenerate directions)
        basis = aligned_basis(vec[:, bad])
        rep.unobservable = [_describe(v) for v in basis.T]
        weak = f" (weakly observable: {'; '.join(rep.weak)})" if rep.weak else ''
        rep.message = 'not observable: ' + '; '.join(rep.unobservable) + weak
    if np.any(bad) or rep.weak:
        rep.message += f' [s0 in units of the RMS mean rate {rate_scale:.3g} rad/s]'
        Pu = vec[:, bad] @ vec[:, bad].T
        unobs_params = [PARAMETER_LABELS[i] for i in range(12) if Pu[i, i] > 0.99]
    return IntegralResult(
        observable=rep.observable, message=rep.message, B=B, s0=s0, covariance=cov, sigma=sigma,
        weighting=weighting, residuals=resid, residual_rms=float(np.sqrt(np.mean(resid ** 2))),
        chi2_per_dof=chi2, dof=dof, intervals=data, observability=rep,
        covariance_residual=cov_res, covariance_model=cov_model, rate_scale=rate_scale,
        unobservable_parameters=unobs_params)


# ------------------------------------------------------------------ the whole chain
def calibrate_from_measurements(gyro_stamps: np.ndarray, delta_theta: np.ndarray,
                                camera_stamps: np.ndarray, camera_quats: np.ndarray,
                                camera_sigma=None, *, camera_covariance=None,
                                gyro_random_walk: float = 0.0, order: int = 3,
                                form: str = 'paper', steps_per_interval: int | None = None,
                                interval_length: float | None = None,
                                intervals: np.ndarray | None = None, weighting: str = 'auto',
                                interpolation: str = 'linear',
                                q_body_camera: np.ndarray | None = None, profile=None,
                                inflate: bool = True, sigma_limit: float = 1e-2,
                                neighbour: str = 'previous') -> IntegralResult:
    """
    Run 002 end to end: gyro increments and star-tracker fixes to B, s0 and their covariance.

    Fixes outside the gyro data are dropped.  Without ``intervals``, ``steps_per_interval``
    or ``interval_length`` an interval is 10 camera steps.

    Parameters
    ----------
    gyro_stamps : (n,) ndarray
        Stamps of the integrating-gyro output, s, each at the end of its increment.
    delta_theta : (n, 3) ndarray
        Gyro increments, rad.
    camera_stamps : (N,) ndarray
        Stamps of the fixes, s.
    camera_quats : (N, 4) ndarray
        Fixes q_ref_camera, scalar first.
    camera_sigma : float or (3,) array_like, optional
        1σ per camera axis, rad.
    camera_covariance : (3, 3) or (N, 3, 3) array_like, optional
        Covariance of the fixes, camera axes, rad² (instead of ``camera_sigma``).
    gyro_random_walk : float
        Angle random walk, rad/√s (0: gyro noise not modelled).
    order, form, neighbour
        Inversion of the fixes, see
        :func:`~strapdown_ros.calibration.star_tracker_increments.step_increments`.
    steps_per_interval : int, optional
        Camera steps per averaging interval.
    interval_length : float, optional
        Length of an averaging interval, s.
    intervals : (K, 2) int ndarray, optional
        Explicit fix-index pairs; every fix must lie inside the gyro data.
    weighting : str
        See :func:`integral_calibration`.
    interpolation : {'linear', 'quadratic'}
        See :func:`~strapdown_ros.calibration.interval_means.mean_measured_rate`.
    q_body_camera : (4,) ndarray, optional
        The boresight q_MF_VF; the body attitude is q_ref_camera ⊗ q_body_camera*.
        Default: camera = body.
    profile : MotionProfile, optional
        When given, the exact mean rates are attached (``result.intervals.w_bar_exact``) and
        the error of the star-tracker w̄ against them is reported in ``result.extra``.
    inflate, sigma_limit
        See :func:`integral_calibration`.

    Returns
    -------
    IntegralResult
        B, s0 with covariance and observability.

    """
    cs = np.asarray(camera_stamps, dtype=float)
    cq = quat_normalize(np.asarray(camera_quats, dtype=float).reshape(-1, 4))
    nodes, _ = gyro_nodes(gyro_stamps, delta_theta)
    keep = (cs >= nodes[0] - 1e-9) & (cs <= nodes[-1] + 1e-9)
    if camera_covariance is not None and np.ndim(camera_covariance) == 3:
        camera_covariance = np.asarray(camera_covariance)[keep]
    if intervals is not None and not np.all(keep):
        raise ValueError('explicit intervals need every camera fix inside the gyro data span')
    cs, cq = cs[keep], cq[keep]
    C_bc = None
    if q_body_camera is not None:
        qbc = quat_normalize(np.asarray(q_body_camera, dtype=float))
        cq = quat_multiply(cq, quat_conjugate(qbc))
        C_bc = quat_to_dcm(qbc)
    if intervals is None and steps_per_interval is None and interval_length is None:
        steps_per_interval = 10
    t0, t1, w, iv = mean_true_rate(cs, cq, intervals=intervals, order=order, form=form,
                                   steps_per_interval=steps_per_interval,
                                   interval_length=interval_length, neighbour=neighbour)
    if len(t0):
        s = mean_measured_rate(gyro_stamps, delta_theta, t0, t1, interpolation=interpolation)
    else:
        s = np.zeros((0, 3))
    R_cam = None
    if camera_sigma is not None or camera_covariance is not None:
        R_cam = camera_rate_covariance(cq, iv, cs, camera_sigma, camera_covariance, C_bc)
    R_gyro = gyro_rate_covariance(t0, t1, gyro_random_walk) if gyro_random_walk > 0 else None
    data = IntervalMeans(t0, t1, w, s, R_cam, R_gyro, iv)
    extra = {}
    if profile is not None and len(t0):
        data.w_bar_exact = profile.delta_theta(t0, t1) / (t1 - t0)[:, None]
        err = w - data.w_bar_exact
        extra['w_bar_error_rms'] = float(np.sqrt(np.mean(err ** 2)))
        extra['w_bar_error_max'] = float(np.max(np.abs(err)))
    res = integral_calibration(data, weighting=weighting, inflate=inflate, sigma_limit=sigma_limit)
    dq = relative_quaternions(cq) if len(cq) > 1 else np.zeros((0, 4))
    extra['max_step_rotation'] = 0.0
    if len(dq):
        extra['max_step_rotation'] = float(np.max(np.linalg.norm(quat_to_rotvec(dq), axis=1)))
    extra['order'], extra['form'], extra['neighbour'] = order, form, neighbour
    res.extra.update(extra)
    return res
