"""
The window tests of the live model check, exact at the window size used, and their level.

A filter whose model is right has white innovations: the whitened innovations
``w_k = L_k⁻¹ z_k`` (``S_k = L_k L_kᵀ``) of a window of N fixes are 3N independent N(0, 1)
numbers.  Both tests below are exact for that null at any N (no large-sample reference):

* **consistency**: ``T = Σ |w_k|²`` (the NIS sum) is χ²(3N);
* **whiteness**: the energy of the window in each band j of the discrete Fourier transform
  (over the fixes, summed over the three axes), ``E_j`` with ``Σ_j E_j = T``.  Its share
  ``E_j / T`` is Beta(d_j/2, (3N − d_j)/2), d_j = 6 (3 for the mean and, N even, the Nyquist
  band), whatever T: the share is independent of T (the direction of a Gaussian vector is
  independent of its length), so the two tests are independent.  The statistic is the smallest
  p-value over the J = ⌊N/2⌋ + 1 bands, and ``min(1, J·p_min)`` its p-value, a union bound
  (Bonferroni) that never understates it (Fisher 1929's test of a hidden periodicity, summed
  over axes).  A bias, a ramp or a drift puts energy in the lowest bands, a periodic error in one
  band; the Ljung–Box statistic this replaces has no exact reference at N = 30 (χ²(3L)
  rejects 0.4 % of white windows at a nominal 0.1 %).

**Level.** A window fails when the NIS sum is outside its two-sided band at ``α/2`` (α/4 each
side) or the whiteness p-value is below ``α/2``: probability ``1 − (1 − α/2)² ≤ α`` for white
innovations.  :func:`window_level` sets α from a stated rate r of false alarms per hour: with a
window ending at every fix, one fix every Δt seconds, ``α = r·Δt/3600`` makes the expected
number of failing windows, hence of WARN episodes (an episode starts at a failing window), at
most r per hour of clean data, whatever the windows' overlap.  No scipy: the node imports this.
"""
from __future__ import annotations

from functools import lru_cache
import math

import numpy as np

from strapdown_ros.estimation.chi_square import chi2_band, chi2_quantile, chi2_sf

#: windows up to this many fixes take their band energies from a cached DFT matrix, not an FFT
DFT_BY_MATRIX = 256
#: largest integer shape a for which :func:`beta_sf` sums the finite series
FINITE_SUM_MAX = 64
#: relative half-width of the level buckets of the cached NIS screen (levels keyed to 3 digits
#: are within 0.5 % of their key)
SCREEN_WIDTH = 0.01

__all__ = ['beta_sf', 'beta_log_sf', 'band_dof', 'band_energies', 'band_tables',
           'spectral_whiteness', 'band_whiteness', 'whiteness_of_bands', 'compiled_helpers',
           'nis_p_values', 'nis_band', 'window_level',
           'WindowVerdict', 'judge_window']


def _beta_fraction(a: float, b: float, x: float) -> float:
    """Continued fraction of the incomplete beta function (Numerical Recipes §6.4, Lentz)."""
    tiny = 1e-300                     # |v| < tiny written as a chained comparison: no abs()
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c = 1.0
    d = 1.0 - qab * x / qap
    d = 1.0 / (tiny if -tiny < d < tiny else d)
    h = d
    for m in range(1, 10000):
        m2 = 2 * m
        aa = m * (b - m) * x / ((qam + m2) * (a + m2))
        d = 1.0 + aa * d
        d = 1.0 / (tiny if -tiny < d < tiny else d)
        c = 1.0 + aa / c
        if -tiny < c < tiny:
            c = tiny
        h *= d * c
        aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))
        d = 1.0 + aa * d
        d = 1.0 / (tiny if -tiny < d < tiny else d)
        c = 1.0 + aa / c
        if -tiny < c < tiny:
            c = tiny
        de = d * c
        h *= de
        if -1e-15 < de - 1.0 < 1e-15:
            break
    return h


def _log_front(x: float, a: float, b: float) -> float:
    return (math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x)
            + b * math.log1p(-x))


