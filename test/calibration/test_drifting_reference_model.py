"""000 (Tkachenko 1983), the model: §6's numbers, the aircraft angles, the drifting reference."""
import numpy as np

from strapdown_ros.calibration.drifting_reference_model import (GyrostabilizerReference,
                                                                PAPER_000, PAPER_000_C,
                                                                PAPER_000_PHI0,
                                                                quat_to_aircraft_angles)
from strapdown_ros.motion.profiles import tkachenko_profile
from strapdown_ros.reproductions.tkachenko1983 import simulate_000
from strapdown_ros.rotation import (aircraft_angles_to_quat, elementary_dcm, quat_angle_between,
                                    quat_conjugate, quat_multiply, quat_to_dcm, rotvec_to_quat)

H = 0.02


def test_paper_numbers_transcribed():
    """PAPER_000 against the text of §6 (read twice); spot checks of every list."""
    assert [len(PAPER_000[k][f]) for k in PAPER_000 for f in ('w0', 'dc', 'dd')] == [3, 9, 3] * 3
    u, r, c = PAPER_000['unquantized'], PAPER_000['quantized_raw'], PAPER_000['quantized_centred']
    assert u['w0'] == [-0.67e-5, 0.32e-5, -1.3e-5] and u['dc'][5] == -2.4e-8
    assert u['dd'] == [-2.2e-7, 2.1e-7, -2.5e-7]
    assert r['w0'] == [-2e-5, 0.5e-5, -3.2e-5] and r['dc'][3] == 1.8e-5 and r['dd'][2] == -1.4e-6
    assert c['w0'] == [1.7e-5, 0.83e-5, -1.4e-5] and c['dc'][2] == -1.8e-5 and c['dd'][0] == 2.9e-7
    np.testing.assert_allclose(PAPER_000_C,
                               [3e-4, 3e-4, 3e-4, 5e-4, 5e-4, -5e-4, 1e-5, -1e-5, -1e-5])


def test_aircraft_angles_convention_and_round_trip():
    """Lurie's aircraft angles: yaw about y, pitch about the new z, roll about the new x."""
    phi = np.array([0.3, -0.4, 1.1])
    C = quat_to_dcm(aircraft_angles_to_quat(phi))
    expected = elementary_dcm(1, 0.3) @ elementary_dcm(2, -0.4) @ elementary_dcm(0, 1.1)
    np.testing.assert_allclose(C, expected, atol=1e-15)
    rng = np.random.default_rng(1)
    ang = rng.uniform([-np.pi, -1.5, -np.pi], [np.pi, 1.5, np.pi], (500, 3))
    round_trip = quat_to_aircraft_angles(aircraft_angles_to_quat(ang))
    np.testing.assert_allclose(round_trip, ang, atol=1e-12)
    # pure yaw turns the longitudinal axis x in the horizontal plane x–z (y up)
    x_axis = quat_to_dcm(aircraft_angles_to_quat([0.5, 0, 0])) @ [1, 0, 0]
    np.testing.assert_allclose(x_axis, [np.cos(0.5), 0, -np.sin(0.5)], atol=1e-15)


def test_phi0_and_lambda0_are_not_the_same_attitude():
    """000 §6 gives Λ(0) = (0.8 + 0.6 i1)∘(0.8 − 0.6 i3) and φ0 apart: 140° apart, so J ≠ E."""
    L0 = tkachenko_profile().attitude(0.0)
    a = 2 * np.arctan2(0.6, 0.8)
    printed = quat_multiply(rotvec_to_quat([a, 0, 0]), rotvec_to_quat([0, 0, -a]))
    np.testing.assert_allclose(printed, L0, atol=1e-15)
    assert np.degrees(quat_angle_between(L0, aircraft_angles_to_quat(PAPER_000_PHI0))) > 139.0
    sim = simulate_000(seed=None)
    np.testing.assert_allclose(sim.reference.angles(np.array(0.0)), PAPER_000_PHI0, atol=1e-14)
    # the aircraft angles stay away from pitch ±90° on the whole run (max |pitch| 44°)
    pitch = sim.reference.angles(H * np.arange(1501))[:, 1]
    assert np.degrees(np.abs(pitch).max()) < 45.0


def test_reference_drift_and_mounting_invariance():
    """The reference drifts as exp(Ψd), and its increments do not depend on the mounting."""
    prof = tkachenko_profile()
    d = np.array([3e-6, -1e-6, 2e-6])
    ref = GyrostabilizerReference(prof, d)
    t = np.array([0.0, 7.3, 30.0])
    # q_I_L = exp(d t): rotation about the fixed axis d at rate |d| (exact for G = E3)
    np.testing.assert_allclose(ref.drift_quaternion(t), rotvec_to_quat(t[:, None] * d), atol=1e-16)
    # the reference increment P does not depend on how J is mounted on E
    other = GyrostabilizerReference(prof, d, mounting=rotvec_to_quat([0.4, -1.0, 2.0]))
    incs = []
    for r in (ref, other):
        P = quat_multiply(r.quaternion(t[1:]), quat_conjugate(r.quaternion(np.array(0.0))))
        incs.append(P * np.sign(P[:, :1]))
    np.testing.assert_allclose(incs[0], incs[1], atol=1e-14)
