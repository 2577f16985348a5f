"""
Runs of the attitude-filter benchmark: Monte Carlo with its bounds, timing, one real trial.

The simulation and the posterior Cramér–Rao bounds of ``filter_bench`` (see its help), the
summary against the bounds and the χ² bands, the cost per increment and per fix, the run
on one RepoIMU wand trial, and ``filter_bag`` timed beside a raw read of a bag.  The report is
``filter_bench_report``.
"""
from __future__ import annotations

import math
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time

import numpy as np

from strapdown_ros.bench.sins_bag_bench import raw_read
from strapdown_ros.bench.stats import (pcrb_filter_smoother, rts_smooth,
                                       simulate_increments)
from strapdown_ros.estimation import AttitudeFilter, chi2_3_quantile
from strapdown_ros.estimation import model_check
from strapdown_ros.estimation.chi_square import chi2_interval
from strapdown_ros.estimation.filter_system import FilterSettings, warm_up as filter_warm_up
from strapdown_ros.estimation.steady_filter import discretize
from strapdown_ros.fleet.cluster import dask_client, map_tasks, TaskError
from strapdown_ros.params import load_model_file, parse_overrides
from strapdown_ros.recording import repoimu
from strapdown_ros.recording.filter_replay import run_filter
from strapdown_ros.recording.reader import read_bag
from strapdown_ros.rotation import quat_conjugate, quat_multiply, quat_to_rotvec, rotvec_to_quat
from strapdown_ros.streams.rate_increments import increments_from_rates
from strapdown_ros.tools.filter_bag import fix_rows, state_rows

RATE = np.array([0.01, -0.02, 0.015])           # body rate of the Monte Carlo motion, rad/s
Q_START = rotvec_to_quat(np.array([0.4, 0.1, -0.7]))


def attitude_error(q_true, q_est):
    """
    Return the attitude error ε of the package convention, ``q_true = q_est ⊗ exp(−ε)``.

    Parameters
    ----------
    q_true, q_est : (..., 4) ndarray
        True and estimated attitude, scalar-first quaternions.

    Returns
    -------
    (..., 3) ndarray
        ε in body axes, rad.

    """
    return quat_to_rotvec(quat_multiply(quat_conjugate(q_true), q_est))


def run_timing(seconds: float, runs: int, blocks) -> dict:
    """
    Time the filter: µs per increment and per fix at 1 kHz Δθ with a fix every second.

    Each fix is delivered before its epoch (in order) or 0.1 s after it (late: re-processing),
    ``blocks`` increments per call; µs per fix are for a fix applied at the newest stamp.  The
    last row: one increment per call with the input queue off (``max_queued=0``), on at most
    3 s of the data.

    Parameters
    ----------
    seconds : float
        Data length, s.
    runs : int
        Timed runs per row.
    blocks : list of int
        Increments per ``propagate`` call.

    Returns
    -------
    dict
        ``rows``: per block, fix mode and queue, the µs per increment and per fix of every run.

    """
    T, n = 1e-3, int(round(seconds * 1000))
    rng = np.random.default_rng(1)
    w = np.array([0.3, -0.2, 0.1])
    d = w * T + 1e-6 * rng.normal(size=(n, 3))
    st = T * np.arange(1, n + 1)
    fixes = [(float(t), quat_multiply(Q_START, rotvec_to_quat(w * t))) for t in st[999::1000]]
    R = 1e-10 * np.eye(3)
    rows = []
    n_all = n
    for block, mode, queue in ([(b, m, 1024) for b in blocks for m in ('in order', '0.1 s late')]
                               + [(1, 'in order', 0)]):
        n = n_all if queue else min(n_all, 3000)
        per_inc, per_fix = [], []
        for _ in range(runs):
            f = AttitudeFilter(Q_START, 0.0, gyro_random_walk=1e-6,
                               gyro_bias_random_walk=1e-8, initial_sigma=1e-4,
                               bias_sigma=1e-5, max_queued=queue)
            lag = 0 if mode == 'in order' else 100
            fx, total = 0, time.perf_counter()
            for i in range(0, n, block):
                j = min(n, i + block)
                while fx < len(fixes) and (lag == 0 and fixes[fx][0] <= st[j - 1]
                                           or lag and fixes[fx][0] + lag * T <= st[i]):
                    f.update(fixes[fx][0], fixes[fx][1], R)
                    fx += 1
                f.propagate(d[i:j], st[i:j])
            total = time.perf_counter() - total
            per_inc.append(total / n * 1e6)
            per_fix.append(_time_fix_now(f, w, R, 20))
        rows.append({'block': block, 'fix': mode, 'max_queued': queue, 'seconds': n / 1000,
                     'us_per_increment': per_inc, 'us_per_fix': per_fix})
    return {'seconds': seconds, 'runs': runs, 'rows': rows}


