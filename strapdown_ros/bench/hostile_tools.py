"""
The offline tools on hostile input: run each in-process, read what it counted and estimated.

:func:`run_tool` runs one command's ``main`` on a bag (stdout and stderr captured, an escaped
exception caught as a traceback) and reads its JSON and outputs into an :class:`Outcome`;
:func:`problems` is the verdict of issue 27 for one hostile kind: no traceback and the clean
run's exit status, the message counted under its named reason (the one summary of what was
read and dropped, ``input.read``), and the estimates of the clean run within 1σ.  Used by the
fuzz test (``test/tools/test_hostile_tools.py``) and ``hostile_bench``.
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
import importlib
import io
import json
from pathlib import Path
import traceback

import numpy as np

from strapdown_ros.bench.hostile_input import BETA, Kind, LONG_FRAME_LENGTH
from strapdown_ros.text import bounded

__all__ = ['TOOLS', 'Outcome', 'run_tool', 'problems', 'counted', 'GYRO_ONLY_TOOLS']

#: the offline tools that read a recording (sins_bag: the gyro and accelerometer only)
TOOLS = ('calibrate_bag', 'filter_bag', 'calibrate_gyro_bag', 'discrepancy', 'nominal_model',
         'sins_bag')
#: tools without an attitude reference
GYRO_ONLY_TOOLS = ('sins_bag',)
#: the model of the recording: its boresight known (the filter takes it), a bias prior
_MODEL = ('/**:\n  ros__parameters:\n    gyro_bias_sigma: 1.0e-4\n    output_period: 1.0\n'
          f"    boresight: [{', '.join(repr(float(b)) for b in BETA)}]\n")


@dataclass
class Outcome:
    """
    What one surface (a tool or a node) did with one recording.

    Attributes
    ----------
    surface : str
        The tool or node.
    status : int or None
        Exit status (nodes: 0 when no exception escaped).
    traceback : str or None
        The exception that escaped, formatted; None when none did.
    stdout, stderr : str
        What it printed.
    read : dict
        What it counted: the ``input.read`` record of the tools, or the node's counters in the
        same shape (``gyro``/``reference`` → ``dropped`` {reason: n}, ``frames``).
    estimate, sigma : ndarray or None
        Its estimates and their 1σ (None: none, e.g. not observable).

    """

    surface: str
    status: int | None
    traceback: str | None
    stdout: str = ''
    stderr: str = ''
    read: dict = field(default_factory=dict)
    estimate: np.ndarray | None = None
    sigma: np.ndarray | None = None


def _json(path: Path):
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _last_row(path: Path):
    try:
        rows = np.genfromtxt(path, delimiter=',', names=True)
    except (OSError, ValueError):
        return None
    rows = np.atleast_1d(rows)
    return rows[-1] if rows.size else None


def _argv(tool: str, bag: Path, work: Path) -> list[str]:
    j = str(work / f'{tool}.json')
    return {
        'calibrate_bag': [str(bag), '--json', j, '--force'],
        'filter_bag': [str(bag), '--output', str(work / 'filter.csv'), '--json', j,
                       '--params', str(work / 'model.yaml'), '--force'],
        'calibrate_gyro_bag': [str(bag), '--method', 'integral', '--json', j, '--force',
                               '--quiet'],
        'discrepancy': [str(bag), '--model', str(work / 'model.yaml'), '--json', j, '--force',
                        '--quiet'],
        'nominal_model': [str(bag), '--output', str(work / 'nominal.yaml'), '--json', j,
                          '--force', '--quiet'],
        'sins_bag': [str(bag), '--output', str(work / 'sins.csv'), '--force'],
    }[tool]


def _main(tool: str):
    return importlib.import_module(f'strapdown_ros.tools.{tool}').main


def run_tool(tool: str, bag, work) -> Outcome:
    """
    Run one tool on a bag, in-process.

    Parameters
    ----------
    tool : str
        One of :data:`TOOLS`.
    bag : str or Path
        The bag.
    work : str or Path
        A directory for its outputs (a model file is written there).

    Returns
    -------
    Outcome
        Its status, printout, counts and estimates.

    """
    work = Path(work)
    (work / 'model.yaml').write_text(_MODEL)
    for old in work.glob(f'{tool}.*'):
        old.unlink()
    out, err = io.StringIO(), io.StringIO()
    tb = None
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            status = _main(tool)(_argv(tool, Path(bag), work))
        except SystemExit as exc:
            status = exc.code if isinstance(exc.code, int) else 1
        except Exception:  # noqa: BLE001 - the verdict: a traceback is a failure
            status, tb = None, traceback.format_exc()
    o = Outcome(tool, status, tb, out.getvalue(), err.getvalue())
    doc = _json(work / f'{tool}.json')
    if isinstance(doc, dict):
        o.read = ((doc.get('input') or {}).get('read')) or {}
    if status != 0:
        return o
    if tool == 'calibrate_bag' and doc and doc.get('observable'):
        o.estimate, o.sigma = np.array(doc['beta_rad']), np.array(doc['beta_sigma_rad'])
    elif tool == 'filter_bag':
        row = _last_row(work / 'filter.csv')
        if row is not None:
            o.estimate = np.array([row[f'bias_{a}'] for a in 'xyz'])
            o.sigma = np.array([row[f'bias_sigma_{a}'] for a in 'xyz'])
    elif tool == 'calibrate_gyro_bag' and doc and doc.get('observable'):
        o.estimate = np.array(list(doc['estimate'].values()), dtype=float)
        o.sigma = np.array(list(doc['sigma'].values()), dtype=float)
    elif tool == 'discrepancy' and doc and doc.get('boresight_rad'):
        o.estimate = np.array(doc['boresight_rad'], dtype=float)
        o.sigma = np.array(doc['boresight_sigma_rad'], dtype=float)
    elif tool == 'nominal_model' and doc:
        vals = doc.get('values') or {}
        keys = ('gyro_rate', 'camera_sigma_xy', 'camera_sigma_z', 'gyro_random_walk')
        o.estimate = np.array([float(vals[k]) for k in keys if k in vals])
        o.sigma = 1e-9 * np.abs(o.estimate)          # no σ: the clean values to round-off
    elif tool == 'sins_bag':
        o.read = {'gyro': {'dropped': _sins_dropped(o.stdout)}}
        row = _last_row(work / 'sins.csv')
        if row is not None:
            o.estimate = np.array([row[k] for k in ('qx', 'qy', 'qz', 'qw')])
            o.sigma = np.full(4, float(max(row[f'sigma_eps_{a}'] for a in 'xyz')))
    return o


#: the words of sins_bag's ``dropped:`` line → the reasons
_SINS_WORDS = {'NaN': 'nan', 'out of range': 'out_of_range', 'out of order': 'out_of_order',
               'duplicate': 'duplicate', 'stamp outlier': 'stamp_outlier',
               'wrong type': 'wrong_type', 'frame mismatch (rejected)': 'frame',
               'frame mismatch (used)': 'frame'}


def _sins_dropped(stdout: str) -> dict:
    """Return the reasons and counts of sins_bag's ``  dropped: ...`` line."""
    line = next((x for x in stdout.splitlines() if x.startswith('  dropped: ')), '')
    out = {}
    for part in line[len('  dropped: '):].split(', '):
        words, _, n = part.rpartition(' ')
        if words in _SINS_WORDS and n.isdigit():
            out[_SINS_WORDS[words]] = int(n)
    return out


