"""
Node tests: real nodes spun in-process under an executor (plain pytest, no launch_testing).

Each test runs its graph in its own namespace; the session has its own ROS_DOMAIN_ID and
LOCALHOST discovery (conftest.py).  Every wait has a timeout.  Content is checked against
independent truth: the closed-form coning attitude and specific force of the profile.
"""
import os
import subprocess
import sys

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import ReliabilityPolicy
from ros_helpers import spin_until
from sensor_msgs.msg import Imu

from strapdown_ros.attitude.coning import ALGORITHMS, theory_drift
from strapdown_ros.motion.profiles import ConingProfile
from strapdown_ros.nodes.imu_sim_node import ImuSimNode
from strapdown_ros.nodes.ros_io import stamp_to_ns, stream_qos
from strapdown_ros.nodes.ros_params import InvalidParameter
from strapdown_ros.nodes.sins_node import SinsNode
from strapdown_ros.rotation import from_ros_xyzw, quat_angle_between, to_ros_xyzw


# one thread serves all nodes here; the events executor keeps up (see
# test/ros/test_calibrator_node.py)
try:
    from rclpy.experimental import EventsExecutor as GraphExecutor
except ImportError:                                                 # older rclpy
    GraphExecutor = SingleThreadedExecutor
# best-effort history deep enough for a whole run, so a stall of this process on a loaded
# machine cannot overwrite samples before they are taken
QUEUE = 20000


ALPHA, NU = 0.1, 4 * np.pi          # 2 Hz cone: Ωh = 0.25 for the 2-sample algorithm at 100 Hz
IDEAL = [Parameter(f'{s}_{k}', value=0.0) for s in ('gyro', 'accel')
         for k in ('bias_sigma', 'scale_sigma', 'misalignment_sigma', 'random_walk')]


class Recorder:
    """Subscribes to topics and keeps (stamp_s, msg) per topic."""

    def __init__(self, node, topics):
        self.data = {name: [] for name, _ in topics}
        for name, typ in topics:
            qos = 10 if typ is DiagnosticArray else stream_qos(QUEUE)
            node.create_subscription(typ, name, lambda m, n=name: self.data[n].append(m), qos)

    def stamps(self, name):
        """Return the header stamps of a topic, s."""
        return np.array([stamp_to_ns(m.header.stamp) * 1e-9 for m in self.data[name]])


def make_graph(ns, algorithm='2', duration=4.0, extra_sim=(), extra_sins=()):
    """Build imu_sim_node and sins_node in one namespace: (sim, sins)."""
    sim = ImuSimNode(namespace=ns, parameter_overrides=[
        Parameter('coning_alpha', value=ALPHA), Parameter('coning_nu', value=NU),
        Parameter('gravity', value=[0.0, 0.0, 9.80665]),
        Parameter('time_scale', value=5.0), Parameter('duration', value=duration),
        Parameter('qos_depth', value=QUEUE), *IDEAL, *extra_sim])
    q0 = ConingProfile(ALPHA, NU).attitude(0.0)
    sins = SinsNode(namespace=ns, parameter_overrides=[
        Parameter('coning_algorithm', value=algorithm),
        Parameter('initial_orientation', value=list(to_ros_xyzw(q0))),
        Parameter('qos_depth', value=QUEUE), *IDEAL, *extra_sins])
    return sim, sins


