"""
Measure how ``discrepancy`` and ``calibrate_bag`` grow with the rate of the attitude reference.

The command ``reference_rate_bench``: figures printed, nothing asserted.

    reference_rate_bench [--rates 1 10 50 286] [--runs N] [--duration S]
                         [--correlation-time S] [--white-runs N] [--threads N]
                         [--json FILE] [--report FILE] [--keep DIR] [--force]

One simulated motion-capture trial (:mod:`strapdown_ros.bench.reference_rate_scenario`): 6 min
of a MEMS gyro as sensor_msgs/Imu at 286 Hz and a PoseStamped reference of the same rigid
body, its error correlated over ``--correlation-time`` (a motion-capture system's smoothing),
written as one bag per reference rate (1, 10, 50 and 286 fixes per second: the same samples,
one in k kept).  Each run, in turn, as separate processes: the raw read of the bag (rosbags'
``AnyReader`` over every record, no decoding; :func:`strapdown_ros.bench.sins_bag_bench.raw_read`),
``discrepancy BAG --model MODEL --json`` and ``calibrate_bag BAG --params MODEL --json``, as a
user runs them (start-up included).  Per command: wall time, CPU time and peak resident memory
of the process (its own ``getrusage``); median (min–max) of ``--runs`` runs; the ratio to the
raw read of the same run.  ``--white-runs`` adds the worst case: the same trial with a white
reference at 286 Hz, where every fix is kept (fewer runs: it is the slowest).

The child processes run with ``--threads`` BLAS threads (default 1: on a machine shared by
several jobs, threads oversubscribe the cores and make the timing erratic).  The estimates are
printed beside the truth: the boresight error in units of its σ at every rate.  Exit 0; 2 for
bad arguments.
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

from strapdown_ros.bench.reference_rate_scenario import (BORESIGHT, input_arguments,
                                                         model_text, write_bags)
from strapdown_ros.bench.sins_bag_bench import raw_read
from strapdown_ros.bench.stats import median_range, stats
from strapdown_ros.cli import (check_outputs, DIRECTORY, FILE, OneLineParser, write_json,
                               write_text)

__all__ = ['main', 'run_tool', 'TARGET_RATIO']

PROG = 'reference_rate_bench'
TARGET_RATIO = 20.0          # discrepancy at 286 Hz within 20× the raw read of the bag
ARCSEC = np.pi / 180.0 / 3600.0

#: runs a tool's module as ``python -m`` does, then reports its own CPU time and peak memory
CHILD = """
import json, resource, runpy, sys
sys.argv = sys.argv[1:]
rc = 0
try:
    runpy.run_module(sys.argv[0], run_name='__main__', alter_sys=True)
except SystemExit as exc:
    rc = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
r = resource.getrusage(resource.RUSAGE_SELF)
print('BENCH ' + json.dumps({'rc': rc, 'cpu_s': r.ru_utime + r.ru_stime,
                             'peak_mb': r.ru_maxrss / 1024.0}), file=sys.stderr)
