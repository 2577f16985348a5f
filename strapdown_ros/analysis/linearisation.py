"""The linearisation of the discrepancy workflow: a recording in the core's terms, the increment
residuals at one model point (004 eq. 5–6) with the columns of the boresight and of every effect,
the whitening by the calibrator's correlated covariance, and the maximum-likelihood fit of a
noise term.  :mod:`.discrepancy` runs the selection on top of it.  No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..rotation import quat_to_dcm, rotvec_to_dcm
from ..sensors.effects import EFFECTS, GyroEffects, get_effect
from .linear_model import Whitener, band_covariance, fit
from .pairs import GyroRecord, PairSet, build_pairs, pair_integral, pair_residuals

__all__ = ["Recording", "InputError", "Linearisation"]

_PRIOR_EFFECTS = (("gyro_bias", "gyro_bias_sigma"), ("gyro_scale_factor", "gyro_scale_sigma"),
                  ("gyro_misalignment", "gyro_misalignment_sigma"))


class InputError(ValueError):
    """The recording cannot be analysed (too few fixes, no overlap, ...)."""


@dataclass
class Recording:
    """A recording in the core's terms: stamps in seconds from an origin (any), VF covariances."""
    gyro_stamps: np.ndarray               # (n,) end of each increment's interval
    delta_theta: np.ndarray               # (n, 3) rad, body (MF) axes
    fix_stamps: np.ndarray                # (m,) camera stamps (camera clock)
    fix_q: np.ndarray                     # (m, 4) q_GCRS_VF scalar-first
    fix_P: np.ndarray                     # (m, 3, 3) reported (or assumed) covariance, VF axes, rad²
    gaps: list = field(default_factory=list)   # gyro gaps (a, b), s

    def __post_init__(self):
        self.gyro_stamps = np.asarray(self.gyro_stamps, dtype=float)
        self.delta_theta = np.asarray(self.delta_theta, dtype=float).reshape(-1, 3)
        self.fix_stamps = np.asarray(self.fix_stamps, dtype=float)
        self.fix_q = np.asarray(self.fix_q, dtype=float).reshape(-1, 4)
        self.fix_P = np.asarray(self.fix_P, dtype=float).reshape(-1, 3, 3)


# ----------------------------------------------------------------------------- the linearisation
class Linearisation:
    """Residuals and columns of the model at one point (parameter values + boresight C)."""

    def __init__(self, rec: Recording, params: dict, C: np.ndarray, epoch: float):
        self.params, self.C = params, C
        st, m = rec.gyro_stamps, rec.delta_theta
        T = np.diff(st, prepend=st[0] - (st[1] - st[0]))
        self.effects = GyroEffects(params, epoch=epoch)
        rho = self.effects.compensate(m, st, T)
        self.gyro = GyroRecord(st, rho)
        self.time_offset = float(EFFECTS["time_offset"].value(params)[0])
        self.pairs: PairSet = build_pairs(self.gyro, rec.fix_stamps, rec.fix_q, self.time_offset, rec.gaps)
        if len(self.pairs) < 2:
            raise InputError(f"only {len(self.pairs)} increment pair(s): the gyro data must cover consecutive "
                             f"camera fixes")
        self.epoch = epoch
        self.rec = rec
        N = len(self.pairs)
        self.R_cam = quat_to_dcm(self.pairs.dq_cam)
        self.R_imu = quat_to_dcm(self.pairs.dq_imu)
        self.f = pair_residuals(C, self.pairs)
        self.r = self.f.reshape(-1)
        # boresight correction δ: C → C exp([δ×]) (VF axes), central differences
        h = 1e-6
        cols = []
        for j in range(3):
            d = np.zeros(3)
            d[j] = h
            cols.append((pair_residuals(C @ rotvec_to_dcm(d), self.pairs)
                         - pair_residuals(C @ rotvec_to_dcm(-d), self.pairs)).reshape(-1) / (2 * h))
        self.col_boresight = np.array(cols).T
        # gyro-effect signatures ∂r/∂θ_model = −Cᵀ ε-signature: computed when first asked for
        self._sig = {}
        # time offset: ∂r/∂τ_model = Cᵀ (ΔSᵀ ω_s − ω_e)
        w_s = self.gyro.rate_at(self.pairs.k_start)
        w_e = self.gyro.rate_at(self.pairs.k_end)
        E = np.einsum("nji,nj->ni", self.R_imu, w_s) - w_e
        self._sig["time_offset"] = (E @ C).reshape(3 * N, 1)
        # nominal random constants (prior) U
        self.U = np.hstack([-self.signature(n) for n, _ in _PRIOR_EFFECTS])
        self.prior_var = np.concatenate([np.full(EFFECTS[n].size, float(params.get(s, 0.0)) ** 2)
                                         for n, s in _PRIOR_EFFECTS])
        self.random_walk = float(params.get("gyro_random_walk", 0.0))
        # quantization: the output lags the integral by the remainder, mean σ/2 in the sense of
        # the motion on each axis (000 §5.3): r_mean = σ/2 · Cᵀ(ΔS_imuᵀ s_s − s_e), s = soft sign
        # of the rate over ±0.5 s (0 where an axis is not driven past its random walk)
        w0 = max(3.0 * self.random_walk, 1e-7)
        s_s = np.tanh(self.gyro.rate_at(self.pairs.k_start, 0.5) / w0)
        s_e = np.tanh(self.gyro.rate_at(self.pairs.k_end, 0.5) / w0)
        self.quant_col = (0.5 * (np.einsum("nji,nj->ni", self.R_imu, s_s) - s_e) @ C).reshape(-1)

    def _times(self, sl):
        st = self.gyro.stamps
        return st[sl] - 0.5 * (st[sl] - st[sl - 1]) - self.epoch

    # ---- columns -----------------------------------------------------------------------
    def signature(self, name: str) -> np.ndarray:
        """∂r/∂θ_model of a systematic effect's parameters, (3N, size)."""
        if name not in self._sig:
            e = EFFECTS[name]
            eps = pair_integral(self.gyro, self.pairs,
                                lambda r_, T_, sl: e.increment_jacobian(r_, T_, self._times(sl)))
            self._sig[name] = -np.einsum("ji,njp->nip", self.C, eps).reshape(3 * len(self.pairs), -1)
        return self._sig[name]

    def columns(self, name: str) -> np.ndarray:
        """∂r/∂(fit combinations) of a systematic effect, (3N, q)."""
        col = self.signature(name)
        S = get_effect(name).fit_basis()
        return col if S is None else col @ S

    def design(self, names) -> np.ndarray:
        return np.hstack([self.col_boresight] + [self.columns(n) for n in names])

    # ---- noise ---------------------------------------------------------------------------
    def fix_covariance(self, noise: dict) -> np.ndarray:
        P = self.rec.fix_P
        for name, theta in noise.items():
            P = EFFECTS[name].fix_covariance(P, np.asarray(theta, dtype=float))
        return P

    def whitener(self, noise: dict, mask=None) -> Whitener:
        pairs = self.pairs if mask is None else self.pairs.subset(mask)
        R = self.R_cam if mask is None else self.R_cam[mask]
        P = self.fix_covariance(noise)
        fixP = np.stack([P[pairs.fix_start], P[pairs.fix_end]], axis=1)
        white = (self.random_walk ** 2 * pairs.duration)[:, None, None] * np.eye(3)
        return Whitener(band_covariance(fixP, R, pairs.adjacent, white))

    def rows(self, mask) -> np.ndarray:
        return np.repeat(np.asarray(mask, dtype=bool), 3)

    def residual(self, noise) -> np.ndarray:
        """r less the mean of the noise terms (the quantization lag)."""
        q = noise.get("gyro_quantization")
        return self.r if q is None else self.r - float(q[0]) * self.quant_col

    def evaluate(self, free, noise, mask=None):
        J = self.design(free)
        r = self.residual(noise)
        if mask is None:
            return fit(r, J, self.U, self.prior_var, self.whitener(noise))
        rows = self.rows(mask)
        return fit(r[rows], J[rows], self.U[rows], self.prior_var, self.whitener(noise, mask))


