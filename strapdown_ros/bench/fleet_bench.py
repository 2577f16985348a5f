"""
Measure the fleet on Dask: recordings per minute, the scheduler's overhead, memory; and scale up.

The command ``fleet_bench`` (figures printed, nothing asserted):

1. **Throughput**: a simulated fleet of ``--recordings`` recordings (``--duration`` s each,
   ``--gyro-rate`` Hz Δθ and a camera fix every ``--camera-interval`` s; the simulator's truth
   topics stripped, so each bag holds what a unit records) analysed by the fleet's task
   (:func:`strapdown_ros.fleet.analysis.analyse_recording`: discrepancy, boresight and gyro
   calibration) on a LocalCluster of 1 and of 2 workers, alternately, ``--repeats`` times each:
   recordings per minute of the task phase (the cluster's start-up and the workers' first
   imports are timed apart: a long-lived cluster pays them once).
2. **Scheduler overhead per task**: ``--overhead-tasks`` empty tasks through the same map, wall
   time per task; and, for the real tasks, workers × wall − Σ the time inside the tasks, per
   task.
3. **Memory**: the peak RSS of each worker process (``ru_maxrss``) after the analyses, the peak
   RSS inside each task, and one recording of ``--scale-duration`` s analysed in this process
   ``--scale-runs`` times: the growth of RSS per message of the bag's index, against the bound
   the fleet's task assumes (``BYTES_PER_MESSAGE``).
4. **On paper**: ``--units`` units recording ``--hours`` hours a day in recordings of one hour:
   the data volume, the tasks, the time on N workers — the arithmetic from the measured cost per
   recording (linear in the recording's length between ``--duration`` and ``--scale-duration``)
   and the measured overhead per task.

Every time: median (min–max) of the repeats; the 1-minute load average at the start and the
end (other processes share this machine).  ``--json FILE``, ``--report FILE`` (markdown).
Exit 0; 2 for bad arguments.
"""
from __future__ import annotations

import importlib
import math
import os
from pathlib import Path
import shutil
import sys
import tempfile
import time

from strapdown_ros.bench.stats import median_range, stats
from strapdown_ros.cli import check_outputs, FILE, OneLineParser, write_json, write_text
from strapdown_ros.fleet.analysis import (analyse_recording, BASE_BYTES, BYTES_PER_MESSAGE,
                                          FleetOptions)
from strapdown_ros.fleet.cluster import dask_client, map_tasks, TaskError, worker_memory
from strapdown_ros.fleet.manifest import read_manifest
from strapdown_ros.fleet.simulated import SimulatedUnit, write_fleet
from strapdown_ros.recording import open_reader
from strapdown_ros.text import json_clean

PROG = 'fleet_bench'
#: the topics a unit records (the simulator's truth topics are left out)
UNIT_TOPICS = ('/imu/delta_theta', '/star_camera/attitude_with_covariance')
MIB = 2 ** 20


def _strip(src: Path, dst: Path) -> int:
    """Copy the unit's own topics of a bag (raw CDR) into a new MCAP bag; return its bytes."""
    from rosbags.rosbag2 import StoragePlugin, Writer         # optional extra (tools)
    reader = open_reader(src)
    try:
        with Writer(dst, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin.MCAP) as w:
            conns = {}
            for c in reader.connections:
                if c.topic in UNIT_TOPICS:
                    conns[c.id] = w.add_connection(c.topic, c.msgtype,
                                                   typestore=reader.typestore)
            for c, t, raw in reader.messages(connections=[c for c in reader.connections
                                                          if c.id in conns]):
                w.write(conns[c.id], t, raw)
    finally:
        reader.close()
    return sum(f.stat().st_size for f in dst.rglob('*') if f.is_file())


