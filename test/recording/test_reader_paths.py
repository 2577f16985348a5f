"""
The two ways ``read_bag`` reads a recording give the same streams.

An indexed MCAP file whose topics all have a fixed layout is read a chunk at a time, decoded
with numpy and screened at array speed; any other bag goes through rosbags' reader record by
record and the rules message by message.  The truth here is the record-by-record path, which
the node-rule tests check against exact motion: the chunked path must give the same stamps,
values, gaps, counters and descriptions, on the shipped real recording (sensor_msgs/Imu rates,
PoseStamped reference, written by other software) and on a simulated Δθ recording with faults.
"""
from __future__ import annotations

import numpy as np
import pytest
from realdata_helpers import DATA

pytest.importorskip('rosbags')

from strapdown_ros.bench.hostile_input import (clean_recording, KINDS,  # noqa: E402
                                               streams_with, write_bag)
from strapdown_ros.recording import reader  # noqa: E402


def _both(monkeypatch, path, **kw):
    used = []
    chunked = reader.chunked_records

    def spy(*a):
        out = chunked(*a)
        used.append(out is not None)
        return out
    with monkeypatch.context() as m:
        m.setattr(reader, 'chunked_records', spy)
        fast = reader.read_bag(path, **kw)
    assert used == [True]                                   # the chunked path was taken
    with monkeypatch.context() as m:
        m.setattr(reader, 'chunked_records', lambda *a: None)
        slow = reader.read_bag(path, **kw)
    return fast, slow


def _same_stream(a, b):
    assert list(map(int, a.stamps)) == list(map(int, b.stamps))
    if len(a.values) and isinstance(a.values[0], tuple) and len(a.values[0]) == 2:
        for k in (0, 1):                                         # fixes: (q, P)
            np.testing.assert_array_equal(np.array([v[k] for v in a.values]),
                                          np.array([v[k] for v in b.values]))
    else:
        np.testing.assert_array_equal(np.asarray(a.values, dtype=float),
                                      np.asarray(b.values, dtype=float))
    assert [tuple(map(int, g)) for g in a.gaps] == [tuple(map(int, g)) for g in b.gaps]
    assert a.received == b.received and a.dropped == b.dropped and a.missing == b.missing
    assert list(a.check.segment_starts) == list(b.check.segment_starts)


def _same(fast, slow):
    _same_stream(fast['gyro'], slow['gyro'])
    _same_stream(fast['camera'], slow['camera'])
    for key in ('gyro_clip', 'camera_fixes', 'frames', 'frame_counts', 'rate_samples',
                'reference_covariance', 'unread_messages', 'messages_read', 'gyro_input'):
        assert fast[key] == slow[key], key


def test_the_shipped_imu_recording_reads_the_same_by_chunks(monkeypatch):
    bag = DATA / 'gaitmap_left'
    fast, slow = _both(monkeypatch, bag, gyro_max_rate=35.0, use_camera_covariance=False,
                       camera_sigma=(1e-3, 1e-3, 1e-3), gyro_topic='/imu/data',
                       reference_topic='/mocap/pose')
    assert fast['gyro_input'] == 'rates' and len(fast['gyro'].stamps) > 7000
    _same(fast, slow)


@pytest.mark.parametrize('stream', ['gyro', 'reference'])
def test_a_hostile_delta_theta_recording_reads_the_same_by_chunks(tmp_path, monkeypatch, stream):
    """Every hostile kind of one stream at once (values, stamps, frames), in one bag."""
    rec = clean_recording(seed=3)
    kinds = [k for k in KINDS if k.stream == stream
             and k.name not in ('wrong_type', 'empty_topic')]    # another type: record by record
    for j, kind in enumerate(kinds):
        rec = streams_with(rec, kind, 40 + 37 * j if stream == 'gyro' else 3 + 2 * j)
    bag = write_bag(tmp_path / stream, rec, accel=False)
    fast, slow = _both(monkeypatch, bag)
    assert sum(fast['gyro' if stream == 'gyro' else 'camera'].dropped.values()) > 0
    _same(fast, slow)


