"""
The calibrator's state file: identity, lock, atomic writes.

The ``state_file`` of ``calibrator_node``.  No ROS imports; the node only calls
:class:`CalibratorStateFile`.  The rules:

* **identity** — the file stores what defines its estimate: every calibrator parameter except
  the operational ones (:data:`OPERATIONAL`: queue depths, publishing thresholds, input
  validation limits, the start value of the solver, the file name itself), among them the
  frames (``frame_id``, ``camera_frame_id``, ``reference_frame_id``), the gyro error model,
  the compensated effects and the camera σ; and the stream identity (the resolved gyro and
  camera topics).  A file whose identity differs is refused with the names of the differing
  entries, left untouched, and the node runs without persistence (ERROR);
* **replay** — pairs are keyed by their start and end stamps (integer ns): a pair whose key is
  already held is not added again (:meth:`BoresightCalibrator.add_pair_keys`), so replaying
  the same recording into a resumed node adds nothing;
* **lock** — ``fcntl.flock`` (exclusive, non-blocking) on ``<state_file>.lock``, held while the
  node runs: a second node on the same file gets an error and runs without persistence;
* **paths** — a ``state_file`` that is a directory, ends with a path separator or lies in a
  directory that does not exist is refused; nothing is ever moved but a regular file that
  cannot be read (renamed ``<state_file>.corrupt[.k]``);
* **writes** — to the fixed temporary ``.<name>.tmp`` beside the file (flushed, fsynced, renamed
  over it, directory fsynced); the temporary of a process killed mid-write is removed when the
  next node takes the lock, so none is left behind.
"""
from __future__ import annotations

import fcntl
import json
import os

import numpy as np

from strapdown_ros.calibration.boresight_increments import IncrementPair

__all__ = ['CalibratorStateFile', 'StateFileError', 'state_identity', 'OPERATIONAL',
           'STATE_VERSION']

STATE_VERSION = 2
#: parameters that do not change the pairs or their estimate (not part of the identity)
OPERATIONAL = frozenset({'qos_depth', 'diagnostics_period', 'state_file', 'weighted', 'max_sigma',
                         'max_chi2_per_dof', 'max_pairs', 'frame_mismatch', 'max_stamp_jump',
                         'resync_count', 'gyro_max_rate', 'min_rotation_deg', 'initial_boresight'})
_SHAPES = {'t_start': (), 't_end': (), 'dq_imu': (4,), 'dq_cam': (4,), 'cov_imu': (3, 3),
           'cov_cam': (3, 3), 'imu_sensitivity': (3, 12), 'cov_imu_white': (3, 3),
           'cov_fix_start': (3, 3), 'cov_fix_end': (3, 3)}
_PAIR_FIELDS = tuple(_SHAPES)
_REQUIRED = ('t_start', 't_end', 'dq_imu', 'dq_cam', 'cov_imu', 'cov_cam')


class StateFileError(RuntimeError):
    """
    The state file cannot be used.

    Parameters
    ----------
    kind : str
        'path', 'locked', 'identity' or 'corrupt'.
    message : str
        What is wrong, in words.

    """

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind = kind


def _plain(v):
    """Return a parameter value as plain JSON (lists for arrays, floats for numpy scalars)."""
    if isinstance(v, (list, tuple, np.ndarray)):
        return [_plain(x) for x in v]
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v)
    return str(v)


def state_identity(params: dict, streams: dict) -> dict:
    """
    Return the identity of a calibrator state.

    Parameters
    ----------
    params : dict
        The calibrator's parameters; all but :data:`OPERATIONAL` define the estimate.
    streams : dict
        The resolved stream names, e.g. ``{'gyro': '/robot/imu/delta_theta', ...}``.

    Returns
    -------
    dict
        ``{'parameters': ..., 'streams': ...}`` as plain JSON values.

    """
    return {'parameters': {k: _plain(v) for k, v in sorted(params.items())
                           if k not in OPERATIONAL},
            'streams': {k: str(v) for k, v in sorted(streams.items())}}


def _differences(stored: dict, current: dict) -> list[str]:
    out = []
    for part in ('parameters', 'streams'):
        a, b = stored.get(part, {}), current.get(part, {})
        for k in sorted(set(a) | set(b)):
            if a.get(k, '<absent>') != b.get(k, '<absent>'):
                was, now = str(a.get(k, '<absent>'))[:60], str(b.get(k, '<absent>'))[:60]
                out.append(f'{k} {was} → {now}')
    return out


