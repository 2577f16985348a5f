"""
boresight_bench: Monte Carlo of the 004 boresight estimator against the Cramér–Rao bound and OpenCV.

Scenario (004 §6 in spirit): a bench on the rotating Earth (50.45° N), 71 star-camera fixes
20.0013 s apart (70 increment pairs; the epochs fall at varied points inside the 5 ms gyro
intervals), 13 rotations of 10–15° about body x, y, z and two oblique axes (two of them
back to back), holds everywhere else; a 200 Hz integrating gyro with the 004 navigation-grade
errors (random constants M, b drawn per run, plus white noise), camera noise σ = (0.6″, 0.6″, 6″)
in VF axes (z = optical axis), true boresight β = (40°, −25°, 120°).

Per run: new gyro constants and noise, new camera noise; pairs by ``gyro_increment`` and
``camera_increment`` (checked once against ``BoresightCalibrator``); estimators

* ``weighted`` / ``unweighted``: ``solve_boresight`` (init='axes'), E_imu of the calibrator's
  ``random_constant`` model;
* ``weighted_004cov``: weighted with the 004 per-increment E_imu (``covariance_model='004'``);
* ``correlated_gls``: a bench-only reference, Gauss–Newton with the *full* covariance of the
  stacked residuals (adjacent pairs share a camera fix; the gyro constants are common to all
  pairs), started from the weighted estimate;
* OpenCV ``calibrateHandEye`` (Tsai, Park, Horaud, Andreff, Daniilidis) on absolute poses
  chained from the same increments.

Bounds: the exact Gaussian CRLB of the linearised model with the full noise covariance, and
the independent-pairs bound Σ H_nᵀ(Cᵀ E_imu,n C + E_avu,n)⁻¹ H_n (what the weighted estimator
assumes).  Also NEES of the published covariances, the timing of a warm-started
``BoresightCalibrator.solve()`` with 1000 pairs, plots and a markdown report.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

from strapdown_ros.bench.boresight_monte_carlo import (calibrator_check, convention_check,
                                                       monte_carlo, performance)
from strapdown_ros.bench.boresight_opencv import opencv_available
from strapdown_ros.bench.boresight_report import make_plots, write_report
from strapdown_ros.bench.boresight_scenario import (BETA_DEG, bounds, build_scenario,
                                                    CAMERA_SIGMA_ARCSEC, FIRST_EXPOSURE,
                                                    GYRO_RATE, INTERVAL, LATITUDE_DEG,
                                                    N_FIXES, ROTATION_TIME, ROTATIONS)
from strapdown_ros.bench.boresight_summary import findings, summarize
from strapdown_ros.cli import check_outputs, DIRECTORY, FILE, write_text
from strapdown_ros.sensors import ARCSEC


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog='boresight_bench', description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--runs', type=int, default=None,
                    help='Monte Carlo runs (default 200; ≥ 100 unless --quick)')
    ap.add_argument('--seed', type=int, default=2024)
    ap.add_argument('--json', help='write the figures to this JSON file')
    ap.add_argument('--plots', help='write PNG plots into this directory')
    ap.add_argument('--report', help='write a markdown report to this file')
    ap.add_argument('--quick', action='store_true', help='fewer runs and repeats (for tests)')
    ap.add_argument('--force', action='store_true', help='overwrite existing outputs')
    ap.add_argument('--perf-pairs', type=int, default=1000,
                    help='pairs accumulated for the timing of solve()')
    ap.add_argument(
        '--jobs', type=int, default=None,
        help='worker processes for the Monte Carlo (default: 2 cores at most; 1 with --quick)')
    args = ap.parse_args(argv)
    try:                                        # the output rule, before any work
        check_outputs([('--json', args.json, FILE), ('--report', args.report, FILE),
                       ('--plots', args.plots, DIRECTORY, ('boresight_errors.png',
                                                           'boresight_nees.png',
                                                           'boresight_ratios.png'))],
                      [], args.force)
    except ValueError as exc:
        print(f'boresight_bench: error: {exc}', file=sys.stderr)
        return 2
    runs = args.runs if args.runs is not None else (24 if args.quick else 200)
    if runs < 2 or (runs < 100 and not args.quick):
        ap.error(f'--runs must be >= 100 (or >= 2 with --quick), got {runs}')
    t_all = time.perf_counter()
    load0 = os.getloadavg()[0] if hasattr(os, 'getloadavg') else float('nan')
    command = 'python -m strapdown_ros.bench.boresight_bench ' + ' '.join(sys.argv[1:] if argv is
                                                                          None else argv)

    sc = build_scenario()
    bnd = bounds(sc)
    sc.Sigma = bnd['Sigma']
    sc.K_gyro = bnd['K_gyro']
    print(
        f'scenario: {sc.pairs_count} pairs, {len(sc.u)} gyro intervals,'
        f' {int(np.sum(sc.angles_deg > 0.5))} pairs > 0.5°, built in {sc.build_s:.1f} s'
    )
    cv_ok, cv_info = opencv_available()
    print(f'OpenCV hand-eye: {cv_info}')
    conv = convention_check(sc)
    print('noise-free convention check (total angle error, ″): ' +
          ', '.join(f'{k} {v:.1e}' if isinstance(v, float) else f'{k}: {v}'
                    for k, v in conv.items()))
    calc = calibrator_check(sc, args.seed + 99)
    print(
        f"calibrator check: pairs {calc['pairs_calibrator']}/{calc['pairs_bench']}, max ΔS_imu"
        f" diff {calc['max_dq_imu_diff_arcsec']:.1e}″, β diff"
        f" {np.max(np.abs(calc['beta_diff_arcsec'])):.1e}″, gyro draw vs IntegratingSensor"
        f" {calc['gyro_draw_vs_IntegratingSensor_max_abs']:.1e}"
    )
    jobs = args.jobs if args.jobs is not None else (
        1 if args.quick else max(1, min(2,
                                        os.cpu_count() or 1)))
    mc = monte_carlo(sc, runs, args.seed, jobs=jobs)
    perf = performance(args.perf_pairs, repeats=5 if args.quick else 15)
    sm = summarize(sc, bnd, mc, runs)

    print(
        f"\n{runs} runs in {mc['wall_s']:.1f} s on {jobs} process(es)"
        f" ({mc['wall_s'] / runs * 1e3:.0f} ms/run)"
    )
    print(f"{'bound':<34}{'σψ″':>9}{'σϑ″':>9}{'σγ″':>9}{'total″':>9}")
    for k, v in sm['crlb'].items():
        s = v['sigma_arcsec']
        print(f"{k:<34}{s[0]:9.3f}{s[1]:9.3f}{s[2]:9.3f}{v['total_angle_rms_arcsec']:9.3f}")
    print(
        f"\n{'estimator':<24}{'RMSψ″':>8}{'RMSϑ″':>8}{'RMSγ″':>8}{'total″':>8}  "
        f" {'eff. vs exact':<20}{'eff. vs indep.':<20}fails"
    )
    for k, v in sm['estimators'].items():
        if not v.get('rms_arcsec'):
            print(f"{k:<24}  all runs failed: {v['failures'][:1]}")
            continue
        r = v['rms_arcsec']
        ee = ' '.join(f'{x:5.2f}' for x in v['efficiency_vs_exact_crlb'])
        ei = ' '.join(f'{x:5.2f}' for x in v['efficiency_vs_independent_pairs_bound'])
        print(
            f"{k:<24}{r[0]:8.3f}{r[1]:8.3f}{r[2]:8.3f}{v['total_angle_rms_arcsec']:8.3f}  "
            f" {ee:<20}{ei:<20}{v['failure_count']}"
        )
    print(
        "\nerrors relative to the gyro triad's own frame exp([a×])·C (a = antisymmetric"
        ' misalignment of the run):'
    )
    for k, v in sm['estimators'].items():
        if v.get('rms_arcsec'):
            r = v['rms_vs_gyro_triad_frame_arcsec']
            print(
                f'  {k:<24}{r[0]:8.3f}{r[1]:8.3f}{r[2]:8.3f}   eff. vs CRLB without triad'
                ' rotation '
                + ' '.join(f'{x:5.2f}' for x in v['efficiency_vs_bound_without_triad_rotation'])
            )
    print('\nNEES means (95% band of the mean of χ²(3)):')
    for k, v in sm['nees'].items():
        print(f"  {k:<40}{v['mean']:8.3f}   [{v['band95'][0]:.3f}, {v['band95'][1]:.3f}]  "
              f"{'inside' if v['inside'] else 'OUTSIDE'}")
    wu = sm['weighted_vs_unweighted']
    print('weighting gain (unweighted/weighted RMS): ' +
          ', '.join(f'{x:.2f}' for x in wu['rms_ratio_unweighted_over_weighted']) +
          f"; total {wu['total_angle_ratio']:.2f}")
    acc = sm['acceptance']
    a1 = acc['weighted_rms_le_1.2_crlb']
    ac = acc['calibrator_rms_le_1.2_crlb']['vs_exact_crlb']
    print('acceptance calibrator (correlated) ≤ 1.2·√CRLB: exact ' +
          ', '.join(f'{x:.2f}' for x in ac['ratios']) + (' PASS' if ac['pass'] else ' FAIL') +
          f"; NEES {sm['nees']['calibrator.covariance_beta']['mean']:.2f}")
    if 'calibrator_le_best_opencv' in acc:
        a3 = acc['calibrator_le_best_opencv']
        print(f"acceptance calibrator ≤ best OpenCV ({a3['best_opencv']}): ratio per angle " +
              ', '.join(f'{x:.2f}' for x in a3['ratio_per_angle']) +
              f", total {a3['ratio_total_angle']:.2f}" + (' PASS' if a3['pass'] else ' FAIL'))
    print('acceptance weighted ≤ 1.2·√CRLB: exact ' +
          ', '.join(f'{x:.2f}' for x in a1['vs_exact_crlb']['ratios']) +
          (' PASS' if a1['vs_exact_crlb']['pass'] else ' FAIL') + ' (predicted ' +
          ', '.join(f'{x:.2f}' for x in a1['vs_exact_crlb']['predicted_ratios']) +
          (' PASS' if a1['vs_exact_crlb']['predicted_pass'] else ' FAIL') +
          '); independent-pairs ' +
          ', '.join(f'{x:.2f}' for x in a1['vs_independent_pairs_bound']['ratios']) +
          (' PASS' if a1['vs_independent_pairs_bound']['pass'] else ' FAIL'))
    if 'weighted_le_best_opencv' in acc:
        a2 = acc['weighted_le_best_opencv']
        print(f"acceptance weighted ≤ best OpenCV ({a2['best_opencv']}): ratio per angle " +
              ', '.join(f'{x:.2f}' for x in a2['ratio_per_angle']) +
              f", total {a2['ratio_total_angle']:.2f}" + (' PASS' if a2['pass'] else ' FAIL'))
    print(
        f"solve() warm start with {perf['pairs']} pairs: median {perf['warm_solve_ms_median']:.1f}"
        f" ms per update (max {perf['warm_solve_ms_max']:.1f}, iterations"
        f" {sorted(set(perf['warm_iterations']))}; cold {perf['cold_solve_ms']:.1f} ms); one pair"
        f" from 20 s of gyro data {perf['pair_formation_ms_median']:.1f} ms"
    )

    cfg = {
        'runs': runs, 'seed': args.seed, 'quick': args.quick, 'fixes': N_FIXES,
        'pairs': sc.pairs_count, 'interval_s': INTERVAL, 'first_exposure_s': FIRST_EXPOSURE,
        'gyro_rate_hz': GYRO_RATE, 'latitude_deg': LATITUDE_DEG, 'rotation_time_s': ROTATION_TIME,
        'rotations': [{'interval': i, 'axis': list(a), 'angle_deg': g} for i, a, g in ROTATIONS
                      ], 'pairs_above_0p5deg': int(np.sum(sc.angles_deg > 0.5)),
        'hold_angle_deg': float(np.median(sc.angles_deg[sc.angles_deg < 0.5])),
        'pair_angles_deg': sc.angles_deg.tolist(), 'beta_deg': list(BETA_DEG),
        'camera_sigma_arcsec': list(CAMERA_SIGMA_ARCSEC), 'gyro': {
            'bias_sigma': sc.gyro.bias_sigma, 'scale_sigma': sc.gyro.scale_sigma,
            'misalignment_sigma': sc.gyro.misalignment_sigma, 'random_walk': sc.gyro.random_walk
        }
    }
    res = {
        'command': command, 'config': cfg, 'opencv': {'available': cv_ok,
                                                      'info': cv_info}, 'convention_check': conv,
        'calibrator_check': calc, 'summary': sm, 'performance': perf, 'per_run_errors_arcsec': {
            k: np.round(v / ARCSEC, 4).tolist()
            for k, v in mc['errors'].items()
        }, 'timing': {'scenario_s': sc.build_s, 'monte_carlo_s': mc['wall_s'], 'jobs': jobs}
    }
    res['findings'] = findings(sm)
    plots = make_plots(sc, bnd, mc, sm, args.plots) if args.plots else []
    res['plots'] = plots
    res['timing']['total_s'] = time.perf_counter() - t_all
    res['timing']['load_average_1min'] = [
        load0, os.getloadavg()[0] if hasattr(os, 'getloadavg') else float('nan')
    ]
    res['timing']['cpu_count'] = os.cpu_count()
    if args.report:
        os.makedirs(os.path.dirname(os.path.abspath(args.report)), exist_ok=True)
        write_report(args.report, res, plots)
    if args.json:
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        write_text(args.json, json.dumps(res, indent=1, default=float))
    print(f"total {res['timing']['total_s']:.1f} s")
    return 0


if __name__ == '__main__':
    sys.exit(main())
