"""Attitude integrator: streaming equivalence, algorithm switching, and covariance honesty."""
from dataclasses import replace

import numpy as np
import pytest

from strapdown_ros.attitude import coning
from strapdown_ros.attitude import kernel as attitude_kernel
from strapdown_ros.attitude.coning import algorithm_names
from strapdown_ros.attitude.integrator import AttitudeIntegrator
from strapdown_ros.motion.profiles import (ConingProfile, PiecewiseRateProfile, Segment,
                                           tkachenko_profile)
from strapdown_ros.rotation import (cross, quat_angle_between, quat_error_rotvec, quat_to_dcm,
                                    rotvec_to_dcm)
from strapdown_ros.sensors import (increment_covariance, IntegratingSensor,
                                   NAVIGATION_GRADE_GYRO, SensorSigmas)


def coning_increments(n, tau=0.01, alpha=0.1, nu=2.0):
    """
    Return exact gyro increments of a coning motion.

    Parameters
    ----------
    n : int
        Number of increments.
    tau : float
        Sample interval, s.
    alpha : float
        Cone half-angle, rad.
    nu : float
        Cone frequency, rad/s.

    Returns
    -------
    tuple
        The profile, the n + 1 sample times (s) and the increments (n, 3), rad.

    """
    p = ConingProfile(alpha, nu)
    t = np.arange(n + 1) * tau
    return p, t, p.delta_theta(t[:-1], t[1:])


@pytest.mark.parametrize('name', ['1', '2', '4+', '5', '7', 'three_sample_optimal'])
def test_chunked_push_equals_single_push(name):
    """
    Pushing increments in blocks of any size gives what one push gives.

    Parameters
    ----------
    name : str
        Coning algorithm.

    """
    p, t, dth = coning_increments(997)
    sig = SensorSigmas(bias_sigma=1e-6, scale_sigma=1e-5, misalignment_sigma=1e-5,
                       random_walk=1e-6)
    whole = AttitudeIntegrator(name, p.attitude(0.0), 0.0, gyro=sig)
    a = whole.push(dth, t[1:])
    parts = AttitudeIntegrator(name, p.attitude(0.0), 0.0, gyro=sig)
    cuts = [0, 1, 2, 7, 100, 101, 500, 997]
    outs = [parts.push(dth[i:j], t[1:][i:j]) for i, j in zip(cuts[:-1], cuts[1:])]
    att = np.vstack([o.attitude for o in outs])
    cov = np.concatenate([o.covariance for o in outs])
    np.testing.assert_allclose(att, a.attitude, atol=1e-14)
    scale = np.abs(a.covariance).max(axis=(1, 2))[:, None, None]
    np.testing.assert_allclose(cov / scale, a.covariance / scale, atol=1e-10)
    np.testing.assert_allclose(np.concatenate([o.stamps for o in outs]), a.stamps)


def test_switching_algorithm_loses_no_rotation():
    """About a fixed axis every algorithm is exact; switching mid-update loses no increment."""
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    prof = PiecewiseRateProfile([Segment(10.0, 0.2 * axis)])
    t = np.arange(1001) * 0.01
    dth = prof.delta_theta(t[:-1], t[1:])
    integ = AttitudeIntegrator('5', prof.attitude(0.0), 0.0)
    integ.push(dth[:333], t[1:334])                 # 333 = 66·5 + 3: three increments pending
    integ.set_algorithm('4+')
    integ.push(dth[333:700], t[334:701])
    integ.set_algorithm('7')
    integ.push(dth[700:], t[701:])
    assert quat_angle_between(integ.q, prof.attitude(10.0)) < 1e-13
    with pytest.raises(ValueError, match='valid names: 1, 2, 3'):
        integ.set_algorithm('nope')


def test_covariance_model_004_is_equation_2():
    """'004' reproduces E_k = Φ_k E_{k−1} Φ_kᵀ + P_ρk (004 eq. 2, Φ = exact ΔCᵀ) step by step."""
    p, t, dth = coning_increments(400)
    sig = SensorSigmas(bias_sigma=2e-6, scale_sigma=3e-5, misalignment_sigma=2e-5,
                       random_walk=1e-5)
    integ = AttitudeIntegrator('1', p.attitude(0.0), 0.0, gyro=sig, covariance_model='004')
    out = integ.push(dth, t[1:])
    E = np.zeros((3, 3))
    P = increment_covariance(dth, 0.01, sig.bias_sigma, sig.scale_sigma,
                             sig.misalignment_sigma, sig.random_walk)
    for k in range(len(dth)):
        Phi = rotvec_to_dcm(dth[k]).T
        E = Phi @ E @ Phi.T + P[k]
    np.testing.assert_allclose(out.covariance[-1], E, rtol=1e-9)


