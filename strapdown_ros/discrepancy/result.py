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
        Largest jackknife σ ÷ reported σ over the combinations.
    repeatable : bool, optional
        Whether the spread ratio is inside the repeatability bound.

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
                'spread_ratio': self.spread_ratio, 'fold_values': self.fold_values}


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
            'repeatability_bound': self.repeatability_bound,
            'pairs': self.pairs, 'fixes': self.fixes,
            'reference_spacing': self.reference_spacing})


def residual_series(lin: Linearisation, f, free) -> dict:
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

    Returns
    -------
    dict
        ``t`` (s), ``residual`` (N, 3) rad and its predicted ``sigma``, ``whitened`` (N, 3),
        rotation angles ``phi_cam``, ``phi_imu`` (004 Fig. 2a) rad, ``rate`` at the epochs
        rad/s, ``accumulated_angle`` rad.

    """
    N = len(lin.pairs)
    J = lin.design(free)
    resid = (lin.r - J @ f.z).reshape(N, 3)            # the residual left after the fit
    phi_cam = np.linalg.norm(quat_to_rotvec(lin.pairs.dq_cam), axis=1)
    phi_imu = np.linalg.norm(quat_to_rotvec(lin.pairs.dq_imu), axis=1)
    w_e = np.linalg.norm(lin.gyro.rate_at(lin.pairs.k_end), axis=1)
    w_s = np.linalg.norm(lin.gyro.rate_at(lin.pairs.k_start), axis=1)
    acc = np.cumsum(phi_imu)
    P = lin.fix_covariance({})
    sig = np.sqrt(np.diagonal(P[lin.pairs.fix_end] + P[lin.pairs.fix_start], axis1=1, axis2=2)
                  + lin.random_walk ** 2 * lin.pairs.duration[:, None])
    return {'t': lin.pairs.t_end, 'residual': resid, 'sigma': sig,
            'whitened': f.whitened.reshape(N, 3), 'phi_cam': phi_cam, 'phi_imu': phi_imu,
            'rate': np.maximum(w_e, w_s), 'accumulated_angle': acc}
