"""
strapdown_demo: three demonstrations over real ROS 2 topics, faster than real time.

1. Coning: imu_sim_node → several sins_node instances on a coning profile, then a table of each
   algorithm's attitude error and cone-axis drift.
2. Calibration (004): imu_sim_node + star_camera_sim_node + sins_node + calibrator_node on the
   bench trajectory with a large boresight, then the estimate ± σ against the truth in arcsec.
3. Navigation (003 §1.5): imu_sim_node on a coordinated turn with navigation-grade sensor errors
   + sins_node with ``navigation: true``; sins/odometry against imu/truth/odometry, with the
   published σ.

All nodes run in this process under one executor and talk over real ROS 2 topics:

    /demo/imu/delta_theta, /demo/imu/delta_velocity   (one simulator)
    /demo/<algorithm>/sins/attitude, .../sins/imu     (one sins_node per algorithm)

Truth is the closed-form coning attitude (003 §2.2); the theory column is the small-α
cone-axis drift of each algorithm (doc/coning_derivations.md).
"""
from __future__ import annotations

import argparse
import json
import sys
import time

from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter

from strapdown_ros import earth as G
from strapdown_ros.attitude.coning import ALGORITHMS, theory_drift
from strapdown_ros.motion.earth_profiles import navigation_profile_from_config
from strapdown_ros.motion.profiles import ConingProfile
from strapdown_ros.nodes.calibrator_node import CalibratorNode
from strapdown_ros.nodes.imu_sim_node import ImuSimNode
from strapdown_ros.nodes.ros_io import stamp_to_ns, stream_qos
from strapdown_ros.nodes.sins_node import SinsNode
from strapdown_ros.nodes.star_camera_sim_node import StarCameraSimNode
from strapdown_ros.params import PROFILE_PARAMS
from strapdown_ros.rotation import (dcm_to_quat, from_ros_xyzw, quat_angle_between, quat_conjugate,
                                    quat_error_rotvec, quat_multiply, to_ros_xyzw, ypr_to_dcm)
from strapdown_ros.sensors import DEG_PER_HOUR

ARCSEC = np.degrees(1.0) * 3600.0


def _teardown(ex, nodes) -> None:
    for n in nodes:
        if n in ex.get_nodes():
            ex.remove_node(n)
        n.destroy_node()


def namespace_for(algorithm: str) -> str:
    """
    Return the node namespace of an algorithm's sins_node (a valid ROS name).

    Parameters
    ----------
    algorithm : str
        A coning algorithm name.

    Returns
    -------
    str
        ``alg_<name>`` with ``+`` and ``.`` replaced.

    """
    return 'alg_' + algorithm.replace('+', 'plus').replace('.', '_')


def parse_args(argv):
    """
    Parse the demo's command line (errors: one line, exit 2).

    Parameters
    ----------
    argv : list of str
        The arguments, without the program name.

    Returns
    -------
    argparse.Namespace
        The options.

    """
    ap = argparse.ArgumentParser(prog='strapdown_demo', description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--algorithms', default='1,2,6,7,4+,three_sample_optimal',
                    help='comma-separated coning algorithms (default: %(default)s)')
    ap.add_argument('--duration', type=float, default=12.0, help='simulated seconds (default 12)')
    ap.add_argument('--time-scale', type=float, default=1.0, help='simulated seconds per wall '
                                                                  'second (default 1: six '
                    'SINS nodes and the simulator share one executor thread)')
    ap.add_argument('--alpha', type=float, default=0.1,
                    help='coning half-angle, rad (default 0.1)')
    ap.add_argument('--nu', type=float, default=4 * np.pi,
                    help='coning frequency, rad/s (default 4π: 2 Hz)')
    ap.add_argument('--errors', choices=('ideal', 'navigation_grade'), default='ideal',
                    help='sensor errors: ideal shows the algorithmic error (default), '
                         'navigation_grade uses 004 §6')
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--json', help='also write the table as JSON to this file')
    ap.add_argument('--no-calibration', action='store_true',
                    help='skip the calibration graph (part 2)')
    ap.add_argument('--no-navigation', action='store_true',
                    help='skip the navigation graph (part 3)')
    ap.add_argument('--boresight-deg', default='40,-25,120',
                    help='true boresight ψ,ϑ,γ in degrees (part 2)')
    args = ap.parse_args(argv)
    args.algorithms = [a for a in args.algorithms.split(',') if a]
    unknown = [a for a in args.algorithms if a not in ALGORITHMS]
    if unknown:
        ap.error(
            f"unknown algorithm(s) {', '.join(unknown)}; valid names: {', '.join(ALGORITHMS)}")
    if args.duration < 10.0:
        ap.error('--duration must be at least 10 simulated seconds')
    return args


