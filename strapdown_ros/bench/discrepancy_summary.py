"""
Summary of the discrepancy benchmark: detection, confusion, false alarms, their conclusions.

Turns the records of ``discrepancy_monte_carlo`` into rates with Clopper–Pearson intervals,
the ideal likelihood-ratio power beside them, the markdown tables and the conclusion
sentences (every number and verdict word computed) of ``discrepancy_bench``.
"""
from __future__ import annotations

from collections import Counter
import math

from strapdown_ros.bench.discrepancy_monte_carlo import median_summary, separable_dimension
from strapdown_ros.sensors.effects import CANDIDATES

CONFUSION_MIN_SIZE = 5.0
#: detection target of the plot marks and the conclusions: ≥ 90 % detected at k ≥ 7σ
TARGET_SIZE, TARGET_DETECTION = 7.0, 0.90


def binom_ci(k: int, n: int) -> tuple[float, float]:
    """
    Return the Clopper–Pearson 95 % interval of a binomial proportion.

    Parameters
    ----------
    k : int
        Successes.
    n : int
        Trials.

    Returns
    -------
    (float, float)
        Lower and upper bound; NaN for n = 0.

    """
    from scipy.stats import beta
    if n == 0:
        return float('nan'), float('nan')
    return (0.0 if k == 0 else float(beta.ppf(0.025, k, n - k + 1)),
            1.0 if k == n else float(beta.ppf(0.975, k + 1, n - k)))


def ideal_power(q: int, k: float, alpha: float) -> float:
    """
    Return the power of the ideal likelihood-ratio test for an effect of size k.

    P(χ²_q(k²) > χ²_q⁻¹(1 − α/(2m))): the selection gets α/2, shared by the m candidates.

    Parameters
    ----------
    q : int
        Separable dimension of the effect.
    k : float
        Mahalanobis size of the effect, σ.
    alpha : float
        Significance level of the workflow.

    Returns
    -------
    float
        Detection probability.

    """
    from scipy.stats import chi2, ncx2
    threshold = chi2.isf(alpha / 2 / len(CANDIDATES), q)      # the selection gets α/2
    return float(ncx2.sf(threshold, q, k * k))


def span_text(m: dict, what: str = 'runs') -> str:
    """
    Format a median summary of times as ``median … s (min … – max … s, n runs)``.

    Parameters
    ----------
    m : dict
        Result of ``median_summary`` (times in s).
    what : str, optional
        What was counted.

    Returns
    -------
    str
        The text.

    """
    return (f"median {m['median']:.1f} s (min {m['min']:.1f} – max {m['max']:.1f} s, "
            f"{m['n']} {what})")


def _count(rs, key) -> int:
    return sum(bool(r.get(key)) for r in rs)


def summarise(mc: dict, args) -> dict:
    """
    Summarise the Monte Carlo: detection per size, confusion, target, false alarms.

    Parameters
    ----------
    mc : dict
        Result of ``discrepancy_monte_carlo.monte_carlo``.
    args : argparse.Namespace
        The run's options (effects, sizes, alpha).

    Returns
    -------
    dict
        ``detection``, ``confusion``, ``detection_target``, ``false_alarm``, ``analysis_s``,
        ``job_s`` (median summaries, s) and ``errors``.

    """
    runs, nulls = mc['runs'], mc['nulls']
    det = {e: {} for e in args.effects}
    for e in args.effects:
        for k in args.sizes:
            rs = [r for r in runs if r['effect'] == e and r['size'] == k]
            det[e][f'{k:g}'] = {
                'n': len(rs),
                'detected': _count(rs, 'detected'),
                'named_first': _count(rs, 'named_first'),
                'within_3sigma': _count(rs, 'within_3sigma'),
                'errors': sum(r['verdict'] == 'error' for r in rs),
                'ideal_power': ideal_power(separable_dimension(e), k, args.alpha),
            }
    cols = list(CANDIDATES) + ['none']
    conf = {e: dict.fromkeys(cols, 0) for e in args.effects}
    for r in runs:
        if r['size'] >= CONFUSION_MIN_SIZE and r['verdict'] != 'error':
            conf[r['effect']][r['first'] or 'none'] += 1
    targets = {}
    for e in args.effects:
        rs = [r for r in runs if r['effect'] == e and r['size'] >= TARGET_SIZE]
        n, d = len(rs), _count(rs, 'detected')
        targets[e] = {
            'n': n,
            'detected': d,
            'rate': d / n if n else None,
            'ci95': list(binom_ci(d, n)),
            'met': d / n >= TARGET_DETECTION if n else None,
        }
    fa, nn = _count(nulls, 'false_alarm'), len(nulls)
    return {
        'detection': det,
        'confusion': {'min_size': CONFUSION_MIN_SIZE, 'columns': cols, 'rows': conf},
        'detection_target': {'size': TARGET_SIZE, 'rate': TARGET_DETECTION, 'per_effect': targets},
        'false_alarm': {
            'n': nn,
            'alarms': fa,
            'rate': fa / nn if nn else None,
            'ci95': list(binom_ci(fa, nn)),
            'alpha': args.alpha,
            'met': fa / nn <= args.alpha if nn else None,
            'verdicts': dict(Counter(r['verdict'] for r in nulls)),
            'alarms_detail': [
                {k: r.get(k) for k in ('seed', 'verdict', 'steps', 'failed_tests')}
                for r in nulls
                if r.get('false_alarm')
            ],
        },
        'analysis_s': median_summary([r['analysis_s'] for r in runs + nulls if 'analysis_s' in r]),
        'job_s': median_summary([r['job_s'] for r in runs + nulls]),
        'errors': [r for r in runs + nulls if r['verdict'] == 'error'],
    }


