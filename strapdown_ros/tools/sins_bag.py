"""
sins_bag: sins_node's solution from a rosbag2 recording, offline and without ROS.

    sins_bag BAG [--params FILE] [-p NAME:=VALUE ...] --output OUT [--force]
                 [--namespace NS] [--gyro-topic T] [--accel-topic T]
                 [--imu-topic T [--rate-rule trapezoid|mean]]

Reads ``imu/delta_theta`` (rad) and ``imu/delta_velocity`` (m/s), both
geometry_msgs/msg/Vector3Stamped stamped at the end of their intervals, from a bag directory or a
single .mcap/.db3 file (MCAP or sqlite3 storage), and runs them through the numerical core of
``sins_node`` (:class:`strapdown_ros.sins.SinsSystem`: the same input rules, blocks,
integrator, gyro-effect compensation and navigation channel), so the solution is the node's on
the same messages.  Topic names match with or without the leading slash, under ``--namespace``
when given; a bag with a single namespace is found without it; ``--gyro-topic``/``--accel-topic``
name other topics (absolute, or relative to the namespace).  ``--imu-topic`` (or a
``--gyro-topic`` of that type) reads sensor_msgs/msg/Imu instead: angular_velocity and
linear_acceleration are rate samples, checked by the node's rules and made into Δθ and Δv by
:mod:`strapdown_ros.streams.rate_increments` (``--rate-rule``), as sins_node's ``gyro_input: imu``
does (:meth:`SinsSystem.screen_imu`); a message whose linear_acceleration_covariance[0] is −1
has no Δv.

Parameters are sins_node's: a ROS 2 parameter file (``--params``; the ``sins_node`` and ``/**``
blocks) and ``-p name:=value`` overrides, validated as the node validates them.  ``gyro_rate``
and ``accel_rate`` come from the stamps (1e9 / the median step in ns, rounded to the fewest
decimals that nanosecond stamps allow) unless given with ``-p``.  ``frame_id`` is the most
frequent non-empty header.frame_id of the Δθ messages unless the parameters name one; messages
in other frames are named, counted and rejected by the frame rule.  The navigation channel is off
by default, as in the node: ``-p navigation:=true`` with ``initial_position``,
``initial_velocity`` and ``initial_orientation`` (q_earth_body) or ``initial_alignment:=static``.

Each stream is read whole (an indexed MCAP file a chunk at a time, :mod:`.mcap_records`; the
records decoded with numpy, :func:`strapdown_ros.streams.cdr.stamped_doubles`), checked by the
node's rules (:meth:`SinsSystem.screen`) and fed to the core in large blocks, each with the Δv
stamped up to its last Δθ (:meth:`SinsSystem.feed`): the numbers are those of the node fed the
messages by header stamp (at equal stamps Δv before Δθ), the attitude to the bit.  When a
stream's stamps resynchronise, the messages go one by one through the node's path instead (merged
by header stamp, each topic keeping its bag order).  At the end of the bag, updates still waiting
for accelerometer data are released as ``accel_wait`` would release them.

Output, by the name of OUT:

* ``*.csv``: one row per navigation step (``navigation:=true``)::

      stamp_s, x, y, z, vx, vy, vz, qx, qy, qz, qw,
      sigma_x, sigma_y, sigma_z, sigma_vx, sigma_vy, sigma_vz, sigma_psi_x, sigma_psi_y, sigma_psi_z

  stamp_s: header stamp, s; position and velocity ECEF (``earth``, PZ-90), m and m/s; q_earth_body
  (ROS order x, y, z, w); the σ: square roots of the covariance diagonal of position, velocity and
  the attitude error ψ about the earth axes X, Y, Z (rad).  Without navigation, one row per
  attitude update: ``stamp_s, qx, qy, qz, qw, sigma_eps_x, sigma_eps_y, sigma_eps_z`` with
  q_ref_body and the σ of the attitude error ε about the body axes (rad).
* anything else: a rosbag2 bag directory (MCAP) with ``sins/attitude``
  (geometry_msgs/msg/QuaternionStamped), ``sins/imu`` (sensor_msgs/msg/Imu) and, with navigation,
  ``sins/odometry`` (nav_msgs/msg/Odometry), under the namespace of the input topics, with the
  content and frame ids sins_node publishes; bag time = header stamp.

OUT must not exist unless ``--force`` (which replaces a file, or a directory that is a rosbag2 bag).
Exit status: 0 solution written, 2 bad arguments/parameters/bag (one line on stderr, before any
work), 3 no solution (e.g. the static alignment never succeeded).
"""
from __future__ import annotations

import argparse
from itertools import islice
import math
import os
from pathlib import Path
import sys
import time

import numpy as np

