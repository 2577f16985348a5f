"""
The fleet on a simulated fleet: three units, eight recordings, on a real Dask scheduler.

Truth is what the simulator injected (its random constants off): unit ``ramp``'s gyro bias x
grows by :data:`RAMP` rad/s per day, unit ``jump``'s boresight yaw steps by :data:`JUMP` rad from
its third recording on, unit ``stable`` changes nothing.  The main run goes through a
``dask scheduler`` and two ``dask worker`` processes started here on 127.0.0.1 with the
distributed package's own commands; a rerun analyses nothing; a corrupt recording is one error
row, analysed on an embedded LocalCluster.
"""
import csv
import json
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import time

import pytest

pytest.importorskip('distributed')
pytest.importorskip('pyarrow')
pytest.importorskip('rosbags')

from strapdown_ros.fleet.report import CHANGE_COLUMNS, EFFECT_COLUMNS  # noqa: E402
from strapdown_ros.fleet.simulated import SimulatedUnit, write_fleet  # noqa: E402
from strapdown_ros.tools import fleet  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
ARCSEC = 3.141592653589793 / 180.0 / 3600.0
RAMP = 1e-6                        # rad/s per day, gyro bias x of unit ramp
JUMP = 60.0 * ARCSEC               # rad, boresight yaw of unit jump from its recording 2 on
UNITS = [SimulatedUnit('ramp', 3, drift_per_day={'gyro_bias': [RAMP, 0.0, 0.0]}),
         SimulatedUnit('jump', 3, jumps={2: {'boresight': [JUMP, 0.0, 0.0]}}),
         SimulatedUnit('stable', 2)]
TIMEOUT = 90.0                     # s for the scheduler and the workers to come up


def _read(path):
    with open(path, newline='', encoding='utf-8') as fh:
        return list(csv.DictReader(fh))


def _dask_command():
    exe = Path(sys.executable).with_name('dask')
    return [str(exe)] if exe.exists() else [sys.executable, '-m', 'dask']


def _stop(procs):
    for p in reversed(procs):                       # only the processes started here
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGTERM)
    for p in reversed(procs):
        try:
            p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait(timeout=10)


def _start_cluster(d: Path):
    """Start ``dask scheduler`` and two ``dask worker`` on 127.0.0.1; return (address, procs)."""
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join(
        [str(REPO)] + [p for p in os.environ.get('PYTHONPATH', '').split(os.pathsep) if p])}
    sched_file = d / 'scheduler.json'
    log = open(d / 'dask.log', 'w')
    procs = [subprocess.Popen(_dask_command() + ['scheduler', '--host', '127.0.0.1', '--port',
                                                 '0', '--no-dashboard', '--scheduler-file',
                                                 str(sched_file)],
                              stdout=log, stderr=log, env=env, start_new_session=True)]
    try:
        t0 = time.monotonic()
        while not sched_file.exists() or not sched_file.read_text().strip():
            assert procs[0].poll() is None, (d / 'dask.log').read_text()
            assert time.monotonic() - t0 < TIMEOUT, 'the scheduler did not start'
            time.sleep(0.2)
        time.sleep(0.2)
        address = json.loads(sched_file.read_text())['address']
        for k in range(2):
            procs.append(subprocess.Popen(
                _dask_command() + ['worker', address, '--host', '127.0.0.1', '--nworkers', '1',
                                   '--nthreads', '1', '--memory-limit', '1GiB', '--no-dashboard',
                                   '--name', f'test-worker-{k}'],
                stdout=log, stderr=log, env=env, start_new_session=True))
        from distributed import Client
        with Client(address, timeout=TIMEOUT) as client:
            client.wait_for_workers(2, timeout=TIMEOUT)
        return address, procs
    except BaseException:
        _stop(procs)
        raise


@pytest.fixture(scope='module')
def simulated(tmp_path_factory):
    """Write the simulated fleet: the recordings, a model per unit, the manifest."""
    d = tmp_path_factory.mktemp('fleet')
    manifest, truth = write_fleet(d / 'units', UNITS, gyro_rate=20.0, camera_interval=2.0,
                                  duration=170.0, seed=100)
    return d, manifest, truth


