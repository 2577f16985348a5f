"""
The real-data excerpt shipped in ``test/data/gaitmap/``: gaitmap's example recording as bags.

The example data of gaitmap (Küderle et al., 2024; MIT licence; see ``test/data/gaitmap/``),
read from the package's source distribution ``gaitmap-2.6.0.tar.gz`` as published on PyPI (the
archive itself or its extracted directory):

* ``example_data/imu_sample_not_rotated.csv``: a foot-worn IMU on each shoe, raw sensor axes,
  204.8 Hz.  Two header rows (``sensor``: ``left_sensor``/``right_sensor``; ``axis``:
  ``acc_x`` … ``gyr_z``), column 0 the sample index; acceleration in m/s², angular rate in °/s.
* ``example_data/mocap_sample.csv``: three markers per shoe from an optical motion-capture
  system, ``TOE``, ``FCC`` (heel) and ``FM5`` (fifth metatarsal head), x, y, z in mm, 100 Hz,
  column 0 the sample index.  Row 0 of both files is the same instant.

Frames (stated once):

* ``imu_frame`` (``gaitmap_<foot>_imu``): the IMU's sensor axes.
* ``reference_frame`` (``gaitmap_mocap``): the motion-capture world frame.
* ``marker_frame`` (``gaitmap_<foot>_foot``): the shoe frame built from the three markers,
  fwd = unit(TOE − FCC), n = unit(fwd × (FM5 − FCC)), side = n × fwd; C = [fwd side n]
  (columns, mocap coordinates) is C_mocap_foot, so the pose orientation is q_mocap_foot and the
  position the markers' centroid, m.  The markers sit on a flexing shoe, not rigidly on the
  IMU: the rotation between ``imu_frame`` and ``marker_frame`` (the boresight the tools
  estimate) is fixed only approximately.

Stamps: one clock for both streams, ``stamp_origin_ns`` + index / rate (IMU: the exact
1e9/204.8 ns = 4 882 812.5 ns period rounded half up to whole ns; mocap 10 ms).  The bags are
written as a driver records them (:func:`strapdown_ros.recording.repoimu.write_bag`):
``/imu/data`` sensor_msgs/Imu and ``/mocap/pose`` PoseStamped at the full motion-capture rate,
MCAP with zstd chunk compression.  The command is ``gaitmap_bag``.
"""
from __future__ import annotations

from pathlib import Path
import tarfile

import numpy as np

from strapdown_ros.recording.repoimu import ImuTrial, write_bag
from strapdown_ros.rotation import dcm_to_quat

__all__ = ['read_sdist', 'read_gaitmap_example', 'foot_frame', 'mit_licence_text',
           'write_excerpt', 'FEET', 'IMU_FILE', 'MOCAP_FILE', 'IMU_RATE_HZ', 'MOCAP_RATE_HZ',
           'STAMP_ORIGIN_NS', 'REFERENCE_FRAME', 'SDIST_VERSION']

#: the gaitmap release the excerpt is made from
SDIST_VERSION = '2.6.0'
IMU_FILE = 'example_data/imu_sample_not_rotated.csv'
MOCAP_FILE = 'example_data/mocap_sample.csv'
IMU_RATE_HZ = 204.8
MOCAP_RATE_HZ = 100.0
#: stamp of row 0 of both files, ns (2020-09-13T12:26:40.123456789Z: a realistic epoch with a
#: non-zero fraction of a second)
STAMP_ORIGIN_NS = 1_600_000_000_123_456_789
REFERENCE_FRAME = 'gaitmap_mocap'
#: foot -> (sensor name in the IMU file, marker prefix in the mocap file)
FEET = {'left': ('left_sensor', 'L'), 'right': ('right_sensor', 'R')}
_NS = 1_000_000_000


