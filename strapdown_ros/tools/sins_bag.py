"""
Run sins_node's numerical core on a rosbag2 recording, offline and without ROS.

    sins_bag BAG [--params FILE] [-p NAME:=VALUE ...] --output OUT [--force]
                 [--namespace NS] [--gyro-topic T] [--accel-topic T]
                 [--imu-topic T [--rate-rule trapezoid|mean]]

Reads ``imu/delta_theta`` (rad) and ``imu/delta_velocity`` (m/s), both
geometry_msgs/msg/Vector3Stamped stamped at the end of their intervals, from a bag directory or
a single .mcap/.db3 file, and runs them through the core of ``sins_node``
(:class:`strapdown_ros.sins.SinsSystem`: the same input rules, blocks, integrator, gyro-effect
compensation and navigation channel), so the solution is the node's on the same messages.
Topic names match with or without the leading slash, under ``--namespace`` when given; a bag
with a single namespace is found without it; ``--gyro-topic``/``--accel-topic`` name other
topics (absolute, or relative to the namespace).  ``--imu-topic`` (or a ``--gyro-topic`` of
that type) reads sensor_msgs/msg/Imu instead: angular_velocity and linear_acceleration are rate
samples, made into Δθ and Δv by ``--rate-rule`` as sins_node's ``gyro_input: imu`` does; a
message whose linear_acceleration_covariance[0] is −1 has no Δv.

Parameters are sins_node's: a ROS 2 parameter file (``--params``; the ``sins_node`` and ``/**``
blocks) and ``-p name:=value`` overrides, validated as the node validates them.  ``gyro_rate``
and ``accel_rate`` come from the stamps unless given with ``-p``; ``frame_id`` is the most
frequent non-empty header.frame_id of the Δθ messages unless the parameters name one (messages
in other frames are counted and rejected by the frame rule).  The navigation channel is off by
default, as in the node: ``-p navigation:=true`` with ``initial_position``,
``initial_velocity`` and ``initial_orientation`` (q_earth_body) or
``initial_alignment:=static``.

The library does the work: :mod:`strapdown_ros.recording.imu_streams` reads the streams whole,
:mod:`strapdown_ros.recording.sins_replay` feeds them to the core in large blocks (message by
message when a stream's stamps resynchronise) and writes the outputs.

Output, by the name of OUT:

* ``*.csv``: one row per navigation step (``navigation:=true``)::

      stamp_s, x, y, z, vx, vy, vz, qx, qy, qz, qw,
      sigma_x, sigma_y, sigma_z, sigma_vx, sigma_vy, sigma_vz,
      sigma_psi_x, sigma_psi_y, sigma_psi_z

  stamp_s: header stamp, s; position and velocity ECEF (``earth``, PZ-90), m and m/s;
  q_earth_body (ROS order x, y, z, w); the σ: square roots of the covariance diagonal of
  position, velocity and the attitude error ψ about the earth axes X, Y, Z (rad).  Without
  navigation, one row per attitude update: ``stamp_s, qx, qy, qz, qw, sigma_eps_x,
  sigma_eps_y, sigma_eps_z`` with q_ref_body and the σ of the attitude error ε about the body
  axes (rad).
* anything else: a rosbag2 bag directory (MCAP) with ``sins/attitude``
  (geometry_msgs/msg/QuaternionStamped), ``sins/imu`` (sensor_msgs/msg/Imu) and, with
  navigation, ``sins/odometry`` (nav_msgs/msg/Odometry), under the namespace of the input
  topics, with the content and frame ids sins_node publishes; bag time = header stamp.

OUT must not exist unless ``--force`` (which replaces a file, or a directory that is a rosbag2
bag).  Exit status: 0 solution written, 2 bad arguments/parameters/bag (one line on stderr,
before any work), 3 no solution (e.g. the static alignment never succeeded).
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys

import numpy as np

from strapdown_ros.cli import check_outputs, REPLACED
from strapdown_ros.earth import geodetic_to_ecef
from strapdown_ros.params import (check_against_recording, load_model_file, not_applied_note,
                                  parse_overrides)
from strapdown_ros.recording import BagError
from strapdown_ros.recording.imu_streams import ACCEL_TOPIC, GYRO_TOPIC, open_input
from strapdown_ros.recording.sins_replay import CsvOutput, McapOutput, run
from strapdown_ros.sins import odometry_arrays, SinsSettings, SinsSystem
from strapdown_ros.streams.rate_increments import RATE_RULES
from strapdown_ros.text import bounded

__all__ = ['main']


def _check_output(out: str, bag: str, force: bool, params: str | None = None) -> None:
    """
    Check that OUT can be written (the tools' one output rule).

    :func:`~strapdown_ros.cli.check_outputs`: not an input, absent unless --force, its directory
    takes a write; a directory is replaced only when it is a rosbag2 bag or empty.
    """
    check_outputs([('--output', out, REPLACED)], [('bag', bag), ('--params', params)], force)
    p = Path(out)
    not_a_bag = (not (p / 'metadata.yaml').exists()) and any(p.iterdir()) if p.is_dir() else False
    if p.is_dir() and (out.lower().endswith('.csv') or not_a_bag):
        raise ValueError(f'--output {out} is a directory that is not a rosbag2 bag; '
                         'not replacing it')


def _recording_model(mf, settings: SinsSettings, inp, say):
    """
    Return the sensor model with the recording's rates and body frame, and the rates.

    A rate or frame the model states must agree with the recording
    (:func:`~strapdown_ros.params.check_against_recording`: an error naming both otherwise);
    one it does not state is taken from the recording: ``gyro_rate``/``accel_rate`` from the
    stamps, ``frame_id`` from the Δθ headers.
    """
    model = mf.model
    frames = [f for f, _ in inp.gyro.frames() if f]
    model = check_against_recording(model, {'gyro_rate_hz': inp.gyro_rate,
                                            'gyro_frames': frames})
    if inp.imu_input and inp.accel is None and 'accel_rate' not in model.stated:
        inp.accel_rate = model.gyro_rate            # Δv from the same Imu messages
    if inp.accel_rate and 'accel_rate' not in model.stated:
        model = model.with_values({'accel_rate': float(inp.accel_rate)},
                                  rule='the median step of the accelerometer stamps')
    rates = {'gyro_rate': model.gyro_rate, 'accel_rate': model.accel_rate}
    for name in ('gyro_rate', 'accel_rate'):
        if name not in mf.model.stated and getattr(mf.model, name) != rates[name]:
            say(f'note: {name} {rates[name]:g} Hz from the stamps')
    # the body frame: the recording's own, unless the model states one
    if 'frame_id' not in model.stated and inp.frame_id and inp.frame_id != model.frame_id:
        model = model.with_values({'frame_id': inp.frame_id},
                                  rule="the recording's Δθ headers")
        say(f"note: frame_id {bounded(inp.frame_id)!r} from the recording's headers "
            '(-p frame_id:=... to impose one)')
    others = [(f, c) for f, c in inp.gyro.frames() if f and f != model.frame_id]
    if others:
        total = len(inp.gyro)
        kind = 'Imu' if inp.imu_input else 'Δθ'
        listed = ', '.join(f'{bounded(f)!r} ({c})' for f, c in others[:3])
        say(f'note: {sum(c for _, c in others)} of {total} {kind} message(s) '
            'name another frame than the body frame and are rejected by the frame rule: '
            + listed + (', …' if len(others) > 3 else ''))
    if settings.navigation:
        pos = settings.navigation_settings.initial_position
        lat, lon, h = (float(x) for x in pos)
        r = float(np.linalg.norm(geodetic_to_ecef(np.radians(lat), np.radians(lon), h)))
        if not 6.0e6 < r < 8.0e6:
            raise ValueError(f'initial_position {list(pos)} is not within '
                             "±1000 km of the Earth's surface")
    return model, rates


def _summary(args, inp, system: SinsSystem, sink, counts: dict, rates: dict) -> str:
    """Return the summary printed after a run: inputs, drops, warnings, updates, output."""
    st = system.status()
    g, a = system.gyro_check, system.accel_check
    g_topic = bounded(inp.gyro_conn.topic)
    a_topic = bounded(inp.accel_conn.topic) if inp.accel_conn is not None else ''
    if inp.accel_conn is None:
        tail = ', no Δv'
    elif inp.imu_input and inp.accel is None:
        tail = f", {counts['accel']} with linear acceleration"
    else:
        tail = f", {counts['accel']} Δv from {a_topic}"
    if inp.imu_input:
        head = (f"sins_bag: {args.bag}: {counts['gyro']} sensor_msgs/Imu from {g_topic} "
                f'(rates → increments, rule {args.rate_rule})')
    else:
        head = f"sins_bag: {args.bag}: {counts['gyro']} Δθ from {g_topic}"
    lines = [head + tail + f"; gyro_rate {rates['gyro_rate']:g} Hz, "
             f"accel_rate {rates['accel_rate']:g} Hz"]
    checks = [g, a] + list(system.rate_checks.values())
    drops = {k: sum(getattr(c, attr) for c in checks)
             for k, attr in (('NaN', 'nan'), ('out of range', 'out_of_range'),
                             ('out of order', 'out_of_order'), ('duplicate', 'duplicate'),
                             ('stamp outlier', 'stamp_outliers'))}
    drops = {k: v for k, v in drops.items() if v}
    wrong = sum(getattr(inp, 'wrong_type', {}).values())
    if wrong:
        drops['wrong type'] = wrong
    fm = system.frame_mismatch
    if fm['gyro'] or fm['accel']:
        how = 'rejected' if system.reject_frames else 'used'
        drops[f'frame mismatch ({how})'] = fm['gyro'] + fm['accel']
    dropped = ', '.join(f'{k} {v}' for k, v in drops.items()) if drops else 'none'
    lines.append('  dropped: ' + dropped)
    if g.missing or g.resyncs:
        lines.append(f'  GYRO: {g.missing} increment(s) missing in {g.gaps} gap(s), '
                     f'{g.resyncs} stamp resync(s): the rotation during them is lost')
    if system.nonfinite:
        lines.append(f'  {system.nonfinite} non-finite update(s) discarded')
    stall = system.accel_stall(a_topic or 'imu/delta_velocity')   # sins_node's /diagnostics rule
    if stall is not None:
        lines.append(f"  WARNING: {stall.text}; sins_node's /diagnostics: {stall.level.upper()}")
    line = (f"  {st['updates']} attitude updates ({st['coning_algorithm']}, "
            f"{st['samples_per_update']} samples/update)")
    if system.nav is not None:
        line += f"; navigation {st['navigation_state']}, {st.get('navigation_steps', 0)} steps"
        if st.get('navigation_steps_accel_extrapolated'):
            line += f" ({st['navigation_steps_accel_extrapolated']} with Δv extrapolated)"
        if 'alignment' in st:
            line += f"; alignment: {st['alignment']}"
    if stall is not None:
        line += f'; accel stall {stall.seconds:.3g} s'
    lines.append(line)
    lines.append(f'  wrote {sink.summary()}')
    return '\n'.join(lines)


def _no_solution(system: SinsSystem) -> str | None:
    """Return why there is no solution (no update, no navigation step), or None."""
    nav = system.nav
    no_steps = nav is not None and (nav.navigator is None or nav.navigator.steps == 0)
    if system.integrator.updates and not no_steps:
        return None
    if nav is not None and nav.navigator is None:
        refused = nav.alignment is not None and not nav.alignment.ok
        why = ('the static alignment did not complete (alignment_time '
               f'{float(system.settings.navigation_settings.alignment_time):g} s'
               + (f'; last refusal: {nav.alignment.reason}' if refused else '') + ')')
    elif system.integrator.updates == 0:
        why = 'no attitude update'
    else:
        why = 'no navigation step'
    if system.integrator.updates == 0 and system.frame_mismatch['gyro'] \
            and system.gyro_check.accepted == 0:
        why = ('every Δθ was rejected: its header.frame_id is not frame_id '
               f'{bounded(system.model.frame_id)!r} '
               '(-p frame_id:=... or -p frame_mismatch:=accept)')
    return why


def _arguments() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog='sins_bag', description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('bag', help='rosbag2 bag directory, or a .mcap / .db3 file')
    ap.add_argument('--output', '-o', required=True, metavar='OUT',
                    help='OUT.csv: the solution as CSV; otherwise an MCAP bag directory with '
                         'sins/* topics')
    ap.add_argument('--params', metavar='FILE',
                    help='the sensor model and settings: a ROS 2 parameter YAML (its model keys, '
                         'and the settings of /** and sins_node)')
    ap.add_argument('-p', '--param', action='append', default=[], metavar='NAME:=VALUE',
                    help='sins_node parameter override (repeatable), as ros2 run -p')
    ap.add_argument('--namespace', default='', help='topic namespace, e.g. /robot1')
    ap.add_argument('--gyro-topic', metavar='TOPIC', help=f'Δθ topic (default {GYRO_TOPIC})')
    ap.add_argument('--accel-topic', metavar='TOPIC', help=f'Δv topic (default {ACCEL_TOPIC})')
    ap.add_argument('--imu-topic', metavar='TOPIC',
                    help='a sensor_msgs/msg/Imu topic giving both Δθ (angular_velocity) and Δv '
                         '(linear_acceleration) by --rate-rule')
    ap.add_argument('--rate-rule', choices=RATE_RULES, default='trapezoid',
                    help='how an Imu rate sample becomes an increment '
                         '(strapdown_ros.streams.rate_increments; default trapezoid)')
    ap.add_argument('--force', action='store_true', help='replace OUT if it exists')
    ap.add_argument('--quiet', action='store_true', help='no progress lines')
    return ap


def main(argv=None) -> int:
    """
    Run the sins_bag command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status: 0 solution written, 2 bad arguments, parameters or bag, 3 no solution,
        130 interrupted.

    """
    args = _arguments().parse_args(argv)

    def err(text: str) -> int:
        print(f'sins_bag: error: {text}', file=sys.stderr)
        return 2

    def say(text: str) -> None:
        if not args.quiet:
            print(f'sins_bag: {text}', file=sys.stderr, flush=True)

    def reading(ns, t0, t1):
        span = max(t1 - t0, 1) * 1e-9
        say(f'reading: {(ns - t0) * 1e-9:.1f} / {span:.1f} s of the recording')

    csv_out = args.output.lower().endswith('.csv')
    inp = None
    try:
        over = parse_overrides(args.param)
        mf = load_model_file(args.params, 'sins_node', over)   # checked before the bag
        for w in mf.warnings:
            say(f'warning: {w}')
        settings = SinsSettings.from_values(mf.settings)
        _check_output(args.output, args.bag, args.force, args.params)
        if args.imu_topic and (args.gyro_topic or args.accel_topic):
            raise ValueError('--imu-topic gives both streams: '
                             'not with --gyro-topic/--accel-topic')
        inp = open_input(args.bag, args.namespace, args.gyro_topic, args.accel_topic,
                         need_accel=bool(settings.navigation), imu_topic=args.imu_topic,
                         progress=reading)
        model, rates = _recording_model(mf, settings, inp, say)
        note = not_applied_note(model, ('gyro', 'accel'), 'sins_bag')
        if note:
            say(f'note: {note}')

        def make_system():
            return SinsSystem(model, settings,
                              log=lambda level, text: say(text if level == 'info'
                                                          else f'{level}: {text}'),
                              imu_wanted=(lambda: not csv_out))
        system = make_system()                          # parameters checked by the core now
    except (ValueError, OSError, BagError) as exc:
        if inp is not None:
            inp.close()
        return err(str(exc))
    try:
        if csv_out:
            sink = CsvOutput(Path(args.output), system.nav is not None)
        else:
            sink = McapOutput(Path(args.output), system, inp.namespace, odometry_arrays)
    except Exception as exc:                           # the writer's own refusal
        inp.close()
        return err(f'cannot write {args.output}: {exc}')
    ok = False
    try:
        counts, system = run(inp, make_system, sink, say, args.rate_rule, system)
        ok = True
    except BagError as exc:
        return err(str(exc))
    except (KeyboardInterrupt, BrokenPipeError):
        return 130
    finally:
        inp.close()
        sink.close(ok)
    print(_summary(args, inp, system, sink, counts, rates))
    why = _no_solution(system)
    if why is not None:
        print(f'sins_bag: no solution: {why}', file=sys.stderr)
        return 3
    return 0


if __name__ == '__main__':
    sys.exit(main())
