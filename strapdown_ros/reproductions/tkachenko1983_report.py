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
        rows = [(case, 'ours_as_printed', 'ours')]
        if 'ours_corrected' in rec:
            rows = [(f'{case} by (5.5)', 'ours_as_printed', 'ours'),
                    (f'{case} by (5.6)', 'ours_as_printed_corrected', 'ours_corrected')]
        for label, kp, ki in rows:
            cells = [f'{_rms(rec["paper"]):.2e}']
            for key in (kp, ki):
                a = r['headline'][case][key]
                cells.append(f"{_rms(rec[key]):.2e} ({a['rms_ratio']:.2f}, "
                             f"{a['signs']}/{a['n']}, {a['corr']:+.2f})")
            L.append(f'| {label} | ' + ' | '.join(cells) + ' |')
    L.append('')
    if 'beyond_paper_printed' in r:
        seeds = r['centring_gain']['seeds']
        parts = []
        for est, b in (("000's method as printed", r['beyond_paper_printed']),
                       ('the modified estimator', r['beyond_paper'])):
            ch = [_change(b['raw'][k], b[m][k]) for m in ('centred', 'corrected')
                  for k in ('rms_c', 'rms_d')]
            ok = _centring_holds(b)
            parts.append(f'with {est} (5.5) changes the RMS of c by {ch[0]}, of d by {ch[1]}, '
                         f'and (5.6) by {ch[2]}, {ch[3]}: '
                         + _verdict(ok, 'the claim reproduces', 'the claim does not reproduce'))
        L += ['000 also says that with centring, (5.5) or (5.6), the errors "approached those of '
              'the unquantized information". Over our Monte Carlo of '
              f'{seeds} initial remainders (threshold: the RMS of c and of d each fall by at '
              f'least {100 * NO_EFFECT:g}%), ' + '; '.join(parts) + '.', '']
    return L


def _change(before: float, after: float) -> str:
    """Return the relative change from ``before`` to ``after`` as text (e.g. ``-0.08%``)."""
    return f'{100 * (after / before - 1):+.2g}%'


def _centring_holds(b: dict) -> bool:
    """000's centring claim by the stated threshold: c and d each fall by ≥ NO_EFFECT."""
    return all(b[m][k] <= (1 - NO_EFFECT) * b['raw'][k]
               for m in ('centred', 'corrected') for k in ('rms_c', 'rms_d'))


