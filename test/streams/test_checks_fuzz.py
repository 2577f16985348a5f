"""
Fuzz tests of the input path.

Extreme values and random bytes never crash it, never
poison what it accepts, and every message is accounted for.
"""
import math

import numpy as np
import pytest

hypothesis = pytest.importorskip('hypothesis')
st = pytest.importorskip('hypothesis.strategies')
given, settings = hypothesis.given, hypothesis.settings

from strapdown_ros.streams.checks import StreamCheck  # noqa: E402

values = st.floats(allow_nan=True, allow_infinity=True, width=64)
stamps = st.one_of(st.integers(0, 10**19), st.integers(10**9, 10**9 + 10**8))
messages = st.lists(st.tuples(stamps, st.tuples(values, values, values)), max_size=200)


@settings(max_examples=300, deadline=None)
@given(messages)
def test_stream_check_never_accepts_poison_and_accounts_for_every_message(msgs):
    c = StreamCheck(0.01, max_norm=0.4, jump_limit=1.0, resync_count=5)
    out = []
    for s, v in msgs:
        got = c.offer(s, v)
        out += got
    for _, v in out:
        assert all(math.isfinite(x) and abs(x) <= 0.4 for x in v)
    held = c.held
    assert c.received == (c.accepted + c.nan + c.out_of_range
                          + c.duplicate + c.out_of_order + c.stamp_outliers + held)
    assert len(out) == c.accepted


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=200))
def test_random_bytes_in_message_decoding_raise_cleanly_or_decode(raw):
    pytest.importorskip('rosbags')
    from rosbags.typesys import get_typestore, Stores
    store = get_typestore(Stores.ROS2_JAZZY)
    for typ in ('geometry_msgs/msg/Vector3Stamped', 'geometry_msgs/msg/PoseWithCovarianceStamped'):
        try:
            m = store.deserialize_cdr(raw, typ)
        except Exception:     # noqa: BLE001 - read_bag turns any of these into BagError
            continue
        # whatever decodes goes through the same rules as a live message
        v = (m.vector.x, m.vector.y, m.vector.z) if hasattr(
            m, 'vector') else tuple(m.pose.covariance[:3])
        StreamCheck(0.01, max_norm=0.4).offer(0, v)


def test_bag_of_garbage_messages_is_a_one_line_error(tmp_path):
    pytest.importorskip('rosbags')
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import get_typestore, Stores

    from strapdown_ros.recording import BagError, read_bag
    from strapdown_ros.tools import calibrate_bag
    store = get_typestore(Stores.ROS2_JAZZY)
    rng = np.random.default_rng(0)
    with Writer(tmp_path / 'bag', version=Writer.VERSION_LATEST) as w:
        c = w.add_connection('/imu/delta_theta',
                             'geometry_msgs/msg/Vector3Stamped', typestore=store)
        k = w.add_connection('/star_camera/attitude',
                             'geometry_msgs/msg/QuaternionStamped', typestore=store)
        for i in range(50):
            w.write(c, i, rng.bytes(int(rng.integers(0, 80))))
            w.write(k, i, rng.bytes(int(rng.integers(0, 80))))
    with pytest.raises(BagError):
        read_bag(tmp_path / 'bag')
    assert calibrate_bag.main([str(tmp_path / 'bag')]) == 2


@settings(max_examples=300, deadline=None)
@given(sec=st.integers(-2 ** 31, 2 ** 31 - 1), nanosec=st.integers(0, 999_999_999),
       frame=st.text(max_size=40),
       xyz=st.tuples(*[st.floats(allow_nan=True, allow_infinity=True)] * 3))
