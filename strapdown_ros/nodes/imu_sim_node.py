"""
imu_sim_node: integrating gyros (Δθ) and accelerometers (Δv) on an exact motion profile.

Publishes (stamps are simulated time: ``start_time`` + profile time; each stamp is the
*end* of its integration interval):

* ``imu/delta_theta``     geometry_msgs/Vector3Stamped, rad, at ``gyro_rate``
* ``imu/delta_velocity``  geometry_msgs/Vector3Stamped, m/s, at ``accel_rate``
* ``imu/data_raw``        sensor_msgs/Imu at ``gyro_rate``: mean rate Δθ/T and mean specific
                          force over the same interval; no orientation (REP-145:
                          orientation_covariance[0] = −1)
* ``imu/truth/attitude``  geometry_msgs/QuaternionStamped, exact q_ref_body at gyro epochs
* ``imu/truth/odometry``  nav_msgs/Odometry at gyro epochs, only for the Earth-referenced
                          navigation profiles (static, straight_flight, coordinated_turn,
                          sculling): header.frame_id ``earth`` (ECEF, PZ-90), child_frame_id
                          ``frame_id``; pose = ECEF position and q_E_B; twist in the child
                          (body) frame: ECEF velocity rotated into body axes, and the body rate
                          relative to the Earth; covariances zero (exact truth)
* ``/diagnostics``

``imu/data_raw``, ``imu/truth/attitude`` and ``imu/truth/odometry`` are derived topics: they are
built and published only while they have a subscriber (each costs as much as a Δθ message).

A wall-clock timer paces the output (``time_scale`` simulated seconds per wall second);
nothing downstream depends on the wall clock.
"""
from __future__ import annotations

import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
from nav_msgs.msg import Odometry
import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import Imu

from strapdown_ros.motion.earth_motion import EarthProfile
from strapdown_ros.motion.from_config import profile_from_config
from strapdown_ros.nodes import ros_io, ros_params, ros_process, ros_status
from strapdown_ros.params import IMU_SIM_PARAMS
from strapdown_ros.rotation import to_ros_xyzw
from strapdown_ros.sensors import simulated_imu

NODE_NAME = 'imu_sim_node'


