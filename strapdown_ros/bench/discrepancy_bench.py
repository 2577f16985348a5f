"""
Benchmark the discrepancy workflow: detection, naming, false alarms, confusion and speed.

The command ``discrepancy_bench``: a Monte Carlo of ``strapdown_ros.discrepancy.workflow``
(the runs in ``discrepancy_monte_carlo``, the summary in ``discrepancy_summary``), printed and
reported here.

Scenario: bench profile (enough 150 s passes for --duration), gyro 200 Hz, a star-camera fix
every 2 s, boresight (0.698, −0.436, 2.094) rad; nominal model = the calibrator defaults.

1. Detection against size: per effect and seed s, σ of the effect (``effect_sigma``; one
   reference null recording, the first seed, unless --sigma per-seed), a hidden effect of
   Mahalanobis size k (``draw_hidden_effect``; seed i gets sizes[i mod n] unless --every-size)
   in a recording of seed s + 10000, ``analyse``: detected, named first, estimate within 3σ in
   every component.  Reference: the ideal LRT power P(χ²_q(k²) > χ²_q⁻¹(1 − α/m)),
   q = separable dimension, m = candidates.
2. False alarms: null recordings of --null-seeds seeds, verdict ≠ ``model_adequate``
   (Clopper–Pearson).
3. Confusion: injected × first named effect at k ≥ 5σ.
4. Speed: the ``discrepancy`` command's work (its library call, JSON and report) on a 900 s
   bag (200 Hz, 450 fixes), 5 runs.

The runs are Dask tasks (``strapdown_ros.fleet.cluster``): an embedded LocalCluster of
``--workers`` processes, one thread each, or the workers of the scheduler at ``--scheduler``.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

from strapdown_ros.bench.discrepancy_monte_carlo import (INJECT_SEED_OFFSET, monte_carlo,
                                                         separable_dimension, speed,
                                                         SPEED_DURATION, SPEED_REPEATS)
from strapdown_ros.bench.discrepancy_summary import (conclusions, ideal_power, span_text,
                                                     summarise, tables, TARGET_DETECTION,
                                                     TARGET_SIZE)
from strapdown_ros.cli import (check_outputs, DIRECTORY, FILE, OneLineParser, write_figure,
                               write_text)
from strapdown_ros.sensors.effects import CANDIDATES

PROG = 'discrepancy_bench'
QUICK = {'effects': ['time_offset', 'gyro_bias'], 'seeds': 2, 'sizes': [5.0], 'null_seeds': 3,
         'duration': 320.0}
FULL = {'effects': list(CANDIDATES), 'seeds': 50, 'sizes': [1.0, 2.0, 3.0, 5.0, 7.0, 10.0],
        'null_seeds': 100, 'duration': 480.0}


# ----------------------------------------------------------------------------- summary
# ----------------------------------------------------------------------------- outputs
def write_plots(res: dict, outdir: str) -> list[str]:
    """
    Write the detection-against-size and confusion plots.

    Parameters
    ----------
    res : dict
        The run's result.
    outdir : str
        Directory for ``discrepancy_detection.png`` and ``discrepancy_confusion.png``.

    Returns
    -------
    list of str
        Paths of the files written.

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    os.makedirs(outdir, exist_ok=True)
    sm, cfg = res['summary'], res['config']
    fig, ax = plt.subplots(figsize=(8, 5))
    kk = np.linspace(0.0, max(*cfg['sizes'], TARGET_SIZE) * 1.05, 200)
    n_e = len(sm['detection'])
    for i, (e, row) in enumerate(sm['detection'].items()):
        col = plt.get_cmap('tab10')(i % 10)
        dx = 0.04 * (i - (n_e - 1) / 2)  # small offsets so that equal rates stay visible
        pts = [(float(k) + dx, c['detected'] / c['n']) for k, c in row.items() if c['n']]
        if pts:
            ax.plot(*zip(*pts), 'o-', color=col, label=e)
        q = separable_dimension(e)
        ax.plot(kk, [ideal_power(q, k, cfg['alpha']) for k in kk], '--', color=col, lw=0.8)
    ks = [k for k in cfg['sizes'] if k >= TARGET_SIZE] or [TARGET_SIZE]
    ax.plot(ks, [TARGET_DETECTION] * len(ks), 'kv', ms=9,
            label=f'target ≥ {TARGET_DETECTION:.0%} at k ≥ {TARGET_SIZE:g}σ')
    ax.axhline(TARGET_DETECTION, color='k', lw=0.5, ls=':')
    ax.set(
        xlabel='injected size k (σ, Mahalanobis)',
        ylabel='detection rate',
        ylim=(-0.03, 1.03),
        title=(
            'Detection vs effect size (dashed: ideal LRT power at (α/2)/m; markers offset slightly'
            ' in k)'
        ),
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc='lower right')
    fig.tight_layout()
    files = [os.path.join(outdir, 'discrepancy_detection.png')]
    write_figure(fig, files[-1], dpi=110)
    plt.close(fig)
    c = sm['confusion']
    rows, cols = list(c['rows']), c['columns']
    M = np.array([[c['rows'][r][k] for k in cols] for r in rows],
                 dtype=float).reshape(len(rows), len(cols))
    frac = M / np.maximum(M.sum(1, keepdims=True), 1)
    fig, ax = plt.subplots(figsize=(1.0 + 0.8 * len(cols), 1.5 + 0.5 * len(rows)))
    im = ax.imshow(frac, cmap='Blues', vmin=0, vmax=1, aspect='auto')
    for i, j in zip(*np.nonzero(M)):
        ax.text(j, i, f'{int(M[i, j])}', ha='center', va='center',
                color='w' if frac[i, j] > 0.5 else 'k')
    ax.set_xticks(range(len(cols)), cols, rotation=45, ha='right', fontsize=7)
    ax.set_yticks(range(len(rows)), rows, fontsize=7)
    ax.set(xlabel='first named effect', ylabel='injected effect',
           title=f"Confusion at k ≥ {c['min_size']:g}σ")
    fig.colorbar(im, ax=ax, label='fraction of row')
    fig.tight_layout()
    files.append(os.path.join(outdir, 'discrepancy_confusion.png'))
    write_figure(fig, files[-1], dpi=110)
    plt.close(fig)
    return files


