"""
Sums of stamped increments over the attitude update intervals.

A node receives accelerometer Δv at its own rate and needs them summed over each attitude
update ``(t_{k−1}, t_k]`` of the gyro stream (the mean specific force of the update).
:class:`IncrementAccumulator` holds them, bounded, until the updates ask.  No ROS imports.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.streams.buffers import StampedBuffer

__all__ = ['IncrementAccumulator']


class IncrementAccumulator:
    """
    Sum stamped increments over arbitrary intervals ``(t_a, t_b]``.

    For example accelerometer Δv at 300 Hz over the gyro update intervals, to give the mean
    specific force.  Bounded, so that Δv arriving without gyro data cannot pile up.

    Parameters
    ----------
    max_len : int
        At most this many increments are held; the oldest are dropped and counted in
        :attr:`overflowed`.

    """

    def __init__(self, max_len: int = 100_000):
        self._buf = StampedBuffer(3, max_len=max_len)
        self.latest = -np.inf

    @property
    def overflowed(self) -> int:
        """
        Return the number of increments dropped because the buffer was full.

        Returns
        -------
        int
            Count since construction.

        """
        return self._buf.overflowed

    def __len__(self) -> int:
        return len(self._buf)

    def add(self, increments: np.ndarray, stamps: np.ndarray) -> None:
        """
        Append increments.

        Parameters
        ----------
        increments : (n, 3) array_like
            Increments (e.g. Δv, m/s).
        stamps : (n,) array_like
            End of each increment's interval, s, increasing.

        """
        st = np.asarray(stamps, dtype=float).reshape(-1)
        self._buf.extend(st, np.asarray(increments, dtype=float).reshape(-1, 3))
        if len(st):
            self.latest = max(self.latest, float(st.max()))

    def discard_through(self, t: float) -> None:
        """
        Forget the increments stamped at or before a time (nobody will take them).

        Parameters
        ----------
        t : float
            Time, s.

        """
        self._buf.drop_through(t)

    def covered_until(self) -> float:
        """
        Return the newest stamp added so far.

        Returns
        -------
        float
            Stamp, s; −inf before the first increment.

        """
        return self.latest

    def take(self, t_a: float, t_b: float) -> tuple[np.ndarray, int]:
        """
        Return the sum of the increments stamped in (t_a, t_b] and drop all up to t_b.

        An increment whose interval straddles t_a or t_b is counted whole in the interval
        holding its end stamp.

        Parameters
        ----------
        t_a, t_b : float
            Interval ends, s.

        Returns
        -------
        tuple of ((3,) ndarray, int)
            The sum and the number of increments in it.

        """
        t, v = self._buf.stamps, self._buf.values
        sel = (t > t_a) & (t <= t_b)
        total = v[sel].sum(0) if np.any(sel) else np.zeros(3)
        n = int(sel.sum())
        self._buf.drop_through(t_b)
        return total, n

    def take_sequence(self, t_a: np.ndarray, t_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """
        Apply :meth:`take` to intervals ``(t_a[i], t_b[i]]`` in increasing order, in one pass.

        The counts are those of calling :meth:`take` for each in turn (an increment already
        taken by an earlier interval is not counted again); each sum is over its interval's
        increments alone, so it does not depend on how the data were blocked.

        Parameters
        ----------
        t_a, t_b : (m,) array_like
            Interval starts and ends, s.

        Returns
        -------
        tuple of ((m, 3) ndarray, (m,) ndarray)
            Sums and counts.

        """
        t_a, t_b = np.asarray(t_a, dtype=float), np.asarray(t_b, dtype=float)
        t, v = self._buf.stamps, self._buf.values
        hi = np.searchsorted(t, t_b, side='right')
        lo = np.searchsorted(t, t_a, side='right')
        taken = np.concatenate([[0], np.maximum.accumulate(hi)[:-1]])    # taken already
        lo = np.maximum(lo, taken)
        lo = np.minimum(lo, hi)
        counts = hi - lo
        sums = np.zeros((len(t_b), 3))
        has = counts > 0
        if has.any():
            # each interval summed over its own increments (reduceat over [lo, hi) pairs): the
            # sum does not depend on what else the buffer holds, so any blocking of the same
            # data gives the same bits
            edges = np.column_stack([lo[has], hi[has]]).ravel()
            padded = np.concatenate([v, np.zeros((1, 3))])
            sums[has] = np.add.reduceat(padded, edges, axis=0)[::2]
        if len(t_b):
            self._buf.drop_through(float(t_b.max()))
        return sums, counts

    def take_many(self, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """
        Apply :meth:`take` to consecutive intervals ``(edges[i], edges[i+1]]``, vectorised.

        Parameters
        ----------
        edges : (m + 1,) array_like
            Increasing interval edges, s.

        Returns
        -------
        tuple of ((m, 3) ndarray, (m,) ndarray)
            Sums and counts.

        """
        edges = np.asarray(edges, dtype=float)
        t, v = self._buf.stamps, self._buf.values
        # stamps in (edges[i], edges[i+1]] are t[lo[i]:lo[i+1]]: sums from one cumulative sum
        pos = np.searchsorted(t, edges, side='right')
        cs = np.concatenate([np.zeros((1, 3)), np.cumsum(v, axis=0)])
        sums, counts = cs[pos[1:]] - cs[pos[:-1]], np.diff(pos)
        sums[counts == 0] = 0.0
        self._buf.drop_through(edges[-1])
        return sums, counts
