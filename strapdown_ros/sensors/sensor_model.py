"""
The sensor model: one typed record of what is known about a unit's IMU and its attitude reference.

Every node and command applies the same :class:`SensorModel`: ``sins_node`` and ``sins_bag``,
``calibrator_node`` and ``calibrate_bag``, ``attitude_filter_node`` and ``filter_bag``,
``calibrate_gyro_bag`` and ``discrepancy``, and the fleet's tasks.  It is built once, from a
model file (:func:`strapdown_ros.params.load_model_file`) or from a node's declared ROS
parameters, and written back by :func:`strapdown_ros.params.write_model_file` with the same
keys, so that the model ``discrepancy --write-model`` finds is the model the other commands run.

It holds

* the rates, the frame ids and the clip levels (:data:`FIXED_KEYS`);
* for every effect of the registry (:data:`strapdown_ros.sensors.effects.EFFECTS`) its value,
  its 1σ and whether the attitude filter estimates it online (:class:`EffectState`): the
  effects own their keys, units, ranges and default priors, so a new effect needs no change
  here;
* the accelerometer statistics, the reference's stated noise (its σ per camera axis, scaled
  per axis by the effect ``camera_noise_anisotropy``) and the boresight with its σ;
* where each value came from (``stated``, ``provenance``), so that a report can say why.

The model-file keys are the ROS parameter names of the nodes, unchanged.  No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import difflib
from typing import Mapping

import numpy as np

from strapdown_ros.sensors.effect_base import EffectParameter
from strapdown_ros.sensors.effects import CameraEffects, EFFECTS, GyroEffects
from strapdown_ros.sensors.model import NAVIGATION_GRADE_ACCEL, SensorSigmas

__all__ = ['FIXED_KEYS', 'ACCEL_KEYS', 'MODEL_ALIASES', 'EffectState', 'SensorModel',
           'model_keys', 'model_key_names', 'nearest_key', 'augment_choices', 'key_group',
           'ARCSEC_RAD']

ARCSEC_RAD = np.pi / 180.0 / 3600.0


def _accel_keys() -> tuple[EffectParameter, ...]:
    g = NAVIGATION_GRADE_ACCEL
    return (
        EffectParameter('accel_bias_sigma', 'm/s²', 1, g.bias_sigma,
                        '1σ of the constant accelerometer bias per axis, m/s²', 0.0, 1000.0),
        EffectParameter('accel_scale_sigma', '1', 1, g.scale_sigma,
                        '1σ of each accelerometer scale-factor error (relative)', 0.0, 0.1),
        EffectParameter('accel_misalignment_sigma', 'rad', 1, g.misalignment_sigma,
                        '1σ of each accelerometer axis misalignment (off-diagonal of M), rad',
                        0.0, 0.1),
        EffectParameter('accel_random_walk', 'm/s/√s', 1, g.random_walk,
                        'accelerometer white-noise velocity random walk, m/s/√s', 0.0, 100.0),
        EffectParameter('accel_quantum', 'm/s', 1, 0.0,
                        'accelerometer pulse weight σ of level quantization (0 = off), m/s',
                        0.0, 10.0),
    )


#: the accelerometer statistics (σ of the random constants, random walk, quantum)
ACCEL_KEYS: tuple[EffectParameter, ...] = _accel_keys()

#: the model keys that are no effect of the registry: rates, frames, clip levels, the reference
#: noise, the boresight and the filter's online states
FIXED_KEYS: tuple[EffectParameter, ...] = (
    EffectParameter('gyro_rate', 'Hz', 1, 100.0, 'gyro output rate, Hz', 0.0, 10000.0,
                    exclusive_minimum=True),
    EffectParameter('accel_rate', 'Hz', 1, 300.0, 'accelerometer output rate, Hz', 0.0,
                    10000.0, exclusive_minimum=True),
    EffectParameter('frame_id', '', 1, 'imu_link', 'body (IMU, MF) frame id'),
    EffectParameter('reference_frame_id', '', 1, 'gcrs',
                    'frame of the reference attitudes: inertial for a star camera, the '
                    "motion-capture world frame (the reference's header.frame_id)"),
    EffectParameter('camera_frame_id', '', 1, 'star_camera',
                    'frame whose attitude the reference gives (VF: the camera, or the '
                    'motion-capture body)'),
    EffectParameter('gyro_max_rate', 'rad/s', 1, 35.0,
                    'gyro range (clip level), rad/s: an increment with a component beyond 2 '
                    'periods at this rate is rejected as impossible, and counted', 0.0, 1e4,
                    exclusive_minimum=True),
    EffectParameter('accel_max', 'm/s²', 1, 500.0,
                    'accelerometer range, m/s²: a Δv with a component beyond 2 periods at this '
                    'is rejected as impossible', 0.0, 1e6, exclusive_minimum=True),
) + ACCEL_KEYS + (
    EffectParameter('camera_sigma_xy', 'rad', 1, 0.6 * ARCSEC_RAD,
                    "1σ attitude noise of the reference about VF x and y, rad (004's star "
                    'camera: 0.6″); used where a fix has no covariance', 0.0, 0.1),
    EffectParameter('camera_sigma_z', 'rad', 1, 6.0 * ARCSEC_RAD,
                    '1σ attitude noise of the reference about VF z (the optical axis), rad; '
                    'used where a fix has no covariance', 0.0, 0.1),
    EffectParameter('reference_spacing', 's', 1, 0.0,
                    "the spacing at which the reference's fixes are used, s: its errors are "
                    'correlated over shorter spacings, so the attitude filter takes the first fix '
                    'of each slot of this length and leaves the others (0: every fix; '
                    '``discrepancy --write-model`` writes the spacing it measured)', 0.0, 3600.0),
    EffectParameter('boresight', 'rad', 3, [0.0, 0.0, 0.0],
                    'β = (heading ψ, pitch ϑ, roll γ) of VF relative to MF, rad (the true one '
                    'in the simulator; the known one in the filter)', -10.0, 10.0),
    EffectParameter('boresight_sigma', 'rad', 1, 1e-3,
                    '1σ of each boresight angle, rad (the prior of an online estimate)',
                    0.0, 0.5),
    EffectParameter('augment', '', 1, '',
                    'effects the attitude filter estimates online besides the bias, '
                    'comma-separated: registry gyro effects (gyro_scale_factor, '
                    'gyro_misalignment, ...), time_offset, boresight; each starts at its value '
                    'with its σ as the prior'),
)

#: model keys renamed: old name → (new name, factor).  The old name is accepted with a warning.
MODEL_ALIASES: dict[str, str] = {'scale_sigma': 'gyro_scale_sigma',
                                 'misalignment_sigma': 'gyro_misalignment_sigma',
                                 'time_offset_sigma': 'camera_time_offset_sigma'}


def model_keys() -> tuple[EffectParameter, ...]:
    """
    Return every key of a sensor model: the fixed keys, then each registry effect's.

    Read from the registry at each call, so an effect added to it is a model key at once.

    Returns
    -------
    tuple of EffectParameter
        The keys (name, unit, size, default, range).

    """
    out = list(FIXED_KEYS)
    have = {k.name for k in out}
    for e in EFFECTS.values():
        for k in e.model_parameters():
            if k.name not in have:
                out.append(k)
                have.add(k.name)
    return tuple(out)


def model_key_names() -> frozenset:
    """Return the names of :func:`model_keys`."""
    return frozenset(k.name for k in model_keys())


def nearest_key(name: str, known) -> str:
    """
    Return ``; did you mean X?`` for the known name nearest to ``name``, or ''.

    Parameters
    ----------
    name : str
        The unknown name.
    known : iterable of str
        The known names.

    Returns
    -------
    str
        The suggestion text.

    """
    m = difflib.get_close_matches(str(name), sorted(known), n=1, cutoff=0.6)
    return f'; did you mean {m[0]!r}?' if m else ''


def augment_choices() -> tuple[str, ...]:
    """
    Return the names the filter's ``augment`` accepts: the registry's filter states.

    The bias is always a state, so it is not among them; ``boresight`` is the boresight.

    Returns
    -------
    tuple of str
        Effect names, then ``boresight``.

    """
    return tuple(n for n, e in EFFECTS.items() if e.filter_state and n != 'gyro_bias') + \
        ('boresight',)


@dataclass(frozen=True)
class EffectState:
    """
    One effect of a sensor model.

    Attributes
    ----------
    value : tuple of float
        The value of its value parameter, SI units (neutral: the effect is absent).
    sigma : float
        1σ of each component (the uncertainty of ``value``; 0: known exactly or no σ).
    estimated : bool
        The attitude filter estimates it online, from ``value`` with prior ``sigma``.
    options : tuple of (str, object)
        Its other parameters (e.g. ``gyro_bias_period``, ``gyro_bias_random_walk``).

    """

    value: tuple
    sigma: float = 0.0
    estimated: bool = False
    options: tuple = ()

    def option(self, name: str, default=None):
        """
        Return one of the other parameters.

        Parameters
        ----------
        name : str
            Its key.
        default : object
            Returned when the effect has no such parameter.

        Returns
        -------
        object
            The value.

        """
        return dict(self.options).get(name, default)


def _default_state(e) -> EffectState:
    """Return the state of an effect at its defaults (neutral value, default σ)."""
    v = e.value_parameter.default
    sigma = e.sigma_spec.default if e.sigma_spec is not None else 0.0
    return EffectState(tuple(np.atleast_1d(np.asarray(v, dtype=float)).tolist()), float(sigma),
                       False, tuple((p.name, p.default) for p in e.parameters[1:]))


def _plain(v):
    """Return a JSON/YAML-plain copy of a value: floats, lists of floats, str, bool, int."""
    if isinstance(v, (str, bool, int)):
        return v
    a = np.asarray(v, dtype=float)
    return float(a) if a.ndim == 0 else [float(x) for x in a.reshape(-1)]


@dataclass(frozen=True)
class SensorModel:
    """
    What is known about one unit: rates, frames, clip levels, noise, effects and boresight.

    Build it with :meth:`from_values` (validated; the loaders and the nodes do) and change it
    with :meth:`with_values`; the attributes are read-only.  Picklable.

    Attributes
    ----------
    gyro_rate, accel_rate : float
        Output rates, Hz.
    frame_id, reference_frame_id, camera_frame_id : str
        The body frame, the reference's frame and the frame whose attitude it gives.
    gyro_max_rate, accel_max : float
        Clip levels, rad/s and m/s².
    accel : SensorSigmas
        The accelerometer statistics.
    camera_sigma_xy, camera_sigma_z : float
        The reference's stated noise where a fix has no covariance, rad.
    reference_spacing : float
        The spacing at which the reference's fixes are used, s (0: every fix).
    boresight : tuple of float
        β = (ψ, ϑ, γ) of VF relative to MF, rad.
    boresight_sigma : float
        Its 1σ per angle, rad.
    boresight_estimated : bool
        The attitude filter estimates the boresight online (``augment`` names it).
    effects : dict
        Registry name → :class:`EffectState`, every effect with a value parameter.
    stated : frozenset of str
        The keys the source stated (the others are defaults).
    provenance : dict
        Key → the rule or command that produced its value.
    source : str
        The file or command the model came from.

    """

    gyro_rate: float = 100.0
    accel_rate: float = 300.0
    frame_id: str = 'imu_link'
    reference_frame_id: str = 'gcrs'
    camera_frame_id: str = 'star_camera'
    gyro_max_rate: float = 35.0
    accel_max: float = 500.0
    accel: SensorSigmas = field(default_factory=SensorSigmas)
    camera_sigma_xy: float = 0.6 * ARCSEC_RAD
    camera_sigma_z: float = 6.0 * ARCSEC_RAD
    reference_spacing: float = 0.0
    boresight: tuple = (0.0, 0.0, 0.0)
    boresight_sigma: float = 1e-3
    boresight_estimated: bool = False
    effects: dict = field(default_factory=dict)
    stated: frozenset = frozenset()
    provenance: dict = field(default_factory=dict)
    source: str = ''

    # ------------------------------------------------------------------ building
    @classmethod
    def from_values(cls, values: Mapping | None = None, stated=None,
                    provenance: Mapping | None = None, source: str = '') -> SensorModel:
        """
        Build a model from model-file keys (defaults where absent), each checked.

        Parameters
        ----------
        values : mapping, optional
            Model key → value (SI units).  Keys that are no model key are refused.
        stated : iterable of str, optional
            The keys the source stated (default: the keys of ``values``).
        provenance : mapping, optional
            Key → the rule that produced its value.
        source : str
            The file or command.

        Returns
        -------
        SensorModel
            The model.

        Raises
        ------
        ValueError
            An unknown key (naming the nearest known one), a value of the wrong type or out of
            its range, or ``augment`` naming no filter state.

        """
        values = dict(values or {})
        keys = {k.name: k for k in model_keys()}
        for name in values:
            if name not in keys:
                raise ValueError(f'{name!r} is not a key of the sensor model'
                                 f'{nearest_key(name, keys)}')
        v = {}
        for name, k in keys.items():
            x = values.get(name, k.default)
            if not isinstance(k.default, (str, bool)):
                if isinstance(x, (bool, str)):
                    raise ValueError(f'{name} must be a number, got {str(x)[:80]!r}')
                x = _plain(x)
            err = k.check(x)
            if err:
                raise ValueError(err)
            v[name] = x
        augment = tuple(n.strip() for n in str(v['augment']).split(',') if n.strip())
        choices = augment_choices()
        for n in augment:
            if n not in choices:
                raise ValueError(f'augment: unknown state {n[:80]!r}; valid: '
                                 f"{', '.join(choices)}{nearest_key(n, choices)}")
        if len(set(augment)) != len(augment):
            raise ValueError('augment: a name is given twice')
        effects = {}
        for name, e in EFFECTS.items():
            extra = tuple((p.name, v[p.name]) for p in e.parameters[1:])
            sigma = float(v[e.sigma_parameter]) if e.sigma_parameter else 0.0
            effects[name] = EffectState(tuple(np.atleast_1d(v[e.value_parameter.name]).tolist()),
                                        sigma, name in augment, extra)
        accel = SensorSigmas(**{f: float(v[f'accel_{f}']) for f in
                                ('bias_sigma', 'scale_sigma', 'misalignment_sigma',
                                 'random_walk', 'quantum')})
        return cls(gyro_rate=float(v['gyro_rate']), accel_rate=float(v['accel_rate']),
                   frame_id=v['frame_id'], reference_frame_id=v['reference_frame_id'],
                   camera_frame_id=v['camera_frame_id'],
                   gyro_max_rate=float(v['gyro_max_rate']), accel_max=float(v['accel_max']),
                   accel=accel, camera_sigma_xy=float(v['camera_sigma_xy']),
                   camera_sigma_z=float(v['camera_sigma_z']),
                   reference_spacing=float(v['reference_spacing']),
                   boresight=tuple(float(x) for x in v['boresight']),
                   boresight_sigma=float(v['boresight_sigma']),
                   boresight_estimated='boresight' in augment, effects=effects,
                   stated=frozenset(values if stated is None else stated),
                   provenance=dict(provenance or {}), source=str(source))

    def values(self) -> dict:
        """
        Return every model key → value (plain numbers and lists): :meth:`from_values`'s input.

        Returns
        -------
        dict
            The values, SI units.

        """
        out = {'gyro_rate': self.gyro_rate, 'accel_rate': self.accel_rate,
               'frame_id': self.frame_id, 'reference_frame_id': self.reference_frame_id,
               'camera_frame_id': self.camera_frame_id, 'gyro_max_rate': self.gyro_max_rate,
               'accel_max': self.accel_max, 'camera_sigma_xy': self.camera_sigma_xy,
               'camera_sigma_z': self.camera_sigma_z,
               'reference_spacing': self.reference_spacing, 'boresight': list(self.boresight),
               'boresight_sigma': self.boresight_sigma,
               'augment': ','.join(self.augment)}
        for f in ('bias_sigma', 'scale_sigma', 'misalignment_sigma', 'random_walk', 'quantum'):
            out[f'accel_{f}'] = getattr(self.accel, f)
        for name, e in EFFECTS.items():
            st = self.effects.get(name) or _default_state(e)   # registered after the model
            p = e.value_parameter
            out[p.name] = list(st.value) if p.size > 1 else float(st.value[0])
            for k, x in st.options:
                out[k] = x
            if e.sigma_parameter:
                out[e.sigma_parameter] = st.sigma
        return {k: _plain(x) for k, x in out.items()}

    def with_values(self, updates: Mapping, rule: str | None = None) -> SensorModel:
        """
        Return a copy with some keys changed, checked as :meth:`from_values` checks them.

        Parameters
        ----------
        updates : mapping
            Model key → new value.
        rule : str, optional
            Recorded as the provenance of each changed key.

        Returns
        -------
        SensorModel
            The new model; the changed keys count as stated.

        """
        v = self.values()
        v.update(updates)
        prov = dict(self.provenance)
        if rule is not None:
            prov.update({k: rule for k in updates})
        new = SensorModel.from_values(v, stated=self.stated | set(updates), provenance=prov,
                                      source=self.source)
        return new

    def with_source(self, source: str) -> SensorModel:
        """
        Return a copy naming another source.

        Parameters
        ----------
        source : str
            The file or command.

        Returns
        -------
        SensorModel
            The copy.

        """
        return replace(self, source=str(source))

    # ------------------------------------------------------------------ reading
    def get(self, name: str, default=None):
        """
        Return the value of one model key (the effects' ``value(model)`` reads through this).

        Parameters
        ----------
        name : str
            A model key.
        default : object
            Returned for a name that is no model key.

        Returns
        -------
        object
            The value, SI units.

        """
        if name in _DIRECT:
            return getattr(self, name)
        for ename, e in EFFECTS.items():
            st = self.effects.get(ename)
            if st is None:
                continue
            p = e.value_parameter
            if name == p.name:
                return list(st.value) if p.size > 1 else float(st.value[0])
            if name == e.sigma_parameter:
                return st.sigma
            for k, x in st.options:
                if k == name:
                    return x
        return self.values().get(name, default)

    @property
    def augment(self) -> tuple[str, ...]:
        """Return the names the attitude filter estimates online besides the bias."""
        names = [n for n, st in self.effects.items() if st.estimated]
        return tuple(names) + (('boresight',) if self.boresight_estimated else ())

    @property
    def gyro(self) -> SensorSigmas:
        """Return the gyro statistics: the σ of bias, scale, misalignment, random walk, quantum."""
        e = self.effects
        sig = {s.statistic: self.effects[n].sigma for n, s in EFFECTS.items() if s.statistic}
        return SensorSigmas(random_walk=float(e['gyro_random_walk'].value[0]),
                            quantum=float(e['gyro_quantization'].value[0]), **sig)

    @property
    def gyro_period(self) -> float:
        """Return the nominal gyro period 1/gyro_rate, s."""
        return 1.0 / self.gyro_rate

    @property
    def camera_sigma(self) -> np.ndarray:
        """Return the stated reference σ about VF x, y, z, rad."""
        return np.array([self.camera_sigma_xy, self.camera_sigma_xy, self.camera_sigma_z])

    def effect_value(self, name: str) -> np.ndarray:
        """
        Return the value of one effect.

        Parameters
        ----------
        name : str
            Registry name.

        Returns
        -------
        ndarray
            The value, SI units.

        """
        return np.asarray(self.effects[name].value, dtype=float)

    def effect_sigma(self, name: str) -> float:
        """
        Return the 1σ of one effect's value.

        Parameters
        ----------
        name : str
            Registry name.

        Returns
        -------
        float
            The σ (0: none stated).

        """
        return float(self.effects[name].sigma)

    def active(self, sensor: str | None = None) -> list[str]:
        """
        Return the effects whose value is not neutral.

        Parameters
        ----------
        sensor : str, optional
            'gyro' or 'camera' only.

        Returns
        -------
        list of str
            Registry names, registry order.

        """
        return [n for n, e in EFFECTS.items()
                if (sensor is None or e.sensor == sensor) and e.is_active(self)]

    def gyro_effects(self, epoch: float | None = None, with_delta_v: bool = False) -> GyroEffects:
        """
        Return the model's systematic gyro effects, ready to compensate.

        Parameters
        ----------
        epoch : float, optional
            The effect epoch (None: the first stamp seen).
        with_delta_v : bool
            The caller has the accelerometer's Δv over each gyro interval.

        Returns
        -------
        GyroEffects
            The active effects.

        Raises
        ------
        ValueError
            An active coupled effect without ``with_delta_v``.

        """
        return GyroEffects(self, epoch=epoch, with_delta_v=with_delta_v)

    def camera_effects(self) -> CameraEffects:
        """Return the reference's effects: the time offset and the noise scale per axis."""
        return CameraEffects(self)

    def not_applied(self, groups) -> list[str]:
        """
        Return the stated keys, off their default, that a consumer of ``groups`` does not apply.

        So that no key is ignored silently: ``sins_bag`` (gyro, accel) names a stated boresight
        it has no use for, ``calibrate_bag`` (gyro, reference) a stated accelerometer key.

        Parameters
        ----------
        groups : iterable of str
            What the consumer applies: ``gyro``, ``accel``, ``reference``, ``filter``
            (:func:`key_group`).

        Returns
        -------
        list of str
            The keys, in key order.

        """
        groups = set(groups)
        off = set(self.differs_from_default())
        return [k for k in self.values() if k in self.stated and k in off
                and key_group(k) not in groups]

    def differs_from_default(self) -> list[str]:
        """Return the model keys whose value is not the default, in key order."""
        d = SensorModel.from_values({}).values()
        mine = self.values()
        return [k for k in mine if mine[k] != d[k]]


def key_group(name: str) -> str:
    """
    Return which part of the unit a model key describes.

    Parameters
    ----------
    name : str
        A model key.

    Returns
    -------
    str
        ``gyro`` (its rate, range, frame and effects), ``accel``, ``reference`` (the camera
        effects, the reference's σ and frames, the boresight) or ``filter`` (``augment``).

    """
    if name == 'augment':
        return 'filter'
    if name.startswith('accel_'):
        return 'accel'
    if name in ('reference_frame_id', 'camera_frame_id', 'camera_sigma_xy', 'camera_sigma_z',
                'reference_spacing', 'boresight', 'boresight_sigma'):
        return 'reference'
    for e in EFFECTS.values():
        if name in {k.name for k in e.model_parameters()}:
            return 'reference' if e.sensor == 'camera' else 'gyro'
    return 'gyro'


#: the fields read directly by :meth:`SensorModel.get`
_DIRECT = frozenset(('gyro_rate', 'accel_rate', 'frame_id', 'reference_frame_id',
                     'camera_frame_id', 'gyro_max_rate', 'accel_max', 'camera_sigma_xy',
                     'camera_sigma_z', 'reference_spacing', 'boresight_sigma'))
