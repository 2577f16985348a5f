"""
002 (Ilyushenko 2009): integral calibration of B, s0 from star-tracker attitudes.

Recovery of B = I + M and s0 = b within 3σ, σ honest in a Monte Carlo, a constant-direction
trajectory flagged unobservable with named parameters.
"""
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from strapdown_ros.calibration.integral_method import (calibrate_from_measurements,
                                                       integral_calibration, PARAMETER_LABELS)
from strapdown_ros.calibration.interval_means import IntervalMeans, mean_true_rate
from strapdown_ros.motion.profiles import (ConingProfile, MotionProfile, PiecewiseRateProfile,
                                           Segment, tkachenko_profile)
from strapdown_ros.reproductions.ilyushenko2009 import simulate_measurements
from strapdown_ros.rotation import (quat_angle_between, quat_conjugate, quat_cumprod,
                                    quat_multiply, quat_rotate, quat_to_dcm, quat_to_rotvec,
                                    rotvec_to_quat)
from strapdown_ros.sensors import IntegratingSensor, SensorErrorModel
from strapdown_ros.sensors.star_camera import StarCameraModel


M_TRUE = np.array([[1.0e-3, 5.0e-4, -5.0e-4],
                   [-4.0e-4, -1.0e-3, 5.0e-4],
                   [3.0e-4, 5.0e-4, 1.5e-3]])
BIAS = np.array([1e-4, -1e-4, 0.5e-4])           # rad/s
CAMERA_SIGMA = 1e-5                               # rad per axis
ARW = 1e-5                                        # rad/√s


def gyro_errors(random_walk=ARW):
    """
    Return the gyro errors of these tests: M_TRUE, BIAS and a random walk.

    Parameters
    ----------
    random_walk : float
        Angle random walk, rad/√s.

    Returns
    -------
    SensorErrorModel
        The errors.

    """
    return SensorErrorModel(bias=BIAS, scale_factor=np.diag(M_TRUE),
                            misalignment=M_TRUE - np.diag(np.diag(M_TRUE)),
                            random_walk=random_walk)


# --------------------------------------------------------------------------- calibration
@pytest.fixture(scope='module')
def paper_000_data():
    """Return 30 s of 000 §6's rate table with gyro errors and camera noise."""
    return simulate_measurements(tkachenko_profile(), 30.0, gyro_errors(), gyro_rate=100.0,
                                 camera_interval=0.1, camera_sigma=CAMERA_SIGMA, seed=3)


def _calibrate(d, **kw):
    kw.setdefault('steps_per_interval', 5)
    return calibrate_from_measurements(d.gyro_stamps, d.delta_theta, d.camera_stamps,
                                       d.camera_quats, d.camera_sigma,
                                       gyro_random_walk=d.gyro_random_walk, profile=d.profile,
                                       **kw)


@pytest.mark.parametrize('weighting', ['model', 'residual', 'pooled'])
def test_recovers_B_and_s0_within_3_sigma(paper_000_data, weighting):
    """
    Recover B and s0 within 3σ with every weighting.

    Parameters
    ----------
    paper_000_data : Measurements
        30 s of 000 §6's rate table with gyro errors and camera noise (fixture).
    weighting : str
        The weighting of the least squares.

    """
    d = paper_000_data
    r = _calibrate(d, weighting=weighting)
    assert r.observable, r.message
    assert len(r.intervals) == 59 and r.covariance.shape == (12, 12) and r.sigma.shape == (12,)
    err = r.x - d.x_true
    z = err / r.sigma
    print(weighting, 'error ×1e6:', np.round(err * 1e6, 1), 'σ ×1e6:', np.round(r.sigma * 1e6, 1))
    assert np.all(np.abs(z) < 3.0), dict(zip(PARAMETER_LABELS, np.round(z, 2)))
    # the estimate is useful: M to a few % of its size, bias to ~5% (σ_cam = 1e-5 rad, 30 s)
    assert np.all(r.sigma[:9] < 0.1 * np.abs(M_TRUE).max())
    assert np.all(r.sigma[9:] < 0.1 * np.abs(BIAS).max())
    np.testing.assert_allclose(r.to_error_model().matrix, r.B - np.eye(3))
    np.testing.assert_allclose(r.bias, r.s0)
    if weighting == 'model':
        assert 0.6 < r.chi2_per_dof < 1.5
        assert r.covariance_residual is not None and r.covariance_model is not None
    # w̄ from the camera against the exact mean rate: at the noise level √2σ/T (order 3, ωh ≤ 0.03)
    assert r.extra['w_bar_error_rms'] < 2.0 * np.sqrt(2) * CAMERA_SIGMA / 0.5


