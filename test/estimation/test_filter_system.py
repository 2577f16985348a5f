"""
FilterSystem (the core of attitude_filter_node and filter_bag) and the live model check.

Against the package's gyro and camera simulators with injected effects (independent truth).
"""
import numpy as np
import pytest

from strapdown_ros.estimation.chi_square import chi2_sf
from strapdown_ros.estimation.filter_system import FilterSettings, FilterSystem
from strapdown_ros.estimation.model_check import ljung_box
from strapdown_ros.motion.profiles import PiecewiseRateProfile, Segment
from strapdown_ros.params import model_and_settings
from strapdown_ros.rotation import quat_conjugate, quat_multiply, quat_to_rotvec, rotvec_to_quat
from strapdown_ros.sensors import ARCSEC
from strapdown_ros.sensors.model import IntegratingSensor, SensorErrorModel
from strapdown_ros.sensors.star_camera import StarCameraModel

RATE = 50.0


def _motion():
    segs = []
    for axis, sign in ((0, 1), (1, 1), (2, 1), (0, -1), (1, -1), (2, -1)):
        w = np.zeros(3)
        w[axis] = sign * 0.05
        segs += [Segment(8.0, w), Segment(2.0)]
    return PiecewiseRateProfile(segs * 10, initial_attitude=rotvec_to_quat([0.2, -0.4, 0.9]))


def _run(scale, seconds=150, bias=(2e-6, -1e-6, 1.5e-6), augment='', seed=4, **extra):
    """Simulate Δθ at RATE Hz and a fix every second through FilterSystem (stamp order)."""
    profile = _motion()
    gyro = IntegratingSensor(profile, 'gyro', RATE,
                             SensorErrorModel(np.array(bias), np.array(scale), np.zeros((3, 3)),
                                              random_walk=2e-6), seed=seed)
    beta = np.array([100.0, -50.0, 30.0]) * ARCSEC
    cam = StarCameraModel(boresight=beta, interval=1.0, sigma=np.array([1.0, 1.0, 5.0]) * ARCSEC,
                          seed=seed + 1)
    # the augmented scale factor's prior is the model's gyro_scale_sigma
    model, settings = model_and_settings('attitude_filter_node', dict(
        gyro_rate=RATE, gyro_random_walk=2e-6, gyro_bias_sigma=1e-5, gyro_scale_sigma=1e-3,
        boresight=list(beta), augment=augment, output_period=0.5, initial_attitude_sigma=1e-4,
        **extra))
    sysf = FilterSystem(model, FilterSettings.from_values(settings))
    fixes = cam.fixes(profile, seconds)
    st, meas, _ = gyro.sample(int(seconds * RATE))
    k = 0
    for fx in fixes:
        while k < len(st) and st[k] <= fx.stamp + 1e-9:
            sysf.add_increments([int(round(st[k] * 1e9))], [meas[k]])
            k += 1
        sysf.add_fix(int(round(fx.stamp * 1e9)), fx.attitude, fx.covariance)
    sysf.process()
    return sysf, profile


def test_chi2_sf_and_ljung_box():
    """chi2_sf against tables, ljung_box of white noise against its χ² mean."""
    assert chi2_sf(3.0, 3) == pytest.approx(0.391625, abs=1e-6)      # tables: χ²(3) at 3.0
    assert chi2_sf(30.0, 10) == pytest.approx(8.5664e-4, rel=1e-3)
    rng = np.random.default_rng(0)
    q = [ljung_box(rng.normal(size=(200, 3)), 5) for _ in range(300)]
    assert np.mean(q) == pytest.approx(15.0, rel=0.1)                 # χ²(3·5) has mean 15


def test_matching_model_passes_and_estimates_attitude_and_bias():
    """Matching model passes and estimates attitude and bias."""
    sysf, profile = _run(scale=(0.0, 0.0, 0.0))
    out, fixes = sysf.take()
    f = sysf.filter
    assert sysf.counts['applied'] >= 140 and sysf.counts['gated'] == 0
    eps = quat_to_rotvec(quat_multiply(quat_conjugate(profile.attitude(f.time)), f.attitude))
    assert np.all(np.abs(eps) < 3 * f.sigma('attitude'))
    b = f.estimate('gyro_bias')
    assert np.all(np.abs(b - [2e-6, -1e-6, 1.5e-6]) < 3 * f.sigma('gyro_bias'))
    assert np.all(f.sigma('gyro_bias') < 5e-7)                        # really estimated
    assert sysf.check.windows > 50
    assert sysf.check.failed <= 0.05 * sysf.check.windows, sysf.check.last.text()
    assert fixes[-1].check_ok
    # outputs every 0.5 s of stamp time, the rate bias-compensated
    t = np.array([o.stamp_ns for o in out]) * 1e-9
    assert np.all(np.diff(t) > 0.45) and np.all(np.diff(t) < 0.55)


