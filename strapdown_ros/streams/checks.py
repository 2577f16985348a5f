"""
Input validation of a stamped stream, once for every node and tool.

``sins_node``, ``calibrator_node``, ``calibrate_bag`` and ``discrepancy`` all accept messages
through :class:`StreamCheck`, so the live and offline paths agree by construction.  The rules,
in the order they are applied to each message (stamps in integer nanoseconds):

1. **non-finite** value (NaN, ±Inf): dropped, counted ``nan``;
2. **out of range**: a value with a component beyond ``max_norm`` (the sensor's per-axis range,
   e.g. ``gyro_max_rate`` × 2 nominal periods for an increment) is physically impossible:
   dropped, counted ``out_of_range`` (a finite 1e308 would otherwise overflow downstream);
3. **duplicate** stamp: dropped, counted;
4. **stamp jump**: a step of more than ``jump_limit`` seconds, forward or backward, is held as a
   *candidate* new timeline (at most ``resync_count`` messages).  A following message that fits
   the old timeline discards the candidates as **stamp outliers** (a lone stamp far in the
   future costs one message and stops nothing); ``resync_count`` consecutive messages that fit
   the candidate timeline confirm it, and the held messages are released in order, so nothing
   is lost.  What the confirmed jump is:

   a. **dropout** — a *forward* jump of at most ``max_dropout`` seconds on a stream with a
      nominal period: the stamps go on on the same timeline, messages were simply not
      received (a driver stall, a saturated sensor whose values were dropped).  Counted as a
      gap (rule 6) with ``round(step / period) − 1`` increments missing; no new time base;
   b. **resynchronisation** — a backward jump, or a forward one beyond ``max_dropout`` (or on
      a stream without a nominal period): a clock reset.  Counted ``resyncs``; ``resynced``
      tells the consumer to restart its time base;
   c. **burst that returns** — when, within ``max_burst`` accepted messages after a dropout or
      resynchronisation, a second confirmed jump lands back on the timeline from before it
      (the first new stamp lies after the last stamp of the old timeline by no more than
      ``jump_limit`` plus 2 nominal periods per message received since) while the messages in
      between lie off it (before its last stamp or after the new one: not a dropout), they
      carried wrong stamps (e.g. 5 increments stamped 1000 s in the past).  They are
      counted ``burst_messages`` (one ``bursts``), the first jump is no longer counted as a
      resynchronisation or dropout, and the old timeline continues with a gap (rule 6) over
      the burst.  Live consumers already received those messages: ``returned`` (with
      ``resynced``) tells them to restart their time base, ``retracted`` how many of the
      latest delivered messages were the burst; offline, :func:`validate` removes them from
      its output, so a burst of k wrong stamps costs only the pairs that contain it;
5. **out of order** (an older stamp within ``jump_limit``): dropped, counted;
6. **gap**: a step above 1.5 nominal periods is accepted but counted (``gaps``, ``missing``):
   the increments in between are lost.

No ROS imports.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ['StreamCheck', 'nominal_period', 'validate', 'segments', 'clip_text']


class StreamCheck:
    """
    Validity bookkeeping of one stamped vector stream.

    :meth:`offer` returns the messages to process now, in order: usually ``[(stamp, value)]``
    or ``[]``; after a confirmed resynchronisation, the held messages too.  ``resynced`` is True
    right after one (the consumer's time base must restart).  The rules are those of the module
    docstring.

    Parameters
    ----------
    nominal_period : float
        Nominal message period, s (inf: none known, no gaps counted).
    max_norm : float or None
        Largest valid absolute component (None: no range check).
    jump_limit : float
        A stamp step beyond this, s, forward or back, is a jump (at least 3 nominal periods).
    resync_count : int
        Consecutive messages that confirm a new timeline.
    max_dropout : float or None
        Longest forward jump, s, that counts as a dropout (None: :attr:`MAX_DROPOUT_S`).
    max_burst : int or None
        Most accepted messages a burst that returns may hold (None: :attr:`MAX_BURST`).

    """

    #: a confirmed forward jump up to this, s, is a dropout (rule 4a), not a clock reset
    MAX_DROPOUT_S = 3600.0
    #: a jump back to the old timeline within this many accepted messages makes a burst (rule 4c)
    MAX_BURST = 1000

    def __init__(self, nominal_period: float = math.inf, max_norm: float | None = None,
                 jump_limit: float = 1.0, resync_count: int = 5, max_dropout: float | None = None,
                 max_burst: int | None = None):
        self.nominal_ns = nominal_period * 1e9
        self.max_norm = max_norm
        self.jump_ns = max(jump_limit * 1e9,
                           3.0 * self.nominal_ns if math.isfinite(self.nominal_ns) else 0.0)
        self._gap_ns = 1.5 * self.nominal_ns   # inf without a nominal period: no gaps
        self.resync_count = max(1, int(resync_count))
        self.last_ns: int | None = None
        self.first_ns: int | None = None
        self.received = self.accepted = 0
        self.nan = self.out_of_range = self.out_of_order = self.duplicate = 0
        self.largest_out_of_range = 0.0    # largest |component| of a message out of range
        self.gaps = self.missing = self.stamp_outliers = self.resyncs = 0
        self.last_jump_s: float | None = None
        self._held: list = []          # candidate new timeline: [(stamp_ns, value)]
        self.accepted_since = 0        # accepted since first_ns (the rate after a resync)
        self.resynced = False
        dropout_s = self.MAX_DROPOUT_S if max_dropout is None else float(max_dropout)
        self.max_dropout_ns = dropout_s * 1e9
        self.max_burst = int(self.MAX_BURST if max_burst is None else max_burst)
        self.dropouts = self.bursts = self.burst_messages = 0
        self.returned = False          # the last offer ended a burst (rule 4c)
        self.retracted = 0             # ... and the latest this many delivered messages were it
        self._before_jump: dict | None = None   # the state before the last dropout/resync
        self.segment_starts: list[int] = []      # set by validate()

    # --- the rules -------------------------------------------------------------------------
    @staticmethod
    def _finite(v, isfinite=math.isfinite) -> bool:
        if len(v) == 3:                        # the hot path: one call per message
            return isfinite(v[0]) and isfinite(v[1]) and isfinite(v[2])
        return all(isfinite(c) for c in v)

    @staticmethod
    def _norm(v) -> float:
        """Largest |component|: per-axis range; never squares, so never overflows."""
        if len(v) == 3:
            return max(abs(v[0]), abs(v[1]), abs(v[2]))
        return max(abs(c) for c in v)

    def clip_warning(self, parameter: str, limit: float, unit: str,
                     period: float | None = None) -> str | None:
        """
        Return the warning of the messages dropped beyond the clip level, or None.

        Parameters
        ----------
        parameter : str
            The model key of the clip level.
        limit : float
            Its value, ``unit``.
        unit : str
            The unit of the limit.
        period : float, optional
            For increments: their period, s (the largest is shown as a rate).

        Returns
        -------
        str or None
            :func:`clip_text`; None when nothing was out of range.

        """
        if not self.out_of_range:
            return None
        largest = self.largest_out_of_range / period if period else self.largest_out_of_range
        return clip_text(self.out_of_range, largest, parameter, limit, unit)

    @property
    def held(self) -> int:
        """Return the number of messages held as a candidate new timeline after a stamp jump."""
        return len(self._held)

    def offer(self, stamp_ns: int, v, isfinite=math.isfinite):
        """
        Offer one message to the rules.

        Parameters
        ----------
        stamp_ns : int
            Header stamp, ns.
        v : sequence of float
            The vector.
        isfinite : callable
            ``math.isfinite`` (bound as a default: the hot path).

        Returns
        -------
        list of (int, tuple)
            The messages to process now, in order: usually this one or none; after a confirmed
            resynchronisation, the held messages too.

        """
        self.received += 1
        self.resynced = self.returned = False
        self.retracted = 0
        if len(v) == 3:                        # the hot path, rules 1 and 2 without calls
            x, y, z = v
            if not (isfinite(x) and isfinite(y) and isfinite(z)):
                self.nan += 1
                return []
            if self.max_norm is not None and max(abs(x), abs(y), abs(z)) > self.max_norm:
                self.out_of_range += 1
                self.largest_out_of_range = max(self.largest_out_of_range, abs(x), abs(y),
                                                abs(z))
                return []
        else:
            if not self._finite(v):
                self.nan += 1
                return []
            if self.max_norm is not None and self._norm(v) > self.max_norm:
                self.out_of_range += 1
                self.largest_out_of_range = max(self.largest_out_of_range, self._norm(v))
                return []
        last = self.last_ns
        if last is None:
            return self._take(stamp_ns, v)
        if self._held:
            return self._with_candidates(stamp_ns, v)
        step = stamp_ns - last
        if 0 < step <= self.jump_ns:           # the usual case: the next stamp (rule 6 inline)
            if step > self._gap_ns:
                self.gaps += 1
                self.missing += int(round(step / self.nominal_ns)) - 1
            self.last_ns = stamp_ns
            self.accepted += 1
            self.accepted_since += 1
            return [(stamp_ns, v)]
        if step == 0:
            self.duplicate += 1
            return []
        if abs(step) > self.jump_ns:
            self._held.append((stamp_ns, v))
            return []
        self.out_of_order += 1                 # step < 0 within jump_limit
        return []

    def _fits(self, prev_ns: int, stamp_ns: int) -> bool:
        return 0 < stamp_ns - prev_ns <= self.jump_ns

    def _with_candidates(self, stamp_ns, v):
        if self._fits(self.last_ns, stamp_ns):             # the old timeline goes on: outliers
            self.stamp_outliers += len(self._held)
            self._held.clear()
            return self._take(stamp_ns, v)
        if self._fits(self._held[-1][0], stamp_ns):
            self._held.append((stamp_ns, v))
            if len(self._held) >= self.resync_count:
                return self._confirm_jump()
            return []
        if stamp_ns == self.last_ns or stamp_ns == self._held[-1][0]:
            self.duplicate += 1
            return []
        if len(self._held) < self.resync_count:            # another stray stamp: a new candidate
            self.stamp_outliers += len(self._held)
            self._held = [(stamp_ns, v)]
            return []
        self.out_of_order += 1
        return []

    def _snapshot(self) -> dict:
        return {'last_ns': self.last_ns, 'first_ns': self.first_ns,
                'accepted_since': self.accepted_since,
                'gaps': self.gaps, 'missing': self.missing, 'resyncs': self.resyncs,
                'dropouts': self.dropouts, 'accepted': self.accepted, 'received': self.received}

    def _confirm_jump(self):
        """
        Confirm a new timeline held by ``resync_count`` messages.

        ``resync_count`` held messages agree on a new timeline: a return from a burst, a
        dropout or a resynchronisation (rule 4), in that order of precedence.
        """
        held, self._held = self._held, []
        first = held[0][0]
        before = self._before_jump
        nominal = self.nominal_ns if math.isfinite(self.nominal_ns) else 0.0
        if before is not None and self.accepted - before['accepted'] <= self.max_burst:
            since = self.received - before['received']
            back = first - before['last_ns']
            off_timeline = not before['last_ns'] < self.last_ns < first   # not a dropout before
            if off_timeline and 0 < back <= self.jump_ns + 2.0 * nominal * since:
                return self._return_from_burst(held, before)
        self._before_jump = self._snapshot()
        step = first - self.last_ns
        self.last_jump_s = step * 1e-9
        if math.isfinite(self.nominal_ns) and 0 < step <= self.max_dropout_ns:
            self.dropouts += 1                          # the same timeline, messages not received
            out = []
            for s, val in held:
                out += self._take(s, val)               # counts the gap and the missing increments
            return out
        self.resyncs += 1
        self.last_ns = None                             # a new time base
        self.first_ns, self.accepted_since = None, 0
        out = []
        for s, val in held:
            out += self._take(s, val)
        self.resynced = True
        return out

    def _return_from_burst(self, held, before):
        n = self.accepted - before['accepted']          # delivered since the first jump: the burst
        self.bursts += 1
        self.burst_messages += n
        self.last_jump_s = (held[0][0] - self.last_ns) * 1e-9
        self.gaps, self.missing = before['gaps'], before['missing']
        self.resyncs, self.dropouts = before['resyncs'], before['dropouts']
        self.last_ns, self.first_ns = before['last_ns'], before['first_ns']
        self.accepted_since = before['accepted_since']
        self._before_jump = None
        out = []
        for s, val in held:
            out += self._take(s, val)                   # the gap over the burst is counted here
        self.resynced = self.returned = True
        self.retracted = n
        return out

    def _take(self, stamp_ns, v):
        if self.last_ns is not None:
            step = stamp_ns - self.last_ns
            if step > self._gap_ns:
                self.gaps += 1
                self.missing += int(round(step / self.nominal_ns)) - 1
        if self.first_ns is None:
            self.first_ns = stamp_ns
        self.last_ns = stamp_ns
        self.accepted += 1
        self.accepted_since += 1
        return [(stamp_ns, v)]

    def offer_many(self, stamps_ns, values) -> int:
        """
        Offer many messages at once, vectorised, in the usual case only.

        The longest prefix whose messages are finite, within ``max_norm`` and each one step of
        (0, ``jump_limit``] after the last accepted stamp, with no candidate timeline held, is
        accepted with the counters :meth:`offer` would give (gaps included).

        Parameters
        ----------
        stamps_ns : array_like (n,) int64
            Stamps, ns.
        values : array_like (n, 3)
            The vectors.

        Returns
        -------
        int
            k, the number accepted; message k (if any) must go through :meth:`offer`.  0 when the
            first message is not the usual case (or none was accepted yet).

        """
        if self.last_ns is None or self._held or not len(stamps_ns):
            return 0
        st = np.asarray(stamps_ns, dtype=np.int64)
        v = np.asarray(values, dtype=float)
        steps = np.diff(st, prepend=np.int64(self.last_ns))
        ok = (steps > 0) & (steps <= self.jump_ns) & np.isfinite(v).all(axis=1)
        if self.max_norm is not None:
            ok &= np.abs(v).max(axis=1) <= self.max_norm
        k = int(np.argmin(ok)) if not ok.all() else len(st)
        if k:
            for step in steps[:k][steps[:k] > self._gap_ns].tolist():   # rule 6, as in offer
                self.gaps += 1
                self.missing += int(round(step / self.nominal_ns)) - 1
            self.received += k
            self.accepted += k
            self.accepted_since += k
            self.last_ns = int(st[k - 1])
            self.resynced = False                   # the flags offer() clears for every message
            if hasattr(self, 'retracted'):          # (the burst flags, where the rules have them)
                self.returned, self.retracted = False, 0
        return k

    def accept(self, stamp_ns: int, v) -> bool:
        """
        Offer one message; True when it is accepted now.

        The single-message form for consumers that process one message at a time (messages
        released by a resynchronisation are not returned here).

        Parameters
        ----------
        stamp_ns : int
            Header stamp, ns.
        v : sequence of float
            The vector.

        Returns
        -------
        bool
            The message itself is accepted now.

        """
        out = self.offer(stamp_ns, v)
        return bool(out) and out[-1][0] == stamp_ns

    # --- reporting -------------------------------------------------------------------------
    @property
    def dropped(self) -> int:
        """Messages dropped by any rule (non-finite, range, duplicate, order, stamp outlier)."""
        return (self.nan + self.out_of_range + self.out_of_order + self.duplicate
                + self.stamp_outliers)

    def rate_hz(self) -> float:
        """Return the rate from the accepted stamps of the current time base, Hz (0: unknown)."""
        if self.first_ns is None or self.last_ns is None or self.last_ns <= self.first_ns \
                or self.accepted_since < 2:
            return 0.0
        return (self.accepted_since - 1) / ((self.last_ns - self.first_ns) * 1e-9)

    def as_dict(self, prefix: str) -> dict:
        """
        Return the counters for /diagnostics and the tools' JSON.

        Parameters
        ----------
        prefix : str
            Prefix of every key (``gyro``, ``accel``, ...).

        Returns
        -------
        dict
            ``<prefix>_received``, ``<prefix>_accepted``, ``<prefix>_dropped_*``, gaps, missing
            samples, resynchronisations and bursts.

        """
        return {f'{prefix}_received': self.received, f'{prefix}_accepted': self.accepted,
                f'{prefix}_rate_hz_from_stamps': self.rate_hz(), f'{prefix}_dropped_nan': self.nan,
                f'{prefix}_dropped_out_of_range': self.out_of_range,
                f'{prefix}_largest_out_of_range': self.largest_out_of_range,
                f'{prefix}_dropped_out_of_order': self.out_of_order,
                f'{prefix}_dropped_duplicate': self.duplicate,
                f'{prefix}_dropped_stamp_outlier': self.stamp_outliers,
                f'{prefix}_stamp_resyncs': self.resyncs, f'{prefix}_gaps': self.gaps,
                f'{prefix}_missing_samples': self.missing, f'{prefix}_dropouts': self.dropouts,
                f'{prefix}_stamp_bursts': self.bursts,
                f'{prefix}_stamp_burst_messages': self.burst_messages}


def clip_text(count: int, largest: float, parameter: str, limit: float, unit: str) -> str:
    """
    Return the one wording of samples beyond a clip level, naming the parameter.

    Parameters
    ----------
    count : int
        Samples dropped as out of range.
    largest : float
        The largest value among them, in ``unit``.
    parameter : str
        The model key of the clip level (``gyro_max_rate``, ``accel_max``).
    limit : float
        Its value, in ``unit``.
    unit : str
        The unit.

    Returns
    -------
    str
        E.g. ``12 samples beyond gyro_max_rate = 20 rad/s dropped (largest 25.3 rad/s): raise
        gyro_max_rate in the model if the sensor's range is larger``.

    """
    return (f'{count} sample(s) beyond {parameter} = {limit:g} {unit} dropped (largest '
            f'{largest:.4g} {unit}): raise {parameter} in the model if the range of the sensor '
            'is larger')


def nominal_period(stamps_ns) -> float:
    """
    Return the period of a stream from its own stamps, s.

    The median of the positive steps, robust to outliers, duplicates and gaps.

    Parameters
    ----------
    stamps_ns : array_like (n,) int64
        Stamps, ns.

    Returns
    -------
    float
        The period, s; inf with fewer than 2 distinct stamps.

    """
    st = np.asarray(stamps_ns, dtype=np.int64)
    d = np.diff(st)
    d = d[d > 0]
    return float(np.median(d)) * 1e-9 if len(d) else math.inf


def validate(stamps_ns, values, check: StreamCheck):
    """
    Run a whole recorded stream through ``check`` (the node's rules, in bag order).

    A burst that returned (rule 4c) is removed from the output: the stamps of each time base
    are strictly increasing.  The index in the output where each time base after a
    resynchronisation starts is left in ``check.segment_starts`` (empty without one).

    Parameters
    ----------
    stamps_ns : iterable of int
        Stamps, ns, in bag order.
    values : iterable of sequence of float
        The vectors.
    check : StreamCheck
        The stream's rules and counters (updated).

    Returns
    -------
    stamps : list of int
        The accepted stamps, ns, in order.
    values : list
        The accepted vectors.
    gaps : list of (int, int)
        Intervals (a, b), ns, that no increment pair may span: gaps (steps above 1.5 nominal
        periods, dropouts and returns from a burst included) and confirmed resynchronisations
        (last stamp before, first after; b < a for a backward jump).

    """
    out_t, out_v, gaps = [], [], []
    starts: list[int] = []
    marks: list[tuple[int, int, int]] = []       # (len(out_t), len(gaps), len(starts)) per jump
    for ns, v in zip(stamps_ns, values):
        prev = check.last_ns
        got = check.offer(int(ns), v)
        if not got:
            continue
        if check.returned:
            n_out, n_gaps, n_starts = marks.pop() if marks else (len(out_t) - check.retracted,
                                                                 len(gaps), len(starts))
            del out_t[n_out:], out_v[n_out:], gaps[n_gaps:], starts[n_starts:]
            prev = out_t[-1] if out_t else None
        elif check.resynced or (prev is not None and got[0][0] - prev > check.jump_ns):
            marks = [(len(out_t), len(gaps), len(starts))]    # the state a return goes back to
            if check.resynced and out_t:
                gaps.append((out_t[-1], got[0][0]))         # across the jump (either direction)
                starts.append(len(out_t))
                prev = None
        for s, val in got:
            if prev is not None and math.isfinite(check.nominal_ns) \
                    and s - prev > 1.5 * check.nominal_ns:
                gaps.append((prev, s))
            out_t.append(s)
            out_v.append(val)
            prev = s
    check.segment_starts = starts
    return out_t, out_v, gaps


def segments(stamps_ns, starts) -> list[tuple[int, int]]:
    """
    Return the index ranges of the time bases of an accepted stream.

    Parameters
    ----------
    stamps_ns : sequence of int
        Accepted stamps (:func:`validate`'s output).
    starts : sequence of int
        ``check.segment_starts``.

    Returns
    -------
    list of (int, int)
        (lo, hi) index ranges; within each, the stamps strictly increase.

    """
    bounds = [0] + [int(k) for k in starts] + [len(stamps_ns)]
    return [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]
