"""
Markdown text, conclusions and plots of ``model_check_bench``.

Every sentence is computed from the run's numbers (``model_check_runs``).
"""
from __future__ import annotations

import math
import os

import numpy as np

from strapdown_ros.figures import save_figure

#: the target of issue 28: false WARN episodes per hour of clean data
TARGET_PER_HOUR = 0.1


def _binomial(k: int, n: int) -> str:
    """k/n as a share with its 95 % interval (Wilson)."""
    if n == 0:
        return '–'
    p, z = k / n, 1.96
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return f'{p:.2e} [{max(0.0, mid - half):.1e}, {mid + half:.1e}]'


def _poisson_upper(k: int) -> float:
    """One-sided 95 % upper bound of a Poisson mean after k events (exact, chi-square)."""
    lam = k + 3.0
    for _ in range(200):          # Newton on P(X ≤ k; λ) = 0.05
        terms = [math.exp(-lam + i * math.log(lam) - math.lgamma(i + 1)) for i in range(k + 1)]
        f = sum(terms) - 0.05
        df = -terms[-1]
        step = f / df
        lam -= step
        if abs(step) < 1e-12:
            break
    return lam


def conclusions(res: dict) -> list[str]:
    """
    Return the conclusions, each computed from the run's numbers.

    Parameters
    ----------
    res : dict
        The run's result.

    Returns
    -------
    list of str
        Sentences.

    """
    out = []
    nw = res.get('null')
    if nw:
        for r in nw['rows']:
            lv = r['level']
            out.append(f"White windows (N = {nw['window']}): Ljung–Box against "
                       f"χ²({3 * nw['lags']}) rejects {r['ljung_box_chi2']:.2%} at a nominal "
                       f"{lv:g} ({r['ljung_box_chi2'] / lv:.2f}×); the spectral whiteness test "
                       f"{r['spectral_whiteness']:.2%} ({r['spectral_whiteness'] / lv:.2f}×), "
                       f"the NIS band {r['nis_band']:.2%} ({r['nis_band'] / lv:.2f}×), the "
                       f"window test {r['window_test']:.2%} ({r['window_test'] / lv:.2f}×).")
    clean = res.get('clean') or []
    ok_runs = [c for c in clean if 'constants' not in c['motion']]
    if ok_runs:
        h = sum(c['hours'] for c in ok_runs)
        ep = sum(c['episodes'] for c in ok_runs)
        old = sum(c['old']['episodes'] for c in ok_runs)
        up = _poisson_upper(ep) / h
        met = 'met' if ep / h <= TARGET_PER_HOUR else 'not met'
        out.append(f'Real filter, {h:g} h of clean recordings over {len(ok_runs)} motions at one '
                   f'fix per second: {ep} WARN episode(s), {ep / h:.3f} per hour (95 % upper '
                   f'bound of {h:g} h: {up:.3f}); the rule before: {old} episodes, '
                   f'{old / h:.2f} per hour, on the same innovations. Target ≤ '
                   f'{TARGET_PER_HOUR} per hour: {met} by the measured rate.')
    for d in res.get('direct') or []:
        out.append(f"White innovations fed to the check directly, {d['hours']:g} h at a fix every "
                   f"{d['fix_interval_s']:g} s: {d['episodes']} episode(s), "
                   f"{d['episodes_per_hour']:.3f} per hour (95 % upper bound "
                   f"{_poisson_upper(d['episodes']) / d['hours']:.3f}; stated ≤ "
                   f"{res['settings']['rate']:g}), {d['failed']} failing windows of "
                   f"{d['windows']}.")
    b = res.get('bag')
    if b and 'episodes' in b:
        out.append(f"record_sim + filter_bag, {b['hours']:g} h clean coning: {b['episodes']} WARN "
                   f"episode(s) over {b['fixes']} fixes, mean NIS {b['mean_nis']:.3f}.")
    for reg, r in (res.get('naming') or {}).items():
        for row in r['rows']:
            if row['answer'] is None:
                lib = sorted(row['names'])
                out.append(f"{reg}: {row['effect']}: failing windows name "
                           f"{', '.join(lib) or 'nothing'} (never an effect outside the "
                           'library).')
    return out