def test_calibration_corrects_the_increments(paper_000_data):
    """
    Remove the systematic part of the increment errors with the estimate.

    Parameters
    ----------
    paper_000_data : Measurements
        30 s of 000 §6's rate table with gyro errors and camera noise (fixture).

    """
    d = paper_000_data
    r = _calibrate(d)
    T = np.diff(np.concatenate([[0.0], d.gyro_stamps]))
    raw = d.delta_theta - d.true_delta_theta
    fixed = r.correct(d.delta_theta, T) - d.true_delta_theta
    # what is left is the random walk plus the calibration residual
    sys_raw = np.abs(raw.sum(0))
    sys_fixed = np.abs(fixed.sum(0))
    assert np.all(sys_fixed < 0.1 * sys_raw), (sys_raw, sys_fixed)


class SmoothProfile(MotionProfile):
    """
    Smooth rotation about all three axes: two coning motions about different axes composed.

    q = c1(t) ⊗ (r ⊗ c2(t) ⊗ r*), ω = C2ᵀω1 + R ω_c2 (|ω| ≤ 0.38 rad/s).  ∫ω dt by composite
    10-point Gauss–Legendre (a trigonometric integrand: exact to round-off on 0.05-s pieces).
    """

    def __init__(self):
        self.c1 = ConingProfile(0.3, 0.7)
        self.c2 = ConingProfile(0.4, 0.45)
        self.r = rotvec_to_quat(np.ones(3) * 2 * np.pi / 3 / np.sqrt(3))     # x → y → z
        self.R = quat_to_dcm(self.r)

    def _q2(self, t):
        return quat_multiply(quat_multiply(self.r, self.c2.attitude(t)), quat_conjugate(self.r))

    def attitude(self, t):
        """
        Return the attitude q_ref_body.

        Parameters
        ----------
        t : float or ndarray
            Time, s.

        Returns
        -------
        ndarray
            Scalar-first quaternions.

        """
        return quat_multiply(self.c1.attitude(t), self._q2(t))

    def body_rate(self, t):
        """
        Return the body rate.

        Parameters
        ----------
        t : float or ndarray
            Time, s.

        Returns
        -------
        ndarray
            ω, body axes, rad/s.

        """
        inner = quat_rotate(quat_conjugate(self._q2(t)), self.c1.body_rate(t))
        return inner + self.c2.body_rate(t) @ self.R.T

    def delta_theta(self, t0, t1):
        """
        Return ∫ω dt over [t0, t1] by composite Gauss–Legendre.

        Parameters
        ----------
        t0, t1 : float or ndarray
            Interval ends, s.

        Returns
        -------
        ndarray
            The integral, rad.

        """
        t0, t1 = np.asarray(t0, dtype=float), np.asarray(t1, dtype=float)
        x, wts = np.polynomial.legendre.leggauss(10)
        n = max(1, int(np.ceil(np.max(t1 - t0) / 0.05)))
        out = np.zeros(np.broadcast(t0, t1).shape + (3,))
        for k in range(n):
            a, b = t0 + (t1 - t0) * k / n, t0 + (t1 - t0) * (k + 1) / n
            nodes = 0.5 * (a + b)[..., None] + 0.5 * (b - a)[..., None] * x
            rates = np.einsum('k,...kj->...j', wts, self.body_rate(nodes))
            out += 0.5 * (b - a)[..., None] * rates
        return out


