"""
filter_bench: the star-camera-aided attitude filter (``AttitudeFilter``, MEKF) against exact
truth, its posterior Cramér–Rao bound, its consistency, its cost, and one real recording.

* **Monte Carlo** (``--runs``, default 100; ``--fixes`` per run): slow constant rotation, the
  gyro's exact increments plus angle random walk and a bias random walk sampled from their exact
  joint law, a camera fix every ``--fix-interval`` s with known covariance R, initial errors drawn
  from the prior (the simulation of ``test/estimation/test_attitude_filter.py``).
* **Posterior Cramér–Rao bound** (Tichavský, Muravchik & Nehorai 1998): for this linear-Gaussian
  error model the PCRB of the causal (filtered) estimate at a fix is the Riccati covariance along
  the true trajectory, and that of the smoothed estimate is the covariance of the fixed-interval
  Rauch–Tung–Striebel smoother.  Both are computed here from the continuous error model
  ``ε̇ = −[ω×]ε − δb + w, δḃ = u`` discretised by Van Loan's method (independent of the filter's
  block transition).  The filter's attitude RMS is set against √(filter PCRB), the RTS smoother
  run on the filter's output against √(smoother PCRB); the filter against the smoother's bound is
  printed for information only (a causal estimate cannot reach it).
* **NEES** (attitude 3, bias 3, joint 6) and **NIS** (3), run-averaged per fix, with their
  two-sided 95 % χ² bands (Bar-Shalom, Li & Kirubarajan 2001, §5.4).
* **Cost**: ``--timing-seconds`` of 1 kHz Δθ with a fix every second through the core, one
  increment per ``propagate`` call (as a node receives them) and in blocks; µs per increment
  (all work included) and per fix; median and min–max of ``--timing-runs``; one process, one
  thread (numpy's BLAS on 3×3..6×6 matrices does not thread); load average at the start.
* **Real data** (RepoIMU, when found: ``$STRAPDOWN_REALDATA``, /work/shared/RepoIMU or the dev
  mirror): one wand trial, bias + time offset + boresight states, the Vicon attitude as one fix
  per second, σ from the data; the bias against the mean rate at rest and the time offset against
  the rate cross-correlation (``strapdown_ros.recording.repoimu``).

Prints a markdown table on stdout; ``--json FILE``; ``--plots DIR`` (attitude error with its
±3σ band, bias convergence with ±3σ, NIS with its χ² band); ``--report FILE`` (markdown).  The
figures are printed, not asserted.  Exit 0; 2 for bad arguments.
"""
from __future__ import annotations

import math
import os
import sys
import tempfile
import time

import numpy as np

from strapdown_ros.bench.stats import (chi2_band, median_range, pcrb_filter_smoother, rts_smooth,
                                       simulate_increments, stats)
from strapdown_ros.cli import check_outputs, DIRECTORY, FILE, OneLineParser, write_json, write_text
from strapdown_ros.estimation import AttitudeFilter, chi2_3_quantile
from strapdown_ros.estimation.steady_filter import discretize
from strapdown_ros.figures import save_figure
from strapdown_ros.recording import repoimu
from strapdown_ros.rotation import quat_conjugate, quat_multiply, quat_to_rotvec, rotvec_to_quat
from strapdown_ros.streams.rate_increments import increments_from_rates
from strapdown_ros.text import json_clean

RATE = np.array([0.01, -0.02, 0.015])           # body rate of the Monte Carlo motion, rad/s
Q_START = rotvec_to_quat(np.array([0.4, 0.1, -0.7]))
TARGET_RATIO = 1.1
TARGET_US = 50.0


def attitude_error(q_true, q_est):
    """ε of the package convention, ``q_true = q_est ⊗ exp(−ε)`` (body axes), rad."""
    return quat_to_rotvec(quat_multiply(quat_conjugate(q_true), q_est))