from strapdown_ros.cli import check_outputs, REPLACED
from strapdown_ros.earth import geodetic_to_ecef
from strapdown_ros.files import commit_directory, discard_directory, stage_directory
from strapdown_ros.params import check_all, load_parameter_file, parse_overrides, SINS_PARAMS
from strapdown_ros.recording import BagError, open_reader, resolve_topic
from strapdown_ros.recording.mcap_records import channel_ids, indexed_mcap, read_topics
from strapdown_ros.recording.writer import offered_qos
from strapdown_ros.rotation import to_ros_xyzw
from strapdown_ros.sins import odometry_arrays, SinsOutput, SinsSystem
from strapdown_ros.streams.cdr import stamped_doubles
from strapdown_ros.streams.rate_increments import RATE_RULES
from strapdown_ros.text import bounded

__all__ = ['main', 'sins_parameters', 'rate_from_stamps', 'open_input', 'run', 'CSV_NAV_COLUMNS',
           'CSV_ATTITUDE_COLUMNS', 'BagError']

GYRO_TOPIC = 'imu/delta_theta'
ACCEL_TOPIC = 'imu/delta_velocity'
VECTOR3_STAMPED = 'geometry_msgs/msg/Vector3Stamped'
OUTPUT_TYPES = {'sins/attitude': 'geometry_msgs/msg/QuaternionStamped', 'sins/imu': 'sensor_msgs/msg/Imu',
                'sins/odometry': 'nav_msgs/msg/Odometry'}
CSV_NAV_COLUMNS = ['stamp_s', 'x', 'y', 'z', 'vx', 'vy', 'vz', 'qx', 'qy', 'qz', 'qw',
                   'sigma_x', 'sigma_y', 'sigma_z', 'sigma_vx', 'sigma_vy', 'sigma_vz',
                   'sigma_psi_x', 'sigma_psi_y', 'sigma_psi_z']
CSV_ATTITUDE_COLUMNS = ['stamp_s', 'qx', 'qy', 'qz', 'qw', 'sigma_eps_x', 'sigma_eps_y', 'sigma_eps_z']
RATE_SAMPLE = 20001              # stamps per topic read for the rate (the first ones)
PROGRESS_PERIOD = 5.0            # wall seconds between progress lines


# --- parameters ---------------------------------------------------------------------------------
def sins_parameters(params_file: str | None = None, overrides: dict | None = None) -> dict:
    """
    sins_node parameters from a ROS 2 parameter YAML (``sins_node`` and ``/**`` blocks) plus
    overrides, validated by the node's specs.
    """
    raw = load_parameter_file(params_file, 'sins_node') if params_file else {}
    raw.update(overrides or {})
    return check_all(SINS_PARAMS, raw)


def rate_from_stamps(stamps_ns) -> float | None:
    """
    A stream's rate (Hz) from its stamps: 1e9 / the median positive step (ns), rounded to the
    fewest decimals whose period is within 1 ns of that step (stamps are whole nanoseconds: a
    300 Hz stream steps 3333333 or 3333334 ns).  None with fewer than two distinct stamps.
    """
    d = np.diff(np.asarray(stamps_ns, dtype=np.int64))
    d = d[d > 0]
    if not len(d):
        return None
    step = float(np.median(d))
    rate = 1e9 / step
    for digits in range(0, 10):
        r = round(rate, digits)
        if r > 0 and abs(1e9 / r - step) <= 1.0:
            return float(r)
    return rate


# --- input ----------------------------------------------------------------------------------------
def _find_topic(topics: dict, name: str, namespace: str) -> str | None:
    """
    An explicit topic (absolute, or relative to the namespace) or the default relative name
    resolved as calibrate_bag resolves it.
    """
    if name.startswith('/'):
        for t in topics:
            if t.strip('/') == name.strip('/'):
                return t
        return None
    return resolve_topic(topics, name, namespace)


IMU = 'sensor_msgs/msg/Imu'
IMU_DOUBLES = 37                 # float64 fields of sensor_msgs/Imu after its header (cdr.py)
IMU_RATE, IMU_ACCEL, IMU_ACCEL_COV = 13, 25, 28     # angular_velocity, linear_acceleration, cov[0]
READ_CHUNK = 200_000             # records decoded at once


class Stream:
    """
    One input topic read whole, in bag order: header stamps (ns), the vectors and the header
    frame ids (``frame_index`` into ``frame_names``).  ``kind``: ``increments`` (Vector3Stamped
    Δθ/Δv) or ``rates`` (sensor_msgs/Imu: ``values`` the angular velocity, ``accel`` the linear
    acceleration, NaN where the message has none).
    """

    def __init__(self, topic, kind, stamps_ns, values, frame_index, frame_names, accel=None):
        self.topic, self.kind = topic, kind
        self.stamps_ns, self.values, self.accel = stamps_ns, values, accel
        self.frame_index, self.frame_names = frame_index, frame_names

    def __len__(self) -> int:
        return len(self.stamps_ns)

    def frames(self) -> list[tuple[str, int]]:
        """(frame id, count) of the messages, most frequent first."""
        if not len(self):
            return []
        counts = np.bincount(self.frame_index, minlength=len(self.frame_names))
        return sorted(((n, int(c)) for n, c in zip(self.frame_names, counts) if c),
                      key=lambda x: -x[1])