def test_smooth_profile_is_exact():
    """The smooth test profile's rate and ∫ω dt agree with its attitude."""
    p = SmoothProfile()
    t, e = 1.234, 1e-6
    step = quat_multiply(quat_conjugate(p.attitude(t - e)), p.attitude(t + e))
    fd = quat_to_rotvec(step) / (2 * e)
    np.testing.assert_allclose(fd, p.body_rate(t), atol=1e-9)
    # ∫ω dt reproduces the attitude through an accurate integration of many small increments
    tt = np.linspace(0.0, 2.0, 2001)
    q = quat_cumprod(p.attitude(0.0), rotvec_to_quat(p.delta_theta(tt[:-1], tt[1:])))[-1]
    assert quat_angle_between(q, p.attitude(2.0)) < 1e-6            # the O(h²) of the rotvec sum


def test_noise_free_bias_of_B_by_order():
    """
    No camera or gyro noise: what is left in B, s0 is the inversion error itself.

    Smooth 3-axis motion: order 2 biases B by (ωh)²-terms (8e-5 at h = 0.1 s), order 3 by 2e-6,
    and halving h divides them by 4 and 8 — the orders carry over to the calibration.
    """
    p = SmoothProfile()
    errs = gyro_errors(random_walk=0.0)
    e = {}
    for h in (0.1, 0.2):
        d = simulate_measurements(p, 30.0, errs, camera_interval=h, camera_sigma=0.0, seed=1)
        for order in (2, 3):
            r = calibrate_from_measurements(d.gyro_stamps, d.delta_theta, d.camera_stamps,
                                            d.camera_quats,
                                            steps_per_interval=int(round(0.5 / h)), order=order,
                                            weighting='residual')
            assert r.observable
            e[h, order] = np.abs(r.x - d.x_true).max()
    print('noise-free max |x − x_true|:', {k: f'{v:.2e}' for k, v in e.items()})
    assert 3e-5 < e[0.1, 2] < 2e-4 and e[0.1, 3] < 5e-6
    assert 3.0 < e[0.2, 2] / e[0.1, 2] < 5.0
    assert 5.0 < e[0.2, 3] / e[0.1, 3] < 12.0


def test_rate_jumps_on_the_camera_grid():
    """
    Test rate jumps that fall on the camera grid.

    000's piecewise-constant rates jump at 5-s multiples, on the 0.1-s camera grid.  The paper's
    order-3 correction then adds (1/12)V_{n−1}×V_n at each jump (w̄ error up to 4e-5 rad/s in the
    interval of the jump; through the recursion ~|V|/12 of it leaks into the next one, 6e-8;
    1e-10 elsewhere); the adaptive neighbour removes it; off the grid the paper's choice is
    better on average (doc/integral_method.md).
    """
    p = tkachenko_profile()
    stamps = 0.1 * np.arange(1, 299)
    out = {}
    for order, nb in ((2, 'previous'), (3, 'previous'), (3, 'adaptive')):
        t0, t1, w, _ = mean_true_rate(stamps, p.attitude(stamps), order=order,
                                      steps_per_interval=5, neighbour=nb)
        err = np.linalg.norm(w - p.delta_theta(t0, t1) / (t1 - t0)[:, None], axis=1)
        jump = np.array([np.any((a <= j + 1e-9) & (j <= b + 0.1 + 1e-9)) for a, b in zip(t0, t1)
                         for j in [np.array([5.0, 10.0, 15.0, 20.0, 25.0])]])
        out[order, nb] = (err[jump].max(), err[~jump].max())
    print({k: tuple(f'{x:.1e}' for x in v) for k, v in out.items()})
    assert out[3, 'previous'][1] < 1e-7 and 1e-5 < out[3, 'previous'][0] < 1e-4
    assert out[3, 'adaptive'][0] < 1e-9 and out[3, 'adaptive'][1] < 1e-9
    assert out[2, 'previous'][1] > 1e-6                     # order 2: (ωh)² everywhere


