"""
A recording replayed through the SINS core, and the solution written as CSV or as a bag.

:func:`run` feeds the streams of :class:`~strapdown_ros.recording.imu_streams.ImuRecording`
through a system with the interface of :class:`strapdown_ros.sins.SinsSystem` (screen the
streams whole, feed them in blocks; message by message when the stamps resynchronise) and hands
every output block to a sink: :class:`CsvOutput` (one row per navigation step or attitude
update) or :class:`McapOutput` (the topics sins_node publishes, in an MCAP bag).  This is the
library part of the ``sins_bag`` command; the system is passed in, so this room does not import
the core above it.

No ROS imports (rosbags writes the bag).
"""
from __future__ import annotations

import os
from pathlib import Path
import time

import numpy as np

from strapdown_ros.files import commit_directory, discard_directory, stage_directory
from strapdown_ros.recording.imu_streams import PROGRESS_PERIOD
from strapdown_ros.recording.writer import offered_qos
from strapdown_ros.rotation import to_ros_xyzw

__all__ = ['run', 'CsvOutput', 'McapOutput', 'CSV_NAV_COLUMNS', 'CSV_ATTITUDE_COLUMNS',
           'OUTPUT_TYPES']

OUTPUT_TYPES = {'sins/attitude': 'geometry_msgs/msg/QuaternionStamped',
                'sins/imu': 'sensor_msgs/msg/Imu',
                'sins/odometry': 'nav_msgs/msg/Odometry'}
CSV_NAV_COLUMNS = ['stamp_s', 'x', 'y', 'z', 'vx', 'vy', 'vz', 'qx', 'qy', 'qz', 'qw',
                   'sigma_x', 'sigma_y', 'sigma_z', 'sigma_vx', 'sigma_vy', 'sigma_vz',
                   'sigma_psi_x', 'sigma_psi_y', 'sigma_psi_z']
CSV_ATTITUDE_COLUMNS = ['stamp_s', 'qx', 'qy', 'qz', 'qw',
                        'sigma_eps_x', 'sigma_eps_y', 'sigma_eps_z']
CSV_BLOCK = 4096            # rows formatted at once


def _merged(g_stamps, a_stamps):
    """
    Yield (is_gyro, index) of two streams merged by stamp, each in its own (bag) order.

    Δv first at equal stamps: the order sins_node is fed in (the one-message path).
    """
    g_ns = g_stamps.tolist()
    a_ns = a_stamps.tolist() if a_stamps is not None else []
    i = j = 0
    while i < len(g_ns) or j < len(a_ns):
        if j < len(a_ns) and (i >= len(g_ns) or a_ns[j] <= g_ns[i]):
            yield False, j
            j += 1
        else:
            yield True, i
            i += 1


def _as_increments(inp, system, rate_rule):
    """
    Return the gyro and accel streams as increments: (stamps, values, frame_index, names).

    The accel tuple is None without Δv; rate samples (sensor_msgs/Imu) are screened and made
    into increments by the system (``screen_imu``).
    """
    g = inp.gyro
    if inp.imu_input:
        use_accel = inp.accel_conn is not None and inp.accel_conn.topic == g.topic
        gi, ai = system.screen_imu(g.stamps_ns, g.values, g.accel if use_accel else None,
                                   g.frame_index, g.frame_names, rate_rule)
        if inp.accel is not None:
            a = inp.accel
            ai = (a.stamps_ns, a.values, a.frame_index, a.frame_names)
        elif ai is not None:
            ai = (ai[0], ai[1], None, ())
        return (gi[0], gi[1], None, ()), ai
    a = inp.accel
    return ((g.stamps_ns, g.values, g.frame_index, g.frame_names),
            None if a is None else (a.stamps_ns, a.values, a.frame_index, a.frame_names))