class Input:
    """The opened bag: the connections, the streams read whole, the rates from the stamps."""

    def __init__(self, reader, gyro_conn, accel_conn, gyro_rate, accel_rate, path, frame_id='',
                 gyro=None, accel=None):
        self.reader, self.gyro_conn, self.accel_conn = reader, gyro_conn, accel_conn
        self.gyro_rate, self.accel_rate, self.path = gyro_rate, accel_rate, path
        self.frame_id = frame_id            # header.frame_id of most Δθ messages (non-empty)
        self.gyro, self.accel = gyro, accel  # Stream (accel None: none, or from the Imu of gyro)

    @property
    def namespace(self) -> str:
        """The namespace of the gyro topic ('' or '/ns') for the output topics."""
        t = '/' + self.gyro_conn.topic.strip('/')
        rel = '/' + GYRO_TOPIC
        return t[:-len(rel)] if t.endswith(rel) else ''

    @property
    def imu_input(self) -> bool:
        return self.gyro is not None and self.gyro.kind == 'rates'

    def close(self):
        self.reader.close()


def _stamp_ns(msg) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def _unreadable(path, exc) -> BagError:
    return BagError(f'{path}: unreadable record ({type(exc).__name__}: '
                    f"{bounded(str(exc).splitlines()[0]) if str(exc) else ''})")


def _decode(reader, conn, records: list):
    """
    Stamps, the float64 fields and the frames of a chunk of records: numpy over the plain CDR
    layout (streams/cdr.py), rosbags' deserializer for any record in another encoding.
    """
    imu = conn.msgtype == IMU
    st, vals, idx, names, bad = stamped_doubles(records, IMU_DOUBLES if imu else 3)
    known = {n: k for k, n in enumerate(names)}
    for i in bad.tolist():
        rec = records[i]
        m = reader.deserialize(rec.tobytes() if isinstance(rec, np.ndarray) else rec, conn.msgtype)
        st[i] = _stamp_ns(m)
        if imu:
            w, f = m.angular_velocity, m.linear_acceleration
            vals[i, IMU_RATE:IMU_RATE + 3] = (w.x, w.y, w.z)
            vals[i, IMU_ACCEL:IMU_ACCEL + 3] = (f.x, f.y, f.z)
            vals[i, IMU_ACCEL_COV] = m.linear_acceleration_covariance[0]
        else:
            vals[i] = (m.vector.x, m.vector.y, m.vector.z)
        name = m.header.frame_id
        if name not in known:
            known[name] = len(names)
            names.append(name)
        idx[i] = known[name]
    return st, vals, idx, names


def _records(reader, conns: list):
    """
    (connection, log time, raw) of the connections in bag order: the bag's own reader when
    there is one bag (rosbags' AnyReader merges several bags by time, at a cost per record).
    """
    owners = {id(getattr(c, 'owner', None)) for c in conns}
    inner = getattr(reader, 'readers', None)
    if inner is not None and len(inner) == 1 and owners == {id(inner[0])}:
        return inner[0].messages(connections=conns)
    return reader.messages(connections=conns)