def cone_axis_drift(stamps, q_est, profile: ConingProfile) -> float:
    """
    Return the least-squares slope of the reference-Z error over whole cone periods.

    Parameters
    ----------
    stamps : ndarray (n,)
        Update times, s.
    q_est : ndarray (n, 4)
        Estimated attitudes q_ref_body, scalar first.
    profile : ConingProfile
        The true motion.

    Returns
    -------
    float
        Drift of the cone-axis error, rad/s.

    """
    whole = np.floor(stamps[-1] / profile.cone_period) * profile.cone_period
    keep = stamps <= whole + 1e-9
    d = quat_multiply(q_est[keep], quat_conjugate(profile.attitude(stamps[keep])))
    ez = 2.0 * d[:, 3] * np.sign(d[:, 0])
    return float(np.polyfit(stamps[keep], ez, 1)[0])


def run(args) -> list[dict]:
    """
    Run the coning demonstration: one simulator, one sins_node per algorithm.

    Parameters
    ----------
    args : argparse.Namespace
        From :func:`parse_args`.

    Returns
    -------
    (list of dict, dict)
        One row per algorithm (errors, drift, counts) and the run's metadata.

    """
    profile = ConingProfile(args.alpha, args.nu)
    sensor_params = []
    if args.errors == 'ideal':
        statistics = ('bias_sigma', 'scale_sigma', 'misalignment_sigma', 'random_walk')
        sensor_params = [Parameter(f'{s}_{k}', value=0.0) for s in ('gyro', 'accel')
                         for k in statistics]
    sim = ImuSimNode(namespace='/demo', parameter_overrides=[
        Parameter('profile', value='coning'), Parameter('coning_alpha', value=args.alpha),
        Parameter('coning_nu', value=args.nu), Parameter('time_scale', value=args.time_scale),
        Parameter('duration', value=args.duration), Parameter('seed', value=args.seed),
        *sensor_params])
    q0 = list(to_ros_xyzw(profile.attitude(0.0)))
    remap = ['--ros-args', '-r', 'imu/delta_theta:=/demo/imu/delta_theta',
             '-r', 'imu/delta_velocity:=/demo/imu/delta_velocity']
    sins = {a: SinsNode(namespace='/demo/' + namespace_for(a), cli_args=remap,
                        parameter_overrides=[Parameter('coning_algorithm', value=a),
                                             Parameter('initial_orientation', value=q0),
                                             *sensor_params])
            for a in args.algorithms}
    mon = rclpy.create_node('demo_monitor', namespace='/demo')
    received = {a: [] for a in args.algorithms}
    counts = {'delta_theta': 0}
    for a in args.algorithms:
        mon.create_subscription(QuaternionStamped, f'/demo/{namespace_for(a)}/sins/attitude',
                                lambda m, a=a: received[a].append(m), stream_qos())
    mon.create_subscription(Vector3Stamped, '/demo/imu/delta_theta',
                            lambda m: counts.__setitem__('delta_theta', counts['delta_theta'] + 1),
                            stream_qos())
    ex = SingleThreadedExecutor()
    for n in (sim, mon, *sins.values()):
        ex.add_node(n)
    try:
        # wait for discovery so no early message is lost, then let the simulator's clock start
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and any(
                mon.count_publishers(f'/demo/{namespace_for(a)}/sins/attitude') == 0
                for a in args.algorithms):
            ex.spin_once(timeout_sec=0.05)
        sim.restart_pacing()
        wall0 = time.monotonic()
        deadline = wall0 + 5.0 * args.duration / args.time_scale + 30.0
        expected = {a: int(round(args.duration * sim.gyro.period ** -1)) // ALGORITHMS[a].samples
                    for a in args.algorithms}
        while time.monotonic() < deadline and not (
                sim.finished and all(len(received[a]) >= expected[a] for a in args.algorithms)):
            ex.spin_once(timeout_sec=0.01)
        wall = time.monotonic() - wall0
        rows = []
        for a in args.algorithms:
            msgs = received[a]
            node = sins[a]
            check = node.gyro_check
            row = {'algorithm': a, 'samples_per_update': ALGORITHMS[a].samples,
                   'published': len(msgs), 'gyro_in': check.accepted,
                   'dropped': check.nan + check.out_of_order + check.duplicate,
                   'missing': check.missing}
            if msgs:
                st = np.array([stamp_to_ns(m.header.stamp) * 1e-9 for m in msgs])
                q = from_ros_xyzw(np.array([[m.quaternion.x, m.quaternion.y, m.quaternion.z,
                                             m.quaternion.w] for m in msgs]))
                row['final_error_arcsec'] = float(quat_angle_between(
                    q[-1], profile.attitude(st[-1])) * ARCSEC)
                row['drift_deg_per_h'] = cone_axis_drift(st, q, profile) / DEG_PER_HOUR
                th = theory_drift(ALGORITHMS[a], args.nu * ALGORITHMS[a].samples * sim.gyro.period)
                row['theory_deg_per_h'] = None if th is None else float(
                    th * args.alpha ** 2 * args.nu / DEG_PER_HOUR)
                sig = np.sqrt(np.diag(node.integrator.covariance()))
                row['published_sigma_arcsec'] = float(np.linalg.norm(sig) * ARCSEC)
            rows.append(row)
        return rows, {'simulated_s': sim.sim_time, 'wall_s': wall,
                      'delta_theta_published': sim.counts['delta_theta'],
                      'delta_velocity_published': sim.counts['delta_velocity'],
                      'delta_theta_seen_by_monitor': counts['delta_theta']}
    finally:
        _teardown(ex, (sim, mon, *sins.values()))


