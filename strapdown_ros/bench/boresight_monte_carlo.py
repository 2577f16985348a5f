"""
Monte Carlo runs, pipeline checks and timing of the boresight benchmark.

One run draws new gyro constants and noise and new camera noise, forms the increment pairs and
runs every estimator (the package's calibrator and solver, a full-covariance reference and
the OpenCV peers); ``monte_carlo`` repeats it, seeded per run: in this process, or as Dask tasks
(an embedded LocalCluster of ``jobs`` workers, or the scheduler at ``scheduler``;
:mod:`strapdown_ros.fleet.cluster`), the scenario sent to each worker once.
"""
from __future__ import annotations

import sys
import time

import numpy as np

from strapdown_ros.bench.boresight_opencv import (all_opencv, OPENCV_METHODS,
                                                  OPENCV_PIVOT_METHODS)
from strapdown_ros.bench.boresight_scenario import (BETA_DEG, camera_covariance,
                                                    CAMERA_SIGMA_ARCSEC, FIRST_EXPOSURE,
                                                    GYRO_RATE, INTERVAL, jacobian, N_FIXES,
                                                    residual_covariance, residuals,
                                                    rotation_angle, Scenario, wrap_angles)
from strapdown_ros.calibration.boresight import solve_boresight
from strapdown_ros.calibration.boresight_increments import (camera_increment, gyro_increment,
                                                            IncrementPair)
from strapdown_ros.calibration.streaming import BoresightCalibrator
from strapdown_ros.fleet.cluster import dask_client, map_tasks, TaskError
from strapdown_ros.rotation import (dcm_to_quat, dcm_to_ypr, quat_conjugate, quat_multiply,
                                    quat_to_dcm, rotvec_to_quat, ypr_to_dcm)
from strapdown_ros.sensors import (ARCSEC, IntegratingSensor, NAVIGATION_GRADE_GYRO,
                                   SensorErrorModel)
from strapdown_ros.sensors.star_camera import StarCameraModel

CORE_ESTIMATORS = ('calibrator', 'weighted', 'unweighted', 'weighted_004cov', 'correlated_gls')


def draw_gyro(sc: Scenario, errors: SensorErrorModel, rng: np.random.Generator) -> np.ndarray:
    """
    Draw the gyro increments y = (I + M) u + b T + w of one run, vectorised.

    The ``IntegratingSensor`` model with quantization off (``calibrator_check`` compares them).

    Parameters
    ----------
    sc : Scenario
        The bench scenario.
    errors : SensorErrorModel
        The run's gyro constants M, b and random walk.
    rng : numpy.random.Generator
        Source of the white noise.

    Returns
    -------
    (K, 3) ndarray
        Measured gyro increments, rad.

    """
    T = 1.0 / GYRO_RATE
    y = sc.u @ (np.eye(3) + errors.matrix).T + errors.bias * T
    if errors.random_walk > 0:
        y = y + rng.normal(0.0, errors.random_walk * np.sqrt(T), y.shape)
    return y


def camera_fixes(sc: Scenario, seed: int, noise: bool = True):
    """
    Simulate the star-camera fixes of one run.

    Parameters
    ----------
    sc : Scenario
        The bench scenario.
    seed : int
        Seed of the camera noise.
    noise : bool, optional
        False gives exact fixes.

    Returns
    -------
    list
        ``N_FIXES`` fixes of ``StarCameraModel.fixes`` (stamp, attitude q_GCRS_VF, covariance).

    """
    cam = StarCameraModel(boresight=sc.beta, interval=INTERVAL, first_exposure=FIRST_EXPOSURE,
                          sigma=sc.cam_sigma if noise else np.zeros(3), seed=seed)
    return cam.fixes(sc.profile, N_FIXES)


def form_pairs(sc: Scenario, y: np.ndarray, fixes, cov_imu=None) -> list[IncrementPair]:
    """
    Form the increment pairs with ``gyro_increment`` and ``camera_increment``.

    E_imu is precomputed from the true increments; it equals what the calibrator computes from
    the measured ones to about 1e-5 relative.

    Parameters
    ----------
    sc : Scenario
        The bench scenario.
    y : (K, 3) ndarray
        Measured gyro increments, rad.
    fixes : list
        Camera fixes of ``camera_fixes``.
    cov_imu : (P, 3, 3) ndarray, optional
        E_imu of every pair; ``sc.E_imu`` when None.

    Returns
    -------
    list of IncrementPair
        The P = N − 1 pairs.

    """
    cov_imu = sc.E_imu if cov_imu is None else cov_imu
    pairs = []
    for n in range(sc.pairs_count):
        dq_i, _ = gyro_increment(sc.stamps, y, sc.epochs[n], sc.epochs[n + 1])
        f0, f1 = fixes[n], fixes[n + 1]
        dq_c, E_c = camera_increment(f0.attitude, f0.covariance, f1.attitude, f1.covariance)
        pairs.append(IncrementPair(sc.epochs[n], sc.epochs[n + 1], dq_i, dq_c, cov_imu[n], E_c))
    return pairs


