"""
star_camera_sim_node: a star camera (astro-visual unit, 004 §3) on the same exact motion profile.

The profile parameters and the time origin (``profile``…, ``start_time``, ``time_scale``,
``duration``) mean exactly what they mean for ``imu_sim_node``, so one parameter file gives
both simulators the same truth: the camera frame VF is the IMU frame MF turned by the
boresight β = (ψ, ϑ, γ), ``q_GCRS_VF = q_GCRS_MF ⊗ q_MF_VF`` with
``C_MF^VF = R_z(−ψ) R_x(ϑ) R_y(γ)`` (:class:`~strapdown_ros.sensors.star_camera.StarCameraModel`).

Publishes, one message per exposure (stamp = ``start_time`` + exposure stamp; exposures every
``camera_interval`` s from ``camera_first_exposure``, 0 meaning one interval after t = 0):

* ``star_camera/attitude``  geometry_msgs/QuaternionStamped: measured q_GCRS_VF,
  frame_id = ``reference_frame_id``.
* ``star_camera/attitude_with_covariance``  geometry_msgs/PoseWithCovarianceStamped: the same
  orientation, frame_id = ``reference_frame_id``, position 0.  Covariance (6×6, row-major):
  the rotation block (rows/columns 3..5, about x, y, z) is the covariance of the measurement
  error θ of 004 §3.3 (``S_GCRS^VF ≈ S̆_GCRS^VF (I + [θ×])``, VF axes, rad²) =
  diag(σ_xy², σ_xy², σ_z²).  **Position is not estimated**: following the robot_localization
  convention for unmeasured quantities, its diagonal carries a very large variance
  (:data:`UNKNOWN_POSITION_VARIANCE` = 1e9 m²) and the cross terms are 0; a consumer must not
  read the position as a measurement.
* ``star_camera/truth/boresight``  geometry_msgs/QuaternionStamped, published once at
  start-up with TRANSIENT_LOCAL durability (depth 1, late subscribers get it): the true
  q_MF_VF (VF coordinates → MF coordinates, i.e. the orientation of the camera frame in the
  IMU frame), stamp = ``start_time``.  The parameters of this node name no IMU frame, so the
  header carries ``camera_frame_id``, the frame the quaternion describes; it is evaluation
  truth, not a transform for tf.
* ``/diagnostics``  exposure count, simulated time, real-time factor.

QoS of the camera topics: RELIABLE, VOLATILE, KEEP_LAST(``qos_depth``).  Camera fixes are rare
(one every ``camera_interval`` s) and each is worth a whole calibration pair, so they must not
be lost the way a best-effort stream may lose samples; reliability costs nothing at this rate.

A wall-clock timer paces the output exactly like ``imu_sim_node`` (``time_scale`` simulated
seconds per wall second; every fix whose stamp is ≤ the simulated time is published; the
node stops at ``duration`` or the end of the profile); nothing downstream depends on the
wall clock.
"""
from __future__ import annotations

import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseWithCovarianceStamped, QuaternionStamped
import numpy as np
from rclpy.node import Node

from strapdown_ros.motion.from_config import profile_from_config
from strapdown_ros.nodes import ros_io, ros_params, ros_process, ros_status
from strapdown_ros.nodes.ros_io import camera_qos, latched_qos, pose_with_covariance
from strapdown_ros.params import STAR_CAMERA_PARAMS
from strapdown_ros.sensors.star_camera import StarCameraModel

NODE_NAME = 'star_camera_sim_node'