def _time_fix_now(f, w, R, count: int) -> float:
    """
    Return the µs of one fix applied at the newest stamp (the increments already processed).

    The median of ``count`` fixes, 10 increments of 1 ms between them (not timed).
    """
    out = []
    for _ in range(count):
        t = f.newest_stamp + 1e-3 * np.arange(1, 11)
        f.propagate(np.tile(w * 1e-3, (10, 1)), t)
        _ = f.attitude                           # everything before the fix processed
        q = quat_multiply(Q_START, rotvec_to_quat(w * t[-1]))
        a = time.perf_counter()
        f.update(t[-1], q, R)
        out.append(time.perf_counter() - a)
    return float(np.median(out) * 1e6)


def one_run(a, run: int, Phi, bound_f) -> dict:
    """
    Run one Monte Carlo run of the bias filter and its RTS smoother (one Dask task).

    Parameters
    ----------
    a : argparse.Namespace
        Options of ``filter_bench`` (its settings: seed, rates, σ, priors).
    run : int
        The run (seed ``a.seed + run``).
    Phi : ndarray
        The error model's transition over one fix interval.
    bound_f : ndarray
        The filter's PCRB at each fix (run 0 compares its covariance with it).

    Returns
    -------
    dict
        Per fix: errors of the filter and the smoother, NEES, NIS, σ, true and estimated bias;
        ``gated`` fixes; ``p_gap`` (run 0: the largest σ and correlation differences of P
        against the PCRB before the first gated fix, and that fix).

    """
    T, k = a.gyro_period, int(round(a.fix_interval / a.gyro_period))
    n, F = k * a.fixes, a.fixes
    stamps = T * np.arange(1, n + 1)
    R = a.camera_sigma ** 2 * np.eye(3)
    out = {k_: np.zeros((F, 3)) for k_ in ('att', 'bias', 'att_s', 'bias_s', 'sig_att',
                                           'sig_bias', 'nees', 'b_true', 'b_est')}
    out['nis'] = np.zeros(F)
    out['gated'] = 0
    p_gap = [0.0, 0.0, a.fixes]         # σ, correlation differences; fixes before a gated one
    rng = np.random.default_rng(a.seed + run)
    b0 = rng.normal(0.0, a.prior_bias, 3)
    d, b = simulate_increments(rng, T, n, a.arw, a.bias_rw, b0)
    d = d + RATE * T
    f = AttitudeFilter(quat_multiply(Q_START, rotvec_to_quat(rng.normal(0, a.prior_attitude,
                                                                        3))), 0.0,
                       gyro_random_walk=a.arw, gyro_bias_random_walk=a.bias_rw,
                       initial_sigma=a.prior_attitude, bias_sigma=a.prior_bias)
    pre, post, P_pre, P_post = [], [], [], []
    for j in range(F):
        f.propagate(d[j * k:(j + 1) * k], stamps[j * k:(j + 1) * k])
        t = stamps[(j + 1) * k - 1]
        q_true = quat_multiply(Q_START, rotvec_to_quat(RATE * t))
        pre.append((f.attitude, f.estimate('gyro_bias')))
        P_pre.append(f.P)
        fix = quat_multiply(q_true, rotvec_to_quat(rng.normal(0.0, a.camera_sigma, 3)))
        res = f.update(t, fix, R)
        post.append((f.attitude, f.estimate('gyro_bias')))
        P = f.P
        P_post.append(P)
        e = np.concatenate([attitude_error(q_true, f.attitude),
                            f.estimate('gyro_bias') - b[(j + 1) * k - 1]])
        out['att'][j], out['bias'][j] = e[:3], e[3:]
        out['nees'][j] = (e @ np.linalg.solve(P, e),
                          e[:3] @ np.linalg.solve(P[:3, :3], e[:3]),
                          e[3:] @ np.linalg.solve(P[3:, 3:], e[3:]))
        out['nis'][j] = res.nis if res.nis is not None else np.nan
        out['gated'] += res.status == 'gated'
        out['sig_att'][j] = np.sqrt(np.diag(P)[:3])
        out['sig_bias'][j] = np.sqrt(np.diag(P)[3:])
        b_fix = b[(j + 1) * k - 1]
        out['b_true'][j], out['b_est'][j] = b_fix, e[3:] + b_fix
        if run == 0 and res.status == 'gated':
            p_gap[2] = min(p_gap[2], j)
        if run == 0 and j < p_gap[2]:        # σ and correlations of P against the PCRB's
            sd, sB = np.sqrt(np.diag(P)), np.sqrt(np.diag(bound_f[j]))
            p_gap[0] = max(p_gap[0], float(np.max(np.abs(sd / sB - 1.0))))
            p_gap[1] = max(p_gap[1], float(np.max(np.abs(P / np.outer(sd, sd)
                                                         - bound_f[j] / np.outer(sB, sB)))))
    smoothed = rts_smooth(pre, post, P_pre, P_post, Phi)
    for j, (q_s, b_s) in enumerate(smoothed):
        q_true = quat_multiply(Q_START, rotvec_to_quat(RATE * stamps[(j + 1) * k - 1]))
        out['att_s'][j] = attitude_error(q_true, q_s)
        out['bias_s'][j] = b_s - b[(j + 1) * k - 1]
    out['p_gap'] = p_gap
    return out


