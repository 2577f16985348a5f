"""
fleet: calibrate and check many units' recordings on Dask, and follow each unit's effects.

    fleet MANIFEST --out DIR [--scheduler ADDRESS] [--workers N] [--memory-limit MIB]
          [--alpha A] [--level L] [--gyro-method integral|tkachenko] [--namespace NS]
          [--force] [--quiet]

MANIFEST: a CSV with the header ``unit,recording,start_time,model`` (paths relative to the
manifest's folder; ISO 8601 start times, UTC when no zone is given; ``model`` a ROS 2 parameter
file, empty for the defaults), or a folder ``FOLDER/UNIT/START[_ANYTHING][.mcap|.db3]`` with
``model.yaml`` per unit or for the whole folder (START as ``20240501T120000Z`` or
``2024-05-01T12-00-00Z``; other names are skipped and counted).

Each recording is one Dask task (``strapdown_ros.fleet.analysis``): read once, then the
discrepancy workflow (verdict, missing effects), the boresight calibration of ``calibrate_bag``
(with the model the discrepancy found) and the gyro calibration of ``calibrate_gyro_bag``
(002 by default: scale factors, misalignments, biases).  The tasks run on an embedded
LocalCluster of ``--workers`` processes (one thread each) or on the scheduler at
``--scheduler tcp://host:8786`` (its workers must import strapdown_ros and read the recordings at
the same paths).  Memory per task is bounded: each worker runs one task at a time under
``--memory-limit`` MiB (default 2048; Dask restarts a worker beyond 95 % of it and the recording
becomes an error row), and a recording whose estimated peak (from its bag index: 350 MiB +
2000 B per gyro and reference message) exceeds the limit is refused before it is read.

Results are cached in DIR/cache by content hash (the bag's bytes, the model file, the options):
a rerun analyses only what is new or changed.  A recording that fails is one error row with its
reason; the fleet goes on.  The report in DIR: ``effects.csv`` and ``effects.parquet``
(``unit, recording, start_time, effect, parameter, index, value, sigma, verdict``),
``recordings.csv``, ``changes.csv`` (``unit, effect, parameter, index, recording, kind, size,
sigma, p_value``: a jump or a trend, Holm over all unit × effect × component series at family
level ``--level``), ``population.csv``, ``trend_*.png``, ``population_*.png``, ``verdicts.png``
and ``summary.md``.  doc/fleet.md describes them.

DIR is created; an existing fleet directory (it holds ``fleet.json``) is updated in place; any
other non-empty directory needs ``--force``.  Exit status: 0 done (error rows included); 2 bad
arguments, manifest or output directory, or no scheduler at the address (one line on stderr).
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys
import time

from strapdown_ros.cli import check_outputs, DIRECTORY, OneLineParser
from strapdown_ros.fleet.analysis import FleetOptions
from strapdown_ros.fleet.changes import DEFAULT_LEVEL
from strapdown_ros.fleet.cluster import DEFAULT_MEMORY_MIB
from strapdown_ros.fleet.manifest import read_manifest
from strapdown_ros.fleet.report import REPORT_FILES
from strapdown_ros.fleet.run import MARKER, run_fleet
from strapdown_ros.runs.gyro import GyroOptions
from strapdown_ros.streams.rate_increments import RATE_RULES

__all__ = ['main']

PROG = 'fleet'


def _arguments() -> argparse.ArgumentParser:
    ap = OneLineParser(prog=PROG, description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('manifest', metavar='MANIFEST',
                    help='manifest CSV (unit,recording,start_time,model) or a fleet folder')
    ap.add_argument('--out', required=True, metavar='DIR', help='the fleet directory')
    ap.add_argument('--scheduler', metavar='ADDRESS',
                    help='a running Dask scheduler, e.g. tcp://host:8786 (default: a '
                         'LocalCluster on this machine)')
    ap.add_argument('--workers', type=int, default=2,
                    help='LocalCluster worker processes, one task each at a time (default 2)')
    ap.add_argument('--memory-limit', type=float, default=DEFAULT_MEMORY_MIB, metavar='MIB',
                    help='memory of one worker and budget of one task, MiB (default '
                         f'{DEFAULT_MEMORY_MIB:g})')
    ap.add_argument('--alpha', type=float, default=0.01,
                    help='family-wise level of the discrepancy workflow per recording '
                         '(default 0.01)')
    ap.add_argument('--level', type=float, default=DEFAULT_LEVEL,
                    help='family-wise level of the change test over all series (default '
                         f'{DEFAULT_LEVEL:g})')
    ap.add_argument('--gyro-method', choices=('integral', 'tkachenko'), default='integral',
                    help='method of the gyro calibration (default integral, 002)')
    ap.add_argument('--namespace', default='', help='topic namespace of every recording')
    ap.add_argument('--gyro-topic', metavar='TOPIC', help='gyro topic (default imu/delta_theta)')
    ap.add_argument('--reference-topic', metavar='TOPIC',
                    help='attitude reference topic (default: the star camera topics)')
    ap.add_argument('--rate-rule', choices=RATE_RULES, default='trapezoid',
                    help='increments from sensor_msgs/Imu rates (default trapezoid)')
    ap.add_argument('--force', action='store_true',
                    help='write into a non-empty directory that is not a fleet directory')
    ap.add_argument('--quiet', action='store_true', help='no progress on stderr')
    return ap


def _check(args) -> None:
    """Check the arguments and the output directory, before any work."""
    if not 1 <= args.workers <= 256:
        raise ValueError(f'--workers must be in [1, 256], got {args.workers}')
    if not 64 <= args.memory_limit <= 1e7:
        raise ValueError(f'--memory-limit must be in [64, 1e7] MiB, got {args.memory_limit:g}')
    for name in ('alpha', 'level'):
        v = getattr(args, name)
        if not 0.0 < v < 0.5:
            raise ValueError(f'--{name} must be in (0, 0.5), got {v:g}')
    if args.scheduler and not args.scheduler.strip():
        raise ValueError('--scheduler must name an address, e.g. tcp://host:8786')
    out = Path(args.out)
    fleet_dir = out.is_dir() and (out / MARKER).is_file()
    # a fleet directory is updated in place (its cache is the point of a rerun); any other
    # non-empty directory needs --force
    outputs = [('--out', args.out, DIRECTORY, ()) if fleet_dir
               else ('--out', args.out, DIRECTORY)]
    check_outputs(outputs, [('MANIFEST', args.manifest)], args.force)
    entries, _ = read_manifest(args.manifest)
    inputs = [(f'recording of unit {e.unit}', e.path) for e in entries]
    inputs += [(f'model of unit {e.unit}', e.model) for e in entries if e.model]
    check_outputs([('--out', args.out, DIRECTORY, REPORT_FILES)],
                  [('MANIFEST', args.manifest)] + inputs, True)


def main(argv=None) -> int:
    """
    Run the fleet command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        0 done (failed recordings are error rows); 2 bad arguments, manifest, output or
        scheduler (one line on stderr).

    """
    args = _arguments().parse_args(argv)
    t0 = time.perf_counter()

    def say(text):
        if not args.quiet:
            print(f'{PROG}: {text}', file=sys.stderr, flush=True)

    try:
        _check(args)
        options = FleetOptions(
            inputs={'namespace': args.namespace, 'gyro_topic': args.gyro_topic,
                    'reference_topic': args.reference_topic, 'rate_rule': args.rate_rule},
            alpha=args.alpha, gyro=GyroOptions(args.gyro_method))
        run = run_fleet(args.manifest, args.out, args.scheduler, args.workers, args.memory_limit,
                        options, args.level, say)
    except (ValueError, OSError) as exc:
        text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        print(f'{PROG}: error: {text}', file=sys.stderr)
        return 2
    verdicts = ', '.join(f'{n} {v}' for v, n in sorted(run.verdicts.items()))
    print(f'{PROG}: {run.recordings} recording(s): {run.analysed} analysed, {run.cached} from '
          f'the cache, {run.errors} error row(s); verdicts: {verdicts or "none"}')
    print(f'{PROG}: {run.changes} change(s) in {run.series} series (Holm, family level '
          f'{args.level:g}); report in {args.out}: {len(run.files)} files (effects.csv, '
          'changes.csv, summary.md, ...)')
    if run.skipped:
        print(f'{PROG}: {run.skipped} folder entr(y/ies) skipped: not named '
              'START[_ANYTHING][.mcap|.db3]', file=sys.stderr)
    say(f'done in {time.perf_counter() - t0:.1f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
