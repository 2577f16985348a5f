"""
Navigation channel (003 §1.5) against exact truth.

The specific-force integrals, the printed misprints, the recursion on the rotating Earth and
the static alignment.
"""
from fractions import Fraction

import numpy as np
import pytest

from strapdown_ros import earth as G
from strapdown_ros.attitude.integrator import AttitudeIntegrator
from strapdown_ros.motion.earth_profiles import navigation_profile_from_config, static_profile
from strapdown_ros.navigation import update
from strapdown_ros.navigation.alignment import static_alignment
from strapdown_ros.navigation.covariance import contract_blocks, NavigationCovariance
from strapdown_ros.navigation.navigator import Navigator
from strapdown_ros.navigation.run import run_profile, summarize
from strapdown_ros.navigation.update import (coefficient_table, derived_coefficients, FORMS,
                                             PRINTED_COEFFICIENTS, specific_force_integrals,
                                             step_layout)
from strapdown_ros.rotation import dcm_to_quat
from strapdown_ros.sensors.covariance import constant_jacobian
from strapdown_ros.sensors.model import (IntegratingSensor, NAVIGATION_GRADE_ACCEL,
                                         NAVIGATION_GRADE_GYRO, SensorSigmas)

GRADE = (NAVIGATION_GRADE_GYRO, NAVIGATION_GRADE_ACCEL)


def _quadratic_case(h=0.01):
    """Return f(s) = c + d s + e s²/2 without rotation: exact increments and integrals."""
    c = np.array([1.0, 2.0, -9.8])
    d = np.array([50.0, -20.0, 10.0])
    e = np.array([3000.0, 1000.0, -2000.0])

    def F(s):
        return c * s + d * s ** 2 / 2 + e * s ** 3 / 6
    edges = np.linspace(0.0, h, 4)
    u = np.array([F(b) - F(a) for a, b in zip(edges[:-1], edges[1:])])[None]
    return u, F(h), c * h ** 2 / 2 + d * h ** 3 / 6 + e * h ** 4 / 24


def test_fit_of_003_equals_the_printed_1_98_values_and_the_derived_integrals_are_exact():
    """The accelerometer fit is (1.98) as printed; the derived forms integrate it exactly."""
    u, dv_true, dr_true = _quadratic_case()
    lay = step_layout(1, 3)
    # (1.98) for τ = 1: c = (11u1 − 7u2 + 2u3)/2, d = −9(2u1 − 3u2 + u3), e = 27(u1 − 2u2 + u3)
    np.testing.assert_allclose(lay.accel_fit * [[1], [1], [1]],
                               [[5.5, -3.5, 1.0], [-18.0, 27.0, -9.0], [27.0, -54.0, 27.0]],
                               atol=1e-12)
    q = np.zeros((1, 2, 3))
    for form in ('exact', 'series'):
        dv, dr = specific_force_integrals(q, u, np.array([0.01]), lay, form)
        np.testing.assert_allclose(dv[0], dv_true, rtol=1e-13)
        np.testing.assert_allclose(dr[0], dr_true, rtol=1e-13)
    dv, dr = specific_force_integrals(q, u, np.array([0.01]), lay, 'printed')
    # the printed leading terms 10u1 − 17u2 + 10u3 and 2u1 − 7/4u2 + 5/4u3 fail a quadratic force
    assert np.max(np.abs(dv[0] - dv_true)) / np.max(np.abs(dv_true)) > 1e-2
    assert np.max(np.abs(dr[0] - dr_true)) / np.max(np.abs(dr_true)) > 1e-3


def test_derived_coefficients_and_the_misprints_of_1_99_and_1_100():
    """The derived coefficients, and exactly which printed ones are misprints."""
    d = derived_coefficients()
    assert d['velocity']['u'] == (1, 1, 1)
    assert d['position']['u'] == (Fraction(7, 8), Fraction(1, 2), Fraction(1, 8))
    wrong = {(r['equation'], r['term'])
             for r in coefficient_table() if r['printed'] and not r['agrees']}
    assert wrong == {('1.99', 'u'), ('1.99', 'Q1Q2'), ('1.99', 'Q2Q1'), ('1.99', 'Q'),
                     ('1.99', 'Q1Q'), ('1.100', 'u'), ('1.100', 'Q2Q1'), ('1.100', 'Q2Q2')}
    # every other printed coefficient is confirmed exactly
    right = [r for r in coefficient_table() if r['printed'] and r['agrees']]
    assert len(right) == 9
    assert PRINTED_COEFFICIENTS['position']['Q2Q2'][2] == Fraction(101, 13446)      # 13440 derived


