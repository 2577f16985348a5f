"""
The discrepancy workflow: where a recording and its model disagree, which effect is missing,
how large it is, and how much the disagreement shrinks once it is added.

Residuals (004 §4.2, eq. 5–6).  For consecutive camera fixes n−1, n the measured camera
increment ΔS_avu is compared with the increment ΔS_imu predicted from the gyro data under the
model (its known effects compensated); f_n = skew(ΔS_avuᵀ Cᵀ ΔS_imu C), VF axes.  The
boresight C is always estimated (the calibration target, not a suspect).  The residuals are
whitened by the calibrator's correlated covariance (:mod:`.linear_model`).

Selection, stated once:

* every candidate of the library (:data:`~strapdown_ros.sensors.effects.CANDIDATES`) is scored
  by a likelihood-ratio statistic against the current model: the drop of −2 log L when its
  parameters are freed (systematic effects: GLS; noise terms: maximum likelihood), referred to
  χ² with as many degrees of freedom as the combinations the trajectory separates;
* the family-wise level α is split: **α/2 for the selection, α/2 for the verdict tests**, so that
  a recording the model describes is called anything but ``model_adequate`` with probability
  at most α;
* the smallest p-value is tested at the **Bonferroni** level (α/2)/m (m = candidates left);
  **mean before variance**: pure variance terms (which can absorb any mean structure by
  inflating the covariance) are considered only when no candidate with a mean signature passes;
* it is accepted only if, in addition, the **held-out** −2 log L per residual improves: the
  pairs are cut into ``blocks`` contiguous time blocks (never shuffled) and each block is
  judged by parameters fitted on the others (leave-one-block-out cross-validation), so every
  residual is judged by parameters fitted without it;
* a candidate whose fitted whitened signature (the residual pattern it explains) has an
  |correlation| above :data:`RHO_MAX` with that of another significant one is not picked: the
  pair is reported "not separable on this trajectory" — unless the encompassing test says the
  data tell them apart: the best candidate still passes its likelihood-ratio test at the same
  level with the other one in the model too (systematic effects only; :func:`_adds_to`);
* accepted effects are refitted jointly (Gauss–Newton on the nonlinear model) and the search
  repeats until nothing passes;
* **backward elimination**: an added effect whose own likelihood-ratio test, given all the
  others, no longer passes at (α/2)/k (k = effects added) is removed (it only mimicked one added
  later), and the rest refitted.

Limits and failures, said out loud: ``max_steps`` counts accepted effects and ``stopped_by``
(:data:`STOPPED_BY`) says what ended the search; a candidate whose own fit fails numerically (or
whose noise scale lands on the end of its stated range) is dropped from that step and listed in
``failed_candidates``; a fit without any candidate that fails raises :class:`AnalysisError` (not
a ValueError: never "bad input").  The boresight must be observable by the rule of
``calibrate_bag`` (:func:`boresight_observability`), else :class:`BoresightUnobservable`.

Verdict tests on the final whitened residuals (each at (α/2)/3): the NIS (χ² of the whitened
sum of squares), the Ljung–Box whiteness test (3 components, ``lags`` lags) and an extreme-value
test on the largest |residual|.  ``model_adequate``: nothing added and all pass;
``explained``: effects added and all pass; ``unexplained_structure``: a test still fails.
``fit_consistent``: the NIS test passes (χ²/dof inside its band).  When the NIS or whiteness test
fails, every σ is the Newey–West sandwich (:func:`.linear_model.hac_covariance`; noise terms: the
leave-one-block-out jackknife), never below the model's, and ``sigma_method`` is ``"hac"``; where
the leave-one-block-out jackknife over time is larger still (structure slower than the sandwich's
bandwidth), the σ is raised to it and ``sigma_method`` is ``"hac_jackknife"``.
Each effect's leave-one-block-out estimates must scatter as its σ says (``repeatable``).
No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from strapdown_ros.calibration.boresight import axis_alignment, check_observability
from strapdown_ros.calibration.pairs import build_pairs, GyroRecord
from strapdown_ros.discrepancy import diagnostics
from strapdown_ros.discrepancy.linear_model import hac_covariance
from strapdown_ros.discrepancy.linearisation import (AnalysisError, BoresightUnobservable,
                                                     fit_noise, InputError, Linearisation,
                                                     noise_of, NUMERICAL_ERRORS, NumericalFailure,
                                                     Recording)
from strapdown_ros.rotation import (dcm_to_ypr, quat_to_dcm, quat_to_rotvec, rotvec_to_dcm,
                                    ypr_error_to_rotation)
from strapdown_ros.sensors.effects import CANDIDATES, EFFECTS, GyroEffects
from strapdown_ros.text import json_clean

__all__ = ['Recording', 'analyse', 'json_clean', 'DiscrepancyResult', 'RHO_MAX', 'DEFAULT_ALPHA', 'MIN_PAIRS',
           'InputError', 'AnalysisError', 'BoresightUnobservable', 'boresight_observability',
           'STOPPED_BY', 'PLAUSIBLE_MAX']

#: why the search stopped: the step limit (accepted effects), no candidate passing its test,
#: none left to try (all added, excluded or failed numerically), or the safety bound on turns
STOPPED_BY = ('max_steps', 'no_significant_candidate', 'no_candidates_left', 'iteration_limit')

DEFAULT_ALPHA = 0.01
#: canonical correlation above which two whitened signatures are called not separable
RHO_MAX = 0.95
MIN_PAIRS = 12
#: largest |value| of a fitted dimensionless gyro effect (scale factor, asymmetry, misalignment
#: in rad) the linearised workflow reports; beyond it the model is not a small correction (a
#: wiring fault, a wrong unit) and the candidate fails with that reason.  Parameters with a
#: stated range (camera_time_offset: ±10 s) are held to it.
PLAUSIBLE_MAX = {'gyro_scale_factor': 0.1, 'gyro_scale_asymmetry': 0.1, 'gyro_misalignment': 0.1}


def _check_plausible(name: str, params: dict) -> None:
    e = EFFECTS[name]
    p = e.value_parameter
    v = np.atleast_1d(np.asarray(e.value(params), dtype=float))
    hi = PLAUSIBLE_MAX.get(name)
    lo_p, hi_p = p.minimum, p.maximum
    if not np.all(np.isfinite(v)):
        raise NumericalFailure(f'a non-finite {p.name}')
    if hi is not None and np.max(np.abs(v)) > hi:
        raise NumericalFailure(f'|{p.name}| = {np.max(np.abs(v)):.3g} > {hi:g}: not a small '
                               f'correction, outside what the linearised workflow reports')
    if (lo_p is not None and np.min(v) < lo_p) or (hi_p is not None and np.max(v) > hi_p):
        raise NumericalFailure(f'{p.name} = {_short(v)} outside its range '
                               f'[{lo_p}, {hi_p}]')


def _short(v):
    return np.round(np.asarray(v, dtype=float), 6).tolist()
# ----------------------------------------------------------------------------- results
@dataclass
class Step:
    effect: str
    parameters: dict
    sigma: dict
    statistic: float
    p_value: float
    heldout_gain: float
    dof: int
    fold_theta: list | None = None        # noise terms: θ fitted on each fold's training blocks
    sigma_model: dict = field(default_factory=dict)   # σ as the model states it
    fold_values: list | None = None       # leave-one-block-out estimates
    spread: dict = field(default_factory=dict)        # their jackknife σ, ROS parameter names
    spread_ratio: float | None = None     # largest jackknife σ ÷ reported σ over the combinations
    repeatable: bool | None = None

    def as_dict(self):
        return {'effect': self.effect, 'parameters': self.parameters, 'sigma': self.sigma,
                'sigma_model': self.sigma_model, 'statistic': self.statistic,
                'p_value': self.p_value, 'heldout_gain': self.heldout_gain, 'dof': self.dof,
                'repeatable': self.repeatable, 'spread': self.spread,
                'spread_ratio': self.spread_ratio, 'fold_values': self.fold_values}


@dataclass
class DiscrepancyResult:
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
    model_out: dict                      # effect parameter values to write to the model
    series: dict                         # per-pair arrays for the report (before/after)
    rejected: list = field(default_factory=list)
    failed_candidates: list = field(default_factory=list)   # [{effect, step, reason}]
    stopped_by: str | None = None                          # one of STOPPED_BY
    max_steps: int = 6
    fit_consistent: bool = True           # final χ²/dof inside its band at the test level
    chi2_per_dof: float = float('nan')
    chi2_per_dof_band: list = field(default_factory=list)
    sigma_method: str = 'model'           # "model" | "hac" (Newey–West) | "hac_jackknife"
    hac_lags: int | None = None
    boresight_sigma_model_rad: list = field(default_factory=list)
    repeatability_bound: float = float('nan')
    observable: bool = True

    def as_json(self) -> dict:
        return json_clean({
            'verdict': self.verdict, 'rms_before': self.rms_before, 'rms_after': self.rms_after,
            'heldout_rms_before': self.heldout_rms_before, 'heldout_rms_after': self.heldout_rms_after,
            'steps': [s.as_dict() for s in self.steps], 'not_separable': self.not_separable,
            'remaining': self.remaining, 'alpha': self.alpha,
            'selection': {'test': 'likelihood ratio, χ²(dof)',
                          'correction': 'α/2 for the selection (Bonferroni (α/2)/m per step), α/2 for the three tests',
                          'heldout': '6 time blocks, leave-one-block-out; gain = drop of −2 log L per judged residual',
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
            'pairs': self.pairs, 'fixes': self.fixes})


# ----------------------------------------------------------------------------- the workflow
class _Split:
    """
    Time-blocked cross-validation: ``blocks`` equal spans of the record; fold k judges block k
    with parameters fitted on the others.  Fixed in time, so it applies to any linearisation
    (the pairs may change with a time offset).
    """

    def __init__(self, lin: Linearisation, blocks: int):
        t = lin.pairs.t_end
        self.edges = np.linspace(t[0], t[-1] + 1e-9, blocks + 1)
        self.blocks = blocks

    def folds(self, lin: Linearisation):
        """[(train mask, test mask)] per block."""
        b = np.clip(np.searchsorted(self.edges, lin.pairs.t_end, side='right') - 1, 0, self.blocks - 1)
        return [(b != k, b == k) for k in range(self.blocks) if np.any(b == k)]


def _heldout(lin, free, noise, split, noise_by_fold=None):
    """
    Leave-one-block-out cross-validation over time blocks: each block is judged by parameters
    fitted on the other blocks.  Returns (−2 log L per judged residual, whitened RMS of the
    judged residuals).  ``noise_by_fold``: the noise terms estimated on each fold's training
    blocks.
    """
    total, sq, n = 0.0, 0.0, 0
    for k, (train, test) in enumerate(split.folds(lin)):
        nz = noise if noise_by_fold is None else noise_by_fold[k]
        f_tr = lin.evaluate(free, nz, train)
        rows = lin.rows(test)
        J = lin.design(free)[rows]
        W = lin.whitener(nz, test)
        pred = lin.residual(nz)[rows] - J @ f_tr.z - lin.U[rows][:, lin.prior_var > 0] @ f_tr.x
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


def _separation(lin, free, noise, a: str, b: str) -> float:
    """
    |correlation| of the whitened residual patterns that a and b each fit (base columns
    removed): near 1 when both explain the same disagreement, so the data cannot say which.

    Systematic terms: the fitted patterns A_a A_a⁺ w and A_b A_b⁺ w of the whitened, projected
    residual w.  Noise terms: their patterns of excess variance, per whitened component.
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
                cols.append(np.diagonal(dP[lin.pairs.fix_end] + dP[lin.pairs.fix_start], axis1=1, axis2=2).ravel())
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


