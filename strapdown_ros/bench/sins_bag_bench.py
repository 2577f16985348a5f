"""
Measure the wall time of the whole ``sins_bag`` command beside the raw read of the same bag.

The command ``sins_bag_bench``; both are measured in the same run (printed; nothing is
asserted).

    sins_bag_bench BAG [--navigation-profile NAME | --params FILE] [-p NAME:=VALUE ...]
                   [--runs N] [--cold] [--json FILE]

Each run, alternately:

* **raw read**: a separate Python process opens BAG with rosbags' ``AnyReader`` and iterates
  over every record of every topic (no decoding): its whole wall time (interpreter start and the
  rosbags import included) and the time of the iteration alone;
* **sins_bag**: the command ``sins_bag BAG --output OUT.csv`` with the parameters given, as a user
  runs it: the whole wall time (start-up, loading the compiled kernels from numba's cache,
  reading, processing, writing the CSV).

``--navigation-profile NAME`` writes the sins_node parameters of a bag from
``record_sim -p profile:=NAME`` (navigation on, the profile's exact initial position, velocity
and attitude; every other parameter at its default).  ``--cold`` adds one sins_bag run with an
empty numba cache (``NUMBA_CACHE_DIR`` set to a new directory): the first run after an install,
compilation included.  The attitude-only path of the library (no covariance) is timed in
process too: 360 000 intervals through the compiled kernel and through the numpy path, beside
the path with covariance.

Every figure: median and min–max of ``--runs`` (default 5), the load average at the start.
The figure of merit is the ratio of the medians, sins_bag / raw iteration, and sins_bag / raw
read process.  Exit 0; 2 for bad arguments.
"""
from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time

import numpy as np

from strapdown_ros import earth as G
from strapdown_ros.attitude import kernel as attitude_kernel
from strapdown_ros.attitude.integrator import AttitudeIntegrator
from strapdown_ros.bench.stats import median_range, stats
from strapdown_ros.cli import check_outputs, FILE, OneLineParser, write_text
from strapdown_ros.motion.earth_profiles import navigation_profile_from_config
from strapdown_ros.motion.profiles import ConingProfile
from strapdown_ros.rotation import to_ros_xyzw
from strapdown_ros.sensors import NAVIGATION_GRADE_GYRO

TARGET_RATIO = 2.0                 # target: sins_bag within 2× the raw read

RAW_READ = """
import sys, time
t0 = time.perf_counter()
from pathlib import Path
from rosbags.highlevel import AnyReader
with AnyReader([Path(sys.argv[1])]) as rd:
    t1 = time.perf_counter()
    n = 0
    for _ in rd.messages():
        n += 1
t2 = time.perf_counter()
print(n, t2 - t1, t2 - t0)
"""


def navigation_parameters(profile: str, path: Path) -> Path:
    """
    Write sins_node parameters with navigation from a profile's exact initial state.

    Parameters
    ----------
    profile : str
        Navigation profile of :mod:`strapdown_ros.motion.earth_profiles`.
    path : pathlib.Path
        ROS 2 parameter YAML to write.

    Returns
    -------
    pathlib.Path
        ``path``.

    """
    prof = navigation_profile_from_config({'profile': profile})
    t0 = np.zeros(1)
    r0, w0 = prof.position(t0)[0], prof.velocity(t0)[0]
    lat, lon, h = G.ecef_to_geodetic(r0)
    enu = G.enu_rotation(lat, lon)

    def fl(xs):
        return '[' + ', '.join(repr(float(x)) for x in xs) + ']'
    path.write_text('sins_node:\n  ros__parameters:\n    navigation: true\n'
                    f'    initial_position: {fl([np.degrees(lat), np.degrees(lon), h])}\n'
                    f'    initial_velocity: {fl(enu.T @ w0)}\n'
                    f'    initial_orientation: {fl(to_ros_xyzw(prof.attitude_ecef(t0)[0]))}\n')
    return path


