"""
The nodes with ``gyro_input: imu``: sensor_msgs/Imu rate samples instead of increments.

sins_node and calibrator_node fed sensor_msgs/Imu rate samples on imu/data_raw (real nodes spun
in-process, every wait with a timeout).

Truth is independent of the code under test: the simulator's exact attitude (imu/truth/attitude),
a closed-form fixed-axis motion, the injected boresight.
"""
import math
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseWithCovarianceStamped, QuaternionStamped
from nav_msgs.msg import Odometry
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from ros_helpers import spin_until
from sensor_msgs.msg import Imu

from strapdown_ros import earth as G
from strapdown_ros.attitude.coning import ALGORITHMS, theory_drift
from strapdown_ros.motion.earth_profiles import navigation_profile_from_config
from strapdown_ros.motion.profiles import ConingProfile
from strapdown_ros.nodes.calibrator_node import CalibratorNode
from strapdown_ros.nodes.imu_sim_node import ImuSimNode
from strapdown_ros.nodes.ros_io import stamp_to_ns, stream_qos
from strapdown_ros.nodes.ros_params import InvalidParameter
from strapdown_ros.nodes.sins_node import SinsNode
from strapdown_ros.params import PROFILE_PARAMS
from strapdown_ros.rotation import (dcm_to_quat, from_ros_xyzw, quat_angle_between,
                                    quat_conjugate, quat_multiply, quat_to_dcm, quat_to_rotvec,
                                    rotvec_to_quat, to_ros_xyzw)


try:
    from rclpy.experimental import EventsExecutor as GraphExecutor
except ImportError:                                                 # older rclpy
    GraphExecutor = SingleThreadedExecutor

QUEUE = 20000
ALPHA, NU = 0.1, 4 * np.pi                       # the cone of test/ros/test_nodes.py
IDEAL = [Parameter(f'{s}_{k}', value=0.0) for s in ('gyro', 'accel')
         for k in ('bias_sigma', 'scale_sigma', 'misalignment_sigma', 'random_walk')]
IMU_MEAN = [Parameter('gyro_input', value='imu'), Parameter('imu_rate_rule', value='mean')]


def _stamped_quaternions(msgs):
    t = np.array([stamp_to_ns(m.header.stamp) for m in msgs])
    q = from_ros_xyzw(np.array([[m.quaternion.x, m.quaternion.y, m.quaternion.z, m.quaternion.w]
                                for m in msgs]))
    return t, q


def _status(diags, prefix):
    st = [s for d in diags for s in d.status if s.name.startswith(prefix)]
    return (st[-1], {v.key: v.value for v in st[-1].values}) if st else (None, {})


def _close(ex, nodes):
    for n in nodes:
        ex.remove_node(n)
        n.destroy_node()