def _adds_to(lin, free, noise, a: str, b: str, level: float) -> bool:
    """
    Encompassing test: does systematic effect ``a`` still explain significantly more (LR test at
    ``level``) once ``b`` is in the model too?  Then the data tell a from b, however alike the
    residual patterns they each fit alone.  Noise terms: False (their patterns only).
    """
    from scipy.stats import chi2
    if EFFECTS[a].kind == 'noise' or EFFECTS[b].kind == 'noise':
        return False
    W = lin.whitener(noise)
    both = free + [a, b]
    dof = int(np.linalg.matrix_rank(W.apply(lin.design(both)))) - \
        int(np.linalg.matrix_rank(W.apply(lin.design(free + [b]))))
    if dof <= 0:
        return False
    stat = lin.evaluate(free + [b], noise).chi2 - lin.evaluate(both, noise).chi2
    return bool(chi2.sf(max(stat, 0.0), dof) < level)


def _score(lin, free, noise, base, name):
    from scipy.stats import chi2
    e = EFFECTS[name]
    why = e.direct_check(lin.rec.delta_theta, None)
    if why:                                    # the raw data rule it out: no fit needed
        return dict(effect=name, statistic=0.0, dof=e.size, p_value=1.0, direct_check=why)
    if e.kind == 'noise':
        theta, f, sig = fit_noise(lin, free, noise, name)
        stat = max(base.nll - f.nll, 0.0)
        dof = e.size
        return dict(effect=name, statistic=stat, dof=dof, p_value=float(chi2.sf(stat, dof)), theta=theta, sigma=sig)
    f = lin.evaluate(free + [name], noise)
    dof = int(np.linalg.matrix_rank(lin.whitener(noise).apply(lin.design(free + [name])), tol=None)) - \
        int(np.linalg.matrix_rank(lin.whitener(noise).apply(lin.design(free))))
    stat = max(base.chi2 - f.chi2, 0.0)
    dof = max(dof, 1)
    return dict(effect=name, statistic=stat, dof=dof, p_value=float(chi2.sf(stat, dof)))


