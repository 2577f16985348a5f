"""
record_sim → rosbag2 → sins_bag: the solution of a recording.

Against the exact truth, against sins_node fed the same messages (same core: the same numbers);
MCAP and CSV outputs, argument errors.
"""
import re

from geometry_msgs.msg import Vector3Stamped
import numpy as np
import pytest
from rclpy.context import Context
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message

from strapdown_ros import earth as G
from strapdown_ros.motion.earth_profiles import navigation_profile_from_config
from strapdown_ros.nodes.ros_io import stamp_to_ns
from strapdown_ros.nodes.sins_node import SinsNode
from strapdown_ros.params import load_parameter_file
from strapdown_ros.recording import mcap_records, open_reader
from strapdown_ros.recording.imu_streams import rate_from_stamps
from strapdown_ros.recording.sins_replay import CSV_ATTITUDE_COLUMNS, CSV_NAV_COLUMNS
from strapdown_ros.rotation import from_ros_xyzw, quat_angle_between, quat_to_dcm, to_ros_xyzw
from strapdown_ros.sins import accel_stall_limits
from strapdown_ros.tools import record_sim, sins_bag


IDEAL = [f'{s}_{k}:=0.0' for s in ('gyro', 'accel')
         for k in ('bias_sigma', 'scale_sigma', 'misalignment_sigma', 'random_walk')]
DURATION = 5.0


def _record(path, profile, *extra, storage='mcap'):
    args = [str(path), '--duration', str(DURATION), '--storage', storage, '-p',
            f'profile:={profile}']
    for item in IDEAL + list(extra):
        args += ['-p', item]
    assert record_sim.main(args) == 0
    return path


