"""
The attitude filter's compiled numerics (filter_kernel) give the numpy path's numbers.

The same increments and fixes go through the filter twice, with ``STRAPDOWN_KERNEL=numpy`` and
with the compiled kernels: every reported state, fix result and the final state agree to
round-off (relative 1e-12 of each array's scale).  The data: a constant rate with a known bias
(and scale factor, camera time offset and boresight where they are states), fixes of the exact
attitude with 2e-5 rad of noise, marks at update ends and inside updates, a late fix, a gated
fix and five gated fixes in a row (a divergence reset).  Both runs also follow the truth.
"""
import numpy as np
import pytest

from strapdown_ros.estimation import AttitudeFilter, filter_kernel
from strapdown_ros.rotation import quat_angle_between, quat_multiply, rotvec_to_quat

W = np.array([0.2, -0.15, 0.1])           # rad/s
BIAS = np.array([2e-5, -1e-5, 3e-5])      # rad/s
SCALE = np.array([2e-4, -1e-4, 3e-4])     # the gyro scale factor errors (with that state)
TAU = 0.013                               # the camera's time offset (with that state), s
Q_BV = rotvec_to_quat(np.array([1e-4, -2e-4, 5e-5]))
DT = 0.01
SECONDS = 24
GATED = (7,)                              # a fix 0.2 rad off: gated
DIVERGE = (14, 15, 16, 17, 18)            # five in a row: the fifth declares divergence
LATE = 10                                 # given 0.37 s after its epoch
ATTITUDE_ROUND_OFF = 1e-14                # rad: of the attitude integrated over the run


