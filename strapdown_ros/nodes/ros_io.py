"""
ROS I/O shared by the nodes: QoS, stamps, message builders, validated parameters, diagnostics.

This is the only place (with the node modules) that imports rclpy and message packages.
Quaternions cross the edge here: ROS messages carry ``x, y, z, w``; the core uses
scalar-first ``[w, x, y, z]`` (:mod:`strapdown_ros.rotation`).
"""
from __future__ import annotations

import gc
import os
import signal
import sys
import time
from typing import Any, Callable, Sequence

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import (PoseWithCovarianceStamped, Quaternion, QuaternionStamped, Vector3,
                               Vector3Stamped)
import numpy as np
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.qos_overriding_options import QoSOverridingOptions

from strapdown_ros.nodes.launch import signal_received
from strapdown_ros.params import ALL_PARAMETER_NAMES, combination_error, ParamSpec
from strapdown_ros.streams import cdr


# --- QoS ---------------------------------------------------------------------------
def stream_qos(depth: int = 500) -> QoSProfile:
    """
    Sensor-data QoS (best effort, volatile) for high-rate streams.

    The history is deeper than rclpy's ``qos_profile_sensor_data`` (5) so that bursts
    from a faster-than-real-time simulator are queued rather than overwritten.
    """
    return QoSProfile(reliability=ReliabilityPolicy.BEST_EFFORT, durability=DurabilityPolicy.VOLATILE,
                      history=HistoryPolicy.KEEP_LAST, depth=depth)


#: Stream and camera topics take the standard ROS QoS override parameters, e.g.
#: ``-p qos_overrides./imu/delta_theta.subscription.reliability:=reliable`` (history, depth,
#: reliability; the topic name fully qualified).  ``/diagnostics`` and the latched outputs have
#: fixed QoS.
QOS_OVERRIDES = QoSOverridingOptions.with_default_policies()

DIAGNOSTICS_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                             history=HistoryPolicy.KEEP_LAST, depth=10)


# --- raw (serialized) stream messages --------------------------------------------------
def decode_vector3_stamped(data: bytes) -> tuple[int, tuple[float, float, float], str] | None:
    """
    ``(stamp_ns, (x, y, z), frame_id)`` of a serialized geometry_msgs/Vector3Stamped.

    The high-rate increment streams are subscribed raw (``raw=True``): rclpy then skips building
    four Python message objects per message (about 18 µs), and the node reads the few fields it
    needs from the bytes (:mod:`strapdown_ros.streams.cdr`, shared with ``sins_bag``).  Any other
    encoding than plain little-endian CDR is handed to rclpy's own deserializer, so nothing is
    misread (test/streams/test_checks_fuzz.py checks both against rclpy's serializer).  None when the bytes
    are not a Vector3Stamped at all (the caller counts and drops them).
    """
    got = cdr.vector3_stamped(data)
    if got is not None:
        return got
    from rclpy.serialization import deserialize_message
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
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import Imu
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
            from rclpy.serialization import deserialize_message
            from sensor_msgs.msg import Imu
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
    return QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                      history=HistoryPolicy.KEEP_LAST, depth=1)


def pose_with_covariance(stamp, frame_id: str, q_wxyz, rotation_covariance) -> PoseWithCovarianceStamped:
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
    return Quaternion(w=float(q_wxyz[0]), x=float(q_wxyz[1]), y=float(q_wxyz[2]), z=float(q_wxyz[3]))


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


# --- parameters ---------------------------------------------------------------------------
def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """
    ROS descriptor of a core :class:`~strapdown_ros.params.ParamSpec` (``ros2 param describe``).

    Ranges and choices are stated in ``additional_constraints`` and enforced by
    :func:`declare_validated` (one message format that lists the valid values), not by
    rclpy's numeric ranges, whose messages differ between start-up and runtime.
    """
    d = ParameterDescriptor(description=spec.description,
                            additional_constraints='valid: ' + spec.range_text())
    # a YAML "50" for a double parameter must not be a type error: spec.check validates it
    # and an unquoted algorithm name "2" (an integer to the YAML parser) is accepted as well
    # and an integer list for a double array ([0, 0, 9]) is read as doubles
    d.dynamic_typing = spec.choices is not None or spec.length is not None or (
        isinstance(spec.default, (int, float)) and not isinstance(spec.default, bool))
    return d


