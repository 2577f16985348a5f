"""FixScreen.screen_many: the same fixes, values and counts as screening each fix in turn."""
from hypothesis import given, settings, strategies as st
import numpy as np

from strapdown_ros.streams.fixes import (CONDITION_LIMIT, FixScreen, MAX_VARIANCE, MIN_VARIANCE,
                                         NORM_TOLERANCE, SYMMETRY_TOLERANCE)

DEFAULT = np.diag([1e-8, 1e-8, 4e-8])


def _quaternion(kind, rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    scale = {'unit': 1.0, 'edge': 1.0 + NORM_TOLERANCE * rng.choice([0.4, 0.6, 1.0, 1.01]),
             'off': 1.3, 'far': 3.0, 'zero': 0.0, 'tiny': 1e-7, 'huge': 1e300,
             'nan': 1.0}[kind]
    q = q * scale
    if kind == 'nan':
        q[rng.integers(4)] = rng.choice([np.nan, np.inf])
    return q


def _covariance(kind, rng):
    if kind == 'none':
        return None
    a = rng.normal(size=(3, 3))
    P = 1e-8 * (a @ a.T + 0.1 * np.eye(3))
    c = np.abs(P).max()
    if kind == 'zero':
        return np.zeros((3, 3))
    if kind == 'asym':
        P[0, 1] += c * SYMMETRY_TOLERANCE * rng.choice([0.3, 0.6, 1.5])
    elif kind == 'singular':
        w, v = np.linalg.eigh(P)
        w[0] = w[-1] * CONDITION_LIMIT * rng.choice([0.5, 1.5, 3.0])
        P = (v * w) @ v.T
    elif kind == 'big':
        P *= MAX_VARIANCE / np.linalg.eigvalsh(P)[-1] * rng.choice([0.4, 0.7, 1.2])
    elif kind == 'small':
        P *= MIN_VARIANCE / np.linalg.eigvalsh(P)[0] * rng.choice([0.8, 1.5, 3.0])
    elif kind == 'nan':
        P[1, 2] = np.nan
    elif kind == 'flat':
        return P.ravel()
    return P


Q_KINDS = ['unit', 'unit', 'unit', 'edge', 'off', 'far', 'zero', 'tiny', 'huge', 'nan']
P_KINDS = ['good', 'good', 'good', 'none', 'zero', 'asym', 'singular', 'big', 'small', 'nan',
           'flat']


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(Q_KINDS), st.sampled_from(P_KINDS)), min_size=0,
                max_size=40),
       st.booleans(), st.integers(0, 2 ** 32 - 1))
def test_screen_many_equals_screen_in_turn(kinds, use_covariance, seed):
    rng = np.random.default_rng(seed)
    qs = [_quaternion(a, rng) for a, _ in kinds]
    ps = [_covariance(b, rng) for _, b in kinds]
    one, many = FixScreen(DEFAULT, use_covariance), FixScreen(DEFAULT, use_covariance)
    expected = [one.screen(q, P) for q, P in zip(qs, ps)]
    got = many.screen_many(qs, ps)
    assert len(got) == len(expected)
    for e, g in zip(expected, got):
        assert (e is None) == (g is None)
        if e is not None:                       # bit for bit: the same arithmetic
            assert np.array_equal(e[0], g[0]) and np.array_equal(e[1], g[1])
    assert many.counts() == one.counts()


def test_screen_many_all_clear_takes_the_arrays():
    """Regular fixes with their covariance: all kept, counted as from their messages."""
    rng = np.random.default_rng(3)
    qs = [_quaternion('unit', rng) for _ in range(50)]
    ps = [_covariance('good', rng) for _ in range(50)]
    screen = FixScreen(DEFAULT)
    got = screen.screen_many(qs, ps)
    assert all(g is not None for g in got)
    assert screen.counts()['covariance_from_messages'] == 50 and screen.received == 50
    for q, P, g in zip(qs, ps, got):
        assert np.array_equal(g[0], q) and np.allclose(g[1], P, rtol=1e-15, atol=0)
