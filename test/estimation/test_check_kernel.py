"""
The live model check's compiled loops against its numpy path, and both against exact truth.

The compiled path (:mod:`strapdown_ros.estimation.check_kernel`, with numba) and the numpy path
(``STRAPDOWN_KERNEL=numpy``) are fed the same increments and fixes: a bias-only filter, filters
carrying augmented states (other candidates, a decaying bias), the time-offset candidate, gated
fixes (no gain), a restart, an interval longer than the float chain.  Truth: the scale-factor
signature of a turn about one axis, ``ω T k`` after k gated fixes; the band energies of an FFT.
"""
import numpy as np
import pytest

from strapdown_ros.estimation import check_kernel
from strapdown_ros.estimation.filter_support import StateLayout
from strapdown_ros.estimation.model_check import check_candidates, ModelCheck
from strapdown_ros.estimation.window_tests import band_energies, band_whiteness
from strapdown_ros.rotation import quat_to_dcm, rotvec_to_quat
from strapdown_ros.sensors.effect_base import linear_partials, partial_features
from strapdown_ros.sensors.effects import EFFECTS

needs_numba = pytest.mark.skipif(check_kernel.compiled() is None,
                                 reason='numba absent or switched off')


def _check(monkeypatch, compiled, augment=(), tau=None, window=10, offset=None):
    """Return a check of a filter carrying ``augment``, on the compiled or the numpy path."""
    if compiled:
        monkeypatch.delenv('STRAPDOWN_KERNEL', raising=False)
    else:
        monkeypatch.setenv('STRAPDOWN_KERNEL', 'numpy')
    lay = StateLayout.build(tuple(augment))
    effects, time_offset = check_candidates(augment)
    cols = sum(sl.stop - sl.start for _, sl in lay.gyro)
    taus = np.full(cols, np.inf) if tau is None else np.asarray(tau, dtype=float)
    chk = ModelCheck(window=window, alpha=0.01, effects=effects,
                     time_offset=time_offset if offset is None else offset,
                     false_alarms_per_hour=0.0, layout=lay, state_tau=taus)
    assert chk.compiled == compiled
    return chk


def _events(seed, size, fixes=45):
    """Return increments (some intervals in two calls, one long) and fixes (every 7th gated)."""
    rng = np.random.default_rng(seed)
    omega = rng.normal(0.0, 0.3, 3)
    t_end, out = 0.02, []
    for k in range(fixes):
        m = 450 if k == 12 else 100                 # k = 12: beyond the float chain
        h = 0.01 + rng.uniform(-1e-4, 1e-4, m)
        t = t_end + np.cumsum(h)
        t_end = t[-1]
        d = (omega + 0.05 * np.sin(3.0 * t)[:, None] * np.array([1.0, -1.0, 0.5])) * h[:, None]
        chunks = [(d[:37], h[:37], t[:37]), (d[37:], h[37:], t[37:])] if k % 3 == 0 else \
            [(d, h, t)]
        A = rng.normal(size=(3, 3))
        S = A @ A.T + 0.5 * np.eye(3)
        z = np.linalg.cholesky(S) @ rng.normal(size=3) * (3.0 if 20 <= k < 30 else 1.0)
        H = np.hstack([quat_to_dcm(rotvec_to_quat(rng.normal(0, 0.1, 3))).T,
                       rng.normal(0.0, 0.2, (3, size - 3))])
        K = None if k % 7 == 6 else rng.normal(0.0, 0.1, (size, 3))
        fix = (t_end, z, S, quat_to_dcm(rotvec_to_quat([0.01, -0.02, 0.03])).T,
               omega + rng.normal(0.0, 0.01, 3), K, H)
        out.append((chunks, rng.normal(0.0, 1e-5, 3), fix))
    return out


def _run(chk, events, restart_at=None):
    res = []
    for k, (chunks, bias, (stamp, z, S, c, rate, K, H)) in enumerate(events):
        for d, h, t in chunks:
            chk.accumulate(d, h, t, 8, bias, 0.5)
        if k == restart_at:
            chk.restart()
            continue
        res.append(chk.add(stamp, z, S, c, rate, gain=K, jacobian=H))
    return res


def _same(a, b):
    """Assert the same verdicts of both paths: the same texts, the numbers to round-off."""
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert x.text() == y.text()
        assert (x.ok, x.window_ok, x.verdict, x.best_effect, x.episodes, x.explained) == \
            (y.ok, y.window_ok, y.verdict, y.best_effect, y.episodes, y.explained)
        np.testing.assert_allclose([x.nis_sum, x.whiteness_p, x.level, *x.nis_band],
                                   [y.nis_sum, y.whiteness_p, y.level, *y.nis_band],
                                   rtol=1e-12)
        # a p-value far in the tail: the log of a share near 1, ill-conditioned
        np.testing.assert_allclose(x.best_p, y.best_p, rtol=1e-6)
        if x.best_estimate is not None:
            np.testing.assert_allclose(x.best_estimate, y.best_estimate, rtol=1e-8)