class InvalidParameter(ValueError):  # noqa: N818 (reads better at the call site)
    """Raised at start-up for a parameter value that fails validation."""


#: parameters rclpy itself may be given (not the package's)
ROS_OWN_PARAMETERS = ('use_sim_time', 'start_type_description_service')


def _retyped(given, used) -> bool:
    """The start-up value ``given`` was read as the number ``used`` of another type."""
    return isinstance(used, (int, float)) and not isinstance(used, bool) \
        and type(given) is not type(used)


def declare_validated(node, specs: Sequence[ParamSpec], on_change: Callable[[dict], str | None] | None = None,
                      apply: Callable[[dict], None] | None = None):
    """
    Declare parameters with descriptors, validate the start-up values (raising
    :class:`InvalidParameter` with the valid values in the message), and validate every runtime
    set in an on-set callback: ``on_change(values)`` may veto a valid change by returning a reason
    (e.g. a read-only value); ``apply(values)`` then makes it effective in a post-set callback,
    once rclpy has accepted it.  Setting a parameter to its current value is no change (so
    ``ros2 param load`` of the shipped file succeeds).  A start-up override that no node of the
    package declares is an error (a typo must not pass silently).  Returns the dict of current
    values, kept up to date.
    """

    by_name = {s.name: s for s in specs}
    values = {}
    for s in specs:
        p = node.declare_parameter(s.name, s.default, descriptor(s))
        v = s.normalise(p.value)
        err = s.check(v)
        if err:
            raise InvalidParameter(err)
        values[s.name] = v
        if _retyped(p.value, v):
            # a number given as text ("0.05", a quoted YAML value) or a double given as an
            # integer: stored with its proper type, so `ros2 param get` shows what is used
            node.set_parameters([Parameter(s.name, value=v)])
    err = combination_error(values)
    if err:
        raise InvalidParameter(err)
    unknown = sorted(n for n in getattr(node, '_parameter_overrides', {})
                     if n not in ALL_PARAMETER_NAMES and n not in ROS_OWN_PARAMETERS and not n.startswith('qos_overrides.'))
    if unknown:
        raise InvalidParameter(f"unknown parameter(s) {', '.join(map(repr, unknown))} for {node.get_name()}; "
                               f"known: {', '.join(sorted(by_name))}")

    def _changes(params: list[Parameter]):
        new = {}
        for p in params:
            spec = by_name.get(p.name)
            if spec is None:
                continue
            v = spec.normalise(p.value)
            err = spec.check(v)
            if err:
                return None, err
            if isinstance(p.value, str) and _retyped(p.value, v):
                # at run time a number given as text would stay text in `ros2 param get`
                # (it cannot be re-set from inside the set callback): refused, as rclpy
                # refuses text for a typed double
                return None, (f'{p.name} must be set as a number, not as text '
                              f'{bounded(repr(p.value), 80)}')
            if v != values.get(p.name):
                new[p.name] = v
        err = combination_error({**values, **new}) if new else None
        return (None, err) if err else (new, None)

    def _on_set(params: list[Parameter]) -> SetParametersResult:
        new, err = _changes(params)
        if err:
            return SetParametersResult(successful=False, reason=err)
        if on_change is not None and new:
            reason = on_change(new)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _post_set(params: list[Parameter]) -> None:
        new, _ = _changes(params)
        if new:
            values.update(new)
            if apply is not None:
                apply(new)

    node.add_on_set_parameters_callback(_on_set)
    node.add_post_set_parameters_callback(_post_set)
    return values


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


# --- process entry point -------------------------------------------------------------------
#: environment variable that selects the executor of the node processes: ``events`` (default)
#: or ``single`` (rclpy's SingleThreadedExecutor)
EXECUTOR_ENV = 'STRAPDOWN_EXECUTOR'


