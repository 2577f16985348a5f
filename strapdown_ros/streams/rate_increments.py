"""
Increments from rate samples: how a ``sensor_msgs/Imu`` stream becomes Δθ (and Δv).

Real drivers publish ``sensor_msgs/Imu`` with an angular velocity ω_k (and a specific force
f_k) per message, stamped t_k.  The core integrates increments (quasi-coordinates
Δθ_k = ∫ ω dt over (t_{k−1}, t_k], stamped at the interval end, as an integrating gyro
outputs them).  One rule makes the increments, stated once and used by every node and tool:

``trapezoid`` (default)
    The sample is the rate *at* its stamp (what most MEMS drivers publish)::

        Δθ_k = ½ (ω_{k−1} + ω_k) (t_k − t_{k−1}),   stamped t_k.

    It is exact for a rate linear in time; otherwise the error of one increment is
    +T³ ω̈ / 12 + O(T⁵) (T = t_k − t_{k−1}), so the error of the integrated angle over a fixed
    time is O(T²): second order.  Sample noise enters as (n_{k−1} + n_k)/2 · T, so the
    increments' noise is correlated between neighbours (an MA(1) of the rate noise).
``mean``
    The sample is the mean rate over the interval that ends at its stamp (what an
    integrating sensor or a driver that publishes Δθ/T gives, e.g. ``imu/data_raw`` of
    ``imu_sim_node``)::

        Δθ_k = ω_k (t_k − t_{k−1}),   stamped t_k.

    Exact when the sample is that mean.

The first sample starts the stream and gives no increment.  An interval that the gap rule of
:class:`~strapdown_ros.streams.checks.StreamCheck` (rule 6: longer than 1.75 periods, the period
the median step of the stamps) calls a gap is not integrated: the rotation over it is unknown,
the increment is not formed, and the increment stream downstream sees a gap of at least three
periods with its missing increments counted, exactly as for a Δθ stream with a dropout.  Stamp
jitter of ±30 % of the period is no gap, so nothing is lost to it.  Samples must be
validated first (finite, in range, in order: :class:`strapdown_ros.streams.checks.StreamCheck`);
after a stamp resynchronisation the integrator is restarted (:meth:`RateIntegrator.reset`).
:class:`RateIncrementStream` is that whole input rule for one stream (validation, integration,
counters), as ``sins_node`` and ``calibrator_node`` use it with ``gyro_input: imu``.

No ROS imports.
"""
from __future__ import annotations

import math

import numpy as np

from strapdown_ros.streams.checks import StreamCheck

__all__ = ['RATE_RULES', 'increments_from_rates', 'RateIntegrator', 'RateIncrementStream']

#: the rules that make increments from rate samples (see the module docstring)
RATE_RULES = ('trapezoid', 'mean')


def _check_rule(rule: str) -> str:
    if rule not in RATE_RULES:
        raise ValueError(f"rate rule {rule!r} is not valid; valid values: {', '.join(RATE_RULES)}")
    return rule


def increments_from_rates(stamps_ns, rates, rule: str = 'trapezoid', max_step_s: float = math.inf,
                          breaks=None):
    """
    Increments from a validated stream of rate samples (offline form).

    Parameters
    ----------
    stamps_ns : array_like of int, shape (n,)
        Sample stamps, integer nanoseconds, strictly increasing (validated samples).
    rates : array_like, shape (n, 3)
        Rate samples (rad/s for a gyro, m/s² for an accelerometer), body axes.
    rule : {'trapezoid', 'mean'}
        How a sample stands for the rate (module docstring).
    max_step_s : float
        Longest interval integrated, s; longer ones (dropouts, jumps) give no increment.
    breaks : array_like of int, optional
        Stamps that follow a gap or a stamp jump (the ends of :func:`~.checks.validate`'s gap
        intervals): the interval ending at each gives no increment.

    Returns
    -------
    stamps_ns : ndarray of int64, shape (m,)
        End stamps of the increments formed (m ≤ n − 1).
    increments : ndarray, shape (m, 3)
        Δθ (rad) or Δv (m/s) over (t_{k−1}, t_k].

    """
    _check_rule(rule)
    t = np.asarray(stamps_ns, dtype=np.int64).reshape(-1)
    w = np.asarray(rates, dtype=float).reshape(-1, 3)
    if len(t) != len(w):
        raise ValueError(f'{len(t)} stamps for {len(w)} rate samples')
    if len(t) < 2:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 3))
    dt_ns = np.diff(t)
    ok = (dt_ns > 0) & (dt_ns <= max_step_s * 1e9)
    if breaks is not None and len(breaks):
        ok &= ~np.isin(t[1:], np.asarray(list(breaks), dtype=np.int64))
    dt = dt_ns * 1e-9
    if rule == 'trapezoid':
        inc = 0.5 * (w[:-1] + w[1:]) * dt[:, None]
    else:
        inc = w[1:] * dt[:, None]
    return t[1:][ok], inc[ok]