"""


def run_tool(module: str, args: list, env: dict) -> dict:
    """
    Run one tool in its own process; return its wall time, CPU time, peak memory and status.

    Parameters
    ----------
    module : str
        The tool's module (``strapdown_ros.tools.discrepancy``).
    args : list of str
        Its arguments.
    env : dict
        The environment of the process.

    Returns
    -------
    dict
        ``wall_s``, ``cpu_s``, ``peak_mb``, ``rc`` and the last line of stderr.

    """
    t0 = time.perf_counter()
    res = subprocess.run([sys.executable, '-c', CHILD, module] + list(args),
                         capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    lines = res.stderr.strip().splitlines()
    got = [json.loads(ln[6:]) for ln in lines if ln.startswith('BENCH ')]
    nan = float('nan')
    out = got[-1] if got else {'rc': res.returncode, 'cpu_s': nan, 'peak_mb': nan}
    out['wall_s'] = wall
    other = [ln for ln in lines if not ln.startswith('BENCH ')]
    out['stderr'] = other[-1][:300] if other else ''
    return out


def _estimate(path: Path, kind: str) -> dict:
    """Return β, σ, pairs and the spacing from a tool's JSON (None where it has none)."""
    try:
        j = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    if kind == 'discrepancy':
        beta, sig = j.get('boresight_rad'), j.get('boresight_sigma_rad')
        chi2 = j.get('chi2_per_dof')
    else:
        beta, sig, chi2 = j.get('beta_rad'), j.get('beta_sigma_rad'), j.get('chi2_per_dof')
    sp = j.get('reference_spacing') or {}
    return {'beta_rad': beta, 'sigma_rad': sig, 'pairs': j.get('pairs'), 'chi2_per_dof': chi2,
            'spacing_step': sp.get('step'), 'spacing_s': sp.get('spacing_s'),
            'verdict': j.get('verdict')}


def _case(bag: str, model: Path, runs: int, env: dict, work: Path, say) -> dict:
    """Time ``runs`` rounds of raw read, discrepancy and calibrate_bag on one bag, in turn."""
    raw, disc, cal = [], [], []
    est = {}
    for k in range(runs):
        order = ('raw', 'discrepancy', 'calibrate_bag')
        if k % 2:
            order = order[::-1]
        for what in order:
            if what == 'raw':
                raw.append(raw_read(bag))
                continue
            out = work / f'{what}.json'
            if what == 'discrepancy':
                args = [bag, '--model', str(model), '--json', str(out), '--force', '--quiet']
                r = run_tool('strapdown_ros.tools.discrepancy', args + input_arguments(), env)
                disc.append(r)
            else:
                args = [bag, '--params', str(model), '--json', str(out), '--force']
                r = run_tool('strapdown_ros.tools.calibrate_bag', args + input_arguments(), env)
                cal.append(r)
            if r['rc'] not in (0, 3):
                raise RuntimeError(f"{what} exited {r['rc']}: {r['stderr']}")
            est[what] = _estimate(out, what)
        say(f"    run {k + 1}/{runs}: raw read {raw[-1]['wall_s']:.2f} s, discrepancy "
            f"{disc[-1]['wall_s']:.1f} s, calibrate_bag {cal[-1]['wall_s']:.1f} s")
    res = {'records': raw[0]['records'], 'runs': runs,
           'raw_wall_s': stats([r['wall_s'] for r in raw]),
           'raw_iteration_s': stats([r['iteration_s'] for r in raw]), 'estimates': est}
    for name, rr in (('discrepancy', disc), ('calibrate_bag', cal)):
        res[name] = {'wall_s': stats([r['wall_s'] for r in rr]),
                     'cpu_s': stats([r['cpu_s'] for r in rr]),
                     'peak_mb': stats([r['peak_mb'] for r in rr]),
                     'ratio_to_raw': stats([r['wall_s'] / w['wall_s'] for r, w in zip(rr, raw)])}
    return res


def _errors(est: dict) -> list:
    """Return (β − truth)/σ per axis, or [] without an estimate."""
    b, s = est.get('beta_rad'), est.get('sigma_rad')
    if not b or not s:
        return []
    return [float((x - t) / max(y, 1e-300)) for x, t, y in zip(b, BORESIGHT, s)]


