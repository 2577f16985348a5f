"""
The recording of ``reference_rate_bench``: a MEMS gyro as sensor_msgs/Imu and a pose reference.

A motion-capture trial in simulation, with exact truth: bench rotations of 30–40° about the
body z, x and y axes in turn (4 s each, 4 s holds, repeated), a MEMS-grade gyro sampled at
``gyro_rate`` (the body rate at each stamp, plus a constant bias and white noise of density
``GYRO_RANDOM_WALK``), and a reference attitude of the rigid body's marker frame (VF) at
``gyro_rate`` with the boresight ``BORESIGHT`` to the IMU frame and noise of σ
``REFERENCE_SIGMA`` per axis, white or first-order Gauss–Markov with a correlation time (a
motion-capture system's smoothing).  :func:`write_bags` writes one bag per reference rate: the
same gyro and the same reference samples, the reference kept every k-th sample.  Topics:
``imu/data_raw`` (sensor_msgs/msg/Imu) and ``mocap/pose`` (geometry_msgs/msg/PoseStamped, no
covariance: its σ comes from the model file, :func:`model_text`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from strapdown_ros.motion.profiles import bench_profile
from strapdown_ros.rotation import (dcm_to_quat, quat_multiply, quat_normalize, rotvec_to_quat,
                                    to_ros_xyzw, ypr_to_dcm)

__all__ = ['BORESIGHT', 'GYRO_BIAS_SIGMA', 'GYRO_RANDOM_WALK', 'REFERENCE_SIGMA', 'GYRO_TOPIC',
           'REFERENCE_TOPIC', 'Simulated', 'simulate', 'write_bag', 'write_bags', 'model_text',
           'input_arguments']

BORESIGHT = np.radians([2.0, -1.0, 3.0])      # β = (ψ, ϑ, γ), rad
GYRO_BIAS_SIGMA = np.radians(10.0) / 3600.0    # 10°/h, rad/s
GYRO_RANDOM_WALK = np.radians(0.01)            # 0.01°/√s = 0.6°/√h, rad/√s
REFERENCE_SIGMA = np.radians(0.05)             # per axis, rad
GYRO_TOPIC = '/imu/data_raw'
REFERENCE_TOPIC = '/mocap/pose'


class Simulated:
    """
    The simulated trial at the full rate.

    Parameters
    ----------
    gyro_ns : (n,) int ndarray
        Stamps of the gyro samples, ns.
    rate : (n, 3) ndarray
        Measured body rate, rad/s.
    fix_ns : (m,) int ndarray
        Stamps of the reference samples, ns.
    fix_q : (m, 4) ndarray
        Measured q_ref_VF, scalar first.
    bias : (3,) ndarray
        The gyro bias drawn, rad/s.

    """

    def __init__(self, gyro_ns, rate, fix_ns, fix_q, bias):
        self.gyro_ns, self.rate, self.bias = gyro_ns, rate, bias
        self.fix_ns, self.fix_q = fix_ns, fix_q


def _profile(duration: float):
    one = 4.0 + 6 * 8.0
    return bench_profile(earth_rate=False, hold=4.0, rotation_time=4.0,
                         angles_deg=(40.0, -35.0, 30.0, -40.0, 35.0, -30.0),
                         axes=(2, 0, 1, 2, 0, 1), repeat=int(np.ceil(duration / one)) + 1)


def simulate(duration: float = 360.0, gyro_rate: float = 286.0, seed: int = 0,
             correlation_time: float = 0.0, reference_sigma: float = REFERENCE_SIGMA
             ) -> Simulated:
    """
    Simulate the trial at the full rate (module docstring).

    Parameters
    ----------
    duration : float
        Length, s.
    gyro_rate : float
        Gyro and reference sampling rate, Hz.
    seed : int
        Seed of the bias and noise draws.
    correlation_time : float
        Correlation time of the reference noise, s (0: white).
    reference_sigma : float
        σ of the reference noise per axis, rad.

    Returns
    -------
    Simulated
        Gyro samples and reference fixes.

    """
    rng = np.random.default_rng(seed)
    prof = _profile(duration)
    T = 1.0 / gyro_rate
    n = int(np.floor(duration * gyro_rate))
    t = (np.arange(n) + 0.5) * T                 # off the profile's rate steps (every 4 s)
    bias = rng.normal(0.0, GYRO_BIAS_SIGMA, 3)
    rate = prof.body_rate(t) + bias + rng.normal(0.0, GYRO_RANDOM_WALK / np.sqrt(T), (n, 3))
    q_mf_vf = dcm_to_quat(ypr_to_dcm(*BORESIGHT))
    q_true = quat_normalize(quat_multiply(prof.attitude(t), q_mf_vf))
    w = rng.normal(0.0, reference_sigma, (n, 3))
    if correlation_time > 0:                     # first-order Gauss–Markov, stationary σ
        a = float(np.exp(-T / correlation_time))
        from scipy.signal import lfilter
        w[1:] *= np.sqrt(1.0 - a * a)
        w = lfilter([1.0], [1.0, -a], w, axis=0)
    fix_q = quat_normalize(quat_multiply(q_true, rotvec_to_quat(w)))
    ns = np.round(t * 1e9).astype(np.int64) + 1_000_000_000
    return Simulated(ns, rate, ns.copy(), fix_q, bias)


def write_bag(path, sim: Simulated, every: int = 1) -> dict:
    """
    Write the gyro and every ``every``-th reference sample to an MCAP bag.

    Parameters
    ----------
    path : str or Path
        The bag directory (must not exist).
    sim : Simulated
        The trial.
    every : int
        Keep one reference sample in this many.

    Returns
    -------
    dict
        Messages per topic.

    """
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores

    store = get_typestore(Stores.ROS2_JAZZY)
    T = store.types
    Time, Header = T['builtin_interfaces/msg/Time'], T['std_msgs/msg/Header']
    V3, Qt = T['geometry_msgs/msg/Vector3'], T['geometry_msgs/msg/Quaternion']
    Imu, Pose, PoseStamped = (T['sensor_msgs/msg/Imu'], T['geometry_msgs/msg/Pose'],
                              T['geometry_msgs/msg/PoseStamped'])
    Point = T['geometry_msgs/msg/Point']
    unknown = np.zeros(9)
    no_orientation = np.zeros(9)
    no_orientation[0] = -1.0                      # REP-145: orientation absent
    no_accel = no_orientation.copy()

    def header(ns, frame):
        return Header(stamp=Time(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000)),
                      frame_id=frame)
    msgs = []
    for ns, w in zip(sim.gyro_ns.tolist(), sim.rate.tolist()):
        m = Imu(header=header(ns, 'imu_link'), orientation=Qt(x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=no_orientation,
                angular_velocity=V3(x=w[0], y=w[1], z=w[2]), angular_velocity_covariance=unknown,
                linear_acceleration=V3(x=0.0, y=0.0, z=0.0),
                linear_acceleration_covariance=no_accel)
        msgs.append((ns, 0, store.serialize_cdr(m, Imu.__msgtype__)))
    keep = np.arange(0, len(sim.fix_ns), int(every))
    for ns, q in zip(sim.fix_ns[keep].tolist(), sim.fix_q[keep]):
        x, y, z, w = (float(c) for c in to_ros_xyzw(q))
        m = PoseStamped(header=header(ns, 'world'),
                        pose=Pose(position=Point(x=0.0, y=0.0, z=0.0),
                                  orientation=Qt(x=x, y=y, z=z, w=w)))
        msgs.append((ns, 1, store.serialize_cdr(m, PoseStamped.__msgtype__)))
    msgs.sort(key=lambda r: (r[0], r[1]))
    counts = {GYRO_TOPIC: 0, REFERENCE_TOPIC: 0}
    with Writer(Path(path), version=Writer.VERSION_LATEST,
                storage_plugin=StoragePlugin.MCAP) as wr:
        conns = [wr.add_connection(GYRO_TOPIC, Imu.__msgtype__, typestore=store),
                 wr.add_connection(REFERENCE_TOPIC, PoseStamped.__msgtype__, typestore=store)]
        topics = (GYRO_TOPIC, REFERENCE_TOPIC)
        for ns, k, data in msgs:
            wr.write(conns[k], ns, data)
            counts[topics[k]] += 1
    return counts


def write_bags(directory, rates, duration: float = 360.0, gyro_rate: float = 286.0,
               seed: int = 0, correlation_time: float = 0.0) -> dict:
    """
    Write one bag per reference rate from one simulated trial.

    Parameters
    ----------
    directory : str or Path
        Where the bags go (``ref_<rate>hz``), created.
    rates : sequence of float
        Reference rates, Hz (each kept as every round(gyro_rate/rate)-th sample).
    duration, gyro_rate : float
        Length (s) and gyro rate (Hz).
    seed : int
        Seed of the trial.
    correlation_time : float
        Correlation time of the reference noise, s.

    Returns
    -------
    dict
        rate → {'bag': path, 'every': k, 'fixes': count, 'rate_hz': actual rate}.

    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    sim = simulate(duration, gyro_rate, seed, correlation_time)
    out = {}
    for r in rates:
        every = max(1, int(round(gyro_rate / float(r))))
        path = directory / f'ref_{r:g}hz'
        counts = write_bag(path, sim, every)
        out[float(r)] = {'bag': str(path), 'every': every, 'fixes': counts[REFERENCE_TOPIC],
                         'rate_hz': gyro_rate / every, 'gyro_messages': counts[GYRO_TOPIC]}
    return out


