"""
Atomic file writes, all-or-nothing output sets and a write probe, shared by the tools.

A base module (no imports from other rooms), used by the offline tools through
:mod:`strapdown_ros.cli` and by the model writer (:func:`strapdown_ros.params.write_model`).
No ROS imports.

* **One file**: a write goes to a temporary file in the target's own directory and is moved
  over the target with ``os.replace`` (atomic on POSIX): a reader sees the old file or the new
  one, never a part, and a failure leaves the old file as it was.  Errors name the target,
  never the temporary file.
* **Several files** (:func:`all_or_nothing`): inside the block every write goes to its
  temporary only; when the block ends, all are renamed into place; a failure before (a full file
  system, an exception) leaves every target as it was, and a failed rename puts back the targets
  already replaced.  ``filter_bag`` (OUT, FIXES, --json) and ``discrepancy`` (--json,
  --write-model, --report) write this way.
* **The umask**: a file is created with mode ``0666 & ~umask`` (as ``open`` would), not the
  0600 of ``mkstemp``.
* **Temporaries**: ``.<name>.<8 characters><suffix>`` beside the target (``.part`` for a bag
  directory staged by :func:`stage_directory`); a name too long for the file system is cut and
  completed by a hash.  Each is locked (``flock``) by its writer while it exists;
  :func:`remove_stale` removes those of a target that no live writer holds (a run killed with
  ``kill -9``), and :func:`strapdown_ros.cli.check_outputs` calls it for every output at start.
"""
from __future__ import annotations

from contextlib import contextmanager
import contextvars
import errno
import fcntl
import hashlib
import os
from pathlib import Path
import re
import shutil
import tempfile
import time

__all__ = ['atomic_write_text', 'atomic_write_bytes', 'atomic_savefig', 'stage_directory',
           'commit_directory', 'discard_directory', 'probe_writable', 'all_or_nothing',
           'remove_stale', 'temporary_prefix', 'file_mode', 'name_error', 'lock_file',
           'STALE_AGE_S']

#: an unlocked temporary younger than this, s, may belong to a writer that has not locked it yet
STALE_AGE_S = 2.0
#: the file-name limit assumed where the file system does not say, bytes
NAME_MAX = 255
#: the longest suffix a temporary gets (mkstemp's 8 characters and e.g. ``.tmp``/``.part``)
_TEMP_EXTRA = 8 + 8
_LOCK = '.lock'                 # the lock file inside a staged directory's holder
_held_locks: dict = {}          # staged holder → its open, locked lock file descriptor
_TX = contextvars.ContextVar('strapdown_ros_all_or_nothing', default=None)


def _umask() -> int:
    try:
        with open('/proc/self/status', encoding='ascii') as fh:
            for line in fh:
                if line.startswith('Umask:'):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    old = os.umask(0o022)       # (not thread-safe; only where /proc says nothing)
    os.umask(old)
    return old


def file_mode() -> int:
    """Return the mode a new file gets under the current umask (``0666 & ~umask``)."""
    return 0o666 & ~_umask()


def _name_max(directory) -> int:
    try:
        return int(os.pathconf(directory, 'PC_NAME_MAX'))
    except (OSError, ValueError):
        return NAME_MAX


def name_error(path) -> str | None:
    """
    Return why ``path``'s file name cannot exist on its file system, or None.

    Parameters
    ----------
    path : str or os.PathLike
        A file or directory path.

    Returns
    -------
    str or None
        E.g. ``the file name is 262 bytes, longer than the file system allows (255)``.

    """
    p = Path(path)
    n = len(os.fsencode(p.name))
    limit = _name_max(_directory(p)) if _directory(p).is_dir() else NAME_MAX
    if n > limit:
        return f'the file name is {n} bytes, longer than the file system allows ({limit})'
    return None


def temporary_prefix(name: str) -> str:
    """
    Return the prefix of the temporaries of a target named ``name``: ``.<name>.``.

    Cut and completed by a hash of ``name`` when the temporary would not fit the file-name
    limit (a target of 250 bytes still gets its temporary).

    Parameters
    ----------
    name : str
        The target's file name.

    Returns
    -------
    str
        The prefix.

    """
    if len(os.fsencode(name)) + 2 + _TEMP_EXTRA <= NAME_MAX:
        return f'.{name}.'
    digest = hashlib.sha256(os.fsencode(name)).hexdigest()[:16]
    return f'.{os.fsdecode(os.fsencode(name)[:100])}~{digest}.'


