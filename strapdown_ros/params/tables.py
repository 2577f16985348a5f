"""
The parameter tables of every node and tool of the package, built from :class:`ParamSpec`.

The sensor statistics and effects come from the sensor room (:mod:`strapdown_ros.sensors`),
the choices from the rooms that own them (coning algorithms, covariance models, gravity
models, motion profiles, rate rules).  ``python -m strapdown_ros.params`` prints them as the
Markdown tables of doc/nodes.md.  No ROS imports.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from strapdown_ros.attitude.coning import algorithm_names
from strapdown_ros.attitude.integrator import COVARIANCE_MODELS
from strapdown_ros.earth import DEFAULT_GRAVITY_MODEL, GRAVITY_MODELS
from strapdown_ros.motion.from_config import PROFILE_NAMES
from strapdown_ros.params.spec import ParamSpec
from strapdown_ros.sensors import SensorSigmas
from strapdown_ros.sensors.effect_base import EffectParameter
from strapdown_ros.sensors.effects import EFFECTS
from strapdown_ros.sensors.sensor_model import ACCEL_KEYS, MODEL_ALIASES, model_keys
from strapdown_ros.streams.rate_increments import RATE_RULES


def spec_of(key: EffectParameter, description: str | None = None) -> ParamSpec:
    """
    Return the node parameter of one model key (:mod:`strapdown_ros.sensors.sensor_model`).

    Parameters
    ----------
    key : EffectParameter
        The model key (name, unit, size, default, range).
    description : str, optional
        Another meaning for the table (default: the key's own).

    Returns
    -------
    ParamSpec
        The parameter, with the key's type, default and range.

    """
    default = key.default
    if key.size > 1:
        default = [float(x) for x in default]
    elif isinstance(default, int) and not isinstance(default, bool):
        default = float(default)
    return ParamSpec(key.name, default, description or key.description, key.minimum,
                     key.maximum, exclusive_minimum=key.exclusive_minimum,
                     length=key.size if key.size > 1 else None)


def _keys(names) -> list[ParamSpec]:
    by_name = {k.name: k for k in model_keys()}
    return [spec_of(by_name[n]) for n in names]


#: every key of the sensor model (:func:`strapdown_ros.sensors.sensor_model.model_keys`): the
#: consuming nodes (sins_node, calibrator_node, attitude_filter_node) declare them all, so that
#: one model file configures each of them the same way
MODEL_PARAMS = [spec_of(k) for k in model_keys()]
#: the old names of renamed model keys, declared so that they keep working (−1: not given)
ALIAS_PARAMS = [ParamSpec(old, -1.0, f'deprecated alias of {new} (-1: not given); a value '
                          f'given here is used as {new}, with a warning', -1.0,
                          next(k.maximum for k in model_keys() if k.name == new))
                for old, new in MODEL_ALIASES.items()]

PROFILE_PARAMS = [
    ParamSpec('profile', 'coning', 'motion profile', choices=PROFILE_NAMES),
    ParamSpec('coning_alpha', 0.087, 'coning half-angle α, rad (003 §2.2)',
              0.0, np.pi, exclusive_minimum=True),
    ParamSpec('coning_nu', 1.0, 'coning frequency ν, rad/s', 0.0, 1000.0, exclusive_minimum=True),
    ParamSpec('bench_latitude_deg', 50.45,
              'bench latitude, degrees (Earth-rate direction)', -90.0, 90.0),
    ParamSpec('bench_earth_rate', True, 'bench profile turns with the Earth'),
    ParamSpec('bench_repeat', 1,
              'passes of the bench turn sequence (150 s each after a 20 s hold)', 1, 100000),
    ParamSpec('profile_file', '', "YAML with 'segments' for profile=piecewise"),
    ParamSpec('gravity', [0.0, 0.0, 0.0], 'specific force at rest in reference axes, m/s² '
              '(coning and piecewise profiles; the bench uses ENU gravity)', length=3),
    # Earth-referenced navigation profiles (static, straight_flight, coordinated_turn, sculling)
    ParamSpec('nav_latitude_deg', 50.45, 'navigation profiles: geodetic latitude of the start '
              "(turn: of the circle's centre), degrees", -90.0, 90.0),
    ParamSpec('nav_longitude_deg', 30.52, 'navigation profiles: longitude, degrees',
              -180.0, 360.0),
    ParamSpec('nav_height', 150.0, 'navigation profiles: height above the PZ-90 ellipsoid, m',
              -1e4, 1e6),
    ParamSpec('nav_speed', 0.0,
              'straight_flight / coordinated_turn speed, m/s (0: 200 straight, 100 turn)',
              0.0, 1e4),
    ParamSpec('nav_heading_deg', 0.0,
              'ENU yaw of the body (static, sculling) or of the initial velocity, degrees '
              'counter-clockwise from east (REP-103)',
              -360.0, 360.0),
    ParamSpec('turn_radius', 2000.0, 'coordinated_turn radius, m',
              0.0, 1e6, exclusive_minimum=True),
    ParamSpec('sculling_angle', 0.01, 'sculling angular amplitude about body x, rad', 0.0, 1.5),
    ParamSpec('sculling_accel', 1.0,
              'sculling acceleration amplitude along the level y axis, m/s²', 0.0, 1e3),
    ParamSpec('sculling_frequency', 10.0, 'sculling frequency, Hz',
              0.0, 1000.0, exclusive_minimum=True),
    ParamSpec('gravity_model', DEFAULT_GRAVITY_MODEL, 'normal gravity of the navigation profiles '
              "(pz90_003: 003's formula corrected, 3.2″ and 35 mGal from normal_exact)",
              choices=tuple(GRAVITY_MODELS)),
]


def _effect_specs(sensor: str, skip: Sequence[ParamSpec] = ()) -> list[ParamSpec]:
    """
    Return the specs of the model keys of one sensor's effects.

    Every key the registry's effects of that sensor own (:mod:`strapdown_ros.sensors.effects`:
    value, other parameters, σ), except names already in ``skip``.
    """
    have = {s.name for s in skip}
    return [spec_of(k) for e in EFFECTS.values() if e.sensor == sensor
            for k in e.model_parameters() if k.name not in have]


#: the gyro's model keys: its rate, then every gyro effect's keys (value, other parameters, σ)
GYRO_PARAMS = _keys(['gyro_rate']) + _effect_specs('gyro')
#: the accelerometer's model keys: its rate and statistics
ACCEL_PARAMS = _keys(['accel_rate'] + [k.name for k in ACCEL_KEYS])

#: what every node of the package declares besides its own parameters
NODE_COMMON_PARAMS = [
    ParamSpec('qos_depth', 500, 'history depth of the stream QoS', 1, 100000),
    ParamSpec('diagnostics_period', 1.0, 'period of /diagnostics, wall seconds', 0.0, 3600.0,
              exclusive_minimum=True),
]
#: the body frame of the IMU simulator (model keys)
COMMON_PARAMS = _keys(['frame_id', 'reference_frame_id']) + NODE_COMMON_PARAMS

IMU_SIM_PARAMS = PROFILE_PARAMS + GYRO_PARAMS + ACCEL_PARAMS + COMMON_PARAMS + [
    ParamSpec('seed', 0, 'seed of the random error constants and noise', 0, 2**31 - 1),
    ParamSpec('time_scale', 1.0, 'simulated seconds per wall second (> 1: faster than real time)',
              0.0, 1e6, exclusive_minimum=True),
    ParamSpec('duration', 0.0, 'simulated seconds to publish (0: the profile length, or forever)',
              0.0),
    ParamSpec('start_time', 0.0, 'header stamp of profile time 0, s', 0.0),
    ParamSpec('publish_period', 0.005, 'wall period of the publishing timer, s',
              0.0, 1.0, exclusive_minimum=True),
    ParamSpec('wait_for_subscribers', 0,
              'the simulated clock starts once imu/delta_theta and imu/data_raw have this many '
              'subscribers in all (0: at start-up), so that separately started consumers lose '
              'nothing', 0, 1000),
]

#: the stream rules of the consuming nodes (strapdown_ros/streams/checks.py); the clip levels
#: gyro_max_rate and accel_max are model keys
STREAM_PARAMS = [
    ParamSpec('max_stamp_jump', 1.0,
              'a stamp step beyond this, s, forward or back, is a jump: a lone one is an '
              'outlier, resync_count consistent ones a new timeline',
              0.0, 1e6, exclusive_minimum=True),
    ParamSpec('resync_count', 5,
              'consecutive messages that confirm a new timeline after a stamp jump', 1, 1000),
    ParamSpec('frame_mismatch', 'reject',
              'a message whose header.frame_id is neither empty nor the expected frame: reject '
              '(counted, WARN) or accept (counted, WARN)',
              choices=('reject', 'accept')),
]
#: input validation of the consuming nodes: the gyro clip level and the stream rules
INPUT_PARAMS = _keys(['gyro_max_rate']) + STREAM_PARAMS
#: the gyro input of the consuming nodes: integrated increments, or sensor_msgs/Imu rate samples
#: made into increments by strapdown_ros/streams/rate_increments.py
GYRO_INPUT_PARAMS = [
    ParamSpec('gyro_input', 'delta_theta',
              'gyro input: delta_theta (imu/delta_theta increments) or imu (imu/data_raw '
              'sensor_msgs/Imu rates made into increments by imu_rate_rule)',
              choices=('delta_theta', 'imu')),
    ParamSpec('imu_rate_rule', 'trapezoid',
              'gyro_input imu: trapezoid (a sample is the rate at its stamp) or mean (the mean '
              "rate over the interval ending at its stamp, as imu_sim_node's imu/data_raw)",
              choices=RATE_RULES),
]
#: the accelerometer clip level (a model key)
ACCEL_INPUT_PARAMS = _keys(['accel_max'])

#: largest velocity component of the navigation, m/s (above any aircraft; orbital speed is
#: 7.9 km/s)
MAX_SPEED = 1e4

#: what sins_node and sins_bag take besides the sensor model (SinsSettings)
SINS_SETTINGS = [
        ParamSpec('coning_algorithm', '2', 'coning algorithm (doc/coning_derivations.md)',
                  choices=tuple(algorithm_names())),
        ParamSpec('initial_orientation', [0.0, 0.0, 0.0, 1.0],
                  'initial q_ref_body as ROS x, y, z, w (normalised if not unit)', length=4),
        ParamSpec('initial_attitude_sigma', 0.0,
                  '1σ initial attitude error per axis, rad', 0.0, np.pi),
        ParamSpec('covariance_model', 'random_constant',
                  'gyro error model of the covariance', choices=COVARIANCE_MODELS),
        ParamSpec('quantization_correction', False, 'apply 000 eq. (5.6) with gyro_quantum'),
        ParamSpec('accel_wait', 0.1,
                  'how long (stamp seconds) sins/imu waits for accelerometer data', 0.0, 10.0),
        ParamSpec('navigation', False,
                  'navigation channel (003 §1.5): ECEF position and velocity on sins/odometry '
                  'from imu/delta_velocity; the attitude reference frame is then the inertial '
                  'frame that coincides with earth at the start (doc/navigation.md)'),
        ParamSpec('initial_position', [50.45, 30.52, 150.0],
                  'initial latitude °, longitude °, height m (PZ-90 ellipsoid)',
                  length=3, element_ranges=((-90.0, 90.0), (-180.0, 360.0), (-1e4, 1e6)),
                  element_names=('latitude °', 'longitude °', 'height m')),
        ParamSpec('initial_velocity', [0.0, 0.0, 0.0], 'initial velocity east, north, up, m/s',
                  -MAX_SPEED, MAX_SPEED, length=3),
        ParamSpec('initial_position_sigma', 0.0, '1σ initial position error per axis, m', 0.0),
        ParamSpec('initial_velocity_sigma', 0.0, '1σ initial velocity error per axis, m/s', 0.0),
        ParamSpec('initial_alignment', 'given',
                  'initial attitude: given (initial_orientation = q_earth_body) or static '
                  '(coarse alignment from gravity and Earth rate over alignment_time at rest)',
                  choices=('given', 'static')),
        ParamSpec('alignment_time', 60.0, 'static alignment window, stamp seconds', 0.1, 86400.0),
        ParamSpec('velocity_update', 'derived',
                  "velocity/position update: derived (exact in the Earth's rotation) or printed "
                  '(003 eqs. 1.99–1.100 as printed, 1 gyro : 3 accelerometer samples only)',
                  choices=('derived', 'printed')),
        ParamSpec('sculling_compensation', True,
                  'rotation and sculling from the fitted motion (false: rotation compensation '
                  '½θ×v only)'),
        ParamSpec('gravity_model', DEFAULT_GRAVITY_MODEL, 'normal gravity model '
                  "(strapdown_ros/earth; pz90_003: 003's formula corrected, 3.2″ and "
                  '35 mGal from normal_exact)',
                  choices=('pz90_003', 'normal_exact', 'j2')),
        ParamSpec('navigation_covariance_period', 1.0,
                  'propagation period of the navigation covariance, s',
                  0.001, 60.0),
        ParamSpec('earth_frame_id', 'earth',
                  'frame id of sins/odometry (REP-105 earth: ECEF, PZ-90)'),
        ParamSpec('batch_period', 0.01,
                  'increments are integrated in blocks spanning this much stamp time, and at '
                  'least every this many wall seconds (0: every message at once); outputs keep '
                  'their own stamps',
                  0.0, 1.0),
]
SINS_PARAMS = MODEL_PARAMS + NODE_COMMON_PARAMS + STREAM_PARAMS + GYRO_INPUT_PARAMS + \
    SINS_SETTINGS


def sigmas_from(values: dict, prefix: str) -> SensorSigmas:
    """
    Return the sensor statistics of a parameter set.

    Parameters
    ----------
    values : dict
        Validated parameters holding ``<prefix>_bias_sigma`` and the others of
        the sensor tables.
    prefix : {'gyro', 'accel'}
        Which sensor.

    Returns
    -------
    SensorSigmas
        The statistics (σ of bias, scale, misalignment, random walk, quantum).

    """
    return SensorSigmas.from_params(values, prefix)


ARCSEC_RAD = np.pi / 180.0 / 3600.0

STAR_CAMERA_PARAMS = PROFILE_PARAMS + _keys(['reference_frame_id', 'camera_frame_id']) + \
    NODE_COMMON_PARAMS + [
        ParamSpec('seed', 0, 'seed of the camera noise', 0, 2**31 - 1),
        ParamSpec('time_scale', 1.0, 'simulated seconds per wall second (as imu_sim_node)',
                  0.0, 1e6, exclusive_minimum=True),
        ParamSpec('duration', 0.0,
                  'simulated seconds to publish (0: the profile length, or forever)', 0.0),
        ParamSpec('start_time', 0.0, 'header stamp of profile time 0, s (as imu_sim_node)', 0.0),
        ParamSpec('publish_period', 0.005, 'wall period of the publishing timer, s',
                  0.0, 1.0, exclusive_minimum=True),
        ParamSpec('wait_for_subscribers', 0,
                  'the simulated clock starts once the camera topics have this many subscribers '
                  'in all (0: at start-up), so that separately started consumers lose nothing',
                  0, 1000),
        ParamSpec('camera_interval', 20.0, 'time between exposures, s',
                  0.0, 3600.0, exclusive_minimum=True),
        ParamSpec('camera_first_exposure', 0.0,
                  'profile time of the first exposure, s (0: one interval)', 0.0),
    ] + _keys(['camera_sigma_xy', 'camera_sigma_z', 'boresight', 'camera_time_offset']) + [
        ParamSpec('camera_exposure_time', 0.0, 'exposure duration, s', 0.0, 10.0),
        ParamSpec('camera_stamp_at_exposure_start', False,
                  'stamp = exposure start while the attitude is mid-exposure'),
    ]
STAR_CAMERA_PARAMS += _effect_specs('camera', STAR_CAMERA_PARAMS)

#: what calibrator_node and calibrate_bag take besides the sensor model (CalibratorSettings)
CALIBRATOR_SETTINGS = [
    ParamSpec('weighted', True,
              'weight the pairs by E_imu and E_avu (false: unit weights as 004)'),
    ParamSpec('covariance_model', 'random_constant',
              'gyro error model of E_imu', choices=COVARIANCE_MODELS),
    ParamSpec('initial_boresight', [0.0, 0.0, 0.0],
              'β0, rad (the solver aligns rotation axes first, so any β0 converges)',
              length=3),
    ParamSpec('min_rotation_deg', 0.5,
              'smallest rotation of the attitude about its second principal axis between two '
              'fixes of the recording that makes the boresight observable (004 §4.1, judged '
              'over all pairs)',
              0.0, 180.0),
    ParamSpec('max_sigma', 1e-3,
              'publish only when every boresight direction has predicted σ below this, rad',
              0.0, 1.0, exclusive_minimum=True),
    ParamSpec('max_pairs', 0, 'keep at most this many latest pairs (0: all)', 0, 10**7),
    ParamSpec('outlier_gate', 6.0,
              'a fix is an outlier when both its pairs disagree in rotation angle by more than '
              'this many σ and the pair skipping it agrees (0: off)',
              0.0, 1000.0),
    ParamSpec('state_file', '',
              'file the pairs and estimate persist to after every new pair (atomic), and resume '
              "from at start-up ('' = off); a corrupted one is reported and moved aside"),
    ParamSpec('max_chi2_per_dof', 3.0,
              'WARN on /diagnostics when the weighted χ²/dof of the solution exceeds this',
              0.0, 1e9, exclusive_minimum=True),
    ParamSpec('use_camera_covariance', True,
              'read P_avu from star_camera/attitude_with_covariance (false: star_camera/attitude '
              'with camera_sigma_xy/z)'),
]
CALIBRATOR_PARAMS = MODEL_PARAMS + NODE_COMMON_PARAMS + STREAM_PARAMS + GYRO_INPUT_PARAMS + \
    CALIBRATOR_SETTINGS

#: what attitude_filter_node and filter_bag take besides the sensor model (FilterSettings)
FILTER_SETTINGS = [
    ParamSpec('coning_algorithm', '2', "coning algorithm of the filter's integrator",
              choices=tuple(algorithm_names())),
    ParamSpec('initial_attitude_sigma', 1e-3, 'prior 1σ of the attitude error per axis, rad '
              '(the filter starts at the first fix)', 0.0, np.pi, exclusive_minimum=True),
    ParamSpec('boresight_source', 'parameter', 'boresight: parameter (boresight) or topic '
              '(the latched calibration/boresight; fixes wait for it, dropped and counted)',
              choices=('parameter', 'topic')),
    ParamSpec('use_camera_covariance', True, 'read the fix covariance from '
              'star_camera/attitude_with_covariance (false: star_camera/attitude, camera σ)'),
    ParamSpec('gate_probability', 0.9999, 'a fix whose NIS exceeds the χ²(3) quantile of this '
              'is gated (not applied) and counted', 0.5, 1.0, exclusive_maximum=True),
    ParamSpec('history', 20000, 'increments kept for late fixes', 16, 10**7),
    ParamSpec('output_period', 0.1, 'filter/attitude, filter/imu and the gyro errors every '
              'this much stamp time, s', 0.0, 3600.0, exclusive_minimum=True),
    ParamSpec('model_check_window', 30, "fixes in the live model check's sliding window",
              5, 10000),
    ParamSpec('model_check_alpha', 0.001, 'largest false-alarm probability of one live '
              'model-check window (NIS band two-sided and whiteness together)', 1e-9, 0.2),
    ParamSpec('model_check_false_alarms_per_hour', 0.1, 'stated rate of false WARN episodes '
              'of the live model check per hour of clean data: each window is tested at '
              'min(model_check_alpha, rate × fix interval / 3600 s) (0: at model_check_alpha)',
              0.0, 3600.0),
    ParamSpec('divergence_gated_fixes', 5, 'divergence after this many consecutive gated fixes: '
              'the fix re-initialises the attitude (σ initial_attitude_sigma), the bias and '
              'other states are kept; ERROR on /diagnostics, counted (0: not this rule)',
              0, 10**6),
    ParamSpec('divergence_nis_window', 10, 'divergence also when the NIS of the last this many '
              'fixes that pass the gate sum above their χ²(3·window) quantile of '
              'divergence_nis_probability (0: not this rule)', 0, 10**4),
    ParamSpec('divergence_nis_probability', 0.999999999, 'probability of that quantile '
              "(default 1 − 1e-9: a mean NIS above 10.2 over 10 fixes; the rule's false alarms "
              'per window on a consistent filter: at most 1 − this)',
              0.5, 1.0 - 1e-12),
]
#: attitude_filter_node and filter_bag (strapdown_ros/estimation/filter_system.py)
FILTER_PARAMS = MODEL_PARAMS + ALIAS_PARAMS + NODE_COMMON_PARAMS + STREAM_PARAMS + \
    GYRO_INPUT_PARAMS + FILTER_SETTINGS


#: every parameter name declared by any node or tool of the package
ALL_PARAMETER_NAMES = frozenset(s.name for s in IMU_SIM_PARAMS + SINS_PARAMS + STAR_CAMERA_PARAMS
                                + CALIBRATOR_PARAMS + FILTER_PARAMS)


#: the nodes whose blocks a model file may hold (ROS 2 parameter-file schema)
NODE_PARAMS = {'imu_sim_node': IMU_SIM_PARAMS, 'sins_node': SINS_PARAMS,
               'star_camera_sim_node': STAR_CAMERA_PARAMS, 'calibrator_node': CALIBRATOR_PARAMS,
               'attitude_filter_node': FILTER_PARAMS}
#: each node's own parameters (not model keys): what its typed settings are built from
NODE_SETTINGS = {'sins_node': NODE_COMMON_PARAMS + STREAM_PARAMS + GYRO_INPUT_PARAMS
                 + SINS_SETTINGS,
                 'calibrator_node': NODE_COMMON_PARAMS + STREAM_PARAMS + GYRO_INPUT_PARAMS
                 + CALIBRATOR_SETTINGS,
                 'attitude_filter_node': NODE_COMMON_PARAMS + STREAM_PARAMS + GYRO_INPUT_PARAMS
                 + FILTER_SETTINGS}
