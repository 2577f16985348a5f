"""
Star-camera-aided attitude filter: the multiplicative error-state Kalman filter (MEKF).

Lefferts, Markley & Shuster (1982), "Kalman filtering for spacecraft attitude estimation",
J. Guidance 5(5); Markley & Crassidis (2014), *Fundamentals of Spacecraft Attitude
Determination and Control*, ch. 6.  The nominal attitude ``q_ref_body`` comes from the
package's own integrator (:class:`strapdown_ros.attitude.integrator.AttitudeIntegrator`) on
increments compensated with the estimated gyro effects; the error state is the attitude error
ε, the gyro bias and, by name, further states of the effect registry (:mod:`.filter_support`
lays them out), the camera time offset and the boresight.  Propagation by
:func:`strapdown_ros.estimation.error_model.block_transition`; a fix is gated on its NIS and
applied in Joseph form on a square-root factor; a late fix rolls back to a checkpoint
(:mod:`.fix_history`).  Model, equations and sources: doc/attitude_filter.md.  The node
(``attitude_filter_node``) and the ``filter_bag`` tool reach it through
:mod:`.filter_system`.  No ROS imports.
"""
from __future__ import annotations

from collections import deque

import numpy as np

from strapdown_ros.attitude.integrator import AttitudeIntegrator
from strapdown_ros.estimation.chi_square import chi2_3_quantile
from strapdown_ros.estimation.error_model import block_transition
from strapdown_ros.estimation.filter_support import (checked_fix, FilterCounters, FixResult,
                                                     psd_factor, StateLayout, triangular_factor)
from strapdown_ros.estimation.fix_history import CameraFix, Checkpoint, IncrementLog
from strapdown_ros.rotation import (quat_conjugate, quat_multiply, quat_normalize, quat_to_dcm,
                                    quat_to_rotvec, rotvec_to_quat)
from strapdown_ros.sensors.effects import EFFECTS, GyroEffects

__all__ = ['AttitudeFilter']


