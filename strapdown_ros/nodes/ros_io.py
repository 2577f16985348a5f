"""
ROS I/O shared by the nodes: QoS, stamps, messages, raw stream decoding, simulator pacing.

The node modules and this room are the only places that import rclpy and message packages.
Quaternions cross the edge here: ROS messages carry ``x, y, z, w``; the core uses scalar-first
``[w, x, y, z]`` (:mod:`strapdown_ros.rotation`).  A node's parameters are declared by
:mod:`strapdown_ros.nodes.ros_params`, its process run by :mod:`strapdown_ros.nodes.ros_process`,
its log and /diagnostics status made by :mod:`strapdown_ros.nodes.ros_status`.
"""
from __future__ import annotations

import time
from typing import Sequence

from builtin_interfaces.msg import Time
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
    Return the sensor-data QoS (best effort, volatile) of the high-rate streams.

    The history is deeper than rclpy's ``qos_profile_sensor_data`` (5) so that bursts
    from a faster-than-real-time simulator are queued rather than overwritten.

    Parameters
    ----------
    depth : int
        History depth, messages (keep-last).

    Returns
    -------
    QoSProfile
        Best effort, volatile, keep-last ``depth``.

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
    Decode a serialized geometry_msgs/Vector3Stamped.

    The high-rate increment streams are subscribed raw (``raw=True``): rclpy then skips building
    four Python message objects per message, and the node reads the few fields it needs from the
    bytes (:mod:`strapdown_ros.streams.cdr`, shared with ``sins_bag``).  Any other encoding than
    plain little-endian CDR is handed to rclpy's own deserializer, so nothing is misread
    (test/streams/test_checks_fuzz.py checks both against rclpy's serializer).  None when the bytes
    are not a Vector3Stamped at all (the caller counts and drops them).

    Parameters
    ----------
    data : bytes
        The serialized message (a raw subscription's callback argument).

    Returns
    -------
    (int, (float, float, float), str) or None
        Header stamp (ns), the vector, header.frame_id; None when undecodable.

    """
    got = cdr.vector3_stamped(data, exact=True)
    if got is not None:
        return got
    if len(data) >= 2 and data[0] == 0 and data[1] == 1:
        return None                    # little-endian CDR of another layout: not this type
    try:
        m = deserialize_message(data, Vector3Stamped)
    except Exception:                                  # malformed bytes
        return None
    v = m.vector
    return stamp_to_ns(m.header.stamp), (v.x, v.y, v.z), m.header.frame_id


def decode_imu(data: bytes):
    """
    Decode a serialized sensor_msgs/Imu (the ``imu/data_raw`` input of ``gyro_input: imu``).

    Read from the bytes as :func:`decode_vector3_stamped` reads a Vector3Stamped (rclpy's
    deserialization of an Imu costs more than the rest of the callback); other encodings through
    rclpy's deserializer.

    Parameters
    ----------
    data : bytes
        The serialized message.

    Returns
    -------
    tuple or None
        ``(stamp_ns, angular_velocity, linear_acceleration, frame_id)``: rad/s and m/s², body
        axes; linear_acceleration is None when the message has none (REP-145:
        linear_acceleration_covariance[0] = −1).  None when the bytes are not an Imu at all
        (the caller counts and drops them).

    """
    got = cdr.imu(data)
    if got is not None:
        return got
    try:
        m = deserialize_message(data, Imu)
    except Exception:                                  # malformed bytes
        return None
    w, a = m.angular_velocity, m.linear_acceleration
    accel = None if m.linear_acceleration_covariance[0] == -1.0 else (a.x, a.y, a.z)
    return stamp_to_ns(m.header.stamp), (w.x, w.y, w.z), accel, m.header.frame_id


def stated_rate_variance(last_imu) -> str:
    """
    Describe what the latest Imu says of its rate noise, for /diagnostics.

    The nodes do not use it: their covariance comes from the model's gyro_random_walk.

    Parameters
    ----------
    last_imu : bytes or sensor_msgs.msg.Imu or None
        The serialized bytes of the raw subscription, or a message object.

    Returns
    -------
    str
        The diagonal of angular_velocity_covariance, (rad/s)², as text; ``unknown`` when it is
        all zero (the ROS convention), ``not provided`` when element 0 is −1, ``none received``
        before any Imu, ``undecodable`` for bytes that are not an Imu.

    """
    if last_imu is None:
        return 'none received'
    if isinstance(last_imu, (bytes, bytearray, memoryview)):
        cov = cdr.imu_rate_covariance(last_imu)
        if cov is None:
            try:
                cov = tuple(deserialize_message(last_imu, Imu).angular_velocity_covariance)
            except Exception:                          # malformed bytes
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
    """
    Return the QoS of rare, important messages (camera fixes): reliable, volatile, keep-last.

    Parameters
    ----------
    depth : int
        History depth, messages.

    Returns
    -------
    QoSProfile
        The profile.

    """
    return QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                      history=HistoryPolicy.KEEP_LAST, depth=int(depth))


def latched_qos() -> QoSProfile:
    """Return the latched QoS (reliable, transient-local, depth 1) for late subscribers."""
    return QoSProfile(reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL,
                      history=HistoryPolicy.KEEP_LAST, depth=1)


def pose_with_covariance(stamp, frame_id: str, q_wxyz,
                         rotation_covariance) -> PoseWithCovarianceStamped:
    """
    Build an attitude-only PoseWithCovarianceStamped.

    Parameters
    ----------
    stamp : builtin_interfaces.msg.Time
        Header stamp.
    frame_id : str
        Header frame id.
    q_wxyz : (4,) array_like
        The orientation, scalar-first (converted to ROS x, y, z, w).
    rotation_covariance : (3, 3) array_like
        Rotation block of the covariance, rad² (symmetrised).

    Returns
    -------
    PoseWithCovarianceStamped
        Position 0 with :data:`UNKNOWN_POSITION_VARIANCE` on its diagonal, the rotation block
        at rows/cols 3..5.

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
    """
    Return the rotation block of a pose covariance.

    Parameters
    ----------
    msg : PoseWithCovarianceStamped
        The message.

    Returns
    -------
    (3, 3) ndarray
        Rows/cols 3..5 of its covariance, rad².

    """
    return np.asarray(msg.pose.covariance, dtype=float).reshape(6, 6)[3:, 3:].copy()


# --- time ----------------------------------------------------------------------------
def stamp_to_ns(stamp: Time) -> int:
    """
    Return a ROS stamp as integer nanoseconds.

    Parameters
    ----------
    stamp : builtin_interfaces.msg.Time
        The stamp.

    Returns
    -------
    int
        sec · 10⁹ + nanosec.

    """
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def ns_to_stamp(ns: int) -> Time:
    """
    Return integer nanoseconds as a ROS stamp.

    Parameters
    ----------
    ns : int
        Nanoseconds.

    Returns
    -------
    builtin_interfaces.msg.Time
        The stamp.

    """
    ns = int(ns)
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def set_stamp(stamp: Time, ns) -> None:
    """
    Write nanoseconds into an existing stamp (no new message: the per-update publishing path).

    Parameters
    ----------
    stamp : builtin_interfaces.msg.Time
        The stamp to overwrite.
    ns : int
        Nanoseconds.

    """
    stamp.sec, stamp.nanosec = divmod(int(ns), 1_000_000_000)


def seconds_to_stamp(t: float) -> Time:
    """
    Return seconds as a ROS stamp, rounded to the nanosecond.

    Parameters
    ----------
    t : float
        Seconds.

    Returns
    -------
    builtin_interfaces.msg.Time
        The stamp.

    """
    return ns_to_stamp(int(round(t * 1e9)))


# --- messages -----------------------------------------------------------------------------
def vector3(v: Sequence[float]) -> Vector3:
    """
    Build a Vector3 message.

    Parameters
    ----------
    v : (3,) sequence of float
        The vector.

    Returns
    -------
    geometry_msgs.msg.Vector3
        The message.

    """
    return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def quaternion_msg(q_wxyz: Sequence[float]) -> Quaternion:
    """
    Convert a core quaternion to a ROS Quaternion message.

    Parameters
    ----------
    q_wxyz : (4,) sequence of float
        The quaternion, scalar-first.

    Returns
    -------
    geometry_msgs.msg.Quaternion
        The message (x, y, z, w).

    """
    return Quaternion(w=float(q_wxyz[0]), x=float(q_wxyz[1]), y=float(q_wxyz[2]),
                      z=float(q_wxyz[3]))


def quaternion_from_msg(q: Quaternion) -> np.ndarray:
    """
    Convert a ROS Quaternion message to a core quaternion.

    Parameters
    ----------
    q : geometry_msgs.msg.Quaternion
        The message.

    Returns
    -------
    (4,) ndarray
        The quaternion, scalar-first.

    """
    return np.array([q.w, q.x, q.y, q.z], dtype=float)


def vector3_stamped(stamp: Time, frame_id: str, v) -> Vector3Stamped:
    """
    Build a Vector3Stamped message.

    Parameters
    ----------
    stamp : builtin_interfaces.msg.Time
        Header stamp.
    frame_id : str
        Header frame id.
    v : (3,) sequence of float
        The vector.

    Returns
    -------
    geometry_msgs.msg.Vector3Stamped
        The message.

    """
    m = Vector3Stamped()
    m.header.stamp = stamp
    m.header.frame_id = frame_id
    m.vector = vector3(v)
    return m


def quaternion_stamped(stamp: Time, frame_id: str, q_wxyz) -> QuaternionStamped:
    """
    Build a QuaternionStamped message.

    Parameters
    ----------
    stamp : builtin_interfaces.msg.Time
        Header stamp.
    frame_id : str
        Header frame id.
    q_wxyz : (4,) sequence of float
        The quaternion, scalar-first.

    Returns
    -------
    geometry_msgs.msg.QuaternionStamped
        The message.

    """
    m = QuaternionStamped()
    m.header.stamp = stamp
    m.header.frame_id = frame_id
    m.quaternion = quaternion_msg(q_wxyz)
    return m


# --- simulators ------------------------------------------------------------------------------
class PacedSimulation:
    """
    Mixin for the simulator nodes: the simulated time paced by the wall clock.

    A wall timer calls :meth:`_tick`, which advances the simulated time to ``time_scale`` × the
    wall time since the first tick (capped at ``end_time``) through the node's
    ``_advance_to(target)``, and calls ``_on_finished()`` once.  Nothing downstream sees the wall
    clock: every stamp is simulated time.  :meth:`restart_pacing` restarts the pacing at
    the next tick (used after discovery).  With ``wait_for_subscribers`` = N > 0 the clock starts
    at the first tick that sees N subscribers (``_subscriber_count()``), so that consumers started
    as separate processes lose nothing.
    """

    _wall_start = None
    finished = False

    @property
    def pacing_started(self) -> bool:
        """Return whether the simulated clock runs (False while waiting for subscribers)."""
        return self._wall_start is not None

    def restart_pacing(self) -> None:
        """Restart the pacing at the next tick (simulated time continues; used after discovery)."""
        self._wall_start = None

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
