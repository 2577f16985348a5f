"""
calibrate_bag: star-camera boresight C_MF^VF from a rosbag2 bag, offline and without ROS.

Reads ``imu/delta_theta`` (geometry_msgs/msg/Vector3Stamped) and the camera attitude — from
``star_camera/attitude_with_covariance`` (geometry_msgs/msg/PoseWithCovarianceStamped, rotation
block = camera covariance in VF axes) when the bag has it and ``use_camera_covariance`` is true,
otherwise from ``star_camera/attitude`` (geometry_msgs/msg/QuaternionStamped) with the assumed
``camera_sigma_xy``/``camera_sigma_z`` — and feeds the same ``BoresightCalibrator`` as
``calibrator_node``, in stamp order.  Topic names match with or without the leading slash, under
``--namespace`` when given; a bag with a single namespace is found without it.  MCAP and
sqlite3 storage (a bag directory or a single .mcap/.db3 file).  Other formats
(``strapdown_ros.recording``): ``--gyro-topic`` of sensor_msgs/msg/Imu rates (increments by
``--rate-rule``), ``--reference-topic`` of PoseStamped, PoseWithCovarianceStamped,
nav_msgs/msg/Odometry or QuaternionStamped, or TF with ``--reference-frames PARENT CHILD``.

Header stamps are the time base.  Input validation is ``calibrator_node``'s, per topic in bag
order: messages with NaN/Inf values, duplicate stamps or stamps older than the previous accepted
one are dropped and counted; a gyro gap (a step above 1.5/``gyro_rate``: increments missing, their
rotation lost) is counted and every increment pair spanning it is discarded; a camera quaternion
that is not unit is normalised, a zero one dropped; an all-zero camera covariance (ROS "unknown")
is replaced by the ``camera_sigma_*`` diagonal, one that is not positive semi-definite is dropped.

Output (``--json FILE``, also printed as a human summary)::

    {"q_mf_vf_xyzw": [x, y, z, w], "rotation_covariance_mf_rad2": 3×3, "beta_rad": [ψ, ϑ, γ],
     "beta_sigma_rad": [...], "covariance_rad2": 3×3, "pairs": n, "observable": bool,
     "unobservable_axes": [...], "residual_rms_rad": r, "weighted": bool, ...extra keys}

``q_mf_vf_xyzw`` is C_MF^VF (maps VF coordinates to MF coordinates) as a ROS quaternion;
``rotation_covariance_mf_rad2`` is the covariance of its error in MF axes (004 eq. 8);
``covariance_rad2`` that of β.  Not observable: those are null and the exit status is 3.
``chi2_per_dof`` (stated noise, dof 3n − 3) is judged against its two-sided band at level 0.01
(``chi2_per_dof_band``): ``fit_consistent``.  When false, a line starting ``WARNING:`` goes to
stderr (χ²/dof, band, meaning; ``beta_sigma_rad`` is ``beta_sigma_stated_noise_rad`` scaled by
√(χ²/dof)) and the summary lines of β are prefixed ``UNTRUSTED``; the exit status stays 0.
Stamp faults are the nodes' (``strapdown_ros.streams.checks``): dropouts and stamp bursts are gaps
(``gyro_gaps``), a burst's messages are removed (``dropped.gyro.stamp_burst``), each time base
after a resynchronisation is calibrated separately.
A reference at any rate: ``--reference-spacing auto`` (default) calibrates on every fix, chooses
from the correlation of the whitened residuals how far apart the fixes of the pairs must be for
their errors to be independent, and calibrates again on the fixes kept
(``strapdown_ros.calibration.reference_spacing``; ``0`` keeps every fix, a number of seconds one
fix per slot of that length); ``reference_spacing`` in the JSON records the choice and why.
Observability is judged from the information of all the pairs together (``min_rotation_deg``:
the attitude's rotation about its second principal axis between two fixes of the recording).
Exit status: 0 solved, 2 bad arguments/parameters/bag, 3 not observable, 4 no convergence.
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from strapdown_ros.calibration.reference_spacing import (choose_spacing, fix_interval,
                                                         MAX_SPACING, parse_spacing,
                                                         refine_spacing, SpacingChoice,
                                                         stated_spacing, thin_fixes)
from strapdown_ros.calibration.streaming import BoresightCalibrator
from strapdown_ros.cli import check_outputs, FILE, OneLineParser, write_json
from strapdown_ros.estimation.chi_square import FIT_LEVEL
from strapdown_ros.params import CALIBRATOR_PARAMS, node_parameters, parse_overrides
from strapdown_ros.recording import (add_input_arguments, BagError, check_input_arguments,
                                     input_lines, input_options, input_summary, input_warnings,
                                     read_bag)
from strapdown_ros.rotation import to_ros_xyzw
from strapdown_ros.streams.checks import segments

__all__ = ['main', 'calibrate', 'calibrate_spaced', 'calibrator_parameters', 'make_calibrator',
           'solution_json']

ARCSEC_PER_RAD = 180.0 / np.pi * 3600.0


# --- parameters -------------------------------------------------------------------------------
def calibrator_parameters(params_file: str | None = None, overrides: dict | None = None) -> dict:
    """
    Return calibrator_node's parameters from a ROS 2 parameter YAML, validated.

    Parameters
    ----------
    params_file : str, optional
        A ROS 2 parameter YAML (its ``calibrator_node`` and ``/**`` blocks).
    overrides : dict, optional
        Values that replace the file's (name → value).

    Returns
    -------
    dict
        Every calibrator_node parameter, name → checked value.

    """
    return node_parameters('calibrator_node', CALIBRATOR_PARAMS, params_file, overrides)


def make_calibrator(p: dict) -> BoresightCalibrator:
    """
    Return the calibrator exactly as calibrator_node builds it.

    Parameters
    ----------
    p : dict
        calibrator_node parameters (:func:`calibrator_parameters`).

    Returns
    -------
    BoresightCalibrator
        The calibrator, its gyro effects compensated.

    """
    return BoresightCalibrator.from_params(p)


def _match_segments(tg, g_segs, tc, c_segs) -> list[tuple[int, int]]:
    """
    Pair each gyro time base with its camera time base, in order.

    Which gyro time base goes with which camera time base, in order.  As many of each (a clock
    reset of both streams, the usual case): the k-th with the k-th.  Otherwise (one stream
    resynchronised alone) by overlapping stamp ranges, walking both lists forward.
    """
    if len(g_segs) == len(c_segs):
        return [(k, k) for k in range(len(g_segs))]
    out, i, j = [], 0, 0
    while i < len(g_segs) and j < len(c_segs):
        g_lo, g_hi = tg[g_segs[i][0]], tg[g_segs[i][1] - 1]
        c_lo, c_hi = tc[c_segs[j][0]], tc[c_segs[j][1] - 1]
        if g_hi >= c_lo and c_hi >= g_lo:
            out.append((i, j))
        if g_hi <= c_hi:                               # the segment that ends first is done
            i += 1
        if c_hi <= g_hi:
            j += 1
    return out


def calibrate(data: dict, p: dict, keep=None):
    """
    Feed the calibrator as calibrator_node is fed and solve.

    Feed the calibrator as calibrator_node is fed — gyro and fixes interleaved in stamp order — and
    solve; returns (solution, calibrator, pairs discarded over gyro gaps and stamp jumps). The
    calibrator's buffer stays bounded on recordings of any length.

    Each stream is split into its time bases (``strapdown_ros.streams.checks.segments``: a
    confirmed resynchronisation starts a new one; a burst that returned has already been removed by
    ``validate``).  Gyro and camera segments are matched in order (the k-th with the k-th);
    the calibrator restarts its gyro history (``restart_gyro``, as calibrator_node does on a
    resynchronisation) at every gyro segment and its fix chain at every camera segment, so no
    pair spans a jump and no stamp array handed to the search is out of order (segments matched
    by :func:`_match_segments`).  The fixes go in blocks (``add_cameras``: the same pairs as one
    at a time), each after the gyro data that covers it.

    Parameters
    ----------
    data : dict
        The streams of :func:`strapdown_ros.recording.reader.read_bag`.
    p : dict
        calibrator_node parameters.
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
    cal = make_calibrator(p)
    tg = (np.asarray(g.stamps, dtype=np.int64) - t0) * 1e-9
    vg = np.asarray(g.values, dtype=float).reshape(-1, 3)
    tc = (np.asarray(c.stamps, dtype=np.int64) - t0) * 1e-9
    qc = np.array([v[0] for v in c.values], dtype=float).reshape(-1, 4)
    Pc = np.array([v[1] for v in c.values], dtype=float).reshape(-1, 3, 3)
    use = np.ones(len(tc), dtype=bool) if keep is None else np.asarray(keep, dtype=bool)
    period = data.get('gyro_period_s') or 1.0 / float(p['gyro_rate'])
    # the in-interval polynomial reads the neighbours
    h = 1.5 * period
    offset = abs(float(p['camera_time_offset']))      # a fix's epoch is its stamp − offset
    lead = 3 * period + offset
    g_segs = segments(g.stamps, getattr(g.check, 'segment_starts', []))
    c_segs = segments(c.stamps, getattr(c.check, 'segment_starts', []))
    discarded = 0
    cur_g = cur_c = None                               # segments the calibrator is fed from
    k = 0                                              # gyro samples of segment cur_g fed so far
    for i, j in _match_segments(tg, g_segs, tc, c_segs):
        (ga, gb), (ca, cb) = g_segs[i], c_segs[j]
        seg_t, seg_v = tg[ga:gb], vg[ga:gb]
        if cur_g != i:
            if cur_g is not None:
                cal.restart_gyro()
            cur_g, k = i, 0
        if cur_c is not None and cur_c != j:
            cal.restart_camera()
        cur_c = j
        gaps = [(seg_t[n], seg_t[n + 1]) for n in np.flatnonzero(np.diff(seg_t) > 1.5 * period)]
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
            if new and gaps:                           # as calibrator_node discards them
                tail = cal.pairs[len(cal.pairs) - new:]
                keep_tail = [pr for pr in tail
                             if not any(pr.t_start - h < gb_ and ga_ < pr.t_end + h
                                        for ga_, gb_ in gaps)]
                discarded += len(tail) - len(keep_tail)
                del cal.pairs[len(cal.pairs) - new:]
                cal.pairs.extend(keep_tail)
            a = b
        if k < len(seg_t):                             # fixes still waiting for gyro coverage
            cal.add_gyro(seg_t[k:], seg_v[k:])
            k = len(seg_t)
    return cal.solve(), cal, discarded


#: fixes fed to the calibrator at once (``calibrate``), and the gyro samples a block may span
BLOCK_FIXES = 4096
BLOCK_GYRO = 200_000


def calibrate_spaced(data: dict, p: dict, spacing: float | None = None):
    """
    Calibrate with the fixes of the pairs at the spacing the reference's error allows.

    The rule of :mod:`strapdown_ros.calibration.reference_spacing`: calibrate on every fix,
    choose the spacing from the whitened residuals (``spacing`` None), and calibrate again on
    the fixes kept when it is more than one fix.  A stated ``spacing`` (s; 0: every fix) is
    used as given.

    Parameters
    ----------
    data : dict
        The streams of :func:`strapdown_ros.recording.reader.read_bag`.
    p : dict
        calibrator_node parameters.
    spacing : float, optional
        Spacing of the fixes, s; None: chosen from the data.

    Returns
    -------
    solution, calibrator, discarded
        As :func:`calibrate`.
    choice : SpacingChoice
        The spacing and why.

    """
    c = data['camera']
    t = (np.asarray(c.stamps, dtype=np.int64) - int(c.stamps[0])) * 1e-9
    interval = fix_interval(t)
    if spacing is not None:
        choice = stated_spacing(spacing, t)
        if choice.step <= 1:
            return (*calibrate(data, p), choice)
        return (*calibrate(data, p, keep=_kept(t, choice.spacing_s)), choice)
    sol, cal, discarded = calibrate(data, p)
    white = sol.whitened_residual
    if interval >= MAX_SPACING or white is None or not sol.observable:
        why = (f'fixes {interval:.3g} s apart, at least {MAX_SPACING:g} s: all kept'
               if interval >= MAX_SPACING else
               'every fix kept: no solution at the full rate to judge the spacing from')
        return sol, cal, discarded, SpacingChoice(1, interval, interval, reason=why,
                                                  pairs_full=len(cal.pairs))
    pairs = cal.pairs
    adjacent = np.array([abs(b.t_start - a.t_end) < 1e-9 for a, b in zip(pairs, pairs[1:])])
    choice = choose_spacing(white, adjacent, t)
    if choice.step <= 1:
        return sol, cal, discarded, choice
    sol, cal, discarded = calibrate(data, p, keep=_kept(t, choice.spacing_s))
    if sol.whitened_residual is None:
        return sol, cal, discarded, choice
    pairs = cal.pairs
    adjacent = np.array([abs(b.t_start - a.t_end) < 1e-9 for a, b in zip(pairs, pairs[1:])])
    wider = refine_spacing(choice, sol.whitened_residual, adjacent)
    if wider.step == choice.step:
        return sol, cal, discarded, choice
    return (*calibrate(data, p, keep=_kept(t, wider.spacing_s)), wider)


def _kept(t, spacing):
    keep = np.zeros(len(t), dtype=bool)
    keep[thin_fixes(t, spacing)] = True
    return keep


# --- output ---------------------------------------------------------------------------------
def _num(x):
    x = float(x)
    return x if np.isfinite(x) else None


def _mat(m):
    return None if m is None else [[_num(v) for v in row] for row in np.asarray(m, dtype=float)]


def solution_json(sol, weighted: bool) -> dict:
    """
    Return the JSON record of a BoresightSolution (schema in the module docstring).

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


def _band_text(result: dict) -> str:
    band = result.get('chi2_per_dof_band')
    if result.get('fit_consistent') is None or not band:
        return ''
    verdict = 'consistent' if result['fit_consistent'] else 'INCONSISTENT'
    return f" ({verdict}: band [{band[0]:.3g}, {band[1]:.3g}] at level {result['chi2_level']:g})"


def _summary(bag: str, data: dict, result: dict, p: dict) -> str:
    g, c = data['gyro'], data['camera']
    cov_from = ('covariance from the bag' if data['camera_covariance_from_bag']
                else 'assumed camera σ')
    lines = [f"calibrate_bag: {bag}: {len(g.stamps)} Δθ from {data['gyro_topic']}, "
             f"{len(c.stamps)} camera fixes from {data['camera_topic']} ({cov_from})"]
    drops = {f'{k} {n}': v for k, d in result['dropped'].items() for n, v in d.items() if v}
    lines.append('  dropped: ' + (', '.join(f'{k} {v}' for k,
                                            v in drops.items()) if drops else 'none'))
    gg, fx = result['gyro_gaps'], result['camera_fixes']
    if gg['gaps']:
        extra = [f'{gg[k]} {w}' for k, w in (('dropouts', 'dropout(s) beyond max_stamp_jump'),
                                             ('stamp_bursts', 'stamp burst(s)')) if gg.get(k)]
        kinds = ' (' + ', '.join(extra) + ')' if extra else ''
        lines.append(f"  GYRO GAPS: {gg['gaps']} gap(s){kinds}, "
                     f"{gg['missing']} increment(s) missing (rotation lost); "
                     f"{gg['pairs_discarded']} pair(s) spanning them discarded")
    rs = result.get('stamp_resyncs', {})
    if any(rs.values()):
        lines.append(f"  STAMP RESYNCS: gyro {rs.get('gyro', 0)}, camera {rs.get('camera', 0)} "
                     '(clock resets): each time base calibrated on its own, no pair spans a reset')
    sp = result.get('reference_spacing')
    if sp and sp['step'] > 1:
        lines.append(f"  reference spacing: one fix in {sp['step']} ({sp['spacing_s']:.3g} s): "
                     f"{sp['reason']}")
    notes = [f"{n.replace('_', ' ')} {v}" for n, v in fx.items() if v and not isinstance(v, list)]
    if notes:
        lines.append('  camera fixes: ' + ', '.join(notes))
    chi2 = result['chi2_per_dof']
    weighting = 'weighted' if result['weighted'] else 'unweighted (004)'
    if result['observable']:
        converged = 'converged' if result['converged'] else 'NOT converged'
        fit = (f"{converged} in {result['iterations']} iterations, "
               f"residual RMS {result['residual_rms_rad'] * ARCSEC_PER_RAD:.3g}″"
               + (f', χ²/dof {chi2:.3g}' + _band_text(result) if chi2 is not None else ''))
    else:
        fit = 'not observable'
    lines.append(f"  pairs {result['pairs']}, {weighting}, "
                 f"covariance model {p['covariance_model']}, " + fit)
    if result['observable']:
        names = ('heading ψ', 'pitch ϑ', 'roll γ')
        untrusted = ('UNTRUSTED (fit inconsistent with the stated noise) '
                     if result['fit_consistent'] is False else '')
        angles = zip(names, result['beta_rad'], result['beta_sigma_rad'])
        lines.append(f'  {untrusted}β: ' + ', '.join(
            f'{n} {np.degrees(b):.6f}° ± {s * ARCSEC_PER_RAD:.3g}″' for n, b, s in angles))
        sig_mf = np.sqrt(np.diag(result['rotation_covariance_mf_rad2'])) * ARCSEC_PER_RAD
        q_text = ', '.join(f'{v:.9f}' for v in result['q_mf_vf_xyzw'])
        lines.append(f'  {untrusted}q_mf_vf (x, y, z, w) = [{q_text}], '
                     f"σ about MF x, y, z = {', '.join(f'{s:.3g}' for s in sig_mf)}″")
    return '\n'.join(lines)


def consistency_warning(result: dict) -> str | None:
    """
    Return the ``WARNING:`` line of a fit whose χ²/dof is outside its band.

    The line gives χ²/dof, the band, what it means, and which σ is reported.

    Parameters
    ----------
    result : dict
        The JSON record of the solution (:func:`solution_json`).

    Returns
    -------
    str or None
        The line; None when χ²/dof is inside its band or not judged.

    """
    if result.get('fit_consistent') is not False:
        return None
    chi2, (lo, hi) = result['chi2_per_dof'], result['chi2_per_dof_band']
    band = (f"its {100 * (1 - result['chi2_level']):g}% band [{lo:.3g}, {hi:.3g}] "
            f"(dof {result['dof']})")
    if chi2 > hi:
        scale = float(np.sqrt(chi2))
        stated = result.get('beta_sigma_stated_noise_rad')
        if result['weighted']:
            stated_text = ', '.join(f'{v * ARCSEC_PER_RAD:.3g}″' for v in stated or [])
            shown = (f'the σ reported for β are scaled by √(χ²/dof) = {scale:.3g}'
                     + (f'; σ with the stated noise {stated_text}' if stated else ''))
        else:
            shown = ('the σ reported for β come from the residual scatter (004 §4.3, unweighted), '
                     f'a scatter √(χ²/dof) = {scale:.3g} times the stated noise')
        return (f'WARNING: χ²/dof = {chi2:.3g} is above {band}: the stated noise is too small '
                f'or the model lacks an effect (outliers, an unmodelled error); {shown}.  Do not '
                'use the estimate as calibrated.')
    return (f'WARNING: χ²/dof = {chi2:.3g} is below {band}: the stated noise is too large (the σ '
            f'reported for β, from the stated noise, are pessimistic; not scaled down).')


def main(argv=None) -> int:
    """
    Run the calibrate_bag command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status (0 success; 2 unusable arguments or input, one line on stderr).

    """
    ap = OneLineParser(prog='calibrate_bag', description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('bag', help='rosbag2 bag directory, or a .mcap / .db3 file')
    ap.add_argument('--params', metavar='FILE',
                    help='ROS 2 parameter YAML (calibrator_node and /** blocks)')
    ap.add_argument('--json', metavar='FILE', help='write the result as JSON')
    ap.add_argument('--force', action='store_true', help='overwrite an existing --json file')
    ap.add_argument('--unweighted', action='store_true',
                    help='unit weights, covariance from the residuals (004)')
    ap.add_argument('--covariance-model', choices=('004', 'random_constant'),
                    help='gyro error model of E_imu (default: the parameter, random_constant)')
    ap.add_argument('--namespace', default='', help='topic namespace, e.g. /robot1')
    ap.add_argument('-p', '--param', action='append', default=[], metavar='NAME:=VALUE',
                    help='calibrator_node parameter override (repeatable)')
    ap.add_argument('--reference-spacing', default='auto', metavar='auto|SECONDS',
                    help='spacing of the fixes of the increment pairs: auto (default: from the '
                         'correlation of the reference error, doc/calibration.md), 0 (every '
                         'fix) or seconds')
    add_input_arguments(ap)
    args = ap.parse_args(argv)
    try:
        check_input_arguments(args)
        spacing = parse_spacing(args.reference_spacing)
        over = parse_overrides(args.param)
        if args.unweighted:
            over['weighted'] = False
        if args.covariance_model:
            over['covariance_model'] = args.covariance_model
        p = calibrator_parameters(args.params, over)
        check_outputs([('--json', args.json, FILE)],
                      [('bag', args.bag), ('--params', args.params)], args.force)
        data = read_bag(args.bag, args.namespace, bool(p['use_camera_covariance']),
                        (p['camera_sigma_xy'], p['camera_sigma_xy'], p['camera_sigma_z']),
                        float(p['gyro_max_rate']), float(p['max_stamp_jump']),
                        int(p['resync_count']), **input_options(args))
    except (ValueError, OSError, BagError) as exc:
        print(f'calibrate_bag: error: {exc}', file=sys.stderr)
        return 2
    for line in input_warnings('calibrate_bag', data):
        print(line, file=sys.stderr)
    for kind, want in (('gyro', p['frame_id']), ('camera', p['reference_frame_id'])):
        other = [f for f in data['frames'][kind] if f != want]
        if other:
            print(f'calibrate_bag: warning: {kind} messages in frame '
                  f"{', '.join(map(repr, other))}, "
                  f'parameters expect {want!r}', file=sys.stderr)

    g, c = data['gyro'], data['camera']
    if not g.stamps or not c.stamps:
        print(f"calibrate_bag: error: no usable {'gyro' if not g.stamps else 'camera'} messages",
              file=sys.stderr)
        return 2
    step = data['gyro_period_s']
    if np.isfinite(step) and abs(step * float(p['gyro_rate']) - 1.0) > 0.1:
        print(f'calibrate_bag: note: gyro stamps are {step:.6g} s apart ({1.0 / step:.6g} Hz); '
              'gaps are judged '
              f"against that, not gyro_rate = {p['gyro_rate']:g} Hz", file=sys.stderr)
    sol, cal, discarded, choice = calibrate_spaced(data, p, spacing)
    result = solution_json(sol, bool(p['weighted']))
    result['reference_spacing'] = choice.as_dict()
    result['covariance_model'] = p['covariance_model']
    result['dropped'] = {'gyro': dict(g.dropped),
                         'camera': {**c.dropped,
                                    'zero_quaternion': data['camera_fixes']['zero_quaternion'],
                                    'bad_covariance': data['camera_fixes']['bad_covariance']}}
    result['gyro_gaps'] = {'gaps': g.check.gaps, 'missing': g.missing,
                           'pairs_discarded': discarded,
                           'dropouts': g.check.dropouts, 'stamp_bursts': g.check.bursts}
    result['stamp_resyncs'] = {'gyro': g.resyncs, 'camera': c.resyncs}
    result['pairs_replayed_not_added'] = cal.replayed_pairs         # stamps of a pair already held
    period = data['gyro_period_s']
    result['gyro_rate_from_stamps_hz'] = _num(1.0 / period) if np.isfinite(period) else None
    result['camera_fixes'] = {k: data['camera_fixes'][k] for k in ('normalised',
                                                                   'covariance_substituted')}
    result['camera_fixes']['outliers_dropped'] = cal.outlier_fixes
    origin_s = min(g.stamps[0], c.stamps[0]) * 1e-9                     # calibrate()'s time origin
    result['camera_fixes']['outlier_stamps_s'] = [float(t) + origin_s for t in cal.outlier_stamps]
    result['messages'] = {'gyro': len(g.stamps), 'camera': len(c.stamps)}
    result['topics'] = {'gyro': data['gyro_topic'], 'camera': data['camera_topic']}
    result['camera_covariance_from_bag'] = data['camera_covariance_from_bag']
    result['input'] = input_summary(data)
    result['unread_messages'] = dict(data['unread_messages'])
    if data['rate_samples']:
        result['dropped']['gyro_rate_samples'] = dict(data['rate_samples']['dropped'])
    print(_summary(args.bag, data, result, p))
    print('\n'.join(input_lines(result['input'])))
    warning = consistency_warning(result) if result['observable'] else None
    if warning:
        print(warning, file=sys.stderr)
    if args.json:
        try:
            write_json(args.json, result, indent=2)
        except (OSError, ValueError) as exc:
            print(f'calibrate_bag: error: {exc}', file=sys.stderr)
            return 2
    if not result['observable']:
        if sol.pairs >= 2:
            advice = ('Record rotations about at least two non-parallel axes, well above the '
                      'reference noise.')
        else:
            advice = 'Needs two camera fixes whose interval the gyro data covers without a gap.'
        print(f'calibrate_bag: boresight NOT observable from this bag: {sol.message}; '
              'unobservable: '
              f"{'; '.join(result['unobservable_axes'])}.  {advice}", file=sys.stderr)
        return 3
    if not result['converged']:
        print(f'calibrate_bag: warning: {sol.message}', file=sys.stderr)
        return 4
    return 0


if __name__ == '__main__':
    sys.exit(main())
