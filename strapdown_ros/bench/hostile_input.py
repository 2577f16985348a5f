"""
Hostile input for every node and tool: a clean recording and one hostile message of each kind.

:func:`clean_recording` simulates a short recording with exact truth (holds and turns about the
three body axes, an injected gyro bias, a star camera with a known boresight);
:data:`KINDS` lists the hostile messages of issue 27, each with the stream it goes into and the
reason every surface must count it under; :func:`streams_with` puts one into the clean streams
and :func:`write_bag` writes them as a rosbag2 bag.  The hostile message is *added* to the clean
streams (none of the clean messages is touched, except where the kind is a property of a message:
its frame id), so a surface that drops and counts it must give the clean run's estimates.
The runners are :mod:`strapdown_ros.bench.hostile_tools` (offline tools) and
:mod:`strapdown_ros.bench.ros.hostile_nodes` (nodes); ``hostile_bench`` runs them all.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from strapdown_ros.motion.profiles import PiecewiseRateProfile, Segment
from strapdown_ros.rotation import to_ros_xyzw
from strapdown_ros.sensors.model import IntegratingSensor, SensorErrorModel
from strapdown_ros.sensors.star_camera import ARCSEC, StarCameraModel

__all__ = ['Kind', 'KINDS', 'Recording', 'Message', 'clean_recording', 'streams_with',
           'write_bag', 'kind_named', 'BETA', 'BIAS', 'FRAME', 'REFERENCE_FRAME',
           'GYRO_TOPIC', 'ACCEL_TOPIC', 'REFERENCE_TOPIC', 'LONG_FRAME_LENGTH']

#: the true boresight β = (ψ, ϑ, γ), rad
BETA = np.radians([40.0, -25.0, 120.0])
#: the injected gyro bias, rad/s
BIAS = np.array([2.0e-5, -1.0e-5, 1.5e-5])
FRAME, REFERENCE_FRAME = 'imu_link', 'gcrs'
GYRO_TOPIC = '/imu/delta_theta'
ACCEL_TOPIC = '/imu/delta_velocity'
REFERENCE_TOPIC = '/star_camera/attitude_with_covariance'
#: characters of the long frame id of the ``long_frame`` kind
LONG_FRAME_LENGTH = 100_000
_NS = 1_000_000_000
ORIGIN_NS = 1_700_000_000 * _NS             # epoch-like stamps


@dataclass(frozen=True)
class Kind:
    """
    One kind of hostile message.

    Attributes
    ----------
    name : str
        Its name (``nan``, ``future_stamp``, ...).
    stream : str
        ``gyro`` (a Δθ message) or ``reference`` (an attitude fix).
    family : str
        ``value``, ``covariance``, ``stamp``, ``frame`` or ``message``.
    reason : str
        The reason it is counted under (``nan``, ``out_of_range``, ``not_unit``,
        ``zero_quaternion``, ``bad_covariance``, ``stamp_outlier``, ``duplicate``, ``frame``,
        ``wrong_type``, ``empty``).

    """

    name: str
    stream: str
    family: str
    reason: str

    @property
    def label(self) -> str:
        """Return ``stream:name``."""
        return f'{self.stream}:{self.name}'


def _kinds() -> tuple[Kind, ...]:
    out = []
    for stream in ('gyro', 'reference'):
        bad_value = 'out_of_range' if stream == 'gyro' else 'not_unit'
        out += [Kind('nan', stream, 'value', 'nan'), Kind('inf', stream, 'value', 'nan'),
                Kind('plus_1e308', stream, 'value', bad_value),
                Kind('minus_1e308', stream, 'value', bad_value)]
    out += [Kind('scaled_1e200', 'reference', 'value', 'not_unit'),
            Kind('zero_quaternion', 'reference', 'value', 'zero_quaternion'),
            Kind('singular_covariance', 'reference', 'covariance', 'bad_covariance'),
            Kind('negative_covariance', 'reference', 'covariance', 'bad_covariance'),
            Kind('huge_covariance', 'reference', 'covariance', 'bad_covariance')]
    for stream in ('gyro', 'reference'):
        out += [Kind('zero_stamp', stream, 'stamp', 'stamp_outlier'),
                Kind('future_stamp', stream, 'stamp', 'stamp_outlier'),
                Kind('past_stamp', stream, 'stamp', 'stamp_outlier'),
                Kind('duplicate_stamp', stream, 'stamp', 'duplicate'),
                Kind('stray_frame', stream, 'frame', 'frame'),
                Kind('long_frame', stream, 'frame', 'frame'),
                Kind('wrong_type', stream, 'message', 'wrong_type')]
    out.append(Kind('empty_topic', 'reference', 'message', 'empty'))
    return tuple(out)


#: every hostile kind of issue 27 (values, covariances, stamps, frames, messages)
KINDS: tuple[Kind, ...] = _kinds()


def kind_named(label: str) -> Kind:
    """
    Return the kind of a label ``stream:name``.

    Parameters
    ----------
    label : str
        E.g. ``reference:future_stamp``.

    Returns
    -------
    Kind
        The kind.

    """
    for k in KINDS:
        if k.label == label:
            return k
    raise ValueError(f'no hostile kind {label!r}')


@dataclass(frozen=True)
class Message:
    """
    One message of a stream.

    Attributes
    ----------
    stamp_ns : int
        Header stamp, ns.
    value : tuple
        Gyro: Δθ (3,), rad.  Reference: (q_wxyz (4,), covariance (3, 3) rad²).
    frame : str
        Header frame id.
    wrong_type : bool
        Written as a message of another type on the same topic.
    log_ns : int or None
        When it is received (the bag time; None: its stamp): a message with a wrong stamp
        arrives in its place in the stream.

    """

    stamp_ns: int
    value: tuple
    frame: str
    wrong_type: bool = False
    log_ns: int | None = None

    @property
    def received_ns(self) -> int:
        """Return when the message is received: ``log_ns``, else its stamp."""
        return self.stamp_ns if self.log_ns is None else self.log_ns


@dataclass
class Recording:
    """
    The streams of a recording: gyro Δθ, accelerometer Δv and attitude fixes.

    Attributes
    ----------
    gyro, accel, reference : list of Message
        The messages in stamp order (the hostile one in its place).
    rate_hz : float
        Gyro and accelerometer rate, Hz.
    camera_interval : float
        Time between fixes, s.
    hostile : Kind or None
        The hostile kind put in (None: the clean recording).
    hostile_index : int
        Where it went (its position in its stream).

    """

    gyro: list
    accel: list
    reference: list
    rate_hz: float
    camera_interval: float
    hostile: Kind | None = None
    hostile_index: int = -1
    truth: dict = field(default_factory=dict)


def clean_recording(seed: int = 0, rate_hz: float = 100.0, camera_interval: float = 0.5,
                    hold: float = 1.0, turn: float = 1.5) -> Recording:
    """
    Simulate the clean recording: holds and ±20° turns about z, x, y; bias; a star camera.

    Parameters
    ----------
    seed : int
        Seed of the gyro and camera noise.
    rate_hz : float
        IMU rate, Hz.
    camera_interval : float
        Time between fixes, s.
    hold, turn : float
        Length of each hold and turn, s.

    Returns
    -------
    Recording
        The streams; ``truth`` holds the boresight and the bias.

    """
    segs = [Segment(hold)]
    for axis, angle in ((2, 20.0), (0, -20.0), (1, 20.0), (2, -20.0), (0, 20.0), (1, -20.0)):
        rate = np.zeros(3)
        rate[axis] = np.radians(angle) / turn
        segs += [Segment(turn, rate), Segment(hold)]
    profile = PiecewiseRateProfile(segs, gravity=(0.0, 0.0, 9.80665))
    n = int(round(profile.duration * rate_hz))
    gyro = IntegratingSensor(profile, 'gyro', rate_hz,
                             SensorErrorModel(bias=BIAS, random_walk=1e-6), seed=seed)
    t, dth, _ = gyro.sample(n)
    acc = IntegratingSensor(profile, 'accel', rate_hz, SensorErrorModel(random_walk=1e-4),
                            seed=seed + 1)
    ta, dv, _ = acc.sample(n)
    cam = StarCameraModel(boresight=BETA, interval=camera_interval, seed=seed + 2,
                          sigma=np.array([0.6, 0.6, 6.0]) * ARCSEC)
    fixes = cam.fixes(profile, int(profile.duration / camera_interval) - 1)

    def ns(x):
        return ORIGIN_NS + int(round(float(x) * _NS))
    return Recording(
        gyro=[Message(ns(a), tuple(float(c) for c in v), FRAME) for a, v in zip(t, dth)],
        accel=[Message(ns(a), tuple(float(c) for c in v), FRAME) for a, v in zip(ta, dv)],
        reference=[Message(ns(fx.stamp), (np.asarray(fx.attitude, dtype=float),
                                          np.asarray(fx.covariance, dtype=float)),
                           REFERENCE_FRAME) for fx in fixes],
        rate_hz=float(rate_hz), camera_interval=float(camera_interval),
        truth={'boresight': BETA.copy(), 'bias': BIAS.copy()})


def _hostile_value(kind: Kind, good: Message):
    """Return the hostile value of a value or covariance kind, made from a good message."""
    if kind.stream == 'gyro':
        v = {'nan': np.nan, 'inf': np.inf, 'plus_1e308': 1e308, 'minus_1e308': -1e308}[kind.name]
        return (v, good.value[1], good.value[2])
    q, P = good.value
    q = np.array(q, dtype=float)
    P = np.array(P, dtype=float)
    if kind.name in ('nan', 'inf', 'plus_1e308', 'minus_1e308'):
        q[1] = {'nan': np.nan, 'inf': np.inf, 'plus_1e308': 1e308, 'minus_1e308': -1e308}[
            kind.name]
    elif kind.name == 'scaled_1e200':
        q = q * 1e200
    elif kind.name == 'zero_quaternion':
        q = np.zeros(4)
    elif kind.name == 'singular_covariance':
        P = np.diag([np.diag(P)[0], np.diag(P)[1], 0.0])
    elif kind.name == 'negative_covariance':
        P = np.diag([np.diag(P)[0], -np.diag(P)[1], np.diag(P)[2]])
    elif kind.name == 'huge_covariance':
        P = np.eye(3) * 1e308
    return (q, P)


def streams_with(rec: Recording, kind: Kind | None, index: int,
                 frames_used: bool = True) -> Recording:
    """
    Return the recording with one hostile message of ``kind`` added near position ``index``.

    The hostile message is an extra message stamped half a period after the good message at
    ``index`` of its stream (value, covariance and type kinds), a copy of it
    (``duplicate_stamp``), or an extra one stamped 0, 100 s ahead or 100 s back (received in
    its place).  A frame kind renames the frame of the good message at ``index`` where the
    surface uses a message in another frame (the tools read a recording in its own frames),
    else it adds an extra message in that frame (a node rejects it).  ``empty_topic`` empties
    the reference stream.

    Parameters
    ----------
    rec : Recording
        The clean recording.
    kind : Kind or None
        The hostile kind (None: the clean recording).
    index : int
        Position in the stream (clipped to its middle).
    frames_used : bool
        The surface uses a message in a stray frame (the tools) rather than rejecting it.

    Returns
    -------
    Recording
        A new recording.

    """
    if kind is None:
        return rec
    name = 'gyro' if kind.stream == 'gyro' else 'reference'
    msgs = list(getattr(rec, name))
    if kind.name == 'empty_topic':
        return replace(rec, reference=[], hostile=kind, hostile_index=0)
    index = int(np.clip(index, 5, len(msgs) - 6))
    good = msgs[index]
    step = msgs[index + 1].stamp_ns - good.stamp_ns
    mid = good.stamp_ns + step // 2
    frame = 'stray_frame' if kind.name == 'stray_frame' else 'x' * LONG_FRAME_LENGTH
    if kind.family in ('value', 'covariance'):
        bad = Message(mid, _hostile_value(kind, good), good.frame)
    elif kind.name == 'duplicate_stamp':
        bad = good
    elif kind.family == 'stamp':
        ns = {'zero_stamp': 0, 'future_stamp': good.stamp_ns + 100 * _NS,
              'past_stamp': good.stamp_ns - 100 * _NS}[kind.name]
        bad = Message(ns, good.value, good.frame, log_ns=mid)
    elif kind.family == 'frame':
        if frames_used:
            msgs[index] = replace(good, frame=frame)
            return replace(rec, **{name: msgs}, hostile=kind, hostile_index=index)
        bad = Message(mid, good.value, frame)
    else:                                       # wrong_type
        bad = Message(mid, good.value, good.frame, wrong_type=True)
    msgs.insert(index + 1, bad)
    return replace(rec, **{name: msgs}, hostile=kind, hostile_index=index + 1)


# ------------------------------------------------------------------ bags
def _types():
    from rosbags.typesys import get_typestore, Stores

    store = get_typestore(Stores.ROS2_JAZZY)
    return store, store.types


def _header(T, ns: int, frame: str):
    return T['std_msgs/msg/Header'](
        stamp=T['builtin_interfaces/msg/Time'](sec=int(ns // _NS), nanosec=int(ns % _NS)),
        frame_id=frame)


def _vector(T, ns, frame, v):
    return T['geometry_msgs/msg/Vector3Stamped'](
        header=_header(T, ns, frame),
        vector=T['geometry_msgs/msg/Vector3'](x=float(v[0]), y=float(v[1]), z=float(v[2])))


def _quaternion(T, q):
    x, y, z, w = (float(c) for c in to_ros_xyzw(np.asarray(q, dtype=float)))
    return T['geometry_msgs/msg/Quaternion'](x=x, y=y, z=z, w=w)


def _pose(T, ns, frame, q, P):
    cov = np.zeros((6, 6))
    cov[0, 0] = cov[1, 1] = cov[2, 2] = 1e9
    cov[3:, 3:] = np.asarray(P, dtype=float)
    pose = T['geometry_msgs/msg/Pose'](position=T['geometry_msgs/msg/Point'](x=0.0, y=0.0, z=0.0),
                                       orientation=_quaternion(T, q))
    return T['geometry_msgs/msg/PoseWithCovarianceStamped'](
        header=_header(T, ns, frame),
        pose=T['geometry_msgs/msg/PoseWithCovariance'](pose=pose, covariance=cov.reshape(36)))


def _quaternion_stamped(T, ns, frame, q):
    return T['geometry_msgs/msg/QuaternionStamped'](header=_header(T, ns, frame),
                                                    quaternion=_quaternion(T, q))


def write_bag(path, rec: Recording, accel: bool = True) -> Path:
    """
    Write a recording as a rosbag2 bag (MCAP), messages in stamp order per topic.

    A ``wrong_type`` message is written on the same topic through a second connection of another
    type (QuaternionStamped on the gyro topic, Vector3Stamped on the reference topic).

    Parameters
    ----------
    path : str or Path
        The bag directory (must not exist).
    rec : Recording
        The streams.
    accel : bool
        Also write the Δv stream (``sins_bag``).

    Returns
    -------
    Path
        The bag.

    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    store, T = _types()
    out = []                                    # (bag time, topic, type, message)
    for m in rec.gyro:
        if m.wrong_type:
            q = np.array([0.5, 0.5, 0.5, 0.5])
            out.append((m.received_ns, GYRO_TOPIC, 'geometry_msgs/msg/QuaternionStamped',
                        _quaternion_stamped(T, m.stamp_ns, m.frame, q)))
        else:
            out.append((m.received_ns, GYRO_TOPIC, 'geometry_msgs/msg/Vector3Stamped',
                        _vector(T, m.stamp_ns, m.frame, m.value)))
    if accel:
        for m in rec.accel:
            out.append((m.received_ns, ACCEL_TOPIC, 'geometry_msgs/msg/Vector3Stamped',
                        _vector(T, m.stamp_ns, m.frame, m.value)))
    for m in rec.reference:
        if m.wrong_type:
            out.append((m.received_ns, REFERENCE_TOPIC, 'geometry_msgs/msg/Vector3Stamped',
                        _vector(T, m.stamp_ns, m.frame, (0.1, 0.2, 0.3))))
        else:
            out.append((m.received_ns, REFERENCE_TOPIC,
                        'geometry_msgs/msg/PoseWithCovarianceStamped',
                        _pose(T, m.stamp_ns, m.frame, *m.value)))
    order = {GYRO_TOPIC: 0, ACCEL_TOPIC: 1, REFERENCE_TOPIC: 2}
    out.sort(key=lambda x: (x[0], order[x[1]]))    # stable: a stream keeps its own order
    path = Path(path)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {}
        for topic, typ in ((GYRO_TOPIC, 'geometry_msgs/msg/Vector3Stamped'),
                           (REFERENCE_TOPIC, 'geometry_msgs/msg/PoseWithCovarianceStamped')):
            conns[(topic, typ)] = w.add_connection(topic, typ, typestore=store)
        for ns, topic, typ, m in out:
            if (topic, typ) not in conns:
                conns[(topic, typ)] = w.add_connection(topic, typ, typestore=store)
            w.write(conns[(topic, typ)], int(ns), store.serialize_cdr(m, typ))
    return path
