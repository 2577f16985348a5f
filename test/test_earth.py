"""
Normal gravity (003 §1.5.2) and geodesy helpers against independent truths.

Truths used: published WGS-84 / PZ-90.11 values (γ_e, γ_p, U0, J2), the level-ellipsoid
property (gravity ⟂ ellipsoid, potential constant on it), the spherical-harmonic series of
the normal field (J4 from Moritz's closed formula), finite differences of the potentials,
and closed geometric facts of the ellipsoid.  Nothing is compared with a value the module
printed.
"""
import math

import numpy as np
import pytest

from strapdown_ros import earth as G

RNG = np.random.default_rng(20261121)
LAT = np.radians(np.arange(-90.0, 90.0 + 1e-9, 5.0))


def _grid(h):
    la, lo = np.meshgrid(LAT, np.radians([0.0, 37.0, 143.0, -100.0]), indexing='ij')
    return la, lo, G.geodetic_to_ecef(la, lo, h)


def _angle_arcsec(a, b):
    c = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.degrees(np.arctan2(c, np.sum(a * b, axis=-1))) * 3600.0


def _random_points(n=50, hmax=1e5):
    return G.geodetic_to_ecef(RNG.uniform(-np.pi / 2, np.pi / 2, n), RNG.uniform(-np.pi, np.pi, n),
                              RNG.uniform(0.0, hmax, n))


def _fd_gradient(pot, r, d=1.0):
    return np.stack([(pot(r + d * e) - pot(r - d * e)) / (2 * d) for e in np.eye(3)], axis=-1)


# --- published constants -----------------------------------------------------------------
def test_somigliana_published_values():
    # WGS-84 (NIMA TR8350.2): γ_e = 9.7803253359, γ_p = 9.8321849379 m/s²
    assert abs(G.somigliana(0.0, G.WGS84) - 9.7803253359) < 1e-9
    assert abs(G.somigliana(np.pi / 2, G.WGS84) - 9.8321849379) < 1e-9
    # PZ-90.11: 003's g_e = 9.780318 is the rounded GRS-67 value; PZ-90.11's own γ_e is
    # 9.7803284 - they differ by 1.04e-5 m/s² (1 mGal), hence the 1.5e-5 tolerance.
    assert abs(G.somigliana(0.0) - G.GE) < 1.5e-5


def test_level_ellipsoid_constants():
    # J2 implied by (a, f, GM, ω) equals the published J2 (PZ-90.11, given to ±5e-12;
    # WGS-84 −√5·C̄20)
    assert abs(G.level_ellipsoid_j2() - 1082.62575e-6) < 5e-12
    assert abs(G.level_ellipsoid_j2(G.WGS84) - math.sqrt(5) * 0.484166774985e-3) < 1e-12
    # WGS-84 normal potential on the ellipsoid U0 = 62 636 851.7146 m²/s², at every latitude
    r = G.geodetic_to_ecef(LAT, 0.3, 0.0, G.WGS84.a, G.WGS84.f)
    assert np.max(np.abs(G.normal_potential(r, G.WGS84) - 62636851.7146)) < 1e-3


# --- the exact normal field --------------------------------------------------------------
@pytest.mark.parametrize('ell', [G.PZ90_11, G.WGS84])
def test_normal_exact_on_ellipsoid(ell):
    la, lo = np.meshgrid(LAT, np.radians([0.0, 75.0, -120.0]), indexing='ij')
    r = G.geodetic_to_ecef(la, lo, 0.0, ell.a, ell.f)
    g = G.normal_gravity_exact(r, ell)
    # magnitude = Somigliana's closed formula (a different expression)
    assert np.max(np.abs(np.linalg.norm(g, axis=-1) - G.somigliana(la, ell))) < 1e-11
    # the ellipsoid is a level surface: gravity along −(geodetic up) = −∇(X²/a²+Y²/a²+Z²/b²)
    b = ell.a * (1 - ell.f)
    n = r / np.array([ell.a ** 2, ell.a ** 2, b ** 2])
    assert np.max(_angle_arcsec(g, -n)) < 1e-6


def test_normal_exact_matches_harmonic_series():
    # normal field = J2 + J4 + J6 + …; J4 from Moritz's closed formula J2n(e², J2)
    j4 = -3 * G.E2 ** 2 / 35 * (1 - 2 + 10 * G.J2 / G.E2)           # −2.3709e-6

    def v4(r):
        rr = np.linalg.norm(r, axis=-1)
        s = r[..., 2] / rr
        return -G.GM / rr * j4 * (G.A / rr) ** 4 * (35 * s ** 4 - 30 * s ** 2 + 3) / 8

    for h in (0.0, 1e4, 1e5):
        r = _grid(h)[2]
        ex, j2 = G.normal_gravity(r, 'normal_exact'), G.normal_gravity(r, 'j2')
        dif = np.linalg.norm(ex - j2, axis=-1)
        assert 5e-5 < np.max(dif) < 1.3e-4          # the J4 term, measured 1.18e-4 m/s²
        # adding J4 leaves the J6 level (J6 = 6.1e-9 → ~4e-7 m/s², measured 4.3e-7)
        assert np.max(np.linalg.norm(j2 + _fd_gradient(v4, r) - ex, axis=-1)) < 1e-6
        assert np.max(_angle_arcsec(ex, j2)) < 1.5     # measured 1.30″


