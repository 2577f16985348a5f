"""
Benchmark the live model check of the attitude filter: false alarms per hour, and naming.

The command ``model_check_bench`` (runs in ``model_check_runs``, text and plots in
``model_check_report``):

* **White windows** (``--null-windows``): the window tests on N(0, 1) windows of
  ``--window`` fixes × 3 axes, the exact null of a right filter: the share rejected at nominal
  levels by the Ljung–Box statistic against χ² (the test before), the NIS band, the spectral
  whiteness test and the window test.
* **Clean recordings through the real filter** (``--clean-hours``, split over coning, a
  three-axis sinusoid, a three-axis piecewise tumble and the 004 bench sequence): a fix per
  second, the filter's model right (the simulator's random scale and misalignment constants
  off); WARN episodes per hour, and the rule before on the same innovations.
  ``--constants-hours`` adds a three-axis run with those constants on (not in the filter's
  model: real effects, reported apart).
* **White innovations directly** (``--direct-hours``): the check alone, at one fix per second
  and, ten times as long, one per 20 s.
* **record_sim + filter_bag** (``--bag-hours``, 0 skips): one clean coning recording through
  the two commands.
* **Naming** (``--naming-seconds``, ``--naming-seeds``): single hidden effects (scale factor,
  symmetric misalignment, bias ramp, scale asymmetry, time offset 4 and 25 ms, camera noise ×2
  and ×0.5, a periodic bias outside the library) under three-axis sinusoidal motion, in a
  low-gain (navigation-grade) and a high-gain regime: the share of windows naming the right
  effect.

Prints a markdown report; ``--json FILE``, ``--report FILE``, ``--plots DIR``.  The figures are
printed, not asserted.  Exit 0; 2 for bad arguments.
"""
from __future__ import annotations

import math
import os
import sys
import time

from strapdown_ros.bench.model_check_report import conclusions, render, write_plots
from strapdown_ros.bench.model_check_runs import (bag_run, clean_runs, direct_hours, naming_runs,
                                                  null_windows, REGIMES)
from strapdown_ros.cli import check_outputs, DIRECTORY, FILE, OneLineParser, write_json, write_text
from strapdown_ros.text import json_clean

MOTIONS = ('coning', 'three_axis', 'tumble', 'bench')


def main(argv=None) -> int:
    """
    Run ``model_check_bench``.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name; ``sys.argv[1:]`` when None.

    Returns
    -------
    int
        0 (figures are printed, not asserted); bad arguments exit 2 with one line on stderr.

    """
    argv = sys.argv[1:] if argv is None else list(argv)
    ap = OneLineParser(prog='model_check_bench', description=__doc__.split('\n\n')[0])
    arg = ap.add_argument
    arg('--window', type=int, default=30, help='fixes per window (default 30)')
    arg('--rate', type=float, default=0.1,
        help='stated false WARN episodes per hour (default 0.1)')
    arg('--null-windows', type=int, default=200_000,
        help='white windows for the calibration (default 200000; 0 skips)')
    arg('--clean-hours', type=float, default=10.0,
        help='hours of clean recordings through the filter (default 10; 0 skips)')
    arg('--constants-hours', type=float, default=1.0,
        help='hours of a three-axis recording with the random constants on (default 1)')
    arg('--direct-hours', type=float, default=100.0,
        help='hours of white innovations fed to the check at a fix per second, ten times as '
             'many at one per 20 s (default 100; 0 skips)')
    arg('--bag-hours', type=float, default=1.0,
        help='hours of the record_sim + filter_bag run (default 1; 0 skips)')
    arg('--naming-seconds', type=float, default=600.0,
        help='s per hidden-effect recording (default 600; 0 skips)')
    arg('--naming-seeds', type=int, default=1, help='recordings per effect (default 1)')
    arg('--seed', type=int, default=2800, help='seed (default 2800)')
    arg('--json', help='write the figures to this JSON file '
        '(documented run: doc/results/model_check_bench/model_check_bench.json)')
    arg('--report', help='write the markdown report to this file '
        '(documented run: doc/results/model_check_bench/model_check_bench.md)')
    arg('--plots', help='write the PNG plots into this directory '
        '(documented run: doc/results/model_check_bench)')
    arg('--force', action='store_true', help='replace existing outputs')
    arg('--quiet', action='store_true', help='no progress on stderr')
    a = ap.parse_args(argv)
    if not 5 <= a.window <= 10_000:
        ap.error('--window must be in [5, 10000]')
    for name in ('rate', 'clean_hours', 'constants_hours', 'direct_hours', 'bag_hours',
                 'naming_seconds'):
        v = getattr(a, name)
        if not (math.isfinite(v) and v >= 0):
            ap.error(f"--{name.replace('_', '-')} must be finite and >= 0, got {v:g}")
    if not 0 <= a.null_windows <= 10**8 or not 1 <= a.naming_seeds <= 100:
        ap.error('--null-windows must be in [0, 1e8] and --naming-seeds in [1, 100]')
    if 0 < a.naming_seconds < 60 * a.window / 30:
        ap.error('--naming-seconds must be 0 or at least two windows of fixes')
    try:
        check_outputs([('--json', a.json, FILE), ('--report', a.report, FILE),
                       ('--plots', a.plots, DIRECTORY)], [], a.force)
    except ValueError as exc:
        ap.error(str(exc))
    t0 = time.perf_counter()

    def progress(msg):
        if not a.quiet:
            print(f'model_check_bench: [{time.perf_counter() - t0:6.1f} s] {msg}',
                  file=sys.stderr, flush=True)

    res = {'command': 'model_check_bench ' + ' '.join(argv), 'cpu_count': os.cpu_count(),
           'load_at_start': list(os.getloadavg()),
           'settings': {'window': a.window, 'rate': a.rate, 'alpha': 0.001,
                        'seed': a.seed}}
    if a.null_windows:
        res['null'] = null_windows(a.null_windows, a.window, (0.01, 0.001, 0.0001), a.seed,
                                   progress)
    if a.clean_hours:
        res['clean'] = clean_runs(a.clean_hours, MOTIONS, a.seed, progress,
                                  constants_hours=a.constants_hours)
    if a.direct_hours:
        res['direct'] = [direct_hours(h, dt, a.window, a.rate, a.seed + k, progress)
                         for k, (h, dt) in enumerate(((a.direct_hours, 1.0),
                                                      (10.0 * a.direct_hours, 20.0)))]
    if a.bag_hours:
        try:
            res['bag'] = bag_run(a.bag_hours, a.seed, None, progress)
        except (OSError, ValueError) as exc:        # reported, not a crash
            res['bag'] = {'reason': f'{type(exc).__name__}: {str(exc)[:200]}'}
    if a.naming_seconds:
        res['naming'] = naming_runs(a.naming_seconds, a.naming_seeds, tuple(REGIMES), progress)
    res['wall_s'] = time.perf_counter() - t0
    res['conclusions'] = conclusions(res)
    text = render(res)
    print(text)
    if a.plots:
        res['plots'] = [os.path.basename(p) for p in write_plots(a.plots, res)]
    if a.json:
        write_json(a.json, json_clean(res))
    if a.report:
        rel = os.path.relpath(a.plots, os.path.dirname(os.path.abspath(a.report))) \
            if a.plots else None
        figs = [f'![{p}]({rel}/{p})' for p in res.get('plots', [])] if rel else []
        write_text(a.report, text + ('\n\n## Plots\n\n' + '\n\n'.join(figs) if figs else '')
                   + '\n')
    progress(f"done in {res['wall_s']:.0f} s")
    return 0


if __name__ == '__main__':
    sys.exit(main())
