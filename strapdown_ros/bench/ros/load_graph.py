"""
The full node graph under load, for ``load_bench``: four node processes and a monitor.

``imu_sim_node``, ``star_camera_sim_node``, ``sins_node`` and ``calibrator_node`` run as
separate processes (``python -m strapdown_ros.nodes.<node>``, as ``ros2 run`` starts them) on
loopback in one namespace, at ``rate_factor`` × the nominal sensor rates (gyro 100 Hz,
accelerometer 300 Hz, one camera fix every 20 s) in real time, on the bench trajectory
(004 §6).  With ``reliable_streams`` the stream topics are switched to RELIABLE through the
standard ``qos_overrides`` parameters, on both ends.

The consumers start first; the simulators start their clocks once every consumer is matched
(``wait_for_subscribers``), so nothing is lost to discovery.  A monitor node in this process
(events executor, like the nodes) subscribes to the inputs and outputs of the graph:

* **loss** per path: what the publisher counted (its ``/diagnostics``) against what the
  subscriber counted (its ``/diagnostics``, or the monitor's own count and sequence gaps);
* **end-to-end latency**: the monitor's receipt of a Δθ → its receipt of the ``sins/attitude``
  with the same stamp; its receipt of a camera fix → its receipt of the ``calibration/boresight``
  solved with that fix.  Input and output reach the same subscriber, so its own transport and
  dispatch delays largely cancel.  (rclpy's message-info callbacks, which carry the DDS source
  timestamp, are not supported by the events executor, and the SingleThreadedExecutor costs
  about four times the CPU per message: it would load the machine it measures);
* **resident memory** (``/proc/<pid>/status`` VmRSS) and CPU time of every node process, sampled
  every second.

Nothing here is asserted; :mod:`strapdown_ros.bench.ros.load_bench` prints and judges the
figures.
"""
from __future__ import annotations

from collections import deque
import math
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from typing import Callable

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseWithCovarianceStamped, QuaternionStamped, Vector3Stamped
import numpy as np
import rclpy
from rclpy.qos import ReliabilityPolicy
from sensor_msgs.msg import Imu

from strapdown_ros.nodes.ros_io import (camera_qos, DIAGNOSTICS_QOS, latched_qos, stamp_to_ns,
                                        stream_qos)
from strapdown_ros.nodes.ros_process import make_executor

NODES = ('sins_node', 'calibrator_node', 'imu_sim_node', 'star_camera_sim_node')

#: topics whose QoS the graph switches with ``qos_overrides`` (topic, publisher or subscription)
STREAM_ENDPOINTS = {
    'imu_sim_node': [
        ('imu/delta_theta', 'publisher'),
        ('imu/delta_velocity', 'publisher'),
        ('imu/data_raw', 'publisher'),
        ('imu/truth/attitude', 'publisher'),
    ],
    'star_camera_sim_node': [
        ('star_camera/attitude', 'publisher'),
        ('star_camera/attitude_with_covariance', 'publisher'),
    ],
    'sins_node': [
        ('imu/delta_theta', 'subscription'),
        ('imu/delta_velocity', 'subscription'),
        ('sins/attitude', 'publisher'),
        ('sins/imu', 'publisher'),
    ],
    'calibrator_node': [
        ('imu/delta_theta', 'subscription'),
        ('star_camera/attitude_with_covariance', 'subscription'),
        ('calibration/imu_attitude_from_camera', 'publisher'),
    ],
}

NOMINAL = {'gyro_rate': 100.0, 'accel_rate': 300.0, 'camera_interval': 20.0}
BENCH_HOLD_S, BENCH_PASS_S = 20.0, 150.0            # bench profile: hold, then 150 s per pass
PAGE_KIB = os.sysconf('SC_PAGE_SIZE') / 1024.0
CLOCK_TICKS = os.sysconf('SC_CLK_TCK')


