"""
Earth-referenced navigation profiles: truth checked against independent references.

* kinematics: 5-point central differences of position / velocity / attitude;
* specific force: second difference of the *inertial* position (C_I_E(t) R(t)) minus gravitation,
  rotated with the inertial attitude, so the Coriolis/centrifugal signs and q_I_B are checked;
* increments: closed forms (static; Δθ of the constant-rate profiles via PiecewiseRateProfile's
  Rodrigues integral) and a Gauss–Legendre rule with twice the nodes and sub-intervals;
* coordinated turn: lateral specific force; sculling: periodic velocity and the drift formula.
"""

import numpy as np
import pytest

from strapdown_ros.earth import enu_rotation, geodetic_to_ecef, normal_gravity, OMEGA
from strapdown_ros.motion.earth_motion import EarthProfile
from strapdown_ros.motion.earth_profiles import (coordinated_turn_profile,
                                                 navigation_profile_from_config,
                                                 NAVIGATION_PROFILE_NAMES, sculling_drift_rate,
                                                 sculling_profile, static_profile,
                                                 straight_flight_profile)
from strapdown_ros.motion.from_config import profile_from_config, PROFILE_NAMES
from strapdown_ros.motion.profiles import PiecewiseRateProfile, Segment
from strapdown_ros.rotation import (quat_angle_between, quat_conjugate, quat_multiply, quat_to_dcm,
                                    quat_to_rotvec)

LAT, LON, H = np.radians(50.45), np.radians(30.52), 150.0

PROFILES = {
    'static': lambda: static_profile(LAT, LON, H, yaw=0.3, pitch=0.1, roll=-0.2),
    'straight': lambda: straight_flight_profile(LAT, LON, H, speed=250.0, heading=0.7),
    'turn': lambda: coordinated_turn_profile(LAT, LON, H, speed=100.0, radius=2000.0, heading=0.4),
    # 1 Hz: slow enough for finite differences on ECEF coordinates of 6.4e6 m
    'sculling_1hz': lambda: sculling_profile(LAT, LON, H, angle_amplitude=0.02,
                                             accel_amplitude=1.0, frequency=1.0, yaw=0.5),
    'sculling': lambda: sculling_profile(LAT, LON, H, angle_amplitude=0.01, accel_amplitude=1.0,
                                         frequency=10.0),
    'sculling_slow': lambda: sculling_profile(LAT, LON, H, angle_amplitude=0.05,
                                              accel_amplitude=0.5, frequency=0.2, yaw=-1.0),
}
FD = [(-2, 1 / 12), (-1, -8 / 12), (1, 8 / 12), (2, -1 / 12)]      # 5-point first derivative
# 5-point second derivative
FD2 = [(-2, -1 / 12), (-1, 16 / 12), (0, -30 / 12), (1, 16 / 12), (2, -1 / 12)]
TIMES = np.array([0.0, 0.37, 3.3, 41.7, 117.0])


def derivative(fun, t, dt):
    return sum(w * fun(t + k * dt) for k, w in FD) / dt


def rate_from(att, t, dt):
    """d/ds log(q(t)* ⊗ q(t+s)) at s = 0: the body-axis rate of the attitude function ``att``."""
    q = att(t)
    return derivative(lambda s: quat_to_rotvec(quat_multiply(quat_conjugate(q), att(s))), t, dt)