def test_sigma_is_honest_monte_carlo():
    """
    50 seeds (camera noise, random walk): RMS error / RMS σ per parameter.

    model weighting (full covariance, consecutive intervals): honest (within 1.5×);
    residual weighting on disjoint intervals (independent errors): honest;
    residual weighting on consecutive intervals: conservative (the shared-boundary noise
    telescopes).
    """
    prof = tkachenko_profile()
    errs = gyro_errors()
    out = {k: ([], []) for k in ('model', 'residual_disjoint', 'residual_consecutive')}
    for seed in range(50):
        d = simulate_measurements(prof, 30.0, errs, camera_interval=0.1,
                                  camera_sigma=CAMERA_SIGMA, seed=100 + seed)
        n = len(d.camera_stamps)
        disjoint = np.array([(a, a + 5) for a in range(0, n - 5, 6)])
        for key, kw in (('model', {'weighting': 'model'}),
                        ('residual_disjoint', {'weighting': 'residual', 'intervals': disjoint,
                                               'steps_per_interval': None}),
                        ('residual_consecutive', {'weighting': 'residual'})):
            r = _calibrate(d, **kw)
            out[key][0].append(r.x - d.x_true)
            out[key][1].append(r.sigma)
    ratios = {}
    for key, (e, s) in out.items():
        e, s = np.array(e), np.array(s)
        ratios[key] = np.sqrt((e ** 2).mean(0)) / np.sqrt((s ** 2).mean(0))
        print(key, 'RMS error / RMS σ:', np.round(ratios[key], 2))
    for key in ('model', 'residual_disjoint'):
        assert np.all(ratios[key] > 1 / 1.5) and np.all(ratios[key] < 1.5), (key, ratios[key])
    assert np.all(ratios['residual_consecutive'] < 0.8)


def test_constant_direction_is_flagged_unobservable():
    """
    Flag rates of one direction unobservable, the parameters named.

    Rates about body x only (six magnitudes): B·e_y and B·e_z (B12, B13, B22, B23, B32, B33)
    are unobservable; the rest is still estimated within 3σ.  One constant rate: B·e_x and s0
    cannot be told apart either (B_j1·ω + s0_j).
    """
    errs = gyro_errors()
    prof = PiecewiseRateProfile([Segment(5.0, [0.05 * (k + 1), 0.0, 0.0]) for k in range(6)],
                                initial_attitude=(0.64, 0.48, 0.36, -0.48))
    d = simulate_measurements(prof, 30.0, errs, camera_interval=0.1, camera_sigma=CAMERA_SIGMA,
                              seed=1)
    for weighting in ('model', 'residual'):
        r = _calibrate(d, weighting=weighting)
        assert not r.observable
        expected = ['B12', 'B13', 'B22', 'B23', 'B32', 'B33']
        assert sorted(r.unobservable_parameters) == expected, r.message
        assert len(r.observability.unobservable) == 6
        print(weighting, r.message)
        bad = np.isin(PARAMETER_LABELS, r.unobservable_parameters)
        assert np.all(np.isinf(r.sigma[bad])) and np.all(np.isfinite(r.sigma[~bad]))
        # unobservable parameters stay at the nominal B = I; the rest is estimated
        np.testing.assert_allclose(r.x[bad], np.eye(3).ravel()[bad[:9]], atol=1e-6)
        assert np.all(np.abs(r.x - d.x_true)[~bad] < 3 * r.sigma[~bad])
    const = PiecewiseRateProfile([Segment(30.0, [0.1, 0.0, 0.0])],
                                 initial_attitude=(0.64, 0.48, 0.36, -0.48))
    d = simulate_measurements(const, 30.0, errs, camera_interval=0.1, camera_sigma=CAMERA_SIGMA,
                              seed=1)
    r = _calibrate(d)
    assert not r.observable and len(r.observability.unobservable) == 9
    assert '+0.71·B11 -0.71·s0_1' in r.message, r.message
    assert np.all(np.isinf(r.sigma))


