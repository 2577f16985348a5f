"""
filter_bag: argument errors, and a run on a recorded simulation.

Argument errors are one line with exit 2; the simulation's gyro bias is injected (independent
truth).
"""
import json
import subprocess
import sys

import numpy as np
import pytest

from strapdown_ros.bench.hostile_input import (clean_recording, kind_named, streams_with,
                                               write_bag)
from strapdown_ros.tools import filter_bag


PY = [sys.executable, '-m']


def _run(*args, cwd):
    return subprocess.run(PY + list(args), cwd=cwd, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    """Record a simulation with an injected gyro bias."""
    d = tmp_path_factory.mktemp('fbag')
    # a model file holds one unit's model: the simulator's (no errors drawn) and the filter's
    # (a bias prior) are two files
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


@pytest.fixture(scope='module')
def hostile(tmp_path_factory):
    """Give a directory with a clean short bag and a model with its boresight."""
    from strapdown_ros.bench.hostile_input import BETA

    d = tmp_path_factory.mktemp('fhostile')
    rec = clean_recording()
    write_bag(d / 'clean', rec, accel=False)
    (d / 'm.yaml').write_text('/**:\n  ros__parameters:\n    gyro_bias_sigma: 1.0e-4\n'
                              '    output_period: 1.0\n    boresight: ['
                              + ', '.join(repr(float(b)) for b in BETA) + ']\n')
    return d, rec


def _filter(d, bag, *extra):
    return filter_bag.main([str(d / bag), '--output', str(d / 'o.csv'), '--params',
                            str(d / 'm.yaml'), '--force', *extra])


def test_filter_bag_prints_and_writes_what_it_read_and_dropped(hostile, capsys):
    """
    Issue 27, findings 5 and 9: the summary every tool prints, a singular covariance counted.

    A NaN fix, a singular covariance, a duplicate stamp and a stray frame: each is named in the
    printout and in --json under input.read, in the words and keys of every tool; an empty
    reference topic is one line and exit 2, not "0 outputs" and exit 0.
    """
    d, rec = hostile
    for name in ('nan', 'singular_covariance', 'duplicate_stamp', 'stray_frame'):
        kind = kind_named(f'reference:{name}')
        write_bag(d / name, streams_with(rec, kind, 12), accel=False)
        assert _filter(d, name, '--json', str(d / 'r.json')) == 0
        out = capsys.readouterr().out
        read = json.loads((d / 'r.json').read_text())['input']['read']
        line = next(x for x in out.splitlines() if x.startswith('  reference: '))
        if name == 'stray_frame':
            assert read['frames']['reference'] == {'gcrs': len(rec.reference) - 1,
                                                   'stray_frame': 1}
            assert "'stray_frame' 1" in out
            continue
        reason = {'nan': 'nan', 'singular_covariance': 'bad_covariance',
                  'duplicate_stamp': 'duplicate'}[name]
        assert read['reference']['dropped'] == {reason: 1}, read
        assert f'{len(rec.reference)} of {len(rec.reference) + 1} fixes kept; dropped ' \
            f"{reason.replace('_', ' ')} 1" in line, line
        if name == 'singular_covariance':
            assert read['reference']['bad_covariance'] == {'not_positive_definite': 1}
    write_bag(d / 'empty', streams_with(rec, kind_named('reference:empty_topic'), 0),
              accel=False)
    assert _filter(d, 'empty') == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'no usable reference fixes on /star_camera/' in err[0], err


def test_filter_bag_writes_its_outputs_all_or_nothing(hostile, monkeypatch, capsys):
    """
    Issue 27, findings 12, 13: a failed second write leaves both old outputs; a long name.

    OUT, FIXES and --json go to temporaries and are renamed together: a disk that fills while
    FIXES is written leaves OUT as it was and no temporary.  An OUT whose derived FIXES name
    the file system cannot hold is one line, exit 2, before any work.
    """
    d, _ = hostile
    assert _filter(d, 'clean') == 0
    before = {p.name: p.read_bytes() for p in d.iterdir() if p.is_file()}
    real = filter_bag.write_text

    def full_disk(path, text):
        if str(path).endswith('_fixes.csv'):
            raise OSError(28, f'cannot write {path}: No space left on device')
        real(path, text)
    monkeypatch.setattr(filter_bag, 'write_text', full_disk)
    assert _filter(d, 'clean') == 2
    assert 'No space left' in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in d.iterdir() if p.is_file()} == before
    monkeypatch.setattr(filter_bag, 'write_text', real)
    long = 'o' * 250 + '.csv'                     # FIXES: 250 + len('_fixes.csv') > 255 bytes
    capsys.readouterr()
    assert filter_bag.main([str(d / 'clean'), '--output', str(d / long), '--params',
                            str(d / 'm.yaml')]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and '--fixes' in err[0] and 'longer than the file system allows' \
        in err[0], err
    assert not any(len(p.name) > 200 for p in d.iterdir())