def test_imu_mean_rule_gives_the_delta_theta_attitude_except_the_first_increment(ros):
    """
    Check: imu mean rule gives the delta theta attitude except the first increment.

    imu_sim_node's imu/data_raw is Δθ/T: with imu_rate_rule mean the increments are its Δθ to
    round-off, except the first (the first Imu sample starts the stream and gives none).  A node
    that starts from the true attitude at the first Imu stamp then differs from the Δθ node by a
    constant rotation (the first step's), and both are within the coning bound of the truth.
    """
    ns = '/t_imu_mean'
    duration = 2.0
    prof = ConingProfile(ALPHA, NU)
    sim = ImuSimNode(namespace=ns, parameter_overrides=[
        Parameter('coning_alpha', value=ALPHA), Parameter('coning_nu', value=NU),
        Parameter('gravity', value=[0.0, 0.0, 9.80665]), Parameter('time_scale', value=4.0),
        Parameter('duration', value=duration), Parameter('qos_depth', value=QUEUE), *IDEAL])
    common = [Parameter('coning_algorithm', value='1'), Parameter('qos_depth', value=QUEUE),
              Parameter('batch_period', value=0.0), *IDEAL]

    def start(t):
        q = to_ros_xyzw(prof.attitude(t))
        return Parameter('initial_orientation', value=[float(c) for c in q])
    sins_d = SinsNode(namespace=ns, parameter_overrides=[start(0.0), *common])
    # the Imu-fed node starts at the first Imu stamp, from the true attitude there
    sins_i = SinsNode(namespace=ns, parameter_overrides=[start(0.01), *IMU_MEAN, *common],
                      cli_args=['--ros-args', '-r', '__node:=sins_imu',
                                '-r', 'sins/attitude:=sins_imu/attitude',
                                '-r', 'sins/imu:=sins_imu/imu'])
    mon = rclpy.create_node('monitor', namespace=ns)
    rec = {'sins/attitude': [], 'sins_imu/attitude': [], 'imu/truth/attitude': []}
    for topic, got in rec.items():
        mon.create_subscription(QuaternionStamped, topic, got.append, stream_qos(QUEUE))
    diags = []
    mon.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 50)
    ex = GraphExecutor()
    nodes = (sim, sins_d, sins_i, mon)
    for n in nodes:
        ex.add_node(n)
    try:
        assert spin_until(ex, lambda: sim.pub_raw.get_subscription_count() >= 1
                          and sim.pub_dtheta.get_subscription_count() >= 1
                          and sim.pub_truth.get_subscription_count() >= 1
                          and mon.count_publishers(f'{ns}/sins_imu/attitude') == 1
                          and mon.count_publishers(f'{ns}/sins/attitude') == 1, 10.0)
        sim.restart_pacing()
        n = int(round(duration * 100))
        assert spin_until(ex, lambda: sim.finished and len(rec['sins/attitude']) >= n
                          and len(rec['sins_imu/attitude']) >= n - 1
                          and len(rec['imu/truth/attitude']) >= n, 30.0), \
            {k: len(v) for k, v in rec.items()}
        t_d, q_d = _stamped_quaternions(rec['sins/attitude'])
        t_i, q_i = _stamped_quaternions(rec['sins_imu/attitude'])
        t_true, q_true = _stamped_quaternions(rec['imu/truth/attitude'])
        truth = dict(zip(t_true.tolist(), q_true))
        assert len(t_d) == n and len(t_i) == n - 1
        np.testing.assert_array_equal(t_i, t_d[1:])          # every Imu sample but the first
        # the same increments from the second on: q_d = c ⊗ q_i with one constant c, to round-off
        c = quat_multiply(q_d[1:], quat_conjugate(q_i))
        assert np.max(quat_angle_between(c, c[:1])) < 1e-12
        # both within the one-sample coning bound of the exact attitude (the bound of
        # test/ros/test_nodes.py)
        drift = abs(theory_drift(ALGORITHMS['1'], NU * 0.01)) * ALPHA ** 2 * NU          # rad/s
        for t, q in ((t_d, q_d), (t_i, q_i)):
            err = quat_angle_between(q, np.array([truth[k] for k in t.tolist()]))
            s = t * 1e-9
            assert np.all(err <= 1.3 * drift * s + 1e-10), (err[-1], drift * s[-1])
            assert err[-1] > 0.5 * drift * (s[-1] - 0.01)             # the coning error is there
        # diagnostics: 200 rate samples, 199 increments formed, nothing dropped or missing
        sins_i.publish_diagnostics()
        assert spin_until(ex, lambda: _status(diags, f'{ns}/sins_imu')[0] is not None, 5.0)
        st, kv = _status(diags, f'{ns}/sins_imu')
        assert st.level == b'\x00', st.message
        assert (kv['gyro_input'], kv['imu_rate_rule']) == ('imu', 'mean')
        assert (kv['imu_gyro_received'], kv['imu_gyro_accepted']) == (str(n), str(n))
        assert kv['imu_gyro_dropped'] == '0'
        assert kv['imu_gyro_increments_formed'] == str(n - 1)
        assert kv['imu_gyro_increments_skipped'] == '0'
        assert int(kv['gyro_accepted']) == n - 1 and int(kv['gyro_missing_samples']) == 0
        assert int(kv['imu_accel_increments_formed']) == n - 1
        # an ideal simulator states zero noise: "unknown" by the ROS convention
        assert kv['imu_stated_rate_variance'] == 'unknown'
        assert float(kv['model_rate_variance']) == 0
    finally:
        _close(ex, nodes)


# --- a closed-form motion sampled as a MEMS driver does: the rate at the stamp ---------------
AXIS = np.array([1.0, 2.0, 2.0]) / 3.0
A_RATE, NU_RATE = 1.0, 2 * np.pi                 # ω(t) = A sin(νt) about AXIS, rad/s
T0_NS = 100 * 10**9