def test_too_few_intervals():
    """Fewer than 4 intervals are refused; exactly 4 solve with the model weighting only."""
    d = simulate_measurements(tkachenko_profile(), 30.0, gyro_errors(), camera_interval=1.0,
                              camera_sigma=CAMERA_SIGMA, seed=2)
    r = _calibrate(d, steps_per_interval=10)                  # 2 intervals of 10 s
    assert not r.observable and 'at least 4' in r.message
    # exactly 4 intervals (4 unknowns per axis): model weighting solves, residual weighting cannot
    # segments 1, 2, 4, 5 of the 000 table
    iv = np.array([[0, 2], [7, 9], [17, 19], [21, 23]])
    r4 = _calibrate(d, intervals=iv, steps_per_interval=None, weighting='model')
    assert r4.observable and r4.dof == 0, r4.message
    assert np.all(np.abs(r4.x - d.x_true) < 3 * r4.sigma)
    r4r = _calibrate(d, intervals=iv, steps_per_interval=None, weighting='residual')
    assert not r4r.observable and 'more than 4' in r4r.message


def test_camera_with_known_boresight():
    """
    Undo a known boresight and rotate the camera noise into body axes.

    Camera frame ≠ body: fixes q_ref_cam = q_ref_body ⊗ q_body_cam (004's anisotropic
    0.6″/0.6″/6″ σ).
    """
    prof = tkachenko_profile()
    errs = gyro_errors()
    cam = StarCameraModel(boresight=np.radians([30.0, -20.0, 50.0]), interval=0.1,
                          first_exposure=0.1, sigma=np.array([1e-5, 1e-5, 1e-4]), seed=5)
    t, meas, _ = IntegratingSensor(prof, 'gyro', 100.0, errs, seed=5).sample(3000)
    fixes = cam.fixes(prof, 299)
    r = calibrate_from_measurements(t, meas, [f.stamp for f in fixes],
                                    [f.attitude for f in fixes], cam.sigma,
                                    gyro_random_walk=ARW, steps_per_interval=5,
                                    q_body_camera=cam.q_mf_vf)
    x_true = np.concatenate([(np.eye(3) + M_TRUE).ravel(), BIAS])
    assert r.observable
    assert np.all(np.abs(r.x - x_true) < 3 * r.sigma)
    assert 0.6 < r.chi2_per_dof < 1.5


def test_integral_calibration_direct_interface():
    """The linear system alone (for other estimators that produce their own means)."""
    rng = np.random.default_rng(4)
    B = np.eye(3) + M_TRUE
    w = rng.normal(0.0, 0.2, (40, 3))
    s = w @ B.T + BIAS + rng.normal(0.0, 1e-6, (40, 3))
    r = integral_calibration(IntervalMeans(np.arange(40.0), np.arange(1.0, 41.0), w, s))
    assert r.weighting == 'residual' and r.observable
    assert np.all(np.abs(r.x - np.concatenate([B.ravel(), BIAS])) < 4 * r.sigma)
    np.testing.assert_allclose(r.sigma[9:], 1e-6 / np.sqrt(40), rtol=0.5)


def test_module_imports_without_ros():
    """The module imports without any ROS package."""
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    code = textwrap.dedent(f"""
        import importlib.abc, sys
        class Blocker(importlib.abc.MetaPathFinder):
            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] in ("rclpy", "geometry_msgs", "sensor_msgs", "std_msgs"):
                    raise ImportError(name)
        sys.meta_path.insert(0, Blocker())
        sys.path.insert(0, {repo!r})
        import strapdown_ros.calibration.integral_method as m
        print("ok", len(m.PARAMETER_LABELS))
    """)
    res = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0 and 'ok 12' in res.stdout, res.stderr
