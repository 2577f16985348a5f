"""
realdata_report: the discrepancy workflow and calibrate_bag over every trial of a real data set.

    realdata_report [--data DIR] [--kinds TStick,Pendulum] [--model MODEL.yaml]
                    [--out doc/realdata] [--limit N] [--force] [--decimation-check]

DIR: a RepoIMU copy (``TStick/`` and ``Pendulum/``; default ``$STRAPDOWN_REALDATA``, else
``shared/RepoIMU``).  Each trial is written as a bag
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
from strapdown_ros.discrepancy.workflow import analyse
from strapdown_ros.params import load_model
from strapdown_ros.recording.repoimu import (find_repoimu, irregular_step_fraction,
                                             rate_plateau_samples, read_repoimu_csv, REALDATA_ENV,
                                             repoimu_trials, rest_mean_rate, write_bag,
                                             xcorr_lag_s)

__all__ = ['main', 'analyse_trial', 'markdown', 'NOMINAL_MODEL', 'estimates_by_fix_interval',
           'agreement_z']

DEG = np.pi / 180.0
#: the nominal model of a MEMS IMU under Vicon: noise from the rest data, no known error
NOMINAL_MODEL = """# Nominal model for RepoIMU (MEMS IMU, 100 Hz; Vicon reference as ~1 Hz fixes):
# angle random walk from the rest segments (std of the rate x sqrt(0.01 s)); no error effect
# assumed known; calibrate_bag publishes the boresight when every direction is known to
# 0.05 rad (2.9 deg), a motion-capture requirement (a star camera's default is 1e-3 rad).
/**:
  ros__parameters:
    gyro_rate: 100.0
    gyro_random_walk: 0.0006
    gyro_bias_sigma: 0.0
    gyro_scale_sigma: 0.0
    gyro_misalignment_sigma: 0.0
    camera_sigma_xy: 0.005
    camera_sigma_z: 0.005
    max_sigma: 0.05
    frame_id: repoimu_imu
    reference_frame_id: repoimu_vicon
"""
TWO_EFFECTS = ('time_offset', 'gyro_bias')
#: samples on the largest-|rate| plateau of one axis from which a trial is called clipped
CLIPPED_SAMPLES = 10
REAL_TOPICS = {'gyro_topic': '/imu/data', 'reference_topic': '/mocap/pose'}


def reads_real_formats() -> bool:
    """
    True when the installed bag reader takes sensor_msgs/Imu + PoseStamped topics
    (``load_recording(..., gyro_topic=..., reference_topic=...)``, ``--gyro-topic``).
    """
    params = inspect.signature(load_recording).parameters.values()
    return any(p.kind is p.VAR_KEYWORD or p.name == 'gyro_topic' for p in params)


def _exe(name: str) -> str:
    return str(Path(sys.executable).with_name(name))


def analyse_trial(csv: Path, model_file: Path, work: Path,
                  decimation_check: bool = False) -> dict:
    """
    All figures of one trial (schema: the keys of the returned dict, SI units).

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
        model, _ = load_model(str(model_file))
        rec, _ = load_recording(str(bag), model, **(REAL_TOPICS if real else {}))
        res = analyse(rec, model, candidates=TWO_EFFECTS)
        two = {'verdict': res.verdict, 'rms_after': res.rms_after, 'named': [], 'values': {}}
        for s in res.steps:
            two['named'].append(s.effect)
            two['values'].update({n: {'value': v, 'sigma': s.sigma[n]}
                                  for n, v in s.parameters.items()})
        two['rejected'] = [r2['effect'] + ': ' + r2['reason'] for r2 in res.rejected]
        two['not_separable'] = [list(p) for p in res.not_separable]
        out['two_effects'] = two
    except Exception as exc:                     # noqa: BLE001 - one trial's failure is reported
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
    The workflow restricted to ``time_offset`` and ``gyro_bias`` on the same trial with the
    reference decimated to one fix per interval: the estimates and σ of each run.

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

    model, _ = load_model(str(model_file))
    real = reads_real_formats()
    out = {}
    for iv in intervals:
        bag = work / f'{trial.name}_fix{iv:g}s'
        try:
            if real:
                write_bag(bag, trial, gyro_format='imu', reference_format='pose',
                          reference_interval_s=iv)
                rec, _ = load_recording(str(bag), model, **REAL_TOPICS)
            else:
                write_bag(bag, trial, gyro_format='delta_theta', reference_format='quaternion',
                          reference_interval_s=iv)
                rec, _ = load_recording(str(bag), model)
            res = analyse(rec, model, candidates=TWO_EFFECTS)
        except Exception as exc:                 # noqa: BLE001 - one run's failure is reported
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


def _pm(v, s, scale=1.0, fmt='{:.3g}'):
    if v is None:
        return '—'
    if s is None:
        return fmt.format(v * scale)
    return (fmt + ' ± ' + fmt).format(v * scale, s * scale)


def _verdict(d: dict) -> str:
    """The verdict, or what the exit status of discrepancy says instead of one."""
    if d.get('verdict'):
        return d['verdict']
    return {3: 'boresight_unobservable', 4: 'analysis_failure', 2: 'input_error'}.get(
        d.get('exit'), 'error')


def _row(t: dict) -> str:
    d, two, cb = t.get('discrepancy', {}), t.get('two_effects', {}), t.get('calibrate_bag', {})
    vals = two.get('values', {})
    lag = vals.get('camera_time_offset')
    bias = vals.get('gyro_bias')
    bias_txt = '—' if not bias else ', '.join(
        _pm(b, s, 1 / DEG) for b, s in zip(bias['value'], bias['sigma']))
    if 'error' in d:                             # exit 3: boresight not observable, 4: failure
        named = f"exit {d.get('exit', '?')}: {d['error'][:60].replace('|', '/')}…"
    else:
        named = ', '.join(s['effect'] for s in d.get('steps') or []) or 'none'
    chi = cb.get('chi2_per_dof')
    fc = ' / '.join('—' if x.get('fit_consistent') is None else str(x['fit_consistent'])
                    for x in (d, cb))
    cb_txt = ('observable' if cb.get('observable') else 'not observable') if 'error' not in cb \
        else 'error'
    rest = t['rest']
    rest_txt = ('—' if rest['samples'] < 2
                else ', '.join(f'{m / DEG:.3f}' for m in rest['mean_rad_s']))
    xl = t.get('xcorr_lag_s')
    rms = d.get('rms_after')
    plateau = t.get('rate_plateau_samples')
    plateau_txt = '—' if plateau is None else str(max(plateau))
    return (f"| {t['trial']} | {t['duration_s']:.1f} | {plateau_txt} | "
            f'{_verdict(d)} | '
            f"{_pm(lag['value'] if lag else None, lag['sigma'] if lag else None, 1e3)} | "
            f"{'—' if xl is None else f'{-xl * 1e3:.2f}'} | {bias_txt} | {rest_txt} | {named} | "
            f'{cb_txt} | {fc} | '
            f"{'—' if chi is None else f'{chi:.3g}'} | "
            f"{'—' if rms is None else f'{rms ** 2:.3g}'} |")


def markdown(trials: list, meta: dict) -> str:
    """
    The report: a table over the trials and sentences computed from the numbers.

    Parameters
    ----------
    trials : list of dict
        :func:`analyse_trial` results.
    meta : dict
        ``data``, ``model``, ``seconds``.

    Returns
    -------
    str
        Markdown text.
    """
    n = len(trials)
    verdicts = {}
    for t in trials:
        v = _verdict(t.get('discrepancy', {}))
        verdicts[v] = verdicts.get(v, 0) + 1
    named = {}
    for t in trials:
        for s in t.get('discrepancy', {}).get('steps') or []:
            named[s['effect']] = named.get(s['effect'], 0) + 1
    lines = [
        '# RepoIMU: the discrepancy workflow on every trial (generated by `realdata_report`)', '',
        f'Data: RepoIMU (Szczęsna et al., ICCVG 2016; see test/data/README.md), {n} trials; '
        f"nominal model `{meta['model']}` (below).  Each trial as a bag of "
        f"{', '.join(sorted({t.get('bag_format', '?') for t in trials}))} (Δθ from the rate "
        'samples by the trapezoid rule), the Vicon attitude as one fix per second.  Run time '
        f"{meta['seconds']:.0f} s"
        + ('.' if meta.get('complete', True) else
           f"; INCOMPLETE: {meta['trials_done']} of {meta['trials_listed']} trials so far."),
        '',
        'Columns: **plateau** = most samples of one gyro axis within 0.1 % of its largest '
        '|rate| in the trial (a clipping gyro sits there for many samples); **lag** = '
        '`camera_time_offset` (ms) and **bias** (°/s, x, y, z) from the '
        'workflow restricted to `time_offset` and `gyro_bias` (— = not named by it); '
        '**−xcorr lag** = minus the lag of |ω_gyro| behind |ω_Vicon| from their '
        'cross-correlation (ms; the same sign convention as the offset); **rest mean** = mean '
        'gyro rate (°/s) over the rest at the start (found from '
        'the Vicon attitude); **verdict** and **effects named** from `discrepancy` with the full '
        'library; **calibrate_bag**: boresight observability; **fit consistent** (discrepancy / '
        'calibrate_bag) and **χ²/dof (cal)** when the installed tools report them (— = not); '
        '**RMS² after** = squared whitened residual RMS of `discrepancy` after its effects '
        '(1 = as the model predicts).', '',
        '| trial | s | plateau | verdict | lag ± σ (ms) | −xcorr lag (ms) | bias ± σ (°/s) '
        '| rest mean (°/s) | effects named | calibrate_bag | fit consistent (disc / cal) '
        '| χ²/dof (cal) '
        '| RMS² after |',
        '|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    lines += [_row(t) for t in trials]
    lines += ['', '## What the numbers say', '']
    lines.append('Verdicts: ' + ', '.join(f'{k} {v}/{n}' for k, v in sorted(verdicts.items()))
                 + '.  Effects named by the full search: '
                 + (', '.join(f'{k} in {v}' for k, v in sorted(named.items(), key=lambda x: -x[1]))
                    or 'none') + '.')
    pairs = {}
    for t in trials:
        for pr in t.get('discrepancy', {}).get('not_separable') or []:
            pairs[' and '.join(pr)] = pairs.get(' and '.join(pr), 0) + 1
    ranked = sorted(pairs.items(), key=lambda x: -x[1])
    lines.append('Called not separable by the full search: '
                 + (', '.join(f'{k} in {v}' for k, v in ranked) or 'no pair') + '.')
    diffs, zs, clipped = [], [], []
    for t in trials:
        lag = t.get('two_effects', {}).get('values', {}).get('camera_time_offset')
        if lag and t.get('xcorr_lag_s') is not None:
            diffs.append(lag['value'] + t['xcorr_lag_s'])
            clipped.append(max(t.get('rate_plateau_samples') or [0]) >= CLIPPED_SAMPLES)
    if diffs:
        d, c = np.abs(diffs) * 1e3, np.asarray(clipped)
        lines.append(f'Lag against the cross-correlation, {len(d)} trials: |difference| median '
                     f'{np.median(d):.2f} ms, max {np.max(d):.2f} ms; within 2 ms on '
                     f'{int(np.sum(d <= 2.0))}/{len(d)}'
                     + (f'; on the {int(np.sum(~c))} without gyro clipping (below) within 2 ms '
                        f'on {int(np.sum(d[~c] <= 2.0))}, max {np.max(d[~c]):.2f} ms'
                        if np.any(c) and np.any(~c) else '') + '.')
    for t in trials:
        b = t.get('two_effects', {}).get('values', {}).get('gyro_bias')
        r = t['rest']
        if b and r['samples'] > 50:
            s = np.hypot(np.asarray(b['sigma']), np.asarray(r['sigma_rad_s']))
            zs.append(np.max(np.abs(np.asarray(b['value']) - np.asarray(r['mean_rad_s'])) / s))
    if zs:
        z = np.asarray(zs)
        lines.append(f'Bias against the mean rate at rest, {len(z)} trials with > 0.5 s of '
                     f'rest: worst axis within 3σ (σ of both combined) on '
                     f'{int(np.sum(z <= 3))}/{len(z)}; median worst-axis |z| '
                     f'{np.median(z):.2g}.')
    clip = [t for t in trials if max(t.get('rate_plateau_samples') or [0]) >= CLIPPED_SAMPLES]
    if clip:
        chis = [t.get('calibrate_bag', {}).get('chi2_per_dof') for t in clip]
        rest_chi = [t.get('calibrate_bag', {}).get('chi2_per_dof') for t in trials
                    if t not in clip]
        med = (lambda v: f'{np.median(v):.3g}' if v else '—')
        lines.append(f'Gyro clipping: {len(clip)} trials have ≥ {CLIPPED_SAMPLES} samples on '
                     f'the plateau of one axis (largest |rate| '
                     f"{max(max(t['max_abs_rate_rad_s']) for t in clip):.3f} rad/s): "
                     f"{', '.join(t['trial'] for t in clip)}; calibrate_bag's χ²/dof on them, "
                     f'median {med([c for c in chis if c is not None])}, against '
                     f'{med([c for c in rest_chi if c is not None])} on the other trials.')
    irr = [t['irregular_step_fraction'] for t in trials if 'irregular_step_fraction' in t]
    if irr:
        irr = np.asarray(irr)
        lines.append(f'IMU stamps: {int(np.sum(irr > 0.05))}/{len(irr)} trials have more than '
                     f'5 % of their steps more than 10 % away from the median step (median '
                     f'fraction {np.median(irr):.1%}, largest {np.max(irr):.1%}).')
    obs = sum(1 for t in trials if t.get('calibrate_bag', {}).get('observable'))
    fc = [t['calibrate_bag']['fit_consistent'] for t in trials
          if t.get('calibrate_bag', {}).get('fit_consistent') is not None]
    lines.append(f'calibrate_bag found the boresight observable on {obs}/{n} trials'
                 + (f'; its fit consistent with the stated noise on {sum(map(bool, fc))}/'
                    f'{len(fc)} of those it reports on' if fc else '') + '.')
    lines += decimation_section(trials)
    lines += ['', 'Nominal model:', '', '```yaml', NOMINAL_MODEL.strip(), '```', '']
    return '\n'.join(lines)


def decimation_section(trials: list) -> list:
    """
    Markdown lines of the fixes-every-1 s against every-2 s check (empty when not run).

    Parameters
    ----------
    trials : list of dict
        :func:`analyse_trial` results.

    Returns
    -------
    list of str
    """
    done = [t for t in trials if 'z' in t.get('decimation_check', {})]
    if not done:
        return []
    names = ['boresight', 'camera_time_offset', 'gyro_bias']
    lines = ['', '## Every fix against every second fix (`--decimation-check`)', '',
             'The workflow restricted to `time_offset` and `gyro_bias` run twice on each trial: '
             'fixes every 1 s and every 2 s (the same IMU data).  Per parameter and axis: '
             'z = (estimate(1 s) − estimate(2 s)) / √(σ₁² + σ₂²), σ as reported (method in '
             'the last column: model, hac = Newey–West, hac_jackknife = raised to the '
             'leave-one-block-out jackknife); — = not named by one of the runs.', '',
             '| trial | boresight z (y, p, r) | time offset z | gyro bias z (x, y, z) | '
             'worst |z| | χ²/dof (1 s) | σ method (1 s / 2 s) |', '|---|---|---|---|---|---|---|']
    within, total, worst_all = 0, 0, []
    for t in done:
        z, runs = t['decimation_check']['z'], t['decimation_check']['runs']
        cells = []
        for n in names:
            cells.append('—' if n not in z else ', '.join(f'{v:+.2f}' for v in z[n]))
        flat = np.abs([v for n in z for v in z[n] if np.isfinite(v)])
        within += int(np.sum(flat <= 3.0))
        total += len(flat)
        worst = float(flat.max()) if len(flat) else float('nan')
        worst_all.append(worst)
        lines.append(f"| {t['trial']} | {' | '.join(cells)} | {worst:.2f} | "
                     f"{runs['1']['chi2_per_dof']:.3g} | {runs['1']['sigma_method']} / "
                     f"{runs['2']['sigma_method']} |")
    w = np.asarray(worst_all)
    bad = []
    for t, x in zip(done, w):
        r1 = t['decimation_check']['runs']['1']
        if x > 3.0:
            bad.append(f"{t['trial']}: |z| {x:.2f}, χ²/dof {r1['chi2_per_dof']:.3g}"
                       + ('' if r1['fit_consistent'] else ', fit not consistent: said so'))
    lines += ['', f'Within 3 combined σ: {within}/{total} estimates (components) over '
              f'{len(done)} trials; every estimate of a trial within 3σ on '
              f'{int(np.sum(w <= 3.0))}/{len(done)} trials'
              + (f" (not: {', '.join(bad)})" if bad else '') + f'; median worst |z| '
              f'{np.median(w):.2f}.']
    return lines


def main(argv=None) -> int:
    ap = OneLineParser(prog='realdata_report', description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--data', default='', help=f'RepoIMU directory (default ${REALDATA_ENV}, '
                                               'else shared/RepoIMU)')
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
            raise ValueError(f'no data set: give --data DIR, set {REALDATA_ENV} or place '
                             'RepoIMU in shared/RepoIMU')
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
