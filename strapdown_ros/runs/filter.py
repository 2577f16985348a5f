"""
Run the star-camera-aided attitude filter on a recording: the library call of ``filter_bag``.

:func:`run_filter_on` reads the recording with the filter's stream rules, checks the model
against it and runs :func:`strapdown_ros.recording.filter_replay.run_filter` (the core of
``attitude_filter_node``); it returns a :class:`FilterRun`: the outputs (one per
``output_period``), the fix results, the counts and the live model check's last verdict.
No printing; the command writes the rows.
"""
from __future__ import annotations

from dataclasses import dataclass

from strapdown_ros.estimation.filter_system import FilterSettings
from strapdown_ros.estimation.reference_check import agreement_with_fixes
from strapdown_ros.recording import input_summary
from strapdown_ros.recording.filter_replay import run_filter
from strapdown_ros.runs.source import read_checked, RecordingSource
from strapdown_ros.sensors.sensor_model import SensorModel

__all__ = ['FilterRun', 'run_filter_on', 'filter_of_data', 'reference_check']


@dataclass(frozen=True)
class FilterRun:
    """
    The filter over one recording.

    Attributes
    ----------
    outputs : list of FilterOutput
        The filter states (stamp, attitude and σ, bias and σ, augmented states).
    fixes : list of FixOutput
        The fixes processed (status, innovation, NIS, lateness, model check).
    status : dict
        Input counts, filter counters and the model check's windows.
    check_text : str or None
        The live model check's last verdict in words (None without a model check).
    augment : tuple of str
        The augmented states.
    model : SensorModel
        The model the filter ran with (checked against the recording).
    read : dict
        What was read and how (:func:`strapdown_ros.recording.input_summary`).
    resets : tuple
        The divergences declared: (stamp ns of the fix, why), the latest kept.
    agreement : ReferenceAgreement or None
        The outputs against the reference fixes the filter did not apply
        (:func:`strapdown_ros.estimation.reference_check.agreement_with_fixes`).

    """

    outputs: list
    fixes: list
    status: dict
    check_text: str | None
    augment: tuple
    model: SensorModel
    read: dict
    resets: tuple = ()
    agreement: object = None


def run_filter_on(source: RecordingSource, model: SensorModel,
                  settings: FilterSettings | None = None) -> FilterRun:
    """
    Read a recording and run the attitude filter over it, in the order a node sees.

    Parameters
    ----------
    source : RecordingSource
        The recording and its input options.
    model : SensorModel
        The unit's sensor model.
    settings : FilterSettings, optional
        The filter's settings (default: the defaults).

    Returns
    -------
    FilterRun
        Outputs, fixes, counts and the model check.

    Raises
    ------
    BagError
        The bag cannot be used.
    ValueError
        The model contradicts the recording.

    """
    settings = settings or FilterSettings()
    data, checked = read_checked(source, model, settings.use_camera_covariance,
                                 settings.max_stamp_jump, settings.resync_count)
    return filter_of_data(data, checked, settings)


def filter_of_data(data: dict, model: SensorModel,
                   settings: FilterSettings | None = None) -> FilterRun:
    """
    Run the attitude filter over streams already read (:func:`run_filter_on` after its read).

    Parameters
    ----------
    data : dict
        The streams of :func:`strapdown_ros.recording.read_bag`.
    model : SensorModel
        The unit's sensor model, checked against the recording.
    settings : FilterSettings, optional
        The filter's settings (default: the defaults).

    Returns
    -------
    FilterRun
        Outputs, fixes, counts, the model check and the agreement with the reference.

    Raises
    ------
    ValueError, ArithmeticError
        The filter failed numerically (never bad input: the streams passed their rules).

    """
    settings = settings or FilterSettings()
    checked = model
    system = run_filter(data, checked, settings)
    outputs, fixes = system.take()
    text = system.check.last.text() if system.check is not None else None
    return FilterRun(outputs, fixes, system.status(), text, tuple(system.augment), checked,
                     input_summary(data), tuple(system.resets),
                     reference_check(data, checked, outputs, fixes))


def reference_check(data: dict, model: SensorModel, outputs, fixes):
    """
    Compare the filter's outputs with the recording's fixes that it did not apply.

    Parameters
    ----------
    data : dict
        The streams read (:func:`strapdown_ros.recording.reader.read_bag`).
    model : SensorModel
        The model the filter ran with (its ``camera_noise_scale`` scales the fixes' σ).
    outputs : list of FilterOutput
        The filter's outputs.
    fixes : list of FixOutput
        The fixes it processed.

    Returns
    -------
    ReferenceAgreement or None
        :func:`strapdown_ros.estimation.reference_check.agreement_with_fixes`.

    """
    cam = data['camera']
    applied = [f.stamp_ns for f in fixes if f.status == 'applied']
    scale = model.camera_effects().noise_scale
    return agreement_with_fixes(outputs, cam.stamps, cam.values, applied, scale)
