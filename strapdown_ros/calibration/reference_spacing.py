"""
How far apart the reference fixes of the increment pairs must be: chosen from the data.

The pair model (004 §3.3, :mod:`strapdown_ros.calibration.pair_covariance`) takes the error of
each fix as independent of the next.  A motion-capture reference at 100–300 Hz smooths its
samples: its error is correlated over several of them, and pairs of fixes closer together
than that correlation time would count the same error many times (χ²/dof far below 1, σ too
small).  The rule, the same in ``calibrate_bag`` and ``discrepancy``:

1. build the pairs of consecutive fixes at the full rate and fit the model (boresight and the
   gyro constants, the chained covariance of white fixes);
2. whiten the residuals with that covariance: with white fix errors they are white; with
   correlated ones they follow the fix error at the short lags (the whitening of chained
   differences gives the error itself back, except at the lowest frequencies, where the
   gyro's random walk dominates and the fit removes the slowest part), so their
   autocorrelation ρ(k) at a lag of k fixes starts as that of the fix error;
3. when |ρ(1)| is within :data:`SIGNIFICANCE` standard errors of zero (3N residuals), every
   fix is kept; otherwise τ, the lag at which ρ falls to 1/e (interpolated in log ρ), is the
   reference's correlation time, and one fix in k is kept, k the smallest lag at which an
   exponential correlation exp(−k/τ) is within :data:`TOLERANCE` standard error of zero
   at the number of residuals that spacing leaves (3N/k): pairs at that spacing carry errors
   the model treats correctly, so χ²/dof and σ stay honest (the exponential is conservative
   for a correlation that falls faster after its 1/e time, as a moving average's does);
4. at most :data:`MAX_SPACING` s apart: residuals that stay above 1/e that far are structure
   the model does not explain (an effect missing), not reference noise, and the pairs are
   taken at that spacing (the rate of a 1-Hz reference).

Fixes already at least :data:`MAX_SPACING` apart are all kept.  O(N log N) at most: the lags
examined are a geometric grid, stopped at the 1/e crossing.  No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from strapdown_ros.calibration.pair_covariance import chain_segments
from strapdown_ros.text import json_clean

__all__ = ['MAX_SPACING', 'SIGNIFICANCE', 'TOLERANCE', 'SpacingChoice', 'lag_grid',
           'residual_correlation', 'choose_spacing', 'refine_spacing', 'fix_interval',
           'stated_spacing', 'thin_fixes', 'parse_spacing']

#: largest spacing of the fixes the rule chooses, s
MAX_SPACING = 1.0
#: the reference error counts as correlated when ρ between consecutive residuals is more than
#: this many standard errors from zero (else every fix is kept)
SIGNIFICANCE = 3.0
#: ... and the correlation left at the chosen spacing within this many standard errors of zero
TOLERANCE = 1.0


@dataclass
class SpacingChoice:
    """
    The spacing of the fixes of the pairs and why.

    Attributes
    ----------
    step : int
        One fix in ``step`` is kept (1: all).
    interval_s : float
        Median interval of the fixes given, s.
    spacing_s : float
        ``step`` × ``interval_s``, s.
    lags : list of int
        Lags examined, fixes.
    correlation : list of float
        ρ at each lag examined (pooled over the three axes).
    limit : float
        |ρ| allowed at the chosen step.
    reason : str
        In words.
    pairs_full : int
        Pairs at the full rate.
    correlation_time_s : float
        The 1/e time of the correlation, s (NaN when not measured).

    """

    step: int
    interval_s: float
    spacing_s: float
    lags: list = field(default_factory=list)
    correlation: list = field(default_factory=list)
    limit: float = float('nan')
    reason: str = ''
    pairs_full: int = 0
    correlation_time_s: float = float('nan')

    def as_dict(self) -> dict:
        """
        Return the choice as plain JSON values.

        Returns
        -------
        dict
            Every field (non-finite numbers as None).

        """
        return json_clean({
            'step': int(self.step), 'interval_s': float(self.interval_s),
            'spacing_s': float(self.spacing_s), 'pairs_full_rate': int(self.pairs_full),
            'lags': [int(k) for k in self.lags],
            'correlation': [float(r) for r in self.correlation],
            'limit': float(self.limit), 'reason': self.reason,
            'correlation_time_s': float(self.correlation_time_s),
            'max_spacing_s': MAX_SPACING, 'significance': SIGNIFICANCE,
            'tolerance': TOLERANCE})


def lag_grid(max_lag: int) -> np.ndarray:
    """
    Return the lags examined: 1, 2, 3, … growing by at most a quarter, up to ``max_lag``.

    Parameters
    ----------
    max_lag : int
        Largest lag, fixes.

    Returns
    -------
    ndarray of int
        The lags, ascending.

    """
    out, k = [], 1
    while k < max_lag:
        out.append(k)
        k = max(k + 1, int(np.floor(k * 1.25)))
    out.append(max(int(max_lag), 1))
    return np.unique(np.array(out, dtype=int))


def residual_correlation(white: np.ndarray, chain: np.ndarray, lag: int) -> float:
    """
    Return the autocorrelation of whitened residuals at a lag, pooled over axes, within chains.

    Parameters
    ----------
    white : (N, 3) ndarray
        Whitened residuals, in pair order.
    chain : (N,) int ndarray
        Chain of each pair (:func:`strapdown_ros.calibration.pair_covariance.chain_segments`);
        only pairs of one chain are compared.
    lag : int
        Lag, pairs.

    Returns
    -------
    float
        ρ(lag) (NaN when no two pairs of one chain are that far apart).

    """
    e = np.asarray(white, dtype=float)
    e = e - e.mean(axis=0)
    den = float(np.sum(e * e)) / max(len(e), 1)
    if lag >= len(e) or den <= 0:
        return float('nan')
    same = chain[lag:] == chain[:-lag]
    if not np.any(same):
        return float('nan')
    num = float(np.sum(e[lag:][same] * e[:-lag][same])) / int(np.sum(same))
    return num / den


def choose_spacing(white: np.ndarray, adjacent: np.ndarray, fix_stamps: np.ndarray,
                   max_spacing: float = MAX_SPACING, significance: float = SIGNIFICANCE
                   ) -> SpacingChoice:
    """
    Choose the spacing of the fixes from the whitened residuals at the full rate (module doc).

    Parameters
    ----------
    white : (N, 3) ndarray
        Whitened residuals of the pairs of consecutive fixes, fitted at the full rate.
    adjacent : (N−1,) array_like of bool
        Pairs n, n+1 share a fix.
    fix_stamps : (M,) ndarray
        Stamps of the fixes, s (for the interval).
    max_spacing : float
        Largest spacing chosen, s.
    significance : float
        Standard errors from zero beyond which consecutive fixes count as correlated.

    Returns
    -------
    SpacingChoice
        The step and why.

    """
    white = np.asarray(white, dtype=float).reshape(-1, 3)
    n = len(white)
    interval = fix_interval(fix_stamps)
    max_lag = int(np.floor(max_spacing / interval + 1e-9)) if np.isfinite(interval) else 1
    if max_lag <= 1 or n < 4:
        return SpacingChoice(1, interval, interval, reason=(
            f'fixes {interval:.3g} s apart, at least {max_spacing:g} s: all kept'),
            pairs_full=n)
    max_lag = min(max_lag, max(1, n // 4))
    chain = chain_segments(adjacent, n)

    def limit(k, level=TOLERANCE):
        return level / np.sqrt(3.0 * n / k)
    lags, rho = [], []
    tau = None
    for k in lag_grid(max_lag):
        r = residual_correlation(white, chain, int(k))
        lags.append(int(k))
        rho.append(r)
        if k == 1 and np.isfinite(r) and abs(r) <= limit(1, significance):
            return SpacingChoice(1, interval, interval, lags, rho, limit(1, significance), (
                f'residuals of consecutive fixes uncorrelated (ρ = {r:.2g}, |ρ| ≤ '
                f'{limit(1, significance):.2g}): every fix kept'), n)
        if np.isfinite(r) and r < np.exp(-1.0):
            # the 1/e crossing, interpolated in log ρ from the lag before (ρ(0) = 1)
            k0, r0 = (lags[-2], rho[-2]) if len(lags) > 1 else (0, 1.0)
            lr0, lr1 = np.log(r0), np.log(max(r, 1e-12))
            tau = k0 + (k - k0) * (lr0 + 1.0) / (lr0 - lr1)
            break
    if tau is None:
        step = max_lag
        why = (f'residuals still correlated {step * interval:.3g} s apart '
               f'(ρ = {rho[-1]:.2g}): structure the model does not explain; pairs at the '
               f'largest spacing, {max_lag * interval:.3g} s')
        return SpacingChoice(step, interval, step * interval, lags, rho, limit(step), why, n)
    ks = np.arange(1, max_lag + 1)
    ok = np.exp(-ks / tau) <= limit(ks)
    step = int(ks[np.argmax(ok)]) if np.any(ok) else max_lag
    why = (f'reference error correlated with a 1/e time of {tau * interval:.3g} s '
           f'(ρ = {rho[0]:.2g} between consecutive fixes): one fix in {step} kept, where '
           f'exp(−k/τ) = {np.exp(-step / tau):.2g} ≤ {limit(step):.2g}')
    return SpacingChoice(step, interval, step * interval, lags, rho, limit(step), why, n,
                         tau * interval)


def refine_spacing(choice: SpacingChoice, white: np.ndarray, adjacent: np.ndarray,
                   max_spacing: float = MAX_SPACING, significance: float = SIGNIFICANCE
                   ) -> SpacingChoice:
    """
    Check the spacing on the pairs it keeps, and widen it once if their residuals are correlated.

    At the full rate the lowest frequencies of the whitened residuals are those of the gyro
    and of the fit, not of the reference, so τ can come out short.  On the pairs kept, the
    correlation between consecutive residuals is that of the reference error ``step`` fixes
    apart, exp(−step/τ): when it is more than :data:`SIGNIFICANCE` standard errors from zero, τ
    is taken from it and the step widened by the same rule (:data:`TOLERANCE`; at most to the
    largest spacing).

    Parameters
    ----------
    choice : SpacingChoice
        The spacing chosen at the full rate (step > 1).
    white : (N', 3) ndarray
        Whitened residuals of the pairs kept.
    adjacent : (N'−1,) array_like of bool
        Pairs n, n+1 share a fix.
    max_spacing : float
        Largest spacing chosen, s.
    significance : float
        Standard errors from zero beyond which the pairs kept count as correlated.

    Returns
    -------
    SpacingChoice
        ``choice`` unchanged, or with a wider step and the reason.

    """
    white = np.asarray(white, dtype=float).reshape(-1, 3)
    n = len(white)
    if choice.step <= 1 or n < 8:
        return choice
    r = residual_correlation(white, chain_segments(adjacent, n), 1)
    lim = significance / np.sqrt(3.0 * n)
    if not (np.isfinite(r) and r > lim):
        return choice
    max_step = max(choice.step, int(np.floor(max_spacing / choice.interval_s + 1e-9)))
    tau = -choice.step / np.log(min(r, 0.999))           # fixes of the full rate
    full = max(choice.pairs_full, 1)
    ks = np.arange(choice.step, max_step + 1)
    ok = np.exp(-ks / tau) <= TOLERANCE / np.sqrt(3.0 * full / ks)
    step = int(ks[np.argmax(ok)]) if np.any(ok) else max_step
    why = (f'{choice.reason}; on the pairs kept the residuals were still correlated (ρ = {r:.2g} '
           f'> {lim:.2g}): τ = {tau * choice.interval_s:.3g} s, one fix in {step} kept')
    return SpacingChoice(step, choice.interval_s, step * choice.interval_s, choice.lags,
                         choice.correlation, TOLERANCE / np.sqrt(3.0 * full / step), why,
                         choice.pairs_full, tau * choice.interval_s)


def fix_interval(fix_stamps) -> float:
    """
    Return the median interval of the fixes, s (inf for fewer than two distinct stamps).

    Parameters
    ----------
    fix_stamps : (M,) array_like
        Stamps, s.

    Returns
    -------
    float
        The interval, s.

    """
    d = np.diff(np.asarray(fix_stamps, dtype=float))
    d = d[d > 0]
    return float(np.median(d)) if len(d) else float('inf')


def stated_spacing(spacing: float, fix_stamps) -> SpacingChoice:
    """
    Return the choice of a spacing the user stated (``--reference-spacing SECONDS``).

    Parameters
    ----------
    spacing : float
        Spacing, s (0: every fix).
    fix_stamps : (M,) array_like
        Stamps of the fixes, s.

    Returns
    -------
    SpacingChoice
        The step that spacing means for these fixes.

    """
    interval = fix_interval(fix_stamps)
    step = max(1, int(round(spacing / interval))) if spacing > 0 else 1
    return SpacingChoice(step, interval, max(spacing, interval) if step > 1 else interval,
                         reason=f'stated: {spacing:g} s' if spacing > 0 else 'stated: every fix',
                         pairs_full=max(len(fix_stamps) - 1, 0))


def thin_fixes(fix_stamps: np.ndarray, spacing: float) -> np.ndarray:
    """
    Return the indices of the fixes kept at a spacing: the first fix of every slot of that length.

    Parameters
    ----------
    fix_stamps : (M,) ndarray
        Stamps, s, ascending.
    spacing : float
        Spacing, s (≤ 0: all kept).

    Returns
    -------
    ndarray of int
        Indices of the kept fixes, ascending.

    """
    t = np.asarray(fix_stamps, dtype=float)
    if len(t) == 0 or not spacing > 0:
        return np.arange(len(t))
    d = np.diff(t)
    interval = float(np.median(d[d > 0])) if np.any(d > 0) else spacing
    # slots of ``spacing`` centred so that regular fixes fall mid-slot, not on its edge
    slot = np.floor((t - t[0]) / spacing + 0.5 * min(interval / spacing, 1.0)).astype(np.int64)
    return np.flatnonzero(np.concatenate([[True], slot[1:] != slot[:-1]]))


def parse_spacing(text) -> float | None:
    """
    Read the ``--reference-spacing`` value of a tool: ``auto`` or seconds.

    Parameters
    ----------
    text : str or float or None
        ``'auto'`` (or None), or a spacing in seconds (0: every fix).

    Returns
    -------
    float or None
        None for auto, else the spacing, s.

    Raises
    ------
    ValueError
        Neither ``auto`` nor a finite number ≥ 0 (one line).

    """
    if text is None or str(text).strip().lower() == 'auto':
        return None
    try:
        v = float(text)
    except ValueError:
        v = float('nan')
    if not (np.isfinite(v) and v >= 0):
        raise ValueError(f"--reference-spacing must be 'auto' or seconds >= 0, got {text!r}")
    return v
