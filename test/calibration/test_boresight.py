"""Boresight estimator (004) against exact truth: increments, solution, covariance, checks."""
import numpy as np
import pytest

from strapdown_ros.calibration.boresight import (check_observability, imu_attitude_from_camera,
                                                 solve_boresight)
from strapdown_ros.calibration.boresight_increments import (camera_increment, gyro_increment,
                                                            IncrementPair, r_partial)
from strapdown_ros.calibration.streaming import BoresightCalibrator
from strapdown_ros.estimation.chi_square import chi2_band
from strapdown_ros.motion.profiles import bench_profile
from strapdown_ros.rotation import (dcm_to_quat, quat_angle_between, quat_conjugate,
                                    quat_error_rotvec, quat_multiply, quat_normalize, quat_to_dcm,
                                    rotvec_to_quat, ypr_to_dcm)
from strapdown_ros.sensors import ARCSEC, IntegratingSensor, NAVIGATION_GRADE_GYRO, SensorSigmas
from strapdown_ros.sensors.star_camera import StarCameraModel

BETA = np.radians([40.0, -25.0, 120.0])


def test_partial_interval_polynomial_r0_coefficient_is_one_eighth():
    """
    Test 004 §2.2 r_0k(τ) against the exact partial rotation of a rate linear in time.

    The ρ·Δρ term with 1/8 (derived from |θ(τ)|²/8) is 3× more accurate than the printed 1/4.
    """
    rng = np.random.default_rng(0)
    T = 0.005
    for _ in range(3):
        a, b = rng.normal(0, 0.5, 3), rng.normal(0, 20, 3)
        rho_prev, rho = a * T + b * T ** 2 / 2, a * T + 1.5 * b * T ** 2
        x = 0.7
        n = 4000
        ts = np.linspace(T, T + x * T, n + 1)
        q = np.array([1.0, 0, 0, 0])
        # midpoint product of a linear rate: exact to 1e-15
        for i in range(n):
            tm = 0.5 * (ts[i] + ts[i + 1])
            q = quat_multiply(q, rotvec_to_quat((a + b * tm) * (ts[i + 1] - ts[i])))
        ours = quat_normalize(r_partial(rho, rho - rho_prev, x)[0])
        d = rho - rho_prev
        printed = ours.copy()
        printed[0] = 1 - rho @ rho / 8 * x ** 2 - (rho @ d) / 4 * (x ** 3 - x ** 2)
        printed = quat_normalize(np.concatenate([[printed[0]], r_partial(rho, d, x)[0][1:]]))
        e_ours, e_printed = quat_angle_between(ours, q), quat_angle_between(printed, q)
        assert e_ours < 0.5 * e_printed and e_ours < 1e-9


def test_gyro_increment_is_exact_on_asynchronous_epochs():
    """ΔS_imu between epochs that fall inside gyro intervals matches the exact attitude."""
    prof = bench_profile(hold=4.0, rotation_time=3.0)
    s = IntegratingSensor(prof, 'gyro', 200.0)
    t, dth, _ = s.sample(int(prof.duration * 200))
    # one pair inside one interval
    for t0, t1 in [(3.0037, 9.1234), (10.0011, 10.0031), (20.4, 33.3)]:
        dq, _ = gyro_increment(t, dth, t0, t1)
        truth = quat_multiply(quat_conjugate(prof.attitude(t0)), prof.attitude(t1))
        assert quat_angle_between(dq, truth) < 2e-8, (t0, t1)
    assert gyro_increment(t, dth, 3.0, t[-1] + 0.01) is None              # not covered yet