@pytest.mark.parametrize('name', ['static', 'straight', 'turn', 'sculling_1hz'])
def test_finite_differences_match_velocity_acceleration_and_rates(name):
    p = PROFILES[name]()
    dt = 0.01
    t = TIMES
    # position → velocity: round-off of 6.4e6 m coordinates (1e-9 m) / dt and dt⁴ truncation:
    # ≤ 1e-6 m/s
    np.testing.assert_allclose(derivative(p.position, t, dt), p.velocity(t), rtol=0, atol=1e-6)
    # velocity → acceleration: truncation dt⁴·max|R⁽⁵⁾|/30 = 2e-8 m/s² for the 1 Hz sculling
    np.testing.assert_allclose(derivative(p.velocity, t, dt / 2), p.acceleration(t), rtol=0,
                               atol=5e-8)
    # attitude → rates: q_E_B gives ω_EB, q_I_B the absolute body rate (1e-10 rad/s;
    # truncation 7e-12)
    np.testing.assert_allclose(rate_from(p.attitude_ecef, t, dt / 10), p.earth_relative_rate(t),
                               rtol=0, atol=1e-10)
    np.testing.assert_allclose(rate_from(p.attitude, t, dt / 10), p.body_rate(t), rtol=0,
                               atol=1e-10)


@pytest.mark.parametrize('name', ['static', 'straight', 'turn', 'sculling_slow'])
def test_specific_force_from_inertial_acceleration(name):
    """
    Check f = C_B_I (r̈_I − G): r_I = C_I_E(t) R(t) differenced twice, G = g − centrifugal.

    Tolerance 1e-5 m/s² (1 µg): the ECEF coordinates carry ~1e-9 m of round-off, which a second
    difference with dt = 0.05 s amplifies to ~2e-6 m/s²; Coriolis is 1e-2…4e-2 m/s² here.
    """
    p = PROFILES[name]()
    r0 = p.initial_position
    dt = 0.05

    def rz(s):
        return np.stack([np.stack([np.cos(OMEGA * s), -np.sin(OMEGA * s), 0 * s], -1),
                         np.stack([np.sin(OMEGA * s), np.cos(OMEGA * s), 0 * s], -1),
                         np.stack([0 * s, 0 * s, 1 + 0 * s], -1)], -2)

    # r_I = C_I_E(R − R0) + C_I_E R0; the second term's second derivative is analytic
    def moving(s):
        return rz(s) @ (p.position(s) - r0)

    for t in TIMES:
        acc_i = sum(w * moving(t + k * dt) for k, w in FD2) / dt ** 2
        acc_i = acc_i + rz(t) @ (np.array([-OMEGA ** 2, -OMEGA ** 2, 0.0]) * r0)
        r = p.position(t)
        centrifugal = OMEGA ** 2 * np.array([r[0], r[1], 0.0])
        gravitation = normal_gravity(r, model=p.gravity_model) - centrifugal
        f_i = acc_i - rz(t) @ gravitation
        f_b = quat_to_dcm(p.attitude(t)).T @ f_i
        np.testing.assert_allclose(f_b, p.specific_force(t), rtol=0, atol=1e-5)


def test_static_closed_forms():
    yaw = 0.8
    p = static_profile(LAT, LON, H, yaw=yaw)
    t = np.linspace(0.0, 600.0, 7)
    g = normal_gravity(geodetic_to_ecef(LAT, LON, H))
    f = p.specific_force(t)
    np.testing.assert_allclose(np.linalg.norm(f, axis=-1), np.linalg.norm(g), rtol=1e-15)
    np.testing.assert_allclose(f, np.broadcast_to(f[0], f.shape), rtol=0, atol=1e-14)
    # level: f along body up, up to the model's deflection from the ellipsoid normal: 003's
    # first-order formula ≈ 2.2″ here (1.05e-4 m/s² north), the exact normal field < 1.5e-7 rad
    assert np.all(np.hypot(f[:, 0], f[:, 1]) < 1.2e-4) and np.all(f[:, 2] > 9.8)
    exact = static_profile(LAT, LON, H, yaw=yaw, gravity_model='normal_exact')
    f_exact = exact.specific_force(0.0)
    assert np.hypot(f_exact[0], f_exact[1]) < 1.5e-6
    # Earth rate in ENU is Ω[0, cos φ, sin φ]; body = ENU turned by yaw about up
    w_enu = OMEGA * np.array([0.0, np.cos(LAT), np.sin(LAT)])
    c_body_enu = np.array([[np.cos(yaw), np.sin(yaw), 0], [-np.sin(yaw), np.cos(yaw), 0],
                           [0, 0, 1]])
    w_body = c_body_enu @ w_enu
    np.testing.assert_allclose(p.body_rate(t), np.broadcast_to(w_body, (7, 3)), rtol=0, atol=1e-19)
    np.testing.assert_allclose(quat_to_dcm(p.attitude_ecef(0.0))[:, 0],
                               enu_rotation(LAT, LON) @ [np.cos(yaw), np.sin(yaw), 0], atol=1e-15)
    # increments are exactly rate × length
    t0 = np.arange(0, 1000) / 300.0 + 17.0
    t1 = t0 + 1 / 300.0
    np.testing.assert_allclose(p.delta_v(t0, t1), f[0] * (t1 - t0)[:, None], rtol=1e-13, atol=0)
    np.testing.assert_allclose(p.delta_theta(t0, t1), w_body * (t1 - t0)[:, None], rtol=1e-13,
                               atol=0)
    np.testing.assert_allclose(p.delta_v(0.0, 600.0), f[0] * 600.0, rtol=1e-14)
    np.testing.assert_allclose(p.velocity(t), 0.0)


