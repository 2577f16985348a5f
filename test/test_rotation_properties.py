"""
Property tests of the rotation core on random inputs.

Property tests of the rotation core: composition, inverse, renormalisation,
conversion round-trips, the angle wrap at π and the double cover — on random inputs.
"""
import numpy as np
import pytest

hypothesis = pytest.importorskip('hypothesis')
st = pytest.importorskip('hypothesis.strategies')
given, settings = hypothesis.given, hypothesis.settings

from strapdown_ros.rotation import (dcm_to_quat, from_ros_xyzw,  # noqa: E402
                                    quat_angle_between, quat_conjugate,
                                    quat_multiply, quat_normalize, quat_to_dcm, quat_to_rotvec,
                                    rotvec_to_quat, to_ros_xyzw)

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
quats = st.lists(finite, min_size=4, max_size=4).filter(lambda v: np.linalg.norm(v) > 1e-3).map(
    lambda v: quat_normalize(np.array(v)))
angles = st.floats(0.0, np.pi, allow_nan=False)
axes = st.lists(st.floats(-1, 1, allow_nan=False), min_size=3, max_size=3).filter(
    lambda v: np.linalg.norm(v) > 1e-3).map(lambda v: np.array(v) / np.linalg.norm(v))
SETTINGS = settings(max_examples=300, deadline=None)


def same_rotation(p, q, tol=1e-12):
    # the double cover: q ≡ −q
    """Tell whether p and q are the same rotation (q ≡ −q)."""
    return min(np.max(np.abs(p - q)), np.max(np.abs(p + q))) < tol


@SETTINGS
@given(quats, quats, quats)
def test_composition_is_associative_and_matches_dcms(p, q, r):
    assert same_rotation(quat_multiply(quat_multiply(p, q), r),
                         quat_multiply(p, quat_multiply(q, r)))
    np.testing.assert_allclose(quat_to_dcm(quat_multiply(p, q)),
                               quat_to_dcm(p) @ quat_to_dcm(q), atol=1e-12)


@SETTINGS
@given(quats)
def test_inverse_and_double_cover(q):
    assert same_rotation(quat_multiply(q, quat_conjugate(q)), np.array([1.0, 0, 0, 0]))
    np.testing.assert_allclose(quat_to_dcm(q), quat_to_dcm(-q), atol=1e-15)
    assert quat_angle_between(q, -q) < 1e-7


@SETTINGS
@given(st.lists(finite, min_size=4, max_size=4).filter(lambda v: np.linalg.norm(v) > 1e-3))
def test_renormalisation(v):
    q = quat_normalize(np.array(v))
    assert abs(np.linalg.norm(q) - 1.0) < 1e-15
    assert same_rotation(quat_normalize(q * 7.5), q)


@SETTINGS
@given(quats)
def test_round_trips(q):
    assert same_rotation(dcm_to_quat(quat_to_dcm(q)), q, 1e-11)
    assert same_rotation(rotvec_to_quat(quat_to_rotvec(q)), q, 1e-11)
    np.testing.assert_array_equal(from_ros_xyzw(to_ros_xyzw(q)), q)


@SETTINGS
@given(axes, angles)
def test_rotation_vector_angle_and_wrap_at_pi(k, a):
    phi = quat_to_rotvec(rotvec_to_quat(a * k))
    assert np.linalg.norm(phi) <= np.pi + 1e-12                             # log maps into [0, π]
    if a < np.pi - 1e-6:
        np.testing.assert_allclose(phi, a * k, atol=1e-9)
    # a rotation by a + 2π·0 past π is the rotation by 2π − a about −k
    b = np.pi + 0.5 * (np.pi - a)
    if np.pi + 1e-9 < b < 2 * np.pi - 1e-6:                 # at π itself ±πk are the same rotation
        np.testing.assert_allclose(quat_to_rotvec(
            rotvec_to_quat(b * k)), -(2 * np.pi - b) * k, atol=1e-9)
