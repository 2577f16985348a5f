"""
A recording for the discrepancy workflow, read from a rosbag2 bag.

:func:`load_recording` turns what :func:`strapdown_ros.recording.read_bag` reads into the
workflow's :class:`~strapdown_ros.discrepancy.linearisation.Recording` (stamps in seconds from a
common origin); :func:`recording_lines` prints what reading found.  Used by ``discrepancy``,
``calibrate_gyro_bag`` and ``realdata_report``.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.discrepancy.linearisation import Recording
from strapdown_ros.recording import (BagError, input_lines, input_summary, read_bag,
                                     recording_facts)
from strapdown_ros.recording.options import usable_error

__all__ = ['load_recording', 'recording_from_data', 'recording_lines']


def load_recording(bag: str, model, settings: dict | None = None, namespace: str = '',
                   **options):
    """
    Read a bag into the core's :class:`Recording`, with what reading it found.

    Parameters
    ----------
    bag : str
        Path of the rosbag2 bag.
    model : SensorModel
        The sensor model: the camera σ of fixes without a covariance, the gyro clip level.
    settings : dict, optional
        The stream rules (``max_stamp_jump``, ``resync_count``; defaults where absent).
    namespace : str
        Namespace of the topics.
    **options
        The input options of :func:`strapdown_ros.recording.read_bag` (``gyro_topic``,
        ``reference_topic``, ``reference_frames``, ``rate_rule``).

    Returns
    -------
    rec : Recording
        Stamps in seconds from a common origin, increments (rad), fixes and covariances.
    info : dict
        Drops, gaps, topics, the gyro rate from the stamps, the input formats.

    Raises
    ------
    BagError
        The bag cannot be read, or holds fewer than 10 usable gyro increments.
    ValueError
        An input option is invalid.

    """
    settings = settings or {}
    data = read_bag(bag, namespace, True, tuple(model.camera_sigma), model.gyro_max_rate,
                    float(settings.get('max_stamp_jump', 1.0)),
                    int(settings.get('resync_count', 5)), **options)
    return recording_from_data(data, bag)


def recording_from_data(data: dict, bag: str = 'the recording'):
    """
    Turn the streams :func:`strapdown_ros.recording.read_bag` read into the core's Recording.

    Parameters
    ----------
    data : dict
        The streams (read with the camera covariance where the messages carry one).
    bag : str
        The recording's name, for the error line.

    Returns
    -------
    rec : Recording
        As :func:`load_recording`.
    info : dict
        As :func:`load_recording`.

    Raises
    ------
    BagError
        Fewer than 10 usable gyro increments.

    """
    g, c = data['gyro'], data['camera']
    unusable = usable_error(data)                     # the tools' one wording
    if unusable:
        raise BagError(f'{bag}: {unusable}')
    if len(g.stamps) < 10:
        raise BagError(f"{bag}: {len(g.stamps)} usable gyro increments on {data['gyro_topic']}")
    origin = min(g.stamps[0], c.stamps[0]) if c.stamps else g.stamps[0]
    t_g = (np.asarray(g.stamps, dtype=np.int64) - origin) * 1e-9
    t_c = (np.asarray(c.stamps, dtype=np.int64) - origin) * 1e-9
    gaps = [((a - origin) * 1e-9, (b - origin) * 1e-9) for a, b in g.gaps]
    period = data['gyro_period_s']
    q = np.array([v[0] for v in c.values]).reshape(-1, 4)
    P = np.array([v[1] for v in c.values]).reshape(-1, 3, 3)
    rec = Recording(t_g, np.asarray(g.values, dtype=float), t_c, q, P, gaps)
    camera_dropped = {k: v for k, v in data['camera_fixes'].items()
                      if k in ('zero_quaternion', 'bad_covariance')}
    info = {'gyro_topic': data['gyro_topic'], 'camera_topic': data['camera_topic'],
            'camera_covariance_from_bag': data['camera_covariance_from_bag'],
            'gyro_messages': len(g.stamps), 'camera_fixes': len(c.stamps),
            'gyro_rate_from_stamps_hz': 1.0 / period if 0 < period < np.inf else None,
            'gyro_gaps': len(gaps), 'gyro_missing': g.missing,
            'stamp_resyncs': {'gyro': g.resyncs, 'camera': c.resyncs},
            'dropped': {'gyro': dict(g.dropped), 'camera': {**c.dropped, **camera_dropped}},
            'stamp_origin_ns': int(origin), 'duration_s': float(t_g[-1] - t_g[0])}
    info.update(input_summary(data))
    info['facts'] = recording_facts(data)
    if data['rate_samples']:
        info['dropped']['gyro_rate_samples'] = dict(data['rate_samples']['dropped'])
    return rec, info


def recording_lines(prog: str, bag, info: dict, counts: str = '') -> list[str]:
    """
    Return the first lines of a tool's summary: what :func:`load_recording` found.

    Parameters
    ----------
    prog : str
        Name of the tool, first word of the summary.
    bag : str or Path
        The bag read.
    info : dict
        What :func:`load_recording` found.
    counts : str
        More figures for the first line, e.g. "448 increment pairs, ".

    Returns
    -------
    list of str
        The lines.

    """
    lines = [f"{prog}: {bag}: {info['gyro_messages']} Δθ at "
             f"{info['gyro_rate_from_stamps_hz']:.6g} Hz (from the stamps), "
             f"{info['camera_fixes']} fixes, {counts}{info['duration_s']:.1f} s"]
    if info['gyro_gaps']:
        lines.append(f"  gyro gaps: {info['gyro_gaps']} ({info['gyro_missing']} increments "
                     'missing); pairs spanning them are not used')
    if 'gyro_input' in info:
        lines += input_lines(info)
    return lines
