"""002 (Ilyushenko 2009), the interval means: gyro side, interval layout, camera covariance."""
import numpy as np
import pytest

from strapdown_ros.calibration.interval_means import (camera_rate_covariance,
                                                      interval_boundaries, mean_measured_rate)
from strapdown_ros.motion.profiles import ConingProfile


def test_mean_measured_rate_exact_sum_and_partial_intervals():
    """s̄ is the exact sum on gyro epochs; between them quadratic beats linear interpolation."""
    p = ConingProfile(0.2, 3.0)
    t = 0.01 * np.arange(1, 501)
    dth = p.delta_theta(t - 0.01, t)
    # on gyro epochs: the exact sum
    s = mean_measured_rate(t, dth, [0.0, 0.5], [1.0, 4.3])
    np.testing.assert_allclose(s, p.delta_theta(np.array([0.0, 0.5]), np.array([1.0, 4.3]))
                               / np.array([[1.0], [3.8]]), atol=1e-15)
    # between epochs: linear interpolation error ~ |ṡ|h²/8 per end, quadratic far smaller
    t0 = np.array([0.1234, 1.0071, 2.5555])
    t1 = t0 + np.array([0.777, 1.3333, 1.2345])
    exact = p.delta_theta(t0, t1) / (t1 - t0)[:, None]
    e_lin = np.abs(mean_measured_rate(t, dth, t0, t1) - exact).max()
    e_quad = np.abs(mean_measured_rate(t, dth, t0, t1, interpolation='quadratic') - exact).max()
    wdot = 0.2 * 3.0 ** 2                                        # |ẇ| ≈ ν² sin α
    assert e_lin < 2 * wdot * 0.01 ** 2 / 8 / 0.777
    assert e_quad < 0.1 * e_lin
    with pytest.raises(ValueError):
        mean_measured_rate(t, dth, [-1.0], [1.0])


def test_interval_boundaries_skip_gaps():
    """No interval spans a data gap; length and step counts give the same layout."""
    stamps = np.concatenate([0.1 * np.arange(1, 40), 6.0 + 0.1 * np.arange(30)])
    iv = interval_boundaries(stamps, steps_per_interval=10)
    assert len(iv) == 3 + 2
    assert np.all(np.diff(stamps)[iv[:, 0]] < 0.2)
    for a, b in iv:
        assert np.all(np.diff(stamps[a:b + 1]) < 0.2)            # no interval spans the gap
    iv2 = interval_boundaries(stamps, interval_length=1.0)
    np.testing.assert_array_equal(iv, iv2)


def test_camera_covariance_shared_boundaries():
    """Consecutive intervals share a fix: their w̄ errors correlate at about −½."""
    p = ConingProfile(0.1, 1.0)
    stamps = 0.1 * np.arange(31)
    q = p.attitude(stamps)
    iv = np.array([[0, 10], [10, 20], [20, 30]])
    R = camera_rate_covariance(q, iv, stamps, camera_sigma=1e-5)
    var = np.diag(R)
    np.testing.assert_allclose(var, 2 * 1e-10 / 1.0 ** 2, rtol=0.05)       # ≈ 2σ²/T²
    corr = R[0, 3] / np.sqrt(R[0, 0] * R[3, 3])
    assert -0.55 < corr < -0.45
    assert np.all(R[0:3, 6:9] == 0.0)
