"""
Earth-referenced motion profiles with exact position, velocity and attitude truth.

An :class:`EarthProfile` is a :class:`~strapdown_ros.motion.profiles.MotionProfile` (usable wherever
one is: the simulated sensors, the attitude benches) whose motion is given in the Earth-fixed
frame E (ECEF, PZ-90, rotating at Ω = :data:`OMEGA` about +Z).

Frames and conventions
----------------------
* Profile time ``t ≥ 0``.  The inertial frame I coincides with E at ``t = 0``:
  ``C_I_E(t) = R_z(+Ωt)`` (a vector fixed in E has inertial coordinates turning at +Ω about Z).
* ``attitude(t)`` is ``q_I_B`` (the :class:`MotionProfile` convention: body → inertial
  reference), ``attitude_ecef(t)`` is ``q_E_B = q_I_E(t)* ⊗ q_I_B``.  Hamilton, scalar-first.
* Body axes: x forward, y left, z up (REP-103 body FLU).
* Local level axes: ENU of the geodetic point (``enu_rotation``); an ENU *yaw* (the
  ``yaw``/``heading`` arguments) is the REP-103 yaw: counter-clockwise seen from up, measured
  from east (0 = east, π/2 = north).  ``static_profile`` pitch and roll follow tf2's
  ``setRPY``: ``C_ENU_B = R_z(yaw) R_y(pitch) R_x(roll)`` (positive pitch = nose down in FLU).

Kinematics (from analytic position R(t), E-frame derivatives Ṙ, R̈, attitude q_E_B(t) and
rate ω_EB of B relative to E in body axes):

* ``body_rate = ω_EB + C_B_E Ω_E`` (absolute rate, Ω_E = [0, 0, Ω]);
* ``specific_force = C_B_E (R̈ + 2Ω×Ṙ − g(R))`` with ``g = normal_gravity(R, model)``
  (gravitation + centrifugal); this is 003 (1.93), ``R̈ = V f − 2Ω×Ṙ + g`` with V = C_E_B;
* ``delta_theta`` / ``delta_v``: composite Gauss–Legendre quadrature of the two (below).

Quadrature
----------
Each profile states the highest angular frequency ν (rad/s) in its body-axis integrands
(never taken below :data:`MIN_FREQUENCY`).  An interval of length L is split into
``ceil(ν L / 1 rad)`` equal sub-intervals (at most 1 rad of phase each) and integrated with the
n-point Gauss–Legendre rule, n the smallest (≥ 3) with the rule's error bound
``(n!)⁴ / ((2n+1)((2n)!)³) · (2νh)^(2n) < 1e-16`` (h the sub-interval, the factor 2 a margin
for harmonics).  All intervals of one call share the rule set by the longest one; the work is
vectorised over intervals and nodes (a 600 s, 300 Hz run of 180 000 intervals is one pass).
The tests check the result against a rule with twice the nodes and twice the sub-intervals
(relative agreement ≤ 1e-12) and against closed forms (static profile; Δθ of the constant
rate profiles).  Node times are ``t0 + L·s`` in float64, so far from ``t = 0`` the
integrands are sampled with an absolute time error of ~1 ulp(t), which bounds the agreement
of two different rules at ~ν·ulp(t) relative (1e-13 at t = 600 s, ν = 60 rad/s).

Presets
-------
:func:`static_profile`, :func:`straight_flight_profile`, :func:`coordinated_turn_profile`,
:func:`sculling_profile`; :func:`navigation_profile_from_config` builds them from node
parameters.  :func:`sculling_drift_rate` is the classical sculling error rate.
"""
from __future__ import annotations

from math import factorial
from typing import Callable

import numpy as np

from strapdown_ros.earth import (DEFAULT_GRAVITY_MODEL, ecef_to_geodetic, enu_rotation,
                                 geodetic_to_ecef, normal_gravity, OMEGA)
from strapdown_ros.motion.profiles import MotionProfile
from strapdown_ros.rotation import dcm_to_quat, quat_multiply, quat_normalize, quat_to_dcm

