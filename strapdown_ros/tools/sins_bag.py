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
message whose linear_acceleration_covariance[0] is −1 has no Δv.  A bag with neither Δθ topic
nor topic options but exactly one sensor_msgs/msg/Imu topic (a driver's recording) is read from
that topic.

Parameters are sins_node's: a ROS 2 parameter file (``--params``; the ``sins_node`` and ``/**``
blocks) and ``-p name:=value`` overrides, validated as the node validates them.  ``gyro_rate``
and ``accel_rate`` come from the stamps unless given with ``-p``; ``frame_id`` is the most
frequent non-empty header.frame_id of the Δθ messages unless the parameters name one (messages
in other frames are counted and rejected by the frame rule).  The navigation channel is off by
default, as in the node: ``-p navigation:=true`` with ``initial_position``,
``initial_velocity`` and ``initial_orientation`` (q_earth_body) or
``initial_alignment:=static``.

The library does the work: :func:`strapdown_ros.runs.sins.run_sins` (the call the fleet makes
too) reads the streams whole (:mod:`strapdown_ros.recording.imu_streams`), takes from the
recording what the model does not state, and has :mod:`strapdown_ros.recording.sins_replay` feed
them to the core in large blocks (message by message when a stream's stamps resynchronise) and
write the outputs; this command checks the arguments, prints and picks the writer.

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

from strapdown_ros.cli import check_outputs, REPLACED
from strapdown_ros.params import load_model_file, parse_overrides
from strapdown_ros.recording import BagError
from strapdown_ros.recording.imu_streams import ACCEL_TOPIC, GYRO_TOPIC
from strapdown_ros.recording.sins_replay import CsvOutput, McapOutput
from strapdown_ros.runs.sins import run_sins, SinkError, SinsRun
from strapdown_ros.runs.source import RecordingSource
from strapdown_ros.sins import odometry_arrays, SinsSettings
from strapdown_ros.streams.rate_increments import RATE_RULES

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


def _summary(bag: str, run: SinsRun) -> str:
    """Return the summary printed after a run: inputs, drops, warnings, updates, output."""
    st, counts, rates = run.status, run.counts, run.rates
    if not run.accel_topic:
        tail = ', no Δv'
    elif run.accel_from_imu:
        tail = f", {counts['accel']} with linear acceleration"
    else:
        tail = f", {counts['accel']} Δv from {run.accel_topic}"
    if run.imu_input:
        head = (f"sins_bag: {bag}: {counts['gyro']} sensor_msgs/Imu from {run.gyro_topic} "
                f'(rates → increments, rule {run.rate_rule})')
    else:
        head = f"sins_bag: {bag}: {counts['gyro']} Δθ from {run.gyro_topic}"
    lines = [head + tail + f"; gyro_rate {rates['gyro_rate']:g} Hz, "
             f"accel_rate {rates['accel_rate']:g} Hz"]
    dropped = ', '.join(f'{k} {v}' for k, v in run.drops.items()) if run.drops else 'none'
    lines.append('  dropped: ' + dropped)
    g = run.gyro
    if g['missing'] or g['resyncs']:
        lines.append(f"  GYRO: {g['missing']} increment(s) missing in {g['gaps']} gap(s), "
                     f"{g['resyncs']} stamp resync(s): the rotation during them is lost")
    if run.nonfinite:
        lines.append(f'  {run.nonfinite} non-finite update(s) discarded')
    stall = run.stall                               # sins_node's /diagnostics rule
    if stall is not None:
        lines.append(f"  WARNING: {stall['text']}; sins_node's /diagnostics: "
                     f"{stall['level'].upper()}")
    line = (f"  {st['updates']} attitude updates ({st['coning_algorithm']}, "
            f"{st['samples_per_update']} samples/update)")
    if run.navigation:
        line += f"; navigation {st['navigation_state']}, {st.get('navigation_steps', 0)} steps"
        if st.get('navigation_steps_accel_extrapolated'):
            line += f" ({st['navigation_steps_accel_extrapolated']} with Δv extrapolated)"
        if 'alignment' in st:
            line += f"; alignment: {st['alignment']}"
    if stall is not None:
        line += f"; accel stall {stall['seconds']:.3g} s"
    lines.append(line)
    lines.append(f'  wrote {run.output}')
    return '\n'.join(lines)


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

    out = Path(args.output)
    csv_out = args.output.lower().endswith('.csv')

    def make_sink(system, namespace):
        if csv_out:
            return CsvOutput(out, system.nav is not None)
        return McapOutput(out, system, namespace, odometry_arrays)

    try:
        over = parse_overrides(args.param)
        mf = load_model_file(args.params, 'sins_node', over)   # checked before the bag
        for w in mf.warnings:
            say(f'warning: {w}')
        settings = SinsSettings.from_values(mf.settings)
        _check_output(args.output, args.bag, args.force, args.params)
        source = RecordingSource(args.bag, args.namespace, args.gyro_topic,
                                 rate_rule=args.rate_rule, accel_topic=args.accel_topic,
                                 imu_topic=args.imu_topic)
        run = run_sins(source, mf.model, settings, make_sink, say, reading,
                       imu_output=not csv_out, who='sins_bag')
    except SinkError as exc:                           # the writer's own refusal
        return err(f'cannot write {args.output}: {exc}')
    except (ValueError, OSError, BagError) as exc:
        return err(str(exc))
    except (KeyboardInterrupt, BrokenPipeError):       # the old output stays as it was
        return 130
    print(_summary(args.bag, run))
    if run.no_solution is not None:
        print(f'sins_bag: no solution: {run.no_solution}', file=sys.stderr)
        return 3
    return 0


if __name__ == '__main__':
    sys.exit(main())
