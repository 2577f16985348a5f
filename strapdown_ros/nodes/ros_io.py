"""
ROS I/O shared by the nodes: QoS, stamps, messages, raw stream decoding, logging, diagnostics.

The node modules and this room are the only places that import rclpy and message packages.
Quaternions cross the edge here: ROS messages carry ``x, y, z, w``; the core uses scalar-first
``[w, x, y, z]`` (:mod:`strapdown_ros.rotation`).  A node's parameters are declared by
:mod:`strapdown_ros.nodes.ros_params`, its process run by :mod:`strapdown_ros.nodes.ros_process`.
"""
from __future__ import annotations

import time
from typing import Any, Sequence

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import (PoseWithCovarianceStamped, Quaternion, QuaternionStamped, Vector3,
                               Vector3Stamped)
import numpy as np
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.qos_overriding_options import QoSOverridingOptions
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu

from strapdown_ros.streams import cdr


# --- QoS ---------------------------------------------------------------------------
def stream_qos(depth: int = 500) -> QoSProfile:
    """
    Sensor-data QoS (best effort, volatile) for high-rate streams.

    The history is deeper than rclpy's ``qos_profile_sensor_data`` (5) so that bursts
    from a faster-than-real-time simulator are queued rather than overwritten.
    """
    return QoSProfile(reliability=ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.VOLATILE,
                      history=HistoryPolicy.KEEP_LAST, depth=depth)


#: Stream and camera topics take the standard ROS QoS override parameters, e.g.
#: ``-p qos_overrides./imu/delta_theta.subscription.reliability:=reliable`` (history, depth,
#: reliability; the topic name fully qualified).  ``/diagnostics`` and the latched outputs have
#: fixed QoS.
QOS_OVERRIDES = QoSOverridingOptions.with_default_policies()

DIAGNOSTICS_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.VOLATILE,
                             history=HistoryPolicy.KEEP_LAST, depth=10)


# --- raw (serialized) stream messages --------------------------------------------------
def decode_vector3_stamped(data: bytes) -> tuple[int, tuple[float, float, float], str] | None:
    """
    ``(stamp_ns, (x, y, z), frame_id)`` of a serialized geometry_msgs/Vector3Stamped.

    The high-rate increment streams are subscribed raw (``raw=True``): rclpy then skips building
    four Python message objects per message (about 18 µs), and the node reads the few fields it
    needs from the bytes (:mod:`strapdown_ros.streams.cdr`, shared with ``sins_bag``).  Any other
    encoding than plain little-endian CDR is handed to rclpy's own deserializer, so nothing is
    misread (test/streams/test_checks_fuzz.py checks both against rclpy's serializer).  None when
    the bytes are not a Vector3Stamped at all (the caller counts and drops them).
    """
    got = cdr.vector3_stamped(data)
    if got is not None:
        return got
    try:
        m = deserialize_message(data, Vector3Stamped)
    except Exception:                                  # noqa: BLE001 - malformed bytes
        return None
    v = m.vector
    return stamp_to_ns(m.header.stamp), (v.x, v.y, v.z), m.header.frame_id


def decode_imu(data: bytes):
    """
    ``(stamp_ns, angular_velocity, linear_acceleration | None, frame_id)`` of a serialized
    sensor_msgs/Imu (the ``imu/data_raw`` input of ``gyro_input: imu``), read from the bytes as
    :func:`decode_vector3_stamped` reads a Vector3Stamped (rclpy's deserialization of an Imu costs
    tens of µs); other encodings through rclpy's deserializer.  linear_acceleration is None when
    the message has none (REP-145: linear_acceleration_covariance[0] = −1).  None when the bytes
    are not an Imu at all (the caller counts and drops them).
    """
    got = cdr.imu(data)
    if got is not None:
        return got
    try:
        m = deserialize_message(data, Imu)
    except Exception:                                  # noqa: BLE001 - malformed bytes
        return None
    w, a = m.angular_velocity, m.linear_acceleration
    accel = None if m.linear_acceleration_covariance[0] == -1.0 else (a.x, a.y, a.z)
    return stamp_to_ns(m.header.stamp), (w.x, w.y, w.z), accel, m.header.frame_id


def stated_rate_variance(last_imu) -> str:
    """
    What the latest Imu says of its rate noise, for /diagnostics (the nodes do not use it:
    their covariance comes from the model's gyro_random_walk): the diagonal of
    angular_velocity_covariance, (rad/s)², as text; ``unknown`` when it is all zero (the ROS
    convention), ``not provided`` when element 0 is −1, ``none received`` before any Imu.
    ``last_imu``: the serialized bytes of the raw subscription, or a message object.
    """
    if last_imu is None:
        return 'none received'
    if isinstance(last_imu, (bytes, bytearray, memoryview)):
        cov = cdr.imu_rate_covariance(last_imu)
        if cov is None:
            try:
                cov = tuple(deserialize_message(last_imu, Imu).angular_velocity_covariance)
            except Exception:                          # noqa: BLE001 - malformed bytes
                return 'undecodable'
    else:
        cov = tuple(last_imu.angular_velocity_covariance)
    if cov[0] == -1.0:
        return 'not provided'
    if not any(cov):
        return 'unknown'
    return ', '.join(f'{cov[k]:.6g}' for k in (0, 4, 8))