def test_a_transform_stamped_reference_reads_as_the_pose_it_carries(tmp_path):
    """
    A motion-capture driver's TransformStamped (vicon_bridge) gives the fixes of the same pose.

    The shipped recording's PoseStamped reference is rewritten as TransformStamped (rotation =
    the pose's orientation, translation = its position, child frame the marker's), the Imu
    records copied as they are; the two bags must give the same fixes and gyro stream.
    """
    from rosbags.rosbag2 import Reader, StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores

    store = get_typestore(Stores.ROS2_JAZZY)
    T = store.types
    src, out = DATA / 'gaitmap_left', tmp_path / 'transform'
    with Reader(src) as r, Writer(out, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        imu = next(c for c in r.connections if c.topic == '/imu/data')
        pose = next(c for c in r.connections if c.topic == '/mocap/pose')
        c_imu = w.add_connection('/imu/data', imu.msgtype, typestore=store)
        c_tf = w.add_connection('/vicon/foot/foot', 'geometry_msgs/msg/TransformStamped',
                                typestore=store)
        for conn, log, raw in r.messages():
            if conn.id == imu.id:
                w.write(c_imu, log, raw)
            elif conn.id == pose.id:
                m = store.deserialize_cdr(raw, pose.msgtype)
                p = m.pose.position
                tf = T['geometry_msgs/msg/TransformStamped'](
                    header=m.header, child_frame_id='foot',
                    transform=T['geometry_msgs/msg/Transform'](
                        translation=T['geometry_msgs/msg/Vector3'](x=p.x, y=p.y, z=p.z),
                        rotation=m.pose.orientation))
                w.write(c_tf, log, store.serialize_cdr(tf, 'geometry_msgs/msg/TransformStamped'))
    kw = {'gyro_max_rate': 35.0, 'use_camera_covariance': False,
          'camera_sigma': (1e-3, 1e-3, 1e-3), 'gyro_topic': '/imu/data'}
    a = reader.read_bag(src, reference_topic='/mocap/pose', **kw)
    b = reader.read_bag(out, reference_topic='/vicon/foot/foot', **kw)
    assert b['reference_type'] == 'geometry_msgs/msg/TransformStamped'
    assert len(b['camera'].stamps) > 1000
    _same_stream(a['gyro'], b['gyro'])
    _same_stream(a['camera'], b['camera'])
    assert a['frames']['camera'] == b['frames']['camera']


def test_a_driver_bag_needs_no_topic_options_when_its_topics_are_unique(tmp_path):
    """One Imu topic and one pose-like topic: taken without --gyro-topic/--reference-topic."""
    kw = {'gyro_max_rate': 35.0, 'use_camera_covariance': False,
          'camera_sigma': (1e-3, 1e-3, 1e-3)}
    named = reader.read_bag(DATA / 'gaitmap_left', gyro_topic='/imu/data',
                            reference_topic='/mocap/pose', **kw)
    found = reader.read_bag(DATA / 'gaitmap_left', **kw)
    assert (found['gyro_topic'], found['camera_topic']) == ('/imu/data', '/mocap/pose')
    _same_stream(named['gyro'], found['gyro'])
    _same_stream(named['camera'], found['camera'])
    # two Imu topics: which one is the user's to say
    from rosbags.rosbag2 import Reader, StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores

    store = get_typestore(Stores.ROS2_JAZZY)
    out = tmp_path / 'two_imus'
    with Reader(DATA / 'gaitmap_left') as r, \
            Writer(out, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {}
        for c in r.connections:
            conns[c.id] = [w.add_connection(c.topic, c.msgtype, typestore=store)]
            if c.topic == '/imu/data':
                conns[c.id].append(w.add_connection('/imu/data_raw', c.msgtype, typestore=store))
        for conn, log, raw in r.messages():
            for c in conns[conn.id]:
                w.write(c, log, raw)
    with pytest.raises(reader.BagError, match='no imu/delta_theta.*/imu/data_raw'):
        reader.read_bag(out, **kw)
    assert reader.read_bag(out, gyro_topic='/imu/data_raw', **kw)['gyro_topic'] == \
        '/imu/data_raw'


def test_sins_bag_input_takes_a_driver_bags_one_imu_topic():
    from strapdown_ros.recording.imu_streams import open_input

    named = open_input(DATA / 'gaitmap_left', imu_topic='/imu/data')
    found = open_input(DATA / 'gaitmap_left')
    try:
        assert found.gyro_conn.topic == '/imu/data' and found.imu_input
        np.testing.assert_array_equal(found.gyro.stamps_ns, named.gyro.stamps_ns)
        np.testing.assert_array_equal(found.gyro.values, named.gyro.values)
    finally:
        named.close()
        found.close()
