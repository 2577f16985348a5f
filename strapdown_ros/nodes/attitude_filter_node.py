"""
attitude_filter_node: the star-camera-aided attitude filter (MEKF) live.

A thin wrapper around :class:`~strapdown_ros.estimation.filter_system.FilterSystem`, the core
``filter_bag`` runs offline (same rules, same numbers): this module decodes messages, calls the
core and publishes.

Subscribes:

* ``imu/delta_theta``  geometry_msgs/Vector3Stamped, rad, stamp = end of interval (stream QoS);
  with ``gyro_input: imu`` instead ``imu/data_raw`` sensor_msgs/Imu rates made into Δθ by
  ``imu_rate_rule`` (:class:`~strapdown_ros.streams.rate_increments.RateIncrementStream`, as
  ``sins_node``).
* ``star_camera/attitude_with_covariance``  geometry_msgs/PoseWithCovarianceStamped
  (``use_camera_covariance``: R = the rotation block, VF axes, rad²) or ``star_camera/attitude``
  geometry_msgs/QuaternionStamped (R from ``camera_sigma_xy``/``camera_sigma_z``); camera QoS.
  The attitude is ``q_GCRS_VF`` in ``reference_frame_id``.
* ``calibration/boresight``  geometry_msgs/PoseWithCovarianceStamped, latched (transient
  local), only with ``boresight_source: topic``: the orientation is ``q_MF_VF`` (as
  ``calibrator_node`` publishes it); fixes before the first one are dropped and counted. The
  boresight is taken as known: its covariance is not used (``augment: boresight`` estimates a
  mounting error on top of it).

Publishes (stream QoS unless said; one message per ``output_period`` of stamp time, at the
first increment stamp of each period, the state at exactly that stamp):

* ``filter/attitude``  geometry_msgs/QuaternionStamped: q_ref_body, frame ``reference_frame_id``.
* ``filter/imu``  sensor_msgs/Imu, frame ``frame_id``: orientation = q_ref_body;
  orientation_covariance = covariance of the attitude error ε in body axes, rad²;
  angular_velocity = the bias-compensated mean body rate since the previous output, with
  angular_velocity_covariance = P_bias + (gyro_random_walk² / output_period)·I; no linear
  acceleration (linear_acceleration_covariance[0] = −1, REP 145).
* ``filter/gyro_bias``  geometry_msgs/Vector3Stamped, frame ``frame_id``: the estimated gyro
  bias, rad/s, body axes.
* ``filter/gyro_bias_with_covariance``  geometry_msgs/TwistWithCovarianceStamped: twist.angular
  = the bias, covariance rows/cols 3–5 = its covariance, (rad/s)²; the linear part is not
  estimated: 0 with −1 on its diagonal (rows/cols 0–2).
* per fix processed (camera QoS): ``filter/innovation`` geometry_msgs/Vector3Stamped, the
  residual z = log(q_meas⁻¹ ⊗ q̂_ref_body ⊗ q_MF_VF), VF axes, rad, frame
  ``camera_frame_id``,
  stamp = the fix's; ``filter/nis`` geometry_msgs/Vector3Stamped, x = NIS, y = its degrees of
  freedom (3), z = the gate (χ²(3) quantile of ``gate_probability``); a gated fix is published
  too (x > z), and so is the fix that declares a divergence.
* ``/diagnostics``  every ``diagnostics_period``: the counters of the core (fixes applied,
  gated, too old, late fixes and the largest lateness, restarts, gaps, dropped input), each
  augmented state and its σ (``<name>_<k>``, ``<name>_sigma_<k>``), the gyro bias and σ, the
  last NIS, and the live model check (``model_check``: its text; WARN while a WARN episode is
  on, e.g. "innovations match gyro_scale_factor (p = …): run discrepancy on a recording"; the
  node never changes its model itself).  A divergence (``divergence_gated_fixes`` consecutive
  gated fixes, or the NIS of the last ``divergence_nis_window`` fixes passing the gate above
  its χ² quantile of ``divergence_nis_probability``) re-initialises the attitude from the fix
  (the bias kept) and restarts the live model check: an ERROR (logged, and on /diagnostics
  until as many fixes have passed since; then a WARN that counts the resets; values ``reset``,
  ``fixes_since_reset``, ``last_reset_stamp``, ``last_reset_reason``).  The level is the worst
  of the conditions
  (:class:`~strapdown_ros.nodes.ros_status.Conditions`).

At construction the node runs a throw-away filter of its model through a few seconds of
synthetic data (:func:`~strapdown_ros.estimation.filter_system.warm_up`): the compiled kernel
is loaded and every code path of a fix has run before the first message.

No parameter may change at runtime (the filter's model is its state); restart the node.
"""
from __future__ import annotations

