"""
The boresight calibrator over a whole recording: what ``calibrate_bag`` runs, as the node is fed.

:func:`calibrate_recording` feeds the calibrator of ``calibrator_node`` in stamp order, one time
base at a time, and :func:`solution_record` gives the JSON record of the result.  No printing;
the command prints and writes.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.calibration.reference_spacing import (choose_spacing, fix_interval,
                                                         MAX_SPACING, refine_spacing,
                                                         SpacingChoice, stated_spacing,
                                                         thin_fixes)
from strapdown_ros.calibration.streaming import BoresightCalibrator, CalibratorSettings
from strapdown_ros.estimation.chi_square import FIT_LEVEL
from strapdown_ros.estimation.model_check import ljung_box
from strapdown_ros.rotation import to_ros_xyzw
from strapdown_ros.sensors.sensor_model import SensorModel
from strapdown_ros.streams.checks import match_segments, segments

__all__ = ['calibrate_recording', 'calibrate_spaced', 'match_segments', 'solution_record',
           'residual_whiteness', 'BLOCK_FIXES', 'BLOCK_GYRO']


def calibrate_recording(data: dict, model: SensorModel,
                        settings: CalibratorSettings | None = None, keep=None):
    """
    Feed the calibrator as calibrator_node is fed and solve.

    Gyro and fixes interleaved in stamp order; the calibrator's buffer stays bounded on
    recordings of any length.  Each stream is split into its time bases
    (:func:`strapdown_ros.streams.checks.segments`: a confirmed resynchronisation starts a new
    one); gyro and camera segments are matched in order (:func:`match_segments`); the
    calibrator restarts its gyro history at every gyro segment and its fix chain at every camera
    segment, so no pair spans a jump.  The fixes go in blocks (``add_cameras``: the same pairs
    as one at a time), each after the gyro data that covers it.  Pairs spanning a gyro gap (the
    reader's, by the check's rule 6) are discarded, as the node does.

    Parameters
    ----------
    data : dict
        The streams of :func:`strapdown_ros.recording.reader.read_bag`.
    model : SensorModel
        The unit's sensor model.
    settings : CalibratorSettings, optional
        The calibrator's settings.
    keep : (n,) bool array_like, optional
        The camera fixes used (default all): the spacing of the pairs.

    Returns
    -------
    solution : BoresightSolution
        The boresight estimate.
    calibrator : BoresightCalibrator
        The calibrator after the recording.
    discarded : int
        Pairs discarded over gyro gaps and stamp jumps.

    """
    g, c = data['gyro'], data['camera']
    t0 = min(g.stamps[0], c.stamps[0])                 # origin: float seconds keep ns resolution
    cal = BoresightCalibrator.from_model(model, settings)
    tg = (np.asarray(g.stamps, dtype=np.int64) - t0) * 1e-9
    vg = np.asarray(g.values, dtype=float).reshape(-1, 3)
    tc = (np.asarray(c.stamps, dtype=np.int64) - t0) * 1e-9
    qc = np.array([v[0] for v in c.values], dtype=float).reshape(-1, 4)
    Pc = np.array([v[1] for v in c.values], dtype=float).reshape(-1, 3, 3)
    use = np.ones(len(tc), dtype=bool) if keep is None else np.asarray(keep, dtype=bool)
    period = data.get('gyro_period_s') or model.gyro_period
    if not np.isfinite(period):
        period = model.gyro_period
    h = 1.5 * period                                   # the in-interval polynomial reads the
    offset = abs(model.camera_effects().time_offset)   # neighbours; a fix's epoch: stamp − offset
    lead = 3 * period + offset
    g_segs = segments(g.stamps, getattr(g.check, 'segment_starts', []))
    c_segs = segments(c.stamps, getattr(c.check, 'segment_starts', []))
    after_gap = {b for a, b in g.gaps}                 # stamps that follow a gap
    discarded = 0
    cur_g = cur_c = None                               # segments the calibrator is fed from
    k = 0                                              # gyro samples of segment cur_g fed so far
    for i, j in match_segments(tg, g_segs, tc, c_segs):
        (ga, gb), (ca, cb) = g_segs[i], c_segs[j]
        seg_t, seg_v = tg[ga:gb], vg[ga:gb]
        if cur_g != i:
            if cur_g is not None:
                cal.restart_gyro()
            cur_g, k = i, 0
        if cur_c is not None and cur_c != j:
            cal.restart_camera()
        cur_c = j
        gaps = [(seg_t[n - 1], seg_t[n]) for n in range(1, gb - ga)   # the reader's (rule 6)
                if g.stamps[ga + n] in after_gap]
        t_fix = tc[ca:cb]
        inside = use[ca:cb] & (t_fix >= seg_t[0] - offset) & (t_fix <= seg_t[-1] + offset)
        idx = ca + np.flatnonzero(inside)               # outside the gyro segment: no pair
        need = np.searchsorted(seg_t, tc[idx] + lead, side='right')
        a = 0
        while a < len(idx):
            # a block of fixes whose gyro data stays well inside the calibrator's bound
            b = int(np.searchsorted(need, need[a] + BLOCK_GYRO, side='right'))
            b = min(max(b, a + 1), a + BLOCK_FIXES)
            k1 = int(need[b - 1])
            if k1 > k:
                cal.add_gyro(seg_t[k:k1], seg_v[k:k1])
                k = k1
            sel = idx[a:b]
            new = cal.add_cameras(tc[sel], qc[sel], Pc[sel])
            discarded += cal.discard_new_pairs_over(new, gaps, h)
            a = b
        if k < len(seg_t):                             # fixes still waiting for gyro coverage
            cal.add_gyro(seg_t[k:], seg_v[k:])
            k = len(seg_t)
    return cal.solve(), cal, discarded


#: fixes fed to the calibrator at once (``calibrate_recording``), and the gyro samples a block
#: may span
BLOCK_FIXES = 4096
BLOCK_GYRO = 200_000


def calibrate_spaced(data: dict, model: SensorModel, settings: CalibratorSettings | None = None,
                     spacing: float | None = None):
    """
    Calibrate with the fixes of the pairs at the spacing the reference's error allows.

    The rule of :mod:`strapdown_ros.calibration.reference_spacing`: calibrate on every fix,
    choose the spacing from the whitened residuals (``spacing`` None), and calibrate again on
    the fixes kept when it is more than one fix.  A stated ``spacing`` (s; 0: every fix) is
    used as given, and so is the model's ``reference_spacing`` when the model states it.

    Parameters
    ----------
    data : dict
        The streams of :func:`strapdown_ros.recording.reader.read_bag`.
    model : SensorModel
        The unit's sensor model.
    settings : CalibratorSettings, optional
        The calibrator's settings.
    spacing : float, optional
        Spacing of the fixes, s; None: the model's ``reference_spacing`` where it states one,
        else chosen from the data.

    Returns
    -------
    solution, calibrator, discarded
        As :func:`calibrate_recording`.
    choice : SpacingChoice
        The spacing and why.

    """
    c = data['camera']
    t = (np.asarray(c.stamps, dtype=np.int64) - int(c.stamps[0])) * 1e-9
    interval = fix_interval(t)

    def run(keep=None):
        return calibrate_recording(data, model, settings, keep)
    if spacing is None and 'reference_spacing' in model.stated:
        spacing = model.reference_spacing               # the model states it: one spacing
    if spacing is not None:
        choice = stated_spacing(spacing, t)
        if choice.step <= 1:
            return (*run(), choice)
        return (*run(_kept(t, choice.spacing_s)), choice)
    sol, cal, discarded = run()
    white = sol.whitened_residual
    if interval >= MAX_SPACING or white is None or not sol.observable:
        why = (f'fixes {interval:.3g} s apart, at least {MAX_SPACING:g} s: all kept'
               if interval >= MAX_SPACING else
               'every fix kept: no solution at the full rate to judge the spacing from')
        return sol, cal, discarded, SpacingChoice(1, interval, interval, reason=why,
                                                  pairs_full=len(cal.pairs))
    choice = choose_spacing(white, _adjacent(cal.pairs), t)
    if choice.step <= 1:
        return sol, cal, discarded, choice
    sol, cal, discarded = run(_kept(t, choice.spacing_s))
    if sol.whitened_residual is None:
        return sol, cal, discarded, choice
    wider = refine_spacing(choice, sol.whitened_residual, _adjacent(cal.pairs))
    if wider.step == choice.step:
        return sol, cal, discarded, choice
    return (*run(_kept(t, wider.spacing_s)), wider)


def _adjacent(pairs) -> np.ndarray:
    return np.array([abs(b.t_start - a.t_end) < 1e-9 for a, b in zip(pairs, pairs[1:])])


def _kept(t, spacing):
    keep = np.zeros(len(t), dtype=bool)
    keep[thin_fixes(t, spacing)] = True
    return keep


def _num(x):
    x = float(x)
    return x if np.isfinite(x) else None


def _mat(m):
    return None if m is None else [[_num(v) for v in row] for row in np.asarray(m, dtype=float)]


def residual_whiteness(white) -> dict | None:
    """
    Return the Ljung–Box test of the whitened residuals of a solution, at the fit's level.

    The σ of the solution assume independent pairs; correlated residuals make them too small
    (``discrepancy`` then reports the Newey–West sandwich instead).

    Parameters
    ----------
    white : (n, 3) array_like or None
        The whitened residuals (:attr:`BoresightSolution.whitened_residual`).

    Returns
    -------
    dict or None
        ``statistic``, ``dof``, ``lags``, ``p_value``, ``level``, ``white`` (p ≥ level); None
        with fewer than 8 pairs.

    """
    from scipy.stats import chi2
    if white is None:
        return None
    w = np.asarray(white, dtype=float).reshape(-1, 3)
    if len(w) < 8 or not np.all(np.isfinite(w)):
        return None
    lags = int(min(20, max(2, len(w) // 10)))
    q = ljung_box(w, lags)
    p = float(chi2.sf(q, 3 * lags))
    return {'statistic': float(q), 'dof': 3 * lags, 'lags': lags, 'p_value': p,
            'level': FIT_LEVEL, 'white': bool(p >= FIT_LEVEL)}


def solution_record(sol, weighted: bool) -> dict:
    """
    Return the JSON record of a BoresightSolution (the schema of ``calibrate_bag --json``).

    Parameters
    ----------
    sol : BoresightSolution
        The solution.
    weighted : bool
        Whether the fit was weighted by the pair covariances.

    Returns
    -------
    dict
        Plain JSON values.

    """
    ok = bool(sol.observable and sol.beta is not None)
    unobs = list(sol.unobservable_axes) if not ok else []
    if not ok and not unobs:                   # too few pairs: nothing is observable
        axes = [', '.join('1.00' if i == j else '0.00' for j in range(3)) for i in range(3)]
        unobs = [f'rotation about VF axis ({a})' for a in axes]
    out = {
        'q_mf_vf_xyzw': [float(c) for c in to_ros_xyzw(sol.q_mf_vf)] if ok else None,
        'rotation_covariance_mf_rad2': _mat(sol.rotation_covariance_mf) if ok else None,
        'beta_rad': [float(b) for b in sol.beta] if ok else None,
        'beta_sigma_rad': ([float(s) for s in np.sqrt(np.diag(sol.covariance_beta))]
                           if ok else None),
        'covariance_rad2': _mat(sol.covariance_beta) if ok else None,
        'pairs': int(sol.pairs),
        'observable': ok,
        'unobservable_axes': unobs,
        'residual_rms_rad': _num(sol.residual_rms),
        'weighted': bool(sol.weighted if ok else weighted),
        # extra keys
        'message': sol.message,
        'converged': bool(sol.converged),
        'iterations': int(sol.iterations),
        'chi2_per_dof': _num(sol.chi2_per_dof),
        'fit_consistent': None if sol.fit_consistent is None else bool(sol.fit_consistent),
        'chi2_per_dof_band': [_num(b) for b in sol.chi2_band] if ok else None,
        'chi2_level': FIT_LEVEL,
        'dof': int(sol.dof),
        # σ from the stated noise alone; beta_sigma_rad is it scaled by √(χ²/dof) when χ²/dof > 1
        # (sigma_method: model, model_scaled_sqrt_chi2, or residual_scatter_004 unweighted)
        'beta_sigma_stated_noise_rad': (
            [float(v) for v in np.sqrt(np.diag(sol.covariance_beta_stated))]
            if ok and sol.covariance_beta_stated is not None else None),
    }
    out['sigma_method'] = (None if not ok else 'residual_scatter_004' if not out['weighted']
                           else 'model_scaled_sqrt_chi2' if (sol.chi2_per_dof or 0.0) > 1.0
                           else 'model')
    out['residual_whiteness'] = residual_whiteness(sol.whitened_residual) if ok else None
    rep = sol.observability
    if rep is not None:
        out['observability'] = {'eigenvalues': [_num(v) for v in rep.eigenvalues],
                                'predicted_sigma_rad': [_num(v) for v in rep.predicted_sigma],
                                'condition': _num(rep.condition), 'weak': list(rep.weak)}
    return out
