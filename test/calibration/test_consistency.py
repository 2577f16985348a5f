"""004 §5 eq. (8) and the Fig. 3 θ_diff check against exact truth (calibration.consistency)."""
import subprocess
import sys

import numpy as np
import pytest

from strapdown_ros.calibration.consistency import (camera_imu_attitude, d_matrices,
                                                   sins_from_camera, theta_diff_check)
from strapdown_ros.estimation.chi_square import chi2_interval
from strapdown_ros.rotation import (dcm_to_quat, quat_conjugate, quat_multiply, quat_normalize,
                                    quat_to_rotvec, rotvec_to_quat, ypr_to_dcm)

AS = np.radians(1.0 / 3600.0)


def _vee(A):
    return 0.5 * np.array([A[2, 1] - A[1, 2], A[0, 2] - A[2, 0], A[1, 0] - A[0, 1]])


def test_d_matrices_printed_and_derived_equal_the_exact_derivative():
    """Both printed and derived D1, D2 equal the finite-difference derivatives of C."""
    rng = np.random.default_rng(3)
    for _ in range(20):
        b = rng.uniform(-1.4, 1.4, 3)
        C = ypr_to_dcm(*b)
        D1 = np.zeros((3, 3))
        for j in range(3):
            d = np.zeros(3)
            d[j] = 1e-6
            # C(β+δ) = C(I+[θ×])
            D1[:, j] = _vee(C.T @ (ypr_to_dcm(*(b + d)) - ypr_to_dcm(*(b - d)))) / 2e-6
        for form in ('derived', 'printed'):
            E1, E2 = d_matrices(b, form)
            assert np.allclose(E1, D1, atol=1e-8) and np.allclose(E2, C @ D1, atol=1e-8)
    with pytest.raises(ValueError):
        d_matrices(np.zeros(3), 'other')


def _scenario(rng, n=25):
    """Exact MF attitudes: static holds and turns of 10°–120° about random axes."""
    q = [quat_normalize(rng.normal(size=4))]
    for k in range(n - 1):
        ang = np.radians(rng.uniform(10, 120)) if k % 2 == 0 else np.radians(0.09)
        ax = rng.normal(size=3)
        step = rotvec_to_quat(ang * ax / np.linalg.norm(ax))
        q.append(quat_normalize(quat_multiply(q[-1], step)))
    return np.array(q)


BETA_TRUE = np.array([0.7, -0.4, 1.9])                     # far from small (004 §1)
SIG_AVU = np.array([2.0, 2.0, 20.0]) * AS                  # anisotropic about the optical axis
P_BETA = np.diag([6.0, 0.6, 0.6]) ** 2 * AS ** 2 + 0.2 * AS ** 2
SIG_GYRO = 1.5 * AS                                        # per interval, per axis


def _run(rng, q_mf, beta_offset=np.zeros(3), printed_alignment=False):
    n = len(q_mf)
    C_true = ypr_to_dcm(*BETA_TRUE)
    q_vf_true = quat_multiply(q_mf, dcm_to_quat(C_true)[None])
    th = rng.normal(size=(n, 3)) * SIG_AVU
    q_vf = quat_normalize(quat_multiply(q_vf_true, rotvec_to_quat(th)))
    d_beta = rng.multivariate_normal(np.zeros(3), P_BETA)
    beta = BETA_TRUE + d_beta + beta_offset
    dq_true = quat_multiply(quat_conjugate(q_mf[:-1]), q_mf[1:])
    gyro_noise = rotvec_to_quat(rng.normal(size=(n - 1, 3)) * SIG_GYRO)
    dq = quat_normalize(quat_multiply(dq_true, gyro_noise))
    E = np.broadcast_to(np.eye(3) * SIG_GYRO ** 2, (n - 1, 3, 3))
    q_ins, P_ins = sins_from_camera(q_vf, beta, dq, E, printed_alignment=printed_alignment)
    P_avu = np.diag(SIG_AVU ** 2)
    return q_vf, P_avu, beta, q_ins, P_ins