def refine_fit(rec, params, C, epoch, free, noise, iterations=6):
    """
    Gauss–Newton on the boresight and the free systematic effects (values in ``params``),
    until a step improves χ² by less than 1e-3 (or ``iterations``).
    """
    last = np.inf
    for _ in range(iterations):
        lin = Linearisation(rec, params, C, epoch)
        f = lin.evaluate(free, noise)
        if last - f.chi2 < 1e-3 and np.max(np.abs(f.z)) < 1e-6:
            break
        last = f.chi2
        z = -f.z                                     # r + J z = 0: model += −(GLS of r on J)
        C = C @ rotvec_to_dcm(z[:3])
        k = 3
        for name in free:
            e = EFFECTS[name]
            S = e.fit_basis()
            q = e.size if S is None else S.shape[1]
            dz = z[k:k + q]
            k += q
            p = e.value_parameter
            v = e.value(params) + (dz if S is None else S @ dz)
            params[p.name] = v.tolist() if p.size > 1 else float(v[0])
    return params, C


def _initial_pairs(rec, params, epoch):
    """Increment pairs of the nominal model (its effects compensated), before any fit."""
    lin0 = GyroEffects(params, epoch=epoch)
    st = rec.gyro_stamps
    T = np.diff(st, prepend=st[0] - (st[1] - st[0]))
    g = GyroRecord(st, lin0.compensate(rec.delta_theta, st, T))
    pairs = build_pairs(g, rec.fix_stamps, rec.fix_q, float(EFFECTS['time_offset'].value(params)[0]), rec.gaps)
    if len(pairs) < 2:
        raise InputError(f'only {len(pairs)} increment pair(s): the gyro data must cover consecutive camera fixes')
    return pairs


