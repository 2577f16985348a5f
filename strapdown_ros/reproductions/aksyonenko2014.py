"""
Aksyonenko 2014 (paper 003), coning §2.3, for ``reproduce_seeds``.

The three cases and the thesis's claims against our measured drift, each value marked where it
is below the float64 round-off floor of its algorithm (the rule of
doc/results/coning_bench/coning.md).  The full comparison is ``coning_bench`` →
doc/results/coning_bench/coning.md.  No ROS imports.
"""
from __future__ import annotations

from strapdown_ros.attitude.coning import SEED_ALGORITHMS
from strapdown_ros.attitude.coning_analysis import FLOOR_FACTOR, measure_case
from strapdown_ros.sensors import DEG_PER_HOUR

__all__ = ['section_003', 'report_003', 'CLAIM_LIMIT_DEG_PER_H']

#: 003 §2.3: in case 1 every algorithm but (1) stays below this drift
CLAIM_LIMIT_DEG_PER_H = 1e-3


def section_003(duration: float) -> dict:
    """
    Measure the drift of every seed algorithm in the three coning cases of 003 §2.3.

    Parameters
    ----------
    duration : float
        Seconds per case.

    Returns
    -------
    dict
        Per case and update size the drift along the cone axis, °/h, the round-off floor and
        the values at it, and the case-1 claim checks (JSON-able).

    """
    names = list(SEED_ALGORITHMS)
    out = {'duration_s': duration, 'cases': []}
    for (a, nu) in ((0.087, 1.0), (0.5, 1.0), (0.087, 0.5)):
        for step in (0.01, 0.001):
            r = measure_case(names, a, nu, step, duration)
            # the rule of coning_bench / doc/results/coning_bench/coning.md
            floor = FLOOR_FACTOR * max(r.floor.values())
            out['cases'].append({'alpha': a, 'nu': nu, 'step': step,
                                 'drift_deg_per_h': {n: r.drift[n] / DEG_PER_HOUR for n in names},
                                 'at_floor': {n: bool(abs(r.drift[n]) <= floor) for n in names},
                                 'floor_deg_per_h': floor / DEG_PER_HOUR})
    claims = {}
    for step in (0.001, 0.01):
        c1 = next(c for c in out['cases']
                  if c['alpha'] == 0.087 and c['nu'] == 1.0 and c['step'] == step)
        d = c1['drift_deg_per_h']
        others = [abs(v) for n, v in d.items() if n != '1']
        claims[str(step)] = {'others_below_1e-3': all(v < CLAIM_LIMIT_DEG_PER_H for v in others),
                             'largest_other': max(abs(v) for n, v in d.items() if n != '1'),
                             'algorithm_1_above_1e-3': abs(d['1']) > CLAIM_LIMIT_DEG_PER_H,
                             'algorithm_1_deg_per_h': d['1']}
    out['claim_case1'] = claims
    return out


def report_003(r: dict) -> str:
    """
    Write the 003 section of the report.

    Parameters
    ----------
    r : dict
        The result of :func:`section_003`.

    Returns
    -------
    str
        Markdown: the thesis's claim beside ours, the drift table and the claim checks.

    """
    names = list(r['cases'][0]['drift_deg_per_h'])
    L = [f"## 003 — coning, §2.3 ({r['duration_s']:g} s per case)", '']
    claim = []
    for step, cl in r['claim_case1'].items():
        claim.append(f"τ = {step} s: largest of the others {cl['largest_other']:.2g} °/h, "
                     f"algorithm (1) {cl['algorithm_1_deg_per_h']:.2g} °/h")
    L += ["**The paper's claim beside ours.** 003 §2.3 (as printed, no drift table): in case 1 "
          f'(α = 0.087, ν = 1) every algorithm but (1) drifts less than {CLAIM_LIMIT_DEG_PER_H:g} '
          '°/h, and algorithm (1) more. Ours: ' + '; '.join(claim) + '.', '',
          'Drift along the cone axis, °/h. The floor is the float64 round-off of the same '
          'arithmetic fed with '
          'the exact rotation vector (|slope| + 3σ, largest over the update sizes, × 3, as '
          'doc/results/coning_bench/coning.md); a value '
          'at or below it is marked *(floor)*: it measures round-off, not the algorithm, and is '
          'not compared.', '',
          '| case | τ | ' + ' | '.join(names) + ' | floor |',
          '|---|---|' + '---|' * (len(names) + 1)]
    n_floor = 0
    for c in r['cases']:
        cells = []
        for n, v in c['drift_deg_per_h'].items():
            fl = c.get('at_floor', {}).get(n, False)
            n_floor += fl
            cells.append(f'{v:.2e}' + (' (floor)' if fl else ''))
        L.append(f"| α={c['alpha']:g}, ν={c['nu']:g} | {c['step']:g} | " + ' | '.join(cells)
                 + f" | {c['floor_deg_per_h']:.1e} |")
    L += ['', f"{n_floor} of {len(r['cases']) * len(names)} values are at the floor.", '']
    for step, cl in r['claim_case1'].items():
        L.append(f'* Case 1, τ = {step} s: every algorithm but (1) below '
                 f'{CLAIM_LIMIT_DEG_PER_H:g} °/h — '
                 f"{'holds' if cl['others_below_1e-3'] else 'does not hold'} (largest "
                 f"{cl['largest_other']:.2g} °/h); "
                 'algorithm (1) above it — '
                 f"{'holds' if cl['algorithm_1_above_1e-3'] else 'does not hold'} "
                 f"({cl['algorithm_1_deg_per_h']:.2g} °/h).")
    L += ['', '* 003 publishes no drift table, only plots, the case-1 statement above and a '
              'ranking; '
          'doc/results/coning_bench/coning.md (coning_bench) tests the ranking.', '']
    return '\n'.join(L)
