"""
002 (Ilyushenko 2009), the star-tracker increments: forward formulas and their inversion.

The printed 2nd/3rd-order forward formulas are of orders 2 and 3 (reversed cross product: 2);
the inversion is exact (round trip) and its vectorised recursion equals the sequential one;
the mean-rate accuracy on exact coning has slopes 2 and 3 on an arbitrary interval, and
cone-axis slopes 2 and 4 over whole cone periods with the literature constants (Ωh)²/12 and
(Ωh)⁴/60.
"""
import numpy as np
import pytest

from strapdown_ros.calibration.interval_means import mean_true_rate
from strapdown_ros.calibration.star_tracker_increments import (forward_step, invert_step,
                                                               noise_jacobians, step_increments)
from strapdown_ros.motion.profiles import ConingProfile
from strapdown_ros.rotation import (quat_angle_between, quat_conjugate, quat_multiply,
                                    quat_normalize, rotvec_to_quat)


def slopes(h, err):
    """
    Return the log-log slopes of an error against the step.

    Parameters
    ----------
    h : ndarray
        Steps.
    err : ndarray
        Errors at the steps.

    Returns
    -------
    ndarray
        The slopes between consecutive steps.

    """
    return np.diff(np.log(err)) / np.diff(np.log(h))


# --------------------------------------------------------------------------- formulas
def _integrate_forward(profile, h, order, reverse=False, T0=0.37, T=3.3):
    n = int(round(T / h))
    t = T0 + h * np.arange(-1, n + 1)
    V = profile.delta_theta(t[:-1], t[1:])
    a = profile.attitude(t[1])
    for k in range(1, n + 1):
        a = forward_step(a, V[k], V[k - 1], order=order, reverse_cross=reverse)
    return float(quat_angle_between(quat_normalize(a), profile.attitude(t[-1])))


def test_printed_forward_formulas_have_their_orders():
    """
    Test 002's Euler formulas with norm correction, fed exact ∫w dt: orders 2 and 3 as printed.

    The cross product with reversed operands is a wrong hypothesis (order 2, twice the error).
    """
    p = ConingProfile(0.3, 1.0)
    h = np.array([0.1, 0.05, 0.025, 0.0125])
    e2 = np.array([_integrate_forward(p, x, 2) for x in h])
    e3 = np.array([_integrate_forward(p, x, 3) for x in h])
    e3r = np.array([_integrate_forward(p, x, 3, reverse=True) for x in h])
    assert np.all(np.abs(slopes(h, e2) - 2.0) < 0.05), slopes(h, e2)
    assert np.all(np.abs(slopes(h, e3) - 3.0) < 0.12), slopes(h, e3)
    assert np.all(np.abs(slopes(h, e3r) - 2.0) < 0.05), slopes(h, e3r)
    assert np.all(e3r > 1.5 * e2)


def test_third_order_inversion_is_exact_inverse_of_forward_formula():
    """The third-order inversion undoes the printed forward formula to round-off."""
    rng = np.random.default_rng(0)
    V = rng.normal(0.0, 0.2, (50, 3))
    V_prev = rng.normal(0.0, 0.2, (50, 3))
    # unit a_{n−1}: Δa = the step
    da = forward_step(np.array([1.0, 0, 0, 0]), V, V_prev, order=3)
    assert np.max(np.abs(invert_step(da, V_prev, order=3) - V)) < 1e-15
    da2 = forward_step(np.array([1.0, 0, 0, 0]), V, order=2)
    assert np.max(np.abs(invert_step(da2, order=2) - V)) < 1e-16
    # the printed |V|² = −8·scal(Δa) + 12 − 4|a_{n−1}|² is exact for a non-unit a_{n−1} (the norm
    # correction) when Δa = a_{n−1}⁻¹∘a_n — the inverse, not the conjugate (they agree for unit a)
    a_prev = quat_normalize(np.array([0.3, -0.2, 0.5, 0.7])) * 1.001
    a_n = forward_step(a_prev, V, V_prev, order=3)
    a2 = float(a_prev @ a_prev)
    da = quat_multiply(quat_conjugate(a_prev) / a2, a_n)
    np.testing.assert_allclose(-8.0 * da[:, 0] + 12.0 - 4.0 * a2, np.sum(V * V, 1), atol=1e-14)
    assert np.max(np.abs(invert_step(da, V_prev, order=3, norm2_prev=a2) - V)) < 1e-14
    # with the conjugate the relation holds only to first order in |a|² − 1
    dc = quat_multiply(quat_conjugate(a_prev), a_n)
    assert np.max(np.abs(-8.0 * dc[:, 0] + 12.0 - 4.0 * a2 - np.sum(V * V, 1))) > 1e-3