def test_gyro_increment_covariance_matches_monte_carlo():
    """E_imu (random-constant model) against 300 draws of navigation-grade gyro errors."""
    prof = bench_profile(hold=2.0, rotation_time=4.0, angles_deg=(15.0, -12.0), axes=(2, 0))
    sig = SensorSigmas(bias_sigma=NAVIGATION_GRADE_GYRO.bias_sigma * 30, scale_sigma=1e-4,
                       misalignment_sigma=1e-4, random_walk=NAVIGATION_GRADE_GYRO.random_walk * 10)
    t0, t1 = 1.0013, 13.4567
    truth = quat_multiply(quat_conjugate(prof.attitude(t0)), prof.attitude(t1))
    rng = np.random.default_rng(4)
    errs = []
    for r in range(300):
        s = IntegratingSensor(prof, 'gyro', 200.0, sig.draw(rng), seed=r)
        t, dth, _ = s.sample(int(15 * 200))
        dq, E = gyro_increment(t, dth, t0, t1, sig)
        errs.append(quat_error_rotvec(dq, truth, 'body'))
    errs = np.array(errs)
    np.testing.assert_allclose(errs.std(0) ** 2, np.diag(E), rtol=0.25)
    nees = np.mean(np.einsum('ri,ij,rj->r', errs, np.linalg.inv(E), errs))
    assert 2.5 < nees < 3.5


def synthetic_pairs(beta, n=40, noise_imu=0.2 * ARCSEC,
                    noise_cam=np.array([0.6, 0.6, 6.0]) * ARCSEC, axes=None, rng=None,
                    angle=np.radians(12.0)):
    """
    Return pairs from random rotations: ΔS_imu = C ΔS_avu Cᵀ exactly, plus noise.

    Parameters
    ----------
    beta : (3,) ndarray
        The boresight, rad.
    n : int
        Number of pairs.
    noise_imu : float
        1σ of the IMU increment noise per axis, rad.
    noise_cam : (3,) ndarray
        1σ of the camera increment noise per axis, rad.
    axes : (n, 3) ndarray, optional
        Rotation axes (default random).
    rng : numpy.random.Generator, optional
        Random source.
    angle : float
        Rotation angle of every pair, rad.

    Returns
    -------
    list of IncrementPair
        The pairs, with their noise covariances.

    """
    rng = rng or np.random.default_rng(0)
    C = ypr_to_dcm(*beta)
    qc = dcm_to_quat(C)
    pairs = []
    P_cam = np.diag(noise_cam ** 2)
    for k in range(n):
        axis = rng.normal(size=3) if axes is None else np.asarray(axes[k % len(axes)], dtype=float)
        axis /= np.linalg.norm(axis)
        dq_vf = rotvec_to_quat(axis * angle * (0.5 + rng.random()))
        dq_mf = quat_multiply(quat_multiply(qc, dq_vf), quat_conjugate(qc))
        E_imu = noise_imu ** 2 * np.eye(3)
        E_cam = 2 * P_cam
        e_imu = rng.multivariate_normal(np.zeros(3), E_imu)
        e_cam = rng.multivariate_normal(np.zeros(3), E_cam)
        pairs.append(IncrementPair(20.0 * k, 20.0 * (k + 1),
                                   quat_multiply(dq_mf, rotvec_to_quat(e_imu)),
                                   quat_multiply(dq_vf, rotvec_to_quat(e_cam)), E_imu, E_cam))
    return pairs


@pytest.mark.parametrize('beta_deg', [(40, -25, 120), (-170, 80, -5), (0, 0, 0), (90, 45, 179)])
def test_converges_from_zero_for_large_boresights(beta_deg):
    """
    Converge from β0 = 0 for large boresights.

    Parameters
    ----------
    beta_deg : tuple of float
        The boresight, degrees.

    """
    beta = np.radians(beta_deg)
    pairs = synthetic_pairs(beta, noise_imu=1e-12, noise_cam=np.full(3, 1e-12))
    sol = solve_boresight(pairs, beta0=(0.0, 0.0, 0.0))
    assert sol.observable and sol.converged
    err = quat_angle_between(dcm_to_quat(sol.c_mf_vf), dcm_to_quat(ypr_to_dcm(*beta)))
    assert err < 1e-9


