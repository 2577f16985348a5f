"""
The filter's block propagation: the numbers do not depend on how the increments arrive.

Exact motion (a constant rate) with the gyro's exact increments plus a known bias, and fixes of
the exact attitude: the same data given one increment per call, in blocks of 37, or at once,
with states reported at chosen stamps, gives the same state bit for bit; and a state reported
inside a block equals the state of a filter stopped there.
"""
import numpy as np
import pytest

from strapdown_ros.estimation import AttitudeFilter
from strapdown_ros.rotation import quat_multiply, rotvec_to_quat

W = np.array([0.3, -0.2, 0.1])            # rad/s
BIAS = np.array([2e-5, -1e-5, 3e-5])      # rad/s
T = 0.01


def _filter(tau):
    return AttitudeFilter([1.0, 0.0, 0.0, 0.0], 0.0, gyro_random_walk=1e-6,
                          gyro_bias_random_walk=1e-7, gyro_bias_correlation_time=tau,
                          initial_sigma=1e-4, bias_sigma=1e-4, max_queued=50)


def _run(f, block, n=1234, marks=()):
    st = T * np.arange(1, n + 1)
    d = np.tile((W + BIAS) * T, (n, 1))
    fixes = [(float(t), rotvec_to_quat(W * t)) for t in st[99::100]]
    reports, k = [], 0
    for i in range(0, n, block):
        j = min(n, i + block)
        while k < len(fixes) and fixes[k][0] <= st[j - 1]:
            f.update(fixes[k][0], fixes[k][1], 1e-10 * np.eye(3))  # applied at its epoch
            k += 1
        m = [x - i for x in marks if i <= x < j]
        f.propagate(d[i:j], st[i:j], marks=m)
        reports += f.take_reports()
    return reports


@pytest.mark.parametrize('tau', [0.0, 30.0])                     # random walk, Gauss–Markov
def test_arrival_does_not_change_a_number(tau):
    marks = (0, 49, 50, 99, 333, 700, 1233)
    runs = [(_filter(tau), b) for b in (1, 37, 10_000)]
    reports = [_run(f, b, marks=marks) for f, b in runs]
    f0 = runs[0][0]
    assert f0.counters.applied == 12
    for f, _ in runs[1:]:
        np.testing.assert_array_equal(f.attitude, f0.attitude)
        np.testing.assert_array_equal(f.P, f0.P)
        np.testing.assert_array_equal(f.x, f0.x)
    for r in reports[1:]:
        assert len(r) == len(reports[0]) == len(marks)
        for a, b in zip(r, reports[0]):
            assert a.stamp == b.stamp
            np.testing.assert_array_equal(a.attitude, b.attitude)
            np.testing.assert_array_equal(a.covariance, b.covariance)


def test_a_report_inside_a_block_is_the_state_of_a_filter_stopped_there():
    """
    A mark at stamp t equals a second filter given the increments up to t only.

    Inside a coning update (algorithm 2, an odd increment) the report applies the unfinished
    update's increments one by one, as the filter stopped there does when asked (its flush).
    """
    for mark in (333, 334):
        f = _filter(0.0)
        r = _run(f, 10_000, marks=(mark,))[0]
        g = _filter(0.0)
        _run(g, 10_000, n=mark + 1)
        far = quat_multiply(g.attitude, rotvec_to_quat(np.array([1.0, 0.0, 0.0])))
        assert g.update(T * (mark + 1), far, 1e-10 * np.eye(3)).status == 'gated'
        # the stopped filter, its unfinished update completed by a gated fix (no correction)
        assert r.stamp == pytest.approx(T * (mark + 1), abs=1e-12)
        np.testing.assert_allclose(r.attitude, g.attitude, rtol=0, atol=1e-15)
        np.testing.assert_allclose(r.covariance[:6, :6], g.P[:6, :6], rtol=1e-12, atol=1e-30)
