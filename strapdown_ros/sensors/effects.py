"""
The error-effect registry: one object per physical effect, owning it end to end.

Every effect the package knows lives here, once.  An effect owns its **parameters** (ROS
names, unit, size, default, valid range, the parameter giving its prior 1σ), how it **acts on
simulated data** (``imu_sim_node``, ``star_camera_sim_node``, ``record_sim``), its
**signature** (the derivative of what it changes with respect to its parameters, which the
discrepancy workflow turns into the Jacobian of the increment residuals) and its
**compensation**, where one exists (``sins_node``, ``calibrator_node``, the offline tools).
The parameters reach the nodes through ``strapdown_ros.params``, which reads them from here.
Adding an effect is one new class (a gyro effect in :mod:`strapdown_ros.sensors.gyro_effects`,
a camera effect below), one entry in :data:`EFFECTS`, its tests, its row in the effect tables of
doc/discrepancy.md and the regenerated parameter tables of doc/nodes.md.  The base class is
in :mod:`strapdown_ros.sensors.effect_base`.

All systematic gyro effects share one measurement equation per increment k (interval
``T_k``, true increment ``ρ_k``, accelerometer increment ``Δv_k`` over the same interval,
body axes)::

    ρ̃_k = K_k ρ_k + b(t_k) T_k + Σ_c G_c(θ_c) Δv_k,
    K_k = I + Σ_e K_e(θ_e, sign ρ_k),     b(t) = Σ_e b_e(θ_e, t)

with ``t_k`` the middle of interval k measured from the **effect epoch** t0 (the end stamp of
the first gyro increment: profile time ``1/gyro_rate`` in the simulators, the first accepted
stamp in a node or tool).  The compensation inverts it exactly, with sign ρ_k read from ρ̃_k.
These act *in addition to* the random constants the simulator draws from the ``*_sigma``
parameters (:class:`~strapdown_ros.sensors.model.SensorSigmas`).  Camera effects act on the
epoch a fix belongs to or on its noise; quantization and random walk are noise-model terms.
"""
from __future__ import annotations

from contextlib import contextmanager
from typing import Sequence

import numpy as np

from strapdown_ros.sensors.effect_base import Effect, EffectParameter, MAX_CAMERA_NOISE_SCALE
from strapdown_ros.sensors.gyro_effects import (GyroBias, GyroBiasDrift, GyroBiasPeriodic,
                                                GyroGSensitivity, GyroMisalignment,
                                                GyroQuantization, GyroRandomWalk,
                                                GyroScaleAsymmetry, GyroScaleFactor)

__all__ = ['EFFECTS', 'CANDIDATES', 'candidates', 'registered', 'get_effect', 'effect_parameters',
           'GyroEffects',
           'CameraEffects', 'CameraNoiseAnisotropy', 'TimeOffset']


