"""
filter_bag: argument errors, and a run on a recorded simulation.

Argument errors are one line with exit 2; the simulation's gyro bias is injected (independent
truth).
"""
import subprocess
import sys

import numpy as np
import pytest


PY = [sys.executable, '-m']


def _run(*args, cwd):
    return subprocess.run(PY + list(args), cwd=cwd, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    """Record a simulation with an injected gyro bias."""
    d = tmp_path_factory.mktemp('fbag')
    # the simulated unit and the filter's model in two files (a model key has one value a file)
    (d / 'sim.yaml').write_text(
        'imu_sim_node:\n  ros__parameters:\n    gyro_rate: 100.0\n'
        '    gyro_bias_sigma: 0.0\n    gyro_scale_sigma: 0.0\n    gyro_misalignment_sigma: 0.0\n'
        '    gyro_bias: [2.0e-6, -1.0e-6, 1.5e-6]\n'
        'star_camera_sim_node:\n  ros__parameters:\n    camera_interval: 1.0\n')
    (d / 'p.yaml').write_text(
        'attitude_filter_node:\n  ros__parameters:\n    gyro_rate: 100.0\n'
        '    gyro_bias_sigma: 1.0e-5\n    output_period: 1.0\n')
    r = _run('strapdown_ros.tools.record_sim', 'b', '--duration', '120', '--no-accel',
             '--params', 'sim.yaml', '-p', 'profile:=coning', cwd=d)
    assert r.returncode == 0, r.stderr
    return d


def test_filter_bag_estimates_the_injected_bias(bag):
    r = _run('strapdown_ros.tools.filter_bag', 'b', '--output', 'o.csv', '--params', 'p.yaml',
             '--force', cwd=bag)
    assert r.returncode == 0, r.stderr
    rows = np.genfromtxt(bag / 'o.csv', delimiter=',', names=True)
    last = rows[-1]
    b = np.array([last['bias_x'], last['bias_y'], last['bias_z']])
    s = np.array([last['bias_sigma_x'], last['bias_sigma_y'], last['bias_sigma_z']])
    assert np.all(np.abs(b - [2e-6, -1e-6, 1.5e-6]) < 3 * s), (b, s)
    assert np.all(s < 3e-7)
    fixes = (bag / 'o_fixes.csv').read_text().splitlines()
    assert len(fixes) > 100 and sum(',applied,' in f for f in fixes) > 100


@pytest.mark.parametrize('args,text', [
    (['missing_bag', '--output', 'x.csv'], 'does not exist'),
    (['b', '--output', 'b/x.csv'], 'would overwrite the input'),
    (['b', '--output', 'p.yaml', '--params', 'p.yaml'], 'would overwrite the input'),
    (['b'], '--output'),
])
def test_filter_bag_argument_errors_are_one_line_exit_2(bag, args, text):
    r = _run('strapdown_ros.tools.filter_bag', *args, cwd=bag)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and text in r.stderr, r.stderr
