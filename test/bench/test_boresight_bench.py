"""boresight_bench at reduced size: schema, bounds, estimator sanity, OpenCV entries, timing."""

import json
import math

import numpy as np
import pytest

from strapdown_ros.bench import boresight_bench
from strapdown_ros.bench.boresight_opencv import OPENCV_METHODS

ESTIMATORS = ('weighted', 'unweighted', 'weighted_004cov', 'correlated_gls')
OPENCV = tuple(f'opencv_{m}' for m in OPENCV_METHODS)
NEES = ('weighted.covariance_beta', 'weighted.covariance_beta_model',
        'weighted.covariance_beta_residual', 'unweighted.covariance_beta', 'correlated_gls.model')


@pytest.fixture(scope='module')
def bench(tmp_path_factory):
    """Run boresight_bench once with 12 runs; the output directory and its JSON."""
    pytest.importorskip('scipy')
    d = tmp_path_factory.mktemp('boresight')
    f = d / 'b.json'
    assert boresight_bench.main(
        ['--quick', '--runs', '12', '--json',
         str(f), '--report',
         str(d / 'b.md')]) == 0
    return d, json.loads(f.read_text())


def _finite(xs, n=3):
    return isinstance(xs, list) and len(xs) == n and all(
        isinstance(x, float) and math.isfinite(x) for x in xs)


def test_schema_and_config(bench):
    """The JSON has every section and the configuration of the scenario."""
    _, res = bench
    for key in ('command', 'config', 'opencv', 'convention_check', 'calibrator_check', 'summary',
                'performance', 'per_run_errors_arcsec', 'timing', 'findings'):
        assert key in res, key
    cfg = res['config']
    assert cfg['runs'] == 12 and cfg['pairs'] == cfg['fixes'] - 1 >= 60
    assert cfg['pairs_above_0p5deg'] >= 10 and cfg['hold_angle_deg'] < 0.5
    for k in ESTIMATORS + OPENCV:
        assert k in res['summary']['estimators'], k
        assert len(res['per_run_errors_arcsec'][k]) == 12


def test_bounds_are_positive_and_decompose(bench):
    """The bounds are positive; exact = triad floor + the rest."""
    _, res = bench
    cr = res['summary']['crlb']
    for k in ('exact', 'independent_pairs', 'without_triad_rotation', 'triad_rotation_floor',
              'white_gyro_only'):
        assert _finite(cr[k]['sigma_arcsec']) and min(cr[k]['sigma_arcsec']) > 0, k
    # the triad rotation (antisymmetric gyro misalignment) is exactly unobservable: it adds to
    # the bound
    ex = np.array(cr['exact']['covariance_rad2'])
    parts = np.array(cr['without_triad_rotation']['covariance_rad2']) + np.array(
        cr['triad_rotation_floor']['covariance_rad2'])
    np.testing.assert_allclose(np.diag(parts), np.diag(ex), rtol=1e-3)
    # sub-arcsecond camera across the axis, 6″ about it: the bound is a few arc seconds
    assert all(0.3 < s < 20 for s in cr['exact']['sigma_arcsec'])


def test_estimators_are_sane(bench):
    """Every estimator converges, weighting helps, NEES means are finite."""
    _, res = bench
    est = res['summary']['estimators']
    for k in ESTIMATORS:
        e = est[k]
        assert e['runs_ok'] == 12 and e['failure_count'] == 0, (k, e['failures'])
        for f in ('rms_arcsec', 'efficiency_vs_exact_crlb',
                  'efficiency_vs_independent_pairs_bound', 'rms_vs_gyro_triad_frame_arcsec',
                  'rms_vf_axes_arcsec'):
            assert _finite(e[f]), (k, f)
    assert est['weighted']['total_angle_rms_arcsec'] < est['unweighted']['total_angle_rms_arcsec']
    assert max(est['weighted']['efficiency_vs_exact_crlb']) < 2.0        # loose: 12 runs
    wu = res['summary']['weighted_vs_unweighted']
    assert _finite(wu['rms_ratio_unweighted_over_weighted'])
    for k in NEES:
        n = res['summary']['nees'][k]
        assert math.isfinite(
            n['mean']) and n['runs'] == 12 and n['band95'][0] < 3 < n['band95'][1], k
    nm = res['summary']['noise_model_check']
    assert nm['E_imu_calibrator_vs_linear_model_max_rel_diff'] < 1e-3
    assert 0.8 < nm['residual_at_truth_normalised_full_sigma_mean'] < 1.2


def test_pipeline_checks(bench):
    """Noise-free estimates are exact; the bench agrees with the calibrator."""
    _, res = bench
    conv = res['convention_check']
    assert conv['weighted'] < 1e-6 and conv['unweighted'] < 1e-6          # arc seconds, noise-free
    cc = res['calibrator_check']
    assert cc['pairs_calibrator'] == cc['pairs_bench']
    assert cc['max_dq_imu_diff_arcsec'] < 1e-6 and max(abs(x)
                                                       for x in cc['beta_diff_arcsec']) < 1e-2
    assert cc['gyro_draw_vs_IntegratingSensor_max_abs'] == 0.0


def test_opencv_methods_present(bench):
    """The OpenCV methods give answers, or every run says why not."""
    _, res = bench
    est = res['summary']['estimators']
    if res['opencv']['available']:
        for m in ('opencv_TSAI', 'opencv_PARK', 'opencv_HORAUD'):
            assert est[m]['runs_ok'] == 12 and _finite(est[m]['rms_arcsec']), m
            assert res['convention_check'][m] < 1e-6, m
        assert 'weighted_le_best_opencv' in res['summary']['acceptance']
    else:                                       # e.g. opencv-python 5.0.0 lacks calibrateHandEye
        for m in OPENCV:
            why = est[m]['failures'][0]
            assert est[m]['failure_count'] == 12 and ('calibrateHandEye' in why or
                                                      'OpenCV' in why), m


def test_performance_and_report(bench):
    """The solve() timing is recorded and the report has its sections."""
    d, res = bench
    pf = res['performance']
    assert pf['pairs'] == 1000 and pf['warm_solve_ms_median'] > 0 and len(
        pf['warm_iterations']) == pf['repeats']
    text = (d / 'b.md').read_text()
    for needle in ('## Bounds', '## Estimators over the Monte Carlo runs', '## Acceptance checks',
                   '## Covariance consistency (NEES)', '## OpenCV hand-eye', '## Performance'):
        assert needle in text, needle


def test_full_run_needs_100_runs():
    """Fewer than 100 runs without --quick is refused."""
    with pytest.raises(SystemExit):
        boresight_bench.main(['--runs', '12'])
