"""
Correction of the system "spatial angular-rate meter — gyrostabilizer"
(Tkachenko 1983; paper 000).

A strapdown gyro triad (body basis E) is integrated into an attitude M; a gyrostabilizer, whose
stabilised basis L drifts slowly away from the inertial basis I, reads the aircraft angles φ of a
body basis J.  From quaternion *increments* of both the method estimates, by least squares,

    x = [w0 (3), c (3m), d (3n)]

— the initial attitude error w0 of M, the gyro errors c (Δω_E = D(ω_E, t)·c) and the drift of the
reference d (δω_L = G(t)·d) — and then refines the attitude.  No rclpy; numpy only (scipy is not
used).

Conventions (000 ↔ this package, :mod:`strapdown_ros.rotation`)
----------------------------------------------------------------
* 000's quaternions "mapped to basis E" with ``Λ̇ = ½ Λ∘ω_E`` are our Hamilton, scalar-first
  ``q_ref_body``: ``Λ = q_I_E``, ``M = q_K_E``, ``N(φ) = q_L_J``.  Matrices: 000's
  ``A: r_E = A r_I`` is ``C_E_I = quat_to_dcm(Λ)ᵀ``; ``B: r_E = B r_K`` is ``quat_to_dcm(M)ᵀ``
  (the printed ``Λ∘r_I∘Λ`` lacks the bar on the first factor).
* Small errors are **half-angle vectors** in reference axes (vector parts of error quaternions):
  ``Λ(t) = (1 + w(t))∘M(t)``, exactly ``Λ = normalize([1, w])⊗M`` for the initial error w0
  (the §6 value "w(0) = 1e-3 per axis" is this w0: a 2e-3 rad rotation per axis);
  ``q_I_L = exp(Ψd)`` so that ``v = ½Ψd`` (2.2).  The corrected-attitude error w⁰ reported
  is the vector part of ``Λ(t)⊗Λ̂(t)*`` (scalar part ≥ 0), the same kind of vector as w.
* ``Φ(r) = skew(r)``: ``Φ(r)u = r × u``.

Measurement equation (2.7), verified in our conventions
-------------------------------------------------------
With ``P = N(φ(t))⊗N(φ0)* = p0 + p`` (reference increment, L axes) and
``P* = M(t)⊗M(t0)* = p0* + p*`` (computed increment, K axes), first order in (w0, c, d):

    2Φ(p)·w0 + ½[p0·E3 − Φ(p)]·[Θ(t)c + Ψ(t, t0)d] = p* − p,
    Θ(t) = ∫ Bᵀ D(ω*, t) dt,   Ψ(t, t0) = ∫ G dt.

(2.7) holds exactly as printed.  On the way: (2.3) ``p° = p + p0 v − p×v`` holds; (2.5) is
misprinted — the cross-product term is ``− p×[w(t) + w0]``, not ``+`` (from
``P° = (1 + w)⊗P*⊗(1 − w0)``); (2.6) and (2.7) follow from the corrected (2.5) and are right as
printed.  ``test/calibration/test_drifting_reference.py`` checks (2.7) against the exact nonlinear model by finite
differences: the remainder is second order in the errors.  The mounting of J on the body
cancels out of P (``q_I_J(t)q_I_J(t0)* = Λ(t)Λ(t0)*`` for any constant E→J rotation), which is
why 000 may say that the E–J orientation is "known only approximately".

Where to evaluate the coefficients: exact in w0 ('identity', the default)
-----------------------------------------------------------------------
(2.7) evaluates every coefficient at the reference increment p.  Any increment equal to p to
first order would do as well for a first-order method, and the choice decides the size of the
second-order remainder.  Exactly, the true attitude is ``Λ(t) = W0∘Δ(t)∘M(t)`` (M computed) with
``W0 ∝ 1 + w0`` and ``Δ(t) ≈ 1 − ½Θ(t)c`` the gyro error accumulated in K (the reference axes of M), so

    P° = W0∘Q∘W0*,   Q = Δ∘P*,   q = p* − Γ(p*)Θc   (to first order in c, exactly in w0).

``W0∘Q = P°∘W0`` gives, vector part, ``p° − q = w0 × (q + p°) + (w0·(q − p°))·w0`` — the last
term is third order — so

    p* − p = 2Φ(½(q + p°))·w0 + Γ(p*)·Θc + Γ(p)·Ψd.

With ``q ≈ p*`` and ``p° ≈ p`` the coefficients are: w0 columns at the mean ``½(p + p*)``,
c columns at the computed increment p*, d columns at the reference p.  For pure w0 (c = d = 0)
this is exact (``test_identity_coefficients_are_exact_in_w0``).  The printed choice leaves ``z``
with ``2w0 × (w0 × p*)``, second order in w0, which the least squares puts into c.
``coefficients='printed'`` keeps 000's form; what each choice gives on §6 is measured by
``reproduce_seeds --only 000`` (doc/seeds/reproduce_seeds.md).

If ``t* < t0`` (L aligned with I at t*), P is taken relative to L(t0), the w0 term becomes
``2Φ(p)(w0 − v(t0))`` with ``v(t0) = ½Ψ(t0, t*)d`` (000 §3, last paragraph); this module keeps
w0 relative to I and puts ``−Φ(p)Ψ(t0, t*)`` into the d columns, which is the same correction.

Quantization (000 §5), checked by Monte Carlo (``test/calibration/test_drifting_reference.py``)
-------------------------------------------------------------------------
With pulses of weight σ and carried remainder Δθ_k (5.1) the pulse sum lacks the latest
remainder, so the computed attitude *lags*:

* (5.2) must read ``q_F = −½Δθ(t)`` (printed ``+½Δθ``); then ``μ(q_F) = −¼σρ`` and
  ``μ(q_K) = −¼σBᵀρ`` ((5.3) prints it without Bᵀ).
* (5.4) must read ``z = z' − δz`` (printed ``+``): 000's own ``p' ≈ p* + p0*q_K − p*×q_K`` gives
  ``z' = z + δz``.  Only with these signs is the centring (5.5) — printed correctly — the removal
  of the mean: ``z' + ¼σ[p0E3 − Φ(p)]Bᵀρ*``.
* ``R(q_K) = σ²/48·E3`` (printed σ²/12, the variance of Δθ itself, not of ½Δθ), hence
  ``R(δz) = σ²/48·[p0²E3 − Φ²(p)] = σ²/48·(E3 − ppᵀ)`` (printed "¼σ[p0E3 − Φ²(p)]σ²").
  (Checked by Monte Carlo over initial remainders in ``test/calibration/test_drifting_reference.py``.)
* The model ``M* = M∘Q_F(t)`` is not literally the error: each step's error
  ``δθ_k = Δθ_{k−1} − Δθ_k`` acts at the time of step k, and to first order the reference-axes
  error is ``Σ_k C_k δθ_k``.  For rates that keep their signs its mean is a *jump at the first
  step*, ``C(t0)(Δθ_0 − ½σρ)``, fixed in reference axes.  It differs from the printed model by a
  constant body-axes rotation, which the increments P* cannot see (like the E–J mounting) and
  which w0 absorbs.  So (5.5) and (5.6) are equivalent for c and d — as 000 found — and (5.6),
  which adds ½σ·sign θ* at the first step and at sign changes, is the exact form of the
  correction (``test/calibration/test_drifting_reference.py`` checks both by Monte Carlo).

Beyond the paper
----------------
* ``iterate=True``: Gauss–Newton on the full nonlinear model — the increments are corrected by the
  current c (``θ = θ* − D(θ/h, t)c·h``, solved by fixed point), M is re-integrated from
  ``normalize([1, w0])⊗M(t0)``, the reference increment is predicted with ``exp(Ψd)`` and the
  equations (2.7) are re-formed about the current estimate until the step is below tolerance.
  Unquantized, the model is then exact and the errors fall to round-off.
* ``weighted=True``: each equation weighted by ``R(δz)⁻¹ = 48/σ²·(E3 + ppᵀ/p0²)`` (000 §5,
  equivalent to multiplying by ``[p0E3 − Φ(p)]⁻¹``), plus the variance of the reference angles.

The §6 experiment (simulation, Monte Carlo, ablations) lives in
:mod:`strapdown_ros.reproductions.tkachenko1983`; its measured results are in doc/seeds/reproduce_seeds.md,
generated by ``reproduce_seeds``.

Everything is accumulated recursively (5.8): ``UᵀU`` and ``UᵀZ`` are updated row by row and no
row is stored (:class:`NormalEquations`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import time as _time
from typing import Callable, Sequence

import numpy as np

from strapdown_ros.attitude.coning import get_algorithm
from strapdown_ros.attitude.integrator import AttitudeIntegrator
from strapdown_ros.estimation.observability import analyze_information, ObservabilityReport
from strapdown_ros.rotation import (aircraft_angles_to_quat, dcm_to_quat, quat_conjugate,
                                    quat_multiply, quat_normalize, quat_to_dcm, quat_to_rotvec,
                                    rotvec_to_quat, skew)
from strapdown_ros.sensors import increment_correction

__all__ = [
    'PAPER_000', 'TKACHENKO_STRUCTURE', 'TKACHENKO_C', 'TKACHENKO_D', 'TKACHENKO_W0', 'TKACHENKO_PHI0', 'MODES',
    'tkachenko_D', 'bias_D', 'identity_G', 'ErrorStructure', 'quat_to_aircraft_angles',
    'GyrostabilizerReference', 'psi_matrix', 'integrate_attitude', 'theta_quadrature',
    'NormalEquations', 'COEFFICIENTS', 'measurement_rows', 'quantization_covariance', 'TkachenkoSolution',
    'estimate', 'predicted_reference_increments', 'rank_test', 'simple_case_test',
    'error_at_epochs',
]

# --------------------------------------------------------------------------- §6 constants
#: c of 000 §6: c1..c3 = 3e-4, c4 = c5 = −c6 = 5e-4, c7 = −c8 = −c9 = 1e-5 s⁻¹
TKACHENKO_C = np.array([3e-4, 3e-4, 3e-4, 5e-4, 5e-4, -5e-4, 1e-5, -1e-5, -1e-5])
#: d of 000 §6: 1e-6 s⁻¹ per axis (L axes)
TKACHENKO_D = np.array([1e-6, 1e-6, 1e-6])
#: w(0) of 000 §6: 1e-3 per axis, the vector part of Λ(0)⊗M(0)*
TKACHENKO_W0 = np.array([1e-3, 1e-3, 1e-3])
#: aircraft angles of J relative to L at t0 (yaw, pitch, roll), 000 §6
TKACHENKO_PHI0 = np.array([-0.5, 0.17, -0.6])

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

MODES = ('raw', 'centred', 'corrected')
QUADRATURES = ('exact', 'trapezoid')


# --------------------------------------------------------------------------- error structures
def tkachenko_D(omega, t=None) -> np.ndarray:
    """
    000 §6: ``D = [D_I D_II E3]``, ``D_I = diag ω``, ``D_II = [[ω2,0,ω3],[ω1,ω3,0],[0,ω2,ω1]]``.

    ``omega`` (..., 3) → (..., 3, 9).  Linear in ω (scale factors, symmetric misalignments)
    plus a constant block (biases), the structure of
    :meth:`SensorErrorModel.from_symmetric_coefficients`.
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
    """``D = E3`` (m = 1): constant gyro biases only (000 §4's simplest case)."""
    w = np.asarray(omega, dtype=float)
    return np.broadcast_to(np.eye(3), w.shape[:-1] + (3, 3)).copy()


