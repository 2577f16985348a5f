"""
One output rule for every console script that writes (cli.py::check_outputs).

An existing output needs --force, no output is an input; each refusal comes before any work, in
one line, exit 2.  Writes are atomic: files (JSON, markdown, PNG) through a temporary file and
os.replace, bag directories through a hidden sibling renamed into place when complete
(strapdown_ros/files.py).
"""
import importlib
import os
from pathlib import Path
import re
import signal
import stat
import subprocess
import sys

import pytest

from strapdown_ros.cli import all_or_nothing, write_figure, write_text
from strapdown_ros.files import (commit_directory, discard_directory, remove_stale,
                                 stage_directory)
from strapdown_ros.runs import sins as runs_sins
from strapdown_ros.tools import record_sim, sins_bag


ROOT = Path(__file__).resolve().parents[2]

#: console scripts that write no file (nodes)
NO_OUTPUT = {'imu_sim_node', 'sins_node', 'strapdown_demo', 'star_camera_sim_node',
             'calibrator_node', 'attitude_filter_node',
             'repeatability_bench'}                      # prints its figures, writes no file

#: script -> argv with an EXISTING output (and no --force); {bag}, {model}, {old}, {trial},
#: {data}, {plots}, {manifest} are filled in by the test
EXISTING = {
    'calibrate_bag': ['{bag}', '--json', '{old}'],
    'calibrate_gyro_bag': ['{bag}', '--method', 'integral', '--json', '{old}'],
    'sins_bag': ['{bag}', '--output', '{old}'],
    'discrepancy': ['{bag}', '--model', '{model}', '--json', '{old}'],
    'record_sim': ['{bag}'],
    'sins_bag_bench': ['{bag}', '--json', '{old}'],
    'realdata_bag': ['{trial}', '{bag}'],
    'gaitmap_bag': ['{data}', '{plots}'],
    'realdata_report': ['--data', '{data}', '--out', '{plots}'],
    'sins_bench': ['--json', '{old}'],
    'coning_bench': ['--plots', '{plots}'],
    'load_bench': ['--json', '{old}'],
    'node_rate_bench': ['--json', '{old}'],
    'nav_bench': ['--report', '{plots}'],
    'boresight_bench': ['--plots', '{plots}'],
    'reproduce_seeds': ['--json', '{old}'],
    'discrepancy_bench': ['--plots', '{plots}'],
    'filter_bench': ['--json', '{old}'],
    'model_check_bench': ['--json', '{old}'],
    'filter_bag': ['{bag}', '--output', '{old}'],
    'reference_rate_bench': ['--json', '{old}'],
    'hostile_bench': ['--json', '{old}'],
    'nominal_model': ['{bag}', '--output', '{old}'],
    'fleet': ['{manifest}', '--out', '{plots}'],
    'fleet_bench': ['--json', '{old}'],
}

#: script -> argv whose output is one of its inputs
AS_INPUT = {
    'calibrate_bag': ['{bag}', '--json', '{bag}/metadata.yaml'],
    'calibrate_gyro_bag': ['{bag}', '--method', 'integral', '--model', '{model}',
                           '--write-model', '{model}'],
    'sins_bag': ['{bag}', '--output', '{bag}'],
    'discrepancy': ['{bag}', '--model', '{model}', '--write-model', '{model}'],
    'record_sim': ['{model}', '--params', '{model}'],
    'sins_bag_bench': ['{bag}', '--json', '{bag}/metadata.yaml'],
    'realdata_bag': ['{trial}', '{trial}'],
    'gaitmap_bag': ['{data}', '{data}', '--force'],
    'realdata_report': ['--data', '{data}', '--out', '{data}'],
    'filter_bag': ['{bag}', '--output', '{bag}/metadata.yaml'],
    'fleet': ['{manifest}', '--out', '{bag}', '--force'],
}


def console_scripts():
    """Return name -> 'module:function' of every console script in setup.py."""
    text = (ROOT / 'setup.py').read_text()
    return dict(re.findall(r'["\'](\w+) = ([\w.]+:\w+)["\']', text))


def test_every_writing_script_is_covered():
    scripts = console_scripts()
    assert scripts, 'no console_scripts parsed from setup.py'
    missing = sorted(set(scripts) - NO_OUTPUT - set(EXISTING))
    assert not missing, ('register these console scripts in test/tools/test_output_rule.py: '
                         f'{missing}')
    assert set(AS_INPUT) <= set(EXISTING)