def test_raw_decoder_reads_what_rclpy_serialized(sec, nanosec, frame, xyz):
    """
    Decode exactly the fields of every message rclpy serializes.

    sins_node and calibrator_node subscribe to the increment streams raw and read stamp, vector
    and frame from the bytes (ros_io.decode_vector3_stamped), as sins_bag reads bag records
    (nodes.cdr): for any message rclpy or rosbags serializes, the decoder must return exactly its
    fields (NaN as NaN: the stream rules drop it later).
    """
    import math

    from geometry_msgs.msg import Vector3Stamped
    from rclpy.serialization import serialize_message

    from strapdown_ros.nodes.ros_io import decode_vector3_stamped
    frame = frame.replace('\x00', '')                     # a ROS string cannot hold NUL
    m = Vector3Stamped()
    m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id = sec, nanosec, frame
    m.vector.x, m.vector.y, m.vector.z = xyz
    ns, v, f = decode_vector3_stamped(serialize_message(m))
    assert ns == sec * 1_000_000_000 + nanosec and f == frame
    for got, want in zip(v, xyz):
        assert (math.isnan(got) and math.isnan(want)) or got == want
    # sins_bag reads bag records with the same decoder: rosbags writes the same bytes
    from rosbags.typesys import get_typestore, Stores

    from strapdown_ros.streams.cdr import vector3_stamped
    ts = get_typestore(Stores.ROS2_JAZZY)
    t = ts.types
    rec = t['geometry_msgs/msg/Vector3Stamped'](
        header=t['std_msgs/msg/Header'](stamp=t['builtin_interfaces/msg/Time']
                                        (sec=sec, nanosec=nanosec), frame_id=frame),
        vector=t['geometry_msgs/msg/Vector3'](x=xyz[0], y=xyz[1], z=xyz[2]))
    ns2, v2, f2 = vector3_stamped(ts.serialize_cdr(rec, 'geometry_msgs/msg/Vector3Stamped'))
    assert (ns2, f2) == (ns, f) and all(
        (math.isnan(a) and math.isnan(b)) or a == b for a, b in zip(v2, v))


def test_raw_decoder_big_endian_and_garbage():
    """
    Give big-endian CDR to rclpy and None for bytes that are no message.

    Big-endian CDR goes to rclpy's deserializer (the same fields); bytes that are no message give
    None (the node counts and drops them) instead of an exception.
    """
    import struct

    from strapdown_ros.nodes.ros_io import decode_vector3_stamped
    frame = b'imu_link\x00'
    body = struct.pack('>iII', 12, 345, len(frame)) + frame
    body += b'\x00' * ((-len(body)) % 8) + struct.pack('>3d', 1.5, -2.0, 3.25)
    got = decode_vector3_stamped(b'\x00\x00\x00\x00' + body)
    assert got == (12_000_000_345, (1.5, -2.0, 3.25), 'imu_link')
    for junk in (b'\x00\x01\x00\x00' + b'\xff' * 12, b'\x07\x07', b'\x00\x01\x00\x00\x01\x00',
                 b'', b'\x00'):
        assert decode_vector3_stamped(junk) is None


faults = st.lists(st.tuples(st.integers(0, 6), st.floats(0, 1), st.integers(1, 400)), max_size=12)


@settings(max_examples=80, deadline=None)
@given(st.integers(5, 2500), faults, st.integers(0, 2**32 - 1))
def test_validate_at_array_speed_equals_message_by_message(n, fault_list, seed):
    """
    validate() over arrays (the regular stretches at once) against one message at a time.

    Stamps, values, gaps, time bases and every counter must be the same, whatever the faults:
    NaN, out of range, duplicates, clock steps both ways, bursts that return, dropouts, outliers.
    """
    from strapdown_ros.streams.checks import validate

    rng = np.random.default_rng(seed)
    t = np.cumsum(np.full(n, 10_000_000)).astype(np.int64)
    v = rng.normal(0.0, 1e-3, (n, 3))
    for kind, where, size in fault_list:
        k = int(where * (len(t) - 1))
        if kind == 0:
            v[k, 0] = np.nan
        elif kind == 1:
            v[k] = 1.0
        elif kind == 2 and k:
            t[k] = t[k - 1]
        elif kind == 3:
            t[k:] += (size - 200) * 10_000_000
        elif kind == 4:
            t[k:k + size % 8 + 1] += 5_000_000_000
        elif kind == 5 and len(t) > size + 2:
            keep = np.ones(len(t), bool)
            keep[k:k + size % 30 + 1] = False
            t, v = t[keep], v[keep]
        elif kind == 6:
            t[k] -= 3_000_000_000
    a = StreamCheck(0.01, max_norm=0.5, jump_limit=1.0, resync_count=5)
    b = StreamCheck(0.01, max_norm=0.5, jump_limit=1.0, resync_count=5)
    one = validate(t.tolist(), [tuple(x) for x in v.tolist()], a)
    many = validate(t, v, b)
    assert one[0] == many[0] and one[2] == many[2]
    np.testing.assert_array_equal(np.array(one[1]).reshape(-1, 3),
                                  np.array(many[1]).reshape(-1, 3))
    assert a.segment_starts == b.segment_starts
    for name in ('received', 'accepted', 'nan', 'duplicate', 'out_of_order', 'out_of_range',
                 'gaps', 'missing', 'resyncs', 'stamp_outliers', 'burst_messages', 'period_ns',
                 'largest_out_of_range', 'last_ns'):
        assert getattr(a, name) == getattr(b, name), name