def write_report(path: str, res: dict, plots: list[str]):
    """
    Write the markdown report of one run.

    Parameters
    ----------
    path : str
        Markdown file to write.
    res : dict
        The run's result.
    plots : list of str
        Plot files, linked relative to the report.

    """
    cfg, sm, tm = res['config'], res['summary'], res['timing']
    sigma = (f"one reference null recording per effect (seed {cfg['first_seed']})"
             if cfg['sigma'] == 'reference' else "each seed's own null recording")
    L = [
        '# discrepancy_bench — detection, false alarms and confusion of the discrepancy workflow',
        '',
        (
            f"Generated by `{res['command']}`: {tm['total_s']:.0f} s wall, "
            f"{cfg.get('scheduler') or str(cfg['workers']) + ' LocalCluster'}"
            f" workers, {tm['cpu_count']} CPUs, load average at start"
            f" {tm['load_average_at_start'][0]:.2f}."
        ),
        '',
        (
            f"Scenario: bench profile, {cfg['duration']:g} s, gyro 200 Hz, a fix every 2 s;"
            f" nominal model = calibrator defaults; α = {cfg['alpha']:g}. {cfg['seeds']} seeds per"
            f" effect, sizes {', '.join(f'{k:g}' for k in cfg['sizes'])}σ"
            f" ({'every size for every seed' if cfg['every_size'] else 'cycled over the seeds'});"
            f' σ of each effect from {sigma}; injected recordings use seed + {INJECT_SEED_OFFSET}.'
        ),
        '',
        '## Conclusions',
        '',
    ]
    L += [f'* {s}' for s in conclusions(res)] + ['']
    L += [x.replace('### ', '## ') for x in tables(sm, cfg['sizes'])]
    if sm['analysis_s']:
        L += ['', f"Analysis time per run: {span_text(sm['analysis_s'])}."]
    base = os.path.dirname(os.path.abspath(path))
    L += [''] + [f'![{os.path.basename(p)}]({os.path.relpath(p, base)})' for p in plots]
    write_text(path, '\n'.join(L) + '\n')