def test_full_graph_topics_qos_rates_and_content(ros):
    ns = '/t_graph'
    sim, sins = make_graph(ns)
    mon = rclpy.create_node('monitor', namespace=ns)
    rec = Recorder(mon, [('imu/delta_theta', Vector3Stamped),
                         ('imu/delta_velocity', Vector3Stamped),
                         ('imu/data_raw', Imu), ('imu/truth/attitude', QuaternionStamped),
                         ('sins/attitude', QuaternionStamped), ('sins/imu', Imu),
                         ('/diagnostics', DiagnosticArray)])
    ex = GraphExecutor()
    for n in (sim, sins, mon):
        ex.add_node(n)
    try:
        # discovery first, then restart the simulator's clock so no sample is sent before
        # every subscription has matched
        assert spin_until(ex, lambda: mon.count_publishers(f'{ns}/sins/attitude') == 1, 10.0)
        sim.restart_pacing()
        assert spin_until(ex, lambda: sim.finished and len(rec.data['sins/attitude']) >= 199,
                          30.0), \
            {k: len(v) for k, v in rec.data.items()}
        spin_until(ex, lambda: len(rec.data['sins/imu']) >= 200, 3.0)

        # --- graph: names, types, publisher counts, QoS
        types = dict(mon.get_topic_names_and_types())
        expect = {'imu/delta_theta': 'geometry_msgs/msg/Vector3Stamped',
                  'imu/delta_velocity': 'geometry_msgs/msg/Vector3Stamped',
                  'imu/data_raw': 'sensor_msgs/msg/Imu',
                  'imu/truth/attitude': 'geometry_msgs/msg/QuaternionStamped',
                  'sins/attitude': 'geometry_msgs/msg/QuaternionStamped',
                  'sins/imu': 'sensor_msgs/msg/Imu'}
        for topic, typ in expect.items():
            assert types[f'{ns}/{topic}'] == [typ]
            assert mon.count_publishers(f'{ns}/{topic}') == 1
            info = mon.get_publishers_info_by_topic(f'{ns}/{topic}')
            assert info[0].qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
        assert types['/diagnostics'] == ['diagnostic_msgs/msg/DiagnosticArray']
        assert mon.count_subscribers(f'{ns}/imu/delta_theta') >= 2          # sins + monitor

        # --- rates from header stamps (the simulated clock)
        for topic, hz in (('imu/delta_theta', 100.0), ('imu/delta_velocity', 300.0),
                          ('sins/attitude', 50.0)):
            st = rec.stamps(topic)
            assert len(st) >= 0.95 * 4.0 * hz, (topic, len(st))
            assert np.median(np.diff(st)) == pytest.approx(1.0 / hz, rel=1e-6)

        # --- content: the simulator against the closed-form profile
        prof = ConingProfile(ALPHA, NU, gravity=(0, 0, 9.80665))
        st = rec.stamps('imu/delta_theta')
        dth = np.array([[m.vector.x, m.vector.y, m.vector.z] for m in rec.data['imu/delta_theta']])
        np.testing.assert_allclose(dth, prof.delta_theta(st - 0.01, st), atol=1e-15)
        raw = rec.data['imu/data_raw']
        assert all(m.orientation_covariance[0] == -1.0 for m in raw)               # REP-145
        f_raw = np.array([[m.linear_acceleration.x, m.linear_acceleration.y,
                           m.linear_acceleration.z] for m in raw])
        t_raw = rec.stamps('imu/data_raw')
        np.testing.assert_allclose(f_raw, prof.delta_v(t_raw - 0.01, t_raw) / 0.01, atol=1e-12)

        # --- content: SINS attitude against truth, within the 2-sample coning error
        st = rec.stamps('sins/attitude')
        q = from_ros_xyzw(np.array([[m.quaternion.x, m.quaternion.y, m.quaternion.z,
                                     m.quaternion.w]
                                    for m in rec.data['sins/attitude']]))
        err = quat_angle_between(q, prof.attitude(st))
        drift = abs(theory_drift(ALGORITHMS['2'], NU * 0.02)) * ALPHA ** 2 * NU       # rad/s
        assert np.all(err <= 1.3 * drift * st + 1e-10), (err[-1], drift * st[-1])
        # the coning error is really there (not a copy of truth)
        assert err[-1] > 0.5 * drift * st[-1]

        # --- sins/imu: orientation equals sins/attitude, covariance present, mean specific force
        imu = {stamp_to_ns(m.header.stamp): m for m in rec.data['sins/imu']}
        m0 = rec.data['sins/attitude'][-1]
        m1 = imu[stamp_to_ns(m0.header.stamp)]
        assert (m1.orientation.x, m1.orientation.w) == (m0.quaternion.x, m0.quaternion.w)
        t1 = stamp_to_ns(m1.header.stamp) * 1e-9
        f = [m1.linear_acceleration.x, m1.linear_acceleration.y, m1.linear_acceleration.z]
        np.testing.assert_allclose(f, prof.delta_v(t1 - 0.02, t1) / 0.02, atol=1e-12)
        w = [m1.angular_velocity.x, m1.angular_velocity.y, m1.angular_velocity.z]
        np.testing.assert_allclose(w, prof.delta_theta(t1 - 0.02, t1) / 0.02, atol=1e-12)

        # --- diagnostics of both nodes
        spin_until(ex, lambda: any(s.name.startswith(f'{ns}/sins_node')
                                   for d in rec.data['/diagnostics'] for s in d.status), 5.0)
        sins.publish_diagnostics()
        spin_until(ex, lambda: False, 0.3)
        status = [s for d in rec.data['/diagnostics'] for s in d.status
                  if s.name.startswith(f'{ns}/sins_node')][-1]
        kv = {v.key: v.value for v in status.values}
        assert kv['coning_algorithm'] == '2' and int(kv['gyro_accepted']) == 400
        assert float(kv['gyro_rate_hz_from_stamps']) == pytest.approx(100.0)
        assert int(kv['gyro_dropped_nan']) == 0 and int(kv['gyro_missing_samples']) == 0
    finally:
        for n in (sim, sins, mon):
            ex.remove_node(n)
            n.destroy_node()