def counted(o: Outcome, kind: Kind) -> int:
    """
    Return how many messages a surface counted under the reason of ``kind``.

    Parameters
    ----------
    o : Outcome
        The surface's outcome.
    kind : Kind
        The hostile kind.

    Returns
    -------
    int
        The count (frames: the messages seen in the stray frame).

    """
    stream = o.read.get('gyro' if kind.stream == 'gyro' else 'reference') or {}
    if kind.reason == 'frame' and 'frame' in (stream.get('dropped') or {}):
        return int(stream['dropped']['frame'])           # a surface that rejects the frame
    if kind.reason == 'frame':
        frames = (o.read.get('frames') or {}).get(kind.stream) or {}
        want = 'stray_frame' if kind.name == 'stray_frame' else 'x' * 64
        return sum(int(n or 1) for f, n in frames.items()
                   if f == want or (kind.name == 'long_frame' and str(f).startswith(want)))
    dropped = dict(stream.get('dropped') or {})
    rates = o.read.get('rate_samples')
    if kind.stream == 'gyro' and rates:
        for k, v in (rates.get('dropped') or {}).items():
            dropped[k] = dropped.get(k, 0) + v
    return int(dropped.get(kind.reason, 0))


def problems(kind: Kind, clean: Outcome, hostile: Outcome) -> list[str]:
    """
    Return what a surface did wrong with one hostile message (empty: nothing).

    Parameters
    ----------
    kind : Kind
        The hostile kind.
    clean, hostile : Outcome
        The surface on the clean recording and on the one with the hostile message.

    Returns
    -------
    list of str
        One line per failed rule: a traceback, another exit status, the message not counted,
        an estimate beyond 1σ of the clean one.

    """
    where = f'{hostile.surface} {kind.label}'
    out = []
    if hostile.traceback is not None:
        out.append(f'{where}: traceback: {hostile.traceback.strip().splitlines()[-1]}')
        return out
    if kind.name == 'empty_topic' and hostile.surface.endswith('_node'):
        return out                     # a node waits for the stream (no traceback: enough)
    if kind.name == 'empty_topic':
        lines = [x for x in hostile.stderr.splitlines() if 'error' in x]
        if hostile.status != 2 or len(lines) != 1 or 'no usable' not in lines[0]:
            out.append(f'{where}: expected one error line and exit 2, got status '
                       f'{hostile.status}: {bounded(hostile.stderr, 300)}')
        return out
    if hostile.status != clean.status:
        out.append(f'{where}: exit status {hostile.status}, clean {clean.status}: '
                   f'{bounded(hostile.stderr, 300)}')
    if kind.reason != 'empty' and counted(hostile, kind) < 1:
        out.append(f'{where}: not counted under {kind.reason}: {bounded(hostile.read, 400)}')
    if (clean.estimate is None) != (hostile.estimate is None):
        out.append(f'{where}: estimate {hostile.estimate}, clean {clean.estimate}')
    elif clean.estimate is not None:
        if clean.estimate.shape != hostile.estimate.shape:
            out.append(f'{where}: estimate shape {hostile.estimate.shape}, clean '
                       f'{clean.estimate.shape}')
        else:
            d = np.abs(hostile.estimate - clean.estimate)
            if not np.all(d <= clean.sigma + 1e-15):
                out.append(f'{where}: estimate off the clean one by {d} > 1σ {clean.sigma}')
    return out


#: the length of the frame id of the ``long_frame`` kind (for the runners' bounds)
LONG_FRAME = LONG_FRAME_LENGTH
