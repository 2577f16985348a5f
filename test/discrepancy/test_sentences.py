"""
Every verdict sentence of ``discrepancy`` agrees with the numbers it states.

The sentences (:mod:`strapdown_ros.discrepancy.sentences`) are fed results built here with
chosen numbers, and each direction in words is checked against those numbers: a χ²/dof below
its band is never called "too small σ", a spread is never compared with itself, "fast motion"
only when the fast pairs carry the larger residual.  The repeatability statistics are checked
against exact linear-Gaussian draws (independent truth), and the report's files against the
umask.
"""
from dataclasses import replace
import os
import re
from types import SimpleNamespace

import numpy as np
import pytest

from strapdown_ros.discrepancy.repeatability import noise_repeatability, weighted_jackknife
from strapdown_ros.discrepancy.result import Step
from strapdown_ros.discrepancy.sentences import (boresight_sigma_sentence, consistency_warning,
                                                 remaining_sentences, repeatability_sentence,
                                                 sigma_sentence)


def _tests(failed, per_dof=1.0, lb_p=0.5):
    return {'failed': failed, 'level': 0.01 / 6,
            'nis': {'per_dof': per_dof, 'p_value': 1e-9 if 'nis' in failed else 0.5},
            'whiteness': {'p_value': lb_p}, 'outliers': {'statistic': 3.0, 'p_value': 0.5}}


def _res(**over):
    base = {'fit_consistent': True, 'chi2_per_dof': 1.0, 'chi2_per_dof_band': [0.8, 1.2],
            'sigma_method': 'model', 'hac_lags': None, 'tests_after': _tests([]), 'steps': [],
            'remaining': {}, 'verdict': 'explained', 'boresight_sigma_rad': [1e-4] * 3,
            'boresight_sigma_model_rad': [1e-4] * 3,
            'boresight_sigma_base_model_rad': [1e-4] * 3,
            'boresight_sigma_calibrate_bag_rule_rad': [1e-4] * 3, 'chi2_per_dof_base': 1.0}
    base.update(over)
    return SimpleNamespace(**base)


@pytest.mark.parametrize('chi2', [0.39, 1.96])
def test_consistency_warning_says_the_direction_of_its_chi2(chi2):
    """The warning calls the residuals smaller below the band, larger above it."""
    text = consistency_warning(_res(fit_consistent=False, chi2_per_dof=chi2))
    assert text.startswith('WARNING: the fit is not consistent with its stated noise')
    assert f'{chi2:.4g}' in text
    if chi2 < 0.8:
        assert 'smaller than' in text and 'pessimistic' in text and 'larger' not in text
    else:
        assert 'larger than' in text and 'smaller' not in text
    assert consistency_warning(_res()) is None


@pytest.mark.parametrize('failed, per_dof', [(['nis'], 0.39), (['nis'], 1.96),
                                             (['whiteness'], 1.0), (['nis', 'whiteness'], 0.39)])
def test_sigma_sentence_never_calls_a_pessimistic_sigma_too_small(failed, per_dof):
    """
    At χ²/dof 0.39 the model's σ are too large, not too small; correlation makes them too small.

    Parameters
    ----------
    failed : list of str
        The tests that fail.
    per_dof : float
        The final χ²/dof.

    """
    res = _res(sigma_method='hac', hac_lags=9, tests_after=_tests(failed, per_dof, 1e-6))
    text = sigma_sentence(res)
    assert 'Newey–West sandwich over 9 pairs' in text
    nis_part = [p for p in text.split(';') if 'χ²/dof' in p]
    if 'nis' in failed:
        assert len(nis_part) == 1 and f'{per_dof:.3g}' in nis_part[0]
        if per_dof < 1:
            assert 'pessimistic' in nis_part[0] and 'too small' not in nis_part[0]
        else:
            assert 'too small' in nis_part[0]
    if 'whiteness' in failed:
        assert 'correlated in time' in text and '1e-06' in text
    assert sigma_sentence(_res()) is None


def _step(repeatable=False, **over):
    s = Step('gyro_bias', {'gyro_bias': [1e-6, 2e-6, 3e-6]}, {'gyro_bias': [1e-7] * 3}, 50.0,
             1e-9, 0.5, 3, spread={'gyro_bias': [1e-7] * 3}, spread_ratio=3.44,
             repeatable=repeatable,
             repeatability={'statistic': 45.21, 'dof': 15, 'p_value': 7.3e-5, 'level': 0.00167,
                            'repeatable': repeatable, 'method': 'hac',
                            'blocks': [{'block': 1, 't_start_s': 0.0, 't_end_s': 50.0,
                                        'pairs': 25, 'statistic': 2.0, 'dof': 3,
                                        'p_value': 0.57, 'difference': [0.0, 0.0, 0.0],
                                        'difference_sigma': [1e-7] * 3},
                                       {'block': 4, 't_start_s': 150.0, 't_end_s': 200.0,
                                        'pairs': 25, 'statistic': 30.0, 'dof': 3,
                                        'p_value': 1e-6, 'difference': [5e-7, -4e-7, 1e-8],
                                        'difference_sigma': [1e-7, 1e-7, 1e-7]}]})
    return replace(s, **over)


