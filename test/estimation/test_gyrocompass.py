"""
001 (Vavilov 1982): the gyrocompass error model and its observability statements.

The error model against geometry, the observability statements against closed-form
derivations (doc/results/reproductions/observability_001.md).
"""
import pathlib
import re

import numpy as np
import pytest

from strapdown_ros.estimation.gyrocompass import (aircraft_matrix, B1, B2, circulation,
                                                  circulation_ship_system, error_matrices,
                                                  exact_measurement, full_system,
                                                  linear_measurement, measurement_vectors,
                                                  orthodrome, Parameters, ship_system, transform)
from strapdown_ros.estimation.observability import (measures_of_observability,
                                                    observability_gramian, stationary_measures)
from strapdown_ros.estimation.steady_filter import (constant_gain_covariance, discretize,
                                                    pole_placement_gain, simulate_constant_gain,
                                                    steady_state_gain)
from strapdown_ros.reproductions import vavilov1982 as seeds_001
from strapdown_ros.reproductions.vavilov1982_text import DERIVATIONS_001

SHIP = Parameters(15.0)


# ------------------------------------------------------------------- §3: the measurement
def _consistent_truth(mu1, V1, V2, lat):
    """ω2 that closes (3.1) exactly: (ω2 − μ1V1)² + (μ1V2)² = cos²φ."""
    return mu1 * V1 + np.sqrt(np.cos(lat) ** 2 - mu1 ** 2 * V2 ** 2)


def test_measurement_linearisation_is_first_order_exact():
    """(3.7) with the corrected factor μ: the nonlinear σ minus h1ᵀx − μμ1 sinφ z is O(ε²)."""
    mu, mu1 = SHIP.mu, SHIP.mu1
    lat, V1, V2 = np.radians(50), 0.6, 0.8
    w2 = _consistent_truth(mu1, V1, V2, lat)
    assert abs(exact_measurement(mu, mu1, V1, V2, w2, 0, 0, np.sin(lat), 0)) < 1e-15
    res = []
    for eps in (1e-3, 1e-4):
        args = (mu, mu1, V1, V2, w2, 2 * eps, 0.03 * eps, np.sin(lat), 1.5 * eps)
        lin = linear_measurement(*args)
        res.append(abs(exact_measurement(*args) - lin) / abs(lin))
    assert res[0] < 1e-4
    assert res[1] / res[0] == pytest.approx(0.1, rel=0.01)     # relative error ∝ ε


def test_printed_coefficients_fail():
    """(3.2)'s prefactor 0.5μ1 and (3.3)'s μ1μ1 are misprints: they miss the exact σ at order 1."""
    mu, mu1 = SHIP.mu, SHIP.mu1
    lat, V1, V2 = np.radians(50), 0.6, 0.8
    w2 = _consistent_truth(mu1, V1, V2, lat)
    eps = 1e-6
    # azimuth and velocity-signal errors only: exact σ equals h1ᵀx (prefactor μ), not (μ1/μ)·h1ᵀx
    args = (mu, mu1, V1, V2, w2, 2 * eps, 0.03 * eps, np.sin(lat), 0.0)
    exact, lin = exact_measurement(*args), linear_measurement(*args)
    assert exact == pytest.approx(lin, rel=1e-5)
    assert abs(exact * mu1 / mu - lin) > 0.4 * abs(lin)       # printed prefactor: 45 % off
    # latitude error only: coefficient −μμ1 sinφ, not −μ1μ1 sinφ
    z = 1e-6
    dz = exact_measurement(mu, mu1, V1, V2, w2, 0, 0, np.sin(lat), z)
    assert dz == pytest.approx(-mu * mu1 * np.sin(lat) * z, rel=1e-5)
    assert abs(dz - (-mu1 * mu1 * np.sin(lat) * z)) > 0.4 * abs(dz)


