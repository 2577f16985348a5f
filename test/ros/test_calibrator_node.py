"""
Calibration node tests: imu_sim_node + star_camera_sim_node + calibrator_node spun in-process.

Plain pytest (no launch_testing); each test runs its graph in its own namespace, the session
has its own ROS_DOMAIN_ID and LOCALHOST discovery (conftest.py), and every wait has a timeout.
The estimate is checked against the simulated truth (β and the exact profile attitude) with
the covariance the calibrator publishes.
"""
import json
import math
import os
import re
import subprocess
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseWithCovarianceStamped, QuaternionStamped, Vector3Stamped
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from ros_helpers import spin_until

from strapdown_ros.bench.hostile_input import clean_recording, kind_named, streams_with
from strapdown_ros.bench.hostile_tools import problems
from strapdown_ros.bench.ros.hostile_nodes import run_node
from strapdown_ros.motion.profiles import bench_profile
from strapdown_ros.nodes.calibrator_node import CalibratorNode
from strapdown_ros.nodes.imu_sim_node import ImuSimNode
from strapdown_ros.nodes.ros_io import camera_qos, latched_qos, stamp_to_ns, stream_qos
from strapdown_ros.nodes.star_camera_sim_node import StarCameraSimNode
from strapdown_ros.rotation import (dcm_to_quat, from_ros_xyzw, quat_error_rotvec, quat_to_dcm,
                                    quat_to_rotvec, to_ros_xyzw, ypr_to_dcm)
from strapdown_ros.sensors import IntegratingSensor
from strapdown_ros.sensors.star_camera import StarCameraModel
from strapdown_ros.tools import calibrate_bag


ARCSEC = math.pi / 180.0 / 3600.0
BETA = np.radians([40.0, -25.0, 120.0])          # (ψ, ϑ, γ): far from small, as in 004 §1
C_TRUE = ypr_to_dcm(*BETA)
REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# The three nodes share one process here.  rclpy's SingleThreadedExecutor takes one message per
# subscription per wait-set rebuild; with the simulators in the same executor it drains about
# 2000 Δθ/s on a 2-core machine, so at 100 Hz it drops best-effort samples above ~20× real time
# (measured: 20% lost at 25×, 35% at 40×).  The EventsExecutor (rclpy.experimental, shipped with
# Jazzy's rclpy 7.1) has no such limit (no loss at 60×), so the simulated minutes run in seconds.
# Deployed, each node spins in its own process and this does not arise.
try:
    from rclpy.experimental import EventsExecutor as Executor
    MAX_TIME_SCALE = 50.0
except ImportError:                                        # older Jazzy rclpy
    Executor = SingleThreadedExecutor
    MAX_TIME_SCALE = 12.0
# History depth of the Δθ stream (simulator and calibrator) in these tests: more than the
# increments of a whole run, so that a stall of this process (a loaded CI machine: with two
# CPU hogs beside it, 0.1–70% of the samples were lost at the default depth 500) cannot
# overwrite samples.  Graph.run still fails, with the counts, if any increment is lost.
QUEUE = 20000


def q_of(msg):
    """Scalar-first quaternion of a Pose/Quaternion(Stamped) message."""
    q = msg.pose.pose.orientation if isinstance(msg, PoseWithCovarianceStamped) else msg.quaternion
    return from_ros_xyzw(np.array([q.x, q.y, q.z, q.w]))


def rot_cov(msg):
    """Return the rotation block of a pose covariance, rad²."""
    return np.asarray(msg.pose.covariance, dtype=float).reshape(6, 6)[3:, 3:]


def status_of(diags, prefix):
    """Return the latest diagnostic status whose name starts with ``prefix``."""
    st = [s for d in diags for s in d.status if s.name.startswith(prefix)]
    return st[-1] if st else None


