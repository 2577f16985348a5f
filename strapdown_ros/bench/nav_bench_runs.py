"""
Runs of the navigation benchmark: the chain against exact truth on each profile and check.

The profiles and configurations of ``nav_bench``, the navigation runs, the sculling check,
the Δv drift per profile, the vertical channel, the round-off runs and the timed runs.  The
report is ``nav_bench_report``; the command ``nav_bench``.
"""
from __future__ import annotations

import math
import os
import time

import numpy as np

from strapdown_ros.earth import enu_rotation, normal_gravity
from strapdown_ros.motion.earth_profiles import (gravity_sculling_term,
                                                 navigation_profile_from_config,
                                                 sculling_drift_rate, sculling_profile)
from strapdown_ros.navigation.run import (generate_increments, navigate, run_profile,
                                          specific_force_drift, summarize)

GYRO_RATE = 100.0
ACCEL_RATE = 300.0
STATIC_TARGET_M = 1e-3            # static 1 h position error target
SCULLING_TOLERANCE = 0.05         # relative, the sculling check's acceptance
FLOOR_RELATIVE = 1e-15  # float floor of a drift: this fraction of the mean specific force
HISTORY = 2                       # gyro periods of sensor data before t0 in the "history" row
PROFILE_NAMES = ('static', 'straight_flight', 'coordinated_turn', 'sculling')

#: key, algorithm, form, scheme, history, label.  one+prev fits the rate over the previous step
#: too, so its rows get HISTORY gyro periods of sensor data before t0; the row "no sensor data
#: before t0" is the node's start-up (the first sample's rate continued).  Coning 2 needs none.
CONFIGS = (
    ('2/exact', '2', 'exact', 'exact', 0, 'coning 2 · Δv exact (sculling on)'),
    ('2/rotation_only', '2', 'rotation_only', 'exact', 0,
     'coning 2 · rotation only (sculling off)'),
    ('opp/exact', 'one_plus_previous', 'exact', 'exact', HISTORY,
     'one+prev · Δv exact (sculling on)'),
    ('opp/exact/no_history', 'one_plus_previous', 'exact', 'exact', 0,
     'one+prev · Δv exact · no sensor data before t0 (node start-up)'),
    ('opp/rotation_only', 'one_plus_previous', 'rotation_only', 'exact', HISTORY,
     'one+prev · rotation only (sculling off)'),
    ('opp/series', 'one_plus_previous', 'series', 'exact', HISTORY,
     'one+prev · 003 series, derived coefficients'),
    ('opp/printed_form', 'one_plus_previous', 'printed', 'exact', HISTORY,
     'one+prev · 003 printed coefficients, exact recursion'),
    ('opp/printed', 'one_plus_previous', 'printed', 'printed', HISTORY,
     'one+prev · 003 as printed (coefficients + recursion)'),
)
SCULLING_FREQUENCIES = (1.0, 2.0, 5.0, 10.0, 20.0)
SCULLING_STEPS = (1, 2)          # gyro increments per step: h = 0.01 s (1 : 3), 0.02 s (2 : 6)
ROUNDOFF_BLOCKS = (3600, 360)


def earth_profile(name: str, **kw):
    """
    Return a navigation profile by name, the sculling one with other amplitude or frequency.

    Parameters
    ----------
    name : str
        One of ``PROFILE_NAMES``.
    **kw
        ``accel_amplitude`` (m/s²) and ``frequency`` (Hz) of the sculling profile.

    Returns
    -------
    profile
        The Earth-referenced profile of ``strapdown_ros.motion.earth_profiles``.

    """
    if name == 'sculling' and kw:
        base = navigation_profile_from_config({'profile': 'sculling'})
        p = base.parameters
        return sculling_profile(p['lat'], p['lon'], p['h'], angle_amplitude=p['angle_amplitude'],
                                accel_amplitude=kw.get('accel_amplitude', p['accel_amplitude']),
                                frequency=kw.get('frequency', p['frequency']), yaw=p['yaw'])
    return navigation_profile_from_config({'profile': name})


def _decimate(t: np.ndarray, y: np.ndarray, points: int = 1500):
    """Max-envelope of ``y`` in ``points`` bins (for the log plots)."""
    if len(t) <= points:
        return t, y
    edges = np.linspace(0, len(t), points + 1).astype(int)
    idx = edges[:-1]
    return t[idx], np.maximum.reduceat(y, idx)