def test_bad_input_is_dropped_counted_and_reported(ros):
    ns = '/t_bad'
    sins = SinsNode(namespace=ns,
                    parameter_overrides=[Parameter('coning_algorithm', value='1'), *IDEAL])
    src = rclpy.create_node('source', namespace=ns)
    pub = src.create_publisher(Vector3Stamped, 'imu/delta_theta', stream_qos())
    diags = []
    src.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 10)
    ex = SingleThreadedExecutor()
    for n in (sins, src):
        ex.add_node(n)
    try:
        assert spin_until(ex, lambda: pub.get_subscription_count() >= 1, 10.0)
        rate = 0.01

        def send(k, v=(0.001, 0.0, 0.0)):
            m = Vector3Stamped()
            m.header.stamp.sec = 100 + k // 100
            m.header.stamp.nanosec = int(round((k % 100) * rate * 1e9))
            m.vector.x, m.vector.y, m.vector.z = v
            pub.publish(m)
            ex.spin_once(timeout_sec=0.005)
        for k in range(1, 21):                    # 16 steps give the gap rule its period
            send(k)
        send(21, (float('nan'), 0.0, 0.0))       # NaN
        send(20)                                  # duplicate stamp
        send(5)                                   # out of order
        send(22)                                  # gap: sample 21 is missing (its NaN was dropped)
        send(23)
        assert spin_until(ex, lambda: sins.gyro_check.received >= 25, 5.0)
        g = sins.gyro_check
        assert (g.accepted, g.nan, g.duplicate, g.out_of_order, g.gaps, g.missing) == (22, 1, 1, 1,
                                                                                       1, 1)
        assert sins.integrator.updates == 22
        sins.publish_diagnostics()
        assert spin_until(ex, lambda: any(s.name.startswith(f'{ns}/sins_node')
                                          for d in diags for s in d.status), 5.0)
        st = [s for d in diags for s in d.status if s.name.startswith(f'{ns}/sins_node')][-1]
        kv = {v.key: v.value for v in st.values}
        # ERROR: rotation lost in a gap
        assert st.level == b'\x02' and 'missing' in st.message
        assert (kv['gyro_dropped_nan'], kv['gyro_dropped_duplicate'],
                kv['gyro_dropped_out_of_order']) == ('1', '1', '1')
    finally:
        for n in (sins, src):
            ex.remove_node(n)
            n.destroy_node()


def test_unknown_algorithm_and_out_of_range_parameters_are_refused(ros):
    with pytest.raises(ValueError, match=r'valid values: 1, 2, 3, .*4\+.*four_sample_optimal'):
        SinsNode(namespace='/t_refuse1',
                 parameter_overrides=[Parameter('coning_algorithm', value='rk4')])
    with pytest.raises(ValueError, match=r'gyro_rate=-100.0 is out of range; valid: > 0'):
        SinsNode(namespace='/t_refuse2',
                 parameter_overrides=[Parameter('gyro_rate', value=-100.0)])
    with pytest.raises(ValueError, match='valid values: coning, tkachenko, bench, piecewise'):
        ImuSimNode(namespace='/t_refuse3',
                   parameter_overrides=[Parameter('profile', value='spiral')])
    node = SinsNode(namespace='/t_refuse4')
    try:
        res = node.set_parameters([Parameter('coning_algorithm', value='bogus')])[0]
        assert not res.successful and 'valid values: 1, 2, 3' in res.reason
        assert node.get_parameter('coning_algorithm').value == '2'
        res = node.set_parameters([Parameter('coning_algorithm', value='4+')])[0]
        assert res.successful and node.integrator.algorithm_name == '4+'
        res = node.set_parameters([Parameter('gyro_rate', value=200.0)])[0]
        assert not res.successful and 'only coning_algorithm can change' in res.reason
    finally:
        node.destroy_node()


