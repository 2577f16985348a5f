"""
One reader of recordings for the offline tools: gyro and attitude reference from a rosbag2 bag.

Gyro (``--gyro-topic``, default ``imu/delta_theta``, else the bag's one ``sensor_msgs/msg/Imu``
topic if it has exactly one), chosen by the topic's type in the bag:

* ``geometry_msgs/msg/Vector3Stamped``: increments Δθ (rad), stamped at the interval end;
* ``sensor_msgs/msg/Imu``: ``angular_velocity`` rate samples (rad/s).  They are validated by
  :class:`strapdown_ros.streams.checks.StreamCheck` (range ``gyro_max_rate`` per axis, period the
  median step of the stamps), made into increments by
  :func:`strapdown_ros.streams.rate_increments.increments_from_rates` (rule ``trapezoid`` or
  ``mean``, intervals above 1.5 periods not integrated), and the increments then take the same path
  as Δθ messages (validation, gaps, missing counts).

Attitude reference (``--reference-topic``, default ``star_camera/attitude_with_covariance``
when present and its covariance is wanted, else ``star_camera/attitude``, else the bag's one
topic of a type below but TF if it has exactly one): q_ref_body of the camera (maps child-frame
vectors to the parent frame), from

* ``geometry_msgs/msg/QuaternionStamped``, ``PoseStamped`` or ``TransformStamped`` (no
  covariance; a TransformStamped's rotation maps ``child_frame_id`` vectors to
  ``header.frame_id``, as motion-capture drivers such as vicon_bridge publish it);
* ``geometry_msgs/msg/PoseWithCovarianceStamped`` or ``nav_msgs/msg/Odometry``
  (``pose.covariance`` rows/columns 3–5: the rotation block, rad²);
* ``tf2_msgs/msg/TFMessage`` (``/tf``) with ``--reference-frames PARENT CHILD``: the transforms
  PARENT → CHILD, or the inverse of CHILD → PARENT when only that is recorded.

Every fix goes through THE screening of a reference fix
(:class:`strapdown_ros.streams.fixes.FixScreen`, as in the nodes): a reference without a
covariance, with an all-zero one (ROS "unknown") or a zero rotation block takes its σ from the
model (``camera_sigma_xy``/``camera_sigma_z``); a quaternion that is not unit is normalised
without overflow, a zero or non-finite one dropped; a covariance that is not symmetric, not
positive definite or beyond its bounds dropped; then the stamp rules of a fix stream
(:meth:`StreamCheck.for_fixes`).  Every drop is counted under its reason.  A message on a used
topic whose connection has another type, or whose bytes do not decode, is dropped and counted
(``wrong_type``, ``undecodable``); the bag is refused only when no message of a topic is usable.
The number of messages read per topic is compared with the bag's own index (rosbags: the
connections' message counts): a chunk the storage reader skipped (a corrupt record, an unknown
opcode) shows as ``unread_messages`` instead of passing silently.

Speed: one MCAP file with a chunk index whose two topics have a fixed plain-CDR layout (every
type above but TFMessage and Odometry) is read a chunk at a time
(:mod:`strapdown_ros.recording.mcap_records`, as ``sins_bag`` reads) and its stream rules run at
array speed (:func:`strapdown_ros.streams.checks.validate`); any other bag record by record
through rosbags.  Both give the same streams and counts (test/recording/test_reader_paths.py).

rosbags is an optional extra (``tools``); only the offline tools import this module.
"""
from __future__ import annotations

import math
from pathlib import Path
import sys

import numpy as np
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.typesys import get_typestore, Stores

from strapdown_ros.recording.mcap_records import channel_ids, indexed_mcap, read_topics
from strapdown_ros.rotation import from_ros_xyzw, quat_conjugate
from strapdown_ros.streams.cdr import stamped_doubles
from strapdown_ros.streams.checks import nominal_period, StreamCheck, validate
from strapdown_ros.streams.fixes import FixScreen
from strapdown_ros.streams.rate_increments import increments_from_rates, RATE_RULES

__all__ = ['BagError', 'Accepted', 'open_reader', 'resolve_topic', 'read_bag', 'bounded',
           'bounded_list', 'GYRO_TOPIC', 'CAMERA_TOPIC', 'CAMERA_COV_TOPIC', 'DELTA_THETA_TYPE',
           'IMU_TYPE', 'REFERENCE_TYPES', 'chunked_records']

