"""
Changes of each unit's effects between recordings, and each effect across the population.

**The change test.**  A series is one unit's values x_i ± σ_i of one effect component (effect,
parameter, index) over its recordings, in start-time order t_i (days).  Each σ_i is first
widened by the component's run-to-run repeatability τ (σ_i² + τ²): the scatter between
recordings that the per-recording σ do not contain (a turn-on bias, an unmodelled condition),
estimated from every consecutive pair of every unit so that the median of
|x_i − x_{i−1}| / √(σ_i² + σ_{i−1}² + 2τ²) is that of a standard normal (0.6745); τ = 0 when
the σ already account for it, or with fewer than 6 pairs.  Against H0 "constant" (the weighted
mean), two alternatives, each a weighted least-squares fit with one parameter more than H0:

* a **jump** between consecutive recordings k−1 and k: two levels, before and after; its size
  is the difference of the two weighted means, σ from the weights; z = size/σ, p_k two-sided;
  every split k is scanned, so the jump's p is (n−1)·min p_k (Bonferroni over the splits);
* a **trend** (n ≥ 3): a straight line in t; its size is the slope per day with its σ;
  z = slope/σ, p two-sided.

The series' p is 2·min(p_jump, p_trend) (Bonferroni over the two kinds; p_jump alone for two
recordings).  The family is every unit × effect × component series of the fleet with two
recordings or more (m of them); **Holm's step-down procedure** at family-wise level α
(default 0.01) decides which series changed, so the probability of any false change in the
whole fleet is at most α when the σ are right.  A changed series is named by the alternative
with the smaller p (the jump's p carries its scan over the splits; a jump on a tie): a jump at
the recording k that starts the new level, or a trend at the series' last recording.  Then, at
the fixed level α/m: each side of a jump is tested again the same way (a second jump or a trend
within a part), and the residuals of a trend are scanned for a jump.  ``p_value`` is Holm's
adjusted p of the series for the first change, m·p for the later ones.

**The population.**  Per effect component, each unit's latest value: the median, the spread
(1.4826 × the median absolute deviation, a σ of a normal population) and the outlier units,
whose modified z = |x − median| / √(spread² + σ² + τ²) exceeds 3.5 (Iglewicz & Hoaglin 1993),
judged with three units or more.
"""
from __future__ import annotations

from dataclasses import dataclass
from math import erfc, log, log1p, pi, sqrt

import numpy as np

__all__ = ['Change', 'SeriesTest', 'series_test', 'series_of', 'repeatability',
           'detect_changes', 'population', 'DEFAULT_LEVEL', 'OUTLIER_Z', 'MAD_SIGMA',
           'MIN_PAIRS']

#: family-wise level of the change test over the whole fleet
DEFAULT_LEVEL = 0.01
#: modified z beyond which a unit is an outlier of the population
OUTLIER_Z = 3.5
#: the MAD of a normal population times this is its σ
MAD_SIGMA = 1.4826
#: fewest consecutive pairs of a component from which its repeatability τ is estimated
MIN_PAIRS = 6
#: the median of |z| for a standard normal z
MEDIAN_ABS_Z = 0.6744897501960817


@dataclass(frozen=True)
class Change:
    """
    One change detected in a unit's series.

    Attributes
    ----------
    unit, effect, parameter : str
        The series.
    index : int
        The component.
    recording : str
        Jump: the first recording of the new level; trend: the last recording of the series.
    kind : str
        ``jump`` or ``trend``.
    size : float
        Jump: new level − old level, SI units; trend: the slope, SI units per day.
    sigma : float
        Its σ.
    p_value : float
        Holm's adjusted p of the series (a first change), or m·p (a later one).
    start : str
        Trend: the first recording of the fitted part; jump: the last one before it.

    """

    unit: str
    effect: str
    parameter: str
    index: int
    recording: str
    kind: str
    size: float
    sigma: float
    p_value: float
    start: str = ''


