"""
Real recordings: a public IMU + optical-motion-capture data set turned into rosbag2 bags.

The data set read here is **RepoIMU** (Szczęsna et al., 2016; see ``test/data/README.md``): an
IMU (accelerometer, gyroscope, magnetometer) on a T-shaped wand ("TStick", 100 Hz) or on the
segments of a three-segment pendulum (irregular stamps, mostly 6 ms apart), with the orientation
of the same rigid body from a Vicon optical motion-capture system, synchronised by the authors
onto the IMU's time base.
One trial is one ``;``-separated CSV file: time (s), Vicon quaternion w, x, y, z, then the IMU's
acceleration (m/s²), angular rate (rad/s) and magnetic field, body axes.

Frames (stated once):

* ``imu_frame`` (``repoimu_imu``): the IMU's measurement axes; gyro and accelerometer samples.
* ``reference_frame`` (``repoimu_vicon``): the motion-capture world frame.
* The Vicon quaternion is the orientation of the rigid body's marker frame (``marker_frame``,
  ``repoimu_marker``) in ``reference_frame``: q_vicon_marker, mapping marker coordinates to Vicon
  world coordinates (the ROS meaning of a pose orientation).  The authors aligned it with the IMU
  axes (it starts at the identity); the remaining rotation between marker and IMU axes is the
  "boresight" the tools estimate (``camera`` = marker frame VF, ``body`` = IMU frame MF).

Bags written (:func:`write_bag`), either or both formats of each stream:

* real formats: ``imu/data`` sensor_msgs/msg/Imu (angular_velocity rad/s, linear_acceleration
  m/s², orientation unknown: ``orientation_covariance[0] = -1``) and ``mocap/pose``
  geometry_msgs/msg/PoseStamped (orientation q_vicon_marker; the data set has no positions, the
  position is written as zero);
* the package's own: ``imu/delta_theta`` geometry_msgs/msg/Vector3Stamped (Δθ from the rate
  samples by :func:`strapdown_ros.streams.rate_increments.increments_from_rates`, trapezoid rule,
  each stamped at the end of its interval) and ``star_camera/attitude``
  geometry_msgs/msg/QuaternionStamped (the same q_vicon_marker).

The reference is decimated to one fix per ``reference_interval_s`` (default 1 s, like a star
camera); stamps are the data set's own (seconds since the start of the recording, plus
``stamp_origin_ns``).  No rclpy and no message packages: messages are serialised with
``rosbags``.
"""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from strapdown_ros.rotation import (quat_angle_between, quat_conjugate, quat_multiply,
                                    quat_normalize, quat_to_rotvec, to_ros_xyzw)
from strapdown_ros.streams.rate_increments import increments_from_rates

__all__ = ['ImuTrial', 'read_repoimu_csv', 'repoimu_trials', 'find_repoimu', 'reference_indices',
           'write_bag', 'REALDATA_ENV', 'TOPICS', 'GYRO_FORMATS',
           'REFERENCE_FORMATS', 'rest_mean_rate', 'xcorr_lag_s',
           'rate_plateau_samples', 'irregular_step_fraction']

#: environment variable naming a directory with RepoIMU's ``TStick/`` and ``Pendulum/`` folders
REALDATA_ENV = 'STRAPDOWN_REALDATA'
#: topic -> message type of the bags written by :func:`write_bag`
TOPICS = {
    'imu/data': 'sensor_msgs/msg/Imu',
    'mocap/pose': 'geometry_msgs/msg/PoseStamped',
    'imu/delta_theta': 'geometry_msgs/msg/Vector3Stamped',
    'star_camera/attitude': 'geometry_msgs/msg/QuaternionStamped',
}
GYRO_FORMATS = {'imu': ('imu/data',), 'delta_theta': ('imu/delta_theta',),
                'both': ('imu/data', 'imu/delta_theta')}
REFERENCE_FORMATS = {'pose': ('mocap/pose',), 'quaternion': ('star_camera/attitude',),
                     'both': ('mocap/pose', 'star_camera/attitude')}
