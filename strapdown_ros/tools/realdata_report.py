"""
realdata_report: the discrepancy workflow and calibrate_bag over every trial of a real data set.

    realdata_report [--data DIR] [--kinds TStick,Pendulum] [--model MODEL.yaml]
                    [--out doc/realdata] [--limit N] [--force] [--decimation-check]

DIR: a RepoIMU copy (``TStick/`` and ``Pendulum/``; default ``$STRAPDOWN_REALDATA``).  Each
trial is written as a bag
(:func:`strapdown_ros.recording.repoimu.write_bag`:
sensor_msgs/Imu + PoseStamped when the installed tools read them, else Δθ increments +
QuaternionStamped; the Vicon attitude decimated to one fix per second) and analysed three ways:

* ``discrepancy`` (the CLI) with the full effect library: verdict, effects named, whitened RMS;
* the workflow restricted to ``time_offset`` and ``gyro_bias`` (library call): the lag and the
  bias with their σ on every trial, named or not by that search;
* ``calibrate_bag`` (the CLI): boresight observable or not, χ²/dof and fit consistency when the
  installed version reports them.

Beside them, figures computed from the data alone: the mean gyro rate over the rest at the start
(rest found from the Vicon attitude) and the lag from a cross-correlation of |ω_gyro| with the
rate of the Vicon attitude.  ``--decimation-check``: the restricted workflow again with fixes
every 2 s, each estimate compared with the 1 s one in units of the combined σ.  Output:
``realdata.json`` and ``realdata.md`` in ``--out``; progress on stderr.  Not part of the test
suite.  Exit 2 with one line on stderr for unusable arguments (no data set, output exists
without ``--force``).
"""
from __future__ import annotations

import argparse
import inspect
import json
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time

import numpy as np

from strapdown_ros.cli import check_output_dir, check_outputs, FILE, OneLineParser, write_json
from strapdown_ros.discrepancy.bag_input import load_recording
from strapdown_ros.discrepancy.repoimu_report import markdown, NOMINAL_MODEL
from strapdown_ros.discrepancy.workflow import analyse, DiscrepancySettings
from strapdown_ros.params import load_model_file
from strapdown_ros.recording.repoimu import (find_repoimu, irregular_step_fraction,
                                             rate_plateau_samples, read_repoimu_csv, REALDATA_ENV,
                                             repoimu_trials, rest_mean_rate, write_bag,
                                             xcorr_lag_s)

__all__ = ['main', 'analyse_trial', 'estimates_by_fix_interval', 'agreement_z']

TWO_EFFECTS = ('time_offset', 'gyro_bias')
REAL_TOPICS = {'gyro_topic': '/imu/data', 'reference_topic': '/mocap/pose'}


def reads_real_formats() -> bool:
    """
    Tell whether the installed bag reader takes sensor_msgs/Imu + PoseStamped topics.

    That is ``load_recording(..., gyro_topic=..., reference_topic=...)`` and ``--gyro-topic``.
    """
    params = inspect.signature(load_recording).parameters.values()
    return any(p.kind is p.VAR_KEYWORD or p.name == 'gyro_topic' for p in params)


def _exe(name: str) -> str:
    return str(Path(sys.executable).with_name(name))