def _angle(t):
    return A_RATE / NU_RATE * (1.0 - np.cos(NU_RATE * t))


def _imu_msg(k, rate, frame='imu_link', period_ns=10_000_000):
    m = Imu()
    ns_ = T0_NS + k * period_ns
    m.header.stamp.sec, m.header.stamp.nanosec = ns_ // 10**9, ns_ % 10**9
    m.header.frame_id = frame
    m.orientation_covariance[0] = -1.0
    m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = (float(c) for c in rate)
    m.linear_acceleration.z = 9.80665
    return m


def test_trapezoid_rule_on_sampled_rates_is_within_its_second_order_bound(ros):
    """
    Check: trapezoid rule on sampled rates is within its second order bound.

    Rates sampled at the stamps of a fixed-axis motion (the coning algorithm is exact for it: the
    error is the increment rule's alone).  The trapezoid rule errs by +T³ω̈/12 per increment, so
    the angle after time t by at most t·T²·max|ω̈|/12 (rate_increments).
    """
    ns = '/t_imu_trap'
    sins = SinsNode(namespace=ns, parameter_overrides=[
        Parameter('gyro_input', value='imu'), Parameter('coning_algorithm', value='1'),
        Parameter('qos_depth', value=QUEUE), *IDEAL])
    src = rclpy.create_node('source', namespace=ns)
    pub = src.create_publisher(Imu, 'imu/data_raw', stream_qos(QUEUE))
    got = []
    src.create_subscription(QuaternionStamped, 'sins/attitude', got.append, stream_qos(QUEUE))
    ex = SingleThreadedExecutor()
    for n in (sins, src):
        ex.add_node(n)
    try:
        assert spin_until(ex, lambda: pub.get_subscription_count() >= 1
                          and src.count_publishers(f'{ns}/sins/attitude') == 1, 10.0)
        spin_until(ex, lambda: False, 0.2)
        n = 201                                                    # 2 s at 100 Hz
        for k in range(n):
            t = k * 0.01
            pub.publish(_imu_msg(k, A_RATE * np.sin(NU_RATE * t) * AXIS))
            ex.spin_once(timeout_sec=0.002)
        assert spin_until(ex, lambda: len(got) >= n - 1, 10.0), \
            (len(got), sins.gyro_rates.check.received)
        t_ns, q = _stamped_quaternions(got)
        t = (t_ns - T0_NS) * 1e-9
        np.testing.assert_allclose(t, 0.01 * np.arange(1, n), atol=1e-12)
        truth = rotvec_to_quat(_angle(t)[:, None] * AXIS)          # q(0) = identity (the default)
        err = quat_angle_between(q, truth)
        T = 0.01
        bound = t * T ** 2 * A_RATE * NU_RATE ** 2 / 12.0            # max|ω̈| = Aν²
        assert np.all(err <= bound * 1.001 + 1e-12), np.max(err / np.maximum(bound, 1e-30))
        # second order and really there: the leading term (T²/12)·|ω̇(t) − ω̇(0)| is what is seen
        lead = T ** 2 / 12.0 * A_RATE * NU_RATE * np.abs(np.cos(NU_RATE * t) - 1.0)
        np.testing.assert_allclose(err, lead, rtol=0.02, atol=2e-8)
        print(f'\ntrapezoid 100 Hz, ω = sin(2πt) rad/s: max angle error {np.max(err):.3g} rad '
              f'(bound at 2 s {bound[-1]:.3g} rad)')
    finally:
        _close(ex, (sins, src))


