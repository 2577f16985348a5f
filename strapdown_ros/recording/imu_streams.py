"""
The IMU streams of a recording, read whole: the input of ``sins_bag``.

Opens a rosbag2 bag (MCAP or sqlite3), finds the Δθ and Δv topics (geometry_msgs/Vector3Stamped)
or one sensor_msgs/Imu topic, and reads each stream whole into arrays: header stamps (ns), the
vectors and the header frame ids.  An indexed MCAP file is read a chunk at a time
(:mod:`strapdown_ros.recording.mcap_records`), the records decoded with numpy
(:func:`strapdown_ros.streams.cdr.stamped_doubles`); any other storage through rosbags' reader.
The streams come out in rosbags' order (by log time, ties in file order).  The rates are taken
from the stamps (:func:`rate_from_stamps`) and the body frame from the Δθ headers.

No ROS imports; the SINS core that consumes the streams sits above this room
(:mod:`strapdown_ros.recording.sins_replay`).
"""
from __future__ import annotations

from itertools import islice
from pathlib import Path
import time

import numpy as np

from strapdown_ros.recording.mcap_records import channel_ids, indexed_mcap, read_topics
from strapdown_ros.recording.reader import (BagError, open_reader, records_in_bag_order,
                                            resolve_topic)
from strapdown_ros.streams.cdr import stamped_doubles
from strapdown_ros.text import bounded

__all__ = ['GYRO_TOPIC', 'ACCEL_TOPIC', 'VECTOR3_STAMPED', 'IMU', 'ImuStream', 'ImuRecording',
           'rate_from_stamps', 'find_topic', 'read_streams', 'open_input', 'PROGRESS_PERIOD']

GYRO_TOPIC = 'imu/delta_theta'
ACCEL_TOPIC = 'imu/delta_velocity'
VECTOR3_STAMPED = 'geometry_msgs/msg/Vector3Stamped'
IMU = 'sensor_msgs/msg/Imu'
IMU_DOUBLES = 37            # float64 fields of sensor_msgs/Imu after its header (streams/cdr.py)
IMU_RATE = 13               # index of angular_velocity among them
IMU_ACCEL = 25              # index of linear_acceleration
IMU_ACCEL_COV = 28          # index of linear_acceleration_covariance[0]
READ_CHUNK = 200_000        # records decoded at once
RATE_SAMPLE = 20001         # stamps per topic read for the rate (the first ones)
PROGRESS_PERIOD = 5.0       # wall seconds between progress lines


