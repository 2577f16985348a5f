"""
Observability of estimation problems: one module every estimator reports through.

Static (least-squares) case — :func:`analyze_information`
    Given the whitened information matrix ``N = Σ Hᵀ W H`` of a least-squares problem, its
    eigen-decomposition says which parameter combinations the data determine:

    * an eigenvalue 0 (relative to the largest): the combination along its eigenvector is
      **unobservable** — the data cannot tell it from zero;
    * a small eigenvalue: **weakly observable**;
    * the predicted standard deviation of the combination along the unit eigenvector v is
      ``σ_v = 1/√λ_v`` (in units of the measurement noise when W is the inverse noise
      covariance).

    The predicted σ of an *arbitrary* combination ``aᵀx`` is ``√(aᵀ N⁻¹ a)``
    (:func:`combination_sigma`).  It equals ``1/√λ`` only when a is an eigenvector of N; for a
    single parameter it is ``√(N⁻¹)_ii``, never smaller than the ``1/√λ`` of any
    eigen-direction.

Dynamic (linear time-varying) case — :func:`observability_gramian`,
:func:`measures_of_observability`
    For ``ẋ = F(t) x``, ``σ(t) = H(t) x + r(t)`` on ``[t0, t1]`` the observability Gramian is
    ``W = ∫ Φ(t,t0)ᵀ H(t)ᵀ H(t) Φ(t,t0) dt``; x(t0) is observable on the interval iff W > 0.

Measure of observability (Vavilov 1982; paper 001, §4.1 after eq. (4.6), citing Parusnikov,
Kalenova, Morozov, Shakot'ko 1980 = 001's ref. [6]).  001 uses it as: *a variable observable
with measure m is estimated with accuracy of order Δσ/m*, Δσ the level of the measurement error
(so a variable measured directly has measure 1).  Reference [6] itself is not available to us;
we implement two readings of that sentence, both exact statements about the least-squares
estimate:

* ``measures_of_observability(W̄, a)`` — **Gramian measure**: ``m(a) = 1/√(aᵀ W̄⁻¹ a)`` with
  the interval-mean Gramian ``W̄ = W/(t1−t0)``.  If σ is sampled n times uniformly on the
  interval with independent errors of σ Δσ, the estimate of ``aᵀx(t0)`` has σ = Δσ/(m √n).
  m = 1 for a constant measured directly; m is invariant to a change of time unit.
* ``stationary_measures(A, H, T)`` — **derivative measure** for a stationary system on an
  interval of length T: with time normalised to the interval (A → A·T), σ and its derivatives
  of orders 0…n−1 are available to accuracy Δσ; x = O⁻¹(σ, σ̇, …) with the observability
  matrix ``O = [H; HA; …; HAⁿ⁻¹]``, so ``m_i = 1/‖row_i(O⁻¹)‖``.  This is the reading that
  reproduces 001's printed orders — derivation in
  doc/results/reproductions/observability_001.md §5.  The Gramian reading reaches those orders
  only over about one Schuler period, not on 001's unit interval.

001's measure is not in general the 1/√λ of :func:`analyze_information`: it is a measure of a
*given* combination, ``1/√(aᵀN⁻¹a)``, and it is normalised per sample and per unit interval
(W̄), whereas N grows with the number of samples (doc/results/reproductions/observability_001.md).
:func:`analyze_information` therefore also reports the σ of each parameter
(``parameter_sigma = √diag N⁻¹``) and :func:`combination_sigma` gives any other.

No ROS imports; numpy only.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

__all__ = ['ObservabilityReport', 'analyze_information', 'combination_sigma', 'expm',
           'GramianResult', 'observability_gramian', 'measures_of_observability',
           'stationary_measures', 'observability_matrix']


@dataclass
class ObservabilityReport:
    """
    What an information matrix determines: its eigen-directions, classified.

    Parameters
    ----------
    observable : bool
        No combination is unobservable.
    eigenvalues : ndarray (n,)
        Eigenvalues of N, ascending.
    directions : ndarray (n, n)
        Columns: unit eigenvectors, same order.
    predicted_sigma : ndarray (n,)
        1/√λ per direction (inf where λ ≤ 0).
    unobservable : list of str
        The unobservable combinations, in words.
    weak : list of str
        The weakly observable ones.
    condition : float
        λ_max / λ_min.
    message : str
        One line: observable, or what is not.
    parameter_sigma : ndarray (n,), optional
        √(N⁻¹)_ii per parameter (inf if not observable).

    """

    observable: bool
    eigenvalues: np.ndarray
    directions: np.ndarray
    predicted_sigma: np.ndarray
    unobservable: list[str] = field(default_factory=list)
    weak: list[str] = field(default_factory=list)
    condition: float = np.inf
    message: str = ''
    parameter_sigma: np.ndarray | None = None

    def as_dict(self) -> dict:
        """
        Return the report as plain JSON values.

        Returns
        -------
        dict
            Every field; directions as rows.

        """
        out = {'observable': self.observable, 'eigenvalues': self.eigenvalues.tolist(),
               'directions': self.directions.T.tolist(),
               'predicted_sigma': self.predicted_sigma.tolist(),
               'unobservable': list(self.unobservable), 'weak': list(self.weak),
               'condition': float(self.condition), 'message': self.message}
        if self.parameter_sigma is not None:
            out['parameter_sigma'] = self.parameter_sigma.tolist()
        return out


def _pinv_quadratic(lam: np.ndarray, vec: np.ndarray, a: np.ndarray, rel_tol: float) -> float:
    """Return aᵀ N⁻¹ a from N's eigen-decomposition; inf if a has a null-space component."""
    lam_max = max(float(lam[-1]), 0.0)
    proj = vec.T @ a
    null = lam <= rel_tol * lam_max if lam_max > 0 else np.ones_like(lam, dtype=bool)
    if np.any(np.abs(proj[null]) > 1e-9 * max(np.linalg.norm(a), 1e-300)):
        return np.inf
    return float(np.sum(proj[~null] ** 2 / lam[~null]))


