"""
Text out of the core: bounded echoes and plain JSON values.

A base module (no imports from other rooms): every string a node or tool echoes (a frame id,
a topic name, a reason read from the input) goes through :func:`bounded`, so that hostile or
broken input (a 2 MB header.frame_id) can neither flood a log nor cost time in formatting;
every JSON result goes through :func:`json_clean`.  No ROS imports.
"""
from __future__ import annotations

import math

__all__ = ['bounded', 'ECHO_LIMIT', 'json_clean']

#: default number of characters of an echoed input string
ECHO_LIMIT = 64


def bounded(text, limit: int = ECHO_LIMIT) -> str:
    """
    Cut ``text`` to at most ``limit`` characters, marking the cut.

    ``text`` (made a str) cut to at most ``limit`` characters, the cut marked by an ellipsis
    and the original length.

    Parameters
    ----------
    text : object
        The string to echo (anything else is converted with ``str``).
    limit : int
        Maximum number of characters kept from ``text`` (≥ 1).

    Returns
    -------
    str
        ``text`` itself when it is short enough; otherwise its first ``limit`` characters,
        ``…`` and ``(N chars)``, so the result is at most ``limit`` + 20 characters long.

    """
    s = text if isinstance(text, str) else str(text)
    limit = max(1, int(limit))
    if len(s) <= limit:
        return s
    return f'{s[:limit]}…({len(s)} chars)'


def json_clean(v):
    """
    Plain JSON values: numpy scalars and arrays to Python, non-finite floats to None.

    Parameters
    ----------
    v : object
        Nested dicts, lists, tuples, numpy arrays and scalars.

    Returns
    -------
    object
        The same structure in Python types that strict JSON (no NaN) can write.

    """
    if isinstance(v, dict):
        return {k: json_clean(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [json_clean(x) for x in v]
    if hasattr(v, 'tolist') and hasattr(v, 'ndim'):          # numpy array or scalar
        return json_clean(v.tolist())
    if isinstance(v, bool):
        return v
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    return v
