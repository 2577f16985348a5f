"""Observability of the boresight from all the pairs together; its cost linear in the pairs."""
import tracemalloc

import numpy as np

from strapdown_ros.calibration.boresight import ChainedCovariance, check_observability
from strapdown_ros.calibration.boresight_increments import IncrementPair
from strapdown_ros.calibration.boresight_observability import (boresight_information,
                                                               judge_observability)
from strapdown_ros.rotation import (quat_conjugate, quat_multiply, quat_to_dcm, quat_to_rotvec,
                                    rotvec_to_quat, ypr_to_dcm)
from strapdown_ros.sensors.covariance import constant_variances
from strapdown_ros.sensors.model import SensorSigmas

SIGMA = 1e-3                       # a motion-capture reference, rad per axis
RATE = 100.0                       # fixes per second


def chain(phi, sigma=SIGMA, seed=0):
    """
    Return the arrays of a chain of pairs from attitudes exp(φ(t)) measured with white noise.

    Parameters
    ----------
    phi : (m, 3) ndarray
        True attitudes as rotation vectors, one per fix.
    sigma : float
        Fix noise per axis, rad.
    seed : int
        Seed of the noise.

    Returns
    -------
    tuple
        dq_cam, fix_P, adjacent, white (the arguments of judge_observability).

    """
    rng = np.random.default_rng(seed)
    q = quat_multiply(rotvec_to_quat(phi), rotvec_to_quat(rng.normal(0.0, sigma, phi.shape)))
    dq = quat_multiply(quat_conjugate(q[:-1]), q[1:])
    n = len(dq)
    fix_P = np.broadcast_to(sigma ** 2 * np.eye(3), (n, 2, 3, 3)).copy()
    white = np.broadcast_to(1e-12 * np.eye(3), (n, 3, 3)).copy()
    return dq, fix_P, np.ones(n - 1, dtype=bool), white


def motion(kind, seconds=60.0):
    """Return rotation vectors at RATE: 'rich' (three axes), 'single' (z) or 'static'."""
    t = np.arange(int(seconds * RATE) + 1) / RATE
    phi = np.zeros((len(t), 3))
    if kind == 'rich':
        phi = 0.3 * np.stack([np.sin(0.9 * t), np.sin(0.7 * t + 1.0), np.sin(1.1 * t + 2.0)], 1)
    elif kind == 'single':
        phi[:, 2] = 0.5 * np.sin(t)
    return phi


def test_dense_rich_motion_is_observable_though_every_pair_turns_less_than_half_a_degree():
    """100 fixes/s, rotations of ≤ 0.3° between fixes: observable from the pairs together."""
    dq, fix_P, adjacent, white = chain(motion('rich'))
    per_pair = np.degrees(np.linalg.norm(quat_to_rotvec(dq), axis=1))
    assert per_pair.max() < 0.5                     # the former per-pair rule refused this
    rep = judge_observability(dq, fix_P, adjacent, white)
    assert rep.observable, rep.message
    # σ of a 0.3-rad excursion measured 6000 times at 1e-3 rad: of order 1e-3/(0.3·√6000)
    assert np.all(rep.predicted_sigma < 1e-4)


def test_single_axis_and_static_dense_motion_are_not_observable():
    """Rotation about z only, or none: not observable however many pairs; the axis named."""
    rep = judge_observability(*chain(motion('single')))
    assert not rep.observable and 'one axis' in rep.message
    named = np.array([float(x) for x in rep.message.split('(')[1].split(')')[0].split(',')])
    assert abs(abs(named[2]) - 1.0) < 1e-2
    rep = judge_observability(*chain(motion('static')))
    assert not rep.observable and 'static' in rep.message and len(rep.unobservable) == 3


def test_information_of_chained_pairs_equals_the_dense_generalised_least_squares():
    """F = Hᵀ Σ⁻¹ H, Σ from the fix errors: f_n = θ_n − R_nᵀ θ_{n−1} + gyro noise (004 §3.3)."""
    dq, fix_P, adjacent, white = chain(motion('rich', 0.4))
    n = len(dq)
    R = quat_to_dcm(dq)
    D = np.zeros((3 * n, 3 * (n + 1)))             # pair errors from fix errors
    for k in range(n):
        D[3 * k:3 * k + 3, 3 * k + 3:3 * k + 6] = np.eye(3)
        D[3 * k:3 * k + 3, 3 * k:3 * k + 3] = -R[k].T
    Sigma = D @ np.kron(np.eye(n + 1), SIGMA ** 2 * np.eye(3)) @ D.T
    Sigma += np.kron(np.eye(n), 1e-12 * np.eye(3))
    H = (np.eye(3)[None] - np.swapaxes(R, 1, 2)).reshape(-1, 3)
    dense = H.T @ np.linalg.solve(Sigma, H)
    np.testing.assert_allclose(boresight_information(R, fix_P, adjacent, white), dense,
                               rtol=1e-7)


