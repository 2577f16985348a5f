"""
The linearisation of the discrepancy workflow: residuals and columns at one model point.

A recording in the core's terms, the increment residuals at one model point (004 eq. 5–6)
with the columns of the boresight and of every effect, the whitening by the calibrator's
correlated covariance (:mod:`strapdown_ros.discrepancy.linear_model`), and the
maximum-likelihood fit of a noise term.  :mod:`strapdown_ros.discrepancy.workflow` runs the
selection on top of it; the workflow's errors are defined here.  No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from strapdown_ros.calibration.boresight import increment_residuals
from strapdown_ros.calibration.pairs import build_pairs, GyroRecord, pair_integral, PairSet
from strapdown_ros.discrepancy.linear_model import band_covariance, fit, Whitener
from strapdown_ros.rotation import quat_to_dcm, rotvec_to_dcm
from strapdown_ros.sensors.effects import EFFECTS, get_effect, GyroEffects

__all__ = ['Recording', 'InputError', 'AnalysisError', 'BoresightUnobservable',
           'NumericalFailure', 'NUMERICAL_ERRORS', 'Linearisation', 'NOISE_SCALE_RANGE',
           'QUANTUM_RANGE', 'noise_of', 'fit_noise', 'pairs_at']

#: range of a fitted camera-noise scale k (true σ ÷ stated σ per VF axis): an estimate at
#: either end is not reported as a value (the candidate fails with that reason)
NOISE_SCALE_RANGE = (1e-3, 1e3)
#: range of a fitted pulse weight σ_q, in units of √12 × the RMS stated fix σ (the remainder
#: variance σ_q²/12 from 0 to 900 times the mean stated fix variance)
QUANTUM_RANGE = (0.0, 30.0)


class InputError(ValueError):
    """The recording cannot be analysed (too few fixes, no overlap, ...)."""


class AnalysisError(Exception):
    """
    A usable recording whose analysis cannot be computed (a base fit failed numerically).

    Deliberately NOT a ValueError: a numerical failure is never reported as bad input.
    """


class BoresightUnobservable(Exception):
    """
    The recording's motion does not determine the boresight.

    004 §4.1 and the conditioning, the rule of
    :func:`strapdown_ros.calibration.boresight.check_observability`.

    Parameters
    ----------
    message : str
        What is unobservable, in words.
    report : ObservabilityReport, optional
        The report (:class:`strapdown_ros.estimation.observability.ObservabilityReport`), kept
        as ``report``.

    """

    def __init__(self, message: str, report=None):
        super().__init__(message)
        self.report = report


class NumericalFailure(ArithmeticError):
    """
    One fit failed numerically.

    A covariance not positive definite, a non-finite result, an estimate at the bound of its
    range.  Caught per candidate by the selection.
    """


#: the exceptions that mean "this fit cannot be computed", never "bad input"
NUMERICAL_ERRORS = (np.linalg.LinAlgError, FloatingPointError, NumericalFailure, OverflowError)


@dataclass
class Recording:
    """
    A recording in the core's terms: stamps in seconds from an origin (any), VF covariances.

    Parameters
    ----------
    gyro_stamps : (n,) array_like
        End of each increment's interval, s.
    delta_theta : (n, 3) array_like
        Gyro increments, rad, body (MF) axes.
    fix_stamps : (m,) array_like
        Camera stamps (camera clock), s.
    fix_q : (m, 4) array_like
        ``q_GCRS_VF``, scalar-first.
    fix_P : (m, 3, 3) array_like
        Reported (or assumed) covariance of each fix, VF axes, rad².
    gaps : list of (float, float)
        Gyro gaps (a, b), s.

    """

    gyro_stamps: np.ndarray
    delta_theta: np.ndarray
    fix_stamps: np.ndarray
    fix_q: np.ndarray
    fix_P: np.ndarray
    gaps: list = field(default_factory=list)

    def __post_init__(self):
        self.gyro_stamps = np.asarray(self.gyro_stamps, dtype=float)
        self.delta_theta = np.asarray(self.delta_theta, dtype=float).reshape(-1, 3)
        self.fix_stamps = np.asarray(self.fix_stamps, dtype=float)
        self.fix_q = np.asarray(self.fix_q, dtype=float).reshape(-1, 4)
        self.fix_P = np.asarray(self.fix_P, dtype=float).reshape(-1, 3, 3)


# ----------------------------------------------------------------------------- the linearisation
#: model points (gyro compensation, pairs, ε-signatures) kept per recording: a refit that moves
#: only the boresight, or returns to an earlier point, reuses them
_POINTS_KEPT = 3


class _ModelPoint:
    """
    What the linearisation at one model point holds that does not depend on the boresight.

    The compensated gyro record, the pairs, their increments as DCMs, the C-free parts of the
    time-offset and quantization columns, and the ε-signatures of the effects (computed when
    first asked for, several effects in one pass over the gyro record).
    """

    def __init__(self, rec: Recording, params: dict, epoch: float):
        st, m = rec.gyro_stamps, rec.delta_theta
        T = np.diff(st, prepend=st[0] - (st[1] - st[0]))
        self.effects = GyroEffects(params, epoch=epoch)
        self.gyro = GyroRecord(st, self.effects.compensate(m, st, T))
        self.time_offset = float(EFFECTS['time_offset'].value(params)[0])
        self.pairs = build_pairs(self.gyro, rec.fix_stamps, rec.fix_q, self.time_offset,
                                 rec.gaps)
        self.params = params
        self.eps: dict = {}
        if len(self.pairs) < 2:
            return
        self.R_cam = quat_to_dcm(self.pairs.dq_cam)
        self.R_imu = quat_to_dcm(self.pairs.dq_imu)
        w_s = self.gyro.rate_at(self.pairs.k_start)
        w_e = self.gyro.rate_at(self.pairs.k_end)
        self.rate_term = np.einsum('nji,nj->ni', self.R_imu, w_s) - w_e
        # quantization: the output lags the integral by the remainder, mean σ/2 in the sense of
        # the motion on each axis (000 §5.3): r_mean = σ/2 · Cᵀ(ΔS_imuᵀ s_s − s_e), s = soft
        # sign of the rate over ±0.5 s (0 where an axis is not driven past its random walk)
        w0 = max(3.0 * float(EFFECTS['gyro_random_walk'].value(params)[0]), 1e-7)
        s_s = np.tanh(self.gyro.rate_at(self.pairs.k_start, 0.5) / w0)
        s_e = np.tanh(self.gyro.rate_at(self.pairs.k_end, 0.5) / w0)
        self.quant_term = 0.5 * (np.einsum('nji,nj->ni', self.R_imu, s_s) - s_e)

    def epsilon(self, names, times) -> dict:
        """Return the ε-signatures of effects (MF axes at τ_e), those missing in one pass."""
        todo = [n for n in names if n not in self.eps]
        if todo:
            effects = [EFFECTS[n].configured(self.params) for n in todo]
            widths: list = []

            def jacobian(r_, T_, sl):
                t = times(sl)
                parts = [e.increment_jacobian(r_, T_, t) for e in effects]
                widths[:] = [d.shape[-1] for d in parts]
                return np.concatenate(parts, axis=2)
            eps = pair_integral(self.gyro, self.pairs, jacobian)
            k = 0
            for n, q in zip(todo, widths or [0] * len(todo)):
                self.eps[n] = eps[:, :, k:k + q]
                k += q
        return self.eps


def _model_point(rec: Recording, params: dict, epoch: float) -> _ModelPoint:
    """Return the model point of these parameters, from the recording's few kept ones."""
    key = (float(epoch),) + tuple(                  # every effect parameter (values, options)
        (k.name, repr(params.get(k.name, k.default))) for e in EFFECTS.values()
        for k in e.parameters)
    kept = rec.__dict__.setdefault('_points', {})
    if key not in kept:
        if len(kept) >= _POINTS_KEPT:
            kept.pop(next(iter(kept)))
        kept[key] = _ModelPoint(rec, params, epoch)
    return kept[key]


