"""
THE screening of an attitude reference fix: one rule for every node and every tool.

``calibrator_node``, ``attitude_filter_node`` (fixes and the latched boresight) and the recording
reader of ``calibrate_bag``, ``calibrate_gyro_bag``, ``discrepancy`` and ``filter_bag`` take a
fix (a quaternion and, where the message has one, the covariance of its rotation, rad²) through
:class:`FixScreen` before its stamp goes to :class:`~strapdown_ros.streams.checks.StreamCheck`.
Nothing here can raise on a value: every number is scaled before it is squared, so no norm and no
eigenvalue computation overflows, and a failure is a named reason, counted.  The rules, in order:

1. **non-finite** quaternion or covariance (NaN, ±Inf): dropped, counted ``nan``;
2. **zero quaternion**: its norm, computed as ``s·‖q/s‖`` with ``s = max |q_i|`` (never
   overflows, never underflows to a false zero), below :data:`MIN_QUATERNION_NORM`: dropped,
   counted ``zero_quaternion``;
3. **far from unit**: a norm outside [1/:data:`MAX_NORM_RATIO`, :data:`MAX_NORM_RATIO`] (a
   factor 2) is no rotation a sensor meant — (1e308, 0, 0, 1) would normalise to a half turn,
   and a quaternion scaled by 1e200 is as broken a message: dropped, counted ``not_unit``;
4. **not unit**: ``|‖q‖ − 1| > 1e-9`` within that factor: normalised as ``(q/s) / ‖q/s‖``,
   counted ``normalised``;
5. **no covariance**: the message has none, or it is all zero (ROS: unknown): the model's
   (``camera_sigma_xy``, ``camera_sigma_z``) is used; an all-zero one is counted
   ``covariance_substituted``;
6. **covariance not symmetric**: after scaling by ``c = max |P_ij|``,
   ``max |P_ij − P_ji| > SYMMETRY_TOLERANCE`` (1e-6 of the largest element): dropped, counted
   ``bad_covariance`` (reason ``asymmetric``); within the tolerance it is symmetrised;
7. **not positive definite**: the eigenvalues of the scaled, symmetrised matrix (each element in
   [−1, 1], so the eigen-solver cannot fail) below ``CONDITION_LIMIT`` (1e-12) times the largest
   one (negative, singular or numerically singular): dropped, counted ``bad_covariance``
   (reason ``not_positive_definite``);
8. **beyond the bounds**: an eigenvalue above :data:`MAX_VARIANCE` (1 rad²: a fix whose σ
   exceeds a radian says nothing a linearised estimator can use; 1e308 lands here) or below
   :data:`MIN_VARIANCE` (1e-24 rad², σ 1e-12 rad = 2e-7″: no instrument states that; its
   inverse would swamp every other weight): dropped, counted ``bad_covariance`` (reason
   ``out_of_bounds``).

No rule clamps a value: a fix that fails one says nothing reliable, and the stream goes on
without it.  :func:`unit_quaternion` is rules 1–4 alone (the latched boresight).  No ROS
imports.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ['FixScreen', 'unit_quaternion', 'screen_covariance', 'MIN_QUATERNION_NORM',
           'MAX_NORM_RATIO', 'NORM_TOLERANCE', 'SYMMETRY_TOLERANCE', 'CONDITION_LIMIT',
           'MAX_VARIANCE', 'MIN_VARIANCE', 'COVARIANCE_REASONS']

#: a quaternion whose norm is below this is a zero quaternion (no rotation is stated)
MIN_QUATERNION_NORM = 1e-6
#: a quaternion whose norm is beyond this factor of 1 is dropped (``not_unit``)
MAX_NORM_RATIO = 2.0
#: a quaternion whose norm differs from 1 by more than this is normalised (and counted)
NORM_TOLERANCE = 1e-9
#: largest |P_ij − P_ji| of a covariance scaled to a largest element of 1 that is rounding
SYMMETRY_TOLERANCE = 1e-6
#: smallest ratio of the smallest to the largest eigenvalue of a positive definite covariance
CONDITION_LIMIT = 1e-12
#: largest eigenvalue of a usable covariance, rad² (σ 1 rad)
MAX_VARIANCE = 1.0
#: smallest eigenvalue of a usable covariance, rad² (σ 1e-12 rad)
MIN_VARIANCE = 1e-24
#: why a covariance is dropped (the breakdown of ``bad_covariance``)
COVARIANCE_REASONS = ('asymmetric', 'not_positive_definite', 'out_of_bounds')


def _finite(a: np.ndarray) -> bool:
    return bool(np.isfinite(a).all())


def unit_quaternion(q) -> tuple[np.ndarray | None, str | None]:
    """
    Return the unit quaternion of ``q``, or None with the reason (rules 1–4).

    Parameters
    ----------
    q : array_like (4,)
        A quaternion, any scale.

    Returns
    -------
    q_unit : ndarray (4,) or None
        ``q`` normalised without overflow; None when it is dropped.
    reason : str or None
        ``nan``, ``zero_quaternion`` or ``not_unit`` when dropped; ``normalised`` when its norm
        was not 1; None for a unit quaternion.

    """
    a = np.asarray(q, dtype=float).reshape(-1)
    if a.shape != (4,):
        return None, 'nan'
    e = a.tolist()                               # (the checks on Python floats: 4 numbers)
    if not all(map(math.isfinite, e)):
        return None, 'nan'
    s = max(map(abs, e))
    if s == 0.0:
        return None, 'zero_quaternion'
    u = a / s                                    # each |u_i| <= 1: the norm cannot overflow
    n = math.sqrt(float(u @ u))                  # in [1, 2]
    if s * n < MIN_QUATERNION_NORM:
        return None, 'zero_quaternion'
    if not 1.0 / MAX_NORM_RATIO <= s * n <= MAX_NORM_RATIO:   # s·n may be inf: still no error
        return None, 'not_unit'
    if abs(s * n - 1.0) <= NORM_TOLERANCE:
        return a, None
    return u / n, 'normalised'


def screen_covariance(P) -> tuple[np.ndarray | None, str | None]:
    """
    Return a covariance that passes rules 5–7, or None with the reason.

    Parameters
    ----------
    P : array_like (3, 3)
        A finite, not all-zero covariance, rad².

    Returns
    -------
    P_ok : ndarray (3, 3) or None
        The symmetrised covariance; None when it is dropped.
    reason : str or None
        One of :data:`COVARIANCE_REASONS` when dropped, else None.

    """
    a = np.asarray(P, dtype=float).reshape(3, 3)
    c = float(np.abs(a).max())
    u = a / c                                    # elements in [-1, 1]: nothing below overflows
    e = u.tolist()                               # (the checks on Python floats: 9 numbers)
    if max(abs(e[i][j] - e[j][i]) for i, j in ((0, 1), (0, 2), (1, 2))) > SYMMETRY_TOLERANCE:
        return None, 'asymmetric'
    u = 0.5 * (u + u.T)
    try:
        lam = np.linalg.eigvalsh(u).tolist()
    except np.linalg.LinAlgError:                # not expected for a bounded matrix
        return None, 'not_positive_definite'
    lo, hi = lam[0], lam[-1]
    if not all(map(math.isfinite, lam)) or hi <= 0.0 or lo < CONDITION_LIMIT * hi:
        return None, 'not_positive_definite'
    if hi * c > MAX_VARIANCE or lo * c < MIN_VARIANCE:
        return None, 'out_of_bounds'
    return u * c, None


class FixScreen:
    """
    The screening of one stream of attitude fixes, with its counters (module docstring).

    Parameters
    ----------
    default_covariance : array_like (3, 3)
        The model's covariance (``camera_sigma_xy``, ``camera_sigma_z``), rad²: the covariance of a
        fix that has none, or an all-zero one.
    use_covariance : bool
        Read the fixes' covariance (false: every fix takes the default).

    Attributes
    ----------
    received : int
        Fixes offered.
    nan, zero_quaternion, not_unit, bad_covariance : int
        Fixes dropped, per rule.
    bad_covariance_reasons : dict
        ``bad_covariance`` per reason (:data:`COVARIANCE_REASONS`).
    normalised, covariance_substituted : int
        Fixes kept after their quaternion was normalised, or their all-zero covariance replaced.
    from_messages : int
        Fixes kept with their own covariance.

    """

    def __init__(self, default_covariance, use_covariance: bool = True):
        self.default_covariance = np.asarray(default_covariance, dtype=float).reshape(3, 3)
        self.use_covariance = bool(use_covariance)
        self.received = 0
        self.nan = self.zero_quaternion = self.not_unit = self.bad_covariance = 0
        self.bad_covariance_reasons = dict.fromkeys(COVARIANCE_REASONS, 0)
        self.normalised = self.covariance_substituted = self.from_messages = 0
        self.last_reason: str | None = None

    def screen(self, q, covariance=None) -> tuple[np.ndarray, np.ndarray] | None:
        """
        Screen one fix.

        Parameters
        ----------
        q : array_like (4,)
            The quaternion, scalar-first, any scale.
        covariance : array_like (3, 3), optional
            Its covariance, rad² (None: the message has none).

        Returns
        -------
        (q_unit, P) or None
            The unit quaternion and the covariance to use; None when the fix is dropped
            (``last_reason`` names the rule).

        """
        self.received += 1
        self.last_reason = None
        P = None
        if covariance is not None and self.use_covariance:
            P = np.asarray(covariance, dtype=float)
            if P.size != 9 or not _finite(P):
                return self._drop('nan')
            P = P.reshape(3, 3)
        u, why = unit_quaternion(q)
        if u is None:
            return self._drop(why)
        if P is None:
            P = self.default_covariance
        elif not P.any():                        # all zero: "unknown" in ROS
            P = self.default_covariance
            self.covariance_substituted += 1
        else:
            P, bad = screen_covariance(P)
            if P is None:
                self.bad_covariance_reasons[bad] += 1
                return self._drop('bad_covariance')
            self.from_messages += 1
        if why == 'normalised':
            self.normalised += 1
        return u, P

    def screen_many(self, quaternions, covariances) -> list:
        """
        Screen fixes in order: the results and counts of :meth:`screen` on each in turn.

        The fixes every rule clearly passes (a finite quaternion within half the tolerance of
        unit norm; a finite covariance, not all zero, symmetric within half the tolerance, whose
        eigenvalues clear each bound by a factor 2) are screened as arrays at once, with the
        arithmetic of :meth:`screen` (the same symmetrisation; a stack of 3×3 eigenvalue problems
        is solved matrix by matrix); every other fix goes through :meth:`screen` itself, so no
        decision near a bound depends on the path.

        Parameters
        ----------
        quaternions : sequence of array_like (4,)
            The quaternions, scalar-first, any scale.
        covariances : sequence of (array_like (3, 3) or None)
            Each fix's covariance, rad² (None: the message has none).

        Returns
        -------
        list of ((q_unit, P) or None)
            One per fix, as :meth:`screen` returns it.

        """
        n = len(quaternions)
        if len(covariances) != n:
            raise ValueError('one covariance (or None) per quaternion')
        out: list = [None] * n
        fast = np.zeros(n, dtype=bool)
        own = self.use_covariance and n > 0 and all(c is not None for c in covariances)
        try:
            q = np.asarray(quaternions, dtype=float).reshape(n, 4)
            P = (np.asarray(covariances, dtype=float).reshape(n, 3, 3) if own
                 else np.zeros((n, 3, 3)))
        except (ValueError, TypeError):                # ragged or odd: one at a time
            own = False
            q = np.zeros((n, 4))
            P = np.zeros((n, 3, 3))
        if own or all(c is None for c in covariances) or not self.use_covariance:
            with np.errstate(all='ignore'):
                fast = np.isfinite(q).all(1) & np.isfinite(P).all((1, 2))
                s = np.abs(q).max(1)
                u = q / np.where(s > 0, s, 1.0)[:, None]
                norm = s * np.sqrt((u * u).sum(1))
                fast &= np.abs(norm - 1.0) <= 0.5 * NORM_TOLERANCE
                if own:
                    c = np.abs(P).max((1, 2))
                    fast &= c > 0
                    a = P / np.where(fast, c, 1.0)[:, None, None]
                    asym = np.abs(a - np.swapaxes(a, 1, 2)).max((1, 2))
                    fast &= asym <= 0.5 * SYMMETRY_TOLERANCE
                    sym = 0.5 * (a + np.swapaxes(a, 1, 2))
                    lam = np.linalg.eigvalsh(np.where(fast[:, None, None], sym, np.eye(3)))
                    lo, hi = lam[:, 0], lam[:, -1]
                    fast &= (hi > 0) & (lo >= 2.0 * CONDITION_LIMIT * hi)
                    fast &= (hi * c <= 0.5 * MAX_VARIANCE) & (lo * c >= 2.0 * MIN_VARIANCE)
                    kept = sym * c[:, None, None]
        for i in np.flatnonzero(fast).tolist():
            out[i] = (q[i], kept[i] if own else self.default_covariance)
        fast_n = int(fast.sum())
        self.received += fast_n
        if own:
            self.from_messages += fast_n
        for i in np.flatnonzero(~fast).tolist():
            out[i] = self.screen(quaternions[i], covariances[i])
        return out

    def _drop(self, reason: str):
        setattr(self, reason, getattr(self, reason) + 1)
        self.last_reason = reason
        return None

    @property
    def dropped(self) -> int:
        """Return the number of fixes dropped by any rule."""
        return self.nan + self.zero_quaternion + self.not_unit + self.bad_covariance

    def counts(self) -> dict:
        """
        Return the counters, JSON-ready.

        Returns
        -------
        dict
            ``received``, ``dropped`` {reason: n}, ``bad_covariance_reasons``, ``normalised``,
            ``covariance_substituted``, ``covariance_from_messages``.

        """
        return {'received': self.received,
                'dropped': {'nan': self.nan, 'zero_quaternion': self.zero_quaternion,
                            'not_unit': self.not_unit, 'bad_covariance': self.bad_covariance},
                'bad_covariance_reasons': dict(self.bad_covariance_reasons),
                'normalised': self.normalised,
                'covariance_substituted': self.covariance_substituted,
                'covariance_from_messages': self.from_messages}
