"""
One reader of recordings for the offline tools: gyro and attitude reference from a rosbag2 bag.

Gyro (``--gyro-topic``, default ``imu/delta_theta``), chosen by the topic's type in the bag:

* ``geometry_msgs/msg/Vector3Stamped``: increments Δθ (rad), stamped at the interval end;
* ``sensor_msgs/msg/Imu``: ``angular_velocity`` rate samples (rad/s).  They are validated by
  :class:`strapdown_ros.streams.checks.StreamCheck` (range ``gyro_max_rate`` per axis, period the
  median step of the stamps), made into increments by
  :func:`strapdown_ros.streams.rate_increments.increments_from_rates` (rule ``trapezoid`` or
  ``mean``, intervals above 1.5 periods not integrated), and the increments then take the same path
  as Δθ messages (validation, gaps, missing counts).

Attitude reference (``--reference-topic``, default ``star_camera/attitude_with_covariance``
when present and its covariance is wanted, else ``star_camera/attitude``): q_ref_body of the
camera (maps child-frame vectors to the parent frame), from

* ``geometry_msgs/msg/QuaternionStamped`` or ``PoseStamped`` (no covariance);
* ``geometry_msgs/msg/PoseWithCovarianceStamped`` or ``nav_msgs/msg/Odometry``
  (``pose.covariance`` rows/columns 3–5: the rotation block, rad²);
* ``tf2_msgs/msg/TFMessage`` (``/tf``) with ``--reference-frames PARENT CHILD``: the transforms
  PARENT → CHILD, or the inverse of CHILD → PARENT when only that is recorded.

A reference without a covariance, with an all-zero one (ROS "unknown") or a zero rotation block
takes its σ from the model (``camera_sigma_xy``/``camera_sigma_z``).  A quaternion that is not
unit is normalised, a zero one dropped, a covariance that is not positive semi-definite dropped;
all counted.  The number of messages read per topic is compared with the bag's own index
(rosbags: the connections' message counts): a chunk the storage reader skipped (a corrupt
record, an unknown opcode) shows as ``unread_messages`` instead of passing silently.

rosbags is an optional extra (``tools``); only the offline tools import this module.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.typesys import get_typestore, Stores

from strapdown_ros.rotation import from_ros_xyzw, quat_conjugate
from strapdown_ros.streams.checks import nominal_period, StreamCheck, validate
from strapdown_ros.streams.rate_increments import increments_from_rates, RATE_RULES

__all__ = ['BagError', 'Accepted', 'open_reader', 'resolve_topic', 'read_bag', 'bounded',
           'bounded_list', 'GYRO_TOPIC', 'CAMERA_TOPIC', 'CAMERA_COV_TOPIC', 'DELTA_THETA_TYPE',
           'IMU_TYPE', 'REFERENCE_TYPES']

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
    'geometry_msgs/msg/PoseWithCovarianceStamped': 'pose_with_covariance',
    'nav_msgs/msg/Odometry': 'odometry',
    'tf2_msgs/msg/TFMessage': 'tf',
}
_WITH_COVARIANCE = ('pose_with_covariance', 'odometry')
MAX_LISTED = 12  # topics or frame pairs named in one error line
MAX_NAME = 80  # characters of one echoed name
MAX_PAIRS_KEPT = 64  # distinct TF frame pairs remembered for the error line


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
    Open a bag directory or file with ``rosbags`` (Jazzy type store).

    Parameters
    ----------
    path : str or Path
        rosbag2 bag directory, or a single ``.mcap`` / ``.db3`` file.

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

    """

    def __init__(self, stamps, values, gaps, check, extra_received: int = 0):
        self.stamps, self.values, self.gaps, self.check = stamps, values, gaps, check
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
        self.resyncs = check.resyncs


# --- topic selection -------------------------------------------------------------------------
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


# --- reference fixes -------------------------------------------------------------------------
def _strip(frame: str) -> str:
    return str(frame).lstrip('/')


