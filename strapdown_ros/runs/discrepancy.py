"""
Analyse where a recording and its model disagree: the library call of ``discrepancy``.

:func:`analyse_discrepancies` reads the recording, checks the model against it, runs the
discrepancy workflow (:func:`strapdown_ros.discrepancy.workflow.analyse`) and, on request, the
Allan comparison on static segments; it returns a :class:`DiscrepancyRun`: the result, the JSON
document ``discrepancy --json`` writes, the found model and the warnings and notes on the input
and the model (said as they arise).  A recording whose motion does not
determine the boresight is a result too (``observable`` false), not an exception.
:func:`discrepancy_of_recording` does the same on a recording already read.  No printing.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

from strapdown_ros.discrepancy.bag_input import load_recording
from strapdown_ros.discrepancy.diagnostics import allan_comparison
from strapdown_ros.discrepancy.workflow import (analyse, BoresightUnobservable,
                                                DiscrepancySettings, json_clean)
from strapdown_ros.params import check_against_recording
from strapdown_ros.runs.source import recording_notes, RecordingSource
from strapdown_ros.sensors.sensor_model import SensorModel

__all__ = ['DiscrepancyRun', 'analyse_discrepancies', 'discrepancy_of_recording', 'CONSUMERS']

#: the consumers of the model keys the discrepancy workflow applies
CONSUMERS = ('gyro', 'reference', 'filter')


@dataclass(frozen=True)
class DiscrepancyRun:
    """
    The discrepancy analysis of one recording.

    Attributes
    ----------
    result : DiscrepancyResult or None
        The workflow's answer (verdict, effects found with σ, tests); None when the boresight
        is not observable.
    record : dict
        JSON-ready: the document of ``discrepancy --json`` (with ``allan`` and ``input``), or
        ``{"observable": false, ...}``.
    model : SensorModel
        The model the analysis ran with (checked against the recording).
    info : dict
        What reading found (drops, gaps, topics, the input record).
    observable : bool
        Whether the motion determines the boresight.
    message : str
        Why not, when not observable.
    unobservable : list of str
        The unobservable combinations, when not observable.
    notes : tuple of str
        The warnings and notes on the input and the model, each starting ``WARNING:``,
        ``warning:`` or ``note:`` (:func:`analyse_discrepancies`; empty from
        :func:`discrepancy_of_recording`).

    """

    result: object
    record: dict
    model: SensorModel
    info: dict
    observable: bool = True
    message: str = ''
    unobservable: list = field(default_factory=list)
    notes: tuple = field(default_factory=tuple)

    @property
    def found_model(self) -> SensorModel | None:
        """Return the model with the found effects and the boresight, or None."""
        return None if self.result is None else self.result.found_model


def analyse_discrepancies(source: RecordingSource, model: SensorModel,
                          settings: DiscrepancySettings | None = None,
                          read_settings: dict | None = None, allan: bool = True,
                          progress=None, say=None, who: str = 'discrepancy') -> DiscrepancyRun:
    """
    Read a recording and find where it and its model disagree.

    The recording is read with the nodes' input rules (refused when a stream has too little
    usable), then the model is checked against it; the warnings on the input and the frames and
    the notes on the model are said, then the workflow runs.

    Parameters
    ----------
    source : RecordingSource
        The recording and its input options.
    model : SensorModel
        The nominal model.
    settings : DiscrepancySettings, optional
        Level, blocks, lags, step limit, candidates, the observability rule.
    read_settings : dict, optional
        The stream rules (``max_stamp_jump``, ``resync_count``; defaults where absent).
    allan : bool
        Also compare the Allan deviation on static segments (``allan`` in the record).
    progress : callable, optional
        ``progress(text)`` between stages.
    say : callable, optional
        ``say(text)`` for each warning and note as it arises (also kept in
        :attr:`DiscrepancyRun.notes`).
    who : str
        The consumer named in the note on model keys the analysis does not apply.

    Returns
    -------
    DiscrepancyRun
        The analysis.

    Raises
    ------
    BagError
        The bag cannot be used, or a stream has too little usable.
    InputError
        Too few fixes or pairs.
    ValueError
        The model contradicts the recording.
    AnalysisError, numpy.linalg.LinAlgError, FloatingPointError, OverflowError
        A base fit failed numerically (never reported as bad input).

    """
    if progress is not None:
        progress('reading the bag')
    rec, info = load_recording(source.path, model, read_settings, source.namespace,
                               **source.read_options())
    checked = check_against_recording(model, info['facts'])
    inputs, frames, model_notes = recording_notes(who, info, model, checked, CONSUMERS)
    notes = inputs + frames + model_notes
    if say is not None:
        for text in notes:
            say(text)
    run = discrepancy_of_recording(rec, info, checked, settings, allan, progress)
    return replace(run, notes=tuple(notes))


def discrepancy_of_recording(rec, info: dict, model: SensorModel,
                             settings: DiscrepancySettings | None = None, allan: bool = True,
                             progress=None) -> DiscrepancyRun:
    """
    Find where a recording already read and its model disagree.

    Parameters
    ----------
    rec : Recording
        The recording (:func:`strapdown_ros.discrepancy.bag_input.recording_from_data`).
    info : dict
        What reading found.
    model : SensorModel
        The nominal model, checked against the recording.
    settings : DiscrepancySettings, optional
        The workflow's settings.
    allan : bool
        Also compare the Allan deviation on static segments.
    progress : callable, optional
        ``progress(text)`` between stages.

    Returns
    -------
    DiscrepancyRun
        The analysis.

    """
    say = progress or (lambda text: None)
    try:
        res = analyse(rec, model, settings or DiscrepancySettings(), progress=say)
    except BoresightUnobservable as exc:
        unobs = list(exc.report.unobservable) if exc.report is not None else []
        record = json_clean({'observable': False, 'message': str(exc), 'unobservable': unobs,
                             'verdict': None, 'input': info})
        return DiscrepancyRun(None, record, model, info, False, str(exc), unobs)
    out = res.as_json()
    if allan:
        say('Allan deviation on static segments')
        try:
            comparison = allan_comparison(rec.gyro_stamps, rec.delta_theta, model,
                                          res.found_model)
        except Exception as exc:  # noqa: BLE001 - the rest of the result stands
            comparison = {'error': str(exc)}
        out['allan'] = json_clean(comparison)
    out['input'] = json_clean(info)
    return DiscrepancyRun(res, out, model, info)