GYRO_TOPIC = 'imu/delta_theta'
CAMERA_TOPIC = 'star_camera/attitude'
CAMERA_COV_TOPIC = 'star_camera/attitude_with_covariance'
TF_TOPIC = 'tf'
DELTA_THETA_TYPE = 'geometry_msgs/msg/Vector3Stamped'
IMU_TYPE = 'sensor_msgs/msg/Imu'
GYRO_TYPES = (DELTA_THETA_TYPE, IMU_TYPE)
#: reference message type → how its orientation (and covariance) is read
REFERENCE_TYPES = {
    'geometry_msgs/msg/QuaternionStamped': 'quaternion',
    'geometry_msgs/msg/PoseStamped': 'pose',
    'geometry_msgs/msg/TransformStamped': 'transform',
    'geometry_msgs/msg/PoseWithCovarianceStamped': 'pose_with_covariance',
    'nav_msgs/msg/Odometry': 'odometry',
    'tf2_msgs/msg/TFMessage': 'tf',
}
_WITH_COVARIANCE = ('pose_with_covariance', 'odometry')
MAX_LISTED = 12  # topics or frame pairs named in one error line
#: rosbags' words for a bag without message definitions (then opened with the Jazzy store)
NO_DEFINITIONS = 'no type definitions'
MAX_NAME = 80  # characters of one echoed name
MAX_PAIRS_KEPT = 64  # distinct TF frame pairs remembered for the error line
MAX_FRAMES_KEPT = 16  # distinct header frame ids counted per stream (the rest: one count)
#: the key under which frame ids beyond MAX_FRAMES_KEPT are counted
OTHER_FRAMES = '(other frames)'


class BagError(RuntimeError):
    """The bag cannot be used (missing topics, wrong types, unreadable)."""


def bounded(text, n: int = MAX_NAME) -> str:
    """
    Bound a string echoed from a bag: one line, at most ``n`` characters.

    Parameters
    ----------
    text : object
        Shown as ``str(text)``; control characters escaped.
    n : int
        Longest result; a cut is marked by an ellipsis.

    Returns
    -------
    str

    """
    text = ''.join(c if c.isprintable() else repr(c)[1:-1] for c in str(text)[: 4 * n])
    return text if len(text) <= n else text[: n - 1] + '…'


def bounded_list(items, n: int = MAX_LISTED) -> str:
    """
    Return a bounded, comma-separated listing.

    Parameters
    ----------
    items : iterable
        Items to list, each shown by :func:`bounded`.
    n : int
        Most items named; the rest are counted ("… and k more").

    Returns
    -------
    str
        ``"none"`` for no items.

    """
    items = list(items)
    head = ', '.join(bounded(i) for i in items[:n])
    return (head + (f', … and {len(items) - n} more' if len(items) > n else '')) or 'none'


def _topics_line(topics: dict) -> str:
    return 'topics in the bag: ' + bounded_list(f'{t} ({ty})' for t, ty in sorted(topics.items()))


def _first_line(exc) -> str:
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return bounded(text, 200)


def open_reader(path):
    """
    Open a bag directory or file with ``rosbags``.

    The message types are the bag's own definitions; a bag without them (a rosbag2 bag from
    before Iron) is opened again with the Jazzy type store (building that store costs a
    tenth of a second, so it is not built for a bag that does not need it).

    Parameters
    ----------
    path : str or Path
        rosbag2 bag directory, a single ``.mcap`` / ``.db3`` file, or a ROS 1 ``.bag``.

    Returns
    -------
    rosbags.highlevel.AnyReader
        Opened; the caller closes it.  Raises :class:`BagError` (one line) when the bag is
        missing or unreadable.

    """
    path = Path(path)
    if not path.exists():
        raise BagError(f'{path} does not exist')
    try:
        try:
            reader = AnyReader([path])
            reader.open()
        except AnyReaderError as exc:
            if NO_DEFINITIONS not in str(exc):
                raise
            reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY))
            reader.open()
    except Exception as exc:  # noqa: BLE001 - any unreadable bag is reported
        raise BagError(f'cannot open {path}: {_first_line(exc)}') from None
    return reader


def resolve_topic(topics, name: str, namespace: str = '') -> str | None:
    """
    Return the bag topic for the relative name ``name``.

    Parameters
    ----------
    topics : iterable of str
        Topic names in the bag.
    name : str
        Relative topic name, e.g. ``imu/delta_theta``.
    namespace : str
        ``/robot1`` or ``""``.

    Returns
    -------
    str or None
        ``[/]<namespace>/<name>``; without a namespace ``[/]<name>`` or else the only topic
        ending in ``/<name>``; None when there is none.

    """
    ns = namespace.strip('/')
    want = f'{ns}/{name}' if ns else name
    for t in topics:
        if t.strip('/') == want:
            return t
    if not ns:
        cands = [t for t in topics if t.strip('/').endswith('/' + name)]
        if len(cands) == 1:
            return cands[0]
    return None


def _named_topic(topics: dict, name: str, namespace: str, option: str, path) -> str:
    """
    Return the topic given by an option.

    The topic given by an option: an absolute name (``/x``) as is, a relative one under the
    namespace (:func:`resolve_topic`).
    """
    if name.startswith('/'):
        found = next((t for t in topics if t.strip('/') == name.strip('/')), None)
    else:
        found = resolve_topic(topics, name, namespace)
    if found is None:
        where = (
            f' under namespace {bounded(namespace)!r}'
            if namespace.strip('/') and not name.startswith('/')
            else ''
        )
        raise BagError(
            f'{path}: {option} {bounded(name)}: no such topic{where}; {_topics_line(topics)}'
        )
    return found