# ----------------------------------------------------------------------------- arguments
def parse_args(argv):
    """
    Parse and check the command line; fill the defaults of the quick or full mode.

    Parameters
    ----------
    argv : list of str
        Arguments without the program name.

    Returns
    -------
    argparse.Namespace
        The options (``sizes`` and ``effects`` as lists).

    """
    ap = OneLineParser(prog=PROG, description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--seeds', type=int, help='seeds per effect (default 50)')
    ap.add_argument('--duration', type=float, help='simulated seconds per recording (default 480)')
    ap.add_argument('--sizes', help='comma-separated effect sizes in σ (default 1,2,3,5,7,10)')
    ap.add_argument('--effects', help=f"all (default) or a comma list of: {', '.join(CANDIDATES)}")
    ap.add_argument('--null-seeds', type=int,
                    help='null recordings for the false-alarm rate (default 100)')
    ap.add_argument('--alpha', type=float, default=0.01,
                    help='significance level of the workflow (default 0.01)')
    ap.add_argument('--workers', type=int, default=2,
                    help='LocalCluster worker processes (default 2)')
    ap.add_argument('--scheduler', metavar='ADDRESS',
                    help='run the trials on a running Dask scheduler, e.g. tcp://host:8786 '
                         '(default: a LocalCluster of --workers)')
    ap.add_argument('--first-seed', type=int, default=0, help='seed of the first run (default 0)')
    ap.add_argument('--every-size', action='store_true',
                    help='run every size for every seed (default: cycle sizes)')
    ap.add_argument(
        '--sigma', choices=('reference', 'per-seed'), default='reference',
        help="σ of an effect from one reference null recording (default) or from each seed's own")
    ap.add_argument('--json', help='write all records and tables to this JSON file '
                    '(documented run: doc/results/discrepancy_bench/bench.json)')
    ap.add_argument('--plots',
                    help='write discrepancy_detection.png and discrepancy_confusion.png here '
                    '(documented run: doc/results/discrepancy_bench)')
    ap.add_argument('--report', help='write the markdown report to this file '
                    '(documented run: doc/results/discrepancy_bench/bench.md)')
    ap.add_argument('--force', action='store_true', help='overwrite existing outputs')
    ap.add_argument(
        '--speed-only', action='store_true',
        help="only the speed measurement (5 runs of the discrepancy command's work on a "
             '15-minute bag)')
    ap.add_argument(
        '--speed', action=argparse.BooleanOptionalAction, default=None,
        help="time the discrepancy command's work on a 900 s recording (default on; off with "
             '--quick)')
    ap.add_argument(
        '--quick', action='store_true',
        help='smoke mode: ' + ', '.join(f'{k}={v}' for k, v in QUICK.items()) + ', no speed')
    args = ap.parse_args(argv)
    # the mode's defaults for what was not given
    for k, v in (QUICK if args.quick else FULL).items():
        if getattr(args, k) is None:
            setattr(args, k, list(v) if isinstance(v, list) else v)
    args.speed = args.speed if args.speed is not None else not args.quick
    if args.seeds < 1 or args.null_seeds < 0:
        ap.error('--seeds must be >= 1 and --null-seeds >= 0')
    if not (0.0 < args.alpha < 1.0) or args.workers < 1 or args.first_seed < 0:
        ap.error('--alpha must lie in (0, 1), --workers be >= 1 and --first-seed >= 0')
    if not (40.0 <= args.duration <= 86400.0):
        ap.error(
            f'--duration must lie in [40, 86400] s (>= 13 fixes 2 s apart), got {args.duration:g}')
    if isinstance(args.sizes, str):
        try:
            args.sizes = [float(s) for s in args.sizes.split(',')]
        except ValueError:
            ap.error(f'--sizes must be comma-separated numbers, got {args.sizes!r}')
        sizes = args.sizes
        if not all(0.0 < s <= 100.0 for s in sizes) or len(set(sizes)) != len(sizes):
            ap.error('--sizes must be distinct numbers in (0, 100]')
    if isinstance(args.effects, str):
        if args.effects.strip() == 'all':
            names = list(CANDIDATES)
        else:
            names = [s.strip() for s in args.effects.split(',')]
        bad = sorted({n for n in names if n not in CANDIDATES or names.count(n) > 1})
        if bad:
            ap.error(
                f"--effects: unknown or repeated {', '.join(map(repr, bad))}; valid: all,"
                f" {', '.join(CANDIDATES)}"
            )
        args.effects = names
    try:                                        # the tools' one output rule
        check_outputs([('--json', args.json, FILE), ('--report', args.report, FILE),
                       ('--plots', args.plots, DIRECTORY, ('discrepancy_detection.png',
                                                           'discrepancy_confusion.png'))],
                      [], args.force)
    except ValueError as exc:
        ap.error(str(exc))
    return args


def main(argv=None) -> int:
    """
    Run ``discrepancy_bench``.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name; ``sys.argv[1:]`` when None.

    Returns
    -------
    int
        0 on success (bad arguments exit 2 with one line on stderr).

    """
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parse_args(argv)
    t_all, load = time.perf_counter(), os.getloadavg()
    if args.speed_only:
        sp = speed(args)
        t = sp['time_s']
        print(
            f"{PROG}: discrepancy command's work on a {sp['duration_s']:g} s recording (200 Hz "
            f"gyro, {sp['fixes']} fixes), report included: median {t['median']:.2f} s (min"
            f" {t['min']:.2f}, max {t['max']:.2f}) over {len(sp['times_s'])} runs; load average at"
            f" start {load[0]:.2f}; exit codes {sp['return_codes']}"
        )
        if args.json:
            write_text(args.json, json.dumps({'command': f'{PROG} ' + ' '.join(argv),
                                              'speed': sp}, indent=1, default=float))
        return 0
    per_seed = len(args.sizes) if args.every_size else 1
    n_jobs = len(args.effects) * args.seeds * per_seed + args.null_seeds
    print(
        f'{PROG}: {len(args.effects)} effects × {args.seeds} seeds, sizes '
        f"{','.join(f'{k:g}' for k in args.sizes)}σ, {args.null_seeds} null seeds,"
        f' {args.duration:g} s each: '
        f"{n_jobs} jobs on {args.scheduler or f'{args.workers} LocalCluster workers'}; "
        f'load average at start {load[0]:.2f}'
        f' {load[1]:.2f} {load[2]:.2f}',
        file=sys.stderr,
    )
    mc = monte_carlo(args)
    cfg = {k: getattr(args, k)
           for k in ('seeds', 'duration', 'sizes', 'effects', 'null_seeds', 'alpha', 'workers',
                     'scheduler', 'first_seed', 'every_size', 'sigma', 'quick')}
    res = {'command': f'{PROG} ' + ' '.join(argv), 'config': cfg, 'summary': summarise(mc, args),
           'reference_sigma': mc['reference_sigma'], 'runs': mc['runs'], 'nulls': mc['nulls']}
    if args.speed:
        print(f'{PROG}: speed: {SPEED_REPEATS} runs on a {SPEED_DURATION:g} s recording ...',
              file=sys.stderr)
        res['speed'] = speed(args)
    sm = res['summary']
    res['plots'] = write_plots(res, args.plots) if args.plots else []
    res['timing'] = {'sigma_wall_s': mc['sigma_wall_s'], 'runs_wall_s': mc['runs_wall_s'],
                     'total_s': time.perf_counter() - t_all, 'load_average_at_start': list(load),
                     'cpu_count': os.cpu_count()}
    print('\n'.join(tables(sm, args.sizes)) + '\n\n' + '\n'.join(conclusions(res)))
    if sm['analysis_s']:
        print(
            f"analysis per run: {span_text(sm['analysis_s'])}; job (simulation + σ + analysis):"
            f" {span_text(sm['job_s'])}"
        )
    print(
        f"total {res['timing']['total_s']:.0f} s (σ {mc['sigma_wall_s']:.0f} s, runs"
        f" {mc['runs_wall_s']:.0f} s); load average at start {load[0]:.2f}"
    )
    if args.report:
        write_report(args.report, res, res['plots'])
    if args.json:
        write_text(args.json, json.dumps(res, indent=1, default=float))
    return 0


if __name__ == '__main__':
    sys.exit(main())
