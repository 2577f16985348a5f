"""
Loopback throughput of sins_node: a separate sins_node process fed at a fixed input rate.

Used by ``sins_bench --node-seconds S``.  The publisher paces itself by the wall clock;
stamps are k/rate (simulated time).  Counts come from the node's own /diagnostics and
from the sins/attitude messages received back.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
import rclpy

from strapdown_ros.nodes.ros_io import ns_to_stamp, stream_qos


def run_loopback(rate_hz: float = 2000.0, seconds: float = 60.0, algorithm: str = '2') -> dict:
    """
    Feed a separate ``sins_node`` process over loopback at a fixed rate and count.

    Parameters
    ----------
    rate_hz : float, optional
        Δθ input rate, Hz.
    seconds : float, optional
        Length of the feed, s.
    algorithm : str, optional
        Coning algorithm of the node.

    Returns
    -------
    dict
        Messages sent and the achieved input rate; accepted, missing and dropped per the node's
        /diagnostics; attitudes received back and expected.

    """
    ns = f'/bench_{os.getpid()}'
    cmd = [
        sys.executable, '-m', 'strapdown_ros.nodes.sins_node', '--ros-args', '-r', f'__ns:={ns}',
        '-p', f'gyro_rate:={rate_hz}', '-p', f'coning_algorithm:={algorithm}', '-p',
        'diagnostics_period:=0.5'
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    rclpy.init()
    node = rclpy.create_node('loopback_source', namespace=ns)
    pub = node.create_publisher(Vector3Stamped, 'imu/delta_theta', stream_qos(1000))
    outputs = [0]
    diags = []
    node.create_subscription(QuaternionStamped, 'sins/attitude',
                             lambda m: outputs.__setitem__(0, outputs[0] + 1), stream_qos(100000))
    node.create_subscription(
        DiagnosticArray, '/diagnostics',
        lambda m: diags.extend(s for s in m.status if s.name.startswith(f'{ns}/sins_node')), 10)
    try:
        t_end = time.monotonic() + 30.0
        while (
            pub.get_subscription_count() == 0 or node.count_publishers(f'{ns}/sins/attitude') == 0
        ) and time.monotonic() < t_end:
            rclpy.spin_once(node, timeout_sec=0.05)
        if pub.get_subscription_count() == 0:
            raise RuntimeError('sins_node did not come up: ' +
                               (proc.stderr.read() if proc.poll() is not None else ''))
        time.sleep(0.5)
        n_total = int(round(rate_hz * seconds))
        msg = Vector3Stamped()
        msg.header.frame_id = 'imu_link'
        msg.vector.x, msg.vector.y, msg.vector.z = 1e-5, -2e-5, 3e-5
        start = time.monotonic()
        sent = 0
        while sent < n_total:  # bursts every 2 ms; sleeps in between (never busy-spins)
            due = min(n_total, int((time.monotonic() - start) * rate_hz) + 1)
            while sent < due:
                sent += 1
                msg.header.stamp = ns_to_stamp(int(round(sent * 1e9 / rate_hz)))
                pub.publish(msg)
            rclpy.spin_once(node, timeout_sec=0.0)
            time.sleep(max(0.0, min(0.002, start + (sent + 0.5) / rate_hz - time.monotonic())))
        send_wall = time.monotonic() - start
        # let the node drain, then read its final diagnostics
        expected_out = n_total // (2 if algorithm in ('2', 'two_sample') else 1)
        t_end = time.monotonic() + 10.0
        while time.monotonic() < t_end and outputs[0] < expected_out:
            rclpy.spin_once(node, timeout_sec=0.05)
        diags.clear()
        t_end = time.monotonic() + 5.0
        while time.monotonic() < t_end and not diags:
            rclpy.spin_once(node, timeout_sec=0.05)
        kv = {v.key: v.value for v in diags[-1].values} if diags else {}
        dropped = sum(int(kv.get(k, 0)) for k in ('gyro_dropped_nan', 'gyro_dropped_out_of_order',
                                                  'gyro_dropped_duplicate'))
        return {'rate_hz': rate_hz, 'seconds': seconds, 'sent': n_total,
                'send_wall_s': send_wall, 'achieved_input_hz': n_total / send_wall,
                'accepted_by_node': int(kv.get('gyro_accepted', -1)),
                'missing_in_node': int(kv.get('gyro_missing_samples', -1)),
                'dropped_in_node': dropped,
                'attitude_outputs_received': outputs[0],
                'attitude_outputs_expected': expected_out}
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
