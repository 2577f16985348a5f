"""
Gyro scale factors, misalignments and biases from a recording: 000 and 002 on real data.

The numerical core of ``calibrate_gyro_bag`` (no ROS imports), after Tkachenko 1983 (000) and
Ilyushenko 2009 (002).  The input is a
:class:`~strapdown_ros.discrepancy.linearisation.Recording` — gyro increments and star-camera
attitudes q_GCRS_VF with their covariances, stamps in seconds, gyro gaps — as the offline tools
read it from a bag.  Two estimators, both the package's library code: ``integral`` (002,
:mod:`strapdown_ros.calibration.integral_method`) and ``tkachenko`` (000, the drifting
reference, :mod:`strapdown_ros.calibration.drifting_reference`, with the covariance of the
equations built from the recording's own noise).  Both publish the common parameters
(:data:`COMMON_LABELS`: diag(M), the symmetric part of the off-diagonal M, the bias; the
reference drift with ``drift``), the ones the effect registry compensates; the antisymmetric
part of M, a rotation of the whole triad, is reported, not estimated as a gyro parameter.
Methods, parameters and Monte Carlo results: doc/results/calibrate_gyro_bag/gyro_bag.md.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from strapdown_ros.calibration.boresight import axis_alignment
from strapdown_ros.calibration.drifting_reference import (estimate, measurement_rows,
                                                          predicted_reference_increments)
from strapdown_ros.calibration.drifting_reference_model import (ErrorStructure, identity_G,
                                                                psi_matrix,
                                                                scale_misalignment_bias_D,
                                                                theta_quadrature)
from strapdown_ros.calibration.integral_method import aligned_basis, calibrate_from_measurements
from strapdown_ros.calibration.interval_means import interval_boundaries
from strapdown_ros.calibration.pairs import build_pairs, GyroRecord
from strapdown_ros.estimation.chi_square import chi2_band, FIT_LEVEL
from strapdown_ros.estimation.observability import analyze_information, ObservabilityReport
from strapdown_ros.rotation import (dcm_to_quat, quat_conjugate, quat_multiply, quat_normalize,
                                    quat_to_dcm, quat_to_rotvec, skew)
from strapdown_ros.sensors.effects import EFFECTS, GyroEffects
from strapdown_ros.sensors.gyro_effects import MISALIGNMENT_INDEX

__all__ = ['COMMON_LABELS', 'DRIFT_LABELS', 'ESTIMATED_PARAMETERS', 'MAX_EQUATIONS',
           'GyroCalibration', 'Prepared', 'calibrate_drifting_reference', 'calibrate_integral',
           'drifting_reference_noise_covariance', 'model_parameters', 'prepare']

COMMON_LABELS = ('scale_x', 'scale_y', 'scale_z', 'mis_xy', 'mis_xz', 'mis_yz',
                 'bias_x', 'bias_y', 'bias_z')
DRIFT_LABELS = ('drift_x', 'drift_y', 'drift_z')
#: effect parameters this calibration determines (the model's values are replaced, not added to)
ESTIMATED_PARAMETERS = ('gyro_scale_factor', 'gyro_misalignment', 'gyro_bias')
#: at most this many equations (fixes, 002 intervals): their noise covariance is a dense matrix
MAX_EQUATIONS = 1500
_SYM = ((0, 1), (0, 2), (1, 2))                 # (row, column) of mis_xy, mis_xz, mis_yz


@dataclass
class GyroCalibration:
    """
    The gyro calibration of a recording by one method, in the common parameters.

    Attributes
    ----------
    method : str
        'integral' or 'tkachenko' (the command-line names).
    observable : bool
        Every published parameter is observable; otherwise ``x`` is NaN.
    message : str
        The observability verdict in words.
    x : ndarray
        Estimate in ``labels`` order, SI units.
    covariance : ndarray
        Covariance of x, scaled by max(1, χ²/dof).
    labels : tuple of str
        :data:`COMMON_LABELS`, plus :data:`DRIFT_LABELS` with a drift.
    observability : ObservabilityReport
        Observability with biases and drifts in units of ``rate_scale``.
    unobservable : list of str
        Named unobservable combinations (scaled units).
    rate_scale : float
        RMS rate of the recording, rad/s: the unit of biases and drifts in the report.
    extra : dict
        Diagnostics: equations, χ²/dof and its band, the triad rotation, w0.

    """

    method: str
    observable: bool
    message: str
    x: np.ndarray
    covariance: np.ndarray
    labels: tuple
    observability: ObservabilityReport
    unobservable: list = field(default_factory=list)
    rate_scale: float = 1.0
    extra: dict = field(default_factory=dict)

    @property
    def sigma(self) -> np.ndarray:
        """Return the 1σ of x (√diag of the covariance)."""
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))

    def value(self, name: str) -> float:
        """
        Return one parameter of the estimate.

        Parameters
        ----------
        name : str
            A label, e.g. 'scale_x'.

        Returns
        -------
        float
            Its value, SI units.

        """
        return float(self.x[self.labels.index(name)])

    @property
    def scale(self) -> np.ndarray:
        """Return the scale-factor errors, diag(M)."""
        return self.x[0:3]

    @property
    def misalignment_matrix(self) -> np.ndarray:
        """Return the off-diagonal M (symmetric), diagonal zero."""
        M = np.zeros((3, 3))
        for v, (i, j) in zip(self.x[3:6], _SYM):
            M[i, j] = M[j, i] = v
        return M

    @property
    def bias(self) -> np.ndarray:
        """Return the gyro bias b, rad/s (gyro axes)."""
        return self.x[6:9]

    @property
    def drift(self):
        """Return the reference drift d, rad/s (reference axes), or None without a drift."""
        return self.x[9:12] if len(self.x) > 9 else None


def model_parameters(cal: GyroCalibration) -> dict:
    """
    Return the estimate as effect parameters of the registry (what sins_node compensates).

    Parameters
    ----------
    cal : GyroCalibration
        An observable calibration.

    Returns
    -------
    dict
        'gyro_scale_factor', 'gyro_misalignment' and 'gyro_bias' as lists of floats, and each
        effect's σ key (its registry ``sigma_parameter``): the largest σ of its components.

    """
    M = cal.misalignment_matrix
    sig = cal.sigma
    out = {'gyro_scale_factor': [float(v) for v in cal.scale],
           'gyro_misalignment': [float(M[i, j]) for i, j in MISALIGNMENT_INDEX],
           'gyro_bias': [float(v) for v in cal.bias]}
    for name, part in (('gyro_scale_factor', sig[0:3]), ('gyro_misalignment', sig[3:6]),
                       ('gyro_bias', sig[6:9])):
        out[EFFECTS[name].sigma_parameter] = float(np.max(part))
    return out


# ----------------------------------------------------------------------------- the data
@dataclass
class Prepared:
    """
    A recording ready for either method.

    Other known effects compensated, fix epochs on the IMU clock, the initial boresight from
    the increment axes.

    Attributes
    ----------
    stamps : (n,) ndarray
        Gyro stamps, s.
    rho : (n, 3) ndarray
        Gyro increments with the other known effects compensated, rad.
    fix_t : (N,) ndarray
        Fix epochs on the IMU clock, s.
    fix_q : (N, 4) ndarray
        Camera attitudes q_GCRS_VF, scalar first.
    fix_P : (N, 3, 3) ndarray
        Their covariances, rad², scaled by the camera noise scale.
    gaps : list
        Gyro gaps (start, end), s.
    C : (3, 3) ndarray
        Initial boresight C (MF ← VF).
    pairs : int
        Increment pairs used for the boresight.
    random_walk : float
        Gyro angle random walk of the model, rad/√s.

    """

    stamps: np.ndarray
    rho: np.ndarray
    fix_t: np.ndarray
    fix_q: np.ndarray
    fix_P: np.ndarray
    gaps: list
    C: np.ndarray
    pairs: int
    random_walk: float


def prepare(rec, model) -> Prepared:
    """
    Prepare a recording for either method.

    Compensate the model's gyro effects *other* than those estimated (bias drift, scale
    asymmetry, ...: values that are then kept), shift the fixes by the camera time offset,
    scale their covariance by the camera noise scale, and find the boresight by axis alignment
    of the increment pairs (the discrepancy workflow's start).

    Parameters
    ----------
    rec : Recording
        Gyro increments, fixes, covariances and gaps as read from a bag.
    model : SensorModel
        The unit's sensor model.

    Returns
    -------
    Prepared
        The data of both methods.

    Raises
    ------
    ValueError
        Fewer than two camera-fix pairs covered by gap-free gyro data.

    """
    # the model's other gyro effects: compensated; those estimated here start from zero
    other = {n: model.effect_value(n) for n in model.active('gyro')
             if EFFECTS[n].kind == 'systematic'
             and EFFECTS[n].value_parameter.name not in ESTIMATED_PARAMETERS}
    st = np.asarray(rec.gyro_stamps, dtype=float)
    T = np.diff(st, prepend=st[0] - (st[1] - st[0]))
    rho = GyroEffects(values=other, epoch=float(st[0])).compensate(rec.delta_theta, st, T)
    cam = model.camera_effects()
    fix_t = cam.epoch(np.asarray(rec.fix_stamps, dtype=float))
    fix_P = cam.covariance(np.asarray(rec.fix_P, dtype=float))
    pairs = build_pairs(GyroRecord(st, rho), fix_t, rec.fix_q, 0.0, rec.gaps)
    if len(pairs) < 2:
        raise ValueError(f'only {len(pairs)} camera-fix pair(s) covered by gap-free gyro data '
                         '(need many)')
    C = axis_alignment(quat_to_dcm(pairs.dq_imu), quat_to_dcm(pairs.dq_cam))
    return Prepared(st, rho, fix_t, quat_normalize(rec.fix_q), fix_P, list(rec.gaps), C,
                    len(pairs), model.gyro.random_walk)


def _report(info_scaled, labels, sigma_limit, rel_tol=1e-9):
    """Judge the scaled information; name unobservable combinations in a parameter basis."""
    rep = analyze_information(info_scaled, labels=labels, rel_tol=rel_tol,
                              sigma_limit=sigma_limit)
    lam, vec = rep.eigenvalues, rep.directions
    bad = (lam <= rel_tol * max(float(lam[-1]), 0.0)) | (rep.predicted_sigma > sigma_limit)
    names = []
    if np.any(bad):
        for v in aligned_basis(vec[:, bad]).T:
            v = v * np.sign(v[np.argmax(np.abs(v))])
            terms = [f'{c:+.2f}·{n}' for c, n in zip(v, labels) if abs(c) >= 0.005]
            names.append(' '.join(terms))
    return rep, names


# ----------------------------------------------------------------------------- 002
def _polar(B):
    """B = P·R, P symmetric positive definite, R a rotation."""
    U, s, Vt = np.linalg.svd(B)
    return U @ np.diag(s) @ U.T, U @ Vt


def _judge_fit(extra: dict) -> float:
    """
    Judge χ²/dof against its two-sided band (``chi2_band`` at FIT_LEVEL).

    ``fit_consistent``, ``chi2_per_dof_band`` and ``chi2_level`` are added to ``extra``.
    Returns the factor max(1, χ²/dof) by which the published covariance is scaled.
    """
    chi2, dof = extra.get('chi2_per_dof'), int(extra.get('dof', 0))
    band = chi2_band(dof, FIT_LEVEL)
    ok = chi2 is not None and np.isfinite(chi2) and dof >= 1
    extra.update({'fit_consistent': bool(band[0] <= chi2 <= band[1]) if ok else None,
                  'chi2_per_dof_band': list(band), 'chi2_level': FIT_LEVEL,
                  'covariance_scale': float(max(1.0, chi2)) if ok else 1.0})
    return extra['covariance_scale']


def _integral_common(x12):
    P, R = _polar(x12[:9].reshape(3, 3))
    return np.concatenate([np.diag(P) - 1.0, [P[i, j] for i, j in _SYM], x12[9:],
                           quat_to_rotvec(dcm_to_quat(R))])


def calibrate_integral(prep: Prepared, interval: float | None = None,
                       sigma_limit: float = 1e-3) -> GyroCalibration:
    """
    Calibrate the gyro of a recording by 002, the integral method.

    Consecutive averaging intervals that span no gyro gap, camera attitudes rotated into gyro
    axes by the initial boresight, model weighting with the camera covariance and the gyro
    random walk.  The antisymmetric part of B is reported as the triad rotation.

    Parameters
    ----------
    prep : Prepared
        The recording (:func:`prepare`).
    interval : float, optional
        Interval length, s (default one camera step, fewer than MAX_EQUATIONS intervals).
    sigma_limit : float
        Predicted σ above which a scaled parameter combination counts as unobservable.

    Returns
    -------
    GyroCalibration
        The nine common parameters, or NaN with the unobservable combinations named.

    """
    stamps = prep.fix_t
    inside = (stamps > prep.stamps[0]) & (stamps <= prep.stamps[-1])
    t, q, P = stamps[inside], prep.fix_q[inside], prep.fix_P[inside]
    if interval is None:           # one camera step, fewer than MAX_EQUATIONS intervals
        steps = max(1, -(-(len(t) - 1) // MAX_EQUATIONS))
        iv = interval_boundaries(t, steps_per_interval=steps)
    else:
        iv = interval_boundaries(t, interval_length=interval)
    if len(prep.gaps) and len(iv):
        h = 1.5 * float(np.median(np.diff(prep.stamps)))
        ok = np.ones(len(iv), dtype=bool)
        for a, b in prep.gaps:
            ok &= ~((t[iv[:, 0]] - h < b) & (a < t[iv[:, 1]] + h))
        iv = iv[ok]
    res = calibrate_from_measurements(prep.stamps, prep.rho, t, q, camera_covariance=P,
                                      gyro_random_walk=prep.random_walk, intervals=iv,
                                      weighting='model', q_body_camera=dcm_to_quat(prep.C),
                                      sigma_limit=sigma_limit)
    extra = {'intervals': int(len(iv)), 'chi2_per_dof': float(res.chi2_per_dof),
             'dof': int(res.dof), 'library_message': res.message}
    _judge_fit(extra)                         # the library scales its covariance by max(1, χ²/dof)
    labels = COMMON_LABELS
    if not res.observable:
        names = list(res.observability.unobservable)
        return GyroCalibration('integral', False, res.message, np.full(9, np.nan),
                               np.full((9, 9), np.nan), labels, res.observability, names,
                               res.rate_scale, extra)
    x12 = res.x
    J = np.zeros((12, 12))
    for k in range(12):                         # polar decomposition, linearised
        d = np.zeros(12)
        d[k] = 1e-7
        J[:, k] = (_integral_common(x12 + d) - _integral_common(x12 - d)) / 2e-7
    y = _integral_common(x12)
    cov_y = J @ res.covariance @ J.T
    rate = res.rate_scale
    D = np.concatenate([np.ones(6), np.full(3, rate)])
    cov9 = cov_y[:9, :9]
    info = np.linalg.pinv(cov9 / np.outer(D, D), hermitian=True)
    rep, names = _report(info, labels, sigma_limit)
    if names:          # the library's 12 parameters pass, the published nine do not
        return GyroCalibration('integral', False, rep.message, np.full(9, np.nan),
                               np.full((9, 9), np.nan), labels, rep, names, rate, extra)
    extra['triad_rotation_rad'] = y[9:].tolist()
    extra['triad_rotation_sigma_rad'] = np.sqrt(np.diag(cov_y[9:, 9:])).tolist()
    extra['initial_boresight_q_mf_vf'] = dcm_to_quat(prep.C).tolist()
    return GyroCalibration('integral', True, res.message, y[:9], cov9, labels, rep, [], rate,
                           extra)


# ----------------------------------------------------------------------------- 000
def _segment(prep: Prepared):
    """
    Return the longest gap-free stretch of the gyro grid and the fixes inside it.

    The fixes lie at least two increments from either end, each carried to the nearest gyro
    boundary with the measured increments (a fraction of one increment: an error of order
    (gyro error)·h/2).
    """
    st = prep.stamps
    h = float(np.median(np.diff(st)))
    # the reader's gaps (the check's rule 6), not a threshold of its own: stamp jitter is no gap
    ends = np.array([b for a, b in prep.gaps if b > a], dtype=float)
    brk = np.flatnonzero(np.isin(st[1:], ends)) if len(ends) else np.zeros(0, dtype=int)
    starts = np.concatenate([[0], brk + 1])
    ends = np.concatenate([brk + 1, [len(st)]])
    i = int(np.argmax(ends - starts))
    lo, hi = int(starts[i]), int(ends[i])              # increments lo..hi−1; boundaries lo−1..hi−1
    g = GyroRecord(st[lo:hi], prep.rho[lo:hi])
    k, x, valid = g.locate(prep.fix_t)
    keep = valid & (k < len(g.stamps) - 2)
    k, x = k[keep], x[keep]
    b = np.where(x < 0.5, k - 1, k)                     # nearest boundary (index into g.stamps)
    A_fix, A_b = g.attitude_at(k, x), g.attitude[b]
    dA = quat_multiply(quat_conjugate(A_fix), A_b)     # body rotation from the fix to the boundary
    qbc = dcm_to_quat(prep.C)
    qc = prep.fix_q[keep]
    q_b = quat_multiply(quat_multiply(quat_multiply(qc, quat_conjugate(qbc)), dA), qbc)
    b, first = np.unique(b, return_index=True)
    return (g, h, b, quat_normalize(q_b[first]), prep.fix_P[keep][first], qc[first])


def drifting_reference_noise_covariance(P_ref, P_hat, cam_q, cam_P, t_rel,
                                        random_walk: float) -> np.ndarray:
    """
    Return the covariance of the residuals z_j = p̂*_j − p_j of the J drifting-reference equations.

    A camera fix N_j·exp(ε_j/2) (ε_j in VF axes) turns P_j = N_j N_0* into exp(e_j/2)·P_j
    (e_j = C_j ε_j, reference axes): δz_j = −Γ(p_j)e_j, Γ = ½(p0 E3 − Φ(p)); the fix at t0
    turns it into P_j·exp(−e_0/2): δz_j = +½(p0 E3 + Φ(p_j))e_0, the same e_0 in every
    equation.  The gyro random walk σ rotates P*_j on the left by the accumulated noise in
    reference axes, covariance σ²·min(t_i, t_j)·E3: δz_j = Γ(p*_j)·n_j.

    Parameters
    ----------
    P_ref : (J, 4) ndarray
        Reference increments of the epochs 1..J, scalar first.
    P_hat : (J, 4) ndarray
        Predicted (computed) increments, scalar first.
    cam_q : (J + 1, 4) ndarray
        Camera attitudes, row 0 the reference epoch 0.
    cam_P : (J + 1, 3, 3) ndarray
        Their covariances, VF axes, rad².
    t_rel : (J,) ndarray
        Times of the epochs since epoch 0, s.
    random_walk : float
        Gyro angle random walk σ, rad/√s.

    Returns
    -------
    (3J, 3J) ndarray
        The covariance, symmetric.

    """
    J = len(P_ref)
    C = quat_to_dcm(cam_q)
    E = C @ cam_P @ np.swapaxes(C, 1, 2)               # e covariances, reference axes
    I3 = np.eye(3)
    G = np.array([-0.5 * (p[0] * I3 - skew(p[1:])) for p in P_ref])
    H = np.array([0.5 * (p[0] * I3 + skew(p[1:])) for p in P_ref]).reshape(3 * J, 3)
    Gs = np.array([0.5 * (p[0] * I3 - skew(p[1:])) for p in P_hat])
    R = np.zeros((3 * J, 3 * J))
    for j in range(J):
        R[3 * j:3 * j + 3, 3 * j:3 * j + 3] = G[j] @ E[j + 1] @ G[j].T
    R += H @ E[0] @ H.T
    if random_walk > 0:
        tm = np.minimum.outer(t_rel, t_rel) * random_walk ** 2
        Gsf = np.zeros((3 * J, 3))
        for j in range(J):
            Gsf[3 * j:3 * j + 3] = Gs[j]
        R += (np.kron(tm, np.ones((3, 3))) * (Gsf @ Gsf.T))
    return 0.5 * (R + R.T)


def _no_drift(t):
    t = np.asarray(t, dtype=float)
    return np.zeros(t.shape + (3, 0))


def _whitened_equations(x, M0, meas, h, epochs, structure, q_b, P_b, random_walk, algorithm):
    """
    Return the equations (2.7) at x, whitened by the recording's noise covariance.

    'identity' coefficients, as ``estimate``; returns (U_w, z_w, equations used).
    """
    P_hat, Lam, th = predicted_reference_increments(x, M0, meas, h, epochs, structure, algorithm)
    P_ref = quat_multiply(q_b[1:], quat_conjugate(q_b[0]))
    P_ref = P_ref * np.where(np.sum(P_ref * P_hat, axis=1) < 0, -1.0, 1.0)[:, None]
    keep = np.abs(P_ref[:, 0]) >= 0.05
    Theta = theta_quadrature(Lam, th, h, structure, 'exact', 1)
    psi = psi_matrix(structure, h * epochs, 0.0)
    U = np.vstack([measurement_rows(P_ref[j], Theta[epochs[j]], psi[j], None, P_hat[j])
                   for j in np.nonzero(keep)[0]])
    z = (P_hat[keep, 1:] - P_ref[keep, 1:]).ravel()
    cam = np.concatenate([[0], 1 + np.nonzero(keep)[0]])
    R = drifting_reference_noise_covariance(P_ref[keep], P_hat[keep], q_b[cam], P_b[cam],
                                            h * epochs[keep], random_walk)
    s = np.sqrt(np.maximum(np.diag(R), 1e-300))
    L = np.linalg.cholesky(R / np.outer(s, s) + 1e-12 * np.eye(len(s)))
    return np.linalg.solve(L, U / s[:, None]), np.linalg.solve(L, z / s), int(keep.sum())


def calibrate_drifting_reference(prep: Prepared, drift: bool = False, sigma_limit: float = 1e-3,
                                 algorithm: str = '2', progress=None) -> GyroCalibration:
    """
    Calibrate the gyro of a recording by 000, the drifting reference.

    x = [w0, c, d] with c = 000 §6's nine gyro errors and d (``drift``) the reference drift;
    w0 is a nuisance (the initial attitude error).  Equations at every fix after the first of
    the longest gap-free stretch.  Observability is judged first, at the nominal point
    (x = 0): an unobservable motion is refused before any estimation (Gauss–Newton would
    wander along the unobservable directions).

    Parameters
    ----------
    prep : Prepared
        The recording (:func:`prepare`).
    drift : bool
        Also estimate a constant drift of the reference.
    sigma_limit : float
        Predicted σ above which a scaled parameter combination counts as unobservable.
    algorithm : str
        Coning algorithm of the computed attitude.
    progress : callable, optional
        Called with a line of progress text.

    Returns
    -------
    GyroCalibration
        The common parameters (with the drift), or NaN with the unobservable combinations
        named.

    Raises
    ------
    ValueError
        Fewer than two camera fixes inside the gyro data.

    """
    say = progress or (lambda s: None)
    g, h, b, q_b, P_b, _ = _segment(prep)
    if len(b) < 2:
        raise ValueError('fewer than two camera fixes inside the gyro data')
    if len(b) > MAX_EQUATIONS + 1:            # the dense noise covariance: fixes evenly thinned
        pick = np.unique(np.round(np.linspace(0, len(b) - 1, MAX_EQUATIONS + 1)).astype(int))
        b, q_b, P_b = b[pick], q_b[pick], P_b[pick]
    structure = ErrorStructure(D=scale_misalignment_bias_D, m=3,
                               G=identity_G if drift else _no_drift, n=1 if drift else 0)
    b0 = int(b[0])
    meas = g.rho[b0 + 1:int(b[-1]) + 1]                # increments after boundary b0
    epochs = (b[1:] - b0).astype(int)
    M0 = quat_multiply(q_b[0], quat_conjugate(dcm_to_quat(prep.C)))   # body from the camera
    args = (M0, meas, h, epochs, structure, q_b, P_b, prep.random_walk, algorithm)
    # common parameters: c = [s1 s2 s3, c4 = M_xy, c5 = M_yz, c6 = M_xz, b] (+ d); w0 eliminated
    order = [3, 4, 5, 6, 8, 7, 9, 10, 11] + ([12, 13, 14] if drift else [])
    labels = COMMON_LABELS + (DRIFT_LABELS if drift else ())
    rate = float(np.sqrt(np.mean(np.sum((meas / h) ** 2, axis=1))))
    rate = rate if rate > 0 else 1.0
    D = np.concatenate([np.ones(6), np.full(len(labels) - 6, rate)])

    def report(Uw):
        info = Uw.T @ Uw
        Nwc = info[np.ix_([0, 1, 2], order)]
        schur = info[np.ix_(order, order)] - Nwc.T @ np.linalg.pinv(info[:3, :3]) @ Nwc
        return info, _report(D[:, None] * schur * D[None, :], labels, sigma_limit)

    say(f'tkachenko: {len(meas)} increments, {len(epochs)} equations; '
        'observability at the nominal point')
    Uw, zw, used = _whitened_equations(np.zeros(structure.size), *args)
    _, (rep, names) = report(Uw)
    extra = {'equations': used, 'skipped': int(len(epochs) - used), 'increments': int(len(meas)),
             'segment_s': [float(g.stamps[b0]), float(g.stamps[int(b[-1])])]}
    if names:
        return GyroCalibration('tkachenko', False, rep.message, np.full(len(labels), np.nan),
                               np.full((len(labels),) * 2, np.nan), labels, rep, names, rate,
                               extra)
    say('tkachenko: Gauss–Newton on the full model')
    sol = estimate(meas, h, M0, q_b[0], q_b[1:], epochs, structure, algorithm=algorithm,
                   iterate=True, min_p0=0.05)
    # one generalised least-squares step about the solution, the recording's noise covariance
    say('tkachenko: generalised least squares (camera fixes, the fix at t0, gyro random walk)')
    Uw, zw, _ = _whitened_equations(sol.x, *args)
    info, (rep, names) = report(Uw)
    step = np.linalg.lstsq(info, Uw.T @ zw, rcond=1e-14)[0]
    x = sol.x + step
    dof = max(len(zw) - len(x), 1)
    cov_full = np.linalg.pinv(info, hermitian=True)
    chi2 = float(np.sum((zw - Uw @ step) ** 2)) / dof
    extra.update({'iterations': sol.iterations, 'chi2_per_dof': chi2, 'dof': int(dof)})
    cov_full = cov_full * _judge_fit(extra)   # as the 002 library: scaled by max(1, χ²/dof)
    extra.update({'w0': x[:3].tolist(), 'w0_sigma': np.sqrt(np.diag(cov_full[:3, :3])).tolist()})
    if names:
        return GyroCalibration('tkachenko', False, rep.message, np.full(len(labels), np.nan),
                               np.full((len(labels),) * 2, np.nan), labels, rep, names, rate,
                               extra)
    return GyroCalibration('tkachenko', True, rep.message, x[order],
                           cov_full[np.ix_(order, order)], labels, rep, [], rate, extra)