def rate_from_stamps(stamps_ns) -> float | None:
    """
    Return a stream's rate from its stamps.

    The rate is 1e9 / the median positive step (ns), rounded to the fewest decimals whose
    period is within 1 ns of that step (stamps are whole nanoseconds: a 300 Hz stream steps
    3333333 or 3333334 ns).

    Parameters
    ----------
    stamps_ns : (N,) array_like of int
        Header stamps, ns, in stream order.

    Returns
    -------
    float or None
        The rate, Hz; None with fewer than two distinct stamps.

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


def find_topic(topics: dict, name: str, namespace: str) -> str | None:
    """
    Return the bag's topic for a topic option.

    An absolute name matches with or without the leading slash; a relative one is resolved
    under the namespace as :func:`strapdown_ros.recording.reader.resolve_topic` resolves it.

    Parameters
    ----------
    topics : dict
        The bag's topics (name → message type).
    name : str
        The topic asked for, absolute (``/x/y``) or relative (``imu/delta_theta``).
    namespace : str
        The namespace of relative names ('' for none).

    Returns
    -------
    str or None
        The topic as the bag spells it; None when there is none.

    """
    if name.startswith('/'):
        for t in topics:
            if t.strip('/') == name.strip('/'):
                return t
        return None
    return resolve_topic(topics, name, namespace)


class ImuStream:
    """
    One input topic read whole, in bag order.

    Parameters
    ----------
    topic : str
        The topic, as the bag spells it.
    kind : str
        ``increments`` (Vector3Stamped Δθ or Δv) or ``rates`` (sensor_msgs/Imu).
    stamps_ns : (N,) ndarray of int64
        Header stamps, ns.
    values : (N, 3) ndarray
        The increments (rad or m/s) or, for ``rates``, the angular velocity, rad/s, body axes.
    frame_index : (N,) ndarray of int64
        Index of each message's header.frame_id into ``frame_names``.
    frame_names : list of str
        The distinct frame ids.
    accel : (N, 3) ndarray, optional
        For ``rates``: the linear acceleration, m/s², NaN where the message has none (REP-145).

    """

    def __init__(self, topic, kind, stamps_ns, values, frame_index, frame_names, accel=None):
        self.topic, self.kind = topic, kind
        self.stamps_ns, self.values, self.accel = stamps_ns, values, accel
        self.frame_index, self.frame_names = frame_index, frame_names

    def __len__(self) -> int:
        return len(self.stamps_ns)

    def frames(self) -> list[tuple[str, int]]:
        """
        Return the frame ids of the messages with their counts, most frequent first.

        Returns
        -------
        list of (str, int)
            (frame id, number of messages).

        """
        if not len(self):
            return []
        counts = np.bincount(self.frame_index, minlength=len(self.frame_names))
        return sorted(((n, int(c)) for n, c in zip(self.frame_names, counts) if c),
                      key=lambda x: -x[1])


class ImuRecording:
    """
    The opened bag: the connections, the streams read whole, the rates from the stamps.

    Parameters
    ----------
    reader : rosbags reader
        The open reader (closed by :meth:`close`).
    gyro_conn, accel_conn : rosbags connection
        The Δθ (or Imu) connection; the Δv connection or None (it may be the Imu one).
    gyro_rate, accel_rate : float or None
        The rates from the stamps, Hz (None: unknown).
    path : Path
        The bag.
    frame_id : str
        The header.frame_id of most Δθ messages ('' when none names one).
    gyro : ImuStream
        The Δθ or Imu stream.
    accel : ImuStream, optional
        The Δv stream; None when there is none or when Δv comes from the Imu of ``gyro``.

    """

    def __init__(self, reader, gyro_conn, accel_conn, gyro_rate, accel_rate, path, frame_id='',
                 gyro=None, accel=None):
        self.reader, self.gyro_conn, self.accel_conn = reader, gyro_conn, accel_conn
        self.gyro_rate, self.accel_rate, self.path = gyro_rate, accel_rate, path
        self.frame_id = frame_id
        self.gyro, self.accel = gyro, accel
        #: messages of another type on the topics read ({topic: n}): not read, counted
        self.wrong_type: dict = {}

    @property
    def namespace(self) -> str:
        """Return the namespace of the gyro topic ('' or '/ns'), for the output topics."""
        t = '/' + self.gyro_conn.topic.strip('/')
        rel = '/' + GYRO_TOPIC
        return t[:-len(rel)] if t.endswith(rel) else ''

    @property
    def imu_input(self) -> bool:
        """Tell whether the gyro stream is sensor_msgs/Imu rate samples."""
        return self.gyro is not None and self.gyro.kind == 'rates'

    def close(self):
        """Close the reader."""
        self.reader.close()


def _stamp_ns(msg) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def _unreadable(path, exc) -> BagError:
    first = bounded(str(exc).splitlines()[0]) if str(exc) else ''
    return BagError(f'{path}: unreadable record ({type(exc).__name__}: {first})')


def _decode(reader, conn, records: list):
    """
    Decode a chunk of records: the stamps, the float64 fields and the frames.

    numpy over the plain CDR layout (streams/cdr.py); rosbags' deserializer for any record in
    another encoding.
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


