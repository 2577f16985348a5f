"""
A recording in another container reads as the same streams: rosbag2 sqlite3, and ROS 1 bags.

Drivers and datasets write ROS 1 ``.bag`` files (EuRoC, TUM-VI, a Noetic driver) and rosbag2
sqlite3 directories (rosbag2 before Iron).  The shipped real recording (MCAP, sensor_msgs/Imu
rates and a PoseStamped reference, written by other software) is converted to both with
``rosbags``' converter; every tool's reader must give the same stamps, values, gaps and counts.
"""
from __future__ import annotations

from pathlib import Path
import sqlite3

import numpy as np
import pytest
from realdata_helpers import DATA

pytest.importorskip('rosbags')

from rosbags.convert import convert  # noqa: E402

from strapdown_ros.recording.reader import open_reader, read_bag  # noqa: E402

KW = {'gyro_max_rate': 35.0, 'use_camera_covariance': False, 'camera_sigma': (1e-3, 1e-3, 1e-3)}


def _converted(tmp_path: Path, name: str) -> Path:
    dst = tmp_path / name
    convert([DATA / 'gaitmap_left'], dst, 'sqlite3', 8, None, 'file', None, None, [], [], [], [])
    return dst


def _same(a, b):
    for key in ('gyro', 'camera'):
        x, y = a[key], b[key]
        assert list(map(int, x.stamps)) == list(map(int, y.stamps)), key
        if key == 'gyro':
            np.testing.assert_array_equal(np.asarray(x.values, dtype=float),
                                          np.asarray(y.values, dtype=float))
        else:
            for k in (0, 1):
                np.testing.assert_array_equal(np.array([v[k] for v in x.values]),
                                              np.array([v[k] for v in y.values]))
        assert [tuple(map(int, g)) for g in x.gaps] == [tuple(map(int, g)) for g in y.gaps]
        assert (x.received, x.dropped, x.missing) == (y.received, y.dropped, y.missing), key
    for key in ('gyro_topic', 'camera_topic', 'gyro_input', 'reference_type', 'camera_fixes',
                'frame_counts', 'rate_samples', 'messages_read', 'unread_messages'):
        assert a[key] == b[key], key


@pytest.mark.parametrize('name', ['left.bag', 'left_sqlite3'])
def test_the_shipped_recording_in_another_container_reads_the_same(tmp_path, name):
    mcap = read_bag(DATA / 'gaitmap_left', **KW)
    other = read_bag(_converted(tmp_path, name), **KW)
    assert other['gyro_input'] == 'rates' and len(other['gyro'].stamps) > 7000
    assert other['reference_type'] == mcap['reference_type']
    _same(mcap, other)


def test_a_sqlite3_bag_without_message_definitions_reads_with_the_jazzy_types(tmp_path):
    """rosbag2 before Iron kept no definitions: the Jazzy type store decodes the messages."""
    bag = _converted(tmp_path, 'left_sqlite3')
    con = sqlite3.connect(next(bag.glob('*.db3')))
    con.execute('DELETE FROM message_definitions')
    con.commit()
    con.close()
    reader = open_reader(bag)
    try:
        assert all(c.msgdef.data == '' for c in reader.connections)
    finally:
        reader.close()
    _same(read_bag(DATA / 'gaitmap_left', **KW), read_bag(bag, **KW))