def _one_by_one(system, gyro_in, accel_in, sink) -> None:
    """Feed every message in stamp order through the node's path (a stamp resynchronisation)."""
    offer_g, offer_a = system.offer_gyro, system.offer_accel

    def frame(s, k):
        return s[3][s[2][k]] if s[2] is not None else ''

    for is_gyro, k in _merged(gyro_in[0], accel_in[0] if accel_in is not None else None):
        if is_gyro:
            v = gyro_in[1][k]
            vec = (float(v[0]), float(v[1]), float(v[2]))
            if offer_g(int(gyro_in[0][k]), vec, frame(gyro_in, k)):
                sink.write(system.process())
            elif system.has_output:                 # a stamp resync processed the old time base
                sink.write(system.take_output())
        else:
            v = accel_in[1][k]
            vec = (float(v[0]), float(v[1]), float(v[2]))
            if offer_a(int(accel_in[0][k]), vec, frame(accel_in, k)):
                sink.write(system.process())
    sink.write(system.process())
    sink.write(system.finish())


def run(inp, make_system, sink, say=None, rate_rule: str = 'trapezoid', system=None):
    """
    Feed a recording's streams through the SINS core and write every output to a sink.

    The streams are screened whole by the node's rules (``SinsSystem.screen``, vectorised) and
    fed in large blocks (``SinsSystem.feed``); when a stream's stamps resynchronise, a fresh
    system takes every message one by one in stamp order instead (sins_node's path).

    Parameters
    ----------
    inp : ImuRecording
        The recording, its streams read whole.
    make_system : callable
        ``make_system()`` returns a fresh :class:`strapdown_ros.sins.SinsSystem`.
    sink : CsvOutput or McapOutput
        ``sink.write(SinsOutput)`` takes every output block.
    say : callable, optional
        ``say(text)`` for progress lines and notes.
    rate_rule : str
        How an Imu rate sample becomes an increment
        (:data:`strapdown_ros.streams.rate_increments.RATE_RULES`).
    system : SinsSystem, optional
        A fresh system already made (else one from ``make_system``).

    Returns
    -------
    counts : dict
        Messages read: ``gyro`` and ``accel``.
    system : SinsSystem
        The system that processed the recording.

    """
    g = inp.gyro
    n = {'gyro': len(g), 'accel': len(inp.accel) if inp.accel is not None else 0}
    if inp.imu_input and inp.accel is None and inp.accel_conn is not None:
        n['accel'] = int(np.sum(~np.all(np.isnan(g.accel), axis=1)))      # Imu messages with Δv
    span = max(inp.reader.end_time - inp.reader.start_time, 1)
    state = {'next': time.monotonic() + PROGRESS_PERIOD}

    def progress(ns, origin):
        now = time.monotonic()
        if say is not None and now >= state['next'] and origin is not None:
            state['next'] = now + PROGRESS_PERIOD
            done = (ns - origin) * 1e-9
            total = span * 1e-9
            say(f'{done:.1f} / {total:.1f} s of the recording ({100.0 * done / total:.0f}%)')

    system = system if system is not None else make_system()
    gyro_in, accel_in = _as_increments(inp, system, rate_rule)
    sg = system.screen('gyro', *gyro_in)
    sa = system.screen('accel', *accel_in) if accel_in is not None and sg is not None else None
    if sg is not None and (accel_in is None or sa is not None):
        for out in system.feed(sg, sa):
            sink.write(out)
            progress(system.processed_until_ns or 0, system.origin_ns)
        return n, system
    # a stamp resynchronisation: the node's path, message by message, from a fresh system
    if say is not None:
        say('note: the stamps resynchronise: processing message by message')
    system = make_system()
    gyro_in, accel_in = _as_increments(inp, system, rate_rule)
    _one_by_one(system, gyro_in, accel_in, sink)
    return n, system


