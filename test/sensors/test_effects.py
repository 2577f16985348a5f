"""
The effect registry (strapdown_ros/sensors/effects.py).

Each effect's simulation, signature and compensation agree with each other and with exact
truth; every effect parameter is a parameter of the nodes that simulate or compensate it.
"""
import numpy as np
import pytest

from strapdown_ros.motion.profiles import bench_profile, STANDARD_GRAVITY
from strapdown_ros.params import (CALIBRATOR_PARAMS, check_all, IMU_SIM_PARAMS, SINS_PARAMS,
                                  STAR_CAMERA_PARAMS)
from strapdown_ros.rotation import quat_conjugate, quat_multiply, quat_to_rotvec
from strapdown_ros.sensors import increment_covariance, NAVIGATION_GRADE_GYRO, simulated_imu
from strapdown_ros.sensors.covariance import constant_jacobian, COVARIANCE_MODELS
from strapdown_ros.sensors.effects import CameraEffects, CANDIDATES, EFFECTS, GyroEffects
from strapdown_ros.sensors.star_camera import StarCameraModel

GYRO_VALUES = {'gyro_bias': [1e-5, -2e-5, 3e-6], 'gyro_bias_drift': [1e-7, 2e-8, -3e-8],
               'gyro_scale_factor': [1e-3, -2e-3, 5e-4],
               'gyro_scale_asymmetry': [2e-4, -1e-4, 3e-4],
               'gyro_misalignment': [1e-3, -2e-3, 3e-3, 1e-4, -5e-4, 2e-3],
               'gyro_bias_periodic': [3e-6, 1e-6, -2e-6], 'gyro_bias_period': 17.0}


def _increments(n=2000, seed=0):
    rng = np.random.default_rng(seed)
    st = 0.37 + 0.005 * np.arange(1, n + 1)
    return st, rng.normal(0.0, 0.01, (n, 3))


def test_compensation_inverts_the_simulation_exactly():
    st, rho = _increments()
    eff = GyroEffects(GYRO_VALUES, epoch=st[0])
    meas = eff.apply(rho, st, 0.005)
    assert np.max(np.abs(meas - rho)) > 1e-5             # the effects are really applied
    back = eff.compensate(meas, st, 0.005)
    # the asymmetry's sign is read from ρ̃
    same = np.all(np.sign(meas) == np.sign(rho), axis=1)
    assert same.mean() > 0.99
    np.testing.assert_allclose(back[same], rho[same], rtol=0, atol=1e-17)
    # where a bias outweighs a tiny increment, the wrong sign costs at most 2|a||ρ|
    a = np.max(np.abs(GYRO_VALUES['gyro_scale_asymmetry']))
    largest = np.abs(rho[~same]).max(axis=1, keepdims=True)
    assert np.all(np.abs(back - rho)[~same] <= 2.1 * a * largest)


@pytest.mark.parametrize('name', ['gyro_bias', 'gyro_bias_drift', 'gyro_scale_factor',
                                  'gyro_scale_asymmetry', 'gyro_misalignment',
                                  'gyro_bias_periodic'])
def test_signature_is_the_derivative_of_the_simulation(name):
    """increment_jacobian = ∂ρ̃/∂θ of apply(), by central differences (exact: linear effects)."""
    st, rho = _increments(200, 1)
    e = EFFECTS[name]
    if name == 'gyro_bias_periodic':
        e = type(e)(17.0)
    T = np.full(len(st), 0.005)
    t_rel = st - 0.5 * T - st[0]
    J = e.increment_jacobian(rho, T, t_rel)
    h = 1e-6
    for i in range(e.size):
        d = np.zeros(e.size)
        d[i] = h
        vals = {'gyro_bias_period': 17.0}
        name = e.value_parameter.name
        plus = GyroEffects({**vals, name: d.tolist() if e.size > 1 else d[0]}, epoch=st[0])
        minus = GyroEffects({**vals, name: (-d).tolist() if e.size > 1 else -d[0]}, epoch=st[0])
        fd = (plus.apply(rho, st, T) - minus.apply(rho, st, T)) / (2 * h)
        # FD round-off
        np.testing.assert_allclose(J[:, :, i], fd, rtol=0, atol=1e-9 * np.max(np.abs(J)))


def test_every_effect_parameter_is_declared_where_it_is_used():
    nodes = (('imu', IMU_SIM_PARAMS), ('sins', SINS_PARAMS), ('cam', STAR_CAMERA_PARAMS),
             ('cal', CALIBRATOR_PARAMS))
    names = {n: {s.name for s in specs} for n, specs in nodes}
    for e in EFFECTS.values():
        for p in e.parameters:
            where = ('imu', 'sins', 'cal') if e.sensor == 'gyro' else ('cam', 'cal')
            for w in where:
                assert p.name in names[w], (e.name, p.name, w)
    assert set(CANDIDATES) == {'time_offset', 'gyro_bias', 'gyro_bias_drift', 'gyro_scale_factor',
                               'gyro_scale_asymmetry', 'gyro_misalignment', 'gyro_quantization',
                               'camera_noise_anisotropy'}


