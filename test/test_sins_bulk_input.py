"""
The whole-recording input path of the SINS core equals the one-message path.

The whole-recording input path of the SINS core (sins_bag's): the vectorised CDR decoder, the
vectorised stream rules and the block feeding give exactly what the node's one-message path
gives — the same accepted messages and counters, the same attitude to the bit, the navigation to
round-off — on streams with faults (NaN, out of range, duplicates, out of order, stamp outliers,
gaps, foreign frames).
"""
import math

import numpy as np
import pytest

from strapdown_ros.params import model_and_settings
from strapdown_ros.sins import screen_stream, SinsSettings, SinsSystem
from strapdown_ros.streams.cdr import stamped_doubles, vector3_stamped
from strapdown_ros.streams.checks import StreamCheck
from strapdown_ros.text import bounded


def _faulty_stream(rng, n, period_ns, scale, arrival=False):
    """
    Make a stream with every kind of fault the rules handle (no resync).

    Stamps and vectors of a stream with every kind of fault the rules handle (no resync);
    ``arrival``: also the times the messages arrive (the stamps before the per-message faults).
    """
    st = np.arange(1, n + 1, dtype=np.int64) * period_ns + 5_000
    v = rng.normal(0.0, scale, (n, 3))
    clean = st.copy()
    for k in sorted(rng.choice(np.arange(10, n - 10), 40, replace=False)):
        kind = k % 6
        if kind == 0:
            v[k, 1] = np.nan
        elif kind == 1:
            v[k, 2] = 1e300                                  # out of range
        elif kind == 2:
            st[k] = st[k - 1]                                # duplicate
        elif kind == 3:
            st[k] = st[k - 1] - period_ns // 2               # out of order
        elif kind == 4:
            st[k] = st[k - 1] + 50 * 10**9                   # a lone stamp far in the future
        else:
            st[k:] += 3 * period_ns                          # a gap
            clean[k:] += 3 * period_ns
    return (st, v, clean) if arrival else (st, v)


def test_stamped_doubles_equals_the_one_message_decoder():
    rosbags = pytest.importorskip('rosbags.typesys')
    ts = rosbags.get_typestore(rosbags.Stores.ROS2_JAZZY)
    T = ts.types
    rng = np.random.default_rng(3)
    recs = []
    for k in range(400):
        frame = ['', 'imu_link', 'a', 'x' * 7, 'y' * 8, 'é', 'imu_link2'][k % 7]
        m = T['geometry_msgs/msg/Vector3Stamped'](
            header=T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
                sec=int(rng.integers(-5, 2**31 - 1)), nanosec=int(rng.integers(0, 10**9))),
                frame_id=frame),
            vector=T['geometry_msgs/msg/Vector3'](x=float(rng.normal()), y=float(rng.normal()),
                                                  z=1e300))
        recs.append(bytes(ts.serialize_cdr(m, 'geometry_msgs/msg/Vector3Stamped')))
    recs += [b'\x00\x00' + recs[0][2:], recs[1][:20]]                # other encoding, truncated
    st, v, idx, names, bad = stamped_doubles(recs, 3)
    assert bad.tolist() == [400, 401]
    for i, r in enumerate(recs[:400]):
        ns, xyz, frame = vector3_stamped(r)
        assert (int(st[i]), tuple(v[i]), names[idx[i]]) == (ns, xyz, frame)


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_screen_stream_gives_the_counters_and_messages_of_offer(seed):
    rng = np.random.default_rng(seed)
    st, v = _faulty_stream(rng, 3000, 10_000_000, 1e-3)
    one = StreamCheck(0.01, max_norm=0.1, jump_limit=1.0, resync_count=5)
    got_one = []
    for s, x in zip(st.tolist(), v.tolist()):
        got_one += one.offer(s, tuple(x))
    bulk = StreamCheck(0.01, max_norm=0.1, jump_limit=1.0, resync_count=5)
    segs = screen_stream(bulk, st, v)
    assert len(segs) == 1
    assert segs[0][0].tolist() == [s for s, _ in got_one]
    assert np.array_equal(segs[0][1], np.array([x for _, x in got_one]))
    assert bulk.as_dict('s') == one.as_dict('s') and bulk.dropped == one.dropped > 0
    assert one.gaps > 0 and one.stamp_outliers > 0 and one.nan > 0 and one.out_of_order > 0


def _params(**kw):
    base = {'gyro_rate': 100.0, 'accel_rate': 300.0, 'gyro_random_walk': 1e-6}
    base.update(kw)
    model, settings = model_and_settings('sins_node', base)
    return model, SinsSettings.from_values(settings)


