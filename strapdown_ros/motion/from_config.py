"""
Motion profiles from parameters: the ``profile`` parameter of the simulators, and user files.

:func:`profile_from_config` is the one place where a parameter dict becomes a
:class:`~strapdown_ros.motion.profile_base.MotionProfile`: the body-frame profiles of
:mod:`strapdown_ros.motion.profiles` and the Earth-referenced ones of
:mod:`strapdown_ros.motion.earth_profiles`.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.motion.earth_profiles import navigation_profile_from_config
from strapdown_ros.motion.profile_base import MotionProfile
from strapdown_ros.motion.profiles import (bench_profile, ConingProfile, PiecewiseRateProfile,
                                           Segment, tkachenko_profile)

__all__ = ['PROFILE_NAMES', 'profile_from_config', 'load_piecewise_profile']

#: every value of the ``profile`` parameter
PROFILE_NAMES = ('coning', 'tkachenko', 'bench', 'piecewise',
                 # Earth-referenced navigation profiles (strapdown_ros.motion.earth_profiles)
                 'static', 'straight_flight', 'coordinated_turn', 'sculling')


def profile_from_config(cfg: dict) -> MotionProfile:
    """
    Build a profile from a plain dict (the ROS parameters of the simulator nodes).

    Keys: ``profile`` (one of :data:`PROFILE_NAMES`), ``coning_alpha``, ``coning_nu``,
    ``bench_latitude_deg``, ``bench_earth_rate``, ``profile_file`` (YAML, for ``piecewise``),
    ``gravity`` (3 floats, reference axes; used by coning and piecewise).  The navigation
    profiles (``static``, ``straight_flight``, ``coordinated_turn``, ``sculling``) are built by
    :func:`strapdown_ros.motion.earth_profiles.navigation_profile_from_config` (``nav_*``,
    ``turn_radius``, ``sculling_*``, ``gravity_model`` keys).

    Parameters
    ----------
    cfg : dict
        The parameters (absent keys take their defaults).

    Returns
    -------
    MotionProfile
        The profile.

    Raises
    ------
    ValueError
        For an unknown profile, or a ``piecewise`` profile without a valid file (one line).

    """
    name = cfg.get('profile', 'coning')
    if name not in PROFILE_NAMES:
        raise ValueError(f"unknown profile {name!r}; valid profiles: {', '.join(PROFILE_NAMES)}")
    if name in ('static', 'straight_flight', 'coordinated_turn', 'sculling'):
        return navigation_profile_from_config(cfg)
    gravity = cfg.get('gravity', (0.0, 0.0, 0.0))
    if name == 'coning':
        return ConingProfile(float(cfg.get('coning_alpha', 0.087)),
                             float(cfg.get('coning_nu', 1.0)), gravity=gravity)
    if name == 'tkachenko':
        return tkachenko_profile()
    if name == 'bench':
        return bench_profile(latitude_deg=float(cfg.get('bench_latitude_deg', 50.45)),
                             earth_rate=bool(cfg.get('bench_earth_rate', True)),
                             repeat=int(cfg.get('bench_repeat', 1)))
    path = cfg.get('profile_file', '')
    if not path:
        raise ValueError("profile 'piecewise' needs profile_file: a YAML file with 'segments'")
    return load_piecewise_profile(path)


def load_piecewise_profile(path: str) -> PiecewiseRateProfile:
    """
    Load a user profile from YAML.

    The file::

        initial_attitude: [w, x, y, z]      # q_ref_body at t = 0 (optional)
        earth_rate: [0, 0, 7.292115e-5]     # rad/s, reference axes (optional)
        gravity: [0, 0, 9.80665]            # specific force at rest, reference axes (optional)
        segments:                           # constant body rates, rad/s, in order
          - {duration: 10.0, rate: [0, 0, 0]}
          - {duration: 5.0,  rate: [0, 0, 0.05]}

    The file may also be a ROS 2 parameter file whose ``ros__parameters`` contain a
    ``profile`` mapping with these keys.

    Parameters
    ----------
    path : str
        The YAML file.

    Returns
    -------
    PiecewiseRateProfile
        The profile.

    Raises
    ------
    ValueError
        When the file cannot be read or is not such a profile (one line).

    """
    import yaml  # optional extra (PyYAML ships with every ROS 2 installation)

    try:
        with open(path, 'r', encoding='utf-8') as fh:
            doc = yaml.safe_load(fh)
    except OSError as exc:
        raise ValueError(f'profile_file {path}: {exc.strerror or exc}') from None
    except yaml.YAMLError as exc:
        first = str(exc).splitlines()[0]
        raise ValueError(f'profile_file {path}: not valid YAML ({first})') from None
    if isinstance(doc, dict) and 'segments' not in doc:
        # ROS 2 parameter file layout: {node: {ros__parameters: {profile: {...}}}}
        for node_block in doc.values():
            params = {}
            if isinstance(node_block, dict):
                params = (node_block or {}).get('ros__parameters', {})
            if isinstance(params.get('profile'), dict):
                doc = params['profile']
                break
    if not isinstance(doc, dict) or 'segments' not in doc:
        raise ValueError(f"{path}: expected a mapping with a 'segments' list")
    if not isinstance(doc['segments'], list) or not doc['segments']:
        raise ValueError(f"{path}: 'segments' must be a non-empty list of "
                         '{duration, rate} mappings')
    segs = []
    for i, s in enumerate(doc['segments']):
        try:
            segs.append(Segment(float(s['duration']), s.get('rate', [0.0, 0.0, 0.0])))
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise ValueError(f'{path}: segment {i}: {exc}') from None
    try:
        zero = (0.0, 0.0, 0.0)
        return PiecewiseRateProfile(
            segs, initial_attitude=doc.get('initial_attitude', (1.0, 0.0, 0.0, 0.0)),
            earth_rate=_vector3(doc.get('earth_rate', zero), 'earth_rate'),
            gravity=_vector3(doc.get('gravity', zero), 'gravity'), name='piecewise')
    except (TypeError, ValueError) as exc:
        raise ValueError(f'{path}: {exc}') from None


def _vector3(v, name):
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f'{name} must be 3 finite numbers, got {v!r}')
    return a
