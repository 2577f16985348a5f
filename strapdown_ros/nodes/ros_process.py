"""
The process of a node: its executor, its spin loop, its signals and its exit status.

Every node's ``main()`` is :func:`run_node`; the benchmark harnesses of ``bench/ros/`` take the
same executor from :func:`make_executor`.  The entry points (:mod:`strapdown_ros.nodes.launch`)
arm the signals before this module is imported.
"""
from __future__ import annotations

import gc
import os
import signal
import sys

import rclpy
from rclpy.exceptions import ParameterException
import rclpy.executors
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future

from strapdown_ros.nodes.launch import signal_received

try:                                                   # Jazzy; absent from older rclpy
    from rclpy.experimental import EventsExecutor
except ImportError:                                    # pragma: no cover - older rclpy
    EventsExecutor = None

__all__ = ['make_executor', 'run_node', 'EXECUTOR_ENV', 'SPIN_SLICE_S']

#: environment variable that selects the executor of the node processes: ``events`` (default)
#: or ``single`` (rclpy's SingleThreadedExecutor)
EXECUTOR_ENV = 'STRAPDOWN_EXECUTOR'

#: longest time between a signal and the start of the shutdown, s
SPIN_SLICE_S = 0.2


def make_executor(kind: str | None = None):
    """
    Return the executor of a node process.

    rclpy's EventsExecutor (``rclpy.experimental``, Jazzy) dispatches a message in a fraction of
    the CPU time of the SingleThreadedExecutor, which rebuilds its wait set on every spin
    (figures: doc/nodes.md, executor); ``single`` selects the latter, and it is the fallback where
    the former does not exist.

    Parameters
    ----------
    kind : str, optional
        ``events`` or ``single``; default the environment variable :data:`EXECUTOR_ENV`, else
        ``events``.

    Returns
    -------
    rclpy.executors.Executor
        A new executor.

    Raises
    ------
    ValueError
        ``kind`` is neither ``events`` nor ``single``.

    """
    kind = (kind or os.environ.get(EXECUTOR_ENV, 'events')).strip().lower()
    if kind not in ('events', 'single'):
        raise ValueError(f"{EXECUTOR_ENV} must be 'events' or 'single', got {kind!r}")
    if kind == 'events' and EventsExecutor is not None:
        return EventsExecutor()
    return rclpy.executors.SingleThreadedExecutor()


def run_node(node_class, name: str, args=None) -> int:
    """
    Run a node process: init, construct, spin until SIGINT/SIGTERM or shutdown, clean up.

    Signals: the process owns SIGINT and SIGTERM (rclpy's native handlers are not installed).
    A signal only records the request; the spin loop sees it within :data:`SPIN_SLICE_S` and
    the node is shut down from the main loop, never from inside a callback (an exception raised
    in a callback would be logged by the events executor as FATAL, and a context shut down under
    a running callback makes its next publish fail).

    Parameters
    ----------
    node_class : type
        The node's class, constructed without arguments.
    name : str
        The node's name, for the error line.
    args : list of str, optional
        The ROS arguments (default the process's).

    Returns
    -------
    int
        The exit status: 0, or 2 for invalid parameters or an invalid executor (one line on
        stderr).

    """
    stop: list[int] = []

    def request_stop(signum, frame):
        stop.append(signum)

    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, request_stop)
        if signal_received():                          # a signal the entry point saw first
            return 0
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except KeyboardInterrupt:                          # the entry point's import-time handler
        return 0
    except Exception as exc:                           # e.g. a bad --params-file
        print(f'[{name}] error: {str(exc).splitlines()[0]}', file=sys.stderr)
        return 2
    try:
        executor = make_executor()
    except ValueError as exc:
        print(f'[{name}] error: {exc}', file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    try:
        node = node_class()
    except (ValueError, ParameterException) as exc:   # invalid parameters: clear message, exit 2
        _quiet_exit(executor)
        if stop:
            return 0
        print(f'[{name}] error: {exc}', file=sys.stderr)
        return 2
    except Exception:
        if stop:
            return _quiet_exit(executor)
        raise
    try:
        executor.add_node(node)
        _freeze_startup_objects()
        _spin(executor, stop)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        _quiet_exit(executor, node)
    return 0


def _freeze_startup_objects() -> None:
    """
    Move every object made at start-up out of the garbage collector's reach (``gc.freeze``).

    Modules, numba's and numpy's tables, the node: without it each full collection walks them
    all (every object of the loaded modules) while the input streams queue up.  Cycles
    made later are still collected.
    """
    gc.collect()
    gc.freeze()


def _spin(executor, stop: list) -> None:
    """Spin in slices of SPIN_SLICE_S until a stop is requested or the context is shut down."""
    never = Future()
    while not stop and rclpy.ok():
        executor.spin_until_future_complete(never, timeout_sec=SPIN_SLICE_S)


def _quiet_exit(executor, node=None) -> int:
    """
    Shut down the executor, the node and the context, each step on its own.

    rclpy's signal handler may shut the context down at the same moment ("rcl_shutdown already
    called"), which is the stop that was asked for, not an error.
    """
    steps = (executor.shutdown, node.destroy_node if node is not None else None,
             rclpy.try_shutdown)
    for step in steps:
        if step is None:
            continue
        try:
            step()
        except Exception:                              # already stopped
            pass
    return 0