_NS = 1_000_000_000


@dataclasses.dataclass(frozen=True)
class ImuTrial:
    """
    One recording: IMU rate samples and the reference attitude, both with their stamps.

    Attributes
    ----------
    name : str
        Trial name (the CSV file's stem).
    stamps_ns : ndarray of int64, shape (n,)
        IMU sample stamps, ns.
    gyro : ndarray, shape (n, 3)
        Angular rate, rad/s, IMU axes.
    accel : ndarray, shape (n, 3)
        Specific force, m/s², IMU axes.
    reference_stamps_ns : ndarray of int64, shape (m,)
        Reference (motion capture) stamps, ns.
    q_reference_marker : ndarray, shape (m, 4)
        Orientation of the marker frame in the reference frame, scalar-first, unit.
    imu_frame, reference_frame, marker_frame : str
        Frame names written into the headers (see the module docstring).
    reference_positions_m : ndarray, shape (m, 3), optional
        Position of the marker frame in the reference frame, m (None: unknown, written as 0).

    """

    name: str
    stamps_ns: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    reference_stamps_ns: np.ndarray
    q_reference_marker: np.ndarray
    imu_frame: str = 'repoimu_imu'
    reference_frame: str = 'repoimu_vicon'
    marker_frame: str = 'repoimu_marker'
    reference_positions_m: np.ndarray | None = None

    @property
    def duration_s(self) -> float:
        """Span of the IMU stamps, s."""
        return float(self.stamps_ns[-1] - self.stamps_ns[0]) / _NS if len(self.stamps_ns) else 0.0

    def excerpt(self, start_s: float, end_s: float) -> 'ImuTrial':
        """
        Return the samples with stamps in a window after the first stamp.

        Parameters
        ----------
        start_s, end_s : float
            Window, s after the first IMU stamp.

        Returns
        -------
        ImuTrial
            The same trial restricted to the window (both streams).

        """
        t0 = int(self.stamps_ns[0])
        lo, hi = t0 + int(round(start_s * _NS)), t0 + int(round(end_s * _NS))
        k = (self.stamps_ns >= lo) & (self.stamps_ns <= hi)
        r = (self.reference_stamps_ns >= lo) & (self.reference_stamps_ns <= hi)
        pos = self.reference_positions_m
        return dataclasses.replace(self, stamps_ns=self.stamps_ns[k], gyro=self.gyro[k],
                                   accel=self.accel[k],
                                   reference_stamps_ns=self.reference_stamps_ns[r],
                                   q_reference_marker=self.q_reference_marker[r],
                                   reference_positions_m=None if pos is None else pos[r])


def read_repoimu_csv(path, stamp_origin_ns: int = 0) -> ImuTrial:
    """
    One RepoIMU trial from its CSV file.

    Rows whose Vicon quaternion is zero or not finite (the static trials carry none) are kept for
    the IMU and left out of the reference; rows with a non-finite IMU value are dropped from the
    IMU stream.  Nothing else is changed: the quaternion is normalised, not otherwise edited.

    Parameters
    ----------
    path : str or Path
        The CSV file (two header lines, then ``t;qw;qx;qy;qz;ax;ay;az;gx;gy;gz;mx;my;mz``).
    stamp_origin_ns : int
        Added to the file's times (s since the start of the recording), ns.

    Returns
    -------
    ImuTrial
        Rates in rad/s and accelerations in m/s² as in the file; reference q_vicon_marker.

    Raises
    ------
    ValueError
        The file has not the columns of a RepoIMU trial, or no row.

    """
    path = Path(path)
    data = np.genfromtxt(path, delimiter=';', skip_header=2, usecols=range(14))
    if data.ndim != 2 or data.shape[0] == 0 or data.shape[1] != 14:
        raise ValueError(f"{path}: not a RepoIMU trial (expected 14 ';'-separated columns)")
    t = data[:, 0]
    stamps = stamp_origin_ns + np.round(t * _NS).astype(np.int64)
    q = data[:, 1:5]
    acc, gyro = data[:, 5:8], data[:, 8:11]
    ok_imu = np.isfinite(t) & np.all(np.isfinite(gyro), axis=1) & np.all(np.isfinite(acc), axis=1)
    norm = np.linalg.norm(q, axis=1)
    ok_ref = np.isfinite(t) & np.isfinite(norm) & (norm > 0.5)
    return ImuTrial(path.stem, stamps[ok_imu], gyro[ok_imu], acc[ok_imu], stamps[ok_ref],
                    quat_normalize(q[ok_ref]))