def render(res: dict) -> str:
    """
    Render the markdown text of the run.

    Parameters
    ----------
    res : dict
        The run's result with its conclusions.

    Returns
    -------
    str
        The markdown.

    """
    s = res['settings']
    L = ['# model_check_bench', '', '```', res['command'], '```', '',
         f"Live model check: windows of {s['window']} fixes, stated rate {s['rate']:g} false WARN "
         f"episodes per hour; a window is tested at α = min({s['alpha']:g}, rate × fix "
         'interval / 3600 s): NIS sum against its χ² band at α/2 (two-sided), spectral '
         'whiteness at α/2; an episode starts at a failing window and ends after a full window '
         'of passing windows.', '']
    nw = res.get('null')
    if nw:
        L += [f"## Window tests on white windows ({nw['windows']} windows of {nw['window']} fixes "
              '× 3 axes, N(0, 1))', '',
              '| nominal level | Ljung–Box vs χ² (before) | NIS band (two-sided) | spectral '
              'whiteness | window test (NIS at α/2, whiteness at α/2) |',
              '|---:|---:|---:|---:|---:|']
        n = nw['windows']
        for r in nw['rows']:
            L.append(f"| {r['level']:g} | "
                     + ' | '.join(_binomial(int(round(r[k] * n)), n) for k in
                                  ('ljung_box_chi2', 'nis_band', 'spectral_whiteness',
                                   'window_test')) + ' |')
        L += ['', f"Share rejected [95 % interval]. Ljung–Box lags {nw['lags']}; the vectorised "
              "statistic equals the package's `ljung_box` within "
              f"{nw['ljung_box_vectorised_max_difference']:.1e}.", '']
    clean = res.get('clean')
    if clean:
        L += ['## Clean recordings through the real filter', '',
              "One fix per second; the simulators' defaults (navigation-grade gyro, "
              '0.6″/0.6″/6″ camera) with the random scale and misalignment constants off; '
              'in stamp order through `FilterSystem` as `filter_bag` runs it.', '',
              '| motion | hours | fixes | gated | mean NIS | NEES/3 | windows | failing | WARN '
              'episodes | per hour | before: failing | before: episodes |',
              '|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|']
        for c in clean:
            L.append(f"| {c['motion']} | {c['hours']:g} | {c['fixes']} | {c['gated']} | "
                     f"{c['mean_nis']:.3f} | {c['nees_over_3']:.3f} | {c['windows']} | "
                     f"{c['failed']} | {c['episodes']} | {c['episodes'] / c['hours']:.3f} | "
                     f"{c['old']['failed']} | {c['old']['episodes']} |")
        ok = [c for c in clean if 'constants' not in c['motion']]
        if ok:
            h = sum(c['hours'] for c in ok)
            ep = sum(c['episodes'] for c in ok)
            old = sum(c['old']['episodes'] for c in ok)
            L.append(f"| **all clean** | {h:g} | {sum(c['fixes'] for c in ok)} | "
                     f"{sum(c['gated'] for c in ok)} | | | {sum(c['windows'] for c in ok)} | "
                     f"{sum(c['failed'] for c in ok)} | {ep} | {ep / h:.3f} | "
                     f"{sum(c['old']['failed'] for c in ok)} | {old} |")
        named = {}
        for c in clean:
            for k, v in c['named_when_failing'].items():
                named[k] = named.get(k, 0) + v
        L += ['', 'Before: the same innovations judged by the rule this check replaces (Σ NIS '
              'band and Ljung–Box against χ², each at 0.001, windows of 30; an episode is a run '
              'of failing windows). Failing windows named: '
              + (', '.join(f'{k} {v}' for k, v in sorted(named.items())) or 'none') + '.', '']
    direct = res.get('direct')
    if direct:
        L += ['## The check fed white innovations directly', '',
              '| fix interval, s | hours | windows | window level | failing windows | WARN '
              'episodes | per hour |', '|---:|---:|---:|---:|---:|---:|---:|']
        for d in direct:
            L.append(f"| {d['fix_interval_s']:g} | {d['hours']:g} | {d['windows']} | "
                     f"{d['window_level']:.2e} | {d['failed']} | {d['episodes']} | "
                     f"{d['episodes_per_hour']:.3f} |")
        L.append('')
    b = res.get('bag')
    if b:
        L += ['## record_sim and filter_bag', '']
        if 'episodes' in b:
            L += ['```', b['record_sim'], b['filter_bag'], '```', '',
                  f"{b['hours']:g} h, {b['fixes']} fixes, mean NIS {b['mean_nis']:.3f}: "
                  f"{b['episodes']} WARN episode(s) (`check_ok` 1 → 0 in OUT_fixes.csv).", '']
            L += ['```'] + b['filter_bag_summary'] + ['```', '']
        else:
            L += [f"not run: {b.get('reason', '')}", '']
    for reg, r in (res.get('naming') or {}).items():
        L += [f'## Naming, regime `{reg}`', '', r['text'] + '; three-axis sinusoidal motion '
              '(rotation vector a_i sin(ν_i t + p_i), a = 0.3, 0.25, 0.2 rad, ν = 0.31, 0.47, '
              '0.73 rad/s), a fix per second.', '',
              '| hidden effect | right answer | windows | failing | right, of all windows | '
              'right, of failing windows | names of the failing windows | fixes applied / '
              'gated |', '|---|---|---:|---:|---:|---:|---|---:|']
        for row in r['rows']:
            ans = row['answer'] or '(none in the library)'
            names = ', '.join(f'{k} {v}' for k, v in sorted(row['names'].items(),
                                                            key=lambda kv: -kv[1]))
            allr = f"{row['right'] / row['windows']:.2f}" if row['windows'] else '–'
            fr = (f"{row['right_when_failing'] / row['failed']:.2f}" if row['failed'] and
                  row['answer'] else '–')
            L.append(f"| {row['effect']} | {ans} | {row['windows']} | {row['failed']} | {allr} "
                     f"| {fr} | {names or '–'} | {row['applied']} / {row['gated']} |")
        L.append('')
    L += ['## Conclusions', ''] + [f'* {c}' for c in res['conclusions']]
    L += ['', f"Wall time {res.get('wall_s', float('nan')):.0f} s; load average at the start "
          f"{' '.join(f'{x:.2f}' for x in res['load_at_start'])} on {res['cpu_count']} cores."]
    return '\n'.join(L)


