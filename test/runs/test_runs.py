"""
The library calls of the commands (strapdown_ros.runs) on one simulated recording.

Each call takes the recording, the typed model and typed settings, prints nothing and returns
a picklable result; the numbers are checked against what the simulator injected.
"""
import pickle

import numpy as np
import pytest

pytest.importorskip('rosbags')

from strapdown_ros.fleet.simulated import BORESIGHT, SimulatedUnit, write_fleet  # noqa: E402
from strapdown_ros.params import load_model_file  # noqa: E402
from strapdown_ros.runs.boresight import calibrate_boresight  # noqa: E402
from strapdown_ros.runs.discrepancy import analyse_discrepancies  # noqa: E402
from strapdown_ros.runs.filter import run_filter_on  # noqa: E402
from strapdown_ros.runs.gyro import calibrate_gyro, GyroOptions  # noqa: E402
from strapdown_ros.runs.sins import run_sins  # noqa: E402
from strapdown_ros.runs.source import RecordingSource  # noqa: E402

BIAS = [3e-6, -2e-6, 1e-6]                       # rad/s, injected


@pytest.fixture(scope='module')
def recording(tmp_path_factory):
    """One 170 s recording at 20 Hz with a gyro bias, and the default model."""
    d = tmp_path_factory.mktemp('runs')
    _, truth = write_fleet(d, [SimulatedUnit('u', 1, values={'gyro_bias': BIAS})],
                           gyro_rate=20.0, duration=170.0, seed=7)
    return RecordingSource(str(d / truth[0]['recording'])), load_model_file(None).model


def _round_trip(run):
    again = pickle.loads(pickle.dumps(run))
    assert type(again) is type(run)
    return again


def test_each_call_prints_nothing_and_returns_a_picklable_result(recording, capsys):
    src, model = recording
    b = _round_trip(calibrate_boresight(src, model))
    assert b.observable and b.record['messages'] == {'gyro': 3400, 'camera': 85}
    beta, sig = np.array(b.record['beta_rad']), np.array(b.record['beta_sigma_rad'])
    assert np.all(np.abs(beta - BORESIGHT) <= 4 * sig) and b.found_model.boresight == tuple(beta)
    g = _round_trip(calibrate_gyro(src, model, GyroOptions('integral')))
    est, s = g.record['estimate'], g.record['sigma']
    for k, axis in enumerate('xyz'):
        assert abs(est[f'bias_{axis}'] - BIAS[k]) <= 4 * s[f'bias_{axis}']
    assert list(g.found_model.effect_value('gyro_bias')) == pytest.approx(
        [est[f'bias_{a}'] for a in 'xyz'])
    d = _round_trip(analyse_discrepancies(src, model, allan=False))
    assert d.observable and d.result.verdict == 'explained'
    assert [st.effect for st in d.result.steps] == ['gyro_bias']
    f = _round_trip(run_filter_on(src, model))
    assert f.outputs and f.fixes and f.status['applied'] > 0
    sins = _round_trip(run_sins(src, model))
    assert sins.counts['gyro'] == 3400 and sins.no_solution is None
    assert capsys.readouterr().out == ''