def _run(monkeypatch, kernel, augment=(), tau=0.0):
    """Run one filter over the scenario; return its reports, fix results and final state."""
    monkeypatch.setenv('STRAPDOWN_KERNEL', kernel)
    if kernel == 'auto' and not filter_kernel.available():
        pytest.skip('numba not installed: only the numpy path exists here')
    calls = []
    real = filter_kernel.update
    monkeypatch.setattr(filter_kernel, 'update', lambda *a, **k: calls.append(1) or real(*a, **k))
    sig = {'gyro_scale_factor': 1e-3, 'time_offset': 0.05, 'boresight': 1e-3}
    f = AttitudeFilter([1.0, 0.0, 0.0, 0.0], 0.0, gyro_random_walk=1e-6,
                       gyro_bias_random_walk=1e-7, gyro_bias_correlation_time=tau,
                       initial_sigma=1e-3, bias_sigma=1e-4, augment=augment,
                       augment_sigma={a: sig[a] for a in augment}, max_queued=0,
                       reset_sigma=1e-3, checkpoint_interval=0.7)
    rng = np.random.default_rng(5)
    n = int(SECONDS / DT)
    st = DT * np.arange(1, n + 1)
    scale = SCALE if 'gyro_scale_factor' in augment else 0.0
    d = np.tile(((1.0 + scale) * W + BIAS) * DT, (n, 1)) + rng.normal(0.0, 1e-7, (n, 3))
    offset = TAU if 'time_offset' in augment else 0.0
    q_bv = Q_BV if 'boresight' in augment else np.array([1.0, 0.0, 0.0, 0.0])

    def fix(s):
        """Return the fix of second s: stamp, attitude, covariance."""
        off = 0.2 if s in GATED + DIVERGE else 0.0
        noise = rng.normal(0.0, 2e-5, 3) + off
        q = quat_multiply(quat_multiply(rotvec_to_quat(W * s), q_bv), rotvec_to_quat(noise))
        return s + offset, q, 4e-10 * np.eye(3)

    results, reports = [], []
    k = 0
    for s in range(1, SECONDS):
        stamp, q, R = fix(s)
        if s != LATE:
            results.append(f.update(stamp, q, R))           # pending: applied when reached
        j = int(np.searchsorted(st, s + 0.37))
        for part in (slice(k, (k + j) // 2), slice((k + j) // 2, j)):   # two calls, odd sizes
            marks = [i for i in range(part.start, part.stop) if i % 23 in (0, 7)]
            results += f.propagate(d[part], st[part], marks=[i - part.start for i in marks])
            reports += f.take_reports()
        k = j
        if s == LATE:
            results.append(f.update(stamp, q, R))           # late: re-processed
    assert (len(calls) > 0) == (kernel == 'auto')
    return f, reports, results


def _same(a, b, what, floor=0.0, rtol=1e-12):
    """Assert two arrays equal to round-off: ``rtol`` of their scale, or ``floor``."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.shape == b.shape, what
    scale = max(np.max(np.abs(a)), np.max(np.abs(b)))
    assert np.max(np.abs(a - b)) <= max(rtol * scale, floor), (what, np.max(np.abs(a - b)))


@pytest.mark.parametrize('augment, tau', [
    ((), 0.0),                                                   # bias random walk
    ((), 30.0),                                                  # Gauss–Markov bias
    (('gyro_scale_factor', 'time_offset', 'boresight'), 0.0),    # augmented states
    (('gyro_scale_factor',), 30.0),
])
def test_compiled_filter_equals_numpy(monkeypatch, augment, tau):
    """Every report, fix result and the final state of both paths agree to round-off."""
    runs = {k: _run(monkeypatch, k, augment, tau) for k in ('numpy', 'auto')}
    (f0, rep0, res0), (f1, rep1, res1) = runs['numpy'], runs['auto']
    statuses = [r.status for r in res0]
    assert statuses == [r.status for r in res1]
    assert statuses.count('gated') >= 5 and statuses.count('reset') >= 1
    assert f0.counters.late == f1.counters.late == 1
    assert f0.counters.applied == f1.counters.applied >= 10
    assert len(rep0) == len(rep1) > 100
    # the residual is a difference of two unit quaternions, one integrated from increments
    # compensated with the estimates (a closed loop): its round-off is that of the attitude,
    # 1e-15 rad here, not relative to |z|; the corrections K z of the states inherit it
    gains = [np.max(np.abs(r.gain)) for r in res0 if r.gain is not None]
    floor = ATTITUDE_ROUND_OFF * max([1.0] + gains)
    for a, b in zip(rep0, rep1):
        assert a.stamp == b.stamp
        for name in ('attitude', 'covariance', 'boresight'):
            _same(getattr(a, name), getattr(b, name), (name, a.stamp))
        _same(a.states, b.states, ('states', a.stamp), floor)
    for a, b in zip(res0, res1):
        assert a.stamp == b.stamp
        # (with the time offset a state, its estimate sets the epoch: round-off)
        np.testing.assert_allclose([a.epoch, a.lateness], [b.epoch, b.lateness], rtol=1e-12,
                                   atol=1e-15)
        for name in ('innovation_covariance', 'jacobian', 'gain'):
            u, v = getattr(a, name), getattr(b, name)
            assert (u is None) == (v is None), name
        if a.residual is None:
            continue
        _same(a.residual, b.residual, ('residual', a.stamp), ATTITUDE_ROUND_OFF)
        lam = np.linalg.eigvalsh(a.innovation_covariance)
        dz = 2.0 * np.sqrt(a.nis / lam[0]) * 2.0 * ATTITUDE_ROUND_OFF      # the NIS from z
        assert abs(a.nis - b.nis) <= 1e-12 * a.nis + dz, ('nis', a.stamp)
        _same(a.innovation_covariance, b.innovation_covariance, ('S', a.stamp))
        if a.jacobian is not None:
            _same(a.jacobian, b.jacobian, ('H', a.stamp), ATTITUDE_ROUND_OFF)
        # K per state (its units), to 1e-10: with a boresight state (a column of H equal to
        # the attitude's up to a rotation) and a weakly observed time offset, P spans 7
        # decades with correlations near ±1, and two correct orders of summation give 2e-11
        for i in range(len(a.gain) if a.gain is not None else 0):
            _same(a.gain[i], b.gain[i], ('K', i, a.stamp), rtol=1e-10)
    _same(f0.P, f1.P, 'P')
    _same(f0.x, f1.x, 'x', floor)
    _same(f0.attitude, f1.attitude, 'attitude')
    # both follow the truth: the attitude within the fixes' noise, the bias estimated
    truth = rotvec_to_quat(W * f1.time)
    assert quat_angle_between(f1.attitude, truth) < 5e-4        # (the boresight: 1e-3 prior)
    if tau == 0.0 and 'gyro_scale_factor' not in augment:
        np.testing.assert_allclose(f1.estimate('gyro_bias'), BIAS, atol=3e-6)
