"""Atomic file writes and a write probe, shared by the offline tools (tools/paths.py) and the
model writer (config.write_model).  No ROS imports.

A write goes to a temporary file in the target's own directory and is moved over the target with
``os.replace`` (atomic on POSIX): a reader sees the old file or the new one, never a part, and a
failure leaves the old file as it was.  Errors name the target, never the temporary file.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

__all__ = ["atomic_write_text", "probe_writable"]


def _directory(path) -> Path:
    d = Path(path).parent
    return d if str(d) else Path(".")


def atomic_write_text(path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically.

    Parameters
    ----------
    path : str or os.PathLike
        The target file; its directory must exist.
    text : str
        The whole content.

    Raises
    ------
    OSError
        The write failed; the message names ``path`` and the target is unchanged.
    """
    d = _directory(path)
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(dir=d, prefix=f".{Path(path).name}.", suffix=".tmp")
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
        tmp = None
    except OSError as exc:
        raise OSError(exc.errno, f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass


def probe_writable(directory) -> str | None:
    """Try what a write into ``directory`` does: create and remove a temporary file there.
    Returns None when it works, else the reason (``os.access`` is not enough: as root it says
    yes for /proc, where creating a file fails).

    Parameters
    ----------
    directory : str or os.PathLike
        An existing directory.
    """
    try:
        fd, tmp = tempfile.mkstemp(dir=directory, prefix=".write-probe.", suffix=".tmp")
    except OSError as exc:
        return exc.strerror or str(exc)
    os.close(fd)
    try:
        os.unlink(tmp)
    except OSError as exc:
        return f"a probe file could not be removed ({exc.strerror or exc})"
    return None
