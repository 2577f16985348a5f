"""record_sim → rosbag2 (MCAP and sqlite3) → calibrate_bag, without ROS."""
import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from strapdown_ros.motion.profiles import PiecewiseRateProfile, Segment
from strapdown_ros.rotation import (dcm_to_quat, from_ros_xyzw, quat_error_rotvec, quat_multiply,
                                    rotvec_to_quat, to_ros_xyzw, ypr_to_dcm)
from strapdown_ros.sensors import ARCSEC, IntegratingSensor, SensorErrorModel
from strapdown_ros.sensors.star_camera import StarCameraModel
from strapdown_ros.tools import calibrate_bag, record_sim


BETA = np.radians([40.0, -25.0, 120.0])
BETA_ARG = 'boresight:=[' + ', '.join(repr(float(b)) for b in BETA) + ']'
NO_GAPS = {'gaps': 0, 'missing': 0, 'pairs_discarded': 0, 'dropouts': 0, 'stamp_bursts': 0}
KEYS = ['q_mf_vf_xyzw', 'rotation_covariance_mf_rad2', 'beta_rad', 'beta_sigma_rad',
        'covariance_rad2', 'pairs',
        'observable', 'unobservable_axes', 'residual_rms_rad', 'weighted']


def _is_3x3(m):
    return (isinstance(m, list) and len(m) == 3
            and all(isinstance(r, list) and len(r) == 3 for r in m)
            and all(isinstance(v, float) for r in m for v in r))


def _floats(v, n):
    return isinstance(v, list) and len(v) == n and all(isinstance(x, float) for x in v)


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_round_trip_bench(tmp_path, storage, capsys):
    bag = tmp_path / f'bench_{storage}'
    args = [str(bag), '--storage', storage, '-p', 'profile:=bench', '-p', 'camera_interval:=5.0',
            '-p', BETA_ARG]
    if storage == 'sqlite3':
        args.append('--no-accel')
    assert record_sim.main(args) == 0
    out = capsys.readouterr().out
    assert '/imu/delta_theta 17000' in out and '/star_camera/attitude 34' in out
    assert ('/imu/delta_velocity 51000' in out) == (storage == 'mcap')
    assert '/star_camera/truth/boresight 1' in out

    f = tmp_path / 'result.json'
    assert calibrate_bag.main([str(bag), '--json', str(f)]) == 0
    r = json.loads(f.read_text())
    assert list(r)[:len(KEYS)] == KEYS
    assert _floats(r['q_mf_vf_xyzw'], 4) and _floats(r['beta_rad'],
                                                     3) and _floats(r['beta_sigma_rad'], 3)
    assert _is_3x3(r['rotation_covariance_mf_rad2']) and _is_3x3(r['covariance_rad2'])
    assert isinstance(r['pairs'], int) and r['pairs'] == 33
    assert r['observable'] is True and r['unobservable_axes'] == [] and r['weighted'] is True
    assert isinstance(r['residual_rms_rad'], float)
    assert set(r['dropped']['gyro'].values()) == {0}
    assert r['gyro_gaps'] == NO_GAPS
    assert r['camera_covariance_from_bag'] is True

    # C_MF^VF error as a rotation in MF axes (q_est = exp(e) ⊗ q_true) within 3σ of P^clb per axis
    q_true = dcm_to_quat(ypr_to_dcm(*BETA))
    e = quat_error_rotvec(from_ros_xyzw(np.array(r['q_mf_vf_xyzw'])), q_true, frame='reference')
    sigma = np.sqrt(np.diag(r['rotation_covariance_mf_rad2']))
    assert np.all(np.abs(e) < 3 * sigma), (e / ARCSEC, sigma / ARCSEC)
    assert np.all(np.abs(np.array(r['beta_rad']) - BETA) < 60 * ARCSEC)
    assert np.allclose(np.sqrt(np.diag(r['covariance_rad2'])), r['beta_sigma_rad'])

    if storage == 'mcap':
        # the bag holds what imu_sim_node publishes: same error draw, same noise seed, same stamps
        from rosbags.highlevel import AnyReader

        from strapdown_ros.motion.profiles import bench_profile
        from strapdown_ros.params import check_all, IMU_SIM_PARAMS, sigmas_from
        p = check_all(IMU_SIM_PARAMS, {'profile': 'bench'})
        gyro = IntegratingSensor(bench_profile(), 'gyro', 100.0,
                                 sigmas_from(p, 'gyro').draw(np.random.default_rng(0)), seed=1)
        t, dth, _ = gyro.sample(5)
        with AnyReader([bag]) as rd:
            conns = [c for c in rd.connections if c.topic == '/imu/delta_theta']
            got = []
            for c, ts, raw in rd.messages(connections=conns):
                m = rd.deserialize(raw, c.msgtype)
                got.append((ts, m.header.stamp.sec * 10**9 + m.header.stamp.nanosec,
                            m.header.frame_id,
                            [m.vector.x, m.vector.y, m.vector.z]))
                if len(got) == 5:
                    break
        assert [g[0] for g in got] == [g[1] for g in got] == [int(round(x * 1e9)) for x in t]
        assert all(g[2] == 'imu_link' for g in got)
        assert np.array_equal(np.array([g[3] for g in got]), dth)