class Graph:
    """The simulators, calibrator_node and a monitor node, in one namespace."""

    def __init__(self, ns, profile, time_scale, camera=(), calibrator=(), plain_peer=False):
        self.ns = ns
        prof = [Parameter(k, value=v) for k, v in profile.items()]
        depth = [Parameter('qos_depth', value=QUEUE)]
        self.calib = CalibratorNode(namespace=ns, parameter_overrides=[*depth, *calibrator])
        # optional second calibrator on star_camera/attitude (no covariance: σ from its
        # parameters),
        # in its own namespace with its inputs remapped to this graph's topics
        self.peer = CalibratorNode(namespace=ns + '_plain', parameter_overrides=[
            *depth, Parameter('use_camera_covariance', value=False)], cli_args=[
            '--ros-args', '-r', f'imu/delta_theta:={ns}/imu/delta_theta',
            '-r', f'star_camera/attitude:={ns}/star_camera/attitude']) if plain_peer else None
        self.sim = ImuSimNode(namespace=ns, parameter_overrides=[
            *prof, *depth, Parameter('gyro_rate', value=100.0),
            Parameter('accel_rate', value=10.0),   # Δv unused
            Parameter('time_scale', value=min(time_scale, MAX_TIME_SCALE))])
        self.cam = StarCameraSimNode(namespace=ns, parameter_overrides=[
            *prof, Parameter('boresight', value=[float(b) for b in BETA]),
            Parameter('time_scale', value=min(time_scale, MAX_TIME_SCALE)), *camera])
        self.mon = rclpy.create_node('monitor', namespace=ns)
        self.diags = []
        self.imu_att = []
        self.mon.create_subscription(DiagnosticArray, '/diagnostics', self.diags.append, 50)
        self.mon.create_subscription(PoseWithCovarianceStamped,
                                     'calibration/imu_attitude_from_camera',
                                     self.imu_att.append, camera_qos(100))
        self.ex = Executor()
        self.nodes = [self.calib, self.mon, self.sim,
                      self.cam] + ([self.peer] if self.peer else [])

    def run(self):
        """
        Run discovery, then both simulators to the end, until every message is taken.

        Discovery first (the simulators start their clocks at their first timer tick, so they join
        the executor only when the calibrator's subscriptions are matched), then run both
        simulators to the end and wait until the calibrator has taken every message.
        """
        for n in (self.calib, self.mon) + ((self.peer,) if self.peer else ()):
            self.ex.add_node(n)
        peers = 2 if self.peer else 1
        assert spin_until(self.ex, lambda: self.sim.pub_dtheta.get_subscription_count() >= peers
                          and self.cam.pub_cov.get_subscription_count() >= 1
                          and self.cam.pub_att.get_subscription_count() >= peers - 1,
                          10.0), 'discovery timed out'
        self.ex.add_node(self.sim)
        self.ex.add_node(self.cam)
        t0 = time.monotonic()
        timeout = 1.5 * self.sim.end_time / self.sim.p['time_scale'] + 5.0
        ok = spin_until(self.ex, lambda: self.sim.finished and self.cam.finished, timeout)
        self.wall = time.monotonic() - t0
        assert ok, (f'simulators did not finish in {timeout:.1f} s '
                    f'(imu t = {self.sim.sim_time}, camera t = {self.cam.sim_time})')
        spin_until(self.ex, self.all_received, 5.0)
        g, c = self.calib.gyro_check, self.calib.camera_check
        assert self.all_received(), (
            'calibrator lost input (best-effort queue overflow? lower time_scale): '
            f'gyro {g.received} of '
            f"{self.sim.counts['delta_theta']}, camera {c.received} of {self.cam.published}")
        assert (g.accepted, g.nan, g.out_of_order, g.duplicate, g.gaps, g.missing) == (g.received,
                                                                                       0, 0, 0, 0,
                                                                                       0)
        assert c.accepted == c.received == self.cam.published

    def all_received(self):
        """Tell whether every calibrator took every message published."""
        return all(n.gyro_check.received == self.sim.counts['delta_theta']
                   and n.camera_check.received == self.cam.published
                   for n in (self.calib, self.peer) if n is not None)

    def diagnostics(self):
        """Publish the calibrator status and return it with its key values."""
        self.calib.publish_diagnostics()
        prefix = f'{self.ns}/calibrator_node'
        n0 = sum(1 for d in self.diags for s in d.status if s.name.startswith(prefix))
        assert spin_until(self.ex, lambda: sum(1 for d in self.diags for s in d.status
                                               if s.name.startswith(prefix)) > n0, 5.0)
        st = status_of(self.diags, prefix)
        return st, {v.key: v.value for v in st.values}

    def late_subscriber(self, topic, typ, wait):
        """Subscribe late (latched QoS) and return what arrives within ``wait`` s."""
        got = []
        self.mon.create_subscription(typ, topic, got.append, latched_qos())
        spin_until(self.ex, lambda: bool(got), wait)
        return got

    def close(self):
        """Destroy the nodes and the executor."""
        for n in self.nodes:
            try:
                self.ex.remove_node(n)
            except Exception:                 # noqa: BLE001 (a node that never joined)
                pass
            n.destroy_node()


