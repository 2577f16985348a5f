"""
The SINS core with the whole-recording input of ``sins_bag``: :class:`SinsSystem`.

:class:`SinsSystem` is :class:`~strapdown_ros.sins.core.SinsCore` (the processing of
``sins_node``, message by message) plus the input of a whole recording at array speed:
:meth:`SinsSystem.screen` / :meth:`SinsSystem.screen_imu` apply the node's input rules to
whole streams, :meth:`SinsSystem.feed` runs them through the core in large blocks.  The
numbers equal the node's on the same messages.  No ROS imports.
"""
from __future__ import annotations

import copy

import numpy as np

from strapdown_ros.sins.core import FEED_ACCEL_BLOCK, FEED_BLOCK, MAX_BATCH, SinsCore
from strapdown_ros.sins.screening import screen_stream
from strapdown_ros.streams.checks import StreamCheck
from strapdown_ros.streams.rate_increments import increments_from_rates


class SinsSystem(SinsCore):
    """
    The processing of ``sins_node``, and the input of a whole recording (``sins_bag``).

    The constructor is :class:`~strapdown_ros.sins.core.SinsCore`'s.
    """

    def _foreign_frames(self, frame_index, frame_names, n: int):
        """
        Mark the records whose frame is not the body frame.

        (mask of the n records whose frame is not the body frame, the first such frame or
        None) from per-record indices into ``frame_names`` (None: every record is ours).
        """
        if frame_index is None or not n:
            return np.zeros(n, bool), None
        codes = np.asarray(frame_index, dtype=np.int64)
        foreign = np.array([name not in self.own_frames for name in frame_names], dtype=bool)
        mask = foreign[codes] if len(foreign) else np.zeros(n, bool)
        first = frame_names[int(codes[np.argmax(mask)])] if mask.any() else None
        return mask, first

    def screen(self, stream: str, stamps_ns, values, frame_index=None, frame_names=()):
        """
        Apply the input rules to a whole recorded stream in bag order.

        The input rules of :meth:`offer_gyro` / :meth:`offer_accel` applied to a whole recorded
        stream in bag order, vectorised where the stream is regular.

        Parameters
        ----------
        stream : {'gyro', 'accel'}
            Δθ (rad) or Δv (m/s).
        stamps_ns : array_like (n,) int
            Header stamps, ns, in bag order.
        values : array_like (n, 3)
            The increments, body axes.
        frame_index : array_like (n,) int, optional
            Index of each message's header.frame_id in ``frame_names`` (None: all unspecified).
        frame_names : sequence of str
            The distinct frame ids.

        Returns
        -------
        (stamps_ns (m,) int64, values (m, 3)) or None
            The accepted messages, exactly those :meth:`offer_gyro` / :meth:`offer_accel` would
            accept one by one, with the same counters (frame mismatches, drops, gaps).  None when
            the stream's time base restarts (a stamp resynchronisation): nothing is changed
            then, and the stream must go through the one-message methods.

        """
        check = copy.deepcopy(self.gyro_check if stream == 'gyro' else self.accel_check)
        st = np.asarray(stamps_ns, dtype=np.int64).reshape(-1)
        v = np.asarray(values, dtype=float).reshape(-1, 3)
        mask, first = self._foreign_frames(frame_index, frame_names, len(st))
        wrong = int(mask.sum())
        if wrong and self.reject_frames:
            st, v = st[~mask], v[~mask]
        segments = screen_stream(check, st, v)
        if len(segments) > 1:
            return None
        if stream == 'gyro':
            self.gyro_check = check
        else:
            self.accel_check = check
        if wrong:
            self.frame_mismatch[stream] += wrong
            self.emit('warn', lambda: self.frame_text(stream, first, wrong), throttle=10.0,
                      key='frame_' + stream)
        return segments[0]

    def screen_imu(self, stamps_ns, angular_velocity, linear_acceleration=None, frame_index=None,
                   frame_names=(), rule: str = 'trapezoid'):
        """
        Make the sensor_msgs/Imu rate samples of a whole recording into Δθ and Δv.

        As ``gyro_input: imu`` makes them: the frame rule (counted under ``gyro``), each rate
        stream validated by a :class:`~strapdown_ros.streams.checks.StreamCheck` (per-axis range
        ``gyro_max_rate`` rad/s or ``accel_max`` m/s², period 1 / ``gyro_rate``), then
        :func:`strapdown_ros.streams.rate_increments.increments_from_rates` with ``rule`` and a
        longest step of 1.5 periods, restarted at each stamp resynchronisation.  The checks are
        kept in :attr:`rate_checks`.

        Parameters
        ----------
        stamps_ns : array_like (n,) int
            Header stamps, ns, bag order.
        angular_velocity : array_like (n, 3)
            rad/s, body axes.
        linear_acceleration : array_like (n, 3), optional
            m/s², body axes; a row of NaN where the message has none (covariance[0] = −1).
        frame_index : array_like (n,) int, optional
            Index of each message's header.frame_id in ``frame_names``, as :meth:`screen`.
        frame_names : sequence of str
            The distinct frame ids.
        rule : {'trapezoid', 'mean'}
            :data:`strapdown_ros.streams.rate_increments.RATE_RULES`.

        Returns
        -------
        gyro : (stamps_ns (m,) int64, Δθ (m, 3))
        accel : (stamps_ns (k,) int64, Δv (k, 3)) or None
            Increments stamped at the end of their intervals, for :meth:`screen`.

        """
        st = np.asarray(stamps_ns, dtype=np.int64).reshape(-1)
        w = np.asarray(angular_velocity, dtype=float).reshape(-1, 3)
        f = None if linear_acceleration is None else \
            np.asarray(linear_acceleration, dtype=float).reshape(-1, 3)
        mask, first = self._foreign_frames(frame_index, frame_names, len(st))
        wrong = int(mask.sum())
        if wrong:
            self.frame_mismatch['gyro'] += wrong
            self.emit('warn', lambda: self.frame_text('gyro', first, wrong), throttle=10.0,
                      key='frame_gyro')
            if self.reject_frames:
                keep = ~mask
                st, w, f = st[keep], w[keep], (None if f is None else f[keep])
        m, s = self.model, self.settings
        period = m.gyro_period
        jump, resync = float(s.max_stamp_jump), int(s.resync_count)
        out = []
        for name, values, max_rate in (('gyro', w, m.gyro_max_rate),
                                       ('accel', f, m.accel_max)):
            if values is None:
                out.append(None)
                continue
            if name == 'accel':                   # messages without acceleration: not offered
                has = ~np.all(np.isnan(values), axis=1)
                s_n, values = st[has], values[has]
                if not len(s_n):
                    out.append(None)
                    continue
            else:
                s_n = st
            check = StreamCheck(period, max_norm=max_rate, jump_limit=jump, resync_count=resync)
            self.rate_checks[name] = check
            marks: list = []          # intervals the check calls gaps are not integrated
            segs = screen_stream(check, s_n, values, marks)
            pieces = [increments_from_rates(a, b, rule, breaks=marks) for a, b in segs]
            out.append((np.concatenate([x[0] for x in pieces]),
                        np.concatenate([x[1] for x in pieces])))
        return out[0], out[1]

    def feed(self, gyro, accel=None, block: int = FEED_BLOCK, accel_block: int = FEED_ACCEL_BLOCK):
        """
        Run screened streams through the system in blocks, and finish.

        Run screened streams (:meth:`screen`'s output) through the system in blocks, as the
        messages in stamp order (Δv first at equal stamps) would have run, and finish.

        Parameters
        ----------
        gyro : (stamps_ns (n,) int64, values (n, 3))
            Accepted Δθ, strictly increasing stamps.
        accel : (stamps_ns (k,) int64, values (k, 3)) or None
            Accepted Δv, strictly increasing stamps.
        block, accel_block : int
            At most this many Δθ / Δv per block (each block carries the Δv stamped up to its
            last Δθ, so no update waits for accelerometer data that the recording holds).  Before
            the navigation has started from a static alignment, blocks are the node's
            (``batch_period``), so the alignment ends where the node's does.

        Yields
        ------
        SinsOutput
            What each block produced; the last one is :meth:`finish`'s.  The numbers equal the
            node's on the same messages to round-off (the attitude to the bit).

        """
        g_ns, g_v = gyro
        a_ns, a_v = accel if accel is not None else (np.zeros(0, np.int64), np.zeros((0, 3)))
        firsts = [int(x[0]) for x in (a_ns, g_ns) if len(x)]
        if self.origin_ns is None and firsts:
            self.origin_ns = min(firsts)
        if len(a_ns):
            self.accel_seen = True
        gi = ai = 0
        while gi < len(g_ns):
            if self.nav is not None and self.nav.navigator is None:     # the node's blocks
                start = self.processed_until_ns if self.processed_until_ns is not None else \
                    int(g_ns[gi]) - self.gyro_period_ns
                end = int(np.searchsorted(g_ns, start + self.batch_span_ns - 1, side='left')) + 1
                end = max(gi + 1, min(end, gi + MAX_BATCH, len(g_ns)))
            else:
                end = min(gi + block, len(g_ns))
                a_end = ai + accel_block
                if a_end < len(a_ns) and a_ns[a_end - 1] < g_ns[end - 1]:
                    end = max(gi + 1, int(np.searchsorted(g_ns, a_ns[a_end - 1], side='right')))
            aj = int(np.searchsorted(a_ns, g_ns[end - 1], side='right')) if end < len(g_ns) \
                else len(a_ns)
            if aj > ai:
                self.accel_blocks.append(((a_ns[ai:aj] - self.origin_ns) * 1e-9, a_v[ai:aj]))
            self.gyro_blocks.append((g_ns[gi:end], g_v[gi:end]))
            gi, ai = end, aj
            yield self.process()
        if ai < len(a_ns):
            self.accel_blocks.append(((a_ns[ai:] - self.origin_ns) * 1e-9, a_v[ai:]))
            yield self.process()
        yield self.finish()
