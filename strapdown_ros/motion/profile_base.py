"""
The interface of every motion profile, with its default specific force and Δv quadrature.

The simulated sensors (:mod:`strapdown_ros.sensors.model`) and the benches sample profiles.  A
profile gives, for any time ``t`` (seconds from the profile origin):

* ``attitude(t)``: ``q_ref_body`` (body → reference, see :mod:`strapdown_ros.rotation`);
* ``body_rate(t)``: absolute angular rate ω in body axes (rad/s);
* ``delta_theta(t0, t1)``: the exact integrating-gyro output ∫ω dt over [t0, t1]
  (the quasi-coordinates of 003 eq. 1.31);
* ``specific_force(t)`` and ``delta_v(t0, t1)``: specific force f in body axes (m/s²)
  and its exact integral (the integrating-accelerometer output).

The reference frame is inertial.  All methods are vectorised over arrays of times.  The
profiles themselves are in :mod:`strapdown_ros.motion.profiles` (body-frame) and
:mod:`strapdown_ros.motion.earth_motion` (Earth-referenced).

The default Δv is n-point Gauss–Legendre quadrature, n (2..8) chosen so that the rule's error
bound (νΔt)^(2n)/(2n)! is below 1e-17 on sub-intervals of at most 1/(8ν) s; for the coning
profile the integrand is a trigonometric polynomial of frequency ≤ 2ν, so the relative
quadrature error is below 1e-15 (checked in the tests against a 32-point rule).
"""
from __future__ import annotations

from math import factorial

import numpy as np

from strapdown_ros.rotation import quat_conjugate, quat_rotate

__all__ = ['MotionProfile']

_GAUSS_LEGENDRE = {n: np.polynomial.legendre.leggauss(n) for n in range(2, 9)}


def _gauss_points(x: float) -> int:
    """Smallest n with x^(2n)/(2n)! < 1e-17 (x = frequency × sub-interval length)."""
    for n in range(2, 9):
        if x ** (2 * n) / factorial(2 * n) < 1e-17:
            return n
    return 8


class MotionProfile:
    """
    Base class of the profiles: subclasses implement attitude, body_rate and delta_theta.

    The default specific force is that of a body without linear acceleration
    (:attr:`reference_specific_force` rotated into body axes), and the default Δv its
    quadrature.
    """

    #: total length in seconds (``inf`` when the motion is unbounded)
    duration: float = np.inf
    #: gravity vector (specific force of a body at rest) in reference axes, m/s²
    reference_specific_force: np.ndarray = np.zeros(3)

    def attitude(self, t) -> np.ndarray:
        """
        Return the attitude q_ref_body.

        Parameters
        ----------
        t : float or ndarray
            Times, s from the profile origin.

        Returns
        -------
        (..., 4) ndarray
            Hamilton quaternions, scalar-first.

        """
        raise NotImplementedError

    def body_rate(self, t) -> np.ndarray:
        """
        Return the absolute angular rate ω.

        Parameters
        ----------
        t : float or ndarray
            Times, s from the profile origin.

        Returns
        -------
        (..., 3) ndarray
            Rate, rad/s, body axes.

        """
        raise NotImplementedError

    def delta_theta(self, t0, t1) -> np.ndarray:
        """
        Return the exact integrating-gyro output ∫ω dt over [t0, t1].

        Parameters
        ----------
        t0, t1 : float or ndarray
            Interval starts and ends, s (broadcast).

        Returns
        -------
        (..., 3) ndarray
            Increments, rad, body axes.

        """
        raise NotImplementedError

    def specific_force(self, t) -> np.ndarray:
        """
        Return the specific force f = C_body_ref · f_ref (a body without linear acceleration).

        Parameters
        ----------
        t : float or ndarray
            Times, s from the profile origin.

        Returns
        -------
        (..., 3) ndarray
            Specific force, m/s², body axes.

        """
        q = self.attitude(t)
        return quat_rotate(quat_conjugate(q), self.reference_specific_force)

    def delta_v(self, t0, t1, max_step: float | None = None) -> np.ndarray:
        """
        Return ∫f dt over [t0, t1] by composite Gauss–Legendre quadrature (vectorised).

        Parameters
        ----------
        t0, t1 : float or ndarray
            Interval starts and ends, s (broadcast).
        max_step : float or None
            Longest sub-interval, s (None: the profile's own).

        Returns
        -------
        (..., 3) ndarray
            Velocity increments, m/s, body axes.

        """
        shape = np.broadcast(np.asarray(t0), np.asarray(t1)).shape + (3,)
        t0, t1 = (np.atleast_1d(np.asarray(x, dtype=float)).ravel()
                  for x in np.broadcast_arrays(t0, t1))
        total = np.zeros(t0.shape + (3,))
        if not np.any(self.reference_specific_force) or t0.size == 0:
            return total.reshape(shape)
        step = max_step if max_step is not None else self._quadrature_step()
        longest = float(np.max(t1 - t0))
        n_sub = max(1, int(np.ceil(longest / step)))
        phase = 2.0 * self._frequency() * longest / n_sub
        nodes_x, weights = _GAUSS_LEGENDRE[_gauss_points(phase)]
        edges = np.linspace(0.0, 1.0, n_sub + 1)
        for a, b in zip(edges[:-1], edges[1:]):
            ta = t0 + a * (t1 - t0)
            tb = t0 + b * (t1 - t0)
            half = 0.5 * (tb - ta)
            mid = 0.5 * (tb + ta)
            nodes = mid[..., None] + half[..., None] * nodes_x             # (..., n)
            f = self.specific_force(nodes)                                 # (..., n, 3)
            total += half[..., None] * np.einsum('...k,...kj->...j', weights, f)
        return total.reshape(shape)

    def _frequency(self) -> float:
        """Highest angular frequency (rad/s) in the specific force, for the quadrature rule."""
        return 20.0

    def _quadrature_step(self) -> float:
        return 0.05
