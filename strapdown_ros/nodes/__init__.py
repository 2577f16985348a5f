"""The ROS 2 nodes of the package, their shared ROS I/O and their entry points (signals first)."""
