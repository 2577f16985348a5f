"""
A bounded buffer of stamped vectors with amortised O(1) appends.

The one buffer behind the calibrator's gyro history and the SINS core's accelerometer
accumulator; it sits in the streams room, below every numerical room.  No ROS imports.

Appends write into preallocated numpy arrays (capacity doubles when full, up to ``max_len``);
dropping the oldest samples moves a start index and compacts only when more than half of the
storage is dead, so neither appending nor trimming copies the whole history each time.  Beyond
``max_len`` the oldest samples are dropped and counted (``overflowed``): memory is bounded
whatever the input does.
"""
from __future__ import annotations

import numpy as np

__all__ = ['StampedBuffer']


class StampedBuffer:
    """
    Stamped vectors in stamp order, bounded in length, with amortised O(1) appends.

    Parameters
    ----------
    width : int
        Length of each vector.
    max_len : int
        Most samples kept; beyond it the oldest are dropped and counted in ``overflowed``.
    initial : int
        Initial capacity (doubles when full, up to ``max_len``).

    """

    def __init__(self, width: int = 3, max_len: int = 1_000_000, initial: int = 1024):
        self.width = int(width)
        self.max_len = int(max_len)
        cap = max(16, min(int(initial), self.max_len))
        self._t = np.empty(cap)
        self._v = np.empty((cap, self.width))
        self._lo = 0                  # first live sample
        self._hi = 0                  # one past the last
        self.overflowed = 0           # samples dropped because the bound was reached

    def __len__(self) -> int:
        return self._hi - self._lo

    @property
    def storage_size(self) -> int:
        """Return the number of rows allocated (at most twice the bound)."""
        return len(self._t)

    @property
    def stamps(self) -> np.ndarray:
        """Live stamps, s (a view; valid until the next append or drop)."""
        return self._t[self._lo:self._hi]

    @property
    def values(self) -> np.ndarray:
        """Live vectors, (n, width) (a view; valid until the next append or drop)."""
        return self._v[self._lo:self._hi]

    @property
    def last_stamp(self) -> float | None:
        """Newest stamp, s, or None when empty."""
        return float(self._t[self._hi - 1]) if self._hi > self._lo else None

    def extend(self, stamps, values) -> None:
        """
        Append many samples in stamp order.

        Parameters
        ----------
        stamps : array_like (n,)
            Stamps, s, not before the newest one held.
        values : array_like (n, width)
            The vectors.

        """
        st = np.atleast_1d(np.asarray(stamps, dtype=float))
        v = np.asarray(values, dtype=float).reshape(-1, self.width)
        n = len(st)
        if n == 0:
            return
        if n > self.max_len:                                  # only the newest max_len can stay
            self.overflowed += n - self.max_len
            st, v, n = st[-self.max_len:], v[-self.max_len:], self.max_len
        over = len(self) + n - self.max_len
        if over > 0:
            self.drop_first(over)
            self.overflowed += over
        if self._hi + n > len(self._t):
            self._make_room(n)
        self._t[self._hi:self._hi + n] = st
        self._v[self._hi:self._hi + n] = v
        self._hi += n

    def append(self, stamp: float, value) -> None:
        """
        Append one sample (the live path: scalar writes, no array conversions).

        Parameters
        ----------
        stamp : float
            Stamp, s, not before the newest one held.
        value : sequence of float
            The vector, length ``width``.

        """
        if self._hi - self._lo >= self.max_len:
            self.drop_first(1)
            self.overflowed += 1
        if self._hi >= len(self._t):
            self._make_room(1)
        i = self._hi
        self._t[i] = stamp
        self._v[i] = value
        self._hi = i + 1

    def _make_room(self, n: int) -> None:
        live = len(self)
        need = live + n
        cap = len(self._t)
        if need > cap // 2 or cap < need:                     # grow (doubling, bounded)
            cap = min(max(2 * cap, need), max(self.max_len, need))
        t, v = np.empty(cap), np.empty((cap, self.width))
        t[:live] = self._t[self._lo:self._hi]
        v[:live] = self._v[self._lo:self._hi]
        self._t, self._v, self._lo, self._hi = t, v, 0, live

    def drop_first(self, k: int) -> None:
        """
        Drop the k oldest samples (O(1); storage compacts on a later append).

        Parameters
        ----------
        k : int
            How many; more than held empties the buffer.

        """
        self._lo = min(self._hi, self._lo + max(0, int(k)))
        if self._lo == self._hi:
            self._lo = self._hi = 0

    def drop_through(self, stamp: float) -> None:
        """
        Drop every sample stamped at or before ``stamp``.

        Parameters
        ----------
        stamp : float
            Stamp, s.

        """
        if self._lo == self._hi:
            return
        self.drop_first(int(np.searchsorted(self.stamps, stamp, side='right')))

    def clear(self) -> None:
        """Drop every sample (``overflowed`` is kept)."""
        self._lo = self._hi = 0
