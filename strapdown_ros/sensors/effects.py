"""
The error-effect registry: one object per physical effect, owning it end to end.

Every effect the package knows lives here, once.  An effect owns

* its **parameters**: ROS parameter names, unit, size, default, valid range, and the name of
  the parameter that gives the 1σ of its prior (when the model has one);
* how it **acts on simulated data** (``imu_sim_node``, ``star_camera_sim_node``, ``record_sim``);
* its **signature**: the derivative of what it changes (a gyro increment, a camera epoch, a
  camera-fix covariance) with respect to its parameters; the discrepancy workflow turns it into
  the Jacobian of the increment residuals (:mod:`strapdown_ros.discrepancy.workflow`);
* its **compensation**, where one exists (``sins_node``, ``calibrator_node``, the offline tools).

Adding an effect is one new class below, one line in :data:`EFFECTS`, and its tests.

Gyro measurement equation
-------------------------
All systematic gyro effects share one equation per increment k (interval ``T_k``, true
increment ``ρ_k``, body axes)::

    ρ̃_k = K_k ρ_k + b(t_k) T_k,     K_k = I + Σ_e K_e(θ_e, sign ρ_k),     b(t) = Σ_e b_e(θ_e, t)

with ``t_k`` the middle of interval k measured from the **effect epoch** t0 (the end stamp of
the first gyro increment: profile time ``1/gyro_rate`` in the simulators, the first accepted
stamp in a node or tool).  The compensation inverts it exactly,
``ρ_k = K_k⁻¹ (ρ̃_k − b(t_k) T_k)``, with sign ρ_k read from ρ̃_k (the same signs unless an
error exceeds the signal).  These act *in addition to* the random constants the simulator
draws from the ``*_sigma`` parameters (:class:`~strapdown_ros.sensors.model.SensorSigmas`).

Camera effects act on the epoch a fix belongs to (``time_offset``) or on its noise
(``camera_noise_anisotropy``); quantization and random walk are noise-model terms.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from strapdown_ros.sensors.model import NAVIGATION_GRADE_GYRO

__all__ = ['EffectParameter', 'Effect', 'EFFECTS', 'CANDIDATES', 'get_effect', 'effect_parameters',
           'GyroEffects', 'CameraEffects', 'MISALIGNMENT_INDEX']


@dataclass(frozen=True)
class EffectParameter:
    """One ROS parameter of an effect (SI units).  ``size`` 1 is a double, n > 1 a double[n]."""
    name: str
    unit: str
    size: int
    default: object
    description: str
    minimum: float | None = None
    maximum: float | None = None
    exclusive_minimum: bool = False


#: physical bounds of the effect parameters (each element): a rate beyond 100 rad/s is no bias, a
#: relative scale error beyond 0.5 and an axis misalignment beyond 0.5 rad are no small error,
#: and values beyond overflow the squares of the error models
MAX_BIAS_RATE = 100.0            # rad/s
MAX_BIAS_DRIFT = 0.01            # rad/s² (100 rad/s after 3 h)
MAX_RELATIVE_ERROR = 0.5         # scale factor, scale asymmetry
MAX_MISALIGNMENT = 0.5           # rad
MAX_RANDOM_WALK = 1.0            # rad/√s
MAX_QUANTUM = 0.1                # rad
# a star-tracker σ stated for a motion-capture reference is ~10⁴ too small: simulable, and the
# discrepancy fit of the term (NOISE_SCALE_RANGE) reports such a scale as at its bound
MAX_CAMERA_NOISE_SCALE = 1e6


#: order of the 6 off-diagonal elements of the gyro misalignment matrix M (row, column):
#: ρ̃_i = ρ_i + Σ_j M_ij ρ_j, i ≠ j
MISALIGNMENT_INDEX = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))


class Effect:
    """
    Base class.  ``sensor``: 'gyro' or 'camera'; ``kind``: 'systematic' (changes the mean of
    the data, has a signature and usually a compensation) or 'noise' (changes the covariance).
    ``candidate``: searched for by the discrepancy workflow; other effects can be simulated and
    compensated but are outside the library the workflow names.
    """
    name: str = ''
    sensor: str = 'gyro'
    kind: str = 'systematic'
    candidate: bool = True
    compensable: bool = True
    parameters: tuple[EffectParameter, ...] = ()
    #: parameter giving the prior 1σ of the value parameter (per component), if any
    sigma_parameter: str | None = None
    #: changes the mean of the residuals (systematic effects, and quantization's lag)
    has_mean: bool = True
    #: the zero-effect value of the estimated parameters (1 for multiplicative noise scales)
    neutral: float = 0.0
    summary: str = ''
    signature_text: str = ''

    @property
    def value_parameter(self) -> EffectParameter:
        """The parameter the workflow estimates and writes to the model."""
        return self.parameters[0]

    @property
    def size(self) -> int:
        return self.value_parameter.size

    def labels(self) -> list[str]:
        p = self.value_parameter
        if p.size == 1:
            return [p.name]
        return [f'{p.name}[{i}]' for i in range(p.size)]

    def value(self, params: dict) -> np.ndarray:
        """The value vector of this effect from a parameter dict (defaults where absent)."""
        p = self.value_parameter
        v = params.get(p.name, p.default)
        return np.asarray(v, dtype=float).reshape(p.size)

    def is_active(self, params: dict) -> bool:
        return bool(np.any(self.value(params) != self.neutral))

    # gyro systematic effects override these -------------------------------------------
    def direct_check(self, delta_theta: np.ndarray, theta: np.ndarray) -> str | None:
        """
        A test of the effect on the raw measured increments, independent of the residuals:
        None when the data are consistent with it (or there is no such test), else the reason.
        """
        return None

    def fit_basis(self) -> np.ndarray | None:
        """
        (size, q) map from the q combinations the residuals can separate to the parameters,
        or None when all are separable.
        """
        return None

    def matrix_term(self, theta: np.ndarray, sign: np.ndarray) -> np.ndarray | None:
        """Contribution to K − I for increments with signs ``sign`` (n, 3) → (n, 3, 3), or None."""
        return None

    def bias_term(self, theta: np.ndarray, t: np.ndarray) -> np.ndarray | None:
        """Contribution to the rate bias at times t (n,) since the effect epoch → (n, 3), or None."""
        return None

    def increment_jacobian(self, rho: np.ndarray, T: np.ndarray, t: np.ndarray) -> np.ndarray:
        """∂ρ̃/∂θ at θ = 0: (n, 3, size), for true increments ρ (n, 3), lengths T (n,), times t (n,)."""
        raise NotImplementedError

    # the attitude filter's view of an effect (strapdown_ros.estimation) ------------------
    #: name of the filter parameter giving the white-noise density that drives the filter
    #: states of this effect as a random walk (None: a random constant, no process noise)
    filter_noise_parameter: str | None = None
    #: name of the filter parameter giving the correlation time of a Gauss–Markov state (None or
    #: 0: no decay)
    filter_correlation_parameter: str | None = None

    def filter_size(self) -> int:
        """Number of filter states: the separable combinations (:meth:`fit_basis`), else size."""
        S = self.fit_basis()
        return self.size if S is None else S.shape[1]

    def filter_values(self, states: np.ndarray) -> np.ndarray:
        """The effect's parameter vector (size,) from its filter states (filter_size,)."""
        S = self.fit_basis()
        states = np.asarray(states, dtype=float).reshape(self.filter_size())
        return states if S is None else S @ states

    def filter_partials(self, rho: np.ndarray, T: np.ndarray, t: np.ndarray) -> np.ndarray:
        """
        ∂ρ̃/∂c of the increments with respect to the filter states c: (n, 3, filter_size),
        for increments ρ (n, 3) of lengths T (n,) at times t (n,) since the effect epoch
        (:meth:`increment_jacobian` mapped through :meth:`fit_basis`).
        """
        J = self.increment_jacobian(np.asarray(rho, dtype=float).reshape(-1, 3),
                                    np.asarray(T, dtype=float).reshape(-1),
                                    np.asarray(t, dtype=float).reshape(-1))
        S = self.fit_basis()
        return J if S is None else J @ S

    def filter_correlation_time(self, noise: dict | None = None) -> np.ndarray:
        """
        Correlation time (filter_size,) of the filter states, s: ``noise[
        filter_correlation_parameter]`` makes the states first-order Gauss–Markov (driven by
        :meth:`filter_process_noise`, steady σ² = density·τ/2: a bias instability); inf (a random
        walk, or a random constant without noise) when not given or 0.
        """
        value = np.inf
        if self.filter_correlation_parameter is not None and noise:
            v = float(noise.get(self.filter_correlation_parameter, 0.0))
            if not (np.isfinite(v) and v >= 0.0):
                raise ValueError(f'{self.filter_correlation_parameter} must be finite and >= 0')
            value = v if v > 0 else np.inf
        return np.full(self.filter_size(), value)

    def filter_process_noise(self, noise: dict | None = None) -> np.ndarray:
        """
        White-noise density (filter_size,) driving the filter states, from a dict of filter
        noise parameters: ``noise[filter_noise_parameter]²`` per state, 0 (random constant)
        when the effect has no such parameter or the dict does not give it.
        """
        value = 0.0
        if self.filter_noise_parameter is not None and noise:
            value = float(noise.get(self.filter_noise_parameter, 0.0))
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f'{self.filter_noise_parameter} must be finite and >= 0')
        return np.full(self.filter_size(), value ** 2)

    def __repr__(self):
        return f'<effect {self.name}>'