def test_series_agrees_with_the_quadrature_to_third_order():
    """The derived series and the quadrature differ at third order in the angle."""
    rng = np.random.default_rng(3)
    lay = step_layout(1, 3)
    errs = []
    for scale in (1e-2, 1e-3):
        q = rng.normal(size=(500, 2, 3)) * scale
        u = rng.normal(size=(500, 3, 3))
        a = specific_force_integrals(q, u, np.full(500, 0.01), lay, 'exact')[0]
        b = specific_force_integrals(q, u, np.full(500, 0.01), lay, 'series')[0]
        errs.append(np.max(np.abs(a - b)))
    assert errs[0] / errs[1] > 500             # O(q³): 1000× for a 10× smaller angle


def test_unknown_form_and_printed_outside_its_layout_are_refused():
    """An unknown form, and a printed form outside 003's layout, are refused."""
    with pytest.raises(ValueError, match='valid'):
        specific_force_integrals(np.zeros((1, 2, 3)), np.zeros((1, 3, 3)), np.ones(1),
                                 step_layout(1, 3), 'magic')
    with pytest.raises(ValueError, match='one gyro and three'):
        specific_force_integrals(np.zeros((1, 2, 3)), np.zeros((1, 6, 3)), np.ones(1),
                                 step_layout(2, 6), 'printed')
    assert 'exact' in FORMS


def _static_run(seconds, algorithm='2', scheme='exact', form='exact', tg=0.01, per=3):
    """Return the navigation of perfect sensors at rest in Kyiv, and the start position."""
    lat, lon, h = np.radians(50.45), np.radians(30.52), 150.0
    r0 = G.geodetic_to_ecef(lat, lon, h)
    v = G.enu_rotation(lat, lon)
    g = G.normal_gravity(r0[None], G.DEFAULT_GRAVITY_MODEL)[0]   # the Navigator default
    w_b, f_b = v.T @ np.array([0.0, 0.0, G.OMEGA]), -v.T @ g
    integ = AttitudeIntegrator(algorithm, initial_attitude=dcm_to_quat(v), initial_time=0.0,
                               nominal_period=tg)
    n_s = integ.algorithm.samples
    nav = Navigator(r0, np.zeros(3), 0.0, n_s, per * n_s, tg, tg / per, form=form, scheme=scheme,
                    covariance=NavigationCovariance(*GRADE, np.zeros((9, 9))))
    n = int(round(seconds / tg))
    t = np.arange(1, n + 1) * tg
    ta = np.arange(1, per * n + 1) * (tg / per)
    nav.add_gyro(np.tile(w_b * tg, (n, 1)), t)
    nav.add_accel(np.tile(f_b * tg / per, (per * n, 1)), ta)
    b = integ.push(np.tile(w_b * tg, (n, 1)), t)
    q_start = np.vstack([dcm_to_quat(v)[None], b.attitude[:-1]])
    nav.add_updates(b.stamps, b.interval, b.attitude, q_start)
    out = nav.process()
    return out, r0


def test_static_on_the_rotating_earth_with_perfect_sensors():
    """At rest with perfect sensors the derived navigation stays put; the printed one drifts."""
    out, r0 = _static_run(600.0)
    assert np.linalg.norm(out.position[-1] - r0) < 1e-5          # measured 1.6e-7 m after 10 min
    assert np.linalg.norm(out.velocity[-1]) < 1e-7
    # the printed update (D(t_k)U(t_{k-1}) on the whole increment, first-order Coriolis and
    # gravity)
    out_p, _ = _static_run(600.0, algorithm='one_plus_previous', scheme='printed', form='printed')
    assert np.linalg.norm(out_p.position[-1] - r0) > 0.1        # measured 0.39 m after 10 min
    # covariance: accelerometer bias through Schuler, about b/ω_s²·(1 − cos ω_s t) ≈ 80 m at 600 s
    sig = np.sqrt(np.diag(out.covariance[-1]))
    assert 30.0 < sig[0] < 300.0 and np.all(np.isfinite(sig))


