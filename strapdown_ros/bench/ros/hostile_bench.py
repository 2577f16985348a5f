"""
hostile_bench: every hostile message of issue 27 into every node and offline tool.

    hostile_bench [--seeds N] [--positions K] [--surfaces tools,nodes] [--json FILE] [--force]

The long profile of the fuzz test (``test/tools/test_hostile_tools.py``,
``test/ros/test_hostile_nodes.py``, which draw a bounded sample of it with a fixed seed): for
each of ``--seeds`` clean recordings (:func:`~strapdown_ros.bench.hostile_input.clean_recording`)
and ``--positions`` places spread over each stream, every kind of
:data:`~strapdown_ros.bench.hostile_input.KINDS` goes into a copy of the recording, and every
surface that takes that stream runs on it: the offline tools in-process on a bag
(:mod:`~strapdown_ros.bench.hostile_tools`), the nodes in-process through their callbacks
(:mod:`~strapdown_ros.bench.ros.hostile_nodes`).  Each run is judged by
:func:`~strapdown_ros.bench.hostile_tools.problems` (no traceback, the clean exit status, the
message counted under its named reason, the estimates within 1σ of the clean run).  It prints the
runs, the failures and the seconds per run per surface, and every failure in full.  Exit 0 (a
benchmark: the figures are the result), 2 for bad arguments.
"""
from __future__ import annotations

import os
from pathlib import Path
import shutil
import sys
import tempfile
import time

import numpy as np

from strapdown_ros.bench.hostile_input import clean_recording, KINDS, streams_with, write_bag
from strapdown_ros.bench.hostile_tools import GYRO_ONLY_TOOLS, problems, run_tool, TOOLS
from strapdown_ros.bench.ros import rate_probe
from strapdown_ros.bench.ros.hostile_nodes import fed_to_nodes, NODES, run_node
from strapdown_ros.bench.stats import median_range, stats
from strapdown_ros.cli import check_outputs, FILE, OneLineParser, write_json

__all__ = ['main']

PROG = 'hostile_bench'


def _positions(n: int, k: int) -> list[int]:
    """Return ``k`` places spread over a stream of ``n`` messages (its ends left out)."""
    return [int(round(x)) for x in np.linspace(6, n - 7, k)]


def _run(args, say) -> dict:
    surfaces = [s for s in args.surfaces.split(',') if s]
    tools = list(TOOLS) if 'tools' in surfaces else []
    nodes = list(NODES) if 'nodes' in surfaces else []
    runs = {s: [] for s in tools + nodes}              # (seconds, problems) per run
    failures: list = []
    work = Path(tempfile.mkdtemp(prefix='hostile_bench.'))
    try:
        for seed in range(args.seed, args.seed + args.seeds):
            rec = clean_recording(seed=seed)
            write_bag(work / 'clean', rec)
            clean = {t: run_tool(t, work / 'clean', work) for t in tools}
            clean.update({n: run_node(n, rec) for n in nodes})
            for s, o in clean.items():
                if o.traceback or o.status != 0:
                    failures.append(f'seed {seed}: {s} fails on the clean recording: '
                                    f'{(o.traceback or o.stderr).strip()[-300:]}')
            shutil.rmtree(work / 'clean')
            say(f'seed {seed}: clean runs done')
            for kind in KINDS:
                n_msgs = len(rec.gyro if kind.stream == 'gyro' else rec.reference)
                for pos in _positions(n_msgs, args.positions):
                    if tools:
                        bag = work / 'hostile'
                        write_bag(bag, streams_with(rec, kind, pos))
                        for t in tools:
                            if t in GYRO_ONLY_TOOLS and kind.stream != 'gyro':
                                continue
                            t0 = time.perf_counter()
                            if t in GYRO_ONLY_TOOLS and kind.family == 'frame':
                                shutil.rmtree(bag)             # sins_bag rejects stray frames
                                write_bag(bag, streams_with(rec, kind, pos, frames_used=False))
                            got = problems(kind, clean[t], run_tool(t, bag, work))
                            runs[t].append((time.perf_counter() - t0, got))
                            failures += [f'seed {seed}, position {pos}: {p}' for p in got]
                        shutil.rmtree(bag)
                    for n in nodes:
                        if not fed_to_nodes(kind, n):
                            continue
                        t0 = time.perf_counter()
                        got = problems(kind, clean[n],
                                       run_node(n, streams_with(rec, kind, pos,
                                                                frames_used=False)))
                        runs[n].append((time.perf_counter() - t0, got))
                        failures += [f'seed {seed}, position {pos}: {p}' for p in got]
                say(f'seed {seed}: {kind.label} done')
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return {'runs': runs, 'failures': failures}