def test_single_axis_not_observable(tmp_path, capsys):
    prof = tmp_path / 'z_only.yaml'
    prof.write_text('earth_rate: [0.0, 0.0, 0.0]\ngravity: [0.0, 0.0, 9.80665]\nsegments:\n'
                    '  - {duration: 10.0, rate: [0.0, 0.0, 0.0]}\n'
                    '  - {duration: 5.0, rate: [0.0, 0.0, 0.05236]}\n'
                    '  - {duration: 10.0, rate: [0.0, 0.0, 0.0]}\n'
                    '  - {duration: 5.0, rate: [0.0, 0.0, -0.04]}\n'
                    '  - {duration: 10.0, rate: [0.0, 0.0, 0.0]}\n')
    bag = tmp_path / 'z_only'
    assert record_sim.main([str(bag), '--no-accel', '-p', 'profile:=piecewise', '-p',
                            f'profile_file:={prof}',
                            '-p', 'camera_interval:=5.0', '-p', BETA_ARG]) == 0
    f = tmp_path / 'z.json'
    capsys.readouterr()
    assert calibrate_bag.main([str(bag), '--json', str(f)]) == 3
    err = capsys.readouterr().err
    assert 'NOT observable' in err
    r = json.loads(f.read_text())
    assert list(r)[:len(KEYS)] == KEYS
    assert r['observable'] is False and r['unobservable_axes']
    assert r['q_mf_vf_xyzw'] is None and r['beta_rad'] is None and r['covariance_rad2'] is None
    assert r['rotation_covariance_mf_rad2'] is None and r['beta_sigma_rad'] is None
    assert r['pairs'] == 7