# -------------------------------------------------------------------------------------------
def test_bench_calibration_full_graph(ros):
    ns = '/t_calib_bench'
    g = Graph(ns, {'profile': 'bench', 'bench_earth_rate': True}, time_scale=25.0,
              camera=[Parameter('camera_interval', value=5.0)], plain_peer=True)
    try:
        g.run()
        cal = g.calib
        assert cal.published['boresight'] >= 1, cal.cal.solution.message
        # star_camera/attitude + σ parameters (the same σ as the simulator's) gives the same answer
        assert g.peer.published['boresight'] == cal.published['boresight']
        np.testing.assert_allclose(g.peer.cal.solution.beta, cal.cal.solution.beta, rtol=0,
                                   atol=1e-12)
        np.testing.assert_allclose(g.peer.cal.solution.rotation_covariance_mf,
                                   cal.cal.solution.rotation_covariance_mf,
                                   rtol=1e-9)

        # --- the estimate reaches a subscriber created after it was published (transient local)
        got = g.late_subscriber('calibration/boresight', PoseWithCovarianceStamped, 5.0)
        assert got, 'late subscriber got no calibration/boresight'
        msg = got[-1]
        assert msg.header.frame_id == 'imu_link'
        assert stamp_to_ns(msg.header.stamp) == 170_000_000_000            # t_E of the newest pair
        C = quat_to_dcm(q_of(msg))
        P = rot_cov(msg)
        cov6 = np.asarray(msg.pose.covariance).reshape(6, 6)
        # position: not estimated
        assert np.all(np.diag(cov6)[:3] == 1e9) and not np.any(cov6[:3, 3:])
        # rotation error in MF axes: C_pub = (I + [e×]) C_true
        e = quat_to_rotvec(dcm_to_quat(C @ C_TRUE.T))
        sig = np.sqrt(np.diag(P))
        np.testing.assert_allclose(P, P.T, atol=1e-30)
        assert np.all(np.linalg.eigvalsh(P) > 0), P
        assert np.all((sig > 0.1 * ARCSEC) & (sig < 60 * ARCSEC)), sig / ARCSEC
        assert np.all(np.abs(e) <= 3 * sig), (e / ARCSEC, sig / ARCSEC)

        ang = g.late_subscriber('calibration/boresight_angles', Vector3Stamped, 5.0)
        assert ang and ang[-1].header.stamp == msg.header.stamp
        beta = np.array([ang[-1].vector.x, ang[-1].vector.y, ang[-1].vector.z])
        assert np.all(np.abs(beta - BETA) < 60 * ARCSEC), (beta - BETA) / ARCSEC
        # the same rotation as the pose
        np.testing.assert_allclose(ypr_to_dcm(*beta), C, atol=1e-12)

        truth = g.late_subscriber('star_camera/truth/boresight', QuaternionStamped, 5.0)
        assert truth and np.allclose(quat_to_dcm(q_of(truth[-1])), C_TRUE, atol=1e-12)

        # --- the IMU attitude from each camera fix, against the exact profile attitude
        prof = bench_profile(earth_rate=True)
        spin_until(g.ex, lambda: len(g.imu_att) >= g.cam.published, 3.0)
        assert len(g.imu_att) == g.cam.published == 34
        t = np.array([stamp_to_ns(m.header.stamp) * 1e-9 for m in g.imu_att])
        np.testing.assert_allclose(t, 5.0 * np.arange(1, 35), atol=1e-9)
        z = []
        for m, tk in zip(g.imu_att, t):
            assert m.header.frame_id == 'gcrs'
            # MF axes, as P^mfa
            eps = quat_error_rotvec(q_of(m), prof.attitude(tk), frame='body')
            s = np.sqrt(np.diag(rot_cov(m)))
            assert np.all(s < 60 * ARCSEC)
            z.append(eps / s)
        z = np.abs(np.array(z))
        # 34 fixes × 3 axes: each within 4σ, and at least 95% within 3σ (all within 3σ is not a
        # property of a correct covariance over ~100 draws)
        assert np.all(z <= 4.0) and np.mean(z <= 3.0) >= 0.95, z.max(0)

        # --- graph: types and QoS
        types = dict(g.mon.get_topic_names_and_types())
        expect = {'calibration/boresight': 'geometry_msgs/msg/PoseWithCovarianceStamped',
                  'calibration/boresight_angles': 'geometry_msgs/msg/Vector3Stamped',
                  'calibration/imu_attitude_from_camera':
                      'geometry_msgs/msg/PoseWithCovarianceStamped',
                  'star_camera/attitude': 'geometry_msgs/msg/QuaternionStamped',
                  'star_camera/attitude_with_covariance':
                      'geometry_msgs/msg/PoseWithCovarianceStamped',
                  'star_camera/truth/boresight': 'geometry_msgs/msg/QuaternionStamped'}
        for topic, typ in expect.items():
            assert types[f'{ns}/{topic}'] == [typ], topic
        for topic, dur in (('calibration/boresight', DurabilityPolicy.TRANSIENT_LOCAL),
                           ('calibration/boresight_angles', DurabilityPolicy.TRANSIENT_LOCAL),
                           ('star_camera/attitude_with_covariance', DurabilityPolicy.VOLATILE),
                           ('star_camera/attitude', DurabilityPolicy.VOLATILE)):
            info = g.mon.get_publishers_info_by_topic(f'{ns}/{topic}')
            assert len(info) == 1
            assert info[0].qos_profile.durability == dur, topic
            assert info[0].qos_profile.reliability == ReliabilityPolicy.RELIABLE, topic
        sub = g.mon.get_subscriptions_info_by_topic(f'{ns}/imu/delta_theta')
        # both calibrators
        assert [i.qos_profile.reliability for i in sub] == [ReliabilityPolicy.BEST_EFFORT] * 2
        for topic in ('star_camera/attitude', 'star_camera/attitude_with_covariance'):
            sub = g.mon.get_subscriptions_info_by_topic(f'{ns}/{topic}')
            assert [i.qos_profile.reliability for i in sub] == [ReliabilityPolicy.RELIABLE], topic

        # --- diagnostics
        st, kv = g.diagnostics()
        assert st.level == b'\x00', st.message
        assert kv['observable'] == 'True' and kv['converged'] == 'True' and int(kv['pairs']) == 33
        assert kv['weighted'] == 'True' and float(kv['chi2_per_dof']) < 3.0
        assert (int(kv['gyro_received']) == g.sim.counts['delta_theta']
                and int(kv['camera_received']) == 34)
        assert float(kv['beta_yaw_deg']) == pytest.approx(40.0, abs=60 / 3600)
        assert 0.1 < float(kv['beta_yaw_sigma_arcsec']) < 60.0
        assert 0.0 < float(kv['last_solve_ms']) < 1000.0

        # --- runtime: only `weighted` may change; the estimate is recomputed at once
        n0 = cal.published['boresight']
        res = cal.set_parameters([Parameter('weighted', value=False)])[0]
        assert res.successful
        assert spin_until(g.ex, lambda: len(got) >= 2, 5.0)
        assert cal.published['boresight'] == n0 + 1 and not cal.cal.solution.weighted
        e_u = quat_to_rotvec(dcm_to_quat(quat_to_dcm(q_of(got[-1])) @ C_TRUE.T))
        sig_u = np.sqrt(np.diag(rot_cov(got[-1])))
        assert np.all(np.abs(e_u) <= 3 * sig_u), (e_u / ARCSEC, sig_u / ARCSEC)
        assert np.all(sig_u > sig), 'unit weights (004) should not beat the weighted estimate'
        res = cal.set_parameters([Parameter('max_pairs', value=5)])[0]
        assert not res.successful and 'only weighted can change' in res.reason
        print(f'\nbench graph: {g.wall:.1f} s wall; σ weighted {np.round(sig / ARCSEC, 2)}″, '
              f'unit weights {np.round(sig_u / ARCSEC, 2)}″; error {np.round(e / ARCSEC, 2)}″')
    finally:
        g.close()


