"""sins_node: strapdown attitude from integrating-gyro increments with a selectable coning algorithm.

Subscribes (stream QoS):
* ``imu/delta_theta``     geometry_msgs/Vector3Stamped, rad, stamp = end of interval
* ``imu/delta_velocity``  geometry_msgs/Vector3Stamped, m/s (optional)

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
                     missing (gap) messages, rates from header stamps

Timing comes only from header stamps.  Invalid input is dropped, counted and reported;
the integrator never sees it.

Hot path: a callback only validates a message and appends it.  The increments are integrated in
blocks covering ``batch_period`` of stamp time (and at least every ``batch_period`` wall seconds,
by a timer) through the vectorised core; every update is still published with its own stamp, and
the result equals message-by-message processing (``batch_period`` 0) to round-off.  Outputs are
built only for topics that have a subscriber (checked once per block).
"""
from __future__ import annotations

import sys
import time
from collections import deque

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
from rclpy.node import Node
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu

from .. import attitude_kernel
from ..config import SINS_PARAMS, sigmas_from
from ..integrator import AttitudeIntegrator, IncrementAccumulator
from ..navigation import recursion as nav_recursion
from ..navigation.channel import NavigationChannel
from ..rotation import dcm_to_quat, from_ros_xyzw, quat_to_dcm
from ..sensors.effects import GyroEffects
from ..streams import StreamCheck
from . import ros_io

NODE_NAME = "sins_node"
NONFINITE_INFLATION = 0.01      # rad per axis added to σ after a non-finite update is discarded
MAX_BATCH = 4096                # a block is processed when it holds this many messages, whatever its span


