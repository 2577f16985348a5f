"""
Run load_bench end to end, short: the graph loses nothing and the report is written.

The graph runs as separate processes, counts come from each node's own /diagnostics, and the
simulators' clocks are held until every consumer is matched, so nothing is lost to discovery
(the 10-minute run at 10× is a benchmark: doc/benchmarks.md).
"""
import json
import os
import subprocess
import sys

import pytest

pytest.importorskip('rclpy')
BIN = os.path.dirname(sys.executable)


def test_short_load_run_loses_nothing_and_reports(tmp_path):
    """A 12 s run loses no message and writes its report."""
    cmd = [os.path.join(BIN, 'load_bench'), '--seconds', '12', '--rate-factor', '1',
           '--warmup', '2', '--json', str(tmp_path / 'l.json'), '--report', str(tmp_path / 'r'),
           '--quiet']
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    assert p.returncode == 0, p.stderr
    d = json.load(open(tmp_path / 'l.json'))
    s = d['summary']
    rows = {(r['topic'], r['path']): r for r in s['loss']}
    # 12 s at 100 Hz / 300 Hz / one fix every 20 s: independent truth from the rates
    assert rows[('imu/delta_theta', 'imu_sim_node → sins_node')]['published'] == 1200
    assert rows[('imu/delta_velocity', 'imu_sim_node → sins_node')]['published'] == 3600
    assert all(r['lost'] == 0 for r in s['loss']), s['loss']
    assert s['loss_target_met'] and s['missing_in_nodes'] == {'sins_node': 0, 'calibrator_node': 0}
    assert rows[('sins/attitude', 'sins_node → monitor')]['published'] == 600  # algorithm 2: N = 2
    assert set(d['raw']['exit_codes_after_sigint'].values()) == {0}
    assert (tmp_path / 'r' / 'load_bench.png').stat().st_size > 10000
    assert 'Loss: 0 message(s) lost' in (tmp_path / 'r' / 'load_bench.md').read_text()
