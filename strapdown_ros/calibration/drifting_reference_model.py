"""
The model of the drifting-reference calibration (Tkachenko 1983, paper 000).

What the estimator of :mod:`strapdown_ros.calibration.drifting_reference` needs to form its
equations: the §6 constants and published error sets, the gyro error structure D(ω, t) and
the drift structure G(t), the aircraft angles of the gyrostabilizer, Ψ(t, t0) = ∫G dt, a
simulated gyrostabilizer reference, the computed attitude integrated with the package's coning
algorithms and the gyro-error integral Θ(t).  Conventions and derivations:
doc/drifting_reference.md.  No ROS; numpy only.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from strapdown_ros.attitude.integrator import AttitudeIntegrator
from strapdown_ros.rotation import (aircraft_angles_to_quat, quat_conjugate, quat_multiply,
                                    quat_normalize, quat_to_dcm, rotvec_to_quat, skew)

__all__ = ['PAPER_000', 'PAPER_000_C', 'PAPER_000_D', 'PAPER_000_PHI0', 'PAPER_000_W0',
           'QUADRATURES', 'SCALE_MISALIGNMENT_BIAS', 'ErrorStructure', 'GyrostabilizerReference',
           'bias_D', 'identity_G', 'integrate_attitude', 'psi_matrix', 'quat_to_aircraft_angles',
           'scale_misalignment_bias_D', 'theta_quadrature']

# ------------------------------------------------------------------ §6 constants
#: c of 000 §6: c1..c3 = 3e-4, c4 = c5 = −c6 = 5e-4, c7 = −c8 = −c9 = 1e-5 s⁻¹
PAPER_000_C = np.array([3e-4, 3e-4, 3e-4, 5e-4, 5e-4, -5e-4, 1e-5, -1e-5, -1e-5])
#: d of 000 §6: 1e-6 s⁻¹ per axis (L axes)
PAPER_000_D = np.array([1e-6, 1e-6, 1e-6])
#: w(0) of 000 §6: 1e-3 per axis, the vector part of Λ(0)⊗M(0)*
PAPER_000_W0 = np.array([1e-3, 1e-3, 1e-3])
#: aircraft angles of J relative to L at t0 (yaw, pitch, roll), 000 §6
PAPER_000_PHI0 = np.array([-0.5, 0.17, -0.6])

#: 000 §6, the three published error sets, transcribed from the text (w0 = w⁰ after correction).
PAPER_000 = {
    'unquantized': {
        'w0': [-0.67e-5, 0.32e-5, -1.3e-5],
        'dc': [-5.9e-7, -5.8e-6, -1.4e-5, 6e-6, -3.7e-6, -2.4e-8, -4.1e-7, 1.4e-7, -1.5e-7],
        'dd': [-2.2e-7, 2.1e-7, -2.5e-7],
    },
    'quantized_raw': {       # σ = 2e-5, no centring
        'w0': [-2e-5, 0.5e-5, -3.2e-5],
        'dc': [9.6e-6, -2.7e-6, -9.7e-6, 1.8e-5, -1.6e-5, -2.8e-6, -1.2e-6, -2.1e-6, 1.9e-6],
        'dd': [-6.7e-8, 2e-7, -1.4e-6],
    },
    'quantized_centred': {   # σ = 2e-5, centring (5.5) or (5.6)
        'w0': [1.7e-5, 0.83e-5, -1.4e-5],
        'dc': [4.5e-6, -9.4e-6, -1.8e-5, 4.9e-6, -5.1e-6, 8.7e-7, -3.8e-7, -1.6e-7, -1.8e-7],
        'dd': [2.9e-7, -1.4e-7, -1.4e-7],
    },
}

QUADRATURES = ('exact', 'trapezoid')


# ------------------------------------------------------------------ error structures
def scale_misalignment_bias_D(omega, t=None) -> np.ndarray:
    """
    Return 000 §6's gyro error structure ``D = [D_I D_II E3]``: scale, misalignment, bias.

    ``D_I = diag ω``, ``D_II = [[ω2,0,ω3],[ω1,ω3,0],[0,ω2,ω1]]``: linear in ω (scale factors,
    symmetric misalignments) plus a constant block (biases), the structure of
    :meth:`~strapdown_ros.sensors.SensorErrorModel.from_scale_misalignment_bias`.

    Parameters
    ----------
    omega : (..., 3) ndarray
        Body rate ω, rad/s.
    t : float or ndarray, optional
        Time, s (unused: D does not depend on t).

    Returns
    -------
    (..., 3, 9) ndarray
        D(ω), so that Δω = D(ω)·c.

    """
    w = np.asarray(omega, dtype=float)
    D = np.zeros(w.shape[:-1] + (3, 9))
    w1, w2, w3 = w[..., 0], w[..., 1], w[..., 2]
    D[..., 0, 0], D[..., 1, 1], D[..., 2, 2] = w1, w2, w3
    D[..., 0, 3], D[..., 0, 5] = w2, w3
    D[..., 1, 3], D[..., 1, 4] = w1, w3
    D[..., 2, 4], D[..., 2, 5] = w2, w1
    D[..., 0, 6] = D[..., 1, 7] = D[..., 2, 8] = 1.0
    return D


def bias_D(omega, t=None) -> np.ndarray:
    """
    Return ``D = E3`` (m = 1): constant gyro biases only (000 §4's simplest case).

    Parameters
    ----------
    omega : (..., 3) ndarray
        Body rate ω, rad/s (only its shape is used).
    t : float or ndarray, optional
        Time, s (unused).

    Returns
    -------
    (..., 3, 3) ndarray
        Identity matrices.

    """
    w = np.asarray(omega, dtype=float)
    return np.broadcast_to(np.eye(3), w.shape[:-1] + (3, 3)).copy()


def identity_G(t) -> np.ndarray:
    """
    Return ``G = E3`` (n = 1): constant drift rate of the stabilised platform.

    Parameters
    ----------
    t : float or ndarray
        Time, s (only its shape is used).

    Returns
    -------
    (..., 3, 3) ndarray
        Identity matrices.

    """
    t = np.asarray(t, dtype=float)
    return np.broadcast_to(np.eye(3), t.shape + (3, 3)).copy()


@dataclass(frozen=True)
class ErrorStructure:
    """
    The user-chosen ``D(ω, t)`` (3×3m) and ``G(t)`` (3×3n) of 000 (1.2).

    Attributes
    ----------
    D : callable
        ``D(omega (..., 3), t) -> (..., 3, 3m)``: gyro errors Δω_E = D(ω_E, t)·c.
    m : int
        Number of 3-column blocks of D.
    G : callable
        ``G(t) -> (..., 3, 3n)``: drift of the reference δω_L = G(t)·d.
    n : int
        Number of 3-column blocks of G (0: no drift estimated).
    D_linear : bool
        D is linear in ω plus a constant (true for D_I, D_II, E3); then the increment
        correction ``∫D(ω)c dt = D(θ/h)c·h`` is exact for any rate history.
    G_constant : bool
        G does not depend on t; then ``Ψ(t, t0) = (t − t0)G`` and ``q_I_L = exp(Ψd)`` are
        exact.

    """

    D: Callable = scale_misalignment_bias_D
    m: int = 3
    G: Callable = identity_G
    n: int = 1
    D_linear: bool = True
    G_constant: bool = True

    @property
    def size(self) -> int:
        """Return the number of unknowns 3(1 + m + n) of x = [w0, c, d]."""
        return 3 * (1 + self.m + self.n)

    @property
    def labels(self) -> list[str]:
        """Return the names of the unknowns: w0_1..w0_3, c1.., d1.."""
        return (['w0_1', 'w0_2', 'w0_3'] + [f'c{i + 1}' for i in range(3 * self.m)]
                + [f'd{i + 1}' for i in range(3 * self.n)])

    def split(self, x):
        """
        Split x into its parts.

        Parameters
        ----------
        x : (size,) array_like
            The unknowns [w0, c, d].

        Returns
        -------
        tuple of ndarray
            w0 (3,), c (3m,) and d (3n,).

        """
        x = np.asarray(x, dtype=float)
        return x[:3], x[3:3 + 3 * self.m], x[3 + 3 * self.m:]


SCALE_MISALIGNMENT_BIAS = ErrorStructure()


# ------------------------------------------------------------------ aircraft angles
def quat_to_aircraft_angles(q) -> np.ndarray:
    """
    Return Lurie's aircraft angles of a quaternion: the inverse of ``aircraft_angles_to_quat``.

    Yaw φ1 about y, pitch φ2 about the new z, roll φ3 about the new x:
    ``C = R_y(φ1)R_z(φ2)R_x(φ3)``, ``C[1,0] = sin φ2``, ``C[0,0] = cos φ1 cos φ2``,
    ``C[2,0] = −sin φ1 cos φ2``, ``C[1,1] = cos φ2 cos φ3``, ``C[1,2] = −cos φ2 sin φ3``.
    Pitch by atan2 (accurate near ±π/2, where yaw and roll become singular).

    Parameters
    ----------
    q : (..., 4) ndarray
        Quaternion, scalar first.

    Returns
    -------
    (..., 3) ndarray
        (yaw, pitch, roll), rad.

    """
    C = quat_to_dcm(q)
    pitch = np.arctan2(C[..., 1, 0], np.hypot(C[..., 1, 1], C[..., 1, 2]))
    yaw = np.arctan2(-C[..., 2, 0], C[..., 0, 0])
    roll = np.arctan2(-C[..., 1, 2], C[..., 1, 1])
    return np.stack([yaw, pitch, roll], -1)


# ------------------------------------------------------------------ Ψ
_GL3 = np.polynomial.legendre.leggauss(3)


def psi_matrix(structure: ErrorStructure, t, t0: float, max_step: float = 0.05) -> np.ndarray:
    """
    Return ``Ψ(t, t0) = ∫_{t0}^{t} G dt``.

    Exact for constant G; otherwise composite 3-point Gauss–Legendre with sub-intervals
    ≤ max_step (error O(step⁶) per sub-interval).

    Parameters
    ----------
    structure : ErrorStructure
        Supplies G.
    t : float or ndarray
        Upper limits, s.
    t0 : float
        Lower limit, s.
    max_step : float
        Longest quadrature sub-interval, s.

    Returns
    -------
    (..., 3, 3n) ndarray
        Ψ(t, t0), s.

    """
    t = np.asarray(t, dtype=float)
    if structure.G_constant:
        g = np.asarray(structure.G(np.asarray(t0)), dtype=float)
        return (t - t0)[..., None, None] * g
    flat = np.atleast_1d(t).ravel()
    out = np.zeros((flat.size, 3, 3 * structure.n))
    x, wts = _GL3
    for i, ti in enumerate(flat):
        k = max(1, int(np.ceil(abs(ti - t0) / max_step)))
        edges = np.linspace(t0, ti, k + 1)
        half = 0.5 * np.diff(edges)
        mid = 0.5 * (edges[1:] + edges[:-1])
        nodes = mid[:, None] + half[:, None] * x
        g = np.asarray(structure.G(nodes), dtype=float)          # (k, 3, 3, 3n)
        out[i] = np.einsum('k,j,kjab->ab', half, wts, g)
    return out.reshape(t.shape + (3, 3 * structure.n))


# ------------------------------------------------------------------ reference simulator
class GyrostabilizerReference:
    """
    The attitude reference of 000: a gyrostabilizer whose basis L drifts, read as aircraft angles.

    * L is aligned with I at ``t_star``; its absolute rate in L axes is ``δω_L = G(t)d``, so
      ``q_I_L(t) = exp(Ψ(t, t*)d)`` — exact for constant G (rotation about a fixed axis),
      first-order Magnus otherwise (error O(|Ψd|²), < 1e-9 rad for 000's sizes).
    * The body basis J is mounted on E by the constant ``mounting = q_E_J``.  000 §6's φ0 and
      Λ(0) are not consistent with J = E (they differ by 140°), so the experiment takes
      ``q_E_J = Λ(0)*⊗N(φ0)``: φ(t0) = φ0 exactly and Λ(0) as printed.  The increments P do
      not depend on the mounting.
    * ``angles(t)``: φ(t) of J relative to L (plus optional white noise);
      ``quaternion(t) = N_L(φ(t))`` recomputed from the angles, so the round trip through the
      angles (and its singularity at pitch ±π/2) is part of the simulation.

    Parameters
    ----------
    profile : MotionProfile
        The true motion; ``profile.attitude(t)`` is Λ(t) = q_I_E.
    d : array_like, (3n,)
        Drift coefficients of the reference, rad/s.
    structure : ErrorStructure
        Supplies G.
    mounting : (4,) array_like, optional
        q_E_J, scalar first (default identity).
    t_star : float
        Time at which L is aligned with I, s.
    angle_noise : float
        1σ white noise of the aircraft angles, rad.
    seed : int, optional
        Seed of the angle noise.

    """

    def __init__(self, profile, d, structure: ErrorStructure = SCALE_MISALIGNMENT_BIAS,
                 mounting=None, t_star: float = 0.0, angle_noise: float = 0.0,
                 seed: int | None = None):
        self.profile = profile
        self.d = np.asarray(d, dtype=float).reshape(3 * structure.n)
        self.structure = structure
        q_e_j = mounting if mounting is not None else [1.0, 0, 0, 0]
        self.mounting = quat_normalize(np.asarray(q_e_j, dtype=float))
        self.t_star = float(t_star)
        self.angle_noise = float(angle_noise)
        self.rng = np.random.default_rng(seed)

    def drift_quaternion(self, t) -> np.ndarray:
        """
        Return the drift of the stabilised basis, ``q_I_L(t)``.

        Parameters
        ----------
        t : float or ndarray
            Time, s.

        Returns
        -------
        (..., 4) ndarray
            q_I_L, scalar first.

        """
        psi = psi_matrix(self.structure, t, self.t_star)
        return rotvec_to_quat(psi @ self.d)

    def true_attitude(self, t) -> np.ndarray:
        """
        Return the true attitude of J in L, ``q_L_J(t) = q_I_L*⊗Λ(t)⊗q_E_J``.

        Parameters
        ----------
        t : float or ndarray
            Time, s.

        Returns
        -------
        (..., 4) ndarray
            q_L_J, scalar first.

        """
        return quat_multiply(quat_conjugate(self.drift_quaternion(t)),
                             quat_multiply(self.profile.attitude(t), self.mounting))

    def angles(self, t) -> np.ndarray:
        """
        Return the aircraft angles φ(t) of J relative to L, with the angle noise.

        Parameters
        ----------
        t : float or ndarray
            Time, s.

        Returns
        -------
        (..., 3) ndarray
            (yaw, pitch, roll), rad.

        """
        phi = quat_to_aircraft_angles(self.true_attitude(t))
        if self.angle_noise > 0:
            phi = phi + self.rng.normal(0.0, self.angle_noise, phi.shape)
        return phi

    def quaternion(self, t) -> np.ndarray:
        """
        Return ``N_J(φ) = N_L(φ)`` from the (measured) angles at the epochs t.

        Parameters
        ----------
        t : float or ndarray
            Time, s.

        Returns
        -------
        (..., 4) ndarray
            The reference quaternion, scalar first.

        """
        return aircraft_angles_to_quat(self.angles(t))


# ------------------------------------------------------------------ computed attitude
def integrate_attitude(q0, increments, h: float, algorithm: str = '2', epochs: Sequence[int] = ()):
    """
    Integrate gyro increments from ``q0`` with the package's attitude integrator.

    At update ends the attitude is the integrator's output; inside an update it is the last
    update's attitude times ``exp(Σθ)`` of the samples since (used only as quadrature nodes
    for Θ).  Where an epoch falls inside an update the update is cut there (the integrator
    applies the pending increments one by one), so that every equation uses the algorithm's
    own attitude.

    Parameters
    ----------
    q0 : (4,) array_like
        Initial attitude, scalar first.
    increments : (N, 3) ndarray
        Gyro increments, rad, on a grid of period h.
    h : float
        Sample period, s.
    algorithm : str
        Coning algorithm name (:func:`strapdown_ros.attitude.coning.get_algorithm`).
    epochs : sequence of int
        Sample indices at which the attitude must be the algorithm's own.

    Returns
    -------
    (N + 1, 4) ndarray
        The attitude at every sample boundary, scalar first.

    """
    inc = np.asarray(increments, dtype=float)
    n = len(inc)
    integ = AttitudeIntegrator(algorithm, q0, initial_time=0.0, nominal_period=h,
                               propagate_covariance=False)
    per = integ.algorithm.samples
    anchor_q = {0: quat_normalize(np.asarray(q0, dtype=float))}
    cuts, offset = [], 0
    for e in sorted({int(e) for e in epochs if 0 < int(e) <= n}):
        if (e - offset) % per:                  # epoch inside an update: cut the update there
            cuts.append(e)
            offset = e
    if not cuts or cuts[-1] != n:
        cuts.append(n)
    pos, pending = 0, 0
    stamps = h * np.arange(1, n + 1)
    for e in cuts:
        if e <= pos:
            continue
        out = integ.push(inc[pos:e], stamps[pos:e])
        idx = np.rint(out.stamps / h).astype(int)
        for i, q in zip(idx, out.attitude):
            anchor_q[int(i)] = q
        pending = (pending + e - pos) % per
        pos = e
        if pending:
            integ.set_algorithm(algorithm)        # flush the partial update at the epoch
            anchor_q[e] = integ.q.copy()
            pending = 0
    keys = np.array(sorted(anchor_q))
    anchors = np.array([anchor_q[k] for k in keys])
    cum = np.vstack([np.zeros(3), np.cumsum(inc, axis=0)])
    b = np.arange(n + 1)
    a = keys[np.searchsorted(keys, b, side='right') - 1]
    q = quat_multiply(anchors[np.searchsorted(keys, a)], rotvec_to_quat(cum[b] - cum[a]))
    q[keys] = anchors
    return quat_normalize(q)


def _rodrigues_integral(u: np.ndarray, h: float) -> np.ndarray:
    """``∫_0^h exp([u×]τ) dτ`` for u (..., 3) → (..., 3, 3), with series for small |u|h."""
    u = np.asarray(u, dtype=float)
    w = np.linalg.norm(u, axis=-1)
    K = skew(u)
    x = w * h
    small = x < 1e-3
    ws = np.where(small, 1.0, w)
    a = np.where(small, h ** 2 * (0.5 - x ** 2 / 24.0 + x ** 4 / 720.0),
                 (1.0 - np.cos(x)) / ws ** 2)
    b = np.where(small, h ** 3 * (1.0 / 6.0 - x ** 2 / 120.0 + x ** 4 / 5040.0),
                 (x - np.sin(x)) / ws ** 3)
    return h * np.eye(3) + a[..., None, None] * K + b[..., None, None] * (K @ K)


def theta_quadrature(q, increments, h: float,
                     structure: ErrorStructure = SCALE_MISALIGNMENT_BIAS, method: str = 'exact',
                     samples_per_update: int = 2, t0: float = 0.0) -> np.ndarray:
    """
    Return ``Θ(t_s) = ∫_{t0}^{t_s} Bᵀ D(ω*, t) dt`` at every sample boundary s.

    ``method='exact'``: per gyro interval, with ω* = θ/h constant on it,
    ``Bᵀ(t) = Bᵀ(t_{s−1})·exp([ω*×](t − t_{s−1}))`` integrates in closed form — exact for
    rates that are constant on each interval (the §6 profile), O(h³) locally otherwise.
    ``method='trapezoid'``: the paper's choice, step H = samples_per_update·h,
    ``ΔΘ = H/2·(Bᵀ_a + Bᵀ_b)·D(ω̄)`` with ω̄ the mean rate of the update (local error
    O(H³)); values between update ends are interpolated linearly.

    Parameters
    ----------
    q : (N + 1, 4) ndarray
        Computed attitude M at every sample boundary (:func:`integrate_attitude`).
    increments : (N, 3) ndarray
        Gyro increments θ*, rad.
    h : float
        Sample period, s.
    structure : ErrorStructure
        Supplies D.
    method : {'exact', 'trapezoid'}
        Quadrature rule.
    samples_per_update : int
        Samples per attitude update (the trapezoid step).
    t0 : float
        Time of the first sample boundary, s.

    Returns
    -------
    (N + 1, 3, 3m) ndarray
        Θ at every sample boundary, s.

    """
    inc = np.asarray(increments, dtype=float)
    n = len(inc)
    C = quat_to_dcm(q)                                       # Bᵀ = C_K_E at every boundary
    t_mid = t0 + h * (np.arange(n) + 0.5)
    if method == 'exact':
        om = inc / h
        Dm = np.asarray(structure.D(om, t_mid), dtype=float)
        step = C[:-1] @ _rodrigues_integral(om, h) @ Dm
        return np.concatenate([np.zeros((1, 3, 3 * structure.m)), np.cumsum(step, axis=0)])
    if method != 'trapezoid':
        raise ValueError(f"unknown quadrature {method!r}; valid: {', '.join(QUADRATURES)}")
    H = samples_per_update
    k = n // H
    ends = H * np.arange(k + 1)
    om = inc[:k * H].reshape(k, H, 3).sum(1) / (H * h)
    Dm = np.asarray(structure.D(om, t0 + h * (ends[:-1] + 0.5 * H)), dtype=float)
    step = 0.5 * H * h * (C[ends[:-1]] + C[ends[1:]]) @ Dm
    nodes = np.concatenate([np.zeros((1, 3, 3 * structure.m)), np.cumsum(step, axis=0)])
    out = np.empty((n + 1, 3, 3 * structure.m))
    s = np.arange(n + 1)
    j = np.minimum(s // H, k - 1) if k > 0 else np.zeros_like(s)
    frac = (s - ends[j]) / H
    out[:] = nodes[j] + frac[:, None, None] * (nodes[np.minimum(j + 1, k)] - nodes[j])
    return out
