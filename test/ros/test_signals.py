"""
Every node exits 0, without a traceback, on SIGINT or SIGTERM at any moment.

That is at any moment after its entry point runs: during the imports, during construction, while
spinning, and with SIGINT ignored as in a job started with ``&`` from a script.
"""
import os
import signal
import subprocess
import sys
import time

import pytest


BIN = os.path.dirname(sys.executable)
NODES = ['imu_sim_node', 'sins_node', 'star_camera_sim_node', 'calibrator_node',
         'attitude_filter_node']


def _ignore_sigint():
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@pytest.mark.parametrize('node', NODES)
def test_signal_at_any_moment_exits_0_quietly(node):
    exe = os.path.join(BIN, node)
    if not os.path.exists(exe):
        pytest.skip(f'{exe} not installed')
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    for sig, delay, ignored in ((signal.SIGINT, 0.35, True), (signal.SIGTERM, 0.6, False),
                                (signal.SIGINT, 0.9, False), (signal.SIGTERM, 2.5, True),
                                (signal.SIGINT, 2.5, True)):
        p = subprocess.Popen([exe, '--ros-args', '-p', 'diagnostics_period:=0.2'],
                             stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True, env=env,
                             preexec_fn=_ignore_sigint if ignored else None)
        time.sleep(delay)
        p.send_signal(sig)
        try:
            out, _ = p.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            p.kill()
            out, _ = p.communicate()
            pytest.fail(f'{node} ignored {sig.name} after {delay} s '
                        f'(SIGINT ignored: {ignored}):\n{out}')
        assert p.returncode == 0, (node, sig.name, delay, ignored, out)
        assert 'Traceback' not in out and 'Error' not in out, out