class CalibratorStateFile:
    """
    One node's state file.

    :meth:`acquire` first (path checks, lock, stale temporary removed), then :meth:`load` once
    and :meth:`save` after every new pair; :meth:`close` releases the lock.

    Parameters
    ----------
    path : str
        ``state_file``.
    identity : dict
        :func:`state_identity` of the running node.

    """

    def __init__(self, path: str, identity: dict):
        self.path = str(path)
        self.identity = identity
        self._lock_fd: int | None = None
        d, name = os.path.split(os.path.abspath(self.path))
        self.directory = d
        self.tmp = os.path.join(d, f'.{name}.tmp')
        self.lock_path = self.path + '.lock'

    # --- start-up ---------------------------------------------------------------------------
    def acquire(self) -> None:
        """
        Check the path, take the lock, remove a temporary left by a killed writer.

        Raises
        ------
        StateFileError
            'path' or 'locked'; nothing is changed on the file system then.

        """
        p = self.path
        if p.endswith(os.sep) or (os.altsep and p.endswith(os.altsep)):
            raise StateFileError('path', f'state_file {p!r} ends with a path separator: '
                                         'it must name a file')
        if os.path.isdir(p):
            raise StateFileError('path', f'state_file {p!r} is a directory: it must name a file')
        if os.path.exists(p) and not os.path.isfile(p):
            raise StateFileError('path', f'state_file {p!r} is not a regular file')
        if not os.path.isdir(self.directory):
            raise StateFileError('path', f'the directory of state_file {p!r} does not exist')
        try:
            fd = os.open(self.lock_path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise StateFileError('path', f'cannot create the lock file {self.lock_path}: '
                                         f'{exc.strerror}') from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise StateFileError('locked', f'state_file {p} is in use by another process '
                                           f'(lock {self.lock_path} held): running without '
                                           'persistence') from None
        self._lock_fd = fd
        try:
            os.unlink(self.tmp)                 # a writer killed between write and rename
        except FileNotFoundError:
            pass

    def close(self) -> None:
        """Release the lock (the lock file stays: removing it would race a waiting node)."""
        if self._lock_fd is not None:
            try:
                fcntl.flock(self._lock_fd, fcntl.LOCK_UN)
            finally:
                os.close(self._lock_fd)
                self._lock_fd = None

    # --- contents ---------------------------------------------------------------------------
    def load(self, cal) -> int | None:
        """
        Restore pairs and last fix into ``cal``.

        Parameters
        ----------
        cal : BoresightCalibrator
            The calibrator to restore into.

        Returns
        -------
        int or None
            The time origin, ns, or None when there is no file.

        Raises
        ------
        StateFileError
            'identity' (the file is left as it is) or 'corrupt' (unreadable or malformed);
            nothing is restored then.

        """
        if not os.path.exists(self.path):
            return None
        try:
            with np.load(self.path, allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
        except Exception as exc:                   # any unreadable file is reported
            why = f'unreadable ({type(exc).__name__}: {str(exc)[:120]})'
            raise StateFileError('corrupt', why) from None
        if int(data.get('version', -1)) != STATE_VERSION:
            raise StateFileError('identity', f"state version {data.get('version')} is not "
                                             f'{STATE_VERSION} (written by another version of '
                                             'the package)')
        try:
            stored = json.loads(str(data['identity']))
        except Exception:                          # any malformed record is reported
            raise StateFileError('corrupt', 'identity record unreadable') from None
        diff = _differences(stored, self.identity)
        if diff:
            more = f'; and {len(diff) - 8} more' if len(diff) > 8 else ''
            raise StateFileError('identity', 'written for another calibration: '
                                 + '; '.join(diff[:8]) + more)
        try:
            n = int(data['n_pairs'])
            fields = {}
            for f, shape in _SHAPES.items():
                a = data.get('pair_' + f)
                if a is None:
                    if f in _REQUIRED and n:
                        raise ValueError(f'missing pair field {f}')
                    continue
                if a.shape != (n,) + shape or not np.all(np.isfinite(a)):
                    raise ValueError(f'pair field {f} has shape {a.shape}, expected '
                                     f'{(n,) + shape}, or non-finite values')
                fields[f] = a
            origin = int(data['origin_ns'])
        except (KeyError, ValueError, TypeError) as exc:
            raise StateFileError('corrupt', str(exc)) from None
        cal.pairs = [IncrementPair(**{f: (float(a[i]) if a.ndim == 1 else a[i].copy())
                                      for f, a in fields.items()}) for i in range(n)]
        cal.add_pair_keys(cal.pairs)
        if 'last_fix_t' in data:
            cal.restore_last_fix(float(data['last_fix_t']), data['last_fix_q'].astype(float),
                                 data['last_fix_P'].astype(float))
        return origin

    def move_aside(self) -> str:
        """Rename an unreadable regular file to ``<state_file>.corrupt[.k]``; return the name."""
        if not os.path.isfile(self.path):
            return ''
        k, aside = 0, f'{self.path}.corrupt'
        while os.path.exists(aside):
            k += 1
            aside = f'{self.path}.corrupt.{k}'
        os.replace(self.path, aside)
        return aside

    def save(self, cal, origin_ns: int) -> None:
        """
        Write pairs, last fix, estimate and identity atomically (module docstring).

        Parameters
        ----------
        cal : BoresightCalibrator
            The calibrator to save.
        origin_ns : int
            The time origin, ns.

        Raises
        ------
        OSError
            The file system refuses.

        """
        arrays = {'version': np.array(STATE_VERSION),
                  'origin_ns': np.array(int(origin_ns), dtype=np.int64),
                  'n_pairs': np.array(len(cal.pairs)),
                  'identity': np.array(json.dumps(self.identity))}
        for f in _PAIR_FIELDS:
            vals = [getattr(p, f) for p in cal.pairs]
            if vals and all(v is not None for v in vals):
                arrays['pair_' + f] = np.array(vals, dtype=float)
        last = cal.last_fix
        if last is not None:
            arrays['last_fix_t'] = np.array(last[0])
            arrays['last_fix_q'] = np.asarray(last[1])
            arrays['last_fix_P'] = np.asarray(last[2])
        sol = cal.solution
        if sol is not None and sol.observable and sol.beta is not None:
            arrays['beta'] = np.asarray(sol.beta, dtype=float)
        try:
            with open(self.tmp, 'wb') as fh:
                np.savez(fh, **arrays)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(self.tmp, self.path)
        except BaseException:
            try:
                os.unlink(self.tmp)
            except OSError:
                pass
            raise
        try:                                       # make the rename itself durable
            dfd = os.open(self.directory, os.O_RDONLY)
            try:
                os.fsync(dfd)
            finally:
                os.close(dfd)
        except OSError:
            pass
