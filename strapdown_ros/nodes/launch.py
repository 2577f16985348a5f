"""
Entry points of the nodes (``ros2 run strapdown_ros <node>``): light on purpose.

The node modules import rclpy and the message packages, which takes a noticeable time.  A
signal in that window used to be lost (SIGINT is ignored in a job started with ``&`` from a
script, and rclpy only re-arms it in ``rclpy.init``) or to print a traceback (Ctrl-C in the
middle of an import).  Here SIGINT and SIGTERM are armed first, before any heavy import: a
signal at any moment ends the process with status 0 and no traceback.  Once ``rclpy.init`` has
run, rclpy's own handlers take over and ``ros_process.run_node`` shuts down cleanly.  (The only
window left is the interpreter's own start-up, before any line of the package runs; a signal
there ends the process by the signal's default action, and nothing can have been lost.)
"""
from __future__ import annotations

import importlib
import signal
import sys

__all__ = ['imu_sim_node', 'sins_node', 'star_camera_sim_node', 'calibrator_node',
           'attitude_filter_node', 'strapdown_demo', 'signal_received']


_signalled = []


def _interrupt(signum, frame):
    _signalled.append(signum)
    raise KeyboardInterrupt


def signal_received() -> bool:
    """
    Tell whether SIGINT or SIGTERM arrived before the node's own handlers took over.

    The KeyboardInterrupt raised for it can be swallowed when it lands in a callback of the
    interpreter (an import-lock or weakref callback: "Exception ignored in ..."), so
    ``ros_process.run_node`` asks here too and stops instead of spinning.

    Returns
    -------
    bool
        True once a signal arrived.

    """
    return bool(_signalled)


def _run(module: str) -> int:
    # module: a node module of strapdown_ros.nodes by its name, or a full dotted module name
    # signals first, then the node module: imported here, lazily, because importing rclpy and
    # the message packages takes a noticeable time, and a signal in that window must end the
    # process cleanly (the one place of the package that imports inside a function)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _interrupt)
    try:
        name = module if '.' in module else f'strapdown_ros.nodes.{module}'
        main = importlib.import_module(name).main
    except KeyboardInterrupt:                # a signal while importing: a clean stop
        return 0
    except ImportError:
        if _signalled:                       # interrupted inside a C extension's initialisation
            return 0
        raise
    if _signalled:                           # a signal swallowed inside an import callback
        return 0
    try:
        return main()
    except KeyboardInterrupt:                # a signal before the node was spinning
        return 0
    except Exception:
        if _signalled:                       # a failure caused by the shutdown a signal started
            return 0
        raise


def imu_sim_node():
    """Run the console script ``imu_sim_node``; return its exit status."""
    return _run('imu_sim_node')


def sins_node():
    """Run the console script ``sins_node``; return its exit status."""
    return _run('sins_node')


def star_camera_sim_node():
    """Run the console script ``star_camera_sim_node``; return its exit status."""
    return _run('star_camera_sim_node')


def calibrator_node():
    """Run the console script ``calibrator_node``; return its exit status."""
    return _run('calibrator_node')


def attitude_filter_node():
    """Run the console script ``attitude_filter_node``; return its exit status."""
    return _run('attitude_filter_node')


def strapdown_demo():
    """Run the console script ``strapdown_demo``; return its exit status."""
    return _run('strapdown_ros.demo')


if __name__ == '__main__':
    sys.exit(_run(sys.argv[1]))