def model_text(gyro_rate: float = 286.0) -> str:
    """
    Return the model file of the trial (ROS 2 parameter YAML, ``/**``).

    Parameters
    ----------
    gyro_rate : float
        Gyro rate, Hz.

    Returns
    -------
    str
        The YAML text: the gyro's noise and bias σ, the reference's σ.

    """
    return ('/**:\n  ros__parameters:\n'
            f'    gyro_rate: {float(gyro_rate)!r}\n'
            f'    gyro_random_walk: {float(GYRO_RANDOM_WALK)!r}\n'
            f'    gyro_bias_sigma: {float(GYRO_BIAS_SIGMA)!r}\n'
            '    gyro_scale_sigma: 0.0\n'
            '    gyro_misalignment_sigma: 0.0\n'
            '    gyro_max_rate: 20.0\n'
            f'    camera_sigma_xy: {float(REFERENCE_SIGMA)!r}\n'
            f'    camera_sigma_z: {float(REFERENCE_SIGMA)!r}\n'
            "    reference_frame_id: 'world'\n")


def input_arguments() -> list:
    """
    Return the input options of calibrate_bag and discrepancy for these bags.

    Returns
    -------
    list of str
        ``--gyro-topic`` and ``--reference-topic``.

    """
    return ['--gyro-topic', GYRO_TOPIC, '--reference-topic', REFERENCE_TOPIC]