def monte_carlo_nees(model: str, runs: int = 200):
    """
    Return the mean NEES of the final attitude error over Monte Carlo runs.

    Parameters
    ----------
    model : str
        Covariance model of the integrator.
    runs : int
        Draws of the error constants and noise.

    Returns
    -------
    tuple
        Mean NEES, the errors (runs, 3) rad and the published covariance (3, 3) rad².

    """
    prof = tkachenko_profile()
    sig = SensorSigmas(bias_sigma=2e-5, scale_sigma=2e-4, misalignment_sigma=2e-4,
                       random_walk=2e-5)
    q_true = prof.attitude(30.0)
    errors, cov = [], None
    rng = np.random.default_rng(11)
    for r in range(runs):
        sensor = IntegratingSensor(prof, 'gyro', 100.0, sig.draw(rng), seed=1000 + r)
        t, meas, _ = sensor.sample(3000)
        integ = AttitudeIntegrator('2', prof.attitude(0.0), 0.0, gyro=sig, covariance_model=model)
        out = integ.push(meas, t)
        errors.append(quat_error_rotvec(out.attitude[-1], q_true, 'body'))
        # the same for every run: it depends on the measured rates only
        cov = out.covariance[-1]
    errors = np.array(errors)
    nees = np.einsum('ri,ij,rj->r', errors, np.linalg.inv(cov), errors)
    return nees.mean(), errors, cov


def test_published_covariance_is_consistent_random_constant_model():
    """
    The random-constant model's covariance matches Monte Carlo errors.

    Monte Carlo over 200 draws of the error constants and noise: the mean NEES of the
    final attitude error must lie in the 95% band of a χ²(3)/200 mean, [2.67, 3.35]
    (a small allowance for the covariance varying slightly with the measured rates).
    """
    mean_nees, errors, cov = monte_carlo_nees('random_constant')
    assert 2.6 < mean_nees < 3.45, mean_nees
    np.testing.assert_allclose(errors.std(0) ** 2, np.diag(cov), rtol=0.3)


def test_004_white_bias_model_is_overconfident_for_constant_bias():
    """
    The 004 model is overconfident for a random constant bias.

    004's P_ρk treats the bias as white between increments; with a random *constant*
    bias the attitude error grows like t, not √t, and that covariance is far too small.
    """
    mean_nees, _, _ = monte_carlo_nees('004', runs=60)
    assert mean_nees > 30.0


def test_quantization_and_initial_sigma_in_covariance():
    """The quantization remainder and the initial σ enter the covariance exactly."""
    p, t, dth = coning_increments(10)
    integ = AttitudeIntegrator('1', p.attitude(0.0), 0.0, gyro=SensorSigmas(quantum=1e-5),
                               initial_sigma=1e-3)
    out = integ.push(dth, t[1:])
    c0 = quat_to_dcm(p.attitude(0.0))
    ck = quat_to_dcm(out.attitude[-1])
    expect = ck.T @ c0 @ (1e-6 * np.eye(3)) @ c0.T @ ck + (1e-10 / 12) * np.eye(3)
    np.testing.assert_allclose(out.covariance[-1], expect, rtol=1e-12, atol=1e-20)


def test_validation_messages():
    """Unknown algorithm, unknown covariance model and a zero quaternion are refused."""
    with pytest.raises(ValueError, match='valid names'):
        AttitudeIntegrator('2-sample')
    with pytest.raises(ValueError, match='covariance_model'):
        AttitudeIntegrator('2', covariance_model='kalman')
    with pytest.raises(ValueError):
        AttitudeIntegrator('2', initial_attitude=(0.0, 0.0, 0.0, 0.0))


@pytest.mark.parametrize('covariance_model, quantum', [('random_constant', 0.0), ('004', 0.0),
                                                       ('random_constant', 1e-6)])