# --- camera and calibration messages ----------------------------------------------------
UNKNOWN_POSITION_VARIANCE = 1e9


def camera_qos(depth: int) -> QoSProfile:
    """Reliable, volatile, keep-last: for rare, important messages (camera fixes)."""
    return QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                      history=HistoryPolicy.KEEP_LAST, depth=int(depth))


def latched_qos() -> QoSProfile:
    """Reliable, transient-local, depth 1: the latest value reaches late subscribers."""
    return QoSProfile(reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL,
                      history=HistoryPolicy.KEEP_LAST, depth=1)


def pose_with_covariance(stamp, frame_id: str, q_wxyz,
                         rotation_covariance) -> PoseWithCovarianceStamped:
    """
    Attitude-only PoseWithCovarianceStamped: position 0 with :data:`UNKNOWN_POSITION_VARIANCE`
    on its diagonal, rotation block (rows/cols 3..5) = ``rotation_covariance`` (3×3, rad²).
    """
    m = PoseWithCovarianceStamped()
    m.header.stamp = stamp
    m.header.frame_id = frame_id
    m.pose.pose.orientation = quaternion_msg(q_wxyz)
    cov = np.zeros((6, 6))
    cov[0, 0] = cov[1, 1] = cov[2, 2] = UNKNOWN_POSITION_VARIANCE
    P = np.asarray(rotation_covariance, dtype=float).reshape(3, 3)
    cov[3:, 3:] = 0.5 * (P + P.T)
    m.pose.covariance = [float(c) for c in cov.reshape(36)]
    return m


def rotation_block(msg: PoseWithCovarianceStamped) -> np.ndarray:
    """The 3×3 rotation block (rows/cols 3..5) of a PoseWithCovariance covariance."""
    return np.asarray(msg.pose.covariance, dtype=float).reshape(6, 6)[3:, 3:].copy()


# --- time ----------------------------------------------------------------------------
def stamp_to_ns(stamp: Time) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def ns_to_stamp(ns: int) -> Time:
    ns = int(ns)
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def set_stamp(stamp: Time, ns) -> None:
    """Write ``ns`` into an existing stamp (no new message: the per-update publishing path)."""
    stamp.sec, stamp.nanosec = divmod(int(ns), 1_000_000_000)


def seconds_to_stamp(t: float) -> Time:
    return ns_to_stamp(int(round(t * 1e9)))


# --- messages -----------------------------------------------------------------------------
def vector3(v: Sequence[float]) -> Vector3:
    return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def quaternion_msg(q_wxyz: Sequence[float]) -> Quaternion:
    """Core scalar-first quaternion → ROS message (x, y, z, w)."""
    return Quaternion(w=float(q_wxyz[0]), x=float(q_wxyz[1]), y=float(q_wxyz[2]),
                      z=float(q_wxyz[3]))


def quaternion_from_msg(q: Quaternion) -> np.ndarray:
    """ROS quaternion → core scalar-first array."""
    return np.array([q.w, q.x, q.y, q.z], dtype=float)


def vector3_stamped(stamp: Time, frame_id: str, v) -> Vector3Stamped:
    m = Vector3Stamped()
    m.header.stamp = stamp
    m.header.frame_id = frame_id
    m.vector = vector3(v)
    return m


def quaternion_stamped(stamp: Time, frame_id: str, q_wxyz) -> QuaternionStamped:
    m = QuaternionStamped()
    m.header.stamp = stamp
    m.header.frame_id = frame_id
    m.quaternion = quaternion_msg(q_wxyz)
    return m


# --- logging -----------------------------------------------------------------------------
#: longest text a node logs or puts in a diagnostic message, characters (echoed input is bounded)
MAX_TEXT = 400


def bounded(text: str, limit: int = MAX_TEXT) -> str:
    """``text`` cut to ``limit`` characters (an ellipsis marks the cut)."""
    text = str(text)
    return text if len(text) <= limit else text[:limit - 1] + '…'