def _piecewise(tmp_path, text):
    path = tmp_path / 'profile.yaml'
    path.write_text(text)
    return {'profile': 'piecewise', 'profile_file': str(path)}


def _not_observable(g, timeout=1.5):
    """Run to the end, then give the calibrator time: nothing on the calibration topics."""
    g.run()
    spin_until(g.ex, lambda: False, timeout)
    assert g.calib.published == {'boresight': 0, 'imu_attitude_from_camera': 0}
    assert not g.late_subscriber('calibration/boresight', PoseWithCovarianceStamped, 1.0)
    assert not g.imu_att
    st, kv = g.diagnostics()
    assert st.level == b'\x01' and kv['observable'] == 'False', (st.level, st.message)
    assert 'not observable' in st.message and st.message == kv['message']
    return st, kv


def test_single_axis_rotation_is_reported_not_observable(ros, tmp_path):
    segs = ['  - {duration: 10.0}']
    for r in (0.05, -0.04, 0.03, -0.05, 0.04, -0.03):
        segs += [f'  - {{duration: 5.0, rate: [0, 0, {r}]}}', '  - {duration: 10.0}']
    # 100 s
    prof = _piecewise(tmp_path, 'earth_rate: [0, 0, 0]\nsegments:\n' + '\n'.join(segs) + '\n')
    g = Graph('/t_calib_axis', prof, time_scale=25.0,
              camera=[Parameter('camera_interval', value=5.0)])
    try:
        st, kv = _not_observable(g)
        assert 'one axis' in st.message
        assert int(kv['pairs']) == 19
        m = re.search(r'VF axis \(([-\d.]+), ([-\d.]+), ([-\d.]+)\)', st.message)
        assert m, st.message
        axis = np.array([float(x) for x in m.groups()])
        expected = C_TRUE.T @ np.array([0.0, 0.0, 1.0])          # MF z seen in VF
        angle = np.degrees(np.arccos(min(1.0, abs(axis @ expected) / np.linalg.norm(axis))))
        assert angle < 2.0, (axis, expected)
    finally:
        g.close()


def test_static_motion_is_reported_not_observable(ros, tmp_path):
    prof = _piecewise(tmp_path,
                      'earth_rate: [0, 4.6e-5, 5.6e-5]\nsegments:\n  - {duration: 150.0}\n')
    g = Graph('/t_calib_static', prof, time_scale=30.0,
              camera=[Parameter('camera_interval', value=5.0)])
    try:
        st, kv = _not_observable(g)
        # the Earth rate turns the bench 0.62° about one axis in 150 s: judged over the
        # recording (not pair by pair) that is a turn about one axis, not observable either
        assert ('static' in st.message or 'one axis' in st.message) and int(kv['pairs']) == 29
    finally:
        g.close()