def pairs_at(rec: Recording, params: dict, epoch: float) -> PairSet:
    """
    Return the increment pairs of the model (its effects compensated), kept with the recording.

    Parameters
    ----------
    rec : Recording
        The recording.
    params : dict
        The model: effect values by ROS parameter name, SI units.
    epoch : float
        Origin of the effects' time, s.

    Returns
    -------
    PairSet
        The pairs (:func:`strapdown_ros.calibration.pairs.build_pairs`).

    """
    return _model_point(rec, params, epoch).pairs


class Linearisation:
    """
    Residuals and columns of the model at one point (parameter values + boresight C).

    Parameters
    ----------
    rec : Recording
        The recording.
    params : dict
        The model point: effect values by ROS parameter name, SI units.
    C : (3, 3) ndarray
        The boresight direction cosine matrix (MF from VF).
    epoch : float
        Origin of the effects' time, s.

    Raises
    ------
    InputError
        Fewer than two increment pairs at this point.

    """

    def __init__(self, rec: Recording, params: dict, C: np.ndarray, epoch: float):
        self.params, self.C = params, C
        base = _model_point(rec, params, epoch)       # what does not depend on C (cached)
        self.effects, self.gyro, self.time_offset = base.effects, base.gyro, base.time_offset
        self.pairs: PairSet = base.pairs
        if len(self.pairs) < 2:
            raise InputError(f'only {len(self.pairs)} increment pair(s): the gyro data must '
                             'cover consecutive camera fixes')
        self.epoch = epoch
        self.rec = rec
        self._base = base
        N = len(self.pairs)
        self.R_cam, self.R_imu = base.R_cam, base.R_imu
        self.f = increment_residuals(C, self.R_imu, self.R_cam)
        self.r = self.f.reshape(-1)
        # boresight correction δ: C → C exp([δ×]) (VF axes), central differences
        h = 1e-6
        cols = []
        for j in range(3):
            d = np.zeros(3)
            d[j] = h
            diff = (increment_residuals(C @ rotvec_to_dcm(d), self.R_imu, self.R_cam)
                    - increment_residuals(C @ rotvec_to_dcm(-d), self.R_imu, self.R_cam))
            cols.append(diff.reshape(-1) / (2 * h))
        self.col_boresight = np.array(cols).T
        # gyro-effect signatures ∂r/∂θ_model = −Cᵀ ε-signature: computed when first asked for
        self._sig = {}
        self._whiteners = {}            # whitening of the residual covariance by noise terms
        # time offset: ∂r/∂τ_model = Cᵀ (ΔSᵀ ω_s − ω_e)
        self._sig['time_offset'] = (base.rate_term @ C).reshape(3 * N, 1)
        # nominal random constants (prior) U
        # the random constants of the registry (bias, scale factor, misalignment): their σ
        prior = [e for e in EFFECTS.values() if e.random_constant and e.sensor == 'gyro']
        base.epsilon([e.name for e in prior], self._times)
        self.U = np.hstack([-self.signature(e.name) for e in prior])
        self.prior_var = np.concatenate([np.full(e.size, e.sigma(params) ** 2) for e in prior])
        self.random_walk = float(EFFECTS['gyro_random_walk'].value(params)[0])
        self.quant_col = (base.quant_term @ C).reshape(-1)

    def _times(self, sl):
        st = self.gyro.stamps
        return st[sl] - 0.5 * (st[sl] - st[sl - 1]) - self.epoch

    # ---- columns -----------------------------------------------------------------------
    def signature(self, name: str) -> np.ndarray:
        """
        Return ∂r/∂θ_model of a systematic effect's parameters.

        Parameters
        ----------
        name : str
            Effect name of the registry.

        Returns
        -------
        (3N, size) ndarray
            The columns, rad per parameter unit (computed once, then kept).

        """
        if name not in self._sig:
            eps = self._base.epsilon([name], self._times)[name]
            sig = -np.einsum('ji,njp->nip', self.C, eps)
            self._sig[name] = sig.reshape(3 * len(self.pairs), -1)
        return self._sig[name]

    def columns(self, name: str) -> np.ndarray:
        """
        Return ∂r/∂(fit combinations) of a systematic effect.

        Parameters
        ----------
        name : str
            Effect name of the registry.

        Returns
        -------
        (3N, q) ndarray
            The columns of its separable combinations (the effect's ``fit_basis``).

        """
        col = self.signature(name)
        S = get_effect(name).fit_basis()
        return col if S is None else col @ S

    def design(self, names) -> np.ndarray:
        """
        Return the design matrix: the boresight columns, then those of each effect.

        Parameters
        ----------
        names : list of str
            The free systematic effects, in order.

        Returns
        -------
        (3N, 3 + Σq) ndarray
            J.

        """
        return np.hstack([self.col_boresight] + [self.columns(n) for n in names])

    # ---- noise ---------------------------------------------------------------------------
    def fix_covariance(self, noise: dict) -> np.ndarray:
        """
        Return the fix covariances with the noise terms applied.

        Parameters
        ----------
        noise : dict
            Noise terms by effect name, their θ.

        Returns
        -------
        (m, 3, 3) ndarray
            Covariance of each fix, VF axes, rad².

        """
        P = self.rec.fix_P
        for name, theta in noise.items():
            P = EFFECTS[name].fix_covariance(P, np.asarray(theta, dtype=float))
        return P

    def whitener(self, noise: dict, mask=None) -> Whitener:
        """
        Return the whitening of the residual covariance B under the noise terms.

        Parameters
        ----------
        noise : dict
            Noise terms by effect name.
        mask : (N,) bool ndarray, optional
            The pairs kept (default: all).

        Returns
        -------
        Whitener
            The banded Cholesky factor of B.

        """
        key = _noise_key(noise)
        if mask is None and key in self._whiteners:
            return self._whiteners[key]
        pairs = self.pairs if mask is None else self.pairs.subset(mask)
        R = self.R_cam if mask is None else self.R_cam[mask]
        P = self.fix_covariance(noise)
        fixP = np.stack([P[pairs.fix_start], P[pairs.fix_end]], axis=1)
        white = (self.random_walk ** 2 * pairs.duration)[:, None, None] * np.eye(3)
        W = Whitener(band_covariance(fixP, R, pairs.adjacent, white))
        if mask is None:
            if len(self._whiteners) >= 4:                # a noise fit tries many: keep a few
                self._whiteners.pop(next(iter(self._whiteners)))
            self._whiteners[key] = W
        return W

    def rows(self, mask) -> np.ndarray:
        """
        Return the residual rows of the pairs in a mask.

        Parameters
        ----------
        mask : (N,) bool array_like
            The pairs.

        Returns
        -------
        (3N,) bool ndarray
            The three rows of each pair.

        """
        return np.repeat(np.asarray(mask, dtype=bool), 3)

    def residual(self, noise) -> np.ndarray:
        """
        Return the residual r less the mean of the noise terms (the quantization lag).

        Parameters
        ----------
        noise : dict
            Noise terms by effect name.

        Returns
        -------
        (3N,) ndarray
            Residual, rad.

        """
        q = noise.get('gyro_quantization')
        return self.r if q is None else self.r - float(q[0]) * self.quant_col

    def evaluate(self, free, noise, mask=None):
        """
        Fit the model with the free effects and noise terms (GLS, gyro constants marginalised).

        Parameters
        ----------
        free : list of str
            Free systematic effects (besides the boresight).
        noise : dict
            Noise terms by effect name.
        mask : (N,) bool ndarray, optional
            The pairs used (default: all).

        Returns
        -------
        Fit
            The fit (:func:`strapdown_ros.discrepancy.linear_model.fit`).

        """
        J = self.design(free)
        r = self.residual(noise)
        if mask is None:
            return fit(r, J, self.U, self.prior_var, self.whitener(noise))
        rows = self.rows(mask)
        return fit(r[rows], J[rows], self.U[rows], self.prior_var, self.whitener(noise, mask))


