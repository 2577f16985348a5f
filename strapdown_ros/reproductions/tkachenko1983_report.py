"""
The report section of Tkachenko 1983 (paper 000) §6 for ``reproduce_seeds``.

Turns the numbers of :func:`strapdown_ros.reproductions.tkachenko1983.section_000` into the
Markdown section and its figures: the paper's published errors beside ours, the ablation table
with its verdicts and thresholds, and the methods beyond the paper.  No ROS imports; matplotlib
only inside :func:`plots_000`.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.figures import save_figure
from strapdown_ros.reproductions.tkachenko1983 import (ESTIMATORS, EXPLAINS_WITHIN, NO_EFFECT,
                                                       SAME_PATTERN)


def _verdict(ok: bool, yes: str, no: str) -> str:
    return yes if ok else no


def ablation_verdict(k: dict, base: dict) -> tuple[str, bool]:
    """
    Judge one knob for one estimator, with the thresholds stated beside the verdict.

    Parameters
    ----------
    k : dict
        The knob's :func:`~strapdown_ros.reproductions.tkachenko1983.agreement` with the paper.
    base : dict
        The same estimator's agreement without the knob.

    Returns
    -------
    verdict : str
        The verdict text, its thresholds included.
    explains : bool
        True when the RMS ratio is within :data:`EXPLAINS_WITHIN` of 1 and the correlation is
        at least :data:`SAME_PATTERN`.

    """
    change = abs(k['rms_ratio'] / base['rms_ratio'] - 1)
    size_ok = abs(np.log(k['rms_ratio'])) <= np.log(EXPLAINS_WITHIN)
    pattern_ok = k['corr'] >= SAME_PATTERN
    if size_ok and pattern_ok:
        return (f'explains size and pattern (ratio within {EXPLAINS_WITHIN:g}× of 1, corr ≥ '
                f'{SAME_PATTERN:g})',
                True)
    if change < NO_EFFECT:
        return f'size unchanged: ratio moves {100 * change:.1f}% (< {100 * NO_EFFECT:g}%)', False
    if size_ok:
        return (f"size only: ratio within {EXPLAINS_WITHIN:g}× of 1, corr {k['corr']:+.3f} < "
                f'{SAME_PATTERN:g}',
                False)
    if pattern_ok:
        return (f"pattern only: corr ≥ {SAME_PATTERN:g}, ratio {k['rms_ratio']:.2g} not within "
                f'{EXPLAINS_WITHIN:g}× of 1', False)
    return (f"neither: ratio {k['rms_ratio']:.2g} not within {EXPLAINS_WITHIN:g}× of 1, corr "
            f"{k['corr']:+.3f} < {SAME_PATTERN:g}", False)


def _ablation_lines(a: dict) -> list[str]:
    L = ["### What makes the paper's unquantized errors larger: ablations", '',
         "One knob changed at a time on the unquantized first-order run (Δθ0 = 0), with 000's "
         'method as '
         'printed and with the modified estimator; RMS ratio = RMS(paper)/RMS(ours) over δc, δd; '
         'corr = '
         "cosine between our 12 errors and the paper's. Thresholds: a knob explains the paper's "
         'errors '
         f'if its ratio is within {EXPLAINS_WITHIN:g}× of 1 and its corr ≥ {SAME_PATTERN:g} '
         '(fixed, not '
         f'the corr of either estimator); the size is unchanged if the ratio moves less than '
         f'{100 * NO_EFFECT:g}% from the same estimator without the knob.', '']
    head = '| knob |'
    for est, name in ESTIMATORS.items():
        head += f' {name}: ratio | signs | corr | verdict |'
    L += [head, '|---|' + '---|---|---|---|' * len(ESTIMATORS)]
    base = {est: a['knobs']['none'][est] for est in ESTIMATORS}
    explained = []
    for key, k in a['knobs'].items():
        row = f"| {k['label']} |"
        for est, name in ESTIMATORS.items():
            v = k[est]
            verdict, ok = (('— (reference row)', False) if key == 'none'
                           else ablation_verdict(v, base[est]))
            if ok:
                explained.append(f"{k['label']} ({name})")
            row += (f" {v['rms_ratio']:.2f} | {v['signs']}/{v['n']} | {v['corr']:+.3f} | "
                    f'{verdict} |')
        L.append(row)
    L.append('')
    for est, name in ESTIMATORS.items():
        n = a['noise'][est]
        noise_ok = (n['corr_mean'] >= SAME_PATTERN
                    and abs(np.log(n['rms_ratio_mean'])) <= np.log(EXPLAINS_WITHIN))
        if noise_ok:
            explained.append(f'noise on the reference angles ({name})')
        L.append(f'* Noise, {name}: white noise on the aircraft angles raises the RMS error of '
                 'δc, δd by '
                 f"{n['rms_per_rad']:.3g} per rad of angle noise (probe {n['probe_rad']:.0e} rad, "
                 f"{n['seeds']} "
                 f"seeds); the paper's RMS needs σ_φ ≈ {n['sigma_for_paper_rms_rad']:.2g} rad. At "
                 'that σ the ratio '
                 f"is {n['rms_ratio_mean']:.2f} on average, with {n['signs_mean']:.1f}/12 signs "
                 'and corr '
                 f"{n['corr_mean']:+.2f} ± {n['corr_std']:.2f}: "
                 + _verdict(noise_ok, f'explains size and pattern (corr ≥ {SAME_PATTERN:g}).',
                            f'not the pattern (corr < {SAME_PATTERN:g}).'))
    if explained:
        L.append("* Knobs that explain the paper's errors by these thresholds: "
                 + '; '.join(explained) + '.')
    else:
        bp, bi = base['printed'], base['identity']
        z = a['w0_zero']['identity']

        def closeness(ke):
            v = a['knobs'][ke[0]][ke[1]]
            return v['corr'] - 10 * max(abs(np.log(v['rms_ratio'])) - np.log(EXPLAINS_WITHIN), 0)

        best = max(((key, est) for key in a['knobs'] for est in ESTIMATORS if key != 'none'),
                   key=closeness)
        kb = a['knobs'][best[0]][best[1]]
        L.append('* No knob tried, with either estimator, brings the ratio within '
                 f'{EXPLAINS_WITHIN:g}× of 1 with '
                 f"corr ≥ {SAME_PATTERN:g}. 000's method as printed gives ratio "
                 f"{bp['rms_ratio']:.2f}, "
                 f"{bp['signs']}/{bp['n']} signs, corr {bp['corr']:+.2f}; the modified "
                 "estimator's remainder "
                 f"(second order: w0·c and c²) has corr {bi['corr']:+.2f} with the paper but is "
                 f"{bi['rms_ratio']:.1f}× smaller (paper ≈ {bi['scale']:.1f}·ours, "
                 f"{100 * bi['misfit']:.0f}% of "
                 f"the paper's vector left over); with w0 = 0 its corr is {z['corr']:+.2f}. "
                 'Closest knob by '
                 f"these thresholds: {a['knobs'][best[0]]['label']} with the "
                 f'{ESTIMATORS[best[1]]} '
                 f"(ratio {kb['rms_ratio']:.2f}, {kb['signs']}/{kb['n']} signs, corr "
                 f"{kb['corr']:+.2f}). "
                 "Which step of the 1983 computation produced the paper's errors is not "
                 'identified.')
    return L + ['']


def _rms(rec: dict) -> float:
    return float(np.sqrt(np.mean(np.square(np.r_[rec['dc'], rec['dd']]))))


def _claim_lines(r: dict) -> list[str]:
    """Open the section with 000's published errors beside ours, case by case."""
    L = ["**The paper's claim beside ours.** 000 §6 prints three sets of estimation errors "
         '(δc1…δc9, δd1…δd3; the rows "paper" of the tables below, as printed). Their RMS '
         'beside the RMS of ours on the same experiment (Δθ0 = 0, as in 000):', '',
         "| case | paper (000 §6, as printed): RMS | ours, 000's method as printed: RMS "
         '(paper/ours, signs, corr) | ours, modified estimator: RMS (paper/ours, signs, corr) |',
         '|---|---|---|---|']
    for case, rec in r['cases'].items():
        cells = [f'{_rms(rec["paper"]):.2e}']
        for key in ('ours_as_printed', 'ours'):
            a = r['headline'][case][key]
            cells.append(f"{_rms(rec[key]):.2e} ({a['rms_ratio']:.2f}, {a['signs']}/{a['n']}, "
                         f"{a['corr']:+.2f})")
        L.append(f'| {case} | ' + ' | '.join(cells) + ' |')
    return L + ['']


