"""
record_sim: write the simulator topics to a rosbag2 bag, without ROS.

The bag holds exactly what ``imu_sim_node`` + ``star_camera_sim_node`` publish for the same
parameters (same core models, same seeds, same stamps):

* ``/imu/delta_theta``       geometry_msgs/msg/Vector3Stamped, rad, frame ``frame_id``
* ``/imu/delta_velocity``    geometry_msgs/msg/Vector3Stamped, m/s (``--no-accel`` skips it)
* ``/imu/truth/attitude``    geometry_msgs/msg/QuaternionStamped, exact q_ref_body, frame
                             ``reference_frame_id``
* ``/star_camera/attitude``  geometry_msgs/msg/QuaternionStamped, measured q_GCRS_VF, frame
                             ``reference_frame_id``
* ``/star_camera/attitude_with_covariance``  geometry_msgs/msg/PoseWithCovarianceStamped: the
                             same attitude; covariance rows/cols 3..5 = camera covariance (rad², VF
                             axes), position unknown (diagonal 1e9)
* ``/star_camera/truth/boresight``  geometry_msgs/msg/QuaternionStamped, once at the camera's
                             ``start_time``: the true q_MF_VF, frame ``camera_frame_id``

The offered QoS recorded for each topic is the publisher's (stream QoS for the IMU topics,
reliable for the camera, reliable + transient-local for the boresight truth), so that
``ros2 bag play`` offers the same.

Stamps: ``start_time`` + profile time (ns, each increment stamped at the end of its interval);
the bag time of every message is its header stamp.  Parameters: a ROS 2 parameter YAML (the
``imu_sim_node`` and ``star_camera_sim_node`` blocks, ``/**`` included) plus ``-p name:=value``
overrides, validated as the nodes validate them.  Defaults: profile ``bench``, navigation-grade
gyro (004 §6), camera every 20 s with 0.6″/0.6″/6″ noise.

No rclpy and no message packages: messages are built and serialised with ``rosbags``.
The output bag must not exist unless ``--force`` (which replaces a rosbag2 bag or an empty
directory, never anything else), nor be an input (``--params``, ``profile_file``).
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys

import numpy as np

from strapdown_ros.cli import check_outputs, OneLineParser, REPLACED
from strapdown_ros.files import commit_directory, discard_directory, stage_directory
from strapdown_ros.params import parse_overrides, PROFILE_PARAMS, simulator_parameters
from strapdown_ros.recording.writer import record

__all__ = ['main']


def main(argv=None) -> int:
    """
    Run the record_sim command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status (0 success; 2 unusable arguments or input, one line on stderr).

    """
    ap = OneLineParser(prog='record_sim', description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('bag', help='output bag directory (must not exist unless --force)')
    ap.add_argument('--force', action='store_true', help='replace an existing output bag')
    ap.add_argument('--params', metavar='FILE',
                    help='ROS 2 parameter YAML (imu_sim_node, star_camera_sim_node, /**)')
    ap.add_argument('--duration', type=float, metavar='S',
                    help="simulated seconds (default: the parameter 'duration', "
                         '0 = the profile length)')
    ap.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap',
                    help='rosbag2 storage (default mcap)')
    ap.add_argument('--no-accel', action='store_true', help='do not record imu/delta_velocity')
    ap.add_argument('--namespace', default='', help='topic namespace, e.g. /robot1')
    ap.add_argument('-p', '--param', action='append', default=[], metavar='NAME:=VALUE',
                    help='parameter override (repeatable), as ros2 run -p')
    args = ap.parse_args(argv)
    from rosbags.rosbag2 import WriterError

    try:
        imu_p, cam_p = simulator_parameters(args.params, parse_overrides(args.param),
                                            args.duration)
        if any(imu_p[s.name] != cam_p[s.name] for s in PROFILE_PARAMS):
            print('record_sim: warning: imu_sim_node and star_camera_sim_node have different '
                  'profile parameters; each uses its own, as the nodes would', file=sys.stderr)
        stale = check_outputs([('bag', args.bag, REPLACED)],
                              [('--params', args.params),
                               ('profile_file', imu_p.get('profile_file'))], args.force)
        for path in stale:                 # a staging an earlier, killed run left
            print(f'record_sim: note: removed {path}, a temporary an earlier run left',
                  file=sys.stderr)
        out = Path(args.bag)
        if out.is_dir() and not out.is_symlink():
            if not (out / 'metadata.yaml').exists() and any(out.iterdir()):
                raise ValueError(f'bag {args.bag} is a directory that is not a rosbag2 bag; '
                                 'not replacing it')
        elif out.exists() or out.is_symlink():
            raise ValueError(f'bag {args.bag} is not a directory; not replacing it')
    except (ValueError, OSError) as exc:
        print(f'record_sim: error: {exc}', file=sys.stderr)
        return 2
    # the bag is written into a hidden sibling and renamed into place when complete: a failure
    # or an interruption leaves no half bag and the old bag (--force) as it was
    staged = None
    try:
        staged = stage_directory(args.bag)
        summary = record(staged, imu_p, cam_p, storage=args.storage, accel=not args.no_accel,
                         namespace=args.namespace)
        commit_directory(staged, args.bag)
        staged = None
        summary['bag'] = str(args.bag)
    # WriterError: the bag exists already, ...
    except (ValueError, OSError, WriterError) as exc:
        print(f'record_sim: error: {exc}', file=sys.stderr)
        return 2
    finally:
        if staged is not None:
            discard_directory(staged)
    beta = np.asarray(summary['boresight_rad'])
    topics = ', '.join(f'{t} {n}' for t, n in summary['messages'].items())
    print(f"record_sim: {summary['bag']} ({summary['storage']}, {summary['duration_s']:g} s): "
          f'{topics}; '
          f"true boresight β = ({', '.join(f'{np.degrees(b):.6g}' for b in beta)})° "
          f"q_mf_vf_xyzw = [{', '.join(f'{c:.9f}' for c in summary['q_mf_vf_xyzw'])}]")
    return 0


if __name__ == '__main__':
    sys.exit(main())
