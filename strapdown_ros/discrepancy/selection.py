"""
The tests that choose an effect in the discrepancy workflow: score, held-out gain, separability.

Each candidate effect is scored by its likelihood-ratio statistic against the current model
(:func:`score_candidate`); a significant one must also improve the held-out −2 log L over
contiguous time blocks (:class:`TimeBlocks`, :func:`heldout_score`); two candidates whose
fitted whitened signatures correlate above :data:`RHO_MAX` are not separable
(:func:`separation`) unless the encompassing test tells them apart (:func:`adds_to`).  The
search that uses them is :mod:`strapdown_ros.discrepancy.workflow`.  No ROS imports.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.discrepancy.linearisation import fit_noise, Linearisation
from strapdown_ros.sensors.effects import EFFECTS

__all__ = ['RHO_MAX', 'TimeBlocks', 'heldout_score', 'separation', 'adds_to', 'score_candidate']

#: canonical correlation above which two whitened signatures are called not separable
RHO_MAX = 0.95


class TimeBlocks:
    """
    Time-blocked cross-validation: ``blocks`` equal spans of the record.

    Fold k judges block k with parameters fitted on the others.  Fixed in time, so it applies
    to any linearisation (the pairs may change with a time offset).

    Parameters
    ----------
    lin : Linearisation
        The linearisation whose pair end stamps span the record.
    blocks : int
        Number of contiguous time blocks.

    """

    def __init__(self, lin: Linearisation, blocks: int):
        t = lin.pairs.t_end
        self.edges = np.linspace(t[0], t[-1] + 1e-9, blocks + 1)
        self.blocks = blocks

    def folds(self, lin: Linearisation) -> list:
        """
        Return the folds of a linearisation: (training mask, test mask) per non-empty block.

        Parameters
        ----------
        lin : Linearisation
            The linearisation whose pairs are split by their end stamps.

        Returns
        -------
        list of tuple of (N,) bool ndarray
            ``(train, test)`` per block, in time order.

        """
        b = np.clip(np.searchsorted(self.edges, lin.pairs.t_end, side='right') - 1, 0,
                    self.blocks - 1)
        return [(b != k, b == k) for k in range(self.blocks) if np.any(b == k)]


def heldout_score(lin: Linearisation, free, noise: dict, split: TimeBlocks, noise_by_fold=None):
    """
    Score a model by leave-one-block-out cross-validation over time blocks.

    Each block is judged by parameters fitted on the other blocks.

    Parameters
    ----------
    lin : Linearisation
        The linearisation at the current model point.
    free : list of str
        Systematic effects fitted with the boresight.
    noise : dict
        The noise terms of the model.
    split : TimeBlocks
        The time blocks.
    noise_by_fold : list of dict, optional
        The noise terms estimated on each fold's training blocks (default: ``noise``).

    Returns
    -------
    nll : float
        −2 log L per judged residual.
    rms : float
        Whitened RMS of the judged residuals.

    """
    total, sq, n = 0.0, 0.0, 0
    for k, (train, test) in enumerate(split.folds(lin)):
        nz = noise if noise_by_fold is None else noise_by_fold[k]
        f_tr = lin.evaluate(free, nz, train)
        rows = lin.rows(test)
        J = lin.design(free)[rows]
        W = lin.whitener(nz, test)
        pred = (lin.residual(nz)[rows] - J @ f_tr.z
                - lin.U[rows][:, lin.prior_var > 0] @ f_tr.x)
        w = W.apply(pred)
        total += float(w @ w) + W.logdet
        sq += float(w @ w)
        n += len(w)
    return total / n, float(np.sqrt(sq / n))


def _span(A: np.ndarray, tol=1e-6) -> np.ndarray:
    if A.shape[1] == 0:
        return A
    U, s, _ = np.linalg.svd(A, full_matrices=False)
    return U[:, s > tol * max(s[0], 1e-300)] if len(s) else U


def separation(lin: Linearisation, free, noise: dict, a: str, b: str) -> float:
    """
    Measure how alike the residual patterns are that two candidates each fit.

    The |correlation| of the whitened residual patterns that ``a`` and ``b`` each fit (base
    columns removed): near 1 when both explain the same disagreement, so the data cannot say
    which.  Systematic terms: the fitted patterns A_a A_a⁺ w and A_b A_b⁺ w of the whitened,
    projected residual w.  Noise terms: their patterns of excess variance, per whitened
    component.

    Parameters
    ----------
    lin : Linearisation
        The linearisation at the current model point.
    free : list of str
        Systematic effects already in the model.
    noise : dict
        The noise terms of the model.
    a, b : str
        The two candidate effects.

    Returns
    -------
    float
        |correlation| in [0, 1]; 0 when the kinds differ or a pattern vanishes.

    """
    ea, eb = EFFECTS[a], EFFECTS[b]
    if ea.kind != eb.kind:
        return 0.0
    W = lin.whitener(noise)
    base = W.apply(lin.design(free))
    Pb = _span(base)

    def proj(X):
        X = W.apply(X)
        return X - Pb @ (Pb.T @ X)
    w = proj(lin.residual(noise)[:, None])[:, 0]
    if ea.kind == 'noise':
        def pattern(name):
            e = EFFECTS[name]
            theta = np.asarray(noise.get(name, [e.neutral] * e.size), dtype=float)
            P0 = lin.fix_covariance(noise)
            cols = []
            for i in range(e.size):
                t2 = theta.copy()
                t2[i] += 1e-3 * max(abs(t2[i]), 1e-6)
                dP = e.fix_covariance(P0, t2) - e.fix_covariance(P0, theta)
                cols.append(np.diagonal(dP[lin.pairs.fix_end] + dP[lin.pairs.fix_start],
                                        axis1=1, axis2=2).ravel())
            X = np.array(cols).T
            y = w ** 2 - 1.0
            return X @ np.linalg.lstsq(X, y, rcond=None)[0]
    else:
        def pattern(name):
            X = proj(lin.columns(name))
            return X @ np.linalg.lstsq(X, w, rcond=1e-10)[0]
    pa, pb = pattern(a), pattern(b)
    na, nb = np.linalg.norm(pa), np.linalg.norm(pb)
    if na == 0 or nb == 0:
        return 0.0
    return float(abs(pa @ pb) / (na * nb))


def adds_to(lin: Linearisation, free, noise: dict, a: str, b: str, level: float) -> bool:
    """
    Tell whether systematic effect ``a`` still explains more once ``b`` is in the model too.

    The encompassing test: the likelihood-ratio test of ``a`` at ``level`` with ``b`` in the
    model.  When it passes, the data tell a from b, however alike the residual patterns they
    each fit alone.

    Parameters
    ----------
    lin : Linearisation
        The linearisation at the current model point.
    free : list of str
        Systematic effects already in the model.
    noise : dict
        The noise terms of the model.
    a, b : str
        The candidate tested and the one it is tested against.
    level : float
        Level of the test.

    Returns
    -------
    bool
        True when ``a`` passes; False for noise terms (judged by their patterns only).

    """
    from scipy.stats import chi2
    if EFFECTS[a].kind == 'noise' or EFFECTS[b].kind == 'noise':
        return False
    W = lin.whitener(noise)
    both = free + [a, b]
    dof = (int(np.linalg.matrix_rank(W.apply(lin.design(both))))
           - int(np.linalg.matrix_rank(W.apply(lin.design(free + [b])))))
    if dof <= 0:
        return False
    stat = lin.evaluate(free + [b], noise).chi2 - lin.evaluate(both, noise).chi2
    return bool(chi2.sf(max(stat, 0.0), dof) < level)


def score_candidate(lin: Linearisation, free, noise: dict, base, name: str) -> dict:
    """
    Score one candidate effect by its likelihood-ratio statistic against the current model.

    Systematic effects: the drop of the GLS χ² when the effect's separable combinations are
    freed, with as many degrees of freedom.  Noise terms: the drop of −2 log L at the
    maximum-likelihood fit of the term.  An effect the raw increments rule out
    (``direct_check``) scores zero without a fit.

    Parameters
    ----------
    lin : Linearisation
        The linearisation at the current model point.
    free : list of str
        Systematic effects already in the model.
    noise : dict
        The noise terms of the model.
    base : Fit
        The fit of the current model (``lin.evaluate(free, noise)``).
    name : str
        The candidate effect.

    Returns
    -------
    dict
        ``effect``, ``statistic``, ``dof``, ``p_value``; noise terms also ``theta`` and
        ``sigma`` (the fitted term and its σ); ``direct_check`` when the raw data rule it out.

    """
    from scipy.stats import chi2
    e = EFFECTS[name]
    why = e.direct_check(lin.rec.delta_theta, None)
    if why:                                    # the raw data rule it out: no fit needed
        return {'effect': name, 'statistic': 0.0, 'dof': e.size, 'p_value': 1.0,
                'direct_check': why}
    if e.kind == 'noise':
        theta, f, sig = fit_noise(lin, free, noise, name)
        stat = max(base.nll - f.nll, 0.0)
        dof = e.size
        return {'effect': name, 'statistic': stat, 'dof': dof,
                'p_value': float(chi2.sf(stat, dof)), 'theta': theta, 'sigma': sig}
    f = lin.evaluate(free + [name], noise)
    with_it = lin.whitener(noise).apply(lin.design(free + [name]))
    without = lin.whitener(noise).apply(lin.design(free))
    dof = int(np.linalg.matrix_rank(with_it, tol=None)) - int(np.linalg.matrix_rank(without))
    stat = max(base.chi2 - f.chi2, 0.0)
    dof = max(dof, 1)
    return {'effect': name, 'statistic': stat, 'dof': dof, 'p_value': float(chi2.sf(stat, dof))}
