"""
The base of the error-effect registry: what every effect declares and the hooks it may fill.

:mod:`strapdown_ros.sensors.effects` holds the effects themselves and the registry
:data:`~strapdown_ros.sensors.effects.EFFECTS`; this module holds their common parts (the
parameter record, the base class with its default hooks, the physical bounds of the values).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ['EffectParameter', 'Effect', 'PARTIAL_FEATURES', 'partial_features', 'linear_partials',
           'MAX_BIAS_RATE', 'MAX_BIAS_DRIFT', 'MAX_RELATIVE_ERROR',
           'MAX_MISALIGNMENT', 'MAX_RANDOM_WALK', 'MAX_QUANTUM', 'MAX_CAMERA_NOISE_SCALE',
           'MAX_G_SENSITIVITY']


@dataclass(frozen=True)
class EffectParameter:
    """
    One ROS parameter of an effect (SI units).

    Attributes
    ----------
    name : str
        ROS parameter name.
    unit : str
        Unit of each element.
    size : int
        1 for a double, n > 1 for a double[n].
    default : float or list of float
        Default value (the neutral value of the effect).
    description : str
        Parameter description shown by the nodes.
    minimum, maximum : float or None
        Valid range of each element.
    exclusive_minimum : bool
        The minimum itself is not valid.

    """

    name: str
    unit: str
    size: int
    default: object
    description: str
    minimum: float | None = None
    maximum: float | None = None
    exclusive_minimum: bool = False

    def check(self, value) -> str | None:
        """
        Return a one-line error for a value outside this parameter's type or range, else None.

        Parameters
        ----------
        value : object
            The value (a string parameter takes a string; a number or a list of ``size``
            numbers otherwise).

        Returns
        -------
        str or None
            The error, naming the parameter, the value and the valid values.

        """
        if isinstance(self.default, str):
            return None if isinstance(value, str) else \
                f'{self.name} must be a string, got {str(value)[:80]!r}'
        if isinstance(self.default, bool):
            return None if isinstance(value, bool) else \
                f'{self.name} must be true or false, got {str(value)[:80]!r}'
        try:
            v = np.asarray(value, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            return f'{self.name} must be {self._shape_text()}, got {str(value)[:80]!r}'
        if v.shape != (self.size,) or not np.all(np.isfinite(v)):
            return f'{self.name} must be {self._shape_text()}, got {str(value)[:80]!r}'
        lo, hi = self.minimum, self.maximum
        bad = (lo is not None and (np.any(v < lo) or (self.exclusive_minimum and np.any(v <= lo)))
               ) or (hi is not None and np.any(v > hi))
        if bad:
            return f'{self.name}={_text(value)} is out of range; valid: {self.range_text()}'
        return None

    def range_text(self) -> str:
        """Return the valid values in words, e.g. ``>= 0 and <= 0.1``."""
        parts = []
        if self.minimum is not None:
            parts.append(('> ' if self.exclusive_minimum else '>= ') + f'{self.minimum:g}')
        if self.maximum is not None:
            parts.append(f'<= {self.maximum:g}')
        return ' and '.join(parts) or 'any'

    def _shape_text(self) -> str:
        return 'a finite number' if self.size == 1 else f'a list of {self.size} finite numbers'


def _text(value) -> str:
    if isinstance(value, (list, tuple, np.ndarray)):
        return '[' + ', '.join(f'{float(x):.6g}' for x in np.ravel(value)) + ']'
    return f'{float(value):.6g}'


# physical bounds of the effect parameters (each element): a rate beyond 100 rad/s is no bias, a
# relative scale error beyond 0.5 and an axis misalignment beyond 0.5 rad are no small error,
# and values beyond overflow the squares of the error models
MAX_BIAS_RATE = 100.0            # rad/s
MAX_BIAS_DRIFT = 0.01            # rad/s² (100 rad/s after 3 h)
MAX_RELATIVE_ERROR = 0.5         # scale factor, scale asymmetry
MAX_MISALIGNMENT = 0.5           # rad
MAX_RANDOM_WALK = 1.0            # rad/√s
MAX_QUANTUM = 0.1                # rad
# a star-tracker σ stated for a motion-capture reference is ~10⁴ too small: simulable, and the
# discrepancy fit of the term reports such a scale as at its bound
MAX_CAMERA_NOISE_SCALE = 1e6
# rad/s per m/s²: 0.1 rad/s at 10 m/s², far beyond any real gyro (~1e-6)
MAX_G_SENSITIVITY = 1e-2


class Effect:
    """
    Base class of the registry's effects: declarations and default (empty) hooks.

    Class attributes declare the effect: ``sensor`` ('gyro' or 'camera'); ``kind``:
    'systematic' (changes the mean of the gyro increments as a function of the increment and
    time, has a signature and usually a compensation), 'coupled' (changes the mean of the gyro
    increments as a function of the accelerometer's velocity increments over the same interval)
    or 'noise' (changes the covariance); ``candidate``: searched for by the discrepancy
    workflow (other effects can be simulated and compensated but are outside the library it
    names).
    """

    name: str = ''
    sensor: str = 'gyro'
    kind: str = 'systematic'
    candidate: bool = True
    compensable: bool = True
    parameters: tuple[EffectParameter, ...] = ()
    #: model key of the 1σ of the value (one σ for every component): the uncertainty of the
    #: stated value, and the prior an estimator starts from (the filter state of an effect it
    #: estimates online, ``augment``).  None: the effect has no σ (the noise terms).
    sigma_parameter: str | None = None
    #: default of the σ key, in the value's unit
    prior_sigma: float = 0.0
    #: largest valid σ (None: the largest |value| of the value parameter's range)
    sigma_maximum: float | None = None
    #: the σ is that of a random constant: the simulators draw value + σ·N(0, 1) per
    #: component, and the discrepancy fit counts it as prior noise of the increment pairs
    random_constant: bool = False
    #: largest |value| the linearised discrepancy workflow reports as a small correction
    #: (None: the value parameter's range); a larger fit is a wiring fault or a wrong unit
    plausible_max: float | None = None
    #: the attitude filter can estimate it online (a name of its ``augment`` parameter)
    filter_state: bool = False
    #: the field of :class:`~strapdown_ros.sensors.model.SensorSigmas` holding its σ, for the
    #: random constants of the sensor statistics (bias, scale factor, misalignment)
    statistic: str | None = None
    #: changes the mean of the residuals (systematic effects, and quantization's lag)
    has_mean: bool = True
    #: the zero-effect value of the estimated parameters (1 for multiplicative noise scales)
    neutral: float = 0.0
    summary: str = ''
    signature_text: str = ''
    #: name of the filter parameter giving the white-noise density that drives the filter
    #: states of this effect as a random walk (None: a random constant, no process noise)
    filter_noise_parameter: str | None = None
    #: name of the filter parameter giving the correlation time of a Gauss–Markov state
    #: (None or 0: no decay)
    filter_correlation_parameter: str | None = None

    @property
    def needs_delta_v(self) -> bool:
        """Tell whether the effect acts through the accelerometer's velocity increments."""
        return self.kind == 'coupled'

    @property
    def value_parameter(self) -> EffectParameter:
        """Return the parameter the workflow estimates and writes to the model."""
        return self.parameters[0]

    @property
    def sigma_spec(self) -> EffectParameter | None:
        """Return the model key of the value's 1σ (None: the effect has none)."""
        if self.sigma_parameter is None:
            return None
        p = self.value_parameter
        hi = self.sigma_maximum
        if hi is None:
            hi = max(abs(p.minimum or 0.0), abs(p.maximum or 0.0)) or None
        return EffectParameter(self.sigma_parameter, p.unit, 1, float(self.prior_sigma),
                               f'1σ of {p.name} (each component), {p.unit}: the uncertainty '
                               'of the stated value and the prior of an online estimate',
                               0.0, hi)

    def model_parameters(self) -> tuple[EffectParameter, ...]:
        """
        Return every model-file key of the effect: its parameters, then its σ.

        Returns
        -------
        tuple of EffectParameter
            The keys, the value parameter first.

        """
        sigma = self.sigma_spec
        return self.parameters + ((sigma,) if sigma is not None else ())

    def sigma(self, params) -> float:
        """
        Return the 1σ of the value stated in a model.

        Parameters
        ----------
        params : mapping or SensorModel
            Anything with ``get(name, default)``: model key → value.

        Returns
        -------
        float
            The σ (0 for an effect without one).

        """
        spec = self.sigma_spec
        return 0.0 if spec is None else float(params.get(spec.name, spec.default))

    def plausible_bound(self) -> float | None:
        """Return the largest |value| reported as a small correction (None: no bound)."""
        if self.plausible_max is not None:
            return float(self.plausible_max)
        return None

    @property
    def size(self) -> int:
        """Return the number of elements of the value parameter."""
        return self.value_parameter.size

    def labels(self) -> list[str]:
        """
        Return the labels of the value parameter's elements.

        Returns
        -------
        list of str
            ``name`` for a scalar, ``name[i]`` per element otherwise.

        """
        p = self.value_parameter
        if p.size == 1:
            return [p.name]
        return [f'{p.name}[{i}]' for i in range(p.size)]

    def value(self, params: dict) -> np.ndarray:
        """
        Return the value vector of this effect from a parameter dict.

        Parameters
        ----------
        params : mapping or SensorModel
            Anything with ``get(name, default)``: model key → value; the default is used where
            the name is absent.

        Returns
        -------
        (size,) ndarray
            The value, SI units.

        """
        p = self.value_parameter
        v = params.get(p.name, p.default)
        return np.asarray(v, dtype=float).reshape(p.size)

    def is_active(self, params: dict) -> bool:
        """
        Tell whether the parameters give the effect a non-neutral value.

        Parameters
        ----------
        params : mapping or SensorModel
            Anything with ``get(name, default)``: model key → value.

        Returns
        -------
        bool
            True when any element differs from :attr:`neutral`.

        """
        return bool(np.any(self.value(params) != self.neutral))

    def configured(self, params) -> Effect:
        """
        Return the effect set up by its other parameters (most effects have none: itself).

        Parameters
        ----------
        params : mapping or SensorModel
            Anything with ``get(name, default)``: model key → value.

        Returns
        -------
        Effect
            The effect to apply.

        """
        return self

    # gyro systematic effects override these -------------------------------------------
    def direct_check(self, delta_theta: np.ndarray, theta: np.ndarray) -> str | None:
        """
        Test the effect on the raw measured increments, independently of the residuals.

        Parameters
        ----------
        delta_theta : (n, 3) ndarray
            Measured gyro increments, rad.
        theta : ndarray or None
            Estimated value of the effect.

        Returns
        -------
        str or None
            None when the data are consistent with the effect (or there is no such test),
            else the reason.

        """
        return None

    def fit_basis(self) -> np.ndarray | None:
        """
        Return the map from the separable combinations to the parameters.

        Returns
        -------
        (size, q) ndarray or None
            Map from the q combinations the residuals can separate to the parameters, or
            None when all are separable.

        """
        return None

    def matrix_term(self, theta: np.ndarray, sign: np.ndarray) -> np.ndarray | None:
        """
        Return the contribution to K − I of the gyro measurement equation.

        Parameters
        ----------
        theta : (size,) ndarray
            Value of the effect.
        sign : (n, 3) ndarray
            Signs of the increments.

        Returns
        -------
        (n, 3, 3) ndarray or None
            The contribution, or None when the effect has none.

        """
        return None

    def bias_term(self, theta: np.ndarray, t: np.ndarray) -> np.ndarray | None:
        """
        Return the contribution to the rate bias of the gyro measurement equation.

        Parameters
        ----------
        theta : (size,) ndarray
            Value of the effect.
        t : (n,) ndarray
            Times since the effect epoch, s.

        Returns
        -------
        (n, 3) ndarray or None
            Rate bias, rad/s, body axes, or None when the effect has none.

        """
        return None

    def delta_v_term(self, theta: np.ndarray, delta_v: np.ndarray) -> np.ndarray | None:
        """
        Return the contribution of a coupled effect to the gyro increments.

        Parameters
        ----------
        theta : (size,) ndarray
            Value of the effect.
        delta_v : (n, 3) ndarray
            Velocity increments ∫f dt over the gyro intervals, m/s, body axes.

        Returns
        -------
        (n, 3) ndarray or None
            Increment error, rad, or None when the effect has none.

        """
        return None

    def increment_jacobian(self, rho: np.ndarray, T: np.ndarray, t: np.ndarray) -> np.ndarray:
        """
        Return the signature ∂ρ̃/∂θ at θ = 0.

        Parameters
        ----------
        rho : (n, 3) ndarray
            True increments, rad.
        T : (n,) ndarray
            Interval lengths, s.
        t : (n,) ndarray
            Interval mid-times since the effect epoch, s.

        Returns
        -------
        (n, 3, size) ndarray
            The derivative of the measured increments with respect to the effect's value.

        """
        raise NotImplementedError

    def filter_size(self) -> int:
        """
        Return the number of filter states of the effect.

        Returns
        -------
        int
            The separable combinations (:meth:`fit_basis`), else :attr:`size`.

        """
        S = self.fit_basis()
        return self.size if S is None else S.shape[1]

    def filter_values(self, states: np.ndarray) -> np.ndarray:
        """
        Return the effect's parameter vector from its filter states.

        Parameters
        ----------
        states : (filter_size,) ndarray
            Filter states.

        Returns
        -------
        (size,) ndarray
            The effect's value.

        """
        S = self.fit_basis()
        states = np.asarray(states, dtype=float).reshape(self.filter_size())
        return states if S is None else S @ states

    def filter_partials(self, rho: np.ndarray, T: np.ndarray, t: np.ndarray) -> np.ndarray:
        """
        Return ∂ρ̃/∂c of the increments with respect to the filter states c.

        :meth:`increment_jacobian` mapped through :meth:`fit_basis`.

        Parameters
        ----------
        rho : (n, 3) ndarray
            Increments, rad.
        T : (n,) ndarray
            Interval lengths, s.
        t : (n,) ndarray
            Times since the effect epoch, s.

        Returns
        -------
        (n, 3, filter_size) ndarray
            The partial derivatives.

        """
        J = self.increment_jacobian(np.asarray(rho, dtype=float).reshape(-1, 3),
                                    np.asarray(T, dtype=float).reshape(-1),
                                    np.asarray(t, dtype=float).reshape(-1))
        S = self.fit_basis()
        return J if S is None else J @ S

    def filter_correlation_time(self, noise: dict | None = None) -> np.ndarray:
        """
        Return the correlation time of the filter states.

        ``noise[filter_correlation_parameter]`` makes the states first-order Gauss–Markov
        (driven by :meth:`filter_process_noise`, steady σ² = density·τ/2: a bias instability).

        Parameters
        ----------
        noise : dict or None
            Filter noise parameters.

        Returns
        -------
        (filter_size,) ndarray
            Correlation time, s; inf (a random walk, or a random constant without noise) when
            not given or 0.

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
        Return the white-noise density driving the filter states.

        Parameters
        ----------
        noise : dict or None
            Filter noise parameters.

        Returns
        -------
        (filter_size,) ndarray
            ``noise[filter_noise_parameter]²`` per state; 0 (random constant) when the effect
            has no such parameter or the dict does not give it.

        """
        value = 0.0
        if self.filter_noise_parameter is not None and noise:
            value = float(noise.get(self.filter_noise_parameter, 0.0))
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f'{self.filter_noise_parameter} must be finite and >= 0')
        return np.full(self.filter_size(), value ** 2)

    def __repr__(self):
        return f'<effect {self.name}>'


