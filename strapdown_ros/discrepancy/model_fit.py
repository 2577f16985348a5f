"""
The model of a recording, fitted: nominal increment pairs, the boresight, the Gauss–Newton refit.

The discrepancy workflow (:mod:`strapdown_ros.discrepancy.workflow`) and the hidden-effect
draws (:mod:`strapdown_ros.discrepancy.synthetic`) start here: the increment pairs of the
nominal model (its effects compensated), the boresight's first estimate from them and its
observability (the rule of ``calibrate_bag``), the refit of the boresight and the free
systematic effects on the linearisation (:mod:`strapdown_ros.discrepancy.linearisation`), and
the plausibility of a fitted value.  No ROS imports.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.calibration.boresight import axis_alignment_quat
from strapdown_ros.calibration.boresight_observability import judge_observability
from strapdown_ros.discrepancy.linearisation import (InputError, Linearisation,
                                                     NumericalFailure, pairs_at, Recording)
from strapdown_ros.rotation import rotvec_to_dcm
from strapdown_ros.sensors.effects import EFFECTS

__all__ = ['check_plausible', 'initial_pairs', 'initial_boresight_estimate',
           'boresight_observability', 'refine_fit']


def check_plausible(name: str, params: dict) -> None:
    """
    Check that a fitted effect value is a small correction inside its stated range.

    Parameters
    ----------
    name : str
        Effect name of the registry (:data:`strapdown_ros.sensors.effects.EFFECTS`).
    params : dict
        The model, the effect's value under its ROS parameter name, SI units.

    Raises
    ------
    NumericalFailure
        The value is not finite, beyond the effect's plausible bound (its registry class: beyond it
    the model is not a small correction, a wiring fault or a wrong unit), or outside the
    parameter's range.

    """
    e = EFFECTS[name]
    p = e.value_parameter
    v = np.atleast_1d(np.asarray(e.value(params), dtype=float))
    hi = e.plausible_bound()
    lo_p, hi_p = p.minimum, p.maximum
    if not np.all(np.isfinite(v)):
        raise NumericalFailure(f'a non-finite {p.name}')
    if hi is not None and np.max(np.abs(v)) > hi:
        raise NumericalFailure(f'|{p.name}| = {np.max(np.abs(v)):.3g} > {hi:g}: not a small '
                               f'correction, outside what the linearised workflow reports')
    if (lo_p is not None and np.min(v) < lo_p) or (hi_p is not None and np.max(v) > hi_p):
        raise NumericalFailure(f'{p.name} = {_short(v)} outside its range [{lo_p}, {hi_p}]')


def _short(v):
    return np.round(np.asarray(v, dtype=float), 6).tolist()


def initial_pairs(rec: Recording, params: dict, epoch: float):
    """
    Return the increment pairs of the nominal model (its effects compensated), before any fit.

    Parameters
    ----------
    rec : Recording
        The recording.
    params : dict
        The nominal model (its effect values and camera time offset), SI units.
    epoch : float
        Origin of the effects' time, s.

    Returns
    -------
    PairSet
        The pairs of consecutive camera fixes
        (:func:`strapdown_ros.calibration.pairs.build_pairs`).

    Raises
    ------
    InputError
        Fewer than two pairs: the gyro data do not cover consecutive fixes.

    """
    pairs = pairs_at(rec, params, epoch)
    if len(pairs) < 2:
        raise InputError(f'only {len(pairs)} increment pair(s): the gyro data must cover '
                         'consecutive camera fixes')
    return pairs


def initial_boresight_estimate(rec: Recording, params: dict, epoch: float) -> np.ndarray:
    """
    Estimate the boresight from the nominal increment pairs by axis alignment.

    Parameters
    ----------
    rec : Recording
        The recording.
    params : dict
        The nominal model, SI units.
    epoch : float
        Origin of the effects' time, s.

    Returns
    -------
    (3, 3) ndarray
        C, the direction cosine matrix of the boresight (IMU frame MF from camera frame VF).

    """
    pairs = initial_pairs(rec, params, epoch)
    return axis_alignment_quat(pairs.dq_imu, pairs.dq_cam)


def boresight_observability(rec: Recording, params: dict, epoch: float | None = None):
    """
    Judge the observability of the boresight on this recording, by the calibrator's rule.

    The rule ``calibrate_bag`` and the calibrator use
    (:func:`strapdown_ros.calibration.boresight_observability.judge_observability`): the
    Fisher information of all the pairs together (shared fixes included) and the motion about
    two axes above the fix noise, in O(N).

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
    pairs = initial_pairs(rec, params, epoch)
    rw2 = float(EFFECTS['gyro_random_walk'].value(params)[0]) ** 2
    P = rec.fix_P
    fix_P = np.stack([P[pairs.fix_start], P[pairs.fix_end]], axis=1)
    white = (rw2 * pairs.duration)[:, None, None] * np.eye(3)
    return judge_observability(pairs.dq_cam, fix_P, pairs.adjacent, white,
                               min_rotation=np.radians(float(params.get('min_rotation_deg', 0.5))),
                               max_sigma=float(params.get('max_sigma', 1e-3)))


def refine_fit(rec: Recording, params: dict, C: np.ndarray, epoch: float, free, noise: dict,
               iterations: int = 6):
    """
    Refit the boresight and the free systematic effects by Gauss–Newton.

    Iterates until a step improves χ² by less than 1e-3 (and moves no parameter by more than
    1e-6), or ``iterations``.

    Parameters
    ----------
    rec : Recording
        The recording.
    params : dict
        The model; the values of the ``free`` effects are updated in place.
    C : (3, 3) ndarray
        Boresight direction cosine matrix to start from (MF from VF).
    epoch : float
        Origin of the effects' time, s.
    free : list of str
        Systematic effects fitted with the boresight.
    noise : dict
        The noise terms of the model (:func:`strapdown_ros.discrepancy.linearisation.noise_of`).
    iterations : int
        Most Gauss–Newton steps.

    Returns
    -------
    params : dict
        The model with the fitted values (the same dict).
    C : (3, 3) ndarray
        The fitted boresight.

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
