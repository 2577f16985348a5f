"""Argument checks shared by the offline tools: output paths are checked before any work, so a
typo costs a one-line error (exit 2), not minutes of computation followed by a traceback."""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

__all__ = ["check_output_file", "check_output_dir", "OneLineParser", "write_json"]


class OneLineParser(argparse.ArgumentParser):
    """argparse whose errors are one line on stderr (``prog: error: ...``) and exit 2, no usage block."""

    def error(self, message):
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        sys.exit(2)


def _writable_dir(d: Path, what: str, path) -> None:
    d = d if str(d) else Path(".")
    if not d.exists():
        raise ValueError(f"{what} {path}: directory {d} does not exist")
    if not d.is_dir():
        raise ValueError(f"{what} {path}: {d} is not a directory")
    if not os.access(d, os.W_OK | os.X_OK):
        raise ValueError(f"{what} {path}: directory {d} is not writable")


def check_output_file(path, what: str) -> None:
    """``path`` can be written as a file: its directory exists and is writable, it is no directory."""
    if not path:
        return
    p = Path(path)
    if p.is_dir():
        raise ValueError(f"{what} {path} is a directory")
    if p.exists() and not os.access(p, os.W_OK):
        raise ValueError(f"{what} {path} is not writable")
    _writable_dir(p.parent, what, path)


def check_output_dir(path, what: str) -> None:
    """``path`` is a writable directory or can be created in a writable one."""
    if not path:
        return
    p = Path(path)
    if p.exists():
        if not p.is_dir():
            raise ValueError(f"{what} {path} exists and is not a directory")
        _writable_dir(p, what, path)
    else:
        _writable_dir(p.parent, what, path)


def write_json(path, data, indent: int = 1) -> None:
    """A JSON result file (strict JSON: no NaN), newline-terminated."""
    import json

    with open(path, "w", encoding="utf-8") as fh:
        json.dump(data, fh, indent=indent, allow_nan=False)
        fh.write("\n")
