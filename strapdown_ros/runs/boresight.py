"""
Calibrate the boresight C_MF^VF on a recording: the library call of ``calibrate_bag``.

:func:`calibrate_boresight` reads the recording (:func:`~strapdown_ros.runs.source.read_checked`),
feeds calibrator_node's calibrator in stamp order
(:func:`strapdown_ros.calibration.replay.calibrate_recording`) and returns a
:class:`BoresightRun`: the JSON record ``calibrate_bag --json`` writes, the model checked against
the recording and the model with the boresight found.  :func:`boresight_of_data` does the same on
streams already read (the fleet reads a recording once for all its analyses).  No printing.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.calibration.replay import calibrate_recording, solution_record
from strapdown_ros.calibration.streaming import CalibratorSettings
from strapdown_ros.recording import input_summary
from strapdown_ros.runs.source import read_checked, RecordingSource
from strapdown_ros.sensors.sensor_model import SensorModel

__all__ = ['BoresightRun', 'calibrate_boresight', 'boresight_of_data']


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

    """

    record: dict
    model: SensorModel
    found_model: SensorModel | None
    frames: dict

    @property
    def observable(self) -> bool:
        """Return True when the boresight was solved: observable, with a solution."""
        return bool(self.record['observable'])


def calibrate_boresight(source: RecordingSource, model: SensorModel,
                        settings: CalibratorSettings | None = None) -> BoresightRun:
    """
    Read a recording and calibrate its boresight as calibrator_node would.

    Parameters
    ----------
    source : RecordingSource
        The recording and its input options.
    model : SensorModel
        The unit's sensor model.
    settings : CalibratorSettings, optional
        The calibrator's settings (default: the defaults).

    Returns
    -------
    BoresightRun
        The record, the checked model and the found model.

    Raises
    ------
    BagError
        The bag cannot be used.
    ValueError
        The model contradicts the recording, or no usable gyro or camera message.

    """
    settings = settings or CalibratorSettings()
    data, checked = read_checked(source, model, settings.use_camera_covariance,
                                 settings.max_stamp_jump, settings.resync_count)
    return boresight_of_data(data, checked, settings)


def boresight_of_data(data: dict, model: SensorModel,
                      settings: CalibratorSettings | None = None) -> BoresightRun:
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

    Returns
    -------
    BoresightRun
        The calibration.

    Raises
    ------
    ValueError
        No usable gyro or camera message.

    """
    settings = settings or CalibratorSettings()
    g, c = data['gyro'], data['camera']
    if not g.stamps or not c.stamps:
        raise ValueError(f"no usable {'gyro' if not g.stamps else 'camera'} messages")
    sol, cal, discarded = calibrate_recording(data, model, settings)
    result = solution_record(sol, settings.weighted)
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
    origin_s = min(g.stamps[0], c.stamps[0]) * 1e-9          # calibrate_recording's time origin
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
