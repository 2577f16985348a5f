"""
A whole fleet run: what the ``fleet`` command calls.

:func:`run_fleet` reads the manifest, hashes every recording with its model and the options
(:func:`strapdown_ros.fleet.cache.content_hash`), takes what the cache holds, runs the rest as
Dask tasks (:func:`strapdown_ros.fleet.cluster.map_tasks` of
:func:`strapdown_ros.fleet.analysis.analyse_recording`: a LocalCluster by default, or a
scheduler address), stores each result as it arrives, then detects the changes, computes the
population and writes the report (:func:`strapdown_ros.fleet.report.write_report`).  Progress
goes to a callback, one line per recording done.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import json
from pathlib import Path
import time

from strapdown_ros.cli import write_json
from strapdown_ros.fleet.analysis import analyse_recording, FleetOptions
from strapdown_ros.fleet.cache import content_hash, ResultCache
from strapdown_ros.fleet.changes import DEFAULT_LEVEL, detect_changes, population
from strapdown_ros.fleet.cluster import dask_client, DEFAULT_MEMORY_MIB, map_tasks, TaskError
from strapdown_ros.fleet.manifest import read_manifest
from strapdown_ros.fleet.report import effect_table, latest_rows, write_report
from strapdown_ros.text import bounded

__all__ = ['FleetRun', 'run_fleet', 'MARKER']

#: the file that makes a directory a fleet directory (a rerun updates it in place)
MARKER = 'fleet.json'


@dataclass(frozen=True)
class FleetRun:
    """
    What a fleet run did.

    Attributes
    ----------
    recordings : int
        Recordings in the manifest.
    analysed : int
        Analysed in this run (new or changed).
    cached : int
        Taken from the cache.
    errors : int
        Recordings that failed (one error row each).
    changes : int
        Changes detected.
    series : int
        Series the change test tested.
    skipped : int
        Folder entries that did not match the naming pattern.
    wall_s : float
        Seconds of the analyses (0 when nothing was analysed).
    files : list of str
        The report's files.
    verdicts : dict
        Verdict → recordings.

    """

    recordings: int
    analysed: int
    cached: int
    errors: int
    changes: int
    series: int
    skipped: int
    wall_s: float
    files: list = field(default_factory=list)
    verdicts: dict = field(default_factory=dict)


def _error(reason: str, stage: str) -> dict:
    return {'status': 'error', 'verdict': 'error', 'reason': reason, 'stage': stage,
            'effects': [], 'seconds': {}}


def run_fleet(manifest, out_dir, scheduler: str | None = None, workers: int = 2,
              memory_mib: float = DEFAULT_MEMORY_MIB, options: FleetOptions | None = None,
              level: float = DEFAULT_LEVEL, progress=None) -> FleetRun:
    """
    Analyse a fleet's recordings (cached by content hash) and write its report.

    Parameters
    ----------
    manifest : str or Path
        The manifest CSV or the fleet folder (:mod:`strapdown_ros.fleet.manifest`).
    out_dir : str or Path
        The fleet's directory (created; its ``cache/`` holds the results).
    scheduler : str or None
        A Dask scheduler address; None: a LocalCluster.
    workers : int
        LocalCluster workers.
    memory_mib : float
        Memory limit of a worker (LocalCluster) and the budget of a task, MiB.
    options : FleetOptions, optional
        The analyses' options (its ``memory_mib`` is set from ``memory_mib``).
    level : float
        Family-wise level of the change test.
    progress : callable, optional
        ``progress(text)``: one line per stage and per recording done.

    Returns
    -------
    FleetRun
        The counts and the files written.

    Raises
    ------
    ValueError
        An unusable manifest (one line).
    OSError
        The scheduler cannot be reached, or the report cannot be written.

    """
    say = progress or (lambda text: None)
    t_run = time.perf_counter()
    opts = options or FleetOptions()
    opts = FleetOptions(opts.inputs, opts.alpha, opts.candidates, opts.gyro, float(memory_mib))
    entries, skipped = read_manifest(manifest)
    out = Path(out_dir)
    cache = ResultCache(out)
    results, keys, todo, hits = {}, {}, [], 0
    key_text = opts.key()
    for e in entries:
        try:
            keys[e.path] = content_hash(e.path, e.model, key_text)
        except OSError as exc:
            results[e.path] = _error(f'hash: cannot read the recording or its model: '
                                     f'{bounded(str(exc), 200)}', 'hash')
            continue
        hit = cache.get(keys[e.path])
        if hit is not None:
            results[e.path] = hit
            hits += 1
        else:
            todo.append(e)
    say(f'{len(entries)} recording(s) of {len({e.unit for e in entries})} unit(s): '
        f'{len(entries) - len(todo)} from the cache or unreadable, {len(todo)} to analyse')
    wall = 0.0
    if todo:
        t0 = time.perf_counter()
        where = scheduler or f'a LocalCluster of {workers} worker(s)'
        say(f'starting the tasks on {where} (memory limit {memory_mib:g} MiB per worker)')

        def done(i, res, k, n):
            e = todo[i]
            if isinstance(res, TaskError):
                res = _error(f'worker: {res}', 'worker')   # the cluster lost it: not cached
            else:
                res['hash'] = keys[e.path]
                try:
                    cache.put(keys[e.path], res)
                except OSError as exc:
                    say(f'warning: cannot cache {e.recording}: {bounded(str(exc), 200)}')
            results[e.path] = res
            el = time.perf_counter() - t0
            eta = el / k * (n - k)
            state = res['verdict'] if res['status'] == 'ok' else 'ERROR ' + res['reason']
            say(f'[{el:6.1f} s] {k}/{n} {bounded(e.unit, 40)} {bounded(e.recording, 60)}: '
                f'{bounded(state, 160)}; ETA {eta:.0f} s')
        with dask_client(scheduler, workers, memory_mib) as client:
            out.mkdir(parents=True, exist_ok=True)        # once the cluster answers
            map_tasks(client, analyse_recording, [(e, opts) for e in todo], done,
                      keys=[f'fleet-{keys[e.path][:16]}-{i}' for i, e in enumerate(todo)])
        wall = time.perf_counter() - t0
    out.mkdir(parents=True, exist_ok=True)
    rows = effect_table(entries, results)
    changes, tests = detect_changes(rows, level)
    pop = population(latest_rows(rows), tests['repeatability'])
    analysed_now = {e.path for e in todo}
    info = {'scheduler': scheduler, 'workers': None if scheduler else workers,
            'memory_mib': memory_mib, 'wall_s': wall, 'alpha': opts.alpha}
    try:
        previous = json.loads((out / MARKER).read_text(encoding='utf-8')).get('report_keys')
    except (OSError, ValueError, AttributeError):
        previous = None
    files, report_keys = write_report(out, entries, results, rows, changes, tests, pop,
                                      analysed_now, info, previous)
    verdicts: dict = {}
    for e in entries:
        v = results[e.path].get('verdict') or 'error'
        verdicts[v] = verdicts.get(v, 0) + 1
    errors = sum(1 for e in entries if results[e.path].get('status') != 'ok')
    run = FleetRun(len(entries), len(todo), hits, errors, len(changes), tests['series'], skipped,
                   wall, files, verdicts)
    write_json(out / MARKER, {'manifest': str(Path(manifest).resolve()),
                              'recordings': run.recordings, 'analysed': run.analysed,
                              'cached': run.cached, 'errors': run.errors,
                              'changes': run.changes, 'series': run.series, 'level': level,
                              'options': opts.key(), 'run': info,
                              'repeatability': [{'effect': k[0], 'parameter': k[1],
                                                 'index': k[2], 'tau': v}
                                                for k, v in tests['repeatability'].items()],
                              'report_keys': report_keys,
                              'total_s': time.perf_counter() - t_run})
    return run
