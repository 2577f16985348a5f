"""
Writing the simulator topics to a rosbag2 bag, without ROS (``rosbags``).

:func:`record` writes exactly what ``imu_sim_node`` + ``star_camera_sim_node`` publish for the
same validated parameters (same core models, same seeds, same stamps), with the offered QoS of
each publisher (:func:`offered_qos`).  The ``record_sim`` command and the benchmarks call it;
the topics and their meaning are listed in doc/tools.md.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from strapdown_ros.motion.from_config import profile_from_config
from strapdown_ros.rotation import to_ros_xyzw
from strapdown_ros.sensors.simulated import simulated_imu
from strapdown_ros.sensors.star_camera import StarCameraModel

__all__ = ['record', 'offered_qos', 'TOPICS', 'UNKNOWN_POSITION_VARIANCE']

#: topic → message type (relative names, as the nodes publish them)
TOPICS = {
    'imu/delta_theta': 'geometry_msgs/msg/Vector3Stamped',
    'imu/delta_velocity': 'geometry_msgs/msg/Vector3Stamped',
    'imu/truth/attitude': 'geometry_msgs/msg/QuaternionStamped',
    'star_camera/attitude': 'geometry_msgs/msg/QuaternionStamped',
    'star_camera/attitude_with_covariance': 'geometry_msgs/msg/PoseWithCovarianceStamped',
    'star_camera/truth/boresight': 'geometry_msgs/msg/QuaternionStamped',
}
UNKNOWN_POSITION_VARIANCE = 1e9          # m², "position unknown" in the pose covariance
_WINDOW = 10.0                           # s of simulated time generated and written at once


def _typestore():
    from rosbags.typesys import get_typestore, Stores
    return get_typestore(Stores.ROS2_JAZZY)


def offered_qos(kind: str, depth: int):
    """
    Return the offered QoS of the simulator publishers (rosbags ``Qos``).

    Parameters
    ----------
    kind : {'stream', 'camera', 'latched'}
        As ``ros_io.stream_qos``, ``star_camera_sim_node.camera_qos`` or
        ``star_camera_sim_node.latched_qos``.
    depth : int
        History depth (latched: 1).

    Returns
    -------
    rosbags.interfaces.Qos
        The profile written into the bag's metadata.

    """
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness, QosReliability,
                                    QosTime)

    # deadline, lifespan, lease: unspecified (the defaults)
    zero = QosTime(0, 0)
    rel = QosReliability.BEST_EFFORT if kind == 'stream' else QosReliability.RELIABLE
    dur = QosDurability.TRANSIENT_LOCAL if kind == 'latched' else QosDurability.VOLATILE
    return Qos(QosHistory.KEEP_LAST, 1 if kind == 'latched' else int(depth), rel, dur, zero, zero,
               QosLiveliness.AUTOMATIC, zero, False)


def _end_time(p: dict, profile, who: str) -> float:
    dur = float(p['duration'])
    end = dur if dur > 0 else float(profile.duration)
    if not np.isfinite(end):
        raise ValueError(f"{who}: profile {p['profile']!r} has no end; give --duration S")
    return end


class _Messages:
    """Builders of the rosbags message objects (ROS 2 Jazzy type store)."""

    def __init__(self, store):
        self.store = store
        T = store.types
        self.Time = T['builtin_interfaces/msg/Time']
        self.Header = T['std_msgs/msg/Header']
        self.Vector3 = T['geometry_msgs/msg/Vector3']
        self.Vector3Stamped = T['geometry_msgs/msg/Vector3Stamped']
        self.Quaternion = T['geometry_msgs/msg/Quaternion']
        self.QuaternionStamped = T['geometry_msgs/msg/QuaternionStamped']
        self.Point = T['geometry_msgs/msg/Point']
        self.Pose = T['geometry_msgs/msg/Pose']
        self.PoseWithCovariance = T['geometry_msgs/msg/PoseWithCovariance']
        self.PoseWithCovarianceStamped = T['geometry_msgs/msg/PoseWithCovarianceStamped']

    def header(self, ns: int, frame_id: str):
        stamp = self.Time(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))
        return self.Header(stamp=stamp, frame_id=frame_id)

    def quaternion(self, q_wxyz):
        x, y, z, w = (float(c) for c in to_ros_xyzw(q_wxyz))
        return self.Quaternion(x=x, y=y, z=z, w=w)

    def vector3_stamped(self, ns, frame_id, v) -> bytes:
        m = self.Vector3Stamped(header=self.header(ns, frame_id),
                                vector=self.Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2])))
        return self.store.serialize_cdr(m, self.Vector3Stamped.__msgtype__)

    def quaternion_stamped(self, ns, frame_id, q_wxyz) -> bytes:
        m = self.QuaternionStamped(header=self.header(ns, frame_id),
                                   quaternion=self.quaternion(q_wxyz))
        return self.store.serialize_cdr(m, self.QuaternionStamped.__msgtype__)

    def pose_with_covariance_stamped(self, ns, frame_id, q_wxyz, cov_rot) -> bytes:
        cov = np.zeros((6, 6))
        cov[0, 0] = cov[1, 1] = cov[2, 2] = UNKNOWN_POSITION_VARIANCE
        cov[3:, 3:] = np.asarray(cov_rot, dtype=float)
        pose = self.Pose(position=self.Point(x=0.0, y=0.0, z=0.0),
                         orientation=self.quaternion(q_wxyz))
        with_cov = self.PoseWithCovariance(pose=pose, covariance=cov.reshape(36))
        m = self.PoseWithCovarianceStamped(header=self.header(ns, frame_id), pose=with_cov)
        return self.store.serialize_cdr(m, self.PoseWithCovarianceStamped.__msgtype__)


def _topic(namespace: str, name: str) -> str:
    ns = namespace.strip('/')
    return '/' + (f'{ns}/{name}' if ns else name)


def record(bag: str | Path, imu_p: dict, cam_p: dict, storage: str = 'mcap', accel: bool = True,
           namespace: str = '') -> dict:
    """
    Simulate the two simulator nodes and write their messages to a bag.

    Mirrors ``imu_sim_node``: error constants ``sigmas_from(p, 'gyro').draw(default_rng(seed))``
    then the accelerometer's from the same generator; gyro noise seed+1, accelerometer seed+2;
    sample k of a sensor covers [(k−1)T, kT] and is stamped ``start_ns + round(kT·1e9)``.

    Parameters
    ----------
    bag : str or Path
        The bag directory to write.
    imu_p, cam_p : dict
        Validated parameters of imu_sim_node and star_camera_sim_node.
    storage : {'mcap', 'sqlite3'}
        The rosbag2 storage.
    accel : bool
        Also write imu/delta_velocity.
    namespace : str
        Namespace of the topics.

    Returns
    -------
    dict
        Summary: messages per topic, the true boresight and error constants, ...

    Raises
    ------
    ValueError
        An invalid ``storage``.

    """
    from rosbags.rosbag2 import StoragePlugin, Writer  # optional extra (tools)

    if storage not in ('mcap', 'sqlite3'):
        raise ValueError(f'storage={storage!r} is not valid; valid values: mcap, sqlite3')
    # --- imu_sim_node ----------------------------------------------------------------------
    profile = profile_from_config(imu_p)
    gyro, acc = simulated_imu(imu_p, profile)
    gyro_errors = gyro.errors
    imu_end = _end_time(imu_p, profile, 'imu_sim_node')
    imu_start_ns = int(round(float(imu_p['start_time']) * 1e9))
    n_gyro = int(np.floor(imu_end / gyro.period + 1e-9))
    n_acc = int(np.floor(imu_end / acc.period + 1e-9)) if accel else 0
    # --- star_camera_sim_node ----------------------------------------------------------------
    cam_profile = profile_from_config(cam_p)
    cam = StarCameraModel.from_params(cam_p)
    cam_end = _end_time(cam_p, cam_profile, 'star_camera_sim_node')
    cam_start_ns = int(round(float(cam_p['start_time']) * 1e9))
    frame_id, ref_frame = imu_p['frame_id'], imu_p['reference_frame_id']
    cam_ref_frame = cam_p['reference_frame_id']

    store = _typestore()
    msgs = _Messages(store)
    names = ['imu/delta_theta'] + (['imu/delta_velocity'] if accel else []) + \
        ['imu/truth/attitude', 'star_camera/attitude', 'star_camera/attitude_with_covariance',
         'star_camera/truth/boresight']
    qos = {n: offered_qos('stream', imu_p['qos_depth']) for n in names if n.startswith('imu/')}
    qos.update({n: offered_qos('camera', cam_p['qos_depth'])
               for n in names if n.startswith('star_camera/')})
    qos['star_camera/truth/boresight'] = offered_qos('latched', 1)
    counts = {_topic(namespace, n): 0 for n in names}
    bag = Path(bag)
    plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
    with Writer(bag, version=Writer.VERSION_LATEST, storage_plugin=plugin) as writer:
        conns = {n: writer.add_connection(_topic(namespace, n), TOPICS[n], typestore=store,
                                          offered_qos_profiles=[qos[n]]) for n in names}

        def emit(batch):
            # by stamp; stable order within a stamp
            batch.sort(key=lambda m: (m[0], m[1]))
            for ns, _, name, data in batch:
                writer.write(conns[name], ns, data)
                counts[_topic(namespace, name)] += 1

        # star_camera_sim_node publishes the true boresight once at start-up (transient local)
        emit([(cam_start_ns, 0, 'star_camera/truth/boresight',
               msgs.quaternion_stamped(cam_start_ns, cam_p['camera_frame_id'], cam.q_mf_vf))])
        t_end = max(imu_end, cam_end)
        w1 = 0.0
        while True:
            w1 = min(w1 + _WINDOW, t_end)
            batch = []
            # accelerometer, then gyro: as ImuSimNode._advance_to (independent noise streams)
            k_a = min(int(np.floor(min(w1, imu_end) / acc.period + 1e-9)),
                      n_acc) - acc.count if accel else 0
            if k_a > 0:
                ta, dv, _ = acc.sample(k_a)
                for t, v in zip(ta, dv):
                    ns = imu_start_ns + int(round(t * 1e9))
                    batch.append((ns, 1, 'imu/delta_velocity',
                                 msgs.vector3_stamped(ns, frame_id, v)))
            k_g = min(int(np.floor(min(w1, imu_end) / gyro.period + 1e-9)), n_gyro) - gyro.count
            if k_g > 0:
                tg, dth, _ = gyro.sample(k_g)
                q_true = profile.attitude(tg)
                for t, v, q in zip(tg, dth, q_true):
                    ns = imu_start_ns + int(round(t * 1e9))
                    batch.append((ns, 0, 'imu/delta_theta', msgs.vector3_stamped(ns, frame_id, v)))
                    batch.append((ns, 2, 'imu/truth/attitude',
                                 msgs.quaternion_stamped(ns, ref_frame, q)))
            while cam.epoch(cam.count) <= min(w1, cam_end) + 1e-9:
                fix = cam.fixes(cam_profile, 1)[0]
                ns = cam_start_ns + int(round(fix.stamp * 1e9))
                batch.append((ns, 3, 'star_camera/attitude',
                             msgs.quaternion_stamped(ns, cam_ref_frame, fix.attitude)))
                batch.append((ns, 4, 'star_camera/attitude_with_covariance',
                              msgs.pose_with_covariance_stamped(ns, cam_ref_frame, fix.attitude,
                                                                fix.covariance)))
            emit(batch)
            if w1 >= t_end:
                break
    beta = np.asarray(cam_p['boresight'], dtype=float)
    return {'bag': str(bag), 'storage': storage, 'messages': counts, 'duration_s': t_end,
            'boresight_rad': beta.tolist(), 'q_mf_vf_xyzw': to_ros_xyzw(cam.q_mf_vf).tolist(),
            'gyro_bias_rad_s': gyro_errors.bias.tolist()}