def test_bad_imu_input_is_dropped_counted_and_reported(ros):
    """
    Check: bad imu input is dropped counted and reported.

    NaN, duplicate and out-of-order stamps, an unknown frame: dropped and counted by both nodes,
    reported on /diagnostics; the interval lost to the NaN is a gap of the increments (ERROR:
    rotation lost); the nodes go on.
    """
    ns = '/t_imu_bad'
    sins = SinsNode(namespace=ns, parameter_overrides=[
        Parameter('gyro_input', value='imu'), Parameter('coning_algorithm', value='1'), *IDEAL])
    cal = CalibratorNode(namespace=ns, parameter_overrides=[Parameter('gyro_input', value='imu')])
    src = rclpy.create_node('source', namespace=ns)
    pub = src.create_publisher(Imu, 'imu/data_raw', stream_qos())
    diags = []
    src.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 50)
    ex = SingleThreadedExecutor()
    nodes = (sins, cal, src)
    for n in nodes:
        ex.add_node(n)
    try:
        assert spin_until(ex, lambda: pub.get_subscription_count() >= 2, 10.0)
        spin_until(ex, lambda: False, 0.2)
        w = (0.1, 0.0, 0.0)

        def send(k, rate=w, frame='imu_link'):
            pub.publish(_imu_msg(k, rate, frame))
            ex.spin_once(timeout_sec=0.005)
        for k in range(1, 21):                 # 16 steps give the gap rule its period
            send(k)
        send(21, (math.nan, 0.0, 0.0))    # NaN: dropped; the interval 20 → 22 is not integrated
        send(20)                               # duplicate stamp
        send(5)                                # out of order
        send(22, frame='camera')               # another frame: rejected (frame_mismatch reject)
        send(22)
        for k in range(23, 31):
            send(k)
        assert spin_until(ex, lambda: sins.gyro_rates.check.received >= 32
                          and cal.gyro_rates.check.received >= 32, 5.0)
        for node in (sins, cal):
            r = node.gyro_rates
            c = r.check
            assert (c.nan, c.duplicate, c.out_of_order, c.accepted) == (1, 1, 1, 29)
            assert (r.integrator.formed, r.integrator.skipped) == (27, 1)
            # the increments: 19 before the NaN, 8 after; the two over (0.20, 0.22] missing
            g = node.gyro_check
            assert (g.accepted, g.gaps, g.missing) == (27, 1, 2)
        assert sins.integrator.updates == 27
        assert sins.frame_mismatch['gyro'] == 1 and cal.gyro_frame_mismatch == 1
        # the node goes on: 1 rad/s for 0.1 s more after the bad messages
        for k in range(31, 41):
            send(k, (1.0, 0.0, 0.0))
        assert spin_until(ex, lambda: sins.integrator.updates == 37
                          and cal.gyro_rates.check.received == 42, 5.0)
        sins.publish_diagnostics()
        cal.publish_diagnostics()
        assert spin_until(ex, lambda: _status(diags, f'{ns}/sins_node')[0] is not None
                          and _status(diags, f'{ns}/calibrator_node')[0] is not None, 5.0)
        for name in ('sins_node', 'calibrator_node'):
            st, kv = _status(diags, f'{ns}/{name}')
            assert st.level == b'\x02', (name, st.message)          # ERROR: rotation lost in a gap
            dropped = [kv[f'imu_gyro_dropped{k}']
                       for k in ('_nan', '_duplicate', '_out_of_order', '')]
            assert dropped == ['1', '1', '1', '3'], name
            formed = kv['imu_gyro_increments_formed'], kv['imu_gyro_increments_skipped']
            assert formed == ('37', '1'), name
            assert kv['gyro_missing_samples'] == '2', name
    finally:
        _close(ex, nodes)


