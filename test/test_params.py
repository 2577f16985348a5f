"""Parameter files shipped in config/ are valid for the nodes that read them."""
import glob
import os

import numpy as np
import pytest

from strapdown_ros.motion.from_config import load_piecewise_profile, profile_from_config
from strapdown_ros.motion.profiles import ConingProfile
from strapdown_ros.params import (check_all, FILTER_PARAMS, IMU_SIM_PARAMS, load_model_file,
                                  load_parameter_file, SINS_PARAMS)
from strapdown_ros.rotation import from_ros_xyzw, quat_angle_between

CONFIG = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'config')
PARAM_FILES = [f for f in glob.glob(os.path.join(CONFIG, '*.yaml')) if 'profile_example' not in f]


@pytest.mark.parametrize('path', PARAM_FILES, ids=os.path.basename)
def test_parameter_files_validate(path):
    sim = check_all(IMU_SIM_PARAMS, load_parameter_file(path, 'imu_sim_node'))
    sins = check_all(SINS_PARAMS, load_parameter_file(path, 'sins_node'))
    prof = profile_from_config(sim)
    # the SINS initial orientation in the file is the profile's true attitude at t = 0
    q0 = from_ros_xyzw(np.asarray(sins['initial_orientation'], dtype=float))
    assert quat_angle_between(q0 / np.linalg.norm(q0), prof.attitude(0.0)) < 1e-6


def test_example_profile_loads():
    p = load_piecewise_profile(os.path.join(CONFIG, 'profile_example.yaml'))
    assert p.duration == 40.0


def test_unknown_parameter_is_refused_with_the_known_names():
    with pytest.raises(ValueError, match="unknown parameter 'coning_algo'; known: "
                                         '.*coning_algorithm'):
        check_all(SINS_PARAMS, {'coning_algo': '2'})
    assert isinstance(ConingProfile(0.1, 1.0).cone_period, float)


def test_gate_probability_says_its_bound_is_below_1():
    """Issue 27, finding 16: gate_probability:=1.0 was refused with 'valid: <= 1'."""
    spec = next(s for s in FILTER_PARAMS if s.name == 'gate_probability')
    assert spec.check(0.999999) is None
    assert spec.check(1.0) == 'gate_probability=1.0 is out of range; valid: >= 0.5 and < 1'


def test_a_model_file_with_an_attitude_filter_node_block_is_read_by_every_tool(tmp_path):
    """
    Issue 27, finding 11: discrepancy refused a block attitude_filter_node ("names no node").

    The model file of one unit holds every node's settings; discrepancy, calibrate_bag and
    calibrate_gyro_bag read it for calibrator_node, filter_bag for the filter, the same model.
    """
    f = tmp_path / 'm.yaml'
    f.write_text('/**:\n  ros__parameters:\n    gyro_bias_sigma: 1.0e-5\n'
                 'attitude_filter_node:\n  ros__parameters:\n    output_period: 0.5\n'
                 '    gate_probability: 0.999\n'
                 'calibrator_node:\n  ros__parameters:\n    weighted: false\n')
    cal = load_model_file(str(f), 'calibrator_node')
    flt = load_model_file(str(f), 'attitude_filter_node')
    assert cal.model.values() == flt.model.values()
    assert cal.settings['weighted'] is False and flt.settings['output_period'] == 0.5
