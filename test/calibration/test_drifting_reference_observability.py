"""000 (Tkachenko 1983), observability: the rank tests of §3 and §4."""
import numpy as np

from strapdown_ros.calibration.drifting_reference_model import bias_D, ErrorStructure
from strapdown_ros.calibration.drifting_reference_observability import (rank_test,
                                                                        simple_case_test)
from strapdown_ros.motion.profiles import PiecewiseRateProfile, Segment, tkachenko_profile
from strapdown_ros.reproductions.tkachenko1983 import run_tkachenko_experiment


def _constant_direction_profile():
    u = np.array([0.3, 0.5, -0.2]) / np.linalg.norm([0.3, 0.5, -0.2])
    segments = [Segment(5, 0.05 * u), Segment(5, 0.2 * u), Segment(10, -0.1 * u),
                Segment(10, 0.15 * u)]
    return PiecewiseRateProfile(segments, initial_attitude=(0.64, 0.48, 0.36, -0.48))


def test_d_rank_test_flags_constant_rate_direction():
    """Rates of one direction fail (3.1), (4.1) and (4.2); the §6 table passes them."""
    t = np.arange(4.0, 30.001, 0.2)
    good, bad = tkachenko_profile(), _constant_direction_profile()
    r = rank_test(good.body_rate(t - 1e-9), good.attitude(t), t)
    assert r['observable'] and r['rank'] == 15
    biases_only = ErrorStructure(bias_D, 1)
    assert rank_test(good.body_rate(t - 1e-9), good.attitude(t), t, biases_only)['rank'] == 9
    rb = rank_test(bad.body_rate(t - 1e-9), bad.attitude(t), t)
    assert not rb['observable'] and rb['rank'] < 15
    # §4, m = n = 1: (4.1) and both sufficient conditions of (4.2)
    idx = [0, 30, 70, 110]
    sc = simple_case_test(good.body_rate(t[idx] - 1e-9), good.attitude(t[idx]))
    assert sc['condition_41'] and sc['sufficient']
    sb = simple_case_test(bad.body_rate(t[idx] - 1e-9), bad.attitude(t[idx]))
    assert not sb['condition_41'] and not sb['sufficient']
    # the normal matrix UᵀU through the shared observability module
    rep_bad = run_tkachenko_experiment(seed=None, profile=bad, full=True)['solution'].observability
    assert not rep_bad.observable and any('w0' in s for s in rep_bad.unobservable)
    rep_good = run_tkachenko_experiment(seed=None, full=True)['solution'].observability
    assert rep_good.observable