class NodeLog:
    """
    The one logging helper of the nodes: ``log(level, text, throttle=0.0, key=None)``.

    rclpy's logger keeps one context per call site (function, file, line) and raises
    ``ValueError('Logger severity cannot be changed between calls.')`` when one call site logs
    at another severity than before, and likewise when its throttle changes.  Every severity
    here has its own call site, and throttling is done here (``throttle`` wall seconds per
    ``key``, default the text), never through rclpy's filters, so any sequence of levels and
    throttles at one caller is safe.  Texts are bounded to :data:`MAX_TEXT` characters.

    Parameters
    ----------
    logger
        The node's rclpy logger (``node.get_logger()``).
    """

    LEVELS = ('debug', 'info', 'warn', 'error')

    def __init__(self, logger):
        self._logger = logger
        self._clock = time.monotonic
        self._last: dict[str, float] = {}

    def __call__(self, level: str, text: str, throttle: float = 0.0,
                 key: str | None = None) -> bool:
        """
        Log ``text`` at ``level`` (debug, info, warn or error); returns False when throttled.

        Parameters
        ----------
        level : str
            ``debug``, ``info``, ``warn`` (or ``warning``) or ``error``.
        text : str
            The message (bounded to :data:`MAX_TEXT` characters).
        throttle : float
            Minimum wall seconds between two messages of the same ``key`` (0: every one).
        key : str, optional
            What the throttle counts (default: the text).
        """
        if level == 'warning':
            level = 'warn'
        if level not in self.LEVELS:
            raise ValueError(f"unknown log level {level!r}; valid: {', '.join(self.LEVELS)}")
        if throttle > 0:
            k = key or text
            now = self._clock()
            if now - self._last.get(k, -float('inf')) < throttle:
                return False
            self._last[k] = now
        text = bounded(text)
        if level == 'error':                      # one call site per severity (see the class doc)
            self._logger.error(text)
        elif level == 'warn':
            self._logger.warning(text)
        elif level == 'info':
            self._logger.info(text)
        else:
            self._logger.debug(text)
        return True

    def error(self, text: str, throttle: float = 0.0, key: str | None = None) -> bool:
        """``log("error", ...)``."""
        return self('error', text, throttle, key)

    def warn(self, text: str, throttle: float = 0.0, key: str | None = None) -> bool:
        """``log("warn", ...)``."""
        return self('warn', text, throttle, key)

    def info(self, text: str, throttle: float = 0.0, key: str | None = None) -> bool:
        """``log("info", ...)``."""
        return self('info', text, throttle, key)


# --- diagnostics -------------------------------------------------------------------------
def diagnostic_array(stamp: Time, name: str, hardware_id: str, level: int, message: str,
                     values: dict[str, Any]) -> DiagnosticArray:
    st = DiagnosticStatus(level=bytes([level]) if isinstance(level, int) else level, name=name,
                          message=message, hardware_id=hardware_id,
                          values=[KeyValue(key=str(k), value=_fmt(v)) for k, v in values.items()])
    arr = DiagnosticArray()
    arr.header.stamp = stamp
    arr.status = [st]
    return arr


def _fmt(v) -> str:
    if isinstance(v, float):
        return f'{v:.6g}'
    return str(v)


OK, WARN, ERROR = 0, 1, 2


class Conditions:
    """
    The current conditions of a node's /diagnostics status: the level is the worst of all of
    them, and the message lists every one, worst first (in the order added within a level),
    bounded to ``limit`` characters with the number of conditions cut off.  A lower-level
    condition never masks a higher one (an undecodable message does not hide a gyro gap).

    Parameters
    ----------
    limit : int
        Longest message, characters.
    """

    def __init__(self, limit: int = MAX_TEXT):
        self.limit = int(limit)
        self.items: list[tuple[int, str]] = []

    def add(self, level: int, text: str) -> None:
        """One condition at ``level`` (:data:`OK`, :data:`WARN` or :data:`ERROR`)."""
        self.items.append((int(level), str(text)))

    @property
    def level(self) -> int:
        """The worst level of all conditions (:data:`OK` when there are none)."""
        return max((lv for lv, _ in self.items), default=OK)

    def message(self, ok_text: str = 'ok') -> str:
        """
        Every condition's text, worst first, joined by ``; `` and bounded; ``ok_text`` when
        there is none.
        """
        texts = [t for _, t in sorted(self.items, key=lambda it: -it[0])]
        if not texts:
            return bounded(ok_text, self.limit)
        out = texts[0]
        for k, t in enumerate(texts[1:], 1):
            more = f' (+{len(texts) - k} more)'
            if len(out) + 2 + len(t) + len(more) > self.limit:
                return bounded(out, self.limit - len(more)) + more
            out += '; ' + t
        return bounded(out, self.limit)


# --- simulators ------------------------------------------------------------------------------
class PacedSimulation:
    """
    Mixin for the simulator nodes: a wall timer calls :meth:`_tick`, which advances the
    simulated time to ``time_scale`` × the wall time since the first tick (capped at
    ``end_time``) through the node's ``_advance_to(target)``, and calls ``_on_finished()`` once.
    Nothing downstream sees the wall clock: every stamp is simulated time.  Setting
    ``_wall_start = None`` restarts the pacing at the next tick (used after discovery).  With
    ``wait_for_subscribers`` = N > 0 the clock starts at the first tick that sees N subscribers
    (``_subscriber_count()``), so that consumers started as separate processes lose nothing.
    """

    _wall_start = None
    finished = False

    def _tick(self):
        if self.finished:
            return
        now = time.monotonic()
        if self._wall_start is None:
            if self._subscriber_count() < int(self.p.get('wait_for_subscribers', 0)):
                return                                   # the clock has not started yet
            self._wall_start = now
        target = min((now - self._wall_start) * float(self.p['time_scale']), self.end_time)
        self._advance_to(target)
        if target >= self.end_time:
            self.finished = True
            self._on_finished()