class CsvOutput:
    """
    The solution as CSV, written to OUT.part and renamed at :meth:`close`.

    Columns :data:`CSV_NAV_COLUMNS` (one row per navigation step) or, without navigation,
    :data:`CSV_ATTITUDE_COLUMNS` (one row per attitude update).

    Parameters
    ----------
    path : Path
        The CSV file.
    navigation : bool
        Rows of navigation steps (else of attitude updates).

    """

    def __init__(self, path: Path, navigation: bool):
        self.path, self.navigation = Path(path), navigation
        self.tmp = self.path.with_name(self.path.name + '.part')
        self.fh = open(self.tmp, 'w', encoding='utf-8', newline='')
        self.fh.write(','.join(CSV_NAV_COLUMNS if navigation else CSV_ATTITUDE_COLUMNS) + '\n')
        self.rows = 0

    def write(self, out) -> None:
        """
        Write the rows of one output block.

        Parameters
        ----------
        out : SinsOutput
            One block: its navigation steps (stamp, position, velocity, q, σ) or, without
            navigation, its attitude updates (stamp, q, σ).

        """
        rec = out.navigation if self.navigation else out.attitude
        k = len(rec)
        if not k:
            return
        q = to_ros_xyzw(rec.attitude).reshape(-1, 4)
        sig = np.sqrt(np.maximum(np.diagonal(rec.covariance, axis1=1, axis2=2), 0.0))
        sec, nsec = np.divmod(np.asarray(rec.stamp_ns, dtype=np.int64), 1_000_000_000)
        state = [rec.position, rec.velocity] if self.navigation else []
        cols = [sec[:, None], nsec[:, None]] + state + [q]
        table = np.hstack([np.asarray(c, dtype=float) for c in cols])   # sec, ns exact in float64
        head = '%d.%09d' + ',%.17g' * (table.shape[1] - 2)             # = "{:.17g}" per value
        tail = ',%.17g' * sig.shape[1]
        for a in range(0, k, CSV_BLOCK):
            part, s_part = table[a:a + CSV_BLOCK], sig[a:a + CSV_BLOCK]
            m = len(part)
            new = np.ones(m, bool)
            new[1:] = np.any(s_part[1:] != s_part[:-1], axis=1)
            runs = np.flatnonzero(new)
            if len(runs) * 4 > m:                     # the σ change at every row: one format
                flat = np.hstack([part, s_part]).ravel().tolist()
                self.fh.write(((head + tail + '\n') * m) % tuple(flat))
                continue
            # the navigation σ change once per covariance epoch: each distinct row formatted once
            flat = s_part[runs].ravel().tolist()
            texts = ((tail + '\n') * len(runs) % tuple(flat)).split('\n')[:-1]
            rows = np.empty((m, part.shape[1] + 1), dtype=object)
            rows[:, :-1] = part
            rows[:, -1] = np.array(texts, dtype=object)[np.cumsum(new) - 1]
            self.fh.write(((head + '%s\n') * m) % tuple(rows.ravel().tolist()))
        self.rows += k

    def close(self, ok: bool = True) -> None:
        """
        Close the file: rename it into place, or remove it.

        Parameters
        ----------
        ok : bool
            The run completed (else the partial file is removed).

        """
        self.fh.close()
        if ok:
            os.replace(self.tmp, self.path)
        else:
            self.tmp.unlink(missing_ok=True)

    def summary(self) -> str:
        """Return the summary line's text: the file and its number of rows."""
        return f'{self.path} ({self.rows} rows)'