@pytest.mark.parametrize('name', ['static', 'straight', 'turn'])
def test_delta_theta_and_attitude_match_closed_form_rodrigues(name):
    """ω_EB constant in body axes: PiecewiseRateProfile integrates ω_EB + C_B_E Ω_E exactly."""
    p = PROFILES[name]()
    w = p.earth_relative_rate(0.0)
    # Δθ depends only on q_E_B at the interval start: one reference per block start T, so that
    # the reference's ∫_0^{t1−T} − ∫_0^{t0−T} does not cancel away its own accuracy
    for T in (0.0, 500.0):
        ref = PiecewiseRateProfile([Segment(1e6, w)], initial_attitude=p.attitude_ecef(T),
                                   earth_rate=(0.0, 0.0, OMEGA))
        t0 = T + np.concatenate([np.arange(0, 300) / 300.0, [0.0, 3.0]])
        t1 = t0 + 1 / 300.0
        t1[-2:] = T + np.array([100.0, 3.7])
        s0, s1 = t0 - T, t1 - T                                   # exact: same interval lengths
        got, exact = p.delta_theta(t0, t1), ref.delta_theta(s0, s1)
        scale = np.linalg.norm(ref.body_rate(s0), axis=-1) * (s1 - s0)
        assert np.max(np.linalg.norm(got - exact, axis=-1) / scale) < 1e-12
    ref = PiecewiseRateProfile([Segment(1e6, w)], initial_attitude=p.attitude_ecef(0.0),
                               earth_rate=(0.0, 0.0, OMEGA))
    t = np.linspace(0.0, 600.0, 31)
    assert np.max(quat_angle_between(p.attitude(t), ref.attitude(t))) < 1e-12


@pytest.mark.parametrize('name', list(PROFILES))
@pytest.mark.parametrize('kind', ['delta_v', 'delta_theta'])
def test_quadrature_converges_against_doubled_rule(name, kind):
    p = PROFILES[name]()
    fun = p.specific_force if kind == 'delta_v' else p.body_rate
    h = 1 / 300.0
    t0 = np.concatenate([np.arange(0, 600) * h, 55.0 + np.arange(0, 300) * h])
    t1 = t0 + h
    default = getattr(p, kind)(t0, t1)
    n_sub, n_pts = p.quadrature_rule(h)
    finer = p.integrate(fun, t0, t1, points=2 * n_pts, subintervals=2 * n_sub)
    scale = h * np.max(np.linalg.norm(fun(np.linspace(0, 2, 2001)), axis=-1))
    assert np.max(np.linalg.norm(default - finer, axis=-1)) / scale < 1e-12
    # long intervals (several sub-intervals)
    t0, t1 = np.array([0.0, 1.3]), np.array([20.0, 9.1])
    n_sub, n_pts = p.quadrature_rule(20.0)
    long_default = getattr(p, kind)(t0, t1)
    long_finer = p.integrate(fun, t0, t1, points=2 * n_pts, subintervals=2 * n_sub)
    assert np.max(np.linalg.norm(long_default - long_finer, axis=-1)) / (scale / h * 20.0) < 1e-12
    # additivity: the long interval equals the sum of its pieces
    edges = np.linspace(1.3, 9.1, 2341)
    pieces = getattr(p, kind)(edges[:-1], edges[1:]).sum(0)
    assert np.linalg.norm(pieces - long_default[1]) / (scale / h * 7.8) < 1e-12


