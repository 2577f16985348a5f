"""
Benchmark the navigation errors of the strapdown chain against exact truth, perfect sensors.

The command ``nav_bench``; the runs are in ``nav_bench_runs``, the conclusions and report in
``nav_bench_report``.

For each Earth-referenced profile of :mod:`strapdown_ros.motion.earth_profiles` (static for
``--static-seconds``, default 3600 s; straight flight, coordinated turn and sculling for
``--seconds``, default 600 s each; node defaults: 50.45° N, 30.52° E, 150 m) the exact gyro and
accelerometer increments (100 Hz and 300 Hz) go through the attitude integrator and the
navigator (:func:`strapdown_ros.navigation.run.run_profile`) with each configuration:

* coning algorithm ``2`` (2 gyro : 6 accelerometer increments per step, h = 0.02 s) or
  ``one_plus_previous`` (1 : 3, h = 0.01 s, 003's layout);
* sculling on / off: the specific-force integral Δv of the fitted model (form ``exact``) or
  rotation compensation only (``rotation_only``, ½Δθ×Δv, no sculling term);
* derived / printed: 003 (1.99)–(1.100) with the derived coefficients (``series``), with the
  printed coefficients in the exact recursion, and as printed (printed coefficients and printed
  recursion) — 1 : 3 layout only;
* start-up: ``one_plus_previous`` fits the rate over the previous step too; at t0 the navigator
  has no previous step and continues the first sample's rate backwards, unless the sensors ran
  before t0.  Its rows are run with 2 gyro periods of sensor data before t0; the row "no sensor
  data before t0" shows the node's start-up, set against them.

Reported: final and maximum |δR| (m) and |δW| (m/s) against the truth, final vertical error and
attitude error.  Then:

* **Sculling check** (no navigation, so neither Schuler nor the vertical channel distorts it):
  :func:`~strapdown_ros.navigation.run.specific_force_drift` — per step Δv of
  ``rotation_only`` rotated into E with the true attitude minus the exact ∫C f dt, accumulated,
  slope over the run, along the local up — on sculling profiles of 1–20 Hz at h = 0.01 and
  0.02 s, each run with +B and −B: the part odd in B against
  :func:`~strapdown_ros.motion.earth_profiles.sculling_drift_rate` ½AB(1 − sin(wh)/(wh)) with
  B the acceleration amplitude, the part even in B against the gravity term
  ½gA²(sin(wh)/(wh) − ½(1 + cos wh)) (the pure roll oscillation in gravity, derived in
  :func:`~strapdown_ros.motion.earth_profiles.gravity_sculling_term`); acceptance 5 % where
  above the float floor (10⁻¹⁵ of the mean specific force: a few ulp per step).
* **Round-off**: the static run with smaller blocks (the navigator's cumulative increment sums are
  rebased once per block).
* **Run time** of ``--timing-seconds`` (3600) of 100 Hz gyro + 300 Hz accelerometer data through
  attitude + navigation + both covariances: median and min–max of ``--runs`` (5) runs, load
  average at the start (data generation not timed).

Prints a markdown report on stdout, progress on stderr; ``--json FILE``; ``--report DIR``
(``nav_bench.md`` and ``position_error_<profile>.png``, log scale).  Every conclusion sentence
is computed from the numbers.  Exit 0 (a benchmark, not a test); 2 for bad arguments.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

from strapdown_ros.bench.nav_bench_report import conclusions, render, write_report
from strapdown_ros.bench.nav_bench_runs import (ACCEL_RATE, CONFIGS, GYRO_RATE, navigation_runs,
                                                profile_drifts, PROFILE_NAMES, roundoff_runs,
                                                sculling_check, timing_runs, vertical_channel)
from strapdown_ros.cli import check_outputs, DIRECTORY, FILE, OneLineParser, write_json
from strapdown_ros.text import json_clean


def main(argv=None):
    """
    Run ``nav_bench``.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name; ``sys.argv[1:]`` when None.

    Returns
    -------
    int
        0 (a benchmark, not a test); bad arguments exit 2 with one line on stderr.

    """
    argv = sys.argv[1:] if argv is None else list(argv)
    ap = OneLineParser(prog='nav_bench', description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--seconds', type=float, default=600.0,
                    help='duration of the moving profiles (default 600)')
    ap.add_argument('--static-seconds', type=float, default=3600.0,
                    help='duration of the static profile (default 3600)')
    ap.add_argument('--drift-seconds', type=float, default=None,
                    help='duration of each sculling-check / drift run (default: --seconds)')
    ap.add_argument('--profiles', default=','.join(PROFILE_NAMES),
                    help=f"comma-separated subset of {','.join(PROFILE_NAMES)}")
    ap.add_argument('--timing-seconds', type=float, default=3600.0,
                    help='data length of the run-time measurement (default 3600; 0 skips it)')
    ap.add_argument('--runs', type=int, default=5,
                    help='runs of the run-time measurement (default 5)')
    ap.add_argument('--block', type=int, default=36000,
                    help='gyro intervals per block fed to the chain (default 36000)')
    ap.add_argument('--json', help='write the figures to this JSON file '
                    '(documented run: doc/results/nav_bench/nav_bench.json)')
    ap.add_argument('--report', help='write nav_bench.md and the PNG plots into this directory '
                    '(documented run: doc/results/nav_bench)')
    ap.add_argument('--quiet', action='store_true', help='no progress on stderr')
    ap.add_argument('--force', action='store_true', help='overwrite existing outputs')
    args = ap.parse_args(argv)
    for name in ('seconds', 'static_seconds'):
        v = getattr(args, name)
        if not (math.isfinite(v) and 1.0 <= v <= 86400.0):
            ap.error(f"--{name.replace('_', '-')} must be in [1, 86400], got {v:g}")
    if args.drift_seconds is None:
        args.drift_seconds = args.seconds
    if not (math.isfinite(args.drift_seconds) and 1.0 <= args.drift_seconds <= 86400.0):
        ap.error(f'--drift-seconds must be in [1, 86400], got {args.drift_seconds:g}')
    if not (math.isfinite(args.timing_seconds) and
            (args.timing_seconds == 0 or 1.0 <= args.timing_seconds <= 86400.0)):
        ap.error(f'--timing-seconds must be 0 or in [1, 86400], got {args.timing_seconds:g}')
    if not 1 <= args.runs <= 100:
        ap.error(f'--runs must be in [1, 100], got {args.runs}')
    if not 100 <= args.block <= 1_000_000:
        ap.error(f'--block must be in [100, 1000000], got {args.block}')
    profiles = [p.strip() for p in args.profiles.split(',') if p.strip()]
    bad = [p for p in profiles if p not in PROFILE_NAMES]
    if bad or not profiles:
        ap.error(
            f"--profiles {args.profiles!r}: unknown {', '.join(bad) or '(empty)'}; valid:"
            f" {', '.join(PROFILE_NAMES)}"
        )
    try:
        check_outputs([('--json', args.json, FILE),
                       ('--report', args.report, DIRECTORY,
                        ('nav_bench.md',) + tuple(f'position_error_{p}.png' for p in profiles))],
                      [], args.force)
    except ValueError as exc:
        ap.error(str(exc))

    t_start = time.perf_counter()

    def progress(msg):
        if not args.quiet:
            print(f'nav_bench: [{time.perf_counter() - t_start:7.1f} s] {msg}', file=sys.stderr,
                  flush=True)

    load = os.getloadavg() if hasattr(os, 'getloadavg') else (math.nan,) * 3
    res: dict = {
        'load_at_start': list(load),
        'cpu_count': os.cpu_count(),
        'settings': {
            'command': f"nav_bench {' '.join(argv)}".rstrip(),
            'seconds': args.seconds,
            'static_seconds': args.static_seconds,
            'drift_seconds': args.drift_seconds,
            'timing_seconds': args.timing_seconds,
            'runs': args.runs,
            'block': args.block,
            'profiles': profiles,
            'gyro_rate': GYRO_RATE,
            'accel_rate': ACCEL_RATE,
            'configurations': [
                dict(zip(('key', 'algorithm', 'form', 'scheme', 'history', 'label'), c))
                for c in CONFIGS
            ],
        },
    }
    res['navigation'], series = navigation_runs(profiles, args.seconds, args.static_seconds,
                                                args.block, progress)
    if 'static' in profiles:
        res['roundoff'] = roundoff_runs(args.static_seconds, args.block, progress)
    res['sculling_check'] = sculling_check(args.drift_seconds, progress)
    res['drift'] = profile_drifts(profiles, args.drift_seconds, progress)
    res['vertical_channel'] = vertical_channel(res)
    if args.timing_seconds > 0:
        res['timing'] = timing_runs(args.timing_seconds, args.runs, args.block, progress)
    res['conclusions'] = conclusions(res)
    text = render(res, argv)
    res['text'] = text
    res['wall_s'] = time.perf_counter() - t_start
    print(text)
    if args.json:
        write_json(args.json, json_clean(res), indent=2)
    if args.report:
        path = write_report(args.report, res, series, text)
        progress(f'report {path}')
    progress(f"done in {res['wall_s']:.0f} s")
    return 0


if __name__ == '__main__':
    sys.exit(main())