# ------------------------------------------------------------------- §4.1: the orthodrome
def test_orthodrome_kinematics_match_4_1():
    """The exact geometry gives 001's (4.1) (with V = 1, λ = μ)."""
    mu, mu1 = SHIP.mu, SHIP.mu1
    th, psi0 = np.radians(40), np.radians(70)
    m = orthodrome(SHIP, th, psi0)
    for tau in (0.0, 0.7):
        k = m.kinematics(tau)
        psi = psi0 + SHIP.speed / SHIP.radius * tau / SHIP.schuler_rate
        v, s = k['omega2'], k['sin_lat']
        assert s == pytest.approx(np.sin(psi) * np.sin(th), rel=1e-12)
        assert v ** 2 == pytest.approx((mu1 + np.cos(th)) ** 2 + (np.sin(th) * np.cos(psi)) ** 2,
                                       rel=1e-12)
        assert k['V1'] == pytest.approx((mu1 + np.cos(th)) / v, rel=1e-12)
        assert k['V2'] == pytest.approx(np.sin(th) * np.cos(psi) / v, rel=1e-12)
        assert k['lam_omega3'] == pytest.approx(mu * s * (1 + mu1 * k['V1'] / v), rel=1e-10)
        assert k['omega2_rate_ratio'] * v == pytest.approx(-mu * mu1 * s * k['V2'], rel=1e-8)


def _transformed(m, tau, h=1e-4):
    mu1 = m.p.mu1

    def G(t):
        k = m.kinematics(t)
        h1, h2 = measurement_vectors(k['V1'], k['V2'], k['omega2'], mu1)
        return transform(h1), transform(h2), k
    G1, G2, k = G(tau)
    G1d = (G(tau + h)[0] - G(tau - h)[0]) / (2 * h)
    G2d = (G(tau + h)[1] - G(tau - h)[1]) / (2 * h)
    B, b = error_matrices(k['lam_omega3'], k['omega2_rate_ratio'])
    return G1, G2, G1d, G2d, B, b, k


def test_change_of_variables_4_3_on_the_orthodrome():
    """
    Change of variables (4.3) holds on the orthodrome.

    y = G1x, z = G2x obey (4.3): ẏ = (B2 + cB1)y + c(μ1z + b1Δ), ż = (B2 + cB1)z + c b2Δ,
    c = μ sinφ.
    """
    mu, mu1 = SHIP.mu, SHIP.mu1
    m = orthodrome(SHIP, np.radians(40), np.radians(70))
    G1, G2, G1d, G2d, B, b, k = _transformed(m, 0.3)
    c, v, V1, V2 = mu * k['sin_lat'], k['omega2'], k['V1'], k['V2']
    Ay = (G1 @ B + G1d) @ np.linalg.inv(G1)
    assert Ay - (B2 + c * B1) == pytest.approx(c * mu1 * G2 @ np.linalg.inv(G1), abs=1e-9)
    assert G1 @ b == pytest.approx(c * np.array([0, v - mu1 ** 2 / v, 0, 2 * mu1 * V2]), abs=1e-12)
    Az = (G2 @ B + G2d) @ np.linalg.inv(G2)
    assert Az == pytest.approx(B2 + c * B1, abs=1e-9)
    assert G2 @ b == pytest.approx(c * np.array([0, -V2, 0, -V1 - mu1 / v]), abs=1e-12)
    assert abs(np.linalg.det(G1)) > 0.1                                   # (4.2) invertible


# ------------------------------------------------------------------- §4.1: the ship (4.6)
def test_ship_measures_closed_form():
    """
    Ship measures of (4.6) have their closed form.

    Derivative measures: y1 = 1, y2 = 2/√10, y3 = y4 = √2c, Δ = c b12/√6 (leading order in c).
    """
    for lat in (np.radians(30), np.radians(60)):
        c, b12 = SHIP.mu * np.sin(lat), np.cos(lat)
        A, H = ship_system(c, b12)
        m = stationary_measures(A, H, 1.0)
        closed = np.array([1.0, 2 / np.sqrt(10), np.sqrt(2) * c, np.sqrt(2) * c,
                           c * b12 / np.sqrt(6)])
        assert m == pytest.approx(closed, rel=5 * c)
        # the paper's statement: y1, y2 of order 1; y3, y4, Δ of order μ sin φ, i.e. ∝ c
        A2, H2 = ship_system(c / 2, b12)
        m2 = stationary_measures(A2, H2, 1.0)
        assert m2[2:] / m[2:] == pytest.approx([0.5] * 3, rel=2 * c)
        assert m2[:2] / m[:2] == pytest.approx([1, 1], rel=2 * c)


