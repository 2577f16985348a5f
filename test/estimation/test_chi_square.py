"""The χ² quantiles, band and interval of estimation.chi_square against scipy's."""
import pytest

from strapdown_ros.estimation.chi_square import chi2_band, chi2_interval


def test_chi2_band_is_the_exact_two_sided_band():
    """chi2_band (numpy only, used inside node callbacks) against scipy's quantiles."""
    stats = pytest.importorskip('scipy.stats')
    for dof in (1, 2, 3, 7, 93, 1000, 30000):
        lo, hi = chi2_band(dof, 0.01)
        assert lo == pytest.approx(stats.chi2.ppf(0.005, dof) / dof, rel=1e-10)
        assert hi == pytest.approx(stats.chi2.ppf(0.995, dof) / dof, rel=1e-10)


def test_chi2_interval_matches_scipy_to_round_off():
    """chi2_interval (numpy only) against scipy's quantiles, fractional dof included."""
    stats = pytest.importorskip('scipy.stats')
    for dof in (0.5, 2.5, 3, 40, 1200):
        lo, hi = chi2_interval(dof, 0.99)
        assert lo == pytest.approx(stats.chi2.ppf(0.005, dof), rel=1e-9)
        assert hi == pytest.approx(stats.chi2.ppf(0.995, dof), rel=1e-9)
