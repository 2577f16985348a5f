"""
Covariance models of the gyro errors, selected by the ``covariance_model`` parameter.

The one registry behind the ``covariance_model`` parameter of ``sins_node`` and
``calibrator_node``.

Both models describe the same error effects of :mod:`strapdown_ros.sensors.effects` with the
statistics of :class:`~strapdown_ros.sensors.model.SensorSigmas`; they differ in what is a
random *constant* (common to all increments) and what is *white*:

``random_constant`` (default)
    bias, scale factor and misalignment are random constants x = [b, vec M] (column-major
    vec M: diagonal = scale factors, off-diagonal = misalignments), as in the sensor and the
    simulator; only the random walk (and quantization) is white.
``004``
    exactly Vasilyuk et al. (2024, 004) §2.1: every term white from one increment to the next,
    ``P_ρk = Σ_e σ_e² D_e D_eᵀ + σ_w² T I`` with D_e the effect's increment Jacobian, which is
    004's printed ``σ_φ² diag(ρy²+ρz², …) + σ_k² diag(ρx², …) + (σ_b T)² I + σ_w² T I``
    (``test/sensors/test_effects.py`` checks the identity against
    :func:`~strapdown_ros.sensors.model.increment_covariance`).

Every consumer (the attitude integrator, ``boresight_increments.gyro_increment``, the calibrator's
weighting) asks the model object, never the model's name.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from strapdown_ros.sensors.effects import EFFECTS
from strapdown_ros.sensors.gyro_effects import MISALIGNMENT_INDEX
from strapdown_ros.sensors.model import SensorSigmas

__all__ = ['CovarianceModel', 'COVARIANCE_MODELS', 'get_covariance_model', 'constant_jacobian',
           'constant_jacobian_basis', 'constant_variances']


def constant_jacobian(rho: np.ndarray, T: np.ndarray) -> np.ndarray:
    """
    Return ∂ρ̃_k/∂x for the gyro constants x = [b (3), vec M (9, column-major)].

    Assembled from the effects' own increment Jacobians (bias, scale factor, misalignment).

    Parameters
    ----------
    rho : (n, 3) ndarray
        Increments, rad.
    T : float or (n,) ndarray
        Interval lengths, s.

    Returns
    -------
    (n, 3, 12) ndarray
        The Jacobian.

    """
    rho = np.asarray(rho, dtype=float).reshape(-1, 3)
    T = np.broadcast_to(np.asarray(T, dtype=float), (len(rho),))
    t = np.zeros(len(rho))
    out = np.zeros((len(rho), 3, 12))
    out[:, :, :3] = EFFECTS['gyro_bias'].increment_jacobian(rho, T, t)
    scale = EFFECTS['gyro_scale_factor'].increment_jacobian(rho, T, t)
    mis = EFFECTS['gyro_misalignment'].increment_jacobian(rho, T, t)
    for i in range(3):
        out[:, :, 3 + 4 * i] = scale[:, :, i]                 # M_ii at 3 + i + 3i
    for c, (i, j) in enumerate(MISALIGNMENT_INDEX):
        out[:, :, 3 + i + 3 * j] = mis[:, :, c]               # M_ij at 3 + i + 3j (column-major)
    return out


@lru_cache(maxsize=1)
def constant_jacobian_basis() -> np.ndarray:
    """
    Return the basis E of :func:`constant_jacobian`: ``J(u, T) = Σ_i u_i E_i + T E_3``.

    Read off :func:`constant_jacobian` itself (the effects' own Jacobians stay the one home of
    the model), which must be linear in (u, T): checked here on random increments.  The
    compiled block kernel (:mod:`strapdown_ros.attitude.kernel`) and the navigation covariance
    contract with it instead of forming the (n, 3, 12) Jacobians.

    Returns
    -------
    (4, 3, 12) ndarray
        E, read-only.

    Raises
    ------
    RuntimeError
        When :func:`constant_jacobian` is not linear in (u, T).

    """
    unit = constant_jacobian(np.eye(3), np.zeros(3))              # (3, 3, 12): u = e_i
    per_t = constant_jacobian(np.zeros((1, 3)), np.ones(1))[0]    # (3, 12): T = 1
    rng = np.random.default_rng(0)
    u, t = rng.normal(size=(4, 3)), rng.uniform(0.1, 1.0, 4)
    linear = np.einsum('ki,iab->kab', u, unit) + t[:, None, None] * per_t
    if not np.allclose(constant_jacobian(u, t), linear, rtol=1e-12, atol=1e-15):
        raise RuntimeError('constant_jacobian is not linear in (u, T); its basis does not exist')
    out = np.concatenate([unit, per_t[None]], axis=0)
    out.setflags(write=False)
    return out


def constant_variances(g: SensorSigmas) -> np.ndarray:
    """
    Return the prior variances of x = [b, vec M] from the sensor statistics.

    Parameters
    ----------
    g : SensorSigmas
        Gyro statistics.

    Returns
    -------
    (12,) ndarray
        Variances (all independent): bias (rad/s)², then vec M (column-major).

    """
    v = np.full(12, g.misalignment_sigma ** 2)
    v[:3] = g.bias_sigma ** 2
    v[3 + np.array([0, 4, 8])] = g.scale_sigma ** 2
    return v


class CovarianceModel:
    """Base class: which gyro errors are random constants and which are white."""

    name = ''
    description = ''
    #: the gyro constants are random constants common to all increments
    constants = False
    #: the white part is (white_variance) × I whatever the increment (no rotation to reference
    #: axes), with white_variance proportional to the interval T (the compiled kernel takes its
    #: value at T = 1)
    isotropic_white = False

    def white(self, rho: np.ndarray, T, g: SensorSigmas) -> np.ndarray:
        """
        Return the covariance of the part of each increment's error that is white.

        Parameters
        ----------
        rho : (n, 3) ndarray
            Increments, rad.
        T : float or (n,) ndarray
            Interval lengths, s.
        g : SensorSigmas
            Gyro statistics.

        Returns
        -------
        (n, 3, 3) ndarray
            Covariances, rad².

        """
        raise NotImplementedError

    def constant_variances(self, g: SensorSigmas) -> np.ndarray:
        """
        Return the prior variances of x = [b, vec M] treated as random constants.

        Parameters
        ----------
        g : SensorSigmas
            Gyro statistics.

        Returns
        -------
        (12,) ndarray
            Variances (zeros: no random constants in this model).

        """
        return constant_variances(g) if self.constants else np.zeros(12)


class RandomConstant(CovarianceModel):
    """Bias, scale factor and misalignment random constants; only the random walk white."""

    name = 'random_constant'
    description = 'bias, scale factor, misalignment random constants; random walk white'
    constants = True
    isotropic_white = True

    def white(self, rho, T, g):
        """
        Return the random-walk covariance σ_w² T I.

        Parameters
        ----------
        rho : (n, 3) ndarray
            Increments, rad.
        T : float or (n,) ndarray
            Interval lengths, s.
        g : SensorSigmas
            Gyro statistics.

        Returns
        -------
        (n, 3, 3) ndarray
            Covariances, rad².

        """
        T = np.broadcast_to(np.asarray(T, dtype=float), (len(np.atleast_2d(rho)),))
        return (g.random_walk ** 2 * T)[:, None, None] * np.eye(3)

    def white_variance(self, T, g):
        """
        Return the per-axis variance of the white part over intervals T: random walk² · T.

        Parameters
        ----------
        T : float or ndarray
            Interval lengths, s.
        g : SensorSigmas
            Gyro statistics.

        Returns
        -------
        float or ndarray
            Variance, rad².

        """
        return g.random_walk ** 2 * np.asarray(T, dtype=float)


class White004(CovarianceModel):
    """004 §2.1: every error term white between increments."""

    name = '004'
    description = '004 §2.1: every term white between increments'

    def white(self, rho, T, g):
        """
        Return ``Σ_e σ_e² D_e D_eᵀ + σ_w² T I``, D_e the effects' increment Jacobians.

        Parameters
        ----------
        rho : (n, 3) ndarray
            Increments, rad.
        T : float or (n,) ndarray
            Interval lengths, s.
        g : SensorSigmas
            Gyro statistics.

        Returns
        -------
        (n, 3, 3) ndarray
            Covariances, rad².

        """
        rho = np.asarray(rho, dtype=float).reshape(-1, 3)
        T = np.broadcast_to(np.asarray(T, dtype=float), (len(rho),))
        t = np.zeros(len(rho))
        out = (g.random_walk ** 2 * T)[:, None, None] * np.eye(3)
        for e in EFFECTS.values():
            s = getattr(g, e.statistic) if e.statistic else 0.0
            if s > 0:
                D = e.increment_jacobian(rho, T, t)
                out = out + s ** 2 * (D @ np.swapaxes(D, 1, 2))
        return out


#: the registry of covariance models, by the name the ``covariance_model`` parameter takes
COVARIANCE_MODELS: dict[str, CovarianceModel] = {m.name: m for m in (RandomConstant(), White004())}


def get_covariance_model(name: str) -> CovarianceModel:
    """
    Return the covariance model of a name.

    Parameters
    ----------
    name : str
        A key of :data:`COVARIANCE_MODELS`.

    Returns
    -------
    CovarianceModel
        The model.

    Raises
    ------
    ValueError
        For an unknown name, listing the valid ones.

    """
    try:
        return COVARIANCE_MODELS[name]
    except KeyError:
        valid = ', '.join(COVARIANCE_MODELS)
        raise ValueError(f'unknown covariance_model {name!r}; valid: {valid}') from None