def node_parameters(ns: str, rate_factor: float, seconds: float,
                    reliable_streams: bool) -> dict[str, dict]:
    """
    Return the ``-p`` parameters of each node process.

    Parameters
    ----------
    ns : str
        Namespace of the graph (the QoS override names include it).
    rate_factor : float
        Multiple of the nominal sensor rates.
    seconds : float
        Sensor time to run, s (sets the bench passes).
    reliable_streams : bool
        Switch the stream topics to RELIABLE on both ends.

    Returns
    -------
    dict
        Node name → parameter name → value.

    """
    gyro, accel = NOMINAL['gyro_rate'] * rate_factor, NOMINAL['accel_rate'] * rate_factor
    passes = max(1, math.ceil((seconds - BENCH_HOLD_S) / BENCH_PASS_S))
    profile = {
        'profile': 'bench',
        'bench_repeat': passes,
        'duration': float(seconds),
        'time_scale': 1.0,
    }
    params = {
        'imu_sim_node': {
            **profile,
            'gyro_rate': gyro,
            'accel_rate': accel,
            'seed': 1,
            'wait_for_subscribers': 3,
        },  # sins, calibrator, monitor
        'star_camera_sim_node': {
            **profile,
            'camera_interval': NOMINAL['camera_interval'] / rate_factor,
            'boresight': [0.01, -0.02, 0.03],
            'seed': 2,
            'wait_for_subscribers': 2,
        },  # calibrator, monitor
        'sins_node': {'gyro_rate': gyro, 'accel_rate': accel},
        'calibrator_node': {'gyro_rate': gyro},
    }
    # history of every stream endpoint: 2 s of the fastest stream, so that a process descheduled
    # for a moment on a busy machine catches up instead of overwriting (KEEP_LAST, both ends)
    depth = max(500, int(2 * accel))
    for node in params:
        params[node]['qos_depth'] = depth
    if reliable_streams:
        for node, endpoints in STREAM_ENDPOINTS.items():
            for topic, kind in endpoints:
                params[node][f'qos_overrides.{ns}/{topic}.{kind}.reliability'] = 'reliable'
    return params


def _ros_value(v) -> str:
    if isinstance(v, bool):
        return 'true' if v else 'false'
    if isinstance(v, (list, tuple)):
        return '[' + ','.join(_ros_value(x) for x in v) + ']'
    return str(v)


def _command(node: str, ns: str, params: dict) -> list[str]:
    cmd = [sys.executable, '-m', f'strapdown_ros.nodes.{node}', '--ros-args', '-r', f'__ns:={ns}']
    for k, v in params.items():
        cmd += ['-p', f'{k}:={_ros_value(v)}']
    return cmd


class ProcessSampler:
    """
    Resident memory (KiB) and CPU seconds of a process, from /proc.

    Parameters
    ----------
    pid : int
        The process.

    """

    def __init__(self, pid: int):
        self.pid = pid

    def rss_kib(self) -> float:
        """Return the resident memory, KiB (NaN once the process is gone)."""
        try:
            with open(f'/proc/{self.pid}/statm', encoding='ascii') as fh:
                return int(fh.read().split()[1]) * PAGE_KIB
        except (OSError, IndexError, ValueError):
            return math.nan

    def cpu_s(self) -> float:
        """Return the user + system CPU time, s (NaN once the process is gone)."""
        try:
            with open(f'/proc/{self.pid}/stat', encoding='ascii') as fh:
                fields = fh.read().rsplit(')', 1)[1].split()
            return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS      # utime + stime
        except (OSError, IndexError, ValueError):
            return math.nan