#: the rows of the error tables: the paper's published set first, then 000's method as printed
ROW_NAMES = {'paper': "paper (000's published errors)", 'ours_as_printed': "ours: 000's method as "
                                                                           'printed',
             'ours_as_printed_corrected': "ours: 000's method as printed, increments by (5.6)",
             'ours': 'ours: modified estimator',
             'ours_corrected': 'ours: modified estimator, increments by (5.6)',
             'ours_iterated': 'ours: Gauss–Newton',
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
        if 'ours_corrected' in hc:
            L.append(f'* **{case}** with the increments corrected by (5.6) instead of (5.5), '
                     f"000's method as printed: {_agree(hc['ours_as_printed_corrected'])}. "
                     f"Modified estimator: {_agree(hc['ours_corrected'])}.")
    L += ['', 'Errors estimate − truth (w0: corrected attitude error w⁰ at t_f; dc, dd in the '
              "paper's units).", '']
    for case, rec in r['cases'].items():
        L += [f'### {case}', '', '| | w0 ×1e-5 | δc1…δc9 | δd1…δd3 |', '|---|---|---|---|']
        for key in ('paper', 'ours_as_printed', 'ours_as_printed_corrected', 'ours',
                    'ours_corrected', 'ours_iterated', 'ours_mc_mean', 'ours_mc_std'):
            if key not in rec:
                continue
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
    L += ['* Quantized, raw, Δθ0 = 0, modified estimator: ours/paper for δc1…δc9 = '
          + ', '.join(f'{v:+.2f}' for v in q_ratio)
          + f" ({hq['signs']}/12 signs over δc, δd; RMS ratio {hq['rms_ratio']:.2f})."]
    L += _centring_lines(r) + _w0_lines(r)
    L += ["* Corrections to 000's §2/§5 print used here, each checked in "
          'test/calibration/test_drifting_reference.py: (2.5) sign of '
          'p×(w+w0); q_F = −½Δθ in (5.2); z = z′ − δz in (5.4); R(q_K) = σ²/48, not σ²/12.', '']
    L += _ablation_lines(r['ablations'])
    L += _beyond_lines(r)
    return '\n'.join(L)


#: the Monte Carlo rows of the quantized table: (estimator key, case key, label)
MC_ROWS = (('printed', 'raw', "000's method as printed: raw (5.4), first order"),
           ('printed', 'centred', "000's method as printed: centred (5.5), first order"),
           ('printed', 'corrected', "000's method as printed: increments by (5.6), first order"),
           ('identity', 'raw', 'modified: raw (5.4), first order'),
           ('identity', 'centred', 'modified: centred (5.5), first order'),
           ('identity', 'corrected', 'modified: increments by (5.6), first order'),
           ('identity', 'raw+iter', 'modified: raw, Gauss–Newton'),
           ('identity', 'centred+iter', 'modified: centred, Gauss–Newton'),
           ('identity', 'raw+weighted', 'modified: raw, weighted R(δz)⁻¹'),
           ('identity', 'centred+weighted', 'modified: centred, weighted'),
           ('identity', 'centred+iter+weighted', 'modified: centred, Gauss–Newton, weighted'))


def _centring_lines(r: dict) -> list[str]:
    """000's centring claim, judged for 000's method as printed first, then the modified one."""
    un, seeds = r['unquantized_rms'], r['centring_gain']['seeds']
    L = []
    for name, b, u in (("000's method as printed", r['beyond_paper_printed'], un['printed']),
                       ('modified estimator', r['beyond_paper'], un['identity'])):
        parts = []
        for m, f in (('centred', '(5.5)'), ('corrected', '(5.6)')):
            parts.append(f'{f}: RMS of c {b["raw"]["rms_c"]:.4g} → {b[m]["rms_c"]:.4g} '
                         f'({_change(b["raw"]["rms_c"], b[m]["rms_c"])}), of the biases c7–9 '
                         f'{b["raw"]["rms_c_bias"]:.3g} → {b[m]["rms_c_bias"]:.3g} '
                         f'({_change(b["raw"]["rms_c_bias"], b[m]["rms_c_bias"])}), of d '
                         f'{b["raw"]["rms_d"]:.4g} → {b[m]["rms_d"]:.4g} '
                         f'({_change(b["raw"]["rms_d"], b[m]["rms_d"])})')
        ok = _centring_holds(b)
        verdict = _verdict(ok, 'holds', 'does not hold')
        if name.startswith('000'):
            verdict += " with the paper's own method"
        L.append(f'* Centring, {name}, Monte Carlo over {seeds} seeds — ' + '; '.join(parts)
                 + f"; unquantized (one run): c {u['rms_c']:.3g}, d {u['rms_d']:.3g}. 000 says "
                 'the centred errors approach the unquantized ones (threshold: the RMS of c and '
                 f'of d each fall by at least {100 * NO_EFFECT:g}%, by (5.5) and by (5.6)): '
                 f'{verdict}.')
    return L


def _w0_lines(r: dict) -> list[str]:
    """Judge w⁰, the attitude error after the correction, which 000 prints too."""
    parts, same, larger, total = [], 0, 0, 0
    for case, rec in r['cases'].items():
        pn = float(np.linalg.norm(rec['paper']['w0']))
        cells = []
        for key, name in (('ours_as_printed', "000's method as printed"),
                          ('ours', 'modified')):
            on = float(np.linalg.norm(rec[key]['w0']))
            signs = int(np.sum(np.sign(rec[key]['w0']) == np.sign(rec['paper']['w0'])))
            total += 1
            same += abs(np.log(pn / on)) <= np.log(EXPLAINS_WITHIN)
            larger += pn > on
            cells.append(f'{name} {on:.2e} (paper/ours {pn / on:.2f}, {signs}/3 signs)')
        parts.append(f'{case}: paper {pn:.2e}, ' + ', '.join(cells))
    L = ['* w⁰, the attitude error left after the correction (000 prints it with each set; '
         '|w⁰| at t_f, Δθ0 = 0): ' + '; '.join(parts) + f'. Same size (within '
         f"{EXPLAINS_WITHIN:g}×, the ablations' threshold) in {same} of {total} comparisons; "
         f"the paper's |w⁰| is the larger in {larger} of {total}."]
    mc = {c: h['monte_carlo'] for c, h in r['headline'].items() if 'monte_carlo' in h}
    if mc:
        zs = ', '.join(f"{c} {m['w0_z_rms']:.2f}" for c, m in mc.items())
        ok = all(m['w0_z_rms'] <= 2.0 for m in mc.values())
        paper = {c: float(np.linalg.norm(r['cases'][c]['paper']['w0']))
                 for c in ('quantized_raw', 'quantized_centred')}
        ch = []
        for name, b in (("000's method as printed", r['beyond_paper_printed']),
                        ('modified', r['beyond_paper'])):
            w = {m: b[m]['rms_w0_final'] for m in ('raw', 'centred', 'corrected')}
            ch.append(f"{name} {_change(w['raw'], w['centred'])} by (5.5), "
                      f"{_change(w['raw'], w['corrected'])} by (5.6)")
        moved = [b[m]['rms_w0_final'] <= (1 - NO_EFFECT) * b['raw']['rms_w0_final']
                 for b in (r['beyond_paper_printed'], r['beyond_paper'])
                 for m in ('centred', 'corrected')]
        verdict = ('brings w⁰ closer to the unquantized one with both estimators and both '
                   'formulas' if all(moved) else
                   'does not bring w⁰ closer with either estimator or formula' if not any(moved)
                   else f'brings w⁰ closer in {sum(moved)} of {len(moved)} (estimator, formula) '
                        'pairs')
        L.append("* w⁰ against our Monte Carlo (modified estimator): RMS z of the paper's w⁰ "
                 f'{zs} — ' + _verdict(ok, 'plausible draws of the quantization noise', 'not all '
                                       'plausible draws of the quantization noise')
                 + ' (plausible if RMS z ≤ 2). Centring changes the RMS of w⁰(t_f) over the '
                 'seeds by ' + '; '.join(ch) + "; the paper's |w⁰| goes from "
                 f"{paper['quantized_raw']:.2e} (raw) to {paper['quantized_centred']:.2e} "
                 f'(centred). Verdict (threshold: a fall of at least {100 * NO_EFFECT:g}%): '
                 f'centring {verdict}.')
    return L


def _beyond_lines(r: dict) -> list[str]:
    """Tabulate the quantized Monte Carlo of both estimators and what goes beyond the paper."""
    b, bp, un = r['beyond_paper'], r['beyond_paper_printed'], r['unquantized_rms']
    seeds = r['centring_gain']['seeds']
    base = bp['raw']
    cols = ('rms_c', 'rms_c_bias', 'rms_d', 'rms_w0_final', 'rms_w')
    L = [f'### Quantized, Monte Carlo over {seeds} seeds (σ = 2e-5): centring, and beyond the '
         'paper', '',
         "RMS errors over the seeds; in brackets the ratio to 000's method as printed, raw (5.4), "
         "first order — the paper's method without centring. The unquantized rows are one run "
         "each (no randomness); 'modified' is this project's estimator.", '',
         '| method | c | c7–9 | d | w⁰ at t_f | w⁰ over the epochs |', '|---|---|---|---|---|---|']
    for est, v in (('printed', un['printed']), ('identity', un['identity'])):
        name = ("000's method as printed" if est == 'printed' else 'modified') + ': unquantized'
        L.append(f'| {name} | ' + ' | '.join(f'{v[q]:.2e} ({v[q] / base[q]:.2f})' for q in cols)
                 + ' |')
    for est, key, name in MC_ROWS:
        src = bp if est == 'printed' else b
        if key not in src:
            continue
        v = src[key]
        L.append(f'| {name} | ' + ' | '.join(f'{v[q]:.2e} ({v[q] / base[q]:.2f})' for q in cols)
                 + ' |')
    it_gain = 1 - b['centred+iter']['rms_c'] / b['centred']['rms_c']
    w_gain = 1 - b['centred+weighted']['rms_c'] / b['centred']['rms_c']
    best = min(b, key=lambda k: b[k]['rms_c'])
    names = {key: name for est, key, name in MC_ROWS if est == 'identity'}
    L += ['', '* On c, from the centred first-order solution of the modified estimator: '
              f'Gauss–Newton {100 * it_gain:+.1f}%, weighting by R(δz)⁻¹ {100 * w_gain:+.1f}%; '
              f"weighting {_verdict(w_gain > it_gain, 'gains more', 'gains less')} than "
              f'iteration. Lowest RMS of c: {names.get(best, best)} '
              f"({b[best]['rms_c'] / base['rms_c']:.2f} of 000's method as printed, raw).", '']
    return L


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
    seeds = r['centring_gain']['seeds']
    fig, ax = plt.subplots(figsize=(8, 4.2))
    keys, labels = ('rms_c', 'rms_c_bias', 'rms_d'), ['c', 'c7–9 (biases)', 'd']
    xx = np.arange(len(keys))
    bars = [(est, m) for est in ('printed', 'identity') for m in ('raw', 'centred', 'corrected')]
    names = {'printed': "000's method as printed", 'identity': 'modified'}
    forms = {'raw': 'raw (5.4)', 'centred': 'centred (5.5)', 'corrected': '(5.6)'}
    width = 0.8 / len(bars)
    for i, (est, m) in enumerate(bars):
        src = r['beyond_paper_printed'] if est == 'printed' else r['beyond_paper']
        vals = [src[m][k] for k in keys]
        pos = xx - 0.4 + (i + 0.5) * width
        ax.bar(pos, vals, width, label=f'{names[est]}, {forms[m]}',
               color=('C3' if est == 'printed' else 'C0'), alpha=(1.0, 0.65, 0.35)[i % 3])
        if m != 'raw':
            for x, v, v0 in zip(pos, vals, [src['raw'][k] for k in keys]):
                ax.annotate(f'{100 * (v / v0 - 1):+.0f}%', (x, v), ha='center', va='bottom',
                            fontsize=6)
    ax.set_xticks(xx, labels)
    ax.set_ylabel('RMS error over seeds')
    ax.set_title(f'000 §6, σ = 2e-5: centring, Monte Carlo over {seeds} seeds')
    ax.legend(fontsize=7)
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
