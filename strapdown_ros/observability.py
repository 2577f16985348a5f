"""Observability of linearised estimation problems: one module every estimator reports through.

Given the (whitened) information matrix ``N = Σ Hᵀ W H`` of a least-squares problem, its
eigen-decomposition says which parameter combinations the data determine:

* an eigenvalue 0 (relative to the largest): the combination along its eigenvector is
  **unobservable** — the data cannot tell it from zero;
* a small eigenvalue: **weakly observable**;
* the predicted standard deviation of the combination along eigenvector v is
  ``σ_v = 1/√λ_v`` (in units of the measurement noise when W is the inverse noise
  covariance).  Its inverse, relative to the noise, is the *measure of observability* of
  Vavilov (001): how well a combination is estimated compared with the measurement error.

No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

__all__ = ["ObservabilityReport", "analyze_information"]


@dataclass
class ObservabilityReport:
    observable: bool
    eigenvalues: np.ndarray                     # ascending
    directions: np.ndarray                      # columns: unit eigenvectors, same order
    predicted_sigma: np.ndarray                 # 1/√λ per direction (inf where λ ≤ 0)
    unobservable: list[str] = field(default_factory=list)
    weak: list[str] = field(default_factory=list)
    condition: float = np.inf                   # λ_max / λ_min
    message: str = ""

    def as_dict(self) -> dict:
        return {"observable": self.observable, "eigenvalues": self.eigenvalues.tolist(),
                "directions": self.directions.T.tolist(), "predicted_sigma": self.predicted_sigma.tolist(),
                "unobservable": list(self.unobservable), "weak": list(self.weak),
                "condition": float(self.condition), "message": self.message}


def analyze_information(info: np.ndarray, describe: Callable[[np.ndarray], str] | None = None,
                        labels: Sequence[str] | None = None, rel_tol: float = 1e-9,
                        sigma_limit: float | None = None, weak_ratio: float = 1e-4) -> ObservabilityReport:
    """Classify the combinations of an information matrix.

    rel_tol: λ ≤ rel_tol·λ_max counts as unobservable (the matrix is singular to working accuracy).
    sigma_limit: a predicted σ above it also counts as unobservable (too poorly determined to publish).
    weak_ratio: λ ≤ weak_ratio·λ_max (and not unobservable) counts as weakly observable.
    describe: turns a unit direction into words (default: components with ``labels``).
    """
    info = 0.5 * (np.asarray(info, dtype=float) + np.asarray(info, dtype=float).T)
    lam, vec = np.linalg.eigh(info)
    lam_max = max(float(lam[-1]), 0.0)
    with np.errstate(divide="ignore"):
        sigma = np.where(lam > 0, 1.0 / np.sqrt(np.maximum(lam, 1e-300)), np.inf)
    if describe is None:
        names = list(labels) if labels is not None else [f"x{i}" for i in range(len(lam))]

        def describe(v):
            v = v * np.sign(v[np.argmax(np.abs(v))])
            terms = [f"{c:+.2f}·{n}" for c, n in zip(v, names) if abs(c) >= 0.005]
            return " ".join(terms) if terms else "0"
    unobs, weak = [], []
    for i in range(len(lam)):
        v = vec[:, i]
        bad = lam_max <= 0 or lam[i] <= rel_tol * lam_max or (sigma_limit is not None and sigma[i] > sigma_limit)
        if bad:
            unobs.append(describe(v))
        elif lam[i] <= weak_ratio * lam_max:
            weak.append(describe(v))
    cond = lam_max / lam[0] if lam[0] > 0 else np.inf
    rep = ObservabilityReport(observable=not unobs, eigenvalues=lam, directions=vec, predicted_sigma=sigma,
                              unobservable=unobs, weak=weak, condition=cond)
    rep.message = ("observable" if not unobs else "not observable: " + "; ".join(unobs)) + \
        (f" (weakly observable: {'; '.join(weak)})" if weak else "")
    return rep