def format_table(rows, meta, args) -> str:
    """
    Return the coning table as text.

    Parameters
    ----------
    rows : list of dict
        From :func:`run`.
    meta : dict
        From :func:`run`.
    args : argparse.Namespace
        The options.

    Returns
    -------
    str
        The table and its legend.

    """
    lines = [f'coning α = {args.alpha:g} rad, ν = {args.nu:.4g} rad/s, gyro 100 Hz, accel 300 Hz, '
             f"sensors: {args.errors}; {meta['simulated_s']:.1f} simulated s in "
             f"{meta['wall_s']:.1f} wall s "
             f"({meta['simulated_s'] / max(meta['wall_s'], 1e-9):.1f}× real time)",
             f"simulator published {meta['delta_theta_published']} Δθ and "
             f"{meta['delta_velocity_published']} Δv messages",
             '',
             f"{'algorithm':<22}{'N':>3}{'final error ″':>15}{'drift °/h':>13}{'theory °/h':>13}"
             f"{'σ pub. ″':>10}{'Δθ in':>8}{'out':>7}{'dropped':>9}"]
    for r in rows:
        th = r.get('theory_deg_per_h')
        nan = float('nan')
        lines.append(f"{r['algorithm']:<22}{r['samples_per_update']:>3}"
                     f"{r.get('final_error_arcsec', nan):>15.4g}"
                     f"{r.get('drift_deg_per_h', nan):>13.4g}"
                     f'{(th if th is not None else nan):>13.4g}'
                     f"{r.get('published_sigma_arcsec', nan):>10.3g}{r['gyro_in']:>8}"
                     f"{r['published']:>7}{r['dropped'] + r['missing']:>9}")
    lines += ['',
              'drift: least-squares slope of the cone-axis error over whole cone periods; '
              'theory: small-α drift',
              'exact in Ωh (doc/coning_derivations.md). At α = 0.1 algorithms of order ≥ 6 sit '
              'on the α⁴ floor,',
              'above their small-α theory. σ pub.: norm of the published 1σ attitude error '
              '(0 with ideal sensors).']
    return '\n'.join(lines)


