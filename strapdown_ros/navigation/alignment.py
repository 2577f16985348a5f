"""
Static coarse alignment: the attitude from the first seconds at rest (gravity and Earth rate).

Used by the navigation channel (:mod:`.channel`) before it starts the navigator.

At rest on the Earth the accelerometers measure ``f = −V_trueᵀ g(R)`` and the gyros
``ω = V_trueᵀ Ω_E`` (V = C_E_B).  With the known position both vectors are known in E, so the
attitude follows from the two measured means by the TRIAD construction, gravity first (it is
measured far better than the Earth rate):

    t1 = f/|f|, t2 = (f × ω)/|f × ω|, t3 = t1 × t2     (body)
    r1 = −g/|g|, r2 = (−g × Ω)/|…|,  r3 = r1 × r2      (E)
    V = [r1 r2 r3] [t1 t2 t3]ᵀ

Covariance: ψ (E axes, ``V_est = (I + [ψ×]) V``) is linear in the errors of the two means to first
order, ``ψ = J_f δf + J_ω δω``; J by central differences of the construction itself (exact to
second order), and ``cov δf = (σ_ba² + σ_va²/T) I``, ``cov δω = (σ_bg² + σ_arw²/T) I`` from the
sensor statistics (biases are random constants the averaging cannot remove; the white noise
averages down with the alignment time T).  Scale factors and misalignments add ``M f`` and
``M ω``, included as extra variance ``σ_k² |f|²``, ``σ_φ² |f|²`` per axis (conservative).  Tilt σ
≈ σ_ba/g; heading σ ≈ σ_bg/(Ω cos φ).

Refusals (``AlignmentResult.ok`` False, with ``reason``): the data are not static (|f| differs
from |g| by more than ``max_specific_force_error``, or the gyro mean exceeds ``max_rate`` — a
body turning faster than Earth rate plus margin, or the per-sample spread is far above the
stated noise), or the heading is unobservable (|latitude| above ``max_latitude_deg``, or the
predicted heading σ above ``max_heading_sigma``).  No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.earth import DEFAULT_GRAVITY_MODEL, normal_gravity, OMEGA
from strapdown_ros.sensors.model import SensorSigmas

__all__ = ['AlignmentResult', 'static_alignment', 'triad']


@dataclass
class AlignmentResult:
    """
    Outcome of :func:`static_alignment`.

    Parameters
    ----------
    ok : bool
        True when aligned.
    reason : str
        ``'aligned'`` or why the alignment was refused.
    attitude : (3, 3) ndarray
        C_E_B; identity when not ok.
    covariance : (3, 3) ndarray
        Covariance of ψ, E axes, rad² (NaN when not ok).
    tilt_sigma : float
        1σ tilt, rad.
    heading_sigma : float
        1σ heading, rad.

    """

    ok: bool
    reason: str
    attitude: np.ndarray
    covariance: np.ndarray
    tilt_sigma: float
    heading_sigma: float

    def as_dict(self) -> dict:
        """
        Return the outcome as plain values for a status message.

        Returns
        -------
        dict
            ``ok``, ``reason``, ``tilt_sigma_rad``, ``heading_sigma_rad``.

        """
        return {'ok': self.ok, 'reason': self.reason, 'tilt_sigma_rad': self.tilt_sigma,
                'heading_sigma_rad': self.heading_sigma}


def triad(f_body: np.ndarray, w_body: np.ndarray, f_earth: np.ndarray,
          w_earth: np.ndarray) -> np.ndarray:
    """
    Return the attitude that maps two body vectors onto two Earth vectors (TRIAD).

    ``C f_body`` has exactly the direction of ``f_earth``; ``w_body`` fixes the rotation about
    it.

    Parameters
    ----------
    f_body, w_body : (3,) ndarray
        First (exact) and second vector, body axes.
    f_earth, w_earth : (3,) ndarray
        The same vectors, E axes.

    Returns
    -------
    (3, 3) ndarray
        C_E_B.

    """
    def frame(a, b):
        t1 = a / np.linalg.norm(a)
        t2 = np.cross(a, b)
        t2 = t2 / np.linalg.norm(t2)
        return np.stack([t1, t2, np.cross(t1, t2)], 1)
    return frame(f_earth, w_earth) @ frame(f_body, w_body).T


def static_alignment(f_mean: np.ndarray, w_mean: np.ndarray, position: np.ndarray,
                     duration: float, gyro: SensorSigmas, accel: SensorSigmas,
                     f_spread: float | None = None,
                     w_spread: float | None = None, sample_period: float = 0.01,
                     gravity_model: str = DEFAULT_GRAVITY_MODEL,
                     max_specific_force_error: float = 0.05,
                     max_rate: float = 1e-3, max_latitude_deg: float = 85.0,
                     max_heading_sigma: float = np.radians(10.0)) -> AlignmentResult:
    """
    Align from the mean specific force and angular rate over a time at rest.

    Parameters
    ----------
    f_mean : (3,) array_like
        Mean specific force, body axes, m/s².
    w_mean : (3,) array_like
        Mean angular rate, body axes, rad/s.
    position : (3,) array_like
        ECEF position, m.
    duration : float
        Averaging time T, s.
    gyro, accel : SensorSigmas
        Statistics of the sensor errors.
    f_spread, w_spread : float or None
        RMS deviation of the per-sample means from the overall mean (for the static test),
        compared with the noise expected at ``sample_period``; None skips the test.
    sample_period : float
        Interval of the per-sample means, s.
    gravity_model : str
        Name in the gravity registry of :mod:`strapdown_ros.earth`.
    max_specific_force_error : float
        Largest accepted ``||f| − |g||``, m/s².
    max_rate : float
        Largest accepted mean rate above the Earth rate, rad/s.
    max_latitude_deg : float
        Largest accepted |latitude|, degrees.
    max_heading_sigma : float
        Largest accepted predicted heading 1σ, rad.

    Returns
    -------
    AlignmentResult
        The attitude and its covariance, or the reason for a refusal.

    """
    f = np.asarray(f_mean, dtype=float).reshape(3)
    w = np.asarray(w_mean, dtype=float).reshape(3)
    r = np.asarray(position, dtype=float).reshape(3)
    g = normal_gravity(r[None], gravity_model)[0]
    om = np.array([0.0, 0.0, OMEGA])
    eye = np.eye(3)

    def refuse(reason):
        return AlignmentResult(False, reason, eye, np.full((3, 3), np.nan), np.nan, np.nan)

    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(w)) and duration > 0):
        return refuse('no finite data to align with')
    if abs(np.linalg.norm(f) - np.linalg.norm(g)) > max_specific_force_error:
        return refuse(f'not static: |mean specific force| {np.linalg.norm(f):.4f} m/s² differs '
                      f'from gravity {np.linalg.norm(g):.4f} m/s² by more than '
                      f'{max_specific_force_error} m/s²')
    if np.linalg.norm(w) > np.linalg.norm(om) + max_rate:
        return refuse(f'not static: mean angular rate {np.linalg.norm(w):.3e} rad/s exceeds '
                      f'Earth rate + {max_rate} rad/s')
    if f_spread is not None:
        expected = 5.0 * (accel.random_walk / np.sqrt(sample_period) + 1e-3)
        if f_spread > expected:
            return refuse(f'not static: specific force varies by {f_spread:.3e} m/s² RMS '
                          f'(limit {expected:.3e})')
    if w_spread is not None:
        expected = 5.0 * (gyro.random_walk / np.sqrt(sample_period) + 1e-5)
        if w_spread > expected:
            return refuse(f'not static: angular rate varies by {w_spread:.3e} rad/s RMS '
                          f'(limit {expected:.3e})')
    lat = np.degrees(np.arcsin(r[2] / np.linalg.norm(r)))
    if abs(lat) > max_latitude_deg:
        return refuse(f'heading unobservable: latitude {lat:.1f}° is within '
                      f'{90 - max_latitude_deg:.0f}° of a pole')
    c = triad(f, w, -g, om)
    # first-order covariance by central differences of the construction
    var_f = (accel.bias_sigma ** 2 + accel.random_walk ** 2 / duration
             + (accel.scale_sigma ** 2 + accel.misalignment_sigma ** 2) * f @ f)
    var_w = (gyro.bias_sigma ** 2 + gyro.random_walk ** 2 / duration
             + (gyro.scale_sigma ** 2 + gyro.misalignment_sigma ** 2) * w @ w)
    jac = np.zeros((3, 6))
    for i in range(6):
        step_f = 1e-6 * max(np.linalg.norm(f), 1.0)
        step_w = 1e-3 * max(np.linalg.norm(w), 1e-9)
        step = step_f if i < 3 else step_w
        d = np.zeros(6)
        d[i] = step
        cp = triad(f + d[:3], w + d[3:], -g, om)
        cm = triad(f - d[:3], w - d[3:], -g, om)
        # V_est = (I + [ψ×]) V: [ψ×] = (V_est − V) Vᵀ
        dpsi = (cp - cm) @ c.T / (2 * step)
        jac[:, i] = [dpsi[2, 1], dpsi[0, 2], dpsi[1, 0]]
    cov = jac @ np.diag([var_f] * 3 + [var_w] * 3) @ jac.T
    up = -g / np.linalg.norm(g)
    heading_sigma = float(np.sqrt(up @ cov @ up))
    tilt_sigma = float(np.sqrt(max(np.trace(cov) - heading_sigma ** 2, 0.0) / 2.0))
    if heading_sigma > max_heading_sigma:
        return refuse(f'heading unobservable: predicted heading σ '
                      f'{np.degrees(heading_sigma):.2f}° exceeds '
                      f'{np.degrees(max_heading_sigma):.2f}° (latitude {lat:.1f}°, gyro bias '
                      f'{gyro.bias_sigma:.2e} rad/s, {duration:.0f} s)')
    return AlignmentResult(True, 'aligned', c, 0.5 * (cov + cov.T), tilt_sigma, heading_sigma)