def analyse_trial(csv: Path, model_file: Path, work: Path,
                  decimation_check: bool = False) -> dict:
    """
    Return all figures of one trial (schema: the keys of the returned dict, SI units).

    Parameters
    ----------
    csv : Path
        RepoIMU trial file.
    model_file : Path
        Nominal model (ROS 2 parameter YAML).
    work : Path
        Scratch directory (the bag and the tools' JSON go there).
    decimation_check : bool
        Also run :func:`estimates_by_fix_interval` (fixes every 1 s and every 2 s).

    Returns
    -------
    dict
        ``trial``, ``duration_s``, ``rest``, ``xcorr_lag_s``, ``discrepancy``, ``two_effects``,
        ``calibrate_bag`` (each tool's part, or ``error``); ``decimation_check`` (the runs and
        ``z``, :func:`agreement_z`) when asked.

    """
    trial = read_repoimu_csv(csv)
    out = {'trial': csv.stem, 'kind': csv.parent.name, 'duration_s': trial.duration_s,
           'imu_samples': int(len(trial.stamps_ns))}
    out['rest'] = rest_mean_rate(trial)
    out['rate_plateau_samples'] = rate_plateau_samples(trial)
    out['max_abs_rate_rad_s'] = np.abs(trial.gyro).max(axis=0).tolist()
    out['irregular_step_fraction'] = irregular_step_fraction(trial.stamps_ns)
    try:
        out['xcorr_lag_s'] = xcorr_lag_s(trial)
    except ValueError as exc:
        out['xcorr_lag_s'] = None
        out['xcorr_error'] = str(exc)
    bag = work / csv.stem
    real = reads_real_formats()
    if real:                                     # sensor_msgs/Imu + PoseStamped, as recorded
        write_bag(bag, trial, gyro_format='imu', reference_format='pose')
        topics = ['--gyro-topic', REAL_TOPICS['gyro_topic'],
                  '--reference-topic', REAL_TOPICS['reference_topic']]
    else:                                        # the package's own Δθ + QuaternionStamped
        write_bag(bag, trial, gyro_format='delta_theta', reference_format='quaternion')
        topics = []
    out['bag_format'] = 'Imu+PoseStamped' if real else 'delta_theta+QuaternionStamped'
    js = work / f'{csv.stem}.discrepancy.json'
    r = subprocess.run([_exe('discrepancy'), str(bag), '--model', str(model_file), '--json',
                        str(js), '--quiet'] + topics, capture_output=True, text=True, timeout=900)
    if r.returncode == 0:
        j = json.loads(js.read_text())
        out['discrepancy'] = {k: j.get(k) for k in ('verdict', 'rms_before', 'rms_after',
                                                    'heldout_rms_before', 'heldout_rms_after',
                                                    'steps', 'not_separable', 'pairs',
                                                    'boresight_rad', 'boresight_sigma_rad')}
        for k in ('fit_consistent', 'chi2_per_dof', 'observable'):     # when the version has them
            if k in j:
                out['discrepancy'][k] = j[k]
    else:
        last = (r.stderr.strip().splitlines() or [f'exit {r.returncode}'])[-1]
        out['discrepancy'] = {'error': last[:300], 'exit': r.returncode}
    try:
        mf = load_model_file(str(model_file), 'calibrator_node')
        model = mf.model
        rec, _ = load_recording(str(bag), model, mf.settings, **(REAL_TOPICS if real else {}))
        res = analyse(rec, model, DiscrepancySettings.from_values(
            {**mf.settings, 'candidates': TWO_EFFECTS}))
        two = {'verdict': res.verdict, 'rms_after': res.rms_after, 'named': [], 'values': {}}
        for s in res.steps:
            two['named'].append(s.effect)
            two['values'].update({n: {'value': v, 'sigma': s.sigma[n]}
                                  for n, v in s.parameters.items()})
        two['rejected'] = [r2['effect'] + ': ' + r2['reason'] for r2 in res.rejected]
        two['not_separable'] = [list(p) for p in res.not_separable]
        out['two_effects'] = two
    except Exception as exc:                     # one trial's failure is reported
        out['two_effects'] = {'error': f'{type(exc).__name__}: {exc}'[:300]}
    if decimation_check:
        runs = estimates_by_fix_interval(trial, model_file, work)
        dc = {'runs': runs}
        if all('values' in r for r in runs.values()):
            dc['z'] = agreement_z(runs['1']['values'], runs['2']['values'])
        out['decimation_check'] = dc
    cj = work / f'{csv.stem}.calibrate.json'
    r = subprocess.run([_exe('calibrate_bag'), str(bag), '--params', str(model_file), '--json',
                        str(cj)] + topics, capture_output=True, text=True, timeout=900)
    if cj.is_file():
        j = json.loads(cj.read_text())
        out['calibrate_bag'] = {k: j.get(k) for k in ('observable', 'converged', 'beta_rad',
                                                      'beta_sigma_rad', 'residual_rms_rad',
                                                      'chi2_per_dof', 'fit_consistent', 'pairs')}
        out['calibrate_bag']['exit'] = r.returncode
    else:
        out['calibrate_bag'] = {'exit': r.returncode,
                                'error': (r.stderr.strip().splitlines() or [''])[-1][:300]}
    return out


