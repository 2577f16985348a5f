"""
The late-fix memory of the attitude filter: camera fixes, checkpoints and the increment log.

A camera fix may arrive after increments past its epoch.  The attitude filter
(:mod:`strapdown_ros.estimation.attitude_filter`) then rolls back to a :class:`Checkpoint`,
re-processes the increments kept in the :class:`IncrementLog` and the fixes
(:class:`CameraFix`) applied since, with the late fix in its place.  No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ['CameraFix', 'Checkpoint', 'IncrementLog']


@dataclass
class CameraFix:
    """
    A camera fix as the filter holds it: waiting, applied or gated, re-processable.

    Parameters
    ----------
    seq : int
        Arrival number (ties of equal epochs keep the arrival order).
    stamp : float
        Header stamp, camera clock, s.
    epoch : float
        IMU-clock epoch it is applied at (stamp − τ̂), s.
    attitude : ndarray (4,)
        Measured ``q_GCRS_VF``, scalar-first.
    covariance : ndarray (3, 3)
        Its covariance in VF axes, rad².
    lateness : float
        Newest increment stamp − epoch at arrival (0: not late), s.
    counted : bool
        Whether its outcome is in the filter's counters (re-processing counts it once).
    order : int
        Rank in the order fixes were processed (re-processing renews it).

    """

    seq: int
    stamp: float
    epoch: float
    attitude: np.ndarray
    covariance: np.ndarray
    lateness: float = 0.0
    counted: bool = False
    order: int = -1


@dataclass
class Checkpoint:
    """
    The filter's state at an increment stamp, to roll back to for a late fix.

    Parameters
    ----------
    epoch : float
        Stamp of the checkpoint, s.
    pieces : int
        Global index of the next piece in the :class:`IncrementLog`.
    order : int
        Fixes processed after the checkpoint have ``order`` ≥ this.
    integrator : tuple
        The integrator's checkpoint.
    states : ndarray (n,)
        The estimates of the filter states.
    boresight : ndarray (4,)
        ``q_MF_VF``, scalar-first.
    covariance : ndarray (n, n)
        Square-root factor of P (never written into).
    open_rho : ndarray (k, 3)
        Compensated pieces not yet in a completed update, rad.
    open_dt : ndarray (k,)
        Their lengths, s.
    last_rate : ndarray (3,)
        Rate of the newest piece, rad/s.
    last_stamp : float
        Stamp of the newest piece, s.
    state_time : float
        Time the estimates hold at (the last fix; Gauss–Markov states decay from it), s.
    divergence : tuple
        The divergence rule's memory (consecutive gated fixes, the recent clipped NIS, fixes
        since the last reset).

    """

    epoch: float
    pieces: int
    order: int
    integrator: tuple
    states: np.ndarray
    boresight: np.ndarray
    covariance: np.ndarray
    open_rho: np.ndarray
    open_dt: np.ndarray
    last_rate: np.ndarray
    last_stamp: float
    state_time: float = 0.0
    divergence: tuple = (0, (), 0)


class IncrementLog:
    """
    A bounded log of the increments as processed (pieces), indexed globally.

    Parameters
    ----------
    history : int
        Most pieces kept; older ones are forgotten.

    Attributes
    ----------
    base : int
        Global index of the oldest piece kept.
    next : int
        Global index of the next piece.

    """

    def __init__(self, history: int):
        self.history = int(history)
        self._t = np.empty(2 * self.history)
        self._d = np.empty((2 * self.history, 3))
        self._lo = 0                  # buffer row of global piece `base`
        self.base = 0
        self.next = 0

    def append(self, d: np.ndarray, t: np.ndarray) -> None:
        """
        Append pieces, forgetting the oldest beyond ``history``.

        Parameters
        ----------
        d : ndarray (k, 3)
            Increments, rad.
        t : ndarray (k,)
            Their end stamps, s.

        """
        k = len(t)
        if k > self.history:                     # keep only the newest pieces
            drop = k - self.history
            d, t = d[drop:], t[drop:]
            self.next += drop
            self.base = self.next
            self._lo = 0
            k = len(t)
        hi = self._lo + (self.next - self.base)
        if hi + k > len(self._t):               # compact: keep the newest `history - k` pieces
            keep = min(self.next - self.base, self.history - k)
            src = slice(hi - keep, hi)
            self._t[:keep] = self._t[src].copy()
            self._d[:keep] = self._d[src].copy()
            self.base = self.next - keep
            self._lo, hi = 0, keep
        self._t[hi:hi + k], self._d[hi:hi + k] = t, d
        self.next += k

    def since(self, pieces: int):
        """
        Return copies of the pieces from global index ``pieces`` (≥ :attr:`base`) on.

        Parameters
        ----------
        pieces : int
            Global index of the first piece.

        Returns
        -------
        d : ndarray (k, 3)
            Increments, rad.
        t : ndarray (k,)
            End stamps, s.

        """
        lo = self._lo + (pieces - self.base)
        hi = self._lo + (self.next - self.base)
        return self._d[lo:hi].copy(), self._t[lo:hi].copy()

    def rewind(self, pieces: int) -> None:
        """
        Forget the pieces from global index ``pieces`` on (they will be appended again).

        Parameters
        ----------
        pieces : int
            Global index of the first piece forgotten.

        """
        self.next = pieces
