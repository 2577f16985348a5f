"""The input rules of every node and tool (strapdown_ros/streams.py), one rule at a time."""
import math

import numpy as np

from strapdown_ros.streams import StreamCheck, nominal_period, validate

MS = 10_000_000          # 10 ms in ns


def feed(check, stamps, values=None):
    out = []
    for k, s in enumerate(stamps):
        v = (0.001, 0.0, 0.0) if values is None else values[k]
        out += check.offer(int(s), v)
    return [s for s, _ in out]


def test_nan_range_duplicate_out_of_order_gap():
    c = StreamCheck(0.01, max_norm=2 * 0.01 * 20.0)
    vals = [(0.001, 0, 0), (math.nan, 0, 0), (1e308, 1e308, 0.0), (1000.0, 0, 0), (0.001, 0, 0), (0.001, 0, 0),
            (0.001, 0, 0), (0.001, 0, 0)]
    got = feed(c, [1 * MS, 2 * MS, 3 * MS, 4 * MS, 5 * MS, 5 * MS, 4 * MS, 8 * MS], vals)
    assert got == [1 * MS, 5 * MS, 8 * MS]
    assert (c.nan, c.out_of_range, c.duplicate, c.out_of_order) == (1, 2, 1, 1)
    assert (c.gaps, c.missing) == (2, 5)          # 1→5 (3 missing), 5→8 (2 missing)


def test_lone_future_stamp_is_an_outlier_and_stops_nothing():
    c = StreamCheck(0.01, jump_limit=1.0, resync_count=5)
    stamps = [k * MS for k in range(1, 11)] + [10**18] + [k * MS for k in range(11, 31)]
    got = feed(c, stamps)
    assert got == [k * MS for k in range(1, 31)]
    assert (c.stamp_outliers, c.resyncs, c.gaps) == (1, 0, 0)


def test_clock_reset_resynchronises_and_loses_nothing():
    c = StreamCheck(0.01, jump_limit=1.0, resync_count=5)
    before = [(1000 + k) * MS for k in range(10)]
    after = [k * MS for k in range(1, 20)]                 # the clock restarted near zero
    got = feed(c, before + after)
    assert got == before + after                           # the held messages are released in order
    assert c.resyncs == 1 and c.out_of_order == 0 and c.last_jump_s < -9.0
    assert c.rate_hz() == np.float64(100.0) or abs(c.rate_hz() - 100.0) < 1e-9


def test_validate_offline_reports_the_jump_as_a_gap_and_the_rate_from_stamps():
    st = [k * 5_000_000 for k in range(1, 200)] + [10**12 + k * 5_000_000 for k in range(200)]
    assert nominal_period(st) == 0.005
    c = StreamCheck(nominal_period(st), jump_limit=1.0, resync_count=5)
    t, v, gaps = validate(st, [(0.0, 0.0, 0.0)] * len(st), c)
    assert len(t) == len(st) and gaps == [(st[198], st[199])]