def run_timing(seconds: float, runs: int, blocks) -> dict:
    """
    µs per increment (all work: increments and fixes) at 1 kHz Δθ, a fix every second
    delivered before its epoch (in order) or 0.1 s after it (late: re-processing), ``blocks``
    increments per call; and µs per fix applied at the newest stamp.  The last row: one increment
    per call with the input queue off (``max_queued=0``), on at most 3 s of the data.
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
    µs of one fix applied at the newest stamp (the increments already processed): the median
    of ``count`` fixes, 10 increments of 1 ms between them (not timed).
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


def monte_carlo(a, progress) -> dict:
    """Runs of the bias filter; per fix: errors (filter, smoother), NEES, NIS, σ."""
    T, dt, k = a.gyro_period, a.fix_interval, int(round(a.fix_interval / a.gyro_period))
    n, F = k * a.fixes, a.fixes
    stamps = T * np.arange(1, n + 1)
    Phi, Qd = discretize(_error_dynamics(RATE), np.diag([a.arw ** 2] * 3 + [a.bias_rw ** 2] * 3),
                         dt)
    P0 = np.diag([a.prior_attitude ** 2] * 3 + [a.prior_bias ** 2] * 3)
    R = a.camera_sigma ** 2 * np.eye(3)
    bound_f, bound_s, bound_pre = pcrb_filter_smoother(Phi, Qd, P0, np.hstack([np.eye(3),
                                                                              np.zeros((3, 3))]),
                                                       R, F)
    out = {k_: np.zeros((a.runs, F, 3)) for k_ in ('att', 'bias', 'att_s', 'bias_s', 'sig_att',
                                                   'sig_bias')}
    out.update(nees=np.zeros((a.runs, F, 3)), nis=np.zeros((a.runs, F)),
               b_true=np.zeros((a.runs, F, 3)), b_est=np.zeros((a.runs, F, 3)))
    p_gap = [0.0, 0.0, a.fixes]         # σ, correlation differences; fixes before a gated one
    out['gated'] = 0
    for run in range(a.runs):
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
            out['att'][run, j], out['bias'][run, j] = e[:3], e[3:]
            out['nees'][run, j] = (e @ np.linalg.solve(P, e),
                                   e[:3] @ np.linalg.solve(P[:3, :3], e[:3]),
                                   e[3:] @ np.linalg.solve(P[3:, 3:], e[3:]))
            out['nis'][run, j] = res.nis if res.nis is not None else np.nan
            out['gated'] += res.status == 'gated'
            out['sig_att'][run, j] = np.sqrt(np.diag(P)[:3])
            out['sig_bias'][run, j] = np.sqrt(np.diag(P)[3:])
            out['b_true'][run, j], out['b_est'][run, j] = b[(j + 1) * k - 1], e[3:] + b[
                (j + 1) * k - 1]
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
            out['att_s'][run, j] = attitude_error(q_true, q_s)
            out['bias_s'][run, j] = b_s - b[(j + 1) * k - 1]
        if (run + 1) % max(1, a.runs // 5) == 0:
            progress(f'Monte Carlo {run + 1}/{a.runs}')
    out.update(bound_f=bound_f, bound_s=bound_s, bound_pre=bound_pre, p_gap=p_gap,
               t=dt * np.arange(1, F + 1))
    return out


def _error_dynamics(w):
    """Continuous error dynamics of [ε, δb] at a constant body rate w."""
    A = np.zeros((6, 6))
    A[:3, :3] = -np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    A[:3, 3:] = -np.eye(3)
    return A


def summarize(mc: dict, runs: int) -> dict:
    """Ratios to the bounds, NEES/NIS against their bands."""
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
        lo, hi = chi2_band(dim * runs)
        inside = np.mean((nees[:, c] > lo / runs) & (nees[:, c] < hi / runs))
        lo_all, hi_all = chi2_band(dim * runs * F)
        out['nees'][name] = {'dim': dim, 'mean': float(nees[:, c].mean()),
                             'band_per_fix': [lo / runs, hi / runs],
                             'fraction_of_fixes_inside': float(inside),
                             'band_if_independent': [lo_all / runs / F, hi_all / runs / F]}
    nis = mc['nis'][np.isfinite(mc['nis'])]
    lo, hi = chi2_band(3 * len(nis))
    out['nis'] = {'mean': float(nis.mean()), 'fixes': int(len(nis)), 'gated': int(mc['gated']),
                  'band': [lo / len(nis), hi / len(nis)],
                  'fraction_single_inside_95': float(np.mean(
                      (nis > chi2_3_quantile(0.025)) & (nis < chi2_3_quantile(0.975))))}
    return out


def realdata_run(a, progress) -> dict:
    """The filter on one RepoIMU wand trial (None fields when not available)."""
    with tempfile.TemporaryDirectory() as scratch:
        root = repoimu.find_repoimu(scratch)
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


def render(res: dict) -> str:
    s, set_ = res['summary'], res['settings']
    att = s['attitude']
    L = ['# filter_bench', '', '```', res['command'], '```', '',
         f"Monte Carlo: {set_['runs']} runs × {set_['fixes']} fixes every "
         f"{set_['fix_interval']:g} s; gyro {1 / set_['gyro_period']:g} Hz, ARW "
         f"{set_['arw']:.1e} rad/√s, bias RW {set_['bias_rw']:.1e} rad/s/√s; camera σ "
         f"{set_['camera_sigma']:.1e} rad; prior σ {set_['prior_attitude']:.1e} rad, "
         f"{set_['prior_bias']:.1e} rad/s; rate {RATE.tolist()} rad/s.", '',
         '## Attitude against the posterior Cramér–Rao bound', '',
         '| quantity | value |', '|---|---:|',
         f'| filter RMS ÷ √(filter PCRB), all fixes (target ≤ {TARGET_RATIO}) | '
         f"{att['filter_over_filter_pcrb']:.3f} |",
         f"| same, second half of the fixes | {att['filter_over_filter_pcrb_second_half']:.3f} |",
         f'| RTS smoother RMS ÷ √(smoother PCRB) (target ≤ {TARGET_RATIO}) | '
         f"{att['smoother_over_smoother_pcrb']:.3f} |",
         f'| filter RMS ÷ √(smoother PCRB) (information: a causal estimate is above it) | '
         f"{att['filter_over_smoother_pcrb']:.3f} |",
         f"| filter RMS, second half, rad | {att['rms_filter_rad']:.3e} |",
         f"| √PCRB filter / smoother, second half, rad | {att['sqrt_pcrb_filter_rad']:.3e} / "
         f"{att['sqrt_pcrb_smoother_rad']:.3e} |",
         f'| bias: filter ÷ filter PCRB, smoother ÷ smoother PCRB | '
         f"{s['bias']['filter_over_filter_pcrb']:.3f}, "
         f"{s['bias']['smoother_over_smoother_pcrb']:.3f} |",
         f"| filter P against the filter PCRB, run 0, its first {s['filter_P_vs_pcrb'][2]} "
         f'fixes (the PCRB assumes every fix applied; a gated fix departs from it): max '
         f'relative σ difference, max correlation difference | '
         f"{s['filter_P_vs_pcrb'][0]:.1e}, {s['filter_P_vs_pcrb'][1]:.1e} |", '',
         '## NEES and NIS (run-averaged per fix, two-sided 95 % χ² bands)', '',
         '| statistic | mean | band per fix | fixes inside |', '|---|---:|---:|---:|']
    for name, v in s['nees'].items():
        L.append(f"| NEES {name} ({v['dim']}) | {v['mean']:.3f} | {v['band_per_fix'][0]:.2f}–"
                 f"{v['band_per_fix'][1]:.2f} | {v['fraction_of_fixes_inside']:.0%} |")
    n = s['nis']
    L.append(
        f"| NIS (3), all {n['fixes']} fixes ({n['gated']} gated at the χ²₃ 0.9999 quantile "
        f"{chi2_3_quantile(0.9999):.2f}, the filter's default) | {n['mean']:.3f} | "
        f"{n['band'][0]:.3f}–"
        f"{n['band'][1]:.3f} (mean) | {n['fraction_single_inside_95']:.1%} single NIS in "
        'χ²₃ 95 % |'
    )
    tm = res.get('timing')
    if tm:
        L += [
            '', f"## Cost of the core: {tm['seconds']:g} s of 1 kHz Δθ, a fix every second", '',
            f"median (min–max) of {tm['runs']} runs; one process, one thread; load average "
            f"at the start {' '.join(f'{x:.2f}' for x in res['load_at_start'])} on "
            f"{res['cpu_count']} cores; data generation not timed", '',
            f'| increments per propagate call | fix | input queue | µs per increment, all work '
            f'(target ≤ {TARGET_US:g}) | µs per fix |', '|---|---|---|---:|---:|'
        ]
        for row in tm['rows']:
            q = f"{row['max_queued']}" if row['max_queued'] else f"off ({row['seconds']:g} s)"
            L.append(f"| {row['block']} | {row['fix']} | {q} | "
                     f"{median_range(stats(row['us_per_increment']), '.1f')} | "
                     f"{median_range(stats(row['us_per_fix']), '.0f')} |")
    rd = res.get('realdata')
    L += ['', '## Real data', '']
    if rd and rd.get('reason') == '--no-realdata':
        L.append('real data: skipped (--no-realdata)')
    elif not rd or not rd.get('available'):
        L.append('real data: not available (set STRAPDOWN_REALDATA)'
                 + (f"; {rd['reason']}" if rd and rd.get('reason') else ''))
    else:
        deg = 180 / math.pi
        L += [
            f"{rd['trial']} ({rd['duration_s']:.1f} s): {rd['applied']}/{rd['fixes']} fixes "
            f"applied, {rd['gated']} gated, mean NIS {rd['mean_nis']:.2f}; ARW from the rest "
            f"{rd['arw_rad_sqrt_s']:.2e} rad/√s, camera σ {rd['camera_sigma_rad']:g} rad.", '',
            '| quantity | filter ± 1σ | independent | z |', '|---|---|---|---|'
        ]
        for i, ax in enumerate('xyz'):
            L.append(f"| bias {ax}, °/s | {rd['bias_rad_s'][i] * deg:.3f} ± "
                     f"{rd['bias_sigma_rad_s'][i] * deg:.3f} | rest mean "
                     f"{rd['rest_mean_rad_s'][i] * deg:.3f} ± "
                     f"{rd['rest_sigma_rad_s'][i] * deg:.3f}"
                     f" | {rd['bias_z'][i]:+.2f} |")
        z_t = (rd['time_offset_s'] - rd['minus_xcorr_lag_s']) / rd['time_offset_sigma_s']
        L.append(f"| time offset, ms | {rd['time_offset_s'] * 1e3:.2f} ± "
                 f"{rd['time_offset_sigma_s'] * 1e3:.2f} | −xcorr lag "
                 f"{rd['minus_xcorr_lag_s'] * 1e3:.2f} | {z_t:+.2f} |")
    L += ['', '## Conclusions', ''] + [f'* {c}' for c in res['conclusions']]
    return '\n'.join(L)


def conclusions(res: dict) -> list[str]:
    s, out = res['summary'], []
    r1, r2 = s['attitude']['filter_over_filter_pcrb'], s['attitude']['smoother_over_smoother_pcrb']
    out.append(f"The filter's attitude RMS is {r1:.3f} × √(filter PCRB) and the RTS smoother's "
               f'{r2:.3f} × √(smoother PCRB): '
               + ('both within' if max(r1, r2) <= TARGET_RATIO else 'NOT both within')
               + f' the target {TARGET_RATIO}.')
    bad = [k for k, v in s['nees'].items() if not v['band_per_fix'][0] <= v['mean']
           <= v['band_per_fix'][1]]
    out.append('Mean NEES of ' + ('every group inside its per-fix 95 % band'
                                  if not bad else f"{', '.join(bad)} outside its per-fix band")
               + f"; mean NIS {s['nis']['mean']:.3f} "
               + ('inside' if s['nis']['band'][0] <= s['nis']['mean'] <= s['nis']['band'][1]
                  else 'outside') + ' its 95 % band.')
    tm = res.get('timing')
    if tm:
        one = next((r for r in tm['rows'] if r['block'] == 1 and r['max_queued']), None)
        if one:
            med = stats(one['us_per_increment'])['median']
            out.append(f'One increment per call costs {med:.1f} µs per increment (median, all '
                       f"work included): {'within' if med <= TARGET_US else 'ABOVE'} the "
                       f'{TARGET_US:g} µs target on this machine at this load.')
    rd = res.get('realdata')
    if rd and rd.get('available'):
        zb = max(abs(z) for z in rd['bias_z'])
        dt = abs(rd['time_offset_s'] - rd['minus_xcorr_lag_s'])
        out.append(f"Real data ({rd['trial']}): the bias is within {zb:.1f}σ of the rest mean on "
                   f'its worst axis; the time offset differs from −(xcorr lag) by '
                   f'{dt * 1e3:.2f} ms.')
    return out


def write_plots(outdir: str, mc: dict) -> list[str]:
    """Attitude error (run 0) ±3σ and RMS against √PCRB; bias ±3σ; NIS with its bands."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    os.makedirs(outdir, exist_ok=True)
    t, paths = mc['t'], []
    fig, axs = plt.subplots(4, 1, figsize=(9, 10), sharex=True)
    for i, ax in enumerate(axs[:3]):
        s3 = 3e6 * mc['sig_att'][0, :, i]
        ax.fill_between(t, -s3, s3, color='C0', alpha=0.2, label='±3σ (filter P)')
        ax.plot(t, 1e6 * mc['att'][0, :, i], 'C0.-', lw=1, label='filter error, run 0')
        ax.set_ylabel(f"ε_{'xyz'[i]}, µrad")
        ax.grid(alpha=0.3)
    axs[0].legend(fontsize=8, loc='upper right')
    rms = lambda e: 1e6 * np.sqrt(np.mean(np.square(e), axis=(0, 2)))      # noqa: E731
    bnd = lambda B: 1e6 * np.sqrt([np.trace(b[:3, :3]) / 3 for b in B])   # noqa: E731
    axs[3].semilogy(t, rms(mc['att']), 'C0.-', label='filter RMS (all runs)')
    axs[3].semilogy(t, bnd(mc['bound_f']), 'C0--', label='√ filter PCRB')
    axs[3].semilogy(t, rms(mc['att_s']), 'C1.-', label='RTS smoother RMS')
    axs[3].semilogy(t, bnd(mc['bound_s']), 'C1--', label='√ smoother PCRB')
    axs[3].set_ylabel('per-axis RMS, µrad')
    axs[3].set_xlabel('time, s')
    axs[3].legend(fontsize=8)
    axs[3].grid(alpha=0.3, which='both')
    fig.suptitle('Attitude error after each fix')
    paths.append(save_figure(fig, outdir, 'attitude_error.png'))
    fig, axs = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    for i, ax in enumerate(axs):
        b, s3 = 1e6 * mc['b_est'][0, :, i], 3e6 * mc['sig_bias'][0, :, i]
        ax.fill_between(t, b - s3, b + s3, color='C0', alpha=0.2, label='estimate ±3σ')
        ax.plot(t, b, 'C0.-', lw=1, label='estimate, run 0')
        ax.plot(t, 1e6 * mc['b_true'][0, :, i], 'k-', lw=1, label='true bias')
        ax.set_ylabel(f"b_{'xyz'[i]}, µrad/s")
        ax.grid(alpha=0.3)
    axs[0].legend(fontsize=8, loc='upper right')
    axs[-1].set_xlabel('time, s')
    fig.suptitle('Gyro bias: estimate converging on the truth')
    paths.append(save_figure(fig, outdir, 'bias_convergence.png'))
    fig, ax = plt.subplots(figsize=(9, 4.5))
    runs = mc['nis'].shape[0]
    lo, hi = chi2_band(3 * runs)
    ax.axhspan(chi2_3_quantile(0.025), chi2_3_quantile(0.975), color='C0', alpha=0.1,
               label='χ²₃ 95 % band (single NIS)')
    ax.plot(t, mc['nis'][0], 'C0.', label='NIS, run 0')
    ax.axhline(chi2_3_quantile(0.9999), color='C3', ls='--', lw=1,
               label='gate (χ²₃ 0.9999): above it a fix is not applied')
    ax.axhspan(lo / runs, hi / runs, color='C1', alpha=0.3,
               label=f'95 % band of the mean of {runs}')
    ax.plot(t, np.nanmean(mc['nis'], axis=0), 'C1.-', label=f'mean NIS over {runs} runs')
    ax.set_xlabel('time, s')
    ax.set_ylabel('NIS')
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc='upper left', ncol=2)
    ax.set_title('Normalised innovation squared')
    paths.append(save_figure(fig, outdir, 'nis.png'))
    return paths


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    ap = OneLineParser(prog='filter_bench', description=__doc__.split('\n\n')[0])
    arg = ap.add_argument
    arg('--runs', type=int, default=100, help='Monte Carlo runs (default 100)')
    arg('--fixes', type=int, default=60, help='fixes per run (default 60)')
    arg('--fix-interval', type=float, default=2.0, help='s between fixes (default 2)')
    arg('--gyro-period', type=float, default=0.25, help='gyro increment period, s (default 0.25)')
    arg('--arw', type=float, default=3e-6, help='angle random walk, rad/√s (default 3e-6)')
    arg('--bias-rw', type=float, default=3e-7, help='bias random walk, rad/s/√s (default 3e-7)')
    arg('--camera-sigma', type=float, default=1e-5, help='fix σ per axis, rad (default 1e-5)')
    arg('--prior-attitude', type=float, default=2e-4, help='prior attitude σ, rad (default 2e-4)')
    arg('--prior-bias', type=float, default=2e-5, help='prior bias σ, rad/s (default 2e-5)')
    arg('--seed', type=int, default=20000, help='seed of run 0 (default 20000)')
    arg('--timing-seconds', type=float, default=30.0,
        help='s of 1 kHz data per timing run (default 30; 0 skips the timing)')
    arg('--timing-runs', type=int, default=5, help='timing runs (default 5)')
    arg('--blocks', default='1,10,100', help='increments per propagate call (default 1,10,100)')
    arg('--trial', default='TStick_Test11_Trial2', help='RepoIMU wand trial')
    arg('--real-camera-sigma', type=float, default=0.005,
        help='σ of a Vicon fix per axis, rad (default 0.005, as doc/realdata/nominal.yaml)')
    arg('--no-realdata', action='store_true', help='skip the real-data run')
    arg('--json', help='write the figures to this JSON file')
    arg('--report', help='write the markdown report to this file')
    arg('--plots', help='write the PNG plots into this directory')
    arg('--force', action='store_true', help='replace existing outputs')
    arg('--quiet', action='store_true', help='no progress on stderr')
    a = ap.parse_args(argv)
    if not 2 <= a.runs <= 100_000 or not 2 <= a.fixes <= 100_000:
        ap.error('--runs and --fixes must be >= 2')
    for name in ('fix_interval', 'gyro_period', 'camera_sigma', 'prior_attitude', 'prior_bias',
                 'real_camera_sigma'):
        v = getattr(a, name)
        if not (math.isfinite(v) and v > 0):
            ap.error(f"--{name.replace('_', '-')} must be > 0, got {v:g}")
    k = a.fix_interval / a.gyro_period
    if abs(k - round(k)) > 1e-9 or round(k) < 1:
        ap.error('--fix-interval must be a whole multiple of --gyro-period')
    for name in ('arw', 'bias_rw', 'timing_seconds'):
        v = getattr(a, name)
        if not (math.isfinite(v) and v >= 0):
            ap.error(f"--{name.replace('_', '-')} must be >= 0, got {v:g}")
    if not 1 <= a.timing_runs <= 100:
        ap.error('--timing-runs must be in [1, 100]')
    try:
        blocks = [int(b) for b in a.blocks.split(',') if b.strip()]
    except ValueError:
        ap.error(f'--blocks {a.blocks!r}: comma-separated positive integers')
    if not blocks or min(blocks) < 1 or max(blocks) > 1000:
        ap.error('--blocks: integers in [1, 1000]')
    try:
        check_outputs([('--json', a.json, FILE), ('--report', a.report, FILE),
                       ('--plots', a.plots, DIRECTORY)], [], a.force)
    except ValueError as exc:
        ap.error(str(exc))
    t0 = time.perf_counter()

    def progress(msg):
        if not a.quiet:
            print(f'filter_bench: [{time.perf_counter() - t0:6.1f} s] {msg}', file=sys.stderr,
                  flush=True)

    res = {'command': 'filter_bench ' + ' '.join(argv), 'cpu_count': os.cpu_count(),
           'load_at_start': list(os.getloadavg()),
           'settings': {k_: getattr(a, k_) for k_ in ('runs', 'fixes', 'fix_interval',
                                                      'gyro_period', 'arw', 'bias_rw',
                                                      'camera_sigma', 'prior_attitude',
                                                      'prior_bias', 'seed', 'timing_seconds',
                                                      'timing_runs')}}
    mc = monte_carlo(a, progress)
    res['summary'] = summarize(mc, a.runs)
    if a.timing_seconds > 0:
        progress('timing')
        res['timing'] = run_timing(a.timing_seconds, a.timing_runs, blocks)
    if a.no_realdata:
        res['realdata'] = {'available': False, 'reason': '--no-realdata'}
    else:
        try:
            res['realdata'] = realdata_run(a, progress)
        except (ValueError, OSError) as exc:          # a data problem: reported, not a crash
            res['realdata'] = {'available': False, 'reason': f'{type(exc).__name__}: '
                               f'{str(exc)[:200]}'}
    res['conclusions'] = conclusions(res)
    text = render(res)
    print(text)
    if a.plots:
        res['plots'] = [os.path.basename(p) for p in write_plots(a.plots, mc)]
    res['wall_s'] = time.perf_counter() - t0
    if a.json:
        write_json(a.json, json_clean(res))
    if a.report:
        rel = os.path.relpath(a.plots, os.path.dirname(os.path.abspath(a.report))) \
            if a.plots else None
        figs = [f'![{p}]({rel}/{p})' for p in res.get('plots', [])] if rel else []
        write_text(a.report, text + ('\n\n## Plots\n\n' + '\n\n'.join(figs) if figs else '')
                   + '\n')
    progress(f"done in {res['wall_s']:.0f} s")
    return 0


if __name__ == '__main__':
    sys.exit(main())