@pytest.fixture(scope='module')
def main_run(simulated):
    """Run the fleet through a real scheduler with two workers; stop them afterwards."""
    d, manifest, _ = simulated
    out = d / 'out'
    address, procs = _start_cluster(d)
    try:
        rc = fleet.main([str(manifest), '--out', str(out), '--scheduler', address,
                         '--memory-limit', '1024', '--quiet'])
        worker_pids = {p.pid for p in procs[1:]}
    finally:
        _stop(procs)
    return rc, out, worker_pids


def test_every_recording_is_analysed_on_the_two_workers(main_run, simulated):
    rc, out, _ = main_run
    assert rc == 0
    recs = _read(out / 'recordings.csv')
    assert len(recs) == 8 and {r['status'] for r in recs} == {'ok'}
    assert {r['analysed'] for r in recs} == {'now'}
    pids = {json.loads(p.read_text())['worker']['pid'] for p in (out / 'cache').glob('*.json')}
    assert len(pids) == 2 and os.getpid() not in pids          # the two remote workers


def test_effects_table_has_the_columns_and_the_boresight(main_run, simulated):
    _, out, _ = main_run
    with open(out / 'effects.csv', newline='', encoding='utf-8') as fh:
        assert next(csv.reader(fh)) == list(EFFECT_COLUMNS)
    rows = _read(out / 'effects.csv')
    bore = [r for r in rows if r['effect'] == 'boresight']
    assert {r['parameter'] for r in bore} == {'boresight'}
    assert sorted({int(r['index']) for r in bore}) == [0, 1, 2]
    assert len(bore) == 24                                     # 8 recordings × ψ, ϑ, γ
    truth = {t['recording']: t['values']['boresight'] for t in simulated[2]}
    for r in bore:                                            # radians, against the truth
        assert abs(float(r['value']) - truth[r['recording']][int(r['index'])]) \
            <= 4 * float(r['sigma']), r
    import pyarrow.parquet as pq
    table = pq.read_table(out / 'effects.parquet')
    assert table.column_names == list(EFFECT_COLUMNS) and table.num_rows == len(rows)
    with open(out / 'changes.csv', newline='', encoding='utf-8') as fh:
        assert next(csv.reader(fh)) == list(CHANGE_COLUMNS)
    for name in ('summary.md', 'verdicts.png', 'trend_boresight.png', 'trend_gyro_bias.png',
                 'population_boresight.png', 'population.csv'):
        assert (out / name).stat().st_size > 0, name


def test_the_bias_ramp_is_a_trend_recovered_within_sigma(main_run):
    _, out, _ = main_run
    ch = [c for c in _read(out / 'changes.csv') if c['unit'] == 'ramp']
    trend = [c for c in ch if c['effect'] == 'gyro_bias' and c['index'] == '0']
    assert len(trend) == 1 and trend[0]['kind'] == 'trend', ch
    size, sigma = float(trend[0]['size']), float(trend[0]['sigma'])
    assert abs(size - RAMP) <= 3 * sigma and sigma < 0.2 * RAMP, (size, sigma)
    assert float(trend[0]['p_value']) <= 0.01


def test_the_boresight_jump_is_found_at_its_recording(main_run, simulated):
    _, out, _ = main_run
    third = sorted(t['recording'] for t in simulated[2] if t['unit'] == 'jump')[2]
    ch = [c for c in _read(out / 'changes.csv') if c['unit'] == 'jump']
    jump = [c for c in ch if c['effect'] == 'boresight' and c['index'] == '0']
    assert len(jump) == 1 and jump[0]['kind'] == 'jump' and jump[0]['recording'] == third, ch
    assert abs(float(jump[0]['size']) - JUMP) <= 4 * float(jump[0]['sigma'])