def _fleet(folder: Path, n: int, duration: float, rate: float, interval: float):
    """Write a fleet of n stripped recordings (n/2 units × 2); return (entries, bytes each)."""
    raw = folder / 'raw'
    units = [SimulatedUnit(f'u{k:03d}', 2) for k in range(max(1, n // 2))]
    manifest, truth = write_fleet(raw, units, duration=duration, gyro_rate=rate,
                                  camera_interval=interval, seed=500)
    lines, sizes = ['unit,recording,start_time,model'], []
    for t in truth[:n]:
        dst = folder / 'bags' / t['recording']
        dst.parent.mkdir(parents=True, exist_ok=True)
        sizes.append(_strip(raw / t['recording'], dst))
        lines.append(f"{t['unit']},bags/{t['recording']},{t['start_time']},")
    shutil.rmtree(raw)
    (folder / 'manifest.csv').write_text('\n'.join(lines) + '\n', encoding='utf-8')
    return read_manifest(folder / 'manifest.csv')[0], sizes


def _noop(k: int) -> int:
    return k


def _warm() -> None:
    """Import what a task imports (the first task of a worker would pay for it)."""
    for name in ('scipy.linalg', 'scipy.stats', 'scipy.optimize', 'rosbags.highlevel',
                 'strapdown_ros.fleet.analysis'):
        importlib.import_module(name)


def _cluster_run(entries, workers: int, overhead_tasks: int) -> dict:
    """One LocalCluster: start it, run the fleet's tasks, the empty tasks, read its memory."""
    t0 = time.perf_counter()
    opts = FleetOptions()
    with dask_client(None, workers) as client:
        t1 = time.perf_counter()
        client.run(_warm)
        tw = time.perf_counter()
        t1, warm = tw, tw - t1
        recs = map_tasks(client, analyse_recording, [(e, opts) for e in entries])
        t2 = time.perf_counter()
        map_tasks(client, _noop, [(k,) for k in range(overhead_tasks)])
        t3 = time.perf_counter()
        rss = worker_memory(client)
    lost = [r for r in recs if isinstance(r, TaskError)]
    ok = [r for r in recs if not isinstance(r, TaskError) and r['status'] == 'ok']
    inside = sum(r['seconds']['total'] for r in ok)
    return {'workers': workers, 'start_s': t1 - t0 - warm, 'warm_s': warm, 'tasks_s': t2 - t1,
            'recordings_per_minute': len(entries) / (t2 - t1) * 60.0,
            'empty_task_ms': (t3 - t2) / max(1, overhead_tasks) * 1e3,
            'overhead_per_task_s': (workers * (t2 - t1) - inside) / max(1, len(ok)),
            'inside_task_s': [r['seconds']['total'] for r in ok],
            'task_peak_rss_mib': [r['memory']['peak_rss_bytes'] / MIB for r in ok],
            'worker_peak_rss_mib': sorted(v / MIB for v in rss.values()),
            'errors': len(recs) - len(ok), 'lost': len(lost),
            'error_reasons': sorted({r['reason'] for r in recs
                                     if not isinstance(r, TaskError) and r['status'] != 'ok'})}


def _scale_run(folder: Path, duration: float, rate: float, interval: float, runs: int) -> dict:
    """One longer recording analysed in this process: cost and memory growth per message."""
    entries, sizes = _fleet(folder, 1, duration, rate, interval)
    analyse_recording(entries[0], FleetOptions())          # imports and caches warm
    recs = [analyse_recording(entries[0], FleetOptions()) for _ in range(runs)]
    ok = [r for r in recs if r['status'] == 'ok']
    n = ok[0]['memory']['index_messages'] if ok else 0
    return {'duration_s': duration, 'bytes': sizes[0], 'index_messages': n,
            'task_s': [r['seconds']['total'] for r in ok],
            'rss_growth_bytes_per_message': [r['memory']['task_increase_bytes'] / max(1, n)
                                             for r in ok],
            'errors': [r['reason'] for r in recs if r['status'] != 'ok']}


def _paper(a, base: dict, scale: dict, overhead_s: float) -> dict:
    """1000 units × 24 h a day: the arithmetic from the measured costs."""
    c1 = base['task_s']['median']
    c2 = stats(scale['task_s'])['median']
    d1, d2 = a.duration, a.scale_duration
    slope = (c2 - c1) / (d2 - d1)
    c0 = c1 - slope * d1
    hour_cost = c0 + slope * 3600.0
    bytes_per_s = scale['bytes'] / d2
    msgs_per_hour = scale['index_messages'] / d2 * 3600.0
    tasks = int(round(a.units * a.hours))
    cpu_s = tasks * (hour_cost + overhead_s)
    out = {'units': a.units, 'hours_per_day': a.hours, 'tasks_per_day': tasks,
           'cost_per_recording_s': {'at_duration': c1, 'at_scale_duration': c2,
                                    'fixed_s': c0, 'per_recorded_s': slope,
                                    'one_hour': hour_cost},
           'bytes_per_recorded_hour': bytes_per_s * 3600.0,
           'data_per_day_bytes': bytes_per_s * 3600.0 * tasks,
           'index_messages_per_hour': msgs_per_hour,
           'task_memory_bound_mib': (BASE_BYTES + BYTES_PER_MESSAGE * msgs_per_hour) / MIB,
           'overhead_per_task_s': overhead_s, 'worker_seconds_per_day': cpu_s,
           'workers_to_keep_up': math.ceil(cpu_s / 86400.0),
           'time_on_workers_h': {str(n): cpu_s / n / 3600.0 for n in a.paper_workers}}
    out['read_rate_per_worker_mb_s'] = bytes_per_s * 3600.0 / hour_cost / 1e6
    return out


def _lines(res: dict) -> list[str]:
    cfg, runs = res['config'], res['runs']
    load = res['load_average']
    out = [f"{PROG}: {cfg['recordings']} recordings of {cfg['duration']:g} s at "
           f"{cfg['gyro_rate']:g} Hz, a fix every {cfg['camera_interval']:g} s "
           f"({res['recording_mib']:.2f} MiB each, the unit's own topics); "
           f"{cfg['repeats']} repeats per cluster size, alternating; load average "
           f'{load[0]:.2f} at the start, {load[1]:.2f} at the end, {res["cpu_count"]} CPUs']
    for w in ('1', '2'):
        r = runs[w]
        out.append(f'  {w} worker(s): {median_range(r["recordings_per_minute"], ".1f")} '
                   f'recordings/min; cluster start {median_range(r["start_s"], ".1f")} s, '
                   f'imports in the workers {median_range(r["warm_s"], ".1f")} s; '
                   f'inside a task {median_range(r["inside_task_s"], ".2f")} s; '
                   f'overhead per task {median_range(r["overhead_per_task_s"], ".2f")} s; '
                   f'empty task {median_range(r["empty_task_ms"], ".1f")} ms; '
                   f'worker peak RSS {median_range(r["worker_peak_rss_mib"], ".0f")} MiB, '
                   f'task peak RSS {median_range(r["task_peak_rss_mib"], ".0f")} MiB')
    sp = res['speedup']
    out.append(f"  2 workers / 1 worker, recordings per minute: {median_range(sp, '.2f')} "
               '(ratio within each alternating pair)')
    sc = res['scale']
    g = stats(sc['rss_growth_bytes_per_message'])
    out.append(f"  one {sc['duration_s']:g} s recording ({sc['index_messages']} messages, "
               f"{sc['bytes'] / MIB:.1f} MiB) in this process: "
               f"{median_range(stats(sc['task_s']), '.1f')} s; RSS growth "
               f"{median_range(g, '.0f')} B per message (the task's bound: "
               f'{BYTES_PER_MESSAGE} B per message + {BASE_BYTES / MIB:.0f} MiB)')
    p = res['paper']
    c = p['cost_per_recording_s']
    out.append(f"  on paper, {p['units']} units × {p['hours_per_day']:g} h a day in 1-h "
               f"recordings: {p['tasks_per_day']} tasks a day; "
               f"{p['bytes_per_recorded_hour'] / MIB:.1f} MiB per recorded hour, "
               f"{p['data_per_day_bytes'] / 2 ** 30:.1f} GiB a day; cost per recording "
               f"{c['fixed_s']:.2f} s + {c['per_recorded_s'] * 1e3:.2f} ms per recorded s = "
               f"{c['one_hour']:.0f} s for 1 h, + {p['overhead_per_task_s']:.2f} s overhead; "
               f"{p['worker_seconds_per_day'] / 3600:.0f} worker-hours a day: "
               f"{p['workers_to_keep_up']} workers keep up; a day's data on "
               + ', '.join(f'{n} workers in {h:.1f} h' for n, h in p['time_on_workers_h'].items())
               + f"; each worker reads {p['read_rate_per_worker_mb_s']:.3f} MB/s; task memory "
               f"bound {p['task_memory_bound_mib']:.0f} MiB for a 1-h recording")
    return out


def main(argv=None) -> int:
    """
    Run ``fleet_bench``.

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
    ap = OneLineParser(prog=PROG, description=__doc__.split('\n\n')[0])
    arg = ap.add_argument
    arg('--recordings', type=int, default=8, help='recordings of the timed fleet (default 8)')
    arg('--duration', type=float, default=170.0, help='s per recording (default 170)')
    arg('--gyro-rate', type=float, default=100.0, help='gyro rate, Hz (default 100)')
    arg('--camera-interval', type=float, default=2.0, help='s between fixes (default 2)')
    arg('--repeats', type=int, default=5, help='runs per cluster size (default 5)')
    arg('--overhead-tasks', type=int, default=200, help='empty tasks per run (default 200)')
    arg('--scale-duration', type=float, default=680.0,
        help='s of the longer recording for the cost per recorded second (default 680)')
    arg('--scale-runs', type=int, default=3, help='analyses of the longer one (default 3)')
    arg('--units', type=int, default=1000, help='on paper: units (default 1000)')
    arg('--hours', type=float, default=24.0, help='on paper: hours recorded a day (default 24)')
    arg('--paper-workers', default='8,32,128', help='on paper: worker counts (default 8,32,128)')
    arg('--json', help='write the figures to this JSON file '
        '(documented run: doc/results/fleet_bench/fleet_bench.json)')
    arg('--report', help='write the markdown report to this file '
        '(documented run: doc/results/fleet_bench/fleet_bench.md)')
    arg('--force', action='store_true', help='replace existing outputs')
    arg('--quiet', action='store_true', help='no progress on stderr')
    a = ap.parse_args(argv)
    if not 2 <= a.recordings <= 10000 or not 1 <= a.repeats <= 100:
        ap.error('--recordings must be in [2, 10000] and --repeats in [1, 100]')
    if not 60.0 <= a.duration < a.scale_duration <= 86400.0:
        ap.error('need 60 <= --duration < --scale-duration <= 86400 s')
    if not (a.gyro_rate > 0 and a.camera_interval > 0 and a.units > 0 and a.hours > 0
            and a.overhead_tasks >= 1 and a.scale_runs >= 1):
        ap.error('--gyro-rate, --camera-interval, --units, --hours, --overhead-tasks and '
                 '--scale-runs must be > 0')
    try:
        a.paper_workers = [int(x) for x in a.paper_workers.split(',') if x.strip()]
        assert a.paper_workers and min(a.paper_workers) >= 1
    except (ValueError, AssertionError):
        ap.error(f'--paper-workers {a.paper_workers!r}: comma-separated positive integers')
    try:
        check_outputs([('--json', a.json, FILE), ('--report', a.report, FILE)], [], a.force)
    except ValueError as exc:
        ap.error(str(exc))
    t_all = time.perf_counter()

    def say(text):
        if not a.quiet:
            print(f'{PROG}: [{time.perf_counter() - t_all:6.1f} s] {text}', file=sys.stderr,
                  flush=True)

    load0 = os.getloadavg()[0]
    tmp = Path(tempfile.mkdtemp(prefix='fleet_bench_'))
    try:
        say(f'writing {a.recordings} recordings')
        entries, sizes = _fleet(tmp / 'fleet', a.recordings, a.duration, a.gyro_rate,
                                a.camera_interval)
        per = {'1': [], '2': []}
        for rep in range(a.repeats):
            for w in (1, 2):
                say(f'repeat {rep + 1}/{a.repeats}: {w} worker(s)')
                per[str(w)].append(_cluster_run(entries, w, a.overhead_tasks))
        say(f'one {a.scale_duration:g} s recording, {a.scale_runs} analyses in this process')
        scale = _scale_run(tmp / 'scale', a.scale_duration, a.gyro_rate, a.camera_interval,
                           a.scale_runs)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    runs = {}
    for w, rs in per.items():
        runs[w] = {k: stats([r[k] for r in rs]) for k in ('recordings_per_minute', 'start_s',
                                                          'warm_s', 'tasks_s', 'empty_task_ms',
                                                          'overhead_per_task_s')}
        for k in ('inside_task_s', 'task_peak_rss_mib', 'worker_peak_rss_mib'):
            runs[w][k] = stats([x for r in rs for x in r[k]])
        runs[w]['errors'] = sum(r['errors'] for r in rs)
        runs[w]['error_reasons'] = sorted({x for r in rs for x in r['error_reasons']})
    speedup = stats([b['recordings_per_minute'] / a_['recordings_per_minute']
                     for a_, b in zip(per['1'], per['2'])])
    base = {'task_s': runs['1']['inside_task_s']}
    res = {'command': f'{PROG} ' + ' '.join(argv), 'cpu_count': os.cpu_count(),
           'load_average': [load0, os.getloadavg()[0]],
           'config': {k: getattr(a, k) for k in ('recordings', 'duration', 'gyro_rate',
                                                 'camera_interval', 'repeats',
                                                 'overhead_tasks', 'scale_duration',
                                                 'scale_runs', 'units', 'hours',
                                                 'paper_workers')},
           'recording_mib': stats(sizes)['median'] / MIB, 'runs': runs, 'speedup': speedup,
           'scale': scale, 'per_run': per}
    res['paper'] = _paper(a, base, scale, runs['2']['overhead_per_task_s']['median'])
    res['wall_s'] = time.perf_counter() - t_all
    text = _lines(res)
    print('\n'.join(text))
    if a.json:
        write_json(a.json, json_clean(res))
    if a.report:
        write_text(a.report, '# fleet_bench\n\nGenerated by `' + res['command'] + '` in '
                   f"{res['wall_s']:.0f} s.\n\n```\n" + '\n'.join(text) + '\n```\n')
    say(f"done in {res['wall_s']:.0f} s")
    return 0


if __name__ == '__main__':
    sys.exit(main())
