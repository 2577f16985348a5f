"""
What a node reports: its log lines and its /diagnostics status.

:class:`NodeLog` is the one logging helper of the nodes (rclpy's logger is safe with any
sequence of levels and throttles only when each severity has its own call site);
:class:`Conditions` gathers the conditions of a node's status, worst first; every echoed text is
bounded to :data:`MAX_TEXT` characters.
"""
from __future__ import annotations

import time
from typing import Any

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

__all__ = ['MAX_TEXT', 'bounded', 'NodeLog', 'diagnostic_array', 'Conditions', 'OK', 'WARN',
           'ERROR']


# --- logging -----------------------------------------------------------------------------
#: longest text a node logs or puts in a diagnostic message, characters (echoed input is bounded)
MAX_TEXT = 400


def bounded(text: str, limit: int = MAX_TEXT) -> str:
    """
    Cut a text to a number of characters (an ellipsis marks the cut).

    Parameters
    ----------
    text : str
        The text (anything else is converted with ``str``).
    limit : int
        Most characters kept.

    Returns
    -------
    str
        The text, at most ``limit`` characters.

    """
    text = str(text)
    return text if len(text) <= limit else text[:limit - 1] + '…'


class NodeLog:
    """
    The one logging helper of the nodes: ``log(level, text, throttle=0.0, key=None)``.

    rclpy's logger keeps one context per call site (function, file, line) and raises
    ``ValueError('Logger severity cannot be changed between calls.')`` when one call site logs
    at another severity than before, and likewise when its throttle changes.  Every severity
    here has its own call site, and throttling is done here (``throttle`` wall seconds per
    ``key``, default the text), never through rclpy's filters, so any sequence of levels and
    throttles at one caller is safe.  Texts are bounded to :data:`MAX_TEXT` characters.

    Parameters
    ----------
    logger : rclpy.impl.rcutils_logger.RcutilsLogger
        The node's rclpy logger (``node.get_logger()``).

    """

    LEVELS = ('debug', 'info', 'warn', 'error')

    def __init__(self, logger):
        self._logger = logger
        self._clock = time.monotonic
        self._last: dict[str, float] = {}

    def __call__(self, level: str, text: str, throttle: float = 0.0,
                 key: str | None = None) -> bool:
        """
        Log ``text`` at ``level`` (debug, info, warn or error); returns False when throttled.

        Parameters
        ----------
        level : str
            ``debug``, ``info``, ``warn`` (or ``warning``) or ``error``.
        text : str
            The message (bounded to :data:`MAX_TEXT` characters).
        throttle : float
            Minimum wall seconds between two messages of the same ``key`` (0: every one).
        key : str, optional
            What the throttle counts (default: the text).

        Returns
        -------
        bool
            False when throttled.

        """
        if level == 'warning':
            level = 'warn'
        if level not in self.LEVELS:
            raise ValueError(f"unknown log level {level!r}; valid: {', '.join(self.LEVELS)}")
        if throttle > 0:
            k = key or text
            now = self._clock()
            if now - self._last.get(k, -float('inf')) < throttle:
                return False
            self._last[k] = now
        text = bounded(text)
        if level == 'error':                      # one call site per severity (see the class doc)
            self._logger.error(text)
        elif level == 'warn':
            self._logger.warning(text)
        elif level == 'info':
            self._logger.info(text)
        else:
            self._logger.debug(text)
        return True

    def error(self, text: str, throttle: float = 0.0, key: str | None = None) -> bool:
        """
        Log a message at level error, as :meth:`__call__` does.

        Parameters
        ----------
        text : str
            The message.
        throttle : float
            Minimum wall seconds between two messages of the same ``key`` (0: every one).
        key : str, optional
            What the throttle counts (default: the text).

        Returns
        -------
        bool
            False when throttled.

        """
        return self('error', text, throttle, key)

    def warn(self, text: str, throttle: float = 0.0, key: str | None = None) -> bool:
        """
        Log a message at level warn, as :meth:`__call__` does.

        Parameters
        ----------
        text : str
            The message.
        throttle : float
            Minimum wall seconds between two messages of the same ``key`` (0: every one).
        key : str, optional
            What the throttle counts (default: the text).

        Returns
        -------
        bool
            False when throttled.

        """
        return self('warn', text, throttle, key)

    def info(self, text: str, throttle: float = 0.0, key: str | None = None) -> bool:
        """
        Log a message at level info, as :meth:`__call__` does.

        Parameters
        ----------
        text : str
            The message.
        throttle : float
            Minimum wall seconds between two messages of the same ``key`` (0: every one).
        key : str, optional
            What the throttle counts (default: the text).

        Returns
        -------
        bool
            False when throttled.

        """
        return self('info', text, throttle, key)


# --- diagnostics -------------------------------------------------------------------------
def diagnostic_array(stamp: Time, name: str, hardware_id: str, level: int, message: str,
                     values: dict[str, Any]) -> DiagnosticArray:
    """
    Build a DiagnosticArray of one status.

    Parameters
    ----------
    stamp : builtin_interfaces.msg.Time
        Header stamp.
    name, hardware_id : str
        The status's name and hardware id.
    level : int or bytes
        :data:`OK`, :data:`WARN` or :data:`ERROR`.
    message : str
        The status message.
    values : dict
        Key → value; floats formatted with 6 significant digits.

    Returns
    -------
    diagnostic_msgs.msg.DiagnosticArray
        The message.

    """
    st = DiagnosticStatus(level=bytes([level]) if isinstance(level, int) else level, name=name,
                          message=message, hardware_id=hardware_id,
                          values=[KeyValue(key=str(k), value=_fmt(v)) for k, v in values.items()])
    arr = DiagnosticArray()
    arr.header.stamp = stamp
    arr.status = [st]
    return arr


def _fmt(v) -> str:
    if isinstance(v, float):
        return f'{v:.6g}'
    return str(v)


OK, WARN, ERROR = 0, 1, 2


class Conditions:
    """
    The current conditions of a node's /diagnostics status.

    The level is the worst of all of them, and the message lists every one, worst first (in the
    order added within a level), bounded to ``limit`` characters with the number of conditions cut
    off.  A lower-level condition never masks a higher one (an undecodable message does not hide a
    gyro gap).

    Parameters
    ----------
    limit : int
        Longest message, characters.

    """

    def __init__(self, limit: int = MAX_TEXT):
        self.limit = int(limit)
        self.items: list[tuple[int, str]] = []

    def add(self, level: int, text: str) -> None:
        """
        Add one condition.

        Parameters
        ----------
        level : int
            :data:`OK`, :data:`WARN` or :data:`ERROR`.
        text : str
            What it says.

        """
        self.items.append((int(level), str(text)))

    @property
    def level(self) -> int:
        """Worst level of all conditions (:data:`OK` when there are none)."""
        return max((lv for lv, _ in self.items), default=OK)

    def message(self, ok_text: str = 'ok') -> str:
        """
        Return the status message: every condition's text, worst first, joined by ``; ``.

        Parameters
        ----------
        ok_text : str
            The message when there is no condition.

        Returns
        -------
        str
            The message, bounded to ``limit`` characters with the number of conditions cut.

        """
        texts = [t for _, t in sorted(self.items, key=lambda it: -it[0])]
        if not texts:
            return bounded(ok_text, self.limit)
        out = texts[0]
        for k, t in enumerate(texts[1:], 1):
            more = f' (+{len(texts) - k} more)'
            if len(out) + 2 + len(t) + len(more) > self.limit:
                return bounded(out, self.limit - len(more)) + more
            out += '; ' + t
        return bounded(out, self.limit)