def test_node_executable_exits_with_a_clear_message_on_bad_algorithm():
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = dict(os.environ,
               PYTHONPATH=os.pathsep.join([repo, os.environ.get('PYTHONPATH', '')]))
    res = subprocess.run([sys.executable, '-m', 'strapdown_ros.nodes.sins_node', '--ros-args',
                          '-p', 'coning_algorithm:=rk4'], capture_output=True, text=True,
                         timeout=60, env=env)
    assert res.returncode == 2
    assert "coning_algorithm='rk4' is not valid; valid values: 1, 2, 3" in res.stderr


def test_numeric_algorithm_names_given_unquoted_are_accepted(ros):
    """`-p coning_algorithm:=2` or `:=3.1` reach the node as numbers (ROS YAML); both are names."""
    node = SinsNode(namespace='/t_numeric', cli_args=['--ros-args', '-p', 'coning_algorithm:=3.1'])
    try:
        assert node.integrator.algorithm_name == '3.1'
        assert node.set_parameters([Parameter('coning_algorithm', value=4)])[0].successful
        assert node.integrator.algorithm_name == '4'
    finally:
        node.destroy_node()


def test_nodes_start_from_the_shipped_parameter_file(ros):
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    path = os.path.join(repo, 'config', 'coning.yaml')
    sim = ImuSimNode(namespace='/t_file', cli_args=['--ros-args', '--params-file', path])
    sins = SinsNode(namespace='/t_file', cli_args=['--ros-args', '--params-file', path])
    try:
        assert sim.p['coning_alpha'] == 0.087 and sins.integrator.algorithm_name == '2'
        assert sins.integrator.gyro.random_walk == pytest.approx(3.4907e-07)
    finally:
        sim.destroy_node()
        sins.destroy_node()


def _sins_error_with(ros, ns, effects, compensate):
    """Return the final attitude error of sins_node on a graph whose gyro carries ``effects``."""
    sim, sins = make_graph(ns, duration=2.0, extra_sim=effects,
                           extra_sins=effects if compensate else ())
    mon = rclpy.create_node('monitor', namespace=ns)
    rec = Recorder(mon, [('sins/attitude', QuaternionStamped)])
    ex = GraphExecutor()
    for n in (sim, sins, mon):
        ex.add_node(n)
    try:
        assert spin_until(ex, lambda: mon.count_publishers(f'{ns}/sins/attitude') == 1, 10.0)
        sim.restart_pacing()
        assert spin_until(ex, lambda: sim.finished and len(rec.data['sins/attitude']) >= 99, 30.0)
        st = rec.stamps('sins/attitude')
        q = from_ros_xyzw(np.array([[m.quaternion.x, m.quaternion.y, m.quaternion.z,
                                     m.quaternion.w]
                                    for m in rec.data['sins/attitude']]))
        return float(quat_angle_between(q[-1], ConingProfile(ALPHA, NU).attitude(st[-1])))
    finally:
        ex.shutdown()
        for n in (sim, sins, mon):
            n.destroy_node()


def test_sins_node_compensates_the_gyro_effects_in_its_parameters(ros):
    """
    Check: sins node compensates the gyro effects in its parameters.

    The model's known effects (sensors/effects.py) are removed from each increment: with them in
    both the simulator and sins_node the error is the coning error; without, it is the effect's.
    """
    effects = [Parameter('gyro_bias', value=[2e-4, -1e-4, 1.5e-4]),
               Parameter('gyro_bias_drift', value=[1e-5, 0.0, -1e-5]),
               Parameter('gyro_scale_factor', value=[1e-3, -5e-4, 2e-3]),
               Parameter('gyro_misalignment', value=[1e-3, 0.0, 1e-3, 0.0, -2e-3, -2e-3])]
    raw = _sins_error_with(ros, '/t_comp_off', effects, compensate=False)
    fixed = _sins_error_with(ros, '/t_comp_on', effects, compensate=True)
    # coning error at 2 s
    drift = abs(theory_drift(ALGORITHMS['2'], NU * 0.02)) * ALPHA ** 2 * NU * 2.0
    assert raw > 1e-4, raw                               # ≈ |b|·2 s
    assert fixed <= 1.3 * drift + 1e-10, (fixed, drift)


