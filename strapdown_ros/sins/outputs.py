"""
The outputs of the SINS core: attitude updates, sins/imu records and navigation steps.

Plain arrays with absolute header stamps (ns), made by :class:`strapdown_ros.sins.system.
SinsSystem` and published by ``sins_node`` or written by ``sins_bag``;
:func:`odometry_arrays` gives the nav_msgs/Odometry covariances and body velocity, and
:func:`accel_stall_limits` the one rule of the accelerometer stall.  No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from strapdown_ros.rotation import quat_to_dcm


class _Arrays:
    """Concatenation and emptiness of the output records (all fields are arrays along axis 0)."""

    def __len__(self) -> int:
        return len(self.stamp_ns)

    @classmethod
    def concat(cls, parts: list):
        if not parts:
            return cls.EMPTY
        if len(parts) == 1:
            return parts[0]
        return cls(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(cls)))


@dataclass
class AttitudeOutput(_Arrays):
    """Attitude updates (``sins/attitude``), M of them."""

    stamp_ns: np.ndarray        # (M,) int64 header stamp, ns (end of the update)
    attitude: np.ndarray        # (M, 4) q_ref_body, scalar-first
    covariance: np.ndarray      # (M, 3, 3) attitude error ε, body axes, rad²
    mean_rate: np.ndarray       # (M, 3) mean angular rate over the update, rad/s
    interval: np.ndarray        # (M,) update length, s

    @classmethod
    def empty(cls):
        """Return a record with no update (zero-length arrays)."""
        return cls(np.zeros(0, np.int64), np.zeros((0, 4)), np.zeros((0, 3, 3)), np.zeros((0, 3)),
                   np.zeros(0))


@dataclass
class ImuOutput(_Arrays):
    """
    The ``sins/imu`` records: attitude updates with their specific force.

    ``sins/imu`` records: the attitude updates once their accelerometer data arrived (or
    waited ``accel_wait``).  ``specific_force`` is the mean Δv/h over the update where
    ``has_accel``, zeros (and ``has_accel`` False) where no accelerometer data covered it.
    """

    stamp_ns: np.ndarray        # (M,) int64
    attitude: np.ndarray        # (M, 4) q_ref_body, scalar-first
    covariance: np.ndarray      # (M, 3, 3) body axes, rad²
    mean_rate: np.ndarray       # (M, 3) rad/s
    specific_force: np.ndarray  # (M, 3) m/s², body axes
    has_accel: np.ndarray       # (M,) bool

    @classmethod
    def empty(cls):
        """Return a record with no sins/imu record (zero-length arrays)."""
        return cls(np.zeros(0, np.int64), np.zeros((0, 4)), np.zeros((0, 3, 3)), np.zeros((0, 3)),
                   np.zeros((0, 3)), np.zeros(0, bool))


@dataclass
class NavigationOutput(_Arrays):
    """Navigation steps (``sins/odometry``), K of them (:class:`.navigator.NavigationBatch`)."""

    stamp_ns: np.ndarray        # (K,) int64
    position: np.ndarray        # (K, 3) ECEF, m
    velocity: np.ndarray        # (K, 3) ECEF, m/s
    attitude: np.ndarray        # (K, 4) q_earth_body, scalar-first
    covariance: np.ndarray      # (K, 9, 9) [δR, δW, ψ] (ψ about earth axes), m, m/s, rad
    extrapolated: np.ndarray    # (K,) bool: accelerometer data were extrapolated for the step

    @classmethod
    def empty(cls):
        """Return a record with no navigation step (zero-length arrays)."""
        return cls(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 4)),
                   np.zeros((0, 9, 9)), np.zeros(0, bool))


for _cls in (AttitudeOutput, ImuOutput, NavigationOutput):
    _cls.EMPTY = _cls.empty()          # shared: zero-length arrays, never written


@dataclass
class SinsOutput:
    """What one :meth:`SinsSystem.process` produced, in stamp order per stream."""

    attitude: AttitudeOutput
    imu: ImuOutput
    navigation: NavigationOutput


#: what a call that produced nothing returns (zero-length arrays, never written)
NO_OUTPUT = SinsOutput(AttitudeOutput.EMPTY, ImuOutput.EMPTY, NavigationOutput.EMPTY)


def odometry_arrays(nav: NavigationOutput,
                    rate_variance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return the nav_msgs/Odometry numbers of navigation steps (REP-105).

    Parameters
    ----------
    nav : NavigationOutput
        K navigation steps.
    rate_variance : float
        Variance of the angular rate per axis, (rad/s)², for the twist's angular block (the
        rate itself is on sins/imu; twist.angular is not filled).

    Returns
    -------
    pose_covariance : ndarray (K, 36)
        Row-major 6×6 covariance of [position, ψ about earth axes], m², rad².
    body_velocity : ndarray (K, 3)
        Velocity in body axes, m/s.
    twist_covariance : ndarray (K, 36)
        Row-major 6×6 covariance of [body velocity, angular rate].

    """
    k = len(nav)
    p = nav.covariance
    c6 = np.zeros((k, 6, 6))
    c6[:, :3, :3], c6[:, :3, 3:] = p[:, :3, :3], p[:, :3, 6:]
    c6[:, 3:, :3], c6[:, 3:, 3:] = p[:, 6:, :3], p[:, 6:, 6:]
    c = quat_to_dcm(nav.attitude).reshape(k, 3, 3)              # C_E_B: twist in body axes
    ct = np.swapaxes(c, -1, -2)
    vb = np.einsum('kij,kj->ki', ct, nav.velocity)
    t6 = np.zeros((k, 6, 6))
    t6[:, :3, :3] = ct @ p[:, 3:6, 3:6] @ c
    t6[:, 3:, 3:] = np.eye(3) * rate_variance
    return c6.reshape(k, 36), vb, t6.reshape(k, 36)


#: the accelerometer stall is an ERROR beyond this factor × accel_wait, and at least this many
#: stamp seconds (a WARN beyond accel_wait): the one rule of sins_node's /diagnostics and
#: sins_bag's summary
ACCEL_STALL_ERROR_FACTOR = 10.0
ACCEL_STALL_ERROR_MIN_S = 1.0


def accel_stall_limits(accel_wait: float) -> tuple[float, float]:
    """
    (WARN, ERROR) thresholds of the accelerometer stall, stamp seconds.

    Parameters
    ----------
    accel_wait : float
        The parameter ``accel_wait``, s: how long sins/imu waits for Δv.

    Returns
    -------
    (float, float)
        ``accel_wait`` and max(:data:`ACCEL_STALL_ERROR_MIN_S`,
        :data:`ACCEL_STALL_ERROR_FACTOR` × ``accel_wait``).

    """
    wait = float(accel_wait)
    return wait, max(ACCEL_STALL_ERROR_MIN_S, ACCEL_STALL_ERROR_FACTOR * wait)


@dataclass(frozen=True)
class AccelStall:
    """
    The accelerometer stream has stopped while the gyro stream runs on.

    Attributes
    ----------
    seconds : float
        Stamp seconds the gyro stream ran beyond the newest accepted Δv (or its first stamp
        when no Δv arrived).
    level : str
        ``"warn"`` (beyond ``accel_wait``) or ``"error"`` (beyond the ERROR limit).
    text : str
        The sentence of /diagnostics and of sins_bag's ``WARNING:`` line, naming the stream.

    """

    seconds: float
    level: str
    text: str
