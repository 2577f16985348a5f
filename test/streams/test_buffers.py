"""Bounded buffers with O(1) amortised appends."""
import numpy as np

from strapdown_ros.attitude.increment_sums import IncrementAccumulator
from strapdown_ros.calibration.streaming import BoresightCalibrator
from strapdown_ros.streams.buffers import StampedBuffer


def test_stamped_buffer_is_bounded_and_keeps_the_newest():
    b = StampedBuffer(3, max_len=1000, initial=16)
    for k in range(5000):
        b.extend([k * 0.01], [[k, 0.0, 0.0]])
        assert b.storage_size <= 2000                          # storage never beyond 2× the bound
    assert len(b) == 1000 and b.overflowed == 4000
    np.testing.assert_array_equal(b.values[:, 0], np.arange(4000, 5000))
    b.drop_through(45.0)
    assert b.stamps[0] > 45.0 and b.last_stamp == 49.99


def test_calibrator_gyro_history_after_a_single_fix_is_bounded():
    """
    Keep the gyro history of the calibrator at its bound without fixes.

    One fix, then a long stream of gyro increments and no second fix: the history stays at its
    bound (it used to grow without limit and each add converted the whole list: 12–20 ms).
    """
    cal = BoresightCalibrator(max_buffer=20_000)
    cal.add_camera(0.0, np.array([1.0, 0, 0, 0]), np.eye(3) * 1e-10)
    for k in range(1, 60_001):
        cal.add_gyro([k * 0.005], [[1e-5, 0.0, 0.0]])
    assert len(cal.gyro_history) == 20_000 and cal.gyro_history.overflowed == 40_000
    assert cal.gyro_history.storage_size <= 40_000


def test_delta_v_without_gyro_does_not_pile_up():
    acc = IncrementAccumulator(max_len=1000)
    for k in range(10):
        acc.add(np.ones((500, 3)), k * 5.0 + np.arange(1, 501) * 0.01)
    assert len(acc) == 1000 and acc.overflowed == 4000
    total, n = acc.take(-1.0, 1e9)
    assert n == 1000 and len(acc) == 0 and np.all(total == 1000.0)


def test_single_sample_path_equals_the_batch_path():
    """calibrator_node's one-increment path gives the pairs of the batch path, to the bit."""
    from strapdown_ros.motion.profiles import bench_profile
    from strapdown_ros.sensors import IntegratingSensor, NAVIGATION_GRADE_GYRO
    from strapdown_ros.sensors.star_camera import StarCameraModel
    prof = bench_profile()
    t, dth, _ = IntegratingSensor(prof, 'gyro', 100.0).sample(6000)
    fixes = StarCameraModel(boresight=[0.7, -0.4, 2.1], interval=5.0, seed=2).fixes(prof, 11)
    a, b = BoresightCalibrator(gyro=NAVIGATION_GRADE_GYRO), BoresightCalibrator(
        gyro=NAVIGATION_GRADE_GYRO)
    a.add_gyro(t, dth)
    for s, v in zip(t, dth):
        b.add_gyro_sample(float(s), v)
    for f in fixes:
        a.add_camera(f.stamp, f.attitude, f.covariance)
        b.add_camera(f.stamp, f.attitude, f.covariance)
    assert len(a.pairs) == len(b.pairs) == 10
    for p, q in zip(a.pairs, b.pairs):
        np.testing.assert_array_equal(p.dq_imu, q.dq_imu)
        np.testing.assert_array_equal(p.cov_imu, q.cov_imu)
