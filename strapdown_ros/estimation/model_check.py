"""
Live model check of the attitude filter: its innovations against the filter's own model.

Are the innovations of the last N fixes what the model says they are, and if not, which effect
of the registry do they look like?  :mod:`strapdown_ros.estimation.filter_system` feeds it
every applied or gated fix.  Over a sliding window of N fixes applied or gated (a gated fix
counts: an unmodelled effect makes the filter gate) (residual z_k, VF axes, with its
innovation covariance S_k):

* consistency: Σ NIS_k against the two-sided χ²(3N) band of probability ``1 − alpha``;
* whiteness: the Ljung–Box statistic of the whitened innovations ``S_k^{-1/2} z_k`` (each
  axis, lags 1..L, L = min(10, N // 5)), summed over the axes, against χ²(3L) at ``alpha``.

When either fails, each candidate effect (a systematic gyro effect of
:data:`strapdown_ros.sensors.effects.EFFECTS` the filter does not carry, and the camera time
offset when the filter does not estimate it) is fitted to the window by weighted least
squares, ``z_k ≈ G_k c`` with G_k its signature (the effect's increment partials integrated
over the interval before the fix and carried into VF axes, or the time offset's fix Jacobian),
and the likelihood ratio ``Σ z_kᵀS_k⁻¹z_k − min_c Σ (z_k − G_k c)ᵀS_k⁻¹(z_k − G_k c)`` is
compared with χ²(size of c): the best match is the effect with the smallest p-value.  The
check only reports; the filter's model is never changed by it.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass
import math

import numpy as np

from strapdown_ros.estimation.chi_square import chi2_band, chi2_sf

__all__ = ['ModelCheck', 'ModelCheckResult', 'ljung_box']


def ljung_box(x: np.ndarray, lags: int) -> float:
    """
    Return the Ljung–Box statistic ``n(n+2) Σ_{k=1}^{L} r_k²/(n−k)``, summed over columns.

    Parameters
    ----------
    x : ndarray (n,) or (n, m)
        Series (whitened innovations), one per column.
    lags : int
        L ≥ 1.

    Returns
    -------
    float
        The statistic, χ²(m L) for white series.

    """
    x = np.asarray(x, dtype=float)
    x = x.reshape(len(x), -1) - x.reshape(len(x), -1).mean(0)
    n = len(x)
    den = (x * x).sum(0)
    den = np.where(den > 0, den, np.inf)
    q = 0.0
    for k in range(1, lags + 1):
        r = (x[k:] * x[:-k]).sum(0) / den
        q += float((r * r).sum()) / (n - k)
    return n * (n + 2) * q


@dataclass
class ModelCheckResult:
    """
    Verdict of one window (None fields: not computed).

    Parameters
    ----------
    fixes : int
        Fixes in the window.
    ok : bool
        True while the window passes (or is not yet full).
    nis_sum : float
        Σ NIS over the window.
    nis_band : tuple of float
        Its two-sided band.
    whiteness_p : float
        p-value of the Ljung–Box statistic.
    best_effect : str, optional
        The effect the innovations match best (failing windows).
    best_p : float
        Its p-value (small: the effect explains the innovations).
    best_estimate : ndarray, optional
        The fitted effect value, in its units.

    """

    fixes: int
    ok: bool
    nis_sum: float = float('nan')
    nis_band: tuple = (float('nan'), float('nan'))
    whiteness_p: float = float('nan')
    best_effect: str | None = None
    best_p: float = float('nan')
    best_estimate: np.ndarray | None = None

    def text(self) -> str:
        """Return the verdict as one line for /diagnostics and logs."""
        if self.fixes == 0 or (self.ok and not math.isfinite(self.nis_sum)):
            return f'model check: {self.fixes} fix(es) in the window, not yet full'
        head = (f'NIS sum {self.nis_sum:.4g} over {self.fixes} fixes (band '
                f'{self.nis_band[0]:.4g}–{self.nis_band[1]:.4g}), whiteness p = '
                f'{self.whiteness_p:.3g}')
        if self.ok:
            return 'innovations consistent with the model: ' + head
        if self.best_effect is None:
            return 'innovations inconsistent with the model (no candidate effect): ' + head
        return (f'innovations match {self.best_effect} (p = {self.best_p:.3g}); run discrepancy '
                f'on a recording ({head})')


class ModelCheck:
    """
    The sliding-window test of the innovations and the naming of the best-matching effect.

    Parameters
    ----------
    window : int
        Fixes per window, N ≥ 5.
    alpha : float
        Probability of a false alarm of each test (the NIS band is two-sided at ``alpha``).
    effects : sequence of Effect
        Candidate gyro effects (registry objects with ``filter_partials``), not filter states.
    time_offset : bool
        The camera time offset is a candidate (its fix Jacobian).

    """

    def __init__(self, window: int = 30, alpha: float = 0.001, effects=(), time_offset=False):
        if int(window) < 5:
            raise ValueError('the model-check window needs at least 5 fixes')
        if not 0.0 < alpha < 0.5:
            raise ValueError('alpha must be in (0, 0.5)')
        self.window = int(window)
        self.alpha = float(alpha)
        self.effects = list(effects)
        self.time_offset = bool(time_offset)
        self.names = [e.name for e in self.effects] + (['time_offset'] if time_offset else [])
        self._sizes = [e.filter_size() for e in self.effects] + ([1] if time_offset else [])
        self._rows: deque = deque(maxlen=self.window)
        lo, hi = chi2_band(3 * self.window, self.alpha)
        self.band = (lo * 3 * self.window, hi * 3 * self.window)
        self.lags = max(1, min(10, self.window // 5))
        self.last = ModelCheckResult(0, True)
        self.windows = self.failed = 0

    def signature(self, rho, h, t_mid, c_end_body) -> list[np.ndarray]:
        """
        Return the signature of each gyro candidate over the interval since the last fix.

        Parameters
        ----------
        rho : ndarray (n, 3)
            Increments, rad, body axes.
        h : ndarray (n,)
            Their lengths, s.
        t_mid : ndarray (n,)
            Their middle times since the effect epoch, s.
        c_end_body : ndarray (n, 3, 3)
            Rotation from each increment's body axes to the body axes at the end of the
            interval (since the last applied fix).

        Returns
        -------
        list of ndarray (3, size)
            One per candidate, body axes at the interval's end.

        """
        return [np.einsum('nij,njk->ik', c_end_body, e.filter_partials(rho, h, t_mid))
                for e in self.effects]

    def add(self, z, S, gyro_signatures, c_vf_mf, rate_body) -> ModelCheckResult:
        """
        Add one applied or gated fix and judge the window ending at it.

        Parameters
        ----------
        z : array_like (3,)
            Residual, VF axes, rad.
        S : array_like (3, 3)
            Its innovation covariance, rad².
        gyro_signatures : list of ndarray (3, size)
            The signatures of the interval before it (:meth:`signature`, body axes).
        c_vf_mf : ndarray (3, 3)
            C_VF^MF.
        rate_body : array_like (3,)
            The body rate at the fix, rad/s.

        Returns
        -------
        ModelCheckResult
            The verdict of the window ending at this fix.

        """
        G = [c_vf_mf @ g for g in gyro_signatures]
        if self.time_offset:
            G.append(-(c_vf_mf @ np.asarray(rate_body, dtype=float))[:, None])
        self._rows.append((np.asarray(z, dtype=float), np.asarray(S, dtype=float), G))
        if len(self._rows) < self.window:
            self.last = ModelCheckResult(len(self._rows), True)
            return self.last
        self.last = self._test()
        self.windows += 1
        self.failed += int(not self.last.ok)
        return self.last

    def _test(self) -> ModelCheckResult:
        n = len(self._rows)
        white = np.empty((n, 3))
        L = []
        nis = 0.0
        for k, (z, S, _) in enumerate(self._rows):
            Lk = np.linalg.cholesky(S)
            w = np.linalg.solve(Lk, z)
            white[k] = w
            L.append(Lk)
            nis += float(w @ w)
        q = ljung_box(white, self.lags)
        p_white = chi2_sf(q, 3 * self.lags)
        ok = self.band[0] <= nis <= self.band[1] and p_white >= self.alpha
        res = ModelCheckResult(n, ok, nis, self.band, p_white)
        if ok or not self.names:
            return res
        best = (math.inf, -math.inf, None, None)
        for j, (name, size) in enumerate(zip(self.names, self._sizes)):
            A = np.vstack([np.linalg.solve(L[k], self._rows[k][2][j]) for k in range(n)])
            c, *_ = np.linalg.lstsq(A, white.reshape(-1), rcond=None)
            r = white.reshape(-1) - A @ c
            lr = nis - float(r @ r)
            p = chi2_sf(max(lr, 0.0), size)
            # the smallest p-value; where p underflows, the largest likelihood ratio per state
            if (p, -lr / size) < (best[0], -best[1]):
                best = (p, lr / size, name, c)
        res.best_p, _, res.best_effect, res.best_estimate = best
        return res
