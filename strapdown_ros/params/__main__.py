"""Print the parameter tables of doc/nodes.md as Markdown: ``python -m strapdown_ros.params``."""
import sys

from strapdown_ros.params.spec import markdown_table
from strapdown_ros.params.tables import (ALIAS_PARAMS, IMU_SIM_PARAMS, MODEL_PARAMS,
                                         NODE_SETTINGS, STAR_CAMERA_PARAMS)

sys.stdout.write('\n### The sensor model (sins_node, calibrator_node, attitude_filter_node and '
                 'every model file)\n\n' + markdown_table(MODEL_PARAMS + ALIAS_PARAMS) + '\n')
for title, specs in (('imu_sim_node', IMU_SIM_PARAMS),
                     ('star_camera_sim_node', STAR_CAMERA_PARAMS)):
    sys.stdout.write(f'\n### {title}\n\n{markdown_table(specs)}\n')
for node, title in (('sins_node', 'sins_node (and sins_bag)'),
                    ('calibrator_node', 'calibrator_node (and calibrate_bag)'),
                    ('attitude_filter_node', 'attitude_filter_node (and filter_bag)')):
    sys.stdout.write(f'\n### {title}\n\nThe sensor model (above), and these settings:\n\n'
                     f'{markdown_table(NODE_SETTINGS[node])}\n')
