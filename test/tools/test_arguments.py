"""Bad files and arguments are refused before any work, in one line, exit 2."""
import hashlib
import json
import os
import subprocess
import sys
import time

import pytest

from strapdown_ros.cli import write_json
from strapdown_ros.tools import record_sim


BIN = os.path.dirname(sys.executable)


def _one_line_exit_2(cmd, timeout=60):
    t0 = time.monotonic()
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    # (rcl logs its own "[ERROR] [rcl]: Failed to parse global arguments" from C: not ours)
    lines = [ln for ln in (p.stdout + p.stderr).splitlines()
             if ln.strip() and '[INFO]' not in ln and '[rcl]' not in ln]
    assert p.returncode == 2, (cmd, p.returncode, p.stdout, p.stderr)
    assert len(lines) == 1 and 'Traceback' not in lines[0] and 'error' in lines[0], lines
    return lines[0], time.monotonic() - t0


@pytest.mark.parametrize('args, needle', [
    (['-p', 'profile:=piecewise', '-p', 'profile_file:=/nonexistent/p.yaml'], 'No such file'),
    (['-p', 'profile:=piecewise', '-p', 'profile_file:={bad}'], 'not valid YAML'),
    (['-p', 'profile:=piecewise', '-p', 'profile_file:={shape}'], 'segments'),
    (['-p', 'gravity:=[1.0, 2.0]'], 'gravity'),
    (['--params-file', '{bad}'], 'params file'),
])
def test_node_refuses_bad_files_and_parameters(tmp_path, args, needle):
    pytest.importorskip('rclpy')
    (tmp_path / 'bad.yaml').write_text('segments: [1, 2')
    (tmp_path / 'shape.yaml').write_text('segments: {duration: 1}')
    args = [a.format(bad=tmp_path / 'bad.yaml', shape=tmp_path / 'shape.yaml') for a in args]
    line, _ = _one_line_exit_2([os.path.join(BIN, 'imu_sim_node'), '--ros-args', *args])
    assert needle in line, line


def test_tools_check_arguments_before_work(tmp_path):
    (tmp_path / 'bad.yaml').write_text('segments: [1, 2')
    for cmd, needle in (
            ([os.path.join(BIN, 'record_sim'), str(tmp_path / 'b'), '--params',
              str(tmp_path / 'bad.yaml')], 'YAML'),
            ([os.path.join(BIN, 'coning_bench'), '--json', '/nonexistent/x.json'], '/nonexistent'),
            ([os.path.join(BIN, 'coning_bench'), '--duration', '5'], 'cone period'),
            ([os.path.join(BIN, 'reproduce_seeds'), '--report', '/nonexistent/x.md'],
             '/nonexistent'),
            ([os.path.join(BIN, 'reproduce_seeds'), '--runs', '0'], '--runs'),
            ([os.path.join(BIN, 'load_bench'), '--seconds', '5'], '--seconds'),
            ([os.path.join(BIN, 'load_bench'), '--report', '/nonexistent/d/e'], '/nonexistent'),
            ([os.path.join(BIN, 'load_bench'), '--rate-factor', '100'], '--rate-factor'),
            ([os.path.join(BIN, 'node_rate_bench'), '--algorithm', 'rk4'], 'rk4'),
            ([os.path.join(BIN, 'sins_bench'), '--runs', '0'], '--runs'),
            ([os.path.join(BIN, 'sins_bench'), '--json', '/nonexistent/s.json'], '/nonexistent'),
            ([os.path.join(BIN, 'node_rate_bench'), '--lo', '5000', '--hi', '100'], '--lo')):
        line, took = _one_line_exit_2(cmd)
        # refused before minutes of work
        assert needle in line and took < 20.0, (cmd, line, took)


