"""
Reading and writing recordings (rosbag2 bags) for the offline tools.

One reader of gyro increments or rate samples and of attitude references in the common ROS
message formats (:mod:`.reader`), the tools' input options and reports (:mod:`.options`), the
MCAP chunk reader of ``sins_bag`` (:mod:`.mcap_records`), the simulated-bag writer
(:mod:`.writer`), the RepoIMU converter (:mod:`.repoimu`) and that of the shipped real-data
excerpt, gaitmap's example recording (:mod:`.gaitmap`).

Imports rosbags (the ``tools`` extra); the numerical core never imports this package.
"""
from strapdown_ros.recording.options import (add_input_arguments, check_input_arguments,
                                             input_lines, input_options, input_summary,
                                             input_warnings, recording_facts)
from strapdown_ros.recording.reader import (Accepted, BagError, CAMERA_COV_TOPIC, CAMERA_TOPIC,
                                            DELTA_THETA_TYPE, GYRO_TOPIC, IMU_TYPE, open_reader,
                                            read_bag, REFERENCE_TYPES, resolve_topic)

__all__ = ['BagError', 'Accepted', 'open_reader', 'resolve_topic', 'read_bag', 'input_summary',
           'input_warnings', 'input_lines', 'add_input_arguments', 'input_options',
           'check_input_arguments', 'recording_facts', 'GYRO_TOPIC', 'CAMERA_TOPIC',
           'CAMERA_COV_TOPIC',
           'DELTA_THETA_TYPE', 'IMU_TYPE', 'REFERENCE_TYPES']
