"""
Markdown text, conclusions and plots of the attitude-filter benchmark.

Every number comes from the run's result (``filter_bench_runs``); the targets below are what
the conclusions compare with.
"""
from __future__ import annotations

import math
import os

import numpy as np

from strapdown_ros.bench.filter_bench_runs import RATE
from strapdown_ros.bench.stats import median_range, stats
from strapdown_ros.estimation import chi2_3_quantile
from strapdown_ros.estimation.chi_square import chi2_interval
from strapdown_ros.figures import save_figure

TARGET_RATIO = 1.1
TARGET_US = 50.0
#: filter_bag within this many times a raw read of the same bag
TARGET_BAG_RATIO = 2.0


def render(res: dict) -> str:
    """
    Render the markdown text of the run (printed, and the body of the report).

    Parameters
    ----------
    res : dict
        The run's result with its conclusions.

    Returns
    -------
    str
        The markdown.

    """
    L = ['# filter_bench', '', '```', res['command'], '```', '']
    if 'summary' in res:
        L += _render_monte_carlo(res)
    bt = res.get('bag_timing')
    if bt:
        L += render_bag_timing(bt)
    L += ['', '## Conclusions', ''] + [f'* {c}' for c in res['conclusions']]
    return '\n'.join(L)


def render_bag_timing(bt: dict) -> list[str]:
    """
    Render the filter_bag-against-raw-read section.

    Parameters
    ----------
    bt : dict
        ``filter_bench_runs.bag_timing``'s result.

    Returns
    -------
    list of str
        The markdown lines.

    """
    raw, fb = stats(bt['raw_process_s']), stats(bt['filter_bag_s'])
    per = bt['ratio_per_run']
    ph = bt['phases']
    shown = ' '.join(f'-p {p}' for p in bt['params'])
    L = ['', f"## filter_bag on {bt['bag']} beside a raw read ({bt['records']} records)", '',
         f"{bt['runs']} pairs in alternating order, separate processes, median (min–max); load "
         f"average at the start {' '.join(f'{x:.2f}' for x in bt['load_at_start'])}.", '',
         '| command | wall time, s |', '|---|---:|',
         '| raw read: rosbags AnyReader over every record (the whole process) | '
         f"{median_range(raw, '.2f')} |",
         '| raw read: the iteration alone | '
         f"{median_range(stats(bt['raw_iteration_s']), '.2f')} |",
         f"| `filter_bag BAG --output OUT.csv{(' ' + shown) if shown else ''}` (whole command) | "
         f"{median_range(fb, '.2f')} |", '',
         f"filter_bag / raw read: **{fb['median'] / raw['median']:.2f}×** (per pair "
         f'{min(per):.2f}–{max(per):.2f}×); the target ≤ {TARGET_BAG_RATIO:g}× is '
         f"{'met' if fb['median'] / raw['median'] <= TARGET_BAG_RATIO else 'NOT met'}.", '',
         f"filter_bag's summary: {bt['summary']}", '',
         f"Phases of one filter_bag in this process ({ph['increments']} increments, "
         f"{ph['fixes']} fixes, {ph['outputs']} outputs):", '',
         '| phase | s | µs per increment |', '|---|---:|---:|']
    n = max(ph['increments'], 1)
    for key, name in (('kernels_s', 'load the compiled kernels (numba, its cache) and warm up'),
                      ('read_s', 'read the bag (recording.reader.read_bag)'),
                      ('filter_s', 'the filter (run_filter), all of it'),
                      ('model_check_add_s', '… of which the live model check (ModelCheck.add)'),
                      ('csv_text_s', 'the CSV text of the outputs and fixes')):
        if key in ph:                          # (kernels_s: not in runs before 0.4.2)
            L.append(f'| {name} | {ph[key]:.2f} | {ph[key] / n * 1e6:.2f} |')
    return L


def _render_monte_carlo(res: dict) -> list[str]:
    """Render the Monte Carlo, timing and real-data sections."""
    s, set_ = res['summary'], res['settings']
    att = s['attitude']
    L = [
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
    return L


def conclusions(res: dict) -> list[str]:
    """
    Return the conclusion sentences, each computed from the run's numbers.

    Parameters
    ----------
    res : dict
        The run's result.

    Returns
    -------
    list of str
        The sentences.

    """
    out = []
    bt = res.get('bag_timing')
    if bt:
        ratio = stats(bt['filter_bag_s'])['median'] / stats(bt['raw_process_s'])['median']
        ph = bt['phases']
        out.append(f'filter_bag takes {ratio:.2f}× the time of a raw read of the bag: '
                   f"{'within' if ratio <= TARGET_BAG_RATIO else 'ABOVE'} the target "
                   f'{TARGET_BAG_RATIO:g}× at this load.  Of its work in one process, '
                   + (f"loading the compiled kernels took {ph['kernels_s']:.2f} s, "
                      if 'kernels_s' in ph else '') +
                   f"reading the bag {ph['read_s']:.2f} s, the filter {ph['filter_s']:.2f} s (the "
                   f"live model check {ph['model_check_add_s']:.2f} s of it) and the CSV text "
                   f"{ph['csv_text_s']:.2f} s.")
    if 'summary' not in res:
        return out
    s = res['summary']
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
    """
    Write the attitude-error, bias and NIS plots.

    Attitude error of run 0 with ±3σ and the RMS against √PCRB; bias with ±3σ; NIS with its
    bands.

    Parameters
    ----------
    outdir : str
        Directory (created).
    mc : dict
        Result of ``filter_bench_runs.monte_carlo``.

    Returns
    -------
    list of str
        Paths of the files written.

    """
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

    def rms(e):
        return 1e6 * np.sqrt(np.mean(np.square(e), axis=(0, 2)))

    def bnd(B):
        return 1e6 * np.sqrt([np.trace(b[:3, :3]) / 3 for b in B])

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
    lo, hi = chi2_interval(3 * runs)
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
