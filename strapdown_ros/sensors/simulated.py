"""
The simulated IMU of ``imu_sim_node`` and ``record_sim``: the sensor model plus the effects.

The gyro and accelerometer triads are :class:`~strapdown_ros.sensors.model.IntegratingSensor`;
the gyro carries the systematic and coupled effects of the registry
(:class:`~strapdown_ros.sensors.effects.GyroEffects`).
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.sensors.effects import GyroEffects
from strapdown_ros.sensors.model import IntegratingSensor, SensorSigmas

__all__ = ['simulated_imu']


def simulated_imu(p: dict, profile):
    """
    Build the gyro and accelerometer triads of ``imu_sim_node`` and ``record_sim``.

    Constants are drawn gyro first, then accelerometer, from ``default_rng(seed)``; the noise
    streams are seeded seed+1 (gyro) and seed+2 (accelerometer); the gyro carries the effects
    of the registry (coupled effects see the exact specific force of the profile integrated
    over each gyro interval).

    Parameters
    ----------
    p : dict
        Validated node parameters (``seed``, ``gyro_rate``, ``accel_rate``, the sensor
        statistics and the effect parameters).
    profile : MotionProfile
        The exact motion.

    Returns
    -------
    tuple of (IntegratingSensor, IntegratingSensor)
        The gyro and the accelerometer.

    """
    seed = int(p['seed'])
    rng = np.random.default_rng(seed)
    gyro_errors = SensorSigmas.from_params(p, 'gyro').draw(rng)
    accel_errors = SensorSigmas.from_params(p, 'accel').draw(rng)
    gyro = IntegratingSensor(profile, 'gyro', float(p['gyro_rate']), gyro_errors, seed=seed + 1,
                             effects=GyroEffects(p, with_delta_v=True))
    accel = IntegratingSensor(profile, 'accel', float(p['accel_rate']), accel_errors,
                              seed=seed + 2)
    return gyro, accel
