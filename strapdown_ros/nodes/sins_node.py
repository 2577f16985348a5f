"""
sins_node: strapdown attitude from integrating-gyro increments with a selectable coning algorithm.

Subscribes (stream QoS):
* ``imu/delta_theta``     geometry_msgs/Vector3Stamped, rad, stamp = end of interval
* ``imu/delta_velocity``  geometry_msgs/Vector3Stamped, m/s (optional)
* ``imu/data_raw``        sensor_msgs/Imu instead of both, with ``gyro_input: imu``: each
                          message's angular_velocity (and linear_acceleration, unless its
                          covariance[0] is −1) is validated as a rate sample and made into Δθ
                          (Δv) by ``imu_rate_rule``
                          (:class:`strapdown_ros.streams.rate_increments.RateIncrementStream`); the
                          increments then take the path of imu/delta_theta (delta_velocity).
                          Its covariance fields are not used (the model's gyro_random_walk is);
                          the Δv stream has the Imu's rate (``gyro_rate`` stands for
                          ``accel_rate``)

Publishes at every update of the algorithm (gyro rate / samples per update):
* ``sins/attitude``  geometry_msgs/QuaternionStamped, q_ref_body (frame_id = reference frame)
* ``sins/imu``       sensor_msgs/Imu: orientation with its covariance (attitude error ε in body
                     axes, rad²), mean angular rate over the update, mean specific force
                     over the update (linear_acceleration_covariance[0] = −1 when no
                     accelerometer data arrived)
* ``sins/odometry``  nav_msgs/Odometry (parameter ``navigation``): ECEF position and velocity of
                     003 §1.5 with covariance; header.frame_id ``earth`` (REP-105, PZ-90),
                     child_frame_id the body frame; pose = position, q_earth_body and the
                     covariance of [position, attitude error ψ about earth axes]; twist.linear =
                     velocity in body axes (REP-105 Odometry) with its covariance; twist.angular
                     is not filled (zeros; the rate is on sins/imu)
* ``/diagnostics``   counts of received, dropped (NaN, out-of-order, duplicate) and
                     missing (gap) messages, rates from header stamps; the level is the worst
                     of all current conditions and the message lists each, worst first
                     (:class:`~strapdown_ros.nodes.ros_status.Conditions`); a Δv stream that stops
                     while Δθ runs on is WARN beyond ``accel_wait`` and ERROR beyond
                     max(1 s, 10 ``accel_wait``) of stamp time

Timing comes only from header stamps.  Invalid input is dropped, counted and reported;
the integrator never sees it.

The numerical processing (validation, blocks, integrator, gyro-effect compensation, the non-finite
rule, the accelerometer accumulator and the navigation channel) is
:class:`strapdown_ros.sins.SinsSystem`, shared with the offline tool ``sins_bag``; this
node decodes messages, feeds the system and publishes what it returns.

Hot path: a callback only validates a message and appends it.  The increments are integrated in
blocks covering ``batch_period`` of stamp time (and at least every ``batch_period`` wall seconds,
by a timer) through the vectorised core; every update is still published with its own stamp, and
the result equals message-by-message processing (``batch_period`` 0) to round-off.  Outputs are
built only for topics that have a subscriber (checked once per block).
"""
from __future__ import annotations

import sys

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
from nav_msgs.msg import Odometry
import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import Imu

from strapdown_ros.nodes import ros_io, ros_params, ros_process, ros_status
from strapdown_ros.params import model_from_parameters, not_applied_note, SINS_PARAMS
from strapdown_ros.sins import odometry_arrays, SinsOutput, SinsSettings, SinsSystem
from strapdown_ros.streams.rate_increments import RateIncrementStream

NODE_NAME = 'sins_node'


