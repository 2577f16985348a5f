"""
strapdown_ros: strapdown inertial navigation with star-camera calibration.

The numerical core (``rotation``, ``profiles``, ``sensors``, ``coning``, ``integrator``)
imports numpy only.  ROS 2 code lives in :mod:`strapdown_ros.nodes` (node wrappers and
message conversion) and is never imported by the core.
"""
__version__ = '0.1.0'
