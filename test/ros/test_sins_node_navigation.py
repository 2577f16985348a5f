"""
sins_node's navigation channel in a real graph (in-process, executor, timeouts).

The sins/odometry
type, frame ids and content against imu_sim_node's exact truth, for the static and turn profiles,
and the static alignment started from the data.
"""

from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter
from ros_helpers import spin_until

from strapdown_ros import earth as G
from strapdown_ros.motion.earth_profiles import navigation_profile_from_config
from strapdown_ros.nodes.imu_sim_node import ImuSimNode
from strapdown_ros.nodes.ros_io import stamp_to_ns, stream_qos
from strapdown_ros.nodes.sins_node import SinsNode
from strapdown_ros.params import PROFILE_PARAMS
from strapdown_ros.rotation import quat_angle_between, to_ros_xyzw


try:
    from rclpy.experimental import EventsExecutor as GraphExecutor
except ImportError:                                                  # pragma: no cover
    from rclpy.executors import SingleThreadedExecutor as GraphExecutor

QUEUE = 20000
IDEAL = [Parameter(f'{s}_{k}', value=0.0) for s in ('gyro', 'accel')
         for k in ('bias_sigma', 'scale_sigma', 'misalignment_sigma', 'random_walk')]


def _run(ns, profile, duration, sins_extra=(), sim_extra=(), expect=None):

    # the truth of the simulator's own parameters (its default gravity_model included: the turn is
    # coordinated with that model's vertical, and the initial state must be that profile's)
    cfg = {**{s.name: s.default for s in PROFILE_PARAMS}, 'profile': profile}
    prof = navigation_profile_from_config(cfg)
    r0, w0 = prof.position(np.array([0.0]))[0], prof.velocity(np.array([0.0]))[0]
    lat, lon, h = G.ecef_to_geodetic(r0)
    enu = G.enu_rotation(lat, lon)
    sim = ImuSimNode(namespace=ns, parameter_overrides=[
        Parameter('profile', value=profile), Parameter('time_scale', value=10.0),
        Parameter('duration', value=duration), Parameter('qos_depth', value=QUEUE),
        # no start lost to discovery
        Parameter('wait_for_subscribers', value=1), *IDEAL, *sim_extra])
    sins = SinsNode(namespace=ns, parameter_overrides=[
        Parameter('navigation', value=True),
        Parameter('coning_algorithm', value='one_plus_previous'),
        Parameter('initial_position',
                  value=[float(np.degrees(lat)), float(np.degrees(lon)), float(h)]),
        Parameter('initial_velocity', value=[float(x) for x in enu.T @ w0]),
        Parameter('initial_orientation',
                  value=[float(x) for x in to_ros_xyzw(prof.attitude_ecef(np.array([0.0]))[0])]),
        Parameter('qos_depth', value=QUEUE), *IDEAL, *sins_extra])
    mon = rclpy.create_node('monitor', namespace=ns)
    got = {'sins': [], 'truth': [], 'diag': []}
    mon.create_subscription(Odometry, 'sins/odometry', got['sins'].append, stream_qos(QUEUE))
    mon.create_subscription(Odometry, 'imu/truth/odometry', got['truth'].append, stream_qos(QUEUE))
    mon.create_subscription(DiagnosticArray, '/diagnostics', got['diag'].append, 10)
    ex = GraphExecutor()
    for n in (sim, sins, mon):
        ex.add_node(n)
    try:
        assert spin_until(ex, lambda: mon.count_publishers(f'{ns}/sins/odometry') == 1
                          and sim.count_subscribers(f'{ns}/imu/delta_velocity') >= 1, 10.0)
        sim.restart_pacing()
        n_expected = expect if expect is not None else int(round(duration * 100)) - 2
        assert spin_until(ex, lambda: sim.finished and len(got['sins']) >= n_expected
                          and len(got['truth']) >= n_expected,
                          60.0), {k: len(v) for k, v in got.items()}
        spin_until(ex, lambda: False, 1.2)          # one more diagnostics period
        return got, sins
    finally:
        for n in (sim, sins, mon):
            ex.remove_node(n)
            n.destroy_node()


def _paired(got):
    truth = {stamp_to_ns(m.header.stamp): m for m in got['truth']}
    pairs = [(m, truth[stamp_to_ns(m.header.stamp)]) for m in got['sins']
             if stamp_to_ns(m.header.stamp) in truth]
    assert len(pairs) > 0.9 * len(got['sins'])
    return pairs


def _pos(m):
    p = m.pose.pose.position
    return np.array([p.x, p.y, p.z])


def _quat(m):
    o = m.pose.pose.orientation
    return np.array([o.w, o.x, o.y, o.z])


@pytest.mark.parametrize('profile, tol_pos, tol_vel',
                         [('static', 1e-6, 1e-6), ('coordinated_turn', 2e-3, 2e-3)])
def test_sins_odometry_matches_the_exact_truth(ros, profile, tol_pos, tol_vel):
    got, _ = _run(f'/t_nav_{profile}', profile, 5.0)
    m0 = got['sins'][0]
    assert m0.header.frame_id == 'earth' and m0.child_frame_id == 'imu_link'
    pairs = _paired(got)
    dp = max(np.linalg.norm(_pos(s) - _pos(t)) for s, t in pairs)
    dv = max(np.linalg.norm(np.array([s.twist.twist.linear.x - t.twist.twist.linear.x,
                                      s.twist.twist.linear.y - t.twist.twist.linear.y,
                                      s.twist.twist.linear.z - t.twist.twist.linear.z]))
             for s, t in pairs)
    da = max(quat_angle_between(_quat(s), _quat(t)) for s, t in pairs)
    assert np.linalg.norm(_pos(pairs[-1][1])) > 6.3e6                     # ECEF, metres
    assert dp < tol_pos and dv < tol_vel and da < 1e-8, (dp, dv, da)
    cov = np.array(pairs[-1][0].pose.covariance).reshape(6, 6)
    assert np.all(np.isfinite(cov)) and np.allclose(cov, cov.T)


def test_static_alignment_starts_navigation_from_the_data(ros):
    got, sins = _run('/t_nav_align', 'static', 8.0, sins_extra=[
        Parameter('initial_alignment', value='static'), Parameter('alignment_time', value=2.0),
        Parameter('initial_orientation', value=[0.0, 0.0, 0.0, 1.0])], expect=590)
    assert sins.nav.alignment is not None and sins.nav.alignment.ok
    pairs = _paired(got) if got['sins'] else []
    # navigation begins after the window
    assert got['sins'] and got['sins'][0].header.stamp.sec >= 2
    # perfect sensors: the aligned attitude equals the truth to the TRIAD's round-off
    da = max(quat_angle_between(_quat(s), _quat(t)) for s, t in pairs)
    assert da < 1e-9
    sins_diag = [st for d in got['diag'] for st in d.status if 'sins_node' in st.name]
    vals = {kv.key: kv.value for kv in sins_diag[-1].values}
    assert vals['navigation_state'] == 'navigating' and vals['alignment'] == 'aligned'
