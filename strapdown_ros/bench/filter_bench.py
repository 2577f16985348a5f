"""
Benchmark the star-camera-aided attitude filter against its bound, for consistency and cost.

The command ``filter_bench``: ``AttitudeFilter`` (MEKF) against exact truth, its posterior
Cramér–Rao bound, its consistency, its cost, and one real recording.  The runs are in
``filter_bench_runs``, the text and plots in ``filter_bench_report``.

* **Monte Carlo** (``--runs``, default 100; ``--fixes`` per run; in this process, or as Dask
  tasks with ``--workers N`` or ``--scheduler ADDRESS``): slow constant rotation, the
  gyro's exact increments plus angle random walk and a bias random walk sampled from their exact
  joint law, a camera fix every ``--fix-interval`` s with known covariance R, initial errors drawn
  from the prior (the simulation of ``test/estimation/test_attitude_filter.py``).
* **Posterior Cramér–Rao bound** (Tichavský, Muravchik & Nehorai 1998): for this linear-Gaussian
  error model the PCRB of the causal (filtered) estimate at a fix is the Riccati covariance along
  the true trajectory, and that of the smoothed estimate is the covariance of the fixed-interval
  Rauch–Tung–Striebel smoother.  Both are computed here from the continuous error model
  ``ε̇ = −[ω×]ε − δb + w, δḃ = u`` discretised by Van Loan's method (independent of the filter's
  block transition).  The filter's attitude RMS is set against √(filter PCRB), the RTS smoother
  run on the filter's output against √(smoother PCRB); the filter against the smoother's bound is
  printed for information only (a causal estimate cannot reach it).
* **NEES** (attitude 3, bias 3, joint 6) and **NIS** (3), run-averaged per fix, with their
  two-sided 95 % χ² bands (Bar-Shalom, Li & Kirubarajan 2001, §5.4).
* **Cost**: ``--timing-seconds`` of 1 kHz Δθ with a fix every second through the core, one
  increment per ``propagate`` call (as a node receives them) and in blocks; µs per increment
  (all work included) and per fix; median and min–max of ``--timing-runs``; one process, one
  thread (numpy's BLAS on 3×3..6×6 matrices does not thread); load average at the start.
* **Real data** (RepoIMU, when ``$STRAPDOWN_REALDATA`` names a copy): one wand trial, bias +
  time offset + boresight states, the Vicon attitude as one fix per second, σ from the data;
  the bias against the mean rate at rest and the time offset against the rate cross-correlation
  (``strapdown_ros.recording.repoimu``).
* **filter_bag against a raw read** (``--bag BAG``): the whole ``filter_bag BAG --output OUT``
  command and a raw rosbags read of the same bag (AnyReader over every record, no decoding,
  ``sins_bag_bench``'s), each a separate process, ``--bag-runs`` pairs in alternating order;
  median and min–max of each, the ratio of the medians and of each pair; then the phases of one
  filter_bag in this process (reading, the filter with the live model check's share, the CSV
  text).  The target: filter_bag within 2× the raw read on a 1 h 100 Hz recording with 1 Hz
  fixes (``record_sim BAG --duration 3600 --no-accel -p camera_interval:=1.0``).
  ``--only-bag`` runs this part alone.

Prints a markdown table on stdout; ``--json FILE``; ``--plots DIR`` (attitude error with its
±3σ band, bias convergence with ±3σ, NIS with its χ² band); ``--report FILE`` (markdown).  The
figures are printed, not asserted.  Exit 0; 2 for bad arguments.
"""
from __future__ import annotations

import math
import os
import sys
import time

from strapdown_ros.bench.filter_bench_report import conclusions, render, write_plots
from strapdown_ros.bench.filter_bench_runs import (bag_timing, monte_carlo, realdata_run,
                                                   run_timing, summarize)
from strapdown_ros.cli import check_outputs, DIRECTORY, FILE, OneLineParser, write_json, write_text
from strapdown_ros.text import json_clean