def correlated_gls(sc: Scenario, pairs, beta0, iterations: int = 3):
    """
    Estimate β by Gauss–Newton with the full covariance Σ of the stacked residuals.

    A bench reference: camera fixes shared by adjacent pairs and gyro constants common to all
    pairs are both in Σ.

    Parameters
    ----------
    sc : Scenario
        The bench scenario.
    pairs : list of IncrementPair
        The run's pairs.
    beta0 : (3,) ndarray
        Start, rad (the weighted estimate).
    iterations : int, optional
        Largest number of Gauss–Newton steps.

    Returns
    -------
    beta : (3,) ndarray
        Estimate (ψ, ϑ, γ), rad.
    covariance : (3, 3) ndarray
        (Hᵀ Σ⁻¹ H)⁻¹ at the estimate, rad².

    """
    A_imu = quat_to_dcm(np.array([p.dq_imu for p in pairs]))
    A_cam = quat_to_dcm(np.array([p.dq_cam for p in pairs]))
    S_cam = camera_covariance(sc, A_cam)
    beta = np.asarray(beta0, dtype=float).copy()
    N = None
    for _ in range(iterations):
        Sigma = residual_covariance(sc, ypr_to_dcm(*beta), sc.K_gyro, S_cam)
        L = np.linalg.cholesky(Sigma)
        f = np.linalg.solve(L, residuals(beta, A_imu, A_cam))
        H = np.linalg.solve(L, jacobian(beta, A_imu, A_cam))
        N = H.T @ H
        step = -np.linalg.solve(N, H.T @ f)
        beta = beta + step
        if np.linalg.norm(step) < 1e-10:
            break
    return beta, np.linalg.inv(N)


def angle_errors(C_est: np.ndarray, sc: Scenario) -> tuple[np.ndarray, float]:
    """
    Return the angle errors of an estimated boresight.

    Parameters
    ----------
    C_est : (3, 3) ndarray
        Estimated C_MF^VF.
    sc : Scenario
        The bench scenario.

    Returns
    -------
    errors : (3,) ndarray
        β̂ − β wrapped, rad.
    total : float
        Rotation angle between Ĉ and C, rad.

    """
    return wrap_angles(dcm_to_ypr(C_est) - sc.beta), rotation_angle(C_est.T @ sc.C)


# --------------------------------------------------------------------------------- checks
def convention_check(sc: Scenario) -> dict:
    """
    Check on noise-free pairs that every estimator returns the truth.

    Parameters
    ----------
    sc : Scenario
        The bench scenario.

    Returns
    -------
    dict
        Estimator → total angle error, arc seconds, or why an OpenCV method gave no answer.

    """
    fixes = camera_fixes(sc, 0, noise=False)
    pairs = form_pairs(sc, sc.u, fixes)
    res = {}
    for w in (True, False):
        sol = solve_boresight(pairs, weighted=w, init='axes')
        res['weighted' if w else 'unweighted'] = angle_errors(sol.c_mf_vf, sc)[1] / ARCSEC
    for name, (R, msg) in all_opencv(pairs, fixes).items():
        res[name] = angle_errors(R, sc)[1] / ARCSEC if R is not None else msg
    return res


