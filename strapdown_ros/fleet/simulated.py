"""
Simulated fleets: units whose effects drift or jump between recordings, with the exact truth.

:func:`write_fleet` writes, for each :class:`SimulatedUnit`, its recordings (what
``record_sim`` writes: the simulator nodes' topics, header stamps at the recording's start
time) one ``days_apart`` after the other, a nominal model file per unit and the manifest CSV.
The simulators' random constants are off (their σ 0): a unit's gyro errors and boresight are
exactly the values given, plus the drift per day, plus the jumps from their recording on.  The
fleet tests and ``fleet_bench`` use it.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from datetime import timedelta, timezone
import json
from pathlib import Path

import numpy as np

from strapdown_ros.fleet.manifest import parse_time
from strapdown_ros.params import simulator_parameters
from strapdown_ros.recording.writer import record

__all__ = ['SimulatedUnit', 'write_fleet', 'unit_values', 'BORESIGHT', 'QUIET']

#: the bench scenario's boresight, rad
BORESIGHT = (0.698, -0.436, 2.094)
#: the simulators' random constants, off: the values given are the truth
QUIET = {'gyro_bias_sigma': 0.0, 'gyro_scale_sigma': 0.0, 'gyro_misalignment_sigma': 0.0}


@dataclass(frozen=True)
class SimulatedUnit:
    """
    One simulated unit.

    Attributes
    ----------
    name : str
        The unit's name.
    recordings : int
        Its recordings, ``days_apart`` apart.
    values : dict
        Simulator parameter → value at the first recording (``gyro_bias``,
        ``gyro_scale_factor``, ``gyro_misalignment``, ``boresight``, ...).
    drift_per_day : dict
        Parameter → change per day (same shape as the value).
    jumps : dict
        Recording index → {parameter: step added from that recording on}.

    """

    name: str
    recordings: int
    values: dict = field(default_factory=dict)
    drift_per_day: dict = field(default_factory=dict)
    jumps: dict = field(default_factory=dict)


def unit_values(unit: SimulatedUnit, k: int, days: float) -> dict:
    """
    Return the true parameter values of a unit's recording.

    Parameters
    ----------
    unit : SimulatedUnit
        The unit.
    k : int
        The recording's index.
    days : float
        Days since the unit's first recording.

    Returns
    -------
    dict
        Parameter → value (lists for vectors).

    """
    out = {'boresight': list(BORESIGHT)}
    out.update(unit.values)
    for p, rate in unit.drift_per_day.items():
        base = np.asarray(out.get(p, np.zeros_like(np.asarray(rate, dtype=float))), dtype=float)
        out[p] = base + np.asarray(rate, dtype=float) * days
    for j, steps in unit.jumps.items():
        if k >= j:
            for p, step in steps.items():
                base = np.asarray(out.get(p, np.zeros_like(np.asarray(step, dtype=float))),
                                  dtype=float)
                out[p] = base + np.asarray(step, dtype=float)
    return {p: np.asarray(v, dtype=float).tolist() if np.ndim(v) else float(v)
            for p, v in out.items()}


def write_fleet(folder, units, start: str = '2024-05-01T00:00:00Z', days_apart: float = 1.0,
                duration: float = 170.0, gyro_rate: float = 50.0, camera_interval: float = 2.0,
                seed: int = 0, model_values: dict | None = None) -> tuple[Path, list[dict]]:
    """
    Write a simulated fleet: the recordings, one model file per unit and the manifest.

    Parameters
    ----------
    folder : str or Path
        Created; holds ``UNIT/<start>`` bags, ``UNIT/model.yaml`` and ``manifest.csv``.
    units : list of SimulatedUnit
        The units.
    start : str
        ISO 8601 time of every unit's first recording.
    days_apart : float
        Days between a unit's recordings.
    duration : float
        Seconds per recording (the ``bench`` profile: 170 s is one pass).
    gyro_rate, camera_interval : float
        The gyro rate, Hz, and the camera interval, s.
    seed : int
        Seed of the first recording (each recording its own).
    model_values : dict, optional
        Model keys the units' model files state (default: none, the defaults).

    Returns
    -------
    manifest : Path
        The manifest CSV.
    truth : list of dict
        Per recording: ``unit``, ``recording``, ``start_time``, ``days``, ``values``.

    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    t0 = parse_time(start)
    rows, truth = ['unit,recording,start_time,model'], []
    n = 0
    for u in units:
        udir = folder / u.name
        udir.mkdir(exist_ok=True)
        model = udir / 'model.yaml'
        model.write_text(json.dumps({'/**': {'ros__parameters': dict(model_values or {})}}) + '\n',
                         encoding='utf-8')
        for k in range(u.recordings):
            days = k * days_apart
            t = t0 + timedelta(days=days)
            name = t.astimezone(timezone.utc).strftime('%Y%m%dT%H%M%SZ')
            values = unit_values(u, k, days)
            over = {'profile': 'bench', 'bench_repeat': 1, 'gyro_rate': gyro_rate,
                    'camera_interval': camera_interval, 'seed': seed + n,
                    'start_time': t.timestamp(), **QUIET, **values}
            imu_p, cam_p = simulator_parameters(overrides=over, duration=duration)
            record(udir / name, imu_p, cam_p, accel=False)
            rows.append(f'{u.name},{u.name}/{name},{t.isoformat()},{u.name}/model.yaml')
            truth.append({'unit': u.name, 'recording': f'{u.name}/{name}',
                          'start_time': t.isoformat(), 'days': days, 'values': values})
            n += 1
    manifest = folder / 'manifest.csv'
    manifest.write_text('\n'.join(rows) + '\n', encoding='utf-8')
    return manifest, truth