def test_long_run_is_one_vectorised_call():
    """10 min at 300 Hz in one call each (the speed is a benchmark's: nav_bench, not a test)."""
    p = PROFILES['sculling']()
    t = np.arange(0, 600 * 300 + 1) / 300.0
    dv = p.delta_v(t[:-1], t[1:])
    dth = p.delta_theta(t[:-1], t[1:])
    assert dv.shape == dth.shape == (180000, 3)
    assert np.all(np.isfinite(dv)) and np.all(np.isfinite(dth))


def test_straight_flight_geometry():
    p = PROFILES['straight']()
    t = np.linspace(0.0, 3600.0, 50)
    tr = p.truth(t)
    r0 = np.linalg.norm(p.initial_position)
    np.testing.assert_allclose(np.linalg.norm(tr['position'], axis=-1), r0, rtol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(tr['velocity'], axis=-1), 250.0, rtol=1e-14)
    c = quat_to_dcm(tr['attitude_ecef'])
    np.testing.assert_allclose(c[..., 0], tr['velocity'] / 250.0, atol=1e-14)   # x along velocity
    np.testing.assert_allclose(c[..., 2], tr['position'] / r0, atol=1e-14)      # z geocentric up
    np.testing.assert_allclose(tr['velocity_body'], np.broadcast_to([250.0, 0, 0], (50, 3)),
                               atol=1e-11)
    # the initial direction is the ENU heading (up to the geodetic/geocentric up difference)
    enu = enu_rotation(LAT, LON).T @ p.initial_velocity
    # (projecting on the plane ⟂ R0 turns the azimuth by 5e-6 rad here)
    assert abs(np.arctan2(enu[1], enu[0]) - 0.7) < 1e-5 and abs(enu[2]) < 250 * 4e-3
    np.testing.assert_allclose(tr['height'][0], H, atol=1e-6)


def _turn_truth(**kw):
    p = coordinated_turn_profile(LAT, LON, H, speed=100.0, radius=2000.0, heading=0.4, **kw)
    t = np.linspace(0.0, 2 * np.pi * 2000.0 / 100.0, 721)            # one full circle
    tr = p.truth(t)
    c = quat_to_dcm(tr['attitude_ecef'])
    f_rel = np.einsum('...ji,...j->...i', c, tr['acceleration'] - tr['gravity'])
    return p, tr, f_rel


