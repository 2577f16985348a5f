"""
The gyro effects of the registry: systematic, coupled (driven by the specific force) and noise.

Each class owns one effect end to end (parameters, simulation, signature, compensation); the
registry :data:`~strapdown_ros.sensors.effects.EFFECTS` lists them with the camera effects, and
:class:`~strapdown_ros.sensors.effects.GyroEffects` applies or compensates the active ones
through the measurement equation of :mod:`strapdown_ros.sensors.effects`.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.sensors.effect_base import (Effect, EffectParameter, MAX_BIAS_DRIFT,
                                               MAX_BIAS_RATE, MAX_G_SENSITIVITY,
                                               MAX_MISALIGNMENT, MAX_QUANTUM, MAX_RANDOM_WALK,
                                               MAX_RELATIVE_ERROR)
from strapdown_ros.sensors.model import NAVIGATION_GRADE_GYRO

__all__ = ['MISALIGNMENT_INDEX', 'GyroBias', 'GyroBiasDrift', 'GyroBiasPeriodic',
           'GyroScaleFactor', 'GyroScaleAsymmetry', 'GyroMisalignment', 'GyroGSensitivity',
           'GyroRandomWalk', 'GyroQuantization']


#: order of the 6 off-diagonal elements of the gyro misalignment matrix M (row, column):
#: ρ̃_i = ρ_i + Σ_j M_ij ρ_j, i ≠ j
MISALIGNMENT_INDEX = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))


def _diagonal(values: np.ndarray) -> np.ndarray:
    """(n, 3) → (n, 3, 3) with the rows of ``values`` on the diagonals."""
    out = np.zeros((len(values), 3, 3))
    idx = np.arange(3)
    out[:, idx, idx] = values
    return out


# ----------------------------------------------------------------------------- gyro, systematic
class GyroBias(Effect):
    """Constant rate bias b, body axes, rad/s."""

    name = 'gyro_bias'
    parameters = (EffectParameter('gyro_bias', 'rad/s', 3, [0.0, 0.0, 0.0],
                                  'known constant gyro bias b, body axes, rad/s (simulated and '
                                  'compensated)',
                                  -MAX_BIAS_RATE, MAX_BIAS_RATE),
                  EffectParameter('gyro_bias_random_walk', 'rad/s/√s', 1, 0.0,
                                  'bias random walk σ_u (rate random walk) of the attitude '
                                  'filter, rad/s/√s (0: a random constant)', 0.0, 1.0),
                  EffectParameter('gyro_bias_correlation_time', 's', 1, 0.0,
                                  'τ > 0: the bias is first-order Gauss–Markov (bias '
                                  'instability) driven by gyro_bias_random_walk, s (0: a random '
                                  'walk)', 0.0, 1e9))
    sigma_parameter = 'gyro_bias_sigma'
    statistic = 'bias_sigma'
    prior_sigma = NAVIGATION_GRADE_GYRO.bias_sigma
    sigma_maximum = MAX_BIAS_RATE
    random_constant = True
    filter_state = True
    #: bias random walk (rate random walk) σ_u, rad/s/√s, of the attitude filter
    filter_noise_parameter = 'gyro_bias_random_walk'
    #: bias instability as a first-order Gauss–Markov bias with this correlation time, s
    filter_correlation_parameter = 'gyro_bias_correlation_time'
    summary = 'constant rate bias'
    signature_text = 'ε grows with the pair duration: Σ C_k T_k b'

    def bias_term(self, theta, t):
        """
        Return the constant bias at every time.

        Parameters
        ----------
        theta : (3,) ndarray
            Bias, rad/s.
        t : (n,) ndarray
            Times since the effect epoch, s.

        Returns
        -------
        (n, 3) ndarray
            Rate bias, rad/s.

        """
        return np.broadcast_to(theta, (len(t), 3))

    def increment_jacobian(self, rho, T, t):
        """
        Return ∂ρ̃/∂b = T·I.

        Parameters
        ----------
        rho : (n, 3) ndarray
            True increments, rad.
        T : (n,) ndarray
            Interval lengths, s.
        t : (n,) ndarray
            Times since the effect epoch, s.

        Returns
        -------
        (n, 3, 3) ndarray
            The signature.

        """
        return T[:, None, None] * np.eye(3)


class GyroBiasDrift(Effect):
    """Bias growing linearly with the time since the effect epoch, rad/s²."""

    name = 'gyro_bias_drift'
    parameters = (EffectParameter('gyro_bias_drift', 'rad/s²', 3, [0.0, 0.0, 0.0],
                                  'linear bias ramp d: bias b + d·(t − t0), t0 = first gyro '
                                  'stamp, rad/s²',
                                  -MAX_BIAS_DRIFT, MAX_BIAS_DRIFT),)
    sigma_parameter = 'gyro_bias_drift_sigma'
    prior_sigma = 1e-6
    filter_state = True
    summary = 'bias growing linearly with time'
    signature_text = 'as gyro_bias, weighted by the time since the first gyro stamp'

    def bias_term(self, theta, t):
        """
        Return the ramp d·t.

        Parameters
        ----------
        theta : (3,) ndarray
            Drift d, rad/s².
        t : (n,) ndarray
            Times since the effect epoch, s.

        Returns
        -------
        (n, 3) ndarray
            Rate bias, rad/s.

        """
        return np.asarray(t)[:, None] * theta

    def increment_jacobian(self, rho, T, t):
        """
        Return ∂ρ̃/∂d = T·t·I.

        Parameters
        ----------
        rho : (n, 3) ndarray
            True increments, rad.
        T : (n,) ndarray
            Interval lengths, s.
        t : (n,) ndarray
            Times since the effect epoch, s.

        Returns
        -------
        (n, 3, 3) ndarray
            The signature.

        """
        return (T * t)[:, None, None] * np.eye(3)


class GyroBiasPeriodic(Effect):
    """
    A bias oscillating with a known period.

    Simulated and compensated, but deliberately not in the workflow's library (its test case
    for 'unexplained structure').

    Parameters
    ----------
    period : float
        Period P, s.

    """

    name = 'gyro_bias_periodic'
    candidate = False
    parameters = (EffectParameter('gyro_bias_periodic', 'rad/s', 3, [0.0, 0.0, 0.0],
                                  'amplitude A of a periodic bias A·sin(2π(t − t0)/P), rad/s '
                                  '(outside the discrepancy library)',
                                  -MAX_BIAS_RATE, MAX_BIAS_RATE),
                  EffectParameter('gyro_bias_period', 's', 1, 600.0,
                                  'period P of gyro_bias_periodic, s',
                                  0.0, 1e7, exclusive_minimum=True))
    sigma_parameter = 'gyro_bias_periodic_sigma'
    prior_sigma = 1e-4
    filter_state = True
    summary = 'bias oscillating with period P'

    def __init__(self, period: float = 600.0):
        self.period = float(period)

    def configured(self, params) -> 'GyroBiasPeriodic':
        """
        Return the effect with the period the parameters give (``gyro_bias_period``).

        Parameters
        ----------
        params : mapping or SensorModel
            Anything with ``get(name, default)``: model key → value.

        Returns
        -------
        GyroBiasPeriodic
            The effect with that period.

        """
        return GyroBiasPeriodic(float(params.get('gyro_bias_period', self.parameters[1].default)))

    def bias_term(self, theta, t):
        """
        Return A·sin(2πt/P).

        Parameters
        ----------
        theta : (3,) ndarray
            Amplitude A, rad/s.
        t : (n,) ndarray
            Times since the effect epoch, s.

        Returns
        -------
        (n, 3) ndarray
            Rate bias, rad/s.

        """
        return np.sin(2.0 * np.pi * np.asarray(t) / self.period)[:, None] * theta

    def increment_jacobian(self, rho, T, t):
        """
        Return ∂ρ̃/∂A = T·sin(2πt/P)·I.

        Parameters
        ----------
        rho : (n, 3) ndarray
            True increments, rad.
        T : (n,) ndarray
            Interval lengths, s.
        t : (n,) ndarray
            Times since the effect epoch, s.

        Returns
        -------
        (n, 3, 3) ndarray
            The signature.

        """
        return (T * np.sin(2.0 * np.pi * t / self.period))[:, None, None] * np.eye(3)


class GyroScaleFactor(Effect):
    """Scale-factor errors s (relative), the diagonal of M."""

    name = 'gyro_scale_factor'
    parameters = (EffectParameter('gyro_scale_factor', '1', 3, [0.0, 0.0, 0.0],
                                  'known scale-factor errors s (relative), diagonal of M',
                                  -MAX_RELATIVE_ERROR, MAX_RELATIVE_ERROR),)
    sigma_parameter = 'gyro_scale_sigma'
    statistic = 'scale_sigma'
    prior_sigma = NAVIGATION_GRADE_GYRO.scale_sigma
    sigma_maximum = 0.1
    random_constant = True
    plausible_max = 0.1
    filter_state = True
    summary = 'scale-factor error, same for both rotation senses'
    signature_text = 'ε ∝ rotation about each gyro axis: Σ C_k diag(ρ_k) s'

    def matrix_term(self, theta, sign):
        """
        Return diag(s) for every increment.

        Parameters
        ----------
        theta : (3,) ndarray
            Scale-factor errors s.
        sign : (n, 3) ndarray
            Signs of the increments (unused).

        Returns
        -------
        (n, 3, 3) ndarray
            Contribution to K − I.

        """
        return np.broadcast_to(np.diag(theta), (len(sign), 3, 3))

    def increment_jacobian(self, rho, T, t):
        """
        Return ∂ρ̃/∂s = diag(ρ).

        Parameters
        ----------
        rho : (n, 3) ndarray
            True increments, rad.
        T : (n,) ndarray
            Interval lengths, s.
        t : (n,) ndarray
            Times since the effect epoch, s.

        Returns
        -------
        (n, 3, 3) ndarray
            The signature.

        """
        return _diagonal(rho)


class GyroScaleAsymmetry(Effect):
    """Scale asymmetry a: scale 1 + s + a for positive, 1 + s − a for negative rates."""

    name = 'gyro_scale_asymmetry'
    parameters = (EffectParameter('gyro_scale_asymmetry', '1', 3, [0.0, 0.0, 0.0],
                                  'scale asymmetry a: scale 1 + s + a for positive, 1 + s − a '
                                  'for negative rates',
                                  -MAX_RELATIVE_ERROR, MAX_RELATIVE_ERROR),)
    sigma_parameter = 'gyro_scale_asymmetry_sigma'
    prior_sigma = 1e-3
    sigma_maximum = 0.1
    plausible_max = 0.1
    filter_state = True
    summary = 'different scale factor for positive and negative rates'
    signature_text = ('ε ∝ |rotation| about each axis: Σ C_k diag(|ρ_k|) a (needs turns of '
                      'both senses to tell from scale)')

    def matrix_term(self, theta, sign):
        """
        Return diag(sign ρ · a) per increment.

        Parameters
        ----------
        theta : (3,) ndarray
            Asymmetry a.
        sign : (n, 3) ndarray
            Signs of the increments.

        Returns
        -------
        (n, 3, 3) ndarray
            Contribution to K − I.

        """
        return _diagonal(sign * theta)

    def increment_jacobian(self, rho, T, t):
        """
        Return ∂ρ̃/∂a = diag(|ρ|).

        Parameters
        ----------
        rho : (n, 3) ndarray
            True increments, rad.
        T : (n,) ndarray
            Interval lengths, s.
        t : (n,) ndarray
            Times since the effect epoch, s.

        Returns
        -------
        (n, 3, 3) ndarray
            The signature.

        """
        return _diagonal(np.abs(rho))


class GyroMisalignment(Effect):
    """Non-orthogonal gyro axes: the off-diagonal elements of M (:data:`MISALIGNMENT_INDEX`)."""

    name = 'gyro_misalignment'
    parameters = (EffectParameter('gyro_misalignment', 'rad', 6, [0.0] * 6,
                                  'known axis misalignments: off-diagonal M_xy, M_xz, M_yx, '
                                  'M_yz, M_zx, M_zy, rad',
                                  -MAX_MISALIGNMENT, MAX_MISALIGNMENT),)
    sigma_parameter = 'gyro_misalignment_sigma'
    statistic = 'misalignment_sigma'
    prior_sigma = NAVIGATION_GRADE_GYRO.misalignment_sigma
    sigma_maximum = 0.1
    random_constant = True
    plausible_max = 0.1
    filter_state = True
    summary = 'non-orthogonal gyro axes (off-diagonal M)'
    signature_text = ('ε ∝ cross-axis rotation: Σ C_k M ρ_k; the antisymmetric part of M is a '
                      'rotation of the whole triad, the same signature as a boresight change, '
                      'so only the symmetric part (non-orthogonality, 3 combinations) is '
                      'separable')

    def fit_basis(self):
        """
        Return the symmetric non-orthogonality basis: M_xy = M_yx, M_xz = M_zx, M_yz = M_zy.

        Returns
        -------
        (6, 3) ndarray
            Map from the three combinations to the six elements.

        """
        S = np.zeros((6, 3))
        for c, pair in enumerate(((0, 2), (1, 4), (3, 5))):
            S[list(pair), c] = 1.0
        return S

    def matrix_term(self, theta, sign):
        """
        Return M (off-diagonal) for every increment.

        Parameters
        ----------
        theta : (6,) ndarray
            Misalignments in :data:`MISALIGNMENT_INDEX` order, rad.
        sign : (n, 3) ndarray
            Signs of the increments (unused).

        Returns
        -------
        (n, 3, 3) ndarray
            Contribution to K − I.

        """
        M = np.zeros((3, 3))
        for v, (i, j) in zip(theta, MISALIGNMENT_INDEX):
            M[i, j] = v
        return np.broadcast_to(M, (len(sign), 3, 3))

    def increment_jacobian(self, rho, T, t):
        """
        Return ∂ρ̃_i/∂M_ij = ρ_j.

        Parameters
        ----------
        rho : (n, 3) ndarray
            True increments, rad.
        T : (n,) ndarray
            Interval lengths, s.
        t : (n,) ndarray
            Times since the effect epoch, s.

        Returns
        -------
        (n, 3, 6) ndarray
            The signature.

        """
        J = np.zeros((len(rho), 3, 6))
        for c, (i, j) in enumerate(MISALIGNMENT_INDEX):
            J[:, i, c] = rho[:, j]
        return J


# ----------------------------------------------------------------------------- gyro, coupled
class GyroGSensitivity(Effect):
    """
    G-sensitivity (g-dependent bias): a rate bias G·f proportional to the specific force f.

    Over a gyro interval the increment error is ``G·Δv``, Δv = ∫f dt over the *gyro*
    interval, G a 3×3 matrix (row-major in the parameter), rad/s per m/s².  The simulators
    integrate the exact specific force of the profile over each gyro interval, whatever the
    accelerometer rate; a consumer compensates it only when it has Δv over its gyro intervals
    (:class:`GyroEffects` with ``with_delta_v=True``).  Outside the discrepancy library (the
    workflow reads no accelerometer data) and not a state of the attitude filter.
    """

    name = 'gyro_g_sensitivity'
    kind = 'coupled'
    candidate = False
    parameters = (EffectParameter('gyro_g_sensitivity', 'rad/s/(m/s²)', 9, [0.0] * 9,
                                  'g-sensitivity G, row-major 3×3: rate bias G·f for the '
                                  'specific force f, body axes, rad/s per m/s²',
                                  -MAX_G_SENSITIVITY, MAX_G_SENSITIVITY),)
    sigma_parameter = 'gyro_g_sensitivity_sigma'
    prior_sigma = 1e-5
    summary = 'rate bias proportional to the specific force (g-dependent bias)'
    signature_text = 'ε = Σ C_k G Δv_k: follows the specific force, not the rotation'

    def delta_v_term(self, theta, delta_v):
        """
        Return G·Δv per increment.

        Parameters
        ----------
        theta : (9,) ndarray
            G, row-major, rad/s per m/s².
        delta_v : (n, 3) ndarray
            Velocity increments over the gyro intervals, m/s, body axes.

        Returns
        -------
        (n, 3) ndarray
            Increment error, rad.

        """
        return np.asarray(delta_v, dtype=float) @ np.reshape(theta, (3, 3)).T

    def delta_v_jacobian(self, delta_v: np.ndarray) -> np.ndarray:
        """
        Return the signature ∂ρ̃/∂G: ∂ρ̃_i/∂G_ij = Δv_j.

        Parameters
        ----------
        delta_v : (n, 3) ndarray
            Velocity increments over the gyro intervals, m/s, body axes.

        Returns
        -------
        (n, 3, 9) ndarray
            The signature, G row-major.

        """
        dv = np.asarray(delta_v, dtype=float).reshape(-1, 3)
        J = np.zeros((len(dv), 3, 9))
        for i in range(3):
            J[:, i, 3 * i:3 * i + 3] = dv
        return J


# ----------------------------------------------------------------------------- noise terms
class GyroRandomWalk(Effect):
    """White angle random walk: part of every nominal model, not searched for."""

    name = 'gyro_random_walk'
    kind = 'noise'
    has_mean = False
    candidate = False
    compensable = False
    parameters = (EffectParameter('gyro_random_walk', 'rad/√s', 1,
                                  NAVIGATION_GRADE_GYRO.random_walk,
                                  'white-noise random walk, rad/√s', 0.0, MAX_RANDOM_WALK),)
    summary = 'angle random walk (white rate noise)'


class GyroQuantization(Effect):
    """Pulse quantization with carried remainder (Tkachenko 1983, 000 §5), uncompensated."""

    name = 'gyro_quantization'
    kind = 'noise'
    compensable = False
    parameters = (EffectParameter('gyro_quantum', 'rad', 1, 0.0,
                                  'pulse weight σ of level quantization (0 = off), rad', 0.0,
                                  MAX_QUANTUM),)
    summary = 'pulse quantization with carried remainder (000 §5), uncompensated'
    signature_text = ('the output lags the integral by the carried remainder: a mean σ/2 in the '
                      'sense of the motion on each axis (000 §5.3), seen where a pair starts and '
                      'ends in different motion, and a variance σ²/12 per axis at each fix, with '
                      'the camera-fix correlation structure')

    @staticmethod
    def lattice_step(delta_theta: np.ndarray, tolerance: float = 0.01,
                     min_fraction: float = 0.9):
        """
        Return the pulse weight the increments are multiples of, per axis.

        The smallest non-zero |Δθ| (1st percentile) is accepted when at least
        ``min_fraction`` of the non-zero increments lie within ``tolerance`` of a multiple,
        then refined as the median of Δθ / round(Δθ / step).

        Parameters
        ----------
        delta_theta : (n, 3) ndarray
            Measured increments, rad.
        tolerance : float
            Accepted distance from a multiple, in steps.
        min_fraction : float
            Fraction of the non-zero increments that must lie on the lattice.

        Returns
        -------
        list of (float or None)
            Per axis, the step in rad, or None where the increments are not quantized.

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
        Check that the increments lie on a lattice whose step agrees with the estimate.

        Parameters
        ----------
        delta_theta : (n, 3) ndarray
            Measured increments, rad.
        theta : (1,) ndarray or None
            Estimated pulse weight, rad.

        Returns
        -------
        str or None
            None when the lattice exists and its step is within a factor 1.5 of the
            estimate, else the reason.

        """
        steps = [s for s in self.lattice_step(delta_theta) if s is not None]
        if not steps:
            return ('the measured increments are not multiples of a pulse weight '
                    '(no quantization lattice)')
        q = float(np.median(steps))
        if theta is None:
            return None
        if not (q / 1.5 <= float(theta[0]) <= 1.5 * q):
            return (f'the increments lie on a lattice of step {q:.3g} rad, '
                    f'not {float(theta[0]):.3g}')
        return None

    def fix_covariance(self, P: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """
        Add the remainder variance σ²/12 to per-fix covariances.

        Parameters
        ----------
        P : (n, 3, 3) ndarray
            Fix covariances, rad² (isotropic addition: the same in MF and VF axes).
        theta : (1,) ndarray
            Pulse weight σ, rad.

        Returns
        -------
        (n, 3, 3) ndarray
            The covariances with σ²/12 added on the diagonal.

        """
        return P + (float(theta[0]) ** 2 / 12.0) * np.eye(3)
