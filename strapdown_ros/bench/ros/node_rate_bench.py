"""
Measure the highest Δθ rate a node takes without loss, against bare rclpy, and its callback cost.

The command ``node_rate_bench``; the ROS side is ``rate_probe`` (the rates) and
``callback_cost``.

1. **Sustained rate.**  Five processes are started: a bare counting subscriber
   (``strapdown_ros.bench.ros.rate_probe``: same QoS, same executor, same spin loop, a callback
   that only counts; it takes deserialized messages, as a plain rclpy subscriber does), the same
   subscriber taking the serialized bytes (``counting_node_raw``; the package's nodes subscribe
   raw and decode the stamp, vector and frame themselves), ``sins_node``, ``calibrator_node``
   and ``attitude_filter_node`` (sent a camera fix every second as well: the exact attitude, so
   every fix is applied; its first fix, in the first trial, starts the filter — a stall there
   shows as a lost first trial) (``--subjects`` runs fewer).  For each, the rate is bisected on
   a log
   scale between ``--lo`` and ``--hi``: a trial publishes ``rate`` × ``--seconds`` Δθ, paced by
   the wall clock in 2 ms bursts (the publisher sleeps, it does not spin), and passes when the
   subject's own count (its ``/diagnostics``) shows every message received.  Each bisection
   step tries the subjects in turn (A, B, C, D, A, B, …), so load drifts hit all alike; the
   ratios of each node's highest passing rate to the counting subscribers' are formed within one
   repeat.  ``--repeats`` (≥ 5) fresh sets of processes give the median and min–max.
2. **Callback cost** (``--callback-runs``, in this process): ``sins_node``'s Δθ callback called
   directly with serialized messages at 1 kHz stamps, as the executor calls it (the nodes
   subscribe raw) — the hot path alone (decode, validate, append), the amortised cost with the
   block processing (no subscriber: no outputs built), and, for information, with a subscriber of
   ``sins/imu`` and ``sins/attitude`` so that every update is published; ``calibrator_node``'s;
   both again per ``sensor_msgs/Imu`` message with ``gyro_input: imu`` (rows ``*_imu``).
   Median and min–max of the runs, the subjects in turn.

Absolute figures vary from machine to machine and with the load (printed at the start); the
ratios measured in one run are the comparable figures.  Exit 0 (a benchmark); 2 for bad
arguments.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time

from strapdown_ros.attitude.coning import algorithm_names
from strapdown_ros.bench.ros import callback_cost as cost
from strapdown_ros.bench.ros import rate_probe as probe
from strapdown_ros.cli import check_outputs, FILE, OneLineParser, write_text

RATIO_TARGET = 0.9
CALLBACK_TARGET_US = 15.0
#: attitude_filter_node: µs per Δθ at 1 kHz with a fix every second
FILTER_TARGET_US = 50.0
#: the filter's output periods measured, s (0.01: the node's default)
FILTER_OUTPUT_PERIODS = (0.01, 0.1)


def _median_range(s: dict) -> str:
    return '–' if s['n'] == 0 else f"{s['median']:.2f} ({s['min']:.2f}–{s['max']:.2f})"


def parse_args(argv):
    """
    Parse and check the command line of ``node_rate_bench``.

    Parameters
    ----------
    argv : list of str
        Arguments without the program name.

    Returns
    -------
    argparse.Namespace
        The options.

    """
    ap = OneLineParser(prog='node_rate_bench', description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--seconds', type=float, default=5.0,
                    help='length of one trial, s (default 5)')
    ap.add_argument('--steps', type=int, default=7, help='bisection steps per subject (default 7)')
    ap.add_argument('--repeats', type=int, default=5, help='fresh process sets (default 5)')
    ap.add_argument('--lo', type=float, default=500.0,
                    help='lower end of the search, Hz (default 500)')
    ap.add_argument('--hi', type=float, default=40000.0,
                    help='upper end of the search, Hz (default 40000)')
    ap.add_argument('--algorithm', default='2', help='coning algorithm of sins_node (default 2)')
    ap.add_argument('--callback-runs', type=int, default=5,
                    help='runs of the callback-cost measurement (0: skip)')
    ap.add_argument('--no-rate', action='store_true', help='skip the sustained-rate part')
    ap.add_argument('--subjects', default=','.join(probe.SUBJECTS),
                    help='subjects of the rate part, comma-separated, counting_node first '
                    f"(default: all, {','.join(probe.SUBJECTS)})")
    ap.add_argument('--json', metavar='FILE', help='write the figures as JSON '
                    '(documented run: doc/results/node_rate_bench/node_rate_bench.json)')
    ap.add_argument('--quiet', action='store_true', help='no progress on stderr')
    ap.add_argument('--force', action='store_true', help='overwrite existing outputs')
    args = ap.parse_args(argv)
    if not (math.isfinite(args.seconds) and 0.5 <= args.seconds <= 600):
        ap.error(f'--seconds must be in [0.5, 600], got {args.seconds}')
    if not 1 <= args.steps <= 20:
        ap.error(f'--steps must be in [1, 20], got {args.steps}')
    if not 1 <= args.repeats <= 100:
        ap.error(f'--repeats must be in [1, 100], got {args.repeats}')
    if not 0 <= args.callback_runs <= 100:
        ap.error(f'--callback-runs must be in [0, 100], got {args.callback_runs}')
    if not (0 < args.lo < args.hi <= 1e6):
        ap.error(f'need 0 < --lo < --hi <= 1e6, got {args.lo}, {args.hi}')
    if args.algorithm not in algorithm_names():
        ap.error(
            f'--algorithm {args.algorithm!r} is not valid; valid values:'
            f" {', '.join(algorithm_names())}"
        )
    subjects = [x.strip() for x in args.subjects.split(',') if x.strip()]
    bad = [x for x in subjects if x not in probe.SUBJECTS]
    if bad or not subjects or subjects[0] != 'counting_node' or len(set(subjects)) < len(subjects):
        ap.error(f'--subjects: counting_node first, then any of {", ".join(probe.SUBJECTS[1:])} '
                 'once each')
    args.subjects = tuple(subjects)
    try:
        check_outputs([('--json', args.json, FILE)], [], args.force)
    except ValueError as exc:
        ap.error(str(exc))
    return args


def _stats(values) -> dict:
    v = [x for x in values if x is not None and math.isfinite(x)]
    if not v:
        return {'median': math.nan, 'min': math.nan, 'max': math.nan, 'n': 0}
    return {'median': statistics.median(v), 'min': min(v), 'max': max(v), 'n': len(v)}


def main(argv=None) -> int:
    """
    Run ``node_rate_bench``.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name; ``sys.argv[1:]`` when None.

    Returns
    -------
    int
        0 (a benchmark); bad arguments exit 2 with one line on stderr.

    """
    argv = sys.argv[1:] if argv is None else argv
    args = parse_args(argv)
    t_start = time.monotonic()

    def say(text):
        if not args.quiet:
            print(f'node_rate_bench: [{time.monotonic() - t_start:6.1f} s] {text}',
                  file=sys.stderr, flush=True)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    load = os.getloadavg()
    out = {'load_at_start': list(load), 'cpu_count': os.cpu_count(), 'args': vars(args)}
    lines = [
        f"$ node_rate_bench {' '.join(argv)}".rstrip(),
        (
            f'load average at start {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()}'
            ' cores; absolute figures vary from machine to machine, the ratios are measured in'
            ' one run'
        ),
    ]
    probe.ros_init()
    try:
        if args.callback_runs:
            alg = 'sins_node_alg_' + args.algorithm
            cb = {alg: [], 'sins_node_alg_one_plus_previous': [], 'calibrator_node': [],
                  alg + '_imu': [], 'calibrator_node_imu': []}
            published = {alg: [], 'sins_node_alg_one_plus_previous': []}
            for k in range(args.callback_runs):              # the subjects in turn
                cb[alg].append(cost.callback_cost(args.algorithm))
                cb['sins_node_alg_one_plus_previous'].append(
                    cost.callback_cost('one_plus_previous'))
                cb['calibrator_node'].append(cost.calibrator_callback_cost())
                cb[alg + '_imu'].append(cost.callback_cost(args.algorithm, gyro_input='imu'))
                cb['calibrator_node_imu'].append(cost.calibrator_callback_cost(gyro_input='imu'))
                published[alg].append(cost.callback_cost(args.algorithm, subscribed=True))
                published['sins_node_alg_one_plus_previous'].append(
                    cost.callback_cost('one_plus_previous', subscribed=True))
            say('callback cost measured')
            out['callback'] = cb
            out['callback_published'] = published
            lines += [
                '',
                (
                    'Callback cost per Δθ message, called directly (1 kHz stamps, no'
                    f' accelerometer), median (min–max) of {args.callback_runs} runs:'
                ),
                '',
                (
                    '| node | hot path (decode, validate, append), µs | with block processing, µs'
                    ' | with block processing and every update published, µs |'
                ),
                '|---|---:|---:|---:|',
            ]
            for name, runs in cb.items():
                a = _stats([r['amortised_us'] for r in runs])
                hp = _stats([r.get('hot_path_us') for r in runs])
                pb = _stats([r['amortised_us'] for r in published.get(name, [])])
                hot = _median_range(hp)
                pub = _median_range(pb)
                lines.append(
                    f"| {name} | {hot} | {a['median']:.2f} ({a['min']:.2f}–{a['max']:.2f}) |"
                    f' {pub} |'
                )
            worst = max(statistics.median([r['amortised_us'] for r in runs])
                        for name, runs in cb.items() if not name.endswith('_imu'))
            lines.append(
                f'\nLargest median with block processing per Δθ message {worst:.2f} µs — '
                f'target ≤ {CALLBACK_TARGET_US:g} µs '
                f"{'met' if worst <= CALLBACK_TARGET_US else 'NOT met'}.  In the middle column no"
                ' one '
                'subscribes to the outputs, so none are built; in the last a second node'
                ' subscribes to '
                'sins/imu and sins/attitude and every update is published (an Imu and a '
                'QuaternionStamped per update).  *_imu: per sensor_msgs/Imu message on '
                'imu/data_raw (gyro_input imu; sins_node makes its rate and specific '
                'force into a Δθ and a Δv, the work of two increment messages; the '
                'target is for Δθ messages).'
            )
            filt = {op: [cost.filter_callback_cost(output_period=op)
                         for _ in range(args.callback_runs)] for op in FILTER_OUTPUT_PERIODS}
            say('filter callback cost measured')
            out['filter_callback'] = {str(op): runs for op, runs in filt.items()}
            lines += [
                '', 'attitude_filter_node, per Δθ message called directly (1 kHz stamps, a '
                'camera fix every second, all applied; fix callbacks included), median '
                f'(min–max) of {args.callback_runs} runs:', '',
                '| output_period, s | µs per Δθ | fixes applied | outputs |',
                '|---:|---:|---:|---:|'
            ]
            for op, runs in filt.items():
                a = _stats([r['amortised_us'] for r in runs])
                lines.append(f"| {op:g} | {a['median']:.1f} ({a['min']:.1f}–{a['max']:.1f}) | "
                             f"{runs[-1]['fixes_applied']} | {runs[-1]['outputs']} |")
            for op, runs in filt.items():
                med = statistics.median(r['amortised_us'] for r in runs)
                lines.append(f'\noutput_period {op:g} s: {med:.1f} µs per Δθ — target ≤ '
                             f'{FILTER_TARGET_US:g} µs '
                             f"{'met' if med <= FILTER_TARGET_US else 'NOT met'}.")
        if not args.no_rate:
            reps = []
            for k in range(args.repeats):
                say(f'repeat {k + 1}/{args.repeats}')
                reps.append(
                    probe.rate_repeat(args.lo, args.hi, args.steps, args.seconds, args.algorithm,
                                      say, args.subjects))
            out['rate'] = reps
            lines += [
                '',
                (
                    f'Highest Δθ rate received without loss over {args.seconds:g} s trials'
                    f' (bisection {args.lo:g}–{args.hi:g} Hz, {args.steps} steps, subjects in'
                    f' turn), median (min–max) of {args.repeats} repeats:'
                ),
                '',
                (
                    '| subject | rate, Hz | ratio to the bare counting subscriber | ratio to the'
                    ' raw counting subscriber |'
                ),
                '|---|---:|---:|---:|',
            ]
            for n in args.subjects:
                r = _stats([x['rates_hz'][n] for x in reps])
                cells = []
                for key, ref in (('ratio', 'counting_node'), ('ratio_to_raw',
                                                              'counting_node_raw')):
                    if n == ref:
                        cells.append('1')
                    elif n in reps[0].get(key, {}):
                        q = _stats([x[key][n] for x in reps])
                        cells.append(f"{q['median']:.2f} ({q['min']:.2f}–{q['max']:.2f})")
                    else:
                        cells.append('–')
                lines.append(
                    f"| {n} | {r['median']:.0f} ({r['min']:.0f}–{r['max']:.0f}) | {cells[0]} |"
                    f' {cells[1]} |'
                )
            for n in ('sins_node', 'attitude_filter_node'):
                if n not in args.subjects:
                    continue
                q = _stats([x['ratio'][n] for x in reps])
                first = sum(x['first_trial_passed'][n] for x in reps)
                met = 'met' if q['median'] >= RATIO_TARGET else 'NOT met'
                fix = ', its first fix' if n == 'attitude_filter_node' else ''
                lines.append(
                    f"\n{n} median ratio {q['median']:.2f} ({q['min']:.2f}–{q['max']:.2f}) — "
                    f'target ≥ {RATIO_TARGET:g} {met}; first trial ({args.lo:g} Hz{fix}) '
                    f'without loss in {first} of {len(reps)} repeats.'
                )
                if n in reps[0].get('fixes', {}):
                    fx = [x['fixes'][n] for x in reps]
                    lines.append(
                        f'{n}: camera fixes sent per repeat {[f["sent"] for f in fx]}, applied '
                        f'{[f.get("applied") for f in fx]}, gated {[f.get("gated") for f in fx]}, '
                        f'divergence resets {[f.get("reset") for f in fx]} (its /diagnostics).')
    except RuntimeError as exc:
        print(f'node_rate_bench: error: {exc}', file=sys.stderr)
        return 1
    finally:
        probe.ros_shutdown()
    text = '\n'.join(lines)
    print(text)
    out['text'] = text
    if args.json:
        write_text(args.json, json.dumps(out, indent=2, default=float))
    return 0


if __name__ == '__main__':
    sys.exit(main())