def test_repeatability_sentence_states_its_test_not_a_spread_against_itself():
    """The sentence gives χ², dof, p and the block that departs most, from the numbers."""
    text = repeatability_sentence(_step())
    assert 'χ² 45.21 on 15 dof, p 7.3e-05 < 0.00167' in text
    assert 'block 4 (t 150.0–200.0 s) departs most' in text       # smallest p of the blocks
    assert '[5e-07, -4e-07, 1e-08] ± [1e-07, 1e-07, 1e-07]' in text
    assert '× the σ above' not in text and 'Newey–West' in text
    assert repeatability_sentence(_step(repeatable=True)) is None


def _remaining(ratio_fast, ratio_rev, nis=True):
    rm = {'whitened_ms_by_axis': [1.2, 4.0, 1.1], 'largest_axis': 1,
          'residual_rms_rad': [1e-5, 6e-5, 1e-5], 'expected_rms_rad': [1e-5, 3e-5, 1e-5],
          'autocorrelation_by_axis': [0.1, 0.2, 0.64], 'correlated_axis': 2,
          'dominant_period_s': 13.5,
          'fast_motion': {'rate_above_rad_s': np.radians(100.0), 'rate_below_rad_s': 0.1,
                          'ms_fast': 4.0 * ratio_fast, 'ms_slow': 4.0, 'ratio': ratio_fast},
          'reversals': {'pairs': 10, 'fraction': 0.2, 'ms_with': ratio_rev, 'ms_without': 1.0,
                        'ratio': ratio_rev}}
    steps = [_step(repeatable=False), replace(_step(repeatable=True), effect='time_offset')]
    failed = ['nis', 'whiteness'] if nis else ['whiteness']
    return _res(verdict='unexplained_structure', remaining=rm, steps=steps,
                sigma_method='hac', tests_after=_tests(failed, 4.0))


@pytest.mark.parametrize('fast, rev', [(4.0, 2.5), (0.25, 1.0), (1.1, 0.5)])
def test_what_is_left_is_said_as_its_numbers_say(fast, rev):
    """
    Size, axis, fast motion, reversals and the use of the effects follow the numbers.

    Parameters
    ----------
    fast : float
        Ratio of the fastest third's residual to the slowest third's.
    rev : float
        Ratio at reversals to elsewhere.

    """
    text = ' '.join(remaining_sentences(_remaining(fast, rev)))
    assert 'largest about VF y' in text and '12.4″' in text and '6.19″' in text
    if fast >= 1.5:
        assert 'during fast motion' in text and f'{fast:.2g}×' in text and '100°/s' in text
    elif fast <= 1 / 1.5:
        assert 'slow motion or rest' in text and f'{1 / fast:.2g}×' in text
    else:
        assert 'does not depend much on the rate' in text
    word = 'larger' if rev >= 1.5 else 'smaller' if rev <= 1 / 1.5 else 'about the same'
    assert f'{word} at reversals' in text and '10, 20%' in text
    assert 'time_offset repeats across the time blocks: usable' in text
    assert 'gyro_bias does not: do not use it as calibrated' in text
    only_white = ' '.join(remaining_sentences(_remaining(1.0, 1.0, nis=False)))
    assert 'about the size the model predicts' in only_white and 'about VF z' in only_white
    assert '0.64' in only_white and '13.5 s' in only_white
    assert '1.65″' in only_white                 # √0.64 × the RMS 2.06″ about VF z
    assert remaining_sentences(_res()) == []


def test_boresight_sigma_sentence_agrees_or_says_why():
    """Within 20 % of calibrate_bag's rule: agree; else the causes, each with its own ratio."""
    ok = boresight_sigma_sentence(_res(boresight_sigma_rad=[1.1e-4, 0.9e-4, 1e-4]))
    assert 'agree within 20%' in ok and '1.10, 0.90, 1.00' in ok
    res = _res(boresight_sigma_rad=[3e-4, 1e-4, 1e-4], boresight_sigma_model_rad=[1.5e-4] * 3,
               sigma_method='hac', tests_after=_tests(['whiteness']),
               steps=[replace(_step(repeatable=True), sigma_method='hac')])
    text = boresight_sigma_sentence(res)
    assert 'differ by more than 20%' in text and 'most about yaw' in text
    assert '1.50× that without' in text                  # the effects: 1.5e-4 / 1e-4
    assert '2.00× the model' in text                     # the sandwich: 3e-4 / 1.5e-4


