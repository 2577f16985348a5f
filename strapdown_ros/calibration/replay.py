"""
The boresight calibrator over a whole recording: what ``calibrate_bag`` runs, as the node is fed.

:func:`calibrate_recording` feeds the calibrator of ``calibrator_node`` in stamp order, one time
base at a time, and :func:`solution_record` gives the JSON record of the result.  No printing;
the command prints and writes.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.calibration.streaming import BoresightCalibrator, CalibratorSettings
from strapdown_ros.estimation.chi_square import FIT_LEVEL
from strapdown_ros.rotation import to_ros_xyzw
from strapdown_ros.sensors.sensor_model import SensorModel
from strapdown_ros.streams.checks import match_segments, segments

__all__ = ['calibrate_recording', 'match_segments', 'solution_record']


def calibrate_recording(data: dict, model: SensorModel,
                        settings: CalibratorSettings | None = None):
    """
    Feed the calibrator as calibrator_node is fed and solve.

    Gyro and fixes interleaved in stamp order; the calibrator's buffer stays bounded on
    recordings of any length.  Each stream is split into its time bases
    (:func:`strapdown_ros.streams.checks.segments`: a confirmed resynchronisation starts a new
    one); gyro and camera segments are matched in order (:func:`match_segments`); the
    calibrator restarts its gyro history at every gyro segment and its fix chain at every camera
    segment, so no pair spans a jump.  Pairs spanning a gyro gap (the reader's, by the check's
    rule 6) are discarded, as the node does.

    Parameters
    ----------
    data : dict
        The streams of :func:`strapdown_ros.recording.reader.read_bag`.
    model : SensorModel
        The unit's sensor model.
    settings : CalibratorSettings, optional
        The calibrator's settings.

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
        for t, (q, P) in zip(tc[ca:cb], c.values[ca:cb]):
            if t < seg_t[0] - offset or t > seg_t[-1] + offset:
                continue                               # outside the gyro segment: no pair
            k1 = int(np.searchsorted(seg_t, t + lead, side='right'))
            new = 0
            if k1 > k:
                new = cal.add_gyro(seg_t[k:k1], seg_v[k:k1])
                k = k1
            new += cal.add_camera(t, q, P)
            discarded += cal.discard_new_pairs_over(new, gaps, h)
        if k < len(seg_t):                             # fixes still waiting for gyro coverage
            cal.add_gyro(seg_t[k:], seg_v[k:])
            k = len(seg_t)
    return cal.solve(), cal, discarded


def _num(x):
    x = float(x)
    return x if np.isfinite(x) else None


def _mat(m):
    return None if m is None else [[_num(v) for v in row] for row in np.asarray(m, dtype=float)]


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
        'beta_sigma_stated_noise_rad': (
            [float(v) for v in np.sqrt(np.diag(sol.covariance_beta_stated))]
            if ok and sol.covariance_beta_stated is not None else None),
    }
    rep = sol.observability
    if rep is not None:
        out['observability'] = {'eigenvalues': [_num(v) for v in rep.eigenvalues],
                                'predicted_sigma_rad': [_num(v) for v in rep.predicted_sigma],
                                'condition': _num(rep.condition), 'weak': list(rep.weak)}
    return out
