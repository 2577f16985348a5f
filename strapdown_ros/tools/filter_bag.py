"""
filter_bag: the star-camera-aided attitude filter of ``attitude_filter_node`` on a recording.

    filter_bag BAG --output OUT.csv [--fixes FIXES.csv] [--json FILE] [--params FILE]
               [-p NAME:=VALUE] [--plots DIR] [--force]

The bag is read by :mod:`strapdown_ros.recording` (Δθ or sensor_msgs/Imu rates; the camera or
another attitude reference) with the nodes' input rules; the increments and fixes go, in stamp
order, through :class:`~strapdown_ros.estimation.filter_system.FilterSystem`, the core the node
runs.  OUT has one row per ``output_period`` of stamp time (at the first increment stamp of
each period): stamp, q x y z w, attitude σ (3, rad), gyro bias (3, rad/s) and its σ, then each
augmented state and its σ (``<name>_<k>``, ``<name>_sigma_<k>``; the boresight is the
quaternion ``q_MF_VF`` w x y z, its σ the 3 angles of its error, rad).  FIXES (default: OUT
with ``_fixes`` before the suffix) has one row per fix: stamp, status (``applied``, ``gated``,
``reset``, ``too_old``, ``overflow``), innovation (3, VF axes, rad), NIS, lateness, the live
model check's verdict, and why a divergence was declared.  A divergence (consecutive gated
fixes, or an NIS excess: parameters ``divergence_*``) is printed as it happened; the filter
re-initialised its attitude from that fix and went on.  ``--plots DIR`` writes the innovation
with its ±3σ, the bias and augmented states with their σ, the NIS with its band and the fixes
applied, gated and reset (PNG).  Parameters come from ``--params`` (the node's block
``attitude_filter_node`` or ``/**``) and ``-p NAME:=VALUE``.
What was read and dropped is printed as every tool prints it (messages per topic, drops per
reason, gaps, resynchronisations, frames) and, with ``--json``, written with the filter's counts.
The outputs are written all or nothing (temporaries, then renamed together; the plots after).
Errors: one line on stderr, exit 2 (bad arguments or input); 4 when the filter fails numerically.
"""
from __future__ import annotations

from pathlib import Path
import sys

import numpy as np

from strapdown_ros.cli import (all_or_nothing, check_outputs, DIRECTORY, FILE, OneLineParser,
                               write_json, write_text)
from strapdown_ros.estimation.filter_plots import PLOT_NAMES, write_filter_plots
from strapdown_ros.estimation.filter_system import FilterOutputs, FilterSettings
from strapdown_ros.params import filled_in, load_model_file, not_applied_note, parse_overrides
from strapdown_ros.recording.options import (add_input_arguments, check_input_arguments,
                                             frame_warnings, input_lines, input_options,
                                             input_summary, input_warnings, usable_error)
from strapdown_ros.recording.reader import BagError
from strapdown_ros.runs.filter import filter_of_data
from strapdown_ros.runs.source import read_checked, RecordingSource
from strapdown_ros.text import json_clean

NODE_NAME = 'attitude_filter_node'
#: divergence resets printed one per line (the rest are counted)
RESETS_PRINTED = 20


def state_header(outputs) -> list[str]:
    """
    Return the column names of the filter outputs.

    Parameters
    ----------
    outputs : list
        The filter's outputs; the augmented columns come from the first.

    Returns
    -------
    list of str
        The names, one per field of every row.

    """
    head = ['stamp', 'qx', 'qy', 'qz', 'qw', 'sigma_x', 'sigma_y', 'sigma_z',
            'bias_x', 'bias_y', 'bias_z', 'bias_sigma_x', 'bias_sigma_y', 'bias_sigma_z']
    for name, (v, s) in (outputs[0].augmented.items() if outputs else []):
        head += [f'{name}_{k}' for k in range(len(v))]
        head += [f'{name}_sigma_{k}' for k in range(len(s))]
    return head


def state_rows(outputs, augment=None) -> str:
    """
    Return the CSV text of the filter outputs, header first.

    Parameters
    ----------
    outputs : FilterOutputs or list of FilterOutput
        The filter's outputs (stamp, attitude, σ, state).
    augment : object
        Not read: the augmented columns come from the outputs themselves.

    Returns
    -------
    str
        The CSV text.

    """
    head = state_header(outputs)
    if not outputs:
        return ','.join(head) + '\n'
    out = FilterOutputs.of(outputs)
    cols = [out.stamps_ns * 1e-9, out.attitude[:, 1:], out.attitude[:, :1]]   # x y z w
    cols.append(np.sqrt(np.diagonal(out.attitude_covariance, 0, 1, 2)))
    cols.append(out.bias)
    cols.append(np.sqrt(np.diagonal(out.bias_covariance, 0, 1, 2)))
    for est, sig in out.augmented.values():
        cols += [est, sig]
    table = np.column_stack(cols)
    row = ','.join(['%.17g'] * table.shape[1])
    # one % over the whole table: the same text as row by row, without a tuple per row
    return ','.join(head) + '\n' + ('\n'.join([row] * len(table)) + '\n') % tuple(
        table.ravel().tolist())