@pytest.mark.parametrize('model,pot', [('j2', G.j2_potential),
                                       ('normal_exact', G.normal_potential)])
def test_gravity_is_gradient_of_potential(model, pot):
    r = _random_points()
    g = G.normal_gravity(r, model)
    assert np.max(np.linalg.norm(_fd_gradient(pot, r) - g, axis=-1)) < 1e-7   # FD error ~1e-8
    assert np.all(_angle_arcsec(g, -r) < 700.0)        # plumb line within 11.6′ of −r̂


# --- the printed formula -----------------------------------------------------------------
def test_printed_structure_is_the_j2_field():
    # Derivation check: with the exact coefficients instead of Clairaut's first-order ones,
    #   g_e(1 − ½e² + 3/2η) → GM/a²,  g_e(e² − η) → 3·J2·GM/a²,
    # the corrected printed expressions are exactly the J2 gradient.
    g0 = G.GM / G.A ** 2
    eta = g0 - 1.0 + 1.5 * G.J2 * g0                        # solved with g_e = 1
    e2 = 3 * G.J2 * g0 + eta
    r = _random_points(hmax=1e6)
    g = G.printed_gravity_variant(r, e2=e2, eta=eta, ge=1.0)
    assert np.max(np.linalg.norm(g - G.normal_gravity(r, 'j2'), axis=-1)) < 1e-13


def test_printed_equatorial_value():
    # at (a, 0, 0) the formula reduces to −g_e(1 + η) + Ω²a = −g_e (η rounded to 8 digits)
    gx, gy, gz = G.printed_gravity_xyz(G.A, 0.0, 0.0)
    assert abs(gx + G.GE) < 1e-8 and gy == 0.0 and gz == 0.0


def test_corrected_printed_vs_exact_and_literal_fails():
    for h in (0.0, 1e3, 1e4, 2e4):
        r = _grid(h)[2]
        ex = G.normal_gravity(r, 'normal_exact')
        pr = G.normal_gravity(r, 'pz90_003')
        # first-order truncation: measured 3.47e-4 m/s² (34.7 mGal), 3.20″ at h = 0
        assert np.max(np.abs(np.linalg.norm(pr, axis=-1) - np.linalg.norm(ex, axis=-1))) < 4e-4
        assert np.max(_angle_arcsec(pr, ex)) < 3.5
        lit = np.array([G.printed_gravity_as_printed(*p)
                       for p in r.reshape(-1, 3)]).reshape(r.shape)
        assert np.max(_angle_arcsec(lit, ex)) > 600.0            # measured 694″
        for kw in ({'g2_omega_sign': 1.0}, {'gz_sign': -1.0}):   # one fix alone is not enough
            assert np.max(_angle_arcsec(G.printed_gravity_variant(r, **kw), ex)) > 600.0


def test_scalar_and_vectorised_agree():
    r = np.concatenate([_random_points(200, 1e6), [[0, 0, 6356751.0], [0, 0, -6356751.0],
                                                   [G.A, 0, 0], [0, -G.A, 0]]])
    vec = G.normal_gravity(r, 'pz90_003')
    sca = np.array([G.printed_gravity_xyz(*p) for p in r])
    assert np.max(np.abs(sca - vec)) <= 1e-15 * np.max(np.abs(vec))
    lit = np.array([G.printed_gravity_as_printed(*p) for p in r])
    ref = G.printed_gravity_variant(r, g2_omega_sign=1.0, gz_sign=-1.0)
    assert np.max(np.abs(lit - ref)) <= 1e-15 * np.max(np.abs(ref))
    assert sca[-4, 0] == 0.0 and sca[-4, 2] < -9.8                   # pole: no 0/0


def test_printed_is_numba_compilable():
    numba = pytest.importorskip('numba')
    f = numba.njit(G.printed_gravity_xyz)
    p = _random_points(3)[1]
    assert np.allclose(f(*p), G.printed_gravity_xyz(*p), rtol=1e-15, atol=0)


# --- registry and report -------------------------------------------------------------------
def test_registry_and_shapes():
    with pytest.raises(ValueError, match='normal_exact'):
        G.get_gravity_model('egm2008')
    r = _random_points(8).reshape(2, 4, 3)
    for name in G.GRAVITY_MODELS:
        assert G.normal_gravity(r, name).shape == (2, 4, 3)
        assert G.normal_gravity(r[0, 0], name).shape == (3,)
    c = G.compare_models(heights=(0.0,))[0.0]
    assert c['max_mag_mgal'] == pytest.approx(1e5 * c['max_mag']) and c['max_dir_arcsec'] < 3.5