def read_streams(reader, conns: list, path, progress=None) -> dict:
    """Every record of the connections, decoded a chunk at a time: {topic: Stream}."""
    t0, t1 = reader.start_time, reader.end_time
    conn_of = {c.topic: c for c in conns}
    parts: dict = {c.topic: [] for c in conns}
    order: dict = {c.topic: [] for c in conns}          # (log times, chunk) of the fast path
    state = {'next': time.monotonic() + PROGRESS_PERIOD}
    storage = indexed_mcap(reader)
    try:
        if storage is not None:                       # one MCAP file with a chunk index
            ids = channel_ids(storage, conns)
            for k, chunk in enumerate(read_topics(storage, ids)):
                for topic, got in chunk.items():
                    parts[topic].append(_decode(reader, conn_of[topic],
                                                got.rows if got.rows is not None else got.records))
                    order[topic].append((got.log_ns, k))
                now = time.monotonic()
                if progress is not None and now >= state['next'] and chunk:
                    state['next'] = now + PROGRESS_PERIOD
                    progress(int(max(int(g.log_ns[-1]) for g in chunk.values())), t0, t1)
        records = _records(reader, conns) if storage is None else iter(())
        while True:
            chunk = list(islice(records, READ_CHUNK))
            if not chunk:
                break
            for topic, conn in conn_of.items():
                raws = [r for c, _, r in chunk if c.topic == topic] if len(conn_of) > 1 else \
                    [r for _, _, r in chunk]
                if raws:
                    parts[topic].append(_decode(reader, conn, raws))
            now = time.monotonic()
            if progress is not None and now >= state['next']:
                state['next'] = now + PROGRESS_PERIOD
                progress(chunk[-1][1], t0, t1)
    except BagError:
        raise
    except Exception as exc:                  # noqa: BLE001 - a corrupted record, whatever says so
        raise _unreadable(path, exc) from None
    out = {}
    for topic, chunks in parts.items():
        conn = conn_of[topic]
        names: list = []
        known: dict = {}
        st_l, v_l, i_l = [], [], []
        for st, vals, idx, nm in chunks:
            remap = np.array([known.setdefault(x, len(known)) for x in nm] or [0], dtype=np.int64)
            names = list(known)
            st_l.append(st)
            v_l.append(vals)
            i_l.append(remap[idx])
        width = IMU_DOUBLES if conn.msgtype == IMU else 3
        st = np.concatenate(st_l) if st_l else np.zeros(0, np.int64)
        vals = np.concatenate(v_l) if v_l else np.zeros((0, width))
        idx = np.concatenate(i_l) if i_l else np.zeros(0, np.int64)
        if order[topic]:
            # rosbags' order: by log time, then chunk, then within the chunk (chunks overlapping
            # in time interleave); usually the chunks follow each other and this is the identity
            log_ns = np.concatenate([o[0] for o in order[topic]])
            chunk = np.concatenate([np.full(len(o[0]), o[1]) for o in order[topic]])
            if not np.all(np.diff(log_ns) >= 0):
                perm = np.lexsort((np.arange(len(log_ns)), chunk, log_ns))
                st, vals, idx = st[perm], vals[perm], idx[perm]
        if conn.msgtype == IMU:
            accel = vals[:, IMU_ACCEL:IMU_ACCEL + 3].copy()
            accel[vals[:, IMU_ACCEL_COV] == -1.0] = np.nan          # REP-145: no acceleration
            rate = np.ascontiguousarray(vals[:, IMU_RATE:IMU_RATE + 3])
            out[topic] = Stream(topic, 'rates', st, rate, idx, names, accel)
        else:
            out[topic] = Stream(topic, 'increments', st, vals, idx, names)
    return out


def open_input(bag, namespace: str = '', gyro_topic: str | None = None, accel_topic: str | None = None,
               need_accel: bool = False, imu_topic: str | None = None, progress=None) -> Input:
    """
    Open the bag, find the topics (types checked), read the two streams whole (or the one
    sensor_msgs/Imu stream), take the rates from their first stamps and the body frame from
    the Δθ headers (the most frequent non-empty frame id).  Raises BagError.
    """

    path = Path(bag)
    reader = open_reader(path)
    try:
        topics = {c.topic: c.msgtype for c in reader.connections}
        where = f' under namespace {bounded(namespace)!r}' if namespace.strip('/') else ''
        listing = f"; topics in the bag: {bounded(', '.join(sorted(topics)) or 'none', 400)}"
        if imu_topic:
            gyro_topic = accel_topic = imu_topic
        g = _find_topic(topics, gyro_topic or GYRO_TOPIC, namespace)
        if g is None:
            raise BagError(f'{path}: no {bounded(gyro_topic or GYRO_TOPIC)}{where}{listing}')
        if topics[g] not in (VECTOR3_STAMPED, IMU):
            raise BagError(f'{bounded(g)} has type {bounded(topics[g])}, expected '
                           f'{VECTOR3_STAMPED} or {IMU}')
        if topics[g] == IMU and not accel_topic:
            accel_topic = g                           # Δv from the same Imu messages
        a = _find_topic(topics, accel_topic or ACCEL_TOPIC, namespace)
        if a is None and (need_accel or accel_topic):
            why = ' (navigation needs it)' if need_accel else ''
            name = bounded(accel_topic or ACCEL_TOPIC)
            raise BagError(f'{path}: no {name}{where}{why}{listing}')
        if a is not None and a != g and topics[a] != VECTOR3_STAMPED:
            also = f' (or the Imu topic {bounded(g)} itself)' if topics[g] == IMU else ''
            raise BagError(f'{bounded(a)} has type {bounded(topics[a])}, expected '
                           f'{VECTOR3_STAMPED}{also}')
        if a is not None and a == g and topics[g] != IMU:
            raise BagError(f'{bounded(g)} cannot be both the Δθ and the Δv topic')
        gc = next(c for c in reader.connections if c.topic == g)
        ac = next((c for c in reader.connections if c.topic == a), None) if a else None
        conns = [c for c in reader.connections if c.topic in {g, a}]
        streams = read_streams(reader, conns, path, progress)
    except BagError:
        reader.close()
        raise
    gs = streams[g]
    accel_stream = None if a is None else (None if a == g else streams[a])
    g_rate = rate_from_stamps(gs.stamps_ns[:RATE_SAMPLE])
    if g_rate is None:
        reader.close()
        raise BagError(f'{path}: {bounded(g)} has {len(gs)} message(s) with distinct stamps; '
                       'at least 2 are needed')
    if a is None:
        a_rate = None
    elif a == g:
        has = ~np.all(np.isnan(gs.accel[:RATE_SAMPLE]), axis=1)
        a_rate = g_rate if has.any() else None
    else:
        a_rate = rate_from_stamps(accel_stream.stamps_ns[:RATE_SAMPLE])
    if a and a_rate is None and need_accel:
        reader.close()
        raise BagError(f'{path}: {bounded(a)} has fewer than 2 messages with distinct stamps (or '
                       'no '
                       'acceleration); navigation needs it')
    named = [(n, c) for n, c in gs.frames() if n]
    frame_id = named[0][0] if named else ''
    return Input(reader, gc, ac, g_rate, a_rate, path, frame_id, gs, accel_stream)


