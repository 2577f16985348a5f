"""
Calibrate the boresight C_MF^VF on a recording: the library call of ``calibrate_bag``.

:func:`calibrate_boresight` reads the recording (:func:`~strapdown_ros.runs.source.read_checked`),
says the warnings and notes on the input and the model, refuses a stream with too little usable
(:class:`~strapdown_ros.runs.source.UnusableRecording`), feeds calibrator_node's calibrator in
stamp order at the spacing of the reference fixes its error allows
(:func:`strapdown_ros.calibration.replay.calibrate_spaced`: stated, the model's
``reference_spacing``, or chosen from the data) and returns a :class:`BoresightRun`: the JSON
record ``calibrate_bag --json`` writes, the model checked against the recording and the model
with the boresight found.  :func:`boresight_of_data` does the same on streams already read (the
fleet reads a recording once for all its analyses).  No printing.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from strapdown_ros.calibration.replay import calibrate_spaced, solution_record
from strapdown_ros.calibration.streaming import CalibratorSettings
from strapdown_ros.recording import input_summary
from strapdown_ros.runs.source import (check_usable, read_checked, recording_notes,
                                       RecordingSource)
from strapdown_ros.sensors.sensor_model import SensorModel

__all__ = ['BoresightRun', 'calibrate_boresight', 'boresight_of_data', 'CONSUMERS']

#: the consumers of the model keys the boresight calibration applies
CONSUMERS = ('gyro', 'reference')


@dataclass(frozen=True)
class BoresightRun:
    """
    The boresight calibration of one recording.

    Attributes
    ----------
    record : dict
        JSON-ready: the schema of ``calibrate_bag --json`` (β, its σ and covariance, the
        quaternion, pairs, observability, the fit's χ² and its band, drops, gaps, input).
    model : SensorModel
        The model the calibration ran with (checked against the recording).
    found_model : SensorModel or None
        ``model`` with ``boresight`` and ``boresight_sigma`` (the largest σ of the angles)
        found; None when not observable.
    frames : dict
        ``gyro`` and ``camera``: the header frame ids seen.
    notes : tuple of str
        The warnings and notes on the input and the model, each starting ``WARNING:``,
        ``warning:`` or ``note:`` (:func:`calibrate_boresight`; empty from
        :func:`boresight_of_data`).

    """

    record: dict
    model: SensorModel
    found_model: SensorModel | None
    frames: dict
    notes: tuple = field(default_factory=tuple)

    @property
    def observable(self) -> bool:
        """Return True when the boresight was solved: observable, with a solution."""
        return bool(self.record['observable'])


def calibrate_boresight(source: RecordingSource, model: SensorModel,
                        settings: CalibratorSettings | None = None, spacing: float | None = None,
                        say=None, who: str = 'calibrate_bag') -> BoresightRun:
    """
    Read a recording and calibrate its boresight as calibrator_node would.

    The recording is read with the nodes' input rules, the model checked against it; the
    warnings on the input, the notes on the model and the warnings on the frames are said, in
    that order, before a stream with too little usable is refused.

    Parameters
    ----------
    source : RecordingSource
        The recording and its input options.
    model : SensorModel
        The unit's sensor model.
    settings : CalibratorSettings, optional
        The calibrator's settings (default: the defaults).
    spacing : float, optional
        Spacing of the fixes of the pairs, s (0: every fix); None: the model's
        ``reference_spacing`` where it states one, else chosen from the data.
    say : callable, optional
        ``say(text)`` for each warning and note as it arises (also kept in
        :attr:`BoresightRun.notes`).
    who : str
        The consumer named in the note on model keys the calibration does not apply.

    Returns
    -------
    BoresightRun
        The record, the checked model and the found model.

    Raises
    ------
    BagError
        The bag cannot be used.
    UnusableRecording
        Too few usable gyro increments or reference fixes (a ValueError).
    ValueError
        The model contradicts the recording.
    ArithmeticError, numpy.linalg.LinAlgError
        The calibration failed numerically (never bad input).

    """
    settings = settings or CalibratorSettings()
    data, checked = read_checked(source, model, settings.use_camera_covariance,
                                 settings.max_stamp_jump, settings.resync_count)
    inputs, frames, model_notes = recording_notes(who, data, model, checked, CONSUMERS)
    notes = inputs + model_notes + frames
    if say is not None:
        for text in notes:
            say(text)
    run = boresight_of_data(data, checked, settings, spacing)
    return replace(run, notes=tuple(notes))


def boresight_of_data(data: dict, model: SensorModel,
                      settings: CalibratorSettings | None = None,
                      spacing: float | None = None) -> BoresightRun:
    """
    Calibrate the boresight on streams already read.

    Parameters
    ----------
    data : dict
        The streams of :func:`strapdown_ros.recording.read_bag`.
    model : SensorModel
        The sensor model, checked against the recording.
    settings : CalibratorSettings, optional
        The calibrator's settings.
    spacing : float, optional
        Spacing of the fixes of the pairs, s; None: the model's ``reference_spacing`` where it
        states one, else chosen from the data (``calibrate_bag --reference-spacing auto``).

    Returns
    -------
    BoresightRun
        The calibration.

    Raises
    ------
    UnusableRecording
        Too few usable gyro increments or reference fixes.
    ArithmeticError, numpy.linalg.LinAlgError
        The calibration failed numerically.

    """
    settings = settings or CalibratorSettings()
    check_usable(data)
    g, c = data['gyro'], data['camera']
    sol, cal, discarded, choice = calibrate_spaced(data, model, settings, spacing)
    result = solution_record(sol, settings.weighted)
    result['reference_spacing'] = choice.as_dict()
    result['covariance_model'] = settings.covariance_model
    result['dropped'] = {'gyro': dict(g.dropped),
                         'camera': {**c.dropped,
                                    'zero_quaternion': data['camera_fixes']['zero_quaternion'],
                                    'bad_covariance': data['camera_fixes']['bad_covariance']}}
    result['gyro_gaps'] = {'gaps': g.check.gaps, 'missing': g.missing,
                           'pairs_discarded': discarded,
                           'dropouts': g.check.dropouts, 'stamp_bursts': g.check.bursts}
    result['stamp_resyncs'] = {'gyro': g.resyncs, 'camera': c.resyncs}
    result['pairs_replayed_not_added'] = cal.replayed_pairs         # stamps of a pair already held
    period = data['gyro_period_s']
    result['gyro_rate_from_stamps_hz'] = float(1.0 / period) if np.isfinite(period) else None
    result['camera_fixes'] = {k: data['camera_fixes'][k] for k in ('normalised',
                                                                   'covariance_substituted')}
    result['camera_fixes']['outliers_dropped'] = cal.outlier_fixes
    origin_s = min(g.stamps[0], c.stamps[0]) * 1e-9          # the replay's time origin
    result['camera_fixes']['outlier_stamps_s'] = [float(t) + origin_s for t in cal.outlier_stamps]
    result['messages'] = {'gyro': len(g.stamps), 'camera': len(c.stamps)}
    result['topics'] = {'gyro': data['gyro_topic'], 'camera': data['camera_topic']}
    result['camera_covariance_from_bag'] = data['camera_covariance_from_bag']
    result['input'] = input_summary(data)
    result['unread_messages'] = dict(data['unread_messages'])
    if data['rate_samples']:
        result['dropped']['gyro_rate_samples'] = dict(data['rate_samples']['dropped'])
    found = None
    if result['observable']:
        try:
            found = model.with_values({'boresight': list(result['beta_rad']),
                                       'boresight_sigma': float(max(result['beta_sigma_rad']))},
                                      rule='estimated by calibrate_bag')
        except ValueError:                          # a σ beyond the key's range: no model
            found = None
    frames = {k: sorted(str(f) for f in v) for k, v in data['frames'].items()}
    return BoresightRun(result, model, found, frames)
