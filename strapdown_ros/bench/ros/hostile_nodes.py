"""
The nodes on hostile input: each spun up in-process and fed a recording through its callbacks.

:func:`run_node` creates ``attitude_filter_node``, ``calibrator_node`` or ``sins_node`` (its own
namespace; the caller isolates the ROS domain), hands it every message of a
:class:`~strapdown_ros.bench.hostile_input.Recording` in the order received — gyro messages as
the serialized bytes its raw subscription gets, fixes as the message objects — and reads what it
counted and estimated into a :class:`~strapdown_ros.bench.hostile_tools.Outcome` (the verdict:
:func:`strapdown_ros.bench.hostile_tools.problems`).  An exception that escapes a callback is
what would make the node exit: it is caught and reported as a traceback.  A reference message of
another type cannot reach a node (ROS matches types), so that kind is not fed to them.
"""
from __future__ import annotations

import itertools
import traceback

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseWithCovarianceStamped, QuaternionStamped, Vector3Stamped
import numpy as np
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from std_msgs.msg import Header

from strapdown_ros.bench.hostile_input import BETA, Kind, Recording
from strapdown_ros.bench.hostile_tools import Outcome
from strapdown_ros.nodes import ros_io
from strapdown_ros.nodes.attitude_filter_node import AttitudeFilterNode
from strapdown_ros.nodes.calibrator_node import CalibratorNode
from strapdown_ros.nodes.sins_node import SinsNode

__all__ = ['NODES', 'run_node', 'fed_to_nodes']

#: the nodes that take a stream (the simulators take none)
NODES = ('attitude_filter_node', 'calibrator_node', 'sins_node')
_COUNTER = itertools.count()
_NS = 1_000_000_000


def fed_to_nodes(kind: Kind | None, node: str) -> bool:
    """
    Tell whether a hostile kind can reach a node at all.

    Parameters
    ----------
    kind : Kind or None
        The kind.
    node : str
        One of :data:`NODES`.

    Returns
    -------
    bool
        False for a reference kind and ``sins_node`` (it has no reference), and for a reference
        message of another type (ROS delivers only the subscribed type).

    """
    if kind is None:
        return True
    if kind.stream == 'reference' and node == 'sins_node':
        return False
    return not (kind.stream == 'reference' and kind.name == 'wrong_type')