@pytest.fixture(scope='module')
def files(tmp_path_factory):
    """Make the inputs every console script is run with: a bag, a model, data."""
    pytest.importorskip('rosbags')
    d = tmp_path_factory.mktemp('rule')
    bag = d / 'bag'
    assert record_sim.main([str(bag), '--no-accel', '--duration', '10',
                            '-p', 'camera_interval:=2.0']) == 0
    model = d / 'm.yaml'
    model.write_text('/**:\n  ros__parameters:\n    gyro_rate: 100.0\n')
    trial = d / 'TStick_Test01_Trial1.csv'
    trial.write_text('not read\n')
    data = d / 'data'
    (data / 'TStick').mkdir(parents=True)
    (data / 'TStick' / 'TStick_Test01_Trial1.csv').write_text('not read\n')
    plots = d / 'plots'
    plots.mkdir()
    for name in ('coning_drift.png', 'nav_bench.md', 'boresight_errors.png',
                 'discrepancy_detection.png', 'realdata.json', 'LICENSE'):
        (plots / name).write_text('old')
    old = d / 'old.json'
    old.write_text('{"kept": true}\n')
    manifest = d / 'manifest.csv'
    manifest.write_text('unit,recording,start_time,model\nu1,bag,2024-05-01T00:00:00Z,m.yaml\n')
    return {'bag': bag, 'model': model, 'old': old, 'trial': trial, 'data': data,
            'plots': plots, 'manifest': manifest}


def _snapshot(root: Path) -> dict:
    return {str(p): p.read_bytes() for p in sorted(root.rglob('*')) if p.is_file()}


def _run(script: str, argv: list, capsys):
    """
    Run main(argv) in-process with a 30 s alarm.

    main(argv) in-process with a 30 s alarm (a refusal comes before any work); returns (exit
    status, non-empty output lines).
    """
    module, func = console_scripts()[script].split(':')
    main = getattr(importlib.import_module(module), func)

    def too_slow(signum, frame):
        raise AssertionError(f'{script} did not refuse before starting its work')
    previous = signal.signal(signal.SIGALRM, too_slow)
    signal.alarm(30)
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    out = capsys.readouterr()
    lines = [ln for ln in (out.out + out.err).splitlines() if ln.strip() and '[INFO]' not in ln]
    return rc, lines


def _fill(argv, files):
    return [a.format(**{k: str(v) for k, v in files.items()}) for a in argv]


@pytest.mark.parametrize('script', sorted(EXISTING))
def test_existing_output_needs_force(script, files, capsys):
    before = _snapshot(files['bag'].parent)
    rc, lines = _run(script, _fill(EXISTING[script], files), capsys)
    assert rc == 2 and len(lines) == 1 and '--force' in lines[0], (script, rc, lines)
    assert _snapshot(files['bag'].parent) == before, script


@pytest.mark.parametrize('script', sorted(AS_INPUT))
def test_output_equal_to_an_input_is_refused(script, files, capsys):
    before = _snapshot(files['bag'].parent)
    rc, lines = _run(script, _fill(AS_INPUT[script], files), capsys)
    assert rc == 2 and len(lines) == 1, (script, rc, lines)
    assert 'input' in lines[0] and 'Traceback' not in lines[0], (script, lines)
    assert _snapshot(files['bag'].parent) == before, script


def test_bag_is_replaced_only_by_a_complete_one(tmp_path, monkeypatch):
    """
    Check: bag is replaced only by a complete one.

    record_sim writes into a hidden sibling and renames it into place: a failure half-way leaves
    the old bag (--force) as it was and no half bag or temporary directory; a success replaces it
    whole.
    """
    pytest.importorskip('rosbags')
    bag = tmp_path / 'bag'
    args = [str(bag), '--no-accel', '--duration', '4', '-p', 'camera_interval:=2.0']
    assert record_sim.main(args) == 0
    before = _snapshot(bag)
    real = record_sim.record

    def fails_half_way(path, *a, **k):
        real(path, *a, **k)                       # a complete bag in the staging directory ...
        raise OSError(28, 'No space left on device')          # ... then the disk is full
    monkeypatch.setattr(record_sim, 'record', fails_half_way)
    assert record_sim.main(args + ['--force', '--duration', '6']) == 2
    assert _snapshot(bag) == before
    assert sorted(os.listdir(tmp_path)) == ['bag']            # no staging directory left
    monkeypatch.setattr(record_sim, 'record', real)
    assert record_sim.main(args + ['--force', '--duration', '6']) == 0
    assert _snapshot(bag) != before and (bag / 'metadata.yaml').exists()
    assert sorted(os.listdir(tmp_path)) == ['bag']
    assert 'duration' in (bag / 'metadata.yaml').read_text()


def test_commit_directory_keeps_the_old_one_until_the_new_one_is_in_place(tmp_path):
    target = tmp_path / 'out'
    target.mkdir()
    (target / 'a').write_text('old')
    staged = stage_directory(target)
    assert staged.name == 'out' and staged.parent.parent == tmp_path and not staged.exists()
    staged.mkdir()
    (staged / 'a').write_text('new')
    commit_directory(staged, target)
    assert (target / 'a').read_text() == 'new' and os.listdir(tmp_path) == ['out']
    staged = stage_directory(target)
    staged.mkdir()
    discard_directory(staged)
    assert (target / 'a').read_text() == 'new' and os.listdir(tmp_path) == ['out']