def _read_chunks(reader, conns: list, progress):
    """Decode every record of the connections: ({topic: [chunk]}, {topic: [(log, k)]})."""
    t0, t1 = reader.start_time, reader.end_time
    conn_of = {c.topic: c for c in conns}
    parts: dict = {c.topic: [] for c in conns}
    order: dict = {c.topic: [] for c in conns}          # (log times, chunk) of the fast path
    state = {'next': time.monotonic() + PROGRESS_PERIOD}

    def report(ns):
        now = time.monotonic()
        if progress is not None and now >= state['next']:
            state['next'] = now + PROGRESS_PERIOD
            progress(ns, t0, t1)

    storage = indexed_mcap(reader)
    if storage is not None:                             # one MCAP file with a chunk index
        ids = channel_ids(storage, conns)
        for k, chunk in enumerate(read_topics(storage, ids)):
            for topic, got in chunk.items():
                rows = got.rows if got.rows is not None else got.records
                parts[topic].append(_decode(reader, conn_of[topic], rows))
                order[topic].append((got.log_ns, k))
            if chunk:
                report(int(max(int(g.log_ns[-1]) for g in chunk.values())))
        return parts, order
    records = records_in_bag_order(reader, conns)
    while True:
        chunk = list(islice(records, READ_CHUNK))
        if not chunk:
            break
        for topic, conn in conn_of.items():
            if len(conn_of) > 1:
                raws = [r for c, _, r in chunk if c.topic == topic]
            else:
                raws = [r for _, _, r in chunk]
            if raws:
                parts[topic].append(_decode(reader, conn, raws))
        report(chunk[-1][1])
    return parts, order


def _joined(conn, chunks, order) -> ImuStream:
    """One topic's decoded chunks joined into a stream, in rosbags' order."""
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
    if order:
        # rosbags' order: by log time, then chunk, then within the chunk (chunks overlapping
        # in time interleave); usually the chunks follow each other and this is the identity
        log_ns = np.concatenate([o[0] for o in order])
        chunk = np.concatenate([np.full(len(o[0]), o[1]) for o in order])
        if not np.all(np.diff(log_ns) >= 0):
            perm = np.lexsort((np.arange(len(log_ns)), chunk, log_ns))
            st, vals, idx = st[perm], vals[perm], idx[perm]
    if conn.msgtype == IMU:
        accel = vals[:, IMU_ACCEL:IMU_ACCEL + 3].copy()
        accel[vals[:, IMU_ACCEL_COV] == -1.0] = np.nan          # REP-145: no acceleration
        rate = np.ascontiguousarray(vals[:, IMU_RATE:IMU_RATE + 3])
        return ImuStream(conn.topic, 'rates', st, rate, idx, names, accel)
    return ImuStream(conn.topic, 'increments', st, vals, idx, names)


def read_streams(reader, conns: list, path, progress=None) -> dict:
    """
    Read every record of the connections, decoded a chunk at a time.

    Parameters
    ----------
    reader : rosbags reader
        The open bag.
    conns : list of rosbags connection
        The connections to read (Vector3Stamped or sensor_msgs/Imu).
    path : Path
        The bag, for the error messages.
    progress : callable, optional
        ``progress(log_ns, start_ns, end_ns)``, called at most every :data:`PROGRESS_PERIOD`
        wall seconds.

    Returns
    -------
    dict
        {topic: :class:`ImuStream`}.

    Raises
    ------
    BagError
        A record cannot be read or decoded.

    """
    try:
        parts, order = _read_chunks(reader, conns, progress)
    except BagError:
        raise
    except Exception as exc:                  # a corrupted record, whatever says so
        raise _unreadable(path, exc) from None
    conn_of = {c.topic: c for c in conns}
    return {topic: _joined(conn_of[topic], chunks, order[topic])
            for topic, chunks in parts.items()}