def make_executor(kind: str | None = None):
    """
    The executor of a node process.  rclpy's EventsExecutor (``rclpy.experimental``, Jazzy)
    dispatches a message in about a tenth of the CPU time of the SingleThreadedExecutor, which
    rebuilds its wait set on every spin (load_bench, node_rate_bench); ``single`` (or
    ``STRAPDOWN_EXECUTOR=single``) selects the latter, and it is the fallback where the former
    does not exist.
    """

    import rclpy.executors
    kind = (kind or os.environ.get(EXECUTOR_ENV, 'events')).strip().lower()
    if kind not in ('events', 'single'):
        raise ValueError(f"{EXECUTOR_ENV} must be 'events' or 'single', got {kind!r}")
    if kind == 'events':
        try:
            from rclpy.experimental import EventsExecutor
            return EventsExecutor()
        except ImportError:                            # pragma: no cover - older rclpy
            pass
    return rclpy.executors.SingleThreadedExecutor()


def run_node(node_class, name: str, args=None) -> int:
    """
    ``main()`` of every node: init, construct (invalid parameters → message on stderr, exit 2),
    spin until SIGINT/SIGTERM or shutdown, clean up.  Returns the process exit status.

    Signals: the process owns SIGINT and SIGTERM (rclpy's native handlers are not installed).
    A signal only records the request; the spin loop sees it within ``SPIN_SLICE_S`` and the
    node is shut down from the main loop, never from inside a callback (an exception raised in a
    callback would be logged by the events executor as FATAL, and a context shut down under a
    running callback makes its next publish fail).
    """

    import rclpy
    from rclpy.exceptions import ParameterException
    import rclpy.executors
    from rclpy.signals import SignalHandlerOptions

    stop: list[int] = []

    def request_stop(signum, frame):
        stop.append(signum)

    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, request_stop)
        if signal_received():                          # a signal the entry point saw first
            return 0
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except KeyboardInterrupt:                          # the entry point's import-time handler
        return 0
    except Exception as exc:                           # noqa: BLE001 - e.g. an unparsable --params-file
        print(f'[{name}] error: {str(exc).splitlines()[0]}', file=sys.stderr)
        return 2
    try:
        executor = make_executor()
    except ValueError as exc:
        print(f'[{name}] error: {exc}', file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    try:
        node = node_class()
    except (ValueError, ParameterException) as exc:   # invalid parameters: clear message, exit 2
        _quiet_exit(executor, rclpy)
        if stop:
            return 0
        print(f'[{name}] error: {exc}', file=sys.stderr)
        return 2
    except Exception:                                  # noqa: BLE001
        if stop:
            return _quiet_exit(executor, rclpy)
        raise
    try:
        executor.add_node(node)
        _freeze_startup_objects()
        _spin(executor, rclpy, stop)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        _quiet_exit(executor, rclpy, node)
    return 0


def _freeze_startup_objects() -> None:
    """
    Move every object made at start-up (modules, numba's and numpy's tables, the node) out of
    the garbage collector's reach (``gc.freeze``).  Without it each full collection walks them
    all (about 10⁵ objects in a sins_node process) while the input streams queue up.  Cycles
    made later are still collected.
    """
    gc.collect()
    gc.freeze()


#: longest time between a signal and the start of the shutdown, s
SPIN_SLICE_S = 0.2


def _spin(executor, rclpy, stop: list) -> None:
    """Spin in slices of ``SPIN_SLICE_S`` until a stop is requested or the context is shut down."""
    from rclpy.task import Future
    never = Future()
    while not stop and rclpy.ok():
        executor.spin_until_future_complete(never, timeout_sec=SPIN_SLICE_S)


def _quiet_exit(executor, rclpy, node=None) -> int:
    """
    Shut down the executor, the node and the context, each step on its own: rclpy's signal
    handler may shut the context down at the same moment ("rcl_shutdown already called"), which
    is the stop that was asked for, not an error.
    """
    for step in (executor.shutdown, node.destroy_node if node is not None else None, rclpy.try_shutdown):
        if step is None:
            continue
        try:
            step()
        except Exception:                              # noqa: BLE001 - a concurrent shutdown: already stopped
            pass
    return 0