def run_calibration(args) -> dict:
    """
    Run the calibration demonstration on the bench trajectory (004 §6 style).

    imu_sim_node + star_camera_sim_node + sins_node + calibrator_node under one executor.

    Parameters
    ----------
    args : argparse.Namespace
        From :func:`parse_args`.

    Returns
    -------
    dict
        The estimate, its σ and the truth (degrees and arcsec), counts and timing.

    """
    # one thread serves four nodes: the events executor keeps up
    try:
        from rclpy.experimental import EventsExecutor as Executor
    except ImportError:                       # pragma: no cover - older rclpy
        Executor = SingleThreadedExecutor
    beta = np.radians([float(x) for x in args.boresight_deg.split(',')])
    time_scale = 8.0                 # four nodes and the monitor on one executor thread
    common = [Parameter('profile', value='bench'), Parameter('time_scale', value=time_scale),
              Parameter('qos_depth', value=20000), Parameter('seed', value=args.seed)]
    sim = ImuSimNode(namespace='/calib',
                     parameter_overrides=[*common, Parameter('accel_rate', value=10.0)])
    cam = StarCameraSimNode(namespace='/calib', parameter_overrides=[
        *common, Parameter('camera_interval', value=5.0),
        Parameter('boresight', value=list(beta))])
    sins = SinsNode(namespace='/calib',
                    parameter_overrides=[Parameter('qos_depth', value=20000),
                                         Parameter('coning_algorithm', value='2')])
    cal = CalibratorNode(namespace='/calib',
                         parameter_overrides=[Parameter('qos_depth', value=20000)])
    ex = Executor()
    nodes = (sim, cam, sins, cal)
    for n in nodes:
        ex.add_node(n)
    try:
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and sim.count_subscribers('/calib/imu/delta_theta') < 2:
            ex.spin_once(timeout_sec=0.05)
        sim.restart_pacing()
        cam.restart_pacing()
        wall0 = time.monotonic()
        deadline = wall0 + 3.0 * sim.end_time / time_scale + 30.0
        while time.monotonic() < deadline and not (sim.finished and cam.finished):
            ex.spin_once(timeout_sec=0.01)
        for _ in range(100):                  # drain
            ex.spin_once(timeout_sec=0.01)
        sol = cal.cal.solution
        out = {'simulated_s': sim.sim_time, 'wall_s': time.monotonic() - wall0,
               'pairs': len(cal.cal.pairs), 'beta_true_deg': np.degrees(beta).tolist(),
               'gyro_received': sins.gyro_check.accepted}
        if sol is None or not sol.observable:
            out['observable'] = False
            out['message'] = 'no solution' if sol is None else sol.message
            return out
        sig = np.sqrt(np.diag(sol.covariance_beta))
        err = (sol.beta - beta + np.pi) % (2 * np.pi) - np.pi
        e_mf = quat_error_rotvec(sol.q_mf_vf, dcm_to_quat(ypr_to_dcm(*beta)), 'reference')
        q_sins = sins.integrator.q
        sins_error = quat_error_rotvec(q_sins, sim.profile.attitude(sins.integrator.time), 'body')
        sigma_mf = np.sqrt(np.diag(sol.rotation_covariance_mf))
        out.update({'observable': True, 'beta_deg': np.degrees(sol.beta).tolist(),
                    'error_arcsec': (err / np.radians(1 / 3600)).tolist(),
                    'sigma_arcsec': (sig / np.radians(1 / 3600)).tolist(),
                    'rotation_error_mf_over_sigma': (e_mf / sigma_mf).tolist(),
                    'chi2_per_dof': sol.chi2_per_dof, 'iterations': sol.iterations,
                    'weighting': sol.weighting,
                    'sins_final_error_arcsec': float(np.linalg.norm(sins_error)
                                                     / np.radians(1 / 3600))})
        return out
    finally:
        _teardown(ex, nodes)


def format_calibration(c: dict) -> str:
    """
    Return the calibration result as text.

    Parameters
    ----------
    c : dict
        From :func:`run_calibration`.

    Returns
    -------
    str
        The estimate against the truth per angle.

    """
    lines = ['', 'Boresight calibration: imu_sim_node + star_camera_sim_node + sins_node + '
                 'calibrator_node, bench '
             f"trajectory, {c['simulated_s']:.0f} simulated s in {c['wall_s']:.1f} wall s, "
             'camera every 5 s, '
             f"{c['pairs']} increment pairs"]
    if not c.get('observable'):
        lines.append(f"  not observable: {c.get('message')}")
        return '\n'.join(lines)
    lines.append(
        f"{'angle':<10}{'truth °':>12}{'estimate °':>14}{'error ″':>10}{'σ ″':>8}{'error/σ':>9}")
    for k, name in enumerate(('heading ψ', 'pitch ϑ', 'roll γ')):
        e, s_ = c['error_arcsec'][k], c['sigma_arcsec'][k]
        lines.append(
            f"{name:<10}{c['beta_true_deg'][k]:>12.4f}{c['beta_deg'][k]:>14.5f}"
            f'{e:>10.2f}{s_:>8.2f}{e / s_:>9.2f}')
    lines.append(f"Gauss–Newton, {c.get('weighting', 'weighted')} weighting, χ²/dof "
                 f"{c['chi2_per_dof']:.2f}; "
                 'rotation error in MF axes / σ: '
                 + ', '.join(f'{v:+.2f}' for v in c['rotation_error_mf_over_sigma'])
                 + '; SINS (algorithm 2) attitude error at the end: '
                   f"{c['sins_final_error_arcsec']:.2f}″")
    return '\n'.join(lines)


