"""
The package builds with colcon and installs the layout `ros2 run` relies on.

A throw-away workspace gets a copy of this repository as src/strapdown_ros and is built
with `colcon build` (isolated install, the default). The tests then check the install
tree, resolve an executable the way `ros2 run strapdown_ros imu_sim_node` does
(ament index -> <prefix>/lib/strapdown_ros/<exe>) in the environment of the sourced
workspace, and start it. Skipped when colcon (+ colcon-ros) is not installed; it comes
with the `test` extra.
"""
import importlib.util
import json
import os
from pathlib import Path
import queue
import re
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time

import pytest


REPO = Path(__file__).resolve().parent.parent.parent
PKG = 'strapdown_ros'
EXECUTABLES = ('imu_sim_node', 'sins_node', 'strapdown_demo', 'sins_bench', 'coning_bench',
               'attitude_filter_node')
BUILD_TIMEOUT_S = 240
NODE_READY_TIMEOUT_S = 30
NODE_EXIT_TIMEOUT_S = 15

# never copied into the workspace
_IGNORE = shutil.ignore_patterns(
    '.venv', 'venv', '.git', 'build', 'install', 'log', '__pycache__', '*.pyc',
    '*.egg-info', '.pytest_cache', 'out', '.mypy_cache', '.ruff_cache',
)


def _colcon_cmd():
    """Command prefix running colcon with this interpreter, or None (-> skip)."""
    if importlib.util.find_spec('colcon_core') is None:
        return None
    if importlib.util.find_spec('colcon') is not None:        # colcon/__main__.py
        return [sys.executable, '-m', 'colcon']
    exe = Path(sys.executable).parent / 'colcon'                # no resolve(): venv bin/
    if exe.is_file() and os.access(exe, os.X_OK):
        return [str(exe)]
    found = shutil.which('colcon')
    return [found] if found else None


def _tail(text, n=6000):
    return text if len(text) <= n else '...\n' + text[-n:]


def _site_packages(prefix: Path) -> Path:
    cands = sorted(prefix.glob('lib/python3*/site-packages')) + sorted(
        prefix.glob('lib/python3*/dist-packages')) + sorted(
        prefix.glob('local/lib/python3*/dist-packages'))
    cands = [c for c in cands if (c / PKG / '__init__.py').is_file()]
    assert cands, f'no site-packages with {PKG}/ under {prefix}'
    return cands[0]


def _sourced_env(install: Path, base_env: dict):
    """
    Return the environment after sourcing the colcon workspace with sh.

    Environment after sourcing the colcon workspace with sh (setup.sh, else local_setup.sh).
    Returns (env, how).
    """
    for script in ('setup.sh', 'local_setup.sh'):
        path = install / script
        if not path.is_file():
            continue
        dump = 'import json, os; print(json.dumps(dict(os.environ)))'
        script_line = (f'. {shlex.quote(str(path))} >&2 && '
                       f'exec {shlex.quote(sys.executable)} -c {shlex.quote(dump)}')
        proc = subprocess.run(['sh', '-c', script_line], env=base_env, cwd=install,
                              capture_output=True, text=True, timeout=60)
        assert proc.returncode == 0, f'sourcing {path} with sh failed:\n{proc.stderr}'
        return json.loads(proc.stdout), f'sh: . {path}'
    # colcon generated no sh scripts: what `source install/setup.bash` would export
    prefix = install / PKG
    env = dict(base_env)
    env['AMENT_PREFIX_PATH'] = os.pathsep.join(
        [str(prefix)] + [p for p in [base_env.get('AMENT_PREFIX_PATH')] if p])
    env['PYTHONPATH'] = os.pathsep.join(
        [str(_site_packages(prefix))] + [p for p in [base_env.get('PYTHONPATH')] if p])
    return env, 'manual AMENT_PREFIX_PATH/PYTHONPATH'


