"""
The σ the discrepancy workflow reports: the model's, the sandwich, the jackknife, repeatability.

When the final residuals pass the NIS and whiteness tests every σ is the model's; when either
fails, the Newey–West sandwich (:func:`strapdown_ros.discrepancy.linear_model.hac_covariance`),
never below the model's, and never below the leave-one-block-out jackknife over time, each block
weighted by its own information (:func:`jackknife_floor`).  Each added effect must take one value
in every time block, judged by each block's own information (:func:`report_steps`,
:mod:`strapdown_ros.discrepancy.repeatability`).  Used by
:mod:`strapdown_ros.discrepancy.workflow`.
No ROS imports.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.discrepancy.linear_model import hac_covariance
from strapdown_ros.discrepancy.linearisation import fit_noise, Linearisation, NUMERICAL_ERRORS
from strapdown_ros.discrepancy.repeatability import (block_spans, noise_repeatability,
                                                     systematic_repeatability,
                                                     weighted_jackknife)
from strapdown_ros.discrepancy.selection import TimeBlocks
from strapdown_ros.sensors.effects import EFFECTS

__all__ = ['hac_lags', 'jackknife_floor', 'effect_values', 'final_covariance',
           'repeatability_bound', 'report_steps']


def hac_lags(pairs: int) -> int:
    """
    Return the bandwidth of the Newey–West sandwich: ⌈2·N^(1/3)⌉ pairs.

    Wider than the textbook 4(N/100)^(2/9), since the structure it must cover is slow: drifts
    and periods of minutes.

    Parameters
    ----------
    pairs : int
        Number of increment pairs N.

    Returns
    -------
    int
        Lags, pairs.

    """
    return int(np.ceil(2.0 * pairs ** (1.0 / 3.0)))


def jackknife_floor(lin: Linearisation, free, noise: dict, split: TimeBlocks, cov_z: np.ndarray):
    """
    Raise every σ of z to at least its leave-one-block-out jackknife σ over time.

    The delete-a-block jackknife over time, each block weighted by its own information
    (:func:`strapdown_ros.discrepancy.repeatability.weighted_jackknife`: the plain
    (K−1)/K Σ_k (z_k − z̄)² overstates σ when the blocks differ in information, as on uneven
    motion); it needs no bandwidth and covers structure as slow as a block.  Correlations are
    kept (the matrix is rescaled by the ratio of σ's).

    Parameters
    ----------
    lin : Linearisation
        The linearisation of the final fit.
    free : list of str
        Systematic effects of the fit.
    noise : dict
        The noise terms of the model.
    split : TimeBlocks
        The time blocks.
    cov_z : ndarray (p, p)
        Covariance of the fitted parameters z (boresight first).

    Returns
    -------
    cov : ndarray (p, p)
        The raised covariance; unchanged when a fold's fit fails numerically.
    grew : bool
        Whether any σ grew.

    """
    jk = _fold_jackknife(lin, free, noise, split)
    if jk is None or len(jk) != cov_z.shape[0]:
        return cov_z, False
    d = np.sqrt(np.maximum(np.diag(cov_z), 0.0))
    grow = jk > d
    if not np.any(grow):
        return cov_z, False
    f_ = np.where(grow & (d > 0), jk / np.where(d > 0, d, 1.0), 1.0)
    out = cov_z * np.outer(f_, f_)
    zero = grow & ~(d > 0)
    out[zero, zero] = jk[zero] ** 2
    return out, True


def _fold_jackknife(lin: Linearisation, free, noise: dict, split: TimeBlocks):
    """Return the information-weighted jackknife σ of z over the time blocks (None: failed)."""
    try:
        full = lin.evaluate(free, noise)
        fits = [lin.evaluate(free, noise, train) for train, _ in split.folds(lin)]
    except NUMERICAL_ERRORS:
        return None
    if len(fits) < 2:
        return None
    return weighted_jackknife(np.array([f.z for f in fits]), full.z, _information(full.cov_z),
                              np.array([_information(f.cov_z) for f in fits]))


def _information(cov: np.ndarray) -> np.ndarray:
    """Return 1 / the diagonal of a covariance (∞ where it is 0)."""
    d = np.diag(cov)
    with np.errstate(divide='ignore'):
        return np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), np.inf)


def effect_values(name: str, params: dict, cov=None, theta=None, sigma=None):
    """
    Return the value and σ of an effect by its ROS parameter name, SI units.

    Parameters
    ----------
    name : str
        Effect name of the registry.
    params : dict
        The model (the effect's value when ``theta`` is None).
    cov : ndarray (q, q), optional
        Covariance of the effect's separable combinations (used when ``sigma`` is None).
    theta : array_like, optional
        The value to report instead of the model's.
    sigma : array_like, optional
        The 1σ to report, per component.

    Returns
    -------
    parameters : dict
        ``{parameter name: value}`` (a float for a one-component parameter).
    sigma : dict
        ``{parameter name: 1σ}``.

    """
    e = EFFECTS[name]
    p = e.value_parameter
    v = e.value(params) if theta is None else np.asarray(theta, dtype=float)
    if sigma is None:
        S = e.fit_basis()
        full = cov if S is None else S @ cov @ S.T
        sigma = np.sqrt(np.maximum(np.diag(full), 0.0))
    val = v.tolist() if p.size > 1 else float(v[0])
    sig = (np.asarray(sigma, dtype=float).tolist() if p.size > 1
           else float(np.asarray(sigma).reshape(-1)[0]))
    return {p.name: val}, {p.name: sig}


def final_covariance(final, lin: Linearisation, free, noise: dict, split: TimeBlocks,
                     tests: dict, lags: int):
    """
    Choose the covariance of the final fit's parameters: the model's, or an honest one.

    When the residuals are not white or not of the stated size, the model covariance assumes
    what the tests just rejected; the Newey–West sandwich does not.  The sandwich is noisy
    where the model is right, so no σ goes below the model's; and its bandwidth cannot cover
    structure as slow as the time blocks, so no σ goes below the jackknife over time either.

    Parameters
    ----------
    final : Fit
        The final joint fit.
    lin : Linearisation
        Its linearisation.
    free : list of str
        Systematic effects of the fit.
    noise : dict
        The noise terms of the model.
    split : TimeBlocks
        The time blocks.
    tests : dict
        The verdict tests of the final residuals
        (:func:`strapdown_ros.discrepancy.diagnostics.verdict_tests`).
    lags : int
        Bandwidth of the sandwich (:func:`hac_lags`).

    Returns
    -------
    method : str
        ``model``, ``hac`` or ``hac_jackknife``.
    cov : ndarray (p, p)
        The covariance reported.
    cov_judged : ndarray (p, p)
        The covariance the repeatability check judges (model or sandwich, before the
        jackknife floor).

    """
    if tests['nis']['p_value'] >= tests['level'] and \
            tests['whiteness']['p_value'] >= tests['level']:
        return 'model', final.cov_z, final.cov_z
    cov_h = hac_covariance(final, lags)
    d = np.sqrt(np.maximum(np.diag(final.cov_z), 0.0))
    dh = np.sqrt(np.maximum(np.diag(cov_h), 0.0))
    f_ = np.maximum(dh, d) / np.where(d > 0, d, 1.0)
    cov_z = np.where(np.outer(d, d) > 0, final.cov_z * np.outer(f_, f_), cov_h)
    cov_floor, jk_used = jackknife_floor(lin, free, noise, split, cov_z)
    return ('hac_jackknife' if jk_used else 'hac'), cov_floor, cov_z


def repeatability_bound(folds: int, level: float) -> float:
    """
    Return the largest jackknife σ ÷ stated σ still called repeatable.

    The leave-one-block-out estimates scatter about as the stated σ says (jackknife σ =
    √((K−1)/K Σ(θ_k − θ̄)²) ≈ σ); a ratio beyond the χ²(K−1) bound at the test level is not.

    Parameters
    ----------
    folds : int
        Number of folds K.
    level : float
        Test level.

    Returns
    -------
    float
        √(χ²_{1−level}(K−1) / (K−1)).

    """
    from scipy.stats import chi2
    dof_k = max(folds - 1, 1)
    return float(np.sqrt(chi2.ppf(1.0 - level, dof_k) / dof_k))


def report_steps(steps, lin: Linearisation, final, free, noise: dict, params: dict,
                 split: TimeBlocks, cov_z, cov_judged, method: str, bound: float,
                 level: float | None = None, lags: int | None = None) -> None:
    """
    Fill in every added effect's value, σ, leave-one-block-out spread and repeatability.

    Repeatability (``repeatability``, ``repeatable``): the effect takes one value in every
    time block, each block judged by its own information
    (:mod:`strapdown_ros.discrepancy.repeatability`; the Newey–West form when ``method`` is not
    ``model``).  ``spread``: the information-weighted leave-one-block-out jackknife σ;
    ``spread_ratio``: it over the σ judged (kept for the record; it no longer decides).

    Parameters
    ----------
    steps : list of Step
        The accepted effects; their value, σ and spread fields are set in place.
    lin : Linearisation
        The linearisation of the final fit.
    final : Fit
        The final joint fit.
    free : list of str
        Systematic effects of the fit, in the order of z after the boresight.
    noise : dict
        The noise terms of the model.
    params : dict
        The fitted model.
    split : TimeBlocks
        The time blocks.
    cov_z, cov_judged : ndarray (p, p)
        The reported covariance and the one the spread ratio is judged against
        (:func:`final_covariance`).
    method : str
        The σ method (noise terms take the jackknife σ when it is not ``model``).
    bound : float
        The former spread-ratio bound (:func:`repeatability_bound`), kept for the record.
    level : float, optional
        Level of the repeatability test (default: the level behind ``bound``, 0.01/6).
    lags : int, optional
        Bandwidth of the Newey–West form of the test, pairs (used when ``method`` is not
        ``model``; default :func:`hac_lags`).

    """
    level = 0.01 / 6.0 if level is None else float(level)
    robust_lags = None if method == 'model' else (lags or hac_lags(len(lin.pairs)))
    k = 3
    offsets = {}
    for name in free:
        S = EFFECTS[name].fit_basis()
        q = EFFECTS[name].size if S is None else S.shape[1]
        offsets[name] = (k, q)
        k += q
    folds = split.folds(lin)
    spans = block_spans(lin, split)
    fold_fits = None
    if any(s.effect in offsets for s in steps):
        try:
            fold_fits = [lin.evaluate(free, noise, train) for train, _ in folds]
        except NUMERICAL_ERRORS:
            fold_fits = None
    for s in steps:
        if s.effect in offsets:
            a, q = offsets[s.effect]
            s.parameters, s.sigma = effect_values(s.effect, params, cov_z[a:a + q, a:a + q])
            _, s.sigma_model = effect_values(s.effect, params, final.cov_z[a:a + q, a:a + q])
            sd = np.sqrt(np.maximum(np.diag(cov_judged[a:a + q, a:a + q]), 0.0))
            S = EFFECTS[s.effect].fit_basis()
            v0 = EFFECTS[s.effect].value(params)
            if fold_fits is not None:
                zf = np.array([f.z[a:a + q] for f in fold_fits])
                vals = [(v0 + (z if S is None else S @ z)) for z in zf]
                s.fold_values = [v.tolist() for v in vals]
                jk = weighted_jackknife(zf, final.z[a:a + q],
                                        _information(final.cov_z)[a:a + q],
                                        np.array([_information(f.cov_z)[a:a + q]
                                                  for f in fold_fits]))
                s.spread_ratio = float(np.max(jk / np.where(sd > 0, sd, np.inf)))
                full_jk = jk if S is None else np.sqrt(np.maximum(np.diag(
                    S @ np.diag(jk ** 2) @ S.T), 0.0))
                s.spread = effect_values(s.effect, params, theta=v0, sigma=full_jk)[1]
            try:
                s.repeatability = systematic_repeatability(lin, final, free, noise, s.effect,
                                                           split, level, robust_lags)
            except NUMERICAL_ERRORS:
                s.repeatability = None
        else:
            try:
                _, _, sig = fit_noise(lin, free, noise, s.effect)
            except NUMERICAL_ERRORS:
                sig = np.full(EFFECTS[s.effect].size, np.inf)
            theta = np.asarray(noise[s.effect], dtype=float)
            s.sigma_model = effect_values(s.effect, params, theta=theta, sigma=sig)[1]
            if s.fold_theta:
                ft = np.asarray(s.fold_theta, dtype=float)
                s.fold_values = ft.tolist()
                if s.fold_sigma:
                    fs = np.asarray(s.fold_sigma, dtype=float).reshape(ft.shape)
                    jk = weighted_jackknife(ft, theta, _information(np.diag(sig ** 2)),
                                            1.0 / np.maximum(fs ** 2, 1e-300))
                    s.repeatability = noise_repeatability(theta, sig, ft, fs, spans, level)
                else:
                    jk = np.sqrt((len(ft) - 1) / len(ft)
                                 * np.sum((ft - ft.mean(axis=0)) ** 2, axis=0))
                s.spread = effect_values(s.effect, params, theta=theta, sigma=jk)[1]
                s.spread_ratio = float(np.max(jk / np.where(sig > 0, sig, np.inf)))
                if method in ('hac', 'hac_jackknife'):
                    sig = np.maximum(sig, jk)       # noise terms: the time-block jackknife
            s.parameters, s.sigma = effect_values(s.effect, params, theta=theta, sigma=sig)
        if s.repeatability is not None:
            s.repeatable = bool(s.repeatability['repeatable'])
        elif s.spread_ratio is not None:
            s.repeatable = bool(s.spread_ratio <= bound)