def test_plain_gauss_newton_from_zero_converges_and_axis_start_saves_iterations():
    """
    Test 004's Gauss–Newton from β0 = 0 (init='given') on random large boresights.

    It converges, including pitch near ±90°; the closed-form axis-alignment start needs 1–2
    iterations.
    """
    rng = np.random.default_rng(8)
    iters_plain, iters_axes = [], []
    betas = [rng.uniform([-np.pi, -1.55, -np.pi], [np.pi, 1.55, np.pi]) for _ in range(30)]
    for beta in betas + [np.array([0.0, 1.569, 0.0]), np.array([np.pi, 0.0, np.pi])]:
        pairs = synthetic_pairs(beta, n=20, noise_imu=1e-12, noise_cam=np.full(3, 1e-12), rng=rng)
        truth = dcm_to_quat(ypr_to_dcm(*beta))
        for init, its in (('given', iters_plain), ('axes', iters_axes)):
            sol = solve_boresight(pairs, init=init, max_iterations=50)
            err = quat_angle_between(dcm_to_quat(sol.c_mf_vf), truth)
            assert sol.converged and err < 1e-6, (init, beta)
            its.append(sol.iterations)
    assert max(iters_axes) <= 2 < np.median(iters_plain)


def test_weighted_covariance_is_consistent_and_better_than_unweighted():
    """The weighted covariance has NEES near 3 and the weighted estimate a smaller error."""
    rng = np.random.default_rng(3)
    C_true = ypr_to_dcm(*BETA)
    errs_w, errs_u, nees_w = [], [], []
    for r in range(150):
        pairs = synthetic_pairs(BETA, n=30, rng=rng)
        for weighted, errs in ((True, errs_w), (False, errs_u)):
            sol = solve_boresight(pairs, weighted=weighted)
            e = quat_error_rotvec(sol.q_mf_vf, dcm_to_quat(C_true), 'reference')     # MF axes
            errs.append(e)
            if weighted:
                nees_w.append(e @ np.linalg.solve(sol.rotation_covariance_mf, e))
    rms_w = np.sqrt(np.mean(np.sum(np.array(errs_w) ** 2, 1)))
    rms_u = np.sqrt(np.mean(np.sum(np.array(errs_u) ** 2, 1)))
    assert 2.5 < np.mean(nees_w) < 3.6
    assert rms_w < 0.8 * rms_u          # the camera's anisotropic noise makes weighting pay


def test_single_axis_and_static_motion_are_unobservable_and_named():
    """Rotations about one axis, or none, are reported unobservable with the axis named."""
    C = ypr_to_dcm(*BETA)
    axis_mf = np.array([0.0, 0.0, 1.0])
    axis_vf = C.T @ axis_mf
    pairs = synthetic_pairs(BETA, axes=[axis_vf, -axis_vf])
    sol = solve_boresight(pairs)
    assert not sol.observable and sol.beta is None
    assert 'all increments share one axis' in sol.message
    named = np.array([float(x) for x in sol.message.split('(')[1].split(')')[0].split(',')])
    assert abs(abs(named @ axis_vf) - 1.0) < 1e-2          # printed with two decimals
    static = synthetic_pairs(BETA, axes=[axis_vf], angle=1.5e-3)          # Earth rate over ~20 s
    sol = solve_boresight(static)
    assert not sol.observable and 'static' in sol.message
    rep = check_observability(synthetic_pairs(BETA))
    assert rep.observable and np.all(rep.predicted_sigma < 1e-3)