def _find_topics(reader, path, namespace, gyro_topic, accel_topic, need_accel, imu_topic):
    """Find the Δθ (or Imu) topic and the Δv topic (or None), their types checked."""
    types: dict = {}                # topic → {type: messages}: a topic recorded with several
    for c in reader.connections:    # types is read as its supported type (the most messages)
        t = types.setdefault(c.topic, {})
        t[c.msgtype] = t.get(c.msgtype, 0) + int(getattr(c, 'msgcount', 0) or 0)
    ok = (VECTOR3_STAMPED, IMU)
    topics = {t: max(ty, key=lambda k: (k in ok, ty[k])) for t, ty in types.items()}
    where = f' under namespace {bounded(namespace)!r}' if namespace.strip('/') else ''
    listing = f"; topics in the bag: {bounded(', '.join(sorted(topics)) or 'none', 400)}"
    if imu_topic:
        gyro_topic = accel_topic = imu_topic
    g = find_topic(topics, gyro_topic or GYRO_TOPIC, namespace)
    imus = [t for t, ty in topics.items() if ty == IMU]
    if g is None and not gyro_topic and not accel_topic and len(imus) == 1:
        g = imus[0]                    # a driver's bag: its one Imu topic gives both streams
    if g is None:
        raise BagError(f'{path}: no {bounded(gyro_topic or GYRO_TOPIC)}{where}{listing}')
    if topics[g] not in (VECTOR3_STAMPED, IMU):
        raise BagError(f'{bounded(g)} has type {bounded(topics[g])}, expected '
                       f'{VECTOR3_STAMPED} or {IMU}')
    if topics[g] == IMU and not accel_topic:
        accel_topic = g                           # Δv from the same Imu messages
    a = find_topic(topics, accel_topic or ACCEL_TOPIC, namespace)
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
    return g, a


def open_input(bag, namespace: str = '', gyro_topic: str | None = None,
               accel_topic: str | None = None, need_accel: bool = False,
               imu_topic: str | None = None, progress=None) -> ImuRecording:
    """
    Open the bag and read its IMU streams whole.

    Finds the topics (types checked), reads the two streams whole (or the one sensor_msgs/Imu
    stream), takes the rates from their first stamps and the body frame from the Δθ headers
    (the most frequent non-empty frame id).

    Parameters
    ----------
    bag : str or Path
        A rosbag2 bag directory, or a .mcap / .db3 file.
    namespace : str
        Namespace of the relative topic names ('' for none).
    gyro_topic, accel_topic : str, optional
        The Δθ and Δv topics (default :data:`GYRO_TOPIC`, :data:`ACCEL_TOPIC`, else the bag's
        one sensor_msgs/Imu topic when it has exactly one); a gyro topic of type sensor_msgs/Imu
        gives Δv too unless ``accel_topic`` names another.
    need_accel : bool
        The Δv stream is required (navigation).
    imu_topic : str, optional
        One sensor_msgs/Imu topic giving both streams.
    progress : callable, optional
        ``progress(log_ns, start_ns, end_ns)`` while reading (:func:`read_streams`).

    Returns
    -------
    ImuRecording
        The open bag with its streams (the caller closes it).

    Raises
    ------
    BagError
        No such topic, a wrong type, too few stamps, or an unreadable record.

    """
    path = Path(bag)
    reader = open_reader(path)
    try:
        g, a = _find_topics(reader, path, namespace, gyro_topic, accel_topic, need_accel,
                            imu_topic)
        gc = _connection(reader, g)
        ac = _connection(reader, a) if a else None
        used = {g: gc.msgtype, **({a: ac.msgtype} if ac is not None else {})}
        conns = [c for c in reader.connections if used.get(c.topic) == c.msgtype]
        wrong = {t: sum(int(getattr(c, 'msgcount', 0) or 0) for c in reader.connections
                        if c.topic == t and c.msgtype != used.msgtype)
                 for t, used in ((g, gc), (a, ac)) if used is not None}
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
        raise BagError(f'{path}: {bounded(a)} has fewer than 2 messages with distinct stamps '
                       '(or no acceleration); navigation needs it')
    named = [(n, c) for n, c in gs.frames() if n]
    frame_id = named[0][0] if named else ''
    inp = ImuRecording(reader, gc, ac, g_rate, a_rate, path, frame_id, gs, accel_stream)
    inp.wrong_type = {t: n for t, n in wrong.items() if n}
    return inp


def _connection(reader, topic: str):
    """Return the connection of ``topic`` of its supported type (the one with most messages)."""
    cands = [c for c in reader.connections if c.topic == topic]
    return max(cands, key=lambda c: (c.msgtype in (VECTOR3_STAMPED, IMU),
                                     int(getattr(c, 'msgcount', 0) or 0)))