def test_unmodelled_scale_factor_is_named():
    # small enough that the gate keeps applying fixes; a 60-fix window spans both signs of the
    # rate about every axis (a one-sided window cannot tell a scale factor from its asymmetry)
    """Unmodelled scale factor is named."""
    sysf, _ = _run(scale=(1e-4, -1e-4, 1e-4), model_check_window=60)
    assert sysf.counts['gated'] < 10
    last = sysf.check.last
    assert not last.ok
    assert last.best_effect == 'gyro_scale_factor', last.text()
    assert last.best_p < 1e-6
    assert sysf.check.failed > 0.9 * sysf.check.windows
    assert 'innovations match gyro_scale_factor (p = ' in last.text()
    assert 'run discrepancy on a recording' in last.text()
    # the model is never changed by the check
    assert [e.name for e, _ in sysf.filter.layout.gyro] == ['gyro_bias']
    assert sysf.filter.layout.size == 6


def test_augmented_scale_factor_is_estimated_and_check_passes():
    """Augmented scale factor is estimated and check passes."""
    sf = np.array([1e-4, -1e-4, 1e-4])
    sysf, _ = _run(scale=sf, augment='gyro_scale_factor', seconds=200, model_check_window=60)
    f = sysf.filter
    assert np.all(np.abs(f.estimate('gyro_scale_factor') - sf) < 3 * f.sigma('gyro_scale_factor'))
    assert sysf.check.last.ok, sysf.check.last.text()


def test_fix_rules_drop_and_count():
    """Fix rules drop and count."""
    s = FilterSystem(*model_and_settings('attitude_filter_node', {'gyro_rate': RATE})[:1])
    assert s.offer_fix(10**9, [0.0, 0.0, 0.0, 0.0]) is None
    assert s.counts['dropped_zero_quaternion'] == 1
    s.offer_fix(2 * 10**9, [2.0, 0.0, 0.0, 0.0], -np.eye(3))
    assert s.counts['dropped_bad_covariance'] == 1
    s.offer_fix(3 * 10**9, [2.0, 0.0, 0.0, 0.0], np.zeros((3, 3)))
    assert s.counts['normalised'] == 1 and s.counts['covariance_substituted'] == 1
    assert s.filter is not None
    s.offer_gyro(3 * 10**9 + 20_000_000, (float('nan'), 0.0, 0.0))
    assert s.gyro_check.nan == 1


def _stream(rate=100.0, seconds=12.0, interval=1.0, seed=9):
    """Δθ at ``rate`` and a fix every ``interval`` s of a turning body (stamps in ns)."""
    profile = PiecewiseRateProfile([Segment(2.0, np.array([0.05, 0.0, 0.0])),
                                    Segment(2.0, np.array([0.0, 0.05, 0.0]))] * 4)
    gyro = IntegratingSensor(profile, 'gyro', rate, SensorErrorModel(random_walk=1e-6),
                             seed=seed)
    st, meas, _ = gyro.sample(int(seconds * rate))
    cam = StarCameraModel(interval=interval, sigma=np.array([1.0, 1.0, 5.0]) * ARCSEC,
                          seed=seed + 1)
    fixes = cam.fixes(profile, int(seconds / interval) - 1)
    return ([int(round(t * 1e9)) for t in st], meas,
            [(int(round(f.stamp * 1e9)), f.attitude, f.covariance) for f in fixes])


def _live(system, gyro_ns, meas, fixes, shift=None):
    """Feed a FilterSystem as the node does, in stamp order (``shift``: fix index → ns)."""
    k = 0
    for i, (ns, q, P) in enumerate(fixes):
        while k < len(gyro_ns) and gyro_ns[k] <= ns:
            system.offer_gyro(gyro_ns[k], tuple(meas[k]))
            k += 1
        system.offer_fix(ns + (shift or {}).get(i, 0), q, P)
    system.process()


def test_overflowing_fixes_are_dropped_and_counted_not_a_crash():
    """Issue 27, findings 1, 2, 5: x = w = 1e200, a 1e308 covariance, a singular one."""
    model, settings = model_and_settings('attitude_filter_node', {'gyro_rate': 100.0})
    s = FilterSystem(model, FilterSettings.from_values(settings))
    g, meas, fixes = _stream()
    hostile = {3: ([1e200, 1e200, 0.0, 0.0], None), 5: (fixes[5][1], np.eye(3) * 1e308),
               7: (fixes[7][1], np.diag([1e-6, 1e-6, 0.0])), 8: (fixes[8][1], np.eye(3) * -1.0)}
    k = 0
    for i, (ns, q, P) in enumerate(fixes):
        while k < len(g) and g[k] <= ns:
            s.offer_gyro(g[k], tuple(meas[k]))
            k += 1
        if i in hostile:                              # one more message at the same stamp
            assert s.offer_fix(ns - 1000, *hostile[i]) is None
        s.offer_fix(ns, q, P)
    s.process()
    c = s.counts
    assert (c['dropped_not_unit'], c['dropped_bad_covariance']) == (1, 3)
    assert s.fix_screen.bad_covariance_reasons == {'asymmetric': 0, 'not_positive_definite': 2,
                                                   'out_of_bounds': 1}
    assert c['applied'] == len(fixes) - 1 and c['restarts'] == 0 and c['gated'] == 0


