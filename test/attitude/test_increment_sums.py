"""Sums of stamped increments over the attitude update intervals."""
import numpy as np
import pytest

from strapdown_ros.attitude.increment_sums import IncrementAccumulator


def test_increment_accumulator_bins_by_stamp():
    """Increments are summed into the interval holding their end stamp."""
    acc = IncrementAccumulator()
    ts = np.arange(1, 13) / 300.0
    acc.add(np.ones((12, 3)), ts)
    s, n = acc.take(0.0, 0.01 + 1e-12)
    assert n == 3 and np.allclose(s, 3.0)
    sums, counts = acc.take_many(np.array([0.01, 0.02, 0.03]) + 1e-12)
    assert list(counts) == [3, 3] and np.allclose(sums, 3.0)
    assert acc.covered_until() == pytest.approx(0.04)