def tables(res: dict) -> str:
    """
    Return the printed tables of a run (markdown).

    Parameters
    ----------
    res : dict
        The run's result.

    Returns
    -------
    str
        The tables and the target line.

    """
    cfg = res['config']
    lines = [f"load average at start {' '.join(f'{v:.2f}' for v in res['load_average'])} on "
             f"{res['cpus']} cores; {cfg['threads']} BLAS thread(s) per process; median "
             f"(min–max) of the runs; ratio = wall time ÷ the raw read's in the same run", '',
             '| reference | fixes | pairs used (discrepancy / calibrate_bag) | raw read, s | '
             'discrepancy, s | ÷ raw read | CPU, s | peak MB | calibrate_bag, s | ÷ raw read '
             '| CPU, s | peak MB |',
             '|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|']
    for c in res['cases']:
        d, k, e = c['discrepancy'], c['calibrate_bag'], c['estimates']
        used = (f"{e.get('discrepancy', {}).get('pairs')} / "
                f"{e.get('calibrate_bag', {}).get('pairs')}")
        lines.append(
            f"| {c['label']} | {c['fixes']} | {used} | {median_range(c['raw_wall_s'], '.2f')} "
            f"| {median_range(d['wall_s'], '.1f')} | {median_range(d['ratio_to_raw'], '.1f')} "
            f"| {median_range(d['cpu_s'], '.1f')} | {median_range(d['peak_mb'], '.0f')} "
            f"| {median_range(k['wall_s'], '.1f')} | {median_range(k['ratio_to_raw'], '.1f')} "
            f"| {median_range(k['cpu_s'], '.1f')} | {median_range(k['peak_mb'], '.0f')} |")
    lines += ['', '| reference | tool | spacing of the fixes | χ²/dof | verdict | '
              'β error ÷ σ (ψ, ϑ, γ) | σ, ″ (ψ, ϑ, γ) |', '|---|---|---|---:|---|---|---|']
    for c in res['cases']:
        for tool in ('discrepancy', 'calibrate_bag'):
            e = c['estimates'].get(tool, {})
            err = _errors(e)
            sig = e.get('sigma_rad') or []
            step, sp = e.get('spacing_step'), e.get('spacing_s')
            spacing = f'1 in {step} ({sp:.3g} s)' if step and sp else '—'
            chi2 = e.get('chi2_per_dof')
            lines.append(
                f"| {c['label']} | {tool} | {spacing} | "
                f"{'—' if chi2 is None else f'{chi2:.3g}'} | {e.get('verdict') or '—'} | "
                f"{', '.join(f'{v:+.2f}' for v in err) or '—'} | "
                f"{', '.join(f'{v / ARCSEC:.3g}' for v in sig) or '—'} |")
    lines.append('')
    growth = res.get('growth')
    if growth:
        lines.append(f"growth from {growth['from']} to {growth['to']} (×{growth['fixes']:.0f} "
                     f"fixes): discrepancy ×{growth['discrepancy_wall']:.2f} wall, "
                     f"×{growth['discrepancy_peak']:.2f} peak memory; calibrate_bag "
                     f"×{growth['calibrate_bag_wall']:.2f} wall, "
                     f"×{growth['calibrate_bag_peak']:.2f} peak memory")
    t = res.get('target')
    if t:
        met = 'met' if t['ratio'] <= TARGET_RATIO else 'NOT met'
        lines.append(f"discrepancy at {t['label']}: {t['ratio']:.1f}× the raw read of the bag "
                     f'(median of the per-run ratios); the target ≤ {TARGET_RATIO:g}× is {met}.')
    return '\n'.join(lines)