class SinsNode(Node):
    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self.p = ros_io.declare_validated(self, SINS_PARAMS, on_change=self._on_change,
                                          apply=self._apply_change)
        p = self.p
        q0_xyzw = np.asarray(p["initial_orientation"], dtype=float)
        if np.linalg.norm(q0_xyzw) < 1e-6:
            raise ValueError("initial_orientation must not be the zero quaternion")
        self.initial_normalised = abs(np.linalg.norm(q0_xyzw) - 1.0) > 1e-6
        period = 1.0 / float(p["gyro_rate"])
        self.integrator = AttitudeIntegrator(
            p["coning_algorithm"], initial_attitude=from_ros_xyzw(q0_xyzw), nominal_period=period,
            gyro=sigmas_from(p, "gyro"), initial_sigma=float(p["initial_attitude_sigma"]),
            covariance_model=p["covariance_model"], quantization_correction=bool(p["quantization_correction"]))
        # known systematic gyro effects of the model (sensors.effects), compensated per increment
        self.gyro_effects = GyroEffects(p)
        self.compensating = self.gyro_effects.names()
        self._last_gyro_t: float | None = None
        jump, resync = float(p["max_stamp_jump"]), int(p["resync_count"])
        self.gyro_check = StreamCheck(period, max_norm=2.0 * period * float(p["gyro_max_rate"]), jump_limit=jump,
                                      resync_count=resync)
        a_period = 1.0 / float(p["accel_rate"])
        self.accel_check = StreamCheck(a_period, max_norm=2.0 * a_period * float(p["accel_max"]), jump_limit=jump,
                                       resync_count=resync)
        self.nonfinite = 0                         # updates whose output was not finite (never published)
        self.frame_mismatch = {"gyro": 0, "accel": 0}
        self.reject_frames = p["frame_mismatch"] == "reject"
        self._good = self.integrator.snapshot()
        self.accel = IncrementAccumulator()
        self.accel_seen = False
        self.origin_ns: int | None = None          # stamps are handled relative to the first one
        self.pending_imu: deque = deque()          # outputs waiting for accelerometer data
        self.published = {"attitude": 0, "imu": 0, "imu_without_accel": 0}
        self.algorithm_changes = 0
        self.frame_id = p["frame_id"]
        self._own_frames = ("", self.frame_id)
        # input batches (hot path: validate and append; process() does the numerical work)
        self._gyro_in: list = []                   # (t, stamp_ns, (x, y, z))
        self._accel_in: list = []                  # (t, (x, y, z))
        self.batch_span = float(p["batch_period"])
        self._gyro_period = 1.0 / float(p["gyro_rate"])
        self._block_end_t: float | None = None     # stamp (relative) of the last sample processed
        self.ref_frame = p["reference_frame_id"]
        self._make_output_messages()
        attitude_kernel.warm_up()                  # compiled before the first message, if numba is there
        self.nav: NavigationChannel | None = None
        if p["navigation"]:
            self.nav = NavigationChannel(p, sigmas_from(p, "gyro"), sigmas_from(p, "accel"), period, a_period,
                                         self.integrator.algorithm.samples)
            nav_recursion.warm_up()
            self._nav_prev_q = self.integrator.q.copy()
            self.published["odometry"] = 0
        qos = ros_io.stream_qos(int(p["qos_depth"]))
        self.pub_att = self.create_publisher(QuaternionStamped, "sins/attitude", qos, qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.pub_imu = self.create_publisher(Imu, "sins/imu", qos, qos_overriding_options=ros_io.QOS_OVERRIDES)
        if self.nav is not None:
            self.pub_odom = self.create_publisher(Odometry, "sins/odometry", qos,
                                                  qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", ros_io.DIAGNOSTICS_QOS)
        self.create_subscription(Vector3Stamped, "imu/delta_theta", self._on_gyro, qos, qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.create_subscription(Vector3Stamped, "imu/delta_velocity", self._on_accel, qos, qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.create_timer(float(p["diagnostics_period"]), self.publish_diagnostics)
        if self.batch_span > 0:                    # a block is processed at least this often
            self.create_timer(self.batch_span, self.process)
        self._wall_start = time.monotonic()
        self.get_logger().info(
            f"started: coning_algorithm={p['coning_algorithm']} "
            f"({self.integrator.algorithm.samples} samples/update), covariance_model={p['covariance_model']}, "
            f"compensating: {', '.join(self.compensating) or 'none'}")
        if self.initial_normalised:
            self.get_logger().warn("initial_orientation was not a unit quaternion; normalised")

    # --- parameters ---------------------------------------------------------------------
    def _on_change(self, new: dict) -> str | None:
        """Validation (on-set): only the coning algorithm may change at runtime."""
        fixed = sorted(set(new) - {"coning_algorithm"})
        if self.nav is not None and "coning_algorithm" in new:
            fixed = sorted(set(new))               # the navigation step is the algorithm's update
        if fixed:
            return ("only coning_algorithm can change at runtime; restart the node to change "
                    + ", ".join(fixed))
        return None

    def _apply_change(self, new: dict) -> None:
        """Application (post-set), once rclpy has accepted the change."""
        name = new["coning_algorithm"]
        if name != self.integrator.algorithm_name:
            self.process()                         # the samples so far belong to the old algorithm
            self.integrator.set_algorithm(name)
            self.algorithm_changes += 1
            self.p["coning_algorithm"] = name
            self.get_logger().info(f"coning_algorithm switched to {name}")

    # --- input ------------------------------------------------------------------------------
    def _rel(self, stamp_ns: int) -> float:
        if self.origin_ns is None:
            self.origin_ns = stamp_ns
        return (stamp_ns - self.origin_ns) * 1e-9

    def _wrong_frame(self, header, stream: str) -> bool:
        """The frame rule: an empty frame_id is unspecified; another frame than ``frame_id`` is
        counted and WARNed, and rejected unless ``frame_mismatch`` is accept."""
        f = header.frame_id
        if not f or f == self.frame_id:
            return False
        self.frame_mismatch[stream] += 1
        self.get_logger().warn(f"{stream} message in frame {f!r}, expected {self.frame_id!r}: "
                               f"{'rejected' if self.reject_frames else 'used'}", throttle_duration_sec=10.0)
        return self.reject_frames

    def _on_gyro(self, msg: Vector3Stamped):
        """Hot path: validate, append to the batch; the numerical work runs in :meth:`process`."""
        if msg.header.frame_id not in self._own_frames and self._wrong_frame(msg.header, "gyro"):
            return
        st = msg.header.stamp
        v = msg.vector
        out = self.gyro_check.offer(st.sec * 1_000_000_000 + st.nanosec, (v.x, v.y, v.z))
        if not out:
            return
        if self.gyro_check.resynced:
            self.process()                                 # the old time base, first
            self.integrator.restart_clock()
            self._last_gyro_t = None
            self._block_end_t = None
            self.origin_ns = None
            self.get_logger().error(f"gyro stamps jumped by {self.gyro_check.last_jump_s:.6g} s and stayed: "
                                    "resynchronised to the new time base; the rotation during the jump is lost")
        for ns_i, val in out:
            t = self._rel(ns_i)
            self._gyro_in.append((t, ns_i, val))
        # the stamp time the block covers, from the end of the previous block (at 100 Hz with
        # batch_period 0.01 every message is processed at once; at 1 kHz, blocks of 10), whatever
        # gyro_rate says
        start = self._block_end_t if self._block_end_t is not None else self._gyro_in[0][0] - self._gyro_period
        if self._gyro_in[-1][0] - start >= self.batch_span - 1e-9 or len(self._gyro_in) >= MAX_BATCH:
            self.process()

    def _on_accel(self, msg: Vector3Stamped):
        """Hot path: validate, append; folded into the accumulator by :meth:`process`."""
        if msg.header.frame_id not in self._own_frames and self._wrong_frame(msg.header, "accel"):
            return
        st = msg.header.stamp
        v = msg.vector
        out = self.accel_check.offer(st.sec * 1_000_000_000 + st.nanosec, (v.x, v.y, v.z))
        if not out:
            return
        if self.accel_check.resynced:
            self._accel_in.clear()
            self.accel = IncrementAccumulator()           # the old time base is gone
        self.accel_seen = True
        for ns_i, val in out:
            self._accel_in.append((self._rel(ns_i), val))
        if len(self._accel_in) >= MAX_BATCH or self.batch_span == 0.0:
            self.process()

    # --- batch processing ------------------------------------------------------------------
    def process(self) -> None:
        """Integrate the buffered increments as one block through the vectorised core and publish
        every update with its own stamp.  The result equals message-by-message processing to
        round-off (test_nodes.py::test_sins_node_batches_equal_per_message_processing)."""
        if self._accel_in:
            t = np.fromiter((a[0] for a in self._accel_in), float, len(self._accel_in))
            dv = np.array([a[1] for a in self._accel_in], dtype=float)
            self.accel.add(dv, t)
            self._accel_in.clear()
            if self.nav is not None:
                self.nav.add_accel(dv, t)
        if self._gyro_in:
            batch, self._gyro_in = self._gyro_in, []
            self._block_end_t = batch[-1][0]
            t = np.fromiter((g[0] for g in batch), float, len(batch))
            inc = np.array([g[2] for g in batch], dtype=float)
            if self.nav is not None and self._navigation_start(inc, t):
                self._flush_imu()
                return
            before = self.integrator.checkpoint()
            last_t = self._last_gyro_t
            if not self._integrate(inc, t):
                # a non-finite update inside the block: redo it sample by sample, from the state
                # before it, so that exactly the offending update is discarded
                self.integrator.rollback(before)
                self._last_gyro_t = last_t
                for k in range(len(t)):
                    self._integrate(inc[k:k + 1], t[k:k + 1], per_sample=True)
        self._flush_imu()
        self._flush_nav()

    def _navigation_start(self, inc: np.ndarray, t: np.ndarray) -> bool:
        """Before navigation runs: True when the block was consumed by the static alignment."""
        nav = self.nav
        if nav.navigator is not None:
            return False
        if nav.mode == "given":
            nav.start(float(t[0]) - self.integrator.nominal_period, attitude_sigma=float(self.p["initial_attitude_sigma"]))
            return False
        comp = self.gyro_effects.compensate(inc, t, np.full(len(t), self.integrator.nominal_period)) \
            if self.compensating else inc
        nav.align_gyro(comp, t)
        done, c_e_b, t_end = nav.try_align()
        if nav.alignment is not None and not nav.alignment.ok:
            self.get_logger().error(f"static alignment refused: {nav.alignment.reason}; trying again",
                                    throttle_duration_sec=5.0)
        if done:
            sigma = float(np.sqrt(np.trace(nav.alignment.covariance) / 3.0))
            self.integrator = AttitudeIntegrator(
                self.p["coning_algorithm"], initial_attitude=dcm_to_quat(c_e_b), initial_time=t_end,
                nominal_period=self.integrator.nominal_period, gyro=sigmas_from(self.p, "gyro"), initial_sigma=sigma,
                covariance_model=self.p["covariance_model"],
                quantization_correction=bool(self.p["quantization_correction"]))
            self._good = self.integrator.snapshot()
            self._nav_prev_q = self.integrator.q.copy()
            self._last_gyro_t = t_end
            self.get_logger().info(f"static alignment done at t = {t_end:.3f} s: tilt σ "
                                   f"{np.degrees(nav.alignment.tilt_sigma) * 3600:.1f}″, heading σ "
                                   f"{np.degrees(nav.alignment.heading_sigma):.4f}°")
        return True

    def _flush_nav(self) -> None:
        if self.nav is None or self.nav.navigator is None:
            return
        newest = self.integrator.time if self.integrator.time is not None else -np.inf
        nb = self.nav.process(newest, float(self.p["accel_wait"]))
        if nb is None or not len(nb) or self.pub_odom.get_subscription_count() == 0:
            return
        m = self._odom_out
        origin = self.origin_ns
        for k in range(len(nb)):
            m.header.stamp = ros_io.ns_to_stamp(origin + int(round(nb.stamps[k] * 1e9)))
            pose = m.pose.pose
            r, w, q = nb.position[k], nb.velocity[k], nb.attitude[k]
            pose.position.x, pose.position.y, pose.position.z = float(r[0]), float(r[1]), float(r[2])
            o = pose.orientation
            o.w, o.x, o.y, o.z = float(q[0]), float(q[1]), float(q[2]), float(q[3])
            p = nb.covariance[k]
            c6 = np.zeros((6, 6))
            c6[:3, :3], c6[:3, 3:], c6[3:, :3], c6[3:, 3:] = p[:3, :3], p[:3, 6:], p[6:, :3], p[6:, 6:]
            m.pose.covariance = np.ascontiguousarray(c6).reshape(36)
            c = quat_to_dcm(q)                              # C_E_B: twist in body axes
            vb = c.T @ w
            tw = m.twist.twist
            tw.linear.x, tw.linear.y, tw.linear.z = float(vb[0]), float(vb[1]), float(vb[2])
            t6 = np.zeros((6, 6))
            t6[:3, :3] = c.T @ p[3:6, 3:6] @ c
            t6[3:, 3:] = np.eye(3) * self.integrator.gyro.random_walk ** 2 / max(self.integrator.nominal_period, 1e-12)
            m.twist.covariance = np.ascontiguousarray(t6).reshape(36)
            self.pub_odom.publish(m)
        self.published["odometry"] += len(nb)

    def _integrate(self, inc: np.ndarray, t: np.ndarray, per_sample: bool = False) -> bool:
        """Compensate, integrate and publish a block; False (nothing published) if an update is
        not finite, unless ``per_sample``, which restores the last good state instead."""
        if self.compensating:
            prev = self._last_gyro_t if self._last_gyro_t is not None else t[0] - self.integrator.nominal_period
            T = np.diff(t, prepend=prev)
            inc = self.gyro_effects.compensate(inc, t, T)
        self._last_gyro_t = float(t[-1])
        batch = self.integrator.push(inc, t)
        if len(batch) and not (np.isfinite(batch.attitude).all() and np.isfinite(batch.covariance).all()):
            if not per_sample:
                return False
            # never publish a non-finite state: back to the last good one, covariance inflated
            self.nonfinite += 1
            self.integrator.restore(self._good, inflate_sigma=NONFINITE_INFLATION)
            self.get_logger().error("non-finite attitude: not published; state reset to the last good update "
                                    f"with {NONFINITE_INFLATION} rad added to its σ", throttle_duration_sec=5.0)
            return True
        if len(batch):
            self._good = self.integrator.snapshot()
        if self.nav is not None:
            self.nav.add_gyro(inc, t)
            if len(batch):
                starts = np.vstack([self._nav_prev_q[None], batch.attitude[:-1]])
                self._nav_prev_q = batch.attitude[-1].copy()
                self.nav.add_updates(batch.stamps, batch.interval, batch.attitude, starts)
        # outputs are built only for topics somebody subscribes to (checked once per block)
        att_on = self.pub_att.get_subscription_count() > 0
        imu_on = self.pub_imu.get_subscription_count() > 0
        origin = self.origin_ns
        att = self._att_out                         # reused: publish serialises it at once
        for k in range(len(batch) if att_on or imu_on else 0):
            st = ros_io.ns_to_stamp(origin + int(round(batch.stamps[k] * 1e9)))
            if att_on:
                q = batch.attitude[k]
                att.header.stamp = st
                o = att.quaternion
                o.w, o.x, o.y, o.z = float(q[0]), float(q[1]), float(q[2]), float(q[3])
                self.pub_att.publish(att)
                self.published["attitude"] += 1
            if imu_on:
                self.pending_imu.append((batch.stamps[k], batch.interval[k], st, batch.attitude[k],
                                         batch.covariance[k], batch.mean_rate[k]))
        if not imu_on and len(batch) and not self.pending_imu:
            self.accel.discard_through(float(batch.stamps[-1]))     # no sins/imu wants the Δv
        return True

    # --- output ------------------------------------------------------------------------------
    def _flush_imu(self):
        """Publish sins/imu for updates whose interval is covered by accelerometer data, or
        that waited longer than ``accel_wait`` (stamp time) for it."""
        if not self.pending_imu:
            return
        wait = float(self.p["accel_wait"])
        newest = self.integrator.time if self.integrator.time is not None else -np.inf
        covered = self.accel.covered_until() + 1e-9
        ready = 0
        for item in self.pending_imu:                  # stamps increase: the ready ones are a prefix
            if item[0] > covered and newest - item[0] < wait:
                break
            ready += 1
        if not ready:
            return
        items = [self.pending_imu.popleft() for _ in range(ready)]
        t = np.array([it[0] for it in items])
        h = np.array([it[1] for it in items])
        dv, n = self.accel.take_sequence(t - h - 1e-9, t + 1e-9)
        for k, (_, hk, st, q, cov, rate) in enumerate(items):
            self.pub_imu.publish(self._imu_msg(st, q, cov, rate, dv[k] / hk if n[k] else None))

    def _imu_msg(self, stamp, q, cov, rate, f_mean) -> Imu:
        """sensor_msgs/Imu of one update.  One message object is reused (publish serialises it at
        once): constructing a new Imu costs more than the rest of the update."""
        m = self._imu_out
        m.header.stamp = stamp
        o = m.orientation
        o.w, o.x, o.y, o.z = float(q[0]), float(q[1]), float(q[2]), float(q[3])
        m.orientation_covariance = np.ascontiguousarray(cov, dtype=np.float64).reshape(9)
        w = m.angular_velocity
        w.x, w.y, w.z = float(rate[0]), float(rate[1]), float(rate[2])
        a = m.linear_acceleration
        if f_mean is None:
            a.x = a.y = a.z = 0.0
            m.linear_acceleration_covariance = self._no_accel_cov    # [0] = −1: no accelerometer data
            self.published["imu_without_accel"] += 1
        else:
            a.x, a.y, a.z = float(f_mean[0]), float(f_mean[1]), float(f_mean[2])
            m.linear_acceleration_covariance = self._accel_cov
        self.published["imu"] += 1
        return m

    def _make_output_messages(self) -> None:
        m = Imu()
        m.header.frame_id = self.frame_id
        g = self.integrator.gyro.random_walk ** 2 / max(self.integrator.nominal_period, 1e-12)
        m.angular_velocity_covariance = np.diag([g, g, g]).reshape(9)
        a = float(self.p["accel_random_walk"]) ** 2 * float(self.p["accel_rate"])
        self._accel_cov = np.diag([a, a, a]).reshape(9)
        self._no_accel_cov = np.zeros(9)
        self._no_accel_cov[0] = -1.0
        self._imu_out = m
        self._att_out = QuaternionStamped()
        self._odom_out = Odometry()
        self._odom_out.header.frame_id = self.p["earth_frame_id"]
        self._odom_out.child_frame_id = self.frame_id
        self._att_out.header.frame_id = self.ref_frame

    def publish_diagnostics(self):
        g, a = self.gyro_check, self.accel_check
        level, message = ros_io.OK, "ok"
        if g.accepted == 0:
            level, message = ros_io.WARN, "no gyro increments received"
        if g.dropped or a.dropped:
            level, message = ros_io.WARN, (
                f"dropped {g.dropped} gyro and {a.dropped} accelerometer messages (NaN {g.nan + a.nan}, out of range "
                f"{g.out_of_range + a.out_of_range}, out of order {g.out_of_order + a.out_of_order}, duplicate "
                f"{g.duplicate + a.duplicate}, stamp outliers {g.stamp_outliers + a.stamp_outliers})")
        if any(self.frame_mismatch.values()):
            level, message = ros_io.WARN, (f"messages in another frame than {self.frame_id!r}: gyro "
                                           f"{self.frame_mismatch['gyro']}, accelerometer {self.frame_mismatch['accel']} "
                                           f"({'rejected' if self.reject_frames else 'used'})")
        if g.missing:
            level, message = ros_io.ERROR, f"{g.missing} gyro increments missing in {g.gaps} gaps: " \
                "the rotation during the gaps is lost"
        if g.resyncs:
            level, message = ros_io.ERROR, (f"gyro stamps jumped {g.resyncs} time(s) (last by {g.last_jump_s:.6g} s): "
                                            "resynchronised; the rotation during a jump is lost")
        if self.nonfinite:
            level, message = ros_io.ERROR, (f"{self.nonfinite} non-finite update(s) discarded (never published); "
                                            "state reset to the last good one with inflated covariance")
        values = {"coning_algorithm": self.integrator.algorithm_name,
                  "samples_per_update": self.integrator.algorithm.samples,
                  "covariance_model": self.integrator.covariance_model,
                  "updates": self.integrator.updates, **g.as_dict("gyro"), **a.as_dict("accel"),
                  "attitude_published": self.published["attitude"], "imu_published": self.published["imu"],
                  "imu_published_without_accel": self.published["imu_without_accel"],
                  "algorithm_changes": self.algorithm_changes,
                  "compensated_effects": ", ".join(self.compensating) or "none",
                  "initial_orientation_normalised": self.initial_normalised,
                  "nonfinite_updates_discarded": self.nonfinite,
                  "gyro_frame_mismatch": self.frame_mismatch["gyro"],
                  "accel_buffer_overflowed": self.accel.overflowed,
                  "accel_frame_mismatch": self.frame_mismatch["accel"]}
        if self.nav is not None:
            values.update(self.nav.status())
            values["odometry_published"] = self.published["odometry"]
            if self.nav.alignment is not None and not self.nav.alignment.ok and self.nav.navigator is None:
                level, message = ros_io.ERROR, f"static alignment refused: {self.nav.alignment.reason}"
        if self.integrator.time is not None:
            sig = np.sqrt(np.diag(self.integrator.covariance()))
            values.update({"attitude_sigma_x_rad": sig[0], "attitude_sigma_y_rad": sig[1],
                           "attitude_sigma_z_rad": sig[2]})
        stamp_ns = g.last_ns if g.last_ns is not None else 0
        self.pub_diag.publish(ros_io.diagnostic_array(ros_io.ns_to_stamp(stamp_ns), f"{self.get_fully_qualified_name()}: attitude",
                                                      "sins", level, message, values))


def main(args=None):
    return ros_io.run_node(SinsNode, NODE_NAME, args)


if __name__ == "__main__":
    sys.exit(main())