# --- geodesy ---------------------------------------------------------------------------------
def test_geodetic_known_points():
    b = G.A * (1 - G.F)
    assert np.allclose(G.geodetic_to_ecef(0.0, 0.0, 0.0), [G.A, 0, 0], atol=1e-9, rtol=0)
    assert np.allclose(G.geodetic_to_ecef(0.0, np.pi / 2, 100.0),
                       [0, G.A + 100, 0], atol=1e-9, rtol=0)
    assert np.allclose(G.geodetic_to_ecef(np.pi / 2, 0.3, 0.0), [0, 0, b], atol=1e-9, rtol=0)
    assert abs(G.E2 - 0.0066943662) < 1e-10


def test_geodetic_round_trip():
    n = 2000
    lat = np.concatenate([RNG.uniform(-np.pi / 2, np.pi / 2, n), [np.pi / 2, -np.pi / 2, 0.0]])
    lon = RNG.uniform(-np.pi, np.pi, n + 3)
    h = np.concatenate([RNG.uniform(-1e3, 1e6, n), [0.0, 10.0, -5.0]])
    r = G.geodetic_to_ecef(lat, lon, h)
    la, lo, hh = G.ecef_to_geodetic(r)
    # float64 limit: 1 ulp of a coordinate in 4.2e6…8.4e6 m is 9.3e-10 m, and each direction
    # rounds a few times; measured 4.0e-9 m (ECEF) and 4.1e-9 m (h) over 1e5 random points
    assert np.max(np.linalg.norm(G.geodetic_to_ecef(la, lo, hh) - r, axis=-1)) < 6e-9
    assert np.max(np.abs(la - lat)) < 1e-14 and np.max(np.abs(hh - h)) < 6e-9
    inner = np.abs(lat) < np.pi / 2 - 1e-6
    assert np.max(np.abs(np.angle(np.exp(1j * (lo - lon)))[inner])) < 1e-12


def test_enu_rotation():
    lat, lon = RNG.uniform(-1.5, 1.5, 30), RNG.uniform(-3, 3, 30)
    c = G.enu_rotation(lat, lon)
    assert np.allclose(c.swapaxes(-1, -2) @ c, np.eye(3), atol=1e-15)
    assert np.allclose(np.linalg.det(c), 1.0)
    r = G.geodetic_to_ecef(lat, lon, 0.0)
    b = G.A * (1 - G.F)
    n = r / np.array([G.A ** 2, G.A ** 2, b ** 2])            # ellipsoid normal
    assert np.allclose(c[..., :, 2], n / np.linalg.norm(n, axis=-1)[..., None], atol=1e-15)
    east = np.cross([0.0, 0.0, 1.0], c[..., :, 2])
    assert np.allclose(c[..., :, 0], east / np.linalg.norm(east, axis=-1)[..., None], atol=1e-15)


def test_scalar_exact_field_and_the_compiled_loop_equal_the_vectorised_field():
    """
    Agree between the scalar and vectorised forms of the normal_exact gravity.

    gravity_model normal_exact is the default: its scalar form (compiled into the navigation
    loop) equals the vectorised closed form (independent code: arrays, series by np.where), and
    the loop run with it equals the same loop run with the vectorised field.
    """
    from strapdown_ros.navigation import recursion as R
    rng = np.random.default_rng(3)
    r = G.geodetic_to_ecef(rng.uniform(-np.pi / 2, np.pi / 2, 300),
                           rng.uniform(-np.pi, np.pi, 300), rng.uniform(-1e4, 1e6, 300))
    r = np.vstack([r, [[0.0, 0.0, 6356752.0], [6378136.0, 0.0, 0.0], [0.0, 0.0, -7.0e6]]])
    scalar = np.array([G.normal_exact_xyz(*x) for x in r])
    np.testing.assert_allclose(scalar, G.normal_gravity(r, 'normal_exact'), rtol=0, atol=1e-14)
    k = 400
    o = G.geodetic_to_ecef(np.radians(50.45), np.radians(30.52), 150.0)
    dv = np.tile([0.0, 0.0, 0.0981], (k, 1))
    h = np.full(k, 0.01)
    w0 = np.array([1.0, 2.0, 3.0])
    got = R.run(o, np.zeros(3), w0, dv, dv * 0.005, h, gravity_model='normal_exact')
    ref = R.exact_generic_step(o, np.zeros(3), w0, dv, dv * 0.005, h, 'normal_exact')
    np.testing.assert_allclose(got[0], ref[0], rtol=0, atol=1e-8)
    np.testing.assert_allclose(got[1], ref[1], rtol=0, atol=1e-11)
    from strapdown_ros.params import PROFILE_PARAMS, SINS_PARAMS
    defaults = {s.default for s in PROFILE_PARAMS + SINS_PARAMS if s.name == 'gravity_model'}
    assert defaults == {'normal_exact'}