def test_coordinated_turn_is_coordinated():
    # Earth-relative specific force C_B_E(R̈ − g) has no lateral component, up to what a constant
    # bank on a plane circle cannot follow.  Measured max |f_y|:
    # * exact normal field: 1.2e-5 m/s² (|g| grows 1.6e-5 m/s² northwards across the circle, seen
    #   through sin β, plus the ellipsoid's curvature anisotropy of the vertical's tilt, 4e-6);
    # * pz90_003: 8.9e-5 m/s² - that model's vertical is 2.2″ (1.05e-4 m/s² north) off the
    #   ellipsoid normal, the circle's plane is ⟂ the geodetic up, and the body turns through it.
    p, tr, f_rel = _turn_truth(gravity_model='normal_exact')
    assert np.max(np.abs(f_rel[:, 1])) < 1.5e-5
    assert np.max(np.abs(f_rel[:, 0])) < 1e-5
    # f_z = √(g² + (v²/ρ − gρ/R)²): the centripetal term less the outward tilt of the vertical
    g0 = p.parameters['g0']
    f_z = np.hypot(g0, 100.0 ** 2 / 2000.0 - g0 * 2000.0 / 6.382e6)
    np.testing.assert_allclose(f_rel[:, 2], f_z, rtol=3e-6)
    assert _turn_truth()[0].gravity_model == 'normal_exact'            # the package default
    p3, tr3, f3 = _turn_truth(gravity_model='pz90_003')
    assert np.max(np.abs(f3[:, 1])) < 1.2e-4 and np.max(np.abs(f3[:, 0])) < 1.2e-4
    # with the nominal atan(v²/ρg0) bank the tilt ρ/R of the vertical leaves ~ g·ρ/R·cos β = 2.7e-3
    _, _, f_nom = _turn_truth(gravity_model='normal_exact', bank=p.parameters['bank_nominal'])
    assert 2e-3 < np.mean(np.abs(f_nom[:, 1])) < 3.5e-3
    # tan β = (v²/ρ − gρ/R)/g  ⇒  β ≈ β_nominal − (ρ/R) cos²β
    bn = p.parameters['bank_nominal']
    assert abs(p.parameters['bank'] - (bn - 2000.0 / 6.382e6 * np.cos(bn) ** 2)) < 1e-6
    # the rest of the sensed lateral force is Coriolis, ≤ 2Ωv
    coriolis_y = tr['specific_force'][:, 1] - f_rel[:, 1]
    assert 0.5 * OMEGA * 100.0 < np.max(np.abs(coriolis_y)) <= 2 * OMEGA * 100.0
    # closed circle, constant speed, body x along velocity; the height rises by ρ²/2R
    np.testing.assert_allclose(tr['position'][-1], tr['position'][0], atol=1e-8)
    np.testing.assert_allclose(tr['velocity_body'], np.broadcast_to([100.0, 0, 0], (721, 3)),
                               atol=1e-11)
    np.testing.assert_allclose(tr['height'], H + 2000.0 ** 2 / (2 * 6.38e6), atol=0.01)
    assert np.ptp(tr['height']) < 5e-3
    radius = np.linalg.norm(tr['position'] - p.parameters['centre'], axis=-1)
    np.testing.assert_allclose(radius, 2000.0, rtol=1e-12)


def test_sculling_velocity_is_periodic_and_drift_formula_matches():
    A, B, fz = 0.01, 1.0, 10.0
    p = sculling_profile(LAT, LON, H, angle_amplitude=A, accel_amplitude=B, frequency=fz)
    w = 2 * np.pi * fz
    t = np.linspace(0.0, 30.0, 301) + 0.0123
    # to the round-off of the phase w·t (~1e-13 of B/w = 0.016 m/s)
    np.testing.assert_allclose(p.velocity(t + 1 / fz), p.velocity(t), rtol=0, atol=1e-14)
    np.testing.assert_allclose(p.velocity(t + 0.5 / fz), -p.velocity(t), rtol=0, atol=1e-14)
    mean_v = np.mean(p.velocity(np.arange(0, 100) / (100 * fz)), axis=0)
    np.testing.assert_allclose(mean_v, 0.0, atol=1e-16)
    np.testing.assert_allclose(p.initial_velocity, -(B / w) * enu_rotation(LAT, LON)[:, 1],
                               atol=1e-15)
    after_period = quat_angle_between(p.attitude_ecef(t + 1 / fz), p.attitude_ecef(t))
    np.testing.assert_allclose(after_period, 0, atol=1e-9)
    # ½∫(α×f + v×ω) dt over each interval, α, v the exact increments from the interval start
    h = 1 / 300.0
    t0 = 3.0 + np.arange(600) * h + 1e-4                     # 20 sculling periods, all phases
    x, wts = np.polynomial.legendre.leggauss(16)
    nodes = t0[:, None] + 0.5 * h * (x + 1.0)                # (600, 16)
    alpha = p.delta_theta(np.broadcast_to(t0[:, None], nodes.shape), nodes)
    vel = p.delta_v(np.broadcast_to(t0[:, None], nodes.shape), nodes)
    integrand = np.cross(alpha, p.specific_force(nodes)) + np.cross(vel, p.body_rate(nodes))
    sculling = 0.5 * 0.5 * h * np.einsum('k,nkj->nj', wts, integrand)
    rate = sculling.mean(0) / h
    b_eff = p.parameters['effective_accel_amplitude']
    assert abs(b_eff - (B + A * 9.81)) < 1e-3
    expected = sculling_drift_rate(A, b_eff, w, h)
    assert abs(rate[2] - expected) < 0.01 * expected
    assert np.all(np.abs(rate[:2]) < 0.05 * expected)
    # per interval the z term is the same whatever the phase (to the gravity/Earth-rate couplings)
    assert np.std(sculling[:, 2]) < 0.02 * np.mean(sculling[:, 2])
    # the nominal B alone would be off by A·g/B ≈ 10 %
    assert abs(rate[2] - sculling_drift_rate(A, B, w, h)) > 0.05 * expected