class ImuSimNode(ros_io.PacedSimulation, Node):
    """
    The IMU simulator node: Δθ, Δv (or Imu rates) of a motion profile, paced by the wall clock.

    Parameters
    ----------
    **kwargs
        Passed to :class:`rclpy.node.Node` (namespace, parameter_overrides, ...).

    """

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self.log = ros_status.NodeLog(self.get_logger())   # the one logging helper of the nodes
        self.p = ros_params.declare_validated(self, IMU_SIM_PARAMS, on_change=self._reject_changes)
        p = self.p
        self.profile = profile_from_config(p)
        self.gyro, self.accel = simulated_imu(p, self.profile)
        self.gyro_errors, self.accel_errors = self.gyro.errors, self.accel.errors
        dur = float(p['duration'])
        self.end_time = dur if dur > 0 else self.profile.duration
        self.start_ns = int(round(float(p['start_time']) * 1e9))
        self.frame_id = p['frame_id']
        self.ref_frame = p['reference_frame_id']
        qos = ros_io.stream_qos(int(p['qos_depth']))
        self.pub_dtheta = self.create_publisher(Vector3Stamped, 'imu/delta_theta', qos,
                                                qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.pub_dv = self.create_publisher(Vector3Stamped, 'imu/delta_velocity', qos,
                                            qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.pub_raw = self.create_publisher(Imu, 'imu/data_raw', qos,
                                             qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.pub_truth = self.create_publisher(QuaternionStamped, 'imu/truth/attitude', qos,
                                               qos_overriding_options=ros_io.QOS_OVERRIDES)
        # ECEF truth exists only for the Earth-referenced navigation profiles
        self.pub_odom = (self.create_publisher(Odometry, 'imu/truth/odometry', qos,
                                               qos_overriding_options=ros_io.QOS_OVERRIDES)
                         if isinstance(self.profile, EarthProfile) else None)
        self._odom_out = Odometry()
        self._odom_out.header.frame_id = 'earth'
        self._odom_out.child_frame_id = self.frame_id
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics',
                                              ros_io.DIAGNOSTICS_QOS)
        self.counts = {'delta_theta': 0, 'delta_velocity': 0, 'data_raw': 0}
        self._dtheta_out = ros_io.vector3_stamped(ros_io.ns_to_stamp(0), self.frame_id,
                                                  (0.0, 0.0, 0.0))
        self._dv_out = ros_io.vector3_stamped(ros_io.ns_to_stamp(0), self.frame_id,
                                              (0.0, 0.0, 0.0))
        self._pending_dv = np.zeros(3)
        self._wall_start = None
        self.sim_time = 0.0
        self.finished = False
        self.timer = self.create_timer(float(p['publish_period']), self._tick)
        self.diag_timer = self.create_timer(float(p['diagnostics_period']),
                                            self._publish_diagnostics)
        self.log.info(
            f"started: profile={p['profile']} gyro {p['gyro_rate']} Hz, "
            f"accel {p['accel_rate']} Hz, "
            f"time_scale {p['time_scale']}, duration {self.end_time:g} s")

    def _reject_changes(self, new: dict) -> str | None:
        return ('imu_sim_node parameters are fixed after start-up (they define the simulated '
                'truth); '
                'restart the node to change ' + ', '.join(sorted(new)))

    # ---------------------------------------------------------------------------------
    def _subscriber_count(self) -> int:
        """Consumers of the gyro data: imu/delta_theta and imu/data_raw (``gyro_input: imu``)."""
        return self.pub_dtheta.get_subscription_count() + self.pub_raw.get_subscription_count()

    def _on_finished(self):
        self._publish_diagnostics()
        self.log.info(f'finished: published {self.counts} up to t = {self.sim_time:.3f} s')

    def _advance_to(self, target: float):
        n_g = int(np.floor(target / self.gyro.period + 1e-9)) - self.gyro.count
        n_a = int(np.floor(target / self.accel.period + 1e-9)) - self.accel.count
        if n_g <= 0 and n_a <= 0:
            return
        ta, dv, _ = self.accel.sample(max(n_a, 0))
        tg, dth, _ = self.gyro.sample(max(n_g, 0))

        def stamp(t):
            return ros_io.ns_to_stamp(self.start_ns + int(round(t * 1e9)))

        # one message object per topic, refilled (publish serialises at once); the derived topics
        # are built only while somebody subscribes to them
        raw_on = self.pub_raw.get_subscription_count() > 0
        truth_on = self.pub_truth.get_subscription_count() > 0
        q_true = self.profile.attitude(tg) if n_g > 0 and truth_on else np.zeros((len(tg), 4))
        odom = (self.profile.truth(tg) if n_g > 0 and self.pub_odom is not None
                and self.pub_odom.get_subscription_count() > 0 else None)
        m = self._dv_out
        for t, v in zip(ta, dv):
            m.header.stamp = stamp(t)
            m.vector.x, m.vector.y, m.vector.z = float(v[0]), float(v[1]), float(v[2])
            self.pub_dv.publish(m)
        self.counts['delta_velocity'] += len(ta)
        # mean specific force over each gyro interval, from the Δv stamped inside it
        edges = np.concatenate([[tg[0] - self.gyro.period], tg]) if n_g > 0 else np.zeros(1)
        m = self._dtheta_out
        for k, (t, v, q) in enumerate(zip(tg, dth, q_true)):
            st = stamp(t)
            m.header.stamp = st
            m.vector.x, m.vector.y, m.vector.z = float(v[0]), float(v[1]), float(v[2])
            self.pub_dtheta.publish(m)
            sel = (ta > edges[k] + 1e-9) & (ta <= t + 1e-9)          # (t_{k-1}, t_k]
            f_mean = (self._pending_dv + dv[sel].sum(0)) / self.gyro.period
            self._pending_dv = np.zeros(3)
            if raw_on:
                self.pub_raw.publish(self._imu_raw(st, v / self.gyro.period, f_mean))
                self.counts['data_raw'] += 1
            if truth_on:
                self.pub_truth.publish(ros_io.quaternion_stamped(st, self.ref_frame, q))
            if odom is not None:
                self.pub_odom.publish(self._odometry(st, odom, k))
        if n_g > 0:
            later = ta > tg[-1] + 1e-9
            self._pending_dv += dv[later].sum(0)
        elif len(ta):
            self._pending_dv += dv.sum(0)
        self.counts['delta_theta'] += len(tg)
        self.sim_time = max(self.gyro.count * self.gyro.period,
                            self.accel.count * self.accel.period)

    def _odometry(self, stamp, truth: dict, k: int) -> Odometry:
        """Entry k of EarthProfile.truth as Odometry (refilled message; covariances stay zero)."""
        m = self._odom_out
        m.header.stamp = stamp
        r = truth['position'][k]
        pos = m.pose.pose.position
        pos.x, pos.y, pos.z = float(r[0]), float(r[1]), float(r[2])
        x, y, z, w = to_ros_xyzw(truth['attitude_ecef'][k])
        o = m.pose.pose.orientation
        o.x, o.y, o.z, o.w = float(x), float(y), float(z), float(w)
        m.twist.twist.linear = ros_io.vector3(truth['velocity_body'][k])
        m.twist.twist.angular = ros_io.vector3(truth['earth_relative_rate'][k])
        return m

    def _imu_raw(self, stamp, rate, f_mean) -> Imu:
        m = Imu()
        m.header.stamp = stamp
        m.header.frame_id = self.frame_id
        m.orientation_covariance[0] = -1.0                      # REP-145: no orientation
        m.angular_velocity = ros_io.vector3(rate)
        m.linear_acceleration = ros_io.vector3(f_mean)
        g = self.gyro_errors.random_walk ** 2 / self.gyro.period    # variance of the mean rate
        a = self.accel_errors.random_walk ** 2 / self.gyro.period
        m.angular_velocity_covariance = [g, 0.0, 0.0, 0.0, g, 0.0, 0.0, 0.0, g]
        m.linear_acceleration_covariance = [a, 0.0, 0.0, 0.0, a, 0.0, 0.0, 0.0, a]
        return m

    def _publish_diagnostics(self):
        wall = (time.monotonic() - self._wall_start) if self._wall_start else 0.0
        st = ros_io.ns_to_stamp(self.start_ns + int(round(self.sim_time * 1e9)))
        values = {'simulated_time_s': self.sim_time,
                  'real_time_factor': self.sim_time / wall if wall > 0 else 0.0,
                  'gyro_rate_hz': self.p['gyro_rate'], 'accel_rate_hz': self.p['accel_rate'],
                  'delta_theta_published': self.counts['delta_theta'],
                  'delta_velocity_published': self.counts['delta_velocity'],
                  'data_raw_published': self.counts['data_raw'], 'finished': self.finished,
                  'profile': self.p['profile']}
        if self.finished:
            msg = 'finished'
        else:
            msg = 'waiting for subscribers' if self._wall_start is None else 'running'
        name = f'{self.get_fully_qualified_name()}: simulator'
        self.pub_diag.publish(ros_status.diagnostic_array(st, name, 'imu_sim', ros_status.OK,
                                                          msg, values))


def main(args=None):
    """
    Run imu_sim_node (the entry point of its process).

    Parameters
    ----------
    args : list of str, optional
        ROS arguments (default the process's).

    Returns
    -------
    int
        The exit status (:func:`strapdown_ros.nodes.ros_process.run_node`).

    """
    return ros_process.run_node(ImuSimNode, NODE_NAME, args)


if __name__ == '__main__':
    sys.exit(main())
