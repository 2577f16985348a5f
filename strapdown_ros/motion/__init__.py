"""Motion profiles with exact truth: body-frame profiles and Earth-referenced trajectories."""
