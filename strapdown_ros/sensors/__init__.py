"""
Sensors: the integrating-sensor model and the registry of error effects.

:mod:`.model` holds the sensor triads, :mod:`.effects` the one home of every effect the
simulators inject, the SINS and the calibrator compensate and the discrepancy workflow looks
for; :mod:`.covariance` the covariance models, :mod:`.star_camera` the camera.
"""
from strapdown_ros.sensors.model import (ARCSEC, DEG_PER_HOUR, increment_correction,
                                         increment_covariance, IntegratingSensor,
                                         NAVIGATION_GRADE_ACCEL, NAVIGATION_GRADE_GYRO,
                                         PulseQuantizer, SensorErrorModel, SensorSigmas)
from strapdown_ros.sensors.simulated import simulated_imu

__all__ = ['SensorSigmas', 'SensorErrorModel', 'PulseQuantizer', 'IntegratingSensor',
           'increment_correction', 'increment_covariance', 'simulated_imu', 'DEG_PER_HOUR',
           'ARCSEC', 'NAVIGATION_GRADE_GYRO', 'NAVIGATION_GRADE_ACCEL']