def test_atomic_writes_respect_the_umask(tmp_path):
    """A file written atomically gets 0666 less the umask, like open(path, 'w')."""
    from strapdown_ros.cli import write_text

    old = os.umask(0o027)
    try:
        write_text(tmp_path / 'a.txt', 'x')
        with open(tmp_path / 'b.txt', 'w') as fh:
            fh.write('x')
    finally:
        os.umask(old)
    assert (tmp_path / 'a.txt').stat().st_mode & 0o777 == 0o640
    assert (tmp_path / 'b.txt').stat().st_mode & 0o777 == 0o640


def test_figures_are_written_atomically(tmp_path):
    matplotlib = pytest.importorskip('matplotlib')
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    out = tmp_path / 'f.png'
    write_figure(fig, out, dpi=50)
    assert out.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and os.listdir(tmp_path) == ['f.png']
    with pytest.raises(OSError, match='missing'):
        write_figure(fig, tmp_path / 'missing' / 'f.png')
    plt.close(fig)
    assert os.listdir(tmp_path) == ['f.png']


def test_sins_bag_interrupted_keeps_the_old_output_bag(files, tmp_path, monkeypatch):
    """
    Check: sins bag interrupted keeps the old output bag.

    sins_bag's MCAP output is staged too: an interruption half-way (--force over an old output)
    leaves the old bag and no staging directory.
    """
    out = tmp_path / 'out'
    assert sins_bag.main([str(files['bag']), '--output', str(out), '--quiet']) == 0
    before = _snapshot(out)
    real = runs_sins.run                        # the replay sins_bag runs, through run_sins

    def interrupted(inp, make_system, sink, *a, **k):
        real(inp, make_system, sink, *a, **k)
        raise KeyboardInterrupt
    monkeypatch.setattr(runs_sins, 'run', interrupted)
    assert sins_bag.main([str(files['bag']), '--output', str(out), '--force', '--quiet']) == 130
    assert _snapshot(out) == before and sorted(os.listdir(tmp_path)) == ['out']


def test_files_take_the_umask_and_several_outputs_are_all_or_nothing(tmp_path):
    """
    Issue 27, findings 13 and 15: mkstemp's 0600 whatever the umask; outputs one by one.

    Every atomically written file gets 0666 & ~umask; inside all_or_nothing() the targets change
    only when the block ends, an exception leaves them all as they were, and a rename that fails
    puts back the ones already replaced.
    """
    old = os.umask(0o027)
    try:
        write_text(tmp_path / 'a.txt', 'a')
        assert stat.S_IMODE(os.stat(tmp_path / 'a.txt').st_mode) == 0o640
        os.umask(0o002)
        write_text(tmp_path / 'a.txt', 'b')
        assert stat.S_IMODE(os.stat(tmp_path / 'a.txt').st_mode) == 0o664
    finally:
        os.umask(old)
    with all_or_nothing():
        write_text(tmp_path / 'a.txt', 'new')
        write_text(tmp_path / 'c.txt', 'c')
        assert (tmp_path / 'a.txt').read_text() == 'b' and not (tmp_path / 'c.txt').exists()
    assert (tmp_path / 'a.txt').read_text() == 'new' and (tmp_path / 'c.txt').read_text() == 'c'
    with pytest.raises(RuntimeError):
        with all_or_nothing():
            write_text(tmp_path / 'a.txt', 'lost')
            raise RuntimeError('the disk filled')
    (tmp_path / 'd').mkdir()
    (tmp_path / 'd' / 'x').write_text('x')                       # a target that cannot be replaced
    with pytest.raises(OSError, match='no output was changed'):
        with all_or_nothing():
            write_text(tmp_path / 'a.txt', 'v3')
            write_text(tmp_path / 'd', 'v3')
    assert (tmp_path / 'a.txt').read_text() == 'new'
    assert sorted(os.listdir(tmp_path)) == ['a.txt', 'c.txt', 'd']


def test_a_staging_left_by_kill_9_is_removed_at_the_next_run(tmp_path):
    """
    Issue 27, finding 14: record_sim's hidden staging stayed forever after kill -9.

    A process that stages a bag and dies by SIGKILL leaves its staging; the next run's output
    check removes it (its writer's lock is free) and says so; a live writer's staging is kept.
    """
    pytest.importorskip('rosbags')
    code = ('from strapdown_ros.files import stage_directory\n'
            f'p = stage_directory({str(tmp_path / "bag")!r}); p.mkdir()\n'
            "(p / 'part.mcap').write_bytes(b'x' * 100000)\n"
            'import os, signal; os.kill(os.getpid(), signal.SIGKILL)\n')
    r = subprocess.run([sys.executable, '-c', code], env={**os.environ, 'PYTHONPATH': str(ROOT)},
                       capture_output=True, timeout=60)
    assert r.returncode == -signal.SIGKILL
    left = [p.name for p in tmp_path.iterdir()]
    assert len(left) == 1 and left[0].startswith('.bag.') and left[0].endswith('.part')
    live = stage_directory(tmp_path / 'other')                   # this process's: kept
    assert remove_stale(tmp_path / 'other') == []
    discard_directory(live)
    assert record_sim.main([str(tmp_path / 'bag'), '--no-accel', '--duration', '2',
                            '-p', 'camera_interval:=1.0']) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ['bag']
