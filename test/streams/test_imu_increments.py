"""
The gyro_input imu core: RateIncrementStream and the raw sensor_msgs/Imu decoder.

gyro_input imu, the core part: RateIncrementStream (validation + the increment rule, the glue
sins_node and calibrator_node share) and the raw decoder of sensor_msgs/Imu bytes.
"""
import math
import struct

import numpy as np
import pytest

from strapdown_ros.streams.rate_increments import increments_from_rates, RateIncrementStream

T_NS = 10_000_000                          # 100 Hz
A, NU = 0.3, 2.0                           # ω_z(t) = A sin(νt), rad/s


def _rate(t):
    return np.stack([0.1 * np.ones_like(t), np.zeros_like(t), A * np.sin(NU * t)], axis=-1)


def _exact(t0, t1):
    """∫ω dt over (t0, t1] of _rate, closed form."""
    z = A / NU * (np.cos(NU * t0) - np.cos(NU * t1))
    return np.stack([0.1 * (t1 - t0), np.zeros_like(t0), z], axis=-1)


def _feed(stream, stamps_ns, rates):
    out = []
    for s, w in zip(stamps_ns, rates):
        out += stream.push(int(s), tuple(float(c) for c in w))
    return out


def test_a_clean_stream_gives_the_offline_increments_and_the_exact_integral():
    st = (10**12 + T_NS * np.arange(1, 301)).astype(np.int64)
    t = (st - 10**12) * 1e-9
    w = _rate(t)
    s = RateIncrementStream(0.01, 20.0, 'trapezoid')
    got = _feed(s, st, w)
    t_off, inc_off = increments_from_rates(st, w, 'trapezoid', 0.015)
    assert [g[0] for g in got] == list(t_off)
    np.testing.assert_array_equal(np.array([g[1] for g in got]), inc_off)        # to the bit
    # against the exact integral: the trapezoid error per increment is T³|ω̈|/12 at most
    exact = _exact(t[:-1], t[1:])
    assert np.max(np.abs(inc_off - exact)) <= 0.01 ** 3 * A * NU ** 2 / 12 * 1.001
    assert s.integrator.formed == 299 and s.integrator.skipped == 0 and s.check.accepted == 300
    # mean rule on mean rates: exact
    mean = exact / 0.01
    s = RateIncrementStream(0.01, 20.0, 'mean')
    got = _feed(s, st, np.vstack([[0, 0, 0], mean]))
    np.testing.assert_allclose(np.array([g[1] for g in got]), exact, rtol=0, atol=1e-16)


def test_bad_samples_are_dropped_counted_and_the_lost_interval_is_a_gap():
    st = (10**12 + T_NS * np.arange(1, 41)).astype(np.int64)
    w = _rate((st - 10**12) * 1e-9)
    s = RateIncrementStream(0.01, 20.0, 'trapezoid')
    out = []
    for k, (ns, v) in enumerate(zip(st, w)):
        v = tuple(float(c) for c in v)
        if k == 25:
            out += s.push(int(ns), (math.nan, 0.0, 0.0))          # NaN: dropped
            continue
        out += s.push(int(ns), v)
        if k == 28:
            out += s.push(int(ns), v)                           # duplicate stamp: dropped
            out += s.push(int(st[3]), v)                        # out of order: dropped
        if k == 30:
            out += s.push(int(ns), (25.0, 0.0, 0.0))            # beyond the range: dropped
    c = s.check
    assert (c.nan, c.duplicate, c.out_of_order, c.out_of_range, c.dropped) == (1, 1, 1, 1, 4)
    assert c.accepted == 39 and c.gaps == 1 and c.missing == 1
    # the interval over the NaN (samples 24 → 26, 2 periods; the gap rule judges from 16 steps
    # of the stamps on) is not integrated: 38 steps, 37 formed
    stamps = [o[0] for o in out]
    assert s.integrator.formed == 37 and s.integrator.skipped == 1
    assert int(st[25]) not in stamps and int(st[26]) not in stamps
    t_off, inc_off = increments_from_rates(np.delete(st, 25), np.delete(w, 25, axis=0),
                                           'trapezoid', 0.015)
    assert stamps == list(t_off)
    np.testing.assert_array_equal(np.array([o[1] for o in out]), inc_off)
    kv = s.status('imu_gyro')
    assert (kv['imu_gyro_dropped'], kv['imu_gyro_increments_formed'],
            kv['imu_gyro_increments_skipped']) == (4, 37, 1)


