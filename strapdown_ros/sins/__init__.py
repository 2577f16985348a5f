"""
The SINS core of ``sins_node`` and ``sins_bag``, without ROS.

Split by subject: :mod:`~strapdown_ros.sins.core` (:class:`SinsCore`: input rules, blocks,
integration, navigation, message by message), :mod:`~strapdown_ros.sins.system`
(:class:`SinsSystem`: the core plus the input of a whole recording),
:mod:`~strapdown_ros.sins.outputs` (the output records and the Odometry numbers) and
:mod:`~strapdown_ros.sins.screening` (a whole recorded stream through the input rules).
Its names are imported from ``strapdown_ros.sins``.
"""
from strapdown_ros.sins.core import (FEED_ACCEL_BLOCK, FEED_BLOCK, MAX_BATCH, NONFINITE_INFLATION,
                                     SinsCore, SinsSettings)
from strapdown_ros.sins.outputs import (ACCEL_STALL_ERROR_FACTOR, ACCEL_STALL_ERROR_MIN_S,
                                        accel_stall_limits, AccelStall, AttitudeOutput,
                                        ImuOutput, NavigationOutput, NO_OUTPUT,
                                        odometry_arrays, SinsOutput)
from strapdown_ros.sins.screening import screen_stream
from strapdown_ros.sins.system import SinsSystem

__all__ = ['ACCEL_STALL_ERROR_FACTOR', 'ACCEL_STALL_ERROR_MIN_S', 'AccelStall',
           'accel_stall_limits', 'AttitudeOutput', 'FEED_ACCEL_BLOCK', 'FEED_BLOCK',
           'ImuOutput', 'MAX_BATCH', 'NavigationOutput', 'NO_OUTPUT', 'NONFINITE_INFLATION',
           'odometry_arrays', 'screen_stream', 'SinsCore', 'SinsOutput', 'SinsSettings',
           'SinsSystem']