def identity_G(t) -> np.ndarray:
    """``G = E3`` (n = 1): constant drift rate of the stabilised platform."""
    t = np.asarray(t, dtype=float)
    return np.broadcast_to(np.eye(3), t.shape + (3, 3)).copy()


@dataclass(frozen=True)
class ErrorStructure:
    """
    The user-chosen ``D(ω, t)`` (3×3m) and ``G(t)`` (3×3n) of (1.2).

    ``D_linear``: D is linear in ω plus a constant (true for D_I, D_II, E3); then the increment
    correction ``∫D(ω)c dt = D(θ/h)c·h`` is exact for any rate history.  ``G_constant``: G does
    not depend on t; then ``Ψ(t, t0) = (t − t0)G`` and ``q_I_L = exp(Ψd)`` are exact.
    """
    D: Callable = tkachenko_D
    m: int = 3
    G: Callable = identity_G
    n: int = 1
    D_linear: bool = True
    G_constant: bool = True

    @property
    def size(self) -> int:
        return 3 * (1 + self.m + self.n)

    @property
    def labels(self) -> list[str]:
        return (['w0_1', 'w0_2', 'w0_3'] + [f'c{i + 1}' for i in range(3 * self.m)]
                + [f'd{i + 1}' for i in range(3 * self.n)])

    def split(self, x):
        x = np.asarray(x, dtype=float)
        return x[:3], x[3:3 + 3 * self.m], x[3 + 3 * self.m:]


