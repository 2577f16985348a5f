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

import math
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
from . import ros_io

NODE_NAME = "sins_node"


class StreamCheck:
    """Validity bookkeeping of one stamped vector stream (stamps in integer ns)."""

    def __init__(self, nominal_period: float):
        self.nominal_ns = nominal_period * 1e9
        self.last_ns: int | None = None
        self.first_ns: int | None = None
        self.received = self.accepted = 0
        self.nan = self.out_of_order = self.duplicate = self.gaps = self.missing = 0

    def accept(self, stamp_ns: int, v) -> bool:
        self.received += 1
        if not all(math.isfinite(c) for c in v):
            self.nan += 1
            return False
        if self.last_ns is not None:
            if stamp_ns == self.last_ns:
                self.duplicate += 1
                return False
            if stamp_ns < self.last_ns:
                self.out_of_order += 1
                return False
            step = stamp_ns - self.last_ns
            if step > 1.5 * self.nominal_ns:
                self.gaps += 1
                self.missing += int(round(step / self.nominal_ns)) - 1
        else:
            self.first_ns = stamp_ns
        self.last_ns = stamp_ns
        self.accepted += 1
        return True

    def rate_hz(self) -> float:
        if self.first_ns is None or self.last_ns == self.first_ns or self.accepted < 2:
            return 0.0
        return (self.accepted - 1) / ((self.last_ns - self.first_ns) * 1e-9)

    def as_dict(self, prefix: str) -> dict:
        return {f"{prefix}_received": self.received, f"{prefix}_accepted": self.accepted,
                f"{prefix}_rate_hz_from_stamps": self.rate_hz(), f"{prefix}_dropped_nan": self.nan,
                f"{prefix}_dropped_out_of_order": self.out_of_order,
                f"{prefix}_dropped_duplicate": self.duplicate, f"{prefix}_gaps": self.gaps,
                f"{prefix}_missing_samples": self.missing}


class SinsNode(Node):
    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self.p = ros_io.declare_validated(self, SINS_PARAMS, on_change=self._on_change)
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
        self.gyro_check = StreamCheck(period)
        self.accel_check = StreamCheck(1.0 / float(p["accel_rate"]))
        self.accel = IncrementAccumulator()
        self.accel_seen = False
        self.origin_ns: int | None = None          # stamps are handled relative to the first one
        self.pending_imu: deque = deque()          # outputs waiting for accelerometer data
        self.published = {"attitude": 0, "imu": 0, "imu_without_accel": 0}
        self.algorithm_changes = 0
        self.frame_id = p["frame_id"]
        self.ref_frame = p["reference_frame_id"]
        qos = ros_io.stream_qos(int(p["qos_depth"]))
        self.pub_att = self.create_publisher(QuaternionStamped, "sins/attitude", qos)
        self.pub_imu = self.create_publisher(Imu, "sins/imu", qos)
        self.pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", ros_io.DIAGNOSTICS_QOS)
        self.create_subscription(Vector3Stamped, "imu/delta_theta", self._on_gyro, qos)
        self.create_subscription(Vector3Stamped, "imu/delta_velocity", self._on_accel, qos)
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
        fixed = sorted(set(new) - {"coning_algorithm"})
        if fixed:
            return ("only coning_algorithm can change at runtime; restart the node to change "
                    + ", ".join(fixed))
        name = new["coning_algorithm"]
        if name != self.integrator.algorithm_name:
            self.integrator.set_algorithm(name)
            self.algorithm_changes += 1
            self.p["coning_algorithm"] = name
            self.get_logger().info(f"coning_algorithm switched to {name}")
        return None

    # --- input ------------------------------------------------------------------------------
    def _rel(self, stamp_ns: int) -> float:
        if self.origin_ns is None:
            self.origin_ns = stamp_ns
        return (stamp_ns - self.origin_ns) * 1e-9

    def _on_gyro(self, msg: Vector3Stamped):
        ns = ros_io.stamp_to_ns(msg.header.stamp)
        v = (msg.vector.x, msg.vector.y, msg.vector.z)
        if not self.gyro_check.accept(ns, v):
            return
        t = self._rel(ns)
        inc = np.array([v])
        if self.compensating:
            T = t - self._last_gyro_t if self._last_gyro_t is not None else self.integrator.nominal_period
            inc = self.gyro_effects.compensate(inc, np.array([t]), T)
        self._last_gyro_t = t
        batch = self.integrator.push(inc, np.array([t]))
        for k in range(len(batch)):
            st = ros_io.ns_to_stamp(self.origin_ns + int(round(batch.stamps[k] * 1e9)))
            self.pub_att.publish(ros_io.quaternion_stamped(st, self.ref_frame, batch.attitude[k]))
            self.published["attitude"] += 1
            self.pending_imu.append((batch.stamps[k], batch.interval[k], st, batch.attitude[k],
                                     batch.covariance[k], batch.mean_rate[k]))
        self._flush_imu()

    def _on_accel(self, msg: Vector3Stamped):
        ns = ros_io.stamp_to_ns(msg.header.stamp)
        v = (msg.vector.x, msg.vector.y, msg.vector.z)
        if not self.accel_check.accept(ns, v):
            return
        self.accel_seen = True
        self.accel.add(np.array([v]), np.array([self._rel(ns)]))
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
        dropped = g.nan + g.out_of_order + g.duplicate
        level, message = ros_io.OK, "ok"
        if g.accepted == 0:
            level, message = ros_io.WARN, "no gyro increments received"
        if dropped or a.nan + a.out_of_order + a.duplicate:
            level, message = ros_io.WARN, f"dropped {dropped} gyro and " \
                f"{a.nan + a.out_of_order + a.duplicate} accelerometer messages (NaN/out-of-order/duplicate)"
        if g.missing:
            level, message = ros_io.ERROR, f"{g.missing} gyro increments missing in {g.gaps} gaps: " \
                "the rotation during the gaps is lost"
        values = {"coning_algorithm": self.integrator.algorithm_name,
                  "samples_per_update": self.integrator.algorithm.samples,
                  "covariance_model": self.integrator.covariance_model,
                  "updates": self.integrator.updates, **g.as_dict("gyro"), **a.as_dict("accel"),
                  "attitude_published": self.published["attitude"], "imu_published": self.published["imu"],
                  "imu_published_without_accel": self.published["imu_without_accel"],
                  "algorithm_changes": self.algorithm_changes,
                  "compensated_effects": ", ".join(self.compensating) or "none",
                  "initial_orientation_normalised": self.initial_normalised}
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