#: the rows of the error tables: the paper's published set first, then 000's method as printed
ROW_NAMES = {'paper': "paper (000's published errors)", 'ours_as_printed': "ours: 000's method as "
                                                                           'printed',
             'ours': 'ours: modified estimator', 'ours_iterated': 'ours: Gauss–Newton',
             'ours_mc_mean': 'ours: modified, Monte Carlo mean',
             'ours_mc_std': 'ours: modified, Monte Carlo std'}


def report_000(r: dict) -> str:
    """
    Write the 000 section of the report.

    Parameters
    ----------
    r : dict
        The result of :func:`strapdown_ros.reproductions.tkachenko1983.section_000`.

    Returns
    -------
    str
        Markdown: the paper's errors beside ours, the headline, the error tables, the
        ablations and the methods beyond the paper.

    """
    L = ['## 000 — gyro errors against a drifting reference (Tkachenko 1983, §6)', '']
    h = r['headline']
    L += _claim_lines(r)
    L += ['Headline — first order, Δθ0 = 0 as in 000 (RMS ratio = RMS(paper)/RMS(ours) over '
          'δc1…δc9, δd1…δd3; '
          "signs = components with the paper's sign; corr = cosine between the two 12-vectors). "
          "First 000's "
          'method as printed (every coefficient of (5.7) at the reference increment p), then this '
          "project's "
          'modified estimator (w0 columns at ½(p + p*), c columns at p*; see below):', '']

    def _agree(o: dict) -> str:
        return (f"the paper's errors are {o['rms_ratio']:.3g}× ours in RMS "
                f"({_verdict(o['rms_ratio'] > 1, 'ours smaller', 'ours larger')}), "
                f"{o['signs']}/{o['n']} signs agree, "
                f"corr {o['corr']:+.2f}")

    for case, hc in h.items():
        o, op = hc['ours'], hc['ours_as_printed']
        line = (f"* **{case}**, 000's method as printed: {_agree(op)}. Modified estimator: "
                f'{_agree(o)}; '
                f"largest |ours/paper| {o['max_ratio']:.2g}.")
        if 'monte_carlo' in hc:
            m = hc['monte_carlo']
            line += (f" Against our Monte Carlo (modified estimator) over {m['seeds']} initial "
                     'remainders: paper '
                     f"RMS / our RMS {m['rms_ratio']:.2f}, {m['within_2sigma']}/{m['n']} paper "
                     'values within 2σ of '
                     f"our mean (RMS z {m['z_rms']:.2f}; plausible if RMS z ≤ 2) — the paper's "
                     'set '
                     + _verdict(m['z_rms'] <= 2.0, 'is a plausible draw of the quantization '
                                                   'noise.',
                                'is not a plausible draw of our quantization noise.'))
        L.append(line)
    L += ['', 'Errors estimate − truth (w0: corrected attitude error w⁰ at t_f; dc, dd in the '
              "paper's units).", '']
    for case, rec in r['cases'].items():
        L += [f'### {case}', '', '| | w0 ×1e-5 | δc1…δc9 | δd1…δd3 |', '|---|---|---|---|']
        for key in ('paper', 'ours_as_printed', 'ours', 'ours_iterated', 'ours_mc_mean',
                    'ours_mc_std'):
            v = rec[key]
            L.append(f'| {ROW_NAMES[key]} | '
                     + ' '.join(f'{x * 1e5:+.2f}' for x in v['w0']) + ' | '
                     + ' '.join(f'{x:+.1e}' for x in v['dc']) + ' | '
                     + ' '.join(f'{x:+.1e}' for x in v['dd']) + ' |')
        L.append('')
    un, hu = r['cases']['unquantized'], h['unquantized']
    L += ["* 'ours: modified estimator' is 000's first-order method — one linear least-squares "
          'solve of '
          '(2.7)/(5.7), no iteration — with its coefficients moved to where the exact quaternion '
          'identity '
          'p° − q = w0 × (p° + q) puts them: the w0 columns at ½(p + p*), the c columns at the '
          'computed '
          'increment p*, the d columns at the reference p (derivation: '
          'strapdown_ros/calibration/drifting_reference.py, '
          "'Where to evaluate the coefficients'). '000's method as printed' evaluates everything "
          'at p, '
          'as 000 prints.',
          '* Unquantized, printed coefficients: the w0² term 2w0 × (w0 × p*) stays in z; RMS '
          'ratio '
          f"{hu['ours_as_printed']['rms_ratio']:.2f}, {hu['ours_as_printed']['signs']}/12 signs, "
          'δc6 = '
          f"{un['ours_as_printed']['dc'][5]:+.1e} against the paper's {un['paper']['dc'][5]:+.1e} "
          f"({abs(un['ours_as_printed']['dc'][5] / un['paper']['dc'][5]):.0f}×).",
          f'* Iterated (Gauss–Newton on the exact model), unquantized: largest |error| '
          f"{max(abs(v) for v in un['ours_iterated']['dc'] + un['ours_iterated']['dd']):.1e}, "
          f"{1 / hu['ours_iterated']['max_ratio']:.1e}× below the paper's component for component "
          'at least.']
    q, hq = r['cases']['quantized_raw'], h['quantized_raw']['ours']
    q_ratio = np.array(q['ours']['dc']) / np.array(q['paper']['dc'])
    L += ['* Quantized, raw, Δθ0 = 0: ours/paper for δc1…δc9 = '
          + ', '.join(f'{v:+.2f}' for v in q_ratio)
          + f" ({hq['signs']}/12 signs over δc, δd; RMS ratio {hq['rms_ratio']:.2f})."]
    g = r['centring_gain']
    gc, gd = 1 - g['rms_c_centred'] / g['rms_c_raw'], 1 - g['rms_d_centred'] / g['rms_d_raw']
    gp = 1 - g['printed_rms_c_centred'] / g['printed_rms_c_raw']
    gb = 1 - g['rms_c_bias_centred'] / g['rms_c_bias_raw']
    L += [f"* Centring (5.5), Monte Carlo over {g['seeds']} seeds: RMS of c {g['rms_c_raw']:.2e} "
          '→ '
          f"{g['rms_c_centred']:.2e} ({100 * abs(gc):.0f}% {_verdict(gc > 0, 'less', 'more')}), "
          'of the biases c7–9 '
          f"{g['rms_c_bias_raw']:.2e} → {g['rms_c_bias_centred']:.2e} ({100 * abs(gb):.0f}% "
          f"{_verdict(gb > 0, 'less', 'more')}), of d {g['rms_d_raw']:.2e} → "
          f"{g['rms_d_centred']:.2e} "
          f"({100 * abs(gd):.0f}% {_verdict(gd > 0, 'less', 'more')}). 000 says centring brings "
          'the errors towards '
          f"the unquantized ones: {_verdict(gc > 0 and gd > 0, 'agrees', 'does not agree')}. With "
          'the printed '
          f'coefficients the gain on c is {100 * gp:.1f}%.',
          "* Corrections to 000's §2/§5 print used here, each checked in "
          'test/calibration/test_drifting_reference.py: (2.5) sign of '
          'p×(w+w0); q_F = −½Δθ in (5.2); z = z′ − δz in (5.4); R(q_K) = σ²/48, not σ²/12.', '']
    L += _ablation_lines(r['ablations'])
    b = r.get('beyond_paper')
    if b:
        base = b['raw']
        L += [f"### Beyond the paper (σ = 2e-5, Monte Carlo over {g['seeds']} seeds)", '',
              "RMS errors, and in brackets the ratio to the paper's method without centring (raw, "
              'first order).', '',
              '| method | c | c7–9 | d | w⁰ (attitude at the epochs) |', '|---|---|---|---|---|']
        names = {'raw': 'raw (5.4), first order', 'centred': 'centred (5.5), first order',
                 'raw+iter': 'raw, Gauss–Newton', 'centred+iter': 'centred, Gauss–Newton',
                 'raw+weighted': 'raw, weighted R(δz)⁻¹', 'centred+weighted': 'centred, weighted',
                 'centred+iter+weighted': 'centred, Gauss–Newton, weighted'}
        for k, v in b.items():
            L.append(f'| {names.get(k, k)} | ' + ' | '.join(
                f'{v[qq]:.2e} ({v[qq] / base[qq]:.2f})' for qq in ('rms_c', 'rms_c_bias', 'rms_d',
                                                                   'rms_w')) + ' |')
        it_gain = 1 - b['centred+iter']['rms_c'] / b['centred']['rms_c']
        w_gain = 1 - b['centred+weighted']['rms_c'] / b['centred']['rms_c']
        best = min(b, key=lambda k: b[k]['rms_c'])
        L += ['', '* On c, from the centred first-order solution: Gauss–Newton '
                  f'{100 * it_gain:+.1f}%, weighting by '
              f'R(δz)⁻¹ {100 * w_gain:+.1f}%; weighting '
              f"{_verdict(w_gain > it_gain, 'gains more', 'gains less')} "
              f'than iteration. Lowest RMS of c: {names.get(best, best)}.', '']
    return '\n'.join(L)