class RateIntegrator:
    """
    Streaming form of :func:`increments_from_rates`: one sample in, at most one increment out.

    The same samples give the same increments as the offline function, to the bit.

    Parameters
    ----------
    rule : {'trapezoid', 'mean'}
        How a sample stands for the rate (:data:`RATE_RULES`).
    max_step_s : float
        An interval longer than this, s, is not integrated (counted ``skipped``).

    """

    def __init__(self, rule: str = 'trapezoid', max_step_s: float = math.inf):
        self.rule = _check_rule(rule)
        self.max_step_ns = max_step_s * 1e9
        self.formed = 0
        self.skipped = 0            # intervals too long to integrate (their rotation is unknown)
        self.reset()

    def reset(self) -> None:
        """Forget the previous sample (after a stamp resynchronisation or a restart)."""
        self._t: int | None = None
        self._w: tuple | None = None

    def push(self, stamp_ns: int, rate):
        """
        Push one rate sample in; return the increment over the interval it ends.

        Parameters
        ----------
        stamp_ns : int
            Stamp, ns.
        rate : sequence of float
            Rate, body axes (rad/s for a gyro).

        Returns
        -------
        (int, (float, float, float)) or None
            ``(stamp_ns, increment)``, or None for the first sample or an interval above
            ``max_step_s``.

        """
        x, y, z = float(rate[0]), float(rate[1]), float(rate[2])
        t_prev, w_prev = self._t, self._w
        self._t, self._w = int(stamp_ns), (x, y, z)
        if t_prev is None:
            return None
        step = int(stamp_ns) - t_prev
        if step <= 0 or step > self.max_step_ns:
            self.skipped += step > 0
            return None
        dt = step * 1e-9
        self.formed += 1
        if self.rule == 'trapezoid':
            return int(stamp_ns), (0.5 * (w_prev[0] + x) * dt, 0.5 * (w_prev[1] + y) * dt,
                                   0.5 * (w_prev[2] + z) * dt)
        return int(stamp_ns), (x * dt, y * dt, z * dt)


class RateIncrementStream:
    """
    The whole input rule of a rate stream, once for every node: validate, integrate, count.

    Each rate sample goes through :class:`strapdown_ros.streams.checks.StreamCheck` (non-finite,
    per-axis range ``max_rate``, duplicate, out of order, stamp jump and resynchronisation, gap)
    and each accepted sample through :class:`RateIntegrator`; an interval the check calls a gap
    (rule 6) is not integrated (counted ``skipped``), and after a confirmed resynchronisation the
    integrator restarts (the first sample of the new timeline gives no increment).  The increments
    returned are what an integrating sensor would publish; they enter the consumer's increment
    path unchanged, so an interval that could not be integrated shows there as a gap (at least 3
    periods: no jitter hides it) with its missing increments counted.

    Parameters
    ----------
    nominal_period : float
        Stated sample period, s (1 / rate); the check's period comes from the stamps.
    max_rate : float
        Sensor range per axis: rad/s for a gyro, m/s² for an accelerometer.
    rule : {'trapezoid', 'mean'}
        How a sample stands for the rate (module docstring).
    jump_limit : float
        Stamp step, s, beyond which a sample starts a candidate new timeline (StreamCheck).
    resync_count : int
        Consecutive samples that confirm a new timeline (StreamCheck).

    """

    def __init__(self, nominal_period: float, max_rate: float, rule: str = 'trapezoid',
                 jump_limit: float = 1.0, resync_count: int = 5):
        self.check = StreamCheck(nominal_period, max_norm=max_rate, jump_limit=jump_limit,
                                 resync_count=resync_count)
        self.integrator = RateIntegrator(rule)      # the check's gap rule decides, not a step
        self._offer, self._push = self.check.offer, self.integrator.push     # the hot path

    def push(self, stamp_ns: int, rate) -> list:
        """
        Push one rate sample in; return the increments it completes.

        Parameters
        ----------
        stamp_ns : int
            Stamp, ns.
        rate : sequence of float
            Rate, body axes.

        Returns
        -------
        list of (int, (float, float, float))
            ``[(stamp_ns, increment)]`` in order: usually one, none for a dropped or first sample,
            several when a resynchronisation releases held samples.

        """
        got = self._offer(stamp_ns, rate)
        if not got:
            return got
        push = self._push
        check = self.check
        marks = check.gap_marks
        if len(got) == 1 and not check.resynced and not marks:   # the usual case: one in, one out
            inc = push(*got[0])
            return [inc] if inc is not None else []
        if check.resynced:
            self.integrator.reset()
        out = []
        for s, w in got:
            if s in marks:                      # the interval before it is a gap: not integrated
                self.integrator.skipped += 1
                self.integrator.reset()
            inc = push(s, w)
            if inc is not None:
                out.append(inc)
        return out

    def status(self, prefix: str) -> dict:
        """
        Return the counters for /diagnostics.

        Parameters
        ----------
        prefix : str
            Prefix of every key.

        Returns
        -------
        dict
            The StreamCheck counters of the rate samples (``<prefix>_received``, ``_accepted``,
            ``_dropped_*``, …) and the increments formed and skipped (an interval longer than 1.5
            nominal periods, or the restart after a jump).

        """
        out = self.check.as_dict(prefix)
        out[f'{prefix}_dropped'] = self.check.dropped
        out[f'{prefix}_increments_formed'] = self.integrator.formed
        out[f'{prefix}_increments_skipped'] = self.integrator.skipped
        return out