@dataclass(frozen=True)
class SeriesTest:
    """
    The tests of one series (or part of one) against a constant.

    Attributes
    ----------
    p : float
        The series' p (both kinds, their corrections included).
    kind : str
        The better alternative: ``jump`` or ``trend``.
    split : int
        The jump's first index of the new level (jump).
    size, sigma : float
        The better alternative's size and σ.
    chi2_const : float
        χ² of the constant, n−1 dof.

    """

    p: float
    kind: str
    split: int
    size: float
    sigma: float
    chi2_const: float


def _p_two_sided(z: float) -> float:
    return float(erfc(abs(z) / sqrt(2.0)))


def _log_p_two_sided(z: float) -> float:
    """Return log of the two-sided normal p of z, finite far beyond where p underflows."""
    p = _p_two_sided(z)
    if p > 1e-300:
        return log(p)
    a = abs(z)                       # erfc(x) ≈ exp(−x²)/(x√π)(1 − 1/(2x²)), x = a/√2
    return -0.5 * a * a - log(a) + 0.5 * log(2.0 / pi) + log1p(-1.0 / (a * a))


def _line(t, x, w):
    """Weighted line: slope, its σ, χ², the fitted values."""
    tm = np.sum(w * t) / np.sum(w)
    stt = np.sum(w * (t - tm) ** 2)
    if not stt > 0:
        return 0.0, float('inf'), float('inf'), np.full_like(x, np.sum(w * x) / np.sum(w))
    b = float(np.sum(w * (t - tm) * x) / stt)
    a = float(np.sum(w * x) / np.sum(w))
    fit = a + b * (t - tm)
    return b, float(1.0 / np.sqrt(stt)), float(np.sum(w * (x - fit) ** 2)), fit


def series_test(t, x, s) -> SeriesTest | None:
    """
    Test a series against a constant: a jump (scanned) or a trend.

    Parameters
    ----------
    t : array_like
        Times, days (increasing).
    x, s : array_like
        Values and their σ (σ > 0).

    Returns
    -------
    SeriesTest or None
        None for fewer than two values.

    """
    t, x, s = (np.asarray(a, dtype=float) for a in (t, x, s))
    n = len(x)
    if n < 2:
        return None
    w = 1.0 / s ** 2
    m = np.sum(w * x) / np.sum(w)
    chi_const = float(np.sum(w * (x - m) ** 2))
    best = None
    cw, cwx = np.cumsum(w), np.cumsum(w * x)
    for k in range(1, n):
        w1, w2 = cw[k - 1], cw[-1] - cw[k - 1]
        m1, m2 = cwx[k - 1] / w1, (cwx[-1] - cwx[k - 1]) / w2
        size, sig = float(m2 - m1), float(np.sqrt(1.0 / w1 + 1.0 / w2))
        z = size / sig
        if best is None or abs(z) > abs(best[3]):
            best = (k, size, sig, z)
    k, j_size, j_sig, j_z = best
    p_jump = min(1.0, (n - 1) * _p_two_sided(j_z))
    if n < 3:
        return SeriesTest(p_jump, 'jump', k, j_size, j_sig, chi_const)
    b, sb, _, _ = _line(t, x, w)
    p_trend = _p_two_sided(b / sb) if np.isfinite(sb) else 1.0
    p = min(1.0, 2.0 * min(p_jump, p_trend))
    # the kinds compared by log p (p itself underflows for large changes); the jump's scan
    # over n − 1 splits counts against it
    log_jump = log(n - 1) + _log_p_two_sided(j_z)
    log_trend = _log_p_two_sided(b / sb) if np.isfinite(sb) else 0.0
    if log_trend < log_jump:
        return SeriesTest(p, 'trend', n - 1, b, sb, chi_const)
    return SeriesTest(p, 'jump', k, j_size, j_sig, chi_const)


def _holm(ps: list[float]) -> list[float]:
    """Holm's adjusted p-values (step-down), in the order given."""
    m = len(ps)
    order = np.argsort(ps, kind='stable')
    adj = np.empty(m)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * ps[i]))
        adj[i] = running
    return adj.tolist()


