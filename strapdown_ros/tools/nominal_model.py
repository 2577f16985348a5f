"""
nominal_model: the starting sensor model of one's own recording, each value with its rule.

    nominal_model BAG --output M.yaml [--gyro-topic T] [--reference-topic T]
                  [--reference-frames PARENT CHILD] [--rate-rule trapezoid|mean]
                  [--json FILE] [--namespace NS] [--force] [--quiet]

Reads the gyro (``sensor_msgs/Imu`` rates or ``Vector3Stamped`` Δθ) and the attitude reference
(PoseStamped, TransformStamped, PoseWithCovarianceStamped, Odometry, QuaternionStamped or TF) of
a rosbag2 recording, with no clip level (so that clipped samples are seen), and writes the model
file ``discrepancy --model``, ``calibrate_bag``, ``filter_bag`` and the nodes start from: the gyro
rate and frame ids, the clip level, the angle random walk and bias instability from the Allan
deviation of the rest segments, a bias prior from the rest mean, the reference's noise from its
residual against the gyro.  Each value is written with the rule that produced it, as a comment
in the file and in the printed summary; where the data cannot support a value it says so and
writes a stated default (the rules: ``strapdown_ros.discrepancy.nominal``).

Exit status: 0 written; 2, one line on stderr, for unusable arguments or input.
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys

import numpy as np

from strapdown_ros.cli import all_or_nothing, check_outputs, FILE, OneLineParser, write_json
from strapdown_ros.discrepancy.nominal import nominal_model
from strapdown_ros.params import write_model_file
from strapdown_ros.recording import (add_input_arguments, BagError, check_input_arguments,
                                     input_lines, input_options, input_summary, input_warnings,
                                     read_bag, recording_facts)
from strapdown_ros.recording.options import usable_error
from strapdown_ros.text import bounded, json_clean

__all__ = ['main']

PROG = 'nominal_model'
#: no clip level while reading: a clipped sample must be seen, not dropped
READ_MAX_RATE = 1e4


def _value_text(v) -> str:
    if isinstance(v, list):
        return '[' + ', '.join(f'{x:.4g}' for x in v) + ']'
    if isinstance(v, float):
        return f'{v:.6g}'
    return repr(bounded(v))


def main(argv=None) -> int:
    """
    Run the nominal_model command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status (0 written; 2 unusable arguments or input, one line on stderr).

    """
    ap = OneLineParser(prog=PROG, description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('bag', help='rosbag2 bag directory, or a .mcap / .db3 file')
    ap.add_argument('--output', required=True, metavar='M.yaml', help='the model file to write')
    ap.add_argument('--json', metavar='FILE', help='the values, rules and measurements as JSON')
    ap.add_argument('--namespace', default='', help='topic namespace, e.g. /robot1')
    ap.add_argument('--force', action='store_true', help='replace existing outputs')
    ap.add_argument('--quiet', action='store_true', help='no progress on stderr')
    add_input_arguments(ap)
    args = ap.parse_args(argv)

    def progress(text):
        if not args.quiet:
            print(f'{PROG}: {text}', file=sys.stderr, flush=True)
    try:
        check_input_arguments(args)
        if not Path(args.bag).exists():
            raise ValueError(f'bag {args.bag} does not exist')
        check_outputs([('--output', args.output, FILE), ('--json', args.json, FILE)],
                      [('bag', args.bag)], args.force)
        progress('reading the bag')
        data = read_bag(args.bag, args.namespace, True, (1e-3, 1e-3, 1e-3), READ_MAX_RATE,
                        1.0, 5, **input_options(args))
        g, c = data['gyro'], data['camera']
        for line in input_warnings(PROG, data):
            print(line, file=sys.stderr)
        unusable = usable_error(data)                 # the tools' one wording
        if unusable:
            raise ValueError(unusable)
        nm = nominal_model(g.stamps, np.asarray(g.values, dtype=float), c.stamps,
                           np.array([v[0] for v in c.values]).reshape(-1, 4),
                           recording_facts(data), progress)
    except (ValueError, OSError, BagError) as exc:
        print(f'{PROG}: error: {str(exc).splitlines()[0] if str(exc) else exc!r}',
              file=sys.stderr)
        return 2
    model = nm.model
    values = model.values()
    lines = [f'{PROG}: {bounded(args.bag)}: {len(g.stamps)} gyro increments '
             f"({data['gyro_topic']}), {len(c.stamps)} reference fixes ({data['camera_topic']})"]
    lines += input_lines(input_summary(data))
    for k in sorted(model.stated, key=list(values).index):
        lines.append(f'  {k} = {_value_text(values[k])}  ({model.provenance.get(k, "")})')
    for k, v in nm.settings.items():
        lines.append(f'  {k} = {_value_text(v)}  ({nm.setting_rules.get(k, "")})')
    for n in nm.notes:
        lines.append(f'  note: {n}')
    head = (f'written by nominal_model from {Path(args.bag).name}: the starting model of this '
            'recording; each value with its rule')
    comment = '\n'.join([head] + [f'note: {n}' for n in nm.notes])
    try:
        with all_or_nothing():                   # the model and --json, or neither
            _write(args, model, comment, nm, values, data)
    except OSError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 2
    lines.append(f'  model: {args.output}')
    print('\n'.join(lines))
    return 0


def _write(args, model, comment, nm, values, data) -> None:
    """Write the model file and the JSON record (inside all_or_nothing)."""
    write_model_file(args.output, model, comment,
                     {'calibrator_node': {'ros__parameters': nm.settings}}
                     if nm.settings else None, setting_rules=nm.setting_rules)
    if args.json:
        write_json(args.json, json_clean({
            'values': {k: values[k] for k in model.stated},
            'rules': {k: model.provenance.get(k) for k in model.stated},
            'settings': nm.settings, 'setting_rules': nm.setting_rules, 'notes': nm.notes,
            'measured': nm.measured, 'input': input_summary(data)}))


if __name__ == '__main__':
    sys.exit(main())