def combination_sigma(info: np.ndarray, combinations: np.ndarray,
                      rel_tol: float = 1e-12) -> np.ndarray:
    """
    Return the predicted σ of each combination ``aᵀx``: ``√(aᵀ N⁻¹ a)``.

    Parameters
    ----------
    info : ndarray (n, n)
        The information matrix N.
    combinations : ndarray (k, n) or (n,)
        Rows a.
    rel_tol : float
        Eigenvalues below ``rel_tol`` λ_max count as zero.

    Returns
    -------
    ndarray (k,)
        σ; inf for a combination the information does not determine (a component in N's
        null space).

    """
    info = 0.5 * (np.asarray(info, float) + np.asarray(info, float).T)
    lam, vec = np.linalg.eigh(info)
    rows = np.atleast_2d(np.asarray(combinations, float))
    return np.sqrt([_pinv_quadratic(lam, vec, a, rel_tol) for a in rows])


def analyze_information(info: np.ndarray, describe: Callable[[np.ndarray], str] | None = None,
                        labels: Sequence[str] | None = None, rel_tol: float = 1e-9,
                        sigma_limit: float | None = None,
                        weak_ratio: float = 1e-4) -> ObservabilityReport:
    """
    Classify the combinations of an information matrix.

    Parameters
    ----------
    info : ndarray (n, n)
        The information matrix N (symmetrised here).
    describe : callable, optional
        Turns a unit direction into words (default: components with ``labels``).
    labels : sequence of str, optional
        Parameter names for the default description.
    rel_tol : float
        λ ≤ rel_tol·λ_max counts as unobservable (singular to working accuracy).
    sigma_limit : float, optional
        A predicted σ above it also counts as unobservable (too poorly determined to publish).
    weak_ratio : float
        λ ≤ weak_ratio·λ_max (and not unobservable) counts as weakly observable.

    Returns
    -------
    ObservabilityReport
        The classification.

    """
    info = 0.5 * (np.asarray(info, dtype=float) + np.asarray(info, dtype=float).T)
    lam, vec = np.linalg.eigh(info)
    lam_max = max(float(lam[-1]), 0.0)
    with np.errstate(divide='ignore'):
        sigma = np.where(lam > 0, 1.0 / np.sqrt(np.maximum(lam, 1e-300)), np.inf)
    if describe is None:
        names = list(labels) if labels is not None else [f'x{i}' for i in range(len(lam))]

        def describe(v):
            v = v * np.sign(v[np.argmax(np.abs(v))])
            terms = [f'{c:+.2f}·{n}' for c, n in zip(v, names) if abs(c) >= 0.005]
            return ' '.join(terms) if terms else '0'
    unobs, weak = [], []
    for i in range(len(lam)):
        v = vec[:, i]
        bad = (lam_max <= 0 or lam[i] <= rel_tol * lam_max
               or (sigma_limit is not None and sigma[i] > sigma_limit))
        if bad:
            unobs.append(describe(v))
        elif lam[i] <= weak_ratio * lam_max:
            weak.append(describe(v))
    cond = lam_max / lam[0] if lam[0] > 0 else np.inf
    par_sigma = np.sqrt([_pinv_quadratic(lam, vec, e, rel_tol) for e in np.eye(len(lam))])
    rep = ObservabilityReport(observable=not unobs, eigenvalues=lam, directions=vec,
                              predicted_sigma=sigma, unobservable=unobs, weak=weak,
                              condition=cond, parameter_sigma=par_sigma)
    rep.message = ('observable' if not unobs else 'not observable: ' + '; '.join(unobs)) + \
        (f" (weakly observable: {'; '.join(weak)})" if weak else '')
    return rep