@pytest.fixture(scope='module')
def workspace(tmp_path_factory):
    """
    Build the package with colcon once per module.

    Build the package with colcon once per module; yields a dict with the paths, the sourced
    environment and the build output.
    """
    cmd = _colcon_cmd()
    if cmd is None:
        pytest.skip('colcon not available (pip install colcon-core colcon-ros '
                    'colcon-python-setup-py catkin_pkg; part of the `test` extra)')
    if importlib.util.find_spec('colcon_ros') is None:
        pytest.skip('colcon-ros not installed: colcon would not treat the package as '
                    'ament_python (part of the `test` extra)')

    ws = tmp_path_factory.mktemp('colcon_ws')
    shutil.copytree(REPO, ws / 'src' / PKG, ignore=_IGNORE, symlinks=True)

    env = dict(os.environ)
    env['COLCON_HOME'] = str(ws / 'colcon_home')     # no user defaults.yaml / mixins
    env.pop('COLCON_DEFAULTS_FILE', None)
    env['PYTHONDONTWRITEBYTECODE'] = '1'
    build_base, install_base, log_base = ws / 'B', ws / 'I', ws / 'L'
    argv = cmd + ['--log-base', str(log_base), 'build',
                  '--base-paths', 'src',
                  '--build-base', str(build_base),
                  '--install-base', str(install_base),
                  '--event-handlers', 'console_direct+']
    t0 = time.monotonic()
    try:
        proc = subprocess.run(argv, cwd=ws, env=env, stdin=subprocess.DEVNULL,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              text=True, timeout=BUILD_TIMEOUT_S)
    except subprocess.TimeoutExpired as exc:
        out = exc.output.decode(errors='replace') if isinstance(exc.output,
                                                                bytes) else (exc.output or '')
        pytest.fail(f'colcon build timed out after {BUILD_TIMEOUT_S} s:\n{_tail(out)}')
    output = proc.stdout
    assert proc.returncode == 0, (
        f"colcon build failed (rc={proc.returncode}): {' '.join(argv)}\n{_tail(output)}")
    assert f'Finished <<< {PKG}' in output, f'colcon did not build {PKG}:\n{_tail(output)}'

    sourced, how = _sourced_env(install_base, env)
    yield {'ws': ws, 'install': install_base, 'prefix': install_base / PKG,
           'env': sourced, 'sourced_with': how, 'build_output': output,
           'build_seconds': time.monotonic() - t0}


