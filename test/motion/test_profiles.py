"""
Motion profiles: exact truth checked against independent numerical references.

* attitude vs body rate: U^T dU/dt from a 6th-order central difference;
* increments vs the integral of the body rate by high-order Gauss–Legendre quadrature;
* attitude vs a tight-tolerance ODE solution of the quaternion kinematics (scipy).
"""
import numpy as np
import pytest

from strapdown_ros.motion.from_config import load_piecewise_profile
from strapdown_ros.motion.profiles import (bench_profile, ConingProfile, PiecewiseRateProfile,
                                           Segment, tkachenko_profile)
from strapdown_ros.rotation import (quat_angle_between, quat_conjugate, quat_multiply, quat_to_dcm,
                                    rotvec_to_dcm)


def rate_from_attitude(profile, t, h=1e-3):
    """ω from U^T dU/dt with a 6th-order central difference (independent of body_rate)."""
    c = [(-3, -1 / 60), (-2, 3 / 20), (-1, -3 / 4), (1, 3 / 4), (2, -3 / 20), (3, 1 / 60)]
    dU = sum(w * quat_to_dcm(profile.attitude(t + k * h)) for k, w in c) / h
    Om = quat_to_dcm(profile.attitude(t)).T @ dU
    return np.array([Om[2, 1] - Om[1, 2], Om[0, 2] - Om[2, 0], Om[1, 0] - Om[0, 1]]) / 2


def gauss_integral(f, t0, t1, n=32, pieces=8):
    x, w = np.polynomial.legendre.leggauss(n)
    edges = np.linspace(t0, t1, pieces + 1)
    total = 0.0
    for a, b in zip(edges[:-1], edges[1:]):
        nodes = 0.5 * (b - a) * x + 0.5 * (a + b)
        total = total + 0.5 * (b - a) * np.einsum('k,kj->j', w, f(nodes))
    return total


@pytest.mark.parametrize('alpha,nu', [(0.087, 1.0), (0.5, 1.0), (1.2, 3.0)])
def test_coning_rate_and_increments_are_exact(alpha, nu):
    p = ConingProfile(alpha, nu)
    for t in (0.3, 1.7, 5.2):
        np.testing.assert_allclose(p.body_rate(t), rate_from_attitude(p, t), atol=1e-10)
    # increments: closed form vs quadrature of (2.9), at the 1e-14 rad level
    t0 = np.array([0.0, 0.37, 12.5])
    t1 = t0 + np.array([0.01, 0.001, 0.9])
    exact = p.delta_theta(t0, t1)
    for k in range(3):
        ref = gauss_integral(p.body_rate, t0[k], t1[k])
        np.testing.assert_allclose(exact[k], ref, atol=1e-15, rtol=1e-13)


def test_coning_printed_dcm_26_has_misprints_and_rodrigues_25_is_used():
    alpha, nu, t = 0.3, 1.0, 0.7
    p = ConingProfile(alpha, nu)
    c, s, v = np.cos(alpha), np.sin(alpha), nu * t
    sin2 = (1 - c) * np.sin(v) ** 2
    cross = 0.5 * (1 - c) * np.sin(2 * v)
    printed = np.array([[c + sin2, -cross, s * np.cos(v)],
                        [cross, c + sin2, -s * np.sin(v)],
                        [-s * np.cos(v), s * np.sin(v), c]])
    U = quat_to_dcm(p.attitude(t))
    rodrigues = rotvec_to_dcm(alpha * np.array([np.sin(v), np.cos(v), 0.0]))
    np.testing.assert_allclose(U, rodrigues, atol=1e-15)
    wrong = np.abs(printed - U) > 1e-9
    assert wrong[0, 1] and wrong[1, 1] and wrong.sum() == 2       # U12 sign, U22 sin² → cos²
    corrected = printed.copy()
    corrected[0, 1] = 0.5 * (1 - c) * np.sin(2 * v)
    corrected[1, 1] = c + (1 - c) * np.cos(v) ** 2
    np.testing.assert_allclose(corrected, U, atol=1e-15)


def test_coning_delta_v_quadrature_accuracy():
    g = np.array([0.0, 0.0, 9.80665])
    p = ConingProfile(0.3, 2.0, gravity=g)
    t0 = np.arange(0, 1, 1 / 300.0)
    dv = p.delta_v(t0, t0 + 1 / 300.0)
    for k in (0, 17, 250):
        ref = gauss_integral(p.specific_force, t0[k], t0[k] + 1 / 300.0, n=16, pieces=1)
        np.testing.assert_allclose(dv[k], ref, atol=1e-16, rtol=1e-14)


