"""
Argument checks shared by the offline tools, run before any work.

A base module (it imports only :mod:`strapdown_ros.files`): output paths are checked before
any work, so a typo costs a one-line error (exit 2), not minutes of computation followed by a
traceback.

:func:`check_outputs` is THE output rule of every tool that writes: no output may be an input
(resolved paths; a file inside an input bag directory counts as the input), outputs differ from
each other, an existing output needs ``--force``, every file name fits the file system, and the
target directory takes a real write (a probe file is created and removed there, before the
work); then the temporaries an earlier, killed run left beside the outputs are removed
(:func:`strapdown_ros.files.remove_stale`).  The writes themselves are atomic
(:func:`write_json`, :func:`write_text`: a temporary file in the same directory, then
``os.replace``, in the umask's mode), and a tool with several outputs writes them all or
nothing (:func:`all_or_nothing`).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys
from typing import Iterable, Sequence

from strapdown_ros.files import (all_or_nothing, atomic_savefig, atomic_write_text, name_error,
                                 probe_writable, remove_stale)
from strapdown_ros.text import bounded

__all__ = ['check_output_file', 'check_output_dir', 'check_outputs', 'OneLineParser', 'write_json',
           'write_text', 'write_figure', 'all_or_nothing', 'FILE', 'DIRECTORY', 'REPLACED']

#: kinds of output: a file; a directory files are written into (created if absent); a file or a
#: directory (a bag) that the tool replaces as a whole
FILE, DIRECTORY, REPLACED = 'file', 'directory', 'replaced'


class OneLineParser(argparse.ArgumentParser):
    """An argparse parser whose errors are one line on stderr and exit 2, no usage block."""

    def error(self, message):
        """
        Print ``prog: error: message`` on stderr and exit 2.

        Parameters
        ----------
        message : str
            The error, one line.

        """
        print(f'{self.prog}: error: {message}', file=sys.stderr)
        sys.exit(2)


def _writable_dir(d: Path, what: str, path) -> None:
    d = d if str(d) else Path('.')
    if not d.exists():
        raise ValueError(f'{what} {path}: directory {d} does not exist')
    if not d.is_dir():
        raise ValueError(f'{what} {path}: {d} is not a directory')
    why = probe_writable(d)
    if why:
        raise ValueError(f'{what} {path}: directory {d} is not writable ({why})')


def check_output_file(path, what: str) -> None:
    """
    Check that ``path`` can be written as a file.

    Its directory exists and takes a write, and it is no directory.

    Parameters
    ----------
    path : str or os.PathLike or None
        The output file (None or '': not asked for, nothing checked).
    what : str
        How the message names it (the option, e.g. ``--json``).

    Raises
    ------
    ValueError
        One line naming ``what`` and ``path``.

    """
    if not path:
        return
    p = Path(path)
    if p.is_dir():
        raise ValueError(f'{what} {path} is a directory')
    _writable_dir(p.parent, what, path)


def check_output_dir(path, what: str) -> None:
    """
    Check that ``path`` is a directory that takes a write, or can be created in one.

    Parameters
    ----------
    path : str or os.PathLike or None
        The output directory (None or '': not asked for, nothing checked).
    what : str
        How the message names it (the option, e.g. ``--outdir``).

    Raises
    ------
    ValueError
        One line naming ``what`` and ``path``.

    """
    if not path:
        return
    p = Path(path)
    if p.exists():
        if not p.is_dir():
            raise ValueError(f'{what} {path} exists and is not a directory')
        _writable_dir(p, what, path)
    else:
        _writable_dir(p.parent, what, path)


def _inside(a: Path, b: Path) -> bool:
    """Tell whether ``a`` is ``b`` or below it (resolved paths)."""
    return a == b or b in a.parents


def check_outputs(outputs: Iterable[Sequence], inputs: Iterable[Sequence],
                  force: bool) -> list[str]:
    """
    Apply the output rule of every tool, before any work.

    Parameters
    ----------
    outputs : iterable of (option, path, kind) or (option, path, DIRECTORY, names)
        Each output: the option that names it (``--json``), its path (None or '' = not asked
        for) and its kind: :data:`FILE`, :data:`DIRECTORY` (files are written into it) or
        :data:`REPLACED` (a file or a bag directory replaced as a whole).  A DIRECTORY with
        ``names`` (the files the tool writes there, e.g. its PNG plots) needs --force only when
        one of those files exists (else: when the directory is not empty).
    inputs : iterable of (what, path)
        Every file or directory the tool reads (None or '' skipped).
    force : bool
        ``--force`` was given: an existing output may be replaced.

    Returns
    -------
    list of str
        The temporaries of earlier runs removed beside the outputs.

    Raises
    ------
    ValueError
        One line naming the option and the path that break the rule.

    """
    try:
        return _check_outputs(outputs, inputs, force)
    except OSError as exc:                  # e.g. a path the file system cannot hold
        raise ValueError(f'{bounded(exc.filename or "an output")}: '
                         f'{exc.strerror or exc}') from None


def _check_outputs(outputs, inputs, force: bool) -> list[str]:
    outputs = [tuple(o) for o in outputs]
    for o in outputs:
        if o[1]:
            why = name_error(o[1])
            if why:
                raise ValueError(f'{o[0]} {bounded(o[1])}: {why}')
    named = {str(o[1]): tuple(o[3]) for o in outputs if o[1] and len(o) > 3}
    outs = [(o[0], str(o[1]), o[2], Path(o[1]).resolve()) for o in outputs if o[1]]
    ins = [(w, str(p), Path(p).resolve()) for w, p in inputs if p]
    for opt, path, _, r in outs:
        for name in named.get(path, ()):
            for what, ipath, ir in ins:
                if r / name == ir:
                    raise ValueError(f'{opt} {path} would overwrite the input {what} {ipath}')
    for opt, path, kind, r in outs:
        for what, ipath, ir in ins:
            if _inside(r, ir) or (kind == REPLACED and ir in r.parents):
                raise ValueError(f'{opt} {path} would overwrite the input {what} {ipath}')
    for i, (opt, path, kind, r) in enumerate(outs):
        for opt2, path2, kind2, r2 in outs[i + 1:]:
            if r == r2 or (kind2 == REPLACED and r2 in r.parents) \
                    or (kind == REPLACED and r in r2.parents):
                raise ValueError(f'{opt} {path} and {opt2} {path2} are the same output')
    for opt, path, kind, r in outs:
        p = Path(path)
        exists = p.exists() or p.is_symlink()
        if kind == FILE:
            if p.is_dir():
                raise ValueError(f'{opt} {path} is a directory')
            if exists and not force:
                raise ValueError(f'{opt} {path} exists (use --force to overwrite)')
            _writable_dir(p.parent, opt, path)
        elif kind == DIRECTORY:
            if exists and not p.is_dir():
                raise ValueError(f'{opt} {path} exists and is not a directory')
            if path in named:
                there = [n for n in named[path] if exists and (p / n).exists()]
                if there and not force:
                    raise ValueError(f'{opt} {path}: {there[0]} exists '
                                     '(use --force to overwrite)')
            elif exists and any(p.iterdir()) and not force:
                raise ValueError(f'{opt} {path} exists and is not empty '
                                 '(use --force to write into it)')
            _writable_dir(p if exists else p.parent, opt, path)
        else:
            if exists and not force:
                raise ValueError(f'{opt} {path} exists (use --force to replace it)')
            _writable_dir(p.parent, opt, path)
    removed = []
    for opt, path, kind, r in outs:
        if kind == DIRECTORY:
            for name in named.get(path, ()):
                removed += remove_stale(Path(path) / name)
        else:
            removed += remove_stale(path)
    return removed


def write_text(path, text: str) -> None:
    """
    Write a text file atomically.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    text : str
        Its content, UTF-8.

    Raises
    ------
    OSError
        Naming ``path``.

    """
    atomic_write_text(path, text)


def write_json(path, data, indent: int = 1) -> None:
    """
    Write a JSON result file atomically (strict JSON: no NaN, newline-terminated).

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    data : object
        Plain JSON values (see :func:`strapdown_ros.text.json_clean`).
    indent : int
        Indentation of the JSON text.

    """
    atomic_write_text(path, json.dumps(data, indent=indent, allow_nan=False) + '\n')


def write_figure(fig, path, **kwargs) -> None:
    """
    Save a matplotlib figure atomically.

    A temporary file with the same extension in the same directory, then ``os.replace``.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : str or os.PathLike
        The image file; its extension gives the format.
    **kwargs
        Passed to ``savefig`` (``dpi``).

    """
    atomic_savefig(fig, path, **kwargs)