def monte_carlo(a, progress, scheduler: str | None = None, workers: int = 1) -> dict:
    """
    Run the Monte Carlo of the bias filter and its bounds.

    Parameters
    ----------
    a : argparse.Namespace
        Options of ``filter_bench``.
    progress : callable
        Called with one line of progress text.
    scheduler : str, optional
        A running Dask scheduler (``tcp://host:8786``) whose workers run the runs.
    workers : int
        Dask LocalCluster workers; 1 (and no scheduler) runs them in this process.

    Returns
    -------
    dict
        Per run and fix: errors of the filter and the RTS smoother (rad, rad/s), NEES, NIS,
        σ; the filter and smoother PCRBs; times of the fixes.

    Raises
    ------
    RuntimeError
        A run's worker was lost.

    """
    dt = a.fix_interval
    F = a.fixes
    Phi, Qd = discretize(_error_dynamics(RATE), np.diag([a.arw ** 2] * 3 + [a.bias_rw ** 2] * 3),
                         dt)
    P0 = np.diag([a.prior_attitude ** 2] * 3 + [a.prior_bias ** 2] * 3)
    R = a.camera_sigma ** 2 * np.eye(3)
    bound_f, bound_s, bound_pre = pcrb_filter_smoother(Phi, Qd, P0, np.hstack([np.eye(3),
                                                                              np.zeros((3, 3))]),
                                                       R, F)
    keys = ('att', 'bias', 'att_s', 'bias_s', 'sig_att', 'sig_bias', 'nees', 'b_true', 'b_est',
            'nis')
    out = {k_: np.zeros((a.runs, F) + (() if k_ == 'nis' else (3,))) for k_ in keys}
    out['gated'] = 0
    step = max(1, a.runs // 5)

    def collect(run, res, done):
        if isinstance(res, TaskError):
            raise RuntimeError(f'Monte Carlo run {run} was lost: {res}')
        for k_ in keys:
            out[k_][run] = res[k_]
        out['gated'] += res['gated']
        if run == 0:
            out['p_gap'] = res['p_gap']
        if done % step == 0:
            progress(f'Monte Carlo {done}/{a.runs}')

    if scheduler or workers > 1:
        with dask_client(scheduler, workers) as client:
            map_tasks(client, one_run, [(a, run, Phi, bound_f) for run in range(a.runs)],
                      on_done=lambda i, res, done, total: collect(i, res, done))
    else:
        for run in range(a.runs):
            collect(run, one_run(a, run, Phi, bound_f), run + 1)
    out.update(bound_f=bound_f, bound_s=bound_s, bound_pre=bound_pre,
               t=dt * np.arange(1, F + 1))
    return out


def _error_dynamics(w):
    """Continuous error dynamics of [ε, δb] at a constant body rate w."""
    A = np.zeros((6, 6))
    A[:3, :3] = -np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    A[:3, 3:] = -np.eye(3)
    return A


def summarize(mc: dict, runs: int) -> dict:
    """
    Summarise the Monte Carlo: ratios to the bounds, NEES and NIS against their bands.

    Parameters
    ----------
    mc : dict
        Result of ``monte_carlo``.
    runs : int
        Number of runs.

    Returns
    -------
    dict
        ``attitude`` and ``bias`` ratios, ``filter_P_vs_pcrb``, ``nees`` and ``nis``.

    """
    def ratio(err, bound, sl, frm=0):
        ms = np.mean(np.square(err[:, frm:]))
        pb = np.mean([np.trace(B[sl, sl]) / 3 for B in bound[frm:]])
        return float(math.sqrt(ms / pb))
    F = mc['att'].shape[1]
    half = F // 2
    att, bia = slice(0, 3), slice(3, 6)
    out = {
        'attitude': {
            'filter_over_filter_pcrb': ratio(mc['att'], mc['bound_f'], att),
            'filter_over_filter_pcrb_second_half': ratio(mc['att'], mc['bound_f'], att, half),
            'smoother_over_smoother_pcrb': ratio(mc['att_s'], mc['bound_s'], att),
            'filter_over_smoother_pcrb': ratio(mc['att'], mc['bound_s'], att),
            'rms_filter_rad': float(np.sqrt(np.mean(np.square(mc['att'][:, half:])))),
            'sqrt_pcrb_filter_rad': float(
                np.sqrt(np.mean([np.trace(B[att, att]) / 3 for B in mc['bound_f'][half:]]))
            ),
            'sqrt_pcrb_smoother_rad': float(
                np.sqrt(np.mean([np.trace(B[att, att]) / 3 for B in mc['bound_s'][half:]]))
            ),
        },
        'bias': {
            'filter_over_filter_pcrb': ratio(mc['bias'], mc['bound_f'], bia),
            'smoother_over_smoother_pcrb': ratio(mc['bias_s'], mc['bound_s'], bia),
        },
        'filter_P_vs_pcrb': mc['p_gap'],
    }
    nees = mc['nees'].mean(axis=0)               # (F, 3): joint, attitude, bias
    out['nees'] = {}
    for c, (name, dim) in enumerate((('joint', 6), ('attitude', 3), ('bias', 3))):
        lo, hi = chi2_interval(dim * runs)
        inside = np.mean((nees[:, c] > lo / runs) & (nees[:, c] < hi / runs))
        lo_all, hi_all = chi2_interval(dim * runs * F)
        out['nees'][name] = {'dim': dim, 'mean': float(nees[:, c].mean()),
                             'band_per_fix': [lo / runs, hi / runs],
                             'fraction_of_fixes_inside': float(inside),
                             'band_if_independent': [lo_all / runs / F, hi_all / runs / F]}
    nis = mc['nis'][np.isfinite(mc['nis'])]
    lo, hi = chi2_interval(3 * len(nis))
    out['nis'] = {'mean': float(nis.mean()), 'fixes': int(len(nis)), 'gated': int(mc['gated']),
                  'band': [lo / len(nis), hi / len(nis)],
                  'fraction_single_inside_95': float(np.mean(
                      (nis > chi2_3_quantile(0.025)) & (nis < chi2_3_quantile(0.975))))}
    return out


def realdata_run(a, progress) -> dict:
    """
    Run the filter on one RepoIMU wand trial, with bias, time offset and boresight states.

    Parameters
    ----------
    a : argparse.Namespace
        Options of ``filter_bench``.
    progress : callable
        Called with one line of progress text.

    Returns
    -------
    dict
        ``available`` False (with the reason) when the data are missing; else the estimates
        with σ against the rest mean rate and the cross-correlation lag, and the mean NIS.

    """
    root = repoimu.find_repoimu()
    if root is None:
        return {'available': False}
    path = next((p for p in repoimu.repoimu_trials(root, ('TStick', )) if p.stem == a.trial),
                None)
    if path is None:
        return {'available': False, 'reason': f'trial {a.trial} not in {root}'}
    trial = repoimu.read_repoimu_csv(path)
    progress(f'real data: {trial.name}')
    rest = repoimu.rest_mean_rate(trial)
    lag = repoimu.xcorr_lag_s(trial)
    at_rest = trial.stamps_ns < trial.stamps_ns[0] + int(rest['end_s'] * 1e9)
    period = float(np.median(np.diff(trial.stamps_ns))) * 1e-9
    arw = float(np.median(trial.gyro[at_rest].std(axis=0, ddof=1)) * math.sqrt(period))
    st_ns, d = increments_from_rates(trial.stamps_ns, trial.gyro)
    ref = repoimu.reference_indices(trial.reference_stamps_ns, 1.0)
    t_ref = (trial.reference_stamps_ns[ref] - trial.stamps_ns[0]) * 1e-9
    q_ref = trial.q_reference_marker[ref]
    t_inc = (st_ns - trial.stamps_ns[0]) * 1e-9
    start = t_ref[0]
    keep = t_inc > start
    f = AttitudeFilter(q_ref[0], start, gyro_random_walk=arw, initial_sigma=a.real_camera_sigma,
                       bias_sigma=0.02, augment=('time_offset', 'boresight'),
                       augment_sigma={'time_offset': 0.05, 'boresight': 0.05})
    R = a.real_camera_sigma ** 2 * np.eye(3)
    d, t_inc = d[keep], t_inc[keep]
    done = 0
    for tf, qf in zip(t_ref[1:], q_ref[1:]):        # each fix 0.1 s after its stamp, as a node
        upto = int(np.searchsorted(t_inc, tf + 0.1, side='right'))
        if upto > done:
            f.propagate(d[done:upto], t_inc[done:upto])
            done = upto
        f.update(tf, qf, R)
    if done < len(t_inc):
        f.propagate(d[done:], t_inc[done:])
    nis = [r.nis for r in f.results if r.nis is not None and r.status == 'applied']
    bias, sb = f.estimate('gyro_bias'), f.sigma('gyro_bias')
    rm, rs = np.array(rest['mean_rad_s']), np.array(rest['sigma_rad_s'])
    return {'available': True, 'trial': trial.name, 'duration_s': trial.duration_s,
            'fixes': len(q_ref) - 1, 'applied': f.counters.applied, 'gated': f.counters.gated,
            'arw_rad_sqrt_s': arw, 'camera_sigma_rad': a.real_camera_sigma,
            'bias_rad_s': bias.tolist(), 'bias_sigma_rad_s': sb.tolist(),
            'rest_mean_rad_s': rm.tolist(), 'rest_sigma_rad_s': rs.tolist(),
            'rest_samples': rest['samples'],
            'bias_z': ((bias - rm) / np.sqrt(sb ** 2 + rs ** 2)).tolist(),
            'time_offset_s': f.time_offset,
            'time_offset_sigma_s': float(f.sigma('time_offset')[0]),
            'minus_xcorr_lag_s': -lag, 'mean_nis': float(np.mean(nis)) if nis else None}


def _filter_bag_run(bag: str, out: str, params: list) -> dict:
    """Time one whole ``filter_bag`` command, as a user runs it (a separate process)."""
    script = Path(sys.executable).parent / 'filter_bag'
    head = ([str(script)] if script.exists()
            else [sys.executable, '-m', 'strapdown_ros.tools.filter_bag'])
    cmd = head + [bag, '--output', out, '--force'] + [x for p in params for x in ('-p', p)]
    t0 = time.perf_counter()
    res = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if res.returncode != 0:
        raise RuntimeError(f'filter_bag exited {res.returncode}: {res.stderr.strip()[-300:]}')
    summary = [x for x in res.stdout.splitlines() if 'outputs,' in x]
    # the outputs' names without the temporary directory (no path of one run in a report)
    line = summary[0].replace(str(Path(out).parent) + os.sep, '') if summary else ''
    return {'wall_s': wall, 'summary': line}


def phases(bag: str, params: list) -> dict:
    """
    Time the phases of filter_bag in this process: kernels, read, filter, CSV text.

    The kernels (numba's import, its cached kernels and a throw-away filter,
    :func:`strapdown_ros.estimation.filter_system.warm_up`) are loaded first, so that the
    read and the filter are timed without them.

    The live model check's share of the filter (its ``add``) is timed on its own.

    Parameters
    ----------
    bag : str
        The bag.
    params : list of str
        ``NAME:=VALUE`` parameter overrides.

    Returns
    -------
    dict
        Seconds of each phase, increments, fixes and outputs.

    """
    mf = load_model_file(None, 'attitude_filter_node', parse_overrides(params))
    settings = FilterSettings.from_values(mf.settings)
    tk = time.perf_counter()
    filter_warm_up(mf.model, settings)         # numba's import and cached kernels, once
    t0 = time.perf_counter()
    data = read_bag(bag, '', settings.use_camera_covariance, tuple(mf.model.camera_sigma),
                    mf.model.gyro_max_rate, settings.max_stamp_jump, settings.resync_count)
    t1 = time.perf_counter()
    spent = [0.0]
    add = model_check.ModelCheck.add

    def timed(self, *a, **kw):
        t = time.perf_counter()
        try:
            return add(self, *a, **kw)
        finally:
            spent[0] += time.perf_counter() - t
    model_check.ModelCheck.add = timed
    try:
        system = run_filter(data, mf.model, settings)
    finally:
        model_check.ModelCheck.add = add
    t2 = time.perf_counter()
    outputs, fixes = system.take()
    _ = state_rows(outputs), fix_rows(fixes)
    t3 = time.perf_counter()
    return {'kernels_s': t0 - tk, 'read_s': t1 - t0, 'filter_s': t2 - t1,
            'model_check_add_s': spent[0],
            'csv_text_s': t3 - t2, 'increments': len(data['gyro'].stamps),
            'fixes': len(fixes), 'outputs': len(outputs)}


def bag_timing(bag: str, runs: int, params: list, progress) -> dict:
    """
    Time filter_bag beside a raw read of the same bag, alternating, in separate processes.

    The raw read is ``sins_bag_bench``'s (rosbags' AnyReader over every record, no decoding).
    One untimed run of each first (numba's cache, the page cache); then ``runs`` pairs, the
    order alternating (A B, B A, …); then the phases of one filter_bag in this process.

    Parameters
    ----------
    bag : str
        A rosbag2 bag (e.g. ``record_sim OUT --duration 3600 --no-accel -p
        camera_interval:=1.0``).
    runs : int
        Pairs timed.
    params : list of str
        ``NAME:=VALUE`` overrides given to filter_bag.
    progress : callable
        Called with one line of progress text.

    Returns
    -------
    dict
        Wall times of every run, the per-run ratios, the load average at the start, filter_bag's
        summary line and the phases.

    """
    load = list(os.getloadavg())
    with tempfile.TemporaryDirectory(prefix='filter_bench_') as tmp:
        out = str(Path(tmp) / 'out.csv')
        _filter_bag_run(bag, out, params)
        raw_read(bag)
        raws, fbs = [], []
        for k in range(runs):
            for which in (('raw', 'filter_bag') if k % 2 == 0 else ('filter_bag', 'raw')):
                if which == 'raw':
                    raws.append(raw_read(bag))
                else:
                    fbs.append(_filter_bag_run(bag, out, params))
            progress(f"bag run {k + 1}/{runs}: raw read {raws[-1]['wall_s']:.2f} s, "
                     f"filter_bag {fbs[-1]['wall_s']:.2f} s")
    progress('phases of filter_bag in this process')
    return {'bag': bag, 'params': list(params), 'runs': runs, 'load_at_start': load,
            'raw_process_s': [r['wall_s'] for r in raws],
            'raw_iteration_s': [r['iteration_s'] for r in raws],
            'records': raws[0]['records'],
            'filter_bag_s': [f['wall_s'] for f in fbs],
            'ratio_per_run': [f['wall_s'] / r['wall_s'] for f, r in zip(fbs, raws)],
            'summary': fbs[0]['summary'], 'phases': phases(bag, params)}