def write_plots(outdir: str, res: dict) -> list[str]:
    """
    Write the calibration and naming plots.

    Parameters
    ----------
    outdir : str
        Directory (created).
    res : dict
        The run's result.

    Returns
    -------
    list of str
        Paths written.

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    os.makedirs(outdir, exist_ok=True)
    paths = []
    nw = res.get('null')
    if nw:
        fig, ax = plt.subplots(figsize=(6.5, 4.8))
        lv = np.array([r['level'] for r in nw['rows']])
        ax.loglog(lv, lv, 'k--', lw=1, label='nominal')
        for key, lab, st in (('ljung_box_chi2', 'Ljung–Box vs χ² (before)', 'C3o-'),
                             ('spectral_whiteness', 'spectral whiteness', 'C0s-'),
                             ('nis_band', 'NIS band (two-sided)', 'C2^-'),
                             ('window_test', 'window test (both)', 'C1d-')):
            y = np.array([max(r[key], 0.5 / nw['windows']) for r in nw['rows']])
            ax.loglog(lv, y, st, label=lab)
        ax.set_xlabel('nominal level')
        ax.set_ylabel('share of white windows rejected')
        ax.set_title(f"white windows of {nw['window']} fixes ({nw['windows']} windows)")
        ax.legend()
        ax.grid(True, which='both', alpha=0.3)
        paths.append(save_figure(fig, outdir, 'null_calibration.png'))
    naming = res.get('naming') or {}
    if naming:
        fig, axs = plt.subplots(1, len(naming), figsize=(7.5 * len(naming), 5.5), squeeze=False)
        for ax, (reg, r) in zip(axs[0], naming.items()):
            rows = r['rows']
            cols = sorted({k for row in rows for k in row['names']} | {'consistent'})
            M = np.zeros((len(rows), len(cols)))
            for i, row in enumerate(rows):
                n = max(row['windows'], 1)
                for j, c in enumerate(cols):
                    M[i, j] = (row['windows'] - row['failed'] if c == 'consistent'
                               else row['names'].get(c, 0)) / n
            ax.imshow(M, cmap='Blues', vmin=0, vmax=1, aspect='auto')
            ax.set_xticks(range(len(cols)))
            ax.set_xticklabels(cols, rotation=40, ha='right', fontsize=8)
            ax.set_yticks(range(len(rows)))
            ax.set_yticklabels([row['effect'] for row in rows], fontsize=8)
            for i in range(len(rows)):
                for j in range(len(cols)):
                    if M[i, j] >= 0.005:
                        ax.text(j, i, f'{M[i, j]:.2f}', ha='center', va='center', fontsize=7,
                                color='w' if M[i, j] > 0.6 else 'k')
            ax.set_title(f'regime {reg}: share of windows per verdict', fontsize=10)
        paths.append(save_figure(fig, outdir, 'naming.png'))
    return paths