def _later_changes(key, t, x, s, names, level_each, m, out, depth=0):
    """Test the parts of a series at the fixed level α/m; append what is found."""
    if depth > 8 or len(x) < 2:
        return
    st = series_test(t, x, s)
    if st is None or not st.p <= level_each:
        return
    _emit(key, st, names, min(1.0, m * st.p), out)
    _follow(key, st, t, x, s, names, level_each, m, out, depth + 1)


def _emit(key, st: SeriesTest, names, p_value, out) -> None:
    unit, effect, parameter, index = key
    if st.kind == 'jump':
        rec, start = names[st.split], names[st.split - 1]
    else:
        rec, start = names[-1], names[0]
    out.append(Change(unit, effect, parameter, int(index), rec, st.kind, float(st.size),
                      float(st.sigma), float(p_value), start))


def _follow(key, st, t, x, s, names, level_each, m, out, depth):
    if st.kind == 'jump':
        k = st.split
        _later_changes(key, t[:k], x[:k], s[:k], names[:k], level_each, m, out, depth)
        _later_changes(key, t[k:], x[k:], s[k:], names[k:], level_each, m, out, depth)
        return
    w = 1.0 / s ** 2
    _, _, _, fit = _line(t, x, w)
    r = x - fit                                    # the trend's residuals: a jump left?
    n = len(r)
    if n < 2:
        return
    k = max(range(1, n), key=lambda j: abs(_split_z(r, w, j)))
    z = _split_z(r, w, k)
    p = min(1.0, (n - 1) * _p_two_sided(z))
    if p <= level_each:
        w1, w2 = np.sum(w[:k]), np.sum(w[k:])
        size = float(np.sum(w[k:] * r[k:]) / w2 - np.sum(w[:k] * r[:k]) / w1)
        sig = float(np.sqrt(1.0 / w1 + 1.0 / w2))
        _emit(key, SeriesTest(p, 'jump', k, size, sig, 0.0), names, min(1.0, m * p), out)


def _split_z(x, w, k) -> float:
    w1, w2 = np.sum(w[:k]), np.sum(w[k:])
    m1, m2 = np.sum(w[:k] * x[:k]) / w1, np.sum(w[k:] * x[k:]) / w2
    return float((m2 - m1) / np.sqrt(1.0 / w1 + 1.0 / w2))


def series_of(rows) -> dict:
    """
    Group effect rows into series, each in start-time order.

    Parameters
    ----------
    rows : iterable of dict
        ``unit, recording, t_days, effect, parameter, index, value, sigma`` (finite value and
        σ > 0 only are kept).

    Returns
    -------
    dict
        (unit, effect, parameter, index) → (t, x, s, recordings).

    """
    groups: dict = {}
    for r in rows:
        v, sg = r['value'], r['sigma']
        if not (np.isfinite(v) and np.isfinite(sg) and sg > 0):
            continue
        key = (r['unit'], r['effect'], r['parameter'], int(r['index']))
        groups.setdefault(key, []).append((r['t_days'], v, sg, r['recording']))
    out = {}
    for key, items in groups.items():
        items.sort(key=lambda it: it[0])
        t, x, s, names = zip(*items)
        out[key] = (np.array(t), np.array(x), np.array(s), list(names))
    return out


def repeatability(series: dict) -> dict:
    """
    Return each component's run-to-run repeatability τ from the consecutive pairs of all units.

    Parameters
    ----------
    series : dict
        (unit, effect, parameter, index) → (t, x, s, recordings) (:func:`series_of`).

    Returns
    -------
    dict
        (effect, parameter, index) → τ ≥ 0, SI units: the smallest τ for which the median of
        |x_i − x_{i−1}| / √(σ_i² + σ_{i−1}² + 2τ²) is at most 0.6745; 0 with fewer than
        :data:`MIN_PAIRS` pairs.

    """
    pairs: dict = {}
    for (_, effect, parameter, index), (_, x, s, _) in series.items():
        d = np.abs(np.diff(x))
        v = s[1:] ** 2 + s[:-1] ** 2
        pairs.setdefault((effect, parameter, index), []).extend(zip(d, v))
    out = {}
    for comp, ps in pairs.items():
        if len(ps) < MIN_PAIRS:
            out[comp] = 0.0
            continue
        d, v = (np.array(a) for a in zip(*ps))

        def med(tau):
            return float(np.median(d / np.sqrt(v + 2.0 * tau * tau)))
        if med(0.0) <= MEDIAN_ABS_Z:
            out[comp] = 0.0
            continue
        lo, hi = 0.0, float(np.max(d))
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if med(mid) > MEDIAN_ABS_Z else (lo, mid)
        out[comp] = hi
    return out