TKACHENKO_STRUCTURE = ErrorStructure()


# --------------------------------------------------------------------------- aircraft angles
def quat_to_aircraft_angles(q) -> np.ndarray:
    """
    Inverse of :func:`strapdown_ros.rotation.aircraft_angles_to_quat` (Lurie's aircraft
    angles: yaw φ1 about y, pitch φ2 about the new z, roll φ3 about the new x).

    ``C = R_y(φ1)R_z(φ2)R_x(φ3)``: ``C[1,0] = sin φ2``, ``C[0,0] = cos φ1 cos φ2``,
    ``C[2,0] = −sin φ1 cos φ2``, ``C[1,1] = cos φ2 cos φ3``, ``C[1,2] = −cos φ2 sin φ3``.
    Pitch by atan2 (accurate near ±π/2, where yaw and roll become singular).
    """
    C = quat_to_dcm(q)
    pitch = np.arctan2(C[..., 1, 0], np.hypot(C[..., 1, 1], C[..., 1, 2]))
    yaw = np.arctan2(-C[..., 2, 0], C[..., 0, 0])
    roll = np.arctan2(-C[..., 1, 2], C[..., 1, 1])
    return np.stack([yaw, pitch, roll], -1)


# --------------------------------------------------------------------------- Ψ
_GL3 = np.polynomial.legendre.leggauss(3)