__all__ = ['EarthProfile', 'static_profile', 'straight_flight_profile', 'coordinated_turn_profile',
           'sculling_profile', 'sculling_drift_rate', 'gravity_sculling_term', 'navigation_profile_from_config',
           'NAVIGATION_PROFILE_NAMES', 'MIN_FREQUENCY']

NAVIGATION_PROFILE_NAMES = ('static', 'straight_flight', 'coordinated_turn', 'sculling')

#: floor of the quadrature frequency, rad/s (gravity along the path varies far slower)
MIN_FREQUENCY = 1e-2
_MAX_PHASE = 1.0               # rad of the highest frequency per sub-interval
_RULE_TOLERANCE = 1e-16
_HARMONIC_MARGIN = 2.0
_BLOCK = 1 << 20               # integrand evaluations per vectorised pass
_RULES: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def _gauss_rule(n: int) -> tuple[np.ndarray, np.ndarray]:
    if n not in _RULES:
        _RULES[n] = np.polynomial.legendre.leggauss(n)
    return _RULES[n]


def _points_for(x: float) -> int:
    """Smallest n ≥ 3 whose Gauss–Legendre error bound for phase x per sub-interval is < 1e-16."""
    x = _HARMONIC_MARGIN * x
    for n in range(3, 16):
        if factorial(n) ** 4 / ((2 * n + 1) * float(factorial(2 * n)) ** 3) * x ** (2 * n) < _RULE_TOLERANCE:
            return n
    return 16


def _zeros3(t: np.ndarray) -> np.ndarray:
    return np.zeros(np.shape(t) + (3,))


def _constant(v) -> Callable[[np.ndarray], np.ndarray]:
    v = np.asarray(v, dtype=float)
    return lambda t: np.zeros(np.shape(t) + v.shape) + v


def _q_ie(t: np.ndarray) -> np.ndarray:
    """``q_I_E(t)``: rotation by +Ωt about Z."""
    half = 0.5 * OMEGA * np.asarray(t, dtype=float)
    z = np.zeros_like(half)
    return np.stack([np.cos(half), z, z, np.sin(half)], -1)


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
    return np.concatenate([np.cos(half)[..., None], _outer(np.sin(half), np.asarray(axis, dtype=float))], -1)


def _outer(scalar: np.ndarray, vec: np.ndarray) -> np.ndarray:
    return np.asarray(scalar, dtype=float)[..., None] * vec