def run_graph(seconds: float = 600.0, rate_factor: float = 10.0, reliable_streams: bool = True,
              warmup: float = 30.0, progress: Callable[[str], None] | None = None) -> dict:
    """
    Run the graph for ``seconds`` of sensor time and return the raw figures.

    Parameters
    ----------
    seconds : float, optional
        Sensor time, s.
    rate_factor : float, optional
        Multiple of the nominal sensor rates.
    reliable_streams : bool, optional
        Switch the stream topics to RELIABLE.
    warmup : float, optional
        Memory growth is measured from this many seconds after the first Δθ.
    progress : callable, optional
        Called with one line of progress text.

    Returns
    -------
    dict
        Counts, latencies (ns), memory and CPU series, the nodes' last /diagnostics, exit codes
        (see the module docstring).

    """
    say = progress or (lambda s: None)
    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.setdefault('ROS_DOMAIN_ID', str(random.randint(1, 100)))
    os.environ.update({k: env[k] for k in ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_DOMAIN_ID')})
    ns = f'/load_{os.getpid()}'
    params = node_parameters(ns, rate_factor, seconds, reliable_streams)
    procs: dict[str, subprocess.Popen] = {}
    log_dir = tempfile.mkdtemp(prefix='load_bench_')
    logs = {n: open(os.path.join(log_dir, f'{n}.log'), 'w', encoding='utf-8')
            for n in NODES}
    rclpy.init()
    mon = rclpy.create_node('load_monitor', namespace=ns)
    ex = make_executor()
    ex.add_node(mon)
    depth = 10000
    sq = stream_qos(depth)
    if reliable_streams:
        sq.reliability = ReliabilityPolicy.RELIABLE
    count = dict.fromkeys(('delta_theta', 'camera', 'attitude', 'imu', 'boresight'), 0)
    t_dtheta: dict[int, int] = {}                             # stamp → monitor receive time, ns
    t_dtheta_keys: deque = deque()
    t_fix: dict[int, int] = {}
    lat = {'delta_theta_to_attitude': [], 'fix_to_boresight': []}
    diags: dict[str, dict] = {}
    first_dtheta = [None]
    now_ns = time.monotonic_ns

    def on_dtheta(msg):
        count['delta_theta'] += 1
        s = stamp_to_ns(msg.header.stamp)
        t_dtheta[s] = now_ns()
        t_dtheta_keys.append(s)
        if len(t_dtheta_keys) > 100000:                       # bounded: 100 s at 1 kHz
            t_dtheta.pop(t_dtheta_keys.popleft(), None)
        if first_dtheta[0] is None:
            first_dtheta[0] = time.monotonic()

    def on_attitude(msg):
        t = now_ns()
        count['attitude'] += 1
        t_in = t_dtheta.get(stamp_to_ns(msg.header.stamp))
        if t_in is not None:
            lat['delta_theta_to_attitude'].append(t - t_in)

    def on_imu(msg):
        count['imu'] += 1

    def on_fix(msg):
        count['camera'] += 1
        t_fix[stamp_to_ns(msg.header.stamp)] = now_ns()

    def on_boresight(msg):
        t = now_ns()
        count['boresight'] += 1
        t_in = t_fix.get(stamp_to_ns(msg.header.stamp))
        if t_in is not None:
            lat['fix_to_boresight'].append(t - t_in)

    def on_diag(msg):
        for st in msg.status:
            if st.name.startswith(ns + '/'):
                node = st.name[len(ns) + 1:].split(':', 1)[0]
                diags[node] = {
                    'level': st.level[0] if isinstance(st.level, bytes) else int(st.level),
                    'message': st.message,
                    **{kv.key: kv.value for kv in st.values},
                    '_received': time.monotonic(),
                }

    mon.create_subscription(Vector3Stamped, 'imu/delta_theta', on_dtheta, sq)
    mon.create_subscription(QuaternionStamped, 'sins/attitude', on_attitude, sq)
    mon.create_subscription(Imu, 'sins/imu', on_imu, sq)
    mon.create_subscription(PoseWithCovarianceStamped, 'star_camera/attitude_with_covariance',
                            on_fix, camera_qos(depth))
    mon.create_subscription(PoseWithCovarianceStamped, 'calibration/boresight', on_boresight,
                            latched_qos())
    mon.create_subscription(DiagnosticArray, '/diagnostics', on_diag, DIAGNOSTICS_QOS)

    samplers: dict[str, ProcessSampler] = {}
    series = {'t': [], **{n: [] for n in NODES}}
    cpu0: dict[str, float] = {}
    result: dict = {
        'seconds': seconds,
        'rate_factor': rate_factor,
        'reliable_streams': reliable_streams,
        'warmup_s': warmup,
        'namespace': ns,
        'ros_domain_id': int(env['ROS_DOMAIN_ID']),
        'load_at_start': list(os.getloadavg()),
        'logs': log_dir,
        'cpu_count': os.cpu_count(),
        'rates_hz': {
            'gyro': params['imu_sim_node']['gyro_rate'],
            'accel': params['imu_sim_node']['accel_rate'],
            'camera': 1.0 / params['star_camera_sim_node']['camera_interval'],
        },
    }

    def spin_for(dt: float, until: Callable[[], bool] | None = None) -> bool:
        end = time.monotonic() + dt
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.01)
            if until is not None and until():
                return True
        return False

    def launch(node: str):
        procs[node] = subprocess.Popen(_command(node, ns,
                                                params[node]), env=env, stdout=logs[node],
                                       stderr=subprocess.STDOUT, start_new_session=True)
        samplers[node] = ProcessSampler(procs[node].pid)

    try:
        for node in ('sins_node', 'calibrator_node'):
            launch(node)
        say('consumers started; waiting for their /diagnostics')
        if not spin_for(60.0, lambda: all(n in diags for n in ('sins_node', 'calibrator_node'))):
            raise RuntimeError(
                f'sins_node/calibrator_node did not come up within 60 s (logs in {log_dir})')
        for node in ('imu_sim_node', 'star_camera_sim_node'):
            launch(node)
        say('simulators started; they start their clocks once every consumer is matched')
        if not spin_for(60.0, lambda: first_dtheta[0] is not None):
            raise RuntimeError(f'no Δθ within 60 s of starting imu_sim_node (logs in {log_dir})')
        t0 = first_dtheta[0]
        cpu0 = {n: s.cpu_s() for n, s in samplers.items()}
        deadline = t0 + seconds * 1.5 + 60.0
        next_sample, next_say = t0, t0 + 30.0

        def finished():
            return all(diags.get(n, {}).get('finished') == 'True'
                       for n in ('imu_sim_node', 'star_camera_sim_node'))

        while time.monotonic() < deadline and not finished():
            ex.spin_once(timeout_sec=0.01)
            now = time.monotonic()
            if now >= next_sample:
                series['t'].append(now - t0)
                for n, s in samplers.items():
                    series[n].append(s.rss_kib())
                next_sample += 1.0
            if now >= next_say:
                say(
                    f"{now - t0:5.0f}/{seconds:.0f} s: Δθ {count['delta_theta']}, attitude"
                    f" {count['attitude']}, fixes {count['camera']}, boresight"
                    f" {count['boresight']}; RSS "
                    + ', '.join(f"{n.split('_')[0]} {series[n][-1] / 1024:.0f} MiB" for n in NODES)
                )
                next_say += 30.0
            if any(p.poll() is not None for p in procs.values()):
                break
        result['finished'] = finished()
        result['wall_s'] = time.monotonic() - t0
        cpu1 = {n: s.cpu_s() for n, s in samplers.items()}
        # drain, then wait for a /diagnostics of every node issued after the end
        mark = time.monotonic()
        spin_for(3.0)
        spin_for(10.0, lambda: all(diags.get(n, {}).get('_received', 0) > mark for n in NODES))
        series['t'].append(time.monotonic() - t0)
        for n, s in samplers.items():
            series[n].append(s.rss_kib())
        result['diagnostics'] = {
            n: {k: v for k, v in d.items() if k != '_received'} for n, d in diags.items()
        }
        result['monitor'] = {k: {'received': v} for k, v in count.items()}
        result['latency_ns'] = {k: np.asarray(v, dtype=np.int64) for k, v in lat.items()}
        result['rss_kib'] = {k: np.asarray(v, dtype=float) for k, v in series.items()}
        result['cpu_s'] = {n: cpu1[n] - cpu0.get(n, math.nan) for n in cpu1}
        result['exit_codes'] = {n: p.poll()
                                for n, p in procs.items()}  # None: still running (normal)
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        codes = {}
        for n, p in procs.items():
            try:
                codes[n] = p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                codes[n] = 'killed'
        result['exit_codes_after_sigint'] = codes
        for fh in logs.values():
            fh.close()
        ex.remove_node(mon)
        mon.destroy_node()
        rclpy.try_shutdown()
    return result