def test_weighted_jackknife_is_unbiased_on_unequal_blocks():
    """
    Exact draws of block estimates with information 2 to 1000: E v = 1/I, the plain one is not.

    θ_k ~ N(0, 1/I_k), θ̂ = Σ I_k θ_k / I, θ₋ₖ the same without block k: the weighted
    jackknife variance averages to 1/I within 3 %, the plain one overstates it.
    """
    rng = np.random.default_rng(5)
    info = np.array([2.0, 3.0, 10.0, 1000.0, 2.0, 30.0])
    total = info.sum()
    th = rng.normal(size=(20000, 6)) / np.sqrt(info)
    full = th @ info / total
    wo = (full[:, None] * total - th * info) / (total - info)
    n = len(th)                                 # every draw a component of one call
    wo_info = np.tile((total - info)[:, None], (1, n))
    v = weighted_jackknife(wo.T, full, np.full(n, total), wo_info) ** 2
    assert np.mean(v) == pytest.approx(1.0 / total, rel=0.03)
    plain = 5.0 / 6.0 * np.sum((wo - wo.mean(axis=1, keepdims=True)) ** 2, axis=1)
    assert np.mean(plain) > 3.0 / total


def test_noise_repeatability_is_chi2_under_the_null_and_flags_a_step():
    """
    Leave-one-block-out fits of exact draws: the statistic has mean dof; a step is flagged.

    The same unequal blocks as above; under the null the mean statistic is the dof (5) within
    7 % and at most 2 % of draws are flagged at level 0.01; with block 3 shifted by 10 of its
    own σ every draw is flagged.
    """
    rng = np.random.default_rng(6)
    info = np.array([2.0, 3.0, 10.0, 1000.0, 2.0, 30.0])
    total = info.sum()
    spans = [(np.ones(2, dtype=bool), 0.0, 1.0)] * 6
    stats, flags = [], []
    for shift in (0.0, 10.0):
        for _ in range(1000 if shift == 0 else 30):
            th = rng.normal(size=6) / np.sqrt(info)
            th[2] += shift / np.sqrt(info[2])
            full = th @ info / total
            wo = (full * total - th * info) / (total - info)
            t = noise_repeatability([full], [1 / np.sqrt(total)], wo[:, None],
                                    1 / np.sqrt(total - info)[:, None], spans, 0.01)
            (stats if shift == 0 else flags).append(t['statistic'] if shift == 0
                                                    else not t['repeatable'])
            assert t['dof'] == 5
    assert np.mean(stats) == pytest.approx(5.0, rel=0.07)
    assert np.mean(np.array(stats) > 15.086) <= 0.02          # χ²(5) 99 % point
    assert all(flags)


def test_report_files_follow_the_umask_and_titles_fit(tmp_path):
    """
    The report's files get 0666 & ~umask; a long list of effects is wrapped, not cut.

    Parameters
    ----------
    tmp_path : fixture
        Temporary directory of the test.

    """
    from strapdown_ros.discrepancy.report import after_title, write_report
    from strapdown_ros.discrepancy.synthetic import simulate_recording
    from strapdown_ros.discrepancy.workflow import analyse, DiscrepancySettings
    from strapdown_ros.params import (check_all, IMU_SIM_PARAMS, model_and_settings,
                                      STAR_CAMERA_PARAMS)
    sc = {'profile': 'bench', 'gyro_rate': 50.0, 'camera_interval': 2.0, 'seed': 3,
          'boresight': [0.698, -0.436, 2.094]}
    rec = simulate_recording(check_all(IMU_SIM_PARAMS, sc), check_all(STAR_CAMERA_PARAMS, sc),
                             120.0)
    model, settings = model_and_settings('calibrator_node', {'gyro_rate': 50.0})
    res = analyse(rec, model, DiscrepancySettings.from_values({**settings, 'max_steps': 0}))
    res.steps = [replace(_step(), effect=e) for e in ('gyro_bias_drift', 'gyro_bias',
                                                      'gyro_scale_asymmetry', 'gyro_scale_factor',
                                                      'camera_noise_anisotropy')]
    old = os.umask(0o027)
    try:
        write_report(str(tmp_path / 'rep'), res, {**res.as_json(), 'input': {}})
    finally:
        os.umask(old)
    for f in (tmp_path / 'rep').iterdir():
        assert (f.stat().st_mode & 0o777) == 0o640, f
    title = after_title(res)
    assert all(len(line) <= 60 for line in title.splitlines())
    assert re.sub(r'\s+', ' ', title).endswith('camera_noise_anisotropy')


@pytest.mark.parametrize('white', [True, False])
def test_calibrate_bag_names_its_sigma_method_and_its_assumption(white):
    """
    calibrate_bag's σ sentence names the method and says whether independence holds.

    Parameters
    ----------
    white : bool
        Whether the Ljung–Box test of the whitened residuals passes.

    """
    from strapdown_ros.tools.calibrate_bag import sigma_note
    wt = {'p_value': 0.5 if white else 1e-6, 'level': 0.01, 'white': white}
    text = sigma_note({'sigma_method': 'model_scaled_sqrt_chi2', 'chi2_per_dof': 4.0,
                       'residual_whiteness': wt})
    assert 'model_scaled_sqrt_chi2' in text and '√(χ²/dof) = 2' in text
    if white:
        assert 'are white (Ljung–Box p 0.5 ≥ 0.01)' in text and 'too small' not in text
    else:
        assert 'correlated in time (Ljung–Box p 1e-06 < 0.01)' in text and 'too small' in text
    assert sigma_note({'sigma_method': None}) is None