def fix_rows(fixes) -> str:
    """
    Return the CSV text of the fix results, header first.

    Parameters
    ----------
    fixes : list
        The filter's fix results (stamp, status, innovation, NIS, lateness, check, reason).

    Returns
    -------
    str
        The CSV text.

    """
    lines = ['stamp,status,innovation_x,innovation_y,innovation_z,nis,lateness,check_ok,check,'
             'reason']
    for f in fixes:
        z = f.innovation if f.innovation is not None else [float('nan')] * 3
        nis = f.nis if f.nis is not None else float('nan')
        text = f.check_text.replace('"', "'")
        why = f.reason.replace('"', "'")
        lines.append(f'{f.stamp_ns * 1e-9:.17g},{f.status},{z[0]:.17g},{z[1]:.17g},'
                     f'{z[2]:.17g},{nis:.17g},{f.lateness:.17g},{int(f.check_ok)},"{text}",'
                     f'"{why}"')
    return '\n'.join(lines) + '\n'


def spacing_line(spacing: float, counts: dict) -> str:
    """
    Return the line on the reference spacing rule ('' when every fix is taken).

    Parameters
    ----------
    spacing : float
        The model's ``reference_spacing``, s.
    counts : dict
        The filter's counts (``spaced``).

    Returns
    -------
    str
        The line.

    """
    if not spacing > 0:
        return ''
    return (f"reference spacing {spacing:.3g} s (the model's reference_spacing): "
            f"{counts.get('spaced', 0)} fixes in between left to the reference check")


def agreement_line(agree) -> str:
    """
    Return the line on the outputs against the reference ('' when there was none to compare).

    Parameters
    ----------
    agree : ReferenceAgreement or None
        :func:`strapdown_ros.estimation.reference_check.agreement_with_fixes`.

    Returns
    -------
    str
        The line: the RMS per VF axis in units of the σ stated together, the share within 3σ.

    """
    if agree is None:
        return ''
    if agree.at == 'filter':
        which = (f'at {agree.samples} outputs, interpolated from the fixes around each '
                 + ('(neither of them applied)' if agree.held_out else
                    '(fewer than 10 outputs away from applied fixes: not independent)'))
    else:
        kind = ('fixes it did not apply' if agree.held_out else
                'fixes (fewer than 10 unapplied: not independent)')
        which = f'at {agree.samples} {kind}'
    ratio = ', '.join(f'{r:.3g}' for r in agree.rms_ratio)
    sig = ', '.join(f'{s:.3g}' for s in agree.sigma_rad)
    return (f'against the reference {which}, with a lag of '
            f'{agree.lag_s * 1e3:.3g} ms and a constant boresight taken out: RMS / σ = {ratio} '
            f'about VF x, y, z (σ {sig} rad, the filter and the reference together; 1 is '
            f'honest), {100 * agree.within_3_sigma:.1f}% within 3σ')