def repoimu_trials(root, kinds=('TStick', 'Pendulum')) -> list[Path]:
    """
    List the trial files of a RepoIMU copy that have a reference attitude.

    Parameters
    ----------
    root : str or Path
        Directory holding ``TStick/`` and ``Pendulum/``.
    kinds : sequence of str
        Sub-directories to list.

    Returns
    -------
    list of Path
        CSV files; the static trials (``*Static*``: no Vicon orientation) are not listed.

    """
    root = Path(root)
    out = []
    for kind in kinds:
        out += [p for p in sorted((root / kind).glob('*.csv')) if 'Static' not in p.name]
    return out


def find_repoimu() -> Path | None:
    """
    Where a RepoIMU copy is, from ``$STRAPDOWN_REALDATA``, or None.

    The data set has no licence, so it is not shipped; it is found only through the environment
    variable :data:`REALDATA_ENV` naming a directory with ``TStick/`` (and ``Pendulum/``).

    Returns
    -------
    Path or None
        That directory, or None when the variable is unset or names no directory with
        ``TStick/``.

    """
    env = os.environ.get(REALDATA_ENV, '').strip()
    if not env:
        return None
    p = Path(env)
    return p if (p / 'TStick').is_dir() else None


def reference_indices(stamps_ns, interval_s: float) -> np.ndarray:
    """
    Return the reference samples kept when decimating to one fix per ``interval_s``.

    The first sample at or after each multiple of ``interval_s`` from the first stamp is kept.

    Parameters
    ----------
    stamps_ns : array_like of int
        Reference stamps, ns, increasing.
    interval_s : float
        Time between kept fixes, s (> 0).

    Returns
    -------
    ndarray of int
        Indices into ``stamps_ns``.

    """
    if not interval_s > 0:
        raise ValueError(f'interval_s must be > 0, got {interval_s}')
    s = np.asarray(stamps_ns, dtype=np.int64)
    if len(s) == 0:
        return np.zeros(0, dtype=int)
    slot = (s - s[0]) // int(round(interval_s * _NS))
    return np.flatnonzero(np.r_[True, np.diff(slot) > 0])