def lock_file(fd: int) -> bool:
    """
    Lock an open temporary for its writer (released when its last descriptor closes).

    Parameters
    ----------
    fd : int
        An open file descriptor.

    Returns
    -------
    bool
        True when locked (a file system without ``flock`` gives False).

    """
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except OSError:
        return False


def _directory(path) -> Path:
    d = Path(path).parent
    return d if str(d) else Path('.')


@contextmanager
def _replacing(path, suffix: str):
    """
    Give a temporary file beside ``path`` that replaces it when the block ends.

    A temporary file beside ``path`` (same directory, ``suffix``, the umask's mode, locked) for
    the caller to fill; moved over ``path`` when the block ends (inside :func:`all_or_nothing`:
    when that block ends), removed if it fails.  Errors name ``path``.
    """
    fd, tmp, lock = None, None, None
    try:
        fd, tmp = tempfile.mkstemp(dir=_directory(path), prefix=temporary_prefix(Path(path).name),
                                   suffix=suffix)
        os.fchmod(fd, file_mode())
        lock = os.open(tmp, os.O_RDONLY)           # held until the rename: not stale
        lock_file(lock)
        yield fd, tmp
        tx = _TX.get()
        if tx is None:
            os.replace(tmp, path)
        else:
            tx.add(tmp, path, lock)
            lock = None
        tmp = None
    except OSError as exc:
        raise OSError(exc.errno, f'cannot write {path}: {exc.strerror or exc}') from None
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass
        if lock is not None:
            os.close(lock)


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
    atomic_write_bytes(path, text if isinstance(text, bytes) else text.encode('utf-8'))


def atomic_write_bytes(path, data: bytes) -> None:
    """
    Write ``data`` to ``path`` atomically, as :func:`atomic_write_text` writes text.

    Parameters
    ----------
    path : str or os.PathLike
        The target file; its directory must exist.
    data : bytes
        The whole content (a Parquet table, ...).

    Raises
    ------
    OSError
        The write failed; the message names ``path`` and the target is unchanged.

    """
    with _replacing(path, '.tmp') as (fd, _):
        with os.fdopen(fd, 'wb') as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())


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
    holder = tempfile.mkdtemp(dir=_directory(p), prefix=temporary_prefix(p.name), suffix='.part')
    fd = os.open(os.path.join(holder, _LOCK), os.O_RDWR | os.O_CREAT, 0o600)
    lock_file(fd)                                 # held by this writer until commit or discard
    _held_locks[os.path.abspath(holder)] = fd
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
    _release(staged.parent)
    shutil.rmtree(staged.parent, ignore_errors=True)


def _release(holder) -> None:
    fd = _held_locks.pop(os.path.abspath(holder), None)
    if fd is not None:
        os.close(fd)


def discard_directory(staged) -> None:
    """
    Remove a staged directory (a failed or interrupted run); the target is untouched.

    Parameters
    ----------
    staged : str or os.PathLike
        A path from :func:`stage_directory`.

    """
    _release(Path(staged).parent)
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


