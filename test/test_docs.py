"""
The documentation covers every parameter and topic; the README gives the commands.

The documentation covers every parameter (with its default) and every topic the nodes use, in
doc/nodes.md, and the README gives the two commands and the ROS 2 workflow.
"""
import os
import re

from strapdown_ros.params import (IMU_SIM_PARAMS, markdown_table, MODEL_PARAMS, NODE_SETTINGS,
                                  STAR_CAMERA_PARAMS)
from strapdown_ros.params.tables import ALIAS_PARAMS

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _read(*path):
    with open(os.path.join(ROOT, *path), encoding='utf-8') as f:
        return f.read()


README = _read('README.md')
NODES_PAGE = _read('doc', 'nodes.md')
LINK = re.compile(r'\]\(([^)#\s]*)(?:#([^)\s]*))?\)')


def test_parameter_tables_are_current():
    for specs in (MODEL_PARAMS + ALIAS_PARAMS, IMU_SIM_PARAMS, STAR_CAMERA_PARAMS,
                  *NODE_SETTINGS.values()):
        assert markdown_table(specs) in NODES_PAGE, \
            'regenerate the tables of doc/nodes.md with: python -m strapdown_ros.params'


def test_every_topic_is_documented():
    topics = set()
    for f in ('imu_sim_node.py', 'sins_node.py', 'star_camera_sim_node.py', 'calibrator_node.py',
              'attitude_filter_node.py'):
        src = _read('strapdown_ros', 'nodes', f)
        created = r'create_(?:publisher|subscription)\(\s*\w+,\s*["\']([^"\']+)["\']'
        topics |= set(re.findall(created, src))
    assert topics >= {'imu/delta_theta', 'imu/delta_velocity', 'imu/data_raw', 'sins/attitude',
                      'sins/imu', '/diagnostics', 'star_camera/attitude', 'calibration/boresight'}
    for t in topics:
        assert f'`{t}`' in NODES_PAGE, t


def test_two_commands_and_ros_workflow_are_documented():
    for needle in ('./scripts/demo.sh', './scripts/test.sh', 'colcon build',
                   'source install/setup.bash', 'ros2 run strapdown_ros', 'ros2 topic list',
                   'ros2 topic info', 'ros2 topic echo', 'ros2 topic hz'):
        assert needle in README, needle
    assert 'scripts/test.sh' in _read('.ci', 'run')


def _anchors(text):
    """Return GitHub's heading anchors of a Markdown text."""
    text = re.sub(r'```.*?```', '', text, flags=re.S)
    return {re.sub(r'[^\w\- ]', '', h.strip().lower()).replace(' ', '-')
            for h in re.findall(r'^#+ (.+)$', text, flags=re.M)}


def test_readme_is_one_screen_and_links_resolve():
    assert len(README.splitlines()) <= 150
    doc = os.path.join(ROOT, 'doc')
    pages = ['README.md'] + [os.path.join('doc', f) for f in sorted(os.listdir(doc))
                             if f.endswith('.md')]
    for page in pages:
        here = os.path.join(ROOT, page)
        for target, anchor in LINK.findall(_read(page)):
            if '://' in target or target.startswith('mailto:'):
                continue
            path = (os.path.normpath(os.path.join(os.path.dirname(here), target)) if target
                    else here)
            if os.path.basename(path) == 'references.md' and not os.path.exists(path):
                continue        # doc/references.md comes with the references work
            assert os.path.exists(path), f'{page}: broken link {target}'
            if anchor and path.endswith('.md'):
                with open(path, encoding='utf-8') as f:
                    assert anchor in _anchors(f.read()), f'{page}: no heading #{anchor} in {path}'


def test_version_matches_the_changelog():
    """setup.py, package.xml and the newest CHANGELOG.rst release carry one version."""
    setup = re.search(r"version='([^']+)'", _read('setup.py')).group(1)
    package = re.search(r'<version>([^<]+)</version>', _read('package.xml')).group(1)
    newest = re.search(r'^(\d+\.\d+\.\d+) \(\d{4}-\d{2}-\d{2}\)$', _read('CHANGELOG.rst'),
                       re.MULTILINE).group(1)
    assert setup == package == newest, (setup, package, newest)
