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
   correlated ones they follow the fix error (the whitening of chained differences gives the
   error itself back), so their autocorrelation ρ(k) at a lag of k fixes is that of the fix
   error;
3. keep every k-th fix, k the smallest lag (on a geometric grid) at which the correlation
   left, |ρ(k)|, is within :data:`SIGNIFICANCE` standard errors of zero at the number of
   pairs that spacing leaves (3N/k residuals): pairs at that spacing carry errors the model
   treats correctly, so χ²/dof stays honest;
4. at most :data:`MAX_SPACING` s apart: residuals still correlated there are structure the
   model does not explain (an effect missing), not reference noise, and the pairs are taken
   at that spacing (the rate of a 1-Hz reference).

Fixes already at least :data:`MAX_SPACING` apart are all kept.  O(N log N) at most: the lags
examined are a geometric grid.  No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from strapdown_ros.calibration.pair_covariance import chain_segments
from strapdown_ros.text import json_clean

__all__ = ['MAX_SPACING', 'SIGNIFICANCE', 'SpacingChoice', 'lag_grid', 'residual_correlation',
           'choose_spacing', 'fix_interval', 'stated_spacing', 'thin_fixes', 'parse_spacing']

#: largest spacing of the fixes the rule chooses, s
MAX_SPACING = 1.0
#: the correlation left at the chosen spacing is within this many standard errors of zero
SIGNIFICANCE = 3.0


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

    """

    step: int
    interval_s: float
    spacing_s: float
    lags: list = field(default_factory=list)
    correlation: list = field(default_factory=list)
    limit: float = float('nan')
    reason: str = ''
    pairs_full: int = 0

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
            'max_spacing_s': MAX_SPACING, 'significance': SIGNIFICANCE})


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
        Standard errors of zero the correlation left may be.

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
    lags, rho = [], []
    limit = float('nan')
    step = None
    for k in lag_grid(max_lag):
        r = residual_correlation(white, chain, int(k))
        lags.append(int(k))
        rho.append(r)
        limit = significance / np.sqrt(3.0 * n / k)
        if np.isfinite(r) and abs(r) <= limit:
            step = int(k)
            break
    if step is None:
        step = int(lags[-1])
        why = (f'residuals still correlated {step * interval:.3g} s apart (ρ = {rho[-1]:.2g}): '
               f'structure the model does not explain; pairs at the largest spacing, '
               f'{max_spacing:g} s')
    elif step == 1:
        why = (f'residuals of consecutive fixes uncorrelated (ρ = {rho[0]:.2g}, '
               f'|ρ| ≤ {limit:.2g}): every fix kept')
    else:
        why = (f'reference error correlated over about {lags[-2] * interval:.3g} s '
               f'(ρ = {rho[0]:.2g} between consecutive fixes, {rho[-1]:.2g} at {step} fixes, '
               f'|ρ| ≤ {limit:.2g}): one fix in {step} kept')
    return SpacingChoice(step, interval, step * interval, lags, rho, limit, why, n)


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