def _merged(g_stamps, a_stamps):
    """
    (is_gyro, index) of two streams merged by stamp, each in its own (bag) order, Δv first at
    equal stamps (the order sins_node is fed in; the one-message path).
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


# --- output -----------------------------------------------------------------------------------------
class CsvOutput:
    """The CSV writer (written to OUT.part, renamed at :meth:`close`)."""

    def __init__(self, path: Path, navigation: bool):
        self.path, self.navigation = Path(path), navigation
        self.tmp = self.path.with_name(self.path.name + '.part')
        self.fh = open(self.tmp, 'w', encoding='utf-8', newline='')
        self.fh.write(','.join(CSV_NAV_COLUMNS if navigation else CSV_ATTITUDE_COLUMNS) + '\n')
        self.rows = 0

    def write(self, out: SinsOutput) -> None:
        """
        One row per navigation step (stamp, position, velocity, q, σ) or, without navigation,
        per attitude update (stamp, q, σ).
        """
        rec = out.navigation if self.navigation else out.attitude
        k = len(rec)
        if not k:
            return
        q = to_ros_xyzw(rec.attitude).reshape(-1, 4)
        sig = np.sqrt(np.maximum(np.diagonal(rec.covariance, axis1=1, axis2=2), 0.0))
        sec, nsec = np.divmod(np.asarray(rec.stamp_ns, dtype=np.int64), 1_000_000_000)
        cols = [sec[:, None], nsec[:, None]] + ([rec.position, rec.velocity] if self.navigation
                                                else []) + [q]
        table = np.hstack([np.asarray(c, dtype=float) for c in cols])   # sec, ns exact in float64
        head = '%d.%09d' + ',%.17g' * (table.shape[1] - 2)                 # = "{:.17g}" per value
        tail = ',%.17g' * sig.shape[1]
        for a in range(0, k, 4096):
            part, s_part = table[a:a + 4096], sig[a:a + 4096]
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
        self.fh.close()
        if ok:
            os.replace(self.tmp, self.path)
        else:
            self.tmp.unlink(missing_ok=True)

    def summary(self) -> str:
        return f'{self.path} ({self.rows} rows)'


class McapOutput:
    """sins/attitude, sins/imu and sins/odometry as sins_node publishes them, in an MCAP bag."""

    def __init__(self, path: Path, system: SinsSystem, namespace: str):
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import get_typestore, Stores

        self.path = Path(path)
        self.store = get_typestore(Stores.ROS2_JAZZY)
        self.T = self.store.types
        p = system.p
        self.frame_id, self.ref_frame = p['frame_id'], p['reference_frame_id']
        self.earth_frame = p['earth_frame_id']
        self.rate_variance = system.rate_variance
        g, a = system.rate_variance, system.accel_variance
        self.rate_cov = np.diag([g, g, g]).reshape(9)
        self.accel_cov = np.diag([a, a, a]).reshape(9)
        self.no_accel_cov = np.zeros(9)
        self.no_accel_cov[0] = -1.0
        names = ['sins/attitude', 'sins/imu'] + (['sins/odometry'] if system.nav is not None else [])
        self.topics = {n: f'{namespace}/{n}' for n in names}
        self.counts = {n: 0 for n in names}
        # written into a hidden sibling, renamed into place by close(): no half bag on a failure,
        # an old bag (--force) replaced only by a complete one
        self.staged = stage_directory(self.path)
        try:
            self.writer = Writer(self.staged, version=Writer.VERSION_LATEST,
                                 storage_plugin=StoragePlugin.MCAP)
            self.writer.open()
        except BaseException:
            discard_directory(self.staged)
            raise
        qos = offered_qos('stream', int(p['qos_depth']))
        self.conns = {n: self.writer.add_connection(self.topics[n], OUTPUT_TYPES[n], typestore=self.store,
                                                    offered_qos_profiles=[qos]) for n in names}
        # one message of each topic, serialised by rosbags: the template of its CDR rows
        T, z3 = self.T, np.zeros(3)
        self.templates: dict = {}
        self._template('sins/attitude', T['geometry_msgs/msg/QuaternionStamped'](
            header=self._header(0, self.ref_frame), quaternion=self._quat(np.zeros(4))), 4)
        self._template('sins/imu', T['sensor_msgs/msg/Imu'](
            header=self._header(0, self.frame_id), orientation=self._quat(np.zeros(4)),
            orientation_covariance=np.zeros(9), angular_velocity=self._vec(z3),
            angular_velocity_covariance=np.zeros(9), linear_acceleration=self._vec(z3),
            linear_acceleration_covariance=np.zeros(9)), 37)
        if 'sins/odometry' in self.conns:
            point = T['geometry_msgs/msg/Point'](x=0.0, y=0.0, z=0.0)
            pose = T['geometry_msgs/msg/Pose'](position=point, orientation=self._quat(np.zeros(4)))
            twist = T['geometry_msgs/msg/Twist'](linear=self._vec(z3), angular=self._vec(z3))
            self._template('sins/odometry', T['nav_msgs/msg/Odometry'](
                header=self._header(0, self.earth_frame), child_frame_id=self.frame_id,
                pose=T['geometry_msgs/msg/PoseWithCovariance'](pose=pose, covariance=np.zeros(36)),
                twist=T['geometry_msgs/msg/TwistWithCovariance'](twist=twist,
                                                                 covariance=np.zeros(36))), 85)

    def _header(self, ns: int, frame_id: str):
        T = self.T
        ns = int(ns)
        return T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
            sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id=frame_id)

    def _quat(self, q):
        return self.T['geometry_msgs/msg/Quaternion'](x=float(q[1]), y=float(q[2]), z=float(q[3]), w=float(q[0]))

    def _vec(self, v):
        return self.T['geometry_msgs/msg/Vector3'](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def _template(self, name: str, msg, doubles: int) -> None:
        """
        The CDR bytes of one message of the topic (its constant frame ids), from which every
        message is made by writing its stamp and its float64 fields (:meth:`_rows`).
        """
        raw = np.frombuffer(bytes(self.store.serialize_cdr(msg, OUTPUT_TYPES[name])), np.uint8)
        self.templates[name] = (raw, len(raw) - 8 * doubles)

    def _rows(self, name: str, stamps_ns, fields: np.ndarray) -> np.ndarray:
        """
        (n, L) uint8: the messages of a topic in CDR (header stamp, then the float64 fields
        after the constant part); the same bytes as rosbags' serializer gives.
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

    def write(self, out: SinsOutput) -> None:
        """The block's messages, as sins_node publishes them."""
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
            pose_cov, v_body, twist_cov = odometry_arrays(nb, self.rate_variance)
            fields = np.hstack([nb.position, to_ros_xyzw(nb.attitude).reshape(-1, 4), pose_cov,
                                v_body, np.zeros((k, 3)), twist_cov])
            rows = self._rows('sins/odometry', nb.stamp_ns, fields)
            self._put_rows('sins/odometry', nb.stamp_ns, rows)

    def close(self, ok: bool = True) -> None:
        try:
            self.writer.close()
            if ok:
                commit_directory(self.staged, self.path)
        finally:
            discard_directory(self.staged)

    @property
    def rows(self) -> int:
        return sum(self.counts.values())

    def summary(self) -> str:
        return f'{self.path} (MCAP: ' + ', '.join(f'{self.topics[n]} {c}' for n, c in self.counts.items()) + ')'