def calibrator_check(sc: Scenario, seed: int) -> dict:
    """
    Check the bench's pair formation and gyro draw against the library on one run.

    The pairs against the streaming ``BoresightCalibrator`` fed the same stream, and the
    vectorised gyro draw against ``IntegratingSensor.sample``.

    Parameters
    ----------
    sc : Scenario
        The bench scenario.
    seed : int
        Seed of the run.

    Returns
    -------
    dict
        Pair counts, largest ΔS_imu and E_imu differences, β difference (arc seconds) and the
        largest gyro draw difference (rad).

    """
    rng = np.random.default_rng(seed)
    errors = sc.gyro.draw(rng)
    y = draw_gyro(sc, errors, np.random.default_rng(seed + 1))
    sens = IntegratingSensor(sc.profile, 'gyro', GYRO_RATE, errors, seed=seed + 1)
    _, y_lib, _ = sens.sample(len(sc.u))
    fixes = camera_fixes(sc, seed + 2)
    cal = BoresightCalibrator(gyro=sc.gyro, weighted=True)
    k = 0
    for f in fixes:
        j = int(np.searchsorted(sc.stamps, f.stamp + 0.5))
        cal.add_gyro(sc.stamps[k:j], y[k:j])
        k = j
        cal.add_camera(f.stamp, f.attitude, f.covariance)
    cal.add_gyro(sc.stamps[k:], y[k:])
    sol_cal = cal.solve()
    pairs = form_pairs(sc, y, fixes)
    # the calibrator's own weighting (correlated) on the calibrator's pairs, against the bench's
    # pairs carrying the same sensitivities: the pair formation must agree
    pairs_c = []
    for p, f0, f1 in zip(pairs, fixes[:-1], fixes[1:]):
        _, E_i, G_i, W_i = gyro_increment(sc.stamps, y, p.t_start, p.t_end, sc.gyro,
                                          sensitivity=True)
        pairs_c.append(
            IncrementPair(p.t_start, p.t_end, p.dq_imu, p.dq_cam, E_i, p.cov_cam,
                          imu_sensitivity=G_i, cov_imu_white=W_i, cov_fix_start=f0.covariance,
                          cov_fix_end=f1.covariance))
    sol = solve_boresight(pairs_c, weighting=sol_cal.weighting, gyro=sc.gyro)
    dq = max(rotation_angle(quat_to_dcm(quat_multiply(quat_conjugate(a.dq_imu), b.dq_imu)))
             for a, b in zip(cal.pairs, pairs))
    dE = max(
        np.max(np.abs(a.cov_imu - b.cov_imu)) / np.max(np.abs(b.cov_imu))
        for a, b in zip(cal.pairs, pairs))
    return {'pairs_calibrator': len(cal.pairs), 'pairs_bench': len(pairs),
            'max_dq_imu_diff_arcsec': dq / ARCSEC, 'max_E_imu_rel_diff': float(dE),
            'beta_diff_arcsec': (wrap_angles(sol_cal.beta - sol.beta) / ARCSEC).tolist(),
            'gyro_draw_vs_IntegratingSensor_max_abs': float(np.max(np.abs(y - y_lib)))}


def _estimator_names() -> list[str]:
    return list(CORE_ESTIMATORS) + [f'opencv_{m}' for m in OPENCV_METHODS] + \
        [f'opencv_{m}_pivot' for m in OPENCV_PIVOT_METHODS]


_COV_NAMES = ('calibrator', 'weighted', 'weighted_model', 'weighted_residual', 'unweighted',
              'weighted_004cov', 'correlated_gls')