# ------------------------------------------------------------------------------ dynamic case
def expm(a: np.ndarray) -> np.ndarray:
    """
    Return the matrix exponential, by scaling and squaring of a Taylor series (numpy only).

    The matrix is scaled by 2⁻ˢ to norm ≤ 0.5; 20 Taylor terms then leave a truncation error
    below 0.5²⁰/20! ≈ 4e-25 relative, so the result is accurate to round-off
    (≈1e-15·‖e^A‖·2ˢ).

    Parameters
    ----------
    a : ndarray (n, n)
        The matrix.

    Returns
    -------
    ndarray (n, n)
        e^a.

    """
    a = np.asarray(a, float)
    norm = np.linalg.norm(a, 1)
    s = max(0, int(np.ceil(np.log2(norm / 0.5)))) if norm > 0.5 else 0
    x = a / 2.0 ** s
    out = np.eye(len(a))
    term = np.eye(len(a))
    for k in range(1, 21):
        term = term @ x / k
        out = out + term
    for _ in range(s):
        out = out @ out
    return out


@dataclass
class GramianResult:
    """
    The observability Gramian over an interval (:func:`observability_gramian`).

    Parameters
    ----------
    gramian : ndarray (n, n)
        W = ∫ Φᵀ Hᵀ H Φ dt over [t0, t1].
    transition : ndarray (n, n)
        Φ(t1, t0).
    duration : float
        t1 − t0.
    relative_error : float
        Richardson estimate of ‖W_h − W‖/‖W‖ (0 for constant F, H).

    """

    gramian: np.ndarray
    transition: np.ndarray
    duration: float
    relative_error: float

    @property
    def mean(self) -> np.ndarray:
        """Return W̄ = W/(t1 − t0): the information per unit time, which 001's measure uses."""
        return self.gramian / self.duration


def _gramian_pass(F, H, t0, t1, steps):
    h = (t1 - t0) / steps
    n = F(t0).shape[0]
    W = np.zeros((n, n))
    Phi = np.eye(n)
    for k in range(steps):
        tm = t0 + (k + 0.5) * h
        Fk = np.asarray(F(tm), float)
        Hk = np.atleast_2d(np.asarray(H(tm), float))
        # Van Loan: exp([[-Fᵀ, HᵀH], [0, F]] h) = [[e^{-Fᵀh}, Q], [0, e^{Fh}]],
        # ∫₀ʰ e^{Fᵀs}HᵀH e^{Fs} ds = e^{Fh}ᵀ Q
        m = np.zeros((2 * n, 2 * n))
        m[:n, :n] = -Fk.T
        m[:n, n:] = Hk.T @ Hk
        m[n:, n:] = Fk
        e = expm(m * h)
        step_phi = e[n:, n:]
        dW = step_phi.T @ e[:n, n:]
        W += Phi.T @ dW @ Phi
        Phi = step_phi @ Phi
    return 0.5 * (W + W.T), Phi


