"""The tool tests that read or write bags need rosbags (the tools extra): else not collected."""
import importlib.util


BAG_TESTS = ['test_calibrate_bag.py', 'test_calibrate_gyro_bag.py', 'test_filter_bag.py',
             'test_filter_bag_outputs.py', 'test_sins_bag.py', 'test_hostile_tools.py']

collect_ignore = [] if importlib.util.find_spec('rosbags') else BAG_TESTS