def test_impossible_increments_lone_future_stamp_and_clock_reset(ros):
    """
    Check: impossible increments lone future stamp and clock reset.

    A finite but impossible increment (1000 rad in 10 ms, 1e308) is rejected by the sensor range
    and never reaches the state; a lone stamp far in the future is an outlier that stops nothing; a
    clock reset is followed after resync_count messages, losing none.
    """
    ns = '/t_hostile'
    sins = SinsNode(namespace=ns,
                    parameter_overrides=[Parameter('coning_algorithm', value='1'), *IDEAL])
    src = rclpy.create_node('source', namespace=ns)
    pub = src.create_publisher(Vector3Stamped, 'imu/delta_theta', stream_qos())
    got = []
    src.create_subscription(QuaternionStamped, 'sins/attitude', got.append, stream_qos(1000))
    diags = []
    src.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 10)
    ex = SingleThreadedExecutor()
    for n in (sins, src):
        ex.add_node(n)
    try:
        assert spin_until(ex, lambda: pub.get_subscription_count() >= 1 and sins.count_publishers(
            f'{ns}/sins/attitude') >= 1, 10.0)

        def send(sec, nsec, v=(0.001, 0.0, 0.0)):
            m = Vector3Stamped()
            m.header.stamp.sec, m.header.stamp.nanosec = sec, nsec
            m.vector.x, m.vector.y, m.vector.z = v
            pub.publish(m)
            ex.spin_once(timeout_sec=0.005)
        for k in range(1, 11):
            send(100, k * 10_000_000)
        send(100, 110_000_000, (1000.0, 0.0, 0.0))            # 1000 rad in 10 ms: impossible
        send(100, 120_000_000, (1e308, 1e308, 0.0))           # overflows when squared
        send(2_000_000_000, 0)                                 # a lone stamp far in the future
        for k in range(13, 21):
            send(100, k * 10_000_000)
        for k in range(1, 7):                                  # the clock restarts at 5 s
            send(5, k * 10_000_000)
        assert spin_until(ex, lambda: sins.gyro_check.received >= 27 and len(got) >= 24,
                          5.0), len(got)
        g = sins.gyro_check
        assert (g.out_of_range, g.stamp_outliers, g.resyncs, g.out_of_order) == (2, 1, 1, 0)
        assert g.accepted == 10 + 8 + 6 and sins.integrator.updates == 24
        q = np.array([[m.quaternion.x, m.quaternion.y, m.quaternion.z,
                       m.quaternion.w] for m in got])
        assert np.all(np.isfinite(q)) and np.allclose(np.linalg.norm(q, axis=1), 1.0)
        # the attitude is the sum of the 24 accepted increments about x (nothing impossible in it)
        angle = 2 * np.arctan2(np.linalg.norm(q[-1, :3]), abs(q[-1, 3]))
        assert angle == pytest.approx(24 * 0.001, rel=1e-9)
        sins.publish_diagnostics()
        assert spin_until(ex, lambda: any(s.name.startswith(f'{ns}/sins_node')
                                          for d in diags for s in d.status), 5.0)
        st = [s for d in diags for s in d.status if s.name.startswith(f'{ns}/sins_node')][-1]
        kv = {v.key: v.value for v in st.values}
        # ERROR naming the cause
        assert st.level == b'\x02' and 'jumped' in st.message, st.message
        assert (kv['gyro_dropped_out_of_range'], kv['gyro_dropped_stamp_outlier'],
                kv['gyro_stamp_resyncs']) == \
            ('2', '1', '1')
    finally:
        for n in (sins, src):
            ex.remove_node(n)
            n.destroy_node()