def _beta_cdf(x: float, a: float, b: float) -> float:
    """Regularised incomplete beta I_x(a, b), from the side where the fraction converges."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    front = math.exp(_log_front(x, a, b))
    if x < (a + 1.0) / (a + b + 2.0):
        return front * _beta_fraction(a, b, x) / a
    return 1.0 - front * _beta_fraction(b, a, 1.0 - x) / b


def beta_sf(x: float, a: float, b: float) -> float:
    """
    Return P(X > x) for X ~ Beta(a, b), accurate in the upper tail.

    Parameters
    ----------
    x : float
        The value, in [0, 1].
    a, b : float
        The shape parameters, > 0.

    Returns
    -------
    float
        The survival function ``I_{1−x}(b, a)``.

    """
    x, a, b = float(x), float(a), float(b)
    if 0.0 < x < 1.0 and 1.0 <= a <= FINITE_SUM_MAX and a == math.floor(a) and b > 0.0:
        # integer a: P(X > x) = (1 − x)^b Σ_{j<a} (b)_j x^j / j!, positive terms, no fraction
        term = total = 1.0
        for j in range(1, int(a)):
            term *= (b + (j - 1)) * x / j
            total += term
        return math.exp(b * math.log1p(-x)) * total
    return _beta_cdf(1.0 - x, b, a)


def beta_log_sf(x: float, a: float, b: float) -> float:
    """
    Return log P(X > x) for X ~ Beta(a, b), accurate where :func:`beta_sf` underflows.

    Parameters
    ----------
    x : float
        The value, in [0, 1].
    a, b : float
        The shape parameters, > 0.

    Returns
    -------
    float
        The logarithm of the survival function, ≤ 0.

    """
    x, a, b = float(x), float(a), float(b)
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return -math.inf
    y = 1.0 - x                       # P(X > x) = I_y(b, a)
    if y < (b + 1.0) / (a + b + 2.0):
        return _log_front(y, b, a) + math.log(_beta_fraction(b, a, y)) - math.log(b)
    return math.log(max(_beta_cdf(y, b, a), 1e-300))


def band_dof(n: int) -> np.ndarray:
    """
    Return the degrees of freedom of each Fourier band of a window of n fixes, three axes.

    Parameters
    ----------
    n : int
        Fixes in the window.

    Returns
    -------
    ndarray (⌊n/2⌋ + 1,)
        3 for the mean and (n even) the Nyquist band, 6 for the others; they sum to 3n.

    """
    d = np.full(n // 2 + 1, 6.0)
    d[0] = 3.0
    if n % 2 == 0:
        d[-1] = 3.0
    return d


def band_energies(white: np.ndarray) -> np.ndarray:
    """
    Return the energy of each Fourier band of the whitened innovations, summed over the axes.

    Parameters
    ----------
    white : ndarray (n, 3)
        Whitened innovations, one row per fix.

    Returns
    -------
    ndarray (⌊n/2⌋ + 1,)
        ``E_j`` with ``Σ_j E_j = Σ |w_k|²`` (Parseval).

    """
    w = np.asarray(white, dtype=float)
    n = len(w)
    if 0 < n <= DFT_BY_MATRIX:     # short windows: one product with the cached DFT matrix
        m, weights = band_tables(n)
        f = m @ w
        s = (f * f).sum(1)
        return weights * (s[:len(weights)] + s[len(weights):])
    f = np.fft.rfft(w, axis=0)
    e = (f.real ** 2 + f.imag ** 2).sum(axis=1) * (2.0 / n)
    e[0] *= 0.5
    if n % 2 == 0:
        e[-1] *= 0.5
    return e


@lru_cache(maxsize=16)
def band_tables(n: int) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the tables of :func:`band_energies` for a window of n fixes.

    ``E_j = v_j Σ_axes ((M w)_j² + (M w)_{J+j}²)``, J = ⌊n/2⌋ + 1.

    Parameters
    ----------
    n : int
        Fixes in the window, ≥ 1.

    Returns
    -------
    m : ndarray (2J, n)
        The real and imaginary parts of the rfft of n samples, stacked.
    v : ndarray (J,)
        The band weights: 2/n, 1/n for the mean and (n even) the Nyquist band.

    """
    j = np.arange(n // 2 + 1)[:, None] * np.arange(n)[None, :] % n    # exact angle indices
    angle = (2.0 * np.pi / n) * j
    m = np.vstack([np.cos(angle), -np.sin(angle)])
    v = np.full(n // 2 + 1, 2.0 / n)
    v[0] *= 0.5
    if n % 2 == 0:
        v[-1] *= 0.5
    m.setflags(write=False)
    v.setflags(write=False)
    return m, v


def spectral_whiteness(white: np.ndarray) -> tuple[float, int]:
    """
    Return the exact-null whiteness p-value of a window and its most loaded band.

    Parameters
    ----------
    white : ndarray (n, 3)
        Whitened innovations, one row per fix.

    Returns
    -------
    p : float
        ``min(1, J·min_j P(Beta_j > E_j/T))``: never below the probability of the event for
        white innovations.
    band : int
        The band of the smallest p (0: the window's mean; j: j cycles per window).

    """
    return band_whiteness(band_energies(white), len(white))


def band_whiteness(energies, n: int) -> tuple[float, int]:
    """
    Return :func:`spectral_whiteness` from the window's band energies.

    Parameters
    ----------
    energies : array_like (⌊n/2⌋ + 1,)
        The :func:`band_energies` of the window (three axes).
    n : int
        Fixes in the window.

    Returns
    -------
    (float, int)
        :func:`whiteness_of_bands` of them.

    """
    energy = energies if isinstance(energies, list) else np.asarray(energies, dtype=float).tolist()
    return whiteness_of_bands(energy, int(n))


def whiteness_of_bands(energy, n: int) -> tuple[float, int]:
    """
    Return :func:`band_whiteness` of a list of band energies (or, compiled, an array).

    Plain arithmetic that a compiled loop may call too (:func:`compiled_helpers`).

    Parameters
    ----------
    energy : list of float, or ndarray
        The band energies, ⌊n/2⌋ + 1 of them.
    n : int
        Fixes in the window (n ≥ 1).

    Returns
    -------
    p : float
        The whiteness p-value.
    band : int
        The band of the smallest p.

    """
    bands = len(energy)
    total = 0.0
    for j in range(bands):
        total += energy[j]
    if not total > 0.0:
        return 1.0, 0
    half = 1.5 * n
    # the most loaded band of each shape (the first of equal ones): the mean and (n even) the
    # Nyquist band have 3 degrees of freedom, the others 6 (band_dof)
    last = bands - 1
    j3 = last if n % 2 == 0 and n > 1 and energy[last] > energy[0] else 0
    j6 = -1
    for j in range(1, last + (n % 2)):
        if j6 < 0 or energy[j] > energy[j6]:
            j6 = j
    p3 = 2.0                       # not computed yet
    if j6 >= 0:
        p6 = beta_sf(energy[j6] / total, 3.0, half - 3.0)
        # P(Beta(3/2, b) > x) ≥ P(Beta(1, b) > x) = (1 − x)^b (larger a: stochastically larger)
        # and ≥ 2 √x (1 − x)^b / B(1/2, b) (I_x(a + 1, b) = I_x(a, b) − x^a (1 − x)^b /
        # (a B(a, b)), DLMF 8.17.20, at a = 1/2): when the larger bound is above p6, the mean's
        # band cannot have the smaller p
        x3 = energy[j3] / total
        if x3 < 1.0:
            front = 2.0 * math.exp(math.lgamma(half - 1.0) - math.lgamma(0.5)
                                   - math.lgamma(half - 1.5))
            bound = math.exp((half - 1.5) * math.log1p(-x3)) * max(1.0, front * math.sqrt(x3))
            if bound * (1.0 - 1e-9) > p6:
                return min(1.0, bands * p6), j6
        p3 = beta_sf(x3, 1.5, half - 1.5)
        if p6 < p3:
            return min(1.0, bands * p6), j6
    if p3 > 1.0:
        p3 = beta_sf(energy[j3] / total, 1.5, half - 1.5)
    return min(1.0, bands * p3), j3


def compiled_helpers() -> tuple:
    """
    Return the functions of this module a compiled loop may call, callees first.

    For :func:`~strapdown_ros.attitude.kernel.jitable_optional`; the check's compiled fix loop
    (:mod:`strapdown_ros.estimation.check_kernel`) calls :func:`whiteness_of_bands`.

    Returns
    -------
    tuple of callable
        The beta survival functions and :func:`whiteness_of_bands`.

    """
    return _beta_fraction, _log_front, _beta_cdf, beta_sf, whiteness_of_bands


def nis_p_values(total: float, dof: int) -> tuple[float, float]:
    """
    Return the lower and upper tail probabilities of a NIS sum.

    Parameters
    ----------
    total : float
        Σ NIS over the window.
    dof : int
        3 × fixes.

    Returns
    -------
    (float, float)
        P(χ² ≤ total) and P(χ² ≥ total).

    """
    upper = chi2_sf(float(total), int(dof))
    return 1.0 - upper, upper


@lru_cache(maxsize=256)
def _band(dof: int, level: float) -> tuple[float, float]:
    lo, hi = chi2_band(dof, level)
    return lo * dof, hi * dof


@lru_cache(maxsize=256)
def _nis_screen(dof: int, level_key: float) -> tuple[float, float]:
    """
    Return (lo, hi): a NIS sum in [lo, hi] is in neither α/4 tail of the levels near the key.

    Near: within ``SCREEN_WIDTH`` of ``level_key``.  The bounds are checked on the distribution
    function itself (else the empty screen: every sum takes its p-values).
    """
    p = 0.25 * level_key * (1.0 + SCREEN_WIDTH)
    if not 0.0 < p < 0.5:
        return math.inf, -math.inf
    lo = chi2_quantile(p, dof) * (1.0 + 1e-9)
    hi = chi2_quantile(1.0 - p, dof) * (1.0 - 1e-9)
    low, _ = nis_p_values(lo, dof)
    _, high = nis_p_values(hi, dof)
    if not (low >= p and high >= p and lo <= hi):
        return math.inf, -math.inf
    return lo, hi


def nis_band(dof: int, level: float) -> tuple[float, float]:
    """
    Return the two-sided band of a NIS sum (``level`` outside it, half on each side).

    Parameters
    ----------
    dof : int
        3 × fixes.
    level : float
        Two-sided probability outside the band (rounded to 3 digits for the cache).

    Returns
    -------
    (float, float)
        The band of the sum.

    """
    return _band(int(dof), float(f'{level:.3g}'))


def window_level(rate_per_hour: float, fix_interval: float, cap: float) -> float:
    """
    Return the false-alarm probability α of one window for a stated rate per hour.

    Parameters
    ----------
    rate_per_hour : float
        r, false WARN episodes per hour of clean data (0: no rate, α = cap).
    fix_interval : float
        Mean time between the window's fixes Δt, s (one window ends at every fix).
    cap : float
        Largest α of one window (``model_check_alpha``).

    Returns
    -------
    float
        ``min(cap, r·Δt/3600)``.

    """
    if rate_per_hour > 0.0 and math.isfinite(fix_interval) and fix_interval > 0.0:
        return min(float(cap), float(rate_per_hour) * fix_interval / 3600.0)
    return float(cap)


class WindowVerdict:
    """
    The two tests of one window at its level.

    Parameters
    ----------
    nis_sum : float
        Σ NIS.
    dof : int
        3 × fixes.
    level : float
        α of the window: NIS two-sided at α/2, whiteness at α/2.
    whiteness_p : float
        The whiteness p-value (:func:`spectral_whiteness`).
    band : int
        Its most loaded band.

    """

    def __init__(self, nis_sum: float, dof: int, level: float, whiteness_p: float, band: int):
        self.nis_sum, self.dof, self.level = float(nis_sum), int(dof), float(level)
        self.whiteness_p, self.band = float(whiteness_p), int(band)
        self._p = None
        lo, hi = _nis_screen(self.dof, float(f'{self.level:.3g}'))
        if lo <= self.nis_sum <= hi:       # inside both tails at this level: no p-value needed
            self.nis_low = self.nis_high = False
        else:
            self.nis_low = self.p_low < 0.25 * level
            self.nis_high = self.p_high < 0.25 * level
        self.not_white = self.whiteness_p < 0.5 * level
        self.ok = not (self.nis_low or self.nis_high or self.not_white)

    @property
    def p_low(self) -> float:
        """Return P(χ² ≤ NIS sum) (:func:`nis_p_values`)."""
        if self._p is None:
            self._p = nis_p_values(self.nis_sum, self.dof)
        return self._p[0]

    @property
    def p_high(self) -> float:
        """Return P(χ² ≥ NIS sum) (:func:`nis_p_values`)."""
        if self._p is None:
            self._p = nis_p_values(self.nis_sum, self.dof)
        return self._p[1]

    @property
    def nis_band(self) -> tuple[float, float]:
        """Return the NIS sum's band at this window's level (α/2 two-sided)."""
        return nis_band(self.dof, 0.5 * self.level)


def judge_window(white: np.ndarray, level: float) -> WindowVerdict:
    """
    Test one window of whitened innovations at level α.

    Parameters
    ----------
    white : ndarray (n, 3)
        Whitened innovations.
    level : float
        α of the window.

    Returns
    -------
    WindowVerdict
        Its tests.

    """
    w = np.asarray(white, dtype=float)
    p, band = band_whiteness(band_energies(w), len(w))
    return WindowVerdict(float((w * w).sum()), w.size, level, p, band)