def main(argv=None) -> int:
    """
    Run hostile_bench.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        0 (the figures are the result); 2 for bad arguments (one line on stderr).

    """
    ap = OneLineParser(prog=PROG, description=__doc__.split('\n')[1])
    ap.add_argument('--seeds', type=int, default=1, help='clean recordings (default 1)')
    ap.add_argument('--seed', type=int, default=0, help='the first seed (default 0)')
    ap.add_argument('--positions', type=int, default=3,
                    help='places per stream each kind goes to (default 3)')
    ap.add_argument('--surfaces', default='tools,nodes',
                    help='tools, nodes or both (default tools,nodes)')
    ap.add_argument('--json', metavar='FILE', help='write the figures as JSON')
    ap.add_argument('--force', action='store_true', help='replace an existing --json')
    ap.add_argument('--quiet', action='store_true', help='no progress on stderr')
    args = ap.parse_args(argv)
    try:
        if args.seeds < 1 or args.positions < 1:
            raise ValueError('--seeds and --positions must be >= 1')
        if not set(args.surfaces.split(',')) <= {'tools', 'nodes'} or not args.surfaces:
            raise ValueError(f'--surfaces {args.surfaces!r}: tools, nodes or both')
        check_outputs([('--json', args.json, FILE)], [], args.force)
    except ValueError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 2
    t_start = time.monotonic()

    def say(text):
        if not args.quiet:
            print(f'{PROG}: [{time.monotonic() - t_start:6.1f} s] {text}', file=sys.stderr,
                  flush=True)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    load = os.getloadavg()
    if 'nodes' in args.surfaces:
        rate_probe.ros_init()
    try:
        res = _run(args, say)
    finally:
        if 'nodes' in args.surfaces:
            rate_probe.ros_shutdown()
    wall = time.monotonic() - t_start
    argv_text = ' '.join(sys.argv[1:] if argv is None else argv)
    lines = [f'$ {PROG} {argv_text}'.rstrip(),
             f'load average at start {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on '
             f'{os.cpu_count()} cores; {len(KINDS)} hostile kinds, {args.seeds} clean '
             f'recording(s), {args.positions} place(s) per stream; wall {wall:.0f} s',
             '', '| surface | runs | failures | s per run, median (min–max) |',
             '|---|---:|---:|---|']
    record = {'load_at_start': list(load), 'cpu_count': os.cpu_count(), 'args': vars(args),
              'kinds': [k.label for k in KINDS], 'wall_s': wall, 'surfaces': {}}
    for s, rs in res['runs'].items():
        st = stats([r[0] for r in rs])
        bad = sum(1 for r in rs if r[1])
        lines.append(f'| {s} | {len(rs)} | {bad} | {median_range(st, ".2f")} |')
        record['surfaces'][s] = {'runs': len(rs), 'failures': bad, 'seconds': st}
    total = sum(len(rs) for rs in res['runs'].values())
    lines += ['', f"{total} runs, {len(res['failures'])} failure(s)"]
    lines += [f'  FAIL {f}' for f in res['failures']]
    record['failures'] = res['failures']
    print('\n'.join(lines))
    if args.json:
        write_json(args.json, record)
    return 0


if __name__ == '__main__':
    sys.exit(main())
