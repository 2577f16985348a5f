"""
filter_bag: the star-camera-aided attitude filter of ``attitude_filter_node`` on a recording.

    filter_bag BAG --output OUT.csv [--fixes FIXES.csv] [--params FILE] [--force]

The bag is read by :mod:`strapdown_ros.recording` (Δθ or sensor_msgs/Imu rates; the camera or
another attitude reference) with the nodes' input rules; the increments and fixes go, in stamp
order, through :class:`~strapdown_ros.estimation.filter_system.FilterSystem`, the core the node
runs.  OUT has one row per filter output (every ``output_period`` of stamp time): stamp, q x y z
w, attitude σ (3, rad), gyro bias (3, rad/s) and its σ, then each augmented state and its σ.
FIXES (default: OUT with ``_fixes`` before the suffix) has one row per fix: stamp, status,
innovation (3, VF axes, rad), NIS, lateness, and the live model check's verdict.
Parameters come from ``--params`` (the node's block ``attitude_filter_node`` or ``/**``).
Errors: one line on stderr, exit 2.
"""
from __future__ import annotations

from pathlib import Path
import sys

import numpy as np

from strapdown_ros.cli import check_outputs, FILE, OneLineParser, write_text
from strapdown_ros.estimation.filter_system import FilterSettings
from strapdown_ros.params import filled_in, load_model_file, not_applied_note, parse_overrides
from strapdown_ros.recording.options import (add_input_arguments, check_input_arguments,
                                             input_options, input_warnings)
from strapdown_ros.recording.reader import BagError
from strapdown_ros.runs.filter import run_filter_on
from strapdown_ros.runs.source import RecordingSource

NODE_NAME = 'attitude_filter_node'


def state_rows(outputs, augment) -> str:
    """
    Return the CSV text of the filter outputs, header first.

    Parameters
    ----------
    outputs : list
        The filter's outputs (stamp, attitude, σ, state).
    augment : object
        Not read: the augmented columns come from the outputs themselves.

    Returns
    -------
    str
        The CSV text.

    """
    head = ['stamp', 'qx', 'qy', 'qz', 'qw', 'sigma_x', 'sigma_y', 'sigma_z',
            'bias_x', 'bias_y', 'bias_z', 'bias_sigma_x', 'bias_sigma_y', 'bias_sigma_z']
    for name, (v, _) in (outputs[0].augmented.items() if outputs else []):
        head += [f'{name}_{k}' for k in range(len(v))]
        head += [f'{name}_sigma_{k}' for k in range(len(v))]
    lines = [','.join(head)]
    for o in outputs:
        q = o.attitude
        vals = [o.stamp_ns * 1e-9, q[1], q[2], q[3], q[0],
                *np.sqrt(np.diag(o.attitude_covariance)), *o.bias,
                *np.sqrt(np.diag(o.bias_covariance))]
        for v, s in o.augmented.values():
            vals += list(v) + list(s)
        lines.append(','.join(f'{x:.17g}' for x in vals))
    return '\n'.join(lines) + '\n'


def fix_rows(fixes) -> str:
    """
    Return the CSV text of the fix results, header first.

    Parameters
    ----------
    fixes : list
        The filter's fix results (stamp, status, innovation, NIS, lateness, check).

    Returns
    -------
    str
        The CSV text.

    """
    lines = ['stamp,status,innovation_x,innovation_y,innovation_z,nis,lateness,check_ok,check']
    for f in fixes:
        z = f.innovation if f.innovation is not None else [float('nan')] * 3
        nis = f.nis if f.nis is not None else float('nan')
        text = f.check_text.replace('"', "'")
        lines.append(f'{f.stamp_ns * 1e-9:.17g},{f.status},{z[0]:.17g},{z[1]:.17g},'
                     f'{z[2]:.17g},{nis:.17g},{f.lateness:.17g},{int(f.check_ok)},"{text}"')
    return '\n'.join(lines) + '\n'


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
    ap = OneLineParser(prog='filter_bag', description=__doc__.split('\n')[0])
    ap.add_argument('bag', help='bag directory or file')
    ap.add_argument('--output', required=True, help='CSV of the filter outputs')
    ap.add_argument('--fixes', help='CSV of the fixes (default: OUTPUT with _fixes)')
    ap.add_argument('--params', help='the sensor model and settings: a ROS 2 parameter file '
                    '(its model keys, and the settings of /** and attitude_filter_node)')
    ap.add_argument('-p', dest='overrides', action='append', metavar='NAME:=VALUE',
                    help='set one parameter (model key or setting), as ros2 run -p; repeatable')
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
        check_outputs([('--output', str(out), FILE), ('--fixes', str(fixes_path), FILE)],
                      [('bag', args.bag), ('--params', args.params)], args.force)
        mf = load_model_file(args.params, NODE_NAME, parse_overrides(args.overrides))
        for w in mf.warnings:
            print(f'filter_bag: warning: {w}', file=sys.stderr)
        settings = FilterSettings.from_values(mf.settings)
        run = run_filter_on(RecordingSource(args.bag, args.namespace, **input_options(args)),
                            mf.model, settings)
    except np.linalg.LinAlgError:                     # numerical, never reported as bad input
        raise
    except (ValueError, BagError) as exc:
        print(f'filter_bag: error: {str(exc).splitlines()[0]}', file=sys.stderr)
        return 2
    model = run.model
    for line in input_warnings('filter_bag', run.read):
        print(line, file=sys.stderr)
    for line in filled_in(mf.model, model):
        print(f'filter_bag: note: {line}', file=sys.stderr)
    note = not_applied_note(model, ('gyro', 'reference', 'filter'), 'filter_bag')
    if note:
        print(f'filter_bag: note: {note}', file=sys.stderr)
    outputs, fixes = run.outputs, run.fixes
    try:
        write_text(out, state_rows(outputs, run.augment))
        write_text(fixes_path, fix_rows(fixes))
    except OSError as exc:
        print(f'filter_bag: error: {exc}', file=sys.stderr)
        return 2
    st = run.status
    print(f"filter_bag: {len(outputs)} outputs, {st['applied']} fixes applied, {st['gated']} "
          f"gated, {st['restarts']} restarts; {out}, {fixes_path}")
    if run.check_text is not None:
        print(f'filter_bag: {run.check_text}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