def _collect(outs):
    att = [o.attitude for o in outs if len(o.attitude)]
    nav = [o.navigation for o in outs if len(o.navigation)]
    imu = [o.imu for o in outs if len(o.imu)]
    return (np.concatenate([a.stamp_ns for a in att]), np.concatenate([a.attitude for a in att]),
            np.concatenate([a.covariance for a in att]),
            np.concatenate([b.position for b in nav]) if nav else np.zeros((0, 3)),
            np.concatenate([b.stamp_ns for b in nav]) if nav else np.zeros(0, np.int64),
            np.concatenate([b.specific_force for b in imu]) if imu else np.zeros((0, 3)),
            np.concatenate([b.covariance for b in nav]) if nav else np.zeros((0, 9, 9)))


@pytest.mark.parametrize('navigation', [False, True])
def test_screen_and_feed_equal_the_node_path(navigation):
    """
    Give the same results on the node's path and the whole-recording path.

    The node's path (every message offered in stamp order, a block every batch_period) and
    the whole-recording path (screen, then blocks of 257 Δθ / 500 Δv) on the same faulty
    streams with foreign frames: the same counters, the same attitude and covariance to the bit,
    the navigation positions to round-off.
    """
    rng = np.random.default_rng(5)
    n = 4000
    g_st, g_v, g_at = _faulty_stream(rng, n, 10_000_000, 2e-4, arrival=True)
    a_st, a_v, a_at = _faulty_stream(rng, 3 * n, 3_333_333, 1e-3, arrival=True)
    a_v[:, 2] += 9.8 / 300
    g_frames = np.zeros(n, np.int64)
    g_frames[[3, 700, 1500]] = 1
    names = ['imu_link', 'stray']
    kw = {}
    if navigation:
        kw = {'navigation': True, 'initial_position': [50.45, 30.52, 150.0],
              'initial_velocity': [0.0, 0.0, 0.0]}
    p = _params(**kw)
    node = SinsSystem(*p, imu_wanted=lambda: True)
    outs_node = []
    # the messages as a node receives them: in the order they arrive (a wrong stamp does not
    # delay a message), Δv first at equal times
    order = sorted([(t, 0, k) for k, t in enumerate(a_at.tolist())] +
                   [(t, 1, k) for k, t in enumerate(g_at.tolist())])
    order = [(is_gyro, k) for _, is_gyro, k in order]
    for is_gyro, k in order:
        if is_gyro:
            if node.offer_gyro(int(g_st[k]), tuple(g_v[k].tolist()), names[g_frames[k]]):
                outs_node.append(node.process())
            elif node.has_output:
                outs_node.append(node.take_output())
        elif node.offer_accel(int(a_st[k]), tuple(a_v[k].tolist()), 'imu_link'):
            outs_node.append(node.process())
    outs_node += [node.process(), node.finish()]

    bulk = SinsSystem(*p, imu_wanted=lambda: True)
    sg = bulk.screen('gyro', g_st, g_v, g_frames, names)
    sa = bulk.screen('accel', a_st, a_v)
    assert sg is not None and sa is not None
    outs_bulk = list(bulk.feed(sg, sa, block=257, accel_block=500))
    assert bulk.status() == node.status() if not navigation else \
        {k: v for k, v in bulk.status().items() if 'sigma' not in k} == \
        {k: v for k, v in node.status().items() if 'sigma' not in k}
    assert bulk.frame_mismatch == node.frame_mismatch == {'gyro': 3, 'accel': 0}
    a, b = _collect(outs_node), _collect(outs_bulk)
    assert np.array_equal(a[0], b[0]) and len(a[0]) > 1000
    assert np.array_equal(a[1], b[1])                            # attitude: to the bit
    assert np.array_equal(a[2], b[2])
    assert np.array_equal(a[5], b[5])                            # sins/imu specific force
    if navigation:
        assert np.array_equal(a[4], b[4]) and len(a[4]) > 1000
        print('navigation: max |Δposition|', np.max(np.abs(a[3] - b[3])), 'm')
        assert np.max(np.abs(a[3] - b[3])) <= 1e-6             # round-off (m; achieved: 0)
        # each step carries the covariance of the latest epoch completed at it, whatever the
        # blocks (navigation/covariance.py)
        scale = np.max(np.abs(a[6]))
        assert scale > 0 and np.max(np.abs(a[6] - b[6])) <= 1e-12 * scale


def test_screen_returns_none_at_a_resync_and_changes_nothing():
    p = _params()
    sys_ = SinsSystem(*p)
    st = np.arange(1, 101, dtype=np.int64) * 10_000_000 + 1000 * 10**9
    st[50:] -= 100 * 10**9          # a clock reset that stays (back; a forward jump is a dropout)
    before = sys_.gyro_check.as_dict('g')
    assert sys_.screen('gyro', st, np.zeros((100, 3))) is None
    assert sys_.gyro_check.as_dict('g') == before


