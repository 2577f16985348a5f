"""
Navigation channel of 003 §1.5 (Aksyonenko 2014): velocity and position in the Earth frame.

Velocity and position in the Earth-fixed (PZ-90) frame from the attitude integrator's updates
and the accelerometer increments.  Modules: :mod:`.update` (specific-force integral, derived
and printed forms), :mod:`.recursion` (velocity and position update), :mod:`.navigator`
(streaming navigation over the attitude integrator), :mod:`.covariance` (navigation error
covariance), :mod:`.alignment` (static coarse alignment), :mod:`.channel` (the channel as the
nodes run it) and :mod:`.run` (whole runs over simulated profiles).  Gravity and geodesy are
in :mod:`strapdown_ros.earth`, Earth-referenced motion in :mod:`strapdown_ros.motion`.
"""