def test_simulator_injects_the_effects_on_exact_increments():
    """imu_sim_node / record_sim: with every random error off, Δθ = apply(exact increments)."""
    zero = {f'gyro_{k}': 0.0
            for k in ('bias_sigma', 'scale_sigma', 'misalignment_sigma', 'random_walk')}
    p = check_all(IMU_SIM_PARAMS, {'profile': 'bench', 'gyro_rate': 200.0, **zero, **GYRO_VALUES})
    prof = bench_profile()
    gyro, _ = simulated_imu(p, prof)
    t, meas, true = gyro.sample(4000)
    np.testing.assert_allclose(true, prof.delta_theta(t - 0.005, t), atol=1e-16)
    expect = GyroEffects(p, epoch=0.005).apply(true, t, 0.005)
    np.testing.assert_allclose(meas, expect, rtol=0, atol=1e-18)


def test_camera_noise_scale_and_time_offset():
    prof = bench_profile()
    cam = StarCameraModel(interval=0.5, noise_scale=[2.0, 1.0, 0.5], seed=3)
    fixes = cam.fixes(prof, 3000)
    err = np.array([quat_to_rotvec(quat_multiply(quat_conjugate(f.true_attitude), f.attitude))
                    for f in fixes])
    ratio = err.std(axis=0) / cam.sigma
    np.testing.assert_allclose(ratio, [2.0, 1.0, 0.5], rtol=0.06)   # 3000 draws: σ of σ ≈ 1.3%
    # the camera reports the nominal σ
    np.testing.assert_allclose(fixes[0].covariance, np.diag(cam.sigma ** 2))
    ce = CameraEffects({'camera_time_offset': 0.02, 'camera_noise_scale': [2.0, 1.0, 0.5]})
    assert ce.epoch(10.0) == pytest.approx(9.98)
    np.testing.assert_allclose(ce.covariance(np.eye(3)), np.diag([4.0, 1.0, 0.25]))


def test_004_white_model_from_the_registry_is_004s_printed_p_rho():
    """
    P_ρk from the effects' Jacobians equals 004 §2.1's printed formula.

    Σ σ_e² D_e D_eᵀ + σ_w² T I against sensors.model.increment_covariance.
    """
    g = NAVIGATION_GRADE_GYRO
    _, rho = _increments(50, 4)
    T = np.full(50, 0.005)
    printed = increment_covariance(rho, T, g.bias_sigma, g.scale_sigma, g.misalignment_sigma,
                                   g.random_walk)
    np.testing.assert_allclose(COVARIANCE_MODELS['004'].white(rho, T, g), printed, rtol=1e-12,
                               atol=0)
    # the random constants x = [b, vec M]: ∂(Mρ)/∂M_ij = e_i ρ_j at column-major index i + 3j
    J = constant_jacobian(rho, T)
    M = np.arange(9.0).reshape(3, 3) * 1e-4
    b = np.array([1e-6, -2e-6, 3e-6])
    x = np.concatenate([b, M.reshape(-1, order='F')])
    np.testing.assert_allclose(J @ x, rho @ M.T + b * 0.005, rtol=1e-13, atol=1e-20)


def test_g_sensitivity_follows_the_specific_force_and_is_compensated_with_delta_v():
    """A known G on the bench profile: Δθ error = G·Δv over each gyro interval, exactly."""
    G = np.array([[1e-6, -2e-6, 3e-6], [4e-7, 5e-7, -6e-7], [2e-6, 1e-6, -1e-6]])
    zero = {f'gyro_{k}': 0.0
            for k in ('bias_sigma', 'scale_sigma', 'misalignment_sigma', 'random_walk')}
    p = check_all(IMU_SIM_PARAMS, {'profile': 'bench', 'gyro_rate': 200.0, **zero,
                                   'gyro_g_sensitivity': G.ravel().tolist()})
    prof = bench_profile()
    gyro, _ = simulated_imu(p, prof)
    t, meas, true = gyro.sample(8000)                  # 40 s: the first hold and a turn
    T = 0.005
    # first hold: the body is level, f = [0, 0, g] exactly, so the error is G[:, 2]·g·T
    hold = t <= 20.0
    np.testing.assert_allclose(meas[hold] - true[hold],
                               np.broadcast_to(G[:, 2] * STANDARD_GRAVITY * T, true[hold].shape),
                               rtol=1e-9, atol=0)
    # everywhere: G·Δv, Δv the exact specific force of the profile over each gyro interval
    dv = prof.delta_v(t - T, t)
    np.testing.assert_allclose(meas - true, dv @ G.T, rtol=0, atol=1e-17)
    effect = EFFECTS['gyro_g_sensitivity']
    J = effect.delta_v_jacobian(dv)
    np.testing.assert_allclose(np.einsum('nij,j->ni', J, G.ravel()), dv @ G.T, rtol=1e-14)
    # compensation with Δv inverts it; a consumer without Δv refuses the effect in one line
    eff = GyroEffects(p, with_delta_v=True)
    np.testing.assert_allclose(eff.compensate(meas, t, T, delta_v=dv), true, rtol=0, atol=1e-17)
    with pytest.raises(ValueError, match='gyro_g_sensitivity needs the accelerometer'):
        GyroEffects(p)
    assert 'gyro_g_sensitivity' not in CANDIDATES
