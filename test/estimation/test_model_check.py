"""
The live model check: WARN episodes, its verdicts, and the naming of an injected effect.

Against injected innovations (bursts, a misstated noise) and against the package's gyro and
camera simulators with one injected effect under three-axis motion (independent truth: the
effect injected).
"""
import numpy as np

from strapdown_ros.estimation.filter_system import FilterSettings, FilterSystem
from strapdown_ros.estimation.model_check import check_candidates, ModelCheck
from strapdown_ros.motion.profiles import PiecewiseRateProfile, Segment
from strapdown_ros.params import model_and_settings
from strapdown_ros.rotation import rotvec_to_quat
from strapdown_ros.sensors import ARCSEC
from strapdown_ros.sensors.effects import CANDIDATES, GyroEffects
from strapdown_ros.sensors.model import IntegratingSensor, SensorErrorModel
from strapdown_ros.sensors.star_camera import StarCameraModel

RATE = 50.0
EYE = np.eye(3)


def _feed(chk, z, scale=1.0, t0=0.0):
    out = []
    for k, zk in enumerate(z):
        out.append(chk.add(t0 + k, zk, scale ** 2 * EYE, EYE, np.zeros(3)))
    return out


def test_an_episode_counts_once_and_ends_after_a_full_passing_window():
    """A burst of 3 bad fixes: one episode, WARN until N windows in a row pass."""
    rng = np.random.default_rng(2)
    chk = ModelCheck(window=30, alpha=1e-7, false_alarms_per_hour=0.0)
    z = rng.standard_normal((200, 3))
    z[80:83] = 12.0                                         # NIS 432 each
    res = _feed(chk, z)
    ok = np.array([r.ok for r in res])
    window_ok = np.array([r.window_ok for r in res])
    assert chk.episodes == 1
    # the windows holding fix 80, 81 or 82 fail: those ending at 80..111
    assert not window_ok[80:112].any() and window_ok[112:].all() and window_ok[29:80].all()
    # WARN from the first failing window until 30 windows in a row pass (112..141)
    assert not ok[80:141].any() and ok[141:].all() and ok[:80].all()
    assert res[120].verdict == 'consistent' and 'WARN episode 1 holds' in res[120].text()


def test_stated_noise_too_large_names_no_effect():
    """Innovations at half their stated σ: 'stated noise too large', no effect named."""
    rng = np.random.default_rng(3)
    effects, offset = check_candidates()
    chk = ModelCheck(window=30, effects=effects, time_offset=offset)
    res = _feed(chk, 0.5 * rng.standard_normal((40, 3)))[-1]
    assert not res.window_ok and res.verdict == 'noise_too_large'
    assert res.best_effect is None and 'stated noise too large' in res.text()


def test_white_innovations_too_large_name_the_noise_effect():
    """White innovations at twice their stated σ: stated noise too small, the library's noise."""
    rng = np.random.default_rng(4)
    chk = ModelCheck(window=30, time_offset=True)
    res = _feed(chk, 2.0 * rng.standard_normal((40, 3)))[-1]
    assert not res.window_ok and res.verdict == 'noise_too_small'
    assert res.best_effect == 'camera_noise_anisotropy' in CANDIDATES


def test_candidates_are_library_effects_outside_the_filter():
    """Only effects of the library; none the filter carries; never the bias or a periodic bias."""
    effects, offset = check_candidates()
    names = [e.name for e in effects]
    assert set(names) <= set(CANDIDATES) and offset
    assert 'gyro_bias_periodic' not in names and 'gyro_bias' not in names
    assert set(names) == {'gyro_bias_drift', 'gyro_scale_factor', 'gyro_scale_asymmetry',
                          'gyro_misalignment'}
    effects, offset = check_candidates(('gyro_scale_factor', 'time_offset'))
    assert 'gyro_scale_factor' not in [e.name for e in effects] and not offset


#: the divergence rules off: the check alone, on a filter that never resets
NO_RESETS = {'divergence_gated_fixes': 0, 'divergence_nis_window': 0}


def _run(seconds=100, offset=0.0, asymmetry=(0.0, 0.0, 0.0), seed=4, extra=NO_RESETS,
         counts=None):
    """Three-axis piecewise motion (4-s segments, rates ±0.05 rad/s) through FilterSystem."""
    rng = np.random.default_rng(3)
    profile = PiecewiseRateProfile([Segment(4.0, rng.uniform(-0.05, 0.05, 3))
                                    for _ in range(int(seconds / 4) + 2)],
                                   initial_attitude=rotvec_to_quat([0.2, -0.4, 0.9]))
    eff = GyroEffects(values={'gyro_scale_asymmetry': np.asarray(asymmetry, dtype=float)},
                      epoch=1.0 / RATE)
    gyro = IntegratingSensor(profile, 'gyro', RATE,
                             SensorErrorModel(np.array([2e-6, -1e-6, 1.5e-6]), np.zeros(3),
                                              np.zeros((3, 3)), random_walk=2e-6),
                             seed=seed, effects=eff)
    cam = StarCameraModel(interval=1.0, sigma=np.array([1.0, 1.0, 5.0]) * ARCSEC,
                          seed=seed + 1, time_offset=offset)
    model, settings = model_and_settings('attitude_filter_node', {
        'gyro_rate': RATE, 'gyro_random_walk': 2e-6, 'gyro_bias_sigma': 1e-5,
        'output_period': 0.5, 'initial_attitude_sigma': 1e-4, **extra})
    sysf = FilterSystem(model, FilterSettings.from_values(settings))
    st, meas, _ = gyro.sample(int(seconds * RATE))
    ns = np.round(st * 1e9).astype(np.int64)
    k = 0
    for fx in cam.fixes(profile, int(seconds)):
        j = int(np.searchsorted(st, fx.stamp + 1e-9, side='right'))
        if j > k:
            sysf.add_increments(ns[k:j], meas[k:j])
            k = j
        sysf.add_fix(int(round(fx.stamp * 1e9)), fx.attitude, fx.covariance)
    sysf.process()
    if counts is not None:
        counts.update(sysf.status())
    return [f.check for f in sysf.take()[1] if f.check is not None and not f.check.window_ok]


def test_time_offset_and_scale_asymmetry_are_told_apart():
    """A 5 ms camera offset and a scale asymmetry, each alone: every failing window names it."""
    failing = _run(offset=0.005)
    assert len(failing) >= 50
    assert all(c.best_effect == 'time_offset' for c in failing), \
        {c.best_effect for c in failing}
    est = np.median([c.best_estimate[0] for c in failing])
    assert abs(est - 0.005) < 0.001                        # its value, s
    failing = _run(asymmetry=(3e-4, 3e-4, -3e-4))
    assert len(failing) >= 30
    assert all(c.best_effect == 'gyro_scale_asymmetry' for c in failing), \
        {c.best_effect for c in failing}


def test_the_effect_is_still_named_when_it_makes_the_filter_diverge():
    """
    A 5 ms camera offset gates fix after fix: divergence resets, and the check still names it.

    The reset restarts the effects' attitude responses (:meth:`ModelCheck.restart`), not the
    window: the failing windows name the offset, its value within 1 ms.
    """
    counts = {}
    failing = _run(offset=0.005, extra={}, counts=counts)
    assert counts['reset'] >= 5
    assert len(failing) >= 40
    assert all(c.best_effect == 'time_offset' for c in failing), \
        {c.best_effect for c in failing}
    assert abs(np.median([c.best_estimate[0] for c in failing]) - 0.005) < 0.001