def read_sdist(sdist) -> dict:
    """
    Read the files the excerpt is made from out of gaitmap's source distribution.

    Parameters
    ----------
    sdist : str or Path
        ``gaitmap-<version>.tar.gz``, or the directory it extracts to.

    Returns
    -------
    dict
        ``imu``, ``mocap``, ``licence``, ``pkg_info``: the texts of :data:`IMU_FILE`,
        :data:`MOCAP_FILE`, ``LICENSE`` and ``PKG-INFO``; ``version`` from ``PKG-INFO``.

    Raises
    ------
    ValueError
        The path is neither such an archive nor such a directory, or a file is missing.

    """
    p = Path(sdist)
    names = {'imu': IMU_FILE, 'mocap': MOCAP_FILE, 'licence': 'LICENSE', 'pkg_info': 'PKG-INFO'}
    out = {}
    if p.is_dir():
        for key, name in names.items():
            if not (p / name).is_file():
                raise ValueError(f'{p}: no {name} (not an extracted gaitmap sdist)')
            out[key] = (p / name).read_text(encoding='utf-8')
    elif p.is_file() and tarfile.is_tarfile(p):
        with tarfile.open(p) as tar:
            members = {}
            for m in tar.getmembers():
                parts = m.name.split('/', 1)
                if m.isfile() and len(parts) == 2:
                    members.setdefault(parts[1], m)
            for key, name in names.items():
                if name not in members:
                    raise ValueError(f'{p}: no {name} in the archive (not a gaitmap sdist)')
                out[key] = tar.extractfile(members[name]).read().decode('utf-8')
    else:
        raise ValueError(f'{p}: neither a gaitmap sdist (.tar.gz) nor its extracted directory')
    version = [ln.split(':', 1)[1].strip() for ln in out['pkg_info'].splitlines()
               if ln.startswith('Version:')]
    out['version'] = version[0] if version else None
    return out


def mit_licence_text(licence: str) -> str:
    """
    Return the MIT section of gaitmap's ``LICENSE``, verbatim.

    The file holds two licences: AGPL-3 for the ``gaitmap_mad`` folder and MIT for everything
    else (the example data included).  The MIT section runs from its ``MIT License`` line to the
    end of the file.

    Parameters
    ----------
    licence : str
        The text of ``LICENSE``.

    Returns
    -------
    str
        From the ``MIT License`` line to the end.

    Raises
    ------
    ValueError
        No ``MIT License`` line, or the section does not say it covers all other files.

    """
    lines = licence.splitlines(keepends=True)
    start = next((i for i, ln in enumerate(lines) if ln.strip() == 'MIT License'), None)
    if start is None:
        raise ValueError('LICENSE has no "MIT License" section')
    text = ''.join(lines[start:])
    if 'all other files' not in text or 'Permission is hereby granted' not in text:
        raise ValueError('the MIT section of LICENSE does not cover the other files')
    return text


def _table(text: str, what: str):
    """Split a CSV with two header rows into (first header, second header, values)."""
    lines = text.splitlines()
    if len(lines) < 4:
        raise ValueError(f'{what}: fewer than two header rows and two data rows')
    h1 = [c.strip() for c in lines[0].split(',')]
    h2 = [c.strip() for c in lines[1].split(',')]
    data = np.array([[float(c) if c.strip() else np.nan for c in ln.split(',')]
                     for ln in lines[2:] if ln.strip()])
    if data.ndim != 2 or data.shape[1] != len(h1) or len(h2) != len(h1):
        raise ValueError(f'{what}: rows and header rows differ in length')
    return h1, h2, data


def _columns(h1, h2, group: str, axes, what: str) -> list:
    cols = []
    for ax in axes:
        k = [i for i in range(len(h1)) if h1[i] == group and h2[i] == ax]
        if len(k) != 1:
            raise ValueError(f'{what}: no single column {group} {ax}')
        cols.append(k[0])
    return cols


def foot_frame(toe, heel, fm5):
    """
    Orientation and position of the shoe frame from its three markers.

    fwd = unit(toe − heel), n = unit(fwd × (fm5 − heel)), side = n × fwd; C = [fwd side n]
    (columns) maps foot coordinates to mocap coordinates.

    Parameters
    ----------
    toe, heel, fm5 : array_like, shape (n, 3)
        Marker positions, any one length unit.

    Returns
    -------
    q : ndarray, shape (n, 4)
        q_mocap_foot, scalar first; rows with a missing or degenerate marker (NaN, or the three
        markers on one line) are NaN.
    centroid : ndarray, shape (n, 3)
        Mean of the three markers, same unit.

    """
    toe, heel, fm5 = (np.asarray(a, dtype=float) for a in (toe, heel, fm5))
    fwd = toe - heel
    n = np.cross(fwd, fm5 - heel)
    lf, ln = np.linalg.norm(fwd, axis=1), np.linalg.norm(n, axis=1)
    scale = np.linalg.norm(fm5 - heel, axis=1) * lf
    ok = np.isfinite(lf) & np.isfinite(ln) & (lf > 0) & (ln > 1e-6 * scale)
    q = np.full((len(toe), 4), np.nan)
    if ok.any():
        f = fwd[ok] / lf[ok, None]
        u = n[ok] / ln[ok, None]
        c = np.stack([f, np.cross(u, f), u], axis=2)          # columns fwd, side, n
        q[ok] = dcm_to_quat(c)
    return q, (toe + heel + fm5) / 3.0