def test_bad_camera_and_gyro_input_is_dropped_counted_and_reported(ros):
    ns = '/t_calib_bad'
    cal = CalibratorNode(namespace=ns)
    src = rclpy.create_node('source', namespace=ns)
    pub_g = src.create_publisher(Vector3Stamped, 'imu/delta_theta', stream_qos())
    pub_c = src.create_publisher(PoseWithCovarianceStamped, 'star_camera/attitude_with_covariance',
                                 camera_qos(10))
    diags = []
    src.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 10)
    ex = Executor()
    for n in (cal, src):
        ex.add_node(n)
    try:
        assert spin_until(ex, lambda: pub_g.get_subscription_count() >= 1
                          and pub_c.get_subscription_count() >= 1
                          and src.count_publishers('/diagnostics') >= 1, 10.0)

        def gyro(k, v=(1e-4, 0.0, 0.0)):
            m = Vector3Stamped()
            m.header.stamp.sec, m.header.stamp.nanosec = 50 + k // 100, (k % 100) * 10_000_000
            m.vector.x, m.vector.y, m.vector.z = v
            pub_g.publish(m)

        def camera(sec, q_xyzw, cov=np.diag([1e-11, 1e-11, 1e-9])):
            m = PoseWithCovarianceStamped()
            m.header.stamp.sec = sec
            m.header.frame_id = 'gcrs'
            o = m.pose.pose.orientation
            o.x, o.y, o.z, o.w = q_xyzw
            c6 = np.zeros((6, 6))
            c6[3:, 3:] = cov
            m.pose.covariance = [float(x) for x in c6.ravel()]
            pub_c.publish(m)

        camera(51, (0.0, 0.0, 0.0, 2.0))                 # non-unit: normalised, accepted
        camera(52, (0.0, 0.0, 0.0, 0.0))                 # zero: dropped
        camera(52, (float('nan'), 0.0, 0.0, 1.0))        # NaN: dropped
        camera(52, (0.0, 0.0, 0.0, 1.0), cov=np.diag([1e-11, -1e-9, 1e-9]))   # not PSD: dropped
        camera(52, (0.0, 0.0, 0.0, 1.0))                 # accepted
        camera(52, (0.0, 0.0, 0.0, 1.0))                 # duplicate stamp
        camera(51, (0.0, 0.0, 0.0, 1.0))                 # out of order
        for k in range(1, 251):
            if k == 120:
                continue                                 # a gap inside the pair (51 s, 52 s]
            gyro(k)
            if k % 20 == 0:
                ex.spin_once(timeout_sec=0.005)
        gyro(250)                                        # duplicate
        gyro(10, (float('nan'), 0.0, 0.0))               # NaN
        assert spin_until(ex, lambda: cal.gyro_check.received >= 251
                          and cal.camera_check.received >= 7, 5.0)
        g, c = cal.gyro_check, cal.camera_check
        assert (g.accepted, g.nan, g.duplicate, g.gaps, g.missing) == (249, 1, 1, 1, 1)
        assert (c.accepted, c.duplicate, c.out_of_order) == (2, 1, 1)
        assert cal.fix_screen.nan == 1                   # THE screening of a fix counts it
        assert (cal.camera_counts['normalised'] == 1
                and cal.camera_counts['dropped_zero_quaternion'] == 1)
        assert cal.camera_counts['dropped_bad_covariance'] == 1
        # the only pair spans the gap
        assert cal.pairs_discarded_gap == 1 and cal.cal.pairs == []
        assert cal.published['boresight'] == 0
        cal.publish_diagnostics()
        assert spin_until(ex, lambda: status_of(diags, f'{ns}/calibrator_node') is not None, 5.0)
        st = status_of(diags, f'{ns}/calibrator_node')
        kv = {v.key: v.value for v in st.values}
        assert st.level == b'\x02' and 'missing' in st.message and 'discarded' in st.message
        assert (kv['gyro_dropped_nan'], kv['camera_dropped_zero_quaternion'],
                kv['camera_normalised']) == ('1', '1', '1')
    finally:
        for n in (cal, src):
            ex.remove_node(n)
            n.destroy_node()


def test_invalid_parameters_are_refused_with_the_valid_values(ros):
    with pytest.raises(ValueError, match=r"covariance_model='bogus' is not valid; "
                                         r'valid values: random_constant, 004'):
        CalibratorNode(namespace='/t_calib_refuse1',
                       parameter_overrides=[Parameter('covariance_model', value='bogus')])
    with pytest.raises(ValueError,
                       match=r'camera_interval=-1.0 is out of range; valid: > 0 and <= 3600'):
        StarCameraSimNode(namespace='/t_calib_refuse2',
                          parameter_overrides=[Parameter('camera_interval', value=-1.0)])
    with pytest.raises(ValueError, match=r'max_sigma=0.0 is out of range; valid: > 0'):
        CalibratorNode(namespace='/t_calib_refuse3',
                       parameter_overrides=[Parameter('max_sigma', value=0.0)])
    with pytest.raises(ValueError, match='valid values: coning, tkachenko, bench, piecewise'):
        StarCameraSimNode(namespace='/t_calib_refuse4',
                          parameter_overrides=[Parameter('profile', value='spiral')])
    cam = StarCameraSimNode(namespace='/t_calib_refuse5')
    try:
        res = cam.set_parameters([Parameter('camera_interval', value=1.0)])[0]
        assert not res.successful and 'fixed after start-up' in res.reason
    finally:
        cam.destroy_node()


@pytest.mark.parametrize('module, arg, text', [
    ('calibrator_node', 'covariance_model:=bogus',
     "covariance_model='bogus' is not valid; valid values: random_constant, 004"),
    ('star_camera_sim_node', 'camera_interval:=-1.0',
     'camera_interval=-1.0 is out of range; valid: > 0'),
])
def test_executables_exit_2_with_a_clear_message(module, arg, text):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([REPO, os.environ.get('PYTHONPATH', '')]))
    res = subprocess.run([sys.executable, '-m', f'strapdown_ros.nodes.{module}', '--ros-args',
                          '-p', arg],
                         capture_output=True, text=True, timeout=60, env=env)
    assert res.returncode == 2, res.stderr
    assert text in res.stderr


