"""
Callback cost of the nodes, for ``node_rate_bench``: their subscription callbacks called directly.

``sins_node``'s, ``calibrator_node``'s and ``attitude_filter_node``'s callbacks are fed
serialized messages in this process, as the executor calls them (the nodes subscribe raw);
µs per message, with and without the block processing and the outputs.
"""
from __future__ import annotations

import math
import os
import time

from geometry_msgs.msg import Quaternion, QuaternionStamped, Vector3Stamped
import numpy as np
import rclpy
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu
from std_msgs.msg import Header

from strapdown_ros.nodes import ros_io
from strapdown_ros.nodes.attitude_filter_node import AttitudeFilterNode
from strapdown_ros.nodes.calibrator_node import CalibratorNode
from strapdown_ros.nodes.sins_node import SinsNode
from strapdown_ros.rotation import rotvec_to_quat


def callback_cost(algorithm: str, n: int = 20000, subscribed: bool = False,
                  gyro_input: str = 'delta_theta') -> dict:
    """
    Return the µs per Δθ message of sins_node's callback, called directly at 1 kHz stamps.

    With ``gyro_input`` ``imu``: per sensor_msgs/Imu message on imu/data_raw instead (rate and
    specific force, made into Δθ and Δv by the trapezoid rule), through the node's raw Imu
    callback.  With ``subscribed``, a second node subscribes to ``sins/imu`` and
    ``sins/attitude`` (it is never spun; the messages are serialised and written to DDS all the
    same), so every update is built and published; otherwise no outputs are built.

    Parameters
    ----------
    algorithm : str
        Coning algorithm.
    n : int, optional
        Messages.
    subscribed : bool, optional
        Subscribe to the outputs.
    gyro_input : {'delta_theta', 'imu'}, optional
        Input message type.

    Returns
    -------
    dict
        ``amortised_us`` and ``hot_path_us`` per message, updates and messages published.

    """
    ns = f'/cb_{os.getpid()}'
    node = SinsNode(namespace=ns, parameter_overrides=[
        Parameter('gyro_rate', value=1000.0), Parameter('coning_algorithm', value=algorithm),
        Parameter('gyro_input', value=gyro_input)])
    listener = None
    if subscribed:
        listener = rclpy.create_node(f'cb_listener_{os.getpid()}', namespace=ns)
        qos = ros_io.stream_qos(10)
        listener.create_subscription(Imu, 'sins/imu', lambda m: None, qos)
        listener.create_subscription(QuaternionStamped, 'sins/attitude', lambda m: None, qos)
        end = time.monotonic() + 10.0
        while time.monotonic() < end and not (node.pub_imu.get_subscription_count() and
                                              node.pub_att.get_subscription_count()):
            time.sleep(0.01)
        if not (node.pub_imu.get_subscription_count() and node.pub_att.get_subscription_count()):
            node.destroy_node()
            listener.destroy_node()
            raise RuntimeError(
                'the in-process subscriber of sins/imu and sins/attitude was not discovered in'
                ' 10 s'
            )
    if gyro_input == 'imu':
        msgs = _serialized_imu(n, lambda k: (0.1 * math.sin(k * 1e-3), 0.1 * math.cos(k * 1e-3),
                                             0.02))
        callback = node.on_imu_raw
    else:
        msgs = _serialized(n, lambda k: (1e-4 * math.sin(k * 1e-3), 1e-4 * math.cos(k * 1e-3),
                                         2e-5))
        callback = node.on_gyro_raw
    spent = [0.0]
    real = node.process

    def timed():
        t = time.perf_counter()
        real()
        spent[0] += time.perf_counter() - t
    node.process = timed
    try:
        t0 = time.perf_counter()
        for m in msgs:
            callback(m)                     # the subscription's callback, as the executor calls it
        node.process()
        total = time.perf_counter() - t0
        return {'amortised_us': total / n * 1e6, 'hot_path_us': (total - spent[0]) / n * 1e6,
                'updates': node.integrator.updates, 'published_imu': node.published['imu'],
                'published_attitude': node.published['attitude']}
    finally:
        node.destroy_node()
        if listener is not None:
            listener.destroy_node()