def one_run(sc: Scenario, r: int, ss: np.random.SeedSequence) -> dict:
    """
    Run one Monte Carlo run: new gyro constants and noise, new camera noise, every estimator.

    Parameters
    ----------
    sc : Scenario
        The bench scenario.
    r : int
        Index of the run.
    ss : numpy.random.SeedSequence
        Seed of the run.

    Returns
    -------
    dict
        ``err``/``tot``/``covs``/``fail`` per estimator, the weighted χ²/dof, the run's
        antisymmetric misalignment ``triad`` and the normalised residual at the truth.

    """
    g_rng, n_rng, c_ss = (np.random.default_rng(s) for s in ss.spawn(3))
    errors = sc.gyro.draw(g_rng)
    A = 0.5 * (errors.matrix - errors.matrix.T)
    out = {'r': r, 'err': {}, 'tot': {}, 'covs': {}, 'fail': {}, 'chi2': np.nan,
           'triad': np.array([A[2, 1], A[0, 2], A[1, 0]])}   # antisymmetric misalignment a
    y = draw_gyro(sc, errors, n_rng)
    fixes = camera_fixes(sc, int(c_ss.integers(0, 2 ** 31 - 1)))
    pairs = form_pairs(sc, y, fixes)
    A_imu = quat_to_dcm(np.array([p.dq_imu for p in pairs]))
    A_cam = quat_to_dcm(np.array([p.dq_cam for p in pairs]))
    # fᵀΣ⁻¹f / 3P at the truth, with the full Σ and with its diagonal blocks
    f_true = residuals(sc.beta, A_imu, A_cam)
    blocks = np.swapaxes(sc.C, 0, 1)[None] @ sc.E_imu @ sc.C[None] + sc.E_cam
    fb = np.linalg.solve(np.linalg.cholesky(blocks), f_true.reshape(-1, 3)[..., None])[..., 0]
    out['full_nees'] = (np.sum(np.linalg.solve(np.linalg.cholesky(sc.Sigma), f_true)**2) /
                        len(f_true), np.sum(fb**2) / len(f_true))
    sols = {'weighted': solve_boresight(pairs, weighted=True, init='axes'),
            'unweighted': solve_boresight(pairs, weighted=False, init='axes')}
    pairs004 = [IncrementPair(p.t_start, p.t_end, p.dq_imu, p.dq_cam, e, p.cov_cam)
                for p, e in zip(pairs, sc.E_imu_004)]
    sols['weighted_004cov'] = solve_boresight(pairs004, weighted=True, init='axes')
    # the package's calibrator (BoresightCalibrator / calibrator_node / calibrate_bag): pairs with
    # the gyro sensitivities and fix covariances, correlated weighting from the measured data
    pairs_c = []
    for n_, (p, f0, f1) in enumerate(zip(pairs, fixes[:-1], fixes[1:])):
        _, E_i, G_i, W_i = gyro_increment(sc.stamps, y, p.t_start, p.t_end, sc.gyro,
                                          sensitivity=True)
        pairs_c.append(
            IncrementPair(p.t_start, p.t_end, p.dq_imu, p.dq_cam, E_i, p.cov_cam,
                          imu_sensitivity=G_i, cov_imu_white=W_i, cov_fix_start=f0.covariance,
                          cov_fix_end=f1.covariance))
    sols['calibrator'] = solve_boresight(pairs_c, init='axes', weighting='correlated',
                                         gyro=sc.gyro)
    for k, sol in sols.items():
        if not (sol.observable and sol.converged):
            out['fail'][k] = f'run {r}: {sol.message}'
            continue
        out['err'][k], out['tot'][k] = angle_errors(sol.c_mf_vf, sc)
        out['covs'][k] = sol.covariance_beta
    w = sols['weighted']
    if w.observable and w.converged:
        out['covs']['weighted_model'] = w.covariance_beta_model
        out['covs']['weighted_residual'] = w.covariance_beta_residual
        out['chi2'] = w.chi2_per_dof
        b, Pg = correlated_gls(sc, pairs, w.beta)
        out['err']['correlated_gls'], out['tot']['correlated_gls'] = angle_errors(
            ypr_to_dcm(*b), sc)
        out['covs']['correlated_gls'] = Pg
    else:
        out['fail']['correlated_gls'] = f'run {r}: no weighted start'
    for name, (R, msg) in all_opencv(pairs, fixes).items():
        if R is None:
            out['fail'][name] = f'run {r}: {msg}'
        else:
            out['err'][name], out['tot'][name] = angle_errors(R, sc)
    return out


