"""
One recording of the fleet, analysed: the task each Dask worker runs.

:func:`analyse_recording` reads the recording once (bounded: :func:`memory_estimate` first,
against the task's memory budget), then runs, on what it read,

1. the discrepancy workflow (:func:`strapdown_ros.runs.discrepancy.discrepancy_of_recording`):
   the verdict and the effects missing from the unit's model;
2. the boresight calibration (:func:`strapdown_ros.runs.boresight.boresight_of_data`) with the
   model the discrepancy found (its found effects compensated; the nominal model when nothing
   was found or the boresight was not observable), at the spacing of the fixes ``calibrate_bag``
   takes by default (the model's ``reference_spacing`` where it states one, else chosen from the
   data), with its σ and verdict;
3. the gyro calibration, 002 by default (:func:`strapdown_ros.runs.gyro.gyro_of_recording`):
   scale factors, misalignments and biases with their σ, in every recording whose motion makes
   them observable.

It returns a JSON-ready record: the verdict, one row per effect component (registry effect and
parameter names, SI units, value and σ), the counts and the time and memory each stage took.
Every failure is caught: the record says ``status: error``, the stage and the reason in one
line; a recording never stops the fleet.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
import json
import os
import threading
import time

import numpy as np

from strapdown_ros.calibration.streaming import CalibratorSettings
from strapdown_ros.discrepancy.bag_input import recording_from_data
from strapdown_ros.discrepancy.workflow import DiscrepancySettings
from strapdown_ros.params import load_model_file
from strapdown_ros.recording import (CAMERA_COV_TOPIC, CAMERA_TOPIC, GYRO_TOPIC, open_reader,
                                     resolve_topic)
from strapdown_ros.runs.boresight import boresight_of_data
from strapdown_ros.runs.discrepancy import discrepancy_of_recording
from strapdown_ros.runs.gyro import gyro_of_recording, GyroOptions
from strapdown_ros.runs.source import read_checked, RecordingSource
from strapdown_ros.sensors.effects import EFFECTS
from strapdown_ros.sensors.gyro_effects import MISALIGNMENT_INDEX
from strapdown_ros.text import bounded

__all__ = ['FleetOptions', 'analyse_recording', 'memory_estimate', 'effect_rows',
           'BYTES_PER_MESSAGE', 'BASE_BYTES', 'GYRO_EFFECTS', 'VERDICTS']

#: peak memory of a task per message read (gyro and reference), bytes: about twice the growth
#: fleet_bench measures (doc/fleet.md)
BYTES_PER_MESSAGE = 2000
#: the worker's own memory before a task (Python, numpy, scipy, rosbags, the package), bytes
BASE_BYTES = 350 * 2 ** 20
#: the effects the gyro calibration estimates (its values win over the discrepancy's)
GYRO_EFFECTS = ('gyro_scale_factor', 'gyro_misalignment', 'gyro_bias')
#: the verdicts of a recording: the discrepancy's, ``unobservable`` (the motion does not
#: determine the boresight) and ``error``
VERDICTS = ('model_adequate', 'explained', 'unexplained_structure', 'unobservable', 'error')


@dataclass(frozen=True)
class FleetOptions:
    """
    What every recording of a fleet is analysed with, besides its unit's model file.

    Attributes
    ----------
    inputs : dict
        Input options of :class:`strapdown_ros.runs.source.RecordingSource` (``namespace``,
        ``gyro_topic``, ``reference_topic``, ``reference_frames``, ``rate_rule``).
    alpha : float
        Family-wise level of the discrepancy workflow per recording.
    candidates : tuple of str or None
        The discrepancy's candidate effects (None: the registry's library).
    gyro : GyroOptions
        The gyro calibration's method and options.
    memory_mib : float
        Memory budget of one task, MiB (the Dask worker's memory limit): a recording whose
        estimated peak (:func:`memory_estimate`) exceeds it is refused before it is read.

    """

    inputs: dict = field(default_factory=dict)
    alpha: float = 0.01
    candidates: tuple | None = None
    gyro: GyroOptions = field(default_factory=GyroOptions)
    memory_mib: float = 2048.0

    def key(self) -> str:
        """Return the options as canonical JSON (part of each recording's content hash)."""
        d = asdict(self)
        d.pop('memory_mib')                    # a budget does not change a result
        return json.dumps(d, sort_keys=True, default=str)


def memory_estimate(path: str, inputs: dict | None = None) -> tuple[int, int]:
    """
    Estimate a task's peak memory from the recording's own index, before reading it.

    Only the topics the task reads count: the gyro topic and the reference topic (the larger of
    the candidates when the reader will choose), as the reader resolves them; a recording whose
    topics do not resolve counts every message (the reader then refuses it anyway).

    Parameters
    ----------
    path : str
        The bag.
    inputs : dict, optional
        The input options (``namespace``, ``gyro_topic``, ``reference_topic``).

    Returns
    -------
    messages : int
        Messages of the topics read, from the bag's index.
    bytes : int
        :data:`BASE_BYTES` + :data:`BYTES_PER_MESSAGE` × messages.

    """
    inputs = inputs or {}
    ns = inputs.get('namespace') or ''
    reader = open_reader(path)
    try:
        counts: dict = {}
        for c in reader.connections:
            counts[c.topic] = counts.get(c.topic, 0) + int(getattr(c, 'msgcount', 0) or 0)
    finally:
        reader.close()

    def find(name):
        if name and name.startswith('/'):
            return next((t for t in counts if t.strip('/') == name.strip('/')), None)
        return resolve_topic(counts, name, ns) if name else None
    gyro = find(inputs.get('gyro_topic') or GYRO_TOPIC)
    refs = [find(inputs.get('reference_topic'))] if inputs.get('reference_topic') else \
        [find(CAMERA_COV_TOPIC), find(CAMERA_TOPIC), find('tf')]
    refs = [counts[r] for r in refs if r]
    n = counts[gyro] + max(refs) if gyro and refs else sum(counts.values())
    return n, BASE_BYTES + BYTES_PER_MESSAGE * n


class _PeakMemory:
    """Sample this process's resident memory every 20 ms; keep the peak."""

    def __init__(self):
        self.peak = self.start = self._rss()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    @staticmethod
    def _rss() -> int:
        try:
            with open('/proc/self/statm', encoding='ascii') as fh:
                return int(fh.read().split()[1]) * os.sysconf('SC_PAGE_SIZE')
        except (OSError, ValueError, IndexError):
            return 0

    def _run(self):
        while not self._stop.wait(0.02):
            self.peak = max(self.peak, self._rss())

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self.peak = max(self.peak, self._rss())


def _rows(effect: str, parameter: str, values, sigmas) -> list[dict]:
    v = np.atleast_1d(np.asarray(values, dtype=float)).ravel()
    s = np.atleast_1d(np.asarray(sigmas, dtype=float)).ravel()
    if s.size == 1 and v.size > 1:
        s = np.full(v.size, s[0])
    return [{'effect': effect, 'parameter': parameter, 'index': i,
             'value': float(v[i]), 'sigma': float(s[i]) if i < s.size else float('nan')}
            for i in range(v.size)]


def effect_rows(boresight: dict | None, gyro_cal, steps) -> list[dict]:
    """
    Return one row per effect component: registry effect and parameter names, value and σ.

    Parameters
    ----------
    boresight : dict or None
        The boresight record (``beta_rad``, ``beta_sigma_rad``) when observable.
    gyro_cal : GyroCalibration or None
        The gyro calibration when observable.
    steps : list of Step
        The effects the discrepancy found.

    Returns
    -------
    list of dict
        ``effect, parameter, index, value, sigma, source``.

    """
    rows = []
    if boresight is not None:
        rows += [dict(r, source='boresight_calibration')
                 for r in _rows('boresight', 'boresight', boresight['beta_rad'],
                                boresight['beta_sigma_rad'])]
    if gyro_cal is not None:
        sig = gyro_cal.sigma
        M = gyro_cal.misalignment_matrix
        sym = {(0, 1): 3, (1, 0): 3, (0, 2): 4, (2, 0): 4, (1, 2): 5, (2, 1): 5}
        parts = (('gyro_scale_factor', gyro_cal.scale, sig[0:3]),
                 ('gyro_misalignment', [M[i, j] for i, j in MISALIGNMENT_INDEX],
                  [sig[sym[ij]] for ij in MISALIGNMENT_INDEX]),
                 ('gyro_bias', gyro_cal.bias, sig[6:9]))
        for name, v, s in parts:
            rows += [dict(r, source='gyro_calibration')
                     for r in _rows(name, EFFECTS[name].value_parameter.name, v, s)]
    have = {r['effect'] for r in rows}
    for st in steps:
        if st.effect in have:
            continue
        for p, v in st.parameters.items():
            rows += [dict(r, source='discrepancy')
                     for r in _rows(st.effect, p, v, st.sigma.get(p, float('nan')))]
    return rows


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ''
    return bounded(f'{type(exc).__name__}: {text}' if text else type(exc).__name__, 300)


def analyse_recording(entry, options: FleetOptions | None = None) -> dict:
    """
    Analyse one recording of the fleet (boresight, gyro, discrepancy); never raises.

    Parameters
    ----------
    entry : FleetEntry
        The recording, its unit, start time and model file.
    options : FleetOptions, optional
        The fleet's options.

    Returns
    -------
    dict
        JSON-ready: ``status`` (``ok`` | ``error``), ``verdict``, ``reason`` and ``stage`` of an
        error, ``effects`` (rows of :func:`effect_rows`), what each analysis concluded
        (``boresight``, ``gyro``, ``discrepancy``), ``messages``, ``seconds`` per stage,
        ``memory`` (estimate and measured peak, bytes), ``worker`` (host and pid).

    """
    options = options or FleetOptions()
    out = {'status': 'ok', 'verdict': None, 'reason': '', 'stage': '', 'effects': [],
           'seconds': {}, 'worker': {'pid': os.getpid(), 'host': os.uname().nodename}}
    stage = 'model'
    clock = time.perf_counter()

    def done(name):
        nonlocal clock
        now = time.perf_counter()
        out['seconds'][name] = now - clock
        clock = now

    t_start = clock
    try:
        with _PeakMemory() as mem:
            mf = load_model_file(entry.model, 'calibrator_node')
            cal_settings = CalibratorSettings.from_values(mf.settings)
            disc_settings = DiscrepancySettings.from_values(
                {**mf.settings, 'alpha': options.alpha, 'candidates': options.candidates})
            stage = 'size'
            n, need = memory_estimate(entry.path, options.inputs)
            out['memory'] = {'estimate_bytes': need, 'index_messages': n,
                             'budget_bytes': int(options.memory_mib * 2 ** 20)}
            if need > options.memory_mib * 2 ** 20:
                raise MemoryError(f'{n} messages need about {need / 2 ** 20:.0f} MiB, above the '
                                  f'task budget of {options.memory_mib:g} MiB: split the '
                                  'recording or raise --memory-limit')
            stage = 'read'
            source = RecordingSource(entry.path, **options.inputs)
            data, model = read_checked(source, mf.model, True, cal_settings.max_stamp_jump,
                                       cal_settings.resync_count)
            rec, info = recording_from_data(data, entry.recording)
            out['messages'] = {'gyro': info['gyro_messages'], 'camera': info['camera_fixes']}
            out['duration_s'] = info['duration_s']
            done('read')
            stage = 'discrepancy'
            drun = discrepancy_of_recording(rec, info, model, disc_settings, allan=False)
            res = drun.result
            out['verdict'] = res.verdict if drun.observable else 'unobservable'
            out['discrepancy'] = ({'observable': False, 'message': drun.message}
                                  if not drun.observable else
                                  {'observable': True, 'verdict': res.verdict,
                                   'found': [s.effect for s in res.steps],
                                   'fit_consistent': bool(res.fit_consistent),
                                   'chi2_per_dof': float(res.chi2_per_dof),
                                   'rms_before': float(res.rms_before),
                                   'rms_after': float(res.rms_after), 'pairs': int(res.pairs)})
            done('discrepancy')
            stage = 'boresight'
            brun = boresight_of_data(data, drun.found_model or model, cal_settings)
            b = brun.record
            out['boresight'] = {k: b.get(k) for k in ('observable', 'pairs', 'chi2_per_dof',
                                                      'fit_consistent', 'message')}
            done('boresight')
            stage = 'gyro'
            try:
                grun = gyro_of_recording(rec, info, model, options.gyro, name=entry.recording)
                cal = grun.calibration
                out['gyro'] = {'observable': bool(cal.observable), 'method': cal.method,
                               'chi2_per_dof': grun.record.get('chi2_per_dof'),
                               'fit_consistent': grun.record.get('fit_consistent'),
                               'message': cal.message}
            except ValueError as exc:                  # too few fixes or pairs: no estimate
                cal = None
                out['gyro'] = {'observable': False, 'message': _one_line(exc)}
            done('gyro')
            steps = res.steps if drun.observable else []
            out['effects'] = effect_rows(b if brun.observable else None,
                                         cal if cal is not None and cal.observable else None,
                                         steps)
        out['memory']['peak_rss_bytes'] = int(mem.peak)
        out['memory']['task_increase_bytes'] = int(mem.peak - mem.start)
    except Exception as exc:  # noqa: BLE001 - one error row per recording, whatever failed
        out.update(status='error', verdict='error', stage=stage,
                   reason=f'{stage}: {_one_line(exc)}', effects=[])
    out['seconds']['total'] = time.perf_counter() - t_start
    return out
