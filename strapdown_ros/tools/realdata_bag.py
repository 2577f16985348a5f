"""
realdata_bag: one RepoIMU trial (IMU + Vicon CSV) as a rosbag2 bag, without ROS.

    realdata_bag TRIAL.csv BAG [--gyro-format imu|delta_theta|both]
                 [--reference-format pose|quaternion|both] [--reference-interval S]
                 [--start S] [--end S] [--storage mcap|sqlite3]

Topics and frames: :mod:`strapdown_ros.recording.repoimu` (``imu/data`` sensor_msgs/Imu and
``mocap/pose`` PoseStamped; ``imu/delta_theta`` Vector3Stamped and ``star_camera/attitude``
QuaternionStamped, the package's own).  The data set's stamps are kept; the reference is
decimated to one fix per ``--reference-interval`` s (default 1).  Exit 2 with one line on
stderr for unusable input or an existing BAG.
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys

from strapdown_ros.cli import check_outputs, OneLineParser, REPLACED
from strapdown_ros.files import commit_directory, discard_directory, stage_directory
from strapdown_ros.recording.repoimu import (GYRO_FORMATS, read_repoimu_csv, REFERENCE_FORMATS,
                                             write_bag)

__all__ = ['main']


def main(argv=None) -> int:
    """
    Run the realdata_bag command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status (0 success; 2 unusable arguments or input, one line on stderr).

    """
    ap = OneLineParser(prog='realdata_bag', description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('trial', help='RepoIMU trial CSV')
    ap.add_argument('bag', help='output bag directory (must not exist unless --force)')
    ap.add_argument('--force', action='store_true', help='replace an existing output bag')
    ap.add_argument('--gyro-format', choices=tuple(GYRO_FORMATS), default='imu')
    ap.add_argument('--reference-format', choices=tuple(REFERENCE_FORMATS), default='pose')
    ap.add_argument('--reference-interval', type=float, default=1.0, metavar='S',
                    help='time between reference fixes written, s (default 1)')
    ap.add_argument('--start', type=float, default=0.0, metavar='S', help='excerpt start, s')
    ap.add_argument('--end', type=float, default=float('inf'), metavar='S', help='excerpt end, s')
    ap.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap')
    args = ap.parse_args(argv)
    from rosbags.rosbag2 import WriterError

    try:
        if not Path(args.trial).is_file():
            raise ValueError(f'trial {args.trial} does not exist')
        check_outputs([('bag', args.bag, REPLACED)], [('trial', args.trial)], args.force)
        if Path(args.bag).is_dir() and not (Path(args.bag) / 'metadata.yaml').exists() \
                and any(Path(args.bag).iterdir()):
            raise ValueError(f'bag {args.bag} is a directory that is not a rosbag2 bag; '
                             'not replacing it')
        if not args.reference_interval > 0:
            raise ValueError('--reference-interval must be > 0')
    except (ValueError, OSError) as exc:
        print(f'realdata_bag: error: {exc}', file=sys.stderr)
        return 2
    staged = None              # written beside the target, renamed into place when complete
    try:
        trial = read_repoimu_csv(args.trial)
        if args.start > 0 or args.end < float('inf'):
            trial = trial.excerpt(args.start, min(args.end, trial.duration_s + 1.0))
        staged = stage_directory(args.bag)
        s = write_bag(staged, trial, args.gyro_format, args.reference_format,
                      args.reference_interval, args.storage)
        commit_directory(staged, args.bag)
        staged = None
        s['bag'] = str(args.bag)
    except (ValueError, OSError, WriterError) as exc:
        print(f'realdata_bag: error: {exc}', file=sys.stderr)
        return 2
    finally:
        if staged is not None:
            discard_directory(staged)
    topics = ', '.join(f'{t} {n}' for t, n in s['messages'].items())
    print(f"realdata_bag: {s['bag']}: {trial.name}, {s['duration_s']:.1f} s, gyro "
          f"{s['gyro_rate_hz']:.6g} Hz (from the stamps); {topics}; frames: IMU "
          f"{s['frames']['imu']!r}, reference {s['frames']['reference']!r} (orientation of "
          f"{s['frames']['marker']!r} in it)")
    return 0


if __name__ == '__main__':
    sys.exit(main())
