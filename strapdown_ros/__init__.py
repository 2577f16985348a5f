"""
strapdown_ros: strapdown inertial navigation with star-camera calibration.

The package is laid out in rooms by role, then by subject (doc/architecture.md): the
numerical rooms import numpy only, and ROS 2 code lives in :mod:`strapdown_ros.nodes`, the
graph benchmarks and the demo, never imported by the core.
"""
__version__ = '0.1.0'
