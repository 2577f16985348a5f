"""
calibrator_node: the boresight β of a star camera (VF) relative to the IMU (MF), live (004).

A thin wrapper around :class:`~strapdown_ros.calibration.streaming.BoresightCalibrator` (the same
object ``calibrate_bag`` uses offline, so live and offline answers agree).

Subscribes:

* ``imu/delta_theta``  geometry_msgs/Vector3Stamped, rad, stamp = end of interval (stream QoS);
  with ``gyro_input: imu`` instead ``imu/data_raw`` sensor_msgs/Imu (stream QoS): each
  angular_velocity is validated as a rate sample and made into Δθ by ``imu_rate_rule``
  (:class:`strapdown_ros.streams.rate_increments.RateIncrementStream`, as ``sins_node``); the
  increments take the path of imu/delta_theta.  Covariance fields and linear_acceleration are
  not used.
* ``star_camera/attitude_with_covariance``  geometry_msgs/PoseWithCovarianceStamped (when
  ``use_camera_covariance``: P_avu = the rotation block, rows/cols 3..5, VF axes, rad²), or
  ``star_camera/attitude``  geometry_msgs/QuaternionStamped (otherwise: P_avu =
  diag(σ_xy², σ_xy², σ_z²) from ``camera_sigma_xy``/``camera_sigma_z``).  Both RELIABLE,
  VOLATILE, KEEP_LAST(``qos_depth``): fixes are rare and each one matters.

Publishes, only while the boresight is observable and the solver converged:

* ``calibration/boresight``  geometry_msgs/PoseWithCovarianceStamped, RELIABLE +
  TRANSIENT_LOCAL, depth 1 (a late subscriber gets the latest estimate).  frame_id =
  ``frame_id`` (MF); orientation = q_MF_VF = C_MF^VF (VF coordinates → MF coordinates: the
  orientation of the camera frame in the IMU frame, the ROS meaning of a pose); the rotation
  block of the covariance is P^clb = D2 P_β D2ᵀ (MF axes, rad², 004 eq. 8); position is not
  estimated: 1e9 m² on its diagonal (as ``star_camera_sim_node``).  Stamp = the end stamp
  t_{E,n} of the newest increment pair.
* ``calibration/boresight_angles``  geometry_msgs/Vector3Stamped, same QoS and frame: β =
  (ψ, ϑ, γ) in rad in x, y, z (004 eq. 1, :func:`~strapdown_ros.rotation.ypr_to_dcm`).
* ``calibration/imu_attitude_from_camera``  geometry_msgs/PoseWithCovarianceStamped, camera
  QoS, one per accepted camera fix once a valid boresight exists (fixes that arrive before
  it wait, the latest ``qos_depth`` of them): q_GCRS_MF = q_GCRS_VF ⊗ q_MF_VFᵀ with P^mfa =
  C P_avu Cᵀ + D2 P_β D2ᵀ (004 §5 eq. 8, MF axes), frame_id = ``reference_frame_id``,
  stamp = the fix's stamp.
* ``/diagnostics``  every ``diagnostics_period``: the frames (``camera_frame_id`` in
  ``frame_id``: the pose message has no child-frame field, and no tf is broadcast), pairs,
  observability (level WARN and the solver's reason when not observable), residual RMS,
  iterations, χ²/dof with its two-sided band at level 0.01 and ``fit_consistent`` (WARN
  ``FIT INCONSISTENT`` outside the band: the stated noise is wrong or the model lacks an
  effect), β and its σ, the processing time of the last solve (perf_counter, ms;
  not used for timing), and the input counters.

When the boresight is not observable nothing is published on the calibration topics; the
reason (which VF rotation axis, and why: one rotation axis, static motion, too few pairs) is
logged when it changes and reported on ``/diagnostics``.  (Once observable, more pairs only
add information; a later invalid solve — possible after a runtime change of ``weighted`` or with a
``max_pairs`` window — publishes nothing and leaves the last valid estimate latched.)

Input validation (as ``sins_node``): NaN/Inf, out-of-order and duplicate stamps are dropped
and counted on both inputs; a gyro gap (missing increments: their rotation is lost; the gap
rule of :class:`~strapdown_ros.streams.checks.StreamCheck`, the period from the stamps) is
counted, reported as ERROR, and every increment pair that spans it is discarded.  Each camera
fix passes THE screening of a reference fix (:class:`~strapdown_ros.streams.fixes.FixScreen`,
as ``attitude_filter_node`` and the offline tools): a quaternion that is not unit is
normalised without overflow and counted, a zero or non-finite one dropped; a covariance whose
rotation block is all zero (the ROS "unknown") is replaced by the ``camera_sigma_*`` diagonal
and counted; one that is not symmetric, not positive definite or beyond its bounds is dropped
and counted; then the stamp rules of a fix stream (a lone fix stamped ahead is an outlier).
Stamps are handled in integer nanoseconds relative to the first stamp seen on any input; timing
comes only from header stamps.

``state_file`` (strapdown_ros.calibration.state): the pairs persist with their identity (the
parameters that define the estimate, the frames, the resolved topics); a file of another
calibration is refused and left as it is; a replay adds no pair (pairs keyed by stamps); a lock
file keeps a second node off it (ERROR, no persistence); a directory is refused, never moved.

Only ``weighted`` may change at runtime (the estimate is recomputed at once); every other
parameter is fixed after start-up.
"""
from __future__ import annotations

