"""
The live model check's window tests against their exact null: white Gaussian windows.

Independent truth: closed forms of the Beta distribution, Parseval's identity, and windows of
N(0, 1) numbers (the whitened innovations of a right filter), whose rejection rate must be the
stated level within binomial error.
"""
import math

import numpy as np
import pytest

from strapdown_ros.estimation.chi_square import chi2_sf
from strapdown_ros.estimation.model_check import ljung_box
from strapdown_ros.estimation.window_tests import (band_dof, band_energies, beta_log_sf, beta_sf,
                                                   judge_window, spectral_whiteness,
                                                   window_level)

N = 30


def _binomial_ok(k, n, p, sigmas=3.5):
    return abs(k - n * p) <= sigmas * math.sqrt(n * p * (1 - p))


def test_beta_survival_against_closed_forms():
    """Beta(1, b) has sf (1 − x)^b, Beta(a, 1) has sf 1 − x^a; the log form far in the tail."""
    for x in (1e-4, 0.1, 0.5, 0.9, 0.999):
        assert beta_sf(x, 1.0, 43.5) == pytest.approx((1 - x) ** 43.5, rel=1e-10, abs=1e-300)
        assert beta_sf(x, 3.0, 1.0) == pytest.approx(1 - x ** 3, rel=1e-10)
        assert beta_log_sf(x, 1.0, 43.5) == pytest.approx(43.5 * math.log1p(-x), rel=1e-10)
    x = 1.0 - 1e-12                                  # beta_sf underflows here, the log does not
    assert beta_log_sf(x, 1.0, 44.0) == pytest.approx(44.0 * math.log(1e-12), rel=1e-6)
    assert beta_sf(0.0, 3.0, 42.0) == 1.0 and beta_sf(1.0, 3.0, 42.0) == 0.0


def test_beta_survival_with_an_integer_shape_against_polynomials():
    """Beta(2, 2) and Beta(3, 2) have polynomial sf; the series meets the continued fraction."""
    for x in (1e-6, 0.01, 0.1, 0.37, 0.9):
        assert beta_sf(x, 2.0, 2.0) == pytest.approx(1 - 3 * x ** 2 + 2 * x ** 3, rel=1e-12)
        assert beta_sf(x, 3.0, 2.0) == pytest.approx(1 - 4 * x ** 3 + 3 * x ** 4, rel=1e-12)
        assert beta_sf(x, 3.0, 42.0) == pytest.approx(math.exp(beta_log_sf(x, 3.0, 42.0)),
                                                      rel=1e-12)


def test_whiteness_p_is_the_smallest_band_p_times_the_bands():
    """The screened test gives min(1, J·min_j P(Beta_j > E_j/T)) over every band, exactly."""
    rng = np.random.default_rng(7)
    for n in (5, 6, 29, 30):
        for k in range(41):
            step = np.sign(np.arange(n) - n / 2)[:, None]
            w = rng.standard_normal((n, 3)) + (0.4 * k / 40) * step
            w = np.ones((n, 3)) if k == 40 else w            # all in the mean's band
            e, d = band_energies(w), band_dof(n)
            ps = [beta_sf(e[j] / e.sum(), d[j] / 2, (3 * n - d[j]) / 2) for j in range(len(e))]
            p, band = spectral_whiteness(w)
            assert p == pytest.approx(min(1.0, len(e) * min(ps)), rel=1e-12)
            assert ps[band] == pytest.approx(min(ps), rel=1e-12)


def test_band_energies_sum_to_the_nis_and_find_a_sinusoid():
    """Parseval: the bands sum to Σ|w|²; a sinusoid at 5 cycles per window loads band 5."""
    rng = np.random.default_rng(1)
    w = rng.standard_normal((N, 3))
    e = band_energies(w)
    assert len(e) == N // 2 + 1 and band_dof(N).sum() == 3 * N
    assert e.sum() == pytest.approx(float((w * w).sum()), rel=1e-12)
    k = np.arange(N)
    w2 = 0.3 * w + 2.0 * np.cos(2 * np.pi * 5 * k / N)[:, None]
    p, band = spectral_whiteness(w2)
    assert band == 5 and p < 1e-6


def test_window_test_rejects_white_windows_at_its_level():
    """White windows: each test and the window test reject at their stated level."""
    rng = np.random.default_rng(28)
    n, level = 8000, 0.02
    x = rng.standard_normal((n, N, 3))
    white = np.array([spectral_whiteness(w)[0] for w in x])
    nis = (x * x).sum(axis=(1, 2))
    upper = np.array([chi2_sf(v, 3 * N) for v in nis])
    verdicts = [judge_window(w, level) for w in x[:3000]]
    # whiteness alone at the level (the union bound over bands is tight at these levels)
    assert _binomial_ok(int(np.sum(white < level)), n, level)
    # the NIS sum, two-sided
    assert _binomial_ok(int(np.sum(np.minimum(upper, 1 - upper) < level / 2)), n, level)
    # the window test: NIS at α/2 two-sided, whiteness at α/2, independent: 1 − (1 − α/2)²
    both = 1 - (1 - level / 2) ** 2
    assert _binomial_ok(sum(not v.ok for v in verdicts), len(verdicts), both)


def test_ljung_box_chi2_reference_is_too_liberal_at_30_fixes():
    """The statistic the check no longer uses: χ²(18) rejects about twice the nominal 1 %."""
    rng = np.random.default_rng(5)
    n = 4000
    p = np.array([chi2_sf(ljung_box(rng.standard_normal((N, 3)), 6), 18) for _ in range(n)])
    assert np.mean(p < 0.01) > 0.015


def test_window_level_from_the_rate_per_hour():
    """α = r·Δt/3600, capped; no rate: the cap."""
    assert window_level(0.1, 1.0, 0.001) == pytest.approx(0.1 / 3600)
    assert window_level(0.1, 60.0, 0.001) == 0.001
    assert window_level(0.0, 1.0, 0.002) == 0.002