class AttitudeFilter:
    """
    Multiplicative error-state Kalman filter of the SINS attitude with star-camera fixes.

    Parameters
    ----------
    initial_attitude : array_like (4,)
        ``q_ref_body`` at ``initial_time``, scalar-first.
    initial_time : float
        Stamp of the initial attitude (the start of the first increment), s.
    algorithm : str
        Coning algorithm (:data:`strapdown_ros.attitude.coning.ALGORITHMS`) of the integrator.
    gyro_random_walk : float
        Angle random walk σ_v, rad/√s.
    gyro_bias_random_walk : float
        Bias random walk σ_u, rad/s/√s (0: the bias is a random constant).
    gyro_bias_correlation_time : float
        τ > 0 makes the bias first-order Gauss–Markov (bias instability) driven by the same
        density: steady σ_b = σ_u √(τ/2), s (0: a random walk).
    initial_sigma : float
        Prior 1σ of the attitude error per axis, rad.
    bias_sigma : float
        Prior 1σ of the bias error per axis, rad/s.
    augment : sequence of str
        Further states: names of systematic gyro effects of the registry, ``time_offset``,
        ``boresight``.
    augment_sigma : dict
        Prior 1σ per augmented name (scalar: every component), in the effect's units.
    initial_values : dict
        Initial estimates per name: the effect's filter states (``gyro_bias`` rad/s;
        ``time_offset`` s); ``boresight`` is given by ``boresight`` below.
    boresight : array_like (4,)
        Initial estimate of ``q_MF_VF`` (maps VF coordinates to MF), scalar-first.
    process_noise : dict
        Further filter noise densities by the effects' ``filter_noise_parameter`` names.
    gate_probability : float
        A fix whose NIS exceeds the χ²(3) quantile of this probability is gated (not applied)
        and counted.
    history : int
        Increments kept for late fixes (pieces as processed).
    max_pending : int
        Fixes waiting for increments to reach their epoch; more are dropped and counted.
    checkpoint_interval : float
        Minimum time between the checkpoints taken at the end of :meth:`propagate`, s.
    epoch : float, optional
        The effect epoch of the time-dependent effects (``gyro_bias_drift``, ...): where their
        time is 0, s (default: ``initial_time``).
    time_offset : float
        The known camera time offset when it is not a filter state, s: a fix stamped t is
        applied at t − time_offset.
    model : SensorModel, optional
        The model the augmented effects are set up from (their other parameters, e.g. the
        period of ``gyro_bias_periodic``); None: the registry's defaults.
    max_queued : int
        Increments :meth:`propagate` may hold before processing them as one block (0: every call
        processed at once).  They are processed when a waiting fix is due, a checkpoint is due,
        the queue is full, or any estimate, the covariance or :meth:`update` is asked for: a
        caller sees the state of immediate processing; one increment per call then costs a
        fraction of the work (``filter_bench``).

    """

    def __init__(self, initial_attitude, initial_time: float, *, algorithm: str = '2',
                 gyro_random_walk: float = 0.0, gyro_bias_random_walk: float = 0.0,
                 gyro_bias_correlation_time: float = 0.0,
                 initial_sigma: float = 1e-3, bias_sigma: float = 1e-5, augment=(),
                 augment_sigma: dict | None = None, initial_values: dict | None = None,
                 boresight=(1.0, 0.0, 0.0, 0.0), process_noise: dict | None = None,
                 gate_probability: float = 0.9999, history: int = 20_000, max_pending: int = 256,
                 checkpoint_interval: float = 1.0, max_queued: int = 1024,
                 epoch: float | None = None, time_offset: float = 0.0, model=None):
        for name, v in (('gyro_random_walk', gyro_random_walk), ('initial_sigma', initial_sigma),
                        ('bias_sigma', bias_sigma),
                        ('gyro_bias_random_walk', gyro_bias_random_walk)):
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f'{name} must be finite and >= 0, got {v}')
        if not np.isfinite(initial_time):
            raise ValueError('initial_time must be finite')
        if int(history) < 16 or int(max_pending) < 1 or int(max_queued) < 0:
            raise ValueError('history must be >= 16, max_pending >= 1 and max_queued >= 0')
        self.max_queued = int(max_queued)
        self.integrator = AttitudeIntegrator(algorithm, initial_attitude,
                                             initial_time=initial_time,
                                             propagate_covariance=False)
        self.sigma_v = float(gyro_random_walk)
        self.noise = dict(process_noise or {})
        self.noise['gyro_bias_random_walk'] = float(gyro_bias_random_walk)
        self.noise['gyro_bias_correlation_time'] = float(gyro_bias_correlation_time)
        # effect epoch of the time-dependent effects (default: the start)
        self.epoch = float(initial_time if epoch is None else epoch)
        if not np.isfinite(time_offset):
            raise ValueError('time_offset must be finite')
        self._fixed_offset = float(time_offset)        # the known offset when it is no state
        self.gate = chi2_3_quantile(gate_probability)
        self.gate_probability = float(gate_probability)
        self.layout = StateLayout.build(tuple(augment), model)
        self._x = np.zeros(self.layout.size)            # the estimates (filter states), not errors
        q_bv = np.asarray(boresight, dtype=float)
        if q_bv.shape != (4,) or not np.all(np.isfinite(q_bv)) or np.linalg.norm(q_bv) < 0.5:
            raise ValueError('boresight must be a finite quaternion [w, x, y, z]')
        self.boresight = quat_normalize(q_bv)
        p0 = np.zeros(self.layout.size)
        p0[:3], p0[3:6] = initial_sigma ** 2, bias_sigma ** 2
        sig = dict(augment_sigma or {})
        for name, sl in self.layout.named_slices():
            if name in ('gyro_bias',):
                continue
            if name not in sig:
                raise ValueError(f'augment_sigma needs the prior 1σ of {name!r}')
            width = (sl.stop - sl.start,)
            p0[sl] = np.broadcast_to(np.asarray(sig[name], dtype=float), width) ** 2
        for name, v in (initial_values or {}).items():
            sl = dict(self.layout.named_slices()).get(name)
            if sl is None:
                raise ValueError(f'initial_values: {name!r} is not a state of this filter')
            self._x[sl] = np.asarray(v, dtype=float).reshape(sl.stop - sl.start)
        if not np.all(np.isfinite(p0)) or np.any(p0 < 0):
            raise ValueError('prior sigmas must be finite and >= 0')
        self._sqrt_p = np.diag(np.sqrt(p0))          # P = S Sᵀ (square-root form)
        self._g_noise = np.concatenate([e.filter_process_noise(self.noise)
                                        for e, _ in self.layout.gyro])
        self._g_tau = np.concatenate([e.filter_correlation_time(self.noise)
                                      for e, _ in self.layout.gyro])
        self.counters = FilterCounters()
        self.results: deque = deque(maxlen=1000)       # the last fix results (bounded)
        self.history = int(history)
        self.max_pending = int(max_pending)
        self.checkpoint_interval = float(checkpoint_interval)
        self._log = IncrementLog(self.history)
        self._open_rho = np.zeros((0, 3))      # compensated pieces not yet in a completed update
        self._open_dt = np.zeros(0)
        self._last_rate = np.zeros(3)
        self._last_stamp = float(initial_time)  # newest piece stamp
        self._queue_d: list = []                # increments received, not processed yet
        self._queue_t: list = []
        self._queued = 0
        self._queued_stamp = float(initial_time)
        self._pending: list[CameraFix] = []
        self._applied: deque = deque()         # fixes applied (or gated), for re-processing
        self._seq = 0
        self._order = 0
        self._checkpoints: deque = deque(maxlen=512)
        self._checkpoint()

    # ------------------------------------------------------------------ layout and estimates
    @property
    def x(self) -> np.ndarray:
        """Return the estimates of the filter states (not errors), in the layout's order."""
        self._drain()
        return self._x

    @property
    def attitude(self) -> np.ndarray:
        """Return the current estimate of ``q_ref_body`` (at :attr:`time`)."""
        self._drain()
        return self.integrator.q

    @property
    def time(self) -> float:
        """Time of the attitude and covariance: the end of the last completed update, s."""
        self._drain()
        return float(self.integrator.time)

    @property
    def newest_stamp(self) -> float:
        """Stamp of the newest increment received, s."""
        return self._queued_stamp

    @property
    def time_offset(self) -> float:
        """Estimated camera time offset τ̂ (camera clock minus IMU clock), s."""
        self._drain()
        sl = self.layout.time_offset
        return self._fixed_offset if sl is None else float(self._x[sl][0])

    def estimate(self, name: str) -> np.ndarray:
        """
        Return the estimate of one group of states.

        Parameters
        ----------
        name : str
            A state group of this filter (``gyro_bias``, an augmented name; ``boresight``:
            the quaternion ``q_MF_VF``).

        Returns
        -------
        ndarray
            A copy of the estimate, in the effect's filter units.

        Raises
        ------
        ValueError
            ``name`` is not a state of this filter.

        """
        self._drain()
        if name == 'boresight':
            return self.boresight.copy()
        return self._x[self.layout.slice_of(name)].copy()

    def sigma(self, name: str) -> np.ndarray:
        """
        Return the 1σ of the error of one group of states, from the covariance.

        Parameters
        ----------
        name : str
            A state group of this filter, or ``attitude`` (rad, body axes).

        Returns
        -------
        ndarray
            1σ per component.

        Raises
        ------
        ValueError
            ``name`` is not a state of this filter.

        """
        self._drain()
        sl = slice(0, 3) if name == 'attitude' else self.layout.slice_of(name)
        return np.sqrt(np.diag(self.P)[sl])

    @property
    def P(self) -> np.ndarray:
        """
        Error-state covariance (n, n).

        ``S Sᵀ`` of the square-root factor the filter keeps, symmetric and positive
        semi-definite by construction.
        """
        self._drain()
        P = self._sqrt_p @ self._sqrt_p.T
        return 0.5 * (P + P.T)

    def implausible(self) -> list[str]:
        """
        Return the names of the estimates outside the valid range of their registry parameter.

        A diverging filter; reported, not clamped.

        Returns
        -------
        list of str
            Effect names.

        """
        self._drain()
        return self.layout.implausible(self._x)

    def _gyro_effects(self, decay_time: float = 0.0) -> GyroEffects:
        """Return the estimated gyro effects, Gauss–Markov states decayed over ``decay_time`` s."""
        x = self._x.copy()
        x[3:3 + len(self._g_tau)] *= np.exp(-decay_time / self._g_tau)
        values = {e.name: e.filter_values(x[sl]) for e, sl in self.layout.gyro}
        return GyroEffects(values=values, epoch=self.epoch)

    # ------------------------------------------------------------------ public stream interface
    def propagate(self, delta_theta, stamps) -> list[FixResult]:
        """
        Consume gyro increments and apply the waiting fixes whose epochs they reach.

        Parameters
        ----------
        delta_theta : array_like (n, 3)
            Measured increments, rad, body axes.
        stamps : array_like (n,)
            End stamps, s, strictly increasing and after :attr:`newest_stamp`.

        Returns
        -------
        list of FixResult
            The fixes applied (or gated) during this call.

        """
        d = np.asarray(delta_theta, dtype=float).reshape(-1, 3)
        t = np.asarray(stamps, dtype=float).reshape(-1)
        if len(d) != len(t):
            raise ValueError('delta_theta and stamps must have the same length')
        if len(t) == 0:
            return []
        if not (np.isfinite(d).all() and np.isfinite(t).all()):
            raise ValueError('increments and stamps must be finite')
        if t[0] <= self._queued_stamp or (len(t) > 1 and (np.diff(t) <= 0).any()):
            raise ValueError('stamps must increase strictly and follow the newest stamp')
        self._queued_stamp = float(t[-1])
        due = bool(self._pending) and self._pending[0].epoch <= t[-1]
        if (not due and self._checkpoints and self._queued + len(t) <= self.max_queued
                and t[-1] - self._checkpoints[-1].epoch < self.checkpoint_interval):
            self._queue_d.append(d)              # processed as one block later
            self._queue_t.append(t)
            self._queued += len(t)
            return []
        if self._queued:
            d, t = np.concatenate(self._queue_d + [d]), np.concatenate(self._queue_t + [t])
            self._queue_d, self._queue_t, self._queued = [], [], 0
        out = self._advance(d, t)
        if (not self._checkpoints
                or self._last_stamp - self._checkpoints[-1].epoch >= self.checkpoint_interval):
            self._checkpoint()
        return out

    def update(self, stamp: float, attitude, covariance, boresight=None) -> FixResult:
        """
        Take a star-camera fix.

        Applied at the epoch ``stamp − τ̂``: now when the increments end exactly there, later
        (status 'pending', the result comes from :meth:`propagate`) when they have not reached
        it, and by re-processing the history when they have passed it (counted as late).

        Parameters
        ----------
        stamp : float
            Header stamp of the fix, camera clock, s.
        attitude : array_like (4,)
            Measured ``q_GCRS_VF``, scalar-first, unit.
        covariance : array_like (3, 3)
            Its covariance in VF axes, rad², positive definite.
        boresight : array_like (4,), optional
            A new known ``q_MF_VF`` (e.g. from the calibrator) for this and later fixes; only
            when the boresight is not a filter state.

        Returns
        -------
        FixResult
            Status ``applied``, ``gated``, ``pending``, ``too_old`` or ``overflow``, with the
            residual and its NIS when it was applied or gated.

        Raises
        ------
        ValueError
            The fix or the boresight is not finite, not a unit quaternion, or the covariance is
            not positive definite.

        """
        self._drain()
        q, R = checked_fix(stamp, attitude, covariance)
        if boresight is not None:
            if self.layout.boresight is not None:
                raise ValueError('the boresight is a filter state here: estimated, not given')
            q_bv = np.asarray(boresight, dtype=float)
            if (q_bv.shape != (4,) or not np.all(np.isfinite(q_bv))
                    or abs(np.linalg.norm(q_bv) - 1) > 1e-3):
                raise ValueError('boresight must be a finite unit quaternion [w, x, y, z]')
            self.boresight = quat_normalize(q_bv)
        fix = CameraFix(self._seq, float(stamp), float(stamp) - self.time_offset,
                        quat_normalize(q), R)
        self._seq += 1
        if fix.epoch > self._last_stamp:
            if len(self._pending) >= self.max_pending:
                self.counters.pending_overflow += 1
                return self._record(fix, 'overflow')
            self._pending.append(fix)
            self._pending.sort(key=lambda f: (f.epoch, f.seq))
            return FixResult(fix.stamp, fix.epoch, 'pending')
        if fix.epoch == self._last_stamp:
            return self._apply(fix)
        return self._late(fix)

    # ------------------------------------------------------------------ processing
    def _drain(self) -> None:
        """
        Process the queued increments.

        None of them reaches a waiting fix: :meth:`propagate` processes at once when one does,
        and :meth:`update` drains first.
        """
        if self._queued:
            d, t = np.concatenate(self._queue_d), np.concatenate(self._queue_t)
            self._queue_d, self._queue_t, self._queued = [], [], 0
            self._advance(d, t)

    def _advance(self, d: np.ndarray, t: np.ndarray) -> list[FixResult]:
        out = []
        start = self._last_stamp
        while True:
            while self._pending and self._pending[0].epoch <= start:   # due at the newest stamp
                out.append(self._apply(self._pending.pop(0)))
            if len(t) == 0:
                break
            if not self._pending or self._pending[0].epoch > t[-1]:
                self._push(d, t)
                break
            fix = self._pending.pop(0)
            i = int(np.searchsorted(t, fix.epoch, side='left'))      # t[i] >= epoch
            t_prev = t[i - 1] if i > 0 else start
            if t[i] == fix.epoch:
                self._push(d[:i + 1], t[:i + 1])
                d, t = d[i + 1:], t[i + 1:]
            else:                    # split the increment at the epoch (constant rate inside it)
                frac = (fix.epoch - t_prev) / (t[i] - t_prev)
                head_d = np.vstack([d[:i], frac * d[i:i + 1]])
                self._push(head_d, np.append(t[:i], fix.epoch))
                d = np.vstack([(1.0 - frac) * d[i:i + 1], d[i + 1:]])
                t = t[i:]
            start = fix.epoch
            out.append(self._apply(fix))
        return out

    def _push(self, d: np.ndarray, t: np.ndarray) -> None:
        """
        Compensate, integrate and propagate the covariance over increments (pieces).

        With Gauss–Markov states, in blocks of at most 5 % of the shortest correlation time
        (the compensation uses the estimate decayed to the middle of a block).
        """
        if len(t) == 0:
            return
        step = 0.05 * float(np.min(self._g_tau))
        if np.isfinite(step) and t[-1] - self._last_stamp > step:
            k = np.floor((t - self._last_stamp) / step)
            cuts = np.flatnonzero(np.diff(k)) + 1
            for dd, tt in zip(np.split(d, cuts), np.split(t, cuts)):
                self._push_block(dd, tt)
            return
        self._push_block(d, t)

    def _push_block(self, d: np.ndarray, t: np.ndarray) -> None:
        self._log.append(d, t)
        dt = np.diff(np.concatenate([[self._last_stamp], t]))
        rho = self._gyro_effects(0.5 * (t[-1] - self._last_stamp)).compensate(d, t, dt)
        self._last_rate = rho[-1] / dt[-1]
        self._last_stamp = float(t[-1])
        q_before = self.integrator.q
        batch = self.integrator.push(rho, t)
        n_new = self.integrator.algorithm.samples
        open_rho = np.concatenate([self._open_rho, rho])
        open_dt = np.concatenate([self._open_dt, dt])
        m = len(batch)
        used = m * n_new
        self._open_rho, self._open_dt = open_rho[used:], open_dt[used:]
        if m:
            c = quat_to_dcm(batch.attitude)
            rho_sum = batch.mean_rate * batch.interval[:, None]
            self._propagate_covariance(quat_to_dcm(q_before), c, rho_sum, batch.interval,
                                       batch.stamps - 0.5 * batch.interval - self.epoch)

    def _flush(self) -> None:
        """
        Complete the unfinished update: attitude and covariance are then at the newest stamp.

        Its increments are applied one by one, the integrator's rule when the algorithm changes.
        """
        if len(self._open_rho) == 0:
            return
        q_before = self.integrator.q
        self.integrator.set_algorithm(self.integrator.algorithm_name)
        h = np.array([self._open_dt.sum()])
        self._propagate_covariance(quat_to_dcm(q_before), quat_to_dcm(self.integrator.q)[None],
                                   self._open_rho.sum(0)[None], h,
                                   np.array([self._last_stamp - 0.5 * h[0] - self.epoch]))
        self.integrator.time = self._last_stamp
        self._open_rho, self._open_dt = np.zeros((0, 3)), np.zeros(0)

    def _propagate_covariance(self, c0, c, rho, h, t_mid) -> None:
        """
        Propagate P over m updates.

        Attitudes C_j (m,3,3), lumped increments ρ_j, lengths h_j, times since the effect epoch
        (:func:`strapdown_ros.estimation.error_model.block_transition`).
        """
        lay = self.layout
        A = np.concatenate([c @ e.filter_partials(rho, h, t_mid) for e, _ in lay.gyro], axis=2)
        k = 3 + A.shape[2]                        # ε and the gyro states, contiguous
        phi_k, q_k, decay = block_transition(c0, c, A, h, self.sigma_v, self._g_noise,
                                             self._g_tau)
        phi = np.eye(lay.size)
        phi[:k, :k] = phi_k
        Q = np.zeros((lay.size, lay.size))
        Q[:k, :k] = q_k
        self._x[3:k] = self._x[3:k] * decay         # a Gauss–Markov estimate decays as the state
        self._sqrt_p = triangular_factor(phi @ self._sqrt_p, psd_factor(Q))     # P ← ΦPΦᵀ + Q

    def _apply(self, fix: CameraFix) -> FixResult:
        """Measurement update at the newest stamp (= the fix epoch)."""
        self._flush()
        lay = self.layout
        c_bv = quat_to_dcm(self.boresight)                 # C_MF^VF
        q_pred = quat_multiply(self.integrator.q, self.boresight)
        z = quat_to_rotvec(quat_multiply(quat_conjugate(fix.attitude), q_pred))
        H = np.zeros((3, lay.size))
        H[:, :3] = c_bv.T
        if lay.boresight is not None:
            H[:, lay.boresight] = np.eye(3)
        if lay.time_offset is not None:
            H[:, lay.time_offset] = EFFECTS['time_offset'].fix_jacobian(self._last_rate, c_bv.T)
        P = self.P
        S = H @ P @ H.T + fix.covariance
        S = 0.5 * (S + S.T)
        nis = float(z @ np.linalg.solve(S, z))
        self._applied.append(fix)
        fix.order = self._order
        self._order += 1
        self._trim_applied()
        if not nis <= self.gate:
            res = self._record(fix, 'gated', z, nis, S)
            res.jacobian = H
            if not fix.counted:
                self.counters.gated += 1
            fix.counted = True
            self._checkpoint()
            return res
        K = np.linalg.solve(S, H @ P).T
        dx = K @ z
        if not (np.all(np.isfinite(K)) and np.all(np.isfinite(dx))):
            raise FloatingPointError('attitude filter: non-finite gain in the update (numerical '
                                     'failure, not bad input); the state is not corrected')
        IKH = np.eye(lay.size) - K @ H
        # Joseph form P ← (I − KH)P(I − KH)ᵀ + KRKᵀ, as the factor of [(I − KH)S, K R^½]
        self._sqrt_p = triangular_factor(IKH @ self._sqrt_p,
                                         K @ np.linalg.cholesky(fix.covariance))
        self.integrator.q = quat_normalize(quat_multiply(self.integrator.q,
                                                         rotvec_to_quat(-dx[:3])))
        self._x[3:] -= dx[3:]
        if lay.boresight is not None:
            self.boresight = quat_normalize(quat_multiply(self.boresight,
                                                          rotvec_to_quat(-dx[lay.boresight])))
            self._x[lay.boresight] = 0.0          # the boresight estimate lives in the quaternion
        if not fix.counted:
            self.counters.applied += 1
            if self.implausible():
                self.counters.implausible += 1
        fix.counted = True
        res = self._record(fix, 'applied', z, nis, S)
        res.jacobian, res.gain = H, K
        self._checkpoint()
        return res

    def _record(self, fix: CameraFix, status: str, z=None, nis=None, S=None) -> FixResult:
        res = FixResult(fix.stamp, fix.epoch, status, fix.lateness, z, nis, S)
        self.results.append(res)
        return res

    # ------------------------------------------------------------------ history
    def _checkpoint(self) -> None:
        self._checkpoints.append(Checkpoint(
            self._last_stamp, self._log.next, self._order,
            self.integrator.checkpoint(), self._x.copy(), self.boresight.copy(), self._sqrt_p,
            self._open_rho, self._open_dt, self._last_rate, self._last_stamp))

    def _late(self, fix: CameraFix) -> FixResult:
        fix.lateness = self._last_stamp - fix.epoch
        cp = None
        for c in reversed(self._checkpoints):
            if c.pieces >= self._log.base and c.epoch <= fix.epoch:
                cp = c
                break
        if cp is None:
            self.counters.too_old += 1
            return self._record(fix, 'too_old')
        self.counters.late += 1
        self.counters.last_lateness = fix.lateness
        self.counters.max_lateness = max(self.counters.max_lateness, fix.lateness)
        d, t = self._log.since(cp.pieces)
        self.counters.reprocessed_increments += len(t)
        # back to the checkpoint
        self.integrator.rollback(cp.integrator)
        self._x, self.boresight = cp.states.copy(), cp.boresight.copy()
        self._sqrt_p = cp.covariance
        self._open_rho, self._open_dt, self._last_rate = cp.open_rho, cp.open_dt, cp.last_rate
        self._last_stamp = cp.last_stamp
        self._log.rewind(cp.pieces)
        while self._checkpoints and self._checkpoints[-1] is not cp:
            self._checkpoints.pop()
        redo = [f for f in self._applied if f.order >= cp.order]
        self._applied = deque(f for f in self._applied if f not in redo)
        self._pending = sorted(self._pending + redo + [fix], key=lambda f: (f.epoch, f.seq))
        self._trim_applied()
        out = self._advance(d, t)
        mine = [r for r in out if r.stamp == fix.stamp and r.epoch == fix.epoch]
        return mine[-1] if mine else FixResult(fix.stamp, fix.epoch, 'pending', fix.lateness)

    def _trim_applied(self) -> None:
        """Forget applied fixes older than every usable checkpoint (no longer re-processable)."""
        oldest = next((c.epoch for c in self._checkpoints if c.pieces >= self._log.base),
                      np.inf)
        while self._applied and self._applied[0].epoch < oldest:
            self._applied.popleft()
        while len(self._applied) > 4 * self.max_pending + 1024:
            self._applied.popleft()
