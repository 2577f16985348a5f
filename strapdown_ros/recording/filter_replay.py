"""
The attitude filter over a whole recording: what ``filter_bag`` runs, in the order a node sees.

No printing; the command prints and writes.  The same core as ``attitude_filter_node``
(:class:`~strapdown_ros.estimation.filter_system.FilterSystem`).
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.estimation.filter_system import FilterSettings, FilterSystem
from strapdown_ros.sensors.sensor_model import SensorModel
from strapdown_ros.streams.checks import gap_ends, match_segments, segments

__all__ = ['run_filter']


def run_filter(data: dict, model: SensorModel, settings: FilterSettings | None = None
               ) -> FilterSystem:
    """
    Run the filter over the streams of a recording.

    Fixes are given after the increments up to their stamps: the order a node sees live.  Each
    stream is split into its time bases (a confirmed clock step starts one) and they are matched
    in order (:func:`strapdown_ros.streams.checks.match_segments`); the reader's gaps restart the
    filter as the node's check does.

    Parameters
    ----------
    data : dict
        The streams of :func:`strapdown_ros.recording.reader.read_bag`.
    model : SensorModel
        The unit's sensor model.
    settings : FilterSettings, optional
        The filter's settings (default: the defaults).

    Returns
    -------
    FilterSystem
        The filter after the recording, its outputs and fix results kept.

    """
    system = FilterSystem(model, settings)
    g, c = data['gyro'], data['camera']
    if not len(g.stamps) or not len(c.stamps):
        return system
    gt = np.asarray(g.stamps, dtype=np.int64).reshape(-1)
    gv = np.asarray(g.values, dtype=float).reshape(-1, 3)
    ct = np.asarray(c.stamps, dtype=np.int64)
    screened = bool(getattr(c, 'screened', False))    # the reader's fixes: screened once
    if hasattr(g, 'gaps'):
        breaks = {b for _, b in g.gaps}                # the reader's gaps and jumps (rule 6)
    else:                                              # streams without them: the same rule
        breaks = gap_ends(g.stamps, model.gyro_period)
    breaks = np.fromiter(breaks, np.int64)             # arrays: taken whole by the filter
    g_segs = segments(g.stamps, getattr(getattr(g, 'check', None), 'segment_starts', []))
    c_segs = segments(c.stamps, getattr(getattr(c, 'check', None), 'segment_starts', []))
    cur_g = cur_c = None
    k = end = 0                                        # increments fed; end of segment cur_g
    for i, j in match_segments(gt, g_segs, ct, c_segs):
        (ga, gb), (ca, cb) = g_segs[i], c_segs[j]
        if cur_g != i:
            if k < end:
                system.add_increments(gt[k:end], gv[k:end], breaks)
            cur_g, k, end = i, ga, gb
        if cur_c is not None and cur_c != j:
            system.resync_fixes()                      # the fixes' clock stepped
        cur_c = j
        for n in range(ca, cb):
            ns = int(ct[n])
            jj = ga + int(np.searchsorted(gt[ga:gb], ns, side='right'))
            if jj > k:
                system.add_increments(gt[k:jj], gv[k:jj], breaks)
                k = jj
            q, P = c.values[n]
            system.add_fix(ns, np.asarray(q, dtype=float), np.asarray(P, dtype=float),
                           screened=screened)
    if k < end:
        system.add_increments(gt[k:end], gv[k:end], breaks)
    system.process()
    return system
