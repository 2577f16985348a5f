"""
A dense reference with a correlated error: the same estimates at 1 Hz and at the full rate.

A motion-capture-like reference at 100 Hz whose error is correlated over 50 ms (five fixes):
``discrepancy`` (the workflow) and ``calibrate_bag`` (the tool, from a bag of sensor_msgs/Imu
and PoseStamped) choose the spacing of the fixes from the data, keep χ²/dof in its band, and
give the boresight of the 1-Hz reference within its σ, both within 3σ of the truth.
"""
import json

import numpy as np
import pytest

from strapdown_ros.bench.reference_rate_scenario import (BORESIGHT, input_arguments, model_text,
                                                         REFERENCE_SIGMA, simulate, write_bag)
from strapdown_ros.discrepancy.linearisation import Recording
from strapdown_ros.discrepancy.workflow import analyse, DiscrepancySettings
from strapdown_ros.params import load_model_file
from strapdown_ros.streams.rate_increments import increments_from_rates
from strapdown_ros.tools import calibrate_bag

RATE, SECONDS, TAU = 100.0, 90.0, 0.05


@pytest.fixture(scope='module')
def trial():
    """Return the simulated trial: gyro rates and reference fixes at 100 Hz."""
    return simulate(SECONDS, RATE, seed=7, correlation_time=TAU)


@pytest.fixture(scope='module')
def model(tmp_path_factory):
    """Return the model file of the trial (the gyro's and the reference's σ)."""
    path = tmp_path_factory.mktemp('model') / 'model.yaml'
    path.write_text(model_text(RATE))
    return path


def _recording(sim, every=1):
    st, inc = increments_from_rates(sim.gyro_ns, sim.rate, 'trapezoid')
    t0 = int(sim.gyro_ns[0])
    k = np.arange(0, len(sim.fix_ns), every)
    P = np.broadcast_to(REFERENCE_SIGMA ** 2 * np.eye(3), (len(k), 3, 3))
    return Recording((st - t0) * 1e-9, inc, (sim.fix_ns[k] - t0) * 1e-9, sim.fix_q[k], P)


def _agree(beta_full, sig_full, beta_1hz, sig_1hz):
    beta_full, beta_1hz = np.asarray(beta_full), np.asarray(beta_1hz)
    assert np.all(np.abs(beta_full - BORESIGHT) < 3 * np.asarray(sig_full))
    assert np.all(np.abs(beta_1hz - BORESIGHT) < 3 * np.asarray(sig_1hz))
    # the 1-Hz fixes are a subset of the full rate's: the difference is within the 1-Hz σ
    # (two standard deviations: one seeded draw per axis)
    assert np.all(np.abs(beta_full - beta_1hz) < 2 * np.asarray(sig_1hz))


def test_discrepancy_at_full_rate_and_at_1_hz_agree(trial, model):
    """The workflow spaces the fixes out, keeps χ²/dof honest, and agrees with 1 Hz."""
    mf = load_model_file(str(model), 'calibrator_node')
    settings = DiscrepancySettings.from_values(mf.settings)
    full = analyse(_recording(trial), mf.model, settings)
    one = analyse(_recording(trial, int(RATE)), mf.model, settings)
    sp = full.reference_spacing
    assert sp['step'] > 1 and abs(sp['correlation_time_s'] - TAU) < 0.3 * TAU, sp
    assert one.reference_spacing['step'] == 1
    for res in (full, one):
        assert res.fit_consistent and res.verdict == 'model_adequate', res.verdict
    _agree(full.boresight_rad, full.boresight_sigma_rad, one.boresight_rad,
           one.boresight_sigma_rad)


def test_calibrate_bag_at_full_rate_and_at_1_hz_agree(trial, model, tmp_path):
    """calibrate_bag on Imu + PoseStamped at 100 Hz: spacing from the data, as at 1 Hz."""
    bag = tmp_path / 'trial'
    write_bag(bag, trial)
    out = {}
    for name, extra in (('full', []), ('1hz', ['--reference-spacing', '1.0'])):
        f = tmp_path / f'{name}.json'
        assert calibrate_bag.main([str(bag), '--params', str(model), '--json', str(f)]
                                  + input_arguments() + extra) == 0
        out[name] = json.loads(f.read_text())
    full, one = out['full'], out['1hz']
    assert full['reference_spacing']['step'] > 1 and one['reference_spacing']['step'] == 100
    assert full['fit_consistent'] and one['fit_consistent']
    _agree(full['beta_rad'], full['beta_sigma_rad'], one['beta_rad'], one['beta_sigma_rad'])
