"""
Atomic file writes and a write probe, shared by the tools and the model writer.

A base module (no imports from other rooms), used by the offline tools through
:mod:`strapdown_ros.cli` and by the model writer (:func:`strapdown_ros.params.write_model`).
No ROS imports.

A write goes to a temporary file in the target's own directory and is moved over the target with
``os.replace`` (atomic on POSIX): a reader sees the old file or the new one, never a part, and a
failure leaves the old file as it was.  Errors name the target, never the temporary file.
"""
from __future__ import annotations

from contextlib import contextmanager
import os
from pathlib import Path
import shutil
import tempfile

__all__ = ['atomic_write_text', 'atomic_write_bytes', 'atomic_savefig', 'stage_directory',
           'commit_directory', 'discard_directory', 'probe_writable']


def _directory(path) -> Path:
    d = Path(path).parent
    return d if str(d) else Path('.')


@contextmanager
def _replacing(path, suffix: str):
    """
    Give a temporary file beside ``path`` that replaces it when the block ends.

    A temporary file beside ``path`` (same directory, ``suffix``) for the caller to fill;
    moved over ``path`` when the block ends, removed if it fails.  Errors name ``path``.
    """
    fd, tmp = None, None
    try:
        fd, tmp = tempfile.mkstemp(dir=_directory(path), prefix=f'.{Path(path).name}.',
                                   suffix=suffix)
        yield fd, tmp
        os.replace(tmp, path)
        tmp = None
    except OSError as exc:
        raise OSError(exc.errno, f'cannot write {path}: {exc.strerror or exc}') from None
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass


def atomic_write_text(path, text: str) -> None:
    """
    Write ``text`` (UTF-8) to ``path`` atomically.

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
    data = text if isinstance(text, bytes) else text.encode('utf-8')
    with _replacing(path, '.tmp') as (fd, _):
        with os.fdopen(fd, 'wb') as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())


def atomic_write_bytes(path, data: bytes) -> None:
    """
    Write ``data`` to ``path`` atomically, as :func:`atomic_write_text` writes text.

    Parameters
    ----------
    path : str or os.PathLike
        The target file; its directory must exist.
    data : bytes
        The whole content (a Parquet table, ...).

    """
    atomic_write_text(path, data)


def atomic_savefig(fig, path, **kwargs) -> None:
    """
    Save a matplotlib figure atomically.

    ``fig.savefig(path, **kwargs)`` atomically: matplotlib writes a temporary file with the
    same extension (it picks the format from it) in the target's directory, then ``os.replace``.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : str or os.PathLike
        The target image (PNG, SVG, ...); its directory must exist.
    **kwargs
        Passed to ``savefig`` (``dpi``, ...).

    """
    with _replacing(path, Path(path).suffix) as (fd, tmp):
        os.close(fd)
        fig.savefig(tmp, **kwargs)


def stage_directory(path) -> Path:
    """
    Return where to write a directory output before it is complete.

    Where to write a directory output (a bag) before it is complete: ``path``'s name inside
    a new hidden temporary directory beside it (same file system, so the final move is a
    rename; the files inside keep the names they will have).  Not created itself.

    Parameters
    ----------
    path : str or os.PathLike
        The final directory.

    Returns
    -------
    pathlib.Path
        The staging path; hand it to :func:`commit_directory` or :func:`discard_directory`.

    """
    p = Path(path)
    holder = tempfile.mkdtemp(dir=_directory(p), prefix=f'.{p.name}.', suffix='.part')
    return Path(holder) / p.name


def commit_directory(staged, path) -> None:
    """
    Move the complete directory ``staged`` to ``path``.

    Move the complete directory ``staged`` (from :func:`stage_directory`) to ``path``.  An
    existing ``path`` (the caller checked --force) is moved aside first and removed only after
    the new one is in place; if the move fails, it is put back.

    Parameters
    ----------
    staged : pathlib.Path
        The complete directory.
    path : str or os.PathLike
        The target.

    """
    staged, p = Path(staged), Path(path)
    old = staged.parent / '.old'
    moved = False
    try:
        if p.is_symlink() or p.is_file():
            os.replace(p, old)
            moved = True
        elif p.exists():
            os.rename(p, old)
            moved = True
        os.rename(staged, p)
    except OSError as exc:
        if moved and not p.exists():
            os.rename(old, p)
        raise OSError(exc.errno, f'cannot write {path}: {exc.strerror or exc}') from None
    shutil.rmtree(staged.parent, ignore_errors=True)


def discard_directory(staged) -> None:
    """
    Remove a staged directory (a failed or interrupted run); the target is untouched.

    Parameters
    ----------
    staged : str or os.PathLike
        A path from :func:`stage_directory`.

    """
    shutil.rmtree(Path(staged).parent, ignore_errors=True)


def probe_writable(directory) -> str | None:
    """
    Try what a write into ``directory`` does.

    Try what a write into ``directory`` does: create and remove a temporary file there.
    Returns None when it works, else the reason (``os.access`` is not enough: as root it says
    yes for /proc, where creating a file fails).

    Parameters
    ----------
    directory : str or os.PathLike
        An existing directory.

    """
    try:
        fd, tmp = tempfile.mkstemp(dir=directory, prefix='.write-probe.', suffix='.tmp')
    except OSError as exc:
        return exc.strerror or str(exc)
    os.close(fd)
    try:
        os.unlink(tmp)
    except OSError as exc:
        return f'a probe file could not be removed ({exc.strerror or exc})'
    return None