def calibrator_callback_cost(n: int = 20000, gyro_input: str = 'delta_theta') -> dict:
    """
    Return the µs per gyro message of calibrator_node's callback, called directly.

    1 kHz stamps: a Δθ, or with ``gyro_input`` ``imu`` a sensor_msgs/Imu rate sample.

    Parameters
    ----------
    n : int, optional
        Messages.
    gyro_input : {'delta_theta', 'imu'}, optional
        Input message type.

    Returns
    -------
    dict
        ``amortised_us`` per message.

    """
    node = CalibratorNode(namespace=f'/cbc_{os.getpid()}', parameter_overrides=[
        Parameter('gyro_rate', value=1000.0), Parameter('gyro_input', value=gyro_input)])
    if gyro_input == 'imu':
        msgs, callback = _serialized_imu(n, lambda k: (0.1, -0.1, 0.02)), node.on_imu_raw
    else:
        msgs, callback = _serialized(n, lambda k: (1e-4, -1e-4, 2e-5)), node.on_gyro_raw
    try:
        t0 = time.perf_counter()
        for m in msgs:
            callback(m)
        return {'amortised_us': (time.perf_counter() - t0) / n * 1e6}
    finally:
        node.destroy_node()


def filter_callback_cost(n: int = 20000, output_period: float = 0.01,
                         warm_up: int = 2000) -> dict:
    """
    Return the µs per Δθ message of attitude_filter_node's callback, called directly.

    1 kHz stamps, a constant body rate (0.1 rad/s about a fixed axis), a camera fix every
    second (the exact attitude, so every fix is applied), outputs every ``output_period``.  The
    first ``warm_up`` messages (the filter's start and the integrator's compilation) are not
    timed.

    Parameters
    ----------
    n : int
        Timed Δθ messages.
    output_period : float
        The node's ``output_period``, s.
    warm_up : int
        Untimed Δθ messages before.

    Returns
    -------
    dict
        ``amortised_us`` per timed message (fix callbacks included), ``fixes_applied``,
        ``outputs``.

    """
    node = AttitudeFilterNode(namespace=f'/cbf_{os.getpid()}', parameter_overrides=[
        Parameter('gyro_rate', value=1000.0), Parameter('output_period', value=output_period),
        Parameter('use_camera_covariance', value=False)])
    step = (1e-4, -1e-4, 2e-5)
    total = n + warm_up
    msgs = _serialized(total, lambda k: step)

    def fix(k):
        q = rotvec_to_quat(np.asarray(step) * k)
        h = Header(frame_id='gcrs')
        h.stamp.sec, h.stamp.nanosec = divmod(k * 1_000_000, 1_000_000_000)
        node.fix(h, Quaternion(w=float(q[0]), x=float(q[1]), y=float(q[2]), z=float(q[3])), None)
    try:
        fix(0)
        t0 = time.perf_counter()
        for k, m in enumerate(msgs, 1):
            if k == warm_up + 1:
                t0 = time.perf_counter()
            node.on_gyro_raw(m)             # the subscription's callback, as the executor calls it
            if k % 1000 == 0:
                fix(k)
        node.process()
        spent = time.perf_counter() - t0
        return {'amortised_us': spent / n * 1e6, 'fixes_applied': node.system.counts['applied'],
                'outputs': node.published['outputs']}
    finally:
        node.destroy_node()


def _serialized(n: int, vector) -> list:
    """Return ``n`` serialized imu/delta_theta messages at 1 kHz stamps, as nodes receive them."""
    out = []
    m = Vector3Stamped()
    m.header.frame_id = 'imu_link'
    for k in range(1, n + 1):
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(k * 1_000_000, 1_000_000_000)
        m.vector.x, m.vector.y, m.vector.z = vector(k)
        out.append(serialize_message(m))
    return out


def _serialized_imu(n: int, rate) -> list:
    """
    Return ``n`` serialized imu/data_raw messages at 1 kHz stamps.

    sensor_msgs/Imu: rate, specific force 9.8 m/s² on z, no orientation.
    """
    out = []
    m = Imu()
    m.header.frame_id = 'imu_link'
    m.orientation_covariance[0] = -1.0
    m.linear_acceleration.z = 9.80665
    for k in range(1, n + 1):
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(k * 1_000_000, 1_000_000_000)
        m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = rate(k)
        out.append(serialize_message(m))
    return out
