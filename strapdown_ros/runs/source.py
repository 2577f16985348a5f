"""
A recording and how to read it: the typed input options of every library call of this room.

:class:`RecordingSource` names the bag and its input options (namespace, topics, the TF frames of
a reference, the rate rule of ``sensor_msgs/Imu`` rates); :func:`read_checked` reads it with the
nodes' input rules (:func:`strapdown_ros.recording.read_bag`) and checks the sensor model against
what the recording shows (:func:`strapdown_ros.params.check_against_recording`).  Frozen and
picklable: a Dask task takes it as it is.
"""
from __future__ import annotations

from dataclasses import dataclass

from strapdown_ros.params import check_against_recording, filled_in, not_applied_note
from strapdown_ros.recording import input_warnings, read_bag, recording_facts
from strapdown_ros.recording.options import frame_warnings, input_summary, usable_error
from strapdown_ros.sensors.sensor_model import SensorModel

__all__ = ['RecordingSource', 'read_checked', 'recording_notes', 'UnusableRecording',
           'check_usable']


class UnusableRecording(ValueError):
    """
    A stream of the recording has too little usable to work on (bad input, not a failure).

    Parameters
    ----------
    message : str
        The one line (:func:`strapdown_ros.recording.options.usable_error`).
    summary : dict
        What was read and how (:func:`strapdown_ros.recording.input_summary`), for the
        command's input lines.

    """

    def __init__(self, message: str, summary: dict):
        super().__init__(message)
        self.summary = summary

    def __reduce__(self):
        """Return how to pickle it (a Dask task's error crosses processes)."""
        return (type(self), (str(self), self.summary))


def check_usable(data: dict) -> None:
    """
    Refuse a recording with too little usable in a stream.

    Parameters
    ----------
    data : dict
        The streams of :func:`strapdown_ros.recording.read_bag`.

    Raises
    ------
    UnusableRecording
        Fewer than 2 gyro increments or no reference fix kept.

    """
    unusable = usable_error(data)
    if unusable:
        raise UnusableRecording(unusable, input_summary(data))


@dataclass(frozen=True)
class RecordingSource:
    """
    One recording and its input options.

    Attributes
    ----------
    path : str
        The rosbag2 bag directory, or a single ``.mcap`` / ``.db3`` file.
    namespace : str
        Topic namespace of the default (and relative) topic names.
    gyro_topic : str or None
        Δθ (Vector3Stamped) or rate (sensor_msgs/Imu) topic; None: the default.
    reference_topic : str or None
        Attitude reference topic; None: the camera's default topics.
    reference_frames : tuple of (str, str) or None
        PARENT, CHILD of a TF reference.
    rate_rule : str
        How an Imu rate sample becomes an increment (``trapezoid`` or ``mean``).
    accel_topic : str or None
        Δv topic (the SINS only); None: the default.
    imu_topic : str or None
        One sensor_msgs/Imu topic giving both Δθ and Δv (the SINS only).

    """

    path: str
    namespace: str = ''
    gyro_topic: str | None = None
    reference_topic: str | None = None
    reference_frames: tuple | None = None
    rate_rule: str = 'trapezoid'
    accel_topic: str | None = None
    imu_topic: str | None = None

    def read_options(self) -> dict:
        """
        Return the keyword options of :func:`strapdown_ros.recording.read_bag`.

        Returns
        -------
        dict
            ``gyro_topic``, ``reference_topic``, ``reference_frames``, ``rate_rule``.

        """
        frames = tuple(self.reference_frames) if self.reference_frames else None
        return {'gyro_topic': self.gyro_topic, 'reference_topic': self.reference_topic,
                'reference_frames': frames, 'rate_rule': self.rate_rule}


def read_checked(source: RecordingSource, model: SensorModel,
                 use_camera_covariance: bool = True, max_stamp_jump: float = 1.0,
                 resync_count: int = 5) -> tuple[dict, SensorModel]:
    """
    Read a recording with the nodes' input rules and check the model against it.

    Parameters
    ----------
    source : RecordingSource
        The recording.
    model : SensorModel
        The unit's sensor model: the σ of fixes without a covariance, the gyro clip level.
    use_camera_covariance : bool
        Use the covariance of the reference messages that carry one.
    max_stamp_jump : float
        Stamp jump limit, s.
    resync_count : int
        Messages that confirm a new timeline.

    Returns
    -------
    data : dict
        The streams of :func:`strapdown_ros.recording.read_bag`.
    model : SensorModel
        The model checked against the recording (an unstated gyro rate taken from the stamps).

    Raises
    ------
    BagError
        The bag cannot be used (one line).
    ValueError
        The model contradicts the recording (one line naming both).

    """
    data = read_bag(source.path, source.namespace, bool(use_camera_covariance),
                    tuple(model.camera_sigma), model.gyro_max_rate, float(max_stamp_jump),
                    int(resync_count), **source.read_options())
    return data, check_against_recording(model, recording_facts(data))


def recording_notes(who: str, data: dict, model: SensorModel, checked: SensorModel,
                    consumers: tuple) -> tuple[list[str], list[str], list[str]]:
    """
    Return what a command says about a recording and its model before the work, by kind.

    Each line lacks the command's ``who:`` prefix (it starts ``WARNING:``, ``warning:`` or
    ``note:``); the caller says them in its command's order.

    Parameters
    ----------
    who : str
        The command, named in the note on model keys it does not apply.
    data : dict
        The streams of :func:`strapdown_ros.recording.read_bag`, or a record holding
        :func:`strapdown_ros.recording.input_summary`.
    model : SensorModel
        The model as stated.
    checked : SensorModel
        The model checked against the recording (:func:`read_checked`).
    consumers : tuple of str
        The consumers of the model keys the command applies (``gyro``, ``reference``,
        ``filter``).

    Returns
    -------
    inputs : list of str
        The warnings on the input (an index that disagrees with what was read, clipped
        increments, rate samples dropped).
    frames : list of str
        The warnings on header frames the model does not expect.
    notes : list of str
        The notes on the model: keys filled in from the recording, keys not applied.

    """
    prefix = f'{who}: '

    def bare(lines):
        return [line[len(prefix):] if line.startswith(prefix) else line for line in lines]
    notes = [f'note: {line}' for line in filled_in(model, checked)]
    text = not_applied_note(checked, consumers, who)
    if text:
        notes.append(f'note: {text}')
    return (bare(input_warnings(who, data)),
            bare(frame_warnings(who, data, checked.frame_id, checked.reference_frame_id)), notes)
