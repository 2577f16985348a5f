"""The input rules of every node and tool (strapdown_ros/streams/checks.py), one rule at a time."""
import math

import numpy as np

from strapdown_ros.streams.checks import nominal_period, StreamCheck, validate

MS = 10_000_000          # 10 ms in ns


def feed(check, stamps, values=None):
    """Offer every message in turn; return what was released."""
    out = []
    for k, s in enumerate(stamps):
        v = (0.001, 0.0, 0.0) if values is None else values[k]
        out += check.offer(int(s), v)
    return [s for s, _ in out]


def test_nan_range_duplicate_out_of_order_gap():
    c = StreamCheck(0.01, max_norm=2 * 0.01 * 20.0)
    head = [(-k) * MS for k in range(16, 0, -1)] + [0]     # 16 steps: the period from the stamps
    vals = [(0.001, 0, 0)] * 17 + [(0.001, 0, 0), (math.nan, 0, 0), (1e308, 1e308, 0.0),
                                   (1000.0, 0, 0), (0.001, 0, 0), (0.001, 0, 0), (0.001, 0, 0),
                                   (0.001, 0, 0)]
    got = feed(c, head + [1 * MS, 2 * MS, 3 * MS, 4 * MS, 5 * MS, 5 * MS, 4 * MS, 8 * MS], vals)
    assert got == head + [1 * MS, 5 * MS, 8 * MS]
    assert (c.nan, c.out_of_range, c.duplicate, c.out_of_order) == (1, 2, 1, 1)
    assert (c.gaps, c.missing) == (2, 5)          # 1→5 (3 missing), 5→8 (2 missing)


def test_gaps_come_from_the_stamps_not_the_stated_period():
    """A 50 Hz stream under a stated 100 Hz, and ±30 % stamp jitter: no gap; a lost one seen."""
    rng = np.random.default_rng(1)
    c = StreamCheck(0.01)                              # stated 100 Hz
    t = np.arange(500) * 2 * MS                        # 50 Hz
    feed(c, t)
    assert (c.gaps, c.missing) == (0, 0) and abs(c.period_s - 0.02) < 1e-12
    k = np.arange(60_000)
    jit = (k * 1_000_000 + rng.uniform(-0.3, 0.3, k.size) * 1_000_000).astype(np.int64)
    c = StreamCheck(1e-3)
    feed(c, jit)
    assert (c.gaps, c.missing) == (0, 0)               # ±30 % of the period: never a gap
    clean = (k * 1_000_000).astype(np.int64)
    c = StreamCheck(1e-3)
    feed(c, np.delete(clean, [1000, 2000, 2001, 30_000]))
    assert (c.gaps, c.missing) == (3, 4)
    assert c.gap_marks == [] and c.period_s == 1e-3


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
    assert got == before + after      # the held messages are released in order
    assert c.resyncs == 1 and c.out_of_order == 0 and c.last_jump_s < -9.0
    assert c.rate_hz() == np.float64(100.0) or abs(c.rate_hz() - 100.0) < 1e-9


def test_validate_offline_reports_the_jump_as_a_gap_and_the_rate_from_stamps():
    st = [k * 5_000_000 for k in range(1, 200)] + [10**12 + k * 5_000_000 for k in range(200)]
    assert nominal_period(st) == 0.005
    c = StreamCheck(nominal_period(st), jump_limit=1.0, resync_count=5)
    t, v, gaps = validate(st, [(0.0, 0.0, 0.0)] * len(st), c)
    assert len(t) == len(st) and gaps == [(st[198], st[199])]


def test_burst_of_past_stamps_costs_only_itself():
    """
    Count a burst of stamps in the past as a burst, not a resynchronisation.

    A burst of 5 consecutive increments stamped 1000 s in the past, then the stream goes
    on.  The two confirmed jumps make a burst: 5 messages counted, no resynchronisation left,
    one gap of exactly the 5 lost increments; offline the output is strictly increasing.
    """
    for sign in (-1, +1):                                  # 1000 s in the past, and in the future
        st = [k * MS for k in range(1, 1001)]
        bad = list(st)
        for i in range(500, 505):
            bad[i] += sign * 1000 * 10**9
        c = StreamCheck(0.01, jump_limit=1.0, resync_count=5)
        t, v, gaps = validate(bad, [(0.0, 0.0, 0.0)] * len(bad), c)
        assert t == st[:500] + st[505:]
        assert gaps == [(st[499], st[505])] and c.segment_starts == []
        counts = (c.bursts, c.burst_messages, c.resyncs, c.dropouts, c.gaps, c.missing)
        assert counts == (1, 5, 0, 0, 1, 5)


def test_dropout_beyond_the_jump_limit_counts_its_missing_increments():
    """
    Keep dropouts and saturation on the same timeline, their losses counted.

    2 s without increments (beyond max_stamp_jump = 1 s) and a 1-s
    saturation (values out of range, dropped) are dropouts on the same timeline, with their
    missing increments counted, not clock resets with 0 missing.
    """
    st = [k * MS for k in range(1, 1001)]
    kept = [s for s in st if not 300 * MS < s <= 500 * MS]                 # 200 not received
    c = StreamCheck(0.01, jump_limit=1.0, resync_count=5)
    t, _, gaps = validate(kept, [(0.001, 0.0, 0.0)] * len(kept), c)
    assert t == kept and gaps == [(300 * MS, 501 * MS)]
    assert (c.dropouts, c.resyncs, c.gaps, c.missing) == (1, 0, 1, 200)
    # saturated for 1.01 s: values beyond the range, dropped
    vals = [(0.5, 0.0, 0.0) if 600 * MS < s <= 701 * MS else (0.001, 0.0, 0.0) for s in st]
    c = StreamCheck(0.01, max_norm=2 * 0.01 * 20.0, jump_limit=1.0, resync_count=5)
    t, _, gaps = validate(st, vals, c)
    assert (c.out_of_range, c.dropouts, c.resyncs, c.gaps, c.missing) == (101, 1, 0, 1, 101)
    assert gaps == [(600 * MS, 702 * MS)]


def test_clock_reset_offline_gives_monotonic_segments():
    from strapdown_ros.streams.checks import segments
    st = [(1000 + k) * MS for k in range(100)] + [k * MS for k in range(1, 50)]
    c = StreamCheck(0.01, jump_limit=1.0, resync_count=5)
    t, _, _ = validate(st, [(0.0, 0.0, 0.0)] * len(st), c)
    assert c.resyncs == 1 and c.segment_starts == [100]
    for a, b in segments(t, c.segment_starts):
        assert all(y > x for x, y in zip(t[a:b - 1], t[a + 1:b]))


def test_two_dropouts_close_together_are_not_a_burst():
    """Two forward dropouts 500 messages apart: both stay on the timeline, nothing is retracted."""
    st = [k * MS for k in range(1, 2001)]
    kept = [s for s in st if not (300 * MS < s <= 500 * MS or 1000 * MS < s <= 1150 * MS)]
    c = StreamCheck(0.01, jump_limit=1.0, resync_count=5)
    t, _, gaps = validate(kept, [(0.0, 0.0, 0.0)] * len(kept), c)
    assert t == kept and gaps == [(300 * MS, 501 * MS), (1000 * MS, 1151 * MS)]
    assert (c.dropouts, c.bursts, c.resyncs, c.gaps, c.missing) == (2, 0, 0, 2, 350)