def _header(ns: int, frame: str) -> Header:
    ns = max(int(ns), 0)
    return Header(stamp=Time(sec=ns // _NS, nanosec=ns % _NS), frame_id=frame)


def _gyro_bytes(m) -> bytes:
    if m.wrong_type:
        q = QuaternionStamped(header=_header(m.stamp_ns, m.frame))
        q.quaternion.x = q.quaternion.y = q.quaternion.z = q.quaternion.w = 0.5
        return serialize_message(q)
    v = Vector3Stamped(header=_header(m.stamp_ns, m.frame))
    v.vector.x, v.vector.y, v.vector.z = (float(c) for c in m.value)
    return serialize_message(v)


def _fix(m) -> PoseWithCovarianceStamped:
    q, P = m.value
    cov = np.zeros((6, 6))
    cov[0, 0] = cov[1, 1] = cov[2, 2] = 1e9
    cov[3:, 3:] = np.asarray(P, dtype=float)
    msg = PoseWithCovarianceStamped(header=_header(m.stamp_ns, m.frame))
    msg.pose.pose.orientation = ros_io.quaternion_msg(np.asarray(q, dtype=float))
    msg.pose.covariance = [float(c) for c in cov.reshape(36)]
    return msg


def _make(node: str, rec: Recording):
    ns = f'/hostile_{node}_{next(_COUNTER)}'
    common = [Parameter('gyro_rate', value=float(rec.rate_hz)),
              Parameter('gyro_bias_sigma', value=1e-4)]
    if node == 'attitude_filter_node':
        return AttitudeFilterNode(namespace=ns, parameter_overrides=common + [
            Parameter('boresight', value=[float(b) for b in BETA]),
            Parameter('output_period', value=1.0)])
    if node == 'calibrator_node':
        return CalibratorNode(namespace=ns, parameter_overrides=common)
    return SinsNode(namespace=ns, parameter_overrides=common + [
        Parameter('accel_rate', value=float(rec.rate_hz))])


def _feed(node: str, n, rec: Recording) -> None:
    events = [(m.received_ns, 0, 'gyro', m) for m in rec.gyro]
    if node == 'sins_node':
        events += [(m.received_ns, 1, 'accel', m) for m in rec.accel]
    else:
        events += [(m.received_ns, 2, 'reference', m) for m in rec.reference]
    events.sort(key=lambda e: (e[0], e[1]))
    for _, _, stream, m in events:
        if stream == 'gyro':
            n.on_gyro_raw(_gyro_bytes(m))
        elif stream == 'accel':
            n.on_accel_raw(_gyro_bytes(m))
        elif node == 'attitude_filter_node':
            msg = _fix(m)
            n.fix(msg.header, msg.pose.pose.orientation, ros_io.rotation_block(msg))
        else:
            n.on_camera_cov(_fix(m))
    if node != 'calibrator_node':
        n.process()


def _read(node: str, n) -> dict:
    """Return the node's counters in the shape of the tools' ``input.read``."""
    if node == 'sins_node':
        g = n.gyro_check
        return {'gyro': {'dropped': {'nan': g.nan, 'out_of_range': g.out_of_range,
                                     'duplicate': g.duplicate, 'out_of_order': g.out_of_order,
                                     'stamp_outlier': g.stamp_outliers,
                                     'frame': n.frame_mismatch['gyro'],
                                     'wrong_type': n.undecodable}}}
    if node == 'attitude_filter_node':
        s = n.system
        g, c, scr = s.gyro_check, s.camera_check, s.fix_screen
        frames = n.frame_mismatch
        undecodable = n.undecodable
    else:
        g, c, scr = n.gyro_check, n.camera_check, n.fix_screen
        frames = {'gyro': n.gyro_frame_mismatch, 'camera': n.camera_counts['frame_mismatch']}
        undecodable = n.undecodable
    gyro = {'nan': g.nan, 'out_of_range': g.out_of_range, 'duplicate': g.duplicate,
            'out_of_order': g.out_of_order, 'stamp_outlier': g.stamp_outliers,
            'frame': frames['gyro'], 'wrong_type': undecodable}
    ref = {'nan': scr.nan + c.nan, 'zero_quaternion': scr.zero_quaternion,
           'not_unit': scr.not_unit, 'bad_covariance': scr.bad_covariance,
           'duplicate': c.duplicate, 'out_of_order': c.out_of_order,
           'stamp_outlier': c.stamp_outliers, 'frame': frames['camera']}
    return {'gyro': {'dropped': gyro}, 'reference': {'dropped': ref}}


def _estimate(node: str, n):
    if node == 'attitude_filter_node':
        f = n.system.filter
        if f is None:
            return None, None
        return np.asarray(f.estimate('gyro_bias'), dtype=float), \
            np.asarray(f.sigma('gyro_bias'), dtype=float)
    if node == 'calibrator_node':
        sol = n.cal.solution
        if sol is None or not (sol.observable and sol.converged) or sol.beta is None:
            return None, None
        return np.asarray(sol.beta, dtype=float), \
            np.sqrt(np.maximum(np.diag(sol.covariance_beta), 0.0))
    q = np.asarray(n.integrator.q, dtype=float)
    sig = np.sqrt(np.maximum(np.diag(n.integrator.covariance()), 0.0))
    return q * np.sign(q[0]), np.full(4, float(sig.max()))


def run_node(node: str, rec: Recording) -> Outcome:
    """
    Run one node over a recording, in-process, and read its counters and estimates.

    The caller holds an rclpy context (``rclpy.init``) and isolates the ROS domain.

    Parameters
    ----------
    node : str
        One of :data:`NODES`.
    rec : Recording
        The streams (:func:`~strapdown_ros.bench.hostile_input.streams_with`, with
        ``frames_used=False``: a node rejects a message in another frame).

    Returns
    -------
    Outcome
        Status 0 (None with the traceback when an exception escaped a callback), counters in
        the tools' shape, estimate and 1σ (filter: the gyro bias; calibrator: β; sins_node: the
        attitude).

    """
    n = _make(node, rec)
    try:
        try:
            _feed(node, n, rec)
            n.publish_diagnostics()           # every condition formatted, as the timer does
        except Exception:  # noqa: BLE001 - the verdict: what would make the node exit
            return Outcome(node, None, traceback.format_exc())
        est, sig = _estimate(node, n)
        return Outcome(node, 0, None, read=_read(node, n), estimate=est, sigma=sig)
    finally:
        n.destroy_node()
