"""
Run the SINS on a recording: the library call of ``sins_bag``.

:func:`run_sins` opens the recording's IMU streams (:func:`strapdown_ros.recording.imu_streams
.open_input`), takes the rates and the body frame the model does not state from the recording
(:func:`recording_model`), runs sins_node's :class:`~strapdown_ros.sins.SinsSystem` over it
(:func:`strapdown_ros.recording.sins_replay.run`) and hands every output block to a sink
(``sins_bag``'s CSV or MCAP writer, or :class:`CountingSink`, which keeps the last solution).
It returns a :class:`SinsRun`: what was read, dropped and lost, the system's counters, why there
is no solution (if so) and the sink's summary.  Notes go to a callback; nothing is printed.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from strapdown_ros.earth import geodetic_to_ecef
from strapdown_ros.params import check_against_recording, not_applied_note
from strapdown_ros.recording.imu_streams import open_input
from strapdown_ros.recording.sins_replay import run
from strapdown_ros.runs.source import RecordingSource
from strapdown_ros.sensors.sensor_model import SensorModel
from strapdown_ros.sins import SinsSettings, SinsSystem
from strapdown_ros.text import bounded

__all__ = ['SinsRun', 'SinkError', 'CountingSink', 'recording_model', 'no_solution',
           'run_sins']


class SinkError(RuntimeError):
    """The output sink could not be made (the command's file or bag cannot be written)."""


class CountingSink:
    """
    A sink that keeps no rows: it counts them and keeps the last solution.

    The default of :func:`run_sins` when the caller writes nothing.

    Parameters
    ----------
    navigation : bool
        Count navigation steps (else attitude updates).

    """

    def __init__(self, navigation: bool = False):
        self.navigation = navigation
        self.rows = 0
        self.last_attitude = None
        self.last_position = None

    def write(self, out) -> None:
        """
        Count one output block and keep its last solution.

        Parameters
        ----------
        out : SinsOutput
            One output block.

        """
        rec = out.navigation if self.navigation else out.attitude
        if not len(rec):
            return
        self.rows += len(rec)
        self.last_attitude = np.asarray(rec.attitude, dtype=float).reshape(-1, 4)[-1]
        if self.navigation:
            self.last_position = np.asarray(rec.position, dtype=float).reshape(-1, 3)[-1]

    def close(self, ok: bool = True) -> None:
        """
        Nothing to close.

        Parameters
        ----------
        ok : bool
            Whether the run completed (not used).

        """

    def summary(self) -> str:
        """Return the summary text: the solutions counted."""
        return f'{self.rows} solutions (not written)'


@dataclass(frozen=True)
class SinsRun:
    """
    The SINS over one recording.

    Attributes
    ----------
    counts : dict
        Messages read: ``gyro`` and ``accel``.
    rates : dict
        ``gyro_rate`` and ``accel_rate`` used, Hz.
    gyro_topic, accel_topic : str
        The topics read (``accel_topic`` '' without Δv).
    imu_input : bool
        The gyro stream is sensor_msgs/Imu rates.
    accel_from_imu : bool
        The Δv come from the same Imu messages' linear acceleration.
    rate_rule : str
        How rate samples became increments.
    drops : dict
        What the input rules dropped, by reason (non-zero counts only).
    gyro : dict
        ``missing`` increments, ``gaps`` and stamp ``resyncs`` of the gyro stream.
    nonfinite : int
        Non-finite updates discarded.
    stall : dict or None
        The accelerometer stall (``seconds``, ``level``, ``text``) as sins_node's /diagnostics
        would report it.
    status : dict
        The system's counters (:meth:`strapdown_ros.sins.SinsSystem.status`).
    navigation : bool
        The system navigated.
    no_solution : str or None
        Why there is no solution (no update, no navigation step, the alignment refused).
    output : str
        The sink's summary (the file and its rows).
    model : SensorModel
        The model the system ran with.
    notes : tuple of str
        The notes said while running.

    """

    counts: dict
    rates: dict
    gyro_topic: str
    accel_topic: str
    imu_input: bool
    accel_from_imu: bool
    rate_rule: str
    drops: dict
    gyro: dict
    nonfinite: int
    stall: dict | None
    status: dict
    navigation: bool
    no_solution: str | None
    output: str
    model: SensorModel
    notes: tuple = field(default_factory=tuple)


def recording_model(model: SensorModel, settings: SinsSettings, inp, say):
    """
    Return the sensor model with the recording's rates and body frame, and the rates.

    A rate or frame the model states must agree with the recording
    (:func:`~strapdown_ros.params.check_against_recording`: an error naming both otherwise);
    one it does not state is taken from the recording: ``gyro_rate``/``accel_rate`` from the
    stamps, ``frame_id`` from the Δθ headers.

    Parameters
    ----------
    model : SensorModel
        The model as read.
    settings : SinsSettings
        The SINS settings (navigation: the initial position is checked).
    inp : ImuRecording
        The open recording.
    say : callable
        ``say(text)`` for the notes.

    Returns
    -------
    model : SensorModel
        The model for the run.
    rates : dict
        ``gyro_rate`` and ``accel_rate``, Hz.

    Raises
    ------
    ValueError
        The model contradicts the recording, or the initial position is not near the Earth.

    """
    read = model
    frames = [f for f, _ in inp.gyro.frames() if f]
    model = check_against_recording(model, {'gyro_rate_hz': inp.gyro_rate,
                                            'gyro_frames': frames})
    if inp.imu_input and inp.accel is None and 'accel_rate' not in model.stated:
        inp.accel_rate = model.gyro_rate            # Δv from the same Imu messages
    if inp.accel_rate and 'accel_rate' not in model.stated:
        model = model.with_values({'accel_rate': float(inp.accel_rate)},
                                  rule='the median step of the accelerometer stamps')
    rates = {'gyro_rate': model.gyro_rate, 'accel_rate': model.accel_rate}
    for name in ('gyro_rate', 'accel_rate'):
        if name not in read.stated and getattr(read, name) != rates[name]:
            say(f'note: {name} {rates[name]:g} Hz from the stamps')
    # the body frame: the recording's own, unless the model states one
    if 'frame_id' not in model.stated and inp.frame_id and inp.frame_id != model.frame_id:
        model = model.with_values({'frame_id': inp.frame_id},
                                  rule="the recording's Δθ headers")
        say(f"note: frame_id {bounded(inp.frame_id)!r} from the recording's headers "
            '(-p frame_id:=... to impose one)')
    others = [(f, c) for f, c in inp.gyro.frames() if f and f != model.frame_id]
    if others:
        total = len(inp.gyro)
        kind = 'Imu' if inp.imu_input else 'Δθ'
        listed = ', '.join(f'{bounded(f)!r} ({c})' for f, c in others[:3])
        say(f'note: {sum(c for _, c in others)} of {total} {kind} message(s) '
            'name another frame than the body frame and are rejected by the frame rule: '
            + listed + (', …' if len(others) > 3 else ''))
    if settings.navigation:
        pos = settings.navigation_settings.initial_position
        lat, lon, h = (float(x) for x in pos)
        r = float(np.linalg.norm(geodetic_to_ecef(np.radians(lat), np.radians(lon), h)))
        if not 6.0e6 < r < 8.0e6:
            raise ValueError(f'initial_position {list(pos)} is not within '
                             "±1000 km of the Earth's surface")
    return model, rates


def no_solution(system: SinsSystem) -> str | None:
    """
    Return why there is no solution (no update, no navigation step), or None.

    Parameters
    ----------
    system : SinsSystem
        The system after the recording.

    Returns
    -------
    str or None
        The reason in words.

    """
    nav = system.nav
    no_steps = nav is not None and (nav.navigator is None or nav.navigator.steps == 0)
    if system.integrator.updates and not no_steps:
        return None
    if nav is not None and nav.navigator is None:
        refused = nav.alignment is not None and not nav.alignment.ok
        why = ('the static alignment did not complete (alignment_time '
               f'{float(system.settings.navigation_settings.alignment_time):g} s'
               + (f'; last refusal: {nav.alignment.reason}' if refused else '') + ')')
    elif system.integrator.updates == 0:
        why = 'no attitude update'
    else:
        why = 'no navigation step'
    if system.integrator.updates == 0 and system.frame_mismatch['gyro'] \
            and system.gyro_check.accepted == 0:
        why = ('every Δθ was rejected: its header.frame_id is not frame_id '
               f'{bounded(system.model.frame_id)!r} '
               '(-p frame_id:=... or -p frame_mismatch:=accept)')
    return why


def _drops(system: SinsSystem) -> dict:
    """Return what the input rules dropped, by reason (non-zero only)."""
    checks = [system.gyro_check, system.accel_check] + list(system.rate_checks.values())
    drops = {k: sum(getattr(c, attr) for c in checks)
             for k, attr in (('NaN', 'nan'), ('out of range', 'out_of_range'),
                             ('out of order', 'out_of_order'), ('duplicate', 'duplicate'),
                             ('stamp outlier', 'stamp_outliers'))}
    drops = {k: v for k, v in drops.items() if v}
    fm = system.frame_mismatch
    if fm['gyro'] or fm['accel']:
        how = 'rejected' if system.reject_frames else 'used'
        drops[f'frame mismatch ({how})'] = fm['gyro'] + fm['accel']
    return drops


def run_sins(source: RecordingSource, model: SensorModel, settings: SinsSettings | None = None,
             make_sink=None, say=None, reading=None, imu_output: bool = False,
             who: str = 'sins_bag') -> SinsRun:
    """
    Run sins_node's core over a recording and hand every output block to a sink.

    Parameters
    ----------
    source : RecordingSource
        The recording: ``gyro_topic``, ``accel_topic`` or ``imu_topic``, ``rate_rule``.
    model : SensorModel
        The unit's sensor model.
    settings : SinsSettings, optional
        The SINS settings (default: the defaults).
    make_sink : callable, optional
        ``make_sink(system, namespace)`` returns the sink (``write(out)``, ``close(ok)``,
        ``summary()``); default :class:`CountingSink`.
    say : callable, optional
        ``say(text)`` for notes and progress.
    reading : callable, optional
        ``reading(log_ns, start_ns, end_ns)`` while the streams are read.
    imu_output : bool
        Make the sins/imu outputs too (an MCAP sink publishes them).
    who : str
        The consumer named in the note on model keys the SINS does not apply.

    Returns
    -------
    SinsRun
        What was read and done.

    Raises
    ------
    BagError
        The bag cannot be used.
    ValueError
        The model contradicts the recording; invalid settings; both ``imu_topic`` and another
        topic.
    SinkError
        The sink could not be made.

    """
    settings = settings or SinsSettings()
    notes: list[str] = []

    def note(text: str) -> None:
        notes.append(text)
        if say is not None:
            say(text)

    if source.imu_topic and (source.gyro_topic or source.accel_topic):
        raise ValueError('--imu-topic gives both streams: not with --gyro-topic/--accel-topic')
    inp = open_input(source.path, source.namespace, source.gyro_topic, source.accel_topic,
                     need_accel=bool(settings.navigation), imu_topic=source.imu_topic,
                     progress=reading)
    sink = None
    ok = False
    try:
        model, rates = recording_model(model, settings, inp, note)
        text = not_applied_note(model, ('gyro', 'accel'), who)
        if text:
            note(f'note: {text}')

        def make_system():
            return SinsSystem(model, settings,
                              log=lambda level, text: note(text if level == 'info'
                                                           else f'{level}: {text}'),
                              imu_wanted=(lambda: bool(imu_output)))
        system = make_system()                          # parameters checked by the core now
        try:
            sink = (make_sink or (lambda s, ns: CountingSink(s.nav is not None)))(
                system, inp.namespace)
        except Exception as exc:  # noqa: BLE001 - the writer's own refusal, in one line
            raise SinkError(str(exc)) from exc
        counts, system = run(inp, make_system, sink, note, source.rate_rule, system)
        ok = True
    finally:
        inp.close()
        if sink is not None:
            sink.close(ok)
    g = system.gyro_check
    a_topic = bounded(inp.accel_conn.topic) if inp.accel_conn is not None else ''
    stall = system.accel_stall(a_topic or 'imu/delta_velocity')   # sins_node's /diagnostics
    return SinsRun(
        counts=dict(counts), rates=dict(rates), gyro_topic=bounded(inp.gyro_conn.topic),
        accel_topic=a_topic, imu_input=bool(inp.imu_input),
        accel_from_imu=bool(inp.imu_input and inp.accel is None), rate_rule=source.rate_rule,
        drops=_drops(system), gyro={'missing': g.missing, 'gaps': g.gaps, 'resyncs': g.resyncs},
        nonfinite=int(system.nonfinite),
        stall=None if stall is None else {'seconds': float(stall.seconds),
                                          'level': stall.level, 'text': stall.text},
        status=system.status(), navigation=system.nav is not None,
        no_solution=no_solution(system), output=sink.summary(), model=model, notes=tuple(notes))
