"""
Hidden effects for testing the discrepancy workflow: their σ on a recording, and a draw.

The σ with which a recording determines an effect, a draw of that effect at a chosen size in
those σ, and an in-memory recording as ``record_sim`` would write it.  Used by the tests and
by ``discrepancy_bench`` alike.  No ROS imports.

Size is the Mahalanobis length in the effect's separable combinations: an effect drawn at
size k changes −2 log L by about k² (the non-centrality of its likelihood-ratio test), whatever
its dimension.  Direction: uniform on the unit sphere of those combinations (one-parameter
effects: a random sign; the quantization pulse weight is positive).
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.discrepancy.linear_model import fit
from strapdown_ros.discrepancy.linearisation import fit_noise, Linearisation, noise_of, Recording
from strapdown_ros.discrepancy.model_fit import initial_boresight_estimate, refine_fit
from strapdown_ros.motion.from_config import profile_from_config
from strapdown_ros.sensors import simulated_imu
from strapdown_ros.sensors.effects import EFFECTS
from strapdown_ros.sensors.star_camera import StarCameraModel

__all__ = ['effect_sigma', 'draw_hidden_effect', 'simulate_recording']


def effect_sigma(rec: Recording, model, names) -> dict:
    """
    Return the covariance of the separable combinations of effects on this recording.

    Parameters
    ----------
    rec : Recording
        The recording.
    model : SensorModel
        The model (the effects absent).
    names : str or sequence of str
        Effect names.

    Returns
    -------
    dict
        ``{name: (q, q) covariance}`` in the units of the effect's combinations.

    """
    params = model.values()
    epoch = float(rec.gyro_stamps[0])
    noise = noise_of(params)
    C = initial_boresight_estimate(rec, params, epoch)
    params, C = refine_fit(rec, params, C, epoch, [], noise)
    lin = Linearisation(rec, params, C, epoch)
    out = {}
    for name in ([names] if isinstance(names, str) else names):
        e = EFFECTS[name]
        if name == 'gyro_quantization':
            # the lag term's information at σ = 0+ (the variance term has none there)
            f = fit(lin.r, np.hstack([lin.design([]), lin.quant_col[:, None]]), lin.U,
                    lin.prior_var, lin.whitener(noise))
            out[name] = f.cov_z[3:, 3:]
        elif e.kind == 'noise':
            _, _, sig = fit_noise(lin, [], noise, name)
            out[name] = np.diag(sig ** 2)
        else:
            out[name] = lin.evaluate([name], noise).cov_z[3:, 3:]
    return out


def draw_hidden_effect(name: str, size: float, cov: np.ndarray,
                       rng: np.random.Generator) -> dict:
    """
    Draw the parameter overrides that inject an effect at a size in σ (Mahalanobis).

    Parameters
    ----------
    name : str
        Effect name of the registry.
    size : float
        Mahalanobis length in the effect's separable combinations.
    cov : (q, q) array_like
        Their covariance on the recording (:func:`effect_sigma`).
    rng : numpy.random.Generator
        Source of the direction.

    Returns
    -------
    dict
        ``{ROS parameter name: value}`` for record_sim or the simulator nodes.

    """
    e = EFFECTS[name]
    p = e.value_parameter
    cov = np.atleast_2d(cov)
    q = cov.shape[0]
    u = rng.normal(size=q)
    u /= np.linalg.norm(u)
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    z = size * (V * np.sqrt(np.maximum(w, 0.0))) @ u
    if name == 'gyro_quantization':
        z = np.abs(z)
    S = e.fit_basis()
    theta = (z if S is None else S @ z) + e.neutral
    return {p.name: theta.tolist() if p.size > 1 else float(theta[0])}


def simulate_recording(imu_p: dict, cam_p: dict, duration: float) -> Recording:
    """
    Simulate in memory what ``record_sim`` writes to a bag for the same validated parameters.

    The same sensor and camera models, seeds and stamps, no accelerometer: the benchmark's
    fast path.

    Parameters
    ----------
    imu_p : dict
        Validated IMU simulator parameters.
    cam_p : dict
        Validated star-camera parameters.
    duration : float
        Length of the recording, s.

    Returns
    -------
    Recording
        The gyro increments and the camera fixes.

    """
    profile = profile_from_config(imu_p)
    gyro, _ = simulated_imu(imu_p, profile)
    t, dth, _ = gyro.sample(int(np.floor(duration / gyro.period + 1e-9)))
    cam = StarCameraModel.from_params(cam_p)
    count = 0
    while cam.epoch(count) <= duration + 1e-9:
        count += 1
    fixes = cam.fixes(profile_from_config(cam_p), count)
    return Recording(t, dth, [f.stamp for f in fixes], [f.attitude for f in fixes],
                     [f.covariance for f in fixes])
