"""
The ROS side of ``node_rate_bench``: a bare counting subscriber and a paced Δθ publisher.

``counting_node`` is the reference: it subscribes to ``imu/delta_theta`` with exactly the QoS of
``sins_node`` and ``calibrator_node`` (:func:`ros_io.stream_qos` of ``qos_depth``, the same QoS
override options), runs under the same ``ros_process.run_node`` (same executor, same spin loop), and
does nothing in its callback but count.  It takes deserialized messages, as a plain rclpy
subscriber does; with ``raw:=true`` (subject ``counting_node_raw``) it takes the serialized bytes,
as sins_node and calibrator_node do — the fastest an rclpy subscriber can be.  It reports ``gyro_received`` on ``/diagnostics``, as
the package's nodes do, so one harness reads every subject the same way.

:class:`PacedSource` publishes Δθ at a given rate in bursts every ``slot`` seconds of wall time
and sleeps in between (it never busy-spins, so on a 2-core machine it does not starve the node
it measures).  Stamps continue across trials at 1/rate steps, strictly increasing.
"""
from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
import numpy as np
from rclpy.node import Node

from strapdown_ros.nodes import ros_io, ros_process, ros_status
from strapdown_ros.nodes.attitude_filter_node import AttitudeFilterNode
from strapdown_ros.nodes.calibrator_node import CalibratorNode
from strapdown_ros.nodes.sins_node import SinsNode
from strapdown_ros.rotation import rotvec_to_quat

NODE_NAME = 'counting_node'
SUBJECTS = ('counting_node', 'counting_node_raw', 'sins_node', 'calibrator_node')


class CountingNode(Node):
    """
    Counts imu/delta_theta messages; nothing else.  Parameter ``raw``: take the serialized bytes
    (as sins_node and calibrator_node do) instead of deserialized messages.
    """

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        depth = self.declare_parameter('qos_depth', 500).value
        period = self.declare_parameter('diagnostics_period', 0.5).value
        raw = self.declare_parameter('raw', False).value
        self.received = 0
        self.create_subscription(Vector3Stamped, 'imu/delta_theta', self._on_gyro, ros_io.stream_qos(int(depth)),
                                 qos_overriding_options=ros_io.QOS_OVERRIDES, raw=bool(raw))
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', ros_io.DIAGNOSTICS_QOS)
        self.create_timer(float(period), self._diag)

    def _on_gyro(self, msg):
        self.received += 1

    def _diag(self):
        self.pub_diag.publish(ros_status.diagnostic_array(ros_io.ns_to_stamp(0), f'{self.get_fully_qualified_name()}: count',
                                                      'counting', ros_status.OK, 'ok',
                                                      {'gyro_received': self.received}))


def main(args=None):
    return ros_process.run_node(CountingNode, NODE_NAME, args)


class Subject:
    """One node process under test, in its own namespace, and the harness's view of it."""

    MODULES = {'counting_node': 'strapdown_ros.bench.ros.rate_probe', 'counting_node_raw': 'strapdown_ros.bench.ros.rate_probe',
               'sins_node': 'strapdown_ros.nodes.sins_node', 'calibrator_node': 'strapdown_ros.nodes.calibrator_node'}

    def __init__(self, harness: Node, name: str, params: dict):
        self.name = name
        self.ns = f'/rate_{os.getpid()}_{name}'
        cmd = [sys.executable, '-m', self.MODULES[name], '--ros-args', '-r', f'__ns:={self.ns}',
               '-p', 'diagnostics_period:=0.25']
        for k, v in params.items():
            cmd += ['-p', f'{k}:={v}']
        self.proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        self.pub = harness.create_publisher(Vector3Stamped, f'{self.ns}/imu/delta_theta', ros_io.stream_qos(500))
        self.received: int | None = None
        self.updated = 0.0
        self.stamp_ns = 1_000_000_000
        self.msg = Vector3Stamped()
        self.msg.header.frame_id = 'imu_link'
        self.msg.vector.x, self.msg.vector.y, self.msg.vector.z = 1e-6, -2e-6, 3e-6

    def on_status(self, status) -> bool:
        if not status.name.startswith(self.ns + '/'):
            return False
        for kv in status.values:
            if kv.key == 'gyro_received':
                self.received = int(kv.value)
                self.updated = time.monotonic()
        return True

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()


