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
from strapdown_ros.recording import input_summary
from strapdown_ros.recording.filter_replay import run_filter
from strapdown_ros.runs.source import read_checked, RecordingSource
from strapdown_ros.sensors.sensor_model import SensorModel

__all__ = ['FilterRun', 'run_filter_on']


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

    """

    outputs: list
    fixes: list
    status: dict
    check_text: str | None
    augment: tuple
    model: SensorModel
    read: dict


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
    system = run_filter(data, checked, settings)
    outputs, fixes = system.take()
    text = system.check.last.text() if system.check is not None else None
    return FilterRun(outputs, fixes, system.status(), text, tuple(system.augment), checked,
                     input_summary(data))