def _noise_of(params: dict) -> dict:
    out = {}
    q = float(params.get("gyro_quantum", 0.0))
    if q > 0:
        out["gyro_quantization"] = [q]
    k = np.asarray(params.get("camera_noise_scale", (1.0, 1.0, 1.0)), dtype=float)
    if np.any(k != 1.0):
        out["camera_noise_anisotropy"] = k.tolist()
    return out


# ----------------------------------------------------------------------------- noise ML
def _fit_noise(lin: Linearisation, free, noise: dict, name: str, mask=None):
    """Maximum-likelihood value of a noise term (others fixed); returns (theta, fit, sigma)."""
    from scipy.optimize import minimize

    e = EFFECTS[name]
    start = np.asarray(noise.get(name, [e.neutral] * e.size), dtype=float)
    if name == "gyro_quantization":
        # parametrise by the remainder variance σ²/12 relative to the mean fix variance
        ref = float(np.mean(np.trace(lin.rec.fix_P, axis1=1, axis2=2)) / 3.0)

        def theta_of(u):
            return np.array([np.sqrt(12.0 * ref) * abs(u[0])])
        u0 = np.array([max(start[0], 0.0) / np.sqrt(12.0 * ref) + 0.3])
    else:
        def theta_of(u):
            return np.exp(u)
        u0 = np.log(np.maximum(start, 1e-3))

    def nll(u):
        trial = dict(noise)
        trial[name] = theta_of(u).tolist()
        try:
            return lin.evaluate(free, trial, mask).nll
        except np.linalg.LinAlgError:
            return np.inf
    best = None
    # −2 log L to 0.01 is ample for a test at α/m; quantization gets a second start near zero
    # (its first may sit on the boundary σ = 0)
    starts = (u0, np.array([0.05])) if name == "gyro_quantization" else (u0,)
    for s0 in starts:
        res = minimize(nll, s0, method="Nelder-Mead", options={"xatol": 1e-3, "fatol": 1e-2, "maxiter": 60 * e.size})
        if best is None or res.fun < best.fun:
            best = res
    theta = theta_of(best.x)
    trial = dict(noise)
    trial[name] = theta.tolist()
    f = lin.evaluate(free, trial, mask)
    # σ from the curvature of −2 log L in θ (Fisher: σ² = 2 / d²(−2 log L)/dθ²)
    sig = np.zeros(e.size)
    for i in range(e.size):
        h = max(1e-3 * abs(theta[i]), 1e-9 if name == "gyro_quantization" else 1e-4)

        def at(dv):
            t2 = theta.copy()
            t2[i] = max(t2[i] + dv, 0.0)
            tr = dict(noise)
            tr[name] = t2.tolist()
            return lin.evaluate(free, tr, mask).nll
        c = (at(h) - 2 * f.nll + at(-h)) / h ** 2
        sig[i] = np.sqrt(2.0 / c) if c > 0 else np.inf
    return theta, f, sig
