"""
The ROS side of ``node_rate_bench``: a bare counting subscriber and a paced Δθ publisher.

``counting_node`` is the reference: it subscribes to ``imu/delta_theta`` with exactly the QoS
of ``sins_node`` and ``calibrator_node`` (:func:`ros_io.stream_qos` of ``qos_depth``, the same
QoS override options), runs under the same ``ros_process.run_node`` (same executor, same spin
loop), and does nothing in its callback but count.  It takes deserialized messages, as a plain
rclpy subscriber does; with ``raw:=true`` (subject ``counting_node_raw``) it takes the serialized
bytes, as sins_node and calibrator_node do — the fastest an rclpy subscriber can be.  It
reports ``gyro_received`` on ``/diagnostics``, as the package's nodes do, so one harness
reads every subject the same way.

:meth:`Harness.trial` publishes Δθ at a given rate in bursts every ``slot`` seconds of wall time
and sleeps in between (it never busy-spins, so on a 2-core machine it does not starve the node
it measures).  Stamps continue across trials at 1/rate steps, strictly increasing.  A subject
that takes camera fixes (``attitude_filter_node``) is also sent one fix per second (every
``rate`` increments, stamped with the last increment's stamp): ``q_GCRS_VF`` = exp(k·Δθ) after k
increments of the constant Δθ, the exact attitude, so every fix is applied; its first fix (in
the first trial) starts the filter.
"""
from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
import numpy as np
import rclpy
from rclpy.node import Node

from strapdown_ros.nodes import ros_io, ros_process, ros_status
from strapdown_ros.rotation import rotvec_to_quat

NODE_NAME = 'counting_node'
SUBJECTS = ('counting_node', 'counting_node_raw', 'sins_node', 'calibrator_node',
            'attitude_filter_node')
#: subjects that take camera fixes (star_camera/attitude, one per second of stamps)
CAMERA_SUBJECTS = ('attitude_filter_node',)


class CountingNode(Node):
    """
    Count imu/delta_theta messages; nothing else.

    The parameter ``raw`` takes the serialized bytes (as sins_node and calibrator_node do)
    instead of deserialized messages; ``qos_depth`` and ``diagnostics_period`` as the nodes'.

    Parameters
    ----------
    **kwargs
        Passed to ``rclpy.node.Node`` (namespace, parameter overrides).

    """

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        depth = self.declare_parameter('qos_depth', 500).value
        period = self.declare_parameter('diagnostics_period', 0.5).value
        raw = self.declare_parameter('raw', False).value
        self.received = 0
        self.create_subscription(Vector3Stamped, 'imu/delta_theta', self.on_gyro,
                                 ros_io.stream_qos(int(depth)),
                                 qos_overriding_options=ros_io.QOS_OVERRIDES, raw=bool(raw))
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics',
                                              ros_io.DIAGNOSTICS_QOS)
        self.create_timer(float(period), self._diag)

    def on_gyro(self, msg):
        """
        Count one message.

        Parameters
        ----------
        msg : geometry_msgs.msg.Vector3Stamped or bytes
            The message (unused).

        """
        self.received += 1

    def _diag(self):
        self.pub_diag.publish(
            ros_status.diagnostic_array(ros_io.ns_to_stamp(0),
                                        f'{self.get_fully_qualified_name()}: count', 'counting',
                                        ros_status.OK, 'ok', {'gyro_received': self.received}))


def main(args=None):
    """
    Run the counting node until interrupted (the entry of ``python -m``).

    Parameters
    ----------
    args : list of str, optional
        ROS command-line arguments.

    Returns
    -------
    int
        Exit status of ``ros_process.run_node``.

    """
    return ros_process.run_node(CountingNode, NODE_NAME, args)


