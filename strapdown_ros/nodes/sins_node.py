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
* ``/diagnostics``   counts of received, dropped (NaN, out-of-order, duplicate) and
                     missing (gap) messages, rates from header stamps

Timing comes only from header stamps.  Invalid input is dropped, counted and reported;
the integrator never sees it.
"""
from __future__ import annotations

import sys
import time
from collections import deque

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
from rclpy.node import Node
from sensor_msgs.msg import Imu

from ..config import SINS_PARAMS, sigmas_from
from ..integrator import AttitudeIntegrator, IncrementAccumulator
from ..rotation import from_ros_xyzw
from ..sensors.effects import GyroEffects
from ..streams import StreamCheck
from . import ros_io

NODE_NAME = "sins_node"
NONFINITE_INFLATION = 0.01      # rad per axis added to σ after a non-finite update is discarded


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
        self.ref_frame = p["reference_frame_id"]
        qos = ros_io.stream_qos(int(p["qos_depth"]))
        self.pub_att = self.create_publisher(QuaternionStamped, "sins/attitude", qos, qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.pub_imu = self.create_publisher(Imu, "sins/imu", qos, qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", ros_io.DIAGNOSTICS_QOS)
        self.create_subscription(Vector3Stamped, "imu/delta_theta", self._on_gyro, qos, qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.create_subscription(Vector3Stamped, "imu/delta_velocity", self._on_accel, qos, qos_overriding_options=ros_io.QOS_OVERRIDES)
        self.create_timer(float(p["diagnostics_period"]), self.publish_diagnostics)
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
        if fixed:
            return ("only coning_algorithm can change at runtime; restart the node to change "
                    + ", ".join(fixed))
        return None

    def _apply_change(self, new: dict) -> None:
        """Application (post-set), once rclpy has accepted the change."""
        name = new["coning_algorithm"]
        if name != self.integrator.algorithm_name:
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
        if self._wrong_frame(msg.header, "gyro"):
            return
        ns = ros_io.stamp_to_ns(msg.header.stamp)
        out = self.gyro_check.offer(ns, (msg.vector.x, msg.vector.y, msg.vector.z))
        if not out:
            return
        if self.gyro_check.resynced:
            self.integrator.restart_clock()
            self._last_gyro_t = None
            self.origin_ns = None
            self.get_logger().error(f"gyro stamps jumped by {self.gyro_check.last_jump_s:.6g} s and stayed: "
                                    "resynchronised to the new time base; the rotation during the jump is lost")
        for ns_i, v in out:
            self._integrate(ns_i, v)
        self._flush_imu()

    def _integrate(self, ns: int, v):
        t = self._rel(ns)
        inc = np.array([v], dtype=float)
        if self.compensating:
            T = t - self._last_gyro_t if self._last_gyro_t is not None else self.integrator.nominal_period
            inc = self.gyro_effects.compensate(inc, np.array([t]), T)
        self._last_gyro_t = t
        batch = self.integrator.push(inc, np.array([t]))
        if len(batch) and not (np.all(np.isfinite(batch.attitude)) and np.all(np.isfinite(batch.covariance))):
            # never publish a non-finite state: back to the last good one, covariance inflated
            self.nonfinite += 1
            self.integrator.restore(self._good, inflate_sigma=NONFINITE_INFLATION)
            self.get_logger().error("non-finite attitude: not published; state reset to the last good update "
                                    f"with {NONFINITE_INFLATION} rad added to its σ", throttle_duration_sec=5.0)
            return
        if len(batch):
            self._good = self.integrator.snapshot()
        for k in range(len(batch)):
            st = ros_io.ns_to_stamp(self.origin_ns + int(round(batch.stamps[k] * 1e9)))
            self.pub_att.publish(ros_io.quaternion_stamped(st, self.ref_frame, batch.attitude[k]))
            self.published["attitude"] += 1
            self.pending_imu.append((batch.stamps[k], batch.interval[k], st, batch.attitude[k],
                                     batch.covariance[k], batch.mean_rate[k]))

    def _on_accel(self, msg: Vector3Stamped):
        if self._wrong_frame(msg.header, "accel"):
            return
        ns = ros_io.stamp_to_ns(msg.header.stamp)
        out = self.accel_check.offer(ns, (msg.vector.x, msg.vector.y, msg.vector.z))
        if not out:
            return
        if self.accel_check.resynced:
            self.accel = IncrementAccumulator()           # the old time base is gone
        self.accel_seen = True
        for ns_i, v in out:
            self.accel.add(np.array([v]), np.array([self._rel(ns_i)]))
        self._flush_imu()

    # --- output ------------------------------------------------------------------------------
    def _flush_imu(self):
        """Publish sins/imu for updates whose interval is covered by accelerometer data, or
        that waited longer than ``accel_wait`` (stamp time) for it."""
        wait = float(self.p["accel_wait"])
        newest = self.integrator.time if self.integrator.time is not None else -np.inf
        while self.pending_imu:
            t, h, st, q, cov, rate = self.pending_imu[0]
            covered = self.accel.covered_until() >= t - 1e-9
            if not covered and newest - t < wait:
                break
            self.pending_imu.popleft()
            dv, n = self.accel.take(t - h - 1e-9, t + 1e-9)
            self.pub_imu.publish(self._imu_msg(st, q, cov, rate, dv / h if n else None))

    def _imu_msg(self, stamp, q, cov, rate, f_mean) -> Imu:
        m = Imu()
        m.header.stamp = stamp
        m.header.frame_id = self.frame_id
        m.orientation = ros_io.quaternion_msg(q)
        m.orientation_covariance = [float(c) for c in np.asarray(cov).reshape(9)]
        m.angular_velocity = ros_io.vector3(rate)
        g = self.integrator.gyro.random_walk ** 2 / max(self.integrator.nominal_period, 1e-12)
        m.angular_velocity_covariance = [g, 0.0, 0.0, 0.0, g, 0.0, 0.0, 0.0, g]
        if f_mean is None:
            m.linear_acceleration_covariance[0] = -1.0          # no accelerometer data for this update
            self.published["imu_without_accel"] += 1
        else:
            m.linear_acceleration = ros_io.vector3(f_mean)
            a = float(self.p["accel_random_walk"]) ** 2 * float(self.p["accel_rate"])
            m.linear_acceleration_covariance = [a, 0.0, 0.0, 0.0, a, 0.0, 0.0, 0.0, a]
        self.published["imu"] += 1
        return m

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
