"""Attitude from gyro increments: the coning registry, the integrator, its kernel and sums."""
