"""
Helpers shared by the tests on the shipped real-data excerpt (test/data/gaitmap/).

The bags are read with rosbags directly, not with the package's reader, so what the tests
compare the tools against does not come from the code under test.
"""
from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np

from strapdown_ros.rotation import quat_angle_between

DATA = Path(__file__).resolve().parent / 'data' / 'gaitmap'
NS = 1_000_000_000


def read_messages(bag) -> dict:
    """
    Return every message of a bag, by topic.

    Parameters
    ----------
    bag : str or Path
        The bag directory.

    Returns
    -------
    dict
        topic -> (log stamps ns, header stamps ns, frame ids, messages).

    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import get_typestore, Stores

    out = {}
    with AnyReader([Path(bag)], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
        for conn, ts, raw in r.messages():
            m = r.deserialize(raw, conn.msgtype)
            rows = out.setdefault(conn.topic, ([], [], [], []))
            rows[0].append(ts)
            rows[1].append(m.header.stamp.sec * NS + m.header.stamp.nanosec)
            rows[2].append(m.header.frame_id)
            rows[3].append(m)
    return {t: (np.array(a), np.array(b), c, d) for t, (a, b, c, d) in out.items()}


def imu_arrays(msgs):
    """
    Return the header stamps, rates and accelerations of ``/imu/data``.

    Parameters
    ----------
    msgs : dict
        From :func:`read_messages`.

    Returns
    -------
    tuple of ndarray
        Stamps (n,) ns, rates (n, 3), accelerations (n, 3).

    """
    _, st, _, ms = msgs['/imu/data']
    w = np.array([[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z]
                  for m in ms])
    a = np.array([[m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z]
                  for m in ms])
    return st, w, a


def pose_arrays(msgs):
    """
    Return the header stamps, orientations and positions of ``/mocap/pose``.

    Parameters
    ----------
    msgs : dict
        From :func:`read_messages`.

    Returns
    -------
    tuple of ndarray
        Stamps (n,) ns, q_mocap_foot (n, 4) scalar first, positions (n, 3) m.

    """
    _, st, _, ms = msgs['/mocap/pose']
    q = np.array([[m.pose.orientation.w, m.pose.orientation.x, m.pose.orientation.y,
                   m.pose.orientation.z] for m in ms])
    p = np.array([[m.pose.position.x, m.pose.position.y, m.pose.position.z] for m in ms])
    return st, q, p


def final_rest(stamps_ns, q, angle_deg=1.0, margin_s=0.25) -> int:
    """
    Return the start of the final rest, found from the reference alone.

    Parameters
    ----------
    stamps_ns : ndarray
        Reference stamps, ns.
    q : ndarray (n, 4)
        Reference orientations.
    angle_deg : float
        The rest is where the orientation stays within this angle of the last one.
    margin_s : float
        Taken off the start of the rest, s.

    Returns
    -------
    int
        Stamp, ns.

    """
    ang = np.degrees(quat_angle_between(q, np.broadcast_to(q[-1], q.shape)))
    return int(stamps_ns[np.flatnonzero(ang > angle_deg)[-1]]) + int(margin_s * NS)


def cut_window(bag, out, start_ns: int, stop_ns: int) -> None:
    """
    Copy the messages of a bag with log stamps in [start_ns, stop_ns) into a new MCAP bag.

    Parameters
    ----------
    bag : str or Path
        The bag to read.
    out : str or Path
        The bag to write (must not exist).
    start_ns, stop_ns : int
        The window, ns.

    """
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores

    store = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([Path(bag)], default_typestore=store) as r, \
            Writer(Path(out), version=Writer.VERSION_LATEST,
                   storage_plugin=StoragePlugin.MCAP) as w:
        conns = {c.topic: w.add_connection(c.topic, c.msgtype, typestore=store)
                 for c in r.connections}
        for c, ts, raw in r.messages(start=start_ns, stop=stop_ns):
            w.write(conns[c.topic], ts, raw)


def run_tool(main, argv):
    """
    Run a command's ``main(argv)`` in this process and capture what it prints.

    Parameters
    ----------
    main : callable
        The command's entry point.
    argv : list of str
        Its arguments.

    Returns
    -------
    tuple
        (exit status, stdout text, stderr text).

    """
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main([str(a) for a in argv])
        except SystemExit as exc:
            rc = exc.code
    return rc, out.getvalue(), err.getvalue()