def test_a_stamp_resync_restarts_the_integrator():
    a = (10**12 + T_NS * np.arange(1, 11)).astype(np.int64)
    b = (5 * 10**12 + T_NS * np.arange(1, 11)).astype(np.int64)       # the clock jumps by 4000 s
    st = np.concatenate([a, b])
    w = np.tile([[0.0, 0.0, 1.0]], (20, 1))
    s = RateIncrementStream(0.01, 20.0, 'trapezoid', jump_limit=1.0, resync_count=3)
    out = _feed(s, st, w)
    assert s.check.resyncs == 1
    # 9 increments per timeline: no increment spans the jump, nothing of the new timeline is lost
    assert [o[0] for o in out] == list(a[1:]) + list(b[1:])
    np.testing.assert_allclose(np.array([o[1] for o in out]), np.tile([[0, 0, 0.01]], (18, 1)),
                               atol=1e-17)


@pytest.mark.parametrize('frame, accel', [('imu_link', True), ('', False), ('é' * 7, True)])
def test_the_raw_imu_decoder_reads_what_rclpy_serialized(frame, accel):
    rclpy = pytest.importorskip('rclpy')   # noqa: F841
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Imu

    from strapdown_ros.nodes.ros_io import decode_imu
    from strapdown_ros.streams.cdr import imu
    m = Imu()
    m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id = 1234, 567_890_123, frame
    m.orientation_covariance[0] = -1.0
    m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = 0.25, -1.5, math.nan
    m.angular_velocity_covariance = [float(k) for k in range(9)]
    m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = 9.5, -0.125, 1e300
    if not accel:
        m.linear_acceleration_covariance[0] = -1.0
    data = serialize_message(m)
    got = imu(data)
    assert got is not None and decode_imu(data)[0] == got[0]
    ns, w, f, fr = got
    assert ns == 1234_567_890_123 and fr == frame
    assert w[:2] == (0.25, -1.5) and math.isnan(w[2])
    assert f == ((9.5, -0.125, 1e300) if accel else None)
    # the stated covariance, read only for /diagnostics
    from strapdown_ros.nodes.ros_io import stated_rate_variance
    from strapdown_ros.streams.cdr import imu_rate_covariance
    assert imu_rate_covariance(data) == tuple(float(k) for k in range(9))
    assert stated_rate_variance(data) == stated_rate_variance(m) == '0, 4, 8'
    m.angular_velocity_covariance = [0.0] * 9
    assert stated_rate_variance(serialize_message(m)) == 'unknown'
    m.angular_velocity_covariance[0] = -1.0
    assert stated_rate_variance(serialize_message(m)) == 'not provided'
    assert stated_rate_variance(None) == 'none received'
    # big-endian CDR goes to rclpy's deserializer; bytes that are no Imu give None
    body = struct.pack('>iII', 12, 345, 1) + b'\x00' + b'\x00' * 3
    doubles = [0.0] * 13 + [1.0, 2.0, 3.0] + [0.0] * 9 + [4.0, 5.0, 6.0] + [0.0] * 9
    body += struct.pack('>37d', *doubles)
    assert decode_imu(b'\x00\x00\x00\x00' + body) == (12_000_000_345, (1.0, 2.0, 3.0),
                                                      (4.0, 5.0, 6.0), '')
    for junk in (b'\x00\x01\x00\x00' + b'\xff' * 12, b'\x07\x07', data[:60], b''):
        assert decode_imu(junk) is None


def test_the_raw_imu_decoder_for_any_frame_length_and_values():
    """
    Decode every padding of the float64 block exactly as rclpy serialized it.

    Every padding of the float64 block (frame_id lengths 0..40, multi-byte characters) and any
    values: the decoder returns exactly what rclpy serialized.
    """
    hypothesis = pytest.importorskip('hypothesis')
    pytest.importorskip('rclpy')
    from hypothesis import strategies as st
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Imu

    from strapdown_ros.streams.cdr import imu, imu_rate_covariance
    f64 = st.floats(allow_nan=False, allow_infinity=True, width=64)

    @hypothesis.settings(max_examples=100, deadline=None)
    @hypothesis.given(sec=st.integers(-2 ** 31, 2 ** 31 - 1), nanosec=st.integers(0, 999_999_999),
                      frame=st.text(max_size=40), w=st.tuples(f64, f64, f64),
                      a=st.tuples(f64, f64, f64), cov=st.lists(f64, min_size=9, max_size=9))
    def check(sec, nanosec, frame, w, a, cov):
        frame = frame.replace('\x00', '')                  # a ROS string cannot hold NUL
        m = Imu()
        m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id = sec, nanosec, frame
        m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = w
        m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = a
        m.angular_velocity_covariance = cov
        data = serialize_message(m)
        ns, w2, a2, f2 = imu(data)
        assert (ns, w2, a2, f2) == (sec * 1_000_000_000 + nanosec, w, a, frame)
        assert imu_rate_covariance(data) == tuple(cov)
    check()