def raw_read(bag: str) -> dict:
    """
    Time one raw-read process over a bag (rosbags ``AnyReader``, no decoding).

    Parameters
    ----------
    bag : str
        rosbag2 bag.

    Returns
    -------
    dict
        Records, iteration time, in-process total and whole wall time, s.

    """
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, '-c', RAW_READ, bag], capture_output=True, text=True,
                         check=True)
    wall = time.perf_counter() - t0
    n, it, total = out.stdout.split()
    return {'records': int(n), 'iteration_s': float(it), 'process_s': float(total), 'wall_s': wall}


def sins_bag_run(bag: str, args: list, out: Path, env: dict | None = None) -> dict:
    """
    Time one whole ``sins_bag`` command with CSV output, as a user runs it.

    Parameters
    ----------
    bag : str
        rosbag2 bag.
    args : list of str
        Further ``sins_bag`` arguments (parameters).
    out : pathlib.Path
        CSV to write.
    env : dict, optional
        Environment of the process (e.g. an empty numba cache).

    Returns
    -------
    dict
        Wall time, s, and the command's summary line.

    Raises
    ------
    RuntimeError
        When ``sins_bag`` exits with an error.

    """
    script = Path(sys.executable).parent / 'sins_bag'       # the console script, as a user runs it
    head = ([str(script)] if script.exists()
            else [sys.executable, '-m', 'strapdown_ros.tools.sins_bag'])
    cmd = head + [bag, '--output', str(out), '--force', '--quiet'] + args
    t0 = time.perf_counter()
    res = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if res.returncode != 0:
        raise RuntimeError(f'sins_bag exited {res.returncode}: {res.stderr.strip()[-300:]}')
    return {'wall_s': wall, 'summary': res.stdout.splitlines()[0] if res.stdout else ''}


def attitude_only_runs(runs: int) -> dict:
    """
    Time 360 000 intervals through ``AttitudeIntegrator`` in one push, three ways.

    1 h at 100 Hz of coning motion: attitude only compiled, attitude only numpy, and with
    covariance compiled.

    Parameters
    ----------
    runs : int
        Runs of each.

    Returns
    -------
    dict
        Wall times of every run, s, per way, and whether the compiled kernel is available.

    """
    t = np.arange(360_001) * 0.01
    prof = ConingProfile(0.087, 1.0)
    inc = prof.delta_theta(t[:-1], t[1:])
    q0 = prof.attitude(t[:1])[0]
    before = os.environ.get(attitude_kernel.ENV)
    attitude_kernel.warm_up()                     # numba's cache loaded before the clock starts
    res: dict = {'attitude_only_compiled_s': [], 'attitude_only_numpy_s': [],
                 'with_covariance_compiled_s': []}
    try:
        for _ in range(runs):
            for key, kernel, cov in (('attitude_only_compiled_s', 'auto', False),
                                     ('attitude_only_numpy_s', 'numpy', False),
                                     ('with_covariance_compiled_s', 'auto', True)):
                os.environ[attitude_kernel.ENV] = kernel
                integ = AttitudeIntegrator('2', q0, 0.0, nominal_period=0.01,
                                           gyro=NAVIGATION_GRADE_GYRO, propagate_covariance=cov)
                t0 = time.perf_counter()
                integ.push(inc, t[1:])
                res[key].append(time.perf_counter() - t0)
    finally:
        if before is None:
            os.environ.pop(attitude_kernel.ENV, None)
        else:
            os.environ[attitude_kernel.ENV] = before
    res['compiled_available'] = attitude_kernel.available()
    return res


def bag_bytes(bag) -> int:
    """
    Return the size of a bag (a directory: all its files).

    Parameters
    ----------
    bag : str or pathlib.Path
        The bag.

    Returns
    -------
    int
        Size, bytes.

    """
    p = Path(bag)
    if p.is_dir():
        return sum(f.stat().st_size for f in p.rglob('*') if f.is_file())
    return p.stat().st_size