def plots_000(r: dict, outdir: str) -> list[str]:
    """
    Draw the figures of the 000 section: errors, centring and ablations.

    Parameters
    ----------
    r : dict
        The result of :func:`strapdown_ros.reproductions.tkachenko1983.section_000`.
    outdir : str
        Directory of the figures.

    Returns
    -------
    list of str
        Paths of ``seeds_000_errors.png``, ``seeds_000_centring.png`` and
        ``seeds_000_ablations.png``.

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    paths = []
    labels = [f'c{i}' for i in range(1, 10)] + [f'd{i}' for i in range(1, 4)]
    x = np.arange(len(labels))
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2), sharey=True)
    for ax, (case, rec) in zip(axes, r['cases'].items()):
        def mag(key):
            return np.abs(np.r_[rec[key]['dc'], rec[key]['dd']])
        ax.semilogy(x, mag('paper'), 'ks', ms=7, label='000 (paper)')
        ax.semilogy(x, mag('ours'), 'o', color='C0', label='ours, modified estimator')
        ax.semilogy(x, mag('ours_as_printed'), 'x', color='C3', ms=7, label="ours, 000's method "
                                                                            'as printed')
        if any(v > 0 for v in rec['ours_mc_std']['dc']):
            rms = np.sqrt(np.square(np.r_[rec['ours_mc_mean']['dc'], rec['ours_mc_mean']['dd']])
                          + np.square(np.r_[rec['ours_mc_std']['dc'], rec['ours_mc_std']['dd']]))
            ax.semilogy(x, rms, '_', color='C2', ms=14, mew=2, label='ours (modified), Monte '
                                                                     'Carlo RMS')
        ho, hp = r['headline'][case]['ours'], r['headline'][case]['ours_as_printed']
        ax.set_xticks(x, labels)
        ax.set_title(f"{case}: paper/ours RMS, signs\nas printed {hp['rms_ratio']:.2g}, "
                     f"{hp['signs']}/{hp['n']}; "
                     f"modified {ho['rms_ratio']:.2g}, {ho['signs']}/{ho['n']}", fontsize=10)
        ax.grid(True, which='both', alpha=0.3)
    axes[0].set_ylabel('|estimate − truth| (c1–6: 1; c7–9, d: rad/s)')
    axes[0].legend(fontsize=8, loc='lower left')
    fig.suptitle('000 §6: estimation errors, paper against ours (iterated: off scale below)')
    paths.append(save_figure(fig, outdir, 'seeds_000_errors.png'))
    g = r['centring_gain']
    fig, ax = plt.subplots(figsize=(6.5, 4))
    raw = [g['rms_c_raw'], g['rms_c_bias_raw'], g['rms_d_raw']]
    cen = [g['rms_c_centred'], g['rms_c_bias_centred'], g['rms_d_centred']]
    xx = np.arange(3)
    ax.bar(xx - 0.2, raw, 0.4, label='raw (5.4)')
    ax.bar(xx + 0.2, cen, 0.4, label='centred (5.5)')
    for i in range(3):
        ax.annotate(f'{-100 * (1 - cen[i] / raw[i]):+.0f}%', (xx[i] + 0.2, cen[i]), ha='center',
                    va='bottom')
    ax.set_xticks(xx, ['c', 'c7–9 (biases)', 'd'])
    ax.set_ylabel('RMS error over seeds')
    ax.set_title(f"000 §6, σ = 2e-5: centring, Monte Carlo over {g['seeds']} seeds")
    ax.legend()
    paths.append(save_figure(fig, outdir, 'seeds_000_centring.png'))
    a = r['ablations']
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5), sharey=True)
    names = list(a['knobs'])
    yy = np.arange(len(names))
    for ax, (est, title) in zip(axes, ESTIMATORS.items()):
        vals = [a['knobs'][k][est] for k in names]
        ax.barh(yy, [v['rms_ratio'] for v in vals],
                color=['C0' if v['corr'] >= SAME_PATTERN else 'C7' for v in vals])
        for y, v in zip(yy, vals):
            ax.annotate(f" corr {v['corr']:+.3f}, {v['signs']}/{v['n']}", (v['rms_ratio'], y),
                        va='center',
                        fontsize=7)
        ax.axvline(1.0, color='k', lw=1)
        ax.axvspan(1 / EXPLAINS_WITHIN, EXPLAINS_WITHIN, color='C2', alpha=0.12)
        ax.set_xscale('log')
        ax.set_xlim(min(0.3 * min(v['rms_ratio'] for v in vals), 0.3),
                    20 * max(v['rms_ratio'] for v in vals))
        ax.set_title(title)
        ax.set_xlabel("RMS(paper)/RMS(ours), unquantized δc, δd (1 = the paper's size)")
    axes[0].set_yticks(yy, names, fontsize=8)
    fig.suptitle(f"000 §6 ablations: green band = within {EXPLAINS_WITHIN:g}× of the paper's "
                 'size; '
                 f'blue bar = corr ≥ {SAME_PATTERN:g}, grey = below')
    paths.append(save_figure(fig, outdir, 'seeds_000_ablations.png'))
    return paths
