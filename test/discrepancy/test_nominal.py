"""
nominal_model against the values a simulated recording was made with (injected parameters).

A piecewise motion: three rests of 20 s and turns about every axis between them, a 100 Hz gyro
with a known angle random walk and bias, a reference at 10 Hz with a known σ, and a known
boresight.  The starting model must recover each within the tolerance its rule allows: the rate
and frames exactly, the ARW from the Allan deviation at rest, the bias within 3 of the σ it
writes, the reference σ from the pair residuals, and the boresight by axis alignment.
"""
from pathlib import Path

import numpy as np
import pytest

from strapdown_ros.discrepancy.nominal import clip_level, noisy_rail
from strapdown_ros.params import load_model_file
from strapdown_ros.tools import nominal_model, record_sim

pytest.importorskip('rosbags')
pytest.importorskip('allantools')

PROFILE = """initial_attitude: [1.0, 0.0, 0.0, 0.0]
earth_rate: [0.0, 0.0, 0.0]
gravity: [0.0, 0.0, 9.80665]
segments:
  - {duration: 20.0, rate: [0.0, 0.0, 0.0]}
  - {duration: 4.0,  rate: [0.0, 0.0, 0.4]}
  - {duration: 4.0,  rate: [0.4, 0.0, 0.0]}
  - {duration: 4.0,  rate: [0.0, 0.4, 0.0]}
  - {duration: 20.0, rate: [0.0, 0.0, 0.0]}
  - {duration: 4.0,  rate: [0.3, -0.3, 0.0]}
  - {duration: 4.0,  rate: [0.0, 0.3, 0.3]}
  - {duration: 20.0, rate: [0.0, 0.0, 0.0]}
"""
ARW, SIGMA = 1e-4, 1e-3
BIAS = np.array([1e-3, -2e-3, 5e-4])
BORESIGHT = np.array([0.1, -0.2, 0.3])


@pytest.fixture(scope='module')
def found(tmp_path_factory):
    """Record the scenario and run nominal_model on it."""
    d = tmp_path_factory.mktemp('nominal')
    (d / 'profile.yaml').write_text(PROFILE)
    p = {'profile': 'piecewise', 'profile_file': str(d / 'profile.yaml'),
         'camera_interval': 0.1, 'camera_sigma_xy': SIGMA, 'camera_sigma_z': SIGMA,
         'gyro_random_walk': ARW, 'gyro_bias': BIAS.tolist(), 'boresight': BORESIGHT.tolist(),
         'seed': 3}
    args = [str(d / 'bag'), '--no-accel', '--duration', '80']
    for k, v in p.items():
        args += ['-p', f'{k}:={v}']
    assert record_sim.main(args) == 0
    out = d / 'nominal.yaml'
    assert nominal_model.main([str(d / 'bag'), '--output', str(out), '--quiet']) == 0
    return load_model_file(str(out)).model, Path(out).read_text()


def test_rate_frames_and_boresight(found):
    m, text = found
    assert m.gyro_rate == pytest.approx(100.0, rel=1e-9)
    assert (m.frame_id, m.reference_frame_id) == ('imu_link', 'gcrs')
    assert np.allclose(m.boresight, BORESIGHT, atol=0.01)        # 0.6°: a start for the fit
    assert 'axis alignment' in text


def test_noise_and_bias(found):
    m, _ = found
    assert m.gyro.random_walk == pytest.approx(ARW, rel=0.15)
    assert m.camera_sigma_xy == pytest.approx(SIGMA, rel=0.25)
    assert m.camera_sigma_z == pytest.approx(SIGMA, rel=0.25)
    b, s = np.asarray(m.effect_value('gyro_bias')), m.effect_sigma('gyro_bias')
    assert np.all(np.abs(b - BIAS) <= 3.0 * s), (b, s)
    assert s < 2e-4                                               # 60 s of rest: well known


def test_a_flat_rail_is_the_clip_level_and_a_noisy_one_is_reported():
    """
    A flat rail, a rail with 0.05 % noise, and smooth peaks.

    Truth: the rail is where the simulated sensor stops the rate (7.36 rad/s on x).  A flat
    rail is the clip level; a noisy one is no clip level but is reported as a possible one (five
    visits); a sinusoid of 0.2 Hz at 100 Hz whose peaks differ by 1 % from one to the next is
    neither.
    """
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 25.0, 0.01)
    w = np.zeros((len(t), 3))
    w[:, 0] = 9.0 * np.sin(2 * np.pi * 0.2 * t)
    w[:, 1] = 0.5
    w += rng.normal(0.0, 1e-3, w.shape)                           # the gyro's white noise
    flat = w.copy()
    flat[:, 0] = np.clip(flat[:, 0], -7.36, 7.36)
    rail, axis, count, _ = clip_level(flat)
    assert (rail, axis) == (pytest.approx(7.36), 0) and count > 100
    noisy = flat.copy()
    at = np.abs(noisy[:, 0]) >= 7.36
    noisy[at, 0] *= 1.0 - 5e-4 * (1.0 + rng.random(int(at.sum())))
    assert clip_level(noisy)[0] is None
    level, axis, count, visits = noisy_rail(noisy)
    assert axis == 0 and level == pytest.approx(7.36, rel=1e-3) and count > 100 and visits >= 5
    smooth = w.copy()
    smooth[:, 0] *= 1.0 + 0.01 * np.floor(t / 2.5)              # each peak 1 % above the last
    assert clip_level(smooth)[0] is None and noisy_rail(smooth)[0] is None