def main(argv=None) -> int:
    """
    Run ``sins_bag_bench``.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name; ``sys.argv[1:]`` when None.

    Returns
    -------
    int
        0; bad arguments exit 2 with one line on stderr.

    """
    ap = OneLineParser(prog='sins_bag_bench', description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('bag', help='rosbag2 bag (e.g. record_sim OUT --duration 3600 '
                                '-p profile:=coordinated_turn)')
    ap.add_argument('--navigation-profile', metavar='NAME',
                    help='navigation on, initial state of this record_sim profile')
    ap.add_argument('--params', metavar='FILE', help='sins_node parameter YAML for sins_bag')
    ap.add_argument('-p', '--param', action='append', default=[], metavar='NAME:=VALUE',
                    help='sins_bag parameter override (repeatable)')
    ap.add_argument('--runs', type=int, default=5, help='alternating runs (default 5)')
    ap.add_argument('--cold', action='store_true',
                    help='one more sins_bag run with an empty numba cache')
    ap.add_argument('--json', metavar='FILE', help='write the figures to this JSON file '
                    '(documented run: doc/results/sins_bag_bench/sins_bag_bench.json)')
    ap.add_argument('--force', action='store_true', help='overwrite an existing --json')
    args = ap.parse_args(argv)
    if args.runs < 1:
        ap.error('--runs must be >= 1')
    if not Path(args.bag).exists():
        ap.error(f'{args.bag} does not exist')
    try:                                        # the tools' one output rule
        check_outputs([('--json', args.json, FILE)],
                      [('bag', args.bag), ('--params', args.params)], args.force)
    except ValueError as exc:
        ap.error(str(exc))
    if args.navigation_profile and args.params:
        ap.error('--navigation-profile and --params exclude each other')
    if args.params and not Path(args.params).is_file():
        ap.error(f'{args.params} does not exist')
    load = os.getloadavg() if hasattr(os, 'getloadavg') else (math.nan,) * 3
    cpus = os.cpu_count()
    busy = load[0] > 0.5 * (cpus or 1)
    print(
        f'sins_bag_bench: load average at start {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} '
        f"({cpus} CPUs){' — the machine is busy: absolute times are inflated' if busy else ''}",
        file=sys.stderr, flush=True)
    with tempfile.TemporaryDirectory(prefix='sins_bag_bench_') as tmp:
        tmp = Path(tmp)
        extra = []
        if args.navigation_profile:
            try:
                nav = navigation_parameters(args.navigation_profile, tmp / 'nav.yaml')
                extra = ['--params', str(nav)]
            except ValueError as exc:
                ap.error(str(exc))
        elif args.params:
            extra = ['--params', args.params]
        for item in args.param:
            extra += ['-p', item]
        out = tmp / 'out.csv'
        try:
            sins_bag_run(args.bag, extra, out)          # warm: numba's cache, the page cache
        except RuntimeError as exc:
            ap.error(str(exc))
        raw_read(args.bag)
        raws, sins = [], []
        for k in range(args.runs):
            order = (raw_read, sins_bag_run) if k % 2 == 0 else (sins_bag_run, raw_read)
            for fn in order:
                if fn is raw_read:
                    raws.append(raw_read(args.bag))
                else:
                    sins.append(sins_bag_run(args.bag, extra, out))
            print(f"  run {k + 1}/{args.runs}: raw read {raws[-1]['iteration_s']:.2f} s "
                  f"(process {raws[-1]['wall_s']:.2f} s), sins_bag {sins[-1]['wall_s']:.2f} s",
                  file=sys.stderr, flush=True)
        cold = None
        if args.cold:
            env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp / 'numba_cache'))
            cold = sins_bag_run(args.bag, extra, out, env=env)
        rows = sum(1 for _ in open(out, encoding='utf-8')) - 1
    att = attitude_only_runs(args.runs)
    res = {
        'bag': str(args.bag),
        'bag_bytes': bag_bytes(args.bag),
        'sins_bag_args': extra,
        'load_average_start': list(load),
        'cpus': cpus,
        'runs': args.runs,
        'sins_bag_shown': (
            f'--params <{args.navigation_profile} initial state>'
            if args.navigation_profile
            else ' '.join(extra)
        ),
        'records': raws[0]['records'],
        'csv_rows': rows,
        'summary': sins[0]['summary'],
        'raw_iteration_s': stats([r['iteration_s'] for r in raws]),
        'raw_process_s': stats([r['wall_s'] for r in raws]),
        'sins_bag_s': stats([r['wall_s'] for r in sins]),
        'cold_sins_bag_s': cold['wall_s'] if cold else None,
        'attitude_only': {k: (stats(v) if isinstance(v, list) else v) for k, v in att.items()},
    }
    res['ratio_to_iteration'] = res['sins_bag_s']['median'] / res['raw_iteration_s']['median']
    res['ratio_to_process'] = res['sins_bag_s']['median'] / res['raw_process_s']['median']
    res['ratios_per_run'] = [s['wall_s'] / r['iteration_s'] for s, r in zip(sins, raws)]
    res['target_ratio'] = TARGET_RATIO
    res['meets_target'] = res['ratio_to_iteration'] <= TARGET_RATIO
    print(render(res))
    if args.json:
        write_text(args.json, json.dumps(res, indent=2) + '\n')
    return 0