import sys

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import (PoseWithCovarianceStamped, QuaternionStamped,
                               TwistWithCovarianceStamped, Vector3Stamped)
import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import Imu

from strapdown_ros.estimation.chi_square import chi2_3_quantile
from strapdown_ros.estimation.filter_system import FilterSettings, FilterSystem, warm_up
from strapdown_ros.nodes import ros_io, ros_params, ros_process, ros_status
from strapdown_ros.params import FILTER_PARAMS, model_from_parameters, not_applied_note
from strapdown_ros.streams.fixes import unit_quaternion
from strapdown_ros.streams.rate_increments import RateIncrementStream

NODE_NAME = 'attitude_filter_node'


class AttitudeFilterNode(Node):
    """
    The star-camera-aided attitude filter node: ROS in and out of the core filter.

    Parameters
    ----------
    **kwargs
        Passed to :class:`rclpy.node.Node` (namespace, parameter_overrides, ...).

    """

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self.log = ros_status.NodeLog(self.get_logger())
        self.p = ros_params.declare_validated(self, FILTER_PARAMS, on_change=self._on_change)
        p = self.p
        # the edge: ROS parameters → the sensor model and the filter's typed settings
        model, warnings = model_from_parameters(p, f'{NODE_NAME} parameters')
        for w in warnings:
            self.log.warn(w)
        note = not_applied_note(model, ('gyro', 'reference', 'filter'), NODE_NAME)
        if note:
            self.log.info(note)
        self.model = model
        settings = FilterSettings.from_values(p)
        self.system = FilterSystem(model, settings)
        try:            # the compiled kernel and every code path of a fix, before any message
            warm_up(model, settings)
        except ValueError as exc:                # the model cannot start a filter: said now
            self.log.error(f'the filter cannot start with these parameters: {exc}')
        self.frame_id = model.frame_id
        self.ref_frame = model.reference_frame_id
        self.camera_frame = model.camera_frame_id
        self.reject_frames = p['frame_mismatch'] == 'reject'
        self.use_cov = bool(p['use_camera_covariance'])
        self.imu_input = p['gyro_input'] == 'imu'
        self.gate = chi2_3_quantile(float(p['gate_probability']))
        self.rate_variance = model.gyro.random_walk ** 2 / float(p['output_period'])
        self.undecodable = 0
        self.frame_mismatch = {'gyro': 0, 'camera': 0}
        self.boresight_counts = {'received': 0, 'dropped': 0}
        self.published = {'outputs': 0, 'fixes': 0}
        self.last_output = None
        self.last_fix = None
        self.restarts_seen = 0
        self.resets_seen = 0
        #: fixes after a divergence reset during which /diagnostics stays at ERROR
        self.recovery_fixes = max(int(p['divergence_gated_fixes']),
                                  int(p['divergence_nis_window']), 1)
        depth = int(p['qos_depth'])
        qos = ros_io.stream_qos(depth)
        over = ros_io.QOS_OVERRIDES
        self.pub_att = self.create_publisher(QuaternionStamped, 'filter/attitude', qos,
                                             qos_overriding_options=over)
        self.pub_imu = self.create_publisher(Imu, 'filter/imu', qos, qos_overriding_options=over)
        self.pub_bias = self.create_publisher(Vector3Stamped, 'filter/gyro_bias', qos,
                                              qos_overriding_options=over)
        self.pub_bias_cov = self.create_publisher(TwistWithCovarianceStamped,
                                                  'filter/gyro_bias_with_covariance', qos,
                                                  qos_overriding_options=over)
        fix_qos = ros_io.camera_qos(depth)
        self.pub_innov = self.create_publisher(Vector3Stamped, 'filter/innovation', fix_qos,
                                               qos_overriding_options=over)
        self.pub_nis = self.create_publisher(Vector3Stamped, 'filter/nis', fix_qos,
                                             qos_overriding_options=over)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics',
                                              ros_io.DIAGNOSTICS_QOS)
        if self.imu_input:
            period = model.gyro_period
            self.gyro_rates = RateIncrementStream(period, model.gyro_max_rate,
                                                  p['imu_rate_rule'], float(p['max_stamp_jump']),
                                                  int(p['resync_count']))
            self.last_imu = None
            self.create_subscription(Imu, 'imu/data_raw', self.on_imu_raw, qos,
                                     qos_overriding_options=over, raw=True)
        else:
            self.create_subscription(Vector3Stamped, 'imu/delta_theta', self.on_gyro_raw, qos,
                                     qos_overriding_options=over, raw=True)
        if self.use_cov:
            self.create_subscription(PoseWithCovarianceStamped,
                                     'star_camera/attitude_with_covariance', self._on_camera_cov,
                                     fix_qos, qos_overriding_options=over)
        else:
            self.create_subscription(QuaternionStamped, 'star_camera/attitude',
                                     self._on_camera_plain, fix_qos, qos_overriding_options=over)
        if p['boresight_source'] == 'topic':
            self.create_subscription(PoseWithCovarianceStamped, 'calibration/boresight',
                                     self._on_boresight, ros_io.latched_qos())
        self.create_timer(float(p['diagnostics_period']), self.publish_diagnostics)
        gyro_topic = f"imu/data_raw ({p['imu_rate_rule']})" if self.imu_input \
            else 'imu/delta_theta'
        camera_topic = 'star_camera/attitude_with_covariance' if self.use_cov \
            else 'star_camera/attitude'
        self.log.info(f'started: gyro input {gyro_topic}, camera {camera_topic}, boresight from '
                      f"{p['boresight_source']}, estimated online: gyro_bias"
                      f"{''.join(', ' + n for n in model.augment)}; compensated: "
                      f"{', '.join(model.active('gyro') + model.active('camera')) or 'none'}")

    # --- parameters ---------------------------------------------------------------------
    def _on_change(self, new: dict) -> str | None:
        """No parameter may change at runtime: the filter's model is its state."""
        return ("no parameter of attitude_filter_node can change at runtime (the filter's model "
                'is its state); restart the node to change ' + ', '.join(sorted(new)))

    # --- input ------------------------------------------------------------------------------
    def on_gyro_raw(self, data: bytes):
        """
        Take one imu/delta_theta message: stamp, vector and frame from its bytes.

        Parameters
        ----------
        data : bytes
            The serialized geometry_msgs/Vector3Stamped.

        """
        got = ros_io.decode_vector3_stamped(data)
        if got is None:
            self.undecodable += 1
            return
        self.gyro(*got)

    def on_imu_raw(self, data: bytes):
        """
        Take one imu/data_raw message (``gyro_input: imu``).

        Parameters
        ----------
        data : bytes
            The serialized sensor_msgs/Imu.

        """
        got = ros_io.decode_imu(data)
        if got is None:
            self.undecodable += 1
            return
        self.last_imu = data
        if not self._frame_ok('gyro', got[3], self.frame_id):
            return
        for ns, dth in self.gyro_rates.push(got[0], got[1]):
            self.gyro(ns, dth, '')

    def gyro(self, stamp_ns: int, value, frame_id: str = '') -> None:
        """
        Take one Δθ: the frame rule, then the core.

        The core runs when an output or a waiting fix is reached (:meth:`FilterSystem.due`).

        Parameters
        ----------
        stamp_ns : int
            Header stamp, ns (the end of the increment's interval).
        value : (3,) sequence of float
            Δθ, rad, body axes.
        frame_id : str
            The header frame id.

        """
        if not self._frame_ok('gyro', frame_id, self.frame_id):
            return
        self.system.offer_gyro(int(stamp_ns), value)
        if self.system.due():
            self.process()

    def _on_camera_cov(self, msg: PoseWithCovarianceStamped):
        self.fix(msg.header, msg.pose.pose.orientation, ros_io.rotation_block(msg))

    def _on_camera_plain(self, msg: QuaternionStamped):
        self.fix(msg.header, msg.quaternion, None)

    def fix(self, header, q_msg, covariance) -> None:
        """
        Take one camera fix q_GCRS_VF.

        Parameters
        ----------
        header : std_msgs.msg.Header
            The fix's header (stamp, frame id).
        q_msg : geometry_msgs.msg.Quaternion
            q_GCRS_VF, ROS order x, y, z, w.
        covariance : (3, 3) array_like or None
            Its covariance, VF axes, rad²; None for the camera σ of the parameters.

        """
        if not self._frame_ok('camera', header.frame_id, self.ref_frame):
            return
        self.system.offer_fix(ros_io.stamp_to_ns(header.stamp),
                              ros_io.quaternion_from_msg(q_msg), covariance)
        self.process()

    def _on_boresight(self, msg: PoseWithCovarianceStamped):
        self.boresight_counts['received'] += 1
        # the quaternion rules of THE screening of a fix: normalised without overflow
        q, why = unit_quaternion(ros_io.quaternion_from_msg(msg.pose.pose.orientation))
        if q is None:
            self.boresight_counts['dropped'] += 1
            self.log.warn(f"calibration/boresight dropped: {why.replace('_', ' ')}",
                          throttle=10.0)
            return
        self.system.set_boresight(q)
        self.log.info(f'boresight q_MF_VF from calibration/boresight: {np.round(q, 9)}')

    def _frame_ok(self, which: str, frame: str, expected: str) -> bool:
        if frame and frame != expected:
            self.frame_mismatch[which] += 1
            self.log.warn(f'{which} message in frame {ros_status.bounded(frame, 80)!r}, expected '
                          f"{expected!r}: {'rejected' if self.reject_frames else 'used'}",
                          throttle=10.0, key=f'frame_{which}')
            return not self.reject_frames
        return True

    # --- output ------------------------------------------------------------------------------
    def process(self) -> None:
        """Run the core over the buffered increments and publish what it produced."""
        self.system.process()
        outputs, fixes = self.system.take()
        for o in outputs:
            self._publish_output(o)
        for f in fixes:
            self._publish_fix(f)
        restarts = self.system.counts['restarts']
        if restarts > self.restarts_seen:
            self.restarts_seen = restarts
            self.log.error('gyro gap or stamp jump: the rotation in it is lost; the filter '
                           'restarts at the next fix', throttle=5.0)
        resets = self.system.counts['reset']
        if resets > self.resets_seen:
            self.resets_seen = resets
            ns, why = self.system.resets[-1]
            self.log.error(f'divergence at {ns * 1e-9:.3f} s: {why}; the attitude is '
                           're-initialised from that fix (bias kept), '
                           f'{resets} reset(s) so far', throttle=5.0, key='divergence')

    def _publish_output(self, o) -> None:
        """Publish one output on the topics that have subscribers (none built for none)."""
        self.last_output = o
        pubs = (self.pub_att, self.pub_imu, self.pub_bias, self.pub_bias_cov)
        wanted = [p.get_subscription_count() > 0 for p in pubs]
        if not any(wanted):
            return
        self.published['outputs'] += 1               # sent on at least one topic
        st = ros_io.ns_to_stamp(o.stamp_ns)
        if wanted[0]:
            self.pub_att.publish(ros_io.quaternion_stamped(st, self.ref_frame, o.attitude))
        if wanted[1]:
            m = Imu()
            m.header.stamp = st
            m.header.frame_id = self.frame_id
            m.orientation = ros_io.quaternion_msg(o.attitude)
            m.orientation_covariance = [float(c) for c in o.attitude_covariance.reshape(9)]
            m.angular_velocity = ros_io.vector3(o.rate)
            rate_cov = o.bias_covariance + self.rate_variance * np.eye(3)
            m.angular_velocity_covariance = [float(c) for c in rate_cov.reshape(9)]
            m.linear_acceleration_covariance = [-1.0] + [0.0] * 8
            self.pub_imu.publish(m)
        if wanted[2]:
            self.pub_bias.publish(ros_io.vector3_stamped(st, self.frame_id, o.bias))
        if wanted[3]:
            t = TwistWithCovarianceStamped()
            t.header.stamp = st
            t.header.frame_id = self.frame_id
            t.twist.twist.angular = ros_io.vector3(o.bias)
            cov = np.zeros((6, 6))
            cov[0, 0] = cov[1, 1] = cov[2, 2] = -1.0
            cov[3:, 3:] = o.bias_covariance
            t.twist.covariance = [float(c) for c in cov.reshape(36)]
            self.pub_bias_cov.publish(t)

    def _publish_fix(self, f) -> None:
        self.last_fix = f
        if f.innovation is None or f.nis is None:
            return
        st = ros_io.ns_to_stamp(f.stamp_ns)
        self.pub_innov.publish(ros_io.vector3_stamped(st, self.camera_frame, f.innovation))
        self.pub_nis.publish(ros_io.vector3_stamped(st, self.camera_frame,
                                                    (float(f.nis), 3.0, float(self.gate))))
        self.published['fixes'] += 1
        if not f.check_ok:
            self.log.warn(f'live model check: {f.check_text}', throttle=30.0, key='model_check')

    # --- diagnostics ---------------------------------------------------------------------------
    def diagnostic_conditions(self, st: dict) -> ros_status.Conditions:
        """
        Return every current condition with its level.

        Parameters
        ----------
        st : dict
            The filter's status (counters and state).

        Returns
        -------
        Conditions
            The conditions; the status level is the worst of them.

        """
        c = ros_status.Conditions()
        g = self.system.gyro_check
        if g.accepted == 0:
            c.add(ros_status.WARN, 'no gyro increments received')
        if self.system.boresight is None:
            c.add(ros_status.WARN, f'no boresight yet (calibration/boresight): '
                  f"{st['dropped_no_boresight']} fix(es) dropped")
        elif self.system.filter is None:
            c.add(ros_status.WARN, 'waiting for a camera fix to start')
        if g.dropped:
            c.add(ros_status.WARN, f'dropped {g.dropped} gyro messages (NaN {g.nan}, out of range '
                  f'{g.out_of_range}, out of order {g.out_of_order}, duplicate {g.duplicate}, '
                  f'stamp outliers {g.stamp_outliers})')
        m = self.model
        clips = [g.clip_warning('gyro_max_rate', m.gyro_max_rate, 'rad/s', m.gyro_period)]
        if self.imu_input:
            clips.append(self.gyro_rates.check.clip_warning('gyro_max_rate', m.gyro_max_rate,
                                                            'rad/s'))
        for text in filter(None, clips):
            c.add(ros_status.WARN, text)
        if self.imu_input and self.gyro_rates.check.dropped:
            c.add(ros_status.WARN, f'dropped {self.gyro_rates.check.dropped} angular-rate samples '
                  'of imu/data_raw')
        cam = self.system.camera_check
        scr = self.system.fix_screen
        bad_fix = cam.dropped + scr.dropped
        if bad_fix:
            c.add(ros_status.WARN,
                  f'dropped {bad_fix} camera fixes (NaN {cam.nan + scr.nan}, zero quaternion '
                  f'{scr.zero_quaternion}, not unit {scr.not_unit}, bad covariance '
                  f'{scr.bad_covariance}, out of order '
                  f'{cam.out_of_order}, duplicate {cam.duplicate}, stamp outliers '
                  f'{cam.stamp_outliers})')
        if cam.resyncs:
            c.add(ros_status.ERROR, f'camera stamps jumped {cam.resyncs} time(s) and stayed: '
                  'resynchronised, the filter restarted')
        if self.boresight_counts['dropped']:
            c.add(ros_status.WARN, f"{self.boresight_counts['dropped']} calibration/boresight "
                  'message(s) dropped (zero or non-finite quaternion)')
        if st['gated']:
            c.add(ros_status.WARN, f"{st['gated']} fix(es) gated: NIS above the χ²(3) gate "
                  f"{self.gate:.4g} (gate_probability {self.p['gate_probability']})")
        if st['too_old'] or st['overflow']:
            c.add(ros_status.WARN, f"{st['too_old']} fix(es) older than the increment history and "
                  f"{st['overflow']} beyond the pending limit dropped")
        if st.get('late_fixes'):
            c.add(ros_status.OK, f"{st['late_fixes']} late fix(es), largest lateness "
                  f"{st['max_lateness_s']:.3g} s")
        if any(self.frame_mismatch.values()):
            c.add(ros_status.WARN, f'messages in an unexpected frame: gyro '
                  f"{self.frame_mismatch['gyro']}, camera {self.frame_mismatch['camera']} "
                  f"({'rejected' if self.reject_frames else 'used'})")
        if self.undecodable:
            c.add(ros_status.WARN, f'{self.undecodable} gyro message(s) could not be decoded: '
                  'dropped')
        chk = self.system.check
        if chk is not None and not chk.last.ok:
            c.add(ros_status.WARN, f'live model check: {chk.last.text()}')
        if st['reset']:
            ns, why = self.system.resets[-1]
            since = st.get('fixes_since_reset')
            text = (f"divergence: {st['reset']} reset(s), the last at {ns * 1e-9:.3f} s ({why}); "
                    'the attitude was re-initialised from the fix')
            if since is not None and since < self.recovery_fixes:
                c.add(ros_status.ERROR, f'{text}, {since} fix(es) since')
            else:
                c.add(ros_status.WARN, text)
        if g.missing:
            c.add(ros_status.ERROR, f'{g.missing} gyro increments missing in {g.gaps} gaps: the '
                  f"rotation is lost; the filter restarted {st['restarts']} time(s)")
        if g.resyncs:
            c.add(ros_status.ERROR, f'gyro stamps jumped {g.resyncs} time(s): resynchronised, the '
                  'filter restarted')
        return c

    def publish_diagnostics(self):
        """Publish the /diagnostics status of the node."""
        st = self.system.status()
        c = self.diagnostic_conditions(st)
        cam = self.system.camera_check
        values = dict(st)
        scr = self.system.fix_screen
        values.update({'camera_received': scr.received, 'camera_accepted': cam.accepted,
                       'camera_dropped_nan': cam.nan + scr.nan,
                       'camera_dropped_out_of_order': cam.out_of_order,
                       'camera_dropped_duplicate': cam.duplicate,
                       'camera_dropped_stamp_outlier': cam.stamp_outliers,
                       'camera_stamp_resyncs': cam.resyncs,
                       **{f'camera_bad_covariance_{k}': v
                          for k, v in scr.bad_covariance_reasons.items()},
                       'gyro_undecodable_dropped': self.undecodable,
                       'gyro_frame_mismatch': self.frame_mismatch['gyro'],
                       'camera_frame_mismatch': self.frame_mismatch['camera'],
                       'boresight_source': self.p['boresight_source'],
                       'boresight_received': self.boresight_counts['received'],
                       'boresight_dropped': self.boresight_counts['dropped'],
                       'outputs_published': self.published['outputs'],
                       'fixes_published': self.published['fixes'], 'nis_gate': self.gate})
        o = self.last_output
        if o is not None:
            sb = np.sqrt(np.maximum(np.diag(o.bias_covariance), 0.0))
            for k, a in enumerate('xyz'):
                values[f'gyro_bias_{a}'] = float(o.bias[k])
                values[f'gyro_bias_sigma_{a}'] = float(sb[k])
            for name, (v, s) in o.augmented.items():
                for k in range(len(v)):
                    values[f'{name}_{k}'] = float(v[k])
                for k in range(len(s)):           # the boresight: 4 components, 3 σ
                    values[f'{name}_sigma_{k}'] = float(s[k])
        if self.last_fix is not None and self.last_fix.nis is not None:
            values['last_nis'] = float(self.last_fix.nis)
            values['last_fix_status'] = self.last_fix.status
        if self.system.resets:
            ns, why = self.system.resets[-1]
            values['last_reset_stamp'] = ns * 1e-9
            values['last_reset_reason'] = ros_status.bounded(why)
        chk = self.system.check
        values['model_check'] = (ros_status.bounded(chk.last.text()) if chk is not None
                                 else 'not started')
        if self.imu_input:
            values.update({'gyro_input': 'imu', 'imu_rate_rule': self.p['imu_rate_rule'],
                           'imu_stated_rate_variance':
                               ros_io.stated_rate_variance(self.last_imu),
                           **self.gyro_rates.status('imu_gyro')})
        g = self.system.gyro_check
        stamp_ns = g.last_ns if g.last_ns is not None else 0
        self.pub_diag.publish(ros_status.diagnostic_array(
            ros_io.ns_to_stamp(stamp_ns), f'{self.get_fully_qualified_name()}: attitude filter',
            'attitude_filter', c.level, c.message(), values))


def main(args=None):
    """
    Run attitude_filter_node (the entry point of its process).

    Parameters
    ----------
    args : list of str, optional
        ROS arguments (default the process's).

    Returns
    -------
    int
        The exit status (:func:`strapdown_ros.nodes.ros_process.run_node`).

    """
    return ros_process.run_node(AttitudeFilterNode, NODE_NAME, args)


if __name__ == '__main__':
    sys.exit(main())
