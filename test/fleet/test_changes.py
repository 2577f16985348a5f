"""
The change test and the population, on series with a known truth.

Values are drawn around an exact jump or line with known σ; the assertions are against the
injected change, and the false-alarm rate against the family-wise level.
"""
import numpy as np

from strapdown_ros.fleet.changes import (detect_changes, population, repeatability, series_of,
                                         series_test)


def _rows(unit, t, x, s, effect='gyro_bias', index=0):
    return [{'unit': unit, 'recording': f'{unit}/{k}', 't_days': float(tk), 'effect': effect,
             'parameter': effect, 'index': index, 'value': float(xk), 'sigma': float(sk)}
            for k, (tk, xk, sk) in enumerate(zip(t, x, s))]


def test_a_jump_is_found_at_its_recording_with_its_size():
    rng = np.random.default_rng(0)
    t = np.arange(8.0)
    x = np.where(t >= 5, 12.0, 0.0) + rng.normal(0.0, 1.0, 8)
    st = series_test(t, x, np.ones(8))
    assert st.kind == 'jump' and st.split == 5 and st.p < 1e-10
    assert abs(st.size - 12.0) <= 3 * st.sigma


def test_a_ramp_is_a_trend_whose_slope_is_within_its_sigma():
    rng = np.random.default_rng(1)
    t = np.arange(6.0) * 1.5
    x = 2.0 + 0.8 * t + rng.normal(0.0, 0.3, 6)
    st = series_test(t, x, np.full(6, 0.3))
    assert st.kind == 'trend' and abs(st.size - 0.8) <= 3 * st.sigma
    # a change far beyond where p underflows still names the right kind
    st = series_test(t, 1e6 * t, np.full(6, 0.3))
    assert st.kind == 'trend' and st.p == 0.0


def test_holm_holds_the_false_alarm_rate_of_a_stable_fleet():
    """100 stable fleets of 20 units × 3 components: about α of them raise any change."""
    rng = np.random.default_rng(2)
    fleets_with_a_change = 0
    for _ in range(100):
        rows = []
        for u in range(20):
            n = int(rng.integers(2, 9))
            t = np.sort(rng.uniform(0, 30, n))
            for c in range(3):
                s = rng.uniform(0.5, 2.0, n)
                rows += _rows(f'u{u}', t, rng.normal(5.0, s), s, index=c)
        changes, tests = detect_changes(rows, level=0.01)
        assert tests['series'] == 60
        fleets_with_a_change += bool(changes)
    assert fleets_with_a_change <= 2                  # α = 0.01: 1 expected, seeded


def test_detect_changes_names_the_unit_and_recording():
    rng = np.random.default_rng(3)
    t = np.arange(5.0)
    rows = _rows('a', t, rng.normal(0.0, 1.0, 5), np.ones(5))
    rows += _rows('b', t, np.where(t >= 3, 20.0, 0.0) + rng.normal(0.0, 1.0, 5), np.ones(5))
    rows += _rows('c', t, 3.0 * t + rng.normal(0.0, 1.0, 5), np.ones(5))
    changes, _ = detect_changes(rows)
    got = {(c.unit, c.kind, c.recording) for c in changes}
    assert got == {('b', 'jump', 'b/3'), ('c', 'trend', 'c/4')}, changes


def test_repeatability_widens_the_sigma_of_a_scattering_component():
    """Values scattering by τ = 2 beyond their stated σ = 0.1: τ is recovered, no change."""
    rng = np.random.default_rng(4)
    rows = []
    for u in range(30):
        t = np.arange(4.0)
        rows += _rows(f'u{u}', t, rng.normal(0.0, np.hypot(2.0, 0.1), 4), np.full(4, 0.1))
    tau = repeatability(series_of(rows))[('gyro_bias', 'gyro_bias', 0)]
    assert 1.5 < tau < 2.6
    assert detect_changes(rows)[0] == []


def test_population_median_spread_and_outlier():
    latest = [{'unit': f'u{k}', 'effect': 'boresight', 'parameter': 'boresight', 'index': 0,
               'value': v, 'sigma': 0.01} for k, v in enumerate([1.0, 1.1, 0.9, 1.05, 0.95, 4.0])]
    (p,) = population(latest)
    assert p['median'] == 1.025 and p['units'] == 6
    assert abs(p['spread'] - 1.4826 * 0.075) < 1e-12
    assert p['outlier_units'] == ['u5']
