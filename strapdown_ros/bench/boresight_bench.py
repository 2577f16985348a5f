"""
Benchmark the boresight calibration (Vasilyuk et al. 2024, 004) against its bound and OpenCV.

A Monte Carlo of the package's boresight estimators against the Cramér–Rao bound and the
OpenCV hand-eye methods; the command ``boresight_bench``.  The modules beside it hold the
scenario and bounds, the OpenCV peers, the Monte Carlo, its summary and the report.

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
from strapdown_ros.bench.boresight_report import (make_plots, PLOT_FILES, print_checks,
                                                  print_summary, write_report)
from strapdown_ros.bench.boresight_scenario import (BETA_DEG, bounds, build_scenario,
                                                    CAMERA_SIGMA_ARCSEC, FIRST_EXPOSURE,
                                                    GYRO_RATE, INTERVAL, LATITUDE_DEG,
                                                    N_FIXES, ROTATION_TIME, ROTATIONS)
from strapdown_ros.bench.boresight_summary import conclusions, summarize
from strapdown_ros.cli import check_outputs, DIRECTORY, FILE, write_text
from strapdown_ros.sensors import ARCSEC


def parse_args(argv=None) -> argparse.Namespace:
    """
    Parse the command line of ``boresight_bench``.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name; ``sys.argv[1:]`` when None.

    Returns
    -------
    argparse.Namespace
        The options; ``runs`` resolved to its default (200, or 24 with ``--quick``).

    """
    ap = argparse.ArgumentParser(prog='boresight_bench', description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--runs', type=int, default=None,
                    help='Monte Carlo runs (default 200; ≥ 100 unless --quick)')
    ap.add_argument('--seed', type=int, default=2024)
    ap.add_argument('--json', help='write the figures to this JSON file '
                    '(documented run: doc/results/boresight_bench/boresight_bench.json)')
    ap.add_argument('--plots', help='write PNG plots into this directory '
                    '(documented run: doc/results/boresight_bench)')
    ap.add_argument('--report', help='write a markdown report to this file '
                    '(documented run: doc/results/boresight_bench/boresight_bench.md)')
    ap.add_argument('--quick', action='store_true', help='fewer runs and repeats (for tests)')
    ap.add_argument('--force', action='store_true', help='overwrite existing outputs')
    ap.add_argument('--perf-pairs', type=int, default=1000,
                    help='pairs accumulated for the timing of solve()')
    ap.add_argument('--jobs', type=int, default=None,
                    help='Dask LocalCluster workers for the Monte Carlo; 1 runs it in this '
                    'process (default: 2 cores at most; 1 with --quick)')
    ap.add_argument('--scheduler', metavar='ADDRESS',
                    help='run the Monte Carlo on a running Dask scheduler, e.g. '
                    'tcp://host:8786 (default: a LocalCluster of --jobs)')
    args = ap.parse_args(argv)
    args.runs = args.runs if args.runs is not None else (24 if args.quick else 200)
    if args.runs < 2 or (args.runs < 100 and not args.quick):
        ap.error(f'--runs must be >= 100 (or >= 2 with --quick), got {args.runs}')
    return args


def _config(args, sc) -> dict:
    """Return the configuration block of the JSON result."""
    gyro = sc.gyro
    return {
        'runs': args.runs, 'seed': args.seed, 'quick': args.quick,
        'fixes': N_FIXES, 'pairs': sc.pairs_count, 'interval_s': INTERVAL,
        'first_exposure_s': FIRST_EXPOSURE, 'gyro_rate_hz': GYRO_RATE,
        'latitude_deg': LATITUDE_DEG, 'rotation_time_s': ROTATION_TIME,
        'rotations': [{'interval': i, 'axis': list(a), 'angle_deg': g}
                      for i, a, g in ROTATIONS],
        'pairs_above_0p5deg': int(np.sum(sc.angles_deg > 0.5)),
        'hold_angle_deg': float(np.median(sc.angles_deg[sc.angles_deg < 0.5])),
        'pair_angles_deg': sc.angles_deg.tolist(), 'beta_deg': list(BETA_DEG),
        'camera_sigma_arcsec': list(CAMERA_SIGMA_ARCSEC),
        'gyro': {'bias_sigma': gyro.bias_sigma, 'scale_sigma': gyro.scale_sigma,
                 'misalignment_sigma': gyro.misalignment_sigma,
                 'random_walk': gyro.random_walk},
    }


def _load_average() -> float:
    return os.getloadavg()[0] if hasattr(os, 'getloadavg') else float('nan')


def main(argv=None) -> int:
    """
    Run the boresight benchmark: scenario, bounds, checks, Monte Carlo, timing, outputs.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments without the program name; ``sys.argv[1:]`` when None.

    Returns
    -------
    int
        0 on success, 2 when an output path breaks the output rule (one line on stderr).

    """
    args = parse_args(argv)
    try:                                        # the output rule, before any work
        check_outputs([('--json', args.json, FILE), ('--report', args.report, FILE),
                       ('--plots', args.plots, DIRECTORY, PLOT_FILES)], [], args.force)
    except ValueError as exc:
        print(f'boresight_bench: error: {exc}', file=sys.stderr)
        return 2
    runs = args.runs
    t_all = time.perf_counter()
    load0 = _load_average()
    command = 'python -m strapdown_ros.bench.boresight_bench ' + ' '.join(
        sys.argv[1:] if argv is None else argv)

    sc = build_scenario()
    bnd = bounds(sc)
    sc.Sigma = bnd['Sigma']
    sc.K_gyro = bnd['K_gyro']
    cv_ok, cv_info = opencv_available()
    conv = convention_check(sc)
    calc = calibrator_check(sc, args.seed + 99)
    print_checks(sc, cv_info, conv, calc)
    if args.jobs is not None:
        jobs = args.jobs
    else:
        jobs = 1 if args.quick else max(1, min(2, os.cpu_count() or 1))
    try:
        mc = monte_carlo(sc, runs, args.seed, jobs=jobs, scheduler=args.scheduler)
    except OSError as exc:                      # no scheduler at the address
        print(f'boresight_bench: error: {exc}', file=sys.stderr)
        return 2
    perf = performance(args.perf_pairs, repeats=5 if args.quick else 15)
    sm = summarize(sc, bnd, mc, runs)
    print_summary(sm, perf, mc, runs, jobs)

    res = {'command': command, 'config': _config(args, sc),
           'opencv': {'available': cv_ok, 'info': cv_info},
           'convention_check': conv, 'calibrator_check': calc,
           'summary': sm, 'performance': perf,
           'per_run_errors_arcsec': {k: np.round(v / ARCSEC, 4).tolist()
                                     for k, v in mc['errors'].items()},
           'timing': {'scenario_s': sc.build_s, 'monte_carlo_s': mc['wall_s'], 'jobs': jobs,
                      'scheduler': args.scheduler}}
    res['findings'] = conclusions(sm)
    plots = make_plots(sc, bnd, mc, sm, args.plots) if args.plots else []
    res['plots'] = plots
    res['timing']['total_s'] = time.perf_counter() - t_all
    res['timing']['load_average_1min'] = [load0, _load_average()]
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