def navigation_runs(profiles, seconds, static_seconds, block, progress) -> tuple[dict, dict]:
    """
    Run every configuration of ``CONFIGS`` on every profile with perfect sensors.

    Parameters
    ----------
    profiles : list of str
        Profile names.
    seconds : float
        Length of the moving profiles, s.
    static_seconds : float
        Length of the static profile, s.
    block : int
        Gyro intervals per block fed to the chain.
    progress : callable
        Called with one line of progress text.

    Returns
    -------
    summaries : dict
        Profile → configuration key → error summary (m, m/s, rad).
    series : dict
        Profile → configuration key → decimated (t, |δR|) for the plots.

    """
    out, series = {}, {}
    total = len(profiles) * len(CONFIGS)
    done = 0
    for name in profiles:
        prof = earth_profile(name)
        dur = static_seconds if name == 'static' else seconds
        incs = {}
        out[name] = {}
        series[name] = {}
        for key, alg, form, scheme, hist, label in CONFIGS:
            if hist not in incs:
                t0 = time.perf_counter()
                incs[hist] = generate_increments(prof, dur, GYRO_RATE, ACCEL_RATE, block=block,
                                                 history=hist)
                progress(
                    f'{name}: {dur:g} s of increments (history {hist}) in'
                    f' {time.perf_counter() - t0:.1f} s'
                )
            t0 = time.perf_counter()
            r = run_profile(prof, dur, algorithm=alg, form=form, scheme=scheme, block=block,
                            increments=incs[hist])
            s = summarize(r)
            s['label'] = label
            s['history'] = hist
            out[name][key] = s
            series[name][key] = _decimate(r['t'], r['position_error_norm'])
            done += 1
            progress(f"[{done}/{total}] {name} {key}: final |δR| {s['final_position_m']:.2e} m "
                     f'({time.perf_counter() - t0:.1f} s)')
    return out, series


def sculling_check(seconds, progress) -> list[dict]:
    """
    Compare the rotation-only Δv drift on sculling profiles with the closed forms.

    The part odd in the acceleration amplitude B against ``sculling_drift_rate``, the part even
    in B against ``gravity_sculling_term``, at each frequency and step.

    Parameters
    ----------
    seconds : float
        Length of each run, s.
    progress : callable
        Called with one line of progress text.

    Returns
    -------
    list of dict
        One row per frequency and step: measured and predicted drifts (m/s²) and ratios.

    """
    rows = []
    for f in SCULLING_FREQUENCIES:
        for n in SCULLING_STEPS:
            t0 = time.perf_counter()
            d = {}
            for sign in (1.0, -1.0):
                base = earth_profile('sculling')
                prof = earth_profile('sculling', frequency=f,
                                     accel_amplitude=sign * base.parameters['accel_amplitude'])
                d[sign] = specific_force_drift(prof, seconds, GYRO_RATE, ACCEL_RATE,
                                               gyro_per_step=n, form='rotation_only')
            p = prof.parameters
            A, B, w = p['angle_amplitude'], abs(p['accel_amplitude']), p['omega']
            h = n / GYRO_RATE
            up = enu_rotation(p['lat'], p['lon'])[:, 2]
            g_up = float(-normal_gravity(prof.initial_position) @ up)
            plus, minus = d[1.0]['slope_up'], d[-1.0]['slope_up']
            odd, even = 0.5 * (plus - minus), 0.5 * (plus + minus)
            classical = -float(sculling_drift_rate(A, B, w, h))  # velocity error: −rate along up
            gravity = float(gravity_sculling_term(A, g_up, w, h))
            beff = -float(sculling_drift_rate(A, B + A * g_up, w, h))
            floor = FLOOR_RELATIVE * d[1.0]['mean_specific_force']
            row = {
                'frequency_hz': f,
                'step_s': h,
                'wh': w * h,
                'A': A,
                'B': B,
                'g_up': g_up,
                'measured_up': plus,
                'measured_body_z': float(d[1.0]['slope_body'][2]),
                'odd': odd,
                'even': even,
                'classical': classical,
                'gravity_term': gravity,
                'predicted': classical + gravity,
                'classical_with_b_eff': beff,
                'float_floor': floor,
                'ratio_odd': odd / classical,
                'ratio_even': even / gravity,
                'ratio_total': plus / (classical + gravity),
                'ratio_b_eff': plus / beff,
                'ratio_body': float(d[1.0]['slope_body'][2]) / classical,
            }
            checked = [k for k, ref in (('ratio_odd', classical), ('ratio_even', gravity),
                                        ('ratio_total', classical + gravity)) if abs(ref) > floor]
            row['checked'] = checked
            row['within_tolerance'] = all(abs(row[k] - 1.0) <= SCULLING_TOLERANCE for k in checked)
            rows.append(row)
            progress(f"sculling check {f:g} Hz, h {h:g} s: odd/formula {row['ratio_odd']:.5f} "
                     f'({time.perf_counter() - t0:.1f} s)')
    return rows


