"""
Real message formats in the offline tools (strapdown_ros.recording).

The same simulated
motion written as sensor_msgs/Imu rates, Δθ increments, and PoseStamped / Odometry / TF
references, read by calibrate_bag and discrepancy; truth is the injected boresight and gyro bias.
Also: argument errors in one line (exit 2), and messages a corrupt MCAP chunk hides are counted,
not lost silently.
"""
import json
import struct

import numpy as np
import pytest

pytest.importorskip('rosbags')

from strapdown_ros.motion.profile_base import MotionProfile  # noqa: E402
from strapdown_ros.recording import read_bag  # noqa: E402
from strapdown_ros.rotation import (dcm_to_quat, from_ros_xyzw, quat_conjugate,  # noqa: E402
                                    quat_error_rotvec,
                                    quat_multiply, rotvec_to_quat, to_ros_xyzw, ypr_to_dcm)
from strapdown_ros.sensors import ARCSEC  # noqa: E402
from strapdown_ros.sensors.star_camera import StarCameraModel  # noqa: E402
from strapdown_ros.tools import (calibrate_bag, calibrate_gyro_bag,  # noqa: E402
                                 discrepancy, record_sim)

BETA = np.radians([40.0, -25.0, 120.0])  # true boresight ψ, ϑ, γ
BIAS = np.array([1.0e-5, -0.7e-5, 0.8e-5])  # injected gyro bias, rad/s (≈ 2 °/h, MEMS grade)
RATE_HZ = 100.0
PERIOD_NS = 10_000_000
CAMERA_INTERVAL = 2.0
ORIGIN_NS = 1_700_000_000 * 10**9  # epoch-like stamps: the tools' own time origin
BIAS_ARG = 'gyro_bias:=[' + ', '.join(repr(float(b)) for b in BIAS) + ']'