def test_bounded_cuts_long_text_and_says_how_long_it_was():
    assert bounded('imu_link') == 'imu_link'
    text = bounded('x' * 2_000_000)
    assert text.startswith('x' * 64 + '…') and '2000000 chars' in text and len(text) < 100
    assert bounded(12345, 3) == '123…(5 chars)'


def test_frame_warning_is_built_only_when_emitted_and_bounded():
    """
    Build the frame warning only when it is emitted, and bounded.

    A 2 MB frame id costs no string building per message, and the warning that
    is emitted carries at most the bounded id.
    """
    p = _params()
    logged = []
    s = SinsSystem(*p, log=lambda level, text: logged.append(text))
    huge = 'f' * 2_000_000
    for k in range(1, 2001):
        s.offer_gyro(k * 10_000_000, (0.0, 0.0, 0.0), huge)
    assert s.frame_mismatch['gyro'] == 2000
    assert len(logged) == 1 and len(logged[0]) < 300 and '2000000 chars' in logged[0]
    assert math.isfinite(s.status()['gyro_received'])


def test_mcap_chunk_reader_gives_rosbags_records_in_rosbags_order(tmp_path):
    """
    Read MCAP chunks as rosbags reads them, in the same order.

    sins_bag's chunk reader (recording/mcap_records.py, compiled scan and its plain form) against
    rosbags' reader on an MCAP file of several chunks overlapping in log time, with frame ids
    of several lengths: the same records in the same order, the same decoded numbers.
    """
    pytest.importorskip('rosbags')
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores

    from strapdown_ros.recording import mcap_records
    from strapdown_ros.recording import open_reader
    from strapdown_ros.recording.imu_streams import read_streams
    store = get_typestore(Stores.ROS2_JAZZY)
    T = store.types
    rng = np.random.default_rng(9)
    n = 40_000
    log = (np.arange(n) + 100) * 1_000_000
    log = log + rng.integers(-30, 30, n) * 1_000_000              # out of order: chunks overlap
    path = tmp_path / 'chunks'
    with Writer(path, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin.MCAP) as w:
        conns = [w.add_connection(t, 'geometry_msgs/msg/Vector3Stamped', typestore=store)
                 for t in ('/imu/delta_theta', '/imu/delta_velocity')]
        for k in range(n):
            ns = int(log[k])
            frame = 'imu_link' if k % 97 else 'imu_link_long'
            m = T['geometry_msgs/msg/Vector3Stamped'](
                header=T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
                    sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame),
                vector=T['geometry_msgs/msg/Vector3'](x=float(k), y=float(rng.normal()), z=0.5))
            w.write(conns[k % 2], ns, store.serialize_cdr(m, 'geometry_msgs/msg/Vector3Stamped'))
    rd = open_reader(path)
    try:
        storage = mcap_records.indexed_mcap(rd)
        assert storage is not None and len(storage.chunks) >= 3
        sel = list(rd.connections)
        ref = {c.topic: [] for c in sel}
        for c, _, raw in rd.messages(connections=sel):
            ref[c.topic].append(vector3_stamped(raw))
        got = read_streams(rd, sel, path)
        ids = mcap_records.channel_ids(storage, sel)
        plain = [mcap_records.scan_plain(np.frombuffer(b'\x05' + bytes(8), np.uint8),
                                         np.ones(3, bool))]
    finally:
        rd.close()
    assert plain[0][1] and len(ids) == 2
    for topic, items in ref.items():
        s = got[topic]
        assert len(s) == len(items) == n // 2
        assert s.stamps_ns.tolist() == [x[0] for x in items]
        assert np.array_equal(s.values, np.array([x[1] for x in items]))
        assert [s.frame_names[i] for i in s.frame_index] == [x[2] for x in items]


def test_mcap_scan_compiled_and_plain_agree():
    from strapdown_ros.recording import mcap_records
    rng = np.random.default_rng(2)
    parts = []
    for k in range(300):
        body = bytes(rng.integers(0, 256, int(rng.integers(22, 80)), dtype=np.uint8))
        op = 0x05 if k % 5 else 0x06
        ch = int(rng.integers(0, 4))
        rec = ch.to_bytes(2, 'little') + body[2:] if op == 0x05 else body
        parts.append(bytes([op]) + len(rec).to_bytes(8, 'little') + rec)
    buf = np.frombuffer(b''.join(parts), np.uint8)
    wanted = np.array([True, False, True, True])
    a, whole_a = mcap_records.scan_python(buf, wanted)
    b, whole_b = mcap_records.scan_plain(buf, wanted)
    c, whole_c = mcap_records.scanner()(buf, wanted)
    assert whole_a and whole_b and whole_c and len(a) > 100
    assert np.array_equal(a, b) and np.array_equal(a, c)
    _, whole = mcap_records.scan_plain(buf[:-3], wanted)
    assert not whole                                                  # a record cut short