def run_navigation(args, duration: float = 60.0) -> dict:
    """
    Run the navigation demonstration: a coordinated turn into sins_node with navigation.

    Parameters
    ----------
    args : argparse.Namespace
        From :func:`parse_args`.
    duration : float
        Simulated seconds.

    Returns
    -------
    dict
        Position, velocity and attitude errors against the truth, NEES, counts and timing.

    """
    from nav_msgs.msg import Odometry
    try:
        from rclpy.experimental import EventsExecutor as Executor
    except ImportError:                       # pragma: no cover - older rclpy
        Executor = SingleThreadedExecutor
    # the simulator's own parameters (its defaults: gravity_model included), so that the
    # initial state given to sins_node is the simulated one
    prof = navigation_profile_from_config({**{s.name: s.default for s in PROFILE_PARAMS},
                                           'profile': 'coordinated_turn'})
    r0, w0 = prof.position(np.array([0.0]))[0], prof.velocity(np.array([0.0]))[0]
    lat, lon, h = G.ecef_to_geodetic(r0)
    enu = G.enu_rotation(lat, lon)
    # best-effort streams: bursts at higher scales lose messages on 2 cores
    time_scale = 4.0
    sim = ImuSimNode(namespace='/nav', parameter_overrides=[
        Parameter('profile', value='coordinated_turn'), Parameter('time_scale', value=time_scale),
        Parameter('duration', value=duration), Parameter('qos_depth', value=20000),
        Parameter('seed', value=args.seed)])
    sins = SinsNode(namespace='/nav', parameter_overrides=[
        Parameter('navigation', value=True), Parameter('coning_algorithm', value='2'),
        Parameter('initial_position', value=[
                  float(np.degrees(lat)), float(np.degrees(lon)), float(h)]),
        Parameter('initial_velocity', value=[float(x) for x in enu.T @ w0]),
        Parameter('initial_orientation', value=[
                  float(x) for x in to_ros_xyzw(prof.attitude_ecef(np.array([0.0]))[0])]),
        Parameter('qos_depth', value=20000)])
    mon = rclpy.create_node('nav_monitor', namespace='/nav')
    got = {'sins': {}, 'truth': {}}
    mon.create_subscription(Odometry, 'sins/odometry',
                            lambda m: got['sins'].__setitem__(stamp_to_ns(m.header.stamp), m),
                            stream_qos(20000))
    mon.create_subscription(Odometry, 'imu/truth/odometry',
                            lambda m: got['truth'].__setitem__(stamp_to_ns(m.header.stamp), m),
                            stream_qos(20000))
    ex = Executor()
    nodes = (sim, sins, mon)
    try:
        # discovery first, without spinning: the simulator publishes nothing before everybody
        # listens
        deadline = time.monotonic() + 10.0
        sim_topics = ('/nav/imu/delta_theta', '/nav/imu/delta_velocity', '/nav/imu/truth/odometry')
        while time.monotonic() < deadline and not (
                sins.count_subscribers('/nav/sins/odometry') >= 1
                and all(sim.count_subscribers(t) >= 1 for t in sim_topics)):
            time.sleep(0.05)
        for n in nodes:
            ex.add_node(n)
        wall0 = time.monotonic()
        deadline = wall0 + 3.0 * duration / time_scale + 30.0
        last, quiet = -1, time.monotonic()
        while time.monotonic() < deadline and not (
                sim.finished and len(got['sins']) >= int(duration * 50) - 2):
            ex.spin_once(timeout_sec=0.01)
            if len(got['sins']) != last:
                last, quiet = len(got['sins']), time.monotonic()
            elif sim.finished and time.monotonic() - quiet > 2.0:      # nothing more is coming
                break
        for _ in range(50):                   # drain
            ex.spin_once(timeout_sec=0.01)
        common = sorted(set(got['sins']) & set(got['truth']))
        out = {'simulated_s': sim.sim_time, 'wall_s': time.monotonic() - wall0,
               'steps': len(got['sins']), 'frame_id': None, 'child_frame_id': None}
        if not common:
            return out
        m, t = got['sins'][common[-1]], got['truth'][common[-1]]
        p = m.pose.pose.position
        dp = np.array([p.x, p.y, p.z]) - np.array([t.pose.pose.position.x, t.pose.pose.position.y,
                                                   t.pose.pose.position.z])
        cov = np.array(m.pose.covariance).reshape(6, 6)[:3, :3]
        out.update({'frame_id': m.header.frame_id, 'child_frame_id': m.child_frame_id,
                    't_s': (common[-1] - common[0]) * 1e-9, 'position_error_m': dp.tolist(),
                    'position_sigma_m': np.sqrt(np.diag(cov)).tolist(),
                    'position_nees': float(dp @ np.linalg.solve(cov, dp)),
                    'attitude_error_arcsec': float(quat_angle_between(
                        from_ros_xyzw([m.pose.pose.orientation.x, m.pose.pose.orientation.y,
                                       m.pose.pose.orientation.z, m.pose.pose.orientation.w]),
                        from_ros_xyzw([t.pose.pose.orientation.x, t.pose.pose.orientation.y,
                                       t.pose.pose.orientation.z, t.pose.pose.orientation.w]))
                        * ARCSEC)})
        return out
    finally:
        _teardown(ex, nodes)