def main(argv=None) -> int:
    """
    Run the filter_bag command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status (0 success; 2 unusable arguments or input, one line on stderr).

    """
    ap = OneLineParser(prog='filter_bag', description=__doc__.strip().split('\n')[0])
    ap.add_argument('bag', help='bag directory or file')
    ap.add_argument('--output', required=True, help='CSV of the filter outputs')
    ap.add_argument('--fixes', help='CSV of the fixes (default: OUTPUT with _fixes)')
    ap.add_argument('--json', metavar='FILE',
                    help='what was read and dropped, and the filter counts, as JSON')
    ap.add_argument('--params', help='the sensor model and settings: a ROS 2 parameter file '
                    '(its model keys, and the settings of /** and attitude_filter_node)')
    ap.add_argument('-p', dest='overrides', action='append', metavar='NAME:=VALUE',
                    help='set one parameter (model key or setting), as ros2 run -p; repeatable')
    ap.add_argument('--plots', metavar='DIR', help='write PNG plots into DIR: the innovation '
                    'with its ±3σ, the bias and augmented states with their σ, the NIS with its '
                    'band, the fixes applied, gated and reset, the attitude against the reference')
    ap.add_argument('--namespace', default='', help='topic namespace')
    ap.add_argument('--force', action='store_true', help='replace existing outputs')
    add_input_arguments(ap)
    args = ap.parse_args(argv)
    out = Path(args.output)
    fixes_path = Path(args.fixes) if args.fixes else out.with_name(out.stem + '_fixes'
                                                                   + (out.suffix or '.csv'))
    try:
        check_input_arguments(args)
        if not Path(args.bag).exists():
            raise ValueError(f'bag {args.bag} does not exist')
        if args.params and not Path(args.params).is_file():
            raise ValueError(f'--params {args.params} is not a file')
        stale = check_outputs([('--output', str(out), FILE), ('--fixes', str(fixes_path), FILE),
                               ('--json', args.json, FILE),
                               ('--plots', args.plots, DIRECTORY, PLOT_NAMES)],
                              [('bag', args.bag), ('--params', args.params)], args.force)
        for path in stale:
            print(f'filter_bag: note: removed {path}, a temporary an earlier run left',
                  file=sys.stderr)
        mf = load_model_file(args.params, NODE_NAME, parse_overrides(args.overrides))
        for w in mf.warnings:
            print(f'filter_bag: warning: {w}', file=sys.stderr)
        settings = FilterSettings.from_values(mf.settings)
        model = mf.model
        source = RecordingSource(str(args.bag), args.namespace, **input_options(args))
        data, model = read_checked(source, model, settings.use_camera_covariance,
                                   settings.max_stamp_jump, settings.resync_count)
    except (ValueError, OSError, BagError) as exc:
        print(f'filter_bag: error: {str(exc).splitlines()[0]}', file=sys.stderr)
        return 2
    for line in input_warnings('filter_bag', data):
        print(line, file=sys.stderr)
    for line in frame_warnings('filter_bag', data, model.frame_id, model.reference_frame_id):
        print(line, file=sys.stderr)
    for line in filled_in(mf.model, model):
        print(f'filter_bag: note: {line}', file=sys.stderr)
    note = not_applied_note(model, ('gyro', 'reference', 'filter'), 'filter_bag')
    if note:
        print(f'filter_bag: note: {note}', file=sys.stderr)
    print(f'filter_bag: {args.bag}')
    print('\n'.join(input_lines(input_summary(data))))
    unusable = usable_error(data)
    if unusable:
        print(f'filter_bag: error: {unusable}', file=sys.stderr)
        return 2
    try:
        run = filter_of_data(data, model, settings)
    except (ValueError, ArithmeticError) as exc:     # numerical: never reported as bad input
        print(f'filter_bag: error: the filter failed: {str(exc).splitlines()[0][:300]}',
              file=sys.stderr)
        return 4
    outputs, fixes, st = run.outputs, run.fixes, run.status
    agree = run.agreement
    try:
        with all_or_nothing():                       # OUT, FIXES and --json, or none of them
            write_text(out, state_rows(outputs, run.augment))
            write_text(fixes_path, fix_rows(fixes))
            if args.json:
                write_json(args.json, json_clean({
                    'input': run.read, 'counts': st, 'outputs': len(outputs),
                    'fixes': len(fixes), 'reference_spacing_s': model.reference_spacing,
                    'reference_agreement': agree.as_dict() if agree is not None else None}))
    except OSError as exc:
        print(f'filter_bag: error: {exc}', file=sys.stderr)
        return 2
    t0 = outputs[0].stamp_ns if outputs else (fixes[0].stamp_ns if fixes else 0)
    for k, (ns, why) in enumerate(run.resets):
        if k < RESETS_PRINTED:
            print(f'filter_bag: divergence at {ns * 1e-9:.3f} s ({(ns - t0) * 1e-9:.3f} s after '
                  f'the start): {why}; the attitude was re-initialised from that fix '
                  '(bias kept)')
    if st['reset'] > RESETS_PRINTED:
        print(f"filter_bag: ... and {st['reset'] - RESETS_PRINTED} more divergence resets "
              f'(status reset in {fixes_path})')
    print(f"filter_bag: {len(outputs)} outputs, {st['applied']} fixes applied, {st['gated']} "
          f"gated, {st['reset']} divergence resets, {st['restarts']} restarts; {out}, "
          f'{fixes_path}')
    for line in (spacing_line(model.reference_spacing, st), agreement_line(agree)):
        if line:
            print(f'filter_bag: {line}')
    if run.check_text is not None:
        print(f'filter_bag: {run.check_text}')
    if args.plots:
        try:
            Path(args.plots).mkdir(parents=True, exist_ok=True)
            written = write_filter_plots(args.plots, outputs, fixes,
                                         settings.gate_probability, agree)
        except OSError as exc:
            print(f'filter_bag: error: {exc}', file=sys.stderr)
            return 2
        print(f"filter_bag: plots {', '.join(written)}")
    return 0


if __name__ == '__main__':
    sys.exit(main())