class McapOutput:
    """
    sins/attitude, sins/imu and sins/odometry as sins_node publishes them, in an MCAP bag.

    The bag is written into a hidden sibling and renamed into place by :meth:`close`: no half
    bag on a failure, and an old bag (``--force``) replaced only by a complete one.  Each
    message is made from a template serialised once by rosbags, with its stamp and float64
    fields written in (the same bytes as rosbags' serializer gives).

    Parameters
    ----------
    path : Path
        The bag directory.
    system : SinsSystem
        The system whose outputs are written (its parameters, noise variances, navigation).
    namespace : str
        Namespace of the output topics ('' or '/ns').
    odometry : callable
        ``odometry(NavigationOutput, rate_variance)`` returns the Odometry pose covariance,
        body velocity and twist covariance (:func:`strapdown_ros.sins.odometry_arrays`).
    qos_depth : int
        History depth of the offered QoS recorded with each topic.

    """

    def __init__(self, path: Path, system, namespace: str, odometry, qos_depth: int = 500):
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import get_typestore, Stores

        self.path = Path(path)
        self.store = get_typestore(Stores.ROS2_JAZZY)
        self.T = self.store.types
        self.odometry = odometry
        self.frame_id = system.model.frame_id
        self.ref_frame = system.model.reference_frame_id
        self.earth_frame = system.settings.earth_frame_id
        self.rate_variance = system.rate_variance
        g, a = system.rate_variance, system.accel_variance
        self.rate_cov = np.diag([g, g, g]).reshape(9)
        self.accel_cov = np.diag([a, a, a]).reshape(9)
        self.no_accel_cov = np.zeros(9)
        self.no_accel_cov[0] = -1.0
        names = ['sins/attitude', 'sins/imu']
        if system.nav is not None:
            names.append('sins/odometry')
        self.topics = {n: f'{namespace}/{n}' for n in names}
        self.counts = dict.fromkeys(names, 0)
        self.staged = stage_directory(self.path)
        try:
            self.writer = Writer(self.staged, version=Writer.VERSION_LATEST,
                                 storage_plugin=StoragePlugin.MCAP)
            self.writer.open()
        except BaseException:
            discard_directory(self.staged)
            raise
        qos = offered_qos('stream', int(qos_depth))
        self.conns = {n: self.writer.add_connection(self.topics[n], OUTPUT_TYPES[n],
                                                    typestore=self.store,
                                                    offered_qos_profiles=[qos])
                      for n in names}
        self.templates: dict = {}
        self._make_templates()

    def _make_templates(self) -> None:
        """Serialise one message of each topic: the template of its CDR rows."""
        T, z3, q0 = self.T, np.zeros(3), np.zeros(4)
        self._template('sins/attitude', T['geometry_msgs/msg/QuaternionStamped'](
            header=self._header(0, self.ref_frame), quaternion=self._quat(q0)), 4)
        self._template('sins/imu', T['sensor_msgs/msg/Imu'](
            header=self._header(0, self.frame_id), orientation=self._quat(q0),
            orientation_covariance=np.zeros(9), angular_velocity=self._vec(z3),
            angular_velocity_covariance=np.zeros(9), linear_acceleration=self._vec(z3),
            linear_acceleration_covariance=np.zeros(9)), 37)
        if 'sins/odometry' in self.conns:
            point = T['geometry_msgs/msg/Point'](x=0.0, y=0.0, z=0.0)
            pose = T['geometry_msgs/msg/Pose'](position=point, orientation=self._quat(q0))
            twist = T['geometry_msgs/msg/Twist'](linear=self._vec(z3), angular=self._vec(z3))
            pose_cov = T['geometry_msgs/msg/PoseWithCovariance'](pose=pose,
                                                                 covariance=np.zeros(36))
            twist_cov = T['geometry_msgs/msg/TwistWithCovariance'](twist=twist,
                                                                   covariance=np.zeros(36))
            self._template('sins/odometry', T['nav_msgs/msg/Odometry'](
                header=self._header(0, self.earth_frame), child_frame_id=self.frame_id,
                pose=pose_cov, twist=twist_cov), 85)

    def _header(self, ns: int, frame_id: str):
        T = self.T
        ns = int(ns)
        return T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
            sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id=frame_id)

    def _quat(self, q):
        return self.T['geometry_msgs/msg/Quaternion'](x=float(q[1]), y=float(q[2]),
                                                      z=float(q[3]), w=float(q[0]))

    def _vec(self, v):
        return self.T['geometry_msgs/msg/Vector3'](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def _template(self, name: str, msg, doubles: int) -> None:
        """
        Keep the CDR bytes of one message of the topic (its constant frame ids).

        Every message is made from them by writing its stamp and its float64 fields
        (:meth:`_rows`).
        """
        raw = np.frombuffer(bytes(self.store.serialize_cdr(msg, OUTPUT_TYPES[name])), np.uint8)
        self.templates[name] = (raw, len(raw) - 8 * doubles)

    def _rows(self, name: str, stamps_ns, fields: np.ndarray) -> np.ndarray:
        """
        Return the messages of a topic in CDR, (n, L) uint8.

        The header stamp, then the float64 fields after the constant part: the same bytes as
        rosbags' serializer gives.
        """
        raw, off = self.templates[name]
        n = len(stamps_ns)
        rows = np.empty((n, len(raw)), np.uint8)
        rows[:] = raw
        sec, nsec = np.divmod(np.asarray(stamps_ns, dtype=np.int64), 1_000_000_000)
        rows[:, 4:8] = sec.astype('<i4').view(np.uint8).reshape(n, 4)
        rows[:, 8:12] = nsec.astype('<u4').view(np.uint8).reshape(n, 4)
        rows[:, off:] = np.ascontiguousarray(fields, dtype='<f8').view(np.uint8).reshape(n, -1)
        return rows

    def _put_rows(self, name: str, stamps_ns, rows: np.ndarray) -> None:
        conn, write = self.conns[name], self.writer.write
        for ns, row in zip(np.asarray(stamps_ns, dtype=np.int64).tolist(), rows):
            write(conn, ns, row.tobytes())
        self.counts[name] += len(rows)

    def write(self, out) -> None:
        """
        Write one output block's messages, as sins_node publishes them.

        Parameters
        ----------
        out : SinsOutput
            The attitude updates, sins/imu records and navigation steps of one block.

        """
        at = out.attitude
        if len(at):
            q = to_ros_xyzw(at.attitude).reshape(-1, 4)
            rows = self._rows('sins/attitude', at.stamp_ns, q)
            self._put_rows('sins/attitude', at.stamp_ns, rows)
        im = out.imu
        m = len(im)
        if m:
            has = np.asarray(im.has_accel, dtype=bool)
            fields = np.hstack([to_ros_xyzw(im.attitude).reshape(-1, 4),
                                im.covariance.reshape(m, 9), im.mean_rate,
                                np.broadcast_to(self.rate_cov, (m, 9)),
                                np.where(has[:, None], im.specific_force, 0.0),
                                np.where(has[:, None], self.accel_cov, self.no_accel_cov)])
            self._put_rows('sins/imu', im.stamp_ns, self._rows('sins/imu', im.stamp_ns, fields))
        nb = out.navigation
        k = len(nb)
        if k:
            pose_cov, v_body, twist_cov = self.odometry(nb, self.rate_variance)
            fields = np.hstack([nb.position, to_ros_xyzw(nb.attitude).reshape(-1, 4), pose_cov,
                                v_body, np.zeros((k, 3)), twist_cov])
            rows = self._rows('sins/odometry', nb.stamp_ns, fields)
            self._put_rows('sins/odometry', nb.stamp_ns, rows)

    def close(self, ok: bool = True) -> None:
        """
        Close the bag: rename it into place, or discard it.

        Parameters
        ----------
        ok : bool
            The run completed (else the staged bag is discarded).

        """
        try:
            self.writer.close()
            if ok:
                commit_directory(self.staged, self.path)
        finally:
            discard_directory(self.staged)

    @property
    def rows(self) -> int:
        """Return the number of messages written."""
        return sum(self.counts.values())

    def summary(self) -> str:
        """Return the summary line's text: the bag and its messages per topic."""
        counts = ', '.join(f'{self.topics[n]} {c}' for n, c in self.counts.items())
        return f'{self.path} (MCAP: {counts})'
