"""Reading the increment messages straight from their serialized bytes, for the nodes' raw
subscriptions (:func:`strapdown_ros.nodes.ros_io.decode_vector3_stamped`) and for ``sins_bag``
(rosbag2 stores the same bytes).  No ROS imports: each caller hands the other encodings to its own
deserializer (rclpy's, or rosbags').

geometry_msgs/Vector3Stamped in plain little-endian CDR (encapsulation 0x0001, what
rmw_fastrtps and rmw_cyclonedds write): 4 bytes of encapsulation, int32 sec, uint32 nanosec, the
frame_id as uint32 length (its terminating NUL included) and bytes, then x, y, z as float64
aligned to 8 bytes counted from the end of the encapsulation.
"""
from __future__ import annotations

import struct

__all__ = ["vector3_stamped"]

_STAMP_AND_LENGTH = struct.Struct("<iII")     # header.stamp.sec, .nanosec, length of frame_id (with its NUL)
_XYZ = struct.Struct("<3d")


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