class Harness:
    """The bench's own node: paced publishers, diagnostics of the subjects, a spin helper."""

    def __init__(self, executor_factory):
        import rclpy
        Harness.count = getattr(Harness, 'count', 0) + 1
        self.node = rclpy.create_node(f'rate_bench_{os.getpid()}_{Harness.count}')
        self.ex = executor_factory()
        self.ex.add_node(self.node)
        self.subjects: list[Subject] = []
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, ros_io.DIAGNOSTICS_QOS)

    def _on_diag(self, msg):
        for st in msg.status:
            for s in self.subjects:
                if s.on_status(st):
                    break

    def add(self, name: str, params: dict) -> Subject:
        s = Subject(self.node, name, params)
        self.subjects.append(s)
        return s

    def spin(self, seconds: float, until=None) -> bool:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.ex.spin_once(timeout_sec=0.02)
            if until is not None and until():
                return True
        return False

    def ready(self, s: Subject, timeout: float = 30.0) -> bool:
        return self.spin(timeout, lambda: s.pub.get_subscription_count() > 0 and s.received is not None)

    def trial(self, s: Subject, rate: float, seconds: float, slot: float = 0.002) -> dict:
        """Publish ``rate`` × ``seconds`` Δθ to ``s`` paced by the wall clock; the count it received."""
        before = self._settled(s)
        n = int(round(rate * seconds))
        step = int(round(1e9 / rate))
        m, pub = s.msg, s.pub
        sent = 0
        t0 = time.monotonic()
        while sent < n:
            due = min(n, int((time.monotonic() - t0) * rate) + 1)
            while sent < due:
                s.stamp_ns += step
                m.header.stamp.sec, m.header.stamp.nanosec = divmod(s.stamp_ns, 1_000_000_000)
                pub.publish(m)
                sent += 1
            nxt = t0 + (sent + 0.5) / rate
            time.sleep(max(0.0, min(slot, nxt - time.monotonic())))
        wall = time.monotonic() - t0
        after = self._settled(s, expect=before + n)
        return {'rate': rate, 'sent': n, 'received': after - before, 'achieved_hz': n / wall,
                'lost': n - (after - before)}

    def _settled(self, s: Subject, expect: int | None = None) -> int:
        """The subject's count once it stops changing (or reaches ``expect``)."""
        last, since = s.received, time.monotonic()
        end = time.monotonic() + 15.0
        while time.monotonic() < end:
            self.spin(0.1)
            if expect is not None and s.received is not None and s.received >= expect:
                self.spin(0.3)                      # one more report, so it is the final count
                return s.received
            if s.received != last:
                last, since = s.received, time.monotonic()
            elif time.monotonic() - since > 1.0:
                break
        return s.received if s.received is not None else 0

    def close(self) -> None:
        for s in self.subjects:
            s.stop()
        self.ex.remove_node(self.node)
        self.node.destroy_node()


