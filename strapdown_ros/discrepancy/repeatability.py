"""
Is a found effect the same in every time block?  Each block judged by its own information.

The time blocks of a recording carry unequal information: a block at rest says much about a
gyro bias and nothing about a scale factor, a block of fast turns the reverse.  A leave-one-
block-out spread compared with one σ assumes the blocks are alike; on uneven motion it flags
true effects.  Here each block is compared with the others through the χ² its own information
predicts:

* **systematic effects** (:func:`systematic_repeatability`): the Chow test of parameter
  constancy.  The effect's columns split by block (block k's own value θ_k, the other
  parameters common) against one common value: the drop of χ², which is
  Σ_k (θ_k − θ̄)ᵀ I_k (θ_k − θ̄) with I_k block k's own information, on as many degrees of
  freedom as the blocks add identifiable directions (a block that carries no information about a
  combination adds none).  When the residuals fail the whiteness or NIS test the Newey–West
  form of the same score test is used (its score covariance never below the model's), so that
  correlated residuals are not read as a changing effect.
* **noise terms** (:func:`noise_repeatability`): from the leave-one-block-out fits θ₋ₖ and their
  Fisher σ₋ₖ, block k's own value and information, θ_k = θ̄ + (I₋ₖ/I_k)(θ̄ − θ₋ₖ) with
  I_k = I − I₋ₖ, and the same χ² Σ I_k (θ_k − θ̄)² on (blocks − 1) dof per component.

Also the delete-a-block jackknife σ weighted by the blocks' information
(:func:`weighted_jackknife`): unbiased for unequal blocks, where the plain one overstates.
Used by :mod:`strapdown_ros.discrepancy.uncertainty`.  No ROS imports.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.discrepancy.linearisation import Linearisation
from strapdown_ros.sensors.effects import EFFECTS

__all__ = ['systematic_repeatability', 'noise_repeatability', 'weighted_jackknife',
           'block_spans', 'MIN_BLOCK_INFORMATION']

#: a block whose own information is below this fraction of the whole recording's (per
#: component) adds no degree of freedom: it cannot tell its value apart from the others'
MIN_BLOCK_INFORMATION = 1e-3
#: singular values of the whitened block columns below this fraction of the largest column norm
#: are directions the blocks do not identify
_RANK_TOL = 1e-7


def block_spans(lin: Linearisation, split) -> list:
    """
    Return each block's test mask and its time span.

    Parameters
    ----------
    lin : Linearisation
        The linearisation whose pairs are split.
    split : TimeBlocks
        The time blocks (:class:`strapdown_ros.discrepancy.selection.TimeBlocks`).

    Returns
    -------
    list of (mask, t_start, t_end)
        Per non-empty block, in time order: its pairs and the end stamps of its first and last
        pair, s.

    """
    t = lin.pairs.t_end
    return [(test, float(t[test][0]), float(t[test][-1])) for _, test in split.folds(lin)]


def _orthonormal(X: np.ndarray, scale: float) -> np.ndarray:
    """Return an orthonormal basis of the columns of X above the rank tolerance."""
    if X.shape[1] == 0 or scale <= 0:
        return X[:, :0]
    U, s, _ = np.linalg.svd(X, full_matrices=False)
    return U[:, s > _RANK_TOL * scale]


def _score_statistic(Q: np.ndarray, w: np.ndarray, pairs: int, lags: int | None) -> float:
    """
    Return the score statistic of the directions Q (orthonormal, ⊥ the fitted columns).

    Model form: |Qᵀw|², χ²(rank) when the whitened residual is white with unit variance.
    Newey–West form (``lags`` given): sᵀ S⁻¹ s with S the Bartlett-kernel covariance of the
    per-pair scores, its eigenvalues raised to at least 1 (the model's): never a larger
    statistic than the model's score covariance gives.  The scores are those of the residual
    with the blocks' own values fitted (the Wald form): a restricted residual would carry the
    very change tested into S and hide it.
    """
    s = Q.T @ w
    if lags is None or Q.shape[1] == 0:
        return float(s @ s)
    n3 = 3 * pairs
    wu = w - Q @ s                                 # the residual with the blocks' own values
    g = (Q[:n3] * wu[:n3, None]).reshape(pairs, 3, -1).sum(axis=1)
    S = g.T @ g
    for lag in range(1, min(int(lags), pairs - 1) + 1):
        G = g[lag:].T @ g[:-lag]
        S += (1.0 - lag / (lags + 1.0)) * (G + G.T)
    P = Q[n3:]
    S += P.T @ P                                   # the prior rows, as the model states them
    lam, V = np.linalg.eigh(0.5 * (S + S.T))
    lam = np.maximum(lam, 1.0)
    u = V.T @ s
    return float(np.sum(u * u / lam))


def systematic_repeatability(lin: Linearisation, final, free, noise: dict, name: str, split,
                             level: float, lags: int | None = None) -> dict:
    """
    Test whether a systematic effect takes one value in every time block (Chow test).

    Parameters
    ----------
    lin : Linearisation
        The linearisation of the final fit.
    final : Fit
        The final joint fit (``lin.evaluate(free, noise)``: whitened design, residual, x).
    free : list of str
        Systematic effects of the fit (``name`` among them).
    noise : dict
        The noise terms of the model.
    name : str
        The effect tested.
    split : TimeBlocks
        The time blocks.
    level : float
        Level of the test.
    lags : int, optional
        Bandwidth of the Newey–West form, pairs; None: the model's form.

    Returns
    -------
    dict
        ``statistic``, ``dof``, ``p_value``, ``level``, ``repeatable`` (p ≥ level, or no
        degree of freedom), ``method`` (``model`` or ``hac``), and ``blocks``: per block its
        ``block`` number (1-based), ``t_start_s``, ``t_end_s``, ``pairs``, the ``statistic``,
        ``dof`` and ``p_value`` of that block against the others, its ``difference`` from them
        in the effect's parameter (SI) and that difference's ``difference_sigma`` (model).

    """
    from scipy.stats import chi2
    e = EFFECTS[name]
    S = e.fit_basis()
    W = lin.whitener(noise)
    pp = np.asarray(final.prior_precision, dtype=float)
    nz, nx = len(final.z), len(pp)
    n3 = final.design.shape[0]
    D = np.vstack([final.design, np.hstack([np.zeros((nx, nz)), np.diag(np.sqrt(pp))])])
    w = np.concatenate([final.whitened, -final.x * np.sqrt(pp)])
    QD = _orthonormal(D, float(np.max(np.linalg.norm(D, axis=0), initial=0.0)))
    raw = lin.columns(name)
    spans = block_spans(lin, split)
    cols = []
    for mask, _, _ in spans:
        X = W.apply(raw * lin.rows(mask)[:, None])
        cols.append(np.vstack([X, np.zeros((nx, X.shape[1]))]))
    scale = max(float(np.max(np.linalg.norm(np.hstack(cols), axis=0), initial=0.0)), 1e-300)

    def perp(X):
        return X - QD @ (QD.T @ X)
    Q = _orthonormal(perp(np.hstack(cols)), scale)
    pairs = n3 // 3
    stat = _score_statistic(Q, w, pairs, lags)
    dof = Q.shape[1]
    p = float(chi2.sf(stat, dof)) if dof else 1.0
    blocks = []
    for k, ((mask, ta, tb), X) in enumerate(zip(spans, cols), 1):
        Xp = perp(X)
        Qk = _orthonormal(Xp, scale)
        sk = _score_statistic(Qk, w, pairs, lags)
        dk = Qk.shape[1]
        Nk = Xp.T @ Xp
        Ck = np.linalg.pinv(Nk, rcond=1e-10, hermitian=True)
        delta = Ck @ (Xp.T @ w)
        if S is not None:
            delta, Ck = S @ delta, S @ Ck @ S.T
        blocks.append({'block': k, 't_start_s': ta, 't_end_s': tb, 'pairs': int(np.sum(mask)),
                       'statistic': sk, 'dof': dk,
                       'p_value': float(chi2.sf(sk, dk)) if dk else 1.0,
                       'difference': delta.tolist(),
                       'difference_sigma': np.sqrt(np.maximum(np.diag(Ck), 0.0)).tolist()})
    return {'statistic': stat, 'dof': dof, 'p_value': p, 'level': float(level),
            'repeatable': bool(p >= level), 'method': 'model' if lags is None else 'hac',
            'blocks': blocks}


def noise_repeatability(theta, sigma, fold_theta, fold_sigma, spans, level: float) -> dict:
    """
    Test whether a noise term takes one value in every time block.

    Block k's own value and information from the leave-one-block-out fits:
    I_k = 1/σ² − 1/σ₋ₖ², θ_k = θ̄ + (I₋ₖ/I_k)(θ̄ − θ₋ₖ); the statistic Σ_k I_k (θ_k − θ̄)² per
    component, summed, on (informative blocks − 1) dof per component.

    Parameters
    ----------
    theta, sigma : (q,) array_like
        The term fitted on all the pairs and its Fisher σ.
    fold_theta, fold_sigma : (K, q) array_like
        The term fitted without each block and those fits' Fisher σ.
    spans : list of (mask, t_start, t_end)
        The blocks (:func:`block_spans`), in the order of the folds.
    level : float
        Level of the test.

    Returns
    -------
    dict
        As :func:`systematic_repeatability` (``method`` ``model``; per block the
        ``difference`` θ_k − θ̄ and its σ).

    """
    from scipy.stats import chi2
    th = np.atleast_1d(np.asarray(theta, dtype=float))
    I_all = 1.0 / np.maximum(np.atleast_1d(np.asarray(sigma, dtype=float)) ** 2, 1e-300)
    ft = np.asarray(fold_theta, dtype=float).reshape(-1, len(th))
    fs = np.asarray(fold_sigma, dtype=float).reshape(-1, len(th))
    I_wo = 1.0 / np.maximum(fs ** 2, 1e-300)
    I_k = I_all[None, :] - I_wo
    use = np.isfinite(I_k) & (I_k > MIN_BLOCK_INFORMATION * I_all[None, :]) & np.isfinite(ft)
    d = ft - th[None, :]
    with np.errstate(divide='ignore', invalid='ignore'):
        terms = np.where(use, I_wo ** 2 * d ** 2 / np.where(use, I_k, 1.0), 0.0)
        own_diff = np.where(use, -(I_wo / np.where(use, I_k, 1.0)) * d, 0.0)
        own_sig = np.where(use, np.sqrt(1.0 / np.where(use, I_k, 1.0) - 1.0 / I_all), np.inf)
    stat = float(np.sum(terms))
    dof = int(np.sum(np.maximum(np.sum(use, axis=0) - 1, 0)))
    p = float(chi2.sf(stat, dof)) if dof else 1.0
    blocks = []
    for k, (mask, ta, tb) in enumerate(spans[:len(ft)]):
        dk = int(np.sum(use[k]))
        sk = float(np.sum(terms[k]))
        blocks.append({'block': k + 1, 't_start_s': ta, 't_end_s': tb,
                       'pairs': int(np.sum(mask)), 'statistic': sk, 'dof': dk,
                       'p_value': float(chi2.sf(sk, dk)) if dk else 1.0,
                       'difference': own_diff[k].tolist(),
                       'difference_sigma': own_sig[k].tolist()})
    return {'statistic': stat, 'dof': dof, 'p_value': p, 'level': float(level),
            'repeatable': bool(p >= level), 'method': 'model', 'blocks': blocks}


def weighted_jackknife(estimates, center, info_all, info_without) -> np.ndarray:
    """
    Return the delete-a-block jackknife σ weighted by the blocks' own information.

    v = (1/K) Σ_k (I₋ₖ / I_k)(θ₋ₖ − θ̂)², I_k = I − I₋ₖ per component, θ̂ the fit on every
    block: the pseudo-value jackknife for unequal groups (h_k = I/I_k, pseudo-value
    θ̂ + (h_k − 1)(θ̂ − θ₋ₖ), block k's own value), unbiased (E v = 1/I) when the blocks differ
    in information; with equal blocks it is the usual (K−1)/K Σ(θ₋ₖ − θ̂)².  Blocks with no own
    information (I_k below :data:`MIN_BLOCK_INFORMATION` · I) are left out.

    Parameters
    ----------
    estimates : (K, p) array_like
        θ₋ₖ, fitted without block k.
    center : (p,) array_like
        θ̂, fitted on every block.
    info_all : (p,) array_like
        I: the information (1/variance) of the fit on every block.
    info_without : (K, p) array_like
        I₋ₖ.

    Returns
    -------
    (p,) ndarray
        The jackknife σ (0 where no block has information of its own).

    """
    zf = np.asarray(estimates, dtype=float)
    c = np.asarray(center, dtype=float).reshape(1, -1)
    I_all = np.asarray(info_all, dtype=float)
    I_wo = np.asarray(info_without, dtype=float).reshape(zf.shape)
    I_k = I_all[None, :] - I_wo
    use = np.isfinite(I_k) & (I_k > MIN_BLOCK_INFORMATION * I_all[None, :]) & np.isfinite(zf)
    n = np.sum(use, axis=0)
    with np.errstate(divide='ignore', invalid='ignore'):
        terms = np.where(use, I_wo / np.where(use, I_k, 1.0) * (zf - c) ** 2, 0.0)
    return np.sqrt(np.where(n > 0, np.sum(terms, axis=0) / np.maximum(n, 1), 0.0))
