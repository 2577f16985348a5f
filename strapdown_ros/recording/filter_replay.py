"""
The attitude filter over a whole recording: what ``filter_bag`` runs, in the order a node sees.

No printing; the command prints and writes.  The same core as ``attitude_filter_node``
(:class:`~strapdown_ros.estimation.filter_system.FilterSystem`).
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.estimation.filter_system import FilterSettings, FilterSystem
from strapdown_ros.sensors.sensor_model import SensorModel

__all__ = ['run_filter']


def run_filter(data: dict, model: SensorModel, settings: FilterSettings | None = None
               ) -> FilterSystem:
    """
    Run the filter over the streams of a recording.

    Fixes are given after the increments up to their stamps: the order a node sees live.

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
    gt = np.asarray(g.stamps, dtype=np.int64).reshape(-1)
    gv = np.asarray(g.values, dtype=float).reshape(-1, 3)
    k = 0
    for ns, (q, P) in zip(c.stamps, c.values):
        j = int(np.searchsorted(gt, ns, side='right'))
        if j > k:
            system.add_increments(gt[k:j], gv[k:j])
            k = j
        system.add_fix(int(ns), np.asarray(q, dtype=float), np.asarray(P, dtype=float))
    system.add_increments(gt[k:], gv[k:])
    system.process()
    return system
