"""
The attitude filter's divergence rule: no silent lock-out, a stated reset, the bias kept.

Truth is injected: the package's gyro and camera simulators, with a glitch of the gyro part way
through (one increment carries a rotation that did not happen, so every fix after it disagrees
with the filter far beyond the gate), or fixes whose stated σ is ten times too small.
"""
import numpy as np

from strapdown_ros.estimation.filter_system import FilterSettings, FilterSystem
from strapdown_ros.motion.profiles import PiecewiseRateProfile, Segment
from strapdown_ros.params import model_and_settings
from strapdown_ros.rotation import quat_conjugate, quat_multiply, quat_to_rotvec, rotvec_to_quat
from strapdown_ros.sensors import ARCSEC
from strapdown_ros.sensors.model import IntegratingSensor, SensorErrorModel
from strapdown_ros.sensors.star_camera import StarCameraModel

RATE = 50.0
BIAS = np.array([2e-6, -1e-6, 1.5e-6])
BETA = np.array([100.0, -50.0, 30.0]) * ARCSEC
SIGMA = np.array([1.0, 1.0, 5.0]) * ARCSEC
GLITCH = np.radians([0.3, -0.2, 0.1])           # a rotation the gyro reports falsely, rad
GLITCH_AT = 40.0                                 # s


def _filtered(seconds=80, glitch=True, sigma_scale=1.0, **settings):
    """Run FilterSystem on simulated Δθ at RATE Hz and a fix every second (stamp order)."""
    segs = [Segment(6.0, w) for w in np.eye(3) * 0.05] + [Segment(2.0)]
    profile = PiecewiseRateProfile(segs * 10, initial_attitude=rotvec_to_quat([0.2, -0.4, 0.9]))
    gyro = IntegratingSensor(profile, 'gyro', RATE,
                             SensorErrorModel(BIAS, np.zeros(3), np.zeros((3, 3)),
                                              random_walk=2e-6), seed=3)
    cam = StarCameraModel(boresight=BETA, interval=1.0, sigma=SIGMA, seed=5)
    model, s = model_and_settings('attitude_filter_node', dict(
        gyro_rate=RATE, gyro_random_walk=2e-6, gyro_bias_sigma=1e-5, boresight=list(BETA),
        output_period=0.5, initial_attitude_sigma=1e-3, **settings))
    f = FilterSystem(model, FilterSettings.from_values(s))
    st, meas, _ = gyro.sample(int(seconds * RATE))
    if glitch:
        meas[int(np.searchsorted(st, GLITCH_AT))] += GLITCH
    st_ns = np.round(st * 1e9).astype(np.int64)
    k = 0
    for fx in cam.fixes(profile, seconds):
        j = int(np.searchsorted(st_ns, round(fx.stamp * 1e9), side='right'))
        f.add_increments(st_ns[k:j], meas[k:j])
        k = j
        f.add_fix(int(round(fx.stamp * 1e9)), fx.attitude, fx.covariance * sigma_scale ** 2)
    f.process()
    out, fixes = f.take()
    return f, profile, out, fixes


def test_a_gyro_glitch_resets_the_attitude_once_and_fixes_apply_again():
    """
    Five consecutive gated fixes declare divergence; the fix re-initialises the attitude.

    After the reset the attitude is the camera's (within its noise, against the exact motion),
    the bias estimate is exactly the one before the reset, and every later fix is applied.
    """
    f, profile, out, fixes = _filtered()
    status = [x.status for x in fixes]
    k = status.index('reset')
    assert status[k - 4:k] == ['gated'] * 4 and set(status[k + 1:]) == {'applied'}
    assert status[:k - 4].count('gated') == 0
    assert f.counts['reset'] == 1 and len(f.resets) == 1
    assert '5 consecutive fixes gated' in f.resets[0][1] == fixes[k].reason
    t_reset = fixes[k].stamp_ns
    assert abs(t_reset * 1e-9 - (GLITCH_AT + 5.0)) < 1.01      # the fifth fix after it
    before = [o for o in out if o.stamp_ns < t_reset][-1]
    after = [o for o in out if t_reset < o.stamp_ns < t_reset + 10 ** 9][0]
    np.testing.assert_array_equal(after.bias, before.bias)     # kept, not re-initialised
    np.testing.assert_allclose(np.sqrt(np.diag(after.attitude_covariance)), 1e-3, rtol=0.01)
    # the attitude at the reset is the camera's: against the exact motion, within its noise
    t = after.stamp_ns * 1e-9
    eps = quat_to_rotvec(quat_multiply(quat_conjugate(profile.attitude(t)), after.attitude))
    assert np.linalg.norm(eps) < 6 * np.linalg.norm(SIGMA), eps
    eps = quat_to_rotvec(quat_multiply(quat_conjugate(profile.attitude(f.filter.time)),
                                       f.filter.attitude))
    assert np.all(np.abs(eps) < 3 * f.filter.sigma('attitude')), eps
    assert np.all(np.abs(f.filter.estimate('gyro_bias') - BIAS) < 3 * f.filter.sigma('gyro_bias'))


def test_without_the_rule_the_filter_locks_out_silently():
    """The same run with both rules off: every fix after the glitch is gated (the lock-out)."""
    f, _, _, fixes = _filtered(divergence_gated_fixes=0, divergence_nis_window=0)
    after = [x.status for x in fixes if x.stamp_ns * 1e-9 > GLITCH_AT + 0.5]
    assert set(after) == {'gated'} and f.counts['reset'] == 0


def test_stated_sigma_ten_times_too_small_keeps_applying_fixes():
    """
    Fixes with σ ten times smaller than their noise: resets, and fixes applied to the end.

    Without the rule the filter gates nearly every fix after its first few.
    """
    f, _, _, fixes = _filtered(seconds=60, glitch=False, sigma_scale=0.1)
    applied = [x.stamp_ns * 1e-9 for x in fixes if x.status == 'applied']
    assert f.counts['reset'] >= 3
    assert sum(t > 30.0 for t in applied) >= 4                 # still applying in the 2nd half
    g, _, _, _ = _filtered(seconds=60, glitch=False, sigma_scale=0.1, divergence_gated_fixes=0,
                           divergence_nis_window=0)
    assert g.counts['applied'] < f.counts['applied'] and g.counts['reset'] == 0


def test_a_consistent_filter_never_declares_divergence():
    """The matching model: no reset over the run, every fix applied."""
    f, _, _, fixes = _filtered(glitch=False)
    assert f.counts['reset'] == 0 and {x.status for x in fixes} == {'applied'}
