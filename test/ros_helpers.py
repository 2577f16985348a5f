"""Helpers shared by the node tests (an executor spun until a condition, with a timeout)."""
import time


def spin_until(executor, predicate, timeout):
    """
    Spin ``executor`` until ``predicate()`` is true or ``timeout`` s pass.

    Spin ``executor`` in 20 ms slices until ``predicate()`` is true; False after ``timeout`` s
    of wall time (every wait of a node test has a timeout).
    """
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.02)
        if predicate():
            return True
    return False