def initial_boresight_estimate(rec, params, epoch):
    pairs = _initial_pairs(rec, params, epoch)
    return axis_alignment(quat_to_dcm(pairs.dq_imu), quat_to_dcm(pairs.dq_cam))


def boresight_observability(rec: Recording, params: dict, epoch: float | None = None):
    """
    The observability of the boresight on this recording, by the rule ``calibrate_bag`` and the
    calibrator use (:func:`strapdown_ros.calibration.boresight.check_observability`: 004 §4.1's rotation
    condition and the conditioning of the normal matrix in VF rotation axes).

    Parameters
    ----------
    rec : Recording
        The recording.
    params : dict
        The nominal model (its effects compensated, its time offset applied; the calibrator's
        ``min_rotation_deg`` and ``max_sigma`` as there, defaults 0.5° and 1e-3 rad).
    epoch : float, optional
        Origin of the effects' time (default: the first gyro stamp), s.

    Returns
    -------
    ObservabilityReport
        ``observable``, ``unobservable`` (the combinations in words) and ``message``.
    """

    epoch = float(rec.gyro_stamps[0]) if epoch is None else epoch
    pairs = _initial_pairs(rec, params, epoch)
    rw2 = float(params.get('gyro_random_walk', 0.0)) ** 2
    P = rec.fix_P
    items = [SimpleNamespace(dq_cam=pairs.dq_cam[n], dq_imu=pairs.dq_imu[n],
                             cov_cam=P[pairs.fix_start[n]] + P[pairs.fix_end[n]],
                             cov_imu=rw2 * float(pairs.duration[n]) * np.eye(3))
             for n in range(len(pairs))]
    return check_observability(items,
                               min_rotation=np.radians(float(params.get('min_rotation_deg', 0.5))),
                               max_sigma=float(params.get('max_sigma', 1e-3)))


def _values_json(name, params, cov=None, theta=None, sigma=None):
    """(parameters, sigma) of an effect by ROS parameter name, SI units."""
    e = EFFECTS[name]
    p = e.value_parameter
    v = e.value(params) if theta is None else np.asarray(theta, dtype=float)
    if sigma is None:
        S = e.fit_basis()
        full = cov if S is None else S @ cov @ S.T
        sigma = np.sqrt(np.maximum(np.diag(full), 0.0))
    val = v.tolist() if p.size > 1 else float(v[0])
    sig = np.asarray(sigma, dtype=float).tolist() if p.size > 1 else float(np.asarray(sigma).reshape(-1)[0])
    return {p.name: val}, {p.name: sig}


