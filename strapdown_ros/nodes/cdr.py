"""Reading the increment messages straight from their serialized bytes, for the nodes' raw
subscriptions (:func:`strapdown_ros.nodes.ros_io.decode_vector3_stamped`) and for ``sins_bag``
(rosbag2 stores the same bytes).  No ROS imports: each caller hands the other encodings to its own
deserializer (rclpy's, or rosbags').

geometry_msgs/Vector3Stamped in plain little-endian CDR (encapsulation 0x0001, what
rmw_fastrtps and rmw_cyclonedds write): 4 bytes of encapsulation, int32 sec, uint32 nanosec, the
frame_id as uint32 length (its terminating NUL included) and bytes, then x, y, z as float64
aligned to 8 bytes counted from the end of the encapsulation.

sensor_msgs/Imu has the same header, then 37 float64 from the same aligned offset: orientation
(x, y, z, w), its covariance (9), angular_velocity (3), its covariance (9), linear_acceleration
(3), its covariance (9).
"""
from __future__ import annotations

import struct

__all__ = ["vector3_stamped", "imu", "imu_rate_covariance"]

_STAMP_AND_LENGTH = struct.Struct("<iII")     # header.stamp.sec, .nanosec, length of frame_id (with its NUL)
_XYZ = struct.Struct("<3d")
_F64 = struct.Struct("<d")


def vector3_stamped(data) -> tuple[int, tuple[float, float, float], str] | None:
    """``(stamp_ns, (x, y, z), frame_id)`` from the bytes (any buffer) of a Vector3Stamped in plain
    little-endian CDR; None for any other encoding or bytes too short for the layout."""
    if len(data) >= 16 and data[0] == 0 and data[1] == 1:
        sec, nanosec, n = _STAMP_AND_LENGTH.unpack_from(data, 4)
        end = 16 + n
        off = 4 + ((end - 4 + 7) & ~7)
        if off + 24 <= len(data):
            frame = bytes(data[16:end - 1]).decode("utf-8", "replace") if n else ""
            return sec * 1_000_000_000 + nanosec, _XYZ.unpack_from(data, off), frame
    return None


_IMU_DOUBLES = 37
_IMU_RATE = 13                  # index of angular_velocity.x among the 37 float64
_IMU_RATE_COV = 16              # angular_velocity_covariance[0]
_IMU_ACCEL = 25                 # linear_acceleration.x
_IMU_ACCEL_COV = 28             # linear_acceleration_covariance[0]


_XYZ_T = tuple[float, float, float]


def imu(data) -> tuple[int, _XYZ_T, _XYZ_T | None, str] | None:
    """``(stamp_ns, angular_velocity, linear_acceleration, frame_id)`` from the bytes (any buffer)
    of a sensor_msgs/Imu in plain little-endian CDR; ``linear_acceleration`` is None when the
    message says it has none (REP-145: linear_acceleration_covariance[0] = −1).  None for any other
    encoding or bytes too short for the layout."""
    if len(data) >= 16 and data[0] == 0 and data[1] == 1:
        sec, nanosec, n = _STAMP_AND_LENGTH.unpack_from(data, 4)
        end = 16 + n
        off = 4 + ((end - 4 + 7) & ~7)
        if off + 8 * _IMU_DOUBLES <= len(data):
            frame = bytes(data[16:end - 1]).decode("utf-8", "replace") if n else ""
            rate = _XYZ.unpack_from(data, off + 8 * _IMU_RATE)
            accel = None
            if _F64.unpack_from(data, off + 8 * _IMU_ACCEL_COV)[0] != -1.0:
                accel = _XYZ.unpack_from(data, off + 8 * _IMU_ACCEL)
            return sec * 1_000_000_000 + nanosec, rate, accel, frame
    return None


_COV = struct.Struct("<9d")


def imu_rate_covariance(data) -> tuple | None:
    """angular_velocity_covariance (9 float64, row-major, (rad/s)²) from the bytes of a
    sensor_msgs/Imu in plain little-endian CDR; None for any other encoding or short bytes."""
    if len(data) >= 16 and data[0] == 0 and data[1] == 1:
        n = _STAMP_AND_LENGTH.unpack_from(data, 4)[2]
        off = 4 + ((16 + n - 4 + 7) & ~7)
        if off + 8 * _IMU_DOUBLES <= len(data):
            return _COV.unpack_from(data, off + 8 * _IMU_RATE_COV)
    return None