class Subject:
    """
    One node process under test, in its own namespace, and the harness's view of it.

    Parameters
    ----------
    harness : rclpy.node.Node
        The harness's node (it owns the publisher to the subject).
    name : str
        One of ``SUBJECTS``.
    params : dict
        ``-p`` parameters of the process.

    """

    MODULES = {
        'counting_node': 'strapdown_ros.bench.ros.rate_probe',
        'counting_node_raw': 'strapdown_ros.bench.ros.rate_probe',
        'sins_node': 'strapdown_ros.nodes.sins_node',
        'calibrator_node': 'strapdown_ros.nodes.calibrator_node',
        'attitude_filter_node': 'strapdown_ros.nodes.attitude_filter_node',
    }

    def __init__(self, harness: Node, name: str, params: dict):
        self.name = name
        self.ns = f'/rate_{os.getpid()}_{name}'
        cmd = [sys.executable, '-m', self.MODULES[name], '--ros-args', '-r', f'__ns:={self.ns}',
               '-p', 'diagnostics_period:=0.25']
        for k, v in params.items():
            cmd += ['-p', f'{k}:={v}']
        self.proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                     text=True)
        self.pub = harness.create_publisher(Vector3Stamped, f'{self.ns}/imu/delta_theta',
                                            ros_io.stream_qos(500))
        self.received: int | None = None
        self.updated = 0.0
        self.stamp_ns = 1_000_000_000
        self.msg = Vector3Stamped()
        self.msg.header.frame_id = 'imu_link'
        self.step = np.array([1e-6, -2e-6, 3e-6])
        self.msg.vector.x, self.msg.vector.y, self.msg.vector.z = (float(c) for c in self.step)
        self.sent = 0                                   # Δθ published to it, all trials
        self.fixes = 0
        self.next_fix = 1                               # the first fix after the first Δθ
        self.fix_counts: dict = {}                      # applied, gated, reset (its diagnostics)
        self.camera = None
        if name in CAMERA_SUBJECTS:
            self.camera = harness.create_publisher(QuaternionStamped,
                                                   f'{self.ns}/star_camera/attitude',
                                                   ros_io.camera_qos(100))

    def fix_due(self, rate: float) -> None:
        """
        Publish a camera fix when a second of increments has passed since the last one.

        Parameters
        ----------
        rate : float
            The trial's rate, Hz (a fix every ``rate`` increments).

        """
        if self.camera is None or self.sent < self.next_fix:
            return
        self.next_fix = self.sent + max(1, int(round(rate)))
        st = ros_io.ns_to_stamp(self.stamp_ns)
        q = rotvec_to_quat(self.step * self.sent)      # exact: k equal increments from identity
        self.camera.publish(ros_io.quaternion_stamped(st, '', q))   # no frame: any is taken
        self.fixes += 1

    def on_status(self, status) -> bool:
        """
        Take the subject's count from one /diagnostics status, if it is the subject's.

        Parameters
        ----------
        status : diagnostic_msgs.msg.DiagnosticStatus
            One status of a DiagnosticArray.

        Returns
        -------
        bool
            True when the status belongs to this subject.

        """
        if not status.name.startswith(self.ns + '/'):
            return False
        for kv in status.values:
            if kv.key == 'gyro_received':
                self.received = int(kv.value)
                self.updated = time.monotonic()
            elif kv.key in ('applied', 'gated', 'reset'):
                self.fix_counts[kv.key] = int(kv.value)
        return True

    def stop(self) -> None:
        """Stop the process (SIGINT, then kill after 10 s)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()


class Harness:
    """
    The bench's own node: paced publishers, diagnostics of the subjects, a spin helper.

    Parameters
    ----------
    executor_factory : callable
        Returns the executor to spin the harness's node with.

    """

    def __init__(self, executor_factory):
        Harness.count = getattr(Harness, 'count', 0) + 1
        self.node = rclpy.create_node(f'rate_bench_{os.getpid()}_{Harness.count}')
        self.ex = executor_factory()
        self.ex.add_node(self.node)
        self.subjects: list[Subject] = []
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag,
                                      ros_io.DIAGNOSTICS_QOS)

    def _on_diag(self, msg):
        for st in msg.status:
            for s in self.subjects:
                if s.on_status(st):
                    break

    def add(self, name: str, params: dict) -> Subject:
        """
        Start a subject process.

        Parameters
        ----------
        name : str
            One of ``SUBJECTS``.
        params : dict
            Its ``-p`` parameters.

        Returns
        -------
        Subject
            The subject.

        """
        s = Subject(self.node, name, params)
        self.subjects.append(s)
        return s

    def spin(self, seconds: float, until=None) -> bool:
        """
        Spin the harness for ``seconds``, or until ``until()`` is true.

        Parameters
        ----------
        seconds : float
            Longest spin, s.
        until : callable, optional
            Condition checked after each spin.

        Returns
        -------
        bool
            True when the condition became true.

        """
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.ex.spin_once(timeout_sec=0.02)
            if until is not None and until():
                return True
        return False

    def ready(self, s: Subject, timeout: float = 30.0) -> bool:
        """
        Wait until the subject is matched and has reported a count.

        Parameters
        ----------
        s : Subject
            The subject.
        timeout : float, optional
            Longest wait, s.

        Returns
        -------
        bool
            True when ready.

        """
        return self.spin(timeout,
                         lambda: s.pub.get_subscription_count() > 0 and s.received is not None)

    def trial(self, s: Subject, rate: float, seconds: float, slot: float = 0.002) -> dict:
        """
        Publish ``rate`` × ``seconds`` Δθ to a subject, paced by the wall clock; count.

        Parameters
        ----------
        s : Subject
            The subject.
        rate : float
            Input rate, Hz.
        seconds : float
            Length of the trial, s.
        slot : float, optional
            Wall time between bursts, s.

        Returns
        -------
        dict
            Rate, messages sent and received, achieved rate, lost.

        """
        before = self._settled(s)
        n = int(round(rate * seconds))
        step = int(round(1e9 / rate))
        m, pub = s.msg, s.pub
        sent = 0
        fixes = s.camera is not None
        t0 = time.monotonic()
        while sent < n:
            due = min(n, int((time.monotonic() - t0) * rate) + 1)
            while sent < due:
                s.stamp_ns += step
                m.header.stamp.sec, m.header.stamp.nanosec = divmod(s.stamp_ns, 1_000_000_000)
                pub.publish(m)
                sent += 1
                if fixes:
                    s.sent += 1
                    s.fix_due(rate)
            nxt = t0 + (sent + 0.5) / rate
            time.sleep(max(0.0, min(slot, nxt - time.monotonic())))
        wall = time.monotonic() - t0
        after = self._settled(s, expect=before + n)
        return {'rate': rate, 'sent': n, 'received': after - before, 'achieved_hz': n / wall,
                'lost': n - (after - before)}

    def _settled(self, s: Subject, expect: int | None = None) -> int:
        """Return the subject's count once it stops changing (or reaches ``expect``)."""
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
        """Stop every subject and destroy the harness's node."""
        for s in self.subjects:
            s.stop()
        self.ex.remove_node(self.node)
        self.node.destroy_node()


