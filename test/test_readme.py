"""The README documents every parameter (with its default) and every topic the nodes use."""
import os
import re

from strapdown_ros.config import (CALIBRATOR_PARAMS, FILTER_PARAMS, IMU_SIM_PARAMS, SINS_PARAMS,
                                  STAR_CAMERA_PARAMS,
                                  markdown_table)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
README = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read()


def test_parameter_tables_are_current():
    for specs in (IMU_SIM_PARAMS, SINS_PARAMS, STAR_CAMERA_PARAMS, CALIBRATOR_PARAMS,
                  FILTER_PARAMS):
        assert markdown_table(specs) in README, "regenerate with: python -m strapdown_ros.config"


def test_every_topic_is_documented():
    topics = set()
    for f in ("imu_sim_node.py", "sins_node.py", "star_camera_sim_node.py", "calibrator_node.py",
              "attitude_filter_node.py"):
        src = open(os.path.join(ROOT, "strapdown_ros", "nodes", f), encoding="utf-8").read()
        topics |= set(re.findall(r'create_(?:publisher|subscription)\(\s*\w+,\s*"([^"]+)"', src))
    assert topics >= {"imu/delta_theta", "imu/delta_velocity", "imu/data_raw", "sins/attitude", "sins/imu",
                      "/diagnostics", "star_camera/attitude", "calibration/boresight"}
    for t in topics:
        assert f"`{t}`" in README, t


def test_two_commands_and_ros_workflow_are_documented():
    for needle in ("./scripts/demo.sh", "./scripts/test.sh", "colcon build", "source install/setup.bash",
                   "ros2 run strapdown_ros", "ros2 topic list", "ros2 topic info", "ros2 topic echo",
                   "ros2 topic hz"):
        assert needle in README, needle
    assert "scripts/test.sh" in open(os.path.join(ROOT, ".ci", "run"), encoding="utf-8").read()