# ----------------------------------------------------------------------------- gyro, systematic
class GyroBias(Effect):
    name = 'gyro_bias'
    parameters = (EffectParameter('gyro_bias', 'rad/s', 3, [0.0, 0.0, 0.0],
                                  'known constant gyro bias b, body axes, rad/s (simulated and '
                                  'compensated)',
                                  -MAX_BIAS_RATE, MAX_BIAS_RATE),)
    sigma_parameter = 'gyro_bias_sigma'
    #: bias random walk (rate random walk) σ_u, rad/s/√s, of the attitude filter
    filter_noise_parameter = 'gyro_bias_random_walk'
    #: bias instability as a first-order Gauss–Markov bias with this correlation time, s
    filter_correlation_parameter = 'gyro_bias_correlation_time'
    summary = 'constant rate bias'
    signature_text = 'ε grows with the pair duration: Σ C_k T_k b'

    def bias_term(self, theta, t):
        return np.broadcast_to(theta, (len(t), 3))

    def increment_jacobian(self, rho, T, t):
        return T[:, None, None] * np.eye(3)


class GyroBiasDrift(Effect):
    name = 'gyro_bias_drift'
    parameters = (EffectParameter('gyro_bias_drift', 'rad/s²', 3, [0.0, 0.0, 0.0],
                                  'linear bias ramp d: bias b + d·(t − t0), t0 = first gyro '
                                  'stamp, rad/s²',
                                  -MAX_BIAS_DRIFT, MAX_BIAS_DRIFT),)
    summary = 'bias growing linearly with time'
    signature_text = 'as gyro_bias, weighted by the time since the first gyro stamp'

    def bias_term(self, theta, t):
        return np.asarray(t)[:, None] * theta

    def increment_jacobian(self, rho, T, t):
        return (T * t)[:, None, None] * np.eye(3)


