"""
The χ² statistics of the estimation side: one home for the band, the p-value and the gate.

A weighted least-squares fit, or a filter's innovations, whose stated noise is right gives a
χ² statistic with ``dof`` degrees of freedom: :func:`chi2_band` is the acceptance band of
χ²/dof, :func:`chi2_sf` the p-value, :func:`chi2_3_quantile` the attitude filter's NIS gate.
They are exact (the regularised incomplete gamma function) and need neither numpy nor scipy,
so a node pays no scipy import in a callback.
"""
from __future__ import annotations

import math
from statistics import NormalDist

__all__ = ['FIT_LEVEL', 'chi2_band', 'chi2_interval', 'chi2_quantile', 'chi2_sf',
           'chi2_3_quantile']

#: two-sided level of the χ²/dof acceptance band: a consistent fit falls outside it with
#: probability FIT_LEVEL
FIT_LEVEL = 0.01


def _gamma_p(a: float, x: float) -> float:
    """
    Return the regularised lower incomplete gamma function P(a, x).

    The series below a + 1, Lentz's continued fraction for Q = 1 − P above (Numerical
    Recipes §6.2).
    """
    if x <= 0.0:
        return 0.0
    log_pre = a * math.log(x) - x - math.lgamma(a)
    if x < a + 1.0:
        term = total = 1.0 / a
        ap = a
        for _ in range(100000):
            ap += 1.0
            term *= x / ap
            total += term
            if term < total * 1e-15:          # both positive (a, x > 0): |term| < |total|·1e-15
                break
        return min(1.0, total * math.exp(log_pre))
    tiny = 1e-300                             # |v| < tiny as a chained comparison: no abs()
    b = x + 1.0 - a
    c, d = 1.0 / tiny, 1.0 / b
    h = d
    for k in range(1, 100000):
        an = -k * (k - a)
        b += 2.0
        d = an * d + b
        if -tiny < d < tiny:
            d = tiny
        c = b + an / c
        if -tiny < c < tiny:
            c = tiny
        d = 1.0 / d
        h *= d * c
        if -1e-15 < d * c - 1.0 < 1e-15:
            break
    return max(0.0, 1.0 - math.exp(log_pre) * h)


def chi2_quantile(p: float, dof: float) -> float:
    """
    Return x with P(χ²_dof ≤ x) = p, the exact quantile.

    Newton's method on the exact distribution function from the Wilson–Hilferty start (no
    scipy: the node must not pay its import inside a callback).

    Parameters
    ----------
    p : float
        Probability, in (0, 1).
    dof : float
        Degrees of freedom, > 0.

    Returns
    -------
    float
        The quantile.

    """
    a = 0.5 * dof
    c = 2.0 / (9.0 * dof)
    x = dof * max(1e-3, 1.0 - c + NormalDist().inv_cdf(p) * math.sqrt(c)) ** 3
    for _ in range(50):
        log_pdf = (a - 1.0) * math.log(x) - 0.5 * x - a * math.log(2.0) - math.lgamma(a)
        step = (_gamma_p(a, 0.5 * x) - p) / math.exp(log_pdf)
        x_new = x - step if x - step > 0 else 0.5 * x
        if abs(x_new - x) <= 1e-12 * x:
            return x_new
        x = x_new
    return x


def chi2_band(dof: int, level: float = FIT_LEVEL) -> tuple[float, float]:
    """
    Return the two-sided acceptance band of χ²/dof.

    (χ²_{level/2}(dof)/dof, χ²_{1−level/2}(dof)/dof): a weighted least-squares fit whose
    stated noise is right lands inside with probability 1 − level.  Exact quantiles, neither
    numpy nor scipy.

    Parameters
    ----------
    dof : int
        Degrees of freedom.
    level : float
        Two-sided level.

    Returns
    -------
    (float, float)
        The band of χ²/dof; (nan, nan) for dof < 1.

    """
    if dof < 1:
        return float('nan'), float('nan')
    return chi2_quantile(level / 2, dof) / dof, chi2_quantile(1 - level / 2, dof) / dof


def chi2_interval(dof: float, probability: float = 0.95) -> tuple[float, float]:
    """
    Return the two-sided interval of a χ² variable that holds it with ``probability``.

    Parameters
    ----------
    dof : float
        Degrees of freedom (a sum of dof squared unit normals), > 0.
    probability : float
        Probability inside the interval (0.95: the 2.5 % and 97.5 % quantiles).

    Returns
    -------
    tuple of float
        The lower and upper quantile (not divided by dof; :func:`chi2_band` is per dof).

    """
    tail = 0.5 * (1.0 - probability)
    return chi2_quantile(tail, dof), chi2_quantile(1.0 - tail, dof)


def chi2_sf(x: float, dof: int) -> float:
    """
    Return the survival function P(χ²_dof > x): the p-value of a χ² statistic.

    From the regularised incomplete gamma function of this module.

    Parameters
    ----------
    x : float
        Statistic, ≥ 0.
    dof : int
        Degrees of freedom, ≥ 1.

    Returns
    -------
    float
        The probability, in [0, 1].

    """
    if not math.isfinite(x):
        return 0.0 if x > 0 else 1.0
    return max(0.0, 1.0 - _gamma_p(0.5 * dof, 0.5 * max(x, 0.0)))


def chi2_3_quantile(probability: float) -> float:
    """
    Return the quantile of the χ² distribution with 3 degrees of freedom: the filter's gate.

    Bisection on its CDF ``erf(√(x/2)) − √(2x/π) e^{−x/2}``.

    Parameters
    ----------
    probability : float
        In (0, 1).

    Returns
    -------
    float
        x with P(χ²₃ ≤ x) = probability.

    Raises
    ------
    ValueError
        ``probability`` is not in (0, 1).

    """
    if not 0.0 < probability < 1.0:
        raise ValueError(f'probability must be in (0, 1), got {probability}')

    def cdf(x):
        return math.erf(math.sqrt(x / 2.0)) - math.sqrt(2.0 * x / math.pi) * math.exp(-x / 2.0)
    lo, hi = 0.0, 200.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if cdf(mid) < probability else (lo, mid)
    return 0.5 * (lo + hi)
