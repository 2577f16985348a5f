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
4. **stamp jump**: a step forward of more than the *forward limit* (``jump_limit``, or 3 periods
   of the stream when that is longer) or backward of more than the *backward limit* (the same;
   ``jump_limit`` while the period is not known yet) is held as a *candidate* new timeline (at
   most ``resync_count`` messages).  A stream without a stated period (attitude fixes,
   :meth:`StreamCheck.for_fixes`) takes its period from its own stamps as the gap rule does
   (from 3 steps on: it only sets the jump limit), and its forward limit is ``initial_jump`` (an
   hour) until it has one.  A following message that
   fits the old timeline discards the candidates as **stamp outliers** (a lone stamp far in the
   future costs one message and stops nothing); ``resync_count`` consecutive messages that fit
   the candidate timeline confirm it, and the held messages are released in order, so nothing
   is lost.  What the confirmed jump is:

   a. **dropout** — a *forward* jump of at most ``max_dropout`` seconds on a stream with a
      period (stated, or from its stamps): the stamps go on on the same timeline, messages were
      simply not received (a driver stall, a saturated sensor whose values were dropped).
      Counted as a gap (rule 6) with ``round(step / period) − 1`` increments missing; no new
      time base;
   b. **resynchronisation** — a backward jump, or a forward one beyond ``max_dropout`` (or on
      a stream without a period yet): a clock reset.  Counted ``resyncs``; ``resynced``
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
5. **out of order** (an older stamp within the backward limit): dropped, counted;
6. **gap** — THE gap rule of every stream, node and tool alike: the period is the median of the
   stream's own mean steps over :attr:`StreamCheck.PERIOD_SPAN` (16) steps, ``(t[k+16] − t[k])
   / 16``, over its last :attr:`StreamCheck.PERIOD_WINDOW` (256) accepted stamps (a stamp's
   jitter enters each 1/16th as much as one step; computed after 16 steps, with spans of 8,
   then after 32, 64, 128 and every 255; no gap is judged before the first: a stated period,
   ``gyro_rate``, is never the gap rule's), and a step longer than
   :attr:`StreamCheck.GAP_FACTOR` (1.75) periods is a gap with
   ``max(1, round(step / period) − 1)`` samples missing.  It is accepted but counted
   (``gaps``, ``missing``): the increments in between are lost.  Stamp jitter up to ±35 %
   of the period (a step of at most 1.7 periods) gives no gap, so a host-stamped 1 kHz IMU with
   ±0.3 ms jitter loses nothing; a single missing sample is always seen while the jitter stays
   below ±12 % (beyond, a missing sample whose neighbours' jitter shortens its step below 1.75
   periods goes unseen).  ``gap_marks`` names the accepted messages that follow a gap, so a
   stated ``gyro_rate`` that is wrong (a 50 Hz IMU under the default 100) costs nothing.

No ROS imports.
"""
from __future__ import annotations

from collections import deque
import math

import numpy as np

__all__ = ['StreamCheck', 'nominal_period', 'validate', 'segments', 'clip_text', 'gap_ends',
           'match_segments']


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
        Stated message period, s (inf: none); rule 6 replaces it by the median step of the
        stamps as soon as 3 steps are known.
    max_norm : float or None
        Largest valid absolute component (None: no range check).
    jump_limit : float
        A stamp step beyond this, s, forward or back, is a jump (at least 3 periods).
    resync_count : int
        Consecutive messages that confirm a new timeline.
    max_dropout : float or None
        Longest forward jump, s, that counts as a dropout (None: :attr:`MAX_DROPOUT_S`).
    max_burst : int or None
        Most accepted messages a burst that returns may hold (None: :attr:`MAX_BURST`).
    count_gaps : bool
        Judge and count gaps (rule 6): increments and rate samples; not attitude fixes.
    initial_jump : float or None
        Forward limit, s, while the stream has no period yet (None: ``jump_limit``).

    """

    #: a confirmed forward jump up to this, s, is a dropout (rule 4a), not a clock reset
    MAX_DROPOUT_S = 3600.0
    #: a jump back to the old timeline within this many accepted messages makes a burst (rule 4c)
    MAX_BURST = 1000
    #: a step longer than this many periods is a gap (rule 6)
    GAP_FACTOR = 1.75
    #: accepted stamps whose mean steps give the median that is the period (rule 6)
    PERIOD_WINDOW = 256
    #: steps each mean step of the median spans (at most; half the steps known, early on)
    PERIOD_SPAN = 16
    #: the median is recomputed every this many accepted steps (sooner while the window fills)
    PERIOD_EVERY = 256
    #: steps needed before the median replaces the stated period and gaps are judged
    PERIOD_MIN_STEPS = 16
    #: the same for a stream without gaps (attitude fixes): its period only sets the jump limit
    FIX_MIN_STEPS = 3
    #: forward limit of an attitude-fix stream before its period is known, s
    FIX_INITIAL_JUMP_S = 3600.0

    def __init__(self, nominal_period: float = math.inf, max_norm: float | None = None,
                 jump_limit: float = 1.0, resync_count: int = 5, max_dropout: float | None = None,
                 max_burst: int | None = None, count_gaps: bool = True,
                 initial_jump: float | None = None):
        self.nominal_ns = nominal_period * 1e9
        self.max_norm = max_norm
        self.jump_limit_ns = float(jump_limit) * 1e9
        self.initial_jump_ns = self.jump_limit_ns if initial_jump is None \
            else max(self.jump_limit_ns, float(initial_jump) * 1e9)
        self.count_gaps = bool(count_gaps)
        self._stamps: deque = deque(maxlen=self.PERIOD_WINDOW)   # accepted stamps, ns
        self._min_steps = self.PERIOD_MIN_STEPS if self.count_gaps else self.FIX_MIN_STEPS
        self._due = self._min_steps         # steps until the median is computed again
        self.period_ns = math.inf        # the median step (inf: not known yet)
        self.gap_marks: list[int] = []   # stamps released by the last offer that follow a gap
        self._limits()
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

    @classmethod
    def for_fixes(cls, jump_limit: float = 1.0, resync_count: int = 5) -> StreamCheck:
        """
        Return the stamp rules of a stream of attitude fixes (a star camera, motion capture).

        No stated period, no gaps counted; the period comes from the stamps (rule 6), so that a
        fix stamped a few periods ahead is a candidate jump and, when the next one continues the
        old timeline, a stamp outlier (one future fix never blinds a consumer); until 3 steps
        are known the forward limit is :attr:`FIX_INITIAL_JUMP_S`.

        Parameters
        ----------
        jump_limit : float
            ``max_stamp_jump``, s.
        resync_count : int
            Consecutive fixes that confirm a new timeline.

        Returns
        -------
        StreamCheck
            The rules.

        """
        return cls(math.inf, jump_limit=jump_limit, resync_count=resync_count, count_gaps=False,
                   initial_jump=cls.FIX_INITIAL_JUMP_S)

    # --- the period and the limits (rules 4 and 6) ----------------------------------------------
    @property
    def reference_ns(self) -> float:
        """Return the period of the rules, ns: the median step, else the stated one (inf: none)."""
        return self.period_ns if math.isfinite(self.period_ns) else self.nominal_ns

    @property
    def period_s(self) -> float:
        """Return the period of the stream from its stamps, s (inf: not known yet)."""
        return self.period_ns * 1e-9

    def _limits(self) -> None:
        ref = self.reference_ns
        if math.isfinite(ref):
            self.jump_ns = max(self.jump_limit_ns, 3.0 * ref)
            self.back_ns = self.jump_ns
        else:
            self.jump_ns = self.initial_jump_ns
            self.back_ns = self.jump_limit_ns
        self._gap_ns = self.GAP_FACTOR * self.period_ns if self.count_gaps else math.inf

    def _update_period(self) -> None:
        a = self._stamps
        n = len(a) - 1                            # steps in the window
        if n < self._min_steps:
            self._due = self._min_steps - max(n, 0)
            return
        m = min(self.PERIOD_SPAN, n // 2)
        a = list(a)
        spans = sorted([y - x for x, y in zip(a, a[m:])])     # integer ns: exact
        h = len(spans) // 2                       # the median of the mean steps over m steps
        mid = spans[h] if len(spans) % 2 else (spans[h - 1] + spans[h]) / 2
        self.period_ns = mid / m
        self._due = min(self.PERIOD_EVERY, max(n, self.PERIOD_MIN_STEPS))   # 16, 32, … 255
        self._limits()

    def _missing(self, step) -> int:
        return max(1, int(round(step / self.reference_ns)) - 1)

    def _record(self, stamp_ns) -> None:
        """Keep an accepted stamp that ends a step (rule 6's window)."""
        self._stamps.append(stamp_ns)
        self._due -= 1
        if not self._due:
            self._update_period()

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
        if self.gap_marks:
            self.gap_marks = []
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
                self.missing += self._missing(step)
                self.gap_marks.append(stamp_ns)
            self._stamps.append(stamp_ns)
            self._due -= 1
            if not self._due:
                self._update_period()
            self.last_ns = stamp_ns
            self.accepted += 1
            self.accepted_since += 1
            return [(stamp_ns, v)]
        if step == 0:
            self.duplicate += 1
            return []
        if step > self.jump_ns or -step > self.back_ns:
            self._held.append((stamp_ns, v))
            return []
        self.out_of_order += 1                 # step < 0 within the backward limit
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
                'dropouts': self.dropouts, 'accepted': self.accepted, 'received': self.received,
                'period': (tuple(self._stamps), self._due, self.period_ns)}

    def confirm(self) -> list:
        """
        Confirm the candidate timeline now, as ``resync_count`` messages would (rule 4).

        For a consumer that knows the jump from another stream: ``attitude_filter_node``
        confirms a clock step of its fixes at the first fix on the new timeline of the gyro,
        whose own step its ``resync_count`` increments have confirmed.

        Returns
        -------
        list of (int, tuple)
            The held messages, released in order (``resynced`` tells a clock step); empty when
            none is held.

        """
        if not self._held:
            return []
        self.resynced = self.returned = False
        self.retracted = 0
        return self._confirm_jump()

    def _confirm_jump(self):
        """
        Confirm a new timeline held by ``resync_count`` messages.

        ``resync_count`` held messages agree on a new timeline: a return from a burst, a
        dropout or a resynchronisation (rule 4), in that order of precedence.
        """
        held, self._held = self._held, []
        first = held[0][0]
        before = self._before_jump
        nominal = self.reference_ns if math.isfinite(self.reference_ns) else 0.0
        if before is not None and self.accepted - before['accepted'] <= self.max_burst:
            since = self.received - before['received']
            back = first - before['last_ns']
            off_timeline = not before['last_ns'] < self.last_ns < first   # not a dropout before
            if off_timeline and 0 < back <= self.jump_ns + 2.0 * nominal * since:
                return self._return_from_burst(held, before)
        self._before_jump = self._snapshot()
        step = first - self.last_ns
        self.last_jump_s = step * 1e-9
        if math.isfinite(self.reference_ns) and 0 < step <= self.max_dropout_ns:
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
        stamps, self._due, self.period_ns = before['period']
        self._stamps = deque(stamps, maxlen=self.PERIOD_WINDOW)
        self._limits()
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
                self.missing += self._missing(step)
                self.gap_marks.append(stamp_ns)
            self._record(stamp_ns)
        else:                                  # a new time base: its own window of stamps
            self._stamps.clear()
            self._stamps.append(stamp_ns)
            self._due = self._min_steps if self.period_ns == math.inf else self._due
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
        # the flags offer() clears for every message (the burst flags, where the rules have them)
        self.resynced = False
        if hasattr(self, 'retracted'):
            self.returned, self.retracted = False, 0
        self.gap_marks = []
        k = self._rule6_many(st[:k], steps[:k])
        if k:
            self.received += k
            self.accepted += k
            self.accepted_since += k
            self.last_ns = int(st[k - 1])
        return k

    def _rule6_many(self, st, steps) -> int:
        """
        Apply rule 6 to accepted steps at once, as :meth:`offer` applies it one by one.

        In stretches between the period's updates (the period and the limits fixed in each),
        so the periods, the limits and the counters are those of the message-by-message path.
        Returns how many of the steps pass (a period update may shorten the forward limit below
        a later step: that message is for :meth:`offer`).
        """
        n = len(steps)
        i = 0
        while i < n:
            m = min(n - i, self._due)
            part = steps[i:i + m]
            over = part > self.jump_ns
            if over.any():
                n = i + int(np.argmax(over))
                continue
            gap = part > self._gap_ns
            if gap.any():
                for j in np.flatnonzero(gap).tolist():
                    self._count_gap(int(part[j]), int(st[i + j]))
            self._stamps.extend(st[i:i + m].tolist())
            self._due -= m
            if not self._due:
                self._update_period()
            i += m
        return n

    def _count_gap(self, step: int, stamp_ns: int) -> None:
        self.gaps += 1
        self.missing += self._missing(step)
        self.gap_marks.append(stamp_ns)

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
                f'{prefix}_stamp_burst_messages': self.burst_messages,
                f'{prefix}_period_s_from_stamps':
                    self.period_s if math.isfinite(self.period_ns) else 0.0}


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

    Arrays are taken at array speed: the regular stretches by :meth:`StreamCheck.offer_many`
    (the counters and the output those of offering every message in turn), each other message
    by :meth:`StreamCheck.offer`.

    Parameters
    ----------
    stamps_ns : iterable of int, or ndarray (n,) int64
        Stamps, ns, in bag order.
    values : iterable of sequence of float, or ndarray (n, 3)
        The vectors.
    check : StreamCheck
        The stream's rules and counters (updated).

    Returns
    -------
    stamps : list of int
        The accepted stamps, ns, in order.
    values : list
        The accepted vectors (rows of ``values`` when it is an array).
    gaps : list of (int, int)
        Intervals (a, b), ns, that no increment pair may span: gaps (rule 6, dropouts and
        returns from a burst included) and confirmed resynchronisations
        (last stamp before, first after; b < a for a backward jump).

    """
    run = _Validation(check)
    if isinstance(values, np.ndarray) and values.ndim == 2 and values.shape[1] == 3:
        st = np.asarray(stamps_ns, dtype=np.int64).reshape(-1)
        i, n, width = 0, len(st), 64
        while i < n:
            before = check.last_ns
            k = check.offer_many(st[i:i + width], values[i:i + width])
            if k:
                run.many(st[i:i + k], values[i:i + k], before)
                full = k == min(width, n - i)
                i += k
                width = min(2 * width, 1 << 16) if full else 64
                continue
            width = 64
            run.one(int(st[i]), values[i])
            i += 1
    else:
        for ns, v in zip(stamps_ns, values):
            run.one(int(ns), v)
    check.segment_starts = run.starts
    return run.out_t, run.out_v, run.gaps


class _Validation:
    """The output of :func:`validate` as messages are offered (one by one, or many at once)."""

    def __init__(self, check: StreamCheck):
        self.check = check
        self.out_t: list = []
        self.out_v: list = []
        self.gaps: list = []
        self.starts: list[int] = []
        self.marks: list[tuple[int, int, int]] = []    # (len(out_t), len(gaps), len(starts))

    def many(self, st: np.ndarray, v: np.ndarray, before: int | None) -> None:
        """
        Take messages :meth:`StreamCheck.offer_many` accepted (steps within the jump limit).

        ``before`` is the check's last stamp before them.
        """
        after_gap = self.check.gap_marks
        if after_gap:
            where = np.searchsorted(st, np.asarray(after_gap, dtype=np.int64))
            for j, s in zip(where.tolist(), after_gap):
                prev = int(st[j - 1]) if j > 0 else before
                if prev is not None:
                    self.gaps.append((prev, int(s)))
        self.out_t.extend(st.tolist())
        self.out_v.extend(v)

    def one(self, ns: int, v) -> None:
        """Offer one message and take what the check releases."""
        check, out_t, gaps, starts = self.check, self.out_t, self.gaps, self.starts
        prev = check.last_ns
        got = check.offer(ns, v)
        if not got:
            return
        if check.returned:
            n_out, n_gaps, n_starts = self.marks.pop() if self.marks else (
                len(out_t) - check.retracted, len(gaps), len(starts))
            del out_t[n_out:], self.out_v[n_out:], gaps[n_gaps:], starts[n_starts:]
            prev = out_t[-1] if out_t else None
        elif check.resynced or (prev is not None and got[0][0] - prev > check.jump_ns):
            self.marks = [(len(out_t), len(gaps), len(starts))]   # the state a return goes to
            if check.resynced and out_t:
                gaps.append((out_t[-1], got[0][0]))          # across the jump (either direction)
                starts.append(len(out_t))
                prev = None
        after_gap = check.gap_marks
        for s, val in got:
            if prev is not None and s in after_gap:          # rule 6, as the check judged it
                gaps.append((prev, s))
            out_t.append(s)
            self.out_v.append(val)
            prev = s


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


def gap_ends(stamps_ns, nominal_period: float = math.inf) -> set:
    """
    Return the stamps that follow a gap by rule 6, for stamps already validated.

    The same rule as :class:`StreamCheck` applies to a live stream (the period the median of the
    stamps' own steps, the stated one until 3 are known), for a consumer handed increments
    without the check that accepted them.

    Parameters
    ----------
    stamps_ns : sequence of int
        Strictly increasing stamps, ns (the first may be the last one already taken).
    nominal_period : float
        The stated period, s.

    Returns
    -------
    set of int
        The stamps whose step from the previous one is a gap.

    """
    st = np.asarray(stamps_ns, dtype=np.int64).reshape(-1)
    if len(st) < 2:
        return set()
    check = StreamCheck(nominal_period, jump_limit=math.inf)
    check.offer(int(st[0]), (0.0, 0.0, 0.0))
    marks: set = set()
    i = 1
    zeros = np.zeros((len(st), 3))
    while i < len(st):
        k = check.offer_many(st[i:], zeros[i:])
        marks.update(check.gap_marks)
        if not k:                                  # not increasing: judged one by one
            check.offer(int(st[i]), (0.0, 0.0, 0.0))
            marks.update(check.gap_marks)
            k = 1
        i += k
    return marks


def match_segments(tg, g_segs, tc, c_segs) -> list[tuple[int, int]]:
    """
    Pair each gyro time base with its reference time base, in order.

    As many of each (a clock reset of both streams, the usual case): the k-th with the k-th.
    Otherwise (one stream resynchronised alone) by overlapping stamp ranges, walking both lists
    forward.

    Parameters
    ----------
    tg, tc : ndarray
        Gyro and reference stamps (any unit, the same for both).
    g_segs, c_segs : list of (int, int)
        Index ranges of each stream's time bases (:func:`segments`).

    Returns
    -------
    list of (int, int)
        (gyro segment, reference segment) pairs.

    """
    if len(g_segs) == len(c_segs):
        return [(k, k) for k in range(len(g_segs))]
    out, i, j = [], 0, 0
    while i < len(g_segs) and j < len(c_segs):
        g_lo, g_hi = tg[g_segs[i][0]], tg[g_segs[i][1] - 1]
        c_lo, c_hi = tc[c_segs[j][0]], tc[c_segs[j][1] - 1]
        if g_hi >= c_lo and c_hi >= g_lo:
            out.append((i, j))
        if g_hi <= c_hi:                               # the segment that ends first is done
            i += 1
        if c_hi <= g_hi:
            j += 1
    return out