def format_navigation(c: dict) -> str:
    """
    Return the navigation result as text.

    Parameters
    ----------
    c : dict
        From :func:`run_navigation`.

    Returns
    -------
    str
        The errors against the truth and the published σ.

    """
    lines = ['', 'Navigation: imu_sim_node (coordinated turn, navigation-grade sensor errors) + '
                 'sins_node '
             f"(navigation: true, algorithm 2), {c['simulated_s']:.0f} simulated s in "
             f"{c['wall_s']:.1f} wall s, "
             f"{c['steps']} sins/odometry messages"]
    if 'position_error_m' not in c:
        lines.append('  no sins/odometry matched imu/truth/odometry')
        return '\n'.join(lines)
    lines.append(f"frames {c['frame_id']} → {c['child_frame_id']}; after {c['t_s']:.1f} s, ECEF "
                 'position error '
                 'against the truth (m) and the published 1σ:')
    for k, ax in enumerate('XYZ'):
        e, s_ = c['position_error_m'][k], c['position_sigma_m'][k]
        lines.append(f'  {ax}: error {e:+9.3f}  σ {s_:8.3f}  error/σ {e / s_:+6.2f}')
    lines.append(f"position NEES {c['position_nees']:.2f} (3 dof; one draw of the sensor "
                 'errors), attitude error '
                 f"{c['attitude_error_arcsec']:.1f}″")
    return '\n'.join(lines)


def main(argv=None):
    """
    Run the three demonstrations and print their results (entry point ``strapdown_demo``).

    Parameters
    ----------
    argv : list of str, optional
        The arguments (None: ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status.

    """
    args = parse_args(sys.argv[1:] if argv is None else argv)
    rclpy.init()
    calib = nav = None
    try:
        rows, meta = run(args)
        if not args.no_calibration:
            calib = run_calibration(args)
        if not args.no_navigation:
            nav = run_navigation(args)
    finally:
        rclpy.try_shutdown()
    print(format_table(rows, meta, args))
    if calib is not None:
        print(format_calibration(calib))
    if nav is not None:
        print(format_navigation(nav))
    if args.json:
        with open(args.json, 'w', encoding='utf-8') as fh:
            json.dump({'rows': rows, 'meta': meta, 'calibration': calib, 'navigation': nav,
                       'args': dict(vars(args))}, fh, indent=2, default=float)
    ok = all(r['published'] > 0 and r['dropped'] + r['missing'] == 0 for r in rows) and \
        (calib is None or calib.get('observable', False)) and (
            nav is None or 'position_error_m' in nav)
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