#: the per-increment quantities u the filter partials of the registry's systematic gyro effects
#: are linear in (:func:`linear_partials`): ρ (3), |ρ| (3), T and T·t
PARTIAL_FEATURES = ('rho_x', 'rho_y', 'rho_z', 'abs_rho_x', 'abs_rho_y', 'abs_rho_z', 'T', 'T_t')


def partial_features(rho: np.ndarray, T: np.ndarray, t: np.ndarray) -> np.ndarray:
    """
    Return the features u of :data:`PARTIAL_FEATURES` of each increment.

    Parameters
    ----------
    rho : (n, 3) ndarray
        Increments, rad.
    T : (n,) ndarray
        Interval lengths, s.
    t : (n,) ndarray
        Times since the effect epoch, s.

    Returns
    -------
    (n, 8) ndarray
        ``[ρ, |ρ|, T, T·t]`` per increment.

    """
    rho = np.asarray(rho, dtype=float).reshape(-1, 3)
    T = np.asarray(T, dtype=float).reshape(-1, 1)
    t = np.asarray(t, dtype=float).reshape(-1, 1)
    return np.hstack([rho, np.abs(rho), T, T * t])


def linear_partials(effects) -> np.ndarray | None:
    """
    Return the constant B with ``Σ_f u_f B_f`` = the effects' filter partials, side by side.

    ``u`` are the :func:`partial_features` of an increment.  Each effect's
    :meth:`Effect.filter_partials` stays the one definition: B is read from it at probe
    increments (ρ = ±e_j, T = 1 with t = 0 and t = 1) and the expansion is checked against
    it at random increments; an effect whose partials are not such a combination gives None
    (its caller evaluates the partials themselves).  One product then gives every effect's
    partials of many increments.

    Parameters
    ----------
    effects : sequence of Effect
        Systematic gyro effects.

    Returns
    -------
    (8, 3, Σ filter_size) ndarray or None
        B, the effects' columns in order; None when an effect is not linear in the features.

    """
    zero, eye = np.zeros(3), np.eye(3)
    probe_rho = np.vstack([eye, -eye, [zero, zero]])
    probe_T = np.array([0.0] * 6 + [1.0, 1.0])
    probe_t = np.array([0.0] * 7 + [1.0])
    rng = np.random.default_rng(0)
    test_rho = rng.standard_normal((16, 3)) * 0.01
    test_T = rng.uniform(1e-3, 0.1, 16)
    test_t = rng.uniform(0.0, 1e4, 16)
    u = partial_features(test_rho, test_T, test_t)
    parts = []
    for e in effects:
        P = np.asarray(e.filter_partials(probe_rho, probe_T, probe_t), dtype=float)
        B = np.concatenate([0.5 * (P[:3] - P[3:6]), 0.5 * (P[:3] + P[3:6]), P[6:7],
                            P[7:8] - P[6:7]])
        want = np.asarray(e.filter_partials(test_rho, test_T, test_t), dtype=float)
        got = np.einsum('nf,fij->nij', u, B)
        scale = np.max(np.abs(want), axis=0, initial=0.0) + 1e-300
        if want.shape != got.shape or not np.all(np.abs(got - want) <= 1e-12 * scale):
            return None
        parts.append(B)
    if not parts:
        return np.zeros((len(PARTIAL_FEATURES), 3, 0))
    return np.concatenate(parts, axis=2)
