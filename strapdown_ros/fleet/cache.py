"""
Results cached per recording by content hash: a rerun analyses only what is new or changed.

:func:`content_hash` is the SHA-256 of everything a result depends on: the bag's bytes (every
file of a bag directory, by relative name, in order), the model file's bytes (or "defaults"),
the fleet's options (:meth:`strapdown_ros.fleet.analysis.FleetOptions.key`) and
:data:`CACHE_VERSION` with the package version (a new analysis invalidates old results).
:class:`ResultCache` keeps one JSON file per hash under ``DIR/cache/``, written atomically.
Errors of the input or the analysis are cached (the same bytes fail the same way); a task the
cluster lost (a killed worker) is not.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from strapdown_ros import __version__
from strapdown_ros.files import atomic_write_text

__all__ = ['content_hash', 'ResultCache', 'CACHE_VERSION', 'CHUNK']

#: changes whenever the per-recording analysis changes what it returns
CACHE_VERSION = 1
#: bytes hashed at a time (the hash reads a bag in bounded memory)
CHUNK = 1 << 20


def _hash_file(h, path: Path) -> None:
    with open(path, 'rb') as fh:
        while True:
            block = fh.read(CHUNK)
            if not block:
                break
            h.update(block)


def content_hash(path: str, model: str | None, options_key: str) -> str:
    """
    Return the SHA-256 of a recording, its model file and the options, as hex.

    Parameters
    ----------
    path : str
        The bag: a directory (every regular file below it, by relative name) or a file.
    model : str or None
        The model file (None: the defaults).
    options_key : str
        The canonical options (:meth:`~strapdown_ros.fleet.analysis.FleetOptions.key`).

    Returns
    -------
    str
        64 hex digits.

    Raises
    ------
    OSError
        A file cannot be read (the recording is then an error row).

    """
    h = hashlib.sha256()
    h.update(f'strapdown_ros {__version__} fleet cache {CACHE_VERSION}\n'.encode())
    h.update(options_key.encode() + b'\n')
    if model:
        h.update(b'model\n')
        _hash_file(h, Path(model))
    else:
        h.update(b'model defaults\n')
    p = Path(path)
    files = sorted(f for f in p.rglob('*') if f.is_file()) if p.is_dir() else [p]
    if p.is_dir() and not files:
        raise OSError(f'{path}: an empty directory')
    for f in files:
        rel = f.relative_to(p).as_posix() if p.is_dir() else f.name
        h.update(f'\nfile {rel} {f.stat().st_size}\n'.encode())
        _hash_file(h, f)
    return h.hexdigest()


class ResultCache:
    """
    One JSON result per content hash, under ``DIR/cache``.

    Parameters
    ----------
    directory : str or Path
        The fleet's output directory.

    """

    def __init__(self, directory):
        self.dir = Path(directory) / 'cache'

    def get(self, key: str) -> dict | None:
        """
        Return the cached result of a hash, or None.

        Parameters
        ----------
        key : str
            The content hash.

        Returns
        -------
        dict or None
            The result; None when absent or unreadable (it is then analysed again).

        """
        p = self.dir / f'{key}.json'
        try:
            return json.loads(p.read_text(encoding='utf-8'))
        except (OSError, ValueError):
            return None

    def put(self, key: str, result: dict) -> None:
        """
        Store a result (atomically).

        Parameters
        ----------
        key : str
            The content hash.
        result : dict
            JSON-ready.

        """
        self.dir.mkdir(parents=True, exist_ok=True)
        atomic_write_text(self.dir / f'{key}.json',
                          json.dumps(result, allow_nan=True, default=float) + '\n')