def test_sculling_drift_rate_series_and_values():
    np.testing.assert_allclose(sculling_drift_rate(0.01, 1.0, 2 * np.pi * 10, 1 / 300.0),
                               0.005 * (1 - np.sin(2 * np.pi / 30) / (2 * np.pi / 30)), rtol=1e-12)
    x = np.array([1e-4, 5e-3, 0.0099, 0.0101])
    exact = 1 - np.sin(x) / x                                # adequate for x ≥ 1e-2 only
    series = sculling_drift_rate(2.0, 1.0, x, 1.0)
    np.testing.assert_allclose(series[2:], exact[2:], rtol=1e-9)
    np.testing.assert_allclose(series[:2], x[:2] ** 2 / 6 - x[:2] ** 4 / 120, rtol=1e-9)
    assert sculling_drift_rate(0.01, 1.0, 0.0, 0.01) == 0.0


def test_profile_from_config_builds_navigation_profiles():
    assert set(NAVIGATION_PROFILE_NAMES) <= set(PROFILE_NAMES)
    for name in NAVIGATION_PROFILE_NAMES:
        p = profile_from_config({'profile': name})
        assert isinstance(p, EarthProfile) and p.name == name
        start = geodetic_to_ecef(np.radians(50.45), np.radians(30.52), 150.0)
        np.testing.assert_allclose(p.initial_position,
                                   start if name != 'coordinated_turn' else p.initial_position)
    cfg = {'profile': 'coordinated_turn', 'nav_latitude_deg': -33.0, 'nav_longitude_deg': 151.0,
           'nav_height': 10.0, 'nav_speed': 60.0, 'nav_heading_deg': 90.0, 'turn_radius': 500.0}
    p = profile_from_config(cfg)
    assert p.parameters['speed'] == 60.0 and p.parameters['radius'] == 500.0
    lat, lon = np.radians(-33.0), np.radians(151.0)
    np.testing.assert_allclose(p.parameters['centre'], geodetic_to_ecef(lat, lon, 10.0))
    np.testing.assert_allclose(enu_rotation(lat, lon).T @ p.initial_velocity,
                               [0.0, 60.0, 0.0], atol=1e-12)               # heading 90° = north
    s = navigation_profile_from_config({'profile': 'sculling', 'sculling_angle': 0.02,
                                        'sculling_accel': 2.0, 'sculling_frequency': 5.0})
    assert s.parameters['angle_amplitude'] == 0.02
    assert s.parameters['omega'] == pytest.approx(10 * np.pi)
    assert straight_flight_profile(LAT, LON, H).parameters['speed'] == 200.0
    assert profile_from_config({'profile': 'straight_flight'}).parameters['speed'] == 200.0
    with pytest.raises(ValueError):
        navigation_profile_from_config({'profile': 'coning'})