def psi_matrix(structure: ErrorStructure, t, t0: float, max_step: float = 0.05) -> np.ndarray:
    """
    ``Ψ(t, t0) = ∫_{t0}^{t} G dt`` (..., 3, 3n).  Exact for constant G; otherwise composite
    3-point Gauss–Legendre with sub-intervals ≤ max_step (error O(step⁶) per sub-interval).
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
        g = np.asarray(structure.G(nodes), dtype=float)                  # (k, 3, 3, 3n)
        out[i] = np.einsum('k,j,kjab->ab', half, wts, g)
    return out.reshape(t.shape + (3, 3 * structure.n))


# --------------------------------------------------------------------------- reference simulator
class GyrostabilizerReference:
    """
    The attitude reference of 000: a gyrostabilizer whose basis L drifts, read as aircraft angles.

    * L is aligned with I at ``t_star``; its absolute rate in L axes is ``δω_L = G(t)d``, so
      ``q_I_L(t) = exp(Ψ(t, t*)d)`` — exact for constant G (rotation about a fixed axis),
      first-order Magnus otherwise (error O(|Ψd|²), < 1e-9 rad for 000's sizes).
    * The body basis J is mounted on E by the constant ``mounting = q_E_J``.  000 §6's φ0 and Λ(0)
      are not consistent with J = E (they differ by 140°; Λ(0) = (0.8 + 0.6i1)∘(0.8 − 0.6i3)
      while N(φ0) = 0.916 − 0.305i1 − 0.260i2 + 0.006i3), so the experiment takes
      ``q_E_J = Λ(0)*⊗N(φ0)``: φ(t0) = φ0 exactly and Λ(0) as printed.  The increments P do not
      depend on the mounting.
    * ``angles(t)``: φ(t) of J relative to L (plus optional white noise ``angle_noise`` rad);
      ``quaternion(t) = N_L(φ(t))`` recomputed from the angles, so the round trip through the
      angles (and its singularity at pitch ±π/2) is part of the simulation.
    """

    def __init__(self, profile, d, structure: ErrorStructure = TKACHENKO_STRUCTURE, mounting=None,
                 t_star: float = 0.0, angle_noise: float = 0.0, seed: int | None = None):
        self.profile = profile
        self.d = np.asarray(d, dtype=float).reshape(3 * structure.n)
        self.structure = structure
        self.mounting = quat_normalize(np.asarray(mounting if mounting is not None else [1.0, 0, 0, 0],
                                                  dtype=float))
        self.t_star = float(t_star)
        self.angle_noise = float(angle_noise)
        self.rng = np.random.default_rng(seed)

    def drift_quaternion(self, t) -> np.ndarray:
        """``q_I_L(t)``."""
        psi = psi_matrix(self.structure, t, self.t_star)
        return rotvec_to_quat(psi @ self.d)

    def true_attitude(self, t) -> np.ndarray:
        """``q_L_J(t) = q_I_L*⊗Λ(t)⊗q_E_J``."""
        return quat_multiply(quat_conjugate(self.drift_quaternion(t)),
                             quat_multiply(self.profile.attitude(t), self.mounting))

    def angles(self, t) -> np.ndarray:
        phi = quat_to_aircraft_angles(self.true_attitude(t))
        if self.angle_noise > 0:
            phi = phi + self.rng.normal(0.0, self.angle_noise, phi.shape)
        return phi

    def quaternion(self, t) -> np.ndarray:
        """``N_J(φ) = N_L(φ)`` from the (measured) angles at the epochs t."""
        return aircraft_angles_to_quat(self.angles(t))


# --------------------------------------------------------------------------- computed attitude
def integrate_attitude(q0, increments, h: float, algorithm: str = '2', epochs: Sequence[int] = ()):
    """
    Integrate increments (N, 3) from ``q0`` with :class:`AttitudeIntegrator`.

    Returns ``q`` (N+1, 4): the attitude at every sample boundary.  At update ends it is the
    integrator's output; inside an update it is the last update's attitude times
    ``exp(Σθ)`` of the samples since (used only as quadrature nodes for Θ).  The sample indices
    ``epochs`` must be attitudes of the algorithm: where an epoch falls inside an update the
    update is cut there (the integrator applies the pending increments one by one), so that
    every equation uses the algorithm's own attitude.
    """
    inc = np.asarray(increments, dtype=float)
    n = len(inc)
    integ = AttitudeIntegrator(algorithm, q0, initial_time=0.0, nominal_period=h,
                               propagate_covariance=False)
    per = integ.algorithm.samples
    anchor_q = {0: quat_normalize(np.asarray(q0, dtype=float))}
    cuts, offset = [], 0
    for e in sorted(set(int(e) for e in epochs if 0 < int(e) <= n)):
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
    a = np.where(small, h ** 2 * (0.5 - x ** 2 / 24.0 + x ** 4 / 720.0), (1.0 - np.cos(x)) / ws ** 2)
    b = np.where(small, h ** 3 * (1.0 / 6.0 - x ** 2 / 120.0 + x ** 4 / 5040.0), (x - np.sin(x)) / ws ** 3)
    return h * np.eye(3) + a[..., None, None] * K + b[..., None, None] * (K @ K)


def theta_quadrature(q, increments, h: float, structure: ErrorStructure = TKACHENKO_STRUCTURE,
                     method: str = 'exact', samples_per_update: int = 2, t0: float = 0.0) -> np.ndarray:
    """
    ``Θ(t_s) = ∫_{t0}^{t_s} Bᵀ D(ω*, t) dt`` at every sample boundary s (N+1, 3, 3m).

    ``method='exact'``: per gyro interval, with ω* = θ/h constant on it,
    ``Bᵀ(t) = Bᵀ(t_{s−1})·exp([ω*×](t − t_{s−1}))`` integrates in closed form — exact for rates
    that are constant on each interval (the §6 profile), O(h³) locally otherwise.
    ``method='trapezoid'``: the paper's choice, step H = samples_per_update·h,
    ``ΔΘ = H/2·(Bᵀ_a + Bᵀ_b)·D(ω̄)`` with ω̄ the mean rate of the update (local error O(H³));
    values between update ends are interpolated linearly.
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


# --------------------------------------------------------------------------- normal equations (5.8)
class NormalEquations:
    """
    Recursive least squares accumulation (5.8): ``(UᵀU)_s = (UᵀU)_{s−1} + u_sᵀu_s``,
    ``(UᵀZ)_s = (UᵀZ)_{s−1} + u_sᵀz_s`` — one scalar row at a time, no row is stored.

    A weighted block (``weight`` = R⁻¹, 3×3) is first whitened with the Cholesky factor of R⁻¹,
    so its three rows are again added one by one.
    """

    def __init__(self, size: int):
        self.size = int(size)
        self.UtU = np.zeros((size, size))
        self.UtZ = np.zeros(size)
        self.ZtZ = 0.0
        self.rows = 0

    def add_row(self, u: np.ndarray, z: float) -> None:
        u = np.asarray(u, dtype=float)
        self.UtU += np.outer(u, u)
        self.UtZ += u * z
        self.ZtZ += z * z
        self.rows += 1

    def add(self, U: np.ndarray, z: np.ndarray, weight: np.ndarray | None = None) -> None:
        U = np.atleast_2d(np.asarray(U, dtype=float))
        z = np.atleast_1d(np.asarray(z, dtype=float))
        if weight is not None:
            L = np.linalg.cholesky(np.asarray(weight, dtype=float))      # W = L Lᵀ
            U, z = L.T @ U, L.T @ z
        for u_s, z_s in zip(U, z):
            self.add_row(u_s, z_s)

    def solve(self, rcond: float = 1e-13) -> np.ndarray:
        """
        Solution of ``UᵀU x = UᵀZ`` with column equilibration (the columns differ in units);
        minimum-norm (pseudo-inverse) when the matrix is singular — an unobservable problem, which
        the observability report flags.
        """
        s = np.sqrt(np.maximum(np.diag(self.UtU), 1e-300))
        Ns = self.UtU / np.outer(s, s)
        return np.linalg.lstsq(Ns, self.UtZ / s, rcond=rcond)[0] / s

    def residual_ss(self, x: np.ndarray) -> float:
        """``|Ux − Z|²`` from the accumulated sums (no rows needed)."""
        x = np.asarray(x, dtype=float)
        return float(max(self.ZtZ - 2.0 * x @ self.UtZ + x @ self.UtU @ x, 0.0))


# --------------------------------------------------------------------------- equations
#: Where the coefficients of the first-order equations are evaluated (see the module docstring).
COEFFICIENTS = ('identity', 'printed')


def measurement_rows(p_ref: np.ndarray, theta: np.ndarray, psi: np.ndarray,
                     psi0: np.ndarray | None = None, p_computed: np.ndarray | None = None) -> np.ndarray:
    """
    Coefficient block of (2.7)/(5.7) for one epoch: ``[2Φ(p), ΓΘ, ΓΨ]``, Γ = ½(p0E3 − Φ(p)).

    ``p_ref`` (4,) the reference increment P; ``psi0`` = Ψ(t0, t*) when t* < t0 (adds
    ``−Φ(p)Ψ(t0, t*)`` to the d columns, see the module docstring).

    ``p_computed`` (4,) the computed increment P*: if given, the coefficients are evaluated where
    the exact quaternion identity puts them ('identity' coefficients): the w0 columns at the
    mean ``2Φ(½(p + p*))``, the c columns at ``Γ(p*)``, the d columns at ``Γ(p)``.  Without it,
    everything at the reference p, as printed in 000.  The two agree to first order.
    """
    p0, p = p_ref[0], p_ref[1:]
    F = skew(p)
    gamma = 0.5 * (p0 * np.eye(3) - F)
    dcols = gamma @ psi
    if p_computed is None:
        F_w, gamma_c = F, gamma
    else:
        F_w = skew(0.5 * (p + p_computed[1:]))
        gamma_c = 0.5 * (p_computed[0] * np.eye(3) - skew(p_computed[1:]))
    if psi0 is not None:
        dcols = dcols - F_w @ psi0
    return np.hstack([2.0 * F_w, gamma_c @ theta, dcols])


def quantization_covariance(p_ref: np.ndarray, quantum: float, angle_noise: float = 0.0) -> np.ndarray:
    """
    ``R(δz)`` of one equation: ``σ²/48·(E3 − ppᵀ)`` (000 §5, corrected; checked by Monte Carlo
    in the tests) plus a rough isotropic term ``½·angle_noise²·E3`` for white noise of the aircraft angles
    (half-angle errors of the two epochs; the t0 part, common to all equations, is not modelled).
    """
    p = p_ref[1:]
    R = quantum ** 2 / 48.0 * (np.eye(3) - np.outer(p, p))
    if angle_noise > 0:
        R = R + 0.5 * angle_noise ** 2 * np.eye(3)
    return R


def quantization_weight(p_ref: np.ndarray, quantum: float, angle_noise: float = 0.0,
                        min_p0: float = 1e-3) -> np.ndarray:
    """``R(δz)⁻¹``; for pure quantization ``48/σ²·(E3 + ppᵀ/p0²)`` (Sherman–Morrison)."""
    p0, p = p_ref[0], p_ref[1:]
    if angle_noise <= 0:
        return 48.0 / quantum ** 2 * (np.eye(3) + np.outer(p, p) / max(p0 * p0, min_p0 ** 2))
    return np.linalg.inv(quantization_covariance(p_ref, quantum, angle_noise))


def _align(P: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Flip quaternions of P onto the hemisphere of ref (both describe the same rotation)."""
    s = np.sign(np.sum(P * ref, axis=-1))
    s[s == 0] = 1.0
    return P * s[..., None]


# --------------------------------------------------------------------------- the estimator
@dataclass
class TkachenkoSolution:
    x: np.ndarray                       # [w0, c, d]
    structure: ErrorStructure
    normal: np.ndarray                  # UᵀU of the last linearisation (weighted if weighted)
    covariance: np.ndarray              # of x: σ̂²(UᵀU)⁻¹ (unweighted) or (UᵀU)⁻¹ (weighted)
    residual_rms: float                 # of z − Ux at the solution, per scalar equation
    iterations: int
    steps: list = field(default_factory=list)        # |step|∞ of each Gauss–Newton iteration
    observability: ObservabilityReport | None = None
    epochs: np.ndarray = field(default_factory=lambda: np.zeros(0))   # sample indices of the equations
    refined_attitude: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))  # Λ̂ at epochs
    w_epochs: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))          # ŵ(t_j)
    equations: int = 0
    skipped: int = 0                     # epochs left out (|p0| < min_p0)
    elapsed: float = 0.0

    @property
    def w0(self):
        return self.structure.split(self.x)[0]

    @property
    def c(self):
        return self.structure.split(self.x)[1]

    @property
    def d(self):
        return self.structure.split(self.x)[2]


def _correct_increments(meas, c, structure: ErrorStructure, h: float, t0: float, iters: int = 6):
    """Gyro increments with the error ``D(ω, t)c`` removed: ``θ = θ* − D(θ/h, t_mid)c·h``."""
    if not np.any(c):
        return np.array(meas, dtype=float, copy=True)
    t_mid = t0 + h * (np.arange(len(meas)) + 0.5)
    th = np.array(meas, dtype=float, copy=True)
    for _ in range(iters):           # contraction |c| ~ 1e-3 per pass
        new = meas - np.einsum('nij,j->ni', structure.D(th / h, t_mid), c) * h
        done = np.max(np.abs(new - th)) <= 1e-18
        th = new
        if done:
            break
    return th


def predicted_reference_increments(x, M0, meas, h: float, epochs, structure: ErrorStructure,
                                   algorithm: str = '2', t0: float = 0.0, t_star: float | None = None):
    """
    Exact nonlinear model of P at the epochs for parameters x:
    ``P̂ = exp(Ψ(t,t*)d)*⊗Λ̂(t)⊗Λ̂(t0)*⊗exp(Ψ(t0,t*)d)`` with Λ̂ integrated from
    ``normalize([1, w0])⊗M(t0)`` with the corrected increments.  Also returns Λ̂ at all
    boundaries and the corrected increments.
    """
    w0, c, d = structure.split(x)
    ts = t0 if t_star is None else t_star
    th = _correct_increments(meas, c, structure, h, t0)
    L0 = quat_multiply(quat_normalize(np.concatenate([[1.0], w0])), M0)
    Lam = integrate_attitude(L0, th, h, algorithm, epochs)
    ep = np.asarray(epochs, dtype=int)
    t_ep = t0 + h * ep
    V = rotvec_to_quat(psi_matrix(structure, t_ep, ts) @ d)
    V0 = rotvec_to_quat(psi_matrix(structure, np.array(t0), ts) @ d)
    P = quat_multiply(quat_conjugate(V), quat_multiply(quat_multiply(Lam[ep], quat_conjugate(Lam[0])), V0))
    return P, Lam, th


def estimate(meas, h: float, M0, ref_q0, ref_q, epochs, structure: ErrorStructure = TKACHENKO_STRUCTURE,
             algorithm: str = '2', quadrature: str = 'exact', mode: str = 'raw', quantum: float = 0.0,
             iterate: bool = False, weighted: bool = False, t0: float = 0.0, t_star: float | None = None,
             tol: float = 1e-13, max_iter: int = 12, angle_noise: float = 0.0, min_p0: float = 0.05,
             noise_sigma: float | None = None, coefficients: str = 'identity') -> TkachenkoSolution:
    """
    Estimate x = [w0, c, d] (000 §2–§5) from gyro increments and reference quaternions.

    meas: measured increments θ* (N, 3) on the grid t0 + k·h (quantized or not).
    M0: the computed attitude M(t0) (with its unknown error w0).
    ref_q0, ref_q: N(φ(t0)) and N(φ(t_j)) at the epochs (sample indices ``epochs``).
    mode: 'raw' (5.4), 'centred' (5.5) or 'corrected' (5.6, increments corrected before use).
    iterate: Gauss–Newton on the full model (re-integration about the current estimate).
    weighted: weight the equations by R(δz)⁻¹ (needs quantum > 0 or angle_noise > 0).
    noise_sigma: σ of z for the observability report of an unweighted solution (default: the
        quantization σ/√48, else the a-posteriori residual RMS).
    coefficients: 'identity' (default) evaluates the coefficients of (2.7) where the exact
        identity ``p° − q = w0 × (p° + q)`` puts them, 'printed' at the reference increment p as
        000 prints (5.7).  Same cost, same first order; 'printed' leaves the w0² term in z
        (see the module docstring).  For ``iterate=True`` both converge to the same solution.
    """
    t_start = _time.perf_counter()
    if mode not in MODES:
        raise ValueError(f"unknown mode {mode!r}; valid: {', '.join(MODES)}")
    if quadrature not in QUADRATURES:
        raise ValueError(f"unknown quadrature {quadrature!r}; valid: {', '.join(QUADRATURES)}")
    if coefficients not in COEFFICIENTS:
        raise ValueError(f"unknown coefficients {coefficients!r}; valid: {', '.join(COEFFICIENTS)}")
    if mode != 'raw' and not quantum > 0:
        raise ValueError(f'mode {mode!r} needs quantum > 0')
    if weighted and not (quantum > 0 or angle_noise > 0):
        raise ValueError('weighted=True needs quantum > 0 or angle_noise > 0 (R(δz) would be 0)')
    meas = np.asarray(meas, dtype=float)
    epochs = np.asarray(epochs, dtype=int)
    ts = t0 if t_star is None else float(t_star)
    per = get_algorithm(algorithm).samples
    if mode == 'corrected':
        meas_used, _ = increment_correction(meas, quantum)
    else:
        meas_used = meas
    t_ep = t0 + h * epochs
    psi = psi_matrix(structure, t_ep, t0)
    psi0 = psi_matrix(structure, np.array(t0), ts) if ts < t0 else None
    # reference increments P (sign: the hemisphere of the computed increment)
    N0 = np.asarray(ref_q0, dtype=float)
    P_ref = quat_multiply(np.asarray(ref_q, dtype=float), quat_conjugate(N0))
    signs = np.sign(meas[np.clip(epochs - 1, 0, len(meas) - 1)])      # ρ*: sign θ*_{i,k} at t_j
    p = structure.size
    x = np.zeros(p)
    steps = []
    ne = None
    it = 0
    keep = np.abs(P_ref[:, 0]) >= min_p0
    while True:
        P_hat, Lam, th = predicted_reference_increments(x, M0, meas_used, h, epochs, structure, algorithm, t0, ts)
        P = _align(P_ref, P_hat)
        Theta = theta_quadrature(Lam, th, h, structure, quadrature, per, t0)
        C_ep = quat_to_dcm(Lam[epochs])
        ne = NormalEquations(p)
        for j in range(len(epochs)):
            if not keep[j]:
                continue
            U = measurement_rows(P[j], Theta[epochs[j]], psi[j], psi0,
                                 P_hat[j] if coefficients == 'identity' else None)
            z = P_hat[j, 1:] - P[j, 1:]
            if mode == 'centred':
                p0j, pj = P[j, 0], P[j, 1:]
                z = z + 0.25 * quantum * (p0j * np.eye(3) - skew(pj)) @ C_ep[j] @ signs[j]
            W = quantization_weight(P[j], quantum, angle_noise) if weighted else None
            ne.add(U, z, W)
        step = ne.solve()
        x = x + step
        it += 1
        steps.append(float(np.max(np.abs(step))))
        if not iterate or steps[-1] < tol or it >= max_iter or (it > 2 and steps[-1] >= steps[-2]):
            break
    # refined attitude at the epochs
    w0, c, d = structure.split(x)
    if iterate:
        _, Lam_hat, _ = predicted_reference_increments(x, M0, meas_used, h, epochs, structure, algorithm, t0, ts)
        refined = Lam_hat[epochs]
        w_ep = np.zeros((len(epochs), 3))
    else:
        # 000 (2.4): Λ ≈ (1 + w(t))∘M(t), w(t) = w0 − ½Θ(t)c, first order, from the unrefined pass
        w_ep = w0 - 0.5 * np.einsum('nij,j->ni', Theta[epochs], c)
        M_ep = Lam[epochs]
        if mode == 'centred':            # the same model as the centred residual: M ≈ (1 + ¼σBᵀρ*)M*
            cq = 0.25 * quantum * np.einsum('nij,nj->ni', C_ep, signs)
            M_ep = quat_multiply(quat_normalize(np.concatenate([np.ones((len(cq), 1)), cq], 1)), M_ep)
        refined = quat_multiply(quat_normalize(np.concatenate([np.ones((len(w_ep), 1)), w_ep], 1)), M_ep)
    # statistics of the last linearisation (about the final estimate when iterated)
    rss = ne.residual_ss(step)
    dof = max(ne.rows - p, 1)
    inv = np.linalg.pinv(ne.UtU, rcond=1e-15, hermitian=True)
    if weighted:
        cov = inv
        info = ne.UtU
    else:
        s2 = rss / dof
        if noise_sigma is not None:
            sz2 = noise_sigma ** 2
        elif quantum > 0:
            sz2 = quantum ** 2 / 48.0
        else:
            sz2 = max(s2, 1e-32)
        cov = s2 * inv
        info = ne.UtU / sz2
    rep = analyze_information(info, labels=structure.labels)
    return TkachenkoSolution(x=x, structure=structure, normal=ne.UtU, covariance=cov,
                             residual_rms=float(np.sqrt(rss / max(ne.rows, 1))), iterations=it, steps=steps,
                             observability=rep, epochs=epochs, refined_attitude=refined, w_epochs=w_ep,
                             equations=int(keep.sum()), skipped=int((~keep).sum()),
                             elapsed=_time.perf_counter() - t_start)


def error_at_epochs(refined: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """w⁰: vector part of ``Λ⊗Λ̂*`` with scalar ≥ 0 (half-angle vector, reference axes)."""
    e = quat_multiply(truth, quat_conjugate(refined))
    e = np.where(e[..., :1] < 0, -e, e)
    return e[..., 1:]


# --------------------------------------------------------------------------- observability (§3, §4)
def rank_test(omegas, attitudes, times, structure: ErrorStructure = TKACHENKO_STRUCTURE,
              rel_tol: float = 1e-9) -> dict:
    """
    000 (3.1): rank of the rows ``[Φ(ω_j), D(ω_j, t_j), A(t_j)G(t_j)]`` over the chosen points.

    ``omegas`` (r, 3) body rates; ``attitudes`` (r, 4) ``Λ(t_j) = q_I_E`` (A = C_E_I);
    full observability ⇔ rank = 3(m + n + 1).  The columns are scaled to unit norm before the
    SVD (they carry different units); rank = number of singular values > rel_tol·max.
    """
    om = np.asarray(omegas, dtype=float)
    A = np.swapaxes(quat_to_dcm(np.asarray(attitudes, dtype=float)), -1, -2)
    t = np.asarray(times, dtype=float)
    D = np.asarray(structure.D(om, t), dtype=float)
    G = np.asarray(structure.G(t), dtype=float)
    rows = np.concatenate([skew(om), D, A @ G], axis=-1).reshape(-1, structure.size)
    norms = np.linalg.norm(rows, axis=0)
    scaled = rows / np.where(norms > 0, norms, 1.0)
    sv = np.linalg.svd(scaled, compute_uv=False)
    rank = int(np.sum(sv > rel_tol * sv[0])) if sv.size and sv[0] > 0 else 0
    return {'rank': rank, 'required': structure.size, 'observable': rank == structure.size,
            'singular_values': sv, 'rows': rows}


def simple_case_test(omegas, attitudes, rel_tol: float = 1e-9) -> dict:
    """
    000 §4, m = n = 1, D = G = E3, four points t1..t4.

    * (4.1): rank of ``[Φ(ω_j) − Φ(ω1), A_j − A1]`` (j = 2, 3, 4) must be 6;
    * (4.2) sufficient conditions: the vectors ``ν_j × (ω_j − ω1)`` are independent (no ω ≠ 0
      solves (4.2)) and ``(ω_j − ω1) × ν_j sin α_j + [(ω_j − ω1) × ν_j] × ν_j (1 − cos α_j)``
      are independent (no v ≠ 0), with ``A_j = S(t_j, t1)A1``,
      ``S = E3 + Φ(ν)sin α + (1 − cos α)Φ²(ν)``: ν α = log(A_j A1ᵀ) (our rotation vector of S).
    """
    om = np.asarray(omegas, dtype=float).reshape(4, 3)
    A = np.swapaxes(quat_to_dcm(np.asarray(attitudes, dtype=float).reshape(4, 4)), -1, -2)
    M41 = np.vstack([np.hstack([skew(om[j]) - skew(om[0]), A[j] - A[0]]) for j in (1, 2, 3)])
    sv = np.linalg.svd(M41 / np.maximum(np.linalg.norm(M41, axis=0), 1e-300), compute_uv=False)
    rank = int(np.sum(sv > rel_tol * sv[0]))
    vw, vv = [], []
    for j in (1, 2, 3):
        S = A[j] @ A[0].T
        rv = quat_to_rotvec(dcm_to_quat(S))
        alpha = np.linalg.norm(rv)
        nu = rv / alpha if alpha > 0 else np.zeros(3)
        dw = om[j] - om[0]
        vw.append(np.cross(nu, dw))
        a = np.cross(dw, nu)
        vv.append(a * np.sin(alpha) + np.cross(a, nu) * (1.0 - np.cos(alpha)))

    def independent(vs):
        m = np.array(vs)
        s = np.linalg.svd(m, compute_uv=False)
        return bool(s[0] > 0 and s[-1] > rel_tol * max(s[0], 1e-300) and s[-1] > 1e-14)

    return {'rank_41': rank, 'condition_41': rank == 6, 'omega_vectors_independent': independent(vw),
            'v_vectors_independent': independent(vv),
            'sufficient': independent(vw) and independent(vv)}
