"""Benchmarks: commands that measure and print figures (nothing is asserted)."""