def estimates_by_fix_interval(trial, model_file: Path, work: Path,
                              intervals=(1.0, 2.0)) -> dict:
    """
    Run the workflow with the reference decimated to one fix per interval.

    The workflow is restricted to ``time_offset`` and ``gyro_bias`` on the same trial: the
    estimates and σ of each run.

    Parameters
    ----------
    trial : ImuTrial
        The recording.
    model_file : Path
        Nominal model (ROS 2 parameter YAML).
    work : Path
        Scratch directory (the bags go there).
    intervals : sequence of float
        Fix intervals, s.

    Returns
    -------
    dict
        interval (str, s) -> ``values`` (name -> {``value``, ``sigma``}: every named effect's
        parameters and ``boresight`` yaw, pitch, roll, rad), ``sigma_method``, ``verdict``,
        ``fit_consistent``, ``chi2_per_dof``, ``pairs``; or ``error``.

    """
    mf = load_model_file(str(model_file), 'calibrator_node')
    model = mf.model
    settings = DiscrepancySettings.from_values({**mf.settings, 'candidates': TWO_EFFECTS})
    real = reads_real_formats()
    out = {}
    for iv in intervals:
        bag = work / f'{trial.name}_fix{iv:g}s'
        try:
            if real:
                write_bag(bag, trial, gyro_format='imu', reference_format='pose',
                          reference_interval_s=iv)
                rec, _ = load_recording(str(bag), model, mf.settings, **REAL_TOPICS)
            else:
                write_bag(bag, trial, gyro_format='delta_theta', reference_format='quaternion',
                          reference_interval_s=iv)
                rec, _ = load_recording(str(bag), model, mf.settings)
            res = analyse(rec, model, settings)
        except Exception as exc:                 # one run's failure is reported
            out[f'{iv:g}'] = {'error': f'{type(exc).__name__}: {exc}'[:300]}
            continue
        vals = {'boresight': {'value': list(res.boresight_rad),
                              'sigma': list(res.boresight_sigma_rad)}}
        for st in res.steps:
            vals.update({n: {'value': np.atleast_1d(v).tolist(),
                             'sigma': np.atleast_1d(st.sigma[n]).tolist()}
                         for n, v in st.parameters.items()})
        out[f'{iv:g}'] = {'values': vals, 'sigma_method': res.sigma_method,
                          'verdict': res.verdict, 'fit_consistent': res.fit_consistent,
                          'chi2_per_dof': res.chi2_per_dof, 'pairs': res.pairs}
    return out


def agreement_z(a: dict, b: dict) -> dict:
    """
    (estimate a − estimate b) / √(σ_a² + σ_b²) per component of every parameter both name.

    Angles of the boresight are compared modulo 2π (wrapped to (−π, π]).

    Parameters
    ----------
    a, b : dict
        ``values`` of two runs of :func:`estimates_by_fix_interval`.

    Returns
    -------
    dict
        name -> list of z (one per component).

    """
    out = {}
    for name in a:
        if name not in b:
            continue
        d = np.asarray(a[name]['value'], float) - np.asarray(b[name]['value'], float)
        if name == 'boresight':
            d = (d + np.pi) % (2.0 * np.pi) - np.pi
        s = np.hypot(np.asarray(a[name]['sigma'], float), np.asarray(b[name]['sigma'], float))
        out[name] = (d / np.where(s > 0, s, np.nan)).tolist()
    return out