def _node_estimate(ns, poison: bool, params=(), keep=False, noise_scale=1.0):
    """Feed calibrator_node bench data through its own callbacks (no DDS): (β, node counters)."""
    prof = bench_profile()
    gyro = IntegratingSensor(prof, 'gyro', 100.0)
    t, dth, _ = gyro.sample(int(prof.duration * 100) - 1)
    cam = StarCameraModel(boresight=np.radians([40.0, -25.0, 120.0]), interval=5.0, seed=1,
                          noise_scale=np.full(3, noise_scale))
    fixes = cam.fixes(prof, int(prof.duration / 5.0) - 1)
    cal = CalibratorNode(namespace=ns, parameter_overrides=list(params))
    try:
        def stamp(m, s):
            ns_ = int(round((1000.0 + s) * 1e9))
            m.header.stamp.sec, m.header.stamp.nanosec = ns_ // 10**9, ns_ % 10**9
        events = [(s, 0, v) for s, v in zip(t, dth)] + [(f.stamp, 1, f) for f in fixes]
        for k, (s, kind, v) in enumerate(sorted(events, key=lambda e: (e[0], e[1]))):
            if kind == 0:
                m = Vector3Stamped()
                stamp(m, s)
                m.vector.x, m.vector.y, m.vector.z = (float(c) for c in v)
                cal.on_gyro(m)
                # one overflowing increment, its own stamp
                if poison and k == 5000:
                    bad = Vector3Stamped()
                    stamp(bad, s + 0.004)
                    bad.vector.x, bad.vector.y = 1e308, 1e308
                    cal.on_gyro(bad)
            else:
                m = PoseWithCovarianceStamped()
                stamp(m, s)
                m.header.frame_id = 'gcrs'
                o = m.pose.pose.orientation
                o.x, o.y, o.z, o.w = (float(c) for c in to_ros_xyzw(v.attitude))
                c6 = np.zeros((6, 6))
                c6[3:, 3:] = v.covariance
                m.pose.covariance = [float(x) for x in c6.ravel()]
                cal.on_camera_cov(m)
        if keep:
            return cal
        return np.array(cal.valid.beta), cal.gyro_check.out_of_range, cal.solve_failures
    finally:
        if not keep:
            cal.destroy_node()


def test_overflowing_increment_is_rejected_and_loses_nothing(ros):
    """
    Check: overflowing increment is rejected and loses nothing.

    Δθ = (1e308, 1e308, 0) used to crash the node with LinAlgError and lose every pair.  Now the
    sensor range rejects it; the estimate is the one without it.
    """
    beta_clean, _, _ = _node_estimate('/t_clean', poison=False)
    beta, out_of_range, failures = _node_estimate('/t_poison', poison=True)
    assert out_of_range == 1 and failures == 0
    np.testing.assert_array_equal(beta, beta_clean)


def test_overflowing_fixes_are_dropped_counted_and_cost_nothing(ros):
    """
    Issue 27, findings 1, 2, 5: fixes that crashed the node or were taken when they were not.

    One more fix with a rotation-block covariance of 1e308 (eigvalsh raised), one scaled by
    1e200 (its norm overflowed), one with a singular covariance: each is dropped and counted by
    the one screening of a fix; the estimate is the clean one to the bit.
    """
    rec = clean_recording()
    clean = run_node('calibrator_node', rec)
    assert clean.traceback is None and clean.estimate is not None
    for name, reason in (('huge_covariance', 'bad_covariance'), ('scaled_1e200', 'not_unit'),
                         ('singular_covariance', 'bad_covariance')):
        kind = kind_named(f'reference:{name}')
        got = run_node('calibrator_node', streams_with(rec, kind, 10, frames_used=False))
        assert problems(kind, clean, got) == []
        assert got.read['reference']['dropped'][reason] == 1
        np.testing.assert_array_equal(got.estimate, clean.estimate)


def test_inconsistent_noise_is_a_warn_with_the_reason(ros):
    """
    Check: inconsistent noise is a warn with the reason.

    Camera noise 100× the σ its covariance states: /diagnostics WARN saying the fit is inconsistent
    (χ²/dof outside its band), fit_consistent False; no good fix dropped as an outlier.  With the
    stated noise right: fit_consistent True.
    """
    for scale in (1.0, 100.0):
        # the simulated gyro is ideal: so is the stated gyro model, the camera σ is the one judged
        ideal = [Parameter(f'gyro_{k}', value=0.0)
                 for k in ('bias_sigma', 'scale_sigma', 'misalignment_sigma', 'random_walk')]
        node = _node_estimate(f'/t_fit_{int(scale)}', poison=False, keep=True, noise_scale=scale,
                              params=ideal)
        try:
            sent = []
            node.pub_diag.publish = sent.append
            node.publish_diagnostics()
            st = sent[-1].status[0]
            kv = {v.key: v.value for v in st.values}
            assert kv['camera_outlier_fixes'] == '0' and kv['pairs'] == '32'
            lo, hi, chi2 = (float(kv[k]) for k in ('chi2_per_dof_band_low',
                                                   'chi2_per_dof_band_high', 'chi2_per_dof'))
            if scale == 1.0:
                assert kv['fit_consistent'] == 'True' and lo <= chi2 <= hi
                assert 'INCONSISTENT' not in st.message
            else:
                assert kv['fit_consistent'] == 'False' and chi2 > 100 * hi
                assert st.level == b'\x01', st.message
                assert 'FIT INCONSISTENT' in st.message and 'band' in st.message, st.message
        finally:
            node.destroy_node()