def main(argv=None) -> int:
    """
    Run the reference_rate_bench command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status (0 success; 2 unusable arguments).

    """
    ap = OneLineParser(prog=PROG, description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--rates', type=float, nargs='+', default=[1.0, 10.0, 50.0, 286.0],
                    help='reference rates, Hz (each ≤ the gyro rate, 286 Hz)')
    ap.add_argument('--runs', type=int, default=5, help='runs per rate (default 5)')
    ap.add_argument('--duration', type=float, default=360.0, help='trial length, s (360)')
    ap.add_argument('--correlation-time', type=float, default=0.02,
                    help='correlation time of the reference error, s (0.02; 0: white)')
    ap.add_argument('--white-runs', type=int, default=3,
                    help='runs with a white reference at the highest rate (0: none)')
    ap.add_argument('--threads', type=int, default=1, help='BLAS threads per process (1)')
    ap.add_argument('--seed', type=int, default=0, help='seed of the trial')
    ap.add_argument('--json', metavar='FILE', help='write the result as JSON')
    ap.add_argument('--report', metavar='FILE', help='write the tables as markdown')
    ap.add_argument('--keep', metavar='DIR', help='write the bags into DIR and keep them')
    ap.add_argument('--force', action='store_true', help='overwrite existing outputs')
    args = ap.parse_args(argv)
    try:
        if args.runs < 1 or args.white_runs < 0 or args.threads < 1:
            raise ValueError('--runs and --threads must be ≥ 1, --white-runs ≥ 0')
        if not (args.duration >= 60.0) or args.correlation_time < 0:
            raise ValueError('--duration must be ≥ 60 s and --correlation-time ≥ 0')
        if any(not (0 < r <= 286.0) for r in args.rates):
            raise ValueError('--rates must be in (0, 286] Hz')
        check_outputs([('--json', args.json, FILE), ('--report', args.report, FILE),
                       ('--keep', args.keep, DIRECTORY)], [], args.force)
    except ValueError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 2

    def say(text):
        print(text, flush=True)
    env = dict(os.environ)
    for name in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS'):
        env[name] = str(args.threads)
    load = os.getloadavg() if hasattr(os, 'getloadavg') else (float('nan'),) * 3
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix='refrate_'))
    cases = []
    try:
        work.mkdir(parents=True, exist_ok=True)
        model = work / 'model.yaml'
        model.write_text(model_text())
        say(f'{PROG}: writing the bags ({args.duration:g} s, 286 Hz gyro) into {work}')
        bags = write_bags(work / 'correlated', args.rates, args.duration, seed=args.seed,
                          correlation_time=args.correlation_time)
        plan = [(f"{b['rate_hz']:.3g} Hz", b, args.runs) for b in bags.values()]
        if args.white_runs:
            top = max(args.rates)
            white = write_bags(work / 'white', [top], args.duration, seed=args.seed)
            plan.append((f"{white[top]['rate_hz']:.3g} Hz, white", white[top], args.white_runs))
        for label, b, runs in plan:
            say(f"  {label}: {b['fixes']} fixes, {runs} run(s)")
            c = _case(b['bag'], model, runs, env, work, say)
            c.update(label=label, fixes=b['fixes'], rate_hz=b['rate_hz'])
            cases.append(c)
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    res = {'config': {'rates': args.rates, 'runs': args.runs, 'duration_s': args.duration,
                      'correlation_time_s': args.correlation_time,
                      'white_runs': args.white_runs, 'threads': args.threads, 'seed': args.seed,
                      'gyro_rate_hz': 286.0, 'boresight_rad': BORESIGHT.tolist()},
           'load_average': list(load), 'cpus': os.cpu_count(), 'cases': cases}
    corr = [c for c in cases if 'white' not in c['label']]
    if len(corr) >= 2:
        lo, hi = corr[0], corr[-1]
        res['growth'] = {
            'from': lo['label'], 'to': hi['label'], 'fixes': hi['fixes'] / lo['fixes'],
            **{f'{t}_{q}': hi[t][k]['median'] / lo[t][k]['median']
               for t in ('discrepancy', 'calibrate_bag')
               for q, k in (('wall', 'wall_s'), ('peak', 'peak_mb'))}}
        res['target'] = {'label': hi['label'],
                         'ratio': hi['discrepancy']['ratio_to_raw']['median']}
    text = tables(res)
    print(text)
    try:
        if args.json:
            write_json(args.json, res, indent=1)
        if args.report:
            cmd = ' '.join([PROG] + (argv if argv is not None else sys.argv[1:]))
            write_text(args.report, f'# {PROG}\n\n```bash\n{cmd}\n```\n\n{text}\n')
    except OSError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