class GyroBiasPeriodic(Effect):
    """
    A bias oscillating with a known period: simulated and compensated, but deliberately not in
    the workflow's library (its test case for 'unexplained structure').
    """
    name = 'gyro_bias_periodic'
    candidate = False
    parameters = (EffectParameter('gyro_bias_periodic', 'rad/s', 3, [0.0, 0.0, 0.0],
                                  'amplitude A of a periodic bias A·sin(2π(t − t0)/P), rad/s (outside the '
                                  'discrepancy library)', -MAX_BIAS_RATE, MAX_BIAS_RATE),
                  EffectParameter('gyro_bias_period', 's', 1, 600.0, 'period P of gyro_bias_periodic, s',
                                  0.0, 1e7, exclusive_minimum=True))
    summary = 'bias oscillating with period P'

    def __init__(self, period: float = 600.0):
        self.period = float(period)

    def bias_term(self, theta, t):
        return np.sin(2.0 * np.pi * np.asarray(t) / self.period)[:, None] * theta

    def increment_jacobian(self, rho, T, t):
        return (T * np.sin(2.0 * np.pi * t / self.period))[:, None, None] * np.eye(3)


class GyroScaleFactor(Effect):
    name = 'gyro_scale_factor'
    parameters = (EffectParameter('gyro_scale_factor', '1', 3, [0.0, 0.0, 0.0],
                                  'known scale-factor errors s (relative), diagonal of M',
                                  -MAX_RELATIVE_ERROR, MAX_RELATIVE_ERROR),)
    sigma_parameter = 'gyro_scale_sigma'
    summary = 'scale-factor error, same for both rotation senses'
    signature_text = 'ε ∝ rotation about each gyro axis: Σ C_k diag(ρ_k) s'

    def matrix_term(self, theta, sign):
        return np.broadcast_to(np.diag(theta), (len(sign), 3, 3))

    def increment_jacobian(self, rho, T, t):
        J = np.zeros((len(rho), 3, 3))
        idx = np.arange(3)
        J[:, idx, idx] = rho
        return J