def test_calibrator_on_imu_rates_recovers_the_boresight(ros):
    """
    Check: calibrator on imu rates recovers the boresight.

    calibration graph (test/ros/test_calibrator_node.py) with the calibrator on imu/data_raw (mean
    rule: imu_sim_node publishes Δθ/T): the injected boresight within 3σ of the published one.
    """
    from test_calibrator_node import ARCSEC, BETA, C_TRUE, Graph, MAX_TIME_SCALE, q_of, rot_cov

    class ImuGraph(Graph):

        def run(self):
            for n in (self.calib, self.mon):
                self.ex.add_node(n)
            assert spin_until(self.ex, lambda: self.sim.pub_raw.get_subscription_count() >= 1
                              and self.cam.pub_cov.get_subscription_count() >= 1, 10.0), \
                'discovery timed out'
            self.ex.add_node(self.sim)
            self.ex.add_node(self.cam)
            # a bound, not the expected time: a loaded machine slows the simulator, which builds
            # an Imu per sample
            timeout = 3.0 * self.sim.end_time / self.sim.p['time_scale'] + 10.0
            t0 = time.monotonic()
            assert spin_until(self.ex, lambda: self.sim.finished and self.cam.finished, timeout), \
                (self.sim.sim_time, self.cam.sim_time)
            self.wall = time.monotonic() - t0
            spin_until(self.ex, self.all_received, 5.0)
            assert self.all_received(), (self.calib.gyro_rates.check.received,
                                         self.sim.counts['data_raw'])

        def all_received(self):
            return (self.calib.gyro_rates.check.received == self.sim.counts['data_raw'] > 0
                    and self.calib.camera_check.received == self.cam.published)

    # imu/data_raw reliable end to end (as load_bench runs the graph): a loaded machine cannot
    # lose a sample to the best-effort path (measured: 5% lost at 40× with the load at 9)
    ns = '/t_imu_calib'
    reliable = f'qos_overrides.{ns}/imu/data_raw.%s.reliability'
    profile = {'profile': 'bench', 'bench_earth_rate': True, reliable % 'publisher': 'reliable'}
    g = ImuGraph(ns, profile, time_scale=min(25.0, MAX_TIME_SCALE),
                 camera=[Parameter('camera_interval', value=5.0)],
                 calibrator=[*IMU_MEAN, Parameter(reliable % 'subscription', value='reliable')])
    try:
        g.run()
        cal = g.calib
        assert cal.published['boresight'] >= 1, cal.cal.solution.message
        sol = cal.valid
        e = quat_to_rotvec(dcm_to_quat(quat_to_dcm(sol.q_mf_vf) @ C_TRUE.T))
        sig = np.sqrt(np.diag(sol.rotation_covariance_mf))
        assert np.all(np.abs(e) <= 3 * sig), (e, sig)
        assert np.all(sig < 60 * ARCSEC)
        got = g.late_subscriber('calibration/boresight', PoseWithCovarianceStamped, 5.0)
        assert got
        np.testing.assert_allclose(quat_to_dcm(q_of(got[-1])), quat_to_dcm(sol.q_mf_vf),
                                   atol=1e-12)
        np.testing.assert_allclose(rot_cov(got[-1]), sol.rotation_covariance_mf, rtol=1e-12)
        r = cal.gyro_rates
        n = g.sim.counts['data_raw']
        assert (r.check.accepted, r.check.dropped) == (n, 0)
        assert (r.integrator.formed, r.integrator.skipped) == (n - 1, 0)
        assert cal.gyro_check.accepted == n - 1 and cal.gyro_check.missing == 0
        st, kv = g.diagnostics()
        assert st.level == b'\x00', st.message
        assert kv['gyro_input'] == 'imu' and int(kv['imu_gyro_increments_formed']) == n - 1
        # the simulator states N²/T, the model's rate variance with the same default random walk
        stated = [float(x) for x in kv['imu_stated_rate_variance'].split(',')]
        model = float(kv['model_rate_variance'])
        assert model > 0 and stated == pytest.approx([model] * 3, rel=1e-5)
        assert np.all(np.abs(np.asarray(sol.beta) - BETA) < 60 * ARCSEC)
        print(f'\nimu-fed calibrator: {g.wall:.1f} s wall; error '
              f'{np.round(e / ARCSEC, 2)}″, σ {np.round(sig / ARCSEC, 2)}″')
    finally:
        g.close()


@pytest.mark.parametrize('profile, tol_pos, tol_vel', [('static', 1e-6, 1e-6),
                                                       ('coordinated_turn', 2e-3, 2e-3)])