def analyse(rec: Recording, params: dict, alpha: float = DEFAULT_ALPHA, blocks: int = 6, lags: int | None = None,
            max_steps: int = 6, candidates=CANDIDATES, progress=None) -> DiscrepancyResult:
    """
    Run the workflow.

    Parameters
    ----------
    rec : Recording
        The recording.
    params : dict
        The nominal model (validated node parameters, effect values included).
    alpha : float
        Family-wise level (α/2 for the selection, α/2 for the verdict tests).
    blocks : int
        Contiguous time blocks of the held-out (leave-one-block-out) check.
    lags : int, optional
        Ljung–Box lags (default min(20, max(2, pairs/10))).
    max_steps : int
        Most effects ACCEPTED by the search (rejected candidates do not count); when it stops
        the search, ``stopped_by`` says ``"max_steps"``.
    candidates : sequence of str
        Effect names to consider.
    progress : callable, optional
        ``progress(text)`` is called between stages.

    Returns
    -------
    DiscrepancyResult

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
    if len(rec.fix_stamps) < MIN_PAIRS + 1:
        raise InputError(f'{len(rec.fix_stamps)} camera fixes: the workflow needs at least {MIN_PAIRS + 1}')
    stage = ['observability', False]        # what is being computed; the base fit is done
    try:
        return _analyse(rec, dict(params), alpha, blocks, lags, max_steps, candidates,
                        progress or (lambda s: None), stage)
    except NUMERICAL_ERRORS as exc:
        raise AnalysisError(f'the analysis cannot be computed: {stage[0]} failed numerically '
                            f'({_reason(exc)})') from exc
    except InputError as exc:
        if not stage[1]:
            raise
        # the input was usable (the base fit ran): a fitted value moved the pairs off the data
        raise AnalysisError(f'the analysis cannot be computed: {stage[0]} failed ({exc})') from exc


def _reason(exc) -> str:
    text = f'{type(exc).__name__}: {exc}' if not isinstance(exc, NumericalFailure) else str(exc)
    return text if len(text) <= 300 else text[:297] + '...'


def _analyse(rec, params, alpha, blocks, lags, max_steps, candidates, say, stage):
    from scipy.stats import chi2 as _chi2
    original = dict(params)
    epoch = float(rec.gyro_stamps[0])
    noise = noise_of(params)
    nominal_noise = dict(noise)
    rep = boresight_observability(rec, params, epoch)
    if not rep.observable:
        raise BoresightUnobservable(rep.message, rep)
    stage[0] = 'the base fit (boresight only)'
    say('base fit: boresight')
    C = initial_boresight_estimate(rec, params, epoch)
    params, C = refine_fit(rec, params, C, epoch, [], noise)
    lin0 = Linearisation(rec, params, C, epoch)
    if len(lin0.pairs) < MIN_PAIRS:
        raise InputError(f'only {len(lin0.pairs)} increment pairs (need {MIN_PAIRS}): the gyro data must cover '
                         f'consecutive camera fixes without gaps')
    lags = lags or int(min(20, max(2, len(lin0.pairs) // 10)))
    base0 = lin0.evaluate([], noise)
    split = _Split(lin0, blocks)
    ho_before = _heldout(lin0, [], noise, split)
    # the family-wise level α is split: α/2 for the selection, α/2 for the three verdict tests, so a
    # recording the model describes is called anything but model_adequate with probability ≤ α
    a_sel, a_tests = 0.5 * alpha, 0.5 * alpha
    tests_before = diagnostics.verdict_tests(base0.whitened, len(lin0.pairs), a_tests, lags)
    series_before = _series(lin0, base0, [])
    stage[1] = True
    # a candidate's own fit may fail: numerically, or by moving the pairs off the data
    candidate_errors = NUMERICAL_ERRORS + (InputError,)

    free: list[str] = []
    steps: list[Step] = []
    not_separable: list = []
    rejected: list = []
    failed: list = []
    excluded: set = set()
    failed_now: set = set()               # failed numerically since the last accepted effect
    first_scores: list = []
    stopped_by = None
    budget = 2 * len(candidates) + max_steps + 2      # every turn accepts or removes a candidate
    while stopped_by is None:
        if len(steps) >= max_steps:
            stopped_by = 'max_steps'
            break
        budget -= 1
        if budget < 0:
            stopped_by = 'iteration_limit'
            break
        stage[0] = f"the fit of the model with {', '.join(free + list(noise)) or 'no effects'}"
        lin = Linearisation(rec, params, C, epoch)
        base = lin.evaluate(free, noise)
        remaining = [c for c in candidates if c not in free and c not in noise
                     and c not in excluded and c not in failed_now]
        if not remaining:
            stopped_by = 'no_candidates_left'
            break
        say(f'step {len(steps) + 1}: scoring {len(remaining)} candidates')
        scores = []
        for c in remaining:
            try:
                sc = _score(lin, free, noise, base, c)
            except candidate_errors as exc:
                failed.append({'effect': c, 'step': len(steps) + 1, 'reason': _reason(exc)})
                failed_now.add(c)
                continue
            # the effect's own test on the raw increments
            why = EFFECTS[c].direct_check(rec.delta_theta, sc.get('theta'))
            if why:
                sc['p_value'], sc['direct_check'] = 1.0, why
            scores.append(sc)
        if not first_scores:
            first_scores = [{k: v for k, v in s.items() if k in ('effect', 'statistic', 'dof', 'p_value',
                                                                 'direct_check')} for s in scores]
        level = a_sel / len(remaining)
        scores.sort(key=lambda s: (s['p_value'], -s['statistic']))
        significant = [s for s in scores if s['p_value'] < level]
        # mean before variance: a pure variance term can absorb any mean structure by inflating
        # the covariance, so it is considered only when no candidate with a mean signature passes
        with_mean = [s for s in significant if EFFECTS[s['effect']].has_mean]
        significant = with_mean or significant
        if not significant:
            if not scores and failed_now:
                continue                                 # every candidate failed: none left
            stopped_by = 'no_significant_candidate'
            break
        best = significant[0]
        twins = []
        for s2 in significant[1:]:
            try:
                if _separation(lin, free, noise, best['effect'], s2['effect']) > RHO_MAX and \
                        not _adds_to(lin, free, noise, best['effect'], s2['effect'], level):
                    twins.append(s2['effect'])
            except NUMERICAL_ERRORS:
                pass                                     # cannot show they are twins
        if twins:
            for t in twins:
                not_separable.append(sorted([best['effect'], t]))
                excluded.add(t)
            excluded.add(best['effect'])
            continue
        name = best['effect']
        trial_free = list(free)
        by_fold = None
        try:
            if EFFECTS[name].kind == 'noise':
                by_fold = []
                for train, _ in split.folds(lin):
                    theta_tr, _, _ = fit_noise(lin, free, noise, name, train)
                    by_fold.append({**noise, name: theta_tr.tolist()})
            else:
                trial_free.append(name)
            ho_b = _heldout(lin, free, noise, split)
            ho_a = _heldout(lin, trial_free, noise, split, by_fold)
        except candidate_errors as exc:
            failed.append({'effect': name, 'step': len(steps) + 1,
                           'reason': 'held-out check: ' + _reason(exc)})
            failed_now.add(name)
            continue
        gain = ho_b[0] - ho_a[0]
        if not gain > 0:
            rejected.append({'effect': name, 'p_value': best['p_value'], 'heldout_gain': gain,
                             'reason': 'held-out −2 log L did not improve'})
            excluded.add(name)
            continue
        say(f"step {len(steps) + 1}: adding {name} (p = {best['p_value']:.3g})")
        t_noise, t_params, t_free = dict(noise), dict(params), list(free)
        if EFFECTS[name].kind == 'noise':
            t_noise[name] = best['theta'].tolist()
            p = EFFECTS[name].value_parameter
            t_params[p.name] = t_noise[name] if p.size > 1 else t_noise[name][0]
        else:
            t_free.append(name)
        try:
            t_params, t_C = refine_fit(rec, t_params, C, epoch, t_free, t_noise)
            for n_ in t_free:
                _check_plausible(n_, t_params)
            Linearisation(rec, t_params, t_C, epoch).evaluate(t_free, t_noise)
        except candidate_errors as exc:
            failed.append({'effect': name, 'step': len(steps) + 1,
                           'reason': 'joint refit: ' + _reason(exc)})
            failed_now.add(name)
            continue
        noise, params, free, C = t_noise, t_params, t_free, t_C
        folds = [d[name] for d in by_fold] if by_fold else None
        steps.append(Step(name, {}, {}, best['statistic'], best['p_value'], gain, best['dof'],
                          fold_theta=folds))
        failed_now.clear()
    # backward elimination: drop an added effect that the others have made unnecessary
    changed = True
    while changed and len(steps) > 1:
        changed = False
        stage[0] = 'backward elimination'
        lin = Linearisation(rec, params, C, epoch)
        full = lin.evaluate(free, noise)
        level = a_sel / len(steps)
        for st in list(reversed(steps)):
            name = st.effect
            f2 = [n for n in free if n != name]
            n2 = {k: v for k, v in noise.items() if k != name or k in nominal_noise}
            if name in nominal_noise:
                n2[name] = nominal_noise[name]
            p_without = dict(params)
            e = EFFECTS[name]
            p_without[e.value_parameter.name] = original[e.value_parameter.name]
            try:
                lin2 = Linearisation(rec, p_without, C, epoch)
                reduced = lin2.evaluate(f2, n2)
            except candidate_errors as exc:
                failed.append({'effect': name, 'step': 'backward elimination',
                               'reason': 'kept: the model without it cannot be fitted: '
                                         + _reason(exc)})
                continue
            stat = max(reduced.nll - full.nll, 0.0)
            if _chi2.sf(stat, st.dof) >= level:
                say(f'backward elimination: removing {name} (p = {_chi2.sf(stat, st.dof):.3g} given the others)')
                try:
                    new_params, new_C = refine_fit(rec, p_without, C, epoch, f2, n2)
                except candidate_errors as exc:
                    failed.append({'effect': name, 'step': 'backward elimination',
                                   'reason': 'kept: the refit without it failed: ' + _reason(exc)})
                    continue
                rejected.append({'effect': name, 'p_value': float(_chi2.sf(stat, st.dof)), 'heldout_gain': st.heldout_gain,
                                 'reason': 'not significant given the effects added after it (backward elimination)'})
                steps.remove(st)
                free, noise, params, C = f2, n2, new_params, new_C
                changed = True
                break
    # final joint fit and the σ of every added effect
    stage[0] = 'the final joint fit'
    lin = Linearisation(rec, params, C, epoch)
    final = lin.evaluate(free, noise)
    tests_after = diagnostics.verdict_tests(final.whitened, len(lin.pairs), a_tests, lags)
    passed = tests_after['passed']
    # honest σ: when the residuals are not white or not of the stated size, the model covariance
    # assumes what the tests just rejected; the Newey–West sandwich does not
    hac_lags = _hac_lags(len(lin.pairs))
    if tests_after['nis']['p_value'] >= tests_after['level'] and \
            tests_after['whiteness']['p_value'] >= tests_after['level']:
        sigma_method, cov_z = 'model', final.cov_z
    else:
        sigma_method = 'hac'
        cov_h = hac_covariance(final, hac_lags)
        # never below the model's σ (the sandwich is noisy where the model is right)
        d = np.sqrt(np.maximum(np.diag(final.cov_z), 0.0))
        dh = np.sqrt(np.maximum(np.diag(cov_h), 0.0))
        f_ = np.maximum(dh, d) / np.where(d > 0, d, 1.0)
        cov_z = np.where(np.outer(d, d) > 0, final.cov_z * np.outer(f_, f_), cov_h)
    # the σ the repeatability check judges (model or sandwich); the reported σ may grow below
    cov_judged = cov_z
    if sigma_method == 'hac':
        # and never below the leave-one-block-out jackknife over time (the sandwich's bandwidth
        # cannot cover structure as slow as the blocks: seen on real recordings whose χ²/dof is
        # in the thousands)
        cov_z, jk_used = _jackknife_floor(lin, free, noise, split, cov_z)
        if jk_used:
            sigma_method = 'hac_jackknife'
    k = 3
    offsets = {}
    for name in free:
        S = EFFECTS[name].fit_basis()
        q = EFFECTS[name].size if S is None else S.shape[1]
        offsets[name] = (k, q)
        k += q
    folds = split.folds(lin)
    kf = len(folds)
    # repeatability: the leave-one-block-out estimates scatter about as the stated σ says
    # (jackknife σ = √((K−1)/K Σ(θ_k − θ̄)²) ≈ σ); a ratio beyond the χ²(K−1) bound at the test
    # level is not
    dof_k = max(kf - 1, 1)
    rep_bound = float(np.sqrt(_chi2.ppf(1.0 - tests_after['level'], dof_k) / dof_k))
    for s in steps:
        if s.effect in offsets:
            a, q = offsets[s.effect]
            s.parameters, s.sigma = _values_json(s.effect, params, cov_z[a:a + q, a:a + q])
            _, s.sigma_model = _values_json(s.effect, params, final.cov_z[a:a + q, a:a + q])
            try:
                zf = np.array([lin.evaluate(free, noise, train).z[a:a + q] for train, _ in folds])
            except NUMERICAL_ERRORS:
                zf = None
            sd = np.sqrt(np.maximum(np.diag(cov_judged[a:a + q, a:a + q]), 0.0))
            S = EFFECTS[s.effect].fit_basis()
            v0 = EFFECTS[s.effect].value(params)
            if zf is not None:
                vals = [(v0 + (z if S is None else S @ z)) for z in zf]
                s.fold_values = [v.tolist() for v in vals]
                jk = np.sqrt((kf - 1) / kf * np.sum((zf - zf.mean(axis=0)) ** 2, axis=0))
                s.spread_ratio = float(np.max(jk / np.where(sd > 0, sd, np.inf)))
                dev = np.array(vals) - np.mean(vals, axis=0)
                full_jk = np.sqrt((kf - 1) / kf * np.sum(dev ** 2, axis=0))
                s.spread = _values_json(s.effect, params, theta=v0, sigma=full_jk)[1]
        else:
            try:
                _, _, sig = fit_noise(lin, free, noise, s.effect)
            except NUMERICAL_ERRORS:
                sig = np.full(EFFECTS[s.effect].size, np.inf)
            theta = np.asarray(noise[s.effect], dtype=float)
            s.sigma_model = _values_json(s.effect, params, theta=theta, sigma=sig)[1]
            if s.fold_theta:
                ft = np.asarray(s.fold_theta, dtype=float)
                jk = np.sqrt((len(ft) - 1) / len(ft) * np.sum((ft - ft.mean(axis=0)) ** 2, axis=0))
                s.fold_values = ft.tolist()
                s.spread = _values_json(s.effect, params, theta=theta, sigma=jk)[1]
                s.spread_ratio = float(np.max(jk / np.where(sig > 0, sig, np.inf)))
                if sigma_method in ('hac', 'hac_jackknife'):
                    sig = np.maximum(sig, jk)       # noise terms: the time-block jackknife
            s.parameters, s.sigma = _values_json(s.effect, params, theta=theta, sigma=sig)
        if s.spread_ratio is not None:
            s.repeatable = bool(s.spread_ratio <= rep_bound)
    ho_after = _heldout(lin, free, noise, split) if steps else ho_before
    verdict = ('model_adequate' if not steps else 'explained') if passed else 'unexplained_structure'
    series_after = _series(lin, final, free)
    remaining = {} if passed else diagnostics.describe_remaining(series_after, lin)
    if not passed:
        # on the increments of the nominal model: the effects fitted since may have bent to a
        # wiring fault
        p0 = _initial_pairs(rec, original, epoch)
        remaining.update(diagnostics.axis_swap_check(_rotvec(p0.dq_imu), _rotvec(p0.dq_cam)))
    beta = dcm_to_ypr(C)
    _, D2 = ypr_error_to_rotation(*beta)
    D2i = np.linalg.inv(D2)
    # boresight σ: δ is a VF rotation of C; β from δ through D2⁻¹ (004 eq. 8)
    sig_beta = np.sqrt(np.maximum(np.diag(D2i @ cov_z[:3, :3] @ D2i.T), 0.0))
    sig_beta_model = np.sqrt(np.maximum(np.diag(D2i @ final.cov_z[:3, :3] @ D2i.T), 0.0))
    model_out = {EFFECTS[s.effect].value_parameter.name: s.parameters[EFFECTS[s.effect].value_parameter.name]
                 for s in steps}
    model_out['boresight'] = beta.tolist()
    nis = tests_after['nis']
    n = nis['dof']
    half = 0.5 * tests_after['level']
    band = [float(_chi2.ppf(half, n) / n), float(_chi2.isf(half, n) / n)]
    return DiscrepancyResult(
        verdict=verdict, rms_before=float(np.sqrt(np.mean(base0.whitened ** 2))),
        rms_after=float(np.sqrt(np.mean(final.whitened ** 2))), heldout_rms_before=ho_before[1],
        heldout_rms_after=ho_after[1], steps=steps, not_separable=not_separable, remaining=remaining, alpha=alpha,
        tests_before=tests_before, tests_after=tests_after, candidates_first_step=first_scores,
        boresight_rad=beta.tolist(), boresight_sigma_rad=sig_beta.tolist(), pairs=len(lin.pairs),
        fixes=len(rec.fix_stamps), model_out=model_out,
        series={'before': series_before, 'after': series_after}, rejected=rejected,
        failed_candidates=failed, stopped_by=stopped_by, max_steps=max_steps,
        fit_consistent=bool(nis['p_value'] >= tests_after['level']),
        chi2_per_dof=float(nis['per_dof']), chi2_per_dof_band=band, sigma_method=sigma_method,
        hac_lags=hac_lags if sigma_method != 'model' else None,
        boresight_sigma_model_rad=sig_beta_model.tolist(), repeatability_bound=rep_bound)


def _jackknife_floor(lin, free, noise, split, cov_z):
    """
    Raise every σ of z to at least its leave-one-block-out jackknife σ over time.

    σ_jk = √((K−1)/K Σ_k (z_k − z̄)²), z_k fitted without time block k (K = ``blocks``): a
    delete-a-block jackknife, which needs no bandwidth and covers structure as slow as a block.
    Correlations are kept (the matrix is rescaled by the ratio of σ's).  Returns the covariance
    and whether any σ grew; unchanged when a fold's fit fails numerically.
    """
    try:
        zf = np.array([lin.evaluate(free, noise, train).z for train, _ in split.folds(lin)])
    except NUMERICAL_ERRORS:
        return cov_z, False
    kf = len(zf)
    if kf < 2 or zf.shape[1] != cov_z.shape[0]:
        return cov_z, False
    jk = np.sqrt((kf - 1) / kf * np.sum((zf - zf.mean(axis=0)) ** 2, axis=0))
    d = np.sqrt(np.maximum(np.diag(cov_z), 0.0))
    grow = jk > d
    if not np.any(grow):
        return cov_z, False
    f_ = np.where(grow & (d > 0), jk / np.where(d > 0, d, 1.0), 1.0)
    out = cov_z * np.outer(f_, f_)
    zero = grow & ~(d > 0)
    out[zero, zero] = jk[zero] ** 2
    return out, True


def _hac_lags(pairs: int) -> int:
    """
    Bandwidth of the Newey–West sandwich in pairs: ⌈2·N^(1/3)⌉ (wider than the textbook
    4(N/100)^(2/9), since the structure it must cover is slow: drifts and periods of minutes).
    """
    return int(np.ceil(2.0 * pairs ** (1.0 / 3.0)))


def _series(lin: Linearisation, f, free) -> dict:
    """
    Per-pair arrays the report plots: time, residual (rad) and its predicted σ, whitened
    residual, rotation angles (004 Fig. 2a), rate at the epochs, accumulated angle.
    """
    N = len(lin.pairs)
    J = lin.design(free)
    resid = (lin.r - J @ f.z).reshape(N, 3)            # the residual left after the fit
    phi_cam = np.linalg.norm(_rotvec(lin.pairs.dq_cam), axis=1)
    phi_imu = np.linalg.norm(_rotvec(lin.pairs.dq_imu), axis=1)
    w_e = np.linalg.norm(lin.gyro.rate_at(lin.pairs.k_end), axis=1)
    w_s = np.linalg.norm(lin.gyro.rate_at(lin.pairs.k_start), axis=1)
    acc = np.cumsum(phi_imu)
    P = lin.fix_covariance({})
    sig = np.sqrt(np.diagonal(P[lin.pairs.fix_end] + P[lin.pairs.fix_start], axis1=1, axis2=2)
                  + lin.random_walk ** 2 * lin.pairs.duration[:, None])
    return {'t': lin.pairs.t_end, 'residual': resid, 'sigma': sig, 'whitened': f.whitened.reshape(N, 3),
            'phi_cam': phi_cam, 'phi_imu': phi_imu, 'rate': np.maximum(w_e, w_s), 'accumulated_angle': acc}


def _rotvec(q):
    return quat_to_rotvec(q)