def test_sins_node_never_publishes_a_non_finite_state(ros, monkeypatch):
    """
    Check: sins node never publishes a non finite state.

    Should the core ever produce a non-finite update, it is not published; the state returns to the
    last good one with an inflated σ and /diagnostics says ERROR.
    """
    sins = SinsNode(namespace='/t_nonfinite',
                    parameter_overrides=[Parameter('coning_algorithm', value='1'), *IDEAL])
    sent = []
    monkeypatch.setattr(sins.pub_att, 'publish', sent.append)
    # outputs are built lazily
    monkeypatch.setattr(sins.pub_att, 'get_subscription_count', lambda: 1)
    try:
        def msg(k):
            m = Vector3Stamped()
            m.header.stamp.sec, m.header.stamp.nanosec = 10, k * 10_000_000
            m.vector.x = 0.001
            return m
        for k in range(1, 6):
            sins.on_gyro(msg(k))
        good_q, sigma0 = sins.integrator.q.copy(), np.sqrt(np.trace(sins.integrator.covariance()))
        real_push = sins.integrator.push

        def poisoned(*a, **kw):
            b = real_push(*a, **kw)
            b.attitude[:] = np.nan
            return b
        monkeypatch.setattr(sins.integrator, 'push', poisoned)
        sins.on_gyro(msg(6))
        monkeypatch.setattr(sins.integrator, 'push', real_push)
        sins.on_gyro(msg(7))
        # update 6 never published
        assert len(sent) == 6 and sins.nonfinite == 1
        assert all(np.isfinite([m.quaternion.w for m in sent]))
        # back at the good state after update 5, then update 7 on top: 6 increments of 0.001 rad
        q = sins.integrator.q
        assert 2 * np.arctan2(np.linalg.norm(q[1:]), abs(q[0])) == pytest.approx(6 * 0.001,
                                                                                 rel=1e-9)
        assert 2 * np.arctan2(np.linalg.norm(good_q[1:]),
                              abs(good_q[0])) == pytest.approx(5 * 0.001, rel=1e-9)
        # inflated by 0.01 rad/axis
        assert np.sqrt(np.trace(sins.integrator.covariance())) > sigma0 + 0.009
        # the raw subscription path: bytes that are no message are counted and dropped, nothing
        # else
        from rclpy.serialization import serialize_message
        updates = sins.integrator.updates
        sins.on_gyro_raw(b'\x00\x01\x00\x00garbage')
        assert sins.undecodable == 1 and sins.integrator.updates == updates
        sins.on_gyro_raw(serialize_message(msg(8)))
        assert sins.integrator.updates == updates + 1 and len(sent) == 7
    finally:
        sins.destroy_node()


@pytest.mark.parametrize('rule, used', [('reject', 2), ('accept', 3)])
def test_frame_rule(ros, rule, used):
    """
    Check: frame rule.

    An increment in another frame than frame_id is counted and WARNed, and rejected by default; an
    empty frame_id is unspecified and used.
    """
    sins = SinsNode(namespace=f'/t_frame_{rule}', parameter_overrides=[
        Parameter('coning_algorithm', value='1'), Parameter('frame_mismatch', value=rule), *IDEAL])
    try:
        for k, frame in enumerate(('imu_link', '', 'camera'), 1):
            m = Vector3Stamped()
            m.header.stamp.sec, m.header.stamp.nanosec = 10, k * 10_000_000
            m.header.frame_id = frame
            m.vector.x = 0.001
            sins.on_gyro(m)
        assert sins.frame_mismatch['gyro'] == 1 and sins.integrator.updates == used
    finally:
        sins.destroy_node()


def test_parameter_rules(ros):
    """
    Check: parameter rules.

    An integer parameter given 1.5 is refused (not truncated); an integer list for a double array
    is read as doubles; setting a parameter to its current value is no change (ros2 param load of
    the shipped file succeeds); an unknown -p name is refused with its name; changes are validated
    on set and applied after.
    """
    with pytest.raises(InvalidParameter, match='qos_depth must be an integer'):
        SinsNode(namespace='/t_p1', parameter_overrides=[Parameter('qos_depth', value=1.5)])
    with pytest.raises(InvalidParameter, match='gyro_bais'):
        SinsNode(namespace='/t_p2',
                 parameter_overrides=[Parameter('gyro_bais', value=[0.0, 0.0, 0.0])])
    sim = ImuSimNode(namespace='/t_p3',
                     parameter_overrides=[Parameter('gravity', value=[0, 0, 9])])
    try:
        assert sim.p['gravity'] == [0.0, 0.0,
                                    9.0] and all(isinstance(g, float) for g in sim.p['gravity'])
    finally:
        sim.destroy_node()
    sins = SinsNode(namespace='/t_p4', parameter_overrides=[*IDEAL])
    try:
        same = sins.set_parameters([Parameter('frame_id', value='imu_link'),
                                    Parameter('qos_depth', value=500)])
        # unchanged values: no change
        assert all(r.successful for r in same)
        changed = sins.set_parameters([Parameter('frame_id', value='other')])
        assert not changed[0].successful and 'restart' in changed[0].reason
        ok = sins.set_parameters([Parameter('coning_algorithm', value='4+')])
        assert (ok[0].successful and sins.integrator.algorithm_name == '4+'
                and sins.p['coning_algorithm'] == '4+')
    finally:
        sins.destroy_node()