def _noise_key(noise: dict) -> tuple:
    return tuple((k, tuple(float(x) for x in np.atleast_1d(np.asarray(v, dtype=float))))
                 for k, v in sorted(noise.items()))


def noise_of(params: dict) -> dict:
    """
    Return the noise terms of the library a model states (quantization, camera-noise scale).

    The registry's noise effects that the workflow searches for (``candidate``), where their
    value is not neutral.

    Parameters
    ----------
    params : mapping or SensorModel
        The model, by model key.

    Returns
    -------
    dict
        ``{effect name: θ}``, only the terms that differ from neutral.

    """
    return {n: e.value(params).tolist() for n, e in EFFECTS.items()
            if e.kind == 'noise' and e.candidate and e.is_active(params)}


# ----------------------------------------------------------------------------- noise ML
def fit_noise(lin: Linearisation, free, noise: dict, name: str, mask=None):
    """
    Fit a noise term by maximum likelihood, the others fixed.

    Bounded parametrisations (the stated ranges :data:`NOISE_SCALE_RANGE`,
    :data:`QUANTUM_RANGE`): the camera-noise scales as u = log k, the pulse weight as
    σ_q = √(12·v̄)·u with v̄ the mean stated fix variance; bounded Nelder–Mead.  A trial point
    whose covariance is not positive definite counts as −2 log L = ∞.  An optimum at a bound of
    the range, or a fit that fails there, raises :class:`NumericalFailure`.  σ: from the
    curvature of −2 log L in θ (Fisher), ∞ where the curvature is not positive or not finite.

    Parameters
    ----------
    lin : Linearisation
        The linearisation at the current model point.
    free : list of str
        Free systematic effects.
    noise : dict
        The other noise terms.
    name : str
        The noise term fitted.
    mask : (N,) bool ndarray, optional
        The pairs used (default: all).

    Returns
    -------
    theta : ndarray
        The term's value.
    fit : Fit
        The fit at it.
    sigma : ndarray
        Its 1σ per component.

    Raises
    ------
    NumericalFailure
        No value gives a positive-definite covariance, or the optimum is at a bound.

    """
    from scipy.optimize import minimize

    e = EFFECTS[name]
    start = np.asarray(noise.get(name, [e.neutral] * e.size), dtype=float)
    if name == 'gyro_quantization':
        # parametrise by the remainder variance σ²/12 relative to the mean fix variance
        ref = float(np.mean(np.trace(lin.rec.fix_P, axis1=1, axis2=2)) / 3.0)
        unit = np.sqrt(12.0 * max(ref, 1e-300))
        lo, hi = QUANTUM_RANGE

        def theta_of(u):
            return np.array([unit * abs(u[0])])
        u0 = np.clip(np.array([max(start[0], 0.0) / unit + 0.3]), lo, hi)
    else:
        lo, hi = np.log(NOISE_SCALE_RANGE[0]), np.log(NOISE_SCALE_RANGE[1])

        def theta_of(u):
            return np.exp(np.clip(u, lo, hi))
        u0 = np.clip(np.log(np.maximum(start, NOISE_SCALE_RANGE[0])), lo, hi)
    bounds = [(lo, hi)] * len(u0)

    def nll(u):
        trial = dict(noise)
        trial[name] = theta_of(u).tolist()
        try:
            v = lin.evaluate(free, trial, mask).nll
        except NUMERICAL_ERRORS:
            return np.inf
        return v if np.isfinite(v) else np.inf
    best = None
    # −2 log L to 0.01 is ample for a test at α/m; quantization gets a second start near zero
    # (its first may sit on the boundary σ = 0)
    starts = (u0, np.array([0.05])) if name == 'gyro_quantization' else (u0,)
    simplex = None
    if name != 'gyro_quantization':
        # a common scale on a coarse log grid first (a simplex that has to grow from a tiny
        # step toward a far optimum gets clipped flat against the bound and stops there),
        # then one sweep axis by axis on the same grid
        grid = np.linspace(lo, hi, 13)
        vals = [nll(np.full(e.size, g)) for g in grid]
        if np.isfinite(np.min(vals)) and np.min(vals) < nll(u0):
            u0 = np.full(e.size, grid[int(np.argmin(vals))])
            for i in range(e.size):
                trial_u = [np.where(np.arange(e.size) == i, g, u0) for g in grid]
                u0 = trial_u[int(np.argmin([nll(u) for u in trial_u]))]
            u0 = np.clip(u0, lo + 1e-6, hi - 1e-6)
            starts = (u0,)
        step = np.log(10.0) / 4.0
        simplex = np.vstack([u0] + [u0 + np.where(np.arange(e.size) == i,
                                                  step if u0[i] + step <= hi else -step, 0.0)
                                    for i in range(e.size)])
    for s0 in starts:
        res = minimize(nll, s0, method='Nelder-Mead', bounds=bounds,
                       options={'xatol': 1e-3, 'fatol': 1e-2, 'maxiter': 60 * e.size,
                                'initial_simplex': simplex})
        if best is None or res.fun < best.fun:
            best = res
    if not np.isfinite(best.fun):
        raise NumericalFailure('no value in its range gives a positive-definite covariance')
    at_bound = (best.x >= hi - 1e-3) | ((best.x <= lo + 1e-3) & (name != 'gyro_quantization'))
    if np.any(at_bound):
        rng = (f'{NOISE_SCALE_RANGE[0]:g} to {NOISE_SCALE_RANGE[1]:g}'
               if name != 'gyro_quantization' else f'up to {unit * hi:.3g} rad')
        raise NumericalFailure(f'the likelihood is largest at the bound of its range ({rng}): '
                               f'{np.round(theta_of(best.x), 6).tolist()}')
    theta = theta_of(best.x)
    trial = dict(noise)
    trial[name] = theta.tolist()
    f = lin.evaluate(free, trial, mask)
    # σ from the curvature of −2 log L in θ (Fisher: σ² = 2 / d²(−2 log L)/dθ²); a curvature
    # that is not positive and finite (or a neighbour that cannot be evaluated) gives σ = ∞
    sig = np.zeros(e.size)
    for i in range(e.size):
        h = max(1e-3 * abs(theta[i]), 1e-9 if name == 'gyro_quantization' else 1e-4)

        def at(dv):
            t2 = theta.copy()
            t2[i] = max(t2[i] + dv, 0.0)
            tr = dict(noise)
            tr[name] = t2.tolist()
            return lin.evaluate(free, tr, mask).nll
        try:
            c = (at(h) - 2 * f.nll + at(-h)) / h ** 2
        except NUMERICAL_ERRORS:
            c = np.nan
        sig[i] = np.sqrt(2.0 / c) if np.isfinite(c) and c > 0 else np.inf
    return theta, f, sig
