"""
Streaming navigation: attitude updates and sensor increments → ECEF position and velocity.

With their covariance.  Used by ``sins_node`` and by ``sins_bag`` through :mod:`.channel`.

Frames and time (written once, here):

* E: Earth-fixed, Greenwich rectangular frame PZ-90 (REP-105 ``earth``), rotating at Ω about +Z.
* I: the inertial frame that coincides with E at the navigator's start time ``t0``; the attitude
  integrator's reference frame.  ``C_E_I(t) = R_z(−Ω(t − t0))``.
* B: body (IMU) frame.  The attitude integrator gives ``U = C_I_B``; the navigation attitude is
  ``V = C_E_B = C_E_I(t) U`` (003 (1.89), V = D·U).
* Stamps are seconds relative to the node's stamp origin; each increment is stamped at the end of
  its interval.  A navigation step is one attitude update ``[t_{k−1}, t_k]``: its gyro increments
  and the accelerometer increments in it (any rates; the sub-interval integrals are read from the
  cumulative increments, exact when the accelerometer stamps divide the step, 003's 3:1
  layout).

No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.earth import DEFAULT_GRAVITY_MODEL
from strapdown_ros.navigation import recursion
from strapdown_ros.navigation.covariance import NavigationCovariance
from strapdown_ros.navigation.update import specific_force_integrals, step_layout
from strapdown_ros.rotation import quat_multiply, quat_to_dcm

__all__ = ['CumulativeIncrements', 'Navigator', 'NavigationBatch', 'earth_from_inertial',
           'earth_from_inertial_quat']


def earth_from_inertial_quat(dt: np.ndarray) -> np.ndarray:
    """
    Return ``q_E_I`` after a time: the rotation by −Ω dt about Z.

    Parameters
    ----------
    dt : float or ndarray
        Time since the navigator's start t0, s.

    Returns
    -------
    (..., 4) ndarray
        ``q_E_I``, scalar first.

    """
    a = -0.5 * recursion.OMEGA * np.asarray(dt, dtype=float)
    z = np.zeros_like(a)
    return np.stack([np.cos(a), z, z, np.sin(a)], -1)


def earth_from_inertial(dt: np.ndarray) -> np.ndarray:
    """
    Return ``C_E_I`` after a time: a vector fixed in I turns by −Ω dt about Z in E.

    Parameters
    ----------
    dt : float or ndarray
        Time since the navigator's start t0, s.

    Returns
    -------
    (..., 3, 3) ndarray
        ``C_E_I``.

    """
    a = -recursion.OMEGA * np.asarray(dt, dtype=float)
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    rows = [np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)]
    return np.stack(rows, -2)


class CumulativeIncrements:
    """
    Running integral of a stamped increment stream, read at any time by interpolation.

    :meth:`increments` gives the integrals over consecutive intervals: exact when the edges
    are stamps; linear within one sample interval (constant rate) otherwise; beyond the newest
    stamp it extrapolates with the newest sample's rate, and before the oldest kept stamp with
    the oldest sample's rate (the fits of the first steps reach before the start: a one-sample
    algorithm's gyro fit takes the previous increment too, and reading it as zero would fake a
    rate jump).

    The running sum is kept as ``S_j = D_j + j·x̄``: cumulative *deviations* from a reference
    increment x̄ plus a sample count.  A plain cumulative sum of 300 Hz accelerometer increments
    reaches 10⁴ m/s within an hour and its round-off is biased (adding nearly the same number
    over and over rounds the same way), ~1e-11 relative — which the vertical channel turns into
    a millimetre in an hour.  The deviations stay small, and ``(j_b − j_a)·x̄`` is one exact
    product.  Bounded: :meth:`trim` forgets what lies before a time and rebases the sums.

    Parameters
    ----------
    max_len : int
        At most this many stamps are kept; the oldest are dropped and counted in
        ``overflowed``.

    """

    def __init__(self, max_len: int = 200_000):
        self.t = np.zeros(0)
        self.d = np.zeros((0, 3))
        self.j = np.zeros(0)
        self.xbar = None
        self.max_len = int(max_len)
        self.overflowed = 0

    def __len__(self) -> int:
        return len(self.t)

    @property
    def newest(self) -> float:
        """
        Return the newest stamp.

        Returns
        -------
        float
            Stamp, s; −inf when empty.

        """
        return float(self.t[-1]) if len(self.t) else -np.inf

    def add(self, increments: np.ndarray, stamps: np.ndarray, period: float) -> None:
        """
        Append increments; stamps not after the newest one are ignored.

        Parameters
        ----------
        increments : (n, 3) array_like
            Increments (rad or m/s).
        stamps : (n,) array_like
            End of each increment's interval, s.
        period : float
            Sample interval, s: the very first increment starts one period before its stamp.

        """
        inc = np.asarray(increments, dtype=float).reshape(-1, 3)
        st = np.asarray(stamps, dtype=float).reshape(-1)
        if not len(st):
            return
        if not len(self.t):                         # the first sample starts one period earlier
            self.t, self.d, self.j = np.array([st[0] - period]), np.zeros((1, 3)), np.zeros(1)
            self.xbar = inc[0].copy()
        keep = st > self.t[-1]
        inc, st = inc[keep], st[keep]
        self.t = np.concatenate([self.t, st])
        self.d = np.concatenate([self.d, self.d[-1] + np.cumsum(inc - self.xbar, axis=0)])
        self.j = np.concatenate([self.j, self.j[-1] + np.arange(1, len(st) + 1)])
        if len(self.t) > self.max_len:
            drop = len(self.t) - self.max_len
            self.overflowed += drop
            self._rebase(drop)

    def _rebase(self, i: int) -> None:
        self.t, self.d, self.j = self.t[i:], self.d[i:] - self.d[i], self.j[i:] - self.j[i]

    def _at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """
        Return ``(D, j)`` at times ``t``.

        Linear within a sample interval, and beyond either end the first or last interval
        continued (that sample's constant rate).
        """
        t = np.asarray(t, dtype=float)
        if len(self.t) < 2:
            return np.zeros(t.shape + (3,)), np.zeros(t.shape)
        i = np.clip(np.searchsorted(self.t, t, side='right') - 1, 0, len(self.t) - 2)
        t0, t1 = self.t[i], self.t[i + 1]
        w = (t - t0) / (t1 - t0)
        d0 = self.d[i]
        d = d0 + w[..., None] * (self.d[i + 1] - d0)
        j = self.j[i] + w * (self.j[i + 1] - self.j[i])
        return d, j

    def increments(self, edges: np.ndarray) -> np.ndarray:
        """
        Return the integrals over consecutive intervals ``(edges[..., i], edges[..., i+1])``.

        Parameters
        ----------
        edges : (..., n) ndarray
            Interval edges, s, increasing along the last axis.

        Returns
        -------
        (..., n − 1, 3) ndarray
            The integrals.

        """
        d, j = self._at(edges)
        return np.diff(d, axis=-2) + np.diff(j, axis=-1)[..., None] * self.xbar

    def trim(self, before: float) -> None:
        """
        Forget the samples before a time (the last one at or before it is kept).

        Parameters
        ----------
        before : float
            Time, s.

        """
        i = int(np.searchsorted(self.t, before, side='right')) - 1
        if i > 0:
            self._rebase(i)


@dataclass
class NavigationBatch:
    """
    Outputs of one :meth:`Navigator.process`: K navigation steps.

    Parameters
    ----------
    stamps : (K,) ndarray
        End of each step, s.
    position : (K, 3) ndarray
        ECEF position, m.
    velocity : (K, 3) ndarray
        ECEF velocity, m/s.
    attitude : (K, 4) ndarray
        q_E_B, scalar first.
    covariance : (K, 9, 9) ndarray
        Covariance of [δR, δW, ψ] (ψ in E axes), the latest propagated; NaN without one.
    extrapolated : (K,) ndarray of bool
        Accelerometer data were extrapolated for the step.

    """

    stamps: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    attitude: np.ndarray
    covariance: np.ndarray
    extrapolated: np.ndarray

    def __len__(self):
        return len(self.stamps)


class Navigator:
    """
    Position and velocity in E from the attitude integrator's updates.

    Parameters
    ----------
    position, velocity : (3,) array_like
        ECEF position (m) and velocity (m/s) at ``t0``.
    t0 : float
        Start of the attitude integrator, s.
    gyro_per_step : int
        Gyro increments per step (the coning algorithm's samples per update).
    accel_per_step : int
        Accelerometer increments per step (from the rates).
    gyro_period, accel_period : float
        Sample intervals, s.
    form : str
        Form of the specific-force integral (:data:`.update.FORMS`).
    scheme : str
        Velocity and position recursion (:data:`.recursion.SCHEMES`).
    gravity_model : str
        Name in the gravity registry of :mod:`strapdown_ros.earth`.
    covariance : NavigationCovariance or None
        Propagated beside the state when given.
    max_pending : int
        At most this many steps are queued; the oldest are dropped and counted in
        ``dropped_steps``.

    Raises
    ------
    ValueError
        For a position not near the Earth's surface, or an unknown form or scheme.

    """

    def __init__(self, position, velocity, t0: float, gyro_per_step: int, accel_per_step: int,
                 gyro_period: float, accel_period: float, form: str = 'exact',
                 scheme: str = 'exact',
                 gravity_model: str = DEFAULT_GRAVITY_MODEL,
                 covariance: NavigationCovariance | None = None,
                 max_pending: int = 100_000):
        self.origin = np.asarray(position, dtype=float).reshape(3).copy()
        radius = np.linalg.norm(self.origin)
        if not (np.all(np.isfinite(self.origin)) and 6.0e6 < radius < 7.0e6 + 1e6):
            raise ValueError("initial position must be ECEF within ±1000 km of the Earth's "
                             f'surface, got {position}')
        self.offset = np.zeros(3)
        self.velocity = np.asarray(velocity, dtype=float).reshape(3).copy()
        self.t0 = float(t0)
        self.layout = step_layout(gyro_per_step, accel_per_step)
        self.form, self.scheme, self.gravity_model = form, scheme, gravity_model
        # validates form against the layout
        specific_force_integrals(np.zeros((1, self.layout.gyro_window, 3)),
                                 np.zeros((1, self.layout.accel_window, 3)),
                                 np.ones(1), self.layout, form)
        if scheme not in recursion.SCHEMES:
            raise ValueError(f'unknown navigation scheme {scheme!r}; '
                             f"valid: {', '.join(recursion.SCHEMES)}")
        self.gyro = CumulativeIncrements()
        self.accel = CumulativeIncrements()
        self.gyro_period, self.accel_period = float(gyro_period), float(accel_period)
        # queued steps as arrays: t_{k-1}, t_k, q_I_B at t_{k-1} and at t_k (bounded: the oldest
        # beyond max_pending are dropped and counted)
        self._pend = (np.zeros(0), np.zeros(0), np.zeros((0, 4)), np.zeros((0, 4)))
        self.max_pending = int(max_pending)
        self.dropped_steps = 0
        self.covariance = covariance
        self.steps = 0
        self.extrapolated_steps = 0
        self.time = self.t0

    @property
    def position(self) -> np.ndarray:
        """
        Return the current position.

        Returns
        -------
        (3,) ndarray
            ECEF, m.

        """
        return self.origin + self.offset

    def add_gyro(self, increments, stamps) -> None:
        """
        Add gyro increments (the fits of the steps read them).

        Parameters
        ----------
        increments : (n, 3) array_like
            Compensated increments, body axes, rad.
        stamps : (n,) array_like
            Their end stamps, s.

        """
        self.gyro.add(increments, stamps, self.gyro_period)

    def add_accel(self, increments, stamps) -> None:
        """
        Add accelerometer increments.

        Parameters
        ----------
        increments : (n, 3) array_like
            Compensated increments, body axes, m/s.
        stamps : (n,) array_like
            Their end stamps, s.

        """
        self.accel.add(increments, stamps, self.accel_period)

    def add_updates(self, stamps, intervals, attitude_end, attitude_start) -> None:
        """
        Queue attitude updates as navigation steps.

        Parameters
        ----------
        stamps : (M,) array_like
            End stamps of the updates, s.
        intervals : (M,) array_like
            Their lengths, s.
        attitude_end, attitude_start : (M, 4) array_like
            q_I_B at their ends and at their starts, scalar first.

        """
        t = np.asarray(stamps, dtype=float).reshape(-1)
        h = np.asarray(intervals, dtype=float).reshape(-1)
        new = (t - h, t, np.asarray(attitude_start, dtype=float).reshape(-1, 4),
               np.asarray(attitude_end, dtype=float).reshape(-1, 4))
        self._pend = tuple(np.concatenate([a, b]) for a, b in zip(self._pend, new))
        over = len(self._pend[0]) - self.max_pending
        if over > 0:
            self.dropped_steps += over
            self._pend = tuple(a[over:] for a in self._pend)

    @property
    def pending(self) -> int:
        """
        Return the number of queued steps.

        Returns
        -------
        int
            Steps waiting for :meth:`process`.

        """
        return len(self._pend[0])

    def ready_count(self, newest: float, wait: float) -> int:
        """
        Return how many queued steps can be navigated now.

        A step is ready when the accelerometer data cover its end, or when it has waited
        ``wait`` for them.

        Parameters
        ----------
        newest : float
            Newest stamp the owner has seen, s.
        wait : float
            How long a step waits for its accelerometer data, s.

        Returns
        -------
        int
            Length of the ready prefix of the queue.

        """
        t_b = self._pend[1]
        ready = (t_b <= self.accel.newest + 1e-9) | (newest - t_b >= wait)
        # the ready ones are a prefix
        return int(np.argmin(ready)) if not ready.all() else len(t_b)

    def process(self, newest: float = np.inf, wait: float = 0.0) -> NavigationBatch:
        """
        Navigate the queued steps whose accelerometer data have arrived (or waited).

        Parameters
        ----------
        newest : float
            Newest stamp the owner has seen, s.
        wait : float
            How long a step waits for its accelerometer data before they are extrapolated, s.

        Returns
        -------
        NavigationBatch
            The steps navigated (possibly none).

        """
        n = self.ready_count(newest, wait)
        if n == 0 or len(self.accel) < 2:
            return _empty()
        t_a, t_b, q_start, q_end = (a[:n] for a in self._pend)
        self._pend = tuple(a[n:] for a in self._pend)
        h = t_b - t_a
        lay = self.layout
        # sub-interval integrals of the windows ending at t_k (oldest first)
        g_back = np.arange(lay.gyro_window, -1, -1)[None, :]
        a_back = np.arange(lay.accel_window, -1, -1)[None, :]
        ge = t_b[:, None] - h[:, None] * g_back / lay.gyro_per_step
        ae = t_b[:, None] - h[:, None] * a_back / lay.accel_per_step
        q_win = self.gyro.increments(ge)
        u_win = self.accel.increments(ae)
        extrap = t_b > self.accel.newest + 1e-9
        self.extrapolated_steps += int(extrap.sum())
        dv_b, dr_b = specific_force_integrals(q_win, u_win, h, lay, self.form)
        # C_E_B at t_{k-1}
        v_start = earth_from_inertial(t_a - self.t0) @ quat_to_dcm(q_start)
        dv_e = (v_start @ dv_b[:, :, None])[:, :, 0]
        dr_e = (v_start @ dr_b[:, :, None])[:, :, 0]
        off, vel = recursion.run(self.origin, self.offset, self.velocity, dv_e, dr_e, h,
                                 self.scheme, self.gravity_model)
        self.offset, self.velocity = off[-1].copy(), vel[-1].copy()
        q_e_b = quat_multiply(earth_from_inertial_quat(t_b - self.t0), q_end)
        if self.covariance is not None:
            theta = q_win[:, -lay.gyro_per_step:].sum(1)
            cov = self.covariance.propagate(self.origin + off, v_start, dv_b, theta, h)
        else:
            cov = np.full((n, 9, 9), np.nan)
        self.steps += n
        self.time = float(t_b[-1])
        keep_from = float(self._pend[0][0]) if self.pending else float(t_b[-1])
        self.gyro.trim(keep_from - 4 * lay.gyro_window * self.gyro_period)
        self.accel.trim(keep_from - 4 * lay.accel_window * self.accel_period)
        return NavigationBatch(t_b, self.origin + off, vel, q_e_b, cov, extrap)


def _empty() -> NavigationBatch:
    z = np.zeros((0, 3))
    return NavigationBatch(np.zeros(0), z, z, np.zeros((0, 4)), np.zeros((0, 9, 9)),
                           np.zeros(0, bool))