def test_correlated_weighting_is_the_dense_gls_without_the_dense_matrix():
    """Give Hᵀ Σ⁻¹ H, Hᵀ Σ⁻¹ f, fᵀ Σ⁻¹ f (ChainedCovariance) as with Σ = B + U P_x Uᵀ built."""
    rng = np.random.default_rng(3)
    dq, fix_P, _, _ = chain(motion('rich', 0.3))
    n = len(dq)
    gyro = SensorSigmas(bias_sigma=1e-5, scale_sigma=1e-4, misalignment_sigma=1e-4,
                        random_walk=1e-5)
    pairs = []
    for k in range(n):
        E = 1e-9 * np.eye(3)
        pairs.append(IncrementPair(0.01 * k, 0.01 * (k + 1), dq[k], dq[k], 2 * E, 2 * E,
                                   imu_sensitivity=rng.normal(0, 0.01, (3, 12)),
                                   cov_imu_white=E, cov_fix_start=fix_P[k, 0],
                                   cov_fix_end=fix_P[k, 1]))
    C = ypr_to_dcm(0.3, -0.2, 1.0)
    A = quat_to_dcm(dq)
    cc = ChainedCovariance(pairs, A, gyro)
    H = rng.normal(size=(n, 3, 3))
    f = rng.normal(scale=1e-3, size=(n, 3))
    N, g, cost = cc.normal(cc.at(C), H, f)
    # dense: B from the fix errors and the white gyro part, U P Uᵀ from the sensitivities
    D = np.zeros((3 * n, 3 * (n + 1)))
    for k in range(n):
        D[3 * k:3 * k + 3, 3 * k + 3:3 * k + 6] = np.eye(3)
        D[3 * k:3 * k + 3, 3 * k:3 * k + 3] = -A[k].T
    B = D @ np.kron(np.eye(n + 1), SIGMA ** 2 * np.eye(3)) @ D.T
    B += np.kron(np.eye(n), C.T @ (1e-9 * np.eye(3)) @ C)
    U = np.vstack([C.T @ p.imu_sensitivity for p in pairs])
    Sigma = B + (U * constant_variances(gyro)) @ U.T
    Hs, fs = H.reshape(-1, 3), f.reshape(-1)
    np.testing.assert_allclose(N, Hs.T @ np.linalg.solve(Sigma, Hs), rtol=1e-7)
    np.testing.assert_allclose(g, Hs.T @ np.linalg.solve(Sigma, fs), rtol=1e-7)
    np.testing.assert_allclose(cost, fs @ np.linalg.solve(Sigma, fs), rtol=1e-7)


def _peak_bytes(fn):
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_observability_memory_grows_linearly_with_the_pairs():
    """Four times the pairs, at most about four times the peak memory (an m×m matrix: 16×)."""
    small = chain(motion('rich', 20.0))
    large = chain(motion('rich', 80.0))
    judge_observability(*small)                     # imports and caches before the count
    ratio = (_peak_bytes(lambda: judge_observability(*large))
             / _peak_bytes(lambda: judge_observability(*small)))
    assert ratio < 5.0, ratio

    # the pair-list entry point too (IncrementPair objects, as the calibrator holds them)
    def pairs(arrays):
        dq, fix_P, _, white = arrays
        return [IncrementPair(0.01 * k, 0.01 * (k + 1), dq[k], dq[k], white[k], 2 * fix_P[k, 0],
                              cov_fix_start=fix_P[k, 0], cov_fix_end=fix_P[k, 1])
                for k in range(len(dq))]
    ps, pl = pairs(small), pairs(large)
    ratio = (_peak_bytes(lambda: check_observability(pl))
             / _peak_bytes(lambda: check_observability(ps)))
    assert ratio < 5.0, ratio