def _captured(node, monkeypatch):
    """
    Copy what a node publishes on sins/attitude and sins/imu.

    Copies of what a node publishes on sins/attitude and sins/imu (the node reuses its message
    objects, so the fields are copied at publish time).
    """
    out = {'att': [], 'imu': []}

    def att(m):
        out['att'].append((stamp_to_ns(m.header.stamp),
                           from_ros_xyzw([m.quaternion.x, m.quaternion.y,
                                          m.quaternion.z, m.quaternion.w])))

    def imu(m):
        a = m.linear_acceleration
        out['imu'].append((stamp_to_ns(m.header.stamp),
                           np.array(m.orientation_covariance, dtype=float),
                           np.array([a.x, a.y, a.z]), float(m.linear_acceleration_covariance[0])))
    monkeypatch.setattr(node.pub_att, 'publish', att)
    monkeypatch.setattr(node.pub_imu, 'publish', imu)
    # as if subscribed: outputs are built lazily
    for pub in (node.pub_att, node.pub_imu):
        monkeypatch.setattr(pub, 'get_subscription_count', lambda: 1)
    return out


def test_sins_node_batches_equal_per_message_processing(ros, monkeypatch):
    """
    Check: sins node batches equal per message processing.

    The hot path only validates and appends; blocks go through the vectorised core.  Blocks of 50
    ms (batch_period 0.05) and message-by-message processing (batch_period 0) publish the same
    updates with the same stamps, attitudes, covariances and specific forces to round-off — with a
    gyro effect compensated, the 004 covariance model, a gap, and a change of coning algorithm in
    the middle.  Both also match the exact coning attitude.
    """
    rate, n = 1000.0, 3000
    prof = ConingProfile(ALPHA, NU, gravity=(0.0, 0.0, 9.80665))
    q0 = prof.attitude(0.0)
    tg = np.arange(n + 1) / rate
    ta = np.arange(3 * n + 1) / (3 * rate)
    bias = np.array([1e-5, -2e-5, 3e-5])                 # rad/s, compensated by the node
    dth = prof.delta_theta(tg[:-1], tg[1:]) + bias / rate
    dv = prof.delta_v(ta[:-1], ta[1:])
    keep = np.ones(n, bool)
    keep[1500:1503] = False                              # a 3-sample gap
    common = [Parameter('gyro_rate', value=rate), Parameter('accel_rate', value=3 * rate),
              Parameter('covariance_model', value='004'), Parameter('gyro_bias', value=list(bias)),
              Parameter('initial_orientation', value=list(to_ros_xyzw(q0))),
              Parameter('coning_algorithm', value='2')]

    def v3(t, v):
        m = Vector3Stamped()
        m.header.frame_id = 'imu_link'
        ns = 5_000_000_000 + int(round(t * 1e9))
        m.header.stamp.sec, m.header.stamp.nanosec = ns // 1_000_000_000, ns % 1_000_000_000
        m.vector.x, m.vector.y, m.vector.z = (float(c) for c in v)
        return m
    gyro = [v3(t, v) for t, v in zip(tg[1:], dth)]
    accel = [v3(t, v) for t, v in zip(ta[1:], dv)]
    results = {}
    for batch in (0.0, 0.05):
        node = SinsNode(namespace=f'/t_batch_{int(batch * 1000)}',
                        parameter_overrides=[*common, Parameter('batch_period', value=batch)])
        try:
            out = _captured(node, monkeypatch)
            pushes = []
            real_push = node.integrator.push
            monkeypatch.setattr(node.integrator, 'push',
                                lambda *x: pushes.append(1) or real_push(*x))
            for k in range(n):
                for j in range(3):
                    node.on_accel(accel[3 * k + j])
                if keep[k]:
                    node.on_gyro(gyro[k])
                if k == 2000:                            # runtime switch, between two messages
                    node.set_parameters([Parameter('coning_algorithm', value='one_plus_previous')])
            node.process()
            results[batch] = out
            # blocks of 50 ms
            assert len(pushes) == (n - 3 if batch == 0 else pytest.approx(n / 50, abs=5))
            assert node.gyro_check.missing == 3 and node.algorithm_changes == 1
        finally:
            node.destroy_node()
    a, b = results[0.0], results[0.05]
    assert (len(a['att']) == len(b['att']) > 1000
            and len(a['imu']) == len(b['imu']) == len(a['att']))
    assert [s for s, _ in a['att']] == [s for s, _ in b['att']]
    qa, qb = np.array([q for _, q in a['att']]), np.array([q for _, q in b['att']])
    assert np.max(np.abs(qa - qb)) < 1e-14
    ca, cb = np.array([c for _, c, _, _ in a['imu']]), np.array([c for _, c, _, _ in b['imu']])
    assert np.max(np.abs(ca - cb)) <= 1e-12 * np.max(np.abs(ca))
    fa, fb = np.array([f for _, _, f, _ in a['imu']]), np.array([f for _, _, f, _ in b['imu']])
    assert np.max(np.abs(fa - fb)) < 1e-9 and all(x[3] >= 0 for x in a['imu'] + b['imu'])
    # independent truth: the exact attitude at each published stamp (compensated bias: no drift)
    t_out = (np.array([s for s, _ in b['att']]) - 5_000_000_000) * 1e-9
    err = quat_angle_between(qb, prof.attitude(t_out))
    # the gap loses 3 ms of rotation after 1.5 s
    assert np.max(err[t_out < 1.5]) < 1e-7
    # specific force: the mean over each update interval of the exact Δv
    f_true = (prof.delta_v(t_out[:200] - 2e-3, t_out[:200]) / 2e-3)
    assert np.max(np.abs(fb[:200] - f_true)) < 1e-9