class StarCameraSimNode(ros_io.PacedSimulation, Node):
    """
    The star camera simulator node: noisy attitude fixes of a motion profile.

    Parameters
    ----------
    **kwargs
        Passed to :class:`rclpy.node.Node` (namespace, parameter_overrides, ...).

    """

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self.log = ros_status.NodeLog(self.get_logger())   # the one logging helper of the nodes
        self.p = ros_params.declare_validated(self, STAR_CAMERA_PARAMS,
                                              on_change=self._reject_changes)
        p = self.p
        self.profile = profile_from_config(p)
        self.model = StarCameraModel.from_params(p)
        sxy, sz = float(p['camera_sigma_xy']), float(p['camera_sigma_z'])
        dur = float(p['duration'])
        self.end_time = dur if dur > 0 else self.profile.duration
        self.start_ns = int(round(float(p['start_time']) * 1e9))
        self.ref_frame = p['reference_frame_id']
        self.camera_frame = p['camera_frame_id']
        qos = camera_qos(int(p['qos_depth']))
        self.pub_att = self.create_publisher(QuaternionStamped, 'star_camera/attitude', qos,
                                             qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.pub_cov = self.create_publisher(PoseWithCovarianceStamped,
                                             'star_camera/attitude_with_covariance', qos,
                                             qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.pub_truth = self.create_publisher(QuaternionStamped, 'star_camera/truth/boresight',
                                               latched_qos())
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics',
                                              ros_io.DIAGNOSTICS_QOS)
        self.pub_truth.publish(ros_io.quaternion_stamped(ros_io.ns_to_stamp(self.start_ns),
                                                         self.camera_frame,
                                                         self.model.q_mf_vf))
        self.published = 0
        self.last_stamp: float | None = None
        self._wall_start = None
        self.sim_time = 0.0
        self.finished = False
        self.timer = self.create_timer(float(p['publish_period']), self._tick)
        self.diag_timer = self.create_timer(float(p['diagnostics_period']),
                                            self.publish_diagnostics)
        self.log.info(
            f"started: profile={p['profile']}, exposure every {p['camera_interval']:g} s from "
            f'{self.model.epoch(0):g} s, σ = ({sxy:.3g}, {sxy:.3g}, {sz:.3g}) rad, boresight β = '
            f'{np.round(np.degrees(self.model.boresight), 6).tolist()}°, '
            f"time_scale {p['time_scale']}, "
            f'duration {self.end_time:g} s')

    def _reject_changes(self, new: dict) -> str | None:
        return ('star_camera_sim_node parameters are fixed after start-up (they define the '
                'simulated truth); '
                'restart the node to change ' + ', '.join(sorted(new)))

    # ---------------------------------------------------------------------------------
    def _subscriber_count(self) -> int:
        return self.pub_att.get_subscription_count() + self.pub_cov.get_subscription_count()

    def _on_finished(self):
        self.publish_diagnostics()
        self.log.info(f'finished: published {self.published} fixes up to '
                      f't = {self.sim_time:.3f} s')

    def _advance_to(self, target: float):
        n = 0
        while self.model.epoch(self.model.count + n) <= target + 1e-9:
            n += 1
        self.sim_time = target
        if n == 0:
            return
        for fix in self.model.fixes(self.profile, n):
            st = ros_io.ns_to_stamp(self.start_ns + int(round(fix.stamp * 1e9)))
            self.pub_att.publish(ros_io.quaternion_stamped(st, self.ref_frame, fix.attitude))
            self.pub_cov.publish(pose_with_covariance(st, self.ref_frame, fix.attitude,
                                                      fix.covariance))
            self.published += 1
            self.last_stamp = fix.stamp

    def publish_diagnostics(self):
        """Publish the /diagnostics status of the node."""
        wall = (time.monotonic() - self._wall_start) if self._wall_start else 0.0
        st = ros_io.ns_to_stamp(self.start_ns + int(round(self.sim_time * 1e9)))
        values = {'simulated_time_s': self.sim_time,
                  'real_time_factor': self.sim_time / wall if wall > 0 else 0.0,
                  'fixes_published': self.published,
                  'camera_interval_s': self.p['camera_interval'],
                  'next_exposure_s': self.model.epoch(self.model.count),
                  'last_exposure_s': self.last_stamp if self.last_stamp is not None else 'none',
                  'finished': self.finished, 'profile': self.p['profile']}
        if self.finished:
            msg = 'finished'
        else:
            msg = 'waiting for subscribers' if self._wall_start is None else 'running'
        name = f'{self.get_fully_qualified_name()}: star camera'
        self.pub_diag.publish(ros_status.diagnostic_array(st, name, 'star_camera_sim',
                                                          ros_status.OK, msg, values))


def main(args=None):
    """
    Run star_camera_sim_node (the entry point of its process).

    Parameters
    ----------
    args : list of str, optional
        ROS arguments (default the process's).

    Returns
    -------
    int
        The exit status (:func:`strapdown_ros.nodes.ros_process.run_node`).

    """
    return ros_process.run_node(StarCameraSimNode, NODE_NAME, args)


if __name__ == '__main__':
    sys.exit(main())
