"""Observability on systems whose rank, weak directions and Gramians are known in closed form."""
import numpy as np
import pytest

from strapdown_ros.estimation.observability import (analyze_information, combination_sigma, expm,
                                                    measures_of_observability,
                                                    observability_gramian, observability_matrix,
                                                    stationary_measures)


# ------------------------------------------------------------------------------ static case
def test_information_known_weak_and_null_directions():
    """
    Information with known weak and null directions is classified.

    N = R diag(0, ε², 1) Rᵀ with a known rotation: null, weak and strong directions are its
    columns.
    """
    eps = 1e-3
    c, s = np.cos(0.3), np.sin(0.3)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    N = rot @ np.diag([0.0, eps ** 2, 1.0]) @ rot.T
    rep = analyze_information(N, labels=['a', 'b', 'c'], weak_ratio=1e-4)
    assert not rep.observable
    assert len(rep.unobservable) == 1 and len(rep.weak) == 1
    assert abs(abs(rep.directions[:, 0] @ rot[:, 0]) - 1) < 1e-12          # null direction
    assert abs(abs(rep.directions[:, 1] @ rot[:, 1]) - 1) < 1e-12          # weak direction
    assert rep.predicted_sigma[1] == pytest.approx(1 / eps, rel=1e-9)
    assert rep.predicted_sigma[2] == pytest.approx(1.0, rel=1e-12)
    assert rep.parameter_sigma[2] == pytest.approx(1.0, rel=1e-12)     # c is decoupled, σ = 1
    assert np.isinf(rep.parameter_sigma[0]) and np.isinf(rep.parameter_sigma[1])


def test_combination_sigma_differs_from_eigen_sigma():
    """σ of a parameter is √(N⁻¹)_ii, not the 1/√λ of any eigen-direction, unless N is diagonal."""
    N = np.array([[2.0, 1.0], [1.0, 1.0]])                      # N⁻¹ = [[1, -1], [-1, 2]]
    assert combination_sigma(N, np.eye(2)) == pytest.approx([1.0, np.sqrt(2.0)], rel=1e-12)
    lam = np.linalg.eigvalsh(N)                                 # (3 ∓ √5)/2
    assert 1 / np.sqrt(lam) == pytest.approx([np.sqrt(2 / (3 - np.sqrt(5))),
                                              np.sqrt(2 / (3 + np.sqrt(5)))])
    rep = analyze_information(N)
    assert rep.parameter_sigma == pytest.approx([1.0, np.sqrt(2.0)], rel=1e-12)
    # along an eigen-direction the two coincide
    v = np.linalg.eigh(N)[1][:, 0]
    assert combination_sigma(N, v)[0] == pytest.approx(1 / np.sqrt(lam[0]), rel=1e-12)


# ------------------------------------------------------------------------------ dynamic case
def test_expm_closed_forms():
    """The matrix exponential matches the closed forms of rotation, nilpotent, diagonal."""
    w = 0.7
    assert expm(np.array([[0, w], [-w, 0]]) * 3.0) == pytest.approx(
        np.array([[np.cos(3 * w), np.sin(3 * w)], [-np.sin(3 * w), np.cos(3 * w)]]), abs=1e-14)
    nil = np.array([[0, 1.0, 0], [0, 0, 1], [0, 0, 0]])
    assert expm(nil * 2) == pytest.approx(np.array([[1, 2, 2], [0, 1, 2], [0, 0, 1.0]]), abs=1e-14)
    assert expm(np.diag([40.0, -3.0])) == pytest.approx(np.diag([np.exp(40.0), np.exp(-3.0)]),
                                                        rel=1e-13)


def test_double_integrator_observed_in_position():
    """
    Double integrator observed in position.

    W = [[T, T²/2], [T²/2, T³/3]]; mean-Gramian measures 1/2 (position), T/√12 (velocity);
    derivative measures 1 and T.
    """
    T = 3.0
    A, H = np.array([[0, 1.0], [0, 0]]), np.array([[1.0, 0]])
    g = observability_gramian(lambda t: A, lambda t: H, 0.0, T, steps=4)
    assert g.gramian == pytest.approx(np.array([[T, T ** 2 / 2], [T ** 2 / 2, T ** 3 / 3]]),
                                      rel=1e-13)
    assert g.transition == pytest.approx(np.array([[1, T], [0, 1.0]]), rel=1e-14)
    assert measures_of_observability(g.mean, np.eye(2)) == pytest.approx([0.5, T / np.sqrt(12)],
                                                                         rel=1e-12)
    assert stationary_measures(A, H, T) == pytest.approx([1.0, T], rel=1e-14)


def test_harmonic_oscillator_full_period():
    """ẋ1 = ωx2, ẋ2 = −ωx1, σ = x1: over a whole period W = (T/2)·I, both measures 1/√2."""
    w = 2.0
    T = 2 * np.pi / w
    A, H = np.array([[0, w], [-w, 0]]), np.array([[1.0, 0]])
    g = observability_gramian(lambda t: A, lambda t: H, 0.0, T, steps=8)
    assert g.gramian == pytest.approx(np.eye(2) * T / 2, abs=1e-13)
    assert measures_of_observability(g.mean, np.eye(2)) == pytest.approx([2 ** -0.5] * 2,
                                                                         rel=1e-12)
    assert stationary_measures(A, H, 1.0) == pytest.approx([1.0, w], rel=1e-14)


