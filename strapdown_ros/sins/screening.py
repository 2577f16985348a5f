"""
Screening of a whole recorded stream by the input rules, vectorised where it is regular.

:func:`screen_stream` gives the messages and counters of offering every message in turn to a
:class:`~strapdown_ros.streams.checks.StreamCheck`; ``SinsSystem.screen`` and ``sins_bag`` use
it to read a recording at array speed.  No ROS imports.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.streams.checks import StreamCheck


def screen_stream(check: StreamCheck, stamps_ns: np.ndarray, values: np.ndarray,
                  gap_marks: list | None = None) -> list:
    """
    Run a whole recorded stream through ``check`` in order.

    A whole recorded stream through ``check`` in order: :meth:`StreamCheck.offer_many` over the
    regular stretches, :meth:`StreamCheck.offer` for each message that is not (so the counters
    and the accepted messages are those of offering every message in turn).

    Parameters
    ----------
    check : StreamCheck
        The stream's rules and counters (updated).
    stamps_ns : ndarray (n,) int64
        Stamps, ns, in bag order.
    values : ndarray (n, 3)
        The vectors.
    gap_marks : list, optional
        Filled with the accepted stamps that follow a gap (rule 6 of the check).

    Returns
    -------
    list of (stamps_ns (m,) int64, values (m, 3))
        The accepted messages per time base: a new element starts at each stamp
        resynchronisation (``check.resynced``), so each element's stamps strictly increase.

    """
    segments: list = []
    parts_t: list = []
    parts_v: list = []
    i, n, width = 0, len(stamps_ns), 64
    while i < n:
        k = check.offer_many(stamps_ns[i:i + width], values[i:i + width])
        if gap_marks is not None and check.gap_marks:
            gap_marks.extend(check.gap_marks)
        if k:
            full = k == min(width, n - i)
            parts_t.append(stamps_ns[i:i + k])
            parts_v.append(values[i:i + k])
            i += k
            width = min(2 * width, 1 << 16) if full else 64
            continue
        width = 64
        v = values[i]
        got = check.offer(int(stamps_ns[i]), (float(v[0]), float(v[1]), float(v[2])))
        if gap_marks is not None and check.gap_marks:
            gap_marks.extend(check.gap_marks)
        if got and check.resynced and parts_t:
            segments.append((np.concatenate(parts_t), np.concatenate(parts_v)))
            parts_t, parts_v = [], []
        if got:
            parts_t.append(np.array([g[0] for g in got], dtype=np.int64))
            parts_v.append(np.array([g[1] for g in got], dtype=float).reshape(-1, 3))
        i += 1
    if parts_t or not segments:
        segments.append((np.concatenate(parts_t) if parts_t else np.zeros(0, np.int64),
                         np.concatenate(parts_v) if parts_v else np.zeros((0, 3))))
    return segments