def profile_drifts(profiles, seconds, progress) -> list[dict]:
    """
    Measure the Δv drift of both forms (rotation only, exact) on every profile.

    Parameters
    ----------
    profiles : list of str
        Profile names.
    seconds : float
        Length of each run, s.
    progress : callable
        Called with one line of progress text.

    Returns
    -------
    list of dict
        One row per profile and step: drift norms and along up, m/s², and the float floor.

    """
    rows = []
    for name in profiles:
        prof = earth_profile(name)
        for n in SCULLING_STEPS:
            row = {'profile': name, 'step_s': n / GYRO_RATE}
            for form in ('rotation_only', 'exact'):
                d = specific_force_drift(prof, seconds, GYRO_RATE, ACCEL_RATE, gyro_per_step=n,
                                         form=form)
                row[form] = float(np.linalg.norm(d['slope_earth']))
                row[form + '_up'] = d['slope_up']
                row['float_floor'] = FLOOR_RELATIVE * d['mean_specific_force']
            rows.append(row)
        progress(f'specific-force drift {name}')
    return rows


def vertical_channel(res: dict) -> list[dict]:
    """
    Predict the final vertical error from the Δv drift along up: δh = δa τ²(cosh(T/τ) − 1).

    Parameters
    ----------
    res : dict
        The run's result with ``navigation`` and ``drift``.

    Returns
    -------
    list of dict
        Per profile and configuration: τ (s), drift (m/s²), predicted and measured error (m).

    """
    drift = {(r['profile'], r['step_s']): r for r in res.get('drift', [])}
    rows = []
    for p, d in res.get('navigation', {}).items():
        r0 = earth_profile(p).position(0.0)
        tau = math.sqrt(
            float(np.linalg.norm(r0)) / (2.0 * float(np.linalg.norm(normal_gravity(r0)))))
        for key, h, form in (('2/exact', 0.02, 'exact'), ('2/rotation_only', 0.02,
                                                          'rotation_only'),
                             ('opp/exact', 0.01, 'exact'), ('opp/rotation_only', 0.01,
                                                            'rotation_only')):
            dr = drift.get((p, h))
            if dr is None:
                continue
            s = d[key]
            a = dr[form + '_up']
            rows.append(
                {
                    'profile': p,
                    'key': key,
                    'label': s['label'],
                    'duration': s['duration'],
                    'tau_s': tau,
                    'drift_up': a,
                    'predicted_m': a * tau**2 * (math.cosh(s['duration'] / tau) - 1.0),
                    'measured_m': s['final_vertical_m'],
                }
            )
    return rows


def roundoff_runs(static_seconds, block, progress) -> list[dict]:
    """
    Run the static profile with smaller blocks to show the round-off of the rebasing.

    Parameters
    ----------
    static_seconds : float
        Length of the static run, s.
    block : int
        The run's block; ``ROUNDOFF_BLOCKS`` are added.
    progress : callable
        Called with one line of progress text.

    Returns
    -------
    list of dict
        Error summary per block size.

    """
    prof = earth_profile('static')
    inc = generate_increments(prof, static_seconds, GYRO_RATE, ACCEL_RATE)
    rows = []
    for b in (block,) + tuple(x for x in ROUNDOFF_BLOCKS if x != block):
        s = summarize(run_profile(prof, static_seconds, algorithm='2', block=b, increments=inc))
        s['block'] = b
        rows.append(s)
        progress(f"round-off: static, block {b}: final |δR| {s['final_position_m']:.2e} m")
    return rows


def timing_runs(seconds, runs, block, progress) -> dict:
    """
    Time attitude, navigation and both covariances on ``seconds`` of data, ``runs`` times.

    Parameters
    ----------
    seconds : float
        Length of the data, s.
    runs : int
        Timed runs per algorithm.
    block : int
        Gyro intervals per block.
    progress : callable
        Called with one line of progress text.

    Returns
    -------
    dict
        Wall times (s), real-time ratios and ns per gyro interval per algorithm, the load.

    """
    prof = earth_profile('static')
    r0, w0, q0 = prof.position(0.0), prof.velocity(0.0), prof.attitude_ecef(0.0)
    warm = generate_increments(prof, 2.0, GYRO_RATE, ACCEL_RATE)
    for alg in ('2', 'one_plus_previous'):              # compile / load the numba caches
        navigate(warm, r0, w0, q0, alg, covariance=True, block=block)
    inc = generate_increments(prof, seconds, GYRO_RATE, ACCEL_RATE, block=block)
    load = os.getloadavg() if hasattr(os, 'getloadavg') else (math.nan,) * 3
    res = {
        'seconds': seconds,
        'gyro_intervals': len(inc.tg),
        'accel_intervals': len(inc.ta),
        'runs': runs,
        'load_at_start': list(load),
        'block': block,
        'algorithms': {'2': [], 'one_plus_previous': []},
    }
    for i in range(runs):
        for alg in res['algorithms']:
            r = navigate(inc, r0, w0, q0, alg, 'exact', 'exact', covariance=True, block=block)
            res['algorithms'][alg].append(
                {
                    'wall_s': r['wall_s'],
                    'steps': r['steps'],
                    'real_time_ratio': seconds / r['wall_s'],
                    'ns_per_gyro_interval': r['wall_s'] / len(inc.tg) * 1e9,
                }
            )
        progress(f'timing run {i + 1}/{runs}')
    return res