def _process_fixes(raw, with_cov: bool, P_assumed):
    """Quaternion and covariance rules of calibrator_node, per fix: (ns, q_wxyz, P 3×3 or None)."""
    out, rejected = [], 0
    counts = {'zero_quaternion': 0, 'bad_covariance': 0,
              'normalised': 0, 'covariance_substituted': 0}
    from_messages = 0
    for ns, q, P in raw:
        norm = float(np.linalg.norm(q)) if np.all(np.isfinite(q)) else float('nan')
        if np.isfinite(norm) and norm < 1e-6:
            rejected += 1
            counts['zero_quaternion'] += 1
            continue
        if not with_cov or P is None:
            P = P_assumed
        elif np.all(np.isfinite(P)):
            P = 0.5 * (P + P.T)
            if not np.any(P):
                P = P_assumed  # all-zero covariance: "unknown" in ROS
                counts['covariance_substituted'] += 1
            elif np.min(np.linalg.eigvalsh(P)) < -1e-12 * max(np.trace(P), 1e-300):
                rejected += 1
                counts['bad_covariance'] += 1
                continue
            else:
                from_messages += 1
        finite = bool(np.isfinite(norm) and np.all(np.isfinite(P)))
        if finite and abs(norm - 1.0) > 1e-9:
            q = q / norm
            counts['normalised'] += 1
        out.append((ns, tuple(q) + tuple(np.asarray(P, dtype=float).ravel())))
    return out, rejected, counts, from_messages


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
        topics: dict = {}
        for c in reader.connections:
            if topics.setdefault(c.topic, c.msgtype) != c.msgtype:
                raise BagError(
                    f'{path}: topic {bounded(c.topic)} is recorded with two types, '
                    f'{bounded(topics[c.topic])} and {bounded(c.msgtype)}'
                )
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
        raw_g, raw_fix = [], []
        rate_absent = 0
        frames = {'gyro': set(), 'camera': set()}
        tf = _TfCollector(reference_frames) if kind == 'tf' else None
        conns = [c for c in reader.connections if c.topic in (gyro_t, ref_t)]
        for conn, _, raw in reader.messages(connections=conns):
            read[conn.topic] += 1
            try:
                msg = reader.deserialize(raw, conn.msgtype)
            except AnyReaderError as exc:
                raise BagError(
                    f'{path}: cannot deserialize a {bounded(conn.msgtype)} message on '
                    f'{bounded(conn.topic)}: '
                    f'{_first_line(exc)}'
                ) from exc
            if conn.topic == gyro_t:
                frames['gyro'].add(msg.header.frame_id)
                if rates and float(msg.angular_velocity_covariance[0]) == -1.0:
                    rate_absent += 1              # ROS: covariance[0] = -1 marks the field absent
                    continue
                v = msg.angular_velocity if rates else msg.vector
                raw_g.append((_stamp_ns(msg.header), (float(v.x), float(v.y), float(v.z))))
                continue
            if kind == 'tf':
                tf.add(msg)
                continue
            frames['camera'].add(msg.header.frame_id)
            if kind == 'quaternion':
                raw_fix.append((_stamp_ns(msg.header), _orientation(msg.quaternion), None))
            elif kind == 'pose':
                raw_fix.append((_stamp_ns(msg.header), _orientation(msg.pose.orientation), None))
            else:  # PoseWithCovarianceStamped, Odometry
                raw_fix.append(
                    (
                        _stamp_ns(msg.header),
                        _orientation(msg.pose.pose.orientation),
                        _rotation_block(msg.pose.covariance),
                    )
                )
        tf_direction = None
        if tf is not None:
            raw_fix, tf_direction = tf.fixes(path, ref_t)
            frames['camera'].add(tf.parent)
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

    # gyro: rate samples → increments, then the increments' rules with the period from the stamps
    rate_info = None
    if rates:
        if rate_absent and not raw_g:
            raise BagError(
                f'{path}: every {IMU_TYPE} message on {bounded(gyro_t)} marks angular_velocity '
                f'absent (angular_velocity_covariance[0] = -1)'
            )
        r_period = nominal_period([t for t, _ in raw_g])
        r_check = StreamCheck(
            r_period,
            max_norm=float(gyro_max_rate),
            jump_limit=max_stamp_jump,
            resync_count=resync_count,
        )
        rt, rv, _ = validate([t for t, _ in raw_g], [v for _, v in raw_g], r_check)
        inc_t, inc_v = increments_from_rates(
            rt,
            np.asarray(rv, dtype=float).reshape(-1, 3),
            rate_rule,
            1.5 * r_period if math.isfinite(r_period) else math.inf,
        )
        rate_info = {
            'received': r_check.received + rate_absent,
            'accepted': len(rt),
            'dropped': {
                'nan': r_check.nan,
                'duplicate': r_check.duplicate,
                'out_of_order': r_check.out_of_order,
                'out_of_range': r_check.out_of_range,
                'stamp_outlier': r_check.stamp_outliers,
                'marked_absent': rate_absent,
            },
            'largest_out_of_range_rad_s': r_check.largest_out_of_range,
            'intervals_not_integrated': max(len(rt) - 1 - len(inc_t), 0),
            'period_s': r_period if math.isfinite(r_period) else None,
        }
        g_stamps, g_values = [int(t) for t in inc_t], [np.array(v) for v in inc_v]
    else:
        g_stamps, g_values = [t for t, _ in raw_g], [np.array(v) for _, v in raw_g]
    g_period = nominal_period(g_stamps)
    g_check = StreamCheck(
        g_period,
        max_norm=2.0 * g_period * float(gyro_max_rate) if np.isfinite(g_period) else None,
        jump_limit=max_stamp_jump,
        resync_count=resync_count,
    )
    gyro = Accepted(*validate(g_stamps, g_values, g_check), g_check)

    # reference: the quaternion and covariance rules, then the stamp rules
    P_assumed = np.diag(np.asarray(camera_sigma, dtype=float) ** 2)
    raw_c, fix_rejected, fix_counts, from_messages = _process_fixes(raw_fix, with_cov, P_assumed)
    c_check = StreamCheck(
        np.inf, jump_limit=max(max_stamp_jump, 3600.0), resync_count=resync_count
    )
    ct, cv, cgaps = validate([t for t, _ in raw_c], [v for _, v in raw_c], c_check)
    cam = Accepted(
        ct,
        [(np.array(v[:4]), np.array(v[4:]).reshape(3, 3)) for v in cv],
        cgaps,
        c_check,
        fix_rejected,
    )
    n_model = len(raw_c) - from_messages
    ref_cov = (
        'from_model' if from_messages == 0 else ('from_messages' if n_model == 0 else 'mixed')
    )
    frames_used = None if tf is None else {'parent': tf.parent, 'child': tf.child,
                                           'transform': tf_direction}
    clip = {'parameter': 'gyro_max_rate', 'limit': float(gyro_max_rate), 'unit': 'rad/s',
            'count': (rate_info['dropped']['out_of_range'] if rate_info else 0)
            + g_check.out_of_range,
            'largest': min(max(rate_info['largest_out_of_range_rad_s'] if rate_info else 0.0,
                               g_check.largest_out_of_range / g_period
                               if np.isfinite(g_period) and g_period > 0 else 0.0),
                           1e308)}                # a 1e308 increment: finite in the JSON
    return {'gyro_clip': clip,
            'gyro_topic': gyro_t, 'camera_topic': ref_t, 'camera_covariance_from_bag': with_cov,
            'gyro': gyro, 'camera': cam, 'camera_fixes': fix_counts, 'gyro_period_s': g_period,
            'frames': {k: sorted(v) for k, v in frames.items()}, 'gyro_type': gyro_type,
            'gyro_input': 'rates' if rates else 'delta_theta',
            'rate_rule': rate_rule if rates else None, 'rate_samples': rate_info,
            'reference_type': ref_type, 'reference_frames': frames_used,
            'reference_covariance': ref_cov, 'reference_covariance_from_model': n_model,
            'unread_messages': unread, 'messages_in_bag_index': expected}