class GyroScaleAsymmetry(Effect):
    name = 'gyro_scale_asymmetry'
    parameters = (EffectParameter('gyro_scale_asymmetry', '1', 3, [0.0, 0.0, 0.0],
                                  'scale asymmetry a: scale 1 + s + a for positive, 1 + s − a for '
                                  'negative rates',
                                  -MAX_RELATIVE_ERROR, MAX_RELATIVE_ERROR),)
    summary = 'different scale factor for positive and negative rates'
    signature_text = 'ε ∝ |rotation| about each axis: Σ C_k diag(|ρ_k|) a (needs turns of both senses to tell from scale)'

    def matrix_term(self, theta, sign):
        out = np.zeros((len(sign), 3, 3))
        idx = np.arange(3)
        out[:, idx, idx] = sign * theta
        return out

    def increment_jacobian(self, rho, T, t):
        J = np.zeros((len(rho), 3, 3))
        idx = np.arange(3)
        J[:, idx, idx] = np.abs(rho)
        return J


class GyroMisalignment(Effect):
    name = 'gyro_misalignment'
    parameters = (EffectParameter('gyro_misalignment', 'rad', 6, [0.0] * 6,
                                  'known axis misalignments: off-diagonal M_xy, M_xz, M_yx, M_yz, '
                                  'M_zx, M_zy, rad',
                                  -MAX_MISALIGNMENT, MAX_MISALIGNMENT),)
    sigma_parameter = 'gyro_misalignment_sigma'
    summary = 'non-orthogonal gyro axes (off-diagonal M)'
    signature_text = ('ε ∝ cross-axis rotation: Σ C_k M ρ_k; the antisymmetric part of M is a rotation of the '
                      'whole triad, the same signature as a boresight change, so only the symmetric part '
                      '(non-orthogonality, 3 combinations) is separable')

    def fit_basis(self):
        """Symmetric non-orthogonality: M_xy = M_yx, M_xz = M_zx, M_yz = M_zy."""
        S = np.zeros((6, 3))
        for c, pair in enumerate(((0, 2), (1, 4), (3, 5))):
            S[list(pair), c] = 1.0
        return S

    def matrix_term(self, theta, sign):
        M = np.zeros((3, 3))
        for v, (i, j) in zip(theta, MISALIGNMENT_INDEX):
            M[i, j] = v
        return np.broadcast_to(M, (len(sign), 3, 3))

    def increment_jacobian(self, rho, T, t):
        J = np.zeros((len(rho), 3, 6))
        for c, (i, j) in enumerate(MISALIGNMENT_INDEX):
            J[:, i, c] = rho[:, j]
        return J


# ----------------------------------------------------------------------------- noise terms
class GyroRandomWalk(Effect):
    """White angle random walk: part of every nominal model, not searched for."""
    name = 'gyro_random_walk'
    kind = 'noise'
    has_mean = False
    candidate = False
    compensable = False
    parameters = (EffectParameter('gyro_random_walk', 'rad/√s', 1, NAVIGATION_GRADE_GYRO.random_walk,
                                  'white-noise random walk, rad/√s', 0.0, MAX_RANDOM_WALK),)
    summary = 'angle random walk (white rate noise)'