def test_navigation_from_imu_messages_matches_the_exact_truth(ros, profile, tol_pos, tol_vel):
    """
    Check: navigation from imu messages matches the exact truth.

    sins_node with navigation on imu/data_raw alone (Δθ and Δv from the same messages, mean rule),
    started from the truth at the first Imu stamp: sins/odometry within the bounds of the Δθ/Δv-fed
    node (test/ros/test_sins_node_navigation.py), against imu/truth/odometry.
    """
    ns, duration, t0 = f'/t_imu_nav_{profile}', 3.0, np.array([0.01])

    # the truth of the simulator's own parameters (its default gravity_model included: the turn
    # is coordinated with that model's vertical)
    prof = navigation_profile_from_config(
        {**{s.name: s.default for s in PROFILE_PARAMS}, 'profile': profile})
    r0, v0 = prof.position(t0)[0], prof.velocity(t0)[0]
    lat, lon, h = G.ecef_to_geodetic(r0)
    enu = G.enu_rotation(lat, lon)
    sim = ImuSimNode(namespace=ns, parameter_overrides=[
        Parameter('profile', value=profile), Parameter('time_scale', value=5.0),
        Parameter('duration', value=duration), Parameter('qos_depth', value=QUEUE),
        Parameter('wait_for_subscribers', value=1), *IDEAL])
    q0 = to_ros_xyzw(prof.attitude_ecef(t0)[0])
    sins = SinsNode(namespace=ns, parameter_overrides=[
        *IMU_MEAN, Parameter('navigation', value=True),
        Parameter('coning_algorithm', value='one_plus_previous'),
        Parameter('initial_position',
                  value=[float(np.degrees(lat)), float(np.degrees(lon)), float(h)]),
        Parameter('initial_velocity', value=[float(x) for x in enu.T @ v0]),
        Parameter('initial_orientation', value=[float(x) for x in q0]),
        Parameter('qos_depth', value=QUEUE), *IDEAL])
    mon = rclpy.create_node('monitor', namespace=ns)
    got = {'sins': [], 'truth': []}
    mon.create_subscription(Odometry, 'sins/odometry', got['sins'].append, stream_qos(QUEUE))
    mon.create_subscription(Odometry, 'imu/truth/odometry', got['truth'].append, stream_qos(QUEUE))
    ex = GraphExecutor()
    nodes = (sim, sins, mon)
    for n in nodes:
        ex.add_node(n)
    try:
        assert spin_until(ex, lambda: mon.count_publishers(f'{ns}/sins/odometry') == 1
                          and sim.pub_odom.get_subscription_count() >= 1, 10.0)
        sim.restart_pacing()       # the clock started on sins_node's imu/data_raw subscription
        n_expected = int(round(duration * 100)) - 3
        assert spin_until(ex, lambda: sim.finished and len(got['sins']) >= n_expected
                          and len(got['truth']) >= n_expected, 60.0), \
            {k: len(v) for k, v in got.items()}
        truth = {stamp_to_ns(m.header.stamp): m for m in got['truth']}
        pairs = [(m, truth[stamp_to_ns(m.header.stamp)]) for m in got['sins']
                 if stamp_to_ns(m.header.stamp) in truth]
        assert len(pairs) > 0.9 * len(got['sins'])

        def pos(m):
            p = m.pose.pose.position
            return np.array([p.x, p.y, p.z])

        def vel(m):
            v = m.twist.twist.linear
            return np.array([v.x, v.y, v.z])

        def att(m):
            o = m.pose.pose.orientation
            return np.array([o.w, o.x, o.y, o.z])
        dp = max(np.linalg.norm(pos(s) - pos(t)) for s, t in pairs)
        dv = max(np.linalg.norm(vel(s) - vel(t)) for s, t in pairs)
        da = max(quat_angle_between(att(s), att(t)) for s, t in pairs)
        assert dp < tol_pos and dv < tol_vel and da < 1e-8, (dp, dv, da)
        assert sins.accel_rates.integrator.formed == sins.gyro_rates.integrator.formed > 0
        assert sins.accel_check.missing == 0 and sins.gyro_check.missing == 0
        print(f'\n{profile} from imu/data_raw: position {dp:.3g} m, velocity {dv:.3g} m/s, '
              f'attitude {da:.3g} rad')
    finally:
        _close(ex, nodes)


@pytest.mark.parametrize('node_class', [SinsNode, CalibratorNode])
def test_gyro_input_parameters_are_validated_and_fixed_at_runtime(ros, node_class):
    for name, bad, valid in (('gyro_input', 'rates', 'delta_theta, imu'),
                             ('imu_rate_rule', 'simpson', 'trapezoid, mean')):
        with pytest.raises(InvalidParameter, match=valid):
            node_class(namespace='/t_imu_params', parameter_overrides=[Parameter(name, value=bad)])
    node = node_class(namespace='/t_imu_params', parameter_overrides=[
        Parameter('gyro_input', value='imu')])
    try:
        topics = dict(node.get_subscriber_names_and_types_by_node(node.get_name(),
                                                                  '/t_imu_params'))
        assert topics.get('/t_imu_params/imu/data_raw') == ['sensor_msgs/msg/Imu']
        assert '/t_imu_params/imu/delta_theta' not in topics
        assert '/t_imu_params/imu/delta_velocity' not in topics
        res = node.set_parameters([Parameter('gyro_input', value='delta_theta')])[0]
        assert not res.successful and 'gyro_input' in res.reason
    finally:
        node.destroy_node()