def test_camera_increment_covariance_and_imu_attitude_from_camera():
    """E_avu of 004 §3.3 and the IMU attitude and covariance of eq. (8)."""
    q0 = dcm_to_quat(ypr_to_dcm(0.3, 0.2, -0.1))
    q1 = quat_multiply(q0, rotvec_to_quat([0.1, -0.2, 0.05]))
    P0, P1 = np.diag([1.0, 2.0, 3.0]), np.diag([4.0, 5.0, 6.0])
    dq, E = camera_increment(q0, P0, q1, P1)
    dS = quat_to_dcm(dq)
    np.testing.assert_allclose(E, P1 + dS.T @ P0 @ dS)
    pairs = synthetic_pairs(BETA)
    sol = solve_boresight(pairs)
    q_vf = dcm_to_quat(ypr_to_dcm(1.0, 0.4, 2.0))
    q_mf, P = imu_attitude_from_camera(q_vf, P1 * 1e-12, sol)
    np.testing.assert_allclose(quat_to_dcm(q_mf), quat_to_dcm(q_vf) @ sol.c_mf_vf.T, atol=1e-14)
    expected = sol.c_mf_vf @ (P1 * 1e-12) @ sol.c_mf_vf.T + sol.rotation_covariance_mf
    np.testing.assert_allclose(P, expected)