def test_unobservable_mode_has_measure_zero():
    """A decoupled oscillator the output never sees: rank 2 of 4, its states measure 0."""
    A = np.zeros((4, 4))
    A[0, 1], A[1, 0] = 1.0, -1.0            # seen oscillator
    A[2, 3], A[3, 2] = 3.0, -3.0            # unseen oscillator
    H = np.array([[1.0, 0, 0, 0]])
    assert np.linalg.matrix_rank(observability_matrix(A, H)) == 2
    g = observability_gramian(lambda t: A, lambda t: H, 0.0, 5.0, steps=10)
    m = measures_of_observability(g.mean, np.eye(4))
    assert m[2] == 0.0 and m[3] == 0.0 and m[0] > 0.5
    assert list(stationary_measures(A, H, 1.0)[2:]) == [0.0, 0.0]
    rep = analyze_information(g.gramian, labels=['p', 'v', 'q', 'r'])
    assert not rep.observable and len(rep.unobservable) == 2
    assert all(('q' in s or 'r' in s) and 'p' not in s for s in rep.unobservable)


def test_time_varying_gramian_accuracy():
    """
    Time varying gramian accuracy.

    F(t) = [[0, t], [0, 0]], σ = x1: Φ = [[1, t²/2], [0, 1]], W = [[T, T³/6], [T³/6, T⁵/20]];
    and F = 0, H(t) = (cos t, sin t): W = [[T/2 + sin2T/4, sin²T/2], [·, T/2 − sin2T/4]].
    """
    T = 2.0
    g = observability_gramian(lambda t: np.array([[0, t], [0, 0.0]]),
                              lambda t: np.array([[1.0, 0]]), 0, T, 200)
    exact = np.array([[T, T ** 3 / 6], [T ** 3 / 6, T ** 5 / 20]])
    assert np.abs(g.gramian - exact).max() / np.abs(exact).max() < 1e-9      # Richardson: O(h⁴)
    assert g.relative_error < 1e-4                                     # bound for the O(h²) pass
    assert g.transition == pytest.approx(np.array([[1, T ** 2 / 2], [0, 1.0]]), rel=1e-4)
    T = 5.0
    g = observability_gramian(lambda t: np.zeros((2, 2)),
                              lambda t: np.array([[np.cos(t), np.sin(t)]]), 0, T, 400)
    exact = np.array([[T / 2 + np.sin(2 * T) / 4, np.sin(T) ** 2 / 2],
                      [np.sin(T) ** 2 / 2, T / 2 - np.sin(2 * T) / 4]])
    assert np.abs(g.gramian - exact).max() < 5e-9               # h = 1/80: O(h⁴) ≈ 2e-8·const


def test_measure_equals_sqrt_eigenvalue_only_along_eigen_directions():
    """001's measure of a unit eigen-direction v of W̄ is √λ_v; of a state variable, smaller."""
    A, H = np.array([[0, 1.0], [0, 0]]), np.array([[1.0, 0]])
    g = observability_gramian(lambda t: A, lambda t: H, 0.0, 1.0, steps=2)
    lam, vec = np.linalg.eigh(g.mean)
    assert measures_of_observability(g.mean, vec.T) == pytest.approx(np.sqrt(lam), rel=1e-12)
    m = measures_of_observability(g.mean, np.eye(2))
    # no variable reaches the best direction
    assert m[0] < np.sqrt(lam[1]) and m[1] < np.sqrt(lam[1])
    assert m == pytest.approx([0.5, 1 / np.sqrt(12)], rel=1e-12)


def test_gramian_measure_predicts_least_squares_accuracy():
    """
    Gramian measure predicts the least-squares accuracy.

    Monte Carlo: σ sampled n times with errors Δσ ⇒ the LS error of x_i(0) has σ = Δσ/(m_i √n).
    """
    w, T, n, ds = 1.3, 4.0, 400, 0.01
    # an oscillator and its forcing
    A, H = np.array([[0, w, 0], [-w, 0, 1.0], [0, 0, 0]]), np.array([[1.0, 0, 0]])
    t = (np.arange(n) + 0.5) * T / n
    M = np.vstack([H @ expm(A * tk) for tk in t])
    g = observability_gramian(lambda s: A, lambda s: H, 0.0, T, steps=2)
    m = measures_of_observability(g.mean, np.eye(3))
    rng = np.random.default_rng(3)
    noise = ds * rng.standard_normal((n, 2000))
    est = np.linalg.lstsq(M, noise, rcond=None)[0]     # x(0) = 0, so the estimate is the error
    assert est.std(axis=1) == pytest.approx(ds / (m * np.sqrt(n)), rel=0.08)