def test_the_stable_unit_raises_no_change(main_run):
    _, out, _ = main_run
    assert [c for c in _read(out / 'changes.csv') if c['unit'] == 'stable'] == []
    summary = (out / 'summary.md').read_text()
    assert 'unit ramp: gyro_bias[0] drifts by' in summary
    assert 'unit jump: boresight[0] jumps by' in summary


def test_a_rerun_analyses_nothing(main_run, simulated, capsys):
    _, out, _ = main_run
    before = {p.name: p.stat().st_mtime_ns for p in (out / 'cache').iterdir()}
    assert fleet.main([str(simulated[1]), '--out', str(out), '--quiet']) == 0
    assert '8 recording(s): 0 analysed, 8 from the cache' in capsys.readouterr().out
    assert json.loads((out / 'fleet.json').read_text())['analysed'] == 0
    assert {p.name: p.stat().st_mtime_ns for p in (out / 'cache').iterdir()} == before
    assert {r['analysed'] for r in _read(out / 'recordings.csv')} == {'cached'}


def test_a_corrupt_recording_is_one_error_row(main_run, simulated, capsys):
    _, out, _ = main_run
    d, manifest, truth = simulated
    good = d / 'units' / truth[0]['recording']
    bad = d / 'units' / 'broken' / '20240510T000000Z'
    shutil.copytree(good, bad)
    for f in bad.glob('*.mcap'):
        data = f.read_bytes()
        f.write_bytes(data[:len(data) // 3] + b'\x00garbage' * 64)
    m2 = d / 'units' / 'manifest_broken.csv'
    m2.write_text(manifest.read_text() + 'broken,broken/20240510T000000Z,2024-05-10T00:00:00Z,\n')
    assert fleet.main([str(m2), '--out', str(out), '--workers', '1', '--memory-limit', '1024',
                       '--quiet']) == 0
    assert '9 recording(s): 1 analysed, 8 from the cache, 1 error row(s)' \
        in capsys.readouterr().out
    recs = _read(out / 'recordings.csv')
    errors = [r for r in recs if r['status'] != 'ok']
    assert len(errors) == 1 and errors[0]['unit'] == 'broken' and errors[0]['reason']
    assert errors[0]['verdict'] == 'error'
    rows = [r for r in _read(out / 'effects.csv') if r['unit'] == 'broken']
    assert len(rows) == 1 and rows[0]['effect'] == 'error' and rows[0]['verdict'] == 'error'
    assert 'broken' in (out / 'summary.md').read_text()
    # the same bytes fail the same way: cached too, a rerun analyses nothing
    assert fleet.main([str(m2), '--out', str(out), '--quiet']) == 0
    assert '0 analysed, 9 from the cache' in capsys.readouterr().out


def test_memory_per_task_is_bounded_before_the_recording_is_read(simulated):
    """The estimate counts the topics read (not the truth topics); beyond the budget: refused."""
    from strapdown_ros.fleet.analysis import (analyse_recording, BASE_BYTES, BYTES_PER_MESSAGE,
                                              FleetOptions, memory_estimate)
    from strapdown_ros.fleet.manifest import read_manifest
    entry = read_manifest(simulated[1])[0][0]
    n, need = memory_estimate(entry.path)
    assert n == 170 * 20 + 85                       # Δθ at 20 Hz for 170 s + a fix every 2 s
    assert need == BASE_BYTES + BYTES_PER_MESSAGE * n
    r = analyse_recording(entry, FleetOptions(memory_mib=64))
    assert r['status'] == 'error' and r['stage'] == 'size' and 'MemoryError' in r['reason']
    assert 'messages' not in r                       # refused before it was read


def test_no_scheduler_at_the_address_is_one_line_and_writes_nothing(simulated, tmp_path,
                                                                    monkeypatch, capsys):
    from strapdown_ros.fleet import cluster
    monkeypatch.setattr(cluster, 'CONNECT_TIMEOUT_S', 2)
    out = tmp_path / 'out'
    assert fleet.main([str(simulated[1]), '--out', str(out), '--scheduler',
                       'tcp://127.0.0.1:9', '--quiet']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('fleet: error: cannot reach the Dask scheduler')
    assert not out.exists()