def test_streaming_calibrator_on_the_bench_with_a_large_boresight():
    """The streaming calibrator fed as a live stream finds a large boresight within 3σ."""
    prof = bench_profile()
    rng = np.random.default_rng(1)
    gyro = IntegratingSensor(prof, 'gyro', 200.0, NAVIGATION_GRADE_GYRO.draw(rng), seed=2)
    cam = StarCameraModel(boresight=BETA, interval=5.0, seed=3)
    cal = BoresightCalibrator(gyro=NAVIGATION_GRADE_GYRO)
    fixes = cam.fixes(prof, int(prof.duration // 5.0))
    t, dth, _ = gyro.sample(int(prof.duration * 200))
    k = 0
    for f in fixes:                                  # interleave as a live stream would
        j = np.searchsorted(t, f.stamp + 0.5)
        cal.add_gyro(t[k:j], dth[k:j])
        k = j
        cal.add_camera(f.stamp, f.attitude, f.covariance)
    cal.add_gyro(t[k:], dth[k:])
    sol = cal.solve()
    assert sol.observable and sol.converged and sol.pairs == len(fixes) - 1
    e = quat_error_rotvec(sol.q_mf_vf, dcm_to_quat(ypr_to_dcm(*BETA)), 'reference')
    assert np.all(np.abs(e) < 3 * np.sqrt(np.diag(sol.rotation_covariance_mf)))
    assert np.all(np.sqrt(np.diag(sol.covariance_beta)) < 30 * ARCSEC)


def test_gyro_sensitivity_predicts_the_increment_error_of_the_constants():
    """G (3×12) of gyro_increment: ε_imu ≈ G·[b, vec M] for known constants (noise off)."""
    prof = bench_profile(hold=2.0, rotation_time=3.0, angles_deg=(15.0, -12.0, 10.0),
                         axes=(2, 0, 1))
    b = np.array([2e-6, -1e-6, 3e-6])
    M = np.array([[1e-4, 2e-4, -1e-4], [-3e-4, -2e-4, 1e-4], [2e-4, 1e-4, 3e-4]])
    err = SensorSigmas()                                   # only for the call signature
    t, u, _ = IntegratingSensor(prof, 'gyro', 200.0).sample(int(prof.duration * 200))
    y = u @ (np.eye(3) + M).T + b / 200.0
    t0, t1 = 1.0037, prof.duration - 0.5
    dq_true, *_ = gyro_increment(t, u, t0, t1)
    dq, _, G, white = gyro_increment(t, y, t0, t1, err, sensitivity=True)
    eps = quat_error_rotvec(dq, dq_true, 'body')
    x = np.concatenate([b, M.reshape(-1, order='F')])
    np.testing.assert_allclose(G @ x, eps, atol=2e-3 * np.linalg.norm(eps))
    assert np.all(white == 0)


def test_correlated_weighting_is_consistent_and_beats_pairwise():
    """
    Model the shared camera fixes and the gyro constants common to all pairs.

    NEES near 3 and a smaller RMS than the independent-pairs weighting on the same data (25
    runs, bench, 33 pairs).
    """
    prof = bench_profile()
    q_true = dcm_to_quat(ypr_to_dcm(*BETA))
    rng = np.random.default_rng(5)
    errs = {'correlated': [], 'pairwise': []}
    nees = []
    t_u, u, _ = IntegratingSensor(prof, 'gyro', 200.0).sample(int(prof.duration * 200))
    for seed in range(25):
        e = NAVIGATION_GRADE_GYRO.draw(rng)
        noise = rng.normal(0, e.random_walk * np.sqrt(1 / 200.0), u.shape)
        y = u @ (np.eye(3) + e.matrix).T + e.bias / 200.0 + noise
        cal = BoresightCalibrator(gyro=NAVIGATION_GRADE_GYRO)
        cal.add_gyro(t_u, y)
        cam = StarCameraModel(boresight=BETA, interval=5.0, seed=100 + seed)
        for f in cam.fixes(prof, int(prof.duration // 5)):
            cal.add_camera(f.stamp, f.attitude, f.covariance)
        for w in errs:
            sol = solve_boresight(cal.pairs, weighting=w, gyro=NAVIGATION_GRADE_GYRO,
                                  common_rotation_sigma=cal.common_rotation_sigma)
            ev = quat_error_rotvec(sol.q_mf_vf, q_true, 'reference')
            errs[w].append(ev)
            if w == 'correlated':
                assert sol.weighting == 'correlated'
                nees.append(ev @ np.linalg.solve(sol.rotation_covariance_mf, ev))
    rms = {w: np.sqrt(np.mean(np.sum(np.square(v), 1))) for w, v in errs.items()}
    assert rms['correlated'] < 0.9 * rms['pairwise']
    assert 2.0 < np.mean(nees) < 4.0
    # what the calibrator publishes (≤ 200 pairs)
    assert cal.solve().weighting == 'correlated'


@pytest.mark.parametrize('noise_scale', [100.0, 6000.0])
def test_a_stated_sigma_far_too_small_still_converges_to_the_boresight(noise_scale):
    """
    Converge although the camera noise is 100× and 6000× what the fixes state.

    6000× is ≈1° per axis, a motion-capture reference judged with star-tracker σ.  Every
    weighting converges (the
    Gauss–Newton step is halved while it raises the cost of its own weights; converged once the
    step is below 1e-4 of the residual-scaled σ), β lies within 3 scaled σ of the injected
    truth, no good fix is gated, and the fit is flagged inconsistent.

    Parameters
    ----------
    noise_scale : float
        Actual over stated camera noise.

    """
    beta = np.radians([40.0, -25.0, 120.0])
    prof = bench_profile()
    t, dth, _ = IntegratingSensor(prof, 'gyro', 100.0).sample(int(prof.duration * 100) - 1)
    cam = StarCameraModel(boresight=beta, interval=5.0, seed=1,
                          noise_scale=np.full(3, noise_scale))
    cal = BoresightCalibrator(gyro=NAVIGATION_GRADE_GYRO)
    cal.add_gyro(t, dth)
    for f in cam.fixes(prof, int(prof.duration / 5.0) - 1):
        cal.add_camera(f.stamp, f.attitude, f.covariance)
    assert cal.outlier_fixes == 0 and len(cal.pairs) == 32
    q_true = dcm_to_quat(ypr_to_dcm(*beta))
    for weighting in ('correlated', 'pairwise', 'unit'):
        sol = solve_boresight(cal.pairs, weighting=weighting, gyro=cal.gyro, max_sigma=1.0)
        assert sol.converged and sol.iterations < 20, (weighting, sol.iterations)
        assert sol.fit_consistent is False and sol.chi2_per_dof > 100 * chi2_band(sol.dof)[1]
        e = quat_error_rotvec(sol.q_mf_vf, q_true, frame='reference')
        assert np.all(np.abs(e) < 3 * np.sqrt(np.diag(sol.rotation_covariance_mf))), (weighting, e)
