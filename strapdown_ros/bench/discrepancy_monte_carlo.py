"""
Monte Carlo and speed runs of the discrepancy benchmark.

The scenario (bench profile, 200 Hz gyro, a fix every 2 s), one job per (effect, seed, size)
or null recording, run as Dask tasks (an embedded LocalCluster of ``--workers`` processes, or
the scheduler at ``--scheduler``: :mod:`strapdown_ros.fleet.cluster`), scored against the
injected effect; and the timing of the ``discrepancy`` command's work on a 900 s bag (its
library call, the JSON and the report).  ``discrepancy_bench`` summarises and reports.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import sys
import tempfile
import time

import numpy as np

from strapdown_ros.cli import write_json
from strapdown_ros.discrepancy.report import write_report
from strapdown_ros.discrepancy.synthetic import (draw_hidden_effect, effect_sigma,
                                                 simulate_recording)
from strapdown_ros.discrepancy.workflow import analyse, DEFAULT_ALPHA, DiscrepancySettings
from strapdown_ros.fleet.cluster import dask_client, map_tasks, TaskError
from strapdown_ros.params import (check_all, IMU_SIM_PARAMS, load_model_file, model_and_settings,
                                  simulator_parameters, STAR_CAMERA_PARAMS)
from strapdown_ros.recording.writer import record
from strapdown_ros.runs.discrepancy import analyse_discrepancies
from strapdown_ros.runs.source import RecordingSource
from strapdown_ros.sensors.effects import CANDIDATES, EFFECTS

BORESIGHT = [0.698, -0.436, 2.094]
INJECT_SEED_OFFSET = 10000
WITHIN = 3.0
SPEED_DURATION, SPEED_REPEATS = 900.0, 5


def separable_dimension(name: str) -> int:
    """
    Return the separable dimension q of an effect (columns of its fit basis).

    Parameters
    ----------
    name : str
        Effect name of the registry.

    Returns
    -------
    int
        q.

    """
    S = EFFECTS[name].fit_basis()
    return EFFECTS[name].size if S is None else S.shape[1]


def scenario_raw(seed: int, duration: float, overrides: dict | None = None) -> dict:
    """
    Return the raw simulator parameters of the bench scenario.

    Parameters
    ----------
    seed : int
        Seed of the recording.
    duration : float
        Length, s (sets the number of 150 s bench passes).
    overrides : dict, optional
        Parameters that replace the scenario's (e.g. an injected effect).

    Returns
    -------
    dict
        Parameter name → value, for ``check_all``.

    """
    raw = {'profile': 'bench', 'bench_repeat': max(1, math.ceil((duration - 20.0) / 150.0)),
           'gyro_rate': 200.0, 'camera_interval': 2.0, 'seed': int(seed),
           'boresight': list(BORESIGHT)}
    return {**raw, **(overrides or {})}


def _simulate(seed, duration, overrides=None):
    raw = scenario_raw(seed, duration, overrides)
    return simulate_recording(check_all(IMU_SIM_PARAMS, raw), check_all(STAR_CAMERA_PARAMS, raw),
                              duration)


def _model():
    return model_and_settings('calibrator_node')[0]


def sigma_job(names, seed: int, duration: float) -> dict:
    """
    Return the covariance of each effect's estimate on the null recording of ``seed``.

    Parameters
    ----------
    names : iterable of str
        Effect names.
    seed : int
        Seed of the null recording.
    duration : float
        Length, s.

    Returns
    -------
    dict
        Name → covariance as a nested list.

    """
    out = effect_sigma(_simulate(seed, duration), _model(), list(names))
    return {n: np.asarray(out[n]).tolist() for n in names}


def run_job(job: dict) -> dict:
    """
    Simulate and analyse one (effect, seed, size) recording; effect None is a null run.

    Parameters
    ----------
    job : dict
        ``effect``, ``seed``, ``size``, ``cov``, ``duration``, ``alpha``, ``draw_seed``.

    Returns
    -------
    dict
        The job's keys, the injected values, the scores of ``score`` and times in s; an
        exception is recorded as verdict ``error``.

    """
    t0 = time.perf_counter()
    name = job['effect']
    out = {k: v for k, v in job.items() if k not in ('cov', 'duration', 'alpha')}
    try:
        injected, sim_seed = {}, job['seed']
        if name is not None:
            cov = job['cov'] if job['cov'] is not None else sigma_job([name], job['seed'],
                                                                      job['duration'])[name]
            injected = draw_hidden_effect(name, job['size'], np.asarray(cov),
                                          np.random.default_rng(job['draw_seed']))
            sim_seed += INJECT_SEED_OFFSET
        rec = _simulate(sim_seed, job['duration'], injected)
        t1 = time.perf_counter()
        res = analyse(rec, _model(), DiscrepancySettings(alpha=job['alpha'])).as_json()
        out.update(sim_seed=sim_seed, injected=injected, analysis_s=time.perf_counter() - t1)
        out.update(score(name, injected, res))
    except Exception as exc:                         # recorded; counted as an error in the summary
        out.update(verdict='error', error=f'{type(exc).__name__}: {exc}', steps=[], first=None)
    out['job_s'] = time.perf_counter() - t0
    return out


def score(name, injected: dict, res: dict) -> dict:
    """
    Score one analysis against the injected effect.

    Parameters
    ----------
    name : str or None
        Injected effect; None for a null recording.
    injected : dict
        Injected parameter values.
    res : dict
        ``analyse(...).as_json()``.

    Returns
    -------
    dict
        Verdict, named effects, and for an injected effect: detected, named first, estimate
        with σ and whether it lies within 3σ of the truth; for a null run: false alarm.

    """
    named = [s['effect'] for s in res['steps']]
    out = {'verdict': res['verdict'], 'steps': named, 'first': named[0] if named else None,
           'failed_tests': res['tests_after'].get('failed', [])}
    if name is None:
        out['false_alarm'] = res['verdict'] != 'model_adequate'
        return out
    out.update(detected=name in named, named_first=bool(named) and named[0] == name)
    if out['detected']:
        st = res['steps'][named.index(name)]
        p = EFFECTS[name].value_parameter.name
        est, sig, inj = (np.atleast_1d(np.asarray(v, dtype=float))
                         for v in (st['parameters'][p], st['sigma'][p], injected[p]))
        z = np.abs(est - inj) / sig
        out.update(p_value=st['p_value'], estimate=est.tolist(), estimate_sigma=sig.tolist(),
                   max_abs_z=float(np.max(z)), within_3sigma=bool(np.all(z <= WITHIN)))
    return out


# ----------------------------------------------------------------------------- execution
def _progress(label: str, done: int, total: int, t0: float):
    """``[#####.....] 12/40 jobs, ETA 1m10s`` on stderr, rewritten in place."""
    eta = int(round((time.perf_counter() - t0) / done * (total - done))) if done else None
    bar = '#' * int(round(30 * done / max(total, 1)))
    print(
        f'\r{label} [{bar:.<30}] {done}/{total} jobs, ETA'
        f" {'?' if eta is None else f'{eta // 60}m{eta % 60:02d}s'}",
        end='\n' if done == total else '',
        file=sys.stderr,
        flush=True,
    )


def _dask_map(client, fn, items, label):
    """Run ``fn(*item)`` for every item as Dask tasks, with a progress bar; results in order."""
    t0 = time.perf_counter()
    _progress(label, 0, len(items), t0)
    return map_tasks(client, fn, items,
                     on_done=lambda i, res, done, total: _progress(label, done, total, t0))


def _lost(job: dict, err: TaskError) -> dict:
    """Return the record of a job whose worker was lost (an error in the summary)."""
    out = {k: v for k, v in job.items() if k not in ('cov', 'duration', 'alpha')}
    out.update(verdict='error', error=f'worker: {err}', steps=[], first=None, job_s=0.0)
    return out


def monte_carlo(args) -> dict:
    """
    Run every job as a Dask task: a LocalCluster of ``--workers``, or ``--scheduler``.

    The workers run numpy with one BLAS thread (Dask's nanny sets it before they start).

    Parameters
    ----------
    args : argparse.Namespace
        Options of ``discrepancy_bench.parse_args`` (``scheduler``, ``workers``, ...).

    Returns
    -------
    dict
        ``runs`` and ``nulls`` (records of ``run_job``), ``reference_sigma`` and wall times, s.

    """
    with dask_client(getattr(args, 'scheduler', None), args.workers) as client:
        t0 = time.perf_counter()
        covs = dict.fromkeys(args.effects)
        if args.sigma == 'reference':
            covs = _dask_map(client, sigma_job, [(args.effects, args.first_seed, args.duration)],
                             'sigma')[0]
            if isinstance(covs, TaskError):
                raise RuntimeError(f'the reference σ job failed: {covs}')
        t_sigma = time.perf_counter() - t0
        jobs = []
        for e in args.effects:
            for i in range(args.seeds):
                seed = args.first_seed + i
                sizes = args.sizes if args.every_size else [args.sizes[i % len(args.sizes)]]
                for k in sizes:
                    draw_seed = [seed, CANDIDATES.index(e), int(round(k * 1000))]
                    jobs.append({'effect': e, 'seed': seed, 'size': float(k), 'cov': covs[e],
                                 'duration': args.duration, 'alpha': args.alpha,
                                 'draw_seed': draw_seed})
        jobs += [
            {'effect': None, 'seed': args.first_seed + i, 'size': 0.0,
             'duration': args.duration, 'alpha': args.alpha} for i in range(args.null_seeds)
        ]
        recs = _dask_map(client, run_job, [(j,) for j in jobs], 'runs')
        recs = [_lost(j, r) if isinstance(r, TaskError) else r for j, r in zip(jobs, recs)]
        t_runs = time.perf_counter() - t0 - t_sigma
    sig = {
        e: None if c is None else np.sqrt(np.diag(np.atleast_2d(c))).tolist()
        for e, c in covs.items()
    }
    return {
        'runs': [r for r in recs if r['effect'] is not None],
        'nulls': [r for r in recs if r['effect'] is None], 'reference_sigma': sig,
        'sigma_wall_s': t_sigma, 'runs_wall_s': t_runs
    }


def _command_work(bag: str, model: str, json_path: str, report_dir: str) -> None:
    """
    Do the ``discrepancy`` command's work on a bag: its library call, the JSON and the report.

    Raises what the call raises (the speed run counts it as an error).
    """
    mf = load_model_file(model, 'calibrator_node')
    settings = DiscrepancySettings.from_values({**mf.settings, 'alpha': DEFAULT_ALPHA})
    run = analyse_discrepancies(RecordingSource(bag), mf.model, settings, mf.settings)
    if not run.observable:
        raise ValueError(f'boresight not observable: {run.message}')
    write_json(json_path, run.record)
    write_report(report_dir, run.result, run.record)


def speed(args) -> dict:
    """
    Time ``SPEED_REPEATS`` runs of the ``discrepancy`` command's work on a 900 s, 200 Hz bag.

    The work is the command's library call
    (:func:`strapdown_ros.runs.discrepancy.analyse_discrepancies`: read, check, analyse, the
    Allan comparison), its JSON and its report, in this process; the command adds its argument
    parsing and printing.

    Parameters
    ----------
    args : argparse.Namespace
        Options (``first_seed`` seeds the recording).

    Returns
    -------
    dict
        Times in s with their median summary, return codes (0 done, 1 failed), errors, the load
        average at start.

    """
    load, times, rcs, errors = os.getloadavg(), [], [], []
    imu_p, cam_p = simulator_parameters(overrides=scenario_raw(args.first_seed, SPEED_DURATION),
                                        duration=SPEED_DURATION)
    tmp = tempfile.mkdtemp(prefix='discrepancy_bench_')
    try:
        bag, model = os.path.join(tmp, 'bag'), os.path.join(tmp, 'model.yaml')
        fixes = record(bag, imu_p, cam_p,
                       accel=False)['messages'].get('/star_camera/attitude_with_covariance')
        with open(model, 'w', encoding='utf-8') as fh:
            json.dump({'/**': {'ros__parameters': {}}}, fh)              # JSON is YAML
        for i in range(SPEED_REPEATS):
            t0 = time.perf_counter()
            try:
                _command_work(bag, model, os.path.join(tmp, f'r{i}.json'),
                              os.path.join(tmp, f'report{i}'))
                rcs.append(0)
            except Exception as exc:  # noqa: BLE001 - counted as a failed run, with its reason
                rcs.append(1)
                errors.append(f'{type(exc).__name__}: {str(exc)[:200]}')
            times.append(time.perf_counter() - t0)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return {'mode': 'library call of the command, JSON and report', 'duration_s': SPEED_DURATION,
            'gyro_rate_hz': 200.0, 'fixes': fixes, 'return_codes': rcs, 'cli_errors': errors,
            'time_s': median_summary(times), 'times_s': times,
            'load_average_at_start': list(load)}


def median_summary(xs):
    """
    Return the median, min, max and count of the values, or None without values.

    Parameters
    ----------
    xs : list of float
        The values.

    Returns
    -------
    dict or None
        ``median``, ``min``, ``max``, ``n``.

    """
    return {
        'median': float(np.median(xs)), 'min': float(min(xs)), 'max': float(max(xs)), 'n': len(xs)
    } if xs else None
