"""
The fleet's manifest: which unit recorded what, when, and with which sensor model.

A CSV file with the header ``unit,recording,start_time,model``: one row per recording; paths
relative to the manifest's folder (absolute ones as they are); ``start_time`` in ISO 8601
(``2024-05-01T12:00:00Z``; a time without a zone is UTC); ``model`` a ROS 2 parameter file
(empty: the defaults).  Or a folder laid out as::

    FOLDER/UNIT/START[_ANYTHING][.mcap|.db3]     one recording: a bag directory or file
    FOLDER/UNIT/model.yaml                        the unit's model (else FOLDER/model.yaml,
                                                  else the defaults)

where START is an ISO 8601 time in basic or extended form with ``-`` for ``:``
(``20240501T120000Z``, ``2024-05-01T12-00-00Z``); entries that do not match are skipped and
counted.  :func:`read_manifest` returns the entries sorted by unit and start time.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone
from pathlib import Path
import re

from strapdown_ros.text import bounded

__all__ = ['FleetEntry', 'read_manifest', 'parse_time', 'COLUMNS', 'MODEL_NAME',
           'FOLDER_PATTERN']

#: the manifest's columns
COLUMNS = ('unit', 'recording', 'start_time', 'model')
#: the model file of a unit (or of the whole folder) in the folder form
MODEL_NAME = 'model.yaml'
#: a recording's name in the folder form: START[_ANYTHING][.mcap|.db3]
FOLDER_PATTERN = re.compile(
    r'^(?P<start>\d{4}-?\d{2}-?\d{2}T\d{2}[-:]?\d{2}[-:]?\d{2}(?:\.\d+)?(?:Z|[+-]\d{2}-?\d{2})?)'
    r'(?:_[^/]*)?(?:\.mcap|\.db3)?$')
MAX_ROWS = 1_000_000


@dataclass(frozen=True)
class FleetEntry:
    """
    One recording of the fleet.

    Attributes
    ----------
    unit : str
        The unit's name.
    recording : str
        The recording as the manifest names it (relative path or folder name).
    path : str
        Its absolute path.
    start_time : datetime
        When it started (UTC, timezone-aware).
    model : str or None
        Absolute path of the unit's model file; None for the defaults.

    """

    unit: str
    recording: str
    path: str
    start_time: datetime
    model: str | None = None

    @property
    def start_iso(self) -> str:
        """Return the start time in ISO 8601 (UTC, ``Z``)."""
        return self.start_time.astimezone(timezone.utc).isoformat().replace('+00:00', 'Z')


def parse_time(text: str) -> datetime:
    """
    Read an ISO 8601 time (extended or basic form; ``-`` may stand for ``:`` in the time).

    Parameters
    ----------
    text : str
        E.g. ``2024-05-01T12:00:00Z``, ``20240501T120000Z``, ``2024-05-01T12-00-00+02:00``,
        ``2024-05-01`` (midnight UTC).

    Returns
    -------
    datetime
        Timezone-aware; a time without a zone is UTC.

    Raises
    ------
    ValueError
        Not such a time.

    """
    s = text.strip()
    if re.fullmatch(r'\d{4}-\d{2}-\d{2}', s):
        s += 'T00:00:00Z'                            # a date alone: its midnight, UTC
    m = re.fullmatch(r'(\d{4})-?(\d{2})-?(\d{2})[T ](\d{2})[-:]?(\d{2})(?:[-:]?(\d{2})(\.\d+)?)?'
                     r'(Z|[+-]\d{2}(?::?\d{2})?)?', s)
    if not m:
        raise ValueError(f'{bounded(s)!r} is not an ISO 8601 time (e.g. 2024-05-01T12:00:00Z)')
    y, mo, d, h, mi, sec, frac, zone = m.groups()
    try:
        t = datetime(int(y), int(mo), int(d), int(h), int(mi), int(sec or 0),
                     int(round(float(frac or 0) * 1e6)))
    except ValueError as exc:
        raise ValueError(f'{bounded(s)!r} is not a valid time: {exc}') from None
    if zone in (None, 'Z'):
        return t.replace(tzinfo=timezone.utc)
    sign = 1 if zone[0] == '+' else -1
    digits = zone[1:].replace(':', '')
    minutes = int(digits[:2]) * 60 + (int(digits[2:4]) if len(digits) > 2 else 0)
    return t.replace(tzinfo=timezone(sign * timedelta(minutes=minutes)))


def _csv_entries(path: Path) -> list[FleetEntry]:
    base = path.parent
    out = []
    with open(path, encoding='utf-8', newline='') as fh:
        reader = csv.reader(fh)
        header = [h.strip() for h in next(reader, [])]
        missing = [c for c in COLUMNS if c not in header]
        if missing:
            raise ValueError(f"manifest {path}: no column {', '.join(missing)} (the header must "
                             f"name {', '.join(COLUMNS)})")
        col = {c: header.index(c) for c in COLUMNS}
        for n, row in enumerate(reader, 2):
            if not any(x.strip() for x in row):
                continue
            if len(out) >= MAX_ROWS:
                raise ValueError(f'manifest {path}: more than {MAX_ROWS} rows')
            if len(row) < len(header):
                raise ValueError(f'manifest {path} line {n}: {len(row)} fields, '
                                 f'the header has {len(header)}')
            unit, rec, start, model = (row[col[c]].strip() for c in COLUMNS)
            if not unit or not rec:
                raise ValueError(f'manifest {path} line {n}: empty unit or recording')
            try:
                t = parse_time(start)
            except ValueError as exc:
                raise ValueError(f'manifest {path} line {n}: start_time {exc}') from None
            rp = Path(rec) if Path(rec).is_absolute() else base / rec
            mp = None
            if model:
                mp = Path(model) if Path(model).is_absolute() else base / model
                mp = str(mp.resolve())
            out.append(FleetEntry(unit, rec, str(rp.resolve()), t, mp))
    return out


def _folder_entries(folder: Path) -> tuple[list[FleetEntry], int]:
    out, skipped = [], 0
    top_model = folder / MODEL_NAME
    for unit_dir in sorted(p for p in folder.iterdir() if p.is_dir()):
        unit_model = unit_dir / MODEL_NAME
        model = unit_model if unit_model.is_file() else top_model if top_model.is_file() \
            else None
        for item in sorted(unit_dir.iterdir()):
            if item.name == MODEL_NAME or item.name.startswith('.'):
                continue
            m = FOLDER_PATTERN.match(item.name)
            if not m or not (item.is_dir() or item.suffix in ('.mcap', '.db3')):
                skipped += 1
                continue
            out.append(FleetEntry(unit_dir.name, f'{unit_dir.name}/{item.name}',
                                  str(item.resolve()), parse_time(m.group('start')),
                                  str(model.resolve()) if model else None))
    return out, skipped


def read_manifest(path) -> tuple[list[FleetEntry], int]:
    """
    Read a manifest (CSV) or a fleet folder.

    Parameters
    ----------
    path : str or Path
        The CSV file, or the folder (layout in the module's description).

    Returns
    -------
    entries : list of FleetEntry
        Sorted by unit, then start time.
    skipped : int
        Folder entries whose name does not match :data:`FOLDER_PATTERN` (0 for a CSV).

    Raises
    ------
    ValueError
        One line: no such file, a missing column, a bad time, a recording named twice.

    """
    p = Path(path)
    if p.is_dir():
        entries, skipped = _folder_entries(p)
    elif p.is_file():
        entries, skipped = _csv_entries(p), 0
    else:
        raise ValueError(f'manifest {path} does not exist')
    seen = {}
    for e in entries:
        if e.path in seen:
            raise ValueError(f'manifest {path}: the recording {bounded(e.recording)!r} is named '
                             f'twice (units {bounded(seen[e.path])!r} and {bounded(e.unit)!r})')
        seen[e.path] = e.unit
    entries.sort(key=lambda e: (e.unit, e.start_time, e.recording))
    return entries, skipped