def test_static_alignment_covariance_covers_the_errors_monte_carlo():
    """The alignment covariance matches Monte Carlo errors (mean NEES, 3σ region)."""
    rng = np.random.default_rng(11)
    lat, lon = np.radians(50.45), np.radians(30.52)
    r0 = G.geodetic_to_ecef(lat, lon, 150.0)
    gyro = SensorSigmas(bias_sigma=NAVIGATION_GRADE_GYRO.bias_sigma,
                        random_walk=NAVIGATION_GRADE_GYRO.random_walk)
    accel = SensorSigmas(bias_sigma=NAVIGATION_GRADE_ACCEL.bias_sigma,
                         random_walk=NAVIGATION_GRADE_ACCEL.random_walk)
    T = 120.0
    g = G.normal_gravity(r0[None], G.DEFAULT_GRAVITY_MODEL)[0]   # alignment default
    nees = []
    for _ in range(200):
        yaw = rng.uniform(-np.pi, np.pi)
        c, s = np.cos(yaw), np.sin(yaw)
        v = G.enu_rotation(lat, lon) @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
        f = (-v.T @ g + rng.normal(0, accel.bias_sigma, 3)
             + rng.normal(0, accel.random_walk / np.sqrt(T), 3))
        w = (v.T @ [0, 0, G.OMEGA] + rng.normal(0, gyro.bias_sigma, 3)
             + rng.normal(0, gyro.random_walk / np.sqrt(T), 3))
        res = static_alignment(f, w, r0, T, gyro, accel)
        assert res.ok, res.reason
        d = res.attitude @ v.T - np.eye(3)
        psi = np.array([d[2, 1], d[0, 2], d[1, 0]])
        nees.append(psi @ np.linalg.solve(res.covariance, psi))
    nees = np.array(nees)
    print(f'alignment mean NEES {nees.mean():.2f} over 200 draws, '
          f'{np.mean(nees < 14.2):.3f} within the 3σ region')
    # mean NEES of 3 dof within the χ² 95 % band for 200 draws: 3 ± 1.96·√(6/200)
    assert abs(nees.mean() - 3.0) < 1.96 * np.sqrt(6.0 / 200) * 1.2
    assert np.mean(nees < 14.2) > 0.98          # χ²₃ 99.7 %: "within 3σ"


def test_static_alignment_refuses_motion_and_the_pole():
    """Motion (specific force or rate) and a pole are refused with the reason."""
    r0 = G.geodetic_to_ecef(np.radians(50.0), 0.0, 0.0)
    g = G.normal_gravity(r0[None])[0]
    res = static_alignment(-g * 1.02, np.array([0.0, 0.0, 7e-5]), r0, 60.0, *GRADE)
    assert not res.ok and 'not static' in res.reason
    res = static_alignment(-g, np.array([0.0, 0.01, 0.0]), r0, 60.0, *GRADE)
    assert not res.ok and 'not static' in res.reason
    pole = G.geodetic_to_ecef(np.radians(89.5), 0.0, 0.0)
    gp = G.normal_gravity(pole[None])[0]
    res = static_alignment(-gp, np.array([0.0, 0.0, G.OMEGA]), pole, 60.0, *GRADE)
    assert not res.ok and 'heading unobservable' in res.reason