def test_ship_reduction_agrees_with_full_model():
    """
    Ship reduction agrees with the full model.

    The full LTV model (x, Δ; z known) on an orthodrome gives the measures of (4.6) over a
    Schuler period.
    """
    lat = np.radians(55)
    th = np.radians(60)
    m = orthodrome(SHIP, th, np.arcsin(np.sin(lat) / np.sin(th)))
    F, H = full_system(m)
    keep = [0, 1, 2, 3, 5]                                                  # drop z (known)
    g = observability_gramian(lambda t: F(t)[np.ix_(keep, keep)], lambda t: H(t)[:, keep],
                              0, 2 * np.pi, 200)
    k = m.kinematics(0.0)
    h1, _ = measurement_vectors(k['V1'], k['V2'], k['omega2'], SHIP.mu1)
    combos = np.zeros((5, 5))
    combos[:4, :4] = transform(h1)
    combos[4, 4] = 1.0
    full = measures_of_observability(g.mean, combos)
    c = SHIP.mu * k['sin_lat']
    A, Hs = ship_system(c, k['omega2'] - SHIP.mu1 ** 2 / k['omega2'], 2 * SHIP.mu1 * k['V2'])
    gs = observability_gramian(lambda t: A, lambda t: Hs, 0, 2 * np.pi, 2)
    reduced = measures_of_observability(gs.mean, np.eye(5))
    assert full == pytest.approx(reduced, rel=0.1)          # neglected terms O(μ1), O(μ²)
    assert full[2:] / c == pytest.approx(reduced[2:] / c, rel=0.1)
    assert np.all(full[2:] < 1.5 * c) and np.all(full[:2] > 3 * c)


# ------------------------------------------------------------------- §4.1: the aircraft (4.8)
def test_aircraft_measures_exact():
    """
    Aircraft measures of (4.8) are exact.

    σ-derivatives give s2 = (σ'−σ''')/2, s4 = (σ'+σ''')/2c, …: measures 1, √2, √2, √2c,
    √2c exactly.
    """
    for c in (0.05, 0.01):
        D, H = aircraft_matrix(c)
        assert stationary_measures(D, H, 1.0) == pytest.approx(
            [1, np.sqrt(2), np.sqrt(2), np.sqrt(2) * c, np.sqrt(2) * c], rel=1e-12)


def test_aircraft_D_against_geometry():
    """At μ1 = 1, ṡ = Ds holds to O(c²) in rows 1–3 (those that reach σ), rows 4–5 only to O(c)."""
    P = Parameters(7.292115e-5 * 6.371e6)          # the speed that makes μ1 = 1
    assert P.mu1 == pytest.approx(1.0)
    mu = P.mu
    m = orthodrome(P, np.radians(40), np.radians(70))
    F, H = full_system(m)

    def S(tau):
        k = m.kinematics(tau)
        h1, h2 = measurement_vectors(k['V1'], k['V2'], k['omega2'], P.mu1)
        G1, G2 = transform(h1), transform(h2)
        c, v = mu * k['sin_lat'], k['omega2']
        Y, Z = np.zeros((4, 6)), np.zeros((4, 6))
        Y[:, :4], Z[:, :4] = G1, G2
        e = np.eye(6)
        rows = [Y[0] - c * e[4], Y[1] - c * (2 * Y[2] - Z[0]),
                -Y[0] + c * (3 * Y[3] + 2 * Z[1] + (v - P.mu1 ** 2 / v) * e[5]), Y[2] - Z[0],
                Y[3] + Z[1]]
        return np.vstack(rows), c
    tau, h = 0.3, 1e-4
    S0, c = S(tau)
    res = (S(tau + h)[0] - S(tau - h)[0]) / (2 * h) + S0 @ F(tau) - aircraft_matrix(c)[0] @ S0
    row = np.abs(res).max(axis=1)
    assert np.all(row[:3] < 10 * c ** 2)
    assert np.all(row[3:] > c) and np.all(row[3:] < 4 * c)
    assert np.abs(S0[0] - H(tau)[0]).max() < 1e-4                        # s1 = σ at μ1 = 1