def _check_output(out: str, bag: str, force: bool, params: str | None = None) -> None:
    """
    OUT can be written (the tools' one output rule,
    :func:`~strapdown_ros.cli.check_outputs`: not an input, absent unless --force, its
    directory takes a write); a directory is replaced only when it is a rosbag2 bag or empty.
    """

    check_outputs([('--output', out, REPLACED)], [('bag', bag), ('--params', params)], force)
    p = Path(out)
    not_a_bag = (not (p / 'metadata.yaml').exists()) and any(p.iterdir()) if p.is_dir() else False
    if p.is_dir() and (out.lower().endswith('.csv') or not_a_bag):
        raise ValueError(f'--output {out} is a directory that is not a rosbag2 bag; '
                         'not replacing it')


# --- the run ----------------------------------------------------------------------------------------
def run(inp: Input, make_system, sink, say=None, rate_rule: str = 'trapezoid',
        system: SinsSystem | None = None):
    """
    Feed the bag's streams through a system made by ``make_system()`` and write every output
    to ``sink`` (``sink.write(SinsOutput)``); ``system``: a fresh one already made.  Returns
    (counts, system).

    The streams are screened whole by the node's rules (:meth:`SinsSystem.screen`, vectorised)
    and fed in large blocks (:meth:`SinsSystem.feed`); when a stream's stamps resynchronise, a
    fresh system takes every message one by one in stamp order instead (sins_node's path).
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

    def streams(system):
        """(gyro (stamps, values, frame_index, frame_names), accel (...) or None) as increments."""
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

    system = system if system is not None else make_system()
    gyro_in, accel_in = streams(system)
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
    gyro_in, accel_in = streams(system)
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
    return n, system


def _summary(args, inp: Input, system: SinsSystem, sink, counts: dict, rates: dict) -> str:
    st = system.status()
    g, a = system.gyro_check, system.accel_check
    g_topic = bounded(inp.gyro_conn.topic)
    a_topic = bounded(inp.accel_conn.topic) if inp.accel_conn is not None else ''
    if inp.accel_conn is None:
        tail = ', no Δv'
    elif inp.imu_input and inp.accel is None:
        tail = f", {counts['accel']} with linear acceleration"
    else:
        tail = f", {counts['accel']} Δv from {a_topic}"
    if inp.imu_input:
        head = (f"sins_bag: {args.bag}: {counts['gyro']} sensor_msgs/Imu from {g_topic} "
                f'(rates → increments, rule {args.rate_rule})')
    else:
        head = f"sins_bag: {args.bag}: {counts['gyro']} Δθ from {g_topic}"
    lines = [head + tail + f"; gyro_rate {rates['gyro_rate']:g} Hz, "
             f"accel_rate {rates['accel_rate']:g} Hz"]
    checks = [g, a] + list(system.rate_checks.values())
    drops = {k: sum(getattr(c, attr) for c in checks)
             for k, attr in (('NaN', 'nan'), ('out of range', 'out_of_range'),
                             ('out of order', 'out_of_order'), ('duplicate', 'duplicate'),
                             ('stamp outlier', 'stamp_outliers'))}
    drops = {k: v for k, v in drops.items() if v}
    fm = system.frame_mismatch
    if fm['gyro'] or fm['accel']:
        drops[f"frame mismatch ({'rejected' if system.reject_frames else 'used'})"] = fm['gyro'] + fm['accel']
    lines.append('  dropped: ' + (', '.join(f'{k} {v}' for k, v in drops.items()) if drops else 'none'))
    if g.missing or g.resyncs:
        lines.append(f'  GYRO: {g.missing} increment(s) missing in {g.gaps} gap(s), {g.resyncs} stamp resync(s): '
                     'the rotation during them is lost')
    if system.nonfinite:
        lines.append(f'  {system.nonfinite} non-finite update(s) discarded')
    stall = system.accel_stall(a_topic or 'imu/delta_velocity')   # sins_node's /diagnostics rule
    if stall is not None:
        lines.append(f"  WARNING: {stall.text}; sins_node's /diagnostics: {stall.level.upper()}")
    line = f"  {st['updates']} attitude updates ({st['coning_algorithm']}, {st['samples_per_update']} samples/update)"
    if system.nav is not None:
        line += f"; navigation {st['navigation_state']}, {st.get('navigation_steps', 0)} steps"
        if st.get('navigation_steps_accel_extrapolated'):
            line += f" ({st['navigation_steps_accel_extrapolated']} with Δv extrapolated)"
        if 'alignment' in st:
            line += f"; alignment: {st['alignment']}"
    if stall is not None:
        line += f'; accel stall {stall.seconds:.3g} s'
    lines.append(line)
    lines.append(f'  wrote {sink.summary()}')
    return '\n'.join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog='sins_bag', description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('bag', help='rosbag2 bag directory, or a .mcap / .db3 file')
    ap.add_argument('--output', '-o', required=True, metavar='OUT',
                    help='OUT.csv: the solution as CSV; otherwise an MCAP bag directory with sins/* topics')
    ap.add_argument('--params', metavar='FILE', help='ROS 2 parameter YAML (sins_node and /** blocks)')
    ap.add_argument('-p', '--param', action='append', default=[], metavar='NAME:=VALUE',
                    help='sins_node parameter override (repeatable), as ros2 run -p')
    ap.add_argument('--namespace', default='', help='topic namespace, e.g. /robot1')
    ap.add_argument('--gyro-topic', metavar='TOPIC', help=f'Δθ topic (default {GYRO_TOPIC})')
    ap.add_argument('--accel-topic', metavar='TOPIC', help=f'Δv topic (default {ACCEL_TOPIC})')
    ap.add_argument('--imu-topic', metavar='TOPIC',
                    help='a sensor_msgs/msg/Imu topic giving both Δθ (angular_velocity) and Δv '
                         '(linear_acceleration) by --rate-rule')
    ap.add_argument('--rate-rule', choices=RATE_RULES, default='trapezoid',
                    help='how an Imu rate sample becomes an increment '
                         '(strapdown_ros.streams.rate_increments; default trapezoid)')
    ap.add_argument('--force', action='store_true', help='replace OUT if it exists')
    ap.add_argument('--quiet', action='store_true', help='no progress lines')
    args = ap.parse_args(argv)

    def err(text: str) -> int:
        print(f'sins_bag: error: {text}', file=sys.stderr)
        return 2

    def say(text: str) -> None:
        if not args.quiet:
            print(f'sins_bag: {text}', file=sys.stderr, flush=True)

    inp = None
    try:
        over = parse_overrides(args.param)
        p = sins_parameters(args.params, over)              # every parameter checked before the bag
        _check_output(args.output, args.bag, args.force, args.params)
        if args.imu_topic and (args.gyro_topic or args.accel_topic):
            raise ValueError('--imu-topic gives both streams: not with --gyro-topic/--accel-topic')

        def reading(ns, t0, t1):
            span = max(t1 - t0, 1) * 1e-9
            say(f'reading: {(ns - t0) * 1e-9:.1f} / {span:.1f} s of the recording')
        inp = open_input(args.bag, args.namespace, args.gyro_topic, args.accel_topic,
                         need_accel=bool(p['navigation']), imu_topic=args.imu_topic,
                         progress=reading)
        if inp.imu_input and 'accel_rate' not in over and inp.accel is None:
            inp.accel_rate = inp.gyro_rate            # Δv from the same Imu messages
        rates = {'gyro_rate': inp.gyro_rate, 'accel_rate': inp.accel_rate}
        for name in ('gyro_rate', 'accel_rate'):
            if name in over or rates[name] is None:
                rates[name] = p[name]
            elif not math.isclose(rates[name], p[name], rel_tol=0.01):
                say(f'note: {name} {rates[name]:g} Hz from the stamps (the parameters say {p[name]:g} Hz; '
                    f'-p {name}:=... to impose one)')
        # the body frame: the recording's own, unless the parameters name one
        named = 'frame_id' in over or (args.params and 'frame_id' in load_parameter_file(args.params, 'sins_node'))
        frame = {}
        if not named and inp.frame_id and inp.frame_id != p['frame_id']:
            frame = {'frame_id': inp.frame_id}
            say(f"note: frame_id {bounded(inp.frame_id)!r} from the recording's headers "
                '(-p frame_id:=... to impose one)')
        others = [(f, c) for f, c in inp.gyro.frames() if f and f != (frame or p).get('frame_id')]
        if others and not named:
            total = len(inp.gyro)
            kind = 'Imu' if inp.imu_input else 'Δθ'
            listed = ', '.join(f'{bounded(f)!r} ({c})' for f, c in others[:3])
            say(f'note: {sum(c for _, c in others)} of {total} {kind} message(s) '
                'name another frame than the body frame and are rejected by the frame rule: '
                + listed + (', …' if len(others) > 3 else ''))
        p = sins_parameters(args.params, {**over, **rates, **frame})
        if p['navigation']:
            lat, lon, h = (float(x) for x in p['initial_position'])
            r = float(np.linalg.norm(geodetic_to_ecef(np.radians(lat), np.radians(lon), h)))
            if not 6.0e6 < r < 8.0e6:
                raise ValueError(f"initial_position {p['initial_position']} is not within ±1000 km of the "
                                 "Earth's surface")
        csv_out = args.output.lower().endswith('.csv')

        def make_system():
            return SinsSystem(p, log=lambda level, text: say(text if level == 'info' else
                                                             f'{level}: {text}'),
                              imu_wanted=(lambda: not csv_out))
        system = make_system()                          # parameters checked by the core now
    except (ValueError, OSError, BagError) as exc:
        if inp is not None:
            inp.close()
        return err(str(exc))
    try:
        sink = CsvOutput(Path(args.output), system.nav is not None) if args.output.lower().endswith('.csv') \
            else McapOutput(Path(args.output), system, inp.namespace)
    except Exception as exc:                           # noqa: BLE001 - the writer's own refusal
        inp.close()
        return err(f'cannot write {args.output}: {exc}')
    ok = False
    try:
        counts, system = run(inp, make_system, sink, say, args.rate_rule, system)
        ok = True
    except BagError as exc:
        return err(str(exc))
    except (KeyboardInterrupt, BrokenPipeError):
        return 130
    finally:
        inp.close()
        sink.close(ok)
    print(_summary(args, inp, system, sink, counts, rates))
    if system.integrator.updates == 0 or (system.nav is not None and
                                          (system.nav.navigator is None or system.nav.navigator.steps == 0)):
        nav = system.nav
        why = (f"the static alignment did not complete (alignment_time {float(system.p['alignment_time']):g} s"
               + (f'; last refusal: {nav.alignment.reason}' if nav.alignment is not None and not nav.alignment.ok
                  else '') + ')') if nav is not None and nav.navigator is None else \
            'no attitude update' if system.integrator.updates == 0 else 'no navigation step'
        if system.integrator.updates == 0 and system.frame_mismatch['gyro'] and system.gyro_check.accepted == 0:
            why = ('every Δθ was rejected: its header.frame_id is not frame_id '
                   f"{bounded(system.p['frame_id'])!r} "
                   '(-p frame_id:=... or -p frame_mismatch:=accept)')
        print(f'sins_bag: no solution: {why}', file=sys.stderr)
        return 3
    return 0


if __name__ == '__main__':
    sys.exit(main())