def main(argv=None) -> int:
    """
    Run the realdata_report command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status (0 success; 2 unusable arguments or input, one line on stderr).

    """
    ap = OneLineParser(prog='realdata_report', description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--data', default='', help=f'RepoIMU directory (default ${REALDATA_ENV})')
    ap.add_argument('--kinds', default='TStick,Pendulum', help='sub-directories to run')
    ap.add_argument('--model', help='nominal model YAML (default: the built-in one, printed in '
                                    'the report)')
    ap.add_argument('--out', default='doc/realdata', help='output directory (realdata.json, '
                                                          'realdata.md)')
    ap.add_argument('--limit', type=int, default=0, help='first N trials only (0 = all)')
    ap.add_argument('--force', action='store_true', help='overwrite existing outputs')
    ap.add_argument('--decimation-check', action='store_true',
                    help='also compare the estimates from fixes every 1 s and every 2 s')
    args = ap.parse_args(argv)
    try:
        root = Path(args.data) if args.data else find_repoimu()
        if root is None or not root.is_dir():
            raise ValueError(f'no data set: give --data DIR or set {REALDATA_ENV} to a RepoIMU '
                             'copy')
        trials = repoimu_trials(root, tuple(k for k in args.kinds.split(',') if k))
        if not trials:
            raise ValueError(f'{root}: no trial CSV under {args.kinds}')
        if args.model and not Path(args.model).is_file():
            raise ValueError(f'model {args.model} does not exist')
        check_output_dir(args.out, '--out')
        out = Path(args.out)
        if out.is_dir():                   # the one output rule (no output is an input, --force)
            check_outputs([('--out', out / n, FILE) for n in ('realdata.json', 'realdata.md')],
                          [('--data', root), ('--model', args.model)], args.force)
        elif root.resolve() in out.resolve().parents or out.resolve() == root.resolve():
            raise ValueError(f'--out {args.out} is inside the input --data {root}')
    except ValueError as exc:
        print(f'realdata_report: error: {exc}', file=sys.stderr)
        return 2
    if args.limit > 0:
        trials = trials[:args.limit]
    t0 = time.perf_counter()
    results = []
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    def save(complete: bool) -> str:
        meta = {'data': 'RepoIMU', 'model': args.model or 'built-in', 'kinds': args.kinds,
                'seconds': time.perf_counter() - t0, 'complete': complete,
                'trials_done': len(results), 'trials_listed': len(trials)}
        write_json(out / '.realdata.json.tmp', {'meta': meta, 'nominal_model': NOMINAL_MODEL,
                                                'trials': results})
        os.replace(out / '.realdata.json.tmp', out / 'realdata.json')
        text = markdown(results, meta)
        (out / '.realdata.md.tmp').write_text(text, encoding='utf-8')
        os.replace(out / '.realdata.md.tmp', out / 'realdata.md')
        return text

    with tempfile.TemporaryDirectory(prefix='realdata_') as tmp:
        work = Path(tmp)
        model_file = Path(args.model) if args.model else work / 'nominal.yaml'
        if not args.model:
            model_file.write_text(NOMINAL_MODEL)
        for k, csv in enumerate(trials, 1):
            print(f'realdata_report: [{time.perf_counter() - t0:6.1f} s] {k}/{len(trials)} '
                  f'{csv.stem}', file=sys.stderr, flush=True)
            try:
                results.append(analyse_trial(csv, model_file, work, args.decimation_check))
            except (ValueError, OSError) as exc:
                results.append({'trial': csv.stem, 'kind': csv.parent.name, 'duration_s': 0.0,
                                'rest': {'samples': 0}, 'error': str(exc)[:300]})
            save(False)                          # partial results survive an interruption
    text = save(True)
    print(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