def records_in_bag_order(reader, conns: list):
    """
    Yield (connection, log time, raw) of the connections in bag order.

    With one bag, its own reader (rosbags' AnyReader merges several bags by time, at a cost
    per record).

    Parameters
    ----------
    reader : rosbags.highlevel.AnyReader
        The open reader.
    conns : list
        Its connections to read.

    Returns
    -------
    iterator
        (connection, log time ns, raw bytes).

    """
    owners = {id(getattr(c, 'owner', None)) for c in conns}
    inner = getattr(reader, 'readers', None)
    if inner is not None and len(inner) == 1 and owners == {id(inner[0])}:
        return inner[0].messages(connections=conns)
    return reader.messages(connections=conns)


def _stamp_ns(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


class Accepted:
    """
    One recorded stream after the nodes' input rules (:mod:`strapdown_ros.streams.checks`).

    Parameters
    ----------
    stamps, values : list
        Accepted stamps (int ns) and values, in order.
    gaps : list of (int, int)
        Intervals (ns) that no increment pair may span.
    check : StreamCheck
        The check that accepted them (its counts).
    extra_received : int
        Messages dropped before the check (e.g. zero quaternions), counted as received.
    extra_dropped : dict, optional
        Those messages per reason (``nan`` adds to the check's).
    screened : bool
        The values are fixes that passed THE screening of a fix
        (:class:`~strapdown_ros.streams.fixes.FixScreen`): a consumer need not screen them again.

    """

    def __init__(self, stamps, values, gaps, check, extra_received: int = 0,
                 extra_dropped: dict | None = None, screened: bool = False):
        self.stamps, self.values, self.gaps, self.check = stamps, values, gaps, check
        self.screened = bool(screened)
        self.received = check.received + extra_received
        self.missing = check.missing
        self.dropped = {
            'nan': check.nan,
            'duplicate': check.duplicate,
            'out_of_order': check.out_of_order,
            'out_of_range': check.out_of_range,
            'stamp_outlier': check.stamp_outliers,
            'stamp_burst': check.burst_messages,
        }
        for k, v in (extra_dropped or {}).items():
            self.dropped[k] = self.dropped.get(k, 0) + int(v)
        self.resyncs = check.resyncs


# --- topic selection -------------------------------------------------------------------------
def _only_topic(topics: dict, types) -> str | None:
    """Return the one topic of these types in the bag, or None (none, or several)."""
    found = [t for t, ty in topics.items() if ty in types]
    return found[0] if len(found) == 1 else None


def _select(
    topics: dict,
    path,
    namespace: str,
    use_camera_covariance: bool,
    gyro_topic,
    reference_topic,
    reference_frames,
) -> tuple[str, str]:
    where = f' under namespace {bounded(namespace)!r}' if namespace.strip('/') else ''
    if gyro_topic:
        g = _named_topic(topics, gyro_topic, namespace, '--gyro-topic', path)
    else:
        g = resolve_topic(topics, GYRO_TOPIC, namespace)
    if reference_topic:
        c = _named_topic(topics, reference_topic, namespace, '--reference-topic', path)
    elif reference_frames:
        c = resolve_topic(topics, TF_TOPIC, namespace) or resolve_topic(topics, TF_TOPIC, '')
        if c is None:
            raise BagError(
                f'{path}: --reference-frames without --reference-topic reads /tf, which the bag '
                f'does not have{where}; {_topics_line(topics)}'
            )
    else:
        cov = resolve_topic(topics, CAMERA_COV_TOPIC, namespace)
        plain = resolve_topic(topics, CAMERA_TOPIC, namespace)
        # the covariance topic when its covariance is wanted, or when it is the only one (σ then
        # from the model)
        c = cov if (cov and (use_camera_covariance or plain is None)) else plain
    # no default topic and no option: the one topic of a driver's type, when there is one
    # (an Imu topic for the gyro; a pose-like topic for the reference), else the error below
    if g is None and not gyro_topic:
        g = _only_topic(topics, (IMU_TYPE,))
    if c is None and not reference_topic and not reference_frames:
        c = _only_topic(topics, [t for t, k in REFERENCE_TYPES.items() if k != 'tf'])
    if g is None or c is None:
        missing = [n for n, t in ((GYRO_TOPIC, g), (CAMERA_TOPIC, c)) if t is None]
        raise BagError(f"{path}: no {' and no '.join(missing)}{where}; {_topics_line(topics)}")
    if topics[g] not in GYRO_TYPES:
        raise BagError(
            f'{path}: gyro topic {bounded(g)} has type {bounded(topics[g])}; supported: '
            f"{', '.join(GYRO_TYPES)}"
        )
    if topics[c] not in REFERENCE_TYPES:
        raise BagError(
            f'{path}: reference topic {bounded(c)} has type {bounded(topics[c])}; supported: '
            f"{', '.join(REFERENCE_TYPES)}"
        )
    kind = REFERENCE_TYPES[topics[c]]
    if kind == 'tf' and not reference_frames:
        raise BagError(
            f'{path}: reference topic {bounded(c)} is {bounded(topics[c])}: '
            f'give --reference-frames PARENT CHILD'
        )
    if kind != 'tf' and reference_frames:
        raise BagError(
            f'{path}: --reference-frames needs a tf2_msgs/msg/TFMessage reference topic; '
            f'{bounded(c)} is {bounded(topics[c])}'
        )
    return g, c


# --- fixed-layout messages, decoded with numpy ---------------------------------------------------
#: message type → (float64 fields after the header, what they hold): the types whose plain CDR
#: layout is a std_msgs/Header and then float64 only
_LAYOUT = {
    DELTA_THETA_TYPE: (3, 'vector'),
    IMU_TYPE: (37, 'imu'),
    'geometry_msgs/msg/QuaternionStamped': (4, 'quaternion'),
    'geometry_msgs/msg/PoseStamped': (7, 'pose'),
    'geometry_msgs/msg/PoseWithCovarianceStamped': (43, 'pose_with_covariance'),
}
_IMU_RATE, _IMU_RATE_COV = 13, 16            # angular_velocity, angular_velocity_covariance[0]


def _decode_records(reader, parts, msgtype, layout) -> dict:
    """
    Decode the records of one topic with numpy (:func:`~.streams.cdr.stamped_doubles`).

    The same values as the deserializer gives: records in another encoding go through it, and
    records it cannot decode either are counted (``undecodable``) and dropped.

    Parameters
    ----------
    reader : rosbags.highlevel.AnyReader
        The open reader (its deserializer).
    parts : list of (records, log_ns)
        The topic's records a part at a time (a list of bytes, or an array of equal-length
        rows), in bag order within each part; ``log_ns`` (ndarray, or None) their log times,
        to merge parts that overlap in time in rosbags' order (by log time, then part).
    msgtype : str
        The message type.
    layout : (int, str)
        Float64 fields after the header and what they hold (``_LAYOUT``).

    Returns
    -------
    dict
        Gyro: ``stamps`` (n,) int64 and ``values`` (n, 3) (Imu messages marking the rate absent
        left out and counted in ``absent``).  Reference: ``items`` (ns, q_wxyz, P or None), the
        form the loop of :func:`read_bag` collects.  Both: ``frames`` (frame id → messages)
        and ``undecodable``.

    """
    count, kind = layout
    decoded = [stamped_doubles(records, count) for records, _ in parts]
    known: dict = {}
    idx_l = []
    for _, _, idx, nm, _ in decoded:
        remap = np.array([known.setdefault(x, len(known)) for x in nm] or [0], dtype=np.int64)
        idx_l.append(np.where(idx >= 0, remap[np.maximum(idx, 0)], -1))
    names = list(known)
    st = np.concatenate([d[0] for d in decoded])
    vals = np.concatenate([d[1] for d in decoded])
    idx = np.concatenate(idx_l)
    offsets = np.cumsum([0] + [len(d[0]) for d in decoded])
    bad = np.concatenate([d[4] + o for d, o in zip(decoded, offsets[:-1])]).astype(np.int64)
    frames: dict = {}
    for i, n in zip(*np.unique(idx[idx >= 0], return_counts=True)):
        frames[names[i]] = frames.get(names[i], 0) + int(n)
    undecodable = np.zeros(len(st), dtype=bool)
    for i in bad.tolist():
        p = int(np.searchsorted(offsets, i, side='right')) - 1
        rec = parts[p][0][i - offsets[p]]
        try:
            msg = reader.deserialize(rec.tobytes() if isinstance(rec, np.ndarray) else rec,
                                     msgtype)
            st[i] = _stamp_ns(msg.header)
            vals[i] = _fields(msg, kind, count)
            frames[msg.header.frame_id] = frames.get(msg.header.frame_id, 0) + 1
        except Exception:  # noqa: BLE001 - bytes that are not this type: counted, dropped
            undecodable[i] = True
    if len(parts) > 1 and all(log is not None for _, log in parts):
        log_ns = np.concatenate([log for _, log in parts])
        if not np.all(np.diff(log_ns) >= 0):          # parts overlapping in time: rosbags' order
            part = np.repeat(np.arange(len(parts)), np.diff(offsets))
            perm = np.lexsort((np.arange(len(st)), part, log_ns))
            st, vals, undecodable = st[perm], vals[perm], undecodable[perm]
    if np.any(undecodable):
        st, vals = st[~undecodable], vals[~undecodable]
    absent = 0
    if kind in ('vector', 'imu'):
        if kind == 'imu':
            present = vals[:, _IMU_RATE_COV] != -1.0   # ROS: covariance[0] = -1 marks it absent
            absent = int(np.sum(~present))
            st, xyz = st[present], vals[present, _IMU_RATE:_IMU_RATE + 3]
        else:
            xyz = vals
        return {'stamps': st, 'values': np.ascontiguousarray(xyz), 'frames': frames,
                'absent': absent, 'undecodable': int(undecodable.sum())}
    st_list = st.tolist()
    q_xyzw = {'quaternion': vals[:, 0:4], 'pose': vals[:, 3:7],
              'pose_with_covariance': vals[:, 3:7]}[kind]
    q = from_ros_xyzw(q_xyzw)
    if kind == 'pose_with_covariance':
        P = vals[:, 7:43].reshape(-1, 6, 6)[:, 3:, 3:]
        items = list(zip(st_list, q, P))
    else:
        items = [(s, qq, None) for s, qq in zip(st_list, q)]
    return {'items': items, 'frames': frames, 'absent': 0,
            'undecodable': int(undecodable.sum())}


def chunked_records(reader, conns, topics, layout):
    """
    Read the records of the connections a chunk at a time, when the bag allows it.

    One MCAP file with a chunk index (:func:`~.mcap_records.indexed_mcap`), every connection of
    its topic's type and of a fixed layout.  :func:`read_bag` reads any other bag record by
    record through rosbags, with the same result.

    Parameters
    ----------
    reader : rosbags.highlevel.AnyReader
        The open reader.
    conns : list
        Its connections to read.
    topics : dict
        Topic → the type it is read as.
    layout : dict
        Topic → its fixed plain-CDR layout (float64 fields after the header), or None.

    Returns
    -------
    dict or None
        {topic: [(records, log_ns) per chunk]}; None when the bag is not read this way.

    """
    if not conns or any(c.msgtype != topics[c.topic] or layout[c.topic] is None for c in conns):
        return None
    storage = indexed_mcap(reader)
    if storage is None:
        return None
    out: dict = {c.topic: [] for c in conns}
    for chunk in read_topics(storage, channel_ids(storage, conns)):
        for topic, got in chunk.items():
            out[topic].append((got.rows if got.rows is not None else got.records, got.log_ns))
    return out


def _fields(msg, kind, count) -> np.ndarray:
    """Return the float64 fields of a deserialized message in the plain-CDR order."""
    out = np.full(count, np.nan)
    if kind == 'vector':
        out[:] = (msg.vector.x, msg.vector.y, msg.vector.z)
    elif kind == 'imu':
        w = msg.angular_velocity
        out[_IMU_RATE:_IMU_RATE + 3] = (w.x, w.y, w.z)
        out[_IMU_RATE_COV] = msg.angular_velocity_covariance[0]
    else:
        o = (msg.quaternion if kind == 'quaternion' else
             msg.pose.orientation if kind == 'pose' else msg.pose.pose.orientation)
        at = 0 if kind == 'quaternion' else 3
        out[at:at + 4] = (o.x, o.y, o.z, o.w)
        if kind == 'pose_with_covariance':
            out[7:43] = np.asarray(msg.pose.covariance, dtype=float)
    return out


# --- reference fixes -------------------------------------------------------------------------
def _strip(frame: str) -> str:
    return str(frame).lstrip('/')


def _process_fixes(raw, screen: FixScreen):
    """Screen each fix (:class:`FixScreen`); return (ns, q_wxyz + P 3×3) of the fixes kept."""
    got = screen.screen_many([q for _, q, _ in raw], [P for _, _, P in raw])
    return [(ns, tuple(g[0].tolist()) + tuple(np.asarray(g[1], dtype=float).ravel().tolist()))
            for (ns, _, _), g in zip(raw, got) if g is not None]


def _rate(increment: float, period: float) -> float:
    """Return an increment as a rate, rad/s, never beyond the largest float (1e308 / 0.01)."""
    if not (np.isfinite(period) and period > 0):
        return 0.0
    return float(min(increment, period * sys.float_info.max) / period)


def _count_frame(frames: dict, frame, n: int = 1) -> None:
    """Count header frame ids (bounded: at most MAX_FRAMES_KEPT distinct names)."""
    name = bounded(frame, 200)
    if name in frames or len(frames) < MAX_FRAMES_KEPT:
        frames[name] = frames.get(name, 0) + n
    else:
        frames[OTHER_FRAMES] = frames.get(OTHER_FRAMES, 0) + n


def _orientation(q) -> np.ndarray:
    return from_ros_xyzw(np.array([q.x, q.y, q.z, q.w], dtype=float))


def _rotation_block(cov) -> np.ndarray:
    return np.asarray(cov, dtype=float).reshape(6, 6)[3:, 3:]


class _TfCollector:
    """Transforms PARENT → CHILD (direct) and CHILD → PARENT (to be inverted) from TFMessages."""

    def __init__(self, frames):
        self.parent, self.child = (_strip(f) for f in frames)
        self.direct, self.inverse = [], []
        self.pairs: dict = {}  # (parent, child) → count, at most MAX_PAIRS_KEPT kept
        self.more_pairs = 0

    def add(self, msg) -> None:
        for tr in msg.transforms:
            a, b = _strip(tr.header.frame_id), _strip(tr.child_frame_id)
            if (a, b) in self.pairs:
                self.pairs[(a, b)] += 1
            elif len(self.pairs) < MAX_PAIRS_KEPT:
                self.pairs[(a, b)] = 1
            else:
                self.more_pairs += 1
            if (a, b) == (self.parent, self.child):
                self.direct.append(
                    (_stamp_ns(tr.header), _orientation(tr.transform.rotation), None)
                )
            elif (a, b) == (self.child, self.parent):
                self.inverse.append(
                    (_stamp_ns(tr.header), _orientation(tr.transform.rotation), None)
                )

    def fixes(self, path, topic):
        if self.direct:
            return self.direct, 'direct'
        if self.inverse:
            return [(ns, quat_conjugate(q), P) for ns, q, P in self.inverse], 'inverse'
        present = bounded_list(f'{a}→{b}' for a, b in sorted(self.pairs))
        more = ' (and more pairs)' if self.more_pairs else ''
        raise BagError(
            f'{path}: {bounded(topic)} has no transform '
            f'{bounded(self.parent)}→{bounded(self.child)} '
            f'nor its inverse; frame pairs present: {present}{more}'
        )


# --- reading ---------------------------------------------------------------------------------
def read_bag(
    path: str | Path,
    namespace: str = '',
    use_camera_covariance: bool = True,
    camera_sigma=(0.0, 0.0, 0.0),
    gyro_max_rate: float = 20.0,
    max_stamp_jump: float = 1.0,
    resync_count: int = 5,
    *,
    gyro_topic: str | None = None,
    reference_topic: str | None = None,
    reference_frames=None,
    rate_rule: str = 'trapezoid',
) -> dict:
    """
    Gyro increments and attitude fixes from a bag, validated by calibrator_node's rules.

    Parameters
    ----------
    path : str or Path
        Bag directory or single file.
    namespace : str
        Topic namespace of the default (and relative) topic names.
    use_camera_covariance : bool
        Use the covariance of the reference messages that carry one (else the model σ).
    camera_sigma : sequence of 3 float
        Model σ about VF x, y, z, rad: the covariance of a fix that has none.
    gyro_max_rate : float
        Gyro range, rad/s per axis (rate samples above it, increments above 2 periods × it, are
        dropped).
    max_stamp_jump : float
        Stamp jump limit, s (:class:`~strapdown_ros.streams.checks.StreamCheck`).
    resync_count : int
        Messages that confirm a new timeline.
    gyro_topic, reference_topic : str or None
        Topics to read (absolute ``/x`` or relative to ``namespace``); None: the defaults.
    reference_frames : (str, str) or None
        PARENT, CHILD of a TF reference.
    rate_rule : {'trapezoid', 'mean'}
        Rule that makes increments from ``sensor_msgs/Imu`` rate samples.

    Returns
    -------
    dict
        ``gyro`` and ``camera`` (:class:`Accepted`; camera values ``(q_wxyz, P 3×3 rad²)``),
        ``gyro_topic``, ``camera_topic``, ``camera_covariance_from_bag``, ``camera_fixes``
        (counts), ``gyro_period_s``, ``frames`` and the input description of
        :func:`input_summary` (types, rate samples, reference covariance, unread messages).
        Raises :class:`BagError` (one line).

    """
    if rate_rule not in RATE_RULES:
        raise BagError(
            f"rate rule {rate_rule!r} is not valid; valid values: {', '.join(RATE_RULES)}"
        )
    path = Path(path)
    reader = open_reader(path)
    try:
        types: dict = {}                   # topic → {type: messages in the index}
        for c in reader.connections:
            t = types.setdefault(c.topic, {})
            t[c.msgtype] = t.get(c.msgtype, 0) + int(getattr(c, 'msgcount', 0) or 0)
        # a topic recorded with several types is read as its supported type (the most
        # messages); the other connections' messages are counted as wrong_type
        supported = set(GYRO_TYPES) | set(REFERENCE_TYPES)
        topics = {t: max(ty, key=lambda k: (k in supported, ty[k])) for t, ty in types.items()}
        gyro_t, ref_t = _select(
            topics,
            path,
            namespace,
            use_camera_covariance,
            gyro_topic,
            reference_topic,
            reference_frames,
        )
        gyro_type, ref_type = topics[gyro_t], topics[ref_t]
        kind = REFERENCE_TYPES[ref_type]
        rates = gyro_type == IMU_TYPE
        with_cov = kind in _WITH_COVARIANCE and bool(use_camera_covariance)
        expected = {gyro_t: 0, ref_t: 0}
        for c in reader.connections:
            if c.topic in expected:
                expected[c.topic] += int(getattr(c, 'msgcount', 0) or 0)
        read = {gyro_t: 0, ref_t: 0}
        skipped = {'gyro': {'wrong_type': 0, 'undecodable': 0},
                   'camera': {'wrong_type': 0, 'undecodable': 0}}
        raw_g, raw_fix = [], []
        rate_absent = 0
        frames: dict = {'gyro': {}, 'camera': {}}
        tf = _TfCollector(reference_frames) if kind == 'tf' else None
        conns = [c for c in reader.connections if c.topic in (gyro_t, ref_t)]
        fast = {gyro_t: [], ref_t: []}                 # plain-CDR records decoded with numpy
        layout = {gyro_t: _LAYOUT.get(gyro_type), ref_t: _LAYOUT.get(ref_type)}
        chunked = chunked_records(reader, conns, topics, layout)
        if chunked is not None:                        # one indexed MCAP file, every type known
            for topic, parts in chunked.items():
                fast[topic] = parts
                read[topic] += sum(len(r) for r, _ in parts)
        for conn, _, raw in (records_in_bag_order(reader, conns) if chunked is None else ()):
            read[conn.topic] += 1
            stream = 'gyro' if conn.topic == gyro_t else 'camera'
            if conn.msgtype != topics[conn.topic]:
                skipped[stream]['wrong_type'] += 1
                continue
            if layout[conn.topic] is not None:
                if not fast[conn.topic]:
                    fast[conn.topic].append(([], None))
                fast[conn.topic][0][0].append(raw)
                continue
            try:
                msg = reader.deserialize(raw, conn.msgtype)
                if conn.topic == gyro_t:
                    ns = _stamp_ns(msg.header)
                    frame = msg.header.frame_id
                    if rates and float(msg.angular_velocity_covariance[0]) == -1.0:
                        rate_absent += 1      # ROS: covariance[0] = -1 marks the field absent
                        _count_frame(frames['gyro'], frame)
                        continue
                    v = msg.angular_velocity if rates else msg.vector
                    value = (float(v.x), float(v.y), float(v.z))
                elif kind == 'tf':
                    tf.add(msg)
                    continue
                else:
                    ns = _stamp_ns(msg.header)
                    frame = msg.header.frame_id
                    if kind == 'quaternion':
                        value = (_orientation(msg.quaternion), None)
                    elif kind == 'pose':
                        value = (_orientation(msg.pose.orientation), None)
                    elif kind == 'transform':         # header.frame_id ← child_frame_id
                        value = (_orientation(msg.transform.rotation), None)
                    else:  # PoseWithCovarianceStamped, Odometry
                        value = (_orientation(msg.pose.pose.orientation),
                                 _rotation_block(msg.pose.covariance))
            except Exception:  # noqa: BLE001 - bytes that are not this type: counted, dropped
                skipped[stream]['undecodable'] += 1
                continue
            _count_frame(frames[stream], frame)
            if stream == 'gyro':
                raw_g.append((ns, value))
            else:
                raw_fix.append((ns, value[0], value[1]))
        gyro_parts = []                                # (stamps, xyz) arrays of the gyro
        for topic, parts in fast.items():
            if not parts:
                continue
            stream = 'gyro' if topic == gyro_t else 'camera'
            dec = _decode_records(reader, parts, topics[topic], layout[topic])
            for name, n in dec['frames'].items():
                _count_frame(frames[stream], name, n)
            skipped[stream]['undecodable'] += dec['undecodable']
            if stream == 'gyro':
                rate_absent += dec['absent']
                gyro_parts.append((dec['stamps'], dec['values']))
            else:
                raw_fix.extend(dec['items'])
        if raw_g:                                      # decoded one by one (another layout)
            gyro_parts.insert(0, (np.array([t for t, _ in raw_g], dtype=np.int64),
                                  np.array([v for _, v in raw_g], dtype=float).reshape(-1, 3)))
        g_raw_t = (np.concatenate([p[0] for p in gyro_parts]) if gyro_parts
                   else np.zeros(0, np.int64))
        g_raw_v = (np.concatenate([p[1] for p in gyro_parts]) if gyro_parts
                   else np.zeros((0, 3)))
        tf_direction = None
        if tf is not None:
            raw_fix, tf_direction = tf.fixes(path, ref_t)
            frames['camera'][bounded(tf.parent, 200)] = len(raw_fix)
    except BagError:
        raise
    except Exception as exc:  # noqa: BLE001 - a corrupted record, whatever the reader says
        raise BagError(
            f'{path}: unreadable record ({type(exc).__name__}: {_first_line(exc)})'
        ) from None
    finally:
        reader.close()
    unread = {
        t: expected[t] - read[t]
        for t in (gyro_t, ref_t)
        if expected[t] > 0 and expected[t] != read[t]
    }
    for stream, topic in (('gyro', gyro_t), ('camera', ref_t)):
        n_skip = sum(skipped[stream].values())
        if n_skip and n_skip == read[topic]:
            why = ', '.join(f'{k} {v}' for k, v in skipped[stream].items() if v)
            raise BagError(f'{path}: no usable message on {bounded(topic)}: all {n_skip} '
                           f'dropped ({why}; type {bounded(topics[topic])})')

    # gyro: rate samples → increments, then the increments' rules with the period from the stamps
    rate_info = None
    rate_gaps: list = []
    if rates:
        if rate_absent and not len(g_raw_t):
            raise BagError(
                f'{path}: every {IMU_TYPE} message on {bounded(gyro_t)} marks angular_velocity '
                f'absent (angular_velocity_covariance[0] = -1)'
            )
        r_period = nominal_period(g_raw_t)
        r_check = StreamCheck(
            r_period,
            max_norm=float(gyro_max_rate),
            jump_limit=max_stamp_jump,
            resync_count=resync_count,
        )
        rt, rv, rate_gaps = validate(g_raw_t, g_raw_v, r_check)
        # THE gap rule decides which intervals are integrated (no step threshold of its own)
        inc_t, inc_v = increments_from_rates(
            rt,
            np.asarray(rv, dtype=float).reshape(-1, 3),
            rate_rule,
            breaks=[b for _, b in rate_gaps],
        )
        rate_info = {
            'received': r_check.received + rate_absent + sum(skipped['gyro'].values()),
            'accepted': len(rt),
            'dropped': {
                'nan': r_check.nan,
                'duplicate': r_check.duplicate,
                'out_of_order': r_check.out_of_order,
                'out_of_range': r_check.out_of_range,
                'stamp_outlier': r_check.stamp_outliers,
                'stamp_burst': r_check.burst_messages,
                'marked_absent': rate_absent,
                **skipped['gyro'],
            },
            'largest_out_of_range_rad_s': r_check.largest_out_of_range,
            'intervals_not_integrated': max(len(rt) - 1 - len(inc_t), 0),
            'gaps': r_check.gaps,
            'missing': r_check.missing,
            'resyncs': r_check.resyncs,
            'period_s': r_period if math.isfinite(r_period) else None,
            'period_s_from_stamps': r_check.period_s if math.isfinite(r_check.period_ns)
            else None,
        }
        g_stamps = np.asarray(inc_t, dtype=np.int64).reshape(-1)
        g_values = np.asarray(inc_v, dtype=float).reshape(-1, 3)
    else:
        g_stamps, g_values = g_raw_t, g_raw_v
    g_period = nominal_period(g_stamps)
    g_check = StreamCheck(
        g_period,
        max_norm=2.0 * g_period * float(gyro_max_rate) if np.isfinite(g_period) else None,
        jump_limit=max_stamp_jump,
        resync_count=resync_count,
    )
    gyro = Accepted(*validate(g_stamps, g_values, g_check), g_check,
                    0 if rates else sum(skipped['gyro'].values()),
                    None if rates else skipped['gyro'])

    # reference: THE screening of a fix, then the stamp rules of a fix stream
    screen = FixScreen(np.diag(np.asarray(camera_sigma, dtype=float) ** 2), with_cov)
    raw_c = _process_fixes(raw_fix, screen)
    c_check = StreamCheck.for_fixes(max_stamp_jump, resync_count)
    ct, cv, cgaps = validate([t for t, _ in raw_c], [v for _, v in raw_c], c_check)
    fix_counts = screen.counts()
    before_check = dict(fix_counts['dropped'])
    before_check.update(skipped['camera'])
    cam = Accepted(
        ct,
        [(np.array(v[:4]), np.array(v[4:]).reshape(3, 3)) for v in cv],
        cgaps,
        c_check,
        screen.dropped + sum(skipped['camera'].values()),
        before_check,
        screened=True,
    )
    from_messages = screen.from_messages
    n_model = len(raw_c) - from_messages
    ref_cov = (
        'from_model' if from_messages == 0 else ('from_messages' if n_model == 0 else 'mixed')
    )
    frames_used = None if tf is None else {'parent': tf.parent, 'child': tf.child,
                                           'transform': tf_direction}
    clip = {'parameter': 'gyro_max_rate', 'limit': float(gyro_max_rate), 'unit': 'rad/s',
            'count': (rate_info['dropped']['out_of_range'] if rate_info else 0)
            + g_check.out_of_range,
            'largest': max(rate_info['largest_out_of_range_rad_s'] if rate_info else 0.0,
                           _rate(g_check.largest_out_of_range, g_period))}
    camera_fixes = {'zero_quaternion': screen.zero_quaternion,
                    'bad_covariance': screen.bad_covariance,
                    'normalised': screen.normalised,
                    'covariance_substituted': screen.covariance_substituted,
                    'nan': screen.nan, 'not_unit': screen.not_unit,
                    'bad_covariance_reasons': dict(screen.bad_covariance_reasons)}
    return {'gyro_clip': clip,
            'gyro_topic': gyro_t, 'camera_topic': ref_t, 'camera_covariance_from_bag': with_cov,
            'gyro': gyro, 'camera': cam, 'camera_fixes': camera_fixes, 'gyro_period_s': g_period,
            'frames': {k: sorted(v) for k, v in frames.items()},
            'frame_counts': {k: dict(v) for k, v in frames.items()}, 'gyro_type': gyro_type,
            'gyro_input': 'rates' if rates else 'delta_theta',
            'rate_rule': rate_rule if rates else None, 'rate_samples': rate_info,
            'reference_type': ref_type, 'reference_frames': frames_used,
            'reference_covariance': ref_cov, 'reference_covariance_from_model': n_model,
            'unread_messages': unread, 'messages_in_bag_index': expected,
            'messages_read': dict(read)}