class GyroQuantization(Effect):
    name = 'gyro_quantization'
    kind = 'noise'
    compensable = False
    parameters = (EffectParameter('gyro_quantum', 'rad', 1, 0.0,
                                  'pulse weight σ of level quantization (0 = off), rad', 0.0,
                                  MAX_QUANTUM),)
    summary = 'pulse quantization with carried remainder (000 §5), uncompensated'
    signature_text = ('the output lags the integral by the carried remainder: a mean σ/2 in the sense of the '
                      'motion on each axis (000 §5.3), seen where a pair starts and ends in different motion, '
                      'and a variance σ²/12 per axis at each fix, with the camera-fix correlation structure')

    @staticmethod
    def lattice_step(delta_theta: np.ndarray, tolerance: float = 0.01, min_fraction: float = 0.9):
        """
        The pulse weight the increments are multiples of, per axis, or None per axis where they
        are not quantized: the smallest non-zero |Δθ| (1st percentile), accepted when at least
        ``min_fraction`` of the non-zero increments lie within ``tolerance`` of a multiple, then
        refined as the median of Δθ / round(Δθ / step).
        """
        steps = []
        for x in np.asarray(delta_theta, dtype=float).reshape(-1, 3).T:
            x = x[x != 0.0]
            if len(x) < 20:
                steps.append(None)
                continue
            q0 = float(np.percentile(np.abs(x), 1.0))
            m = np.round(x / q0)
            good = (m != 0) & (np.abs(x / q0 - m) < tolerance)
            if np.mean(good) < min_fraction:
                steps.append(None)
                continue
            steps.append(float(np.median(x[good] / m[good])))
        return steps

    def direct_check(self, delta_theta, theta):
        """
        Quantized increments are multiples of the pulse weight: the lattice must exist and its
        step must agree with the estimate within a factor 1.5.
        """
        steps = [s for s in self.lattice_step(delta_theta) if s is not None]
        if not steps:
            return 'the measured increments are not multiples of a pulse weight (no quantization lattice)'
        q = float(np.median(steps))
        if theta is None:
            return None
        if not (q / 1.5 <= float(theta[0]) <= 1.5 * q):
            return f'the increments lie on a lattice of step {q:.3g} rad, not {float(theta[0]):.3g}'
        return None

    def fix_covariance(self, P: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """
        Per-fix covariance (n, 3, 3) with the remainder variance σ²/12 added (isotropic, so the
        same in MF and VF axes).
        """
        return P + (float(theta[0]) ** 2 / 12.0) * np.eye(3)


class CameraNoiseAnisotropy(Effect):
    name = 'camera_noise_anisotropy'
    sensor = 'camera'
    kind = 'noise'
    has_mean = False
    neutral = 1.0
    parameters = (EffectParameter('camera_noise_scale', '1', 3, [1.0, 1.0, 1.0],
                                  'true camera noise σ about VF x, y, z ÷ the σ the camera reports (or '
                                  'camera_sigma_*): simulated, and applied to P_avu by the '
                                  'calibrator', 0.0,
                                  MAX_CAMERA_NOISE_SCALE),)
    summary = 'camera noise about its axes differs from its stated covariance'
    signature_text = 'no mean; scales each VF axis of the camera-fix covariance: P → K P K, K = diag(k)'

    def fix_covariance(self, P: np.ndarray, theta: np.ndarray) -> np.ndarray:
        K = np.diag(np.asarray(theta, dtype=float))
        return K @ P @ K


class TimeOffset(Effect):
    name = 'time_offset'
    sensor = 'camera'
    parameters = (EffectParameter('camera_time_offset', 's', 1, 0.0,
                                  'camera clock minus IMU clock, s (a fix stamped t shows t − offset)', -10.0, 10.0),)
    summary = 'camera–IMU timestamp offset'
    signature_text = ('ε = (ΔSᵀ ω(t_start) − ω(t_end))·τ: only fixes taken while turning see it, so it shows as '
                      'spikes at the rotations (004 Fig. 2a)')

    def fix_jacobian(self, rate_body: np.ndarray, c_vf_mf: np.ndarray) -> np.ndarray:
        """
        ∂z/∂δτ (3, 1) of a camera-fix residual z (VF axes, predicted minus measured) with
        respect to the error δτ = τ̂ − τ of the estimated offset: the camera saw the attitude
        δτ later than the epoch the fix is applied at, q(t + δτ) ≈ q(t) ⊗ exp(ω δτ), so
        ∂z/∂δτ = −C_VF^MF ω (ω the body rate at the fix, rad/s, body axes).
        """
        rate = np.asarray(rate_body, dtype=float).reshape(3)
        return -(np.asarray(c_vf_mf, dtype=float) @ rate)[:, None]


#: the registry: every effect, by name
EFFECTS: dict[str, Effect] = {e.name: e for e in (
    TimeOffset(), GyroBias(), GyroBiasDrift(), GyroScaleFactor(), GyroScaleAsymmetry(), GyroMisalignment(),
    GyroQuantization(), CameraNoiseAnisotropy(), GyroBiasPeriodic(), GyroRandomWalk())}
#: the library the discrepancy workflow searches, in a fixed order
CANDIDATES: tuple[str, ...] = tuple(n for n, e in EFFECTS.items() if e.candidate)


def get_effect(name: str) -> Effect:
    try:
        return EFFECTS[name]
    except KeyError:
        raise ValueError(f"unknown effect {name!r}; known: {', '.join(EFFECTS)}") from None


def effect_parameters(sensor: str) -> list[EffectParameter]:
    """Every parameter of the effects of one sensor ('gyro' or 'camera'), registry order."""
    return [p for e in EFFECTS.values() if e.sensor == sensor for p in e.parameters]


# ----------------------------------------------------------------------------- gyro bundle
class GyroEffects:
    """
    The systematic gyro effects of one parameter set, ready to apply or compensate.

    ``params``: a dict with any of the effects' parameter names (others are ignored);
    ``epoch``: the effect epoch t0 in the caller's time base (see the module docstring).
    """

    def __init__(self, params: dict | None = None, epoch: float | None = None,
                 values: dict[str, Sequence[float]] | None = None):
        params = dict(params or {})
        for name, v in (values or {}).items():
            params[get_effect(name).value_parameter.name] = v
        self.epoch = epoch
        self.effects: list[tuple[Effect, np.ndarray]] = []
        for e in EFFECTS.values():
            if e.sensor != 'gyro' or e.kind != 'systematic' or not e.is_active(params):
                continue
            if isinstance(e, GyroBiasPeriodic):
                e = GyroBiasPeriodic(float(params.get('gyro_bias_period', 600.0)))
            self.effects.append((e, e.value(params)))
        self._has_sign = any(isinstance(e, GyroScaleAsymmetry) for e, _ in self.effects)
        self._has_matrix = any(e.matrix_term(np.zeros(e.size), np.zeros((1, 3))) is not None
                               for e, _ in self.effects)

    @property
    def active(self) -> bool:
        return bool(self.effects)

    def names(self) -> list[str]:
        return [e.name for e, _ in self.effects]

    def _times(self, stamps: np.ndarray, T: np.ndarray) -> np.ndarray:
        if self.epoch is None:
            self.epoch = float(stamps[0])
        return stamps - 0.5 * T - self.epoch

    def _terms(self, sign, t):
        n = len(t)
        K = np.broadcast_to(np.eye(3), (n, 3, 3)).copy() if self._has_matrix else None
        b = np.zeros((n, 3))
        for e, theta in self.effects:
            m = e.matrix_term(theta, sign)
            if m is not None:
                K += m
            bt = e.bias_term(theta, t)
            if bt is not None:
                b += bt
        return K, b

    def apply(self, rho: np.ndarray, stamps: np.ndarray, T) -> np.ndarray:
        """Measured increments ρ̃ (n, 3) from true ρ (n, 3) with end stamps (n,) and lengths T."""
        rho = np.asarray(rho, dtype=float).reshape(-1, 3)
        if not self.effects or len(rho) == 0:
            return rho
        stamps = np.asarray(stamps, dtype=float).reshape(-1)
        T = np.broadcast_to(np.asarray(T, dtype=float), stamps.shape)
        K, b = self._terms(np.sign(rho), self._times(stamps, T))
        out = rho if K is None else np.einsum('nij,nj->ni', K, rho)
        return out + b * T[:, None]

    def compensate(self, measured: np.ndarray, stamps: np.ndarray, T) -> np.ndarray:
        """True increments from measured ones: the exact inverse of :meth:`apply`."""
        m = np.asarray(measured, dtype=float).reshape(-1, 3)
        if not self.effects or len(m) == 0:
            return m
        stamps = np.asarray(stamps, dtype=float).reshape(-1)
        T = np.broadcast_to(np.asarray(T, dtype=float), stamps.shape)
        K, b = self._terms(np.sign(m), self._times(stamps, T))
        x = m - b * T[:, None]
        if K is None:
            return x
        if not self._has_sign:                        # one matrix for every increment
            return x @ np.linalg.inv(K[0]).T
        return np.linalg.solve(K, x[..., None])[..., 0]


class CameraEffects:
    """Camera-side effects of one parameter set: the epoch a fix belongs to and its noise."""

    def __init__(self, params: dict | None = None):
        params = params or {}
        self.time_offset = float(EFFECTS['time_offset'].value(params)[0])
        self.noise_scale = EFFECTS['camera_noise_anisotropy'].value(params)

    def epoch(self, stamp):
        """IMU-clock time of the attitude in a fix stamped ``stamp`` (compensation)."""
        return stamp - self.time_offset

    def covariance(self, P: np.ndarray) -> np.ndarray:
        """The covariance a fix really has, given the one it reports (compensation)."""
        return EFFECTS['camera_noise_anisotropy'].fix_covariance(np.asarray(P, dtype=float), self.noise_scale)
