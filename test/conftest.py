"""
Test-session isolation for ROS 2.

Every pytest session, and each of its xdist workers (``pytest -n 2``), gets its own
ROS_DOMAIN_ID and keeps discovery on this machine (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST)
*before* anything imports rclpy, so parallel sessions and workers (or another ROS graph on the
machine) never see each other.
"""
import os
import sys

_WORKER = os.environ.get('PYTEST_XDIST_WORKER', '')   # gw0, gw1, ... under pytest -n N
if _WORKER[2:].isdigit():                             # workers of one run: one domain each
    _DOMAIN = str(1 + (os.getppid() % 12) * 8 + int(_WORKER[2:]) % 8)
else:
    _DOMAIN = str(1 + (os.getpid() % 100))            # 1..100, valid on Linux
os.environ['ROS_DOMAIN_ID'] = _DOMAIN
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_STATIC_PEERS', None)
os.environ.setdefault('RCUTILS_LOGGING_BUFFERED_STREAM', '1')

# tests import the package from the repository checkout
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# shared test helpers (ros_helpers) for the tests in the room folders
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))


import pytest  # noqa: E402  (after the environment above, before any test imports rclpy)


@pytest.fixture(scope='module')
def ros():
    """Give an rclpy context for one test module of node tests."""
    import rclpy
    rclpy.init()
    yield
    rclpy.shutdown()
