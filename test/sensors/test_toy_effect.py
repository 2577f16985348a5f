"""
A new effect is a class and a registry entry: every consumer reads the registry.

A toy effect (a bias about body x that switches on at a stated time) is put in the registry
for the test (:func:`strapdown_ros.sensors.effects.registered`) and goes through the whole
chain with no other change: its keys are read from a model file and refused when out of
range, the SINS compensation inverts the simulation exactly, the attitude filter estimates it
online from a prior the model states, the discrepancy workflow names it on a recording where it
is hidden, and the found model is written and read back.  The truths are the injected values.
"""
from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.discrepancy.synthetic import simulate_recording
from strapdown_ros.discrepancy.workflow import analyse, DiscrepancySettings
from strapdown_ros.estimation.filter_system import FilterSettings, FilterSystem
from strapdown_ros.motion.profiles import PiecewiseRateProfile, Segment
from strapdown_ros.params import (check_all, IMU_SIM_PARAMS, load_model_file,
                                  STAR_CAMERA_PARAMS, write_model_file)
from strapdown_ros.sensors import ARCSEC
from strapdown_ros.sensors.effect_base import Effect, EffectParameter
from strapdown_ros.sensors.effects import EFFECTS, registered
from strapdown_ros.sensors.model import IntegratingSensor, SensorErrorModel
from strapdown_ros.sensors.star_camera import StarCameraModel


class ToyBiasStep(Effect):
    """
    A bias about body x that switches on at a stated time (the toy: one value, one option).

    Parameters
    ----------
    step_time : float
        When it switches on, s from the effect epoch.

    """

    name = 'toy_bias_step'
    parameters = (EffectParameter('toy_bias_step', 'rad/s', 1, 0.0,
                                  'a bias about body x from toy_bias_step_time on, rad/s',
                                  -1.0, 1.0),
                  EffectParameter('toy_bias_step_time', 's', 1, 0.0,
                                  'when toy_bias_step switches on, s from the effect epoch',
                                  0.0, 1e7))
    sigma_parameter = 'toy_bias_step_sigma'
    prior_sigma = 1e-4
    filter_state = True
    summary = 'bias step about x'
    signature_text = 'as gyro_bias about x, from the step on'

    def __init__(self, step_time: float = 0.0):
        self.step_time = float(step_time)

    def configured(self, params):
        """Return the toy with the step time of the parameters."""
        return ToyBiasStep(float(params.get('toy_bias_step_time', 0.0)))

    def bias_term(self, theta, t):
        """Return (θ, 0, 0) from the step on."""
        out = np.zeros((len(t), 3))
        out[:, 0] = theta[0] * (np.asarray(t) >= self.step_time)
        return out

    def increment_jacobian(self, rho, T, t):
        """Return ∂ρ̃/∂θ = T e_x from the step on."""
        J = np.zeros((len(rho), 3, 1))
        J[:, 0, 0] = T * (np.asarray(t) >= self.step_time)
        return J


@pytest.fixture
def toy():
    """Hold the toy effect in the registry for one test."""
    with registered(ToyBiasStep()) as e:
        yield e
    assert 'toy_bias_step' not in EFFECTS


def _yaml(path: Path, values: dict) -> Path:
    lines = ['/**:', '  ros__parameters:'] + [f'    {k}: {v}' for k, v in values.items()]
    path.write_text('\n'.join(lines) + '\n')
    return path


def test_model_file_reads_checks_and_writes_the_toy_keys(toy, tmp_path):
    """The toy's keys are model keys: read, range-checked, written back unchanged."""
    f = _yaml(tmp_path / 'm.yaml', {'toy_bias_step': 2e-4, 'toy_bias_step_sigma': 5e-5,
                                    'augment': 'toy_bias_step'})
    m = load_model_file(str(f)).model
    assert m.effect_value('toy_bias_step')[0] == 2e-4 and m.effect_sigma('toy_bias_step') == 5e-5
    assert m.augment == ('toy_bias_step',) and 'toy_bias_step' in m.active('gyro')
    with pytest.raises(ValueError, match=r'toy_bias_step=5(\.0)? is out of range'):
        load_model_file(str(_yaml(tmp_path / 'bad.yaml', {'toy_bias_step': 5.0})))
    with pytest.raises(ValueError, match="did you mean 'toy_bias_step'"):
        load_model_file(str(_yaml(tmp_path / 'typo.yaml', {'toy_axis_bais': 1e-4})))
    write_model_file(str(tmp_path / 'out.yaml'), m, 'round trip')
    assert load_model_file(str(tmp_path / 'out.yaml')).model.values() == m.values()