def _write_bag(path, gyro_msgs, cam_msgs, namespace='/robot1'):
    """Write a bag with rosbags directly: (ns, vector) gyro messages, (ns, q_wxyz) fixes."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores
    ts = get_typestore(Stores.ROS2_JAZZY)
    T = ts.types
    Time, Header = T['builtin_interfaces/msg/Time'], T['std_msgs/msg/Header']
    V3S, V3 = T['geometry_msgs/msg/Vector3Stamped'], T['geometry_msgs/msg/Vector3']
    QS, Q = T['geometry_msgs/msg/QuaternionStamped'], T['geometry_msgs/msg/Quaternion']

    def header(ns, frame):
        return Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        cg = w.add_connection(f'{namespace}/imu/delta_theta', V3S.__msgtype__, typestore=ts)
        cc = w.add_connection(f'{namespace}/star_camera/attitude', QS.__msgtype__, typestore=ts)
        for ns, v in gyro_msgs:
            m = V3S(header=header(ns, 'imu_link'),
                    vector=V3(x=float(v[0]), y=float(v[1]), z=float(v[2])))
            w.write(cg, ns, ts.serialize_cdr(m, V3S.__msgtype__))
        for ns, q in cam_msgs:
            x, y, z, qw = to_ros_xyzw(q)
            m = QS(header=header(ns, 'gcrs'), quaternion=Q(x=x, y=y, z=z, w=qw))
            w.write(cc, ns, ts.serialize_cdr(m, QS.__msgtype__))


def test_nan_and_duplicate_are_dropped_and_counted(tmp_path, capsys):
    deg = np.radians(1.0)
    segs = [Segment(6.0)]
    for axis, ang in ((2, 15), (0, -12), (1, 10), (2, -10)):
        rate = np.zeros(3)
        rate[axis] = ang * deg / 4.0
        segs += [Segment(4.0, rate), Segment(6.0)]
    profile = PiecewiseRateProfile(segs)
    gyro = IntegratingSensor(profile, 'gyro', 100.0, SensorErrorModel(random_walk=1e-7), seed=3)
    t, dth, _ = gyro.sample(int(round(profile.duration * 100)))
    # epoch-like stamps: tests the time origin
    start_ns = 1_700_000_000 * 10**9
    msgs = [(start_ns + int(round(x * 1e9)), v) for x, v in zip(t, dth)]
    # t = 7.5 s, inside the first pair (5, 10] s
    msgs[749] = (msgs[749][0], np.array([np.nan, 0.0, 0.0]))
    msgs.insert(201, msgs[200])                               # a repeated message: duplicate stamp
    cam = StarCameraModel(boresight=BETA, interval=5.0, seed=4)
    fixes = cam.fixes(profile, int(profile.duration // 5.0))
    _write_bag(tmp_path / 'bad', msgs,
               [(start_ns + int(round(fx.stamp * 1e9)), fx.attitude) for fx in fixes])

    f = tmp_path / 'bad.json'
    assert calibrate_bag.main([str(tmp_path / 'bad'), '--namespace', '/robot1', '--json',
                               str(f)]) == 0
    out = capsys.readouterr().out
    assert 'gyro nan 1' in out and 'gyro duplicate 1' in out and 'GYRO GAPS' in out
    r = json.loads(f.read_text())
    assert r['dropped']['gyro'] == {'nan': 1, 'duplicate': 1, 'out_of_order': 0, 'out_of_range': 0,
                                    'stamp_outlier': 0, 'stamp_burst': 0, 'wrong_type': 0,
                                    'undecodable': 0}
    assert r['messages']['gyro'] == len(msgs) - 2
    # the dropped NaN increment is a gap (its rotation is lost): the pair spanning it is discarded
    assert r['gyro_gaps'] == {**NO_GAPS, 'gaps': 1, 'missing': 1, 'pairs_discarded': 1}
    assert r['pairs'] == len(fixes) - 2
    # no attitude_with_covariance: assumed σ
    assert r['camera_covariance_from_bag'] is False
    assert r['observable'] is True
    assert np.all(np.abs(np.array(r['beta_rad']) - BETA) < 60 * ARCSEC)

    # the single namespace is found without --namespace; a wrong one is a clear error (exit 2)
    assert calibrate_bag.main([str(tmp_path / 'bad')]) == 0
    capsys.readouterr()
    assert calibrate_bag.main([str(tmp_path / 'bad'), '--namespace', '/robot2']) == 2
    assert 'robot2' in capsys.readouterr().err


def test_tools_run_with_ros_absent(tmp_path):
    """record_sim and calibrate_bag import and run with rclpy and every message package blocked."""
    repo = str(__import__('pathlib').Path(__file__).resolve().parents[2])
    code = textwrap.dedent(f"""
        import importlib.abc, sys
        BLOCK = ("rclpy", "rcl_interfaces", "builtin_interfaces", "std_msgs", "geometry_msgs",
                 "sensor_msgs", "diagnostic_msgs", "nav_msgs", "rosidl_runtime_py")
        class Blocker(importlib.abc.MetaPathFinder):
            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] in BLOCK:
                    raise ImportError("blocked for this test: " + name)
        sys.meta_path.insert(0, Blocker())
        sys.path.insert(0, {repo!r})
        from strapdown_ros.tools import calibrate_bag, record_sim
        bag = {str(tmp_path / "short")!r}
        assert record_sim.main([bag, '--duration', '30', '--no-accel',
                                '-p', 'camera_interval:=5.0']) == 0
        assert calibrate_bag.main([bag]) == 3          # one turn about z only: not observable
        loaded = [m for m in sys.modules if m.split(".")[0] in BLOCK]
        assert not loaded, loaded
        print("tools ok")
    """)
    res = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert 'tools ok' in res.stdout


def test_long_recording_keeps_every_pair_and_takes_the_rate_from_the_stamps(tmp_path, capsys):
    """
    Check: long recording keeps every pair and takes the rate from the stamps.

    > 200 000 gyro messages (here 210 000 at 200 Hz, gyro_rate left at 100) used to give 1 pair or
    none.  Now gyro and fixes are fed in stamp order and gaps are judged against the rate of the
    stamps.
    """
    bag = tmp_path / 'long'
    assert record_sim.main([str(bag), '--no-accel', '--duration', '1050', '-p', 'profile:=bench',
                            '-p', 'bench_repeat:=7', '-p', 'gyro_rate:=200.0', '-p',
                            'camera_interval:=20.0',
                            '-p', BETA_ARG]) == 0
    f = tmp_path / 'r.json'
    assert calibrate_bag.main([str(bag), '--json', str(f)]) == 0
    r = json.loads(f.read_text())
    assert r['messages']['gyro'] == 210000 and r['messages']['camera'] == 52
    assert r['pairs'] == 51 and r['gyro_gaps'] == NO_GAPS
    assert r['gyro_rate_from_stamps_hz'] == pytest.approx(200.0, rel=1e-9)
    assert '200 Hz' in capsys.readouterr().err
    q_true = dcm_to_quat(ypr_to_dcm(*BETA))
    e = quat_error_rotvec(from_ros_xyzw(np.array(r['q_mf_vf_xyzw'])), q_true, frame='reference')
    assert np.all(np.abs(e) < 3 * np.sqrt(np.diag(r['rotation_covariance_mf_rad2'])))


def test_overflowing_and_future_stamped_increments_in_a_bag(tmp_path):
    """
    Check: overflowing and future stamped increments in a bag.

    Offline, a (1e308, 1e308, 0) increment and a lone stamp far in the future are dropped by the
    nodes' rules and counted; the estimate is the clean bag's.
    """
    from rosbags.rosbag2 import Reader, Writer
    from rosbags.typesys import get_typestore, Stores

    clean = tmp_path / 'clean'
    assert record_sim.main([str(clean), '--no-accel', '-p', 'profile:=bench', '-p',
                            'camera_interval:=5.0',
                            '-p', BETA_ARG]) == 0
    store = get_typestore(Stores.ROS2_JAZZY)
    dirty = tmp_path / 'dirty'
    with Reader(clean) as rd, Writer(dirty, version=Writer.VERSION_LATEST) as wr:
        conns = {c.id: wr.add_connection(c.topic, c.msgtype,
                                         typestore=store) for c in rd.connections}
        n = 0
        for c, t, raw in rd.messages():
            wr.write(conns[c.id], t, raw)
            if c.topic == '/imu/delta_theta':
                n += 1
                if n in (3000, 9000):
                    m = store.deserialize_cdr(raw, c.msgtype)
                    if n == 3000:
                        m.vector.x, m.vector.y = 1e308, 1e308
                        m.header.stamp.nanosec += 1000
                    else:
                        m.header.stamp.sec += 10**6
                    wr.write(conns[c.id], t + 1000, store.serialize_cdr(m, c.msgtype))
    out = {}
    for name, bag in (('clean', clean), ('dirty', dirty)):
        f = tmp_path / f'{name}.json'
        assert calibrate_bag.main([str(bag), '--json', str(f)]) == 0
        out[name] = json.loads(f.read_text())
    d = out['dirty']['dropped']['gyro']
    assert (d['out_of_range'], d['stamp_outlier']) == (1, 1)
    assert out['dirty']['pairs'] == out['clean']['pairs'] == 33
    np.testing.assert_allclose(out['dirty']['beta_rad'], out['clean']['beta_rad'], rtol=0,
                               atol=1e-12)


def test_one_outlier_camera_fix_is_gated(tmp_path):
    """
    Check: one outlier camera fix is gated.

    One fix rotated 5° used to move β by 6113″.  The outlier rule (both pairs of the fix off in
    rotation angle, the pair skipping it consistent) drops it: β stays within 3σ of the truth and
    one pair fewer is used.
    """
    from rosbags.rosbag2 import Reader, Writer
    from rosbags.typesys import get_typestore, Stores

    clean = tmp_path / 'clean'
    assert record_sim.main([str(clean), '--no-accel', '-p', 'profile:=bench', '-p',
                            'camera_interval:=5.0',
                            '-p', BETA_ARG]) == 0
    store = get_typestore(Stores.ROS2_JAZZY)
    dirty = tmp_path / 'dirty'
    bad = rotvec_to_quat(np.radians(5.0) * np.array([0.6, -0.64, 0.48]))
    with Reader(clean) as rd, Writer(dirty, version=Writer.VERSION_LATEST) as wr:
        conns = {c.id: wr.add_connection(c.topic, c.msgtype,
                                         typestore=store) for c in rd.connections}
        for c, t, raw in rd.messages():
            # the fix at 60 s
            if c.topic.startswith('/star_camera/attitude') and t == 60 * 10**9:
                m = store.deserialize_cdr(raw, c.msgtype)
                q = m.pose.pose.orientation if hasattr(m, 'pose') else m.quaternion
                w, x, y, z = quat_multiply(np.array([q.w, q.x, q.y, q.z]), bad)
                q.w, q.x, q.y, q.z = float(w), float(x), float(y), float(z)
                raw = store.serialize_cdr(m, c.msgtype)
            wr.write(conns[c.id], t, raw)
    out = {}
    for name, bag in (('clean', clean), ('dirty', dirty)):
        f = tmp_path / f'{name}.json'
        assert calibrate_bag.main([str(bag), '--json', str(f)]) == 0
        out[name] = json.loads(f.read_text())
    r = out['dirty']
    assert r['camera_fixes']['outliers_dropped'] == 1
    assert r['camera_fixes']['outlier_stamps_s'] == [pytest.approx(60.0)]
    assert out['clean']['camera_fixes']['outliers_dropped'] == 0
    assert r['pairs'] == out['clean']['pairs'] - 1
    q_true = dcm_to_quat(ypr_to_dcm(*BETA))
    e = quat_error_rotvec(from_ros_xyzw(np.array(r['q_mf_vf_xyzw'])), q_true, frame='reference')
    assert np.all(np.abs(e) < 3 * np.sqrt(np.diag(r['rotation_covariance_mf_rad2']))), e / ARCSEC


def test_dropout_and_stamp_burst_cost_only_the_pairs_containing_them(tmp_path, capsys):
    """
    Check: dropout and stamp burst cost only the pairs containing them.

    Offline, 2 s without increments (t in (62.5, 64.5] s) and 5 increments stamped 1000 s in the
    past (t = 102.5 s) each cost the one pair that contains them (33 → 31); the dropout reports its
    200 missing increments, the burst its 5.
    """
    from rosbags.rosbag2 import Reader, Writer
    from rosbags.typesys import get_typestore, Stores

    clean = tmp_path / 'clean'
    assert record_sim.main([str(clean), '--no-accel', '-p', 'profile:=bench', '-p',
                            'camera_interval:=5.0', '-p', BETA_ARG]) == 0
    store = get_typestore(Stores.ROS2_JAZZY)
    dirty = tmp_path / 'dirty'
    with Reader(clean) as rd, Writer(dirty, version=Writer.VERSION_LATEST) as wr:
        conns = {c.id: wr.add_connection(c.topic, c.msgtype, typestore=store)
                 for c in rd.connections}
        for c, t, raw in rd.messages():
            if c.topic == '/imu/delta_theta':
                if 62_500_000_000 < t <= 64_500_000_000:
                    continue                                          # the dropout
                if 102_500_000_000 <= t < 102_550_000_000:            # the burst
                    m = store.deserialize_cdr(raw, c.msgtype)
                    m.header.stamp.sec -= 1000
                    raw = store.serialize_cdr(m, c.msgtype)
            wr.write(conns[c.id], t, raw)
    f = tmp_path / 'r.json'
    assert calibrate_bag.main([str(dirty), '--json', str(f)]) == 0
    r = json.loads(f.read_text())
    assert r['gyro_gaps'] == {'gaps': 2, 'missing': 205, 'pairs_discarded': 2, 'dropouts': 1,
                              'stamp_bursts': 1}
    assert r['dropped']['gyro']['stamp_burst'] == 5 and r['stamp_resyncs']['gyro'] == 0
    assert r['pairs'] == 31
    assert ('2 gap(s) (1 dropout(s) beyond max_stamp_jump, 1 stamp burst(s)), 205 increment(s) '
            'missing') in capsys.readouterr().out
    q_true = dcm_to_quat(ypr_to_dcm(*BETA))
    e = quat_error_rotvec(from_ros_xyzw(np.array(r['q_mf_vf_xyzw'])), q_true, frame='reference')
    assert np.all(np.abs(e) < 3 * np.sqrt(np.diag(r['rotation_covariance_mf_rad2']))), e / ARCSEC


def _noisy_bench(tmp_path, name, scale):
    """Write a bench bag whose camera noise is ``scale`` × the σ its covariance states."""
    bag = tmp_path / name
    assert record_sim.main([str(bag), '--no-accel', '-p', 'profile:=bench', '-p',
                            'camera_interval:=5.0', '-p', BETA_ARG, '-p',
                            f'camera_noise_scale:=[{scale}, {scale}, {scale}]']) == 0
    return bag


@pytest.mark.parametrize('scale', [1.0, 100.0])
def test_fit_consistency_is_judged_and_a_wrong_sigma_drops_no_good_fix(tmp_path, capsys, scale):
    """
    Check: fit consistency is judged and a wrong sigma drops no good fix.

    Camera noise 100× the stated σ → fit_consistent false, a WARNING line on stderr, exit 0, no
    good fix dropped as an outlier (the gate widens with the robust scatter), β within 3 scaled σ
    of the injected truth.  Consistent noise → no warning.
    """
    bag = _noisy_bench(tmp_path, f's{scale:g}', scale)
    capsys.readouterr()
    f = tmp_path / 'r.json'
    assert calibrate_bag.main([str(bag), '--json', str(f)]) == 0
    cap = capsys.readouterr()
    r = json.loads(f.read_text())
    lo, hi = r['chi2_per_dof_band']
    assert r['dof'] == 3 * r['pairs'] - 3 and lo < 1.0 < hi
    assert r['camera_fixes']['outliers_dropped'] == 0 and r['pairs'] == 33
    q_true = dcm_to_quat(ypr_to_dcm(*BETA))
    e = quat_error_rotvec(from_ros_xyzw(np.array(r['q_mf_vf_xyzw'])), q_true, frame='reference')
    sigma = np.sqrt(np.diag(r['rotation_covariance_mf_rad2']))
    assert np.all(np.abs(e) < 3 * sigma), e / sigma
    if scale == 1.0:
        assert r['fit_consistent'] is True and lo <= r['chi2_per_dof'] <= hi
        assert 'WARNING' not in cap.err and 'UNTRUSTED' not in cap.out
    else:
        assert r['fit_consistent'] is False and r['chi2_per_dof'] > 100 * hi
        warn = [ln for ln in cap.err.splitlines() if ln.startswith('WARNING:')]
        assert len(warn) == 1 and 'χ²/dof' in warn[0] and 'band' in warn[0] and 'scaled' in warn[0]
        assert 'UNTRUSTED' in cap.out
        # the published σ is the stated-noise σ scaled by √(χ²/dof)
        np.testing.assert_allclose(r['beta_sigma_rad'], np.array(r['beta_sigma_stated_noise_rad'])
                                   * np.sqrt(r['chi2_per_dof']), rtol=0.05)


def test_an_outlier_fix_is_still_gated_when_the_sigma_is_wrong(tmp_path):
    """The robust gate still drops a fix rotated 5° when the stated σ is 100× too small."""
    from rosbags.rosbag2 import Reader, Writer
    from rosbags.typesys import get_typestore, Stores

    clean = _noisy_bench(tmp_path, 'clean', 100.0)
    store = get_typestore(Stores.ROS2_JAZZY)
    dirty = tmp_path / 'dirty'
    bad = rotvec_to_quat(np.radians(5.0) * np.array([0.6, -0.64, 0.48]))
    with Reader(clean) as rd, Writer(dirty, version=Writer.VERSION_LATEST) as wr:
        conns = {c.id: wr.add_connection(c.topic, c.msgtype, typestore=store)
                 for c in rd.connections}
        for c, t, raw in rd.messages():
            if c.topic.startswith('/star_camera/attitude') and t == 60 * 10**9:
                m = store.deserialize_cdr(raw, c.msgtype)
                q = m.pose.pose.orientation if hasattr(m, 'pose') else m.quaternion
                w, x, y, z = quat_multiply(np.array([q.w, q.x, q.y, q.z]), bad)
                q.w, q.x, q.y, q.z = float(w), float(x), float(y), float(z)
                raw = store.serialize_cdr(m, c.msgtype)
            wr.write(conns[c.id], t, raw)
    f = tmp_path / 'r.json'
    assert calibrate_bag.main([str(dirty), '--json', str(f)]) == 0
    r = json.loads(f.read_text())
    assert r['camera_fixes']['outliers_dropped'] == 1
    assert r['camera_fixes']['outlier_stamps_s'] == [pytest.approx(60.0)] and r['pairs'] == 32


def test_a_clock_reset_of_both_streams_calibrates_each_time_base(tmp_path):
    """
    Check: a clock reset of both streams calibrates each time base.

    A confirmed resynchronisation offline: both clocks jump 5000 s ahead at t = 85 s (beyond 3600
    s: a clock change, not a dropout).  Each time base is calibrated on its own, as calibrator_node
    restarts its gyro history: no pair spans the reset, none is lost but the one across it, and β
    is the truth's.
    """
    from rosbags.rosbag2 import Reader, Writer
    from rosbags.typesys import get_typestore, Stores

    clean = tmp_path / 'clean'
    assert record_sim.main([str(clean), '--no-accel', '-p', 'profile:=bench', '-p',
                            'camera_interval:=5.0', '-p', BETA_ARG]) == 0
    store = get_typestore(Stores.ROS2_JAZZY)
    reset = tmp_path / 'reset'
    with Reader(clean) as rd, Writer(reset, version=Writer.VERSION_LATEST) as wr:
        conns = {c.id: wr.add_connection(c.topic, c.msgtype, typestore=store)
                 for c in rd.connections}
        for c, t, raw in rd.messages():
            if t > 85 * 10**9 - 5_000_000 and c.topic in (
                    '/imu/delta_theta', '/star_camera/attitude_with_covariance'):
                m = store.deserialize_cdr(raw, c.msgtype)
                m.header.stamp.sec += 5000
                raw = store.serialize_cdr(m, c.msgtype)
            wr.write(conns[c.id], t, raw)
    f = tmp_path / 'r.json'
    assert calibrate_bag.main([str(reset), '--json', str(f)]) == 0
    r = json.loads(f.read_text())
    assert r['stamp_resyncs'] == {'gyro': 1, 'camera': 1}
    assert r['pairs'] == 33 - 1                      # fixes 5..80 s and 85..170 s: 15 + 17 pairs
    q_true = dcm_to_quat(ypr_to_dcm(*BETA))
    e = quat_error_rotvec(from_ros_xyzw(np.array(r['q_mf_vf_xyzw'])), q_true, frame='reference')
    assert np.all(np.abs(e) < 3 * np.sqrt(np.diag(r['rotation_covariance_mf_rad2']))), e / ARCSEC
