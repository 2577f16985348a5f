"""
The node tests need rclpy and the message packages: without them they are not collected.

The layout and core checks of this folder (test_layout.py, test_core_without_ros.py,
test_colcon_layout.py) run without ROS.
"""
import importlib.util

ROS_TESTS = ['test_attitude_filter_node.py', 'test_calibrator_node.py', 'test_diagnostics.py',
             'test_imu_input_nodes.py', 'test_nodes.py', 'test_signals.py',
             'test_sins_node_navigation.py', 'test_hostile_nodes.py']

collect_ignore = [] if importlib.util.find_spec('rclpy') else ROS_TESTS