# ------------------------------------------------------------------ stale temporaries
def _held(path) -> bool | None:
    """Tell whether a live process holds the lock of ``path`` (None: it cannot be opened)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        return False
    except OSError as exc:
        return exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES)
    finally:
        os.close(fd)


def _young(entry: Path) -> bool:
    try:
        return time.time() - entry.lstat().st_mtime < STALE_AGE_S
    except OSError:
        return False


def _is_live(entry: Path) -> bool:
    """
    Tell whether a writer still owns a temporary.

    A staged directory's lock file, or a temporary file itself, held by a live process: yes; not
    held: no (its writer died: ``kill -9`` releases the lock), except that a temporary younger
    than :data:`STALE_AGE_S` without a lock file, or whose lock is free, may be a writer between
    creating it and locking it.
    """
    if entry.is_dir() and not entry.is_symlink():
        held = _held(entry / _LOCK)
        return _young(entry) if held is None else held
    held = _held(entry)
    return bool(held) or _young(entry)


def remove_stale(path) -> list[str]:
    """
    Remove the temporaries of ``path`` that earlier runs left (killed before they renamed).

    A temporary is ``<prefix><8 characters><suffix>`` beside ``path`` (:func:`temporary_prefix`;
    suffix ``.tmp``, ``.part``, ``.old`` or the target's own), or ``<name>.part`` (the CSV of
    ``sins_bag``), and no live writer holds its lock.

    Parameters
    ----------
    path : str or os.PathLike
        A target file or directory.

    Returns
    -------
    list of str
        The temporaries removed.

    """
    p = Path(path)
    d = _directory(p)
    try:
        entries = list(d.iterdir())
    except OSError:
        return []
    suffixes = {'.tmp', '.part', '.old'} | ({p.suffix} if p.suffix else set())
    pattern = re.compile(re.escape(temporary_prefix(p.name)) + r'[A-Za-z0-9_]{8}('
                         + '|'.join(re.escape(x) for x in sorted(suffixes)) + r')$')
    removed = []
    for e in entries:
        if not (pattern.match(e.name) or e.name == p.name + '.part'):
            continue
        if _is_live(e):
            continue
        try:
            if e.is_dir() and not e.is_symlink():
                shutil.rmtree(e)
            else:
                e.unlink()
            removed.append(str(e))
        except OSError:
            pass
    return removed


# ------------------------------------------------------------------ several outputs
class _Transaction:
    """The temporaries of an :func:`all_or_nothing` block, renamed together at its end."""

    def __init__(self):
        self.items: dict = {}       # target → (temporary, lock fd)

    def add(self, tmp, path, lock) -> None:
        old = self.items.pop(str(path), None)
        if old is not None:          # written twice: the last one counts
            _unlink(old[0])
            os.close(old[1])
        self.items[str(path)] = (tmp, lock)

    def discard(self) -> None:
        for tmp, lock in self.items.values():
            _unlink(tmp)
            os.close(lock)
        self.items = {}

    def commit(self) -> None:
        done = []                    # (target, backup or None, existed)
        try:
            for path, (tmp, _) in self.items.items():
                existed = os.path.lexists(path)
                backup = _backup(path) if existed else None
                os.replace(tmp, path)
                done.append((path, backup, existed))
        except OSError as exc:
            for target, backup, existed in reversed(done):      # put the old ones back
                try:
                    if backup is not None:
                        os.replace(backup, target)
                    elif not existed:
                        os.unlink(target)
                except OSError:
                    pass
            self.discard()
            raise OSError(exc.errno, f'cannot write {path}: {exc.strerror or exc}; no output '
                          'was changed') from None
        for _, backup, _ in done:
            if backup is not None:
                _unlink(backup)
        for _, lock in self.items.values():
            os.close(lock)
        self.items = {}


def _unlink(path) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


def _backup(path) -> str | None:
    """Hard-link the current target beside it (None where links are not possible)."""
    if os.path.islink(path) or not os.path.isfile(path):
        return None
    d = _directory(path)
    for _ in range(16):
        name = d / (temporary_prefix(Path(path).name)
                    + os.urandom(6).hex()[:8] + '.old')
        try:
            os.link(path, name)
            return str(name)
        except FileExistsError:
            continue
        except OSError:
            return None
    return None


@contextmanager
def all_or_nothing():
    """
    Write several outputs all or nothing.

    Inside the block :func:`atomic_write_text` and :func:`atomic_savefig` (and so every writer
    of :mod:`strapdown_ros.cli` and the model writer) write their temporaries only; at its end
    all are renamed into place.  An exception in the block removes them and leaves every target
    as it was; a rename that fails puts back the targets already replaced (:class:`OSError`
    naming the target).

    Yields
    ------
    object
        The set of staged outputs (no method of it is needed).

    """
    tx = _Transaction()
    token = _TX.set(tx)
    try:
        yield tx
    except BaseException:
        tx.discard()
        raise
    else:
        tx.commit()
    finally:
        _TX.reset(token)