# ----------------------------------------------------------------------------- camera effects
class CameraNoiseAnisotropy(Effect):
    """Camera noise about its axes differs from its stated covariance by a factor per axis."""

    name = 'camera_noise_anisotropy'
    sensor = 'camera'
    kind = 'noise'
    has_mean = False
    neutral = 1.0
    parameters = (EffectParameter('camera_noise_scale', '1', 3, [1.0, 1.0, 1.0],
                                  'true camera noise σ about VF x, y, z ÷ the σ the camera '
                                  'reports (or camera_sigma_*): simulated, and applied to P_avu '
                                  'by the calibrator', 0.0,
                                  MAX_CAMERA_NOISE_SCALE),)
    summary = 'camera noise about its axes differs from its stated covariance'
    signature_text = ('no mean; scales each VF axis of the camera-fix covariance: P → K P K, '
                      'K = diag(k)')

    def fix_covariance(self, P: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """
        Scale the fix covariances: P → K P K, K = diag(k).

        Parameters
        ----------
        P : (..., 3, 3) ndarray
            Stated fix covariances, rad², VF axes.
        theta : (3,) ndarray
            Scales k per VF axis.

        Returns
        -------
        (..., 3, 3) ndarray
            The true covariances.

        """
        K = np.diag(np.asarray(theta, dtype=float))
        return K @ P @ K


class TimeOffset(Effect):
    """Camera clock minus IMU clock: a fix stamped t shows the attitude at t − offset."""

    name = 'time_offset'
    sensor = 'camera'
    parameters = (EffectParameter('camera_time_offset', 's', 1, 0.0,
                                  'camera clock minus IMU clock, s (a fix stamped t shows '
                                  't − offset)', -10.0, 10.0),)
    sigma_parameter = 'camera_time_offset_sigma'
    prior_sigma = 0.01
    filter_state = True
    summary = 'camera–IMU timestamp offset'
    signature_text = ('ε = (ΔSᵀ ω(t_start) − ω(t_end))·τ: only fixes taken while turning see '
                      'it, so it shows as spikes at the rotations (004 Fig. 2a)')

    def fix_jacobian(self, rate_body: np.ndarray, c_vf_mf: np.ndarray) -> np.ndarray:
        """
        Return ∂z/∂δτ of a camera-fix residual with respect to the offset error.

        z is in VF axes, predicted minus measured; δτ = τ̂ − τ.  The camera saw the attitude
        δτ later than the epoch the fix is applied at, q(t + δτ) ≈ q(t) ⊗ exp(ω δτ), so
        ∂z/∂δτ = −C_VF^MF ω.

        Parameters
        ----------
        rate_body : (3,) ndarray
            Body rate at the fix, rad/s, body axes.
        c_vf_mf : (3, 3) ndarray
            Rotation from MF to VF axes.

        Returns
        -------
        (3, 1) ndarray
            The derivative, rad/s.

        """
        rate = np.asarray(rate_body, dtype=float).reshape(3)
        return -(np.asarray(c_vf_mf, dtype=float) @ rate)[:, None]


#: the registry: every effect, by name
EFFECTS: dict[str, Effect] = {e.name: e for e in (
    TimeOffset(), GyroBias(), GyroBiasDrift(), GyroScaleFactor(), GyroScaleAsymmetry(),
    GyroMisalignment(), GyroQuantization(), CameraNoiseAnisotropy(), GyroBiasPeriodic(),
    GyroRandomWalk(), GyroGSensitivity())}
#: the library the discrepancy workflow searches, in a fixed order (as imported; the registry's
#: current library is :func:`candidates`)
CANDIDATES: tuple[str, ...] = tuple(n for n, e in EFFECTS.items() if e.candidate)


def candidates() -> tuple[str, ...]:
    """Return the library the discrepancy workflow searches: the registry's candidate effects."""
    return tuple(n for n, e in EFFECTS.items() if e.candidate)


@contextmanager
def registered(effect: Effect):
    """
    Hold one more effect in the registry for the duration of a ``with`` block.

    A new effect of the package is a class and an entry in :data:`EFFECTS`; this puts one there
    for a while (the tests prove that every consumer reads the registry, not a table of its
    own).  Read at each use: the model keys, compensation, the filter's states, the discrepancy
    library.  The nodes' ROS parameters are declared from the registry at import.

    Parameters
    ----------
    effect : Effect
        The effect; its name must be new.

    Yields
    ------
    Effect
        The effect.

    """
    if effect.name in EFFECTS:
        raise ValueError(f'effect {effect.name!r} is registered already')
    EFFECTS[effect.name] = effect
    try:
        yield effect
    finally:
        EFFECTS.pop(effect.name, None)


def get_effect(name: str) -> Effect:
    """
    Return the registered effect of a name.

    Parameters
    ----------
    name : str
        Effect name (a key of :data:`EFFECTS`).

    Returns
    -------
    Effect
        The effect.

    Raises
    ------
    ValueError
        For an unknown name, listing the known ones.

    """
    try:
        return EFFECTS[name]
    except KeyError:
        raise ValueError(f"unknown effect {name!r}; known: {', '.join(EFFECTS)}") from None


def effect_parameters(sensor: str) -> list[EffectParameter]:
    """
    Return every parameter of the effects of one sensor, in registry order.

    Parameters
    ----------
    sensor : str
        'gyro' or 'camera'.

    Returns
    -------
    list of EffectParameter
        The parameters (the nodes declare them through ``strapdown_ros.params``).

    """
    return [p for e in EFFECTS.values() if e.sensor == sensor for p in e.parameters]


class _Overlay:
    """``get(name, default)`` of ``first``, then of ``base`` (a mapping or a sensor model)."""

    def __init__(self, base, first: dict):
        self.base, self.first = base, first

    def get(self, name, default=None):
        if name in self.first:
            return self.first[name]
        return default if self.base is None else self.base.get(name, default)


# ----------------------------------------------------------------------------- gyro bundle
class GyroEffects:
    """
    The systematic gyro effects of one parameter set, ready to apply or compensate.

    Parameters
    ----------
    params : mapping, SensorModel or None
        Anything with ``get(name, default)`` giving the effects' parameters by model key (a
        :class:`~strapdown_ros.sensors.sensor_model.SensorModel`, or a dict; other keys are
        not read).
    epoch : float or None
        The effect epoch t0 in the caller's time base (see the module docstring); None: the
        first stamp seen.
    values : dict or None
        Effect name → value, overriding ``params``.
    with_delta_v : bool
        The caller gives the accelerometer's Δv over its gyro intervals to :meth:`apply` and
        :meth:`compensate`.  Without it an active coupled effect (``gyro_g_sensitivity``) is
        refused here, with one line, rather than ignored.

    """

    def __init__(self, params: dict | None = None, epoch: float | None = None,
                 values: dict[str, Sequence[float]] | None = None, with_delta_v: bool = False):
        params = _Overlay(params, {get_effect(name).value_parameter.name: v
                                   for name, v in (values or {}).items()})
        self.epoch = epoch
        self.effects: list[tuple[Effect, np.ndarray]] = []
        for e in EFFECTS.values():
            if e.sensor != 'gyro' or e.kind not in ('systematic', 'coupled') \
                    or not e.is_active(params):
                continue
            e = e.configured(params)
            if e.needs_delta_v and not with_delta_v:
                raise ValueError(f'{e.name} needs the accelerometer increments over each gyro '
                                 'interval, which this consumer does not have: set it to 0')
            self.effects.append((e, e.value(params)))
        self._has_sign = any(isinstance(e, GyroScaleAsymmetry) for e, _ in self.effects)
        self._has_matrix = any(e.matrix_term(np.zeros(e.size), np.zeros((1, 3))) is not None
                               for e, _ in self.effects)

    @property
    def active(self) -> bool:
        """Tell whether any effect is active."""
        return bool(self.effects)

    @property
    def needs_delta_v(self) -> bool:
        """Tell whether an active effect acts through the accelerometer's Δv."""
        return any(e.needs_delta_v for e, _ in self.effects)

    def names(self) -> list[str]:
        """
        Return the names of the active effects.

        Returns
        -------
        list of str
            Registry order.

        """
        return [e.name for e, _ in self.effects]

    def _times(self, stamps: np.ndarray, T: np.ndarray) -> np.ndarray:
        if self.epoch is None:
            self.epoch = float(stamps[0])
        return stamps - 0.5 * T - self.epoch

    def _terms(self, sign, t, delta_v):
        """K (n, 3, 3) or None, and the additive increment error b·T + G·Δv (n, 3), rad."""
        n = len(t)
        K = np.broadcast_to(np.eye(3), (n, 3, 3)).copy() if self._has_matrix else None
        b = np.zeros((n, 3))
        extra = np.zeros((n, 3))
        for e, theta in self.effects:
            m = e.matrix_term(theta, sign)
            if m is not None:
                K += m
            bt = e.bias_term(theta, t)
            if bt is not None:
                b += bt
            if e.needs_delta_v:
                if delta_v is None:
                    raise ValueError(f'{e.name} needs delta_v, the accelerometer increments '
                                     'over the gyro intervals')
                extra += e.delta_v_term(theta, np.asarray(delta_v, dtype=float).reshape(n, 3))
        return K, b, extra

    def _arrays(self, stamps, T):
        stamps = np.asarray(stamps, dtype=float).reshape(-1)
        return stamps, np.broadcast_to(np.asarray(T, dtype=float), stamps.shape)

    def apply(self, rho: np.ndarray, stamps: np.ndarray, T, delta_v=None) -> np.ndarray:
        """
        Return the measured increments from true ones (the simulation).

        Parameters
        ----------
        rho : (n, 3) ndarray
            True increments, rad, body axes.
        stamps : (n,) ndarray
            End stamps of the intervals, s.
        T : float or (n,) ndarray
            Interval lengths, s.
        delta_v : (n, 3) ndarray or None
            Velocity increments ∫f dt over the same intervals, m/s, body axes; needed only by
            the coupled effects.

        Returns
        -------
        (n, 3) ndarray
            ρ̃, rad.

        """
        rho = np.asarray(rho, dtype=float).reshape(-1, 3)
        if not self.effects or len(rho) == 0:
            return rho
        stamps, T = self._arrays(stamps, T)
        K, b, extra = self._terms(np.sign(rho), self._times(stamps, T), delta_v)
        out = rho if K is None else np.einsum('nij,nj->ni', K, rho)
        return out + b * T[:, None] + extra

    def compensate(self, measured: np.ndarray, stamps: np.ndarray, T,
                   delta_v=None) -> np.ndarray:
        """
        Return the true increments from measured ones: the exact inverse of :meth:`apply`.

        Parameters
        ----------
        measured : (n, 3) ndarray
            Measured increments ρ̃, rad, body axes.
        stamps : (n,) ndarray
            End stamps of the intervals, s.
        T : float or (n,) ndarray
            Interval lengths, s.
        delta_v : (n, 3) ndarray or None
            Velocity increments over the same intervals, m/s; needed only by the coupled
            effects.

        Returns
        -------
        (n, 3) ndarray
            ρ, rad (the signs of ρ read from ρ̃).

        """
        m = np.asarray(measured, dtype=float).reshape(-1, 3)
        if not self.effects or len(m) == 0:
            return m
        stamps, T = self._arrays(stamps, T)
        K, b, extra = self._terms(np.sign(m), self._times(stamps, T), delta_v)
        x = m - b * T[:, None] - extra
        if K is None:
            return x
        if not self._has_sign:                        # one matrix for every increment
            return x @ np.linalg.inv(K[0]).T
        return np.linalg.solve(K, x[..., None])[..., 0]


class CameraEffects:
    """
    Camera-side effects of one parameter set: the epoch a fix belongs to and its noise.

    Parameters
    ----------
    params : mapping, SensorModel or None
        Anything with ``get(name, default)`` giving the camera effects' parameters (defaults
        where absent).

    """

    def __init__(self, params=None):
        params = _Overlay(params, {})
        self.time_offset = float(EFFECTS['time_offset'].value(params)[0])
        self.noise_scale = EFFECTS['camera_noise_anisotropy'].value(params)

    def epoch(self, stamp):
        """
        Return the IMU-clock time of the attitude in a fix (compensation).

        Parameters
        ----------
        stamp : float or ndarray
            Fix stamps, s, camera clock.

        Returns
        -------
        float or ndarray
            ``stamp − time_offset``, s.

        """
        return stamp - self.time_offset

    def covariance(self, P: np.ndarray) -> np.ndarray:
        """
        Return the covariance a fix really has, given the one it reports (compensation).

        Parameters
        ----------
        P : (..., 3, 3) ndarray
            Reported covariances, rad², VF axes.

        Returns
        -------
        (..., 3, 3) ndarray
            True covariances.

        """
        return EFFECTS['camera_noise_anisotropy'].fix_covariance(np.asarray(P, dtype=float),
                                                                 self.noise_scale)