def test_gaps_come_from_the_stamps_not_gyro_rate():
    """Issue 27, finding 7: a 100 Hz stream under gyro_rate 200 (live) or 50 (offline)."""
    g, meas, fixes = _stream()
    for rate in (200.0, 50.0):
        model, settings = model_and_settings('attitude_filter_node', {'gyro_rate': rate})
        s = FilterSystem(model, FilterSettings.from_values(settings))
        _live(s, g, meas, fixes)
        assert (s.counts['gaps'], s.counts['restarts'], s.gyro_check.gaps) == (0, 0, 0), rate
        assert s.counts['applied'] == len(fixes) - 1
        t = FilterSystem(model, FilterSettings.from_values(settings))
        k = 0
        for ns, q, P in fixes:                        # the tool's path, without the reader
            j = int(np.searchsorted(g, ns, side='right'))
            t.add_increments(g[k:j], meas[k:j])
            k = j
            t.add_fix(ns, q, P)
        assert (t.counts['gaps'], t.counts['restarts']) == (0, 0)
        t.add_increments([g[-1] + 30_000_000], [meas[-1]])       # 2 increments missing
        assert t.counts['gaps'] == 1


def test_a_future_fix_is_an_outlier_and_a_clock_step_restarts_once():
    """Issue 27, finding 10: one fix 100 s ahead blinds nothing; both clocks step back 100 s."""
    model, settings = model_and_settings('attitude_filter_node', {'gyro_rate': 100.0})
    g, meas, fixes = _stream()
    s = FilterSystem(model, FilterSettings.from_values(settings))
    _live(s, g, meas, fixes, shift={5: 100 * 10**9})
    assert s.camera_check.stamp_outliers == 1 and s.counts['camera_resyncs'] == 0
    assert s.counts['applied'] == len(fixes) - 2 and s.counts['restarts'] == 0
    s = FilterSystem(model, FilterSettings.from_values(settings))
    step = 100 * 10**9                                # both clocks back 100 s after fix 5
    k = 0
    for i, (ns, q, P) in enumerate(fixes):            # received in time order, stamped back
        while k < len(g) and g[k] <= ns:
            s.offer_gyro(g[k] - (step if g[k] > fixes[5][0] else 0), tuple(meas[k]))
            k += 1
        s.offer_fix(ns - (step if i > 5 else 0), q, P)
    s.process()
    assert s.gyro_check.resyncs == 1 and s.camera_check.resyncs == 1
    assert s.filter is not None and s.counts['camera_resyncs'] == 1
    # the first fix on the gyro's new timeline confirms the step and restarts the filter:
    # every later fix is applied
    assert s.counts['applied'] == len(fixes) - 2 and s.counts['restarts'] == 1, s.counts


def test_output_rate_is_the_mean_since_the_previous_output_whatever_the_chunks():
    """The rate of each output: Σ Δθ / Σ h since the previous output, less the bias estimate."""
    g, meas, fixes = _stream(seconds=8.0)
    model, settings = model_and_settings('attitude_filter_node', {'gyro_rate': 100.0,
                                                                  'output_period': 0.3})
    runs = []
    for chunk in (1, 7, 10_000):                  # increments per call: live, odd, whole
        s = FilterSystem(model, FilterSettings.from_values(settings))
        k = 0
        for ns, q, P in fixes:
            j = int(np.searchsorted(g, ns, side='right'))
            for a in range(k, j, chunk):
                s.add_increments(g[a:min(j, a + chunk)], meas[a:min(j, a + chunk)])
            k = j
            s.add_fix(ns, q, P)
        s.process()
        runs.append(s.outputs)
    outs = runs[0]
    assert len(outs) >= 20 and all(len(r) == len(outs) for r in runs)
    g = np.asarray(g)
    for prev, o in zip(outs[:-1], outs[1:]):
        inside = (g > prev.stamp_ns) & (g <= o.stamp_ns)
        truth = meas[inside].sum(0) / ((o.stamp_ns - prev.stamp_ns) * 1e-9) - o.bias
        for r in runs:
            same = next(x for x in r if x.stamp_ns == o.stamp_ns)
            np.testing.assert_allclose(same.rate, truth, rtol=1e-9, atol=1e-15)