def ode_attitude(profile, t_end, q0):
    from scipy.integrate import solve_ivp

    def f(t, q):
        w = profile.body_rate(t)
        return 0.5 * quat_multiply(q, np.concatenate([[0.0], w]))
    sol = solve_ivp(f, (0.0, t_end), q0, method='DOP853', rtol=1e-13, atol=1e-14, max_step=0.05)
    return sol.y[:, -1] / np.linalg.norm(sol.y[:, -1])


def test_piecewise_with_earth_rate_is_exact():
    pytest.importorskip('scipy')
    p = bench_profile(hold=2.0, rotation_time=1.5, earth_rate=True)
    # exaggerate the Earth rate so that it matters at test tolerances
    p = PiecewiseRateProfile(p.segments, earth_rate=p.earth_rate * 1000.0, gravity=(0, 0, 9.8))
    # body rate consistent with attitude
    for t in (0.5, 2.7, 10.1):
        np.testing.assert_allclose(p.body_rate(t), rate_from_attitude(p, t, h=1e-4), atol=1e-9)
    # increments over intervals that straddle segment boundaries vs quadrature of the body rate
    bounds = p.starts
    t0 = np.array([bounds[1] - 0.003, bounds[2] - 0.5, 0.0])
    t1 = np.array([bounds[1] + 0.007, bounds[3] + 0.2, 0.01])
    exact = p.delta_theta(t0, t1)
    dv = p.delta_v(t0, t1)
    for k in range(3):
        # integrate each smooth piece separately (the rate is discontinuous at boundaries)
        cuts = np.concatenate([[t0[k]], bounds[(bounds > t0[k]) & (bounds < t1[k])], [t1[k]]])
        ref = sum(gauss_integral(p.body_rate, a, b) for a, b in zip(cuts[:-1], cuts[1:]))
        ref_dv = sum(gauss_integral(p.specific_force, a, b) for a, b in zip(cuts[:-1], cuts[1:]))
        np.testing.assert_allclose(exact[k], ref, atol=1e-15, rtol=1e-13)
        np.testing.assert_allclose(dv[k], ref_dv, atol=1e-14, rtol=1e-13)
    # attitude vs direct ODE solution of the quaternion kinematics
    q_ode = ode_attitude(p, p.duration, p.attitude(0.0))
    assert quat_angle_between(q_ode, p.attitude(p.duration)) < 1e-10


def test_tkachenko_table_and_initial_quaternion():
    p = tkachenko_profile()
    assert p.duration == 30.0
    np.testing.assert_allclose(p.attitude(0.0), [0.64, 0.48, 0.36, -0.48], atol=1e-15)
    np.testing.assert_allclose(p.body_rate(7.0), [0.02, 0.32, -0.015])
    np.testing.assert_allclose(p.body_rate(29.0), [0.02, 0.02, -0.02])
    across = [0.01 * 0.01 + 0.02 * 0.01, 0.02 * 0.01 + 0.32 * 0.01, -0.01 * 0.01 - 0.015 * 0.01]
    np.testing.assert_allclose(p.delta_theta(4.99, 5.01), across, atol=1e-17)
    pytest.importorskip('scipy')
    q_ode = ode_attitude(p, 30.0, p.attitude(0.0))
    assert quat_angle_between(q_ode, p.attitude(30.0)) < 1e-10


def test_user_profile_from_yaml(tmp_path):
    f = tmp_path / 'profile.yaml'
    f.write_text('initial_attitude: [1, 0, 0, 0]\nsegments:\n'
                 '  - {duration: 1.0, rate: [0, 0, 0.5]}\n'
                 '  - {duration: 2.0, rate: [0.1, 0, 0]}\n')
    p = load_piecewise_profile(str(f))
    assert p.duration == 3.0
    expected = quat_multiply(np.array([np.cos(0.25), 0, 0, np.sin(0.25)]),
                             np.array([np.cos(0.1), np.sin(0.1), 0, 0]))
    assert quat_angle_between(p.attitude(3.0), expected) < 1e-15
    bad = tmp_path / 'bad.yaml'
    bad.write_text('segments:\n  - {duration: -1.0}\n')
    with pytest.raises(ValueError, match='segment 0'):
        load_piecewise_profile(str(bad))


def test_segment_validation():
    with pytest.raises(ValueError):
        Segment(0.0)
    with pytest.raises(ValueError):
        Segment(1.0, [np.nan, 0, 0])
    assert np.allclose(quat_multiply(quat_conjugate([1, 0, 0, 0]), [1, 0, 0, 0]), [1, 0, 0, 0])
