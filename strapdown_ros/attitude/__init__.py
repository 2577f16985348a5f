"""Attitude from gyro increments: the coning-algorithm registry, the integrator and its kernel."""
