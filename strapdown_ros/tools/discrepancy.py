"""
discrepancy: where a recording and its model disagree, and which effect is missing.

How much the disagreement shrinks once the missing effect is added is reported too.

    discrepancy BAG --model MODEL.yaml [--json FILE] [--report DIR] [--write-model OUT.yaml]
                [--force]

BAG: a rosbag2 recording (MCAP or sqlite3) of ``imu/delta_theta`` (geometry_msgs/Vector3Stamped)
and the star camera, ``star_camera/attitude_with_covariance`` (its covariance is used) or
``star_camera/attitude`` (then ``camera_sigma_xy``/``camera_sigma_z`` of the model), at any gyro
rate (taken from the stamps), any length and any stamp origin; no truth topics are needed.
Other formats (``strapdown_ros.recording``): ``--gyro-topic`` of sensor_msgs/msg/Imu rates
(increments by ``--rate-rule``), ``--reference-topic`` of PoseStamped, PoseWithCovarianceStamped,
nav_msgs/msg/Odometry or QuaternionStamped, or TF with ``--reference-frames PARENT CHILD``.
MODEL: a ROS 2 parameter file in the schema of the package's nodes (``/**`` and per-node
blocks; any parameter of any node).  The known effects it states (``gyro_bias``,
``camera_time_offset``, …) are compensated before the search, as ``sins_node`` and
``calibrator_node`` compensate them.

Method (``strapdown_ros.discrepancy.workflow``): increment residuals of consecutive camera
fixes (004 eq. 5–6) whitened by the calibrator's correlated covariance, the boresight always
estimated; likelihood-ratio selection over the effect library at a Bonferroni-corrected level,
confirmed on held-out time blocks; verdict ``model_adequate``, ``explained`` or
``unexplained_structure``.  The Allan deviation of the gyro on static segments is set beside
that of the model simulated on the same segments (allantools).

A reference at any rate: ``--reference-spacing auto`` (default) keeps the fixes of the pairs
as far apart as the correlation of the reference's error requires (every fix when it is white;
``0`` keeps every fix, a number of seconds one per slot); ``reference_spacing`` in the JSON.

Output: a summary on stdout; ``--json`` the full result (doc/discrepancy.md); ``--report DIR``
``report.md`` with PNG plots; ``--write-model`` the model with the found effects and the
estimated boresight.  No output may be an input (the bag, the model) or another output; an
existing one needs ``--force``; the files are written atomically and all or nothing (every
output to its temporary first, then all renamed into place; temporaries an earlier, killed run
left are removed at start).

The work is :func:`strapdown_ros.runs.discrepancy.analyse_discrepancies` (read, check the model,
the workflow, the Allan comparison: the call the fleet makes too); this command checks the
arguments, prints and writes.

Exit status: 0 for every verdict (a fit inconsistent with its stated noise is printed with a line
starting ``WARNING:``); 2, with one line on stderr, for unusable input (missing or malformed bag
or model, no camera topic, too few fixes, a model key no node of the package knows); 3 when the
motion does not determine the boresight (the rule of ``calibrate_bag``; no model is written, the
JSON says ``"observable": false``); 4 when a usable recording cannot be analysed because a base
fit fails numerically (one line on stderr: ``discrepancy: analysis failed: ...``).
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys
import time

import numpy as np

from strapdown_ros.calibration.reference_spacing import parse_spacing
from strapdown_ros.cli import (all_or_nothing, check_outputs, DIRECTORY, FILE, OneLineParser,
                               write_json)
from strapdown_ros.discrepancy.bag_input import recording_lines
from strapdown_ros.discrepancy.report import write_report
from strapdown_ros.discrepancy.sentences import (boresight_sigma_sentence, consistency_warning,
                                                 remaining_sentences, repeatability_sentence,
                                                 sigma_sentence)
from strapdown_ros.discrepancy.workflow import (AnalysisError, DEFAULT_ALPHA,
                                                DiscrepancySettings, InputError)
from strapdown_ros.params import load_model_file, write_model_file
from strapdown_ros.recording import (add_input_arguments, BagError, check_input_arguments,
                                     input_options)
from strapdown_ros.runs.discrepancy import analyse_discrepancies
from strapdown_ros.runs.source import RecordingSource

__all__ = ['main', 'write_model']

ARCSEC_PER_RAD = 180.0 / np.pi * 3600.0


def write_model(path: str, doc: dict, result) -> None:
    """
    Write the found model: the nominal model with the found effects, σ, online states, boresight.

    Every command and node reads it unchanged (one sensor model); each value written carries
    the rule that produced it as a comment.

    Parameters
    ----------
    path : str
        The output model file (written atomically).
    doc : dict
        The input model document (its settings are kept).
    result : DiscrepancyResult
        The workflow's result.

    """
    added = ', '.join(s.effect for s in result.steps) or 'none'
    consistent = '' if result.fit_consistent else \
        '\nWARNING: the fit is not consistent with its stated noise: not a plain result'
    write_model_file(path, result.found_model,
                     f'written by discrepancy: verdict {result.verdict}; effects added: {added}'
                     f'{consistent}', doc)


def _summary(bag, info, res) -> str:
    j = res.as_json()
    lines = recording_lines('discrepancy', bag, info, f'{res.pairs} increment pairs, ')
    lines.append(f'  verdict: {res.verdict}')
    warning = consistency_warning(res)
    if warning:
        lines.append(warning)
    sigma = sigma_sentence(res)
    if sigma:
        lines.append(f'  {sigma}')
    lines.append(f'  whitened RMS {res.rms_before:.3g} → {res.rms_after:.3g} '
                 '(1 = as the model predicts); held out '
                 f'{res.heldout_rms_before:.3g} → {res.heldout_rms_after:.3g}')
    for k, s in enumerate(res.steps, 1):
        vals = '; '.join(f'{n} = {_fmt(v)} ± {_fmt(s.sigma[n])}' for n, v in s.parameters.items())
        lines.append(f'  step {k}: {s.effect}: {vals}  (LR {s.statistic:.4g}, dof {s.dof}, '
                     f'p {s.p_value:.3g}, '
                     f'held-out gain {s.heldout_gain:.3g}, σ {s.sigma_method})')
        text = repeatability_sentence(s)
        if text:
            lines.append(f'    {text}')
    stops = {'max_steps': f'the step limit ({res.max_steps} accepted effects) stopped the search; '
                          f'more may be missing',
             'no_significant_candidate': 'search stopped: no candidate left passes its test',
             'no_candidates_left': 'search stopped: every candidate was added, excluded or failed',
             'iteration_limit': 'search stopped by its turn limit'}
    stop = stops.get(res.stopped_by, f'{res.stopped_by}')
    lines.append(f'  {stop}')
    seen: dict = {}
    for f in res.failed_candidates:                  # one line per effect and reason
        seen.setdefault((f['effect'], f['reason']), []).append(str(f['step']))
    for (effect, reason), at in seen.items():
        lines.append(f"  not fitted (dropped at step {', '.join(at)}): {effect}: {reason}")
    for a, b in res.not_separable:
        lines.append(f'  not separable on this trajectory: {a} and {b}')
    for r in res.rejected:
        lines.append(f"  not added: {r['effect']}: {r['reason']}")
    ta = j['tests_after']
    lines.append('  tests: ' + ', '.join(f"{k} p = {ta[k]['p_value']:.3g}" for k in ('nis',
                                                                                     'whiteness',
                                                                                     'outliers'))
                 + f" (level {ta['level']:.3g} each)")
    if res.remaining:
        rm = res.remaining
        nan = float('nan')
        lines.append('  remaining structure: dominant period '
                     f"{rm.get('dominant_period_s', nan):.4g} s, "
                     f"lag-{rm.get('dominant_lag_pairs')} autocorrelation "
                     f"{rm.get('dominant_lag_autocorrelation', nan):.2f}, correlation with rate "
                     f"{rm.get('correlation_with_rate', nan):.2f}, with accumulated angle "
                     f"{rm.get('correlation_with_accumulated_angle', nan):.2f}")
        for c in rm.get('candidate_explanations', []):
            sw = rm.get('gyro_axis_swap_sign', {})
            lines.append(f'  candidate explanation outside the library: {c}: the gyro triad '
                         f"as wired is left-handed; read as e.g. {sw.get('mapping')} the "
                         f"axis-alignment RMS drops to {sw.get('ratio', float('nan')):.2g}× "
                         f'(which axis, the camera cannot tell: a rotation goes into the '
                         f'boresight)')
    lines += [f'  {t}' for t in remaining_sentences(res)]
    b = np.degrees(res.boresight_rad)
    s = np.asarray(res.boresight_sigma_rad) * ARCSEC_PER_RAD
    lines.append(f'  boresight β = ({b[0]:.6f}, {b[1]:.6f}, {b[2]:.6f})° '
                 f'± ({s[0]:.3g}, {s[1]:.3g}, {s[2]:.3g})″ (σ {res.sigma_method})')
    text = boresight_sigma_sentence(res)
    if text:
        lines.append(f'  {text}')
    return '\n'.join(lines)


def _fmt(v):
    if isinstance(v, (list, tuple)):
        return '[' + ', '.join(f'{x:.4g}' for x in v) + ']'
    return f'{v:.4g}'


def main(argv=None) -> int:
    """
    Run the discrepancy command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status (0 success; 2 unusable arguments or input, one line on stderr).

    """
    ap = OneLineParser(prog='discrepancy', description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('bag', help='rosbag2 bag directory, or a .mcap / .db3 file')
    ap.add_argument('--model', required=True, metavar='MODEL.yaml',
                    help='nominal model: ROS 2 parameter file')
    ap.add_argument('--json', metavar='FILE', help='write the result as JSON')
    ap.add_argument('--report', metavar='DIR',
                    help='write report.md and PNG plots into DIR (created)')
    ap.add_argument('--write-model', metavar='OUT.yaml',
                    help='write the model with the found effects')
    ap.add_argument('--force', action='store_true', help='overwrite existing outputs (--json, '
                    '--write-model, a non-empty --report directory)')
    ap.add_argument('--alpha', type=float, default=None,
                    help='family-wise level of the selection (default 0.01)')
    ap.add_argument('--namespace', default='', help='topic namespace, e.g. /robot1')
    ap.add_argument('--quiet', action='store_true', help='no progress on stderr')
    ap.add_argument('--reference-spacing', default='auto', metavar='auto|SECONDS',
                    help='spacing of the fixes of the increment pairs: auto (default: the '
                         "model's reference_spacing where it states one, else from the "
                         'correlation of the reference error, doc/discrepancy.md), 0 (every '
                         'fix) or seconds')
    add_input_arguments(ap)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()

    alpha = DEFAULT_ALPHA if args.alpha is None else args.alpha
    try:
        if not (0.0 < alpha < 0.5):
            raise ValueError(f'--alpha must be in (0, 0.5), got {alpha}')
        spacing = parse_spacing(args.reference_spacing)
        check_input_arguments(args)
        if not Path(args.bag).exists():
            raise ValueError(f'bag {args.bag} does not exist')
        if not Path(args.model).is_file():
            raise ValueError(f'model {args.model} does not exist')
        check_outputs([('--json', args.json, FILE), ('--write-model', args.write_model, FILE),
                       ('--report', args.report, DIRECTORY)],
                      [('bag', args.bag), ('--model', args.model)], args.force)
        mf = load_model_file(args.model, 'calibrator_node')
        model, doc = mf.model, mf.doc
        settings = DiscrepancySettings.from_values({**mf.settings, 'alpha': alpha,
                                                    'reference_spacing': spacing})
        for w in mf.warnings:
            print(f'discrepancy: warning: {w}', file=sys.stderr)
    except (ValueError, OSError) as exc:
        print(f'discrepancy: error: {exc}', file=sys.stderr)
        return 2

    def progress(text):
        if not args.quiet:
            print(f'discrepancy: [{time.perf_counter() - t0:6.1f} s] {text}', file=sys.stderr,
                  flush=True)
    source = RecordingSource(args.bag, args.namespace, **input_options(args))
    try:
        run = analyse_discrepancies(source, model, settings, mf.settings, progress=progress,
                                    say=lambda text: print(f'discrepancy: {text}',
                                                           file=sys.stderr))
    except (AnalysisError, np.linalg.LinAlgError, FloatingPointError, OverflowError) as exc:
        # a numerical failure is never reported as bad input (LinAlgError is a ValueError)
        msg = str(exc).splitlines()[0][:300] if str(exc) else type(exc).__name__
        print(f'discrepancy: analysis failed: {msg}', file=sys.stderr)
        return 4
    except (BagError, InputError, ValueError, OSError) as exc:
        print(f'discrepancy: error: {exc}', file=sys.stderr)
        return 2
    if not run.observable:
        if args.json:
            try:
                write_json(args.json, run.record)
            except OSError as exc:
                print(f'discrepancy: error: {exc}', file=sys.stderr)
                return 2
        print(f'discrepancy: boresight NOT observable from this bag: {run.message}; '
              f"unobservable: {'; '.join(run.unobservable)}.  Record rotations about at least "
              'two non-parallel axes, well above the reference noise; no model written.',
              file=sys.stderr)
        return 3
    res, out = run.result, run.record
    print(_summary(args.bag, run.info, res))
    made_report_dir = bool(args.report) and not Path(args.report).exists()
    try:
        with all_or_nothing():             # --json, --write-model and --report, or none
            if args.json:
                write_json(args.json, out)
            if args.write_model:
                write_model(args.write_model, doc, res)
            if args.report:
                progress('report and plots')
                path = write_report(args.report, res, out)
        if args.write_model:
            print(f'  model with the found effects: {args.write_model}')
        if args.report:
            print(f'  report: {path}')
    except OSError as exc:
        if made_report_dir:
            try:
                Path(args.report).rmdir()         # created for the report: empty again
            except OSError:
                pass
        print(f'discrepancy: error: {exc}', file=sys.stderr)
        return 2
    progress(f'done in {time.perf_counter() - t0:.1f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