from collections import deque
import math
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseWithCovarianceStamped, QuaternionStamped, Vector3Stamped
import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import Imu

from strapdown_ros.calibration.boresight import imu_attitude_from_camera
from strapdown_ros.calibration.state import CalibratorStateFile, state_identity, StateFileError
from strapdown_ros.calibration.streaming import BoresightCalibrator, CalibratorSettings
from strapdown_ros.nodes import ros_io, ros_params, ros_process, ros_status
from strapdown_ros.nodes.calibrator_status import boresight_status
from strapdown_ros.nodes.ros_io import (camera_qos, latched_qos, pose_with_covariance,
                                        rotation_block)
from strapdown_ros.params import CALIBRATOR_PARAMS, model_from_parameters, not_applied_note
from strapdown_ros.streams.checks import StreamCheck
from strapdown_ros.streams.fixes import FixScreen
from strapdown_ros.streams.rate_increments import RateIncrementStream

NODE_NAME = 'calibrator_node'
#: the forward stamp limit of the fixes until their period is known, s (StreamCheck.for_fixes)
CAMERA_JUMP_S = StreamCheck.FIX_INITIAL_JUMP_S
# a not-observable reason that keeps its wording is repeated at most this often
LOG_THROTTLE_S = 30.0


class CalibratorNode(Node):
    """
    The boresight calibrator node: ROS in and out of :class:`BoresightCalibrator`.

    Parameters
    ----------
    **kwargs
        Passed to :class:`rclpy.node.Node` (namespace, parameter_overrides, ...).

    """

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self.log = ros_status.NodeLog(self.get_logger())   # the one logging helper of the nodes
        self.p = ros_params.declare_validated(self, CALIBRATOR_PARAMS, on_change=self._on_change,
                                              apply=self._apply_change)
        p = self.p
        # the edge: ROS parameters → the sensor model and the calibrator's typed settings
        model, warnings = model_from_parameters(p, f'{NODE_NAME} parameters')
        for w in warnings:
            self.log.warn(w)
        note = not_applied_note(model, ('gyro', 'reference'), NODE_NAME)
        if note:
            self.log.info(note)
        self.model = model
        self.gyro_period = model.gyro_period
        # as calibrate_bag builds it (effects compensated)
        self.cal = BoresightCalibrator.from_model(model, CalibratorSettings.from_values(p))
        self.default_p_avu = np.diag(model.camera_sigma ** 2)
        jump, resync = float(p['max_stamp_jump']), int(p['resync_count'])
        self.gyro_check = StreamCheck(self.gyro_period,
                                      max_norm=2.0 * self.gyro_period * model.gyro_max_rate,
                                      jump_limit=jump, resync_count=resync)
        # exposures need not be periodic (no gap test); their period from their own stamps
        self.camera_check = StreamCheck.for_fixes(jump, resync)
        self.fix_screen = FixScreen(self.default_p_avu, bool(p['use_camera_covariance']))
        self.solve_failures = 0
        self.gyro_frame_mismatch = 0
        self.reject_frames = p['frame_mismatch'] == 'reject'
        self.camera_counts = {'dropped_zero_quaternion': 0, 'dropped_not_unit': 0,
                              'normalised': 0, 'dropped_bad_covariance': 0,
                              'covariance_substituted': 0, 'frame_mismatch': 0}
        # stamps are handled relative to the first one
        self.origin_ns: int | None = None
        self.gaps: deque = deque(maxlen=1000)          # (start, end) relative seconds of gyro gaps
        self.pairs_discarded_gap = 0
        self.solves = 0
        self.solve_ms = float('nan')
        self.published = {'boresight': 0, 'imu_attitude_from_camera': 0}
        # serialized gyro input that is not a Vector3Stamped
        self.undecodable = 0
        self.valid = None                              # the latest observable, converged solution
        self.valid_stamp_ns: int | None = None
        # (stamp_ns, q, P) awaiting a solution
        self.pending_fixes: deque = deque(maxlen=int(p['qos_depth']))
        self._last_reason: str | None = None
        self._last_reason_log = -math.inf
        self.frame_id = p['frame_id']
        self.ref_frame = p['reference_frame_id']
        self.use_cov = bool(p['use_camera_covariance'])

        self.pub_boresight = self.create_publisher(PoseWithCovarianceStamped,
                                                   'calibration/boresight', latched_qos())
        self.pub_angles = self.create_publisher(Vector3Stamped, 'calibration/boresight_angles',
                                                latched_qos())
        self.pub_imu_att = self.create_publisher(PoseWithCovarianceStamped,
                                                 'calibration/imu_attitude_from_camera',
                                                 camera_qos(int(p['qos_depth'])),
                                                 qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics',
                                              ros_io.DIAGNOSTICS_QOS)
        self.imu_input = p['gyro_input'] == 'imu'
        # raw subscriptions: stamp, vector and frame decoded from the bytes in ros_io
        if self.imu_input:                  # rate samples made into Δθ (the rule of sins_node)
            self.gyro_rates = RateIncrementStream(self.gyro_period, model.gyro_max_rate,
                                                  p['imu_rate_rule'], jump, resync)
            self.last_imu = None                       # the latest Imu (bytes or message)
            self.create_subscription(Imu, 'imu/data_raw', self.on_imu_raw,
                                     ros_io.stream_qos(int(p['qos_depth'])),
                                     qos_overriding_options=ros_io.QOS_OVERRIDES, raw=True)
        else:
            self.create_subscription(Vector3Stamped, 'imu/delta_theta', self.on_gyro_raw,
                                     ros_io.stream_qos(int(p['qos_depth'])),
                                     qos_overriding_options=ros_io.QOS_OVERRIDES, raw=True)
        if self.use_cov:
            self.create_subscription(PoseWithCovarianceStamped,
                                     'star_camera/attitude_with_covariance',
                                     self.on_camera_cov, camera_qos(int(p['qos_depth'])),
                                     qos_overriding_options=ros_io.QOS_OVERRIDES)
        else:
            self.create_subscription(QuaternionStamped, 'star_camera/attitude',
                                     self.on_camera_plain,
                                     camera_qos(int(p['qos_depth'])),
                                     qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.create_timer(float(p['diagnostics_period']), self.publish_diagnostics)
        self.state = {'file': p['state_file'], 'saves': 0, 'restored_pairs': 0, 'errors': 0,
                      'moved_aside': '', 'problem': '', 'persisting': False}
        self.state_file: CalibratorStateFile | None = None
        camera_topic = ('star_camera/attitude_with_covariance' if self.use_cov
                        else 'star_camera/attitude')
        gyro_topic = (f"imu/data_raw ({p['imu_rate_rule']})" if self.imu_input
                      else 'imu/delta_theta')
        if p['state_file']:
            gyro_name = 'imu/data_raw' if self.imu_input else 'imu/delta_theta'
            streams = {'gyro': self.resolve_topic_name(gyro_name),
                       'camera': self.resolve_topic_name(camera_topic)}
            self._restore_state(state_identity(dict(p), streams))
        self.log.info(
            f'started: gyro input {gyro_topic}, camera input {camera_topic}, '
            f"weighted={p['weighted']}, covariance_model={p['covariance_model']}, "
            f"min_rotation {p['min_rotation_deg']:g}°, max_sigma {p['max_sigma']:g} rad, "
            f"max_pairs {p['max_pairs']}")

    # --- parameters ---------------------------------------------------------------------
    def _on_change(self, new: dict) -> str | None:
        """Validate a change (on-set): only the weighting may change at runtime."""
        fixed = sorted(set(new) - {'weighted'})
        if fixed:
            return ('only weighted can change at runtime; restart the node to change '
                    + ', '.join(fixed))
        return None

    def _apply_change(self, new: dict) -> None:
        """Application (post-set), once rclpy has accepted the change."""
        w = bool(new['weighted'])
        if w != self.cal.weighted:
            self.cal.weighted = w
            self.p['weighted'] = w
            self.log.info(f'weighted switched to {w}; re-solving')
            # the warm start of the previous weighting is as good a start as any: solve() keeps it
            if len(self.cal.pairs) >= 2:
                self._solve()

    # --- input ------------------------------------------------------------------------------
    def _rel(self, stamp_ns: int) -> float:
        if self.origin_ns is None:
            self.origin_ns = stamp_ns
        return (stamp_ns - self.origin_ns) * 1e-9

    def _abs_ns(self, t_rel: float) -> int:
        return self.origin_ns + int(round(t_rel * 1e9))

    def on_gyro_raw(self, data: bytes):
        """
        Take one imu/delta_theta message: stamp, vector and frame read from its bytes.

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
        v = msg.vector
        self._gyro(ros_io.stamp_to_ns(msg.header.stamp), (v.x, v.y, v.z), msg.header.frame_id)

    def on_imu_raw(self, data: bytes):
        """
        Take one imu/data_raw message (``gyro_input: imu``): stamp, rate and frame from its bytes.

        Parameters
        ----------
        data : bytes
            The serialized sensor_msgs/Imu (a raw subscription's argument).

        """
        got = ros_io.decode_imu(data)
        if got is None:
            self.undecodable += 1
            return
        self.last_imu = data                   # its stated covariance: read for /diagnostics
        self._imu(got[0], got[1], got[3])

    def on_imu(self, msg: Imu):
        """
        Take one imu/data_raw message object (tests, tools).

        Parameters
        ----------
        msg : sensor_msgs.msg.Imu
            The message.

        """
        w = msg.angular_velocity
        self.last_imu = msg
        self._imu(ros_io.stamp_to_ns(msg.header.stamp), (w.x, w.y, w.z), msg.header.frame_id)

    def _imu(self, ns: int, rate, f: str):
        """
        Take one rate sample: the frame rule, then validation and the increment rule.

        One rate sample: the frame rule, then validation and the increment rule
        (RateIncrementStream); each increment formed enters the Δθ path (:meth:`_gyro`).
        """
        if not self._gyro_frame_ok(f):
            return
        for ns_i, dth in self.gyro_rates.push(ns, rate):
            self._gyro(ns_i, dth, '')

    def _gyro_frame_ok(self, f: str) -> bool:
        if f and f != self.frame_id:                   # the frame rule of sins_node
            self.gyro_frame_mismatch += 1
            self.log.warn(f'gyro increment in frame {ros_status.bounded(f, 80)!r}, expected '
                          f'{self.frame_id!r}: '
                          f"{'rejected' if self.reject_frames else 'used'}",
                          throttle=10.0, key='gyro_frame')
            if self.reject_frames:
                return False
        return True

    def _gyro(self, ns: int, value, f: str):
        if not self._gyro_frame_ok(f):
            return
        g = self.gyro_check
        prev_ns = g.last_ns
        out = g.offer(ns, value)
        if not out:
            return
        if g.resynced:
            self.cal.restart_gyro()
            prev_ns = None
            if g.returned:
                self.log.error(
                    f'{g.retracted} gyro increment(s) carried stamps off their timeline and the '
                    'stream came back to it: dropped as a stamp burst; the pairs containing the '
                    'burst are lost')
            else:
                self.log.error(
                    f'gyro stamps jumped by {g.last_jump_s:.6g} s and stayed: resynchronised; no '
                    'increment pair spans the jump')
        new = 0
        marks = g.gap_marks
        for ns_i, v in out:
            t = self._rel(ns_i)
            if prev_ns is not None and marks and ns_i in marks:    # the check's rule 6
                # the rotation of the missing increments is lost: no pair may span (prev, t]
                self.gaps.append(((prev_ns - self.origin_ns) * 1e-9, t))
                self.log.error(
                    f'gyro gap: {max(1, int(round((ns_i - prev_ns) / g.reference_ns)) - 1)} '
                    'increment(s) missing '
                    f'before stamp {ns_i * 1e-9:.6f} s; pairs spanning it are discarded',
                    throttle=5.0, key='gyro_gap')
            prev_ns = ns_i
            new += self.cal.add_gyro_sample(t, v)
        self._after_input(new)

    def on_camera_cov(self, msg: PoseWithCovarianceStamped):
        """
        Take one camera fix with its covariance (the rotation block, VF axes, rad²).

        Parameters
        ----------
        msg : geometry_msgs.msg.PoseWithCovarianceStamped
            The message.

        """
        self._on_camera(msg.header, msg.pose.pose.orientation, rotation_block(msg))

    def on_camera_plain(self, msg: QuaternionStamped):
        """
        Take one camera fix without covariance (the σ of the parameters).

        Parameters
        ----------
        msg : geometry_msgs.msg.QuaternionStamped
            The message.

        """
        self._on_camera(msg.header, msg.quaternion, self.default_p_avu)

    def _on_camera(self, header, q_msg, P):
        ns = ros_io.stamp_to_ns(header.stamp)
        c = self.camera_check
        screen = self.fix_screen
        got = screen.screen(ros_io.quaternion_from_msg(q_msg), P)     # THE screening of a fix
        cc = self.camera_counts
        cc['normalised'] = screen.normalised
        cc['covariance_substituted'] = screen.covariance_substituted
        if got is None:
            c.received += 1
            why = screen.last_reason
            cc['dropped_zero_quaternion'] = screen.zero_quaternion
            cc['dropped_not_unit'] = screen.not_unit
            cc['dropped_bad_covariance'] = screen.bad_covariance
            self.log.warn(f'camera fix dropped: {why.replace("_", " ")}', throttle=10.0,
                          key=f'camera_{why}')
            return
        q, P = got
        if header.frame_id and header.frame_id != self.ref_frame:
            self.camera_counts['frame_mismatch'] += 1
            frame = ros_status.bounded(header.frame_id, 80)
            self.log.warn(f'camera attitude in frame {frame!r}, expected {self.ref_frame!r}: '
                          f"{'rejected' if self.reject_frames else 'used'}",
                          throttle=30.0, key='camera_frame')
            if self.reject_frames:
                return
        out = c.offer(ns, list(q) + list(np.asarray(P, dtype=float).ravel()))
        if c.resynced:
            self.cal.restart_camera()
            self.log.error(f'camera stamps jumped by {c.last_jump_s:.6g} s and stayed: '
                           'resynchronised')
        for ns_i, v in out:                        # after a resync, the held fixes too, in order
            q_i, P_i = np.asarray(v[:4]), np.asarray(v[4:], dtype=float).reshape(3, 3)
            self.pending_fixes.append((ns_i, q_i, P_i))
            self._after_input(self.cal.add_camera(self._rel(ns_i), q_i, P_i))
        if out:
            self._publish_imu_attitudes()

    # --- persistence ---------------------------------------------------------------------------
    def _restore_state(self, identity: dict):
        """
        Resume from ``state_file``: its pairs, last fix and time origin.

        Resume from ``state_file`` (strapdown_ros.calibration.state: identity, lock, atomic
        writes): its pairs, last fix and time origin; the estimate is solved again and republished
        latched.  A file that cannot be used is reported (ERROR) and the node runs without
        persistence; only an unreadable regular file is moved aside.
        """
        path = self.state['file']
        sf = CalibratorStateFile(path, identity)
        try:
            sf.acquire()
        except StateFileError as exc:
            self._state_problem(str(exc))
            return
        try:
            origin = sf.load(self.cal)
        except StateFileError as exc:
            if exc.kind == 'corrupt':
                aside = sf.move_aside()
                self.state['moved_aside'] = aside
                self._state_problem(f'state file {path} not used: {exc}; moved aside to {aside}; '
                                    'starting afresh')
                self.state_file, self.state['persisting'] = sf, True
            else:
                sf.close()
                self._state_problem(f'state file {path} refused: {exc}; running without '
                                    'persistence (remove the file or point state_file elsewhere)')
            return
        self.state_file, self.state['persisting'] = sf, True
        if origin is None:
            return
        self.origin_ns = origin
        self.state['restored_pairs'] = len(self.cal.pairs)
        self.log.info(f'resumed from {path}: {len(self.cal.pairs)} pairs')
        if len(self.cal.pairs) >= 2:
            self._solve()

    def _state_problem(self, message: str):
        self.state['errors'] += 1
        self.state['problem'] = message[:300]
        self.log.error(message)

    def _save_state(self):
        if self.state_file is None:
            return
        try:
            self.state_file.save(self.cal, self.origin_ns)
            self.state['saves'] += 1
        except OSError as exc:
            self.state['errors'] += 1
            self.state['problem'] = f"cannot write state file {self.state['file']}: {exc}"[:300]
            self.log.error(f"cannot write state file {self.state['file']}: {exc}",
                           throttle=30.0, key='state_file')

    def destroy_node(self):
        """Close the state file (its lock), then destroy the node."""
        if self.state_file is not None:
            self.state_file.close()
            self.state_file = None
        return super().destroy_node()

    # --- estimate ------------------------------------------------------------------------------
    def _after_input(self, new_pairs: int):
        if new_pairs <= 0:
            return
        if self.gaps:
            self._discard_pairs_over_gaps(new_pairs)
        self._solve()
        if self.state_file is not None:
            self._save_state()                      # at most once per new pair

    def _discard_pairs_over_gaps(self, new_pairs: int):
        # public list of the core; the newest pairs are at its end
        pairs = self.cal.pairs
        # (max_pairs may already have trimmed the list)
        start = max(0, len(pairs) - new_pairs)
        # the in-interval polynomial also reads the neighbouring increments
        h = 1.5 * self.gyro_period
        keep_tail = []
        for pair in pairs[start:]:
            if any(pair.t_start - h < b and a < pair.t_end + h for a, b in self.gaps):
                self.pairs_discarded_gap += 1
            else:
                keep_tail.append(pair)
        del pairs[start:]
        pairs.extend(keep_tail)

    def _solve(self):
        t0 = time.perf_counter()
        try:
            sol = self.cal.solve()
        except (np.linalg.LinAlgError, ValueError, FloatingPointError) as exc:
            # never lose the pairs or the latched estimate to one bad solve
            self.solve_failures += 1
            self.log.error(f'boresight solve failed ({exc}); the last estimate stays published',
                           throttle=10.0, key='solve_failed')
            return
        self.solve_ms = (time.perf_counter() - t0) * 1e3
        self.solves += 1
        sigma = np.sqrt(np.maximum(np.diag(sol.covariance_beta),
                                   0.0)) if sol.observable and sol.converged else None
        if sigma is not None and np.max(sigma) > float(self.p['max_sigma']):
            # never publish a σ above max_sigma: the estimate is not good enough yet
            self.valid = None
            self._log_reason(f'published σ {np.max(sigma):.3g} rad would exceed max_sigma '
                             f"{self.p['max_sigma']:g}")
            return
        if sol.observable and sol.converged:
            self.valid = sol
            self.valid_stamp_ns = self._abs_ns(self.cal.pairs[-1].t_end)
            self._publish_solution()
            self._publish_imu_attitudes()
            if self._last_reason is not None or self.published['boresight'] == 1:
                self.log.info(f'boresight observable from {sol.pairs} pairs: publishing β = '
                              f'{np.round(np.degrees(sol.beta), 5).tolist()}°')
            self._last_reason = None
        else:
            # the published estimate stays what it was (transient-local); no new output
            self.valid = None
            self._log_reason(sol.message)

    def _log_reason(self, message: str):
        # the "why" part; the axis numbers may jitter
        key = message.split(':', 1)[-1].strip()
        now = time.monotonic()
        if key != self._last_reason or now - self._last_reason_log >= LOG_THROTTLE_S:
            self.log.warn(f'boresight not published: {message}')
            self._last_reason = key
            self._last_reason_log = now

    # --- output ------------------------------------------------------------------------------
    def _publish_solution(self):
        sol = self.valid
        st = ros_io.ns_to_stamp(self.valid_stamp_ns)
        self.pub_boresight.publish(pose_with_covariance(st, self.frame_id, sol.q_mf_vf,
                                                        sol.rotation_covariance_mf))
        self.pub_angles.publish(ros_io.vector3_stamped(st, self.frame_id, sol.beta))
        self.published['boresight'] += 1

    def _publish_imu_attitudes(self):
        if self.valid is None:
            return
        while self.pending_fixes:
            ns, q, P = self.pending_fixes.popleft()
            q_mf, P_mfa = imu_attitude_from_camera(q, P, self.valid)
            self.pub_imu_att.publish(pose_with_covariance(ros_io.ns_to_stamp(ns), self.ref_frame,
                                                          q_mf, P_mfa))
            self.published['imu_attitude_from_camera'] += 1

    def publish_diagnostics(self):
        """Publish the /diagnostics status (:func:`~.calibrator_status.boresight_status`)."""
        level, message, values = boresight_status(self)
        stamp_ns = max(self.gyro_check.last_ns or 0, self.camera_check.last_ns or 0)
        name = f'{self.get_fully_qualified_name()}: boresight'
        self.pub_diag.publish(ros_status.diagnostic_array(ros_io.ns_to_stamp(stamp_ns), name,
                                                          'calibrator', level, message, values))


def main(args=None):
    """
    Run calibrator_node (the entry point of its process).

    Parameters
    ----------
    args : list of str, optional
        ROS arguments (default the process's).

    Returns
    -------
    int
        The exit status (:func:`strapdown_ros.nodes.ros_process.run_node`).

    """
    return ros_process.run_node(CalibratorNode, NODE_NAME, args)


if __name__ == '__main__':
    sys.exit(main())