def _imu_stamps(index, origin_ns: int) -> np.ndarray:
    # index · 1e9/204.8 ns = index · 9 765 625 / 2 ns, rounded half up, in integers
    k = np.asarray(index).astype(np.int64)
    return origin_ns + (k * 9_765_625 + 1) // 2


def read_gaitmap_example(files: dict, foot: str = 'left',
                         stamp_origin_ns: int = STAMP_ORIGIN_NS) -> tuple[ImuTrial, dict]:
    """
    One foot of gaitmap's example recording as an :class:`ImuTrial`.

    Parameters
    ----------
    files : dict
        From :func:`read_sdist`.
    foot : {'left', 'right'}
        Which shoe.
    stamp_origin_ns : int
        Stamp of row 0 of both files, ns.

    Returns
    -------
    trial : ImuTrial
        Rates in rad/s, accelerations in m/s², q_mocap_foot, the markers' centroid in m.
    counts : dict
        ``imu_rows``, ``mocap_rows``, ``mocap_dropped`` (rows with a missing or degenerate
        marker, left out of the reference).

    Raises
    ------
    ValueError
        Unknown foot, or a file without the expected columns.

    """
    if foot not in FEET:
        raise ValueError(f"foot={foot!r}; valid: {', '.join(FEET)}")
    sensor, prefix = FEET[foot]
    h1, h2, imu = _table(files['imu'], IMU_FILE)
    acc = imu[:, _columns(h1, h2, sensor, ('acc_x', 'acc_y', 'acc_z'), IMU_FILE)]
    gyr = imu[:, _columns(h1, h2, sensor, ('gyr_x', 'gyr_y', 'gyr_z'), IMU_FILE)]
    ok = np.all(np.isfinite(acc), axis=1) & np.all(np.isfinite(gyr), axis=1)
    m1, m2, mocap = _table(files['mocap'], MOCAP_FILE)
    xyz = ('x', 'y', 'z')
    markers = {k: mocap[:, _columns(m1, m2, f'{prefix}_{k}', xyz, MOCAP_FILE)]
               for k in ('TOE', 'FCC', 'FM5')}
    q, centroid_mm = foot_frame(markers['TOE'], markers['FCC'], markers['FM5'])
    good = np.all(np.isfinite(q), axis=1)
    ref_ns = stamp_origin_ns + mocap[:, 0].astype(np.int64) * (_NS // int(MOCAP_RATE_HZ))
    trial = ImuTrial(
        name=f'gaitmap_{foot}', stamps_ns=_imu_stamps(imu[ok, 0], stamp_origin_ns),
        gyro=np.radians(gyr[ok]), accel=acc[ok], reference_stamps_ns=ref_ns[good],
        q_reference_marker=q[good], imu_frame=f'gaitmap_{foot}_imu',
        reference_frame=REFERENCE_FRAME, marker_frame=f'gaitmap_{foot}_foot',
        reference_positions_m=centroid_mm[good] * 1e-3)
    return trial, {'imu_rows': int(len(imu)), 'imu_dropped': int((~ok).sum()),
                   'mocap_rows': int(len(mocap)), 'mocap_dropped': int((~good).sum())}


def write_excerpt(files: dict, out_dir, feet=('left', 'right'), compression: str = 'zstd',
                  stamp_origin_ns: int = STAMP_ORIGIN_NS, bag_paths: dict | None = None) -> dict:
    """
    Write one bag per foot (``gaitmap_<foot>``) into ``out_dir``.

    Parameters
    ----------
    files : dict
        From :func:`read_sdist`.
    out_dir : str or Path
        Directory the bags go into (exists).
    feet : sequence of str
        Keys of :data:`FEET`.
    compression : {'zstd', 'none'}
        MCAP chunk compression.
    stamp_origin_ns : int
        Stamp of row 0, ns.
    bag_paths : dict, optional
        foot -> where to write that bag instead of ``out_dir/gaitmap_<foot>`` (a staging path);
        the path reported stays ``out_dir/gaitmap_<foot>``.

    Returns
    -------
    dict
        foot -> the summary of :func:`strapdown_ros.recording.repoimu.write_bag` plus the
        counts of :func:`read_gaitmap_example`.

    """
    out = {}
    for foot in feet:
        trial, counts = read_gaitmap_example(files, foot, stamp_origin_ns)
        final = Path(out_dir) / trial.name
        target = (bag_paths or {}).get(foot, final)
        s = write_bag(target, trial, gyro_format='imu', reference_format='pose',
                      reference_interval_s=None, storage='mcap', compression=compression)
        s.update(counts, bag=str(final))
        out[foot] = s
    return out