def monte_carlo(sc: Scenario, runs: int, seed: int, progress: bool = True, jobs: int = 1,
                scheduler: str | None = None) -> dict:
    """
    Run ``runs`` independent runs, seeded per run so the result does not depend on ``jobs``.

    Parameters
    ----------
    sc : Scenario
        The bench scenario.
    runs : int
        Number of runs.
    seed : int
        Seed of the whole Monte Carlo.
    progress : bool, optional
        Print progress on stderr.
    jobs : int, optional
        Dask LocalCluster workers; 1 (and no scheduler) runs in this process.
    scheduler : str, optional
        A running Dask scheduler (``tcp://host:8786``) whose workers run the runs.

    Returns
    -------
    dict
        Per-estimator arrays ``errors`` (runs, 3) rad, ``total`` (runs,), ``covs``
        (runs, 3, 3), ``failures``; ``chi2``, ``full_nees``, ``triad``, ``wall_s``, ``jobs``.

    Raises
    ------
    RuntimeError
        A run's worker was lost (a run that raises is the bench's own bug: it propagates).

    """
    children = np.random.SeedSequence(seed).spawn(runs)
    names = _estimator_names()
    err = {k: np.full((runs, 3), np.nan) for k in names}
    tot = {k: np.full(runs, np.nan) for k in names}
    covs = {k: np.full((runs, 3, 3), np.nan) for k in _COV_NAMES}
    chi2 = np.full(runs, np.nan)
    triad = np.zeros((runs, 3))
    full_nees = np.full((runs, 2), np.nan)
    failures = {k: [] for k in names}
    t_start = time.perf_counter()
    tasks = list(enumerate(children))

    def collect(res, done):
        if isinstance(res, TaskError):
            raise RuntimeError(f'a Monte Carlo run was lost: {res}')
        r = res['r']
        for k, v in res['err'].items():
            err[k][r], tot[k][r] = v, res['tot'][k]
        for k, v in res['covs'].items():
            covs[k][r] = v
        for k, v in res['fail'].items():
            failures[k].append(v)
        chi2[r], triad[r], full_nees[r] = res['chi2'], res['triad'], res['full_nees']
        if progress and done % max(1, runs // 10) == 0:
            print(f'  run {done}/{runs}  {time.perf_counter() - t_start:.1f} s', file=sys.stderr,
                  flush=True)

    if jobs > 1 or scheduler:
        with dask_client(scheduler, jobs) as client:
            sc_f = client.scatter(sc, broadcast=True)          # once per worker, not per run
            map_tasks(client, one_run, [(sc_f, r, ss) for r, ss in tasks],
                      on_done=lambda i, res, done, total: collect(res, done))
    else:
        for done, (r, ss) in enumerate(tasks, 1):
            collect(one_run(sc, r, ss), done)
    for k in failures:
        failures[k].sort(key=lambda m: int(m.split(':')[0].split()[1]))
    return {
        'errors': err, 'total': tot, 'covs': covs, 'chi2': chi2, 'full_nees': full_nees,
        'failures': failures, 'triad': triad, 'wall_s': time.perf_counter() - t_start,
        'jobs': jobs, 'scheduler': scheduler
    }


# ------------------------------------------------------------------------------ performance
def performance(n_pairs: int = 1000, repeats: int = 15, seed: int = 7) -> dict:
    """
    Time a warm-started ``BoresightCalibrator.solve()`` after one new pair.

    Synthetic pairs: one in five a 10–15° rotation about a random axis, the rest Earth-rate
    holds, with camera noise (0.6″, 0.6″, 6″) and 0.5″ gyro noise.  Also times the forming of
    one pair from 20 s of 200 Hz gyro data.

    Parameters
    ----------
    n_pairs : int, optional
        Pairs accumulated before the timed solves.
    repeats : int, optional
        Timed solves (one new pair each).
    seed : int, optional
        Seed of the synthetic pairs.

    Returns
    -------
    dict
        Times in ms (cold, warm median/max/all, pair formation), iterations, the 50 ms target
        and whether it is met.

    """
    rng = np.random.default_rng(seed)
    C = ypr_to_dcm(*np.radians(BETA_DEG))
    qc = dcm_to_quat(C)
    Pc = np.diag((np.array(CAMERA_SIGMA_ARCSEC) * ARCSEC) ** 2)
    E_imu = (0.5 * ARCSEC) ** 2 * np.eye(3)

    def pair(k):
        ax = rng.normal(size=3)
        ax /= np.linalg.norm(ax)
        ang = np.radians(rng.uniform(10, 15)) if k % 5 == 0 else 1.5e-3
        dq_vf = rotvec_to_quat(ax * ang)
        R = quat_to_dcm(dq_vf)
        E_cam = Pc + R.T @ Pc @ R
        dq_mf = quat_multiply(quat_multiply(qc, dq_vf), quat_conjugate(qc))
        return IncrementPair(
            20.0 * k, 20.0 * (k + 1),
            quat_multiply(dq_mf, rotvec_to_quat(rng.multivariate_normal(np.zeros(3), E_imu))),
            quat_multiply(dq_vf, rotvec_to_quat(rng.multivariate_normal(np.zeros(3), E_cam))),
            E_imu, E_cam)
    cal = BoresightCalibrator(gyro=NAVIGATION_GRADE_GYRO, weighted=True)
    cal.pairs = [pair(k) for k in range(n_pairs)]
    t0 = time.perf_counter()
    cold = cal.solve()
    cold_ms = (time.perf_counter() - t0) * 1e3
    times, iters = [], []
    for i in range(repeats):
        cal.pairs.append(pair(n_pairs + i))
        t0 = time.perf_counter()
        sol = cal.solve()
        times.append((time.perf_counter() - t0) * 1e3)
        iters.append(sol.iterations)
    # forming one pair from 20 s of 200 Hz gyro data (gyro_increment with its covariance)
    T = 1.0 / GYRO_RATE
    st = np.arange(1, int(22 / T) + 1) * T
    dth = rng.normal(0, 1e-5, (len(st), 3))
    tp = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        gyro_increment(st, dth, 0.5013, 20.5026, NAVIGATION_GRADE_GYRO)
        tp.append((time.perf_counter() - t0) * 1e3)
    return {
        'pairs': n_pairs, 'repeats': repeats, 'cold_solve_ms': cold_ms,
        'cold_iterations': cold.iterations, 'warm_solve_ms_median': float(np.median(times)),
        'warm_solve_ms_max': float(np.max(times)), 'warm_solve_ms_all': times,
        'warm_iterations': iters, 'pair_formation_ms_median': float(np.median(tp)),
        'target_ms': 50.0, 'meets_target': bool(np.median(times) < 50.0)
    }