# --- the harness's measurements (called by bench/ros/node_rate_bench.py) ---------------------------------------------------------------------
def rate_repeat(lo_hz: float, hi_hz: float, steps: int, seconds: float, algorithm: str, say) -> dict:
    """One repeat: a fresh process per subject, interleaved bisections; the highest passing rates."""
    h = Harness(ros_process.make_executor)
    params = {'counting_node': {}, 'counting_node_raw': {'raw': 'true'}, 'sins_node': {'coning_algorithm': algorithm},
              'calibrator_node': {}}
    try:
        subj = {n: h.add(n, params[n]) for n in SUBJECTS}
        for n, s in subj.items():
            if not h.ready(s):
                raise RuntimeError(f'{n} did not come up: ' + (s.proc.stderr.read() if s.proc.poll() is not None else ''))
        lo = {n: lo_hz for n in SUBJECTS}
        hi = {n: hi_hz for n in SUBJECTS}
        passed_lo = {}
        for n in SUBJECTS:                                  # the lower end must pass
            r = h.trial(subj[n], lo_hz, seconds)
            passed_lo[n] = r['lost'] == 0
        trials = []
        for step in range(steps):
            for n in SUBJECTS:                              # the subjects in turn at every step
                if not passed_lo[n]:
                    continue
                mid = math.sqrt(lo[n] * hi[n])
                r = h.trial(subj[n], mid, seconds)
                r['subject'], r['step'] = n, step
                trials.append(r)
                if r['lost'] == 0:
                    lo[n] = mid
                else:
                    hi[n] = mid
            say('step %d: ' % (step + 1) + ', '.join(f'{n} {lo[n]:.0f}–{hi[n]:.0f} Hz' for n in SUBJECTS))
        rates = {n: (lo[n] if passed_lo[n] else 0.0) for n in SUBJECTS}
        return {'rates_hz': rates, 'bracket_hi_hz': hi, 'trials': trials,
                'ratio': {n: rates[n] / rates['counting_node'] if rates['counting_node'] else math.nan
                          for n in SUBJECTS[1:]},
                'ratio_to_raw': {n: rates[n] / rates['counting_node_raw'] if rates['counting_node_raw'] else math.nan
                                 for n in SUBJECTS[2:]}}
    finally:
        h.close()


# --- 2. callback cost ------------------------------------------------------------------------
def callback_cost(algorithm: str, n: int = 20000, subscribed: bool = False,
                  gyro_input: str = 'delta_theta') -> dict:
    """
    µs per Δθ message of sins_node called directly (1 kHz stamps, no accelerometer).

    ``gyro_input`` ``imu``: per sensor_msgs/Imu message on imu/data_raw instead (rate and
    specific force, made into Δθ and Δv by the trapezoid rule), through the node's raw Imu
    callback.

    ``subscribed``: a second node subscribes to ``sins/imu`` and ``sins/attitude`` (it is never
    spun; the messages are serialised and written to DDS all the same), so every update is
    built and published; otherwise no one subscribes and no outputs are built.
    """
    from geometry_msgs.msg import QuaternionStamped
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import Imu

    ns = f'/cb_{os.getpid()}'
    node = SinsNode(namespace=ns, parameter_overrides=[
        Parameter('gyro_rate', value=1000.0), Parameter('coning_algorithm', value=algorithm),
        Parameter('gyro_input', value=gyro_input)])
    listener = None
    if subscribed:
        import rclpy
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
            raise RuntimeError('the in-process subscriber of sins/imu and sins/attitude was not discovered in 10 s')
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
    µs per gyro message of calibrator_node called directly (1 kHz stamps): a Δθ, or with
    ``gyro_input`` ``imu`` a sensor_msgs/Imu rate sample.
    """
    from rclpy.parameter import Parameter

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
    µs per Δθ message of attitude_filter_node called directly: 1 kHz stamps, a constant body
    rate (0.1 rad/s about a fixed axis), a camera fix every second (the exact attitude, so every
    fix is applied), outputs every ``output_period``.  The first ``warm_up`` messages (the filter's
    start and the integrator's compilation) are not timed.

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
    from geometry_msgs.msg import Quaternion
    from rclpy.parameter import Parameter
    from std_msgs.msg import Header

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
    """
    ``n`` serialized imu/delta_theta messages at 1 kHz stamps, as the subscription receives them
    (the nodes subscribe raw).
    """
    from geometry_msgs.msg import Vector3Stamped
    from rclpy.serialization import serialize_message
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
    ``n`` serialized imu/data_raw messages (sensor_msgs/Imu: rate, specific force 9.8 m/s² on
    z, no orientation) at 1 kHz stamps.
    """
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Imu
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


def ros_init() -> None:
    import rclpy
    rclpy.init()


def ros_shutdown() -> None:
    import rclpy
    rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
