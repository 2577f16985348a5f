"""Increments from rate samples: the stated rule and its error order, against exact integrals."""
import numpy as np
import pytest

from strapdown_ros.streams.rate_increments import increments_from_rates, RateIntegrator


def _exact(a, w, t0, t1):
    """∫ a sin(w t) dt over (t0, t1], per axis."""
    return (a[None, :] / w) * (np.cos(w * t0)[:, None] - np.cos(w * t1)[:, None])


@pytest.mark.parametrize('rule', ['trapezoid', 'mean'])
def test_streaming_and_offline_forms_agree_to_the_bit(rule):
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.integers(9_000_000, 11_000_000, 200)).astype(np.int64)
    t[100:] += 50_000_000                       # one dropout of ~5 periods
    w = rng.normal(0, 1, (200, 3))
    ts, inc = increments_from_rates(t, w, rule, max_step_s=0.015)
    integ = RateIntegrator(rule, max_step_s=0.015)
    out = [r for r in (integ.push(a, b) for a, b in zip(t, w)) if r is not None]
    assert [s for s, _ in out] == ts.tolist()
    assert np.array_equal(np.array([v for _, v in out]), inc)
    assert len(ts) == 198 and integ.skipped == 1      # first sample and the dropout give none


def test_trapezoid_is_exact_for_a_linear_rate_and_second_order_otherwise():
    a, w = np.array([0.3, -0.2, 0.1]), 2.0
    errs = []
    for T in (0.02, 0.01, 0.005):
        t = np.arange(0.0, 10.0 + T / 2, T)
        rate = a[None, :] * np.sin(w * t)[:, None]
        ts, inc = increments_from_rates(np.round(t * 1e9).astype(np.int64), rate, 'trapezoid')
        t1 = ts * 1e-9
        exact = _exact(a, w, t1 - T, t1)
        # local error +T³ ω̈ /12 (trapezoid minus exact): check the constant, then the order of the
        # summed angle
        omega_dd = -w ** 2 * a[None, :] * np.sin(w * (t1 - T / 2))[:, None]
        assert np.allclose(inc - exact, T ** 3 * omega_dd / 12.0, atol=T ** 4 * 2)
        errs.append(np.max(np.abs(np.cumsum(inc - exact, axis=0))))
    assert 3.9 < errs[0] / errs[1] < 4.1 and 3.9 < errs[1] / errs[2] < 4.1     # O(T²)
    lin = np.array([[0.1, 0.2, 0.3]]) + np.outer(np.arange(5) * 0.01, [1.0, -2.0, 0.5])
    ts, inc = increments_from_rates(np.arange(5) * 10_000_000, lin, 'trapezoid')
    assert np.allclose(inc, 0.5 * (lin[:-1] + lin[1:]) * 0.01, rtol=0, atol=1e-15)


def test_mean_rule_is_exact_for_mean_rates():
    a, w, T = np.array([0.3, -0.2, 0.1]), 2.0, 0.01
    t = np.arange(0.0, 2.0, T)
    exact = _exact(a, w, t[:-1], t[1:])
    ts, inc = increments_from_rates(np.round(t * 1e9).astype(np.int64),
                                    np.vstack([np.zeros(3), exact / T]), 'mean')
    assert np.allclose(inc, exact, rtol=0, atol=1e-15)


def test_an_unknown_rule_is_refused_with_the_valid_values():
    with pytest.raises(ValueError, match='valid values: trapezoid, mean'):
        RateIntegrator('simpson')