def test_stream_qos_overrides_and_simulator_waits_for_subscribers(ros):
    """
    Check: stream qos overrides and simulator waits for subscribers.

    The stream topics take the standard qos_overrides parameters (load_bench makes every path
    reliable so); a simulator with wait_for_subscribers starts its clock only once matched, so a
    consumer started later still gets the first increment.
    """
    ns = '/t_qos'
    sins = SinsNode(namespace=ns, parameter_overrides=[
        Parameter(f'qos_overrides.{ns}/imu/delta_theta.subscription.reliability',
                  value='reliable')])
    sim = ImuSimNode(namespace=ns, parameter_overrides=[
        Parameter('wait_for_subscribers', value=2), Parameter('time_scale', value=5.0), *IDEAL,
        Parameter(f'qos_overrides.{ns}/imu/delta_theta.publisher.reliability', value='reliable')])
    ex = GraphExecutor()
    probe = rclpy.create_node('probe', namespace=ns)
    try:
        for n in (sins, sim, probe):
            ex.add_node(n)
        infos = probe.get_subscriptions_info_by_topic(f'{ns}/imu/delta_theta')
        assert [i.qos_profile.reliability for i in infos] == [ReliabilityPolicy.RELIABLE]
        pub = probe.get_publishers_info_by_topic(f'{ns}/imu/delta_theta')[0]
        assert pub.qos_profile.reliability == ReliabilityPolicy.RELIABLE
        spin_until(ex, lambda: False, 1.0)
        # one subscriber of two
        assert sim.counts['delta_theta'] == 0 and not sim.pacing_started
        got = []
        probe.create_subscription(Vector3Stamped, 'imu/delta_theta', got.append, stream_qos(QUEUE))
        assert spin_until(ex, lambda: len(got) > 20, 20.0)
        # the first 100 Hz increment
        assert stamp_to_ns(got[0].header.stamp) == 10_000_000
        assert sins.gyro_check.received > 0
    finally:
        for n in (sins, sim, probe):
            ex.remove_node(n)
            n.destroy_node()