# ------------------------------------------------------------------- §4.2: the circulation
def test_circulation_two_periods():
    """
    Circulation over two periods.

    (4.11): on τ1 ∈ (0,1) p1, p2 have measure λ1μ1/√(1+λ1⁴); on (0, 1/λ1) (≈ two circulation
    periods … 1.6 for λ1 = 0.1) μ1/(√2λ1) and μ1/(√2λ1²) — derived from O⁻¹ by hand.
    """
    lam1, mu1 = 0.1, SHIP.mu1
    A, H = circulation_ship_system(lam1, mu1)
    short = stationary_measures(A, H, 1.0)
    long = stationary_measures(A, H, 1 / lam1)
    assert short[2:] == pytest.approx([lam1 * mu1 / np.sqrt(1 + lam1 ** 4)] * 2, rel=1e-10)
    assert long[2:] == pytest.approx([mu1 / (np.sqrt(2) * lam1), mu1 / (np.sqrt(2) * lam1 ** 2)],
                                     rel=1e-10)
    assert short[1] == pytest.approx(lam1, rel=1e-12)


def test_circulation_geometry_matches_4_10():
    """
    Circulation geometry matches (4.10).

    On a real circulation y' = λ1B2y + μ1dΔ (time τ1) up to terms of order λ1μ (001: 'accuracy
    λ1μ1').
    """
    period = 420.0
    lam1 = SHIP.schuler_rate * period / (2 * np.pi)
    m = circulation(SHIP, np.radians(50), period)
    for tau in (0.0, 0.05):
        G1, _, G1d, _, B, b, k = _transformed(m, tau, h=1e-5)
        Ay_tau1 = (G1 @ B + G1d) @ np.linalg.inv(G1) * lam1                # d/dτ1 = λ1 d/dτ
        assert np.abs(Ay_tau1 - lam1 * B2).max() < 1.5 * lam1 * SHIP.mu
        v, V1, V2 = k['omega2'], k['V1'], k['V2']
        d = np.array([0, V1 - SHIP.mu1 / v, 0, V2])
        assert np.abs(G1 @ b * lam1 - SHIP.mu1 * d).max() < 1.5 * lam1 * SHIP.mu


# ------------------------------------------------------------------- the stationary filters
def test_asymptotic_observer_gains_scale_as_one_over_c():
    """001: the observer gains of y3, y4, Δ are ∝ 1/(μ sin φ); those of y1, y2 stay finite."""
    poles = [-1.0, -1.5, -2.0, -2.5, -3.0]
    L = {}
    for c in (0.04, 0.02):
        A, H = ship_system(c, 0.6)
        L[c] = pole_placement_gain(A, H, poles)
        eig = np.sort(np.linalg.eigvals(A - np.outer(L[c], H[0])).real)
        assert eig == pytest.approx(sorted(poles), abs=1e-8)
    assert L[0.02][2:] / L[0.04][2:] == pytest.approx([2.0] * 3, rel=0.01)
    assert L[0.02][:2] / L[0.04][:2] == pytest.approx([1.0] * 2, rel=0.01)