def _pct(x):
    return '—' if x is None or (isinstance(x, float) and math.isnan(x)) else f'{100 * x:.1f}%'


def tables(sm: dict, sizes) -> list[str]:
    """
    Format the markdown tables of the summary (also printed on stdout).

    Parameters
    ----------
    sm : dict
        Result of ``summarise``.
    sizes : list of float
        Effect sizes of the run, σ.

    Returns
    -------
    list of str
        Lines of markdown.

    """
    L = [
        '### Detection: detected/runs (ideal LRT power)', '',
        '| effect | q | ' + ' | '.join(f'k = {k:g}σ'
                                       for k in sizes) + ' | named first | estimate within 3σ |',
        '|---' * (len(sizes) + 4) + '|'
    ]
    for e, row in sm['detection'].items():
        tot = {
            key: sum(c[key] for c in row.values())
            for key in ('n', 'detected', 'named_first', 'within_3sigma')
        }
        L.append(
            f'| {e} | {separable_dimension(e)} | ' +
            ' | '.join(f"{c['detected']}/{c['n']} ({_pct(c['ideal_power'])})"
                       for c in row.values()) +
            f" | {tot['named_first']}/{tot['n']} | {tot['within_3sigma']}/{tot['detected']} |")
    c = sm['confusion']
    shown = [
        k for k in c['columns']
        if k in c['rows'] or k == 'none' or any(r[k] for r in c['rows'].values())
    ]
    L += [
        '',
        f"### Confusion at k ≥ {c['min_size']:g}σ: injected (rows) × first named (columns)",
        '',
        '| injected | ' + ' | '.join(shown) + ' |',
        '|---' * (len(shown) + 1) + '|',
    ]
    L += [f'| {e} | ' + ' | '.join(str(r[k]) for k in shown) + ' |' for e, r in c['rows'].items()]
    fa = sm['false_alarm']
    L += [
        '',
        '### False alarms (null data)',
        '',
        '| runs | alarms | rate | 95% CI | α | verdicts |',
        '|---' * 6 + '|',
        (
            f"| {fa['n']} | {fa['alarms']} | {_pct(fa['rate'])} |"
            f" {_pct(fa['ci95'][0])}–{_pct(fa['ci95'][1])} | {_pct(fa['alpha'])} |"
            f" {', '.join(f'{k} {v}' for k, v in fa['verdicts'].items())} |"
        ),
    ]
    return L


def conclusions(res: dict) -> list[str]:
    """
    Return sentences whose every number and verdict word is computed.

    Parameters
    ----------
    res : dict
        The run's result (summary, config, speed).

    Returns
    -------
    list of str
        The sentences.

    """
    sm, a = res['summary'], res['config']['alpha']
    fa, t, out = sm['false_alarm'], sm['detection_target'], []
    if fa['n']:
        lo, hi = fa['ci95']
        where = 'contains' if lo <= a <= hi else ('lies above' if lo > a else 'lies below')
        out.append(
            f"False-alarm rate {_pct(fa['rate'])} (95% CI {_pct(lo)}–{_pct(hi)},"
            f" {fa['alarms']}/{fa['n']} null runs) {'≤' if fa['met'] else '>'} α = {_pct(a)}:"
            f" {'met' if fa['met'] else 'not met'}; the interval {where} α."
        )
        out += [
            f"Null seed {d['seed']}: {d['verdict']}, added {', '.join(d['steps']) or 'nothing'},"
            f" failed tests after: {', '.join(d['failed_tests'] or []) or 'none'}."
            for d in fa['alarms_detail']
        ]
    for e, v in t['per_effect'].items():
        out.append(
            f"{e}: no runs at k ≥ {t['size']:g}σ, detection target not assessed."
            if not v['n']
            else (
                f"{e}: detected in {v['detected']}/{v['n']} runs at k ≥ {t['size']:g}σ"
                f" ({_pct(v['rate'])}, 95% CI {_pct(v['ci95'][0])}–{_pct(v['ci95'][1])})"
                f" {'≥' if v['met'] else '<'} {_pct(t['rate'])}:"
                f" {'met' if v['met'] else 'not met'}."
            )
        )
    conf = sm['confusion']['rows']
    tot = sum(sum(r.values()) for r in conf.values())
    if tot:
        right, none = sum(r[e] for e, r in conf.items()), sum(r['none'] for r in conf.values())
        out.append(
            f"At k ≥ {sm['confusion']['min_size']:g}σ the injected effect was named first in"
            f' {right}/{tot} runs ({_pct(right / tot)}); another effect in {tot - right - none},'
            f' none in {none}.'
        )
    cells = [c for row in sm['detection'].values() for c in row.values()]
    nd, w = sum(c['detected'] for c in cells), sum(c['within_3sigma'] for c in cells)
    if nd:
        out.append(
            f'{w}/{nd} detected estimates ({_pct(w / nd)}) lie within 3σ of the injected value in'
            ' every component.'
        )
    sp = res.get('speed')
    if sp:
        out.append(
            f"Speed of the discrepancy command's work (library call, JSON, report) on a bag: "
            f"{span_text(sp['time_s'])} for"
            f" {sp['duration_s']:g} s at {sp['gyro_rate_hz']:g} Hz with {sp['fixes']} fixes; load"
            f" average at start {sp['load_average_at_start'][0]:.2f}"
            + (f"; return codes {sorted(set(sp['return_codes']))}" if sp['return_codes'] else '')
            + (f"; error: {sp['cli_errors'][0]}." if sp.get('cli_errors') else '.')
        )
    if sm['errors']:
        out.append(f"{len(sm['errors'])} runs raised an error (see the JSON).")
    return out