class SinsNode(Node):
    """
    The strapdown attitude (and navigation) node: ROS in and out of :class:`SinsSystem`.

    Parameters
    ----------
    **kwargs
        Passed to :class:`rclpy.node.Node` (namespace, parameter_overrides, ...).

    """

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self.log = ros_status.NodeLog(self.get_logger())   # the one logging helper (any severity)
        self.p = ros_params.declare_validated(self, SINS_PARAMS, on_change=self._on_change,
                                              apply=self._apply_change)
        p = self.p
        self.published = {'attitude': 0, 'imu': 0, 'imu_without_accel': 0}
        self.undecodable = 0                       # serialized input that is not a Vector3Stamped
        self.algorithm_changes = 0
        # the edge: ROS parameters → the sensor model and the SINS's typed settings
        model, warnings = model_from_parameters(p, f'{NODE_NAME} parameters')
        for w in warnings:
            self.log.warn(w)
        note = not_applied_note(model, ('gyro', 'accel'), NODE_NAME)
        if note:
            self.log.info(note)
        self.frame_id = model.frame_id
        self.ref_frame = model.reference_frame_id
        self.imu_input = p['gyro_input'] == 'imu'
        # with Imu input, Δv comes from the same messages: at the Imu rate, which is gyro_rate
        if self.imu_input:
            model = model.with_values({'accel_rate': model.gyro_rate},
                                      rule='gyro_input imu: Δv at the Imu rate')
        # the numerical core; sins/imu records are made only while it has a subscriber
        # (asked once per block)
        self.system = SinsSystem(model, SinsSettings.from_values(p), log=self.log,
                                 imu_wanted=lambda: self.pub_imu.get_subscription_count() > 0)
        self._make_output_messages()
        qos = ros_io.stream_qos(int(p['qos_depth']))
        self.pub_att = self.create_publisher(QuaternionStamped, 'sins/attitude', qos,
                                             qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.pub_imu = self.create_publisher(Imu, 'sins/imu', qos,
                                             qos_overriding_options=ros_io.QOS_OVERRIDES)
        if self.nav is not None:
            self.published['odometry'] = 0
            self.pub_odom = self.create_publisher(Odometry, 'sins/odometry', qos,
                                                  qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics',
                                              ros_io.DIAGNOSTICS_QOS)
        # raw: the callbacks read stamp, vector and frame from the serialized bytes (ros_io)
        if self.imu_input:
            period = model.gyro_period
            jump, resync = float(p['max_stamp_jump']), int(p['resync_count'])
            rule = p['imu_rate_rule']
            self.gyro_rates = RateIncrementStream(period, model.gyro_max_rate, rule, jump,
                                                  resync)
            self.accel_rates = RateIncrementStream(period, model.accel_max, rule, jump,
                                                   resync)
            self.last_imu = None                   # the latest Imu (bytes or message)
            self.create_subscription(Imu, 'imu/data_raw', self.on_imu_raw, qos,
                                     qos_overriding_options=ros_io.QOS_OVERRIDES, raw=True)
        else:
            self.create_subscription(Vector3Stamped, 'imu/delta_theta', self.on_gyro_raw, qos,
                                     qos_overriding_options=ros_io.QOS_OVERRIDES, raw=True)
            self.create_subscription(Vector3Stamped, 'imu/delta_velocity', self.on_accel_raw, qos,
                                     qos_overriding_options=ros_io.QOS_OVERRIDES, raw=True)
        self.create_timer(float(p['diagnostics_period']), self.publish_diagnostics)
        if self.system.batch_span > 0:             # a block is processed at least this often
            self.create_timer(self.system.batch_span, self.process)
        self.log.info(
            f"started: gyro_input={p['gyro_input']}"
            + (f" ({p['imu_rate_rule']}; Δv at gyro_rate)" if self.imu_input else '')
            + f", coning_algorithm={p['coning_algorithm']} "
            f'({self.integrator.algorithm.samples} samples/update), '
            f"covariance_model={p['covariance_model']}, "
            f"compensating: {', '.join(self.system.compensating) or 'none'}")
        if self.system.initial_normalised:
            self.log.warn('initial_orientation was not a unit quaternion; normalised')

    # --- the core's state, as the node's (diagnostics, tests, tools) --------------------------
    @property
    def integrator(self):
        """Return the core's attitude integrator."""
        return self.system.integrator

    @property
    def nav(self):
        """Return the core's navigation channel (None when ``navigation`` is off)."""
        return self.system.nav

    @property
    def gyro_check(self):
        """Return the stream rules of the Δθ input (with their counters)."""
        return self.system.gyro_check

    @property
    def accel_check(self):
        """Return the stream rules of the Δv input (with their counters)."""
        return self.system.accel_check

    @property
    def nonfinite(self) -> int:
        """Return the number of non-finite updates discarded."""
        return self.system.nonfinite

    @property
    def frame_mismatch(self) -> dict:
        """Return the messages in another frame than ``frame_id``, per stream."""
        return self.system.frame_mismatch

    # --- parameters ---------------------------------------------------------------------
    def _on_change(self, new: dict) -> str | None:
        """
        Validate a change (on-set): only the coning algorithm may change.

        Validation (on-set): only the coning algorithm may change at runtime, and only while
        navigation is off (the navigation step is the algorithm's update).
        """
        if self.nav is not None:
            return ('no parameter can change at runtime while navigation is on (the navigation '
                    "step is the coning algorithm's update); restart the node to change "
                    + ', '.join(sorted(new)))
        fixed = sorted(set(new) - {'coning_algorithm'})
        if fixed:
            return ('only coning_algorithm can change at runtime; restart the node to change '
                    + ', '.join(fixed))
        return None

    def _apply_change(self, new: dict) -> None:
        """Apply a change (post-set), once rclpy has accepted it."""
        name = new['coning_algorithm']
        if name != self.integrator.algorithm_name:
            self.process()                         # the samples so far belong to the old algorithm
            self.system.set_algorithm(name)
            self.algorithm_changes += 1
            self.p['coning_algorithm'] = name
            self.log.info(f'coning_algorithm switched to {name}')

    # --- input ------------------------------------------------------------------------------
    def on_gyro_raw(self, data: bytes):
        """
        Take one imu/delta_theta message: decode, validate, append to the block.

        The numerical work runs in :meth:`process`.

        Parameters
        ----------
        data : bytes
            The serialized geometry_msgs/Vector3Stamped (a raw subscription's argument).

        """
        got = ros_io.decode_vector3_stamped(data)
        if got is None:
            self.undecodable += 1
            return
        self._gyro(*got)

    def on_gyro(self, msg: Vector3Stamped):
        """
        Take one imu/delta_theta message object (tests, tools).

        Parameters
        ----------
        msg : geometry_msgs.msg.Vector3Stamped
            The message.

        """
        st = msg.header.stamp
        v = msg.vector
        self._gyro(st.sec * 1_000_000_000 + st.nanosec, (v.x, v.y, v.z), msg.header.frame_id)

    def _gyro(self, stamp_ns: int, value, frame_id: str):
        if self.system.offer_gyro(stamp_ns, value, frame_id):
            self.process()
        elif self.system.has_output:               # a stamp resync processed the old time base
            self._publish(self.system.take_output())

    def on_accel_raw(self, data: bytes):
        """
        Take one imu/delta_velocity message: decode, validate, append.

        Folded into the accumulator by :meth:`process`.

        Parameters
        ----------
        data : bytes
            The serialized geometry_msgs/Vector3Stamped (a raw subscription's argument).

        """
        got = ros_io.decode_vector3_stamped(data)
        if got is None:
            self.undecodable += 1
            return
        if self.system.offer_accel(*got):
            self.process()

    def on_accel(self, msg: Vector3Stamped):
        """
        Take one imu/delta_velocity message object (tests, tools).

        Parameters
        ----------
        msg : geometry_msgs.msg.Vector3Stamped
            The message.

        """
        st = msg.header.stamp
        v = msg.vector
        if self.system.offer_accel(st.sec * 1_000_000_000 + st.nanosec, (v.x, v.y, v.z),
                                   msg.header.frame_id):
            self.process()

    def on_imu_raw(self, data: bytes):
        """
        Take one imu/data_raw message (``gyro_input: imu``): decode, then the rate rule.

        Parameters
        ----------
        data : bytes
            The serialized sensor_msgs/Imu (a raw subscription's argument).

        """
        got = ros_io.decode_imu(data)
        if got is None:
            self.undecodable += 1
            return
        self.last_imu = data                       # its stated covariance: read for /diagnostics
        self._imu(*got)

    def on_imu(self, msg: Imu):
        """
        Take one imu/data_raw message object (tests, tools).

        Parameters
        ----------
        msg : sensor_msgs.msg.Imu
            The message.

        """
        w, a = msg.angular_velocity, msg.linear_acceleration
        accel = None if msg.linear_acceleration_covariance[0] == -1.0 else (a.x, a.y, a.z)
        self.last_imu = msg
        self._imu(ros_io.stamp_to_ns(msg.header.stamp), (w.x, w.y, w.z), accel,
                  msg.header.frame_id)

    def _imu(self, stamp_ns: int, rate, accel, frame_id: str):
        """
        Take one Imu message: the frame rule, then each rate through its stream.

        One Imu message: the frame rule, then each rate through its RateIncrementStream
        (validation, then the increment rule); the increments formed enter the Δθ/Δv path.  The Δv
        goes first, so that the update of the same stamp finds its specific force.
        """
        if not self.system.frame_accepted(frame_id, 'gyro'):
            return
        if accel is not None:
            for s, dv in self.accel_rates.push(stamp_ns, accel):
                if self.system.offer_accel(s, dv):
                    self.process()
        for s, dth in self.gyro_rates.push(stamp_ns, rate):
            self._gyro(s, dth, '')

    # --- batch processing ------------------------------------------------------------------
    def process(self) -> None:
        """
        Integrate the buffered increments as one block and publish the updates.

        Integrate the buffered increments as one block through the vectorised core and publish
        every update with its own stamp.  The result equals message-by-message processing to
        round-off (test/ros/test_nodes.py::test_sins_node_batches_equal_per_message_processing).
        """
        self._publish(self.system.process())

    # --- output ------------------------------------------------------------------------------
    def _publish(self, out: SinsOutput) -> None:
        """
        Publish the system's outputs of one block.

        Publish the system's outputs; sins/attitude and sins/odometry only when subscribed (checked
        once per block).
        """
        att_out, imu_out, nav_out = out.attitude, out.imu, out.navigation
        if len(att_out) and self.pub_att.get_subscription_count() > 0:
            att = self._att_out                     # reused: publish serialises it at once
            o = att.quaternion
            for k in range(len(att_out)):
                q = att_out.attitude[k]
                ros_io.set_stamp(att.header.stamp, att_out.stamp_ns[k])
                o.w, o.x, o.y, o.z = float(q[0]), float(q[1]), float(q[2]), float(q[3])
                self.pub_att.publish(att)
            self.published['attitude'] += len(att_out)
        for k in range(len(imu_out)):
            f_mean = imu_out.specific_force[k] if imu_out.has_accel[k] else None
            self.pub_imu.publish(self._imu_msg(imu_out.stamp_ns[k], imu_out.attitude[k],
                                               imu_out.covariance[k], imu_out.mean_rate[k],
                                               f_mean))
        if len(nav_out) and self.pub_odom.get_subscription_count() > 0:
            self._publish_odometry(nav_out)

    def _publish_odometry(self, nb) -> None:
        m = self._odom_out
        pose_cov, v_body, twist_cov = odometry_arrays(nb, self.system.rate_variance)
        for k in range(len(nb)):
            ros_io.set_stamp(m.header.stamp, nb.stamp_ns[k])
            pose = m.pose.pose
            r, q = nb.position[k], nb.attitude[k]
            pos = pose.position
            pos.x, pos.y, pos.z = float(r[0]), float(r[1]), float(r[2])
            o = pose.orientation
            o.w, o.x, o.y, o.z = float(q[0]), float(q[1]), float(q[2]), float(q[3])
            m.pose.covariance = pose_cov[k]
            vb = v_body[k]
            tw = m.twist.twist
            tw.linear.x, tw.linear.y, tw.linear.z = float(vb[0]), float(vb[1]), float(vb[2])
            m.twist.covariance = twist_cov[k]
            self.pub_odom.publish(m)
        self.published['odometry'] += len(nb)

    def _imu_msg(self, stamp_ns, q, cov, rate, f_mean) -> Imu:
        """
        Fill the sensor_msgs/Imu of one update.

        sensor_msgs/Imu of one update.  One message object is reused (publish serialises it at
        once): constructing a new Imu costs more than the rest of the update.
        """
        m = self._imu_out
        ros_io.set_stamp(m.header.stamp, stamp_ns)
        o = m.orientation
        o.w, o.x, o.y, o.z = float(q[0]), float(q[1]), float(q[2]), float(q[3])
        m.orientation_covariance = np.ascontiguousarray(cov, dtype=np.float64).reshape(9)
        w = m.angular_velocity
        w.x, w.y, w.z = float(rate[0]), float(rate[1]), float(rate[2])
        a = m.linear_acceleration
        if f_mean is None:
            a.x = a.y = a.z = 0.0
            # [0] = −1: no accelerometer data
            m.linear_acceleration_covariance = self._no_accel_cov
            self.published['imu_without_accel'] += 1
        else:
            a.x, a.y, a.z = float(f_mean[0]), float(f_mean[1]), float(f_mean[2])
            m.linear_acceleration_covariance = self._accel_cov
        self.published['imu'] += 1
        return m

    def _make_output_messages(self) -> None:
        m = Imu()
        m.header.frame_id = self.frame_id
        g = self.system.rate_variance
        m.angular_velocity_covariance = np.diag([g, g, g]).reshape(9)
        a = self.system.accel_variance
        self._accel_cov = np.diag([a, a, a]).reshape(9)
        self._no_accel_cov = np.zeros(9)
        self._no_accel_cov[0] = -1.0
        self._imu_out = m
        self._att_out = QuaternionStamped()
        self._odom_out = Odometry()
        self._odom_out.header.frame_id = self.system.settings.earth_frame_id
        self._odom_out.child_frame_id = self.frame_id
        self._att_out.header.frame_id = self.ref_frame

    def accel_stall_s(self) -> float | None:
        """
        Return the stamp seconds the gyro stream ran beyond the newest Δv.

        Returns
        -------
        float or None
            Seconds; None before any gyro data.

        """
        return self.system.accel_stall_s()

    def diagnostic_conditions(self) -> ros_status.Conditions:
        """
        Return every current condition of the node with its level.

        Returns
        -------
        Conditions
            The conditions (:class:`strapdown_ros.nodes.ros_status.Conditions`); the status
            level is the worst of them.

        """
        g, a = self.gyro_check, self.accel_check
        c = ros_status.Conditions()
        if g.accepted == 0:
            c.add(ros_status.WARN, 'no gyro increments received')
        if g.dropped or a.dropped:
            c.add(ros_status.WARN,
                  f'dropped {g.dropped} gyro and {a.dropped} accelerometer messages '
                  f'(NaN {g.nan + a.nan}, out of range {g.out_of_range + a.out_of_range}, out of '
                  f'order {g.out_of_order + a.out_of_order}, duplicate '
                  f'{g.duplicate + a.duplicate}, stamp outliers '
                  f'{g.stamp_outliers + a.stamp_outliers})')
        m = self.system.model
        clips = [self.gyro_check.clip_warning('gyro_max_rate', m.gyro_max_rate, 'rad/s',
                                              m.gyro_period),
                 self.accel_check.clip_warning('accel_max', m.accel_max, 'm/s²',
                                               1.0 / m.accel_rate)]
        if self.imu_input:
            clips += [self.gyro_rates.check.clip_warning('gyro_max_rate', m.gyro_max_rate,
                                                         'rad/s'),
                      self.accel_rates.check.clip_warning('accel_max', m.accel_max, 'm/s²')]
        for text in filter(None, clips):
            c.add(ros_status.WARN, text)
        if self.imu_input and (self.gyro_rates.check.dropped or self.accel_rates.check.dropped):
            gr, ar = self.gyro_rates.check, self.accel_rates.check
            c.add(ros_status.WARN,
                  f'dropped {gr.dropped} angular-rate and {ar.dropped} acceleration '
                  f'samples of imu/data_raw (NaN {gr.nan + ar.nan}, out of range '
                  f'{gr.out_of_range + ar.out_of_range}, out of order '
                  f'{gr.out_of_order + ar.out_of_order}, duplicate {gr.duplicate + ar.duplicate}, '
                  f'stamp outliers {gr.stamp_outliers + ar.stamp_outliers})')
        if any(self.frame_mismatch.values()):
            c.add(ros_status.WARN,
                  'messages in another frame than '
                  f'{ros_status.bounded(self.frame_id, 80)!r}: '
                  f"gyro {self.frame_mismatch['gyro']}, "
                  f"accelerometer {self.frame_mismatch['accel']} "
                  f"({'rejected' if self.system.reject_frames else 'used'})")
        if self.undecodable:
            c.add(ros_status.WARN,
                  f'{self.undecodable} input message(s) could not be decoded: dropped')
        stall = self.system.accel_stall('imu/data_raw' if self.imu_input
                                        else 'imu/delta_velocity')
        if stall is not None:                     # the core's rule, shared with sins_bag
            c.add(ros_status.ERROR if stall.level == 'error' else ros_status.WARN, stall.text)
        if g.missing:
            c.add(ros_status.ERROR, f'{g.missing} gyro increments missing in {g.gaps} gaps: '
                  'the rotation during the gaps is lost')
        if g.resyncs:
            c.add(ros_status.ERROR, f'gyro stamps jumped {g.resyncs} time(s) (last by '
                  f'{g.last_jump_s:.6g} s): resynchronised; the rotation during a jump is lost')
        if self.nonfinite:
            c.add(ros_status.ERROR, f'{self.nonfinite} non-finite update(s) discarded (never '
                  'published); state reset to the last good one with inflated covariance')
        if self.nav is not None and self.nav.alignment is not None and not self.nav.alignment.ok \
                and self.nav.navigator is None:
            c.add(ros_status.ERROR, f'static alignment refused: {self.nav.alignment.reason}')
        return c

    def publish_diagnostics(self):
        """Publish the /diagnostics status of the node."""
        g = self.gyro_check
        c = self.diagnostic_conditions()
        values = self.system.status()
        values.update({'undecodable_dropped': self.undecodable,
                       'attitude_published': self.published['attitude'],
                       'imu_published': self.published['imu'],
                       'imu_published_without_accel': self.published['imu_without_accel'],
                       'algorithm_changes': self.algorithm_changes})
        if self.imu_input:
            values.update({'gyro_input': 'imu', 'imu_rate_rule': self.p['imu_rate_rule'],
                           'imu_stated_rate_variance': ros_io.stated_rate_variance(self.last_imu),
                           'model_rate_variance': self.system.rate_variance,
                           **self.gyro_rates.status('imu_gyro'),
                           **self.accel_rates.status('imu_accel')})
        stall = self.accel_stall_s()
        if stall is not None:
            values['accel_stall_s'] = stall
        if self.nav is not None:
            values['odometry_published'] = self.published['odometry']
        stamp_ns = g.last_ns if g.last_ns is not None else 0
        name = f'{self.get_fully_qualified_name()}: attitude'
        self.pub_diag.publish(ros_status.diagnostic_array(ros_io.ns_to_stamp(stamp_ns), name,
                                                          'sins', c.level, c.message(), values))


def main(args=None):
    """
    Run sins_node (the entry point of its process).

    Parameters
    ----------
    args : list of str, optional
        ROS arguments (default the process's).

    Returns
    -------
    int
        The exit status (:func:`strapdown_ros.nodes.ros_process.run_node`).

    """
    return ros_process.run_node(SinsNode, NODE_NAME, args)


if __name__ == '__main__':
    sys.exit(main())
