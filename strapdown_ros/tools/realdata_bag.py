"""realdata_bag: one RepoIMU trial (IMU + Vicon CSV) as a rosbag2 bag, without ROS.

    realdata_bag TRIAL.csv BAG [--gyro-format imu|delta_theta|both]
                 [--reference-format pose|quaternion|both] [--reference-interval S]
                 [--start S] [--end S] [--storage mcap|sqlite3]

Topics and frames: :mod:`strapdown_ros.realdata` (``imu/data`` sensor_msgs/Imu and
``mocap/pose`` PoseStamped; ``imu/delta_theta`` Vector3Stamped and ``star_camera/attitude``
QuaternionStamped, the package's own).  The data set's stamps are kept; the reference is
decimated to one fix per ``--reference-interval`` s (default 1).  Exit 2 with one line on
stderr for unusable input or an existing BAG.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..realdata import GYRO_FORMATS, REFERENCE_FORMATS, read_repoimu_csv, write_bag
from .paths import OneLineParser

__all__ = ["main"]


def main(argv=None) -> int:
    ap = OneLineParser(prog="realdata_bag", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("trial", help="RepoIMU trial CSV")
    ap.add_argument("bag", help="output bag directory (must not exist)")
    ap.add_argument("--gyro-format", choices=tuple(GYRO_FORMATS), default="imu")
    ap.add_argument("--reference-format", choices=tuple(REFERENCE_FORMATS), default="pose")
    ap.add_argument("--reference-interval", type=float, default=1.0, metavar="S",
                    help="time between reference fixes written, s (default 1)")
    ap.add_argument("--start", type=float, default=0.0, metavar="S", help="excerpt start, s")
    ap.add_argument("--end", type=float, default=float("inf"), metavar="S", help="excerpt end, s")
    ap.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    args = ap.parse_args(argv)
    from rosbags.rosbag2 import WriterError

    try:
        if not Path(args.trial).is_file():
            raise ValueError(f"trial {args.trial} does not exist")
        if Path(args.bag).exists():
            raise ValueError(f"bag {args.bag} exists")
        if not args.reference_interval > 0:
            raise ValueError("--reference-interval must be > 0")
        trial = read_repoimu_csv(args.trial)
        if args.start > 0 or args.end < float("inf"):
            trial = trial.excerpt(args.start, min(args.end, trial.duration_s + 1.0))
        s = write_bag(args.bag, trial, args.gyro_format, args.reference_format,
                      args.reference_interval, args.storage)
    except (ValueError, OSError, WriterError) as exc:
        print(f"realdata_bag: error: {exc}", file=sys.stderr)
        return 2
    topics = ", ".join(f"{t} {n}" for t, n in s["messages"].items())
    print(f"realdata_bag: {s['bag']}: {trial.name}, {s['duration_s']:.1f} s, gyro "
          f"{s['gyro_rate_hz']:.6g} Hz (from the stamps); {topics}; frames: IMU "
          f"{s['frames']['imu']!r}, reference {s['frames']['reference']!r} (orientation of "
          f"{s['frames']['marker']!r} in it)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
