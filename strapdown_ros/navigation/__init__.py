"""
Navigation channel of 003 §1.5 (Aksyonenko 2014; paper 003): velocity and position in the
Earth-fixed (PZ-90) frame.

Modules: :mod:`.gravity` (normal gravity, geodetic conversions), :mod:`.trajectories`
(Earth-referenced motion profiles with exact truth), :mod:`.update` (specific-force integral,
velocity and position update, derived and printed forms), :mod:`.navigator` (streaming
navigation over the attitude integrator), :mod:`.alignment` (static coarse alignment).
"""
