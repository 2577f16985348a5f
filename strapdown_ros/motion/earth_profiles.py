"""
Earth-referenced navigation profiles: the presets of the Earth-frame motion.

The presets build :class:`~strapdown_ros.motion.earth_motion.EarthProfile` objects:
:func:`static_profile`, :func:`straight_flight_profile`, :func:`coordinated_turn_profile`,
:func:`sculling_profile`; :func:`navigation_profile_from_config` builds them from node
parameters (the ``profile`` parameter of the simulators).  :func:`sculling_drift_rate` and
:func:`gravity_sculling_term` are the sculling error rates the navigation bench checks.
Frames and conventions are those of :mod:`strapdown_ros.motion.earth_motion`: body axes FLU,
ENU yaw counter-clockwise from east (REP-103), tf2 ``setRPY`` pitch and roll.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from strapdown_ros.earth import (DEFAULT_GRAVITY_MODEL, enu_rotation, geodetic_to_ecef,
                                 normal_gravity)
from strapdown_ros.motion.earth_motion import EarthProfile
from strapdown_ros.rotation import dcm_to_quat, quat_multiply, quat_normalize

__all__ = ['static_profile', 'straight_flight_profile', 'coordinated_turn_profile',
           'sculling_profile', 'sculling_drift_rate', 'gravity_sculling_term',
           'navigation_profile_from_config', 'NAVIGATION_PROFILE_NAMES']

NAVIGATION_PROFILE_NAMES = ('static', 'straight_flight', 'coordinated_turn', 'sculling')


def _zeros3(t: np.ndarray) -> np.ndarray:
    return np.zeros(np.shape(t) + (3,))


def _constant(v) -> Callable[[np.ndarray], np.ndarray]:
    v = np.asarray(v, dtype=float)
    return lambda t: np.zeros(np.shape(t) + v.shape) + v


def _rz(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rx(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _axis_angle_quat(axis, angle) -> np.ndarray:
    """``exp(angle·axis)`` for a fixed unit axis (3,) and an array of angles → (..., 4)."""
    half = 0.5 * np.asarray(angle, dtype=float)
    vector = _outer(np.sin(half), np.asarray(axis, dtype=float))
    return np.concatenate([np.cos(half)[..., None], vector], -1)


def _outer(scalar: np.ndarray, vec: np.ndarray) -> np.ndarray:
    return np.asarray(scalar, dtype=float)[..., None] * vec


# --- presets ------------------------------------------------------------------------------
def _enu(lat: float, lon: float) -> np.ndarray:
    return np.asarray(enu_rotation(lat, lon), dtype=float).reshape(3, 3)


def _ecef(lat: float, lon: float, h: float) -> np.ndarray:
    return np.asarray(geodetic_to_ecef(lat, lon, h), dtype=float).reshape(3)


def _check_finite(**kw):
    for k, v in kw.items():
        if not np.isfinite(v):
            raise ValueError(f'{k} must be finite, got {v!r}')


def static_profile(lat: float, lon: float, h: float = 0.0, yaw: float = 0.0, pitch: float = 0.0,
                   roll: float = 0.0, gravity_model: str = DEFAULT_GRAVITY_MODEL,
                   duration: float = np.inf) -> EarthProfile:
    """
    Return a body at rest on the rotating Earth at geodetic (lat, lon, h).

    ``C_ENU_B = R_z(yaw) R_y(pitch) R_x(roll)`` (tf2 ``setRPY``; yaw counter-clockwise from
    east, REP-103).  f = −C_B_E g(R) and ω = C_B_E Ω_E are constant in body axes.

    Parameters
    ----------
    lat, lon : float
        Geodetic latitude and longitude, rad.
    h : float
        Height above the ellipsoid, m.
    yaw, pitch, roll : float
        Attitude relative to ENU, rad.
    gravity_model : str
        Normal gravity model (:func:`strapdown_ros.earth.normal_gravity`).
    duration : float
        Length of the motion, s.

    Returns
    -------
    EarthProfile
        The profile.

    """
    _check_finite(lat=lat, lon=lon, h=h, yaw=yaw, pitch=pitch, roll=roll)
    r0 = _ecef(lat, lon, h)
    c_eb = _enu(lat, lon) @ _rz(yaw) @ _ry(pitch) @ _rx(roll)
    q0 = quat_normalize(dcm_to_quat(c_eb))
    return EarthProfile(_constant(r0), _zeros3, _zeros3, _constant(q0), _zeros3,
                        frequency=0.0, duration=duration, name='static',
                        gravity_model=gravity_model,
                        parameters={'lat': lat, 'lon': lon, 'h': h, 'yaw': yaw,
                                    'pitch': pitch, 'roll': roll})


def straight_flight_profile(lat: float, lon: float, h: float = 0.0, speed: float = 200.0,
                            heading: float = 0.0, gravity_model: str = DEFAULT_GRAVITY_MODEL,
                            duration: float = np.inf) -> EarthProfile:
    """
    Constant speed along a great circle of the geocentric sphere of radius r = |R0|.

    "Straight" means a great circle at constant *geocentric* radius: R(t) = Rot(n, v t/r) R0 with
    n ⟂ R0, so |R| = r exactly, while the height above the ellipsoid varies slightly with latitude
    (tens of metres per degree of latitude travelled).  The start R0 is geodetic (lat, lon, h);
    the direction of travel is ``heading`` (ENU yaw, counter-clockwise from east) projected on
    the plane ⟂ R0.  Body x along the velocity, z along the geocentric up R/r, y = n; the body
    turns relative to E at the constant rate (v/r) about body y (nose down, following the
    sphere).

    Parameters
    ----------
    lat, lon : float
        Geodetic latitude and longitude, rad.
    h : float
        Height above the ellipsoid, m.
    speed : float
        Speed v, m/s.
    heading : float
        Direction of travel, ENU yaw, rad.
    gravity_model : str
        Normal gravity model (:func:`strapdown_ros.earth.normal_gravity`).
    duration : float
        Length of the motion, s.

    Returns
    -------
    EarthProfile
        The profile.

    """
    _check_finite(lat=lat, lon=lon, h=h, speed=speed, heading=heading)
    r0 = _ecef(lat, lon, h)
    r = float(np.linalg.norm(r0))
    u = r0 / r
    enu = _enu(lat, lon)
    d = np.cos(heading) * enu[:, 0] + np.sin(heading) * enu[:, 1]
    d = d - (d @ u) * u
    d /= np.linalg.norm(d)
    n = np.cross(u, d)
    q0 = quat_normalize(dcm_to_quat(np.column_stack([d, n, u])))
    rate = speed / r
    v = float(speed)

    def position(t):
        th = rate * t
        return r * (_outer(np.cos(th), u) + _outer(np.sin(th), d))

    def velocity(t):
        th = rate * t
        return v * (_outer(-np.sin(th), u) + _outer(np.cos(th), d))

    def acceleration(t):
        th = rate * t
        return -(v * rate) * (_outer(np.cos(th), u) + _outer(np.sin(th), d))

    def attitude(t):
        return quat_multiply(q0, _axis_angle_quat((0.0, 1.0, 0.0), rate * t))

    w_eb = np.array([0.0, rate, 0.0])
    return EarthProfile(position, velocity, acceleration, attitude, _constant(w_eb),
                        frequency=abs(rate), duration=duration, name='straight_flight',
                        gravity_model=gravity_model,
                        parameters={'lat': lat, 'lon': lon, 'h': h, 'speed': v, 'heading': heading,
                                    'radius': r, 'axis': n, 'rate': rate})


def coordinated_turn_profile(lat: float, lon: float, h: float = 0.0, speed: float = 100.0,
                             radius: float = 2000.0, heading: float = 0.0,
                             bank: float | None = None,
                             gravity_model: str = DEFAULT_GRAVITY_MODEL,
                             duration: float = np.inf) -> EarthProfile:
    """
    Constant-speed left (counter-clockwise from above) turn on a circle in a tangent plane.

    The circle has radius ρ = ``radius`` and centre R_c = geodetic (lat, lon, h), in the plane
    ⟂ the geodetic up u of the centre: ``R = R_c + ρ(cos ψ e + sin ψ n)``, ψ = ψ0 + (v/ρ)t,
    (e, n) east/north at the centre.  ``heading`` is the initial direction of the velocity (ENU
    yaw), so ψ0 = heading − π/2.  Being in a plane, the path rises above the ellipsoid towards
    the rim: height h + ρ²/2R (≈ 0.3 m for ρ = 2 km), varying around the circle by
    ρ²/2·(1/M − 1/N) (millimetres).

    Body x along the velocity, banked left about x by the coordinated-turn angle β: body
    ``C_E_B = [x_L, y_L, u] R_x(−β)`` (y_L towards the centre).  β is chosen so that the mean
    over the circle of the Earth-relative specific force ``R̈ − g`` lies in the body x–z plane;
    this is ``atan(v²/(ρ g0))`` corrected for the tilt ρ/R of the local vertical around the
    circle (``parameters['bank_nominal']`` holds the uncorrected value).  What remains in body y
    is the ellipsoid's anisotropy of that tilt (≲ 1e-5 m/s²) plus the Coriolis term
    ``(C_B_E 2Ω×Ṙ)_y`` (≤ 2Ωv, 1.5e-2 m/s² at 100 m/s), which no constant bank can cancel.
    ``bank`` overrides β (radians).  The body turns relative to E at the constant rate v/ρ about
    u: ω_EB = (v/ρ) C_B_E u is constant in body axes, so the attitude is closed-form.

    Parameters
    ----------
    lat, lon : float
        Geodetic latitude and longitude, rad.
    h : float
        Height above the ellipsoid, m.
    speed : float
        Speed v, m/s.
    radius : float
        Radius ρ of the circle, m.
    heading : float
        Initial direction of the velocity, ENU yaw, rad.
    bank : float or None
        Bank angle β, rad (None: the coordinated-turn angle).
    gravity_model : str
        Normal gravity model (:func:`strapdown_ros.earth.normal_gravity`).
    duration : float
        Length of the motion, s.

    Returns
    -------
    EarthProfile
        The profile.

    """
    _check_finite(lat=lat, lon=lon, h=h, speed=speed, radius=radius, heading=heading)
    if not radius > 0:
        raise ValueError(f'radius must be > 0, got {radius}')
    rc = _ecef(lat, lon, h)
    enu = _enu(lat, lon)
    e1, e2, up = enu[:, 0], enu[:, 1], enu[:, 2]
    v = float(speed)
    rho = float(radius)
    psi_dot = v / rho
    psi0 = heading - 0.5 * np.pi

    def position(t):
        psi = psi0 + psi_dot * t
        return rc + rho * (_outer(np.cos(psi), e1) + _outer(np.sin(psi), e2))

    def velocity(t):
        psi = psi0 + psi_dot * t
        return v * (_outer(-np.sin(psi), e1) + _outer(np.cos(psi), e2))

    def acceleration(t):
        psi = psi0 + psi_dot * t
        return -(v * psi_dot) * (_outer(np.cos(psi), e1) + _outer(np.sin(psi), e2))

    g0 = float(np.linalg.norm(normal_gravity(rc, model=gravity_model)))
    bank_nominal = float(np.arctan2(v * psi_dot, g0))
    if bank is None:
        psi = np.linspace(0.0, 2 * np.pi, 64, endpoint=False)
        pts = rc + rho * (np.outer(np.cos(psi), e1) + np.outer(np.sin(psi), e2))
        inward = -(np.outer(np.cos(psi), e1) + np.outer(np.sin(psi), e2))
        f_rel = (v * psi_dot) * inward - normal_gravity(pts, model=gravity_model)
        bank = float(np.arctan2(np.mean(np.sum(f_rel * inward, -1)), np.mean(f_rel @ up)))
    _check_finite(bank=bank)
    x0 = np.cos(heading) * e1 + np.sin(heading) * e2
    level = np.column_stack([x0, np.cross(up, x0), up])
    c0 = level @ _rx(-bank)
    q0 = quat_normalize(dcm_to_quat(c0))
    w_eb = psi_dot * (c0.T @ up)

    w_norm = float(np.linalg.norm(w_eb))
    axis = w_eb / w_norm if w_norm > 0 else np.array([0.0, 0.0, 1.0])

    def attitude(t):
        return quat_multiply(q0, _axis_angle_quat(axis, w_norm * t))

    return EarthProfile(position, velocity, acceleration, attitude, _constant(w_eb),
                        frequency=abs(psi_dot), duration=duration, name='coordinated_turn',
                        gravity_model=gravity_model,
                        parameters={'lat': lat, 'lon': lon, 'h': h, 'speed': v, 'radius': rho,
                                    'heading': heading, 'bank': bank,
                                    'bank_nominal': bank_nominal, 'g0': g0,
                                    'turn_rate': psi_dot, 'centre': rc})


def sculling_profile(lat: float, lon: float, h: float = 0.0, angle_amplitude: float = 0.01,
                     accel_amplitude: float = 1.0, frequency: float = 10.0, yaw: float = 0.0,
                     gravity_model: str = DEFAULT_GRAVITY_MODEL,
                     duration: float = np.inf) -> EarthProfile:
    """
    Classical sculling about a level attitude at geodetic (lat, lon, h).

    Level frame L = ENU rotated by ``yaw`` (REP-103) about up.  With w = 2π·``frequency``:

    * attitude ``q_E_B = q_E_L ⊗ exp(θ(t) x̂)``, θ = A sin wt (A = ``angle_amplitude``, rad),
      so ω_EB = [A w cos wt, 0, 0];
    * position ``R = R0 − (B/w²) sin(wt) y_L`` along the L-frame y axis (body y at θ = 0), so the
      E-frame acceleration is ``B sin(wt) y_L`` (B = ``accel_amplitude``, m/s²) and the velocity
      ``−(B/w) cos(wt) y_L`` is periodic with zero mean.  The body does **not** start at rest:
      ``initial_velocity = −(B/w) y_L``.

    In body axes the in-phase lateral specific force has amplitude ``B_eff = B + A·g``
    (gravity, tilted by the roll oscillation, adds A·g to body y);
    ``parameters['effective_accel_amplitude']`` holds it.  It is the B of the *first-order*
    sculling term ``½∫(α×f + v×ω) dt`` (test/motion/test_earth_profiles.py).  It is **not** the
    B of the drift of a Δv without sculling compensation: the second-order rotation of the large
    vertical force, ``½α×(α×g ẑ)``, cancels the A·g part in body axes, so that drift is
    :func:`sculling_drift_rate` with the real B (``nav_bench``, doc/results/nav_bench/), plus,
    in level
    axes, the term even in B of :func:`gravity_sculling_term`.

    Parameters
    ----------
    lat, lon : float
        Geodetic latitude and longitude, rad.
    h : float
        Height above the ellipsoid, m.
    angle_amplitude : float
        A, rad.
    accel_amplitude : float
        B, m/s².
    frequency : float
        Oscillation frequency, Hz.
    yaw : float
        Yaw of the level frame L, rad (REP-103).
    gravity_model : str
        Normal gravity model (:func:`strapdown_ros.earth.normal_gravity`).
    duration : float
        Length of the motion, s.

    Returns
    -------
    EarthProfile
        The profile.

    """
    _check_finite(lat=lat, lon=lon, h=h, angle_amplitude=angle_amplitude,
                  accel_amplitude=accel_amplitude, frequency=frequency, yaw=yaw)
    if not frequency > 0:
        raise ValueError(f'frequency must be > 0, got {frequency}')
    r0 = _ecef(lat, lon, h)
    c_el = _enu(lat, lon) @ _rz(yaw)
    y_l = c_el[:, 1]
    q_l = quat_normalize(dcm_to_quat(c_el))
    A = float(angle_amplitude)
    B = float(accel_amplitude)
    w = 2.0 * np.pi * float(frequency)

    def position(t):
        return r0 + _outer(-(B / w ** 2) * np.sin(w * t), y_l)

    def velocity(t):
        return _outer(-(B / w) * np.cos(w * t), y_l)

    def acceleration(t):
        return _outer(B * np.sin(w * t), y_l)

    def attitude(t):
        return quat_multiply(q_l, _axis_angle_quat((1.0, 0.0, 0.0), A * np.sin(w * t)))

    def rate(t):
        z = np.zeros_like(t)
        return np.stack([A * w * np.cos(w * t), z, z], -1)

    g_up = float(-normal_gravity(r0, model=gravity_model) @ c_el[:, 2])
    return EarthProfile(position, velocity, acceleration, attitude, rate,
                        frequency=w * (1.0 + abs(A)), duration=duration, name='sculling',
                        gravity_model=gravity_model,
                        parameters={'lat': lat, 'lon': lon, 'h': h, 'yaw': yaw,
                                    'angle_amplitude': A, 'accel_amplitude': B,
                                    'frequency': float(frequency), 'omega': w,
                                    'effective_accel_amplitude': B + A * g_up})


def sculling_drift_rate(angle_amplitude, accel_amplitude, omega, interval):
    """
    Return the classical sculling error rate ``½·A·B·(1 − sin(wh)/(wh))``.

    For ω = A w cos(wt) x̂ and f = B sin(wt) ŷ, with α(t), v(t) the integrals of ω and f from
    the start t0 of an update interval, ``α×f + v×ω = A B (1 − cos w(t − t0)) ẑ``, so the
    sculling term ``½∫(α×f + v×ω) dt = ½AB(h − sin(wh)/w) ẑ`` over every interval, whatever its
    phase.  A strapdown algorithm with rotation compensation (½Δθ×Δv) but no sculling
    correction omits it, and its velocity error grows at ``−sculling_drift_rate`` along body z
    (a mean specific-force error).  Vectorised; the small-wh limit uses the series
    (wh)²/6 − ….

    Parameters
    ----------
    angle_amplitude : float or ndarray
        A, rad.
    accel_amplitude : float or ndarray
        B, the in-phase body-y specific-force amplitude, m/s².
    omega : float or ndarray
        w, rad/s.
    interval : float or ndarray
        Update interval h, s.

    Returns
    -------
    float or ndarray
        The rate, m/s².

    """
    x = np.asarray(omega, dtype=float) * np.asarray(interval, dtype=float)
    small = np.abs(x) < 1e-2
    xs = np.where(small, 1.0, x)
    one_minus_sinc = np.where(small, x ** 2 / 6.0 - x ** 4 / 120.0 + x ** 6 / 5040.0,
                              1.0 - np.sin(xs) / xs)
    a = np.asarray(angle_amplitude, dtype=float)
    return 0.5 * a * np.asarray(accel_amplitude, dtype=float) * one_minus_sinc


def navigation_profile_from_config(cfg: dict) -> EarthProfile:
    """
    Build a navigation profile from node parameters.

    Keys: ``profile`` ∈ :data:`NAVIGATION_PROFILE_NAMES`; ``nav_latitude_deg`` (50.45),
    ``nav_longitude_deg`` (30.52), ``nav_height`` (150 m), ``nav_speed`` (m/s; 0 = the preset's
    default, 200 straight flight / 100 turn), ``nav_heading_deg`` (ENU yaw of the body /
    initial velocity, degrees counter-clockwise from east; 0), ``turn_radius`` (2000 m),
    ``sculling_angle`` (0.01 rad), ``sculling_accel`` (1.0 m/s²), ``sculling_frequency``
    (10 Hz), ``gravity_model`` (:data:`~strapdown_ros.earth.DEFAULT_GRAVITY_MODEL`).

    Parameters
    ----------
    cfg : dict
        Node parameters (absent keys take the defaults above).

    Returns
    -------
    EarthProfile
        The profile.

    Raises
    ------
    ValueError
        For an unknown profile name.

    """
    name = cfg.get('profile', 'static')
    if name not in NAVIGATION_PROFILE_NAMES:
        valid = ', '.join(NAVIGATION_PROFILE_NAMES)
        raise ValueError(f'unknown navigation profile {name!r}; valid: {valid}')
    lat = np.radians(float(cfg.get('nav_latitude_deg', 50.45)))
    lon = np.radians(float(cfg.get('nav_longitude_deg', 30.52)))
    h = float(cfg.get('nav_height', 150.0))
    heading = np.radians(float(cfg.get('nav_heading_deg', 0.0)))
    speed = float(cfg.get('nav_speed', 0.0))
    model = str(cfg.get('gravity_model', DEFAULT_GRAVITY_MODEL))
    if name == 'static':
        return static_profile(lat, lon, h, yaw=heading, gravity_model=model)
    if name == 'straight_flight':
        return straight_flight_profile(lat, lon, h, speed=speed or 200.0, heading=heading,
                                       gravity_model=model)
    if name == 'coordinated_turn':
        return coordinated_turn_profile(lat, lon, h, speed=speed or 100.0,
                                        radius=float(cfg.get('turn_radius', 2000.0)),
                                        heading=heading, gravity_model=model)
    return sculling_profile(lat, lon, h, angle_amplitude=float(cfg.get('sculling_angle', 0.01)),
                            accel_amplitude=float(cfg.get('sculling_accel', 1.0)),
                            frequency=float(cfg.get('sculling_frequency', 10.0)), yaw=heading,
                            gravity_model=model)


def gravity_sculling_term(angle_amplitude, g_up, omega, interval):
    """
    Return the mean vertical drift of ``rotation_only`` from a roll oscillation in gravity.

    The roll oscillation is θ = A sin(wt), in gravity alone (no lateral acceleration); the
    drift is in the navigation frame, m/s², + = up.

    To second order in A, with δ(s) = θ(t0 + s) − θ(t0), the error of Δv + ½Δθ×Δv against the
    exact ∫C f dt, in level axes, is ``g(I₁ − ½Δh) ŷ + ½g(ΔI₁ − I₂) ẑ`` (I₁ = ∫δ, I₂ = ∫δ²,
    Δ = δ(h)); averaged over the phase of the step, ⟨ΔI₁ − I₂⟩ = A²h(sin x/x − ½(1 + cos x)),
    x = wh.  So the drift is ``½gA²(sin x/x − ½(1 + cos x))`` ≈ gA²x²/24 (small x), upward,
    against the classical sculling term's downward ½AB(1 − sin x/x).  In body axes at the step
    start the same phase average vanishes (the ŷ error, correlated with θ(t0), turns into ẑ
    only in level axes), so a body-axis drift shows the classical term alone.

    Parameters
    ----------
    angle_amplitude : float or ndarray
        A, rad.
    g_up : float or ndarray
        Upward gravity magnitude, m/s².
    omega : float or ndarray
        w, rad/s.
    interval : float or ndarray
        Update interval h, s.

    Returns
    -------
    float or ndarray
        The drift, m/s².

    """
    x = np.asarray(omega, dtype=float) * np.asarray(interval, dtype=float)
    small = np.abs(x) < 1e-2
    xs = np.where(small, 1.0, x)
    bracket = np.where(small, x ** 2 / 12.0 - x ** 4 / 180.0,
                       np.sin(xs) / xs - 0.5 * (1.0 + np.cos(xs)))
    a = np.asarray(angle_amplitude, dtype=float)
    return 0.5 * np.asarray(g_up, dtype=float) * a ** 2 * bracket
