"""Calibration: star-camera boresight, gyro calibration by the seed methods, increment pairs."""
