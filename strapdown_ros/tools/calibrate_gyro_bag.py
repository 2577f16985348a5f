"""
calibrate_gyro_bag: gyro scale factors, misalignments and biases from a recording, by 000 or 002.

    calibrate_gyro_bag BAG --method integral|tkachenko [--model MODEL.yaml]
                       [--write-model OUT.yaml] [--json FILE] [--force] [--drift]
                       [--interval S] [--sigma-limit X]

BAG: a rosbag2 recording (MCAP or sqlite3) of ``imu/delta_theta``
(geometry_msgs/Vector3Stamped) and the star camera — ``star_camera/attitude_with_covariance``
(geometry_msgs/PoseWithCovarianceStamped, its covariance is used) or ``star_camera/attitude``
(geometry_msgs/QuaternionStamped, then ``camera_sigma_xy``/``camera_sigma_z`` of the model) — at
any rates, stamps from the headers, read and validated as ``calibrate_bag`` and ``discrepancy``
read them (drops, gyro gaps).  No truth topic is needed and the boresight need not be known: it
is found from the increment axes.  Other formats (``strapdown_ros.recording``): ``--gyro-topic``
of sensor_msgs/msg/Imu rates (increments by ``--rate-rule``), ``--reference-topic`` of
PoseStamped, TransformStamped, PoseWithCovarianceStamped, nav_msgs/msg/Odometry or
QuaternionStamped, or TF with ``--reference-frames PARENT CHILD``.

Methods (``strapdown_ros.calibration.gyro``):
``integral`` — 002 (Ilyushenko): mean rates over consecutive camera intervals (``--interval`` s,
default one camera step), generalised least squares with the camera covariance and the gyro
random walk of the model; ``tkachenko`` — 000 (Tkachenko): quaternion-increment equations at
every fix, Gauss–Newton, then generalised least squares with the noise of the recording;
``--drift`` also estimates a constant drift of the attitude reference (000's gyrostabilizer).

Output: a summary on stdout; ``--json`` the estimates, σ, covariance and observability report;
``--write-model`` the model (``--model``, else the defaults) with ``gyro_scale_factor``,
``gyro_misalignment`` (symmetric) and ``gyro_bias`` replaced by the estimates — the effect
parameters that ``sins_node`` and ``calibrator_node`` compensate (ρ = (I + M)⁻¹(ρ̃ − b·T)).  The
model's other effects (bias drift, scale asymmetry, camera time offset, ...) are compensated
before the estimation and kept.  Existing output files need ``--force``.

The fit is judged against its stated noise (camera covariance, gyro random walk): χ²/dof and its
two-sided band at level 0.01 (``chi2_per_dof_band``), ``fit_consistent``.  Outside the band a
line starting ``WARNING:`` goes to stderr and the summary says ``UNTRUSTED``; ``sigma`` is
``sigma_stated_noise`` scaled by √max(1, χ²/dof) (both methods); the exit status stays 0.

The work is :func:`strapdown_ros.runs.gyro.calibrate_gyro` (the call the fleet makes too); this
command checks the arguments, prints and writes.

Exit status: 0 estimated; 2, with one line on stderr, for bad arguments or an unusable bag or
model; 3 when the motion does not make the gyro errors observable (the combinations are named,
nothing is written but the JSON report), or when an estimate is beyond the range of its model key
(one line; the JSON report is written, the model is not).
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys
import time

import numpy as np

from strapdown_ros.cli import all_or_nothing, check_outputs, FILE, OneLineParser, write_json
from strapdown_ros.discrepancy.bag_input import recording_lines
from strapdown_ros.discrepancy.workflow import InputError
from strapdown_ros.params import load_model_file, write_model_file
from strapdown_ros.recording import (add_input_arguments, BagError, check_input_arguments,
                                     input_options)
from strapdown_ros.runs.gyro import calibrate_gyro, GyroOptions
from strapdown_ros.runs.gyro import gyro_record as result_json   # the JSON record (old name)
from strapdown_ros.runs.source import RecordingSource

__all__ = ['main', 'result_json']

PROG = 'calibrate_gyro_bag'
DEG_H = np.degrees(1.0) * 3600.0                 # rad/s → °/h


def _summary(bag, info, cal) -> str:
    lines = recording_lines(PROG, bag, info)
    lines[0] += f'; method {cal.method}'
    d = cal.extra
    chi2 = d.get('chi2_per_dof')
    band = d.get('chi2_per_dof_band')
    verdict = ''
    if d.get('fit_consistent') is not None and band is not None:
        verdict = (f", {'consistent' if d['fit_consistent'] else 'INCONSISTENT'}: "
                   f"band [{band[0]:.3g}, {band[1]:.3g}] at level {d['chi2_level']:g}")
    chi2_text = f", χ²/dof {chi2:.3g} (dof {d.get('dof')}{verdict})" if chi2 is not None else ''
    lines.append(f"  {'observable' if cal.observable else 'NOT observable'}{chi2_text}")
    if not cal.observable:
        return '\n'.join(lines)
    if d.get('fit_consistent') is False:
        lines.append('  UNTRUSTED: the fit is inconsistent with the stated noise (the WARNING)')
    for n, v, s in zip(cal.labels, cal.x, cal.sigma):
        if n.startswith(('bias', 'drift')):
            lines.append(f'  {n:8s} {v: .6e} rad/s ± {s:.2e}   '
                         f'({v * DEG_H: .5f} ± {s * DEG_H:.5f} °/h)')
        else:
            lines.append(f'  {n:8s} {v: .6e}       ± {s:.2e}   '
                         f'({v * 1e6: .2f} ± {s * 1e6:.2f} ppm)')
    if 'triad_rotation_rad' in d:
        r, s = np.asarray(d['triad_rotation_rad']), np.asarray(d['triad_rotation_sigma_rad'])
        lines.append('  triad rotation against the initial boresight (not written): '
                     + ', '.join(f'{a * 206264.806:.3g}″ ± {b * 206264.806:.2g}″' for a,
                                 b in zip(r, s)))
    if cal.observability.weak:
        lines.append(f"  weakly observable: {'; '.join(cal.observability.weak)}")
    return '\n'.join(lines)


def consistency_warning(out: dict) -> str | None:
    """
    Return the ``WARNING:`` line of an estimate whose χ²/dof is outside its band.

    Parameters
    ----------
    out : dict
        The JSON record (:func:`result_json`).

    Returns
    -------
    str or None
        The line; None when inside the band.

    """
    if out.get('fit_consistent') is not False or not out.get('observable'):
        return None
    chi2, (lo, hi), d = out['chi2_per_dof'], out['chi2_per_dof_band'], out['details']
    band = f"its {100 * (1 - d['chi2_level']):g}% band [{lo:.3g}, {hi:.3g}] (dof {d['dof']})"
    if chi2 > hi:
        return (f'WARNING: χ²/dof = {chi2:.3g} is above {band}: the stated noise (camera '
                'covariance, gyro random walk) is too small or the model lacks an effect; the σ '
                f'reported are scaled by √(χ²/dof) = {np.sqrt(chi2):.3g} (sigma_stated_noise in '
                'the JSON: unscaled).  Do not use the estimate as calibrated.')
    return (f'WARNING: χ²/dof = {chi2:.3g} is below {band}: the stated noise is too large (the '
            'σ reported, from the stated noise, are pessimistic; not scaled down).')


def _parse(argv):

    ap = OneLineParser(prog=PROG, description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('bag', help='rosbag2 bag directory, or a .mcap / .db3 file')
    ap.add_argument('--method', required=True, choices=('integral', 'tkachenko'),
                    help='002 integral method or 000 (Tkachenko) increment equations')
    ap.add_argument('--model', metavar='MODEL.yaml',
                    help='model: ROS 2 parameter file (default: the defaults)')
    ap.add_argument('--write-model', metavar='OUT.yaml',
                    help='write the model with the estimated gyro errors')
    ap.add_argument('--json', metavar='FILE', help='write the result as JSON')
    ap.add_argument('--force', action='store_true', help='overwrite existing output files')
    ap.add_argument('--drift', action='store_true',
                    help='tkachenko: also estimate a constant drift of the reference')
    ap.add_argument('--interval', type=float, metavar='S',
                    help='integral: averaging interval, s (default: one camera step)')
    ap.add_argument('--sigma-limit', type=float, default=1e-3, metavar='X',
                    help='a combination whose predicted σ exceeds X (scale units; biases in '
                         'RMS-rate units) '
                         'counts as unobservable (default 0.001)')
    ap.add_argument('--namespace', default='', help='topic namespace, e.g. /robot1')
    ap.add_argument('--quiet', action='store_true', help='no progress on stderr')
    add_input_arguments(ap)
    return ap.parse_args(argv)


def _options(args) -> GyroOptions:
    """Return the method and its options, as the library takes them."""
    return GyroOptions(args.method, args.interval, args.drift, args.sigma_limit)


def _check(args) -> None:
    """Check the arguments, input files and output paths, before any work."""
    check_input_arguments(args)
    _options(args).check()
    if not Path(args.bag).exists():
        raise ValueError(f'bag {args.bag} does not exist')
    if args.model and not Path(args.model).is_file():
        raise ValueError(f'model {args.model} does not exist')
    check_outputs([('--json', args.json, FILE), ('--write-model', args.write_model, FILE)],
                  [('bag', args.bag), ('--model', args.model)], args.force)


def main(argv=None) -> int:
    """
    Run the calibrate_gyro_bag command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status (0 success; 2 unusable arguments or input, one line on stderr; 3 not
        observable, or an estimate beyond its model key's range).

    """
    args = _parse(argv)
    t_start = time.perf_counter()

    def progress(text):
        if not args.quiet:
            print(f'{PROG}: [{time.perf_counter() - t_start:6.1f} s] {text}', file=sys.stderr,
                  flush=True)

    def fail(msg, status=2):
        print(f'{PROG}: error: {msg}', file=sys.stderr)
        return status

    try:
        _check(args)
        mf = load_model_file(args.model, 'calibrator_node')
        model, doc = mf.model, mf.doc
        for w in mf.warnings:
            print(f'{PROG}: warning: {w}', file=sys.stderr)
    except (ValueError, OSError) as exc:
        return fail(exc)
    if model.gyro.quantum > 0 and not args.quiet:
        print(f'{PROG}: warning: gyro_quantum > 0: pulse quantization (000 §5) is not '
              'modelled; the σ may be '
              f'optimistic', file=sys.stderr)
    source = RecordingSource(args.bag, args.namespace, **input_options(args))
    try:
        run = calibrate_gyro(source, model, _options(args), mf.settings, progress,
                             say=lambda text: print(f'{PROG}: {text}', file=sys.stderr),
                             who=PROG)
    except (BagError, InputError, ValueError, OSError, np.linalg.LinAlgError) as exc:
        return fail(str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
    cal, out = run.calibration, run.record
    print(_summary(args.bag, run.info, cal))
    warning = consistency_warning(out)
    if warning:
        print(warning, file=sys.stderr)
    found = run.found_model if cal.observable and args.write_model else None
    try:
        with all_or_nothing():                   # --json and --write-model, or neither
            if args.json:
                write_json(args.json, out)
            if found is not None:
                write_model_file(args.write_model, found,
                                 f'written by calibrate_gyro_bag --method {cal.method}: '
                                 'gyro_scale_factor, gyro_misalignment, '
                                 f'gyro_bias estimated from {Path(args.bag).name}', doc)
        if found is not None:
            print(f'  model with the estimated gyro errors: {args.write_model}')
    except OSError as exc:
        return fail(exc)
    if cal.observable and args.write_model and found is None:   # an estimate beyond a key's range
        return fail(f'--write-model {args.write_model} not written: {run.not_found}', 3)
    if not cal.observable:
        print(f'{PROG}: gyro errors NOT observable from this bag ({cal.method}): unobservable: '
              f"{'; '.join(cal.unobservable)}.  Record turns about three non-parallel axes, "
              'in both senses, '
              f'and rest periods; nothing was estimated', file=sys.stderr)
        return 3
    progress(f'done in {time.perf_counter() - t_start:.1f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