def test_navigation_covariance_is_consistent_monte_carlo():
    """
    The published [δR, δW] covariance matches Monte Carlo errors at rest.

    Default navigation-grade sensors (bias, scale, misalignment, random walk of gyros and
    accelerometers drawn anew each run), static on the rotating Earth for 120 s: the mean NEES
    of the published [δR, δW] covariance over 100 draws lies in the χ²₆ 95 % band.
    """
    prof = static_profile(np.radians(50.45), np.radians(30.52), 150.0, yaw=0.3)
    r0, q0 = prof.position(0.0), prof.attitude_ecef(0.0)
    T, tg, ta = 120.0, 0.01, 0.01 / 3
    nees = []
    for draw in range(100):
        rng = np.random.default_rng(1000 + draw)
        gyro = IntegratingSensor(prof, 'gyro', 100.0, NAVIGATION_GRADE_GYRO.draw(rng),
                                 seed=2 * draw)
        accel = IntegratingSensor(prof, 'accel', 300.0, NAVIGATION_GRADE_ACCEL.draw(rng),
                                  seed=2 * draw + 1)
        t_g, d_th, _ = gyro.sample(int(T / tg))
        t_a, d_v, _ = accel.sample(int(round(T / ta)))
        integ = AttitudeIntegrator('2', initial_attitude=q0, initial_time=0.0, nominal_period=tg,
                                   propagate_covariance=False)
        nav = Navigator(r0, np.zeros(3), 0.0, 2, 6, tg, ta,
                        covariance=NavigationCovariance(*GRADE, np.zeros((9, 9))))
        nav.add_gyro(d_th, t_g)
        nav.add_accel(d_v, t_a)
        b = integ.push(d_th, t_g)
        q_start = np.vstack([q0[None], b.attitude[:-1]])
        nav.add_updates(b.stamps, b.interval, b.attitude, q_start)
        out = nav.process()
        assert abs(out.stamps[-1] - T) < 1e-9
        err = np.concatenate([out.position[-1] - r0, out.velocity[-1]])
        nees.append(err @ np.linalg.solve(out.covariance[-1][:6, :6], err))
    mean = float(np.mean(nees))
    # χ²₆/6 mean over 100 draws: 6 ± 1.96·√(12/100)
    band = 1.96 * np.sqrt(2 * 6 / 100)
    print(f'mean NEES {mean:.2f} over 100 draws (band 6 ± {band:.2f})')
    assert abs(mean - 6.0) < band, (mean, band)


def test_one_sample_algorithm_starts_without_a_fake_rate_jump():
    """
    A one-sample algorithm starts without a fake rate jump.

    one_plus_previous fits the rate over the previous and the present gyro increment; at the
    start the previous one is before the data.  Read as zero it faked a rate jump (6e-5 m after
    30 s of the turn); continued at the first sample's rate the error stays at the float floor.
    """
    prof = navigation_profile_from_config({'profile': 'coordinated_turn'})
    s = summarize(run_profile(prof, 30.0, algorithm='one_plus_previous'))
    assert s['final_position_m'] < 1e-6


@pytest.mark.parametrize('layout', [(1, 3), (2, 6), (4, 12), (1, 1), (3, 3)])
def test_compiled_specific_force_loop_equals_the_numpy_path(monkeypatch, layout):
    """
    The compiled specific-force loop equals the numpy path to round-off.

    Parameters
    ----------
    monkeypatch : pytest.MonkeyPatch
        Sets ``STRAPDOWN_KERNEL``.
    layout : tuple of int
        Gyro and accelerometer increments per step.

    """
    monkeypatch.delenv('STRAPDOWN_KERNEL', raising=False)
    if not update.kernel_available():
        pytest.skip('numba not installed: only the numpy path exists here')
    lay = update.step_layout(*layout)
    rng = np.random.default_rng(sum(layout))
    k = 400
    q = rng.normal(0.0, 0.02, (k, lay.gyro_window, 3))
    q[:50] *= 1e-5                                      # the small-angle series branch as well
    u = rng.normal(0.0, 0.1, (k, lay.accel_window, 3))
    h = rng.uniform(0.005, 0.05, k)
    dv_c, dr_c = update.specific_force_integrals(q, u, h, lay)
    monkeypatch.setenv('STRAPDOWN_KERNEL', 'numpy')
    dv_n, dr_n = update.specific_force_integrals(q, u, h, lay)
    assert np.max(np.abs(dv_c - dv_n)) <= 1e-14 * np.max(np.abs(dv_n))
    assert np.max(np.abs(dr_c - dr_n)) <= 1e-14 * np.max(np.abs(dr_n))


def test_navigation_covariance_forcing_equals_the_effects_jacobians():
    """
    The covariance's forcing equals the sum of the effects' own Jacobians.

    The covariance sums V·[u, T] per epoch and multiplies by the Jacobian basis once; the sum
    of V_k·J(u_k, T_k) with the effects' own Jacobians per step must be the same.
    """
    rng = np.random.default_rng(3)
    k = 50
    v = rng.normal(size=(k, 3, 3))
    u = rng.normal(size=(k, 3))
    t = rng.uniform(0.001, 0.02, k)
    direct = np.einsum('kab,kbc->ac', v, constant_jacobian(u, t))
    w = np.concatenate([v[:, :, :, None] * u[:, None, None, :],
                        (v * t[:, None, None])[:, :, :, None]], axis=-1)
    np.testing.assert_allclose(contract_blocks(w.reshape(k, 3, 12).sum(0)[None])[0], direct,
                               rtol=1e-13, atol=1e-13)