class EarthProfile(MotionProfile):
    """
    Motion given in the rotating Earth frame E, with exact truth (see the module docstring).

    Parameters are callables of a time array ``t`` (any shape S) returning arrays of shape
    S + (3,) (S + (4,) for the attitude): ``position`` R(t) (ECEF, m), ``velocity`` Ṙ(t),
    ``acceleration`` R̈(t) (E-frame derivatives), ``attitude_ecef`` q_E_B(t) and
    ``earth_relative_rate`` ω_EB(t) (rate of B relative to E, body axes, rad/s).
    ``frequency`` (rad/s) is the highest angular frequency of the body-axis integrands (it sets
    the quadrature rule).  ``parameters`` records the preset's parameters (informational).
    """

    reference_specific_force = np.zeros(3)   # not used: specific_force is computed from the motion

    def __init__(self, position, velocity, acceleration, attitude_ecef, earth_relative_rate, *,
                 frequency: float = 0.0, duration: float = np.inf, name: str = 'earth',
                 gravity_model: str = DEFAULT_GRAVITY_MODEL, parameters: dict | None = None):
        self._position = position
        self._velocity = velocity
        self._acceleration = acceleration
        self._attitude_ecef = attitude_ecef
        self._rate = earth_relative_rate
        if not (np.isfinite(frequency) and frequency >= 0):
            raise ValueError(f'frequency must be finite and ≥ 0, got {frequency}')
        self.frequency = max(float(frequency), MIN_FREQUENCY)
        self.duration = float(duration)
        self.name = name
        self.gravity_model = gravity_model
        self.parameters = dict(parameters or {})
        self.initial_position = np.asarray(self.position(0.0), dtype=float)
        self.initial_velocity = np.asarray(self.velocity(0.0), dtype=float)
        # fail early on an unknown gravity model
        normal_gravity(self.initial_position, model=self.gravity_model)

    # --- truth in E ------------------------------------------------------------------
    def position(self, t) -> np.ndarray:
        """ECEF position R(t), m."""
        return self._position(np.asarray(t, dtype=float))

    def velocity(self, t) -> np.ndarray:
        """Ṙ(t): velocity relative to E in ECEF axes, m/s."""
        return self._velocity(np.asarray(t, dtype=float))

    def acceleration(self, t) -> np.ndarray:
        """R̈(t): E-frame second derivative of the position, ECEF axes, m/s²."""
        return self._acceleration(np.asarray(t, dtype=float))

    def attitude_ecef(self, t) -> np.ndarray:
        """``q_E_B(t)`` (body → ECEF)."""
        return self._attitude_ecef(np.asarray(t, dtype=float))

    def earth_relative_rate(self, t) -> np.ndarray:
        """ω_EB(t): angular rate of the body relative to E, body axes, rad/s."""
        return self._rate(np.asarray(t, dtype=float))

    def gravity(self, t) -> np.ndarray:
        """Normal gravity g(R(t)) (gravitation + centrifugal), ECEF axes, m/s²."""
        return normal_gravity(self.position(t), model=self.gravity_model)

    # --- MotionProfile interface --------------------------------------------------------
    def attitude(self, t) -> np.ndarray:
        """``q_I_B(t) = q_I_E(t) ⊗ q_E_B(t)``."""
        t = np.asarray(t, dtype=float)
        return quat_normalize(quat_multiply(_q_ie(t), self.attitude_ecef(t)))

    def body_rate(self, t) -> np.ndarray:
        """Absolute rate ``ω_EB + C_B_E Ω_E`` in body axes."""
        t = np.asarray(t, dtype=float)
        c_eb = quat_to_dcm(self.attitude_ecef(t))
        return self.earth_relative_rate(t) + OMEGA * c_eb[..., 2, :]

    def _specific_force_ecef(self, t: np.ndarray, r: np.ndarray) -> np.ndarray:
        v = self.velocity(t)
        a = self.acceleration(t)
        coriolis = np.stack([-v[..., 1], v[..., 0], np.zeros_like(v[..., 0])], -1) * (2.0 * OMEGA)
        return a + coriolis - normal_gravity(r, model=self.gravity_model)

    def specific_force(self, t) -> np.ndarray:
        """``C_B_E (R̈ + 2Ω×Ṙ − g(R))``, body axes, m/s²."""
        t = np.asarray(t, dtype=float)
        c_eb = quat_to_dcm(self.attitude_ecef(t))
        f_e = self._specific_force_ecef(t, self.position(t))
        return np.einsum('...ji,...j->...i', c_eb, f_e)

    def delta_theta(self, t0, t1) -> np.ndarray:
        """∫ body_rate dt over each [t0, t1] (composite Gauss–Legendre, see the module docstring)."""
        return self.integrate(self.body_rate, t0, t1)

    def delta_v(self, t0, t1, max_step: float | None = None) -> np.ndarray:
        """∫ specific_force dt over each [t0, t1]; ``max_step`` optionally caps the sub-interval."""
        return self.integrate(self.specific_force, t0, t1, max_step=max_step)

    def quadrature_rule(self, length: float, max_step: float | None = None) -> tuple[int, int]:
        """``(sub-intervals, points)`` used for intervals up to ``length`` seconds."""
        length = abs(float(length))
        n_sub = max(1, int(np.ceil(self.frequency * length / _MAX_PHASE)))
        if max_step is not None and max_step > 0:
            n_sub = max(n_sub, int(np.ceil(length / max_step)))
        return n_sub, _points_for(self.frequency * length / n_sub)

    def integrate(self, fun, t0, t1, points: int | None = None, subintervals: int | None = None,
                  max_step: float | None = None) -> np.ndarray:
        """
        ``∫_{t0}^{t1} fun(t) dt`` for a vectorised ``fun(t) -> (..., 3)``, broadcasting t0, t1.

        ``points``/``subintervals`` override the automatic rule (used by the tests to compare
        against a finer one).
        """
        b = np.broadcast(np.asarray(t0), np.asarray(t1))
        shape = b.shape
        a0, a1 = (np.asarray(x, dtype=float).ravel() for x in np.broadcast_arrays(t0, t1))
        length = a1 - a0
        out = np.zeros(a0.shape + (3,))
        if a0.size == 0:
            return out.reshape(shape + (3,))
        n_sub, n_pts = self.quadrature_rule(float(np.max(np.abs(length))), max_step)
        if subintervals is not None:
            n_sub = int(subintervals)
        if points is not None:
            n_pts = int(points)
        x, w = _gauss_rule(n_pts)
        frac = ((np.arange(n_sub)[:, None] + 0.5 * (x + 1.0)[None, :]) / n_sub).ravel()
        weights = np.tile(w, n_sub) * (0.5 / n_sub)             # sums to 1 over [0, 1]
        n_int = a0.size
        rows = max(1, _BLOCK // max(1, frac.size))               # intervals per pass
        cols = max(1, _BLOCK // n_int)                           # nodes per pass
        for i in range(0, n_int, rows):
            s0, ln = a0[i:i + rows], length[i:i + rows]
            acc = np.zeros(s0.shape + (3,))
            for j in range(0, frac.size, cols):
                nodes = s0[:, None] + ln[:, None] * frac[None, j:j + cols]
                acc += np.einsum('k,nkj->nj', weights[j:j + cols], fun(nodes))
            out[i:i + rows] = acc * ln[:, None]
        return out.reshape(shape + (3,))

    def _quadrature_step(self) -> float:                        # base-class hook, for completeness
        return _MAX_PHASE / self.frequency

    def _frequency(self) -> float:
        return self.frequency

    # --- everything at once ----------------------------------------------------------
    def truth(self, t) -> dict:
        """
        All truth at times ``t``: a dict of arrays (leading shape of ``t``).

        Keys: ``time``; ``position``, ``velocity``, ``acceleration`` (ECEF); ``velocity_body``
        (C_B_E Ṙ); ``latitude``, ``longitude`` (rad), ``height`` (m, geodetic, PZ-90 ellipsoid
        of :mod:`.gravity`); ``attitude`` (q_I_B), ``attitude_ecef`` (q_E_B);
        ``earth_relative_rate`` (ω_EB), ``body_rate`` (absolute); ``gravity`` (ECEF);
        ``specific_force`` (body).
        """
        t = np.asarray(t, dtype=float)
        q_eb = self.attitude_ecef(t)
        c_eb = quat_to_dcm(q_eb)
        r = self.position(t)
        v = self.velocity(t)
        a = self.acceleration(t)
        g = normal_gravity(r, model=self.gravity_model)
        w_eb = self.earth_relative_rate(t)
        coriolis = np.stack([-v[..., 1], v[..., 0], np.zeros_like(v[..., 0])], -1) * (2.0 * OMEGA)
        geo = ecef_to_geodetic(r)
        lat, lon, h = (geo[..., 0], geo[..., 1], geo[..., 2]) if isinstance(geo, np.ndarray) else geo
        to_body = lambda x: np.einsum('...ji,...j->...i', c_eb, x)  # noqa: E731
        return {
            'time': t, 'position': r, 'velocity': v, 'acceleration': a, 'velocity_body': to_body(v),
            'latitude': np.asarray(lat), 'longitude': np.asarray(lon), 'height': np.asarray(h),
            'attitude': quat_normalize(quat_multiply(_q_ie(t), q_eb)), 'attitude_ecef': q_eb,
            'earth_relative_rate': w_eb, 'body_rate': w_eb + OMEGA * c_eb[..., 2, :],
            'gravity': g, 'specific_force': to_body(a + coriolis - g),
        }

    def __repr__(self) -> str:
        return f'EarthProfile({self.name!r}, {self.parameters})'


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
    At rest on the rotating Earth at geodetic (lat, lon, h) (radians, m).

    ``C_ENU_B = R_z(yaw) R_y(pitch) R_x(roll)`` (tf2 ``setRPY``; yaw counter-clockwise from east,
    REP-103).  f = −C_B_E g(R) and ω = C_B_E Ω_E are constant in body axes.
    """
    _check_finite(lat=lat, lon=lon, h=h, yaw=yaw, pitch=pitch, roll=roll)
    r0 = _ecef(lat, lon, h)
    c_eb = _enu(lat, lon) @ _rz(yaw) @ _ry(pitch) @ _rx(roll)
    q0 = quat_normalize(dcm_to_quat(c_eb))
    return EarthProfile(_constant(r0), _zeros3, _zeros3, _constant(q0), _zeros3,
                        frequency=0.0, duration=duration, name='static', gravity_model=gravity_model,
                        parameters=dict(lat=lat, lon=lon, h=h, yaw=yaw, pitch=pitch, roll=roll))


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
    turns relative to E at the constant rate (v/r) about body y (nose down, following the sphere).
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
                        parameters=dict(lat=lat, lon=lon, h=h, speed=v, heading=heading, radius=r,
                                        axis=n, rate=rate))


def coordinated_turn_profile(lat: float, lon: float, h: float = 0.0, speed: float = 100.0,
                             radius: float = 2000.0, heading: float = 0.0, bank: float | None = None,
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
                        parameters=dict(lat=lat, lon=lon, h=h, speed=v, radius=rho, heading=heading,
                                        bank=bank, bank_nominal=bank_nominal, g0=g0, turn_rate=psi_dot,
                                        centre=rc))


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

    In body axes the in-phase lateral specific force has amplitude ``B_eff = B + A·g`` (gravity,
    tilted by the roll oscillation, adds A·g to body y); ``parameters['effective_accel_amplitude']``
    holds it.  It is the B of the *first-order* sculling term ``½∫(α×f + v×ω) dt``
    (test/motion/test_earth_profiles.py).  It is **not** the B of the drift of a Δv without sculling
    compensation: the second-order rotation of the large vertical force, ``½α×(α×g ẑ)``, cancels
    the A·g part in body axes, so that drift is :func:`sculling_drift_rate` with the real B
    (measured by ``nav_bench``, doc/bench/nav/), plus, in level axes, the term even in B of
    :func:`gravity_sculling_term`.
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
                        parameters=dict(lat=lat, lon=lon, h=h, yaw=yaw, angle_amplitude=A,
                                        accel_amplitude=B, frequency=float(frequency), omega=w,
                                        effective_accel_amplitude=B + A * g_up))


def sculling_drift_rate(angle_amplitude, accel_amplitude, omega, interval):
    """
    Classical sculling error rate ``½·A·B·(1 − sin(wh)/(wh))`` (m/s²), w = ``omega`` (rad/s),
    h = ``interval`` (s), B the in-phase body-y specific-force amplitude.

    For ω = A w cos(wt) x̂ and f = B sin(wt) ŷ, with α(t), v(t) the integrals of ω and f from
    the start t0 of an update interval, ``α×f + v×ω = A B (1 − cos w(t − t0)) ẑ``, so the
    sculling term ``½∫(α×f + v×ω) dt = ½AB(h − sin(wh)/w) ẑ`` over every interval, whatever its
    phase.  A strapdown algorithm with rotation compensation (½Δθ×Δv) but no sculling
    correction omits it, and its velocity error grows at ``−sculling_drift_rate`` along body z
    (a mean specific-force error).  Vectorised; the small-wh limit uses the series (wh)²/6 − ….
    """
    x = np.asarray(omega, dtype=float) * np.asarray(interval, dtype=float)
    small = np.abs(x) < 1e-2
    xs = np.where(small, 1.0, x)
    one_minus_sinc = np.where(small, x ** 2 / 6.0 - x ** 4 / 120.0 + x ** 6 / 5040.0, 1.0 - np.sin(xs) / xs)
    return 0.5 * np.asarray(angle_amplitude, dtype=float) * np.asarray(accel_amplitude, dtype=float) * one_minus_sinc


def navigation_profile_from_config(cfg: dict) -> EarthProfile:
    """
    Build a navigation profile from node parameters.

    ``profile`` ∈ :data:`NAVIGATION_PROFILE_NAMES`; ``nav_latitude_deg`` (50.45),
    ``nav_longitude_deg`` (30.52), ``nav_height`` (150 m), ``nav_speed`` (m/s; 0 = the preset's
    default, 200 straight flight / 100 turn), ``nav_heading_deg`` (ENU yaw of the body /
    initial velocity, degrees counter-clockwise from east; 0), ``turn_radius`` (2000 m),
    ``sculling_angle`` (0.01 rad), ``sculling_accel`` (1.0 m/s²), ``sculling_frequency``
    (10 Hz), ``gravity_model`` (:data:`~.gravity.DEFAULT_GRAVITY_MODEL`).
    """
    name = cfg.get('profile', 'static')
    if name not in NAVIGATION_PROFILE_NAMES:
        raise ValueError(f"unknown navigation profile {name!r}; valid: {', '.join(NAVIGATION_PROFILE_NAMES)}")
    lat = np.radians(float(cfg.get('nav_latitude_deg', 50.45)))
    lon = np.radians(float(cfg.get('nav_longitude_deg', 30.52)))
    h = float(cfg.get('nav_height', 150.0))
    heading = np.radians(float(cfg.get('nav_heading_deg', 0.0)))
    speed = float(cfg.get('nav_speed', 0.0))
    model = str(cfg.get('gravity_model', DEFAULT_GRAVITY_MODEL))
    if name == 'static':
        return static_profile(lat, lon, h, yaw=heading, gravity_model=model)
    if name == 'straight_flight':
        return straight_flight_profile(lat, lon, h, speed=speed or 200.0, heading=heading, gravity_model=model)
    if name == 'coordinated_turn':
        return coordinated_turn_profile(lat, lon, h, speed=speed or 100.0,
                                        radius=float(cfg.get('turn_radius', 2000.0)), heading=heading,
                                        gravity_model=model)
    return sculling_profile(lat, lon, h, angle_amplitude=float(cfg.get('sculling_angle', 0.01)),
                            accel_amplitude=float(cfg.get('sculling_accel', 1.0)),
                            frequency=float(cfg.get('sculling_frequency', 10.0)), yaw=heading,
                            gravity_model=model)


def gravity_sculling_term(angle_amplitude, g_up, omega, interval):
    """
    Mean vertical drift (m/s², + = up) of ``rotation_only`` in the navigation frame caused by a
    roll oscillation θ = A sin(wt) in gravity alone (no lateral acceleration).

    To second order in A, with δ(s) = θ(t0 + s) − θ(t0), the error of Δv + ½Δθ×Δv against the
    exact ∫C f dt, in level axes, is ``g(I₁ − ½Δh) ŷ + ½g(ΔI₁ − I₂) ẑ`` (I₁ = ∫δ, I₂ = ∫δ²,
    Δ = δ(h)); averaged over the phase of the step, ⟨ΔI₁ − I₂⟩ = A²h(sin x/x − ½(1 + cos x)),
    x = wh.  So the drift is ``½gA²(sin x/x − ½(1 + cos x))`` ≈ gA²x²/24 (small x), upward,
    against the classical sculling term's downward ½AB(1 − sin x/x).  In body axes at the step
    start the same phase average vanishes (the ŷ error, correlated with θ(t0), turns into ẑ
    only in level axes), so a body-axis drift shows the classical term alone.
    """
    x = np.asarray(omega, dtype=float) * np.asarray(interval, dtype=float)
    small = np.abs(x) < 1e-2
    xs = np.where(small, 1.0, x)
    bracket = np.where(small, x ** 2 / 12.0 - x ** 4 / 180.0, np.sin(xs) / xs - 0.5 * (1.0 + np.cos(xs)))
    return 0.5 * np.asarray(g_up, dtype=float) * np.asarray(angle_amplitude, dtype=float) ** 2 * bracket