def test_compensation_inverts_the_simulation_exactly(toy):
    """The SINS compensation (the model's GyroEffects) inverts what the simulator applies."""
    m = load_model_file(None).model.with_values({'toy_bias_step': 3e-4})
    rng = np.random.default_rng(1)
    rho = rng.normal(0.0, 1e-3, (50, 3))
    t = 0.01 * np.arange(1, 51)
    measured = m.gyro_effects(epoch=0.0).apply(rho, t, 0.01)
    np.testing.assert_allclose(measured[:, 0] - rho[:, 0], 3e-6, rtol=1e-12)
    np.testing.assert_allclose(m.gyro_effects(epoch=0.0).compensate(measured, t, 0.01), rho,
                               atol=1e-17)


def _turns():
    segs = []
    for axis in (0, 1, 2, 0, 2, 1):
        w = np.zeros(3)
        w[axis] = 0.05
        segs += [Segment(6.0, w), Segment(2.0)]
    return PiecewiseRateProfile(segs * 4, initial_attitude=np.array([1.0, 0.0, 0.0, 0.0]))


def test_filter_estimates_the_toy_online(toy):
    """
    The filter, told by the model to estimate the toy (prior from its σ), finds it.

    A hidden toy step of 2e-5 rad/s at 30 s (the model says 0 ± 1e-4; the gyro bias is stated
    known): the estimate is within 3σ of the truth after 100 s of
    fixes every second, with σ below half of it.
    """
    rate, truth = 25.0, 2e-5
    profile = _turns()
    model = load_model_file(None).model.with_values({
        'gyro_rate': rate, 'gyro_random_walk': 2e-6, 'gyro_bias_sigma': 1e-9,
        'toy_bias_step_time': 30.0,
        'toy_bias_step_sigma': 1e-4, 'augment': 'toy_bias_step'})
    sim = model.with_values({'toy_bias_step': truth})
    gyro = IntegratingSensor(profile, 'gyro', rate,
                             SensorErrorModel(np.zeros(3), np.zeros(3), np.zeros((3, 3)),
                                              random_walk=2e-6), seed=3,
                             effects=sim.gyro_effects())
    cam = StarCameraModel(boresight=np.zeros(3), interval=1.0,
                          sigma=np.array([1.0, 1.0, 5.0]) * ARCSEC, seed=4)
    system = FilterSystem(model, FilterSettings(output_period=1.0))
    st, meas, _ = gyro.sample(int(100 * rate))
    k = 0
    for fx in cam.fixes(profile, 100):
        while k < len(st) and st[k] <= fx.stamp + 1e-9:
            system.add_increments([int(round(st[k] * 1e9))], [meas[k]])
            k += 1
        system.add_fix(int(round(fx.stamp * 1e9)), fx.attitude, fx.covariance)
    system.process()
    est, sig = system.filter.estimate('toy_bias_step')[0], system.filter.sigma('toy_bias_step')[0]
    assert abs(est - truth) < 3 * sig and sig < 0.5 * truth, (est, sig)


def test_discrepancy_names_the_hidden_toy_and_writes_it(toy, tmp_path):
    """The workflow's library is the registry's: the hidden toy is named, its value recovered."""
    over = {'profile': 'bench', 'bench_repeat': 2, 'gyro_rate': 50.0, 'camera_interval': 2.0,
            'boresight': [0.698, -0.436, 2.094], 'seed': 5}
    imu_p = check_all(IMU_SIM_PARAMS, over)
    imu_p.update(toy_bias_step=4e-6, toy_bias_step_time=160.0)   # the simulators read it too
    rec = simulate_recording(imu_p, check_all(STAR_CAMERA_PARAMS, over), 320.0)
    model = load_model_file(None).model.with_values({'gyro_rate': 50.0,
                                                     'toy_bias_step_time': 160.0})
    res = analyse(rec, model, DiscrepancySettings(max_steps=2))
    named = {s.effect: s for s in res.steps}
    assert 'toy_bias_step' in named, [s.effect for s in res.steps]
    s = named['toy_bias_step']
    assert abs(s.parameters['toy_bias_step'] - 4e-6) < 3 * s.sigma['toy_bias_step']
    found = res.found_model
    assert 'toy_bias_step' in found.augment and found.effect_sigma('toy_bias_step') > 0
    write_model_file(str(tmp_path / 'found.yaml'), found, 'found')
    back = load_model_file(str(tmp_path / 'found.yaml')).model
    assert back.effect_value('toy_bias_step')[0] == pytest.approx(
        s.parameters['toy_bias_step'], rel=1e-12)