def test_corrupted_mcap_is_one_line_exit_2(tmp_path):
    pytest.importorskip('rosbags')
    bag = tmp_path / 'bag'
    assert record_sim.main([str(bag), '--no-accel', '--duration', '30', '-p',
                            'camera_interval:=2.0']) == 0
    f = next(bag.glob('*.mcap'))
    data = bytearray(f.read_bytes())
    for i in range(len(data) // 3, len(data) // 3 + 4000, 7):          # garbage in the middle
        data[i] = 0xFF
    f.write_bytes(bytes(data))
    model = tmp_path / 'm.yaml'
    model.write_text('{}')
    for cmd in ([os.path.join(BIN, 'calibrate_bag'), str(bag)],
                [os.path.join(BIN, 'discrepancy'), str(bag), '--model', str(model)]):
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
        assert p.returncode == 2 and 'Traceback' not in p.stderr, (cmd, p.returncode,
                                                                   p.stderr[-2000:])
        errs = [ln for ln in p.stderr.splitlines() if 'error' in ln]
        assert len(errs) == 1, p.stderr


def _digest(paths):
    """Content of every file under ``paths`` (inputs must come out untouched)."""
    out = {}
    for root in paths:
        files = [root] if root.is_file() else sorted(p for p in root.rglob('*') if p.is_file())
        for f in files:
            out[str(f)] = hashlib.sha256(f.read_bytes()).hexdigest()
    return out


def test_no_output_overwrites_an_input(tmp_path):
    """
    Check: no output overwrites an input.

    One output rule for every tool (cli.py::check_outputs): no output may be an input (a file
    inside the input bag directory included) or another output, an existing one needs --force, the
    target directory must take a real write (/proc: os.access says yes as root); each refusal is
    one line, exit 2, and the inputs are untouched.
    """
    pytest.importorskip('rosbags')
    bag = tmp_path / 'bag'
    assert record_sim.main([str(bag), '--no-accel', '--duration', '10',
                            '-p', 'camera_interval:=2.0']) == 0
    mcap = next(bag.glob('*.mcap'))
    model = tmp_path / 'm.yaml'
    model.write_text("# the user's comment\n/**:\n  ros__parameters:\n    gyro_rate: 100.0\n")
    old = tmp_path / 'old.json'
    old.write_text('{"kept": true}\n')
    before = _digest([bag, model, old])
    b = lambda name: os.path.join(BIN, name)          # noqa: E731
    cases = [
        ([b('calibrate_bag'), str(bag), '--json', str(mcap)], 'would overwrite the input bag'),
        ([b('calibrate_bag'), str(bag), '--json', str(bag)], 'would overwrite the input bag'),
        ([b('calibrate_bag'), str(bag), '--json', str(old)], '--force'),
        ([b('calibrate_bag'), str(bag), '--json', '/proc/strapdown_probe.json'], 'not writable'),
        ([b('discrepancy'), str(bag), '--model', str(model), '--json', str(mcap)], 'input bag'),
        ([b('discrepancy'), str(bag), '--model', str(model), '--json', str(model)],
         'input --model'),
        ([b('discrepancy'), str(bag), '--model', str(model), '--write-model', str(model)],
         'input --model'),
        ([b('discrepancy'), str(bag), '--model', str(model), '--report', str(bag)], 'input bag'),
        ([b('discrepancy'), str(bag), '--model', str(model), '--json', str(tmp_path / 'o.yaml'),
          '--write-model', str(tmp_path / '.' / 'o.yaml')], 'same output'),
        ([b('discrepancy'), str(bag), '--model', str(model), '--write-model', str(old)],
         '--force'),
        ([b('calibrate_gyro_bag'), str(bag), '--method', 'integral', '--model', str(model),
          '--write-model', str(model)], 'input --model'),
        ([b('sins_bag'), str(bag), '--output', str(bag)], 'input bag'),
        ([b('sins_bag'), str(bag), '--output', str(mcap)], 'input bag'),
        ([b('sins_bag'), str(bag), '--params', str(model), '--output', str(model)],
         'input --params'),
        ([b('sins_bag'), str(bag), '--output', str(old)], '--force'),
        ([b('record_sim'), str(bag)], '--force'),
        ([b('record_sim'), str(model), '--params', str(model)], 'input --params'),
        ([b('reproduce_seeds'), '--json', str(tmp_path / 'r'), '--report', str(tmp_path / 'r')],
         'same output'),
        ([b('reproduce_seeds'), '--json', str(old)], '--force'),
    ]
    for cmd, needle in cases:
        line, took = _one_line_exit_2(cmd)
        assert needle in line and took < 20.0, (cmd, line, took)
        assert _digest([bag, model, old]) == before, cmd
    assert not list(tmp_path.glob('.*.tmp')) and not list(tmp_path.glob('*.tmp'))
    # --force replaces an existing output, atomically (no temporary file left), with valid JSON
    p = subprocess.run([b('calibrate_bag'), str(bag), '--json', str(old), '--force'],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode in (0, 3), p.stderr                # 3: this static bag is unobservable
    assert 'observable' in json.loads(old.read_text())
    assert not [f for f in os.listdir(tmp_path) if f.endswith('.tmp')]


def test_atomic_write_leaves_the_old_file_when_the_write_fails(tmp_path):
    out = tmp_path / 'r.json'
    out.write_text('old\n')
    with pytest.raises(ValueError):
        write_json(out, {'x': float('nan')})               # strict JSON: refused before the write
    assert out.read_text() == 'old\n'
    with pytest.raises(OSError, match=str(tmp_path / 'missing' / 'r.json')):
        write_json(tmp_path / 'missing' / 'r.json', {})    # the error names the target, not a .tmp
    write_json(out, {'x': 1})
    assert out.read_text() == '{\n "x": 1\n}\n' and os.listdir(tmp_path) == ['r.json']


@pytest.mark.parametrize('body, needle', [
    ('gyro_bias_sigma: 1.0e300', 'gyro_bias_sigma=1e+300 is out of range; valid: >= 0 and <= 100'),
    ('gyro_random_walk: 1.0e300', 'valid: >= 0 and <= 1'),
    ('gyro_quantum: 1.0e300', 'valid: >= 0 and <= 0.1'),
    ('gyro_scale_factor: [1.0e10, 0, 0]', 'valid: >= -0.5 and <= 0.5'),
    ('gyro_misalignment: [0.6, 0, 0, 0, 0, 0]', 'valid: >= -0.5 and <= 0.5'),
    ('frame_id: 2024-01-01', 'frame_id must be a string, got date'),
])
def test_model_values_beyond_physics_or_of_wrong_type_are_refused_first(tmp_path, body, needle):
    """
    Check: model values beyond physics or of wrong type are refused first.

    Huge in-range values used to overflow later, a YAML date for a string used to fail after the
    JSON was written; now each is one line, exit 2, nothing written.
    """
    bag = tmp_path / 'bag'
    bag.mkdir()                                   # never read: the model is refused first
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: {}\n')
    model = tmp_path / 'm.yaml'
    model.write_text(f'/**:\n  ros__parameters:\n    {body}\n')
    line, _ = _one_line_exit_2([os.path.join(BIN, 'discrepancy'), str(bag), '--model', str(model),
                                '--json', str(tmp_path / 'out.json')])
    assert needle in line and not (tmp_path / 'out.json').exists(), line