def test_eq8_covariance_matches_monte_carlo():
    """θ^mfa = log(S̆ᵀ S̃) has the covariance of eq. (8): mean NEES in the χ² band."""
    rng = np.random.default_rng(5)
    q_mf = _scenario(rng, 10)
    nees = []
    for _ in range(400):
        q_vf, P_avu, beta, _, _ = _run(rng, q_mf)
        q_cam, P = camera_imu_attitude(q_vf, P_avu, beta, P_BETA)
        th = quat_to_rotvec(quat_multiply(quat_conjugate(q_mf), q_cam))
        nees.append(np.einsum('ni,ni->n', th, np.linalg.solve(P, th[..., None])[..., 0]))
    nees = np.array(nees)                                       # runs × epochs
    lo, hi = chi2_interval(3 * 400, 1 - 0.01 / 10)
    assert np.all((nees.sum(0) > lo) & (nees.sum(0) < hi)), nees.mean(0)


def test_theta_diff_derived_covariance_consistent_printed_not():
    """
    Test the Fig. 3 check with exact truth over a Monte Carlo.

    The derived P^diff holds at every epoch; 004 §6's P^imu + P^mfa misses the shared
    boresight error and the alignment fix.
    """
    rng = np.random.default_rng(11)
    q_mf = _scenario(rng, 25)
    M = 300
    nees = {'derived': [], 'printed': []}
    within = []
    for _ in range(M):
        q_vf, P_avu, beta, q_ins, P_ins = _run(rng, q_mf)
        for form in nees:
            chk = theta_diff_check(q_vf, P_avu, beta, P_BETA, q_ins, P_ins, aligned_at=0,
                                   covariance=form)
            nees[form].append(chk.nees[1:])
            if form == 'derived':
                within.append(chk.within_3sigma)
                assert chk.theta[0] == pytest.approx(np.zeros(3), abs=1e-12)    # aligned there
    lo, hi = chi2_interval(3 * M, 1 - 0.01 / 24)
    s_der = np.sum(nees['derived'], axis=0)
    s_pr = np.sum(nees['printed'], axis=0)
    assert np.all((s_der > lo) & (s_der < hi)), s_der / M
    assert np.mean(within) > 0.99
    # the printed form fails at many epochs
    assert np.sum((s_pr < lo) | (s_pr > hi)) >= 5, s_pr / M


def test_wrong_boresight_detected_and_right_one_passes():
    """A boresight off by many σ fails the check; the right one passes."""
    rng = np.random.default_rng(21)
    q_mf = _scenario(rng, 25)
    passed = 0
    for _ in range(20):
        q_vf, P_avu, beta, q_ins, P_ins = _run(rng, q_mf)
        passed += theta_diff_check(q_vf, P_avu, beta, P_BETA, q_ins, P_ins).consistent
    assert passed >= 17                                   # 95% band: 19 expected
    # the check can see a bias only as well as θ_diff itself resolves β (≈ 10″ here): 30″, 120″
    for offset in (np.array([0.0, 0.0, 30.0]) * AS, np.array([120.0, 0.0, 0.0]) * AS):
        # the SINS is aligned through the wrong C too: the error shows only after turns (I − Rᵀ)
        q_vf, P_avu, beta, q_ins, P_ins = _run(rng, q_mf, beta_offset=offset)
        chk = theta_diff_check(q_vf, P_avu, beta, P_BETA, q_ins, P_ins)
        assert not chk.consistent and chk.joint_nees > 3 * chk.nees_band[1], chk.joint_nees
    # 004 §6 as printed, S_1^MF = S_1^VF: off by the whole boresight rotation
    q_vf, P_avu, beta, q_ins, P_ins = _run(rng, q_mf, printed_alignment=True)
    chk = theta_diff_check(q_vf, P_avu, beta, P_BETA, q_ins, P_ins)
    assert not chk.consistent and np.nanmax(np.linalg.norm(chk.theta, axis=1)) > 0.5


