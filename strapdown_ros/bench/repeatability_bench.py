"""
repeatability_bench: are true effects called repeatable by ``discrepancy`` on uneven motion.

Two kinds of simulated recording (the package's own simulator, in memory:
:func:`strapdown_ros.discrepancy.synthetic.simulate_recording`), 100 Hz gyro, a fix every
second, on an uneven piecewise motion: a long rest with slow small turns, a burst of fast turns
about every axis, then rest with turns about one axis only, so that the six time blocks differ
by orders of magnitude in what they say about each effect.

* **constant**: a gyro bias and a scale factor, constant, nothing outside the library: every
  found injected effect flagged "not repeatable" is a false flag (target ≤ 5 %);
* **step**: the same, plus a bias step at half time (outside the library: the model's bias is
  constant): the found bias (or whatever absorbs the step) must be flagged.

For each recording it prints the verdict, the effects found and their repeatability test
(χ², dof, p); at the end the fraction flagged, with the count, by the test of each block's own
information (``repeatable``) and by the former rule (the plain leave-one-block-out jackknife ÷
the model's σ against √(χ²(K−1)/(K−1)), recomputed from the same fold values), and the times
per analysis (median, min–max).

    repeatability_bench [--runs N] [--step-runs M] [--seed S] [--duration SECONDS]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time

import numpy as np

from strapdown_ros.bench.stats import stats
from strapdown_ros.discrepancy.synthetic import simulate_recording
from strapdown_ros.discrepancy.workflow import analyse, DiscrepancySettings
from strapdown_ros.params import check_all, IMU_SIM_PARAMS, model_and_settings, STAR_CAMERA_PARAMS

__all__ = ['main', 'uneven_profile_yaml', 'run_one', 'old_rule_flag']

BORESIGHT = [0.698, -0.436, 2.094]
BIAS = [3e-6, -2e-6, 1.5e-6]                  # rad/s: found at tens of σ
SCALE = [3e-4, -2e-4, 2.5e-4]
STEP = [2e-6, -2e-6, 1e-6]                    # rad/s, added at half time
TRUE_EFFECTS = ('gyro_bias', 'gyro_scale_factor')


def uneven_profile_yaml(duration: float) -> str:
    """
    Return the piecewise profile of the benchmark as YAML.

    Parameters
    ----------
    duration : float
        Length, s: a third of slow small turns between long rests, a third of fast turns about
        every axis, a third of rest and turns about z only.

    Returns
    -------
    str
        The profile file (:func:`strapdown_ros.motion.from_config.load_piecewise_profile`).

    """
    third = duration / 3.0
    segs = []

    def add(d, r):
        segs.append(f'  - {{duration: {d:.6g}, rate: [{r[0]:.6g}, {r[1]:.6g}, {r[2]:.6g}]}}')
    t = 0.0
    k = 0
    while t < third:                            # long rests, slow 3° turns
        add(15.0, (0, 0, 0))
        r = np.zeros(3)
        r[k % 3] = np.radians(3.0) / 10.0 * (1 if k % 2 == 0 else -1)
        add(10.0, r)
        t += 25.0
        k += 1
    while t < 2 * third:                        # fast 60° turns, every axis, both senses
        for ax in range(3):
            for sgn in (1, -1):
                r = np.zeros(3)
                r[ax] = sgn * np.radians(60.0) / 2.0
                add(2.0, r)
                add(1.0, (0, 0, 0))
                t += 3.0
    while t < duration + 30.0:                  # rest, z turns only
        add(20.0, (0, 0, 0))
        add(4.0, (0, 0, np.radians(20.0) / 4.0 * (1 if k % 2 == 0 else -1)))
        t += 24.0
        k += 1
    return 'segments:\n' + '\n'.join(segs) + '\n'


def _recording(profile: str, seed: int, duration: float, step: bool):
    sc = {'profile': 'piecewise', 'profile_file': profile, 'gyro_rate': 100.0,
          'camera_interval': 1.0, 'boresight': BORESIGHT, 'seed': int(seed),
          'gyro_bias': BIAS, 'gyro_scale_factor': SCALE}
    rec = simulate_recording(check_all(IMU_SIM_PARAMS, sc), check_all(STAR_CAMERA_PARAMS, sc),
                             duration)
    if step:
        late = rec.gyro_stamps > 0.5 * duration
        T = np.diff(rec.gyro_stamps, prepend=rec.gyro_stamps[0] - 0.01)
        rec.delta_theta[late] += np.outer(T[late], STEP)
    return rec


def old_rule_flag(step, folds: int, level: float) -> bool | None:
    """
    Return whether the former rule flags an effect: plain jackknife ÷ model σ above its bound.

    Parameters
    ----------
    step : Step
        An accepted effect (its ``fold_values`` and ``sigma_model``).
    folds : int
        Number of time blocks K.
    level : float
        The test level.

    Returns
    -------
    bool or None
        True when flagged; None without fold values.

    """
    from scipy.stats import chi2
    if not step.fold_values:
        return None
    v = np.asarray(step.fold_values, dtype=float).reshape(len(step.fold_values), -1)
    k = len(v)
    jk = np.sqrt((k - 1) / k * np.sum((v - v.mean(axis=0)) ** 2, axis=0))
    sig = np.asarray(next(iter(step.sigma_model.values())), dtype=float).reshape(-1)
    ratio = float(np.max(jk / np.where(sig > 0, sig, np.inf)))
    bound = float(np.sqrt(chi2.ppf(1.0 - level, max(folds - 1, 1)) / max(folds - 1, 1)))
    return ratio > bound


def run_one(profile: str, seed: int, duration: float, step: bool) -> dict:
    """
    Simulate and analyse one recording.

    Parameters
    ----------
    profile : str
        The profile file.
    seed : int
        Seed of the recording.
    duration : float
        Length, s.
    step : bool
        Add the bias step at half time.

    Returns
    -------
    dict
        ``verdict``, ``seconds``, and per found effect its ``repeatable``, the test's
        ``statistic``, ``dof``, ``p_value``, ``method`` and the former rule's ``old_flag``.

    """
    rec = _recording(profile, seed, duration, step)
    model, settings = model_and_settings('calibrator_node', {'gyro_rate': 100.0})
    t0 = time.perf_counter()
    r = analyse(rec, model, DiscrepancySettings.from_values(settings))
    dt = time.perf_counter() - t0
    level = r.tests_after['level']
    effects = {}
    for s in r.steps:
        t = s.repeatability or {}
        effects[s.effect] = {'repeatable': s.repeatable, 'statistic': t.get('statistic'),
                             'dof': t.get('dof'), 'p_value': t.get('p_value'),
                             'method': t.get('method'),
                             'old_flag': old_rule_flag(s, 6, level)}
    return {'verdict': r.verdict, 'seconds': dt, 'effects': effects}


def _fraction(flags) -> str:
    flags = [f for f in flags if f is not None]
    if not flags:
        return 'n/a (none found)'
    return f'{sum(flags)}/{len(flags)} = {100.0 * sum(flags) / len(flags):.1f} %'


def main(argv=None) -> int:
    """
    Run the benchmark and print its figures.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        0.

    """
    ap = argparse.ArgumentParser(prog='repeatability_bench', description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--runs', type=int, default=20, help='recordings with constant effects')
    ap.add_argument('--step-runs', type=int, default=10, help='recordings with a bias step')
    ap.add_argument('--seed', type=int, default=1, help='first seed')
    ap.add_argument('--duration', type=float, default=300.0, help='length of each recording, s')
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        profile = os.path.join(tmp, 'uneven.yaml')
        with open(profile, 'w', encoding='utf-8') as fh:
            fh.write(uneven_profile_yaml(args.duration))
        results = {'constant': [], 'step': []}
        for kind, n, step in (('constant', args.runs, False), ('step', args.step_runs, True)):
            for i in range(n):
                seed = args.seed + i + (100000 if step else 0)
                res = run_one(profile, seed, args.duration, step)
                results[kind].append(res)
                found = '; '.join(
                    f"{e} {'repeatable' if v['repeatable'] else 'NOT repeatable'} "
                    f"(χ² {v['statistic'] or float('nan'):.3g}/{v['dof']}, p "
                    f"{v['p_value'] if v['p_value'] is not None else float('nan'):.2g}, "
                    f"{v['method']}; former rule {'flags' if v['old_flag'] else 'passes'})"
                    for e, v in res['effects'].items())
                print(f"{kind} seed {seed}: {res['verdict']}, {res['seconds']:.1f} s: "
                      f'{found or "nothing found"}', flush=True)
    const = [e for r in results['constant'] for n, e in r['effects'].items()
             if n in TRUE_EFFECTS]
    print()
    print(f'uneven motion, constant effects ({args.runs} recordings of {args.duration:g} s, '
          f'{", ".join(TRUE_EFFECTS)} injected):')
    print(f'  true effects found: {len(const)} of {len(TRUE_EFFECTS) * args.runs}')
    print('  flagged "not repeatable" (each block\'s own information): '
          + _fraction([e['repeatable'] is False for e in const]) + '  (target ≤ 5 %)')
    print('  flagged by the former rule (plain jackknife ÷ model σ): '
          + _fraction([e['old_flag'] for e in const]))
    bias_step = [r['effects'].get('gyro_bias') for r in results['step']]
    any_flag = [any(e['repeatable'] is False for e in r['effects'].values())
                for r in results['step']]
    print(f'uneven motion, bias step {STEP} rad/s at half time ({args.step_runs} recordings):')
    print('  gyro_bias found and flagged "not repeatable": '
          + _fraction([e['repeatable'] is False for e in bias_step if e]))
    print('  recordings with some found effect flagged: ' + _fraction(any_flag))
    print('  verdict unexplained_structure: '
          + _fraction([r['verdict'] == 'unexplained_structure' for r in results['step']]))
    times = [r['seconds'] for v in results.values() for r in v]
    st = stats(times)
    if times:
        print(f"time per analysis: median {st['median']:.2f} s (min {st['min']:.2f}, max "
              f"{st['max']:.2f}; {len(times)} runs; mean {statistics.mean(times):.2f} s)")
    return 0


if __name__ == '__main__':
    sys.exit(main())
