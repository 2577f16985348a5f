"""Benchmark harnesses that run ROS 2 graphs (rclpy imported here and in nodes/ only)."""
