"""
Calibrate the gyro (scale factors, misalignments, biases) on a recording: ``calibrate_gyro_bag``.

:func:`calibrate_gyro` reads the recording as ``discrepancy`` reads it, compensates the model's
other effects and runs 002 (``integral``) or 000 (``tkachenko``) of
:mod:`strapdown_ros.calibration.gyro`; it returns a :class:`GyroRun`: the JSON record the
command writes (:func:`gyro_record`), the estimate, the model with the gyro errors found and the
notes on the input and the model (the command's warning and note lines, said as they arise).
:func:`gyro_of_recording` does the same on a recording already read.  No printing.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from strapdown_ros.calibration import gyro as gc
from strapdown_ros.discrepancy.bag_input import load_recording
from strapdown_ros.params import check_against_recording
from strapdown_ros.runs.source import recording_notes, RecordingSource
from strapdown_ros.sensors.sensor_model import SensorModel
from strapdown_ros.text import json_clean

__all__ = ['GyroOptions', 'GyroRun', 'calibrate_gyro', 'gyro_of_recording', 'gyro_record',
           'MIN_FIXES']

#: fewest usable camera fixes a gyro calibration takes
MIN_FIXES = 6


@dataclass(frozen=True)
class GyroOptions:
    """
    How the gyro is calibrated.

    Attributes
    ----------
    method : str
        ``integral`` (002) or ``tkachenko`` (000).
    interval : float or None
        integral: the averaging interval, s (None: one camera step).
    drift : bool
        tkachenko: also estimate a constant drift of the reference.
    sigma_limit : float
        A combination whose predicted σ exceeds it counts as unobservable.

    """

    method: str = 'integral'
    interval: float | None = None
    drift: bool = False
    sigma_limit: float = 1e-3

    def check(self) -> None:
        """
        Refuse inconsistent options, in one line.

        Raises
        ------
        ValueError
            An unknown method, --drift without tkachenko, an interval without integral or not
            positive, a σ limit not positive.

        """
        if self.method not in ('integral', 'tkachenko'):
            raise ValueError(f'method {self.method!r}: integral or tkachenko')
        if self.drift and self.method != 'tkachenko':
            raise ValueError('--drift needs --method tkachenko (002 has no reference drift)')
        if self.interval is not None:
            if self.method != 'integral':
                raise ValueError('--interval needs --method integral')
            if not (np.isfinite(self.interval) and self.interval > 0):
                raise ValueError(f'--interval must be > 0 s, got {self.interval}')
        if not (np.isfinite(self.sigma_limit) and self.sigma_limit > 0):
            raise ValueError(f'--sigma-limit must be > 0, got {self.sigma_limit}')


@dataclass(frozen=True)
class GyroRun:
    """
    The gyro calibration of one recording.

    Attributes
    ----------
    record : dict
        JSON-ready: the schema of ``calibrate_gyro_bag --json``.
    calibration : GyroCalibration
        The estimate (:class:`strapdown_ros.calibration.gyro.GyroCalibration`).
    model : SensorModel
        The model it ran with (checked against the recording).
    found_model : SensorModel or None
        ``model`` with ``gyro_scale_factor``, ``gyro_misalignment``, ``gyro_bias`` and their σ
        keys replaced by the estimate; None when not observable, or when an estimate is beyond
        the range of its key (``not_found`` says which).
    info : dict
        What reading found (drops, gaps, topics, the input record).
    notes : tuple of str
        The warnings and notes on the input and the model, each starting ``WARNING:``,
        ``warning:`` or ``note:`` (:func:`calibrate_gyro`; empty from
        :func:`gyro_of_recording`).
    not_found : str or None
        Why an observable estimate gave no ``found_model``.

    """

    record: dict
    calibration: object
    model: SensorModel
    found_model: SensorModel | None
    info: dict
    notes: tuple = field(default_factory=tuple)
    not_found: str | None = None

    @property
    def observable(self) -> bool:
        """Return whether every published parameter was observable."""
        return bool(self.calibration.observable)


def _num(x):
    x = float(x)
    return x if np.isfinite(x) else None


def gyro_record(cal, info: dict) -> dict:
    """
    Return the JSON record of a gyro calibration.

    Parameters
    ----------
    cal : GyroCalibration
        The estimate (:class:`strapdown_ros.calibration.gyro.GyroCalibration`).
    info : dict
        What was read from the bag (messages, fixes, topics).

    Returns
    -------
    dict
        Plain JSON values.

    """
    ok = bool(cal.observable)
    rep = cal.observability
    return json_clean({
        'method': cal.method,
        'observable': ok,
        'labels': list(cal.labels),
        'estimate': {n: _num(v) for n, v in zip(cal.labels, cal.x)} if ok else None,
        'sigma': {n: _num(v) for n, v in zip(cal.labels, cal.sigma)} if ok else None,
        'covariance': [[_num(v) for v in row] for row in cal.covariance] if ok else None,
        'model_parameters': gc.model_parameters(cal) if ok else None,
        'unobservable': list(cal.unobservable),
        'message': cal.message,
        'observability': {'eigenvalues': [_num(v) for v in rep.eigenvalues],
                          'predicted_sigma': [_num(v) for v in rep.predicted_sigma],
                          'condition': _num(rep.condition), 'weak': list(rep.weak),
                          'units': 'scale and misalignment 1; bias and drift '
                                   f'{cal.rate_scale:.6g} rad/s (the RMS rate of the recording)'},
        'fit_consistent': cal.extra.get('fit_consistent'),
        'chi2_per_dof': _num(cal.extra['chi2_per_dof']) if 'chi2_per_dof' in cal.extra else None,
        'chi2_per_dof_band': cal.extra.get('chi2_per_dof_band'),
        # sigma is scaled by √max(1, χ²/dof); this is the σ of the stated noise alone
        'sigma_stated_noise': ({n: _num(v / np.sqrt(cal.extra.get('covariance_scale', 1.0)))
                                for n, v in zip(cal.labels, cal.sigma)} if ok else None),
        'rate_scale_rad_s': cal.rate_scale,
        'details': cal.extra,
        'input': info,
    })


def calibrate_gyro(source: RecordingSource, model: SensorModel,
                   options: GyroOptions | None = None, settings: dict | None = None,
                   progress=None, say=None, who: str = 'calibrate_gyro_bag') -> GyroRun:
    """
    Read a recording and calibrate its gyro.

    The recording is read with the nodes' input rules (refused when a stream has too little
    usable), then the model is checked against it (a key it does not state is filled in from
    the recording); the warnings on the input (an index that disagrees with what was read,
    clipped increments, rate samples dropped, frames the model does not expect) and the notes
    on the model (keys filled in, keys the gyro calibration does not apply) are said, then the
    gyro is calibrated.

    Parameters
    ----------
    source : RecordingSource
        The recording and its input options.
    model : SensorModel
        The unit's sensor model.
    options : GyroOptions, optional
        The method and its options (default: 002, one camera step).
    settings : dict, optional
        The stream rules (``max_stamp_jump``, ``resync_count``; defaults where absent).
    progress : callable, optional
        ``progress(text)`` between stages.
    say : callable, optional
        ``say(text)`` for each warning and note as it arises (also kept in
        :attr:`GyroRun.notes`).
    who : str
        The consumer named in the note on model keys the calibration does not apply.

    Returns
    -------
    GyroRun
        The calibration.

    Raises
    ------
    BagError
        The bag cannot be used.
    ValueError
        The model contradicts the recording, too few fixes, inconsistent options.

    """
    options = options or GyroOptions()
    options.check()
    notes: list[str] = []

    def note(text: str) -> None:
        notes.append(text)
        if say is not None:
            say(text)

    rec, info = load_recording(source.path, model, settings, source.namespace,
                               **source.read_options())
    checked = check_against_recording(model, info['facts'])
    inputs, frames, model_notes = recording_notes(who, info, model, checked,
                                                  ('gyro', 'reference', 'filter'))
    for line in inputs + frames + model_notes:
        note(line)
    run = gyro_of_recording(rec, info, checked, options, progress, source.path)
    return replace(run, notes=tuple(notes))


def gyro_of_recording(rec, info: dict, model: SensorModel, options: GyroOptions | None = None,
                      progress=None, name: str = 'the recording') -> GyroRun:
    """
    Calibrate the gyro on a recording already read.

    Parameters
    ----------
    rec : Recording
        The recording (:func:`strapdown_ros.discrepancy.bag_input.recording_from_data`).
    info : dict
        What reading found.
    model : SensorModel
        The sensor model, checked against the recording.
    options : GyroOptions, optional
        The method and its options.
    progress : callable, optional
        ``progress(text)`` between stages.
    name : str
        The recording's name, for the error line.

    Returns
    -------
    GyroRun
        The calibration.

    Raises
    ------
    ValueError
        Too few camera fixes, or no pair covered by gap-free gyro data.

    """
    options = options or GyroOptions()
    say = progress or (lambda text: None)
    if len(rec.fix_stamps) < MIN_FIXES:
        raise ValueError(f'{name}: {len(rec.fix_stamps)} usable camera fixes '
                         f'(need at least {MIN_FIXES})')
    say(f"read {info['gyro_messages']} increments and {info['camera_fixes']} camera fixes")
    say("compensating the model's other effects; initial boresight from the increment axes")
    prep = gc.prepare(rec, model)
    if options.method == 'integral':
        say(f'002 integral method over {prep.pairs} camera steps')
        cal = gc.calibrate_integral(prep, options.interval, options.sigma_limit)
    else:
        cal = gc.calibrate_drifting_reference(
            prep, options.drift, options.sigma_limit,
            progress=lambda s: say(s.replace('tkachenko: ', '000: ')))
    found = not_found = None
    if cal.observable:
        try:
            found = model.with_values(gc.model_parameters(cal),
                                      rule=f'estimated by calibrate_gyro_bag --method '
                                           f'{cal.method}')
        except ValueError as exc:                   # an estimate beyond a key's range
            not_found = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return GyroRun(gyro_record(cal, info), cal, model, found, info, not_found=not_found)