# --- the harness's measurements (called by bench/ros/node_rate_bench.py) ---------------------
def rate_repeat(lo_hz: float, hi_hz: float, steps: int, seconds: float, algorithm: str,
                say, subjects=SUBJECTS) -> dict:
    """
    Run one repeat: a fresh process per subject, interleaved bisections.

    Parameters
    ----------
    lo_hz, hi_hz : float
        Ends of the search, Hz.
    steps : int
        Bisection steps.
    seconds : float
        Length of one trial, s.
    algorithm : str
        Coning algorithm of sins_node.
    say : callable
        Called with one line of progress text.
    subjects : sequence of str
        The subjects (of :data:`SUBJECTS`; ``counting_node`` first: the ratios' reference).

    Returns
    -------
    dict
        Highest passing rate per subject, Hz, the brackets, every trial, whether the first trial
        (at ``lo_hz``, with the filter's first fix) passed, and the ratios to the counting
        subscribers.

    """
    h = Harness(ros_process.make_executor)
    params = {
        'counting_node': {},
        'counting_node_raw': {'raw': 'true'},
        'sins_node': {'coning_algorithm': algorithm},
        'calibrator_node': {},
        'attitude_filter_node': {'coning_algorithm': algorithm, 'use_camera_covariance': 'false'},
    }
    SUBJECTS_RUN = tuple(subjects)
    try:
        subj = {n: h.add(n, params[n]) for n in SUBJECTS_RUN}
        for n, s in subj.items():
            if not h.ready(s):
                raise RuntimeError(f'{n} did not come up: ' +
                                   (s.proc.stderr.read() if s.proc.poll() is not None else ''))
        lo = {n: lo_hz for n in SUBJECTS_RUN}
        hi = {n: hi_hz for n in SUBJECTS_RUN}
        passed_lo = {}
        for n in SUBJECTS_RUN:                              # the lower end must pass
            r = h.trial(subj[n], lo_hz, seconds)
            passed_lo[n] = r['lost'] == 0
        trials = []
        for step in range(steps):
            for n in SUBJECTS_RUN:                          # the subjects in turn at every step
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
            say('step %d: ' % (step + 1) + ', '.join(f'{n} {lo[n]:.0f}–{hi[n]:.0f} Hz'
                                                     for n in SUBJECTS_RUN))
        rates = {n: (lo[n] if passed_lo[n] else 0.0) for n in SUBJECTS_RUN}
        out = {'rates_hz': rates, 'bracket_hi_hz': hi, 'trials': trials,
               'first_trial_passed': passed_lo, 'ratio': {}, 'ratio_to_raw': {},
               'fixes': {n: dict(subj[n].fix_counts, sent=subj[n].fixes)
                         for n in SUBJECTS_RUN if subj[n].camera is not None}}
        for key, ref in (('ratio', 'counting_node'), ('ratio_to_raw', 'counting_node_raw')):
            if ref in rates:
                out[key] = {n: rates[n] / rates[ref] if rates[ref] else math.nan
                            for n in SUBJECTS_RUN if n not in ('counting_node', ref)}
        return out
    finally:
        h.close()


def ros_init() -> None:
    """Initialise rclpy in this process."""
    rclpy.init()


def ros_shutdown() -> None:
    """Shut rclpy down in this process (if it is up)."""
    rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
