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

from strapdown_ros.params import check_against_recording
from strapdown_ros.recording import read_bag, recording_facts
from strapdown_ros.sensors.sensor_model import SensorModel

__all__ = ['RecordingSource', 'read_checked']


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