def test_restart_resumes_the_same_estimate_and_a_corrupted_state_is_moved_aside(ros, tmp_path):
    """
    Check: restart resumes the same estimate and a corrupted state is moved aside.

    Restart without loss: the pairs and estimate persist to state_file (atomic, after every new
    pair); a restarted node resumes the same estimate and republishes it latched; replaying the
    same recording into it adds no pair; a corrupted file is reported and moved aside, never used;
    no temporary is left behind.
    """
    state = str(tmp_path / 'calib_state.npz')
    sf = [Parameter('state_file', value=state)]
    beta, _, _ = _node_estimate('/t_state', poison=False, params=sf)
    assert sorted(os.listdir(tmp_path)) == ['calib_state.npz', 'calib_state.npz.lock']
    node = CalibratorNode(namespace='/t_state', parameter_overrides=sf)
    try:
        # 33 fixes
        assert node.state['restored_pairs'] == 32 and node.published['boresight'] == 1
        np.testing.assert_allclose(node.valid.beta, beta, rtol=0, atol=1e-12)
    finally:
        node.destroy_node()
    node = _node_estimate('/t_state', poison=False, params=sf, keep=True)
    try:                                          # the same recording replayed into it
        assert len(node.cal.pairs) == 32 and node.cal.replayed_pairs == 32
        assert node.state['errors'] == 0
        np.testing.assert_allclose(node.valid.beta, beta, rtol=0, atol=1e-12)
    finally:
        node.destroy_node()
    with open(state, 'wb') as fh:
        fh.write(b'not a state file')
    node = CalibratorNode(namespace='/t_state', parameter_overrides=sf)
    try:
        assert (node.state['errors'] == 1 and node.cal.pairs == []
                and node.published['boresight'] == 0)
        assert not os.path.exists(state) and os.path.exists(state + '.corrupt')
    finally:
        node.destroy_node()


def test_state_file_identity_lock_and_paths(ros, tmp_path):
    """
    Check: state file identity lock and paths.

    The state file in the node: a state of another calibration (another camera frame) is refused
    with the reason and left as it is; a second node on the same file gets an ERROR and runs
    without persistence; a directory (with or without a trailing slash) is refused and never moved.
    """
    state = str(tmp_path / 's.npz')
    _node_estimate('/t_sid', poison=False, params=[Parameter('state_file', value=state)])
    before = open(state, 'rb').read()

    def diag(node):
        sent = []
        node.pub_diag.publish = sent.append
        node.publish_diagnostics()
        st = sent[-1].status[0]
        return st, {v.key: v.value for v in st.values}

    other = CalibratorNode(namespace='/t_sid', parameter_overrides=[
        Parameter('state_file', value=state), Parameter('camera_frame_id', value='camera2')])
    try:
        st, kv = diag(other)
        assert other.cal.pairs == [] and kv['state_persisting'] == 'False' and st.level == b'\x02'
        assert 'refused' in st.message and 'camera_frame_id' in st.message
    finally:
        other.destroy_node()
    assert open(state, 'rb').read() == before
    sf = [Parameter('state_file', value=state)]
    first = CalibratorNode(namespace='/t_sid', parameter_overrides=sf)
    second = CalibratorNode(namespace='/t_sid', parameter_overrides=sf)
    try:
        assert first.state['persisting'] and first.state['restored_pairs'] == 32
        st, kv = diag(second)
        assert kv['state_persisting'] == 'False' and st.level == b'\x02' and 'in use' in st.message
        assert second.cal.pairs == []
    finally:
        second.destroy_node()
        first.destroy_node()
    d = tmp_path / 'adir'
    d.mkdir()
    for path in (str(d), str(d) + '/'):
        node = CalibratorNode(namespace='/t_sid',
                              parameter_overrides=[Parameter('state_file', value=path)])
        try:
            st, kv = diag(node)
            assert kv['state_persisting'] == 'False'
            assert 'directory' in st.message or 'separator' in st.message
        finally:
            node.destroy_node()
    assert d.is_dir() and not [f for f in os.listdir(tmp_path) if 'corrupt' in f]


