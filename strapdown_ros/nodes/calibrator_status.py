"""
The /diagnostics status of calibrator_node: level, message and key values from its state.

Every condition is listed in the message, the level is the worst of them: the solution
(observability, convergence, the χ² band of the fit), then the input counters (frames, drops,
outliers, bursts, resynchronisations, gaps) and the state file.  Kept beside the node so that
the node module holds its topics and callbacks only.
"""
from __future__ import annotations

import math

import numpy as np

from strapdown_ros.estimation.chi_square import FIT_LEVEL
from strapdown_ros.nodes import ros_io, ros_status

__all__ = ['boresight_status', 'ARCSEC']

ARCSEC = math.pi / 180.0 / 3600.0


def boresight_status(node) -> tuple[int, str, dict]:
    """
    Return the /diagnostics status of a calibrator node.

    Parameters
    ----------
    node : CalibratorNode
        The node (its calibrator, counters, parameters and state file).

    Returns
    -------
    level : int
        :data:`~strapdown_ros.nodes.ros_status.OK`, ``WARN`` or ``ERROR``: the worst condition.
    message : str
        Every condition, the solution's first.
    values : dict
        The key values of the status (pairs, β and σ, counters, state file).

    """
    g, c = node.gyro_check, node.camera_check
    sol = node.cal.solution
    values = {'pairs': len(node.cal.pairs), 'solves': node.solves}
    if sol is None:
        level = ros_status.WARN
        message = 'waiting for increment pairs (need gyro data and two camera fixes)'
        values.update({'observable': False, 'message': message})
    else:
        message = sol.message
        ok = sol.observable and sol.converged
        level = ros_status.OK if ok else ros_status.WARN
        chi2 = sol.chi2_per_dof
        lo, hi = sol.chi2_band
        if ok and sol.fit_consistent is False:
            level = ros_status.WARN
            sig = (f'the published σ is scaled by √(χ²/dof) = {math.sqrt(chi2):.3g}'
                   if sol.weighted else
                   'the published σ comes from the residual scatter (unweighted)')
            what = ('the stated noise is too small or the model lacks an effect (outliers, an '
                    f'unmodelled error: run discrepancy on a recording); {sig}' if chi2 > hi
                    else 'the stated noise is too large (σ pessimistic)')
            message = (f'{message}; FIT INCONSISTENT: χ²/dof = {chi2:.3g} outside its band '
                       f'[{lo:.3g}, {hi:.3g}] (dof {sol.dof}, level {FIT_LEVEL:g}): {what}')
        elif ok and np.isfinite(chi2) and chi2 > float(node.p['max_chi2_per_dof']):
            level = ros_status.WARN
            message = (f'{message}; χ²/dof = {chi2:.3g}: the residuals exceed the model '
                       '(outliers, or an effect the model lacks: run discrepancy on a '
                       'recording)')
        values.update({'fit_consistent': sol.fit_consistent, 'chi2_per_dof_band_low': lo,
                       'chi2_per_dof_band_high': hi, 'dof': sol.dof})
        values.update({'observable': sol.observable, 'message': sol.message,
                       'unobservable_axes': ('; '.join(sol.unobservable_axes)
                                             if sol.unobservable_axes else 'none'),
                       'residual_rms_rad': sol.residual_rms, 'iterations': sol.iterations,
                       'converged': sol.converged, 'chi2_per_dof': sol.chi2_per_dof})
        if sol.observable and sol.beta is not None:
            b = np.degrees(sol.beta)
            s = np.sqrt(np.maximum(np.diag(sol.covariance_beta), 0.0)) / ARCSEC
            values.update({'beta_yaw_deg': float(b[0]), 'beta_pitch_deg': float(b[1]),
                           'beta_roll_deg': float(b[2]), 'beta_yaw_sigma_arcsec': float(s[0]),
                           'beta_pitch_sigma_arcsec': float(s[1]),
                           'beta_roll_sigma_arcsec': float(s[2])})
    values.update({'weighted': node.cal.weighted,
                   'covariance_model': node.cal.covariance_model,
                   'boresight_of': f"{node.p['camera_frame_id']} in {node.frame_id}",
                   'last_solve_ms': node.solve_ms,
                   'boresight_published': node.published['boresight'],
                   'imu_attitude_from_camera_published':
                       node.published['imu_attitude_from_camera'],
                   'pairs_discarded_gyro_gap': node.pairs_discarded_gap,
                   **g.as_dict('gyro'),
                   'camera_received': c.received, 'camera_accepted': c.accepted,
                   'camera_dropped_nan': c.nan + node.fix_screen.nan,
                   'camera_dropped_out_of_order': c.out_of_order,
                   'camera_dropped_duplicate': c.duplicate,
                   'camera_dropped_stamp_outlier': c.stamp_outliers,
                   'camera_stamp_resyncs': c.resyncs, 'solve_failures': node.solve_failures,
                   'camera_outlier_fixes': node.cal.outlier_fixes,
                   'gyro_frame_mismatch': node.gyro_frame_mismatch,
                   'gyro_undecodable_dropped': node.undecodable,
                   'gyro_history_overflowed': node.cal.gyro_history_overflowed,
                   'state_file': node.state['file'] or 'off',
                   'state_saves': node.state['saves'],
                   'state_restored_pairs': node.state['restored_pairs'],
                   'state_errors': node.state['errors'],
                   'state_persisting': node.state['persisting'],
                   'state_problem': node.state['problem'] or 'none',
                   'pairs_replayed_not_added': node.cal.replayed_pairs,
                   **{f'camera_{k}': v for k, v in node.camera_counts.items()}})
    mism = node.gyro_frame_mismatch + node.camera_counts['frame_mismatch']
    if mism:                              # every condition listed, the level the worst
        level = max(level, ros_status.WARN)
        message = (f'{message}; {mism} message(s) in an unexpected frame '
                   f"({'rejected' if node.reject_frames else 'used'})")
    if node.undecodable:
        level = max(level, ros_status.WARN)
        message = (f'{message}; {node.undecodable} gyro message(s) could not be decoded: '
                   'dropped')
    if node.cal.outlier_fixes:
        level = max(level, ros_status.WARN)
        message = (f'{message}; {node.cal.outlier_fixes} camera fix(es) dropped as outliers '
                   f"(both pairs off by more than {node.p['outlier_gate']:g} σ in rotation "
                   'angle, the pair skipping it consistent)')
    m = node.model
    clips = [g.clip_warning('gyro_max_rate', m.gyro_max_rate, 'rad/s', m.gyro_period)]
    if node.imu_input:
        clips.append(node.gyro_rates.check.clip_warning('gyro_max_rate', m.gyro_max_rate,
                                                        'rad/s'))
    for text in filter(None, clips):
        level = max(level, ros_status.WARN)
        message = f'{message}; {text}'
    g_drop = g.dropped
    if node.imu_input:
        r = node.gyro_rates.check
        values.update({'gyro_input': 'imu', 'imu_rate_rule': node.p['imu_rate_rule'],
                       'imu_stated_rate_variance': ros_io.stated_rate_variance(node.last_imu),
                       'model_rate_variance': node.model.gyro.random_walk ** 2
                       / node.gyro_period,
                       **node.gyro_rates.status('imu_gyro')})
        if r.dropped and level == ros_status.OK:
            level = ros_status.WARN
            message = (f'{message}; dropped {r.dropped} angular-rate samples of imu/data_raw '
                       f'(NaN {r.nan}, out of range {r.out_of_range}, out of order '
                       f'{r.out_of_order}, duplicate {r.duplicate}, stamp outliers '
                       f'{r.stamp_outliers})')
    c_drop = c.dropped + node.fix_screen.dropped
    if g_drop or c_drop:
        level = max(level, ros_status.WARN)
        message = f'{message}; dropped {g_drop} gyro and {c_drop} camera messages'
    if node.state['errors']:
        level = ros_status.ERROR
        message = (f"{message}; state file: {node.state['errors']} error(s): "
                   f"{node.state['problem']}"
                   + ('' if node.state['persisting'] else ' (no persistence)'))
    if g.bursts:
        level = ros_status.ERROR
        message = (f'{message}; {g.burst_messages} gyro increment(s) in {g.bursts} burst(s) '
                   'stamped off the timeline, dropped; the pairs containing them are lost')
    if g.resyncs or c.resyncs:
        level = ros_status.ERROR
        message = (f'{message}; stamps jumped and were resynchronised (gyro {g.resyncs}, '
                   f'camera {c.resyncs}); no pair spans a jump')
    if node.solve_failures:
        level = ros_status.ERROR
        message = (f'{message}; {node.solve_failures} solve(s) failed, the last estimate '
                   'stays published')
    if g.missing:
        level = ros_status.ERROR
        message = (f'{message}; {g.missing} gyro increments missing in {g.gaps} gaps: '
                   f'{node.pairs_discarded_gap} pair(s) spanning them discarded')
    return level, message, values
