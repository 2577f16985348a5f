"""
Body-frame motion profiles with exact truth: coning, piecewise-constant rates, presets.

Each is a :class:`~strapdown_ros.motion.profile_base.MotionProfile` (the interface the
simulated sensors and the benches sample).

Exactness
---------
* :class:`ConingProfile`: attitude, rate and increments are closed-form (Aksyonenko
  2014, 003, §2.2, with the printed misprints of (2.6) and (2.10) corrected, see
  doc/coning_derivations.md); Δv by the quadrature of the base class.
* :class:`PiecewiseRateProfile`: body rate piecewise constant relative to an
  optionally rotating Earth frame.  Attitude and both increments are closed-form
  (Rodrigues' formula and its time integral); an interval that spans segment
  boundaries is split at the boundaries.  Round-off only (~1e-16 rad).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from strapdown_ros.motion.profile_base import MotionProfile
from strapdown_ros.rotation import (quat_multiply, quat_normalize, quat_to_dcm, rotvec_to_quat,
                                    skew)

EARTH_RATE = 7.2921150e-5      # rad/s, PZ-90 / WGS-84
STANDARD_GRAVITY = 9.80665     # m/s²

__all__ = ['ConingProfile', 'PiecewiseRateProfile', 'Segment', 'tkachenko_profile',
           'bench_profile', 'EARTH_RATE', 'STANDARD_GRAVITY']


class ConingProfile(MotionProfile):
    """
    Classical coning motion, 003 §2.2.

    The rotation vector of the body relative to the reference (in body axes, which
    coincide with reference axes for this vector) is (2.4)
    ``φ(t) = α·[sin νt, cos νt, 0]``, so ``U(t) = exp([φ×])`` (2.5); the body z axis
    describes a cone of half-angle α about the reference Z axis.  The body rate is
    (2.9) ``ω = [ν sin α cos νt, −ν sin α sin νt, ν(1 − cos α)]`` and the exact
    increments are ``Δθ_x = sin α (sin νt1 − sin νt0)``,
    ``Δθ_y = sin α (cos νt1 − cos νt0)``, ``Δθ_z = ν(1 − cos α)(t1 − t0)``.
    (The printed (2.10) carries a spurious leading minus on x and y.)

    The cone axis is the reference Z axis; a perfect algorithm has zero mean drift
    about it and any algorithmic error accumulates about it (003 §2.3).

    Parameters
    ----------
    alpha : float
        Cone half-angle α, rad.
    nu : float
        Coning frequency ν, rad/s.
    gravity : sequence of 3 float
        Specific force of the body at rest, reference axes, m/s².
    duration : float
        Length of the motion, s.

    """

    def __init__(self, alpha: float, nu: float, gravity: Sequence[float] = (0.0, 0.0, 0.0),
                 duration: float = np.inf):
        if not np.isfinite(alpha) or not np.isfinite(nu):
            raise ValueError('coning alpha and nu must be finite')
        self.alpha = float(alpha)
        self.nu = float(nu)
        self.duration = float(duration)
        self.reference_specific_force = np.asarray(gravity, dtype=float)

    def rotation_vector(self, t) -> np.ndarray:
        """
        Return the rotation vector φ(t) = α·[sin νt, cos νt, 0] of (2.4).

        Parameters
        ----------
        t : float or ndarray
            Times, s from the profile origin.

        Returns
        -------
        (..., 3) ndarray
            φ, rad.

        """
        t = np.asarray(t, dtype=float)
        phase = self.nu * t
        return self.alpha * np.stack([np.sin(phase), np.cos(phase), np.zeros_like(t)], -1)

    def attitude(self, t) -> np.ndarray:
        """
        Return q_ref_body = exp(φ(t)).

        Parameters
        ----------
        t : float or ndarray
            Times, s from the profile origin.

        Returns
        -------
        (..., 4) ndarray
            Quaternions, scalar-first.

        """
        return rotvec_to_quat(self.rotation_vector(t))

    def body_rate(self, t) -> np.ndarray:
        """
        Return the body rate (2.9).

        Parameters
        ----------
        t : float or ndarray
            Times, s from the profile origin.

        Returns
        -------
        (..., 3) ndarray
            ω, rad/s, body axes.

        """
        t = np.asarray(t, dtype=float)
        a, v = self.alpha, self.nu
        return np.stack([v * np.sin(a) * np.cos(v * t), -v * np.sin(a) * np.sin(v * t),
                         np.full_like(t, v * self._one_minus_cos)], -1)

    @property
    def _one_minus_cos(self) -> float:
        # 1 − cos α written without cancellation: 1 − cos(0.087) loses ~3e-15 of its value,
        # which would put a spurious common drift of ~2e-17 rad/s into every algorithm
        return 2.0 * np.sin(0.5 * self.alpha) ** 2

    def delta_theta(self, t0, t1) -> np.ndarray:
        """
        Return the closed-form increments (2.10, sign corrected).

        Parameters
        ----------
        t0, t1 : float or ndarray
            Interval starts and ends, s (broadcast).

        Returns
        -------
        (..., 3) ndarray
            Δθ, rad, body axes.

        """
        t0 = np.asarray(t0, dtype=float)
        t1 = np.asarray(t1, dtype=float)
        a, v = self.alpha, self.nu
        # sin(x1) - sin(x0) = 2 cos((x1+x0)/2) sin((x1-x0)/2): no cancellation for short intervals
        half = 0.5 * v * (t1 - t0)
        mid = 0.5 * v * (t1 + t0)
        s = 2.0 * np.sin(half)
        return np.stack([np.sin(a) * np.cos(mid) * s, -np.sin(a) * np.sin(mid) * s,
                         v * self._one_minus_cos * (t1 - t0)], -1)

    def _quadrature_step(self) -> float:
        return 1.0 / (8.0 * max(abs(self.nu), 1e-9))

    def _frequency(self) -> float:
        return abs(self.nu)

    @property
    def cone_period(self) -> float:
        """Period 2π/|ν| of the coning motion, s."""
        return 2.0 * np.pi / abs(self.nu)


@dataclass
class Segment:
    """
    One segment of a piecewise-rate profile.

    Attributes
    ----------
    duration : float
        Length, s, > 0.
    rate : (3,) ndarray
        Constant body rate relative to Earth, rad/s, body axes.

    """

    duration: float
    rate: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        self.rate = np.asarray(self.rate, dtype=float).reshape(3)
        if not (np.isfinite(self.duration) and self.duration > 0):
            raise ValueError(f'segment duration must be positive and finite, got {self.duration}')
        if not np.all(np.isfinite(self.rate)):
            raise ValueError('segment rate must be finite')


def _rodrigues_integral(u: np.ndarray, s: np.ndarray) -> np.ndarray:
    """
    ``∫_0^s exp([u×] σ) dσ`` for constant u (3,), times s (...) → (..., 3, 3).

    = s·I + (1 − cos(ws))/w²·[u×] + (ws − sin(ws))/w³·[u×]², with series near w = 0.
    """
    s = np.asarray(s, dtype=float)
    w = np.linalg.norm(u)
    K = skew(u)
    x = w * s
    small = np.abs(x) < 1e-3
    with np.errstate(invalid='ignore', divide='ignore'):
        w_safe = np.where(w > 0, w, 1)
        a = np.where(small, s ** 2 * (0.5 - x ** 2 / 24.0 + x ** 4 / 720.0),
                     (1 - np.cos(x)) / w_safe ** 2)
        b = np.where(small, s ** 3 * (1.0 / 6.0 - x ** 2 / 120.0 + x ** 4 / 5040.0),
                     (x - np.sin(x)) / w_safe ** 3)
    return s[..., None, None] * np.eye(3) + a[..., None, None] * K + b[..., None, None] * (K @ K)


class PiecewiseRateProfile(MotionProfile):
    """
    Body rate piecewise constant relative to an Earth frame E that may rotate.

    Attitude: ``q_I_B(t) = q_I_E(t) ⊗ q_E_B(t)`` with ``q_I_E(t) = exp(Ω_E·t)`` (Earth
    rotation about the fixed vector ``earth_rate`` in reference axes; zero by
    default) and ``q_E_B`` propagated through the segments from ``initial_attitude``.
    The absolute body rate is ``ω = ω_seg + C_B_E(t)·Ω_E``; its integral over any
    interval is closed-form (:func:`_rodrigues_integral`).  After the last segment
    the body holds still relative to E.

    ``reference_specific_force`` is the specific force of a body at rest in E,
    expressed in E axes (e.g. ``[0, 0, g]`` for an ENU bench); it is rotated into
    body axes through ``C_B_E`` (so it stays fixed on the rotating Earth).

    Parameters
    ----------
    segments : sequence of Segment
        The segments, in order (at least one).
    initial_attitude : sequence of 4 float
        q_E_B at t = 0, scalar-first.
    earth_rate : sequence of 3 float
        Ω_E, rad/s, reference axes.
    gravity : sequence of 3 float
        Specific force at rest in E, E axes, m/s².
    name : str
        Profile name.

    """

    def __init__(self, segments: Sequence[Segment], initial_attitude=(1.0, 0.0, 0.0, 0.0),
                 earth_rate: Sequence[float] = (0.0, 0.0, 0.0),
                 gravity: Sequence[float] = (0.0, 0.0, 0.0), name: str = 'piecewise'):
        if len(segments) == 0:
            raise ValueError('a piecewise profile needs at least one segment')
        self.name = name
        self.segments = list(segments)
        q0 = np.asarray(initial_attitude, dtype=float)
        if q0.shape != (4,) or not np.all(np.isfinite(q0)) or np.linalg.norm(q0) < 0.5:
            raise ValueError('initial_attitude must be a finite quaternion [w, x, y, z]')
        self.q0 = quat_normalize(q0)
        self.earth_rate = np.asarray(earth_rate, dtype=float)
        self.reference_specific_force = np.asarray(gravity, dtype=float)
        self.rates = np.array([s.rate for s in self.segments])
        self.starts = np.concatenate([[0.0], np.cumsum([s.duration for s in self.segments])])
        self.duration = float(self.starts[-1])
        # attitude q_E_B at each segment start
        qs = [self.q0]
        for seg in self.segments:
            turn = rotvec_to_quat(seg.rate * seg.duration)
            qs.append(quat_normalize(quat_multiply(qs[-1], turn)))
        self.segment_q = np.array(qs)

    # --- helpers -------------------------------------------------------------------
    def _segment_index(self, t: np.ndarray) -> np.ndarray:
        idx = np.searchsorted(self.starts, t, side='right') - 1
        # index len(segments): the hold after the end
        return np.clip(idx, 0, len(self.segments))

    def _rate_of(self, idx: np.ndarray) -> np.ndarray:
        rates = np.vstack([self.rates, np.zeros((1, 3))])
        return rates[idx]

    def attitude_earth(self, t) -> np.ndarray:
        """
        Return ``q_E_B(t)``: the attitude relative to the (possibly rotating) Earth frame.

        Parameters
        ----------
        t : float or ndarray
            Times, s from the profile origin.

        Returns
        -------
        (..., 4) ndarray
            Quaternions, scalar-first.

        """
        t = np.asarray(t, dtype=float)
        idx = self._segment_index(t)
        dt = t - self.starts[idx]
        return quat_normalize(quat_multiply(self.segment_q[idx],
                                            rotvec_to_quat(self._rate_of(idx) * dt[..., None])))

    def attitude(self, t) -> np.ndarray:
        """
        Return ``q_I_B(t) = q_I_E(t) ⊗ q_E_B(t)``.

        Parameters
        ----------
        t : float or ndarray
            Times, s from the profile origin.

        Returns
        -------
        (..., 4) ndarray
            Quaternions, scalar-first.

        """
        t = np.asarray(t, dtype=float)
        q_ie = rotvec_to_quat(self.earth_rate * t[..., None])
        return quat_normalize(quat_multiply(q_ie, self.attitude_earth(t)))

    def body_rate(self, t) -> np.ndarray:
        """
        Return the absolute body rate ``ω_seg + C_B_E(t)·Ω_E``.

        Parameters
        ----------
        t : float or ndarray
            Times, s from the profile origin.

        Returns
        -------
        (..., 3) ndarray
            ω, rad/s, body axes.

        """
        t = np.asarray(t, dtype=float)
        idx = self._segment_index(t)
        c_eb = quat_to_dcm(self.attitude_earth(t))
        return self._rate_of(idx) + np.einsum('...ji,j->...i', c_eb, self.earth_rate)

    def specific_force(self, t) -> np.ndarray:
        """
        Return the specific force at rest in E, rotated into body axes.

        Parameters
        ----------
        t : float or ndarray
            Times, s from the profile origin.

        Returns
        -------
        (..., 3) ndarray
            f, m/s², body axes.

        """
        c_eb = quat_to_dcm(self.attitude_earth(np.asarray(t, dtype=float)))
        return np.einsum('...ji,j->...i', c_eb, self.reference_specific_force)

    def _segments_touched(self, t0: np.ndarray, t1: np.ndarray, n: int) -> range:
        """
        Return the indices (< n) of the segments intervals within [min t0, max t1] can touch.

        The others contribute exactly zero, so a short block costs a few segments, not all.
        """
        if t0.size == 0 or t1.size == 0:
            return range(0)
        lo = int(np.searchsorted(self.starts, min(t0.min(), t1.min()), side='right')) - 1
        hi = int(np.searchsorted(self.starts, max(t0.max(), t1.max()), side='left'))
        return range(max(lo, 0), min(hi + 1, n))

    def _integral_of_cbe(self, t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
        """``∫_{t0}^{t1} C_B_E(t) dt`` (3×3 each), exact, splitting at segment boundaries."""
        t0 = np.asarray(t0, dtype=float)
        t1 = np.asarray(t1, dtype=float)
        out = np.zeros(np.broadcast(t0, t1).shape + (3, 3))
        bounds = np.concatenate([self.starts, [np.inf]])
        for i in self._segments_touched(t0, t1, len(self.segments) + 1):
            a = np.clip(t0, bounds[i], bounds[i + 1])
            b = np.clip(t1, bounds[i], bounds[i + 1])
            active = b > a
            if not np.any(active):
                continue
            u = self.rates[i] if i < len(self.segments) else np.zeros(3)
            c_start = quat_to_dcm(self.segment_q[i])             # C_E_B at segment start
            # C_B_E(t) = exp(-[u×](t - ts)) C_start^T ; ∫ exp(-[u×]σ)dσ = R(-u, σ)
            ia = _rodrigues_integral(-u, np.where(active, a - bounds[i], 0.0))
            ib = _rodrigues_integral(-u, np.where(active, b - bounds[i], 0.0))
            out += np.where(active[..., None, None], (ib - ia) @ c_start.T, 0.0)
        return out

    def delta_theta(self, t0, t1) -> np.ndarray:
        """
        Return the exact ∫ω dt over [t0, t1], split at the segment boundaries.

        Parameters
        ----------
        t0, t1 : float or ndarray
            Interval starts and ends, s (broadcast).

        Returns
        -------
        (..., 3) ndarray
            Δθ, rad, body axes.

        """
        t0 = np.asarray(t0, dtype=float)
        t1 = np.asarray(t1, dtype=float)
        out = np.zeros(np.broadcast(t0, t1).shape + (3,))
        bounds = np.concatenate([self.starts, [np.inf]])
        for i in self._segments_touched(t0, t1, len(self.segments)):
            a = np.clip(t0, bounds[i], bounds[i + 1])
            b = np.clip(t1, bounds[i], bounds[i + 1])
            out += np.maximum(b - a, 0.0)[..., None] * self.rates[i]
        if np.any(self.earth_rate):
            out += self._integral_of_cbe(t0, t1) @ self.earth_rate
        return out

    def delta_v(self, t0, t1, max_step=None) -> np.ndarray:
        """
        Return the exact ∫f dt over [t0, t1] (closed form).

        Parameters
        ----------
        t0, t1 : float or ndarray
            Interval starts and ends, s (broadcast).
        max_step : float or None
            Unused (the integral is closed-form).

        Returns
        -------
        (..., 3) ndarray
            Δv, m/s, body axes.

        """
        if not np.any(self.reference_specific_force):
            return np.zeros(np.broadcast(np.asarray(t0), np.asarray(t1)).shape + (3,))
        return self._integral_of_cbe(t0, t1) @ self.reference_specific_force


# --- presets ----------------------------------------------------------------------------
def tkachenko_profile() -> PiecewiseRateProfile:
    """
    Return the test motion of Tkachenko (1983, 000) §6.

    Piecewise-constant body rates over [0, 30] s and Λ(0) = 0.64+0.48i1+0.36i2−0.48i3.

    Returns
    -------
    PiecewiseRateProfile
        The profile, no Earth rate, no gravity.

    """
    table = [(0.01, 0.02, -0.01), (0.02, 0.32, -0.015), (0.01, 0.01, -0.02),
             (0.16, 0.015, -0.03), (0.03, 0.017, -0.16), (0.02, 0.02, -0.02)]
    return PiecewiseRateProfile([Segment(5.0, r) for r in table],
                                initial_attitude=(0.64, 0.48, 0.36, -0.48), name='tkachenko')


def bench_profile(latitude_deg: float = 50.45, earth_rate: bool = True,
                  hold: float = 20.0, rotation_time: float = 5.0,
                  angles_deg: Sequence[float] = (15.0, -12.0, 10.0, -15.0, 12.0, -10.0),
                  axes: Sequence[int] = (2, 0, 1, 2, 0, 1),
                  repeat: int = 1) -> PiecewiseRateProfile:
    """
    Return a bench sequence in the spirit of 004 §6.

    Static holds and 10–15° rotations about the body z, x and y axes in turn, on a bench that
    turns with the Earth.  Reference frame: inertial, coinciding with the local ENU frame at
    t = 0.  Earth rate in ENU is Ω·[0, cos φ, sin φ]; gravity specific force [0, 0, g].

    Parameters
    ----------
    latitude_deg : float
        Latitude φ, degrees.
    earth_rate : bool
        The bench turns with the Earth.
    hold : float
        Length of each static hold, s.
    rotation_time : float
        Length of each rotation, s.
    angles_deg : sequence of float
        Rotation angles, degrees.
    axes : sequence of int
        Body axis of each rotation (0 x, 1 y, 2 z).
    repeat : int
        Passes of the sequence (the turns of a pass cancel about each axis, so the attitude
        stays near the start).

    Returns
    -------
    PiecewiseRateProfile
        The profile.

    """
    segments = [Segment(hold)]
    for ang, ax in list(zip(angles_deg, axes)) * int(repeat):
        rate = np.zeros(3)
        rate[ax] = np.radians(ang) / rotation_time
        segments += [Segment(rotation_time, rate), Segment(hold)]
    lat = np.radians(latitude_deg)
    omega = EARTH_RATE * np.array([0.0, np.cos(lat), np.sin(lat)]) if earth_rate else np.zeros(3)
    return PiecewiseRateProfile(segments, earth_rate=omega,
                                gravity=(0.0, 0.0, STANDARD_GRAVITY), name='bench')