def test_compiled_and_numpy_recursions_agree_with_each_other_and_truth(
        monkeypatch, covariance_model, quantum):
    """
    The compiled recursion and the numpy fallback agree, and both follow the exact motion.

    The optional compiled recursion (numba) and the numpy fallback compute the same attitudes
    and covariances, in blocks of any size.

    Parameters
    ----------
    monkeypatch : pytest.MonkeyPatch
        Sets ``STRAPDOWN_KERNEL``.
    covariance_model : str
        Covariance model of the integrator.
    quantum : float
        Gyro pulse weight, rad.

    """
    prof = ConingProfile(0.087, 2.0)
    n = 4000
    tg = np.arange(n + 1) * 0.01
    dth = prof.delta_theta(tg[:-1], tg[1:])
    gyro = replace(NAVIGATION_GRADE_GYRO, quantum=quantum)
    out = {}
    for kernel in ('numpy', 'auto'):
        monkeypatch.setenv('STRAPDOWN_KERNEL', kernel)
        if kernel == 'auto' and not attitude_kernel.available():
            pytest.skip('numba not installed: only the numpy path exists here')
        integ = AttitudeIntegrator('one_plus_previous', prof.attitude(0.0), 0.0, gyro=gyro,
                                   covariance_model=covariance_model)
        q, cov = [], []
        for k, block in zip(range(0, n, 7), [7] * (n // 7 + 1)):     # odd blocks
            b = integ.push(dth[k:k + block], tg[k + 1:k + block + 1])
            q.append(b.attitude)
            cov.append(b.covariance)
        out[kernel] = np.vstack(q), np.concatenate(cov)
    (qa, ca), (qb, cb) = out['numpy'], out['auto']
    assert np.max(np.abs(qa - qb)) < 1e-13
    assert np.max(np.abs(ca - cb)) <= 1e-10 * np.max(np.abs(ca))
    assert np.all(np.linalg.eigvalsh(cb) > 0)
    assert np.max(quat_angle_between(qb, prof.attitude(tg[1:]))) < 1e-8


@pytest.mark.parametrize('covariance_model', ['random_constant', '004'])
def test_compiled_block_kernel_equals_numpy_for_every_coning_algorithm(
        monkeypatch, covariance_model):
    """
    The compiled block kernel gives the numpy path's results for every registered algorithm.

    It evaluates every algorithm from its table (coning.bilinear_form), history included; it
    must give the numpy path's attitudes, rotation vectors, mean rates and covariances to
    round-off, in blocks of odd sizes.

    Parameters
    ----------
    monkeypatch : pytest.MonkeyPatch
        Sets ``STRAPDOWN_KERNEL``.
    covariance_model : str
        Covariance model of the integrator.

    """
    rng = np.random.default_rng(7)
    n = 300
    dth = rng.normal(0.0, 2e-3, (n, 3))
    tg = np.cumsum(rng.uniform(0.009, 0.011, n))
    for name in algorithm_names():
        out = {}
        for kernel in ('numpy', 'auto'):
            monkeypatch.setenv('STRAPDOWN_KERNEL', kernel)
            if kernel == 'auto' and not attitude_kernel.available():
                pytest.skip('numba not installed: only the numpy path exists here')
            integ = AttitudeIntegrator(name, (0.9, 0.1, -0.3, 0.2), tg[0] - 0.01,
                                       gyro=NAVIGATION_GRADE_GYRO, initial_sigma=1e-4,
                                       covariance_model=covariance_model)
            parts = []
            k = 0
            for size in [1, 5, 2, 13, 7] * 100:
                if k >= n:
                    break
                parts.append(integ.push(dth[k:k + size], tg[k:k + size]))
                k += size
            out[kernel] = [np.concatenate([getattr(b, f) for b in parts])
                           for f in ('stamps', 'attitude', 'covariance', 'rotation_vector',
                                     'mean_rate', 'interval')]
        for a, b in zip(out['numpy'], out['auto']):
            assert a.shape == b.shape, name
            assert np.max(np.abs(a - b)) <= 1e-12 * max(np.max(np.abs(a)), 1e-300), name


def test_attitude_only_path_is_compiled_and_equals_numpy(monkeypatch):
    """
    The attitude-only path runs the compiled kernel too and equals the numpy path.

    With propagate_covariance False, its attitudes, rotation vectors, mean rates and intervals
    equal the numpy path's to 1e-12 for every algorithm, blocks of odd sizes, and its
    covariance is NaN in both; against the exact attitude of a coning motion it is as good as
    the path with covariance.

    Parameters
    ----------
    monkeypatch : pytest.MonkeyPatch
        Sets ``STRAPDOWN_KERNEL`` and counts the kernel's calls.

    """
    monkeypatch.setenv('STRAPDOWN_KERNEL', 'auto')
    if not attitude_kernel.available():
        pytest.skip('numba not installed: only the numpy path exists here')
    calls = []
    real = attitude_kernel.block_update
    monkeypatch.setattr(attitude_kernel, 'block_update',
                        lambda *a, **k: calls.append(k) or real(*a, **k))
    rng = np.random.default_rng(11)
    n = 300
    dth = rng.normal(0.0, 2e-3, (n, 3))
    tg = np.cumsum(rng.uniform(0.009, 0.011, n))
    for name in algorithm_names():
        out = {}
        for kernel in ('numpy', 'auto'):
            monkeypatch.setenv('STRAPDOWN_KERNEL', kernel)
            integ = AttitudeIntegrator(name, (0.9, 0.1, -0.3, 0.2), tg[0] - 0.01,
                                       propagate_covariance=False)
            parts, k = [], 0
            for size in [1, 5, 2, 13, 7] * 100:
                if k >= n:
                    break
                parts.append(integ.push(dth[k:k + size], tg[k:k + size]))
                k += size
            out[kernel] = [np.concatenate([getattr(b, f) for b in parts])
                           for f in ('stamps', 'attitude', 'rotation_vector', 'mean_rate',
                                     'interval', 'covariance')]
        for a, b in zip(out['numpy'][:-1], out['auto'][:-1]):
            assert a.shape == b.shape and len(a), name
            assert np.max(np.abs(a - b)) <= 1e-12 * max(np.max(np.abs(a)), 1e-300), name
        assert np.all(np.isnan(out['numpy'][-1])) and np.all(np.isnan(out['auto'][-1]))
    assert calls and all(c.get('covariance') is False for c in calls)   # the compiled kernel ran
    # exact truth: a coning motion, attitude only, compiled
    prof = ConingProfile(0.087, 2.0)
    t = np.arange(0, 2001) * 0.01
    q_true = prof.attitude(t)
    inc = prof.delta_theta(t[:-1], t[1:])
    integ = AttitudeIntegrator('2', q_true[0], 0.0, nominal_period=0.01,
                               propagate_covariance=False)
    b = integ.push(inc, t[1:])
    assert np.max(quat_angle_between(b.attitude, prof.attitude(b.stamps))) < 1e-8


def test_every_coning_algorithm_has_a_table_and_the_table_is_phi():
    """
    The table the compiled kernel uses is read off ``phi`` and reproduces it.

    It must exist for every algorithm of the registry and reproduce ``phi`` on independent
    random windows; a φ that is not linear plus bilinear cross products must be refused
    (None), not approximated.
    """
    rng = np.random.default_rng(3)
    for name in coning.algorithm_names():
        alg = coning.ALGORITHMS[name]
        lin, pairs = coning.bilinear_form(name)
        w = rng.normal(0.0, 0.05, (50, alg.window, 3))
        rebuilt = np.einsum('i,mia->ma', lin, w)
        for i, j, k in pairs:
            rebuilt += k * cross(w[:, int(i)], w[:, int(j)])
        assert np.max(np.abs(rebuilt - alg.phi(w))) < 1e-15, name

    def cubic_phi(w):
        return w[:, 0] + w[:, 1] + 0.1 * np.sum(w[:, 0] ** 2, axis=-1, keepdims=True) * w[:, 1]
    cubic = replace(coning.ALGORITHMS['2'], name='_test_cubic', phi=cubic_phi)
    coning.ALGORITHMS['_test_cubic'] = cubic
    try:
        assert coning.bilinear_form('_test_cubic') is None
    finally:
        del coning.ALGORITHMS['_test_cubic']
        coning.bilinear_form.cache_clear()


def test_an_algorithm_reading_five_previous_increments_gets_them_in_any_blocks():
    """
    A registered algorithm with a long history gets it, whatever the blocks.

    The integrator keeps as many used increments as the algorithm reads: pushed one at a time,
    an algorithm that reads the fifth previous increment gives what one push gives.
    """
    def phi(w):
        return w[:, 5] + (1.0 / 12.0) * cross(w[:, 4], w[:, 5]) + 0.01 * cross(w[:, 0], w[:, 5])
    long_history = replace(coning.ALGORITHMS['6'], name='_test_long_history', history=5,
                           phi=phi)
    coning.ALGORITHMS['_test_long_history'] = long_history
    try:
        p, t, dth = coning_increments(60)
        whole = AttitudeIntegrator('_test_long_history', p.attitude(0.0), 0.0)
        a = whole.push(dth, t[1:])
        parts = AttitudeIntegrator('_test_long_history', p.attitude(0.0), 0.0)
        att = np.vstack([parts.push(dth[i:i + 1], t[1:][i:i + 1]).attitude for i in range(60)])
        np.testing.assert_allclose(att, a.attitude, atol=1e-14)
    finally:
        del coning.ALGORITHMS['_test_long_history']
        coning.bilinear_form.cache_clear()