def render(res: dict) -> str:
    """
    Render the markdown text of the run.

    Parameters
    ----------
    res : dict
        The run's result.

    Returns
    -------
    str
        The markdown.

    """
    a = res['attitude_only']
    lines = [
        f"## sins_bag on {res['bag']} ({res['records']} records, {res['bag_bytes'] / 1e6:.0f} MB; "
        f"{res['csv_rows']} CSV rows)",
        '',
        f"Load average at start {res['load_average_start'][0]:.2f} on {res['cpus']} CPUs; "
        f"{res['runs']} alternating runs, median (min–max).",
        '',
        '| command | wall time, s |',
        '|---|---|',
        '| raw read: rosbags AnyReader over every record (iteration) | '
        f"{median_range(res['raw_iteration_s'], '.2f')} |",
        f"| raw read: the whole process | {median_range(res['raw_process_s'], '.2f')} |",
        f"| `sins_bag BAG {res['sins_bag_shown']} --output OUT.csv` (whole command) | "
        f"{median_range(res['sins_bag_s'], '.2f')} |",
    ]
    if res['cold_sins_bag_s'] is not None:
        lines.append('| sins_bag, empty numba cache (first run after install) | '
                     f"{res['cold_sins_bag_s']:.2f} |")
    r = res['ratio_to_iteration']
    per = res['ratios_per_run']
    lines += [
        '',
        f'sins_bag / raw read: **{r:.2f}×** the iteration (per run {min(per):.2f}–'
        f"{max(per):.2f}×), {res['ratio_to_process']:.2f}× the raw-read process; the target "
        f"≤ {res['target_ratio']:g}× the raw read is "
        f"{'met' if res['meets_target'] else 'NOT met'}.",
        '',
        f"sins_bag's summary: {res['summary']}",
        '',
        'Attitude-only path of the library (360 000 intervals, algorithm 2, one push; '
        f"compiled kernel {'available' if a['compiled_available'] else 'NOT available'}):",
        '',
        '| path | s |',
        '|---|---|',
        f"| attitude only, compiled | {median_range(a['attitude_only_compiled_s'], '.3f')} |",
        '| attitude only, numpy (STRAPDOWN_KERNEL=numpy) | '
        f"{median_range(a['attitude_only_numpy_s'], '.3f')} |",
        f"| with covariance, compiled | {median_range(a['with_covariance_compiled_s'], '.3f')} |",
    ]
    c, n = a['attitude_only_compiled_s']['median'], a['with_covariance_compiled_s']['median']
    speedup = a['attitude_only_numpy_s']['median'] / c
    lines += ['', f'The attitude-only path takes {c / n:.2f}× the time of the path with '
              'covariance '
              f"({'faster' if c < n else 'not faster'}); the numpy form takes {speedup:.1f}× "
              "the compiled one's time."]
    return '\n'.join(lines)


if __name__ == '__main__':
    sys.exit(main())
