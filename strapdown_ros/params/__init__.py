"""
Parameters of every node and tool: one declaration, used by the nodes, the tools and the docs.

The ROS nodes declare them as validated ROS parameters, the offline tools read them from the
same ROS 2 parameter YAML file, and ``python -m strapdown_ros.params`` prints the tables of
doc/nodes.md.  The package is split by subject: :mod:`~strapdown_ros.params.spec` (the
declaration and the file readers), :mod:`~strapdown_ros.params.tables` (the node tables),
:mod:`~strapdown_ros.params.validation` (values and the rules between them) and
:mod:`~strapdown_ros.params.model_files` (model files of every node).  Its names are imported
from ``strapdown_ros.params``.  No ROS imports.
"""
from strapdown_ros.params.model_files import (check_against_recording, filled_in,
                                              load_model_file, model_and_settings,
                                              model_from_parameters, model_of_document,
                                              ModelFile, not_applied_note,
                                              settings_from_parameters,
                                              simulator_parameters, write_model_file)
from strapdown_ros.params.spec import (load_parameter_file, markdown_table, ParamSpec,
                                       parse_overrides)
from strapdown_ros.params.tables import (ACCEL_INPUT_PARAMS, ACCEL_PARAMS,
                                         ALL_PARAMETER_NAMES, ARCSEC_RAD, CALIBRATOR_PARAMS,
                                         COMMON_PARAMS, FILTER_PARAMS, GYRO_INPUT_PARAMS,
                                         GYRO_PARAMS, IMU_SIM_PARAMS, INPUT_PARAMS, MAX_SPEED,
                                         MODEL_PARAMS, NODE_PARAMS, NODE_SETTINGS,
                                         PROFILE_PARAMS,
                                         sigmas_from, SINS_PARAMS, STAR_CAMERA_PARAMS)
from strapdown_ros.params.validation import check_all, combination_error

__all__ = ['ACCEL_INPUT_PARAMS', 'ACCEL_PARAMS', 'ALL_PARAMETER_NAMES', 'ARCSEC_RAD',
           'CALIBRATOR_PARAMS', 'check_against_recording', 'check_all', 'combination_error',
           'COMMON_PARAMS', 'FILTER_PARAMS', 'filled_in', 'GYRO_INPUT_PARAMS', 'GYRO_PARAMS',
           'IMU_SIM_PARAMS', 'INPUT_PARAMS', 'load_model_file', 'load_parameter_file',
           'markdown_table', 'MAX_SPEED', 'model_and_settings', 'model_from_parameters',
           'model_of_document', 'MODEL_PARAMS', 'ModelFile', 'NODE_PARAMS', 'NODE_SETTINGS',
           'not_applied_note',
           'ParamSpec', 'parse_overrides', 'PROFILE_PARAMS', 'settings_from_parameters',
           'sigmas_from', 'simulator_parameters', 'SINS_PARAMS', 'STAR_CAMERA_PARAMS',
           'write_model_file']