def main(argv=None) -> int:
    """
    Run ``filter_bench``.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name; ``sys.argv[1:]`` when None.

    Returns
    -------
    int
        0 (figures are printed, not asserted); bad arguments exit 2 with one line on stderr; 1
        when filter_bag fails on --bag.

    """
    argv = sys.argv[1:] if argv is None else list(argv)
    ap = OneLineParser(prog='filter_bench', description=__doc__.split('\n\n')[0])
    arg = ap.add_argument
    arg('--runs', type=int, default=100, help='Monte Carlo runs (default 100)')
    arg('--fixes', type=int, default=60, help='fixes per run (default 60)')
    arg('--fix-interval', type=float, default=2.0, help='s between fixes (default 2)')
    arg('--gyro-period', type=float, default=0.25, help='gyro increment period, s (default 0.25)')
    arg('--arw', type=float, default=3e-6, help='angle random walk, rad/√s (default 3e-6)')
    arg('--bias-rw', type=float, default=3e-7, help='bias random walk, rad/s/√s (default 3e-7)')
    arg('--camera-sigma', type=float, default=1e-5, help='fix σ per axis, rad (default 1e-5)')
    arg('--prior-attitude', type=float, default=2e-4, help='prior attitude σ, rad (default 2e-4)')
    arg('--prior-bias', type=float, default=2e-5, help='prior bias σ, rad/s (default 2e-5)')
    arg('--seed', type=int, default=20000, help='seed of run 0 (default 20000)')
    arg('--timing-seconds', type=float, default=30.0,
        help='s of 1 kHz data per timing run (default 30; 0 skips the timing)')
    arg('--timing-runs', type=int, default=5, help='timing runs (default 5)')
    arg('--blocks', default='1,10,100', help='increments per propagate call (default 1,10,100)')
    arg('--trial', default='TStick_Test11_Trial2', help='RepoIMU wand trial')
    arg('--real-camera-sigma', type=float, default=0.005,
        help='σ of a Vicon fix per axis, rad '
             '(default 0.005, as doc/results/realdata/nominal.yaml)')
    arg('--no-realdata', action='store_true', help='skip the real-data run')
    arg('--bag', help='time filter_bag on this bag beside a raw read of it')
    arg('--bag-runs', type=int, default=5, help='alternating pairs of that timing (default 5)')
    arg('--bag-param', action='append', default=[], metavar='NAME:=VALUE',
        help='a parameter override given to filter_bag (repeatable)')
    arg('--only-bag', action='store_true', help='only the --bag timing')
    arg('--json', help='write the figures to this JSON file '
        '(documented run: doc/results/filter_bench/filter_bench.json)')
    arg('--report', help='write the markdown report to this file '
        '(documented run: doc/results/filter_bench/filter_bench.md)')
    arg('--plots', help='write the PNG plots into this directory '
        '(documented run: doc/results/filter_bench)')
    arg('--workers', type=int, default=1,
        help='Dask LocalCluster workers for the Monte Carlo runs (default 1: in this process)')
    arg('--scheduler', metavar='ADDRESS',
        help='run the Monte Carlo runs on a running Dask scheduler, e.g. tcp://host:8786')
    arg('--force', action='store_true', help='replace existing outputs')
    arg('--quiet', action='store_true', help='no progress on stderr')
    a = ap.parse_args(argv)
    if not 2 <= a.runs <= 100_000 or not 2 <= a.fixes <= 100_000:
        ap.error('--runs and --fixes must be >= 2')
    for name in ('fix_interval', 'gyro_period', 'camera_sigma', 'prior_attitude', 'prior_bias',
                 'real_camera_sigma'):
        v = getattr(a, name)
        if not (math.isfinite(v) and v > 0):
            ap.error(f"--{name.replace('_', '-')} must be > 0, got {v:g}")
    k = a.fix_interval / a.gyro_period
    if abs(k - round(k)) > 1e-9 or round(k) < 1:
        ap.error('--fix-interval must be a whole multiple of --gyro-period')
    for name in ('arw', 'bias_rw', 'timing_seconds'):
        v = getattr(a, name)
        if not (math.isfinite(v) and v >= 0):
            ap.error(f"--{name.replace('_', '-')} must be >= 0, got {v:g}")
    if not 1 <= a.timing_runs <= 100:
        ap.error('--timing-runs must be in [1, 100]')
    if not 1 <= a.workers <= 256:
        ap.error('--workers must be in [1, 256]')
    if a.only_bag and not a.bag:
        ap.error('--only-bag needs --bag')
    if a.bag and not os.path.exists(a.bag):
        ap.error(f'--bag {a.bag} does not exist')
    if not 1 <= a.bag_runs <= 100:
        ap.error('--bag-runs must be in [1, 100]')
    try:
        blocks = [int(b) for b in a.blocks.split(',') if b.strip()]
    except ValueError:
        ap.error(f'--blocks {a.blocks!r}: comma-separated positive integers')
    if not blocks or min(blocks) < 1 or max(blocks) > 1000:
        ap.error('--blocks: integers in [1, 1000]')
    try:
        check_outputs([('--json', a.json, FILE), ('--report', a.report, FILE),
                       ('--plots', a.plots, DIRECTORY)], [('--bag', a.bag)], a.force)
    except ValueError as exc:
        ap.error(str(exc))
    t0 = time.perf_counter()

    def progress(msg):
        if not a.quiet:
            print(f'filter_bench: [{time.perf_counter() - t0:6.1f} s] {msg}', file=sys.stderr,
                  flush=True)

    res = {'command': 'filter_bench ' + ' '.join(argv), 'cpu_count': os.cpu_count(),
           'load_at_start': list(os.getloadavg()),
           'settings': {k_: getattr(a, k_) for k_ in ('runs', 'fixes', 'fix_interval',
                                                      'gyro_period', 'arw', 'bias_rw',
                                                      'camera_sigma', 'prior_attitude',
                                                      'prior_bias', 'seed', 'timing_seconds',
                                                      'timing_runs')}}
    mc = None
    if not a.only_bag:
        try:
            mc = monte_carlo(a, progress, a.scheduler, a.workers)
        except OSError as exc:                        # no scheduler at the address
            print(f'filter_bench: error: {exc}', file=sys.stderr)
            return 2
        res['summary'] = summarize(mc, a.runs)
        if a.timing_seconds > 0:
            progress('timing')
            res['timing'] = run_timing(a.timing_seconds, a.timing_runs, blocks)
        if a.no_realdata:
            res['realdata'] = {'available': False, 'reason': '--no-realdata'}
        else:
            try:
                res['realdata'] = realdata_run(a, progress)
            except (ValueError, OSError) as exc:      # a data problem: reported, not a crash
                res['realdata'] = {'available': False, 'reason': f'{type(exc).__name__}: '
                                   f'{str(exc)[:200]}'}
    if a.bag:
        try:
            res['bag_timing'] = bag_timing(a.bag, a.bag_runs, a.bag_param, progress)
        except RuntimeError as exc:
            print(f'filter_bench: error: {exc}', file=sys.stderr)
            return 1
    res['conclusions'] = conclusions(res)
    text = render(res)
    print(text)
    if a.plots and mc is not None:
        res['plots'] = [os.path.basename(p) for p in write_plots(a.plots, mc)]
    res['wall_s'] = time.perf_counter() - t0
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