def _sins_params(path, profile):
    """
    Write sins_node parameters (ROS 2 YAML) from the profile's exact initial state.

    sins_node parameters (ROS 2 YAML) from the profile's exact initial state, as
    test/ros/test_sins_node_navigation.py configures the node.
    """
    prof = navigation_profile_from_config({'profile': profile})
    r0, w0 = prof.position(np.array([0.0]))[0], prof.velocity(np.array([0.0]))[0]
    lat, lon, h = G.ecef_to_geodetic(r0)
    enu = G.enu_rotation(lat, lon)
    fl = lambda xs: '[' + ', '.join(repr(float(x)) for x in xs) + ']'  # noqa: E731
    ideal = ''.join(f"    {s.split(':=')[0]}: 0.0\n" for s in IDEAL)
    path.write_text('sins_node:\n  ros__parameters:\n    navigation: true\n'
                    '    coning_algorithm: one_plus_previous\n'
                    f'    initial_position: {fl([np.degrees(lat), np.degrees(lon), h])}\n'
                    f'    initial_velocity: {fl(enu.T @ w0)}\n'
                    '    initial_orientation: '
                    f'{fl(to_ros_xyzw(prof.attitude_ecef(np.array([0.0]))[0]))}\n' + ideal)
    return path, prof


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Record the static and turn profiles with their parameter files."""
    d = tmp_path_factory.mktemp('sins_bag')
    out = {}
    for profile, storage in (('static', 'mcap'), ('coordinated_turn', 'sqlite3')):
        bag = _record(d / f'{profile}_{storage}', profile, storage=storage)
        params, prof = _sins_params(d / f'{profile}.yaml', profile)
        out[profile] = (bag, params, prof)
    return out


def _csv(path):
    header = path.read_text().splitlines()[0].split(',')
    data = np.loadtxt(path, delimiter=',', skiprows=1, ndmin=2)
    rows = path.read_text().splitlines()[1:]
    stamps = [int(s.replace('.', '')) for s in (ln.split(',')[0] for ln in rows)]
    return header, data, np.array(stamps, dtype=np.int64)


def _run_tool(capsys, *args):
    rc = sins_bag.main([str(a) for a in args] + ['--quiet'])
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


# --- the solution --------------------------------------------------------------------------------
def test_csv_matches_the_exact_truth_static(bags, tmp_path, capsys):
    bag, params, prof = bags['static']
    out = tmp_path / 'static.csv'
    rc, stdout, err = _run_tool(capsys, bag, '--params', params, '--output', out)
    assert rc == 0, err
    assert 'gyro_rate 100 Hz, accel_rate 300 Hz' in stdout and '500 steps' in stdout
    header, d, ns = _csv(out)
    assert header == CSV_NAV_COLUMNS
    assert (len(d) == int(DURATION * 100) and np.all(np.diff(ns) == 10_000_000)
            and ns[-1] == 5_000_000_000)
    # record_sim: start_time 0 = profile time 0
    t = ns * 1e-9
    dp = np.max(np.linalg.norm(d[:, 1:4] - prof.position(t), axis=1))
    dv = np.max(np.linalg.norm(d[:, 4:7] - prof.velocity(t), axis=1))
    da = np.max(quat_angle_between(from_ros_xyzw(d[:, 7:11]), prof.attitude_ecef(t)))
    assert np.linalg.norm(d[0, 1:4]) > 6.3e6
    # mm, mm/s (achieved: ~1e-6)
    assert dp < 1e-3 and dv < 1e-3 and da < 1e-8, (dp, dv, da)
    assert np.all(d[:, 11:] == 0.0)                            # ideal sensors, zero initial σ


def test_static_alignment_from_the_recording(bags, tmp_path, capsys):
    """
    Check: static alignment from the recording.

    initial_alignment static: the solution starts after alignment_time, aligned to the truth; a
    window longer than the recording gives no solution (exit 3).
    """
    bag, params, prof = bags['static']
    out = tmp_path / 'aligned.csv'
    rc, stdout, err = _run_tool(capsys, bag, '--params', params, '-p', 'initial_alignment:=static',
                                '-p', 'alignment_time:=2.0', '-p',
                                'initial_orientation:=[0.0, 0.0, 0.0, 1.0]',
                                '--output', out)
    assert rc == 0 and 'alignment: aligned' in stdout, err
    _, d, ns = _csv(out)
    t = ns * 1e-9
    assert t[0] > 2.0 and len(d) == 300
    assert np.max(quat_angle_between(from_ros_xyzw(d[:, 7:11]), prof.attitude_ecef(t))) < 1e-9
    assert np.max(np.linalg.norm(d[:, 1:4] - prof.position(t), axis=1)) < 1e-3
    rc, stdout, err = _run_tool(capsys, bag, '--params', params, '-p', 'initial_alignment:=static',
                                '-p', 'alignment_time:=20.0', '--output', tmp_path / 'none.csv')
    assert rc == 3 and 'static alignment did not complete' in err


def test_attitude_only_csv_and_rates_from_the_stamps(tmp_path, capsys):
    """
    Check: attitude only csv and rates from the stamps.

    Navigation off (the node's default): one row per attitude update, σ about body axes.  A 200 Hz
    gyro recording runs at 200 Hz whatever gyro_rate the parameters say.
    """
    bag = _record(tmp_path / 'bag200', 'coning', 'gyro_rate:=200.0')
    out = tmp_path / 'att.csv'
    rc, stdout, err = _run_tool(capsys, bag, '-p', 'gyro_random_walk:=1.0e-6', '--output', out)
    assert rc == 0, err
    assert 'gyro_rate 200 Hz' in stdout
    header, d, ns = _csv(out)
    assert header == CSV_ATTITUDE_COLUMNS
    # algorithm 2: 2 samples
    assert len(d) == int(DURATION * 200) // 2 and np.all(np.diff(ns) == 10_000_000)
    # σ of ε, body axes
    assert np.all(d[:, 5:] > 0) and np.all(d[-1, 5:] > 10 * d[0, 5:])
    assert rate_from_stamps(np.round(np.arange(1, 100) * 1e9 / 300).astype(np.int64)) == 300.0
    assert rate_from_stamps([5, 5]) is None


def test_the_recordings_own_body_frame_unless_one_is_named(tmp_path, capsys):
    """
    Check: the recordings own body frame unless one is named.

    A recording from other software names its own body frame: sins_bag takes it from the headers
    unless frame_id is given; given and different, the model contradicts the recording: an error
    naming both.
    """
    bag = _record(tmp_path / 'bag_imu', 'coning', 'frame_id:=imu')
    rc, stdout, err = _run_tool(capsys, bag, '--output', tmp_path / 'own.csv')
    assert rc == 0, err
    assert len(_csv(tmp_path / 'own.csv')[1]) == int(DURATION * 100) // 2
    rc, stdout, err = _run_tool(capsys, bag, '-p', 'frame_id:=imu_link', '--output',
                                tmp_path / 'named.csv')
    # a stated frame that contradicts the recording is an error naming both (one sensor model)
    assert rc == 2 and "frame_id 'imu_link'" in err and "'imu'" in err, err


def test_mcap_output_has_the_node_topics_and_types(bags, tmp_path, capsys):
    from rosbags.highlevel import AnyReader
    bag, params, prof = bags['coordinated_turn']
    out = tmp_path / 'turn_out'
    rc, stdout, err = _run_tool(capsys, bag, '--params', params, '--output', out)
    assert rc == 0, err
    with AnyReader([out]) as rd:
        types = {c.topic: c.msgtype for c in rd.connections}
        assert types == {'/sins/attitude': 'geometry_msgs/msg/QuaternionStamped',
                         '/sins/imu': 'sensor_msgs/msg/Imu',
                         '/sins/odometry': 'nav_msgs/msg/Odometry'}
        assert all(c.msgcount == 500 for c in rd.connections)
        odo = [rd.deserialize(raw, c.msgtype) for c, _, raw in
               rd.messages(connections=[c for c in rd.connections if c.topic == '/sins/odometry'])]
        imu = [rd.deserialize(raw, c.msgtype) for c, _, raw in
               rd.messages(connections=[c for c in rd.connections if c.topic == '/sins/imu'])]
    assert odo[0].header.frame_id == 'earth' and odo[0].child_frame_id == 'imu_link'
    assert imu[0].header.frame_id == 'imu_link' and imu[-1].linear_acceleration_covariance[0] >= 0
    t = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in odo])
    r = np.array([[m.pose.pose.position.x, m.pose.pose.position.y,
                   m.pose.pose.position.z] for m in odo])
    # as sins_node on the turn
    assert np.max(np.linalg.norm(r - prof.position(t), axis=1)) < 2e-3
    cov = np.array(odo[-1].pose.covariance).reshape(6, 6)
    assert np.all(np.isfinite(cov)) and np.allclose(cov, cov.T)


def test_mcap_output_bytes_are_rosbags_serialization(bags, tmp_path, capsys):
    """
    Check: mcap output bytes are rosbags serialization.

    sins_bag writes its messages as CDR rows made with numpy from one serialised message per topic:
    every record must be exactly what rosbags' serializer makes of the message it holds.
    """
    from rosbags.highlevel import AnyReader
    bag, params, _ = bags['coordinated_turn']
    out = tmp_path / 'bytes_out'
    assert _run_tool(capsys, bag, '--params', params, '--output', out)[0] == 0
    with AnyReader([out]) as rd:
        n = 0
        for c, _, raw in rd.messages():
            msg = rd.deserialize(raw, c.msgtype)
            assert bytes(rd.typestore.serialize_cdr(msg, c.msgtype)) == bytes(raw), c.topic
            n += 1
    assert n == 1500


def test_namespaced_topics_and_force(tmp_path, capsys):
    bag = tmp_path / 'ns_bag'
    assert record_sim.main([str(bag), '--duration', '1', '--namespace', '/robot1', '-p',
                            'profile:=coning']) == 0
    capsys.readouterr()
    out = tmp_path / 'ns_out'
    assert _run_tool(capsys, bag, '--output', out)[0] == 0
    from rosbags.highlevel import AnyReader
    with AnyReader([out]) as rd:
        assert {c.topic for c in rd.connections} == {'/robot1/sins/attitude', '/robot1/sins/imu'}
    rc, _, err = _run_tool(capsys, bag, '--output', out)
    assert rc == 2 and '--force' in err
    assert _run_tool(capsys, bag, '--namespace', 'robot1', '--output', out, '--force')[0] == 0
    assert _run_tool(capsys, bag, '--gyro-topic', '/robot1/imu/delta_theta', '--output', out,
                     '--force')[0] == 0


# --- node and tool: the same core ----------------------------------------------------------------
@pytest.mark.parametrize('profile', ['static', 'coordinated_turn'])
def test_node_and_tool_give_the_same_solution(bags, tmp_path, capsys, monkeypatch, profile):
    """
    Check: node and tool give the same solution.

    sins_node fed the bag's messages through its callbacks (deserialised by rclpy, in the tool's
    order: by stamp, Δv first at equal stamps) publishes exactly what sins_bag writes.
    """
    rclpy = pytest.importorskip('rclpy')
    from rosbags.highlevel import AnyReader

    bag, params, _ = bags[profile]
    out_csv, out_bag = tmp_path / 'tool.csv', tmp_path / 'tool_bag'
    assert _run_tool(capsys, bag, '--params', params, '--output', out_csv)[0] == 0
    assert _run_tool(capsys, bag, '--params', params, '--output', out_bag)[0] == 0

    msgs = []
    with AnyReader([bag]) as rd:
        conns = [c for c in rd.connections if c.topic in ('/imu/delta_theta',
                                                          '/imu/delta_velocity')]
        for c, _, raw in rd.messages(connections=conns):
            m = deserialize_message(bytes(raw), Vector3Stamped)
            msgs.append((stamp_to_ns(m.header.stamp), c.topic == '/imu/delta_theta', m))
    msgs.sort(key=lambda x: (x[0], x[1]))                  # stable: each topic keeps its order
    ctx = Context()                                         # its own: whatever other modules hold
    rclpy.init(context=ctx)
    try:
        node = SinsNode(context=ctx, namespace=f'/t_sins_bag_{profile}', parameter_overrides=[
            Parameter(k, value=v) for k,
            v in load_parameter_file(str(params), 'sins_node').items()])
        got = {'att': [], 'imu': [], 'odom': []}
        monkeypatch.setattr(node.pub_att, 'publish', lambda m: got['att'].append(
            (stamp_to_ns(m.header.stamp),
             [m.quaternion.x, m.quaternion.y, m.quaternion.z, m.quaternion.w])))
        monkeypatch.setattr(node.pub_imu, 'publish', lambda m: got['imu'].append(
            (stamp_to_ns(m.header.stamp), list(m.orientation_covariance),
             [m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z])))

        def odom(m):
            p, o, v = m.pose.pose.position, m.pose.pose.orientation, m.twist.twist.linear
            q = np.array([o.w, o.x, o.y, o.z])
            got['odom'].append((stamp_to_ns(m.header.stamp), [p.x, p.y, p.z],
                                quat_to_dcm(q) @ [v.x, v.y, v.z],
                                [o.x, o.y, o.z, o.w],
                                np.sqrt(np.diag(np.array(m.pose.covariance).reshape(6, 6)))))
        monkeypatch.setattr(node.pub_odom, 'publish', odom)
        for pub in (node.pub_att, node.pub_imu, node.pub_odom):
            monkeypatch.setattr(pub, 'get_subscription_count', lambda: 1)
        try:
            for _, is_gyro, m in msgs:
                (node.on_gyro if is_gyro else node.on_accel)(m)
            node.process()
        finally:
            node.destroy_node()
    finally:
        rclpy.shutdown(context=ctx)

    # CSV (ECEF position, velocity, q_earth_body, σ) against sins/odometry
    _, d, ns = _csv(out_csv)
    n = len(got['odom'])
    assert n == len(d) == int(DURATION * 100)
    assert ns.tolist() == [s for s, *_ in got['odom']]
    r_node = np.array([o[1] for o in got['odom']])
    v_node = np.array([o[2] for o in got['odom']])
    dr = np.max(np.abs(d[:, 1:4] - r_node) / np.linalg.norm(r_node, axis=1)[:, None])
    dv = np.max(np.abs(d[:, 4:7] - v_node))
    dq = np.max(np.abs(d[:, 7:11] - np.array([o[3] for o in got['odom']])))
    assert dr <= 1e-9 and dv <= 1e-9 and dq <= 1e-12, (dr, dv, dq)
    print(f'{profile}: node vs tool: position {dr:.1e} relative, velocity {dv:.1e} m/s, '
          f'quaternion {dq:.1e}')
    # the MCAP bag against what the node published on all three topics
    with AnyReader([out_bag]) as rd:
        per = {c.topic: [rd.deserialize(raw, c.msgtype) for _, _,
                         raw in rd.messages(connections=[c])]
               for c in rd.connections}
    att = per['/sins/attitude']
    assert [stamp_to_ns(m.header.stamp) for m in att] == [s for s, _ in got['att']]
    assert np.array_equal([[m.quaternion.x, m.quaternion.y, m.quaternion.z,
                            m.quaternion.w] for m in att],
                          [q for _, q in got['att']])
    imu = per['/sins/imu']
    assert [stamp_to_ns(m.header.stamp) for m in imu] == [s for s, _, _ in got['imu']]
    assert np.array_equal([list(m.orientation_covariance) for m in imu],
                          [c for _, c, _ in got['imu']])
    assert np.array_equal([[m.linear_acceleration.x, m.linear_acceleration.y,
                            m.linear_acceleration.z] for m in imu],
                          [f for _, _, f in got['imu']])
    odo = per['/sins/odometry']
    assert np.array_equal([[m.pose.pose.position.x, m.pose.pose.position.y,
                            m.pose.pose.position.z] for m in odo],
                          r_node)


# --- errors --------------------------------------------------------------------------------------
def test_argument_errors_are_one_line_exit_2_before_any_work(bags, tmp_path, capsys):
    bag, params, _ = bags['static']
    no_accel = tmp_path / 'no_accel'
    assert record_sim.main([str(no_accel), '--duration', '1', '--no-accel', '-p',
                            'profile:=static']) == 0
    (tmp_path / 'exists.csv').write_text('x\n')
    (tmp_path / 'dir').mkdir()
    (tmp_path / 'dir' / 'keep.txt').write_text('x')
    capsys.readouterr()
    cases = [
        ([tmp_path / 'nope', '-o', tmp_path / 'a.csv'], 'does not exist'),
        ([bag, '-o', tmp_path / 'a.csv', '--gyro-topic', '/imu/nothing'], '/imu/nothing'),
        ([bag, '-o', tmp_path / 'a.csv', '--namespace', '/robot9'], 'robot9'),
        ([bag, '-o', tmp_path / 'a.csv', '-p', 'coning_algorithm:=rk4'], 'rk4'),
        ([bag, '-o', tmp_path / 'a.csv', '-p', 'gyro_bais:=1.0'], 'gyro_bais'),
        ([bag, '-o', tmp_path / 'a.csv', '-p', 'navigation'], 'name:=value'),
        ([bag, '-o', tmp_path / 'a.csv', '--params', tmp_path / 'missing.yaml'], 'missing.yaml'),
        ([bag, '-o', tmp_path / 'a.csv', '-p', 'initial_position:=[0.0, 0.0, 1.0e7]', '-p',
          'navigation:=true'],
         'initial_position'),
        ([no_accel, '-o', tmp_path / 'a.csv', '-p', 'navigation:=true'], 'delta_velocity'),
        ([bag, '-o', tmp_path / 'exists.csv'], '--force'),
        ([bag, '-o', tmp_path / 'dir', '--force'], 'not a rosbag2 bag'),
        ([bag, '-o', '/nonexistent/dir/a.csv'], '/nonexistent'),
        ([bag, '-o', bag, '--force'], 'input bag'),
    ]
    for args, needle in cases:
        rc, out, err = _run_tool(capsys, *args)
        lines = [ln for ln in (out + err).splitlines() if ln.strip()]
        assert rc == 2 and len(lines) == 1 and lines[0].startswith('sins_bag: error:'), (args, rc,
                                                                                         out, err)
        assert needle in lines[0], (needle, lines[0])
    assert not (tmp_path / 'a.csv').exists() and (tmp_path / 'exists.csv').read_text() == 'x\n'
    assert (tmp_path / 'dir' / 'keep.txt').exists() and (bag / 'metadata.yaml').exists()
    # the attitude alone needs no accelerometer
    rc, out, err = _run_tool(capsys, no_accel, '-o', tmp_path / 'att.csv')
    assert rc == 0 and 'no Δv' in out, err


# --- frames, bounded echoes, sensor_msgs/Imu input --- -------------------------------------------
def _read_vectors(bag, topic):
    """(stamp_ns, (x, y, z), frame) of a Vector3Stamped topic of a bag, in bag order."""
    from rosbags.highlevel import AnyReader
    with AnyReader([bag]) as rd:
        conns = [c for c in rd.connections if c.topic == topic]
        out = []
        for c, _, raw in rd.messages(connections=conns):
            m = rd.deserialize(raw, c.msgtype)
            v = m.vector
            ns = m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
            out.append((ns, (v.x, v.y, v.z), m.header.frame_id))
    return out


def _write_bag(path, topics: dict):
    """Write a rosbag2 MCAP bag: {topic: (msgtype, [(stamp_ns, message)])}."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores
    store = get_typestore(Stores.ROS2_JAZZY)
    with Writer(path, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {t: w.add_connection(t, mt, typestore=store) for t, (mt, _) in topics.items()}
        items = sorted(((ns, t, m) for t, (mt, msgs) in topics.items() for ns, m in msgs),
                       key=lambda x: x[0])
        for ns, t, m in items:
            w.write(conns[t], ns, store.serialize_cdr(m, topics[t][0]))
    return path


def _header(T, ns, frame):
    return T['std_msgs/msg/Header'](
        stamp=T['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9),
        frame_id=frame)


def _vector_msgs(items, frame=None):
    from rosbags.typesys import get_typestore, Stores
    T = get_typestore(Stores.ROS2_JAZZY).types
    return [(ns, T['geometry_msgs/msg/Vector3Stamped'](
        header=_header(T, ns, frame(k, f) if frame else f),
        vector=T['geometry_msgs/msg/Vector3'](x=v[0], y=v[1], z=v[2])))
        for k, (ns, v, f) in enumerate(items)]


def test_body_frame_of_the_majority_and_the_rest_reported(tmp_path, capsys):
    """
    Check: body frame of the majority and the rest reported.

    One stray first Δθ in another frame no longer rejects the recording: the body frame is the most
    frequent one, the stray messages are named, counted and rejected, and the solution is that of
    the recording without them.
    """
    src = _record(tmp_path / 'src', 'coning', 'frame_id:=imu')
    g = _read_vectors(src, '/imu/delta_theta')
    a = _read_vectors(src, '/imu/delta_velocity')
    stray = {0, 7}
    bag = _write_bag(tmp_path / 'stray', {
        '/imu/delta_theta': ('geometry_msgs/msg/Vector3Stamped',
                             _vector_msgs(g, lambda k, f: 'camera' if k in stray else f)),
        '/imu/delta_velocity': ('geometry_msgs/msg/Vector3Stamped', _vector_msgs(a))})
    ref = _write_bag(tmp_path / 'clean', {
        '/imu/delta_theta': ('geometry_msgs/msg/Vector3Stamped',
                             _vector_msgs([x for k, x in enumerate(g) if k not in stray])),
        '/imu/delta_velocity': ('geometry_msgs/msg/Vector3Stamped', _vector_msgs(a))})
    rc = sins_bag.main([str(bag), '--output', str(tmp_path / 'stray.csv')])
    cap = capsys.readouterr()
    assert rc == 0, cap.err
    assert "frame_id 'imu' from the recording's headers" in cap.err
    assert '2 of 500 Δθ message(s) name another frame' in cap.err and "'camera' (2)" in cap.err
    assert 'frame mismatch (rejected) 2' in cap.out
    assert _run_tool(capsys, ref, '--output', tmp_path / 'clean.csv')[0] == 0
    d_stray, d_clean = _csv(tmp_path / 'stray.csv'), _csv(tmp_path / 'clean.csv')
    # the first Δθ is missing from the stray bag: its solution starts one increment later; from
    # the second update on it equals the clean recording's (same increments, same stamps)
    common = np.intersect1d(d_stray[2], d_clean[2])
    assert len(common) >= len(d_clean[2]) - 5
    i = np.searchsorted(d_stray[2], common[-1])
    j = np.searchsorted(d_clean[2], common[-1])
    assert np.max(np.abs(d_stray[1][i, 1:5] - d_clean[1][j, 1:5])) < 1e-6      # the same motion


def test_huge_frame_ids_are_cheap_and_every_echo_is_bounded(tmp_path, capsys):
    """
    Check: huge frame ids are cheap and every echo is bounded.

    Three Δθ with 2 MB frame ids cost no time (86 s before) and the output stays short: every
    echoed frame id is cut to 64 characters.
    """
    src = _record(tmp_path / 'src', 'coning')
    g = _read_vectors(src, '/imu/delta_theta')
    a = _read_vectors(src, '/imu/delta_velocity')
    huge = {5, 6, 300}
    bag = _write_bag(tmp_path / 'huge', {
        '/imu/delta_theta': ('geometry_msgs/msg/Vector3Stamped',
                             _vector_msgs(g, lambda k, f: 'h' * 2_000_000 + str(k) if k in huge
                                          else f)),
        '/imu/delta_velocity': ('geometry_msgs/msg/Vector3Stamped', _vector_msgs(a))})
    rc = sins_bag.main([str(bag), '--output', str(tmp_path / 'huge.csv')])
    cap = capsys.readouterr()
    assert rc == 0, cap.err[:500]
    assert len(cap.out) + len(cap.err) < 3000, (len(cap.out), len(cap.err))
    assert 'chars)' in cap.err and 'frame mismatch (rejected) 3' in cap.out
    # a 2 MB frame id named as the body frame contradicts the recording: one bounded line
    rc = sins_bag.main([str(bag), '-p', 'frame_id:=' + 'z' * 2_000_000,
                        '--output', str(tmp_path / 'z.csv')])
    cap = capsys.readouterr()
    assert rc == 2 and len(cap.out) + len(cap.err) < 3000


def _imu_bag(path, g, a):
    """
    Write sensor_msgs/Imu messages with the exact mean rates of the increments.

    sensor_msgs/Imu messages with the exact mean rates of the Δθ/Δv increments (the mean rule:
    rate_k = Δ_k / (t_k − t_{k−1})), one extra sample at the start of the first interval.
    """
    from rosbags.typesys import get_typestore, Stores
    T = get_typestore(Stores.ROS2_JAZZY).types
    assert [s for s, _, _ in g] == [s for s, _, _ in a]
    stamps = [g[0][0] - (g[1][0] - g[0][0])] + [s for s, _, _ in g]
    msgs = []
    for k, ns in enumerate(stamps):
        if k == 0:
            w = f = (0.0, 0.0, 0.0)
        else:
            dt = (stamps[k] - stamps[k - 1]) * 1e-9
            w = tuple(x / dt for x in g[k - 1][1])
            f = tuple(x / dt for x in a[k - 1][1])
        v3 = T['geometry_msgs/msg/Vector3']
        msgs.append((ns, T['sensor_msgs/msg/Imu'](
            header=_header(T, ns, 'imu_link'),
            orientation=T['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=np.full(9, -1.0) * np.eye(3).reshape(9),
            angular_velocity=v3(x=w[0], y=w[1], z=w[2]), angular_velocity_covariance=np.zeros(9),
            linear_acceleration=v3(x=f[0], y=f[1], z=f[2]),
            linear_acceleration_covariance=np.zeros(9))))
    return _write_bag(path, {'/imu/data_raw': ('sensor_msgs/msg/Imu', msgs)})


def test_imu_input_with_mean_rates_gives_the_increment_solution(tmp_path, capsys):
    """
    Check: imu input with mean rates gives the increment solution.

    sensor_msgs/Imu input: a bag of Imu messages whose rates are the exact means over their
    intervals gives, with --rate-rule mean, the solution of the Δθ/Δv bag to round-off (navigation,
    100 Hz gyro and accelerometer).
    """
    src = _record(tmp_path / 'src', 'coordinated_turn', 'accel_rate:=100.0')
    params, prof = _sins_params(tmp_path / 'p.yaml', 'coordinated_turn')
    g = _read_vectors(src, '/imu/delta_theta')
    a = _read_vectors(src, '/imu/delta_velocity')
    imu = _imu_bag(tmp_path / 'imu', g, a)
    rc, out, err = _run_tool(capsys, src, '--params', params, '--output', tmp_path / 'inc.csv')
    assert rc == 0, err
    rc, out, err = _run_tool(capsys, imu, '--params', params, '--imu-topic', '/imu/data_raw',
                             '--rate-rule', 'mean', '--output', tmp_path / 'imu.csv')
    assert rc == 0, err
    assert '501 sensor_msgs/Imu from /imu/data_raw' in out and 'rule mean' in out
    assert 'gyro_rate 100 Hz, accel_rate 100 Hz' in out and 'dropped: none' in out
    _, d_inc, ns_inc = _csv(tmp_path / 'inc.csv')
    _, d_imu, ns_imu = _csv(tmp_path / 'imu.csv')
    assert np.array_equal(ns_inc, ns_imu) and len(ns_inc) == int(DURATION * 100)
    dr = np.max(np.abs(d_imu[:, 1:4] - d_inc[:, 1:4]))
    dv = np.max(np.abs(d_imu[:, 4:7] - d_inc[:, 4:7]))
    dq = np.max(np.abs(d_imu[:, 7:11] - d_inc[:, 7:11]))
    assert dr < 1e-6 and dv < 1e-8 and dq < 1e-12, (dr, dv, dq)
    # and both against the exact truth
    t = ns_imu * 1e-9
    assert np.max(np.linalg.norm(d_imu[:, 1:4] - prof.position(t), axis=1)) < 1e-2
    # the trapezoid rule on the same samples is a different (second-order) reading of them
    rc, out, err = _run_tool(capsys, imu, '--params', params, '--imu-topic', '/imu/data_raw',
                             '--output', tmp_path / 'trap.csv')
    assert rc == 0 and 'rule trapezoid' in out, err


def test_a_damaged_mcap_chunk_is_one_line_exit_2(tmp_path, capsys):
    """
    Check: a damaged mcap chunk is one line exit 2.

    The chunk reader refuses a chunk whose record runs past its end (or whose checksum fails): one
    line on stderr, exit 2, no output file.
    """
    bag = _record(tmp_path / 'dmg', 'coning')
    rd = open_reader(bag)
    try:
        chunk = mcap_records.indexed_mcap(rd).chunks[0]
    finally:
        rd.close()
    mcap = next(bag.glob('*.mcap'))
    data = bytearray(mcap.read_bytes())
    first = chunk.chunk_start_offset + 9 + 40 + len(chunk.compression)
    assert chunk.compression == '' and 0x01 <= data[first] <= 0x10     # a record opcode
    data[first + 1:first + 9] = (2**40).to_bytes(8, 'little')     # a record longer than its chunk
    mcap.write_bytes(bytes(data))
    capsys.readouterr()
    rc, out, err = _run_tool(capsys, bag, '--output', tmp_path / 'x.csv')
    lines = [ln for ln in (out + err).splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and lines[0].startswith('sins_bag: error:'), (out, err)
    assert not (tmp_path / 'x.csv').exists()


def _drop_accel_after(src, dst, t_stop):
    """Copy the bag ``src`` with its Δv stopping ``t_stop`` s after its start."""
    from rosbags.rosbag2 import Reader, StoragePlugin, Writer
    with Reader(src) as r, Writer(dst, version=Writer.VERSION_LATEST,
                                  storage_plugin=StoragePlugin.MCAP) as w:
        conns = {c.id: w.add_connection(c.topic, c.msgtype, typestore=None,
                                        serialization_format=c.ext.serialization_format,
                                        offered_qos_profiles=c.ext.offered_qos_profiles,
                                        msgdef=c.msgdef.data, rihs01=c.digest)
                 for c in r.connections}
        stop = r.start_time + int(t_stop * 1e9)
        for c, t, raw in r.messages():
            if c.topic.endswith('delta_velocity') and t > stop:
                continue
            w.write(conns[c.id], t, raw)
    return dst


@pytest.mark.parametrize('accel_wait, level', [(0.1, 'ERROR'), (0.5, 'WARN')])
def test_accelerometer_stall_is_reported_by_the_nodes_rule(tmp_path, capsys, accel_wait, level):
    """
    Check: accelerometer stall is reported by the nodes rule.

    Δv stop half-way through the recording while Δθ run on; sins_bag reports it as sins_node does
    on /diagnostics (the core's rule, SinsSystem.accel_stall: WARN beyond accel_wait, ERROR beyond
    max(1 s, 10 accel_wait)), naming the stalled stream, with the stall's length in the summary
    counts.
    """
    full = _record(tmp_path / 'full', 'static')
    bag = _drop_accel_after(full, tmp_path / 'half', DURATION / 2)
    rc, out, err = _run_tool(capsys, bag, '-o', tmp_path / 'a.csv',
                             '-p', f'accel_wait:={accel_wait}')
    assert rc == 0, err
    warn = [ln for ln in out.splitlines() if 'WARNING:' in ln]
    assert len(warn) == 1, out
    assert 'accelerometer increments (/imu/delta_velocity) stopped' in warn[0] \
        or 'accelerometer increments (imu/delta_velocity) stopped' in warn[0], warn
    assert warn[0].rstrip().endswith(level), warn
    warn_s, error_s = accel_stall_limits(accel_wait)
    assert f'WARN beyond {warn_s:g} s, ERROR beyond {error_s:g} s' in warn[0]
    stall = float(re.search(r'accel stall ([\d.e+-]+) s', out).group(1))
    assert stall == pytest.approx(DURATION / 2, abs=0.02)           # the gyro ran on 2.5 s
    rc, out, err = _run_tool(capsys, full, '-o', tmp_path / 'b.csv',
                             '-p', f'accel_wait:={accel_wait}')
    assert rc == 0 and 'WARNING' not in out and 'accel stall' not in out, out
