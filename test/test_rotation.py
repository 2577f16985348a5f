"""Rotation conventions: checked against independent constructions (scipy, matrix exponentials)."""
import numpy as np
import pytest

from strapdown_ros import rotation as R

rng = np.random.default_rng(1)


def random_quats(n):
    """Return n random unit quaternions."""
    return R.quat_normalize(rng.normal(size=(n, 4)))


def test_quaternion_dcm_matches_scipy_convention():
    scipy_rot = pytest.importorskip('scipy.spatial.transform').Rotation
    q = random_quats(50)
    C = R.quat_to_dcm(q)
    # scipy: scalar-last, active rotation matrix mapping body → reference
    C_ref = scipy_rot.from_quat(R.to_ros_xyzw(q)).as_matrix()
    np.testing.assert_allclose(C, C_ref, atol=1e-14)
    np.testing.assert_allclose(R.quat_rotate(q, [1.0, 2.0, 3.0]), C @ [1.0, 2.0, 3.0], atol=1e-13)


def test_rotvec_quaternion_dcm_roundtrips_and_rodrigues():
    axis = R.quat_normalize(np.hstack([np.zeros((100, 1)), rng.normal(size=(100, 3))]))[:, 1:]
    phi = axis * rng.uniform(0.0, np.pi - 1e-3, (100, 1))          # principal range of log
    q = R.rotvec_to_quat(phi)
    np.testing.assert_allclose(R.quat_to_rotvec(q), phi, atol=1e-13)
    # Rodrigues (003 eq. 1.42) against a series matrix exponential
    for p in phi[:5]:
        K = R.skew(p)
        expm = np.eye(3)
        term = np.eye(3)
        for k in range(1, 40):
            term = term @ K / k
            expm = expm + term
        np.testing.assert_allclose(R.rotvec_to_dcm(p), expm, atol=1e-13)
    sign = np.sign(q[:, :1])
    np.testing.assert_allclose(R.dcm_to_quat(R.quat_to_dcm(q)) * sign, q * sign, atol=1e-13)


def test_small_and_zero_rotation_vectors_are_exact():
    tiny = np.array([[1e-12, -2e-12, 3e-12], [0.0, 0.0, 0.0]])
    q = R.rotvec_to_quat(tiny)
    np.testing.assert_allclose(q[:, 1:], tiny / 2, rtol=1e-12, atol=0)
    np.testing.assert_allclose(R.quat_to_rotvec(q), tiny, rtol=1e-9, atol=1e-30)


def test_composition_and_body_increment_update():
    a, b = random_quats(2)
    np.testing.assert_allclose(R.quat_to_dcm(R.quat_multiply(a, b)),
                               R.quat_to_dcm(a) @ R.quat_to_dcm(b), atol=1e-14)
    # a body-axis increment multiplies on the right: U_k = U_{k-1} A(φ)   (003 eq. 1.64)
    phi = np.array([0.1, -0.2, 0.3])
    np.testing.assert_allclose(R.quat_to_dcm(R.quat_multiply(a, R.rotvec_to_quat(phi))),
                               R.quat_to_dcm(a) @ R.rotvec_to_dcm(phi), atol=1e-14)


def test_cumprod_equals_sequential_product():
    q0 = random_quats(1)[0]
    dq = R.rotvec_to_quat(rng.normal(size=(37, 3)) * 0.2)
    seq = [q0]
    for d in dq:
        seq.append(R.quat_normalize(R.quat_multiply(seq[-1], d)))
    out = R.quat_cumprod(q0, dq)
    np.testing.assert_allclose(out, np.array(seq[1:]), atol=1e-14)


def test_error_rotvec_definitions():
    q_true = random_quats(1)[0]
    eps = np.array([1e-4, -2e-4, 3e-4])
    q_est = R.quat_multiply(q_true, R.rotvec_to_quat(eps))
    np.testing.assert_allclose(R.quat_error_rotvec(q_est, q_true, 'body'), eps, atol=1e-15)
    # C_est = C_true (I + [ε×]) to first order: the 004 §2.3 definition
    np.testing.assert_allclose(R.quat_to_dcm(q_est), R.quat_to_dcm(
        q_true) @ (np.eye(3) + R.skew(eps)), atol=1e-7)
    e_ref = R.quat_to_dcm(q_true) @ eps
    np.testing.assert_allclose(R.quat_error_rotvec(q_est, q_true, 'reference'), e_ref, atol=1e-15)
    assert R.quat_angle_between(q_est, q_true) == pytest.approx(np.linalg.norm(eps), rel=1e-9)


def test_ros_order_roundtrip():
    q = random_quats(3)
    np.testing.assert_array_equal(R.from_ros_xyzw(R.to_ros_xyzw(q)), q)
    assert list(R.to_ros_xyzw([1.0, 0.0, 0.0, 0.0])) == [0.0, 0.0, 0.0, 1.0]


def test_ypr_sequence_of_004():
    yaw, pitch, roll = 0.7, -0.4, 2.1
    C = R.ypr_to_dcm(yaw, pitch, roll)
    np.testing.assert_allclose(C, R.rotvec_to_dcm([0, 0, -yaw]) @ R.rotvec_to_dcm([pitch, 0, 0])
                               @ R.rotvec_to_dcm([0, roll, 0]), atol=1e-15)
    np.testing.assert_allclose(R.dcm_to_ypr(C), [yaw, pitch, roll], atol=1e-14)
    angles = rng.uniform([-np.pi, -1.5, -np.pi], [np.pi, 1.5, np.pi], size=(200, 3))
    back = R.dcm_to_ypr(R.ypr_to_dcm(angles[:, 0], angles[:, 1], angles[:, 2]))
    np.testing.assert_allclose(back, angles, atol=1e-12)


def test_ypr_error_maps_match_004_d1_d2_by_finite_differences():
    """004 §5: C(β + δβ) ≈ C(β)(I + [D1 δβ ×]) and D2 = C D1 (its printed D2 fixes the signs)."""
    beta = np.array([0.7, -0.4, 2.1])
    D1, D2 = R.ypr_error_to_rotation(*beta)
    C = R.ypr_to_dcm(*beta)
    for k in range(3):
        d = np.zeros(3)
        d[k] = 1e-6
        dC = (R.ypr_to_dcm(*(beta + d)) - R.ypr_to_dcm(*(beta - d))) / 2e-6
        W = C.T @ dC                                      # = [θ×] per unit δβ_k
        np.testing.assert_allclose([W[2, 1], W[0, 2], W[1, 0]], D1[:, k], atol=1e-8)
    # the printed D1 of 004 §5
    sp, cp, sg, cg = np.sin(-0.4), np.cos(-0.4), np.sin(2.1), np.cos(2.1)
    np.testing.assert_allclose(D1, [[sg * cp, cg, 0], [-sp, 0, 1], [-cg * cp, sg, 0]], atol=1e-15)
    np.testing.assert_allclose(D2, C @ D1, atol=1e-15)


def test_aircraft_angles_of_000():
    phi = np.array([-0.5, 0.17, -0.6])        # 000 §6 initial angles
    q = R.aircraft_angles_to_quat(phi)
    C = (R.rotvec_to_dcm([0, phi[0], 0]) @ R.rotvec_to_dcm([0, 0, phi[1]])
         @ R.rotvec_to_dcm([phi[2], 0, 0]))
    np.testing.assert_allclose(R.quat_to_dcm(q), C, atol=1e-15)