def test_colcon_install_layout(workspace):
    prefix = workspace['prefix']
    assert prefix.is_dir(), f'isolated install prefix missing: {prefix}'
    libexec = prefix / 'lib' / PKG
    for exe in EXECUTABLES:
        path = libexec / exe
        there = sorted(p.name for p in libexec.glob('*')) if libexec.is_dir() else 'nothing'
        assert path.is_file(), (f'{path} missing; installed there: {there}'
                                ' (setup.cfg [install] install_scripts=$base/lib/strapdown_ros?)')
        assert os.access(path, os.X_OK), f'{path} is not executable'
        assert path.read_text().startswith('#!'), f'{path} has no shebang'
    marker = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / PKG
    assert marker.is_file(), f'ament index marker missing: {marker}'
    assert (prefix / 'share' / PKG / 'package.xml').is_file()
    site = _site_packages(prefix)

    # importable from the install (not from the checkout) in the sourced environment
    env = workspace['env']
    proc = subprocess.run(
        [sys.executable, '-c', f'import {PKG}, {PKG}.nodes, {PKG}.tools; print({PKG}.__file__)'],
        cwd=workspace['ws'], env=env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, (f"import {PKG} failed ({workspace['sourced_with']}):\n"
                                  f'{proc.stderr}')
    imported = Path(proc.stdout.strip().splitlines()[-1]).resolve()
    assert imported.is_relative_to(site.resolve()), (
        f'{PKG} imported from {imported}, expected under {site}')


def _resolve_like_ros2_run(workspace, exe):
    """`ros2 run PKG EXE`: ament index prefix of PKG, then <prefix>/lib/PKG/EXE."""
    pytest.importorskip('ament_index_python',
                        reason='ament_index_python not installed (`ros` extra)')
    code = ('from ament_index_python.packages import get_package_prefix; '
            f'print(get_package_prefix({PKG!r}))')
    proc = subprocess.run([sys.executable, '-c', code], cwd=workspace['ws'], env=workspace['env'],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, (f'get_package_prefix({PKG!r}) failed with '
                                  'AMENT_PREFIX_PATH='
                                  f"{workspace['env'].get('AMENT_PREFIX_PATH')!r}:\n"
                                  f'{proc.stderr}')
    prefix = Path(proc.stdout.strip().splitlines()[-1])
    assert prefix.resolve() == workspace['prefix'].resolve(), (
        f"ament index resolved {PKG} to {prefix}, expected {workspace['prefix']}")
    path = prefix / 'lib' / PKG / exe
    assert path.is_file() and os.access(path, os.X_OK), f'{path} is not an executable file'
    return path


def test_ros2_run_resolution(workspace):
    for exe in EXECUTABLES:
        _resolve_like_ros2_run(workspace, exe)


_READY = re.compile(r'\[imu_sim_node\]:|\bstarted\b')


def test_imu_sim_node_starts_from_install(workspace):
    exe = _resolve_like_ros2_run(workspace, 'imu_sim_node')
    env = dict(workspace['env'])
    env['PYTHONUNBUFFERED'] = '1'
    env['RCUTILS_COLORIZED_OUTPUT'] = '0'
    env['RCUTILS_LOGGING_BUFFERED_STREAM'] = '1'
    # run like ros2 run does: the file itself (its shebang picks the interpreter)
    proc = subprocess.Popen(
        [str(exe), '--ros-args', '-p', 'time_scale:=50.0', '-p', 'duration:=2.0'],
        cwd=workspace['ws'], env=env, stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1)
    lines: 'queue.Queue[str | None]' = queue.Queue()
    seen = []

    def pump():
        for line in proc.stdout:
            lines.put(line)
        lines.put(None)

    reader = threading.Thread(target=pump, daemon=True)
    reader.start()
    try:
        ready = False
        eof = False
        deadline = time.monotonic() + NODE_READY_TIMEOUT_S
        while not ready and time.monotonic() < deadline:
            try:
                line = lines.get(timeout=0.2)
            except queue.Empty:
                continue
            if line is None:
                eof = True
                break
            seen.append(line)
            if 'Traceback' in line:
                break
            if _READY.search(line) and not re.search(r'\[(ERROR|FATAL)\]', line):
                ready = True
        if not ready:
            # collect the rest of a crash report / the exit code before failing
            drain_until = time.monotonic() + 5
            while not eof and time.monotonic() < drain_until:
                try:
                    line = lines.get(timeout=0.2)
                except queue.Empty:
                    continue
                if line is None:
                    eof = True
                else:
                    seen.append(line)
            if eof:
                try:
                    proc.wait(timeout=NODE_EXIT_TIMEOUT_S)
                except subprocess.TimeoutExpired:
                    pass
            out = ''.join(seen)
            what = ('crashed' if 'Traceback' in out else
                    'exited' if proc.poll() is not None else 'printed nothing matching')
            pytest.fail(f'{exe} {what} before reporting start within {NODE_READY_TIMEOUT_S} s '
                        f'(rc={proc.poll()}):\n{_tail(out)}')

        if proc.poll() is None:          # may already have finished its run on its own
            proc.send_signal(signal.SIGINT)
        try:
            rc = proc.wait(timeout=NODE_EXIT_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            pytest.fail(f'imu_sim_node ignored SIGINT for {NODE_EXIT_TIMEOUT_S} s:\n'
                        f"{_tail(''.join(seen))}")
        reader.join(timeout=5)
        while True:
            try:
                line = lines.get_nowait()
            except queue.Empty:
                break
            if line is not None:
                seen.append(line)
        out = ''.join(seen)
        assert rc in (0, -signal.SIGINT, 128 + signal.SIGINT), (
            f'imu_sim_node exited with {rc}:\n{_tail(out)}')
        assert 'Traceback' not in out, f'imu_sim_node printed a traceback:\n{_tail(out)}'
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