def observability_gramian(F: Callable[[float], np.ndarray], H: Callable[[float], np.ndarray],
                          t0: float, t1: float, steps: int = 200) -> GramianResult:
    """
    Compute the observability Gramian of ẋ = F(t)x, σ = H(t)x.

    ``W = ∫_{t0}^{t1} Φ(t,t0)ᵀ H(t)ᵀ H(t) Φ(t,t0) dt``.  F and H are frozen at the midpoint of
    each of ``steps`` equal sub-intervals; on each the transition matrix and the Gramian
    increment are exact matrix exponentials (Van Loan's block exponential).  One pass is exact
    for constant F, H and second-order accurate otherwise (the midpoint rule's error expands in
    even powers of h); the returned Gramian is the Richardson combination (4W_h − W_{2h})/3 of
    passes with ``steps`` and ``steps/2`` (even ``steps``), error O(h⁴).

    Parameters
    ----------
    F : callable
        F(t), the (n, n) system matrix.
    H : callable
        H(t), the measurement rows.
    t0, t1 : float
        The interval.
    steps : int
        Sub-intervals.

    Returns
    -------
    GramianResult
        W, Φ(t1, t0), the duration and ``relative_error`` = |W_h − W_{2h}|/(3|W|), the error
        estimate of the *second-order* pass (a conservative bound for the returned matrix).

    """
    W, Phi = _gramian_pass(F, H, t0, t1, steps)
    err = 0.0
    if steps >= 2 and steps % 2 == 0:
        W2, _ = _gramian_pass(F, H, t0, t1, steps // 2)
        err = float(np.linalg.norm(W - W2) / (3.0 * max(np.linalg.norm(W), 1e-300)))
        W = (4.0 * W - W2) / 3.0
    return GramianResult(W, Phi, float(t1 - t0), err)


def measures_of_observability(mean_gramian: np.ndarray, combinations: np.ndarray,
                              rel_tol: float = 1e-12) -> np.ndarray:
    """
    Return 001's measure (Gramian reading) of each combination: ``m = 1/√(aᵀ W̄⁻¹ a)``.

    Parameters
    ----------
    mean_gramian : ndarray (n, n)
        W̄ = W/(t1 − t0) (:attr:`GramianResult.mean`).
    combinations : ndarray (k, n)
        Rows a of the combinations ``aᵀx(t0)`` (e.g. the identity for the state variables).
    rel_tol : float
        Eigenvalues below ``rel_tol`` λ_max count as zero.

    Returns
    -------
    ndarray (k,)
        m; 0 for an unobservable combination.

    """
    sig = combination_sigma(mean_gramian, combinations, rel_tol)
    with np.errstate(divide='ignore'):
        return np.where(np.isfinite(sig), 1.0 / sig, 0.0)


def observability_matrix(A: np.ndarray, H: np.ndarray) -> np.ndarray:
    """
    Return O = [H; HA; HA²; …; HAⁿ⁻¹] of a stationary system.

    Parameters
    ----------
    A : ndarray (n, n)
        System matrix.
    H : ndarray (m, n)
        Measurement rows.

    Returns
    -------
    ndarray (m n, n)
        O; row block k is the k-th derivative of σ.

    """
    A = np.asarray(A, float)
    H = np.atleast_2d(np.asarray(H, float))
    blocks, row = [], H
    for _ in range(A.shape[0]):
        blocks.append(row)
        row = row @ A
    return np.vstack(blocks)


def stationary_measures(A: np.ndarray, H: np.ndarray, interval: float = 1.0,
                        combinations: np.ndarray | None = None,
                        rel_tol: float = 1e-12) -> np.ndarray:
    """
    Return 001's measure (derivative reading) for a stationary system ẋ = Ax, σ = Hx.

    Time is normalised to the interval (A → A·interval); σ and its derivatives are taken as
    known to the measurement accuracy, so the combination aᵀx(0) = aᵀ O⁺ (σ, σ', …) has error
    Δσ·‖aᵀO⁺‖ and measure ``m = 1/‖aᵀ O⁺‖``.

    Parameters
    ----------
    A : ndarray (n, n)
        System matrix.
    H : ndarray (m, n)
        Measurement rows.
    interval : float
        Length of the interval, in A's time unit.
    combinations : ndarray (k, n), optional
        Rows a (default: the state variables).
    rel_tol : float
        Singular values below ``rel_tol`` times the largest count as zero.

    Returns
    -------
    ndarray (k,)
        m; 0 for a combination outside O's row space.

    """
    obs = observability_matrix(np.asarray(A, float) * interval, H)
    n = obs.shape[1]
    rows = np.eye(n) if combinations is None else np.atleast_2d(np.asarray(combinations, float))
    u, s, vt = np.linalg.svd(obs, full_matrices=False)
    keep = s > rel_tol * s[0]
    out = []
    for a in rows:
        proj = vt @ a
        if np.linalg.norm(proj[~keep]) > 1e-9 * np.linalg.norm(a):
            out.append(0.0)
            continue
        coeff = u[:, keep] @ (proj[keep] / s[keep])        # aᵀO⁺ as a vector over the derivatives
        out.append(1.0 / np.linalg.norm(coeff))
    return np.asarray(out)