def test_independent_sins_and_printed_log():
    """
    Test a SINS aligned independently of the camera.

    P^diff = P^imu + P^mfa is exact (004 §6's form); the printed skew-part log agrees with the
    exact one to second order.
    """
    rng = np.random.default_rng(8)
    q_mf = _scenario(rng, 12)
    P_ins = np.broadcast_to(np.eye(3) * (3 * AS) ** 2, (12, 3, 3))
    tot = np.zeros(12)
    for _ in range(300):
        q_vf, P_avu, beta, _, _ = _run(rng, q_mf)
        sins_error = rotvec_to_quat(rng.normal(size=(12, 3)) * 3 * AS)
        q_ins = quat_normalize(quat_multiply(q_mf, sins_error))
        a = theta_diff_check(q_vf, P_avu, beta, P_BETA, q_ins, P_ins, aligned_at=None)
        b = theta_diff_check(q_vf, P_avu, beta, P_BETA, q_ins, P_ins, aligned_at=None,
                             log='printed')
        assert np.max(np.abs(a.theta - b.theta)) < np.max(np.abs(a.theta)) ** 3      # third order
        assert a.used.all()
        tot += a.nees
    lo, hi = chi2_interval(3 * 300, 1 - 0.01 / 12)
    assert np.all((tot > lo) & (tot < hi)), tot / 300


def test_arguments_checked():
    """Unknown forms and wrong shapes raise ValueError."""
    q = np.tile([1.0, 0, 0, 0], (3, 1))
    with pytest.raises(ValueError):
        theta_diff_check(q, np.eye(3), np.zeros(3), np.eye(3), q, covariance='other')
    with pytest.raises(ValueError):
        theta_diff_check(q, np.eye(3), np.zeros(3), np.eye(3), q[:2])
    with pytest.raises(ValueError):
        sins_from_camera(q, np.zeros(3), q[:1])


def test_sins_constants_recursion_against_exact_propagation():
    """ε_n = ΔS_nᵀ ε_{n−1} + G_n x: the SINS error for interval errors G_n x equals J_n x."""
    rng = np.random.default_rng(2)
    q_mf = _scenario(rng, 15)
    C = ypr_to_dcm(*BETA_TRUE)
    q_vf = quat_multiply(q_mf, dcm_to_quat(C)[None])                    # exact camera
    G = rng.normal(size=(14, 3, 12))
    x = rng.normal(size=12) * 1e-7
    dq_true = quat_multiply(quat_conjugate(q_mf[:-1]), q_mf[1:])
    dq = quat_normalize(quat_multiply(dq_true, rotvec_to_quat(G @ x)))
    Pc = np.diag(rng.uniform(0.5, 2.0, 12)) * 1e-14
    q_ins, P, J = sins_from_camera(q_vf, BETA_TRUE, dq, sensitivity=G, white=np.zeros((14, 3, 3)),
                                   constant_variances=Pc, return_sensitivity=True)
    err = quat_to_rotvec(quat_multiply(quat_conjugate(q_mf), q_ins))
    # second order in |ε|
    assert np.max(np.abs(err - J @ x)) < 10 * np.max(np.abs(err)) ** 2 + 1e-14
    assert np.allclose(P, J @ Pc @ np.swapaxes(J, 1, 2), rtol=1e-12, atol=0)


def test_core_module_imports_no_ros():
    """The module imports neither ROS nor matplotlib nor scipy."""
    code = ('import sys, strapdown_ros.calibration.consistency; '
            "heavy = ('rclpy', 'rosbag2_py', 'matplotlib', 'scipy'); "
            "bad = [m for m in sys.modules if m.split('.')[0] in heavy]; "
            'print(bad); sys.exit(1 if bad else 0)')
    assert subprocess.run([sys.executable, '-c', code], capture_output=True).returncode == 0
