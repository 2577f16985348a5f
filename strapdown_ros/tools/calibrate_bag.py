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
The work is :func:`strapdown_ros.runs.boresight.boresight_of_data` on the recording read by
:func:`strapdown_ros.runs.source.read_checked` (the calls the fleet makes too); this command checks
the arguments, prints and writes.
Exit status: 0 solved, 2 bad arguments/parameters/bag, 3 not observable, 4 no convergence or a
numerical failure of the calibration (one line on stderr, never reported as bad input).
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from strapdown_ros.calibration.reference_spacing import parse_spacing
from strapdown_ros.calibration.streaming import CalibratorSettings
from strapdown_ros.cli import check_outputs, FILE, OneLineParser, write_json
from strapdown_ros.params import load_model_file, parse_overrides
from strapdown_ros.recording import (add_input_arguments, BagError, check_input_arguments,
                                     input_lines, input_options)
from strapdown_ros.runs.boresight import boresight_of_data, CONSUMERS
from strapdown_ros.runs.source import (read_checked, recording_notes, RecordingSource,
                                       UnusableRecording)

__all__ = ['main', 'sigma_note', 'consistency_warning']

ARCSEC_PER_RAD = 180.0 / np.pi * 3600.0


def _band_text(result: dict) -> str:
    band = result.get('chi2_per_dof_band')
    if result.get('fit_consistent') is None or not band:
        return ''
    verdict = 'consistent' if result['fit_consistent'] else 'INCONSISTENT'
    return f" ({verdict}: band [{band[0]:.3g}, {band[1]:.3g}] at level {result['chi2_level']:g})"


def _summary(bag: str, result: dict) -> str:
    n, topic = result['messages'], result['topics']
    cov_from = ('covariance from the bag' if result['camera_covariance_from_bag']
                else 'assumed camera σ')
    lines = [f"calibrate_bag: {bag}: {n['gyro']} Δθ from {topic['gyro']}, "
             f"{n['camera']} camera fixes from {topic['camera']} ({cov_from})"]
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
                 f"covariance model {result['covariance_model']}, " + fit)
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
        note = sigma_note(result)
        if note:
            lines.append(f'  {note}')
    return '\n'.join(lines)


def sigma_note(result: dict) -> str | None:
    """
    Return how the σ of β were computed and what they assume, from the record's numbers.

    ``discrepancy`` estimates the same boresight; its σ differ from these when its residuals are
    correlated (it then uses the Newey–West sandwich, these assume independent pairs) or when it
    adds effects or a noise model: the sentence says which applies here.

    Parameters
    ----------
    result : dict
        The JSON record (``sigma_method``, ``chi2_per_dof``, ``residual_whiteness``).

    Returns
    -------
    str or None
        The sentence; None when there is no solution.

    """
    method = result.get('sigma_method')
    if not method:
        return None
    chi2 = result.get('chi2_per_dof')
    head = {'model': "σ (sigma_method model): the stated noise's, gyro constants marginalised",
            'model_scaled_sqrt_chi2': 'σ (sigma_method model_scaled_sqrt_chi2): the stated '
                                      f"noise's, scaled by √(χ²/dof) = {np.sqrt(chi2 or 1.0):.3g}",
            'residual_scatter_004': 'σ (sigma_method residual_scatter_004): from the residual '
                                    'scatter (004 §4.3, unit weights)'}[method]
    wt = result.get('residual_whiteness')
    if not wt:
        return head + '; they assume independent pairs (too few pairs to test it)'
    if wt['white']:
        return (head + f'; they assume independent pairs, and the residuals are white (Ljung–Box '
                f"p {wt['p_value']:.3g} ≥ {wt['level']:g}): discrepancy gives the same σ unless "
                'it adds effects or a noise term')
    return (head + f'; they assume independent pairs, but the residuals are correlated in time '
            f"(Ljung–Box p {wt['p_value']:.3g} < {wt['level']:g}): these σ may be too small; "
            'discrepancy replaces them by the Newey–West sandwich (never smaller) when its own '
            'whiteness test, at its stricter level, fails too')


def consistency_warning(result: dict) -> str | None:
    """
    Return the ``WARNING:`` line of a fit whose χ²/dof is outside its band.

    The line gives χ²/dof, the band, what it means, and which σ is reported.

    Parameters
    ----------
    result : dict
        The JSON record of the solution
        (:func:`strapdown_ros.calibration.replay.solution_record`).

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
                    help='the sensor model and settings: a ROS 2 parameter YAML (its model keys, '
                         'and the settings of /** and calibrator_node)')
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
                    help='spacing of the fixes of the increment pairs: auto (default: the '
                         "model's reference_spacing where it states one, else from the "
                         'correlation of the reference error, doc/calibration.md), 0 (every '
                         'fix) or seconds')
    add_input_arguments(ap)
    args = ap.parse_args(argv)

    def say(text):
        print(f'calibrate_bag: {text}', file=sys.stderr)
    try:
        check_input_arguments(args)
        spacing = parse_spacing(args.reference_spacing)
        over = parse_overrides(args.param)
        if args.unweighted:
            over['weighted'] = False
        if args.covariance_model:
            over['covariance_model'] = args.covariance_model
        mf = load_model_file(args.params, 'calibrator_node', over)
        settings = CalibratorSettings.from_values(mf.settings)
        check_outputs([('--json', args.json, FILE)],
                      [('bag', args.bag), ('--params', args.params)], args.force)
        for w in mf.warnings:
            say(f'warning: {w}')
        source = RecordingSource(args.bag, args.namespace, **input_options(args))
        data, model = read_checked(source, mf.model, settings.use_camera_covariance,
                                   settings.max_stamp_jump, settings.resync_count)
    except (ValueError, OSError, BagError) as exc:
        say(f'error: {exc}')
        return 2
    inputs, frames, notes = recording_notes('calibrate_bag', data, mf.model, model, CONSUMERS)
    for text in inputs + notes + frames:
        say(text)
    try:
        run = boresight_of_data(data, model, settings, spacing)
    except UnusableRecording as exc:               # what was read, then why it is not enough
        print('\n'.join(input_lines(exc.summary)))
        say(f'error: {exc}')
        return 2
    except (ValueError, ArithmeticError) as exc:   # numerical: never reported as bad input
        why = str(exc).splitlines()[0][:300] if str(exc) else type(exc).__name__
        say(f'error: the calibration failed: {why}')
        return 4
    result = run.record
    print(_summary(args.bag, result))
    print('\n'.join(input_lines(result['input'])))
    warning = consistency_warning(result) if result['observable'] else None
    if warning:
        print(warning, file=sys.stderr)
    if args.json:
        try:
            write_json(args.json, result, indent=2)
        except (OSError, ValueError) as exc:
            say(f'error: {exc}')
            return 2
    if not result['observable']:
        if result['pairs'] >= 2:
            advice = ('Record rotations about at least two non-parallel axes, well above the '
                      'reference noise.')
        else:
            advice = 'Needs two camera fixes whose interval the gyro data covers without a gap.'
        say(f"boresight NOT observable from this bag: {result['message']}; unobservable: "
            f"{'; '.join(result['unobservable_axes'])}.  {advice}")
        return 3
    if not result['converged']:
        say(f"warning: {result['message']}")
        return 4
    return 0


if __name__ == '__main__':
    sys.exit(main())
