"""
The discrepancy workflow: where a recording and its model disagree, and which effect is missing.

On the increment residuals of consecutive camera fixes (004 §4.2, eq. 5–6;
:mod:`strapdown_ros.discrepancy.linearisation`), whitened by the calibrator's correlated
covariance, :func:`analyse` searches the effect library
(:data:`strapdown_ros.sensors.effects.CANDIDATES`) step by step: score every candidate
(likelihood ratio), test the best at a Bonferroni level, keep it only if the held-out fit
improves and it is separable from the others, refit jointly; then drop by backward
elimination what the later effects made unnecessary, and judge the final residuals (NIS,
whiteness, extreme value) with honest σ.  The boresight is always estimated (the calibration
target, not a suspect).  The tests live in :mod:`strapdown_ros.discrepancy.selection`, the fits
in :mod:`strapdown_ros.discrepancy.model_fit`, the σ in
:mod:`strapdown_ros.discrepancy.uncertainty`; the method, its levels and its JSON are
described in doc/discrepancy.md.  No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from strapdown_ros.calibration.reference_spacing import (choose_spacing, fix_interval,
                                                         MAX_SPACING, refine_spacing,
                                                         stated_spacing, thin_fixes)
from strapdown_ros.discrepancy import diagnostics
from strapdown_ros.discrepancy.linearisation import (AnalysisError, BoresightUnobservable,
                                                     fit_noise, InputError, Linearisation,
                                                     noise_of, NUMERICAL_ERRORS,
                                                     NumericalFailure, Recording)
from strapdown_ros.discrepancy.model_fit import (boresight_observability, check_plausible,
                                                 initial_boresight_estimate, initial_pairs,
                                                 refine_fit)
from strapdown_ros.discrepancy.result import DiscrepancyResult, residual_series, Step
from strapdown_ros.discrepancy.selection import (adds_to, heldout_score, RHO_MAX,
                                                 score_candidate, separation, TimeBlocks)
from strapdown_ros.discrepancy.uncertainty import (final_covariance, hac_lags,
                                                   repeatability_bound, report_steps)
from strapdown_ros.rotation import dcm_to_ypr, quat_to_rotvec, ypr_error_to_rotation
from strapdown_ros.sensors.effects import candidates, EFFECTS
from strapdown_ros.sensors.sensor_model import SensorModel
from strapdown_ros.text import json_clean

__all__ = ['Recording', 'analyse', 'json_clean', 'DiscrepancyResult', 'DEFAULT_ALPHA',
           'MIN_PAIRS', 'InputError', 'AnalysisError', 'BoresightUnobservable', 'STOPPED_BY',
           'DiscrepancySettings', 'found_model']

#: why the search stopped: the step limit (accepted effects), no candidate passing its test,
#: none left to try (all added, excluded or failed numerically), or the safety bound on turns
STOPPED_BY = ('max_steps', 'no_significant_candidate', 'no_candidates_left', 'iteration_limit')

#: family-wise level α of the selection and the verdict tests together
DEFAULT_ALPHA = 0.01
#: fewest increment pairs the workflow analyses (a recording needs one fix more)
MIN_PAIRS = 12


@dataclass(frozen=True)
class DiscrepancySettings:
    """
    What ``discrepancy`` takes besides the sensor model.

    Attributes
    ----------
    alpha : float
        Family-wise level (α/2 for the selection, α/2 for the verdict tests).
    blocks : int
        Contiguous time blocks of the held-out (leave-one-block-out) check.
    lags : int or None
        Ljung–Box lags (None: min(20, max(2, pairs/10))).
    max_steps : int
        Most effects ACCEPTED by the search; when it stops the search, ``stopped_by`` says
        ``"max_steps"``.
    candidates : tuple of str or None
        Effect names to consider (None: the registry's library, read when the analysis runs).
    min_rotation_deg : float
        The calibrator's smallest rotation between exposures (the observability rule).
    max_sigma : float
        The calibrator's largest predicted boresight σ (the observability rule), rad.
    reference_spacing : float or None
        Seconds between the fixes used (0: every fix; None: chosen from the data,
        :mod:`strapdown_ros.calibration.reference_spacing`).

    """

    alpha: float = DEFAULT_ALPHA
    blocks: int = 6
    lags: int | None = None
    max_steps: int = 6
    candidates: tuple | None = None
    min_rotation_deg: float = 0.5
    max_sigma: float = 1e-3
    reference_spacing: float | None = None

    @classmethod
    def from_values(cls, values) -> DiscrepancySettings:
        """
        Build the settings from values by name (the calibrator's settings among them).

        Parameters
        ----------
        values : mapping
            Name → value (defaults where absent).

        Returns
        -------
        DiscrepancySettings
            The settings.

        """
        return cls(**{f.name: values[f.name] for f in fields(cls) if f.name in values})


def analyse(rec: Recording, model: SensorModel, settings: DiscrepancySettings | None = None,
            progress=None) -> DiscrepancyResult:
    """
    Find where the recording and its model disagree and which effects are missing.

    The steps, each a method of the search: the base fit (boresight only, after the
    observability check); the forward search (score every candidate, test the best at
    (α/2)/m — mean before variance —, set aside pairs that are not separable, keep it only if
    the held-out −2 log L improves, refit jointly; until nothing passes or ``max_steps``);
    backward elimination at (α/2)/k; the final fit with its verdict tests at (α/2)/3 and honest
    σ.  The family-wise level α is split: α/2 for the selection, α/2 for the verdict tests, so
    that a recording the model describes is called anything but ``model_adequate`` with
    probability at most α.  A candidate whose own fit fails numerically is dropped from that
    step and listed in ``failed_candidates``.

    Parameters
    ----------
    rec : Recording
        The recording.
    model : SensorModel
        The nominal model: its effects are compensated, its noise terms and priors weight the
        pairs.
    settings : DiscrepancySettings, optional
        The level, blocks, lags, step limit, candidates, the observability rule and the
        spacing of the fixes of the pairs (``reference_spacing``: None chooses it from the data,
        :mod:`strapdown_ros.calibration.reference_spacing`, the correlation of the reference's
        error; 0 keeps every fix; a positive value keeps one fix per slot of that length).
    progress : callable, optional
        ``progress(text)`` is called between stages.

    Returns
    -------
    DiscrepancyResult
        The verdict, the effects added with their σ, the tests before and after.

    Raises
    ------
    InputError
        The recording cannot be analysed (too few fixes or pairs): bad input.
    BoresightUnobservable
        The motion does not determine the boresight (the rule of calibrate_bag).
    AnalysisError
        A base fit (without any candidate) failed numerically: the analysis cannot be computed.
        A candidate whose own fit fails is only dropped (``failed_candidates``).

    """
    if isinstance(model, dict):
        raise TypeError('analyse takes a SensorModel and DiscrepancySettings '
                        '(strapdown_ros.params.load_model_file), not a parameter dict')
    s = settings or DiscrepancySettings()
    if len(rec.fix_stamps) < MIN_PAIRS + 1:
        raise InputError(f'{len(rec.fix_stamps)} camera fixes: the workflow needs at least '
                         f'{MIN_PAIRS + 1}')
    # the working model point: the model's keys, changed as effects are accepted
    params = {**model.values(), 'min_rotation_deg': float(s.min_rotation_deg),
              'max_sigma': float(s.max_sigma)}
    names = candidates() if s.candidates is None else tuple(s.candidates)
    search = _Search(rec, params, s.alpha, s.blocks, s.lags, s.max_steps, names,
                     progress or (lambda t: None))
    search.model = model
    search.spacing_wanted = s.reference_spacing
    if s.reference_spacing is None and 'reference_spacing' in model.stated:
        search.spacing_wanted = model.reference_spacing   # the model states it: one spacing
    try:
        search.base_fit()
        search.forward()
        search.backward()
        return search.result()
    except NUMERICAL_ERRORS as exc:
        raise AnalysisError(f'the analysis cannot be computed: {search.stage} failed '
                            f'numerically ({_reason(exc)})') from exc
    except InputError as exc:
        if not search.base_done:
            raise
        # the input was usable (the base fit ran): a fitted value moved the pairs off the data
        raise AnalysisError(f'the analysis cannot be computed: {search.stage} failed ({exc})'
                            ) from exc


def _reason(exc) -> str:
    text = f'{type(exc).__name__}: {exc}' if not isinstance(exc, NumericalFailure) else str(exc)
    return text if len(text) <= 300 else text[:297] + '...'


#: a candidate's own fit may fail: numerically, or by moving the pairs off the data
_CANDIDATE_ERRORS = NUMERICAL_ERRORS + (InputError,)


class _Search:
    """
    The state of one analysis, advanced by the steps :func:`analyse` calls in order.

    The model point (``params``, boresight ``C``, ``free`` systematic effects, ``noise``
    terms) changes as effects are accepted or removed; the lists ``steps``, ``rejected``,
    ``failed``, ``not_separable`` record what happened.  ``stage`` names what is being
    computed (for the error message) and ``base_done`` whether the base fit ran.
    """

    def __init__(self, rec, params, alpha, blocks, lags, max_steps, candidates, say):
        self.rec, self.params, self.alpha = rec, params, alpha
        self.blocks, self.lags, self.max_steps = blocks, lags, max_steps
        self.candidates, self.say = candidates, say
        self.stage = 'observability'
        self.base_done = False
        # the family-wise level α is split: α/2 for the selection, α/2 for the three verdict
        # tests, so a recording the model describes is called anything but model_adequate
        # with probability ≤ α
        self.a_sel, self.a_tests = 0.5 * alpha, 0.5 * alpha
        self.free: list[str] = []
        self.steps: list[Step] = []
        self.not_separable: list = []
        self.rejected: list = []
        self.failed: list = []
        self.excluded: set = set()
        self.failed_now: set = set()      # failed numerically since the last accepted effect
        self.first_scores: list = []
        self.fold_sigma: list = []        # the Fisher σ of the last noise term's fold fits
        self.stopped_by = None

    # ------------------------------------------------------------------ the base fit
    def base_fit(self) -> None:
        """
        Check the boresight's observability and fit the model with the boresight only.

        Sets the epoch, the noise terms, the boresight, the time blocks, the tests, held-out
        score and series before any effect is added.

        Raises
        ------
        BoresightUnobservable
            The motion does not determine the boresight.
        InputError
            Fewer than :data:`MIN_PAIRS` increment pairs.

        """
        params = self.params
        self.original = dict(params)
        self.epoch = epoch = float(self.rec.gyro_stamps[0])
        self.noise = noise_of(params)
        self.nominal_noise = dict(self.noise)
        self.stage = 'the spacing of the fixes'
        self.rec = rec = self._spaced(self.rec, params, epoch)
        self.stage = 'observability'
        rep = boresight_observability(rec, params, epoch)
        if not rep.observable:
            raise BoresightUnobservable(rep.message, rep)
        self.stage = 'the base fit (boresight only)'
        self.say('base fit: boresight')
        C = initial_boresight_estimate(rec, params, epoch)
        self.params, self.C = refine_fit(rec, params, C, epoch, [], self.noise)
        lin0 = Linearisation(rec, self.params, self.C, epoch)
        if len(lin0.pairs) < MIN_PAIRS:
            raise InputError(f'only {len(lin0.pairs)} increment pairs (need {MIN_PAIRS}): the '
                             'gyro data must cover consecutive camera fixes without gaps')
        self.lags = self.lags or int(min(20, max(2, len(lin0.pairs) // 10)))
        self.base0 = lin0.evaluate([], self.noise)
        self.split = TimeBlocks(lin0, self.blocks)
        self.ho_before = heldout_score(lin0, [], self.noise, self.split)
        self.tests_before = diagnostics.verdict_tests(self.base0.whitened, len(lin0.pairs),
                                                      self.a_tests, self.lags)
        self.series_before = residual_series(lin0, self.base0, [], self.noise)
        self.base_done = True

    def _spaced(self, rec: Recording, params: dict, epoch: float) -> Recording:
        """
        Return the recording with the fixes at the spacing of the pairs (the module rule).

        Chosen from the whitened residuals of the nominal model at the full rate
        (:func:`strapdown_ros.calibration.reference_spacing.choose_spacing`) unless
        ``spacing_wanted`` states it; kept in ``spacing`` (a JSON record).
        """
        want = getattr(self, 'spacing_wanted', None)
        stamps = rec.fix_stamps
        interval = fix_interval(stamps)
        # at most MAX_SPACING, and enough fixes left for the workflow
        longest = min(MAX_SPACING, float(stamps[-1] - stamps[0]) / (2 * MIN_PAIRS))
        if want is not None:
            choice = stated_spacing(max(float(want), 0.0), stamps)
        else:
            if interval >= longest:
                choice = choose_spacing(np.zeros((0, 3)), [], stamps, longest)
            else:
                self.say('spacing of the fixes: fit at the full rate')
                C0 = initial_boresight_estimate(rec, params, epoch)
                lin = Linearisation(rec, params, C0, epoch)
                white = lin.evaluate([], self.noise).whitened
                choice = choose_spacing(white, lin.pairs.adjacent, stamps, longest)
        if choice.step > 1 and want is None:
            thin = _thinned(rec, choice.spacing_s)
            lin = Linearisation(thin, params, initial_boresight_estimate(thin, params, epoch),
                                epoch)
            choice = refine_spacing(choice, lin.evaluate([], self.noise).whitened,
                                    lin.pairs.adjacent, longest)
        self.spacing = choice.as_dict()
        if choice.step <= 1:
            return rec
        thin = _thinned(rec, choice.spacing_s)
        self.say(f'spacing of the fixes: {choice.spacing_s:.3g} s, {len(thin.fix_stamps)} of '
                 f'{len(stamps)} fixes')
        return thin

    # ------------------------------------------------------------------ the forward search
    def forward(self) -> None:
        """Add effects one turn at a time until the search stops (``stopped_by``)."""
        budget = 2 * len(self.candidates) + self.max_steps + 2   # a turn accepts or removes one
        while self.stopped_by is None:
            if len(self.steps) >= self.max_steps:
                self.stopped_by = 'max_steps'
                break
            budget -= 1
            if budget < 0:
                self.stopped_by = 'iteration_limit'
                break
            self._turn()

    def _turn(self) -> None:
        """One turn: score the candidates left, pick the best, check it, accept it."""
        free, noise = self.free, self.noise
        self.stage = f"the fit of the model with {', '.join(free + list(noise)) or 'no effects'}"
        lin = Linearisation(self.rec, self.params, self.C, self.epoch)
        base = lin.evaluate(free, noise)
        remaining = [c for c in self.candidates if c not in free and c not in noise
                     and c not in self.excluded and c not in self.failed_now]
        if not remaining:
            self.stopped_by = 'no_candidates_left'
            return
        self.say(f'step {len(self.steps) + 1}: scoring {len(remaining)} candidates')
        scores = self._score_all(lin, base, remaining)
        level = self.a_sel / len(remaining)
        significant = _significant(scores, level)
        if not significant:
            if scores or not self.failed_now:      # else every candidate failed: none left
                self.stopped_by = 'no_significant_candidate'
            return
        best = significant[0]
        if self._set_aside_twins(lin, best, significant[1:], level):
            return
        checked = self._heldout_check(lin, best)
        if checked is not None:
            self._accept(best, *checked)

    def _score_all(self, lin, base, remaining) -> list:
        """Score every remaining candidate; record the ones whose fit fails."""
        scores = []
        for c in remaining:
            try:
                sc = score_candidate(lin, self.free, self.noise, base, c)
            except _CANDIDATE_ERRORS as exc:
                self.failed.append({'effect': c, 'step': len(self.steps) + 1,
                                    'reason': _reason(exc)})
                self.failed_now.add(c)
                continue
            # the effect's own test on the raw increments
            why = EFFECTS[c].direct_check(self.rec.delta_theta, sc.get('theta'))
            if why:
                sc['p_value'], sc['direct_check'] = 1.0, why
            scores.append(sc)
        if not self.first_scores:
            keys = ('effect', 'statistic', 'dof', 'p_value', 'direct_check')
            self.first_scores = [{k: v for k, v in s.items() if k in keys} for s in scores]
        return scores

    def _set_aside_twins(self, lin, best, others, level) -> bool:
        """
        Exclude the best candidate and those not separable from it; True when there were any.

        A candidate whose fitted whitened signature correlates above :data:`RHO_MAX` with the
        best one's is its twin, unless the encompassing test tells them apart.
        """
        twins = []
        for s2 in others:
            try:
                if (separation(lin, self.free, self.noise, best['effect'], s2['effect']) > RHO_MAX
                        and not adds_to(lin, self.free, self.noise, best['effect'],
                                        s2['effect'], level)):
                    twins.append(s2['effect'])
            except NUMERICAL_ERRORS:
                pass                                     # cannot show they are twins
        for t in twins:
            self.not_separable.append(sorted([best['effect'], t]))
            self.excluded.add(t)
        if twins:
            self.excluded.add(best['effect'])
        return bool(twins)

    def _heldout_check(self, lin, best):
        """
        Judge the candidate on held-out time blocks.

        Returns (gain, noise terms by fold) when the held-out −2 log L per residual improves,
        else None (the candidate is recorded as failed or rejected).
        """
        name = best['effect']
        trial_free = list(self.free)
        by_fold = None
        try:
            if EFFECTS[name].kind == 'noise':
                by_fold, self.fold_sigma = [], []
                for train, _ in self.split.folds(lin):
                    theta_tr, _, sig_tr = fit_noise(lin, self.free, self.noise, name, train)
                    by_fold.append({**self.noise, name: theta_tr.tolist()})
                    self.fold_sigma.append(sig_tr.tolist())
            else:
                trial_free.append(name)
            ho_b = heldout_score(lin, self.free, self.noise, self.split)
            ho_a = heldout_score(lin, trial_free, self.noise, self.split, by_fold)
        except _CANDIDATE_ERRORS as exc:
            self.failed.append({'effect': name, 'step': len(self.steps) + 1,
                                'reason': 'held-out check: ' + _reason(exc)})
            self.failed_now.add(name)
            return None
        gain = ho_b[0] - ho_a[0]
        if not gain > 0:
            self.rejected.append({'effect': name, 'p_value': best['p_value'],
                                  'heldout_gain': gain,
                                  'reason': 'held-out −2 log L did not improve'})
            self.excluded.add(name)
            return None
        return gain, by_fold

    def _accept(self, best, gain, by_fold) -> None:
        """Add the candidate to the model and refit jointly (unless the refit fails)."""
        name = best['effect']
        self.say(f"step {len(self.steps) + 1}: adding {name} (p = {best['p_value']:.3g})")
        t_noise, t_params, t_free = dict(self.noise), dict(self.params), list(self.free)
        if EFFECTS[name].kind == 'noise':
            t_noise[name] = best['theta'].tolist()
            p = EFFECTS[name].value_parameter
            t_params[p.name] = t_noise[name] if p.size > 1 else t_noise[name][0]
        else:
            t_free.append(name)
        try:
            t_params, t_C = refine_fit(self.rec, t_params, self.C, self.epoch, t_free, t_noise)
            for n_ in t_free:
                check_plausible(n_, t_params)
            Linearisation(self.rec, t_params, t_C, self.epoch).evaluate(t_free, t_noise)
        except _CANDIDATE_ERRORS as exc:
            self.failed.append({'effect': name, 'step': len(self.steps) + 1,
                                'reason': 'joint refit: ' + _reason(exc)})
            self.failed_now.add(name)
            return
        self.noise, self.params, self.free, self.C = t_noise, t_params, t_free, t_C
        folds = [d[name] for d in by_fold] if by_fold else None
        self.steps.append(Step(name, {}, {}, best['statistic'], best['p_value'], gain,
                               best['dof'], fold_theta=folds,
                               fold_sigma=list(self.fold_sigma) if folds else None))
        self.failed_now.clear()

    # ------------------------------------------------------------------ backward elimination
    def backward(self) -> None:
        """Drop, one at a time, an added effect that the others have made unnecessary."""
        changed = True
        while changed and len(self.steps) > 1:
            self.stage = 'backward elimination'
            changed = self._eliminate_one()

    def _eliminate_one(self) -> bool:
        """
        Test every added effect given the others at (α/2)/k; remove the first that fails.

        Returns True when one was removed (and the rest refitted).
        """
        from scipy.stats import chi2
        rec, C, epoch = self.rec, self.C, self.epoch
        lin = Linearisation(rec, self.params, C, epoch)
        full = lin.evaluate(self.free, self.noise)
        level = self.a_sel / len(self.steps)
        for st in list(reversed(self.steps)):
            name = st.effect
            f2 = [n for n in self.free if n != name]
            n2 = {k: v for k, v in self.noise.items() if k != name or k in self.nominal_noise}
            if name in self.nominal_noise:
                n2[name] = self.nominal_noise[name]
            p_without = dict(self.params)
            e = EFFECTS[name]
            p_without[e.value_parameter.name] = self.original[e.value_parameter.name]
            try:
                reduced = Linearisation(rec, p_without, C, epoch).evaluate(f2, n2)
            except _CANDIDATE_ERRORS as exc:
                self.failed.append({'effect': name, 'step': 'backward elimination',
                                    'reason': 'kept: the model without it cannot be fitted: '
                                              + _reason(exc)})
                continue
            stat = max(reduced.nll - full.nll, 0.0)
            p_value = chi2.sf(stat, st.dof)
            if not p_value >= level:
                continue
            self.say(f'backward elimination: removing {name} (p = {p_value:.3g} given the '
                     'others)')
            try:
                new_params, new_C = refine_fit(rec, p_without, C, epoch, f2, n2)
            except _CANDIDATE_ERRORS as exc:
                self.failed.append({'effect': name, 'step': 'backward elimination',
                                    'reason': 'kept: the refit without it failed: '
                                              + _reason(exc)})
                continue
            self.rejected.append({'effect': name, 'p_value': float(p_value),
                                  'heldout_gain': st.heldout_gain,
                                  'reason': 'not significant given the effects added after it '
                                            '(backward elimination)'})
            self.steps.remove(st)
            self.free, self.noise, self.params, self.C = f2, n2, new_params, new_C
            return True
        return False

    # ------------------------------------------------------------------ the final fit
    def judge_again(self, noise: dict) -> None:
        """
        Judge the observability again with the reference noise found, as calibrate_bag will.

        The first judgement used the stated fix noise; where the search found the reference
        noisier (``camera_noise_scale`` above 1), the found model makes ``calibrate_bag`` and the
        calibrator judge the same motion against that noise, so the workflow does too.

        Parameters
        ----------
        noise : dict
            The noise terms found.

        Raises
        ------
        BoresightUnobservable
            The motion does not determine the boresight against the noise found.

        """
        scale = noise.get('camera_noise_anisotropy')
        if scale is None or not np.any(np.asarray(scale, dtype=float) > 1.0):
            return
        self.stage = 'observability with the noise found'
        e = EFFECTS['camera_noise_anisotropy']
        rec = replace(self.rec, fix_P=e.fix_covariance(self.rec.fix_P, np.asarray(scale)))
        rep = boresight_observability(rec, self.params, self.epoch)
        if not rep.observable:
            rep.message = ('with the reference noise found (camera_noise_scale '
                           f"{', '.join(f'{k:.3g}' for k in scale)}): {rep.message}")
            raise BoresightUnobservable(rep.message, rep)

    def result(self) -> DiscrepancyResult:
        """Fit the final model jointly, judge its residuals, and assemble the result."""
        self.stage = 'the final joint fit'
        rec, free, noise, steps = self.rec, self.free, self.noise, self.steps
        self.judge_again(noise)
        lin = Linearisation(rec, self.params, self.C, self.epoch)
        final = lin.evaluate(free, noise)
        tests_after = diagnostics.verdict_tests(final.whitened, len(lin.pairs), self.a_tests,
                                                self.lags)
        passed = tests_after['passed']
        lags = hac_lags(len(lin.pairs))
        sigma_method, cov_z, cov_judged = final_covariance(final, lin, free, noise, self.split,
                                                           tests_after, lags)
        bound = repeatability_bound(len(self.split.folds(lin)), tests_after['level'])
        report_steps(steps, lin, final, free, noise, self.params, self.split, cov_z,
                     cov_judged, sigma_method, bound, level=tests_after['level'], lags=lags)
        ho_after = heldout_score(lin, free, noise, self.split) if steps else self.ho_before
        verdict = (('model_adequate' if not steps else 'explained') if passed
                   else 'unexplained_structure')
        series_after = residual_series(lin, final, free, noise)
        remaining = {} if passed else diagnostics.describe_remaining(series_after, lin)
        if not passed:
            # on the increments of the nominal model: the effects fitted since may have bent
            # to a wiring fault
            p0 = initial_pairs(rec, self.original, self.epoch)
            remaining.update(diagnostics.axis_swap_check(quat_to_rotvec(p0.dq_imu),
                                                         quat_to_rotvec(p0.dq_cam)))
        beta = dcm_to_ypr(self.C)
        _, D2 = ypr_error_to_rotation(*beta)
        D2i = np.linalg.inv(D2)
        # boresight σ: δ is a VF rotation of C; β from δ through D2⁻¹ (004 eq. 8)
        sig_beta = np.sqrt(np.maximum(np.diag(D2i @ cov_z[:3, :3] @ D2i.T), 0.0))
        sig_beta_model = np.sqrt(np.maximum(np.diag(D2i @ final.cov_z[:3, :3] @ D2i.T), 0.0))
        # what calibrate_bag's rule gives on these pairs: the boresight alone (the gyro
        # constants marginalised, the stated noise), σ scaled by √(χ²/dof) when above 1
        b0 = self.base0
        sig_base = np.sqrt(np.maximum(np.diag(D2i @ b0.cov_z[:3, :3] @ D2i.T), 0.0))
        chi2_base = b0.chi2 / max(b0.dof, 1)
        for s in steps:
            s.sigma_method = (sigma_method if EFFECTS[s.effect].kind != 'noise' else
                              'fisher' if sigma_method == 'model' else 'fisher_jackknife')
        model_out = {}
        for s in steps:
            name = EFFECTS[s.effect].value_parameter.name
            model_out[name] = s.parameters[name]
        model_out['boresight'] = beta.tolist()
        found = found_model(self.model, steps, beta, sig_beta, verdict, self.spacing)
        return DiscrepancyResult(
            verdict=verdict, rms_before=float(np.sqrt(np.mean(self.base0.whitened ** 2))),
            rms_after=float(np.sqrt(np.mean(final.whitened ** 2))),
            heldout_rms_before=self.ho_before[1], heldout_rms_after=ho_after[1], steps=steps,
            not_separable=self.not_separable, remaining=remaining, alpha=self.alpha,
            tests_before=self.tests_before, tests_after=tests_after,
            candidates_first_step=self.first_scores, boresight_rad=beta.tolist(),
            boresight_sigma_rad=sig_beta.tolist(), pairs=len(lin.pairs),
            fixes=len(rec.fix_stamps), model_out=model_out,
            series={'before': self.series_before, 'after': series_after},
            rejected=self.rejected, failed_candidates=self.failed, stopped_by=self.stopped_by,
            max_steps=self.max_steps,
            fit_consistent=bool(tests_after['nis']['p_value'] >= tests_after['level']),
            chi2_per_dof=float(tests_after['nis']['per_dof']),
            chi2_per_dof_band=_chi2_band(tests_after), sigma_method=sigma_method,
            hac_lags=lags if sigma_method != 'model' else None,
            boresight_sigma_model_rad=sig_beta_model.tolist(), repeatability_bound=bound,
            found_model=found, reference_spacing=self.spacing,
            boresight_sigma_calibrate_bag_rule_rad=(sig_base
                                                    * np.sqrt(max(1.0, chi2_base))).tolist(),
            boresight_sigma_base_model_rad=sig_base.tolist(), chi2_per_dof_base=chi2_base)


def found_model(model: SensorModel, steps, beta, sigma_beta, verdict: str,
                spacing: dict | None = None) -> SensorModel:
    """
    Return the nominal model with the found effects and the boresight, ready to write.

    Each found effect gets its value and, as its σ key, the largest σ of its components (the
    σ reported, honest when the residuals are not white); the effects the attitude filter can
    estimate online are added to ``augment``, so that it starts from the found value with the
    found σ as its prior.  The spacing of the fixes the pairs used becomes the model's
    ``reference_spacing``, so that the filter takes the reference as the fit did.  Each changed
    key records the rule that produced it.

    Parameters
    ----------
    model : SensorModel
        The nominal model the analysis started from.
    steps : list of Step
        The effects added.
    beta : (3,) array_like
        The boresight β, rad.
    sigma_beta : (3,) array_like
        Its σ, rad.
    verdict : str
        The verdict (recorded in the provenance).
    spacing : dict, optional
        The spacing record of the pairs (:meth:`SpacingChoice.as_dict`).

    Returns
    -------
    SensorModel
        The found model.

    """
    updates, rules = {}, {}
    online = list(model.augment)
    for st in steps:
        e = EFFECTS[st.effect]
        name = e.value_parameter.name
        updates[name] = st.parameters[name]
        rule = (f'found by discrepancy: {st.effect}, LR {st.statistic:.4g} on {st.dof} dof, '
                f'p {st.p_value:.3g}' + ('' if st.repeatable is not False
                                         else '; not repeatable across time blocks'))
        rules[name] = rule
        if e.sigma_parameter:
            updates[e.sigma_parameter] = float(np.max(np.atleast_1d(st.sigma[name])))
            rules[e.sigma_parameter] = 'the σ of the found value (its largest component)'
        if e.filter_state and st.effect != 'gyro_bias' and st.effect not in online:
            online.append(st.effect)
    updates['boresight'] = [float(b) for b in beta]
    rules['boresight'] = f'estimated by discrepancy (verdict {verdict})'
    updates['boresight_sigma'] = float(np.max(sigma_beta))
    rules['boresight_sigma'] = 'the largest σ of the estimated boresight angles'
    if spacing and spacing.get('step', 1) > 1 and spacing.get('spacing_s'):
        updates['reference_spacing'] = float(f"{spacing['spacing_s']:.6g}")
        rules['reference_spacing'] = ('the spacing of the fixes of the pairs: one fix in '
                                      f"{spacing['step']} ({spacing.get('reason') or ''})"
                                      )[:400].replace(' ()', '')
    if online != list(model.augment):
        updates['augment'] = ','.join(online)
        rules['augment'] = 'every found effect the filter can estimate online'
    out = model.with_values(updates)
    prov = dict(out.provenance)
    prov.update(rules)
    return SensorModel.from_values(out.values(), stated=out.stated, provenance=prov,
                                   source='discrepancy')


def _thinned(rec: Recording, spacing: float) -> Recording:
    """Return the recording with one fix per slot of ``spacing`` seconds."""
    keep = thin_fixes(rec.fix_stamps, spacing)
    return Recording(rec.gyro_stamps, rec.delta_theta, rec.fix_stamps[keep], rec.fix_q[keep],
                     rec.fix_P[keep], rec.gaps)


def _significant(scores: list, level: float) -> list:
    """
    Return the scores below ``level``, smallest p-value first, mean before variance.

    A pure variance term can absorb any mean structure by inflating the covariance, so it is
    considered only when no candidate with a mean signature passes.
    """
    scores.sort(key=lambda s: (s['p_value'], -s['statistic']))
    significant = [s for s in scores if s['p_value'] < level]
    with_mean = [s for s in significant if EFFECTS[s['effect']].has_mean]
    return with_mean or significant


def _chi2_band(tests: dict) -> list:
    """Return the two-sided band of the final χ²/dof at the test level."""
    from scipy.stats import chi2
    n = tests['nis']['dof']
    half = 0.5 * tests['level']
    return [float(chi2.ppf(half, n) / n), float(chi2.isf(half, n) / n)]