class SmoothTurns(MotionProfile):
    """
    Rests and turns about body axes, both senses, with a smooth rate.

    Rests and turns about body axes, both senses, with a smooth rate: over a turn of length D
    and angle Φ the rate about the axis is s(τ) = 2Φ/D · sin²(πτ/D), zero with its derivative
    at both ends.  Attitude, rate, ω̈ and ∫ω dt are closed-form (the turn axis is fixed in body
    and reference axes, so the rotation vector of a turn is axis · ∫s).
    """

    #: (duration s, body axis or None for a rest, angle rad); durations are whole gyro periods
    TURNS = ((2, 1), (0, 1), (1, -1), (2, -1), (0, -1), (1, 1)) * 2
    SEGMENTS = [(10.0, None, 0.0)] + [
        seg
        for axis, sign in TURNS
        for seg in ((8.0, axis, sign * np.radians(75.0)), (12.0, None, 0.0))
    ]

    def __init__(self):
        self.start = np.concatenate([[0.0], np.cumsum([d for d, _, _ in self.SEGMENTS])])
        self.duration = float(self.start[-1])
        q, self.q_start = np.array([1.0, 0.0, 0.0, 0.0]), []
        self.angle_before = np.zeros((len(self.SEGMENTS) + 1, 3))  # ∫ω dt up to each start
        for k, (d, axis, phi) in enumerate(self.SEGMENTS):
            self.q_start.append(q)
            u = self._axis(axis)
            q = quat_multiply(q, rotvec_to_quat(u * phi))
            self.angle_before[k + 1] = self.angle_before[k] + u * phi
        self.q_start = np.array(self.q_start)

    @staticmethod
    def _axis(axis):
        u = np.zeros(3)
        if axis is not None:
            u[axis] = 1.0
        return u

    def _where(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        k = np.clip(np.searchsorted(self.start, t, side='right') - 1, 0, len(self.SEGMENTS) - 1)
        D = np.array([self.SEGMENTS[i][0] for i in k])
        U = np.array([self._axis(self.SEGMENTS[i][1]) for i in k])
        phi = np.array([self.SEGMENTS[i][2] for i in k])
        return k, np.clip(t - self.start[k], 0.0, D), D, U, phi

    def _angle(self, tau, D, phi):  # ∫ s over [0, τ]
        return phi / D * (tau - D / (2 * np.pi) * np.sin(2 * np.pi * tau / D))

    def attitude(self, t):
        """Return q_ref_body at times ``t`` (closed form)."""
        k, tau, D, U, phi = self._where(t)
        q = quat_multiply(self.q_start[k], rotvec_to_quat(U * self._angle(tau, D, phi)[:, None]))
        return q.reshape(np.shape(t) + (4,))

    def body_rate(self, t):
        """Return the body rate at times ``t``, rad/s."""
        k, tau, D, U, phi = self._where(t)
        return (U * (2 * phi / D * np.sin(np.pi * tau / D) ** 2)[:, None]).reshape(
            np.shape(t) + (3,)
        )

    def rate_second_derivative(self, t):
        """Return ω̈ at times ``t``, rad/s³."""
        k, tau, D, U, phi = self._where(t)
        return U * (phi / D * (2 * np.pi / D) ** 2 * np.cos(2 * np.pi * tau / D))[:, None]

    def delta_theta(self, t0, t1):
        """Return ∫ω dt over [t0, t1], rad (exact)."""
        def F(t):
            k, tau, D, U, phi = self._where(t)
            return self.angle_before[k] + U * self._angle(tau, D, phi)[:, None]

        return F(t1) - F(t0)


PROFILE = SmoothTurns()
DURATION = PROFILE.duration


class Motion:
    """The exact motion sampled at the gyro stamps, and the camera fixes (true boresight BETA)."""

    def __init__(self):
        n = int(round(DURATION * RATE_HZ))
        self.k_ns = np.arange(n + 1, dtype=np.int64) * PERIOD_NS  # profile time, ns
        t = self.k_ns * 1e-9
        self.stamps = ORIGIN_NS + self.k_ns
        self.rate = PROFILE.body_rate(t) + BIAS  # ω at each stamp
        dt = np.diff(self.k_ns) * 1e-9
        self.delta_theta = PROFILE.delta_theta(t[:-1], t[1:]) + BIAS * dt[:, None]  # exact ∫ω dt
        self.mean_rate = self.delta_theta / dt[:, None]  # exact mean rates
        cam = StarCameraModel(boresight=BETA, interval=CAMERA_INTERVAL, seed=11)
        self.fixes = cam.fixes(PROFILE, int(DURATION / CAMERA_INTERVAL) - 1)


@pytest.fixture(scope='module')
def motion():
    """Give the simulated motion shared by the tests of this module."""
    return Motion()


# --- writing bags with rosbags ---------------------------------------------------------------
class BagWriter:
    """Write bags with rosbags' own serializer (independent of the package's writer)."""

    def __init__(self):
        from rosbags.typesys import get_typestore, Stores

        self.store = get_typestore(Stores.ROS2_JAZZY)
        self.T = self.store.types

    def header(self, ns, frame):
        """Return a std_msgs/Header at ``ns`` in ``frame``."""
        T = self.T
        return T['std_msgs/msg/Header'](
            stamp=T['builtin_interfaces/msg/Time'](sec=int(ns // 10**9), nanosec=int(ns % 10**9)),
            frame_id=frame,
        )

    def vec(self, v):
        """Return a geometry_msgs/Vector3."""
        return self.T['geometry_msgs/msg/Vector3'](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def quat(self, q_wxyz):
        """Return a geometry_msgs/Quaternion from a scalar-first quaternion."""
        x, y, z, w = (float(c) for c in to_ros_xyzw(np.asarray(q_wxyz, dtype=float)))
        return self.T['geometry_msgs/msg/Quaternion'](x=x, y=y, z=z, w=w)

    def pose(self, q):
        """Return a geometry_msgs/Pose at the origin with orientation ``q``."""
        T = self.T
        return T['geometry_msgs/msg/Pose'](
            position=T['geometry_msgs/msg/Point'](x=1.0, y=2.0, z=3.0), orientation=self.quat(q)
        )

    def imu(self, ns, rate, absent=False):
        """Return a sensor_msgs/Imu of rate ``rate`` (``absent``: covariance[0] = −1)."""
        T = self.T
        z9 = np.zeros(9)
        rate_cov = np.array([-1.0] + [0.0] * 8) if absent else z9  # ROS: -1 = field absent
        return T['sensor_msgs/msg/Imu'](
            header=self.header(ns, 'imu_link'),
            orientation=self.quat([1, 0, 0, 0]),
            orientation_covariance=np.array([-1.0] + [0.0] * 8),
            angular_velocity=self.vec(rate),
            angular_velocity_covariance=rate_cov,
            linear_acceleration=self.vec([0.0, 0.0, 9.8]),
            linear_acceleration_covariance=z9,
        )

    def vector3_stamped(self, ns, v):
        """Return a Vector3Stamped in imu_link."""
        return self.T['geometry_msgs/msg/Vector3Stamped'](
            header=self.header(ns, 'imu_link'), vector=self.vec(v)
        )

    def pose_stamped(self, ns, q):
        """Return a PoseStamped in gcrs."""
        return self.T['geometry_msgs/msg/PoseStamped'](
            header=self.header(ns, 'gcrs'), pose=self.pose(q)
        )

    def odometry(self, ns, q, cov_rot):
        """Return an Odometry with the rotation block ``cov_rot`` of the pose covariance."""
        T = self.T
        cov = np.zeros((6, 6))
        cov[:3, :3] = np.eye(3) * 4.0  # position: known to 2 m
        cov[3:, 3:] = cov_rot
        twist = T['geometry_msgs/msg/Twist'](
            linear=self.vec([0, 0, 0]), angular=self.vec([0, 0, 0])
        )
        return T['nav_msgs/msg/Odometry'](
            header=self.header(ns, 'gcrs'),
            child_frame_id='star_tracker',
            pose=T['geometry_msgs/msg/PoseWithCovariance'](
                pose=self.pose(q), covariance=cov.reshape(36)
            ),
            twist=T['geometry_msgs/msg/TwistWithCovariance'](twist=twist, covariance=np.zeros(36)),
        )

    def tf(self, ns, transforms):
        """Record transforms: [(parent, child, q_parent_child)]."""
        T = self.T
        out = [
            T['geometry_msgs/msg/TransformStamped'](
                header=self.header(ns, parent),
                child_frame_id=child,
                transform=T['geometry_msgs/msg/Transform'](
                    translation=self.vec([0.5, 0.0, 0.0]), rotation=self.quat(q)
                ),
            )
            for parent, child, q in transforms
        ]
        return T['tf2_msgs/msg/TFMessage'](transforms=out)

    def write(self, path, messages):
        """messages: [(topic, stamp_ns, message)], written in stamp order (MCAP)."""
        from rosbags.rosbag2 import StoragePlugin, Writer

        conns = {}
        with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
            for topic, ns, m in sorted(messages, key=lambda x: x[1]):
                if topic not in conns:
                    conns[topic] = w.add_connection(topic, m.__msgtype__, typestore=self.store)
                w.write(conns[topic], int(ns), self.store.serialize_cdr(m, m.__msgtype__))
        return path


def _gyro_messages(bw, motion, kind):
    if kind == 'delta_theta':
        return [
            ('/imu/delta_theta', ns, bw.vector3_stamped(ns, v))
            for ns, v in zip(motion.stamps[1:], motion.delta_theta)
        ]
    # Imu: one sample per stamp; the first (t = 0) only starts the integration
    rates = (
        motion.rate
        if kind == 'rate_at_stamp'
        else np.vstack([motion.mean_rate[:1], motion.mean_rate])
    )
    return [('/imu/data', ns, bw.imu(ns, w)) for ns, w in zip(motion.stamps, rates)]


def _fix_ns(fx):
    return ORIGIN_NS + int(round(fx.stamp * 1e9))


def _reference_messages(bw, motion, kind):
    if kind == 'pose':
        return [
            ('/camera/pose', _fix_ns(fx), bw.pose_stamped(_fix_ns(fx), fx.attitude))
            for fx in motion.fixes
        ]
    if kind in ('odometry', 'odometry_zero_cov'):
        return [
            (
                '/camera/odom',
                _fix_ns(fx),
                bw.odometry(
                    _fix_ns(fx),
                    fx.attitude,
                    fx.covariance if kind == 'odometry' else np.zeros((3, 3)),
                ),
            )
            for fx in motion.fixes
        ]
    # TF: the camera transform among others; "tf_inverse" records only star_tracker → gcrs
    out = []
    for k, fx in enumerate(motion.fixes):
        ns = _fix_ns(fx)
        cam = (
            ('gcrs', 'star_tracker', fx.attitude)
            if kind == 'tf'
            else ('star_tracker', 'gcrs', quat_conjugate(fx.attitude))
        )
        out.append(
            (
                '/tf',
                ns,
                bw.tf(
                    ns,
                    [
                        ('map', 'odom', [np.cos(0.1 * k), 0, 0, np.sin(0.1 * k)]),
                        cam,
                        ('base_link', 'imu_link', [1, 0, 0, 0]),
                    ],
                ),
            )
        )
    for j in range(int(DURATION * 5)):  # other transforms at 5 Hz, between the fixes
        ns = ORIGIN_NS + 100_000_000 + j * 200_000_000
        out.append(
            (
                '/tf',
                ns,
                bw.tf(ns, [('odom', 'base_link', [np.cos(0.01 * j), np.sin(0.01 * j), 0, 0])]),
            )
        )
    return out


@pytest.fixture(scope='module')
def bags(tmp_path_factory, motion):
    """(gyro format, reference format) → bag path, written once per module."""
    root = tmp_path_factory.mktemp('formats')
    bw = BagWriter()
    cache = {}

    def get(gyro, ref):
        if (gyro, ref) not in cache:
            cache[(gyro, ref)] = bw.write(
                root / f'{gyro}_{ref}',
                _gyro_messages(bw, motion, gyro) + _reference_messages(bw, motion, ref),
            )
        return cache[(gyro, ref)]

    return get


def _calibrate(tmp_path, bag, *args):
    out = tmp_path / 'cal.json'
    if out.exists():
        out.unlink()
    status = calibrate_bag.main([str(bag), '--json', str(out), '-p', BIAS_ARG, *args])
    return status, (json.loads(out.read_text()) if out.exists() else None)


def _assert_boresight(r, bound_arcsec):
    """β recovered: the C_MF^VF error within 3σ per MF axis and within an absolute bound."""
    assert r['observable'] and r['converged'], r['message']
    q_true = dcm_to_quat(ypr_to_dcm(*BETA))
    e = quat_error_rotvec(from_ros_xyzw(np.array(r['q_mf_vf_xyzw'])), q_true, frame='reference')
    sigma = np.sqrt(np.diag(r['rotation_covariance_mf_rad2']))
    assert np.all(np.abs(e) < 3 * sigma), (e / ARCSEC, sigma / ARCSEC)
    assert np.all(np.abs(e) < bound_arcsec * ARCSEC), e / ARCSEC


# --- formats ---------------------------------------------------------------------------------
def test_imu_rates_at_the_stamps_with_pose_stamped_reference(tmp_path, bags, capsys):
    """
    Read sensor_msgs/Imu rates at the stamps with a PoseStamped reference.

    (a) sensor_msgs/Imu with the exact rate at each stamp (trapezoid rule, error T³ω̈/12 per
    increment), PoseStamped reference without covariance: σ from the model.
    """
    status, r = _calibrate(
        tmp_path,
        bags('rate_at_stamp', 'pose'),
        '--gyro-topic',
        '/imu/data',
        '--reference-topic',
        '/camera/pose',
    )
    assert status == 0
    _assert_boresight(r, 5.0)
    inp = r['input']
    assert inp['gyro_type'] == 'sensor_msgs/msg/Imu' and inp['gyro_input'] == 'rates'
    assert (
        inp['rate_rule'] == 'trapezoid'
        and inp['reference_type'] == 'geometry_msgs/msg/PoseStamped'
    )
    assert inp['reference_covariance'] == 'from_model' and r['camera_covariance_from_bag'] is False
    n = int(round(DURATION * RATE_HZ)) + 1
    assert inp['rate_samples']['received'] == inp['rate_samples']['accepted'] == n
    assert inp['rate_samples']['intervals_not_integrated'] == 0
    assert r['messages']['gyro'] == n - 1 and r['gyro_gaps']['gaps'] == 0
    assert r['unread_messages'] == {} and r['dropped']['gyro_rate_samples']['nan'] == 0
    out = capsys.readouterr().out
    assert (
        'rate samples on /imu/data → increments by the trapezoid rule' in out
        and 'σ from the model' in out
    )


def test_trapezoid_increments_against_the_exact_integral(motion, bags):
    """The trapezoid increments of exact rate samples differ from ∫ω dt by T³ω̈/12 + O(T⁵)."""
    d = read_bag(
        bags('rate_at_stamp', 'pose'), gyro_topic='/imu/data', reference_topic='/camera/pose'
    )
    got = np.asarray(d['gyro'].values)
    assert np.array_equal(np.asarray(d['gyro'].stamps), motion.stamps[1:])
    t = motion.k_ns * 1e-9
    w2 = PROFILE.rate_second_derivative(0.5 * (t[:-1] + t[1:]))  # ω̈ mid-interval
    T = 1.0 / RATE_HZ
    err = got - motion.delta_theta
    assert np.max(np.abs(err)) > 1e-11  # the rule's error is there, and it is
    np.testing.assert_allclose(
        err, T**3 * w2 / 12.0, rtol=0, atol=1e-3 * T**3 * np.max(np.abs(w2))
    )


def test_imu_mean_rates_equal_the_delta_theta_topic(tmp_path, motion, bags):
    """
    Read the mean rule fed by exact mean rates as the Δθ topic.

    (d) the 'mean' rule fed by exact mean rates gives the Δθ topic's increments to round-off,
    and so the same boresight.
    """
    dth = read_bag(bags('delta_theta', 'pose'), reference_topic='/camera/pose')
    mean = read_bag(
        bags('mean_rate', 'pose'),
        gyro_topic='/imu/data',
        reference_topic='/camera/pose',
        rate_rule='mean',
    )
    assert dth['gyro_input'] == 'delta_theta' and mean['gyro_input'] == 'rates'
    assert mean['gyro'].stamps == dth['gyro'].stamps
    a, b = np.asarray(mean['gyro'].values), np.asarray(dth['gyro'].values)
    np.testing.assert_allclose(a, b, rtol=4e-16, atol=1e-22)
    np.testing.assert_allclose(b, motion.delta_theta, rtol=0, atol=0)
    s1, r1 = _calibrate(tmp_path, bags('delta_theta', 'pose'), '--reference-topic', '/camera/pose')
    s2, r2 = _calibrate(
        tmp_path,
        bags('mean_rate', 'pose'),
        '--gyro-topic',
        '/imu/data',
        '--rate-rule',
        'mean',
        '--reference-topic',
        '/camera/pose',
    )
    assert s1 == s2 == 0 and r2['input']['rate_rule'] == 'mean'
    np.testing.assert_allclose(r2['beta_rad'], r1['beta_rad'], rtol=0, atol=1e-12)
    _assert_boresight(r1, 5.0)


def test_dropped_rate_samples_are_counted_and_become_gaps(tmp_path, motion, capsys):
    """
    Drop and count bad rate samples; their intervals become gaps.

    A NaN, an out-of-range and an 'absent' (covariance[0] = −1) rate sample: each is dropped
    and counted, the interval over it (2 periods) is not integrated, so two increments are missing
    and the one pair spanning each gap is discarded; the boresight stands.
    """
    bw = BagWriter()
    msgs = _gyro_messages(bw, motion, 'rate_at_stamp')
    bad = {
        5100: {'rate': [np.nan, 0.0, 0.0]},
        9100: {'rate': [1e308, 0.0, 0.0]},  # mid-interval
        13100: {'rate': motion.rate[13100], 'absent': True},
    }  # of the fixes
    for k, kw in bad.items():
        msgs[k] = ('/imu/data', motion.stamps[k], bw.imu(motion.stamps[k], **kw))
    bag = bw.write(tmp_path / 'drops', msgs + _reference_messages(bw, motion, 'pose'))
    capsys.readouterr()
    status, r = _calibrate(
        tmp_path, bag, '--gyro-topic', '/imu/data', '--reference-topic', '/camera/pose'
    )
    assert status == 0
    rs = r['input']['rate_samples']
    assert rs['dropped'] == {
        'nan': 1,
        'duplicate': 0,
        'out_of_order': 0,
        'out_of_range': 1,
        'stamp_outlier': 0,
        'stamp_burst': 0,
        'marked_absent': 1,
        'wrong_type': 0,
        'undecodable': 0,
    }
    assert rs['received'] == len(motion.stamps) and rs['accepted'] == len(motion.stamps) - 3
    assert rs['intervals_not_integrated'] == 3
    assert r['messages']['gyro'] == len(motion.stamps) - 1 - 6
    gg = r['gyro_gaps']
    assert (gg['gaps'], gg['missing'], gg['pairs_discarded']) == (3, 6, 3)
    assert r['pairs'] == len(motion.fixes) - 1 - 3
    err = capsys.readouterr().err
    assert 'WARNING: gyro rate samples: dropped nan 1, out_of_range 1, marked_absent 1' in err, err
    _assert_boresight(r, 5.0)


def test_odometry_reference_covariance_from_the_messages_or_the_model(tmp_path, motion, bags):
    """
    Read an Odometry reference covariance from the messages or the model.

    (b) nav_msgs/Odometry: the rotation block of pose.covariance is the camera covariance; a
    zero rotation block takes the model's σ (the same as the simulated one here).
    """
    status, r = _calibrate(
        tmp_path,
        bags('rate_at_stamp', 'odometry'),
        '--gyro-topic',
        '/imu/data',
        '--reference-topic',
        'camera/odom',
    )
    assert status == 0
    _assert_boresight(r, 5.0)
    assert r['input']['reference_type'] == 'nav_msgs/msg/Odometry'
    assert (
        r['input']['reference_covariance'] == 'from_messages'
        and r['camera_covariance_from_bag'] is True
    )
    status, r0 = _calibrate(
        tmp_path,
        bags('rate_at_stamp', 'odometry_zero_cov'),
        '--gyro-topic',
        '/imu/data',
        '--reference-topic',
        '/camera/odom',
    )
    assert status == 0 and r0['input']['reference_covariance'] == 'from_model'
    assert r0['camera_fixes']['covariance_substituted'] == len(motion.fixes)
    _assert_boresight(r0, 5.0)
    np.testing.assert_allclose(
        r0['beta_rad'], r['beta_rad'], rtol=0, atol=1e-9
    )  # same σ: same fit


def test_tf_reference_among_other_frames_direct_and_inverse(tmp_path, motion, bags):
    """
    Read a /tf reference among other frames, direct and inverse.

    (c) /tf with other frame pairs: gcrs → star_tracker is taken; when only star_tracker → gcrs
    is recorded its inverse is used, with the same result.
    """
    status, r = _calibrate(
        tmp_path,
        bags('rate_at_stamp', 'tf'),
        '--gyro-topic',
        '/imu/data',
        '--reference-frames',
        'gcrs',
        'star_tracker',
    )
    assert status == 0
    _assert_boresight(r, 5.0)
    inp = r['input']
    assert inp['reference_topic'] == '/tf' and inp['reference_type'] == 'tf2_msgs/msg/TFMessage'
    assert inp['reference_frames'] == {
        'parent': 'gcrs',
        'child': 'star_tracker',
        'transform': 'direct',
    }
    assert inp['reference_covariance'] == 'from_model'
    assert r['messages']['camera'] == len(motion.fixes)
    status, ri = _calibrate(
        tmp_path,
        bags('rate_at_stamp', 'tf_inverse'),
        '--gyro-topic',
        '/imu/data',
        '--reference-topic',
        '/tf',
        '--reference-frames',
        'gcrs',
        'star_tracker',
    )
    assert status == 0 and ri['input']['reference_frames']['transform'] == 'inverse'
    np.testing.assert_allclose(ri['beta_rad'], r['beta_rad'], rtol=0, atol=1e-12)


def test_discrepancy_names_a_gyro_bias_on_imu_rate_input(tmp_path, bags):
    """The injected bias (rad/s) on sensor_msgs/Imu rate input is named and recovered within 3σ."""
    model = tmp_path / 'model.yaml'
    model.write_text(json.dumps({'/**': {'ros__parameters': {'gyro_rate': RATE_HZ}}}))
    out = tmp_path / 'd.json'
    assert (
        discrepancy.main(
            [
                str(bags('rate_at_stamp', 'odometry')),
                '--model',
                str(model),
                '--json',
                str(out),
                '--quiet',
                '--gyro-topic',
                '/imu/data',
                '--reference-topic',
                '/camera/odom',
            ]
        )
        == 0
    )
    r = json.loads(out.read_text())
    named = [s['effect'] for s in r['steps']]
    assert 'gyro_bias' in named, (r['steps'], r.get('candidates_first_step'))
    step = r['steps'][named.index('gyro_bias')]
    est, sig = np.asarray(step['parameters']['gyro_bias']), np.asarray(step['sigma']['gyro_bias'])
    assert np.all(np.abs(est - BIAS) <= 3 * sig), (est, BIAS, sig)
    assert np.all(sig < 0.2 * np.abs(BIAS))  # a real detection, not a wide interval
    assert (
        r['input']['gyro_input'] == 'rates'
        and r['input']['reference_type'] == 'nav_msgs/msg/Odometry'
    )


# --- errors ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    'args, needles',
    [
        (
            ['--reference-topic', '/imu/data'],
            ['/imu/data has type sensor_msgs/msg/Imu', 'supported'],
        ),
        (
            ['--reference-frames', 'gcrs', 'camera'],
            ['no transform gcrs→camera', 'frame pairs present', 'gcrs→star_tracker', 'map→odom'],
        ),
        (
            ['--reference-topic', '/nonexistent'],
            [
                '--reference-topic /nonexistent: no such topic',
                '/imu/data (sensor_msgs/msg/Imu)',
                '/tf (tf2_msgs/msg/TFMessage)',
            ],
        ),
        (['--reference-topic', '/tf'], ['--reference-frames PARENT CHILD']),
        (
            ['--gyro-topic', '/tf', '--reference-frames', 'gcrs', 'star_tracker'],
            ['gyro topic /tf has type'],
        ),
        (['--reference-frames', 'gcrs', 'gcrs'], ['same frame']),
        (['--rate-rule', 'simpson'], ['invalid choice', 'simpson']),
    ],
)
def test_bad_input_options_are_one_line_exit_2(tmp_path, bags, capsys, args, needles):
    bag = bags('rate_at_stamp', 'tf')
    model = tmp_path / 'm.yaml'
    model.write_text('{}')
    for tool, base in (
        (calibrate_bag, [str(bag)]),
        (discrepancy, [str(bag), '--model', str(model), '--quiet']),
        (calibrate_gyro_bag, [str(bag), '--method', 'integral', '--model', str(model)]),
    ):
        capsys.readouterr()
        try:
            status = tool.main(
                base + ['--gyro-topic', '/imu/data'] * ('--gyro-topic' not in args) + args
            )
        except SystemExit as exc:  # argparse errors
            status = exc.code
        out, err = capsys.readouterr()
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert status == 2 and len(lines) == 1 and 'error' in lines[0], (
            tool.__name__,
            status,
            err,
        )
        assert all(n in lines[0] for n in needles), lines[0]
        assert len(lines[0]) < 1000


def test_error_listing_is_bounded(tmp_path, capsys):
    """A bag with 60 topics: the error names a dozen and counts the rest."""
    bw = BagWriter()
    msgs = [
        (
            f'/noise/topic_{i:02d}/' + 'x' * 200,
            PERIOD_NS * (i + 1),
            bw.vector3_stamped(PERIOD_NS * (i + 1), [0, 0, 0]),
        )
        for i in range(60)
    ]
    bag = bw.write(tmp_path / 'many', msgs)
    assert calibrate_bag.main([str(bag), '--gyro-topic', '/nope']) == 2
    err = capsys.readouterr().err.strip()
    assert '\n' not in err and 'and 48 more' in err and len(err) < 1500, err


# --- a corrupt chunk -------------------------------------------------------------------------
def _flip_message_opcodes(mcap, channel_id, t0_ns, t1_ns) -> int:
    """
    Hide the messages of one channel in the first chunk of an MCAP file.

    Flip the top bit of the opcode of every message record of ``channel_id`` logged in
    [t0, t1) in the first chunk (an uncompressed rosbags MCAP): readers skip unknown opcodes, so
    those messages vanish from the data while the index still counts them.  Returns how many.
    """
    b = bytearray(mcap.read_bytes())
    pos = 8  # magic
    while b[pos] != 0x06:  # to the first chunk record
        pos += 9 + struct.unpack_from('<Q', b, pos + 1)[0]
    body = pos + 9
    size = struct.unpack_from('<Q', b, body + 16)[0]  # uncompressed size
    comp = struct.unpack_from('<I', b, body + 28)[0]  # compression string length
    assert comp == 0  # rosbags writes uncompressed chunks
    rec = body + 28 + 4 + 8
    end, n = rec + size, 0
    while rec < end:
        op, length = b[rec], struct.unpack_from('<Q', b, rec + 1)[0]
        if op == 0x05:
            (chan,) = struct.unpack_from('<H', b, rec + 9)
            (log_time,) = struct.unpack_from('<Q', b, rec + 9 + 6)
            if chan == channel_id and t0_ns <= log_time < t1_ns:
                b[rec] ^= 0x80
                n += 1
        rec += 9 + length
    mcap.write_bytes(bytes(b))
    return n


def test_corrupt_first_chunk_is_reported_not_silent(tmp_path, capsys):
    """
    Report a corrupt first chunk instead of dropping its messages silently.

    A corrupt first MCAP chunk dropped 25 s of gyro data and
    calibrate_bag said 'dropped: none'.  Now the read counts are compared with the bag's index.
    """
    bag = tmp_path / 'bag'
    assert (
        record_sim.main(
            [str(bag), '--no-accel', '-p', 'profile:=bench', '-p', 'camera_interval:=5.0']
        )
        == 0
    )
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as rd:
        gyro_id = next(c.id for c in rd.connections if c.topic == '/imu/delta_theta')
    hidden = _flip_message_opcodes(next(bag.glob('*.mcap')), gyro_id, 10 * 10**9, 35 * 10**9)
    assert hidden > 2000  # 25 s at 100 Hz inside the first chunk
    capsys.readouterr()
    f = tmp_path / 'r.json'
    status = calibrate_bag.main([str(bag), '--json', str(f)])
    out, err = capsys.readouterr()
    assert f'UNREAD: /imu/delta_theta +{hidden} message(s)' in out
    assert status == 0  # the bench motion is still observable
    r = json.loads(f.read_text())
    assert r['unread_messages'] == {'/imu/delta_theta': hidden}
    assert r['messages']['gyro'] == 17000 - hidden
    warn = [ln for ln in err.splitlines() if 'WARNING:' in ln]
    assert len(warn) == 1 and f'/imu/delta_theta: +{hidden}' in warn[0], err
    # discrepancy reads through the same reader: the same count in its JSON input record
    model = tmp_path / 'm.yaml'
    model.write_text('{}')
    d = tmp_path / 'd.json'
    assert discrepancy.main([str(bag), '--model', str(model), '--json', str(d), '--quiet']) == 0
    assert json.loads(d.read_text())['input']['unread_messages'] == {'/imu/delta_theta': hidden}
    assert 'WARNING:' in capsys.readouterr().err


def test_overflowing_and_singular_fixes_cost_one_fix_not_the_bag(tmp_path):
    """
    Issue 27, findings 4, 5, 6: a fix scaled by 1e200, one with a 1e308 covariance, a singular one.

    The reader passed the first on unnormalised (garbage downstream), refused the whole bag on
    the second (eigvalsh raised) and passed the third to a filter that needs it positive
    definite.  Now each is one fix dropped under its reason; the rest is read as clean.
    """
    from strapdown_ros.bench.hostile_input import (clean_recording, kind_named, streams_with,
                                                   write_bag)

    rec = clean_recording()
    clean = read_bag(write_bag(tmp_path / 'clean', rec, accel=False))
    for name, reason, why in (('scaled_1e200', 'not_unit', None),
                              ('huge_covariance', 'bad_covariance', 'out_of_bounds'),
                              ('singular_covariance', 'bad_covariance', 'not_positive_definite')):
        bag = write_bag(tmp_path / name,
                        streams_with(rec, kind_named(f'reference:{name}'), 10), accel=False)
        got = read_bag(bag)
        c = got['camera']
        assert c.dropped[reason] == 1 and c.received == clean['camera'].received + 1
        if why:
            assert got['camera_fixes']['bad_covariance_reasons'][why] == 1
        assert c.stamps == clean['camera'].stamps
        for (q, P), (q0, P0) in zip(c.values, clean['camera'].values):
            np.testing.assert_array_equal(q, q0)
            np.testing.assert_array_equal(P, P0)


def test_imu_stamp_jitter_of_30_percent_loses_nothing(tmp_path):
    """
    Issue 27, finding 8: a 1 kHz IMU stamped with ±0.3 ms uniform jitter, no sample missing.

    The gap rule's period is the median step of the stamps and a gap is a step above 1.75
    periods: no interval is left unintegrated and no increment is missing; three samples lost in
    a row are one gap, counted on the rates and on the increments alike.
    """
    rng = np.random.default_rng(3)
    bw = BagWriter()
    n = 4000
    t = ORIGIN_NS + (np.arange(n) * 1_000_000 + rng.uniform(-0.3, 0.3, n) * 1_000_000).astype(
        np.int64)
    rates = PROFILE.body_rate((t - ORIGIN_NS) * 1e-9 + 10.0)
    fixes = [('/camera/pose', ORIGIN_NS + k * 500_000_000,
              bw.pose_stamped(ORIGIN_NS + k * 500_000_000, [1.0, 0.0, 0.0, 0.0]))
             for k in range(1, 8)]
    for name, keep in (('jitter', np.ones(n, bool)), ('lost', ~np.isin(np.arange(n),
                                                                       [2000, 2001, 2002]))):
        msgs = [('/imu/data', int(s), bw.imu(int(s), w)) for s, w in zip(t[keep], rates[keep])]
        d = read_bag(bw.write(tmp_path / name, msgs + fixes), gyro_topic='/imu/data',
                     reference_topic='/camera/pose')
        rs, g = d['rate_samples'], d['gyro']
        lost = int((~keep).sum() > 0)
        assert (rs['gaps'], rs['intervals_not_integrated']) == (lost, lost), rs
        assert (g.check.gaps, len(g.gaps)) == (lost, lost)
        assert len(g.stamps) == keep.sum() - 1 - lost
        assert abs(d['gyro_period_s'] - 1e-3) < 2e-5
