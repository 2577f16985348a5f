"""
Measure the speed of the SINS core, against peers, and of ``sins_node`` over loopback.

The command ``sins_bench``; figures are printed, nothing is asserted.

1. **Core**: one hour of 100 Hz gyro and 300 Hz accelerometer increments (360 000 gyro
   intervals) through algorithm ``--algorithm`` with covariance propagation (``random_constant``
   and ``004``, alternately) and accelerometer binning, pushed in 60 s blocks.  Data generation is
   not timed.
2. **Peers** (:mod:`strapdown_ros.bench.core_peers`): the same 360 000 intervals with the
   one-plus-previous coning term through strapdown_ros (covariance included), pyins's compiled
   kernel and a 20-line compiled quaternion loop, in turn within each run; ratios per run.
3. **Node** (``--node-seconds S``, default 20; 0 skips): a separate ``sins_node`` process fed at
   ``--node-rate`` Hz (default 2000) over loopback by a publisher that sleeps between 2 ms bursts;
   accepted, dropped and missing counts from the node's /diagnostics, outputs received back.

Every figure is the median and min–max of ``--runs`` (≥ 5 by default) runs, with the load
average at the start.  Absolute times vary from machine to machine and with the load; ratios
measured in one run are the comparable figures.  Exit 0; 2 for bad arguments.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import numpy as np

from strapdown_ros.attitude import kernel as attitude_kernel
from strapdown_ros.attitude.coning import algorithm_names
from strapdown_ros.attitude.increment_sums import IncrementAccumulator
from strapdown_ros.attitude.integrator import AttitudeIntegrator
from strapdown_ros.bench.core_peers import peer_runs
from strapdown_ros.bench.stats import median_range, stats
from strapdown_ros.cli import check_outputs, FILE, OneLineParser, write_text
from strapdown_ros.motion.profiles import ConingProfile, STANDARD_GRAVITY
from strapdown_ros.sensors import NAVIGATION_GRADE_GYRO

PYINS_RATIO_TARGET = 1.0          # at least as fast as pyins's compiled kernel
COMPILED_RATIO_TARGET = 5.0       # within 5× of a compiled quaternion loop


def coning_data(hours: float = 1.0):
    """
    Generate the increments of the core benchmark: coning motion with gravity.

    Parameters
    ----------
    hours : float, optional
        Length of the data, h.

    Returns
    -------
    tuple
        (profile, gyro edges tg (n+1,) s, accel edges ta (3n+1,) s, Δθ (n, 3) rad,
        Δv (3n, 3) m/s): 100 Hz gyro, 300 Hz accelerometer.

    """
    prof = ConingProfile(0.087, 1.0, gravity=(0.0, 0.0, STANDARD_GRAVITY))
    n_g = int(round(hours * 3600 * 100))
    tg = np.arange(n_g + 1) * 0.01
    ta = np.arange(3 * n_g + 1) / 300.0
    return prof, tg, ta, prof.delta_theta(tg[:-1], tg[1:]), prof.delta_v(ta[:-1], ta[1:])


def core_run(data, algorithm: str = '2', covariance_model: str = 'random_constant',
             block: int = 6000) -> dict:
    """
    Time one pass of the attitude core and the Δv binning over ``data``.

    Parameters
    ----------
    data : tuple
        Result of :func:`coning_data`.
    algorithm : str, optional
        Coning algorithm name.
    covariance_model : str, optional
        ``'random_constant'`` or ``'004'``.
    block : int, optional
        Gyro increments per ``push``.

    Returns
    -------
    dict
        Wall time in s, real-time ratio, ns per gyro interval, counts.

    """
    prof, tg, ta, dth, dv = data
    n_g = len(dth)
    integ = AttitudeIntegrator(algorithm, prof.attitude(0.0), 0.0, gyro=NAVIGATION_GRADE_GYRO,
                               covariance_model=covariance_model)
    acc = IncrementAccumulator()
    t0 = time.perf_counter()
    for k in range(0, n_g, block):
        out = integ.push(dth[k:k + block], tg[k + 1:k + block + 1])
        acc.add(dv[3 * k:3 * (k + block)], ta[3 * k + 1:3 * (k + block) + 1])
        edges = np.concatenate([[out.stamps[0] - out.interval[0]], out.stamps])
        acc.take_many(edges)
    wall = time.perf_counter() - t0
    return {'algorithm': algorithm, 'covariance_model': covariance_model, 'gyro_intervals': n_g,
            'accel_intervals': 3 * n_g, 'updates': integ.updates, 'wall_s': wall,
            'real_time_ratio': n_g * 0.01 / wall, 'ns_per_gyro_interval': wall / n_g * 1e9}


def core_benchmark(algorithm: str = '2', hours: float = 1.0,
                   covariance_model: str = 'random_constant', repeats: int = 3) -> dict:
    """
    Return the best of ``repeats`` passes of :func:`core_run` (``main`` reports medians).

    Parameters
    ----------
    algorithm : str, optional
        Coning algorithm name.
    hours : float, optional
        Length of the data, h.
    covariance_model : str, optional
        ``'random_constant'`` or ``'004'``.
    repeats : int, optional
        Passes.

    Returns
    -------
    dict
        The fastest pass.

    """
    data = coning_data(hours)
    runs = [core_run(data, algorithm, covariance_model) for _ in range(repeats)]
    return min(runs, key=lambda r: r['wall_s'])


def main(argv=None):
    """
    Run ``sins_bench``.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name; ``sys.argv[1:]`` when None.

    Returns
    -------
    int
        0 on success, 2 for bad arguments or outputs.

    """
    argv = sys.argv[1:] if argv is None else argv
    ap = OneLineParser(prog='sins_bench', description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--algorithm', default='2')
    ap.add_argument('--hours', type=float, default=1.0)
    ap.add_argument('--runs', type=int, default=5, help='runs of every figure (default 5)')
    ap.add_argument('--no-peers', action='store_true',
                    help='skip the pyins / compiled-loop comparison')
    ap.add_argument('--node-seconds', type=float, default=20.0)
    ap.add_argument('--node-rate', type=float, default=2000.0)
    ap.add_argument('--json', help='write the figures to this JSON file '
                    '(documented run: doc/results/sins_bench/sins_bench.json)')
    ap.add_argument('--force', action='store_true', help='overwrite existing outputs')
    args = ap.parse_args(argv)
    if args.algorithm not in algorithm_names():
        ap.error(
            f'--algorithm {args.algorithm!r} is not valid; valid values:'
            f" {', '.join(algorithm_names())}"
        )
    if not (math.isfinite(args.hours) and 0 < args.hours <= 24):
        ap.error(f'--hours must be in (0, 24], got {args.hours}')
    if not 1 <= args.runs <= 100:
        ap.error(f'--runs must be in [1, 100], got {args.runs}')
    if not (math.isfinite(args.node_seconds) and 0 <= args.node_seconds <= 3600):
        ap.error(f'--node-seconds must be in [0, 3600], got {args.node_seconds}')
    if not (math.isfinite(args.node_rate) and 1 <= args.node_rate <= 100000):
        ap.error(f'--node-rate must be in [1, 100000], got {args.node_rate}')
    try:
        check_outputs([('--json', args.json, FILE)], [], args.force)
    except ValueError as exc:
        ap.error(str(exc))

    load = os.getloadavg()
    res: dict = {'load_at_start': list(load), 'cpu_count': os.cpu_count(), 'runs': args.runs}
    lines = [
        f"$ sins_bench {' '.join(argv)}".rstrip(),
        (
            f'load average at start {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()}'
            f' cores; median (min–max) of {args.runs} runs; absolute times vary from machine to'
            ' machine, ratios are measured in one run'
        ),
    ]
    res['compiled_kernel'] = attitude_kernel.available()
    lines.append('attitude core: ' +
                 ('compiled block kernel (numba)' if res['compiled_kernel'] else
                  'vectorised numpy path (numba absent, or STRAPDOWN_KERNEL=numpy)'))
    data = coning_data(args.hours)
    core = {'random_constant': [], '004': []}
    for m in core:                                   # compilation (or numba's cache) is not timed
        core_run(coning_data(0.001), args.algorithm, m)
    for _ in range(args.runs):                       # the two covariance models alternately
        for m in core:
            core[m].append(core_run(data, args.algorithm, m))
    res['core'] = core
    lines += [
        '',
        (
            '| core: 360 000 gyro + 1 080 000 accel intervals | wall, s | × real time | ns per'
            ' gyro interval |'
        ),
        '|---|---:|---:|---:|',
    ]
    for m, runs in core.items():
        lines.append(
            f'| algorithm {args.algorithm}, covariance `{m}` |'
            f" {median_range(stats([r['wall_s'] for r in runs]), '.3f')} |"
            f" {median_range(stats([r['real_time_ratio'] for r in runs]), '.0f')} |"
            f" {median_range(stats([r['ns_per_gyro_interval'] for r in runs]), '.0f')} |"
        )
    if not args.no_peers:
        prof, tg, _, dth, _ = data
        peers = peer_runs(dth, tg, prof.attitude(0.0), runs=args.runs)
        res['peers'] = peers
        rows = peers['runs']
        a = stats([r['strapdown_ros_s'] for r in rows])
        b = stats([r['pyins_s'] for r in rows])
        bapi = stats([r['pyins_api_s'] for r in rows])
        c = stats([r['compiled_loop_s'] for r in rows])
        rb = stats([r['ratio_to_pyins'] for r in rows])
        rc = stats([r['ratio_to_compiled'] for r in rows])
        rapi = stats([r['strapdown_ros_s'] / r['pyins_api_s'] for r in rows
                      if math.isfinite(r['pyins_api_s'])])
        diff = max((r.get('final_attitude_difference_rad', math.nan) for r in rows),
                   default=math.nan)
        lines += [
            '',
            (
                f"| {peers['intervals']} Δθ intervals, one-plus-previous coning term | wall, s | "
                'strapdown_ros ÷ this |'
            ),
            '|---|---:|---:|',
            f"| A strapdown_ros core, covariance included | {median_range(a, '.3f')} | 1 |",
            (
                '| B pyins 1.0.1 compiled kernel (coning term in numpy, as its API computes it) |'
                f" {median_range(b, '.3f')} | {median_range(rb, '.2f')} |"
            ),
            (
                '| pyins public API around that kernel (pandas in and out), for information |'
                f" {median_range(bapi, '.3f')} | "
                f"{median_range(rapi, '.2f')} |"
            ),
            (
                f"| C compiled 20-line quaternion loop (numba) | {median_range(c, '.4f')} |"
                f" {median_range(rc, '.1f')} |"
            ),
            '',
        ]
        if rb['n']:
            lines.append(f"A ÷ B median {rb['median']:.2f} — target ≤ {PYINS_RATIO_TARGET:g} "
                         f"{'met' if rb['median'] <= PYINS_RATIO_TARGET else 'NOT met'}.")
        if rc['n']:
            lines.append(
                f"A ÷ C median {rc['median']:.1f} — target ≤ {COMPILED_RATIO_TARGET:g}"
                f" {'met' if rc['median'] <= COMPILED_RATIO_TARGET else 'NOT met'}; the final"
                f' attitudes of A and C differ by {diff:.1e} rad (same mathematics, independent'
                ' code).'
            )
        if not (b['n'] and c['n']):
            lines.append("(pyins or numba is not installed: pip install 'strapdown_ros[bench]')")
    if args.node_seconds > 0:
        # the ROS part (rclpy): imported only when the loopback figure is asked for
        from strapdown_ros.bench.ros.loopback_bench import run_loopback
        nodes = []
        for _ in range(args.runs):
            nodes.append(run_loopback(args.node_rate, args.node_seconds, args.algorithm))
        res['node'] = nodes
        lost = stats([n['sent'] - n['accepted_by_node'] for n in nodes])
        ach = stats([n['achieved_input_hz'] for n in nodes])
        out = stats([
            n['attitude_outputs_received'] / max(n['attitude_outputs_expected'], 1) for n in nodes
        ])
        lines += [
            '',
            (
                f'| sins_node in its own process, {args.node_rate:g} Hz Δθ for'
                f' {args.node_seconds:g} s over loopback (paced publisher) | median (min–max) |'
            ),
            '|---|---:|',
            f"| achieved input rate, Hz | {median_range(ach, '.0f')} |",
            f"| messages lost (sent − accepted by the node) | {median_range(lost, '.0f')} |",
            f"| attitudes received back ÷ expected | {median_range(out, '.4f')} |",
        ]
    text = '\n'.join(lines)
    print(text)
    res['text'] = text
    if args.json:
        write_text(args.json, json.dumps(res, indent=2, default=float))
    return 0


if __name__ == '__main__':
    sys.exit(main())
