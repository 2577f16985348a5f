"""Print the parameter tables of doc/nodes.md as Markdown: ``python -m strapdown_ros.params``."""
import sys

from strapdown_ros.params.spec import markdown_table
from strapdown_ros.params.tables import (CALIBRATOR_PARAMS, FILTER_PARAMS, IMU_SIM_PARAMS,
                                         SINS_PARAMS, STAR_CAMERA_PARAMS)

for title, specs in (('imu_sim_node', IMU_SIM_PARAMS), ('sins_node', SINS_PARAMS),
                     ('star_camera_sim_node', STAR_CAMERA_PARAMS),
                     ('calibrator_node', CALIBRATOR_PARAMS),
                     ('attitude_filter_node (and filter_bag)', FILTER_PARAMS)):
    sys.stdout.write(f'\n#### {title}\n\n{markdown_table(specs)}\n')