@needs_numba
@pytest.mark.parametrize('augment, tau', [
    ((), None),                                               # bias only: 4 effects + offset
    (('gyro_scale_factor', 'time_offset'), None),             # other candidates, no offset
    (('gyro_misalignment', 'gyro_scale_asymmetry'), [500.0, 500.0, 500.0] + [np.inf] * 6),
])
def test_compiled_and_numpy_paths_agree(monkeypatch, augment, tau):
    """Same verdicts and signatures, gated fixes, a restart and a long interval included."""
    size = StateLayout.build(augment).size
    events = _events(7, size)
    fast = _check(monkeypatch, True, augment, tau)
    slow = _check(monkeypatch, False, augment, tau)
    a, b = _run(fast, events, restart_at=33), _run(slow, events, restart_at=33)
    assert {r.verdict for r in a} >= {'filling', 'consistent'}
    assert any(r.best_effect is not None for r in a)          # the naming ran
    _same(a, b)
    for x, y in zip(fast.window_rows(), slow.window_rows()):      # whitened rows, signatures
        np.testing.assert_allclose(x, y, rtol=1e-9, atol=1e-12 * np.abs(y).max())
    assert fast.windows == slow.windows and fast.episodes == slow.episodes


def test_effects_outside_the_features_run_the_numpy_path(monkeypatch):
    """A periodic bias state is not linear in [ρ, |ρ|, T, T t]: the check runs numpy."""
    monkeypatch.delenv('STRAPDOWN_KERNEL', raising=False)
    assert linear_partials([EFFECTS['gyro_bias_periodic']]) is None
    lay = StateLayout.build(('gyro_bias_periodic',))
    effects, offset = check_candidates(('gyro_bias_periodic',))
    chk = ModelCheck(window=10, effects=effects, time_offset=offset, layout=lay)
    assert not chk.compiled
    res = _run(chk, _events(3, lay.size, fixes=15))
    assert res[-1].verdict != 'filling'


def test_linear_partials_are_the_effects_own():
    """B reproduces every candidate's and state's filter partials at other increments."""
    rng = np.random.default_rng(5)
    rho, T, t = rng.normal(0.0, 0.02, (9, 3)), rng.uniform(0.005, 0.05, 9), rng.uniform(0, 900, 9)
    names = ['gyro_bias', 'gyro_bias_drift', 'gyro_scale_factor', 'gyro_scale_asymmetry',
             'gyro_misalignment']
    B = linear_partials([EFFECTS[n] for n in names])
    got = np.einsum('nf,fij->nij', partial_features(rho, T, t), B)
    want = np.concatenate([EFFECTS[n].filter_partials(rho, T, t) for n in names], axis=2)
    np.testing.assert_allclose(got, want, rtol=1e-14, atol=0.0)


@pytest.mark.parametrize('compiled', [True, False])
def test_scale_factor_signature_of_a_turn_about_one_axis(monkeypatch, compiled):
    """Turning at ω about z, fixes gated: the s_z signature is ω T k, the others' z rows 0."""
    if compiled and check_kernel.compiled() is None:
        pytest.skip('numba absent or switched off')
    monkeypatch.setenv('STRAPDOWN_KERNEL', 'auto' if compiled else 'numpy')
    chk = ModelCheck(window=5, effects=[EFFECTS['gyro_scale_factor']], false_alarms_per_hour=0.0)
    w, T = 0.3, 1.0
    h = np.full(100, T / 100)
    for k in range(1, 8):
        t = (k - 1) * T + np.cumsum(h)
        chk.accumulate(np.outer(h, [0.0, 0.0, w]), h, t, 8)
        chk.add(k * T, np.zeros(3), np.eye(3), np.eye(3), np.array([0.0, 0.0, w]))
        sig = chk.window_rows()[1][-1]                             # the fix's whitened columns
        np.testing.assert_allclose(sig[:, 2], [0.0, 0.0, w * T * k], rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(sig[2, :2], 0.0, atol=1e-15)


@needs_numba
def test_the_window_tests_are_those_of_an_fft(monkeypatch):
    """The compiled window's NIS sum and whiteness p: those of an FFT's band energies."""
    monkeypatch.delenv('STRAPDOWN_KERNEL', raising=False)
    rng = np.random.default_rng(11)
    for n in (10, 11):
        chk = ModelCheck(window=n, time_offset=True, false_alarms_per_hour=0.0)
        for k in range(n + 3):
            r = chk.add(float(k), rng.normal(size=3), np.eye(3) * 2.0, np.eye(3), np.ones(3))
        w = chk.window_rows()[0]
        f = np.fft.rfft(w, axis=0)
        e = (np.abs(f) ** 2).sum(1) * (2.0 / n)
        e[0] /= 2
        if n % 2 == 0:
            e[-1] /= 2
        np.testing.assert_allclose(band_energies(w), e, rtol=1e-12)
        np.testing.assert_allclose(r.nis_sum, (w * w).sum(), rtol=1e-14)
        np.testing.assert_allclose(r.whiteness_p, band_whiteness(e, n)[0], rtol=1e-12)