def _sequential(quats, form='paper'):
    """Run the paper's recursion as written: V_{n−1} is the previously computed increment."""
    q = quat_normalize(quats)
    dq = quat_multiply(quat_conjugate(q[:-1]), q[1:])
    out = np.empty((len(dq), 3))
    # first step: the next increment, whose own value needs V_1 — iterate the pair to its
    # fixed point
    v1 = invert_step(dq[1], order=2, form=form)
    for _ in range(40):
        out[0] = invert_step(dq[0], -v1, order=3, form=form)
        v1 = invert_step(dq[1], out[0], order=3, form=form)
    for n in range(1, len(dq)):
        out[n] = invert_step(dq[n], out[n - 1], order=3, form=form)
    return out


@pytest.mark.parametrize('form', ['paper', 'rotvec'])
def test_vectorised_recursion_equals_sequential(form):
    """
    The vectorised fixed-point recursion equals the sequential one to round-off.

    Parameters
    ----------
    form : str
        'paper' or 'rotvec'.

    """
    p = ConingProfile(0.3, 2.0)
    q = p.attitude(0.1 * np.arange(200))                 # 0.06 rad per step
    V = step_increments(q, order=3, form=form)
    ref = _sequential(q, form)
    assert np.max(np.abs(V - ref)) < 1e-15


def _mean_rate_error(profile, h, order, form='paper', T0=0.37, T=3.3, component=None):
    n = int(round(T / h))
    stamps = T0 + h * np.arange(-1, n + 2)               # one fix before and after the interval
    t0, t1, w, _ = mean_true_rate(stamps, profile.attitude(stamps), intervals=[[1, 1 + n]],
                                  order=order, form=form)
    exact = profile.delta_theta(t0, t1) / (t1 - t0)[:, None]
    e = (w - exact)[0]
    return float(np.linalg.norm(e)) if component is None else float(abs(e[component]))


@pytest.mark.parametrize('form', ['paper', 'rotvec'])
def test_mean_rate_orders_on_coning(form):
    """
    Measure the order of w̄ against the exact ∫w dt/T over an arbitrary interval.

    3.3 s, not whole cone periods: slopes 2.00 and 3.0 — the orders the paper names.

    Parameters
    ----------
    form : str
        'paper' or 'rotvec'.

    """
    p = ConingProfile(0.3, 1.0)
    h = np.array([0.1, 0.05, 0.025, 0.0125])
    e2 = np.array([_mean_rate_error(p, x, 2, form) for x in h])
    e3 = np.array([_mean_rate_error(p, x, 3, form) for x in h])
    print(form, 'order 2:', e2, slopes(h, e2), 'order 3:', e3, slopes(h, e3))
    assert np.all(np.abs(slopes(h, e2) - 2.0) < 0.05)
    assert np.all(np.abs(slopes(h, e3) - 3.0) < 0.15)
    assert np.abs(slopes(h, e3)[-1] - 3.0) < 0.05
    assert np.all(e3 < 0.1 * e2)


def test_mean_rate_over_whole_cone_periods_matches_coning_theory():
    """
    Match coning theory over whole cone periods.

    Over whole cone periods the periodic terms cancel; what remains is the cone-axis drift
    of the equivalent coning algorithm: α²Ω(Ωh)²/12 ('none') for order 2 and α²Ω(Ωh)⁴/60
    ('one plus previous') for order 3 (003 table, small-α).
    """
    alpha, nu = 0.05, 1.0
    p = ConingProfile(alpha, nu)
    period = 2 * np.pi / nu
    h = period / np.array([16, 32, 64, 128])
    e2 = np.array([_mean_rate_error(p, x, 2, T=2 * period, component=2) for x in h])
    e3 = np.array([_mean_rate_error(p, x, 3, T=2 * period, component=2) for x in h])
    print('whole periods, cone axis: order 2', e2, slopes(h, e2), 'order 3', e3, slopes(h, e3))
    assert np.all(np.abs(slopes(h, e2) - 2.0) < 0.05)
    assert np.all(np.abs(slopes(h, e3) - 4.0) < 0.1)
    np.testing.assert_allclose(e2, alpha ** 2 * nu * (nu * h) ** 2 / 12, rtol=0.02)
    np.testing.assert_allclose(e3, alpha ** 2 * nu * (nu * h) ** 4 / 60, rtol=0.05)


def test_noise_jacobians_against_finite_differences():
    """δV_n = (cI + [v×])θ_n + (−cI + [v×])θ_{n−1}: the camera covariance is built on it."""
    p = ConingProfile(0.3, 2.0)
    q = p.attitude(0.1 * np.arange(6))
    Jp, Jm = noise_jacobians(q)
    V = step_increments(q, order=2)
    eps = 1e-7
    for k in (2, 3):
        for i in range(3):
            th = np.zeros(3)
            th[i] = eps
            qq = q.copy()
            qq[k] = quat_multiply(q[k], rotvec_to_quat(th))
            dV = (step_increments(qq, order=2) - V) / eps
            # step k ends at fix k
            np.testing.assert_allclose(dV[k - 1], Jp[k - 1][:, i], atol=1e-7)
            # step k+1 starts at fix k
            np.testing.assert_allclose(dV[k], Jm[k][:, i], atol=1e-7)