def test_steady_state_kalman_filter_riccati_and_nees():
    """
    Steady-state Kalman filter: the Riccati solution and the NEES.

    The doubling solution satisfies the DARE; a small Monte Carlo of the constant-gain filter stays
    in the χ² band of its exactly propagated covariance.
    """
    c = SHIP.mu * np.sin(np.radians(55))
    A, H = ship_system(c, np.cos(np.radians(55)))
    h, ds, q = 0.02, 0.1 * SHIP.mu, 1e-3
    Phi, Q = discretize(A, np.eye(5) * q ** 2, h)
    R = np.array([[ds ** 2 / h]])
    P, K, _ = steady_state_gain(Phi, H, Q, R)
    rhs = Phi @ P @ Phi.T - Phi @ P @ H.T @ np.linalg.inv(H @ P @ H.T + R) @ H @ P @ Phi.T + Q
    assert np.abs(rhs - P).max() < 1e-10 * np.abs(P).max()
    assert Phi == pytest.approx(np.eye(5) + A * h + A @ A * h * h / 2, abs=h ** 3)
    steps, runs = 400, 60
    P0 = np.eye(5)
    Ps = constant_gain_covariance(Phi, H, Q, R, K, P0, steps)
    err = simulate_constant_gain(Phi, H, Q, R, K, P0, steps, runs, np.random.default_rng(7))
    # mean over runs
    nees = np.einsum('rki,kij,rkj->rk', err, np.linalg.inv(Ps), err).mean(axis=0)
    # mean of `runs` χ²(5) values: 5 ± 3.3·√(10/runs) holds at each epoch with prob. ≈ 0.999
    band = 3.3 * np.sqrt(10 / runs)
    sel = nees[::50]
    assert np.all(np.abs(sel - 5) < band), sel


# ------------------------------------------------------------------- the report tool
def test_seeds_001_tool_quick(tmp_path, capsys):
    """
    Seeds-001 report tool runs quickly and reports argument errors in one line.

    section_001 → report_001 → main: numbers against the derivations, and a one-line argument
    error.

    Parameters
    ----------
    tmp_path : fixture
        Temporary directory of the test.
    capsys : fixture
        Capture of the standard output and error.

    """
    res = seeds_001.section_001(quick=True)
    assert res['misprints']['h1_corrected_rel_error'] < 1e-6
    assert res['misprints']['h1_printed_prefactor_rel_error'] == pytest.approx(
        1 - SHIP.mu1 / SHIP.mu, rel=1e-4)
    c = res['ship']['c']
    assert res['ship']['derivative'][2] == pytest.approx(np.sqrt(2) * c, rel=5 * c)
    lam1, mu1 = res['circulation']['lam1'], res['circulation']['mu1']
    assert res['circulation']['derivative']['unit'][2] == pytest.approx(
        lam1 * mu1 / np.sqrt(1 + lam1 ** 4), rel=1e-9)
    text = seeds_001.report_001(res)
    assert text.startswith('## 001')
    assert "consistent with the filter's propagated covariance" in text
    import json
    json.dumps(res)                                                       # JSON-able
    if __import__('importlib').util.find_spec('matplotlib'):
        files = seeds_001.plots_001(res, str(tmp_path))
        assert all(f.endswith('.png') and (tmp_path / f.split('/')[-1]).exists() for f in files)
    with pytest.raises(SystemExit) as e:
        seeds_001.main(['--bogus'])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('vavilov1982: error:')


def test_001_derivation_text_is_labelled_and_its_checks_exist():
    """
    001 derivation text is labelled and its checks exist.

    The hand-written derivations say so, claim orders (001 prints no numbers), and every
    check command they name selects existing tests.
    """
    assert 'derivation text, not computed' in DERIVATIONS_001
    assert "reproduces 001's numbers" not in DERIVATIONS_001
    checks = re.findall(r"pytest (test/\S+\.py) -k '?([^'`]+)'?`", DERIVATIONS_001)
    assert len(checks) >= 8
    root = pathlib.Path(__file__).resolve().parent.parent.parent
    for path, expr in checks:
        names = re.findall(r'^def (test_\w+)', (root / path).read_text(), re.M)
        for token in expr.split(' or '):
            assert any(token.strip() in n for n in names), (path, token)
    # verdicts print their threshold beside them
    assert seeds_001.order_verdict(0.82, 1.0) == 'same order (×0.82, within 10×)'
    assert seeds_001.order_verdict(0.05, 1.0) == 'smaller by ×0.05 (not within 10×)'
