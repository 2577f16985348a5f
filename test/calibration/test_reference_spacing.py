"""The spacing of the reference fixes, from the correlation of the whitened residuals."""
import numpy as np
from scipy.signal import lfilter

from strapdown_ros.calibration.reference_spacing import (choose_spacing, MAX_SPACING,
                                                         refine_spacing, thin_fixes)
from strapdown_ros.calibration.streaming import BoresightCalibrator
from strapdown_ros.motion.profiles import bench_profile
from strapdown_ros.rotation import quat_multiply, rotvec_to_quat
from strapdown_ros.sensors import IntegratingSensor, NAVIGATION_GRADE_GYRO

N = 30000
DT = 0.01


def ar1(a, n=N, seed=0):
    """Return (n, 3) unit-variance first-order Gauss–Markov noise with coefficient a."""
    w = np.random.default_rng(seed).normal(size=(n, 3))
    w[1:] *= np.sqrt(1.0 - a * a)
    return lfilter([1.0], [1.0, -a], w, axis=0)


def test_white_residuals_keep_every_fix():
    """White residuals: every fix kept."""
    stamps = np.arange(N + 1) * DT
    c = choose_spacing(ar1(0.0), np.ones(N - 1, bool), stamps)
    assert c.step == 1 and 'every fix kept' in c.reason


def test_correlated_residuals_give_the_correlation_time_and_a_spacing_that_decorrelates():
    """An exponential correlation of τ = 10 fixes: τ measured, pairs spaced until ρ is noise."""
    stamps = np.arange(N + 1) * DT
    tau = 10.0
    c = choose_spacing(ar1(np.exp(-1.0 / tau)), np.ones(N - 1, bool), stamps)
    assert abs(c.correlation_time_s / DT - tau) < 1.0
    left = np.exp(-c.step / tau)                       # the true correlation at the step
    assert left <= 2.0 / np.sqrt(3.0 * N / c.step)     # within 2 standard errors at that count
    assert c.step < 8 * tau                            # and not needlessly far apart
    # the check on the pairs kept leaves a right spacing alone
    kept = ar1(np.exp(-c.step / tau), N // c.step, seed=1)
    assert refine_spacing(c, kept, np.ones(len(kept) - 1, bool)).step == c.step


def test_structure_that_does_not_decorrelate_takes_the_largest_spacing():
    """Take a random walk (an effect the model misses) as structure: pairs MAX_SPACING apart."""
    stamps = np.arange(N + 1) * DT
    c = choose_spacing(np.cumsum(ar1(0.0), axis=0), np.ones(N - 1, bool), stamps)
    assert abs(c.spacing_s - MAX_SPACING) < 1e-9 and 'does not explain' in c.reason


def test_thinning_keeps_one_fix_per_slot_even_with_jitter_and_dropouts():
    """Regular fixes with jitter and a dropout: one per slot of the spacing, the first."""
    rng = np.random.default_rng(2)
    t = np.arange(1000) * DT + rng.uniform(-0.1, 0.1, 1000) * DT
    t = np.delete(t, np.arange(300, 340))              # a dropout of 0.4 s
    keep = thin_fixes(t, 10 * DT)
    gaps = np.diff(t[keep])
    assert np.all(gaps > 8.5 * DT) and np.sum(gaps > 11.5 * DT) == 1      # the dropout only
    assert np.array_equal(thin_fixes(t, 0.0), np.arange(len(t)))


def test_fixes_in_blocks_make_the_same_pairs_as_one_at_a_time():
    """Make the same pairs and outliers with add_cameras (calibrate_bag) as add_camera (node)."""
    prof = bench_profile(hold=2.0, rotation_time=3.0)
    s = IntegratingSensor(prof, 'gyro', 100.0)
    t, dth, _ = s.sample(int(40 * 100))
    ts = np.arange(1.0, 39.0, 0.25) + 0.003
    rng = np.random.default_rng(5)
    q = quat_multiply(prof.attitude(ts), rotvec_to_quat(rng.normal(0, 3e-6, (len(ts), 3))))
    q[60] = quat_multiply(q[60], rotvec_to_quat([0.0, 0.0, 2e-3]))      # an outlier fix
    P = np.broadcast_to(np.diag([3e-6, 3e-6, 3e-5]) ** 2, (len(ts), 3, 3))
    one, block = (BoresightCalibrator(gyro=NAVIGATION_GRADE_GYRO) for _ in range(2))
    one.add_gyro(t, dth)
    block.add_gyro(t, dth)
    for k in range(len(ts)):
        one.add_camera(ts[k], q[k], P[k])
    block.add_cameras(ts[:50], q[:50], P[:50])
    block.add_cameras(ts[50:], q[50:], P[50:])
    # the injected fix is gated (and, with it, fixes at the profile's rate steps, where the
    # in-interval polynomial is off): the same ones either way
    assert list(one.outlier_stamps) == list(block.outlier_stamps)
    assert ts[60] in block.outlier_stamps and one.outlier_fixes == block.outlier_fixes
    assert len(one.pairs) == len(block.pairs) == len(ts) - 1 - one.outlier_fixes
    for a, b in zip(one.pairs, block.pairs):
        assert (a.t_start, a.t_end) == (b.t_start, b.t_end)
        np.testing.assert_allclose(a.dq_imu, b.dq_imu, rtol=0, atol=1e-13)
        for x, y in ((a.cov_imu, b.cov_imu), (a.imu_sensitivity, b.imu_sensitivity),
                     (a.cov_imu_white, b.cov_imu_white), (a.cov_cam, b.cov_cam)):
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-9 * np.max(np.abs(x)))