def test_one_input_path_node_and_calibrate_bag_agree_on_a_hostile_stream(ros, tmp_path):
    """
    Check: one input path node and calibrate bag agree on a hostile stream.

    One input path: the same hostile stream (NaN, duplicate, out-of-order, impossible and
    far-future increments; a zero and a non-unit camera quaternion) fed to calibrator_node and
    written to a bag for calibrate_bag gives the same counts and the same estimate.
    """
    pytest.importorskip('rosbags')
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import get_typestore, Stores

    prof = bench_profile()
    t, dth, _ = IntegratingSensor(prof, 'gyro', 100.0).sample(int(prof.duration * 100) - 1)
    fixes = StarCameraModel(boresight=np.radians([40.0, -25.0, 120.0]), interval=5.0,
                            seed=1).fixes(
        prof, int(prof.duration / 5.0) - 1)
    base = 1_000_000_000_000
    gyro = [(base + int(round(s * 1e9)), tuple(map(float, v))) for s, v in zip(t, dth)]
    # a burst of 5 increments stamped 1000 s in the past at t = 62.5 s
    # (inside the pair of the fixes at 60 and 65 s); then the stream returns to its timeline
    for k in range(6250, 6255):
        gyro[k] = (gyro[k][0] - 1000 * 10**9, gyro[k][1])
    # NaN, duplicate
    hostile = [(gyro[100][0] + 1, (float('nan'), 0.0, 0.0)), (gyro[200][0], gyro[200][1]),
               # older, huge
               (gyro[250][0] - 30_000_000, gyro[250][1]), (gyro[300][0] + 2, (1e308, 1e308, 0.0)),
               # far future
               (gyro[400][0] + 10**15, gyro[400][1])]
    at = {100: hostile[0], 200: hostile[1], 250: hostile[2], 300: hostile[3], 400: hostile[4]}
    stream = []
    for k, g in enumerate(gyro):
        stream.append(('g', g[0], g[1]))
        if k in at:
            stream.append(('g',) + at[k])
    cams = [(base + int(round(f.stamp * 1e9)), to_ros_xyzw(f.attitude),
             f.covariance) for f in fixes]
    # non-unit
    cams[5] = (cams[5][0], 2.0 * cams[5][1], cams[5][2])
    # zero quaternion
    cams.insert(9, (cams[8][0] + 1_000_000, np.zeros(4), cams[8][2]))
    # arrival order: the gyro stream as built (hostile messages where they arrived), the fixes
    # merged
    # in by stamp against the regular increments
    events, j = [], 0
    for k, e in enumerate(stream):
        ref = e[1] if (e[1] in {g_[0] for g_ in gyro[max(0, k // 1 - 10):k + 10]}) else None
        while ref is not None and j < len(cams) and cams[j][0] <= ref:
            events.append(('c', cams[j][0], (cams[j][1], cams[j][2])))
            j += 1
        events.append(e)
    events += [('c', s_, (q, P)) for s_, q, P in cams[j:]]
    store = get_typestore(Stores.ROS2_JAZZY)
    T = store.types
    node = CalibratorNode(namespace='/t_equiv')
    bag = tmp_path / 'hostile'
    try:
        with Writer(bag, version=Writer.VERSION_LATEST) as w:
            cg = w.add_connection('/imu/delta_theta', 'geometry_msgs/msg/Vector3Stamped',
                                  typestore=store)
            cc = w.add_connection('/star_camera/attitude_with_covariance',
                                  'geometry_msgs/msg/PoseWithCovarianceStamped',
                                  typestore=store)
            for i, (kind, ns, v) in enumerate(events):
                stamp = T['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9)
                if kind == 'g':
                    h = T['std_msgs/msg/Header'](stamp=stamp, frame_id='imu_link')
                    vec = T['geometry_msgs/msg/Vector3'](x=v[0], y=v[1], z=v[2])
                    m = T['geometry_msgs/msg/Vector3Stamped'](header=h, vector=vec)
                    w.write(cg, i, store.serialize_cdr(m, 'geometry_msgs/msg/Vector3Stamped'))
                    r = Vector3Stamped()
                    r.header.stamp.sec, r.header.stamp.nanosec = ns // 10**9, ns % 10**9
                    r.header.frame_id = 'imu_link'
                    r.vector.x, r.vector.y, r.vector.z = v
                    node.on_gyro(r)
                else:
                    q, P = v
                    c6 = np.zeros((6, 6))
                    c6[3:, 3:] = P
                    h = T['std_msgs/msg/Header'](stamp=stamp, frame_id='gcrs')
                    point = T['geometry_msgs/msg/Point'](x=0.0, y=0.0, z=0.0)
                    quat = T['geometry_msgs/msg/Quaternion'](x=float(q[0]), y=float(q[1]),
                                                             z=float(q[2]), w=float(q[3]))
                    pose = T['geometry_msgs/msg/Pose'](position=point, orientation=quat)
                    m = T['geometry_msgs/msg/PoseWithCovarianceStamped'](
                        header=h,
                        pose=T['geometry_msgs/msg/PoseWithCovariance'](pose=pose,
                                                                       covariance=c6.reshape(36)))
                    w.write(cc, i,
                            store.serialize_cdr(m, 'geometry_msgs/msg/PoseWithCovarianceStamped'))
                    r = PoseWithCovarianceStamped()
                    r.header.stamp.sec, r.header.stamp.nanosec = ns // 10**9, ns % 10**9
                    r.header.frame_id = 'gcrs'
                    o = r.pose.pose.orientation
                    o.x, o.y, o.z, o.w = (float(c) for c in q)
                    r.pose.covariance = [float(x) for x in c6.ravel()]
                    node.on_camera_cov(r)
        f = tmp_path / 'r.json'
        assert calibrate_bag.main([str(bag), '--json', str(f)]) == 0
        r = json.loads(f.read_text())
        g = node.gyro_check
        assert r['dropped']['gyro'] == {'nan': g.nan, 'duplicate': g.duplicate,
                                        'out_of_order': g.out_of_order,
                                        'out_of_range': g.out_of_range,
                                        'stamp_outlier': g.stamp_outliers,
                                        'stamp_burst': g.burst_messages,
                                        'wrong_type': 0, 'undecodable': 0}
        assert (g.nan, g.duplicate, g.out_of_order, g.out_of_range, g.stamp_outliers) == (1, 1, 1,
                                                                                          1, 1)
        # the burst: 5 increments lost in one gap, no resynchronisation left standing; it costs the
        # one pair that contains it (the hostile extras above have their own stamps: no gap)
        assert (g.bursts, g.burst_messages, g.resyncs, g.gaps, g.missing) == (1, 5, 0, 1, 5)
        assert r['gyro_gaps']['stamp_bursts'] == 1 and r['gyro_gaps']['missing'] == 5
        assert r['pairs'] == len(node.cal.pairs) == len(fixes) - 1 - 1
        assert (r['dropped']['camera']['zero_quaternion']
                == node.camera_counts['dropped_zero_quaternion'] == 1)
        assert r['camera_fixes']['normalised'] == node.camera_counts['normalised'] == 1
        assert r['messages']['gyro'] == g.accepted - g.burst_messages   # offline: burst removed
        np.testing.assert_allclose(r['beta_rad'], node.valid.beta, rtol=0, atol=1e-10)
    finally:
        node.destroy_node()
