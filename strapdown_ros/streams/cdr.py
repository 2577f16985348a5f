"""
Reading the increment messages straight from their serialized bytes.

Used by the nodes' raw subscriptions (:func:`strapdown_ros.nodes.ros_io.decode_vector3_stamped`)
and by ``sins_bag`` (rosbag2 stores the same bytes).  No ROS imports: each caller hands the
other encodings to its own deserializer (rclpy's, or rosbags').

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

import numpy as np

__all__ = ['vector3_stamped', 'imu', 'imu_rate_covariance', 'stamped_doubles']

# header.stamp.sec, .nanosec, length of frame_id (with its NUL)
_STAMP_AND_LENGTH = struct.Struct('<iII')
_XYZ = struct.Struct('<3d')
_F64 = struct.Struct('<d')


def vector3_stamped(data, exact: bool = False):
    """
    Decode a Vector3Stamped from plain little-endian CDR bytes.

    Parameters
    ----------
    data : bytes-like
        The serialized message (any buffer).
    exact : bool
        Also refuse bytes longer than the layout (beyond 3 bytes of padding): those of a longer
        message, e.g. a QuaternionStamped, would otherwise decode as a Vector3Stamped.

    Returns
    -------
    (int, (float, float, float), str) or None
        ``(stamp_ns, (x, y, z), frame_id)``; None for any other encoding or bytes too short (or,
        ``exact``, too long) for the layout.

    """
    if len(data) >= 16 and data[0] == 0 and data[1] == 1:
        sec, nanosec, n = _STAMP_AND_LENGTH.unpack_from(data, 4)
        end = 16 + n
        off = 4 + ((end - 4 + 7) & ~7)
        if off + 24 <= len(data) and not (exact and len(data) > off + 27):
            frame = bytes(data[16:end - 1]).decode('utf-8', 'replace') if n else ''
            return sec * 1_000_000_000 + nanosec, _XYZ.unpack_from(data, off), frame
    return None


_IMU_DOUBLES = 37
_IMU_RATE = 13                  # index of angular_velocity.x among the 37 float64
_IMU_RATE_COV = 16              # angular_velocity_covariance[0]
_IMU_ACCEL = 25                 # linear_acceleration.x
_IMU_ACCEL_COV = 28             # linear_acceleration_covariance[0]


_XYZ_T = tuple[float, float, float]


def imu(data) -> tuple[int, _XYZ_T, _XYZ_T | None, str] | None:
    """
    Decode a sensor_msgs/Imu from plain little-endian CDR bytes.

    Parameters
    ----------
    data : bytes-like
        The serialized message (any buffer).

    Returns
    -------
    (int, tuple, tuple or None, str) or None
        ``(stamp_ns, angular_velocity, linear_acceleration, frame_id)``; ``linear_acceleration``
        is None when the message says it has none (REP-145: linear_acceleration_covariance[0] =
        −1).  None for any other encoding or bytes too short for the layout.

    """
    if len(data) >= 16 and data[0] == 0 and data[1] == 1:
        sec, nanosec, n = _STAMP_AND_LENGTH.unpack_from(data, 4)
        end = 16 + n
        off = 4 + ((end - 4 + 7) & ~7)
        if off + 8 * _IMU_DOUBLES <= len(data):
            frame = bytes(data[16:end - 1]).decode('utf-8', 'replace') if n else ''
            rate = _XYZ.unpack_from(data, off + 8 * _IMU_RATE)
            accel = None
            if _F64.unpack_from(data, off + 8 * _IMU_ACCEL_COV)[0] != -1.0:
                accel = _XYZ.unpack_from(data, off + 8 * _IMU_ACCEL)
            return sec * 1_000_000_000 + nanosec, rate, accel, frame
    return None


_COV = struct.Struct('<9d')


def imu_rate_covariance(data) -> tuple | None:
    """
    Decode the angular velocity covariance of a sensor_msgs/Imu from CDR bytes.

    Parameters
    ----------
    data : bytes-like
        The serialized message, plain little-endian CDR.

    Returns
    -------
    tuple of 9 float or None
        angular_velocity_covariance, row-major, (rad/s)²; None for any other encoding or short
        bytes.

    """
    if len(data) >= 16 and data[0] == 0 and data[1] == 1:
        n = _STAMP_AND_LENGTH.unpack_from(data, 4)[2]
        off = 4 + ((16 + n - 4 + 7) & ~7)
        if off + 8 * _IMU_DOUBLES <= len(data):
            return _COV.unpack_from(data, off + 8 * _IMU_RATE_COV)
    return None


def stamped_doubles(records, count: int):
    """
    Decode many stamped messages at once with numpy.

    Many stamped messages at once: a std_msgs/Header followed by ``count`` float64 fields in
    plain little-endian CDR (geometry_msgs/Vector3Stamped: 3; sensor_msgs/Imu: 37 — orientation 4,
    its covariance 9, angular_velocity 3, its covariance 9, linear_acceleration 3, its covariance
    9), decoded with numpy over records grouped by length and frame-id length.

    Parameters
    ----------
    records : sequence of bytes-like, or ndarray (n, L) uint8
        The serialized messages (rosbag2 records), in bag order; or n records of L bytes each
        as the rows of an array.
    count : int
        Number of float64 fields after the header.

    Returns
    -------
    stamps_ns : ndarray (n,) int64
        header.stamp, ns (0 where not decoded).
    values : ndarray (n, count) float64
        The fields (NaN where not decoded).
    frame_index : ndarray (n,) int64
        Index of each record's header.frame_id in ``frame_names``; -1 where not decoded.
    frame_names : list of str
        The distinct frame ids, in order of first appearance by group.
    undecoded : ndarray of int
        Indices of the records in another encoding or too short for the layout: the caller
        hands them to a deserializer.  Every decoded record equals :func:`vector3_stamped`'s
        reading of it (for ``count`` 3).

    """
    n = len(records)
    stamps = np.zeros(n, np.int64)
    values = np.full((n, count), np.nan)
    index = np.full(n, -1, np.int64)
    names: list[str] = []
    known: dict[str, int] = {}
    if n == 0:
        return stamps, values, index, names, np.zeros(0, np.int64)
    table = isinstance(records, np.ndarray) and records.ndim == 2      # rows of equal length
    if table:
        groups = [(records.shape[1], None)]
    else:
        lengths = np.fromiter(map(len, records), np.int64, n)
        same = bool(np.all(lengths == lengths[0]))
        groups = [(int(lengths[0]), None)] if same else [(int(L), np.flatnonzero(lengths == L))
                                                         for L in np.unique(lengths)]
    for length, rows in groups:
        if length < 16:
            continue
        if table:
            buf = records
        else:
            part = records if rows is None else [records[i] for i in rows]
            buf = np.frombuffer(b''.join(part), np.uint8).reshape(len(part), length)
        rows = np.arange(n) if rows is None else rows
        ok = (buf[:, 0] == 0) & (buf[:, 1] == 1)
        head = np.ascontiguousarray(buf[:, 4:16]).view('<u4')       # sec, nanosec, len(frame_id)
        slen = head[:, 2]
        sizes = [int(slen[0])] if ok.all() and np.all(slen == slen[0]) else \
            [int(s) for s in np.unique(slen[ok])]
        for s in sizes:
            end = 16 + s
            off = 4 + ((end - 4 + 7) & ~7)
            if off + 8 * count > length:
                continue
            sel = ok & (slen == s) if len(sizes) > 1 or not ok.all() else slice(None)
            sub, hd, dst = buf[sel], head[sel], rows[sel]
            stamps[dst] = hd[:, 0].view('<i4').astype(np.int64) * 1_000_000_000 + hd[:, 1]
            values[dst] = np.ascontiguousarray(sub[:, off:off + 8 * count]).view('<f8')
            if s <= 1:
                frames, inverse = [b''], np.zeros(len(dst), np.int64)
            else:
                raw = np.ascontiguousarray(sub[:, 16:end - 1])
                if np.all(raw == raw[0]):
                    frames, inverse = [raw[0].tobytes()], np.zeros(len(dst), np.int64)
                else:
                    uniq, inverse = np.unique(raw.view(f'V{s - 1}').ravel(), return_inverse=True)
                    frames = [u.tobytes() for u in uniq]
            codes = []
            for f in frames:
                name = f.decode('utf-8', 'replace')
                if name not in known:
                    known[name] = len(names)
                    names.append(name)
                codes.append(known[name])
            index[dst] = np.asarray(codes, np.int64)[inverse.ravel()]
    return stamps, values, index, names, np.flatnonzero(index < 0)