def detect_changes(rows, level: float = DEFAULT_LEVEL) -> tuple[list[Change], dict]:
    """
    Find the changes of every series of the fleet, the false-alarm rate held by Holm.

    Parameters
    ----------
    rows : iterable of dict
        Effect rows (:func:`series_of`).
    level : float
        Family-wise level α over all series.

    Returns
    -------
    changes : list of Change
        Sorted by unit, effect, parameter, index, recording.
    tests : dict
        ``series`` (m, tested), ``level``, ``method``, the smallest adjusted p and
        ``repeatability`` (:func:`repeatability`, added to each σ in quadrature).

    """
    series = series_of(rows)
    tau = repeatability(series)
    series = {k: (t, x, np.sqrt(s ** 2 + tau[k[1:]] ** 2), names)
              for k, (t, x, s, names) in series.items()}
    keys = [k for k, v in series.items() if len(v[1]) >= 2]
    tests = {k: series_test(*series[k][:3]) for k in keys}
    m = len(keys)
    adjusted = _holm([tests[k].p for k in keys]) if keys else []
    changes: list[Change] = []
    for k, p_adj in zip(keys, adjusted):
        if p_adj > level:
            continue
        t, x, s, names = series[k]
        _emit(k, tests[k], names, p_adj, changes)
        _follow(k, tests[k], t, x, s, names, level / m, m, changes, 1)
    changes.sort(key=lambda c: (c.unit, c.effect, c.parameter, c.index, c.recording))
    return changes, {'series': m, 'level': level, 'method': 'Holm step-down over the series; '
                     'Bonferroni over the jump splits and the two kinds',
                     'min_adjusted_p': float(min(adjusted)) if adjusted else None,
                     'repeatability': tau}


def population(latest, tau: dict | None = None) -> list[dict]:
    """
    Return the population of each effect component: median, spread and outlier units.

    Parameters
    ----------
    latest : iterable of dict
        Each unit's latest row per component: ``unit, effect, parameter, index, value,
        sigma``.
    tau : dict, optional
        (effect, parameter, index) → repeatability τ (:func:`repeatability`).

    Returns
    -------
    list of dict
        ``effect, parameter, index, units, median, spread, repeatability, outlier_units`` (a
        list), sorted.

    """
    groups: dict = {}
    for r in latest:
        if np.isfinite(r['value']):
            groups.setdefault((r['effect'], r['parameter'], int(r['index'])), []).append(r)
    out = []
    for (effect, parameter, index), rs in sorted(groups.items()):
        x = np.array([r['value'] for r in rs])
        s = np.array([r['sigma'] if np.isfinite(r['sigma']) else 0.0 for r in rs])
        med = float(np.median(x))
        spread = float(MAD_SIGMA * np.median(np.abs(x - med)))
        rep = float((tau or {}).get((effect, parameter, index), 0.0))
        outliers = []
        if len(rs) >= 3:
            z = np.abs(x - med) / np.sqrt(spread ** 2 + s ** 2 + rep ** 2 + 1e-300)
            outliers = sorted(r['unit'] for r, zi in zip(rs, z) if zi > OUTLIER_Z)
        out.append({'effect': effect, 'parameter': parameter, 'index': index, 'units': len(rs),
                    'median': med, 'spread': spread, 'repeatability': rep,
                    'outlier_units': outliers})
    return out
