"""
What the discrepancy workflow returns: the accepted steps, the verdict and the per-pair series.

:class:`Step` is one accepted effect with its value, σ and repeatability;
:class:`DiscrepancyResult` is the whole answer of
:func:`strapdown_ros.discrepancy.workflow.analyse` and its JSON (``discrepancy --json``);
:func:`residual_series` gives the per-pair arrays the report
(:mod:`strapdown_ros.discrepancy.report`) plots.  No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from strapdown_ros.discrepancy.linearisation import Linearisation
from strapdown_ros.discrepancy.selection import RHO_MAX
from strapdown_ros.rotation import quat_to_rotvec
from strapdown_ros.text import json_clean

__all__ = ['Step', 'DiscrepancyResult', 'residual_series']


@dataclass
class Step:
    """
    One effect the search accepted, with its fitted value and uncertainty.

    Parameters
    ----------
    effect : str
        Effect name of the registry.
    parameters : dict
        Fitted value by ROS parameter name, SI units.
    sigma : dict
        Reported 1σ by ROS parameter name (model, sandwich or jackknife: ``sigma_method``).
    statistic : float
        Likelihood-ratio statistic when it was accepted.
    p_value : float
        Its p-value, χ²(``dof``).
    heldout_gain : float
        Drop of the held-out −2 log L per judged residual.
    dof : int
        Degrees of freedom of the test (separable combinations).
    fold_theta : list, optional
        Noise terms: θ fitted on each fold's training blocks.
    sigma_model : dict
        1σ as the model states it.
    fold_values : list, optional
        The leave-one-block-out estimates.
    spread : dict
        Their jackknife σ, by ROS parameter name.
    spread_ratio : float, optional
        Largest jackknife σ ÷ the σ judged (model or sandwich) over the combinations.
    repeatable : bool, optional
        Whether the effect takes one value in every time block (``repeatability``).
    fold_sigma : list, optional
        Noise terms: the Fisher σ of each fold's θ.
    repeatability : dict, optional
        The test of one value in every time block, each block judged by its own information
        (:mod:`strapdown_ros.discrepancy.repeatability`): statistic, dof, p-value, level,
        method and the blocks.
    sigma_method : str
        How ``sigma`` was computed: ``model``, ``hac``, ``hac_jackknife`` (systematic effects,
        as the result's ``sigma_method``), ``fisher`` or ``fisher_jackknife`` (noise terms: the
        curvature of −2 log L, raised to the time-block jackknife).

    """

    effect: str
    parameters: dict
    sigma: dict
    statistic: float
    p_value: float
    heldout_gain: float
    dof: int
    fold_theta: list | None = None
    sigma_model: dict = field(default_factory=dict)
    fold_values: list | None = None
    spread: dict = field(default_factory=dict)
    spread_ratio: float | None = None
    repeatable: bool | None = None
    fold_sigma: list | None = None
    repeatability: dict | None = None
    sigma_method: str = 'model'

    def as_dict(self) -> dict:
        """
        Return the step as the JSON fields of ``discrepancy --json``.

        Returns
        -------
        dict
            Effect, values, σ (reported and the model's), test, repeatability.

        """
        return {'effect': self.effect, 'parameters': self.parameters, 'sigma': self.sigma,
                'sigma_model': self.sigma_model, 'statistic': self.statistic,
                'p_value': self.p_value, 'heldout_gain': self.heldout_gain, 'dof': self.dof,
                'repeatable': self.repeatable, 'spread': self.spread,
                'spread_ratio': self.spread_ratio, 'fold_values': self.fold_values,
                'repeatability': self.repeatability, 'sigma_method': self.sigma_method}


@dataclass
class DiscrepancyResult:
    """
    The answer of the discrepancy workflow on one recording.

    Parameters
    ----------
    verdict : str
        ``model_adequate``, ``explained`` or ``unexplained_structure``.
    rms_before, rms_after : float
        Whitened RMS of the residuals before and after the effects were added.
    heldout_rms_before, heldout_rms_after : float
        The same over held-out time blocks.
    steps : list of Step
        The effects added, in order.
    not_separable : list
        Pairs of effect names the trajectory does not tell apart.
    remaining : dict
        Description of the structure left (when a verdict test fails).
    alpha : float
        Family-wise level.
    tests_before, tests_after : dict
        The verdict tests (NIS, whiteness, extreme value) before and after.
    candidates_first_step : list
        Scores of every candidate at the first step.
    boresight_rad, boresight_sigma_rad : list
        Boresight yaw, pitch, roll and their reported 1σ, rad.
    pairs, fixes : int
        Increment pairs and camera fixes used.
    model_out : dict
        Effect parameter values to write to the model.
    found_model : SensorModel, optional
        The nominal model with the found effects, their σ, the filter's online states and the
        boresight (:func:`strapdown_ros.discrepancy.workflow.found_model`): what
        ``--write-model`` writes.
    series : dict
        Per-pair arrays for the report (``before``/``after``: :func:`residual_series`).
    rejected : list
        Candidates rejected (held-out check, backward elimination), with the reason.
    failed_candidates : list
        ``{effect, step, reason}`` of candidates whose fit failed numerically.
    stopped_by : str, optional
        What ended the search (:data:`strapdown_ros.discrepancy.workflow.STOPPED_BY`).
    max_steps : int
        Most effects the search could accept.
    fit_consistent : bool
        The final χ²/dof is inside its band at the test level.
    chi2_per_dof : float
        The final χ²/dof.
    chi2_per_dof_band : list
        Its two-sided band.
    sigma_method : str
        ``model``, ``hac`` (Newey–West) or ``hac_jackknife``.
    hac_lags : int, optional
        Bandwidth of the sandwich, pairs.
    boresight_sigma_model_rad : list
        Boresight 1σ as the model states it, rad.
    repeatability_bound : float
        Largest spread ratio called repeatable.
    observable : bool
        Whether the boresight is observable.
    reference_spacing : dict
        How far apart the fixes of the pairs are and why
        (:meth:`strapdown_ros.calibration.reference_spacing.SpacingChoice.as_dict`).
    boresight_sigma_calibrate_bag_rule_rad : list
        The boresight σ by ``calibrate_bag``'s rule on the same pairs: the boresight alone with
        the stated noise (``boresight_sigma_base_model_rad``), scaled by √(χ²/dof) of that fit
        (``chi2_per_dof_base``) when above 1, rad.
    boresight_sigma_base_model_rad : list
        The model's boresight σ with no effect added, rad.
    chi2_per_dof_base : float
        χ²/dof of the fit with no effect added.

    """

    verdict: str
    rms_before: float
    rms_after: float
    heldout_rms_before: float
    heldout_rms_after: float
    steps: list
    not_separable: list
    remaining: dict
    alpha: float
    tests_before: dict
    tests_after: dict
    candidates_first_step: list
    boresight_rad: list
    boresight_sigma_rad: list
    pairs: int
    fixes: int
    model_out: dict
    series: dict
    rejected: list = field(default_factory=list)
    failed_candidates: list = field(default_factory=list)
    stopped_by: str | None = None
    max_steps: int = 6
    fit_consistent: bool = True
    chi2_per_dof: float = float('nan')
    chi2_per_dof_band: list = field(default_factory=list)
    sigma_method: str = 'model'
    hac_lags: int | None = None
    boresight_sigma_model_rad: list = field(default_factory=list)
    repeatability_bound: float = float('nan')
    observable: bool = True
    found_model: object = None
    reference_spacing: dict = field(default_factory=dict)
    boresight_sigma_calibrate_bag_rule_rad: list = field(default_factory=list)
    boresight_sigma_base_model_rad: list = field(default_factory=list)
    chi2_per_dof_base: float = float('nan')

    def as_json(self) -> dict:
        """
        Return the result as plain JSON values (the ``discrepancy --json`` document).

        Returns
        -------
        dict
            Every field except the series and ``model_out``, non-finite numbers as None.

        """
        return json_clean({
            'verdict': self.verdict, 'rms_before': self.rms_before, 'rms_after': self.rms_after,
            'heldout_rms_before': self.heldout_rms_before,
            'heldout_rms_after': self.heldout_rms_after,
            'steps': [s.as_dict() for s in self.steps], 'not_separable': self.not_separable,
            'remaining': self.remaining, 'alpha': self.alpha,
            'selection': {'test': 'likelihood ratio, χ²(dof)',
                          'correction': 'α/2 for the selection (Bonferroni (α/2)/m per step), '
                                        'α/2 for the three tests',
                          'heldout': '6 time blocks, leave-one-block-out; gain = drop of '
                                     '−2 log L per judged residual',
                          'separability_bound': RHO_MAX},
            'tests_before': self.tests_before, 'tests_after': self.tests_after,
            'candidates_first_step': self.candidates_first_step, 'rejected': self.rejected,
            'boresight_rad': self.boresight_rad, 'boresight_sigma_rad': self.boresight_sigma_rad,
            'boresight_sigma_model_rad': self.boresight_sigma_model_rad,
            'observable': self.observable,
            'failed_candidates': self.failed_candidates, 'stopped_by': self.stopped_by,
            'max_steps': self.max_steps, 'fit_consistent': self.fit_consistent,
            'chi2_per_dof': self.chi2_per_dof, 'chi2_per_dof_band': self.chi2_per_dof_band,
            'sigma_method': self.sigma_method, 'hac_lags': self.hac_lags,
            'boresight_sigma_method': self.sigma_method,
            'sigma_methods': {'boresight': self.sigma_method,
                              **{s.effect: s.sigma_method for s in self.steps}},
            'boresight_sigma_calibrate_bag_rule_rad':
                self.boresight_sigma_calibrate_bag_rule_rad,
            'boresight_sigma_base_model_rad': self.boresight_sigma_base_model_rad,
            'chi2_per_dof_base': self.chi2_per_dof_base,
            'repeatability_bound': self.repeatability_bound,
            'pairs': self.pairs, 'fixes': self.fixes,
            'reference_spacing': self.reference_spacing})


def residual_series(lin: Linearisation, f, free, noise: dict | None = None) -> dict:
    """
    Return the per-pair arrays the report plots.

    Parameters
    ----------
    lin : Linearisation
        The linearisation of the fit.
    f : Fit
        The fit (``lin.evaluate(free, noise)``).
    free : list of str
        The systematic effects of the fit.
    noise : dict, optional
        The noise terms of the fit (the camera-noise scale, the quantization remainder): the
        predicted σ is the model's as found (default: none, the stated noise).

    Returns
    -------
    dict
        ``t`` (s), ``residual`` (N, 3) rad and its predicted ``sigma`` (the model with its
        noise terms), ``whitened`` (N, 3), rotation angles ``phi_cam``, ``phi_imu``
        (004 Fig. 2a, the net angle between the fixes) rad, ``path_angle`` (the angle the gyro
        turned between the fixes, Σ|Δθ|) rad, ``rate`` at the epochs and ``rate_peak`` (the
        largest between them) rad/s, ``reversals`` (sign changes of the body rate about any axis
        between the fixes), ``accumulated_angle`` rad.

    """
    N = len(lin.pairs)
    J = lin.design(free)
    resid = (lin.r - J @ f.z).reshape(N, 3)            # the residual left after the fit
    phi_cam = np.linalg.norm(quat_to_rotvec(lin.pairs.dq_cam), axis=1)
    phi_imu = np.linalg.norm(quat_to_rotvec(lin.pairs.dq_imu), axis=1)
    w_e = np.linalg.norm(lin.gyro.rate_at(lin.pairs.k_end), axis=1)
    w_s = np.linalg.norm(lin.gyro.rate_at(lin.pairs.k_start), axis=1)
    acc = np.cumsum(phi_imu)
    P = lin.fix_covariance(noise or {})
    var = (np.diagonal(P[lin.pairs.fix_end] + P[lin.pairs.fix_start], axis1=1, axis2=2)
           + lin.random_walk ** 2 * lin.pairs.duration[:, None])
    path, peak, flips = _motion_between_fixes(lin)
    return {'t': lin.pairs.t_end, 'residual': resid, 'sigma': np.sqrt(var),
            'whitened': f.whitened.reshape(N, 3), 'phi_cam': phi_cam, 'phi_imu': phi_imu,
            'path_angle': path, 'rate': np.maximum(w_e, w_s), 'rate_peak': peak,
            'reversals': flips, 'accumulated_angle': acc}


def _motion_between_fixes(lin: Linearisation):
    """
    Return, per pair, the angle turned (Σ|Δθ|), the peak rate and the rate reversals.

    The rate is the mean over ±2 increments; a reversal is a change of sign about an axis
    between two moments where that axis turns faster than a dead band (5 % of the 95th
    percentile of the rate, at least 5× the model's white rate noise).
    """
    g = lin.gyro
    rho = g.rho
    n = len(rho)
    T = np.maximum(np.diff(g.stamps, prepend=g.stamps[0] - (g.stamps[1] - g.stamps[0])), 1e-12)
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(rho, axis=1))])
    ks = np.clip(lin.pairs.k_start, 0, n - 1)
    ke = np.clip(lin.pairs.k_end, 0, n - 1)
    path = cum[ke + 1] - cum[ks]
    kern = np.ones(5) / 5.0
    rate = np.column_stack([np.convolve(rho[:, c] / T, kern, mode='same') for c in range(3)])
    norm = np.linalg.norm(rate, axis=1)
    idx = np.column_stack([ks, np.maximum(ke + 1, ks + 1)]).ravel()
    peak = np.maximum.reduceat(norm, np.minimum(idx, n - 1))[::2] if n else np.zeros(len(ks))
    noise = 5.0 * lin.random_walk / np.sqrt(float(np.median(T)))
    dead = max(0.05 * float(np.percentile(np.abs(rate), 95)) if n else 0.0, noise)
    flips = np.zeros(len(ks))
    for c in range(3):
        sgn = np.where(rate[:, c] > dead, 1, np.where(rate[:, c] < -dead, -1, 0))
        at = np.where(sgn != 0, np.arange(n), 0)
        last = sgn[np.maximum.accumulate(at)]          # the last sign outside the dead band
        change = np.concatenate([[0], (last[1:] != last[:-1]) & (last[:-1] != 0)])
        cum_c = np.cumsum(change)
        flips += cum_c[ke] - cum_c[ks]
    return path, peak, flips