class _Messages:
    """rosbags message builders (ROS 2 Jazzy type store)."""

    def __init__(self, store):
        self.store = store
        self.T = store.types

    def header(self, ns: int, frame_id: str):
        T = self.T
        return T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
            sec=int(ns // _NS), nanosec=int(ns % _NS)), frame_id=frame_id)

    def vector3(self, v):
        return self.T['geometry_msgs/msg/Vector3'](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def quaternion(self, q_wxyz):
        x, y, z, w = (float(c) for c in to_ros_xyzw(np.asarray(q_wxyz, dtype=float)))
        return self.T['geometry_msgs/msg/Quaternion'](x=x, y=y, z=z, w=w)

    def serialize(self, msg) -> bytes:
        return self.store.serialize_cdr(msg, msg.__msgtype__)

    def imu(self, ns, frame, rate, acc) -> bytes:
        T = self.T
        cov_unknown = np.zeros(9)
        cov_orientation = np.zeros(9)
        cov_orientation[0] = -1.0                # REP-145: no orientation estimate
        m = T['sensor_msgs/msg/Imu'](
            header=self.header(ns, frame), orientation=self.quaternion([1.0, 0.0, 0.0, 0.0]),
            orientation_covariance=cov_orientation, angular_velocity=self.vector3(rate),
            angular_velocity_covariance=cov_unknown, linear_acceleration=self.vector3(acc),
            linear_acceleration_covariance=cov_unknown)
        return self.serialize(m)

    def pose(self, ns, frame, q, position=(0.0, 0.0, 0.0)) -> bytes:
        T = self.T
        x, y, z = (float(c) for c in position)
        m = T['geometry_msgs/msg/PoseStamped'](header=self.header(ns, frame), pose=T[
            'geometry_msgs/msg/Pose'](position=T['geometry_msgs/msg/Point'](x=x, y=y, z=z),
                                      orientation=self.quaternion(q)))
        return self.serialize(m)

    def vector3_stamped(self, ns, frame, v) -> bytes:
        return self.serialize(self.T['geometry_msgs/msg/Vector3Stamped'](
            header=self.header(ns, frame), vector=self.vector3(v)))

    def quaternion_stamped(self, ns, frame, q) -> bytes:
        return self.serialize(self.T['geometry_msgs/msg/QuaternionStamped'](
            header=self.header(ns, frame), quaternion=self.quaternion(q)))


def write_bag(bag, trial: ImuTrial, gyro_format: str = 'imu', reference_format: str = 'pose',
              reference_interval_s: float | None = 1.0, storage: str = 'mcap',
              compression: str = 'none') -> dict:
    """
    Write one trial (or an excerpt) as a rosbag2 bag.

    Parameters
    ----------
    bag : str or Path
        Output bag directory; must not exist.
    trial : ImuTrial
        The recording.
    gyro_format : {'imu', 'delta_theta', 'both'}
        ``imu/data`` sensor_msgs/Imu rate samples, ``imu/delta_theta`` Δθ increments (trapezoid
        rule over consecutive samples at most 1.5 nominal periods apart), or both.
    reference_format : {'pose', 'quaternion', 'both'}
        ``mocap/pose`` PoseStamped, ``star_camera/attitude`` QuaternionStamped, or both.
    reference_interval_s : float or None
        Time between reference fixes written, s (the reference is decimated); None writes every
        reference sample (the full motion-capture rate).
    storage : {'mcap', 'sqlite3'}
        rosbag2 storage plug-in.
    compression : {'none', 'zstd'}
        ``zstd``: MCAP chunks compressed with zstd (rosbag2's storage compression; mcap only).

    Returns
    -------
    dict
        ``bag``, ``messages`` (per topic), ``duration_s``, ``gyro_rate_hz`` (from the stamps),
        ``reference_fixes``, ``frames``.

    """
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores

    if gyro_format not in GYRO_FORMATS:
        raise ValueError(f"gyro_format={gyro_format!r}; valid: {', '.join(GYRO_FORMATS)}")
    if reference_format not in REFERENCE_FORMATS:
        raise ValueError(f'reference_format={reference_format!r}; valid: '
                         f"{', '.join(REFERENCE_FORMATS)}")
    if storage not in ('mcap', 'sqlite3'):
        raise ValueError(f'storage={storage!r}; valid: mcap, sqlite3')
    if compression not in ('none', 'zstd') or (compression == 'zstd' and storage != 'mcap'):
        raise ValueError(f'compression={compression!r} with storage={storage!r}; valid: none, '
                         'or zstd with mcap')
    if len(trial.stamps_ns) < 2 or len(trial.reference_stamps_ns) < 2:
        raise ValueError(f'{trial.name}: fewer than 2 IMU samples or reference fixes')
    stamps = np.asarray(trial.stamps_ns, dtype=np.int64)
    period = float(np.median(np.diff(stamps))) / _NS
    ref_k = (np.arange(len(trial.reference_stamps_ns)) if reference_interval_s is None
             else reference_indices(trial.reference_stamps_ns, reference_interval_s))
    pos = trial.reference_positions_m
    names = GYRO_FORMATS[gyro_format] + REFERENCE_FORMATS[reference_format]
    store = get_typestore(Stores.ROS2_JAZZY)
    msgs = _Messages(store)
    batch = []                                   # (stamp, order, topic, bytes)
    if 'imu/data' in names:
        for ns, w, a in zip(stamps, trial.gyro, trial.accel):
            batch.append((int(ns), 0, 'imu/data', msgs.imu(int(ns), trial.imu_frame, w, a)))
    if 'imu/delta_theta' in names:
        ok = np.r_[True, np.diff(stamps) > 0]    # the integration rule wants increasing stamps
        inc_ns, dth = increments_from_rates(stamps[ok], trial.gyro[ok], rule='trapezoid',
                                            max_step_s=1.5 * period)
        for ns, v in zip(inc_ns, dth):
            batch.append((int(ns), 1, 'imu/delta_theta',
                          msgs.vector3_stamped(int(ns), trial.imu_frame, v)))
    for k in ref_k:
        ns = int(trial.reference_stamps_ns[k])
        q = trial.q_reference_marker[k]
        if 'mocap/pose' in names:
            batch.append((ns, 2, 'mocap/pose', msgs.pose(
                ns, trial.reference_frame, q, (0.0, 0.0, 0.0) if pos is None else pos[k])))
        if 'star_camera/attitude' in names:
            batch.append((ns, 3, 'star_camera/attitude',
                          msgs.quaternion_stamped(ns, trial.reference_frame, q)))
    batch.sort(key=lambda m: (m[0], m[1]))
    counts = {'/' + n: 0 for n in names}
    plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
    writer = Writer(Path(bag), version=Writer.VERSION_LATEST, storage_plugin=plugin)
    if compression == 'zstd':
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with writer:
        conns = {n: writer.add_connection('/' + n, TOPICS[n], typestore=store) for n in names}
        for ns, _, name, data in batch:
            writer.write(conns[name], ns, data)
            counts['/' + name] += 1
    return {'bag': str(bag), 'messages': counts, 'duration_s': trial.duration_s,
            'gyro_rate_hz': 1.0 / period if period > 0 else None,
            'reference_fixes': int(len(ref_k)),
            'frames': {'imu': trial.imu_frame, 'reference': trial.reference_frame,
                       'marker': trial.marker_frame}}


def rest_mean_rate(trial: ImuTrial, angle_deg: float = 0.5, margin_s: float = 0.5) -> dict:
    """
    Mean gyro rate over the rest at the start of a trial, the rest found from the reference.

    The rest ends ``margin_s`` before the reference attitude first departs more than
    ``angle_deg`` from its first value; the gyro is not used to find it.

    Parameters
    ----------
    trial : ImuTrial
        The recording.
    angle_deg : float
        Departure from the first reference attitude that ends the rest, degrees.
    margin_s : float
        Time taken off the end of the rest, s.

    Returns
    -------
    dict
        ``samples`` (gyro samples at rest), ``end_s`` (s after the first IMU stamp),
        ``mean_rad_s`` and ``sigma_rad_s`` (standard error of the mean, per axis), rad/s.

    """
    q = trial.q_reference_marker
    ang = quat_angle_between(q, np.broadcast_to(q[0], q.shape))
    moving = np.flatnonzero(ang > np.radians(angle_deg))
    stamps = trial.reference_stamps_ns
    end = int(stamps[moving[0]] if len(moving) else stamps[-1])
    end -= int(round(margin_s * _NS))
    rest = trial.stamps_ns < end
    n = int(rest.sum())
    out = {'samples': n, 'end_s': float(end - int(trial.stamps_ns[0])) / _NS,
           'mean_rad_s': None, 'sigma_rad_s': None}
    if n >= 2:
        g = trial.gyro[rest]
        out['mean_rad_s'] = g.mean(axis=0).tolist()
        out['sigma_rad_s'] = (g.std(axis=0, ddof=1) / np.sqrt(n)).tolist()
    return out


def xcorr_lag_s(trial: ImuTrial, max_lag_s: float = 0.3) -> float:
    """
    Lag of the gyro behind the reference from the cross-correlation of rate magnitudes, s.

    |ω| of the gyro and of the reference attitude differentiated (body increments
    q_{k−1}* ⊗ q_k over consecutive distinct stamps) are put on one uniform grid (the median
    IMU period, linear interpolation); the peak of their cross-correlation is refined by a
    parabola.  Positive: the gyro shows a motion later than the reference.

    Parameters
    ----------
    trial : ImuTrial
        The recording.
    max_lag_s : float
        Largest lag searched, s.

    Returns
    -------
    float
        Lag, s.

    Raises
    ------
    ValueError
        Too few samples, or the peak lies at the edge of the search.

    """
    ti, tr = trial.stamps_ns, trial.reference_stamps_ns
    keep_i = np.r_[True, np.diff(ti) > 0]
    keep_r = np.r_[True, np.diff(tr) > 0]
    ti, gi = ti[keep_i], trial.gyro[keep_i]
    tr, q = tr[keep_r], trial.q_reference_marker[keep_r]
    if len(ti) < 10 or len(tr) < 10:
        raise ValueError(f'{trial.name}: too few samples for a cross-correlation')
    period = float(np.median(np.diff(ti)))
    dq = quat_multiply(quat_conjugate(q[:-1]), q[1:])
    w_ref = np.linalg.norm(quat_to_rotvec(dq), axis=1) / (np.diff(tr) / _NS)
    t_ref = 0.5 * (tr[:-1] + tr[1:]).astype(float)
    lo, hi = max(ti[0], t_ref[0]), min(ti[-1], t_ref[-1])
    grid = np.arange(lo, hi, period)
    a = np.interp(grid, ti.astype(float), np.linalg.norm(gi, axis=1))
    b = np.interp(grid, t_ref, w_ref)
    a, b = a - a.mean(), b - b.mean()
    m = int(round(max_lag_s * _NS / period))
    lags = np.arange(-m, m + 1)
    cc = np.array([np.dot(a[max(0, L):len(a) + min(0, L)], b[max(0, -L):len(b) - max(0, L)])
                   for L in lags])
    k = int(np.argmax(cc))
    if k == 0 or k == len(lags) - 1:
        raise ValueError(f'{trial.name}: cross-correlation peak at the edge of ±{max_lag_s} s')
    y0, y1, y2 = cc[k - 1], cc[k], cc[k + 1]
    den = y0 - 2.0 * y1 + y2
    frac = 0.5 * (y0 - y2) / den if den != 0 else 0.0
    return float((lags[k] + frac) * period / _NS)


def rate_plateau_samples(trial: ImuTrial, rel: float = 0.999) -> list:
    """
    Find, per gyro axis, the samples on the plateau of the largest rate.

    Per gyro axis, the samples whose |rate| lies within ``1 − rel`` of that axis' largest
    |rate| in the trial.  A gyro that clips (saturates) sits on such a plateau for many samples;
    an unclipped peak reaches it for one or two.

    Parameters
    ----------
    trial : ImuTrial
        The recording.
    rel : float
        Fraction of the largest |rate| that counts as the plateau.

    Returns
    -------
    list of int
        Counts for x, y, z.

    """
    g = np.abs(np.asarray(trial.gyro, dtype=float))
    if len(g) == 0:
        return [0, 0, 0]
    return [int(np.sum(g[:, i] >= rel * g[:, i].max())) for i in range(3)]


def irregular_step_fraction(stamps_ns, tolerance: float = 0.1) -> float:
    """
    Fraction of stamp steps more than ``tolerance`` (relative) away from the median step.

    Parameters
    ----------
    stamps_ns : array_like of int
        Stamps, ns.
    tolerance : float
        Relative deviation from the median step that counts as irregular.

    Returns
    -------
    float
        In [0, 1]; 0 for fewer than two steps.

    """
    d = np.diff(np.asarray(stamps_ns, dtype=np.int64)).astype(float)
    if len(d) < 2:
        return 0.0
    med = float(np.median(d))
    return float(np.mean(np.abs(d - med) > tolerance * abs(med)))
