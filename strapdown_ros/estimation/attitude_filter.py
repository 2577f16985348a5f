"""
Star-camera-aided attitude filter: the multiplicative error-state Kalman filter (MEKF).

Lefferts, Markley & Shuster (1982), "Kalman filtering for spacecraft attitude estimation",
J. Guidance 5(5); Markley & Crassidis (2014), *Fundamentals of Spacecraft Attitude
Determination and Control*, ch. 6.  The nominal attitude ``q_ref_body`` comes from the
package's own integrator (:class:`strapdown_ros.attitude.integrator.AttitudeIntegrator`) on
increments compensated with the estimated gyro effects; the error state is the attitude error
ε, the gyro bias and, by name, further states of the effect registry (:mod:`.filter_support`
lays them out), the camera time offset and the boresight.  Between fixes the increments are
integrated at once and the covariance carried as the running sums of the block
(:class:`strapdown_ros.estimation.error_model.BlockSums`), committed to the square-root factor at
fixes and every ``checkpoint_interval``; the state at any increment stamp is read from the sums
(``propagate(..., marks)``).  A fix is gated on its NIS and applied in Joseph form on the
square-root factor; a late fix rolls back to a checkpoint (:mod:`.fix_history`); consecutive
gated fixes or an NIS excess declare divergence, and the fix re-initialises the attitude.
Model, equations and sources: doc/attitude_filter.md.  The node (``attitude_filter_node``) and
the ``filter_bag`` tool reach it through :mod:`.filter_system`.  No ROS imports.
"""
from __future__ import annotations

from collections import deque

import numpy as np

from strapdown_ros.attitude.integrator import AttitudeIntegrator
from strapdown_ros.estimation import filter_kernel
from strapdown_ros.estimation.chi_square import chi2_3_quantile
from strapdown_ros.estimation.chi_square import chi2_quantile
from strapdown_ros.estimation.error_model import BlockSums
from strapdown_ros.estimation.filter_support import (checked_fix, FilterCounters, FixResult,
                                                     psd_factor, ReportBatch, StateLayout,
                                                     StateReport, triangular_factor)
from strapdown_ros.estimation.fix_history import CameraFix, Checkpoint, IncrementLog
from strapdown_ros.rotation import (quat_conjugate, quat_cumprod, quat_multiply, quat_normalize,
                                    quat_to_dcm, quat_to_rotvec, rotvec_to_quat)
from strapdown_ros.sensors.effects import EFFECTS, GyroEffects

__all__ = ['AttitudeFilter']

# the compiled path's empty arguments (the kernels' types fixed: one compilation each)
_NO_ATTITUDE = np.zeros((0, 4))
_NO_LENGTHS = np.zeros(0)
_NO_PARTIALS = np.zeros((1, 3, 1))


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
        Increments :meth:`propagate` may hold before processing them (0: every call processed
        at once).  They are processed when a waiting fix is due, the queue is full, a state is
        to be reported (``marks``), or any estimate, the covariance or :meth:`update` is asked
        for: a caller sees the state of immediate processing; one increment per call then costs
        a fraction of the work (``filter_bench``).
    divergence_gated_fixes : int
        Divergence is declared after this many consecutive gated fixes (0: never by this rule).
    divergence_nis_window : int
        ... or when the NIS of the last this many fixes that pass the gate sum above their
        χ²(3·window) quantile of ``divergence_nis_probability`` (0: never by this rule).
    divergence_nis_probability : float
        That quantile's probability.
    reset_sigma : float, optional
        1σ of the attitude error per axis after a divergence reset, rad (default:
        ``initial_sigma``).

    Notes
    -----
    Between fixes the increments are integrated at once and the covariance is carried as the
    running sums of the block (:class:`~strapdown_ros.estimation.error_model.BlockSums`); the
    block is committed to the square-root factor at each fix and every ``checkpoint_interval``
    of stamp time (at the first update end past it), where a checkpoint is kept.  On divergence
    the fix that declares it re-initialises the attitude (``q_ref_body = q_fix ⊗ q_MF_VF⁻¹``)
    with the covariance ``reset_sigma²·I``, uncorrelated with the other states, which keep their
    estimates and covariance; it is reported with status ``reset`` and counted
    (``counters.resets``).

    """

    def __init__(self, initial_attitude, initial_time: float, *, algorithm: str = '2',
                 gyro_random_walk: float = 0.0, gyro_bias_random_walk: float = 0.0,
                 gyro_bias_correlation_time: float = 0.0,
                 initial_sigma: float = 1e-3, bias_sigma: float = 1e-5, augment=(),
                 augment_sigma: dict | None = None, initial_values: dict | None = None,
                 boresight=(1.0, 0.0, 0.0, 0.0), process_noise: dict | None = None,
                 gate_probability: float = 0.9999, history: int = 20_000, max_pending: int = 256,
                 checkpoint_interval: float = 1.0, max_queued: int = 1024,
                 epoch: float | None = None, time_offset: float = 0.0, model=None,
                 divergence_gated_fixes: int = 5, divergence_nis_window: int = 10,
                 divergence_nis_probability: float = 1.0 - 1e-9,
                 reset_sigma: float | None = None):
        for name, v in (('gyro_random_walk', gyro_random_walk), ('initial_sigma', initial_sigma),
                        ('bias_sigma', bias_sigma),
                        ('gyro_bias_random_walk', gyro_bias_random_walk)):
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f'{name} must be finite and >= 0, got {v}')
        if not np.isfinite(initial_time):
            raise ValueError('initial_time must be finite')
        if int(history) < 16 or int(max_pending) < 1 or int(max_queued) < 0:
            raise ValueError('history must be >= 16, max_pending >= 1 and max_queued >= 0')
        if int(divergence_gated_fixes) < 0 or int(divergence_nis_window) < 0 \
                or not 0.5 <= divergence_nis_probability < 1.0:
            raise ValueError('divergence_gated_fixes and divergence_nis_window must be >= 0, '
                             'divergence_nis_probability in [0.5, 1)')
        if not (np.isfinite(checkpoint_interval) and checkpoint_interval > 0):
            raise ValueError('checkpoint_interval must be > 0')
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
        self.gated_limit = int(divergence_gated_fixes)
        self.nis_window = int(divergence_nis_window)
        self.nis_limit = (chi2_quantile(float(divergence_nis_probability), 3 * self.nis_window)
                          if self.nis_window else np.inf)
        rs = initial_sigma if reset_sigma is None else reset_sigma
        if not (np.isfinite(rs) and rs > 0):
            raise ValueError('reset_sigma (default initial_sigma) must be > 0')
        self.reset_sigma = float(rs)
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
        self._identity = np.eye(self.layout.size)
        self._g_noise = np.concatenate([e.filter_process_noise(self.noise)
                                        for e, _ in self.layout.gyro])
        self._g_tau = np.concatenate([e.filter_correlation_time(self.noise)
                                      for e, _ in self.layout.gyro])
        self._nq = len(self._g_tau)                     # gyro states (bias first)
        #: Gauss–Markov states: the compensation's cells, 5 % of the shortest correlation time
        self._cell = 0.05 * float(np.min(self._g_tau))
        self._markov = bool(np.isfinite(self._cell))       # some estimate decays
        #: longest open block, s: the checkpoint interval (and at most 2 correlation times)
        self.block_length = min(float(checkpoint_interval), 2.0 * float(np.min(self._g_tau)))
        self._x_time = float(initial_time)              # the estimates are those at this time
        self._effects = None                            # the compensation of the estimates
        self._effects_cell = None
        self._bias_only = len(self.layout.gyro) == 1
        # the compiled numerics (filter_kernel), if numba is there and STRAPDOWN_KERNEL allows
        self._compiled = filter_kernel.available()
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
        self._block_t0 = self._last_stamp
        self._queue_d: list = []                # increments received, not processed yet
        self._queue_t: list = []
        self._queued = 0
        self._queued_stamp = float(initial_time)
        self._pending: list[CameraFix] = []
        self._applied: deque = deque()         # fixes applied (or gated), for re-processing
        self._seq = 0
        self._order = 0
        self._marks: list = []                  # stamps to report the state at (propagate)
        self._reports: list = []                # ReportBatch of the marks, not yet taken
        self._gated_run = 0                     # the divergence rule's memory
        self._nis_recent: deque = deque(maxlen=max(self.nis_window, 1))
        self._fixes_since_reset = 0
        self._checkpoints: deque = deque(maxlen=512)
        self._block: BlockSums | None = None
        self._new_block()
        self._checkpoint()

    # ------------------------------------------------------------------ layout and estimates
    @property
    def x(self) -> np.ndarray:
        """Return the estimates of the filter states (not errors) at :attr:`time`."""
        self._drain()
        return self._decayed(float(self.integrator.time) - self._x_time)

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
        return self._fixed_offset if sl is None else float(self._x[sl][0])   # not decaying

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
        sl = self.layout.slice_of(name)
        return self._decayed(float(self.integrator.time) - self._x_time)[sl]    # (a copy)

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

        ``S Sᵀ`` of the square-root factor the filter keeps, propagated over the open block
        (``ΦSSᵀΦᵀ + Q``), symmetric and positive semi-definite.
        """
        self._drain()
        if not self._block.m:
            P = self._sqrt_p @ self._sqrt_p.T
            return 0.5 * (P + P.T)
        phi, Q, _ = self._block.transition(self._block.state(), self.sigma_v)
        k = 3 + self._nq
        F = self._sqrt_p.copy()
        F[:k] = phi[0] @ self._sqrt_p[:k]
        P = F @ F.T
        P[:k, :k] += Q[0]
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
        return self.layout.implausible(self.x)

    def _gyro_effects(self, x: np.ndarray) -> GyroEffects:
        """Return the gyro effects of estimates ``x`` (the compensation)."""
        values = {e.name: e.filter_values(x[sl]) for e, sl in self.layout.gyro}
        return GyroEffects(values=values, epoch=self.epoch)

    # ------------------------------------------------------------------ public stream interface
    def propagate(self, delta_theta, stamps, marks=None) -> list[FixResult]:
        """
        Consume gyro increments and apply the waiting fixes whose epochs they reach.

        Parameters
        ----------
        delta_theta : array_like (n, 3)
            Measured increments, rad, body axes.
        stamps : array_like (n,)
            End stamps, s, strictly increasing and after :attr:`newest_stamp`.
        marks : array_like of int, optional
            Indices of increments at whose end stamps the state is reported
            (:meth:`take_reports`): attitude, covariance and estimates there (after a waiting
            fix of that very epoch).  The call then processes at once.

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
        if t[0] <= self._queued_stamp or (len(t) > 1 and (t[1:] <= t[:-1]).any()):
            raise ValueError('stamps must increase strictly and follow the newest stamp')
        self._queued_stamp = float(t[-1])
        marked = marks is not None and len(marks) > 0
        due = bool(self._pending) and self._pending[0].epoch <= t[-1]
        if not (due or marked) and self._queued + len(t) <= self.max_queued:
            self._queue_d.append(d)              # processed as one block later
            self._queue_t.append(t)
            self._queued += len(t)
            return []
        if marked:
            self._marks = sorted(t[np.asarray(marks, dtype=int)].tolist())
        if self._queued:
            d, t = np.concatenate(self._queue_d + [d]), np.concatenate(self._queue_t + [t])
            self._queue_d, self._queue_t, self._queued = [], [], 0
        out = self._advance(d, t)
        self._marks = []
        return out

    def take_reports(self) -> list[StateReport]:
        """
        Return the states reported at the marks of :meth:`propagate` since the last call.

        Returns
        -------
        list of StateReport
            In stamp order.

        """
        return self.take_report_batch().reports()

    def take_report_batch(self) -> ReportBatch:
        """
        Return the states reported at the marks since the last call, as arrays.

        What :meth:`take_reports` returns, without an object per stamp.

        Returns
        -------
        ReportBatch
            In stamp order.

        """
        out, self._reports = self._reports, []
        return ReportBatch.joined(out, self.layout.size)

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
            Status ``applied``, ``gated``, ``reset`` (divergence declared: the attitude was
            re-initialised from this fix), ``pending``, ``too_old`` or ``overflow``, with the
            residual and its NIS when it was applied, gated or reset.

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
            out = self._apply(fix)
            self._report_held()
            return out
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
            self._report_held()
            if len(t) == 0:
                break
            if not self._pending or self._pending[0].epoch > t[-1]:
                self._push(d, t)
                break
            epoch = self._pending[0].epoch
            i = int(np.searchsorted(t, epoch, side='left'))          # t[i] >= epoch
            t_prev = t[i - 1] if i > 0 else start
            if t[i] == epoch:
                self._push(d[:i + 1], t[:i + 1])
                d, t = d[i + 1:], t[i + 1:]
            else:                    # split the increment at the epoch (constant rate inside it)
                frac = (epoch - t_prev) / (t[i] - t_prev)
                head_d = np.vstack([d[:i], frac * d[i:i + 1]])
                self._push(head_d, np.append(t[:i], epoch))
                d = np.vstack([(1.0 - frac) * d[i:i + 1], d[i + 1:]])
                t = t[i:]
            start = epoch
        return out

    def _push(self, d: np.ndarray, t: np.ndarray) -> None:
        """
        Integrate increments (pieces) into the open block, committing it at its length limit.

        The block is committed (P ← ΦPΦᵀ + Q on the factor, a checkpoint) at the first update
        end past :attr:`block_length` after the block's start: a point of the data, not of how
        the increments arrived.
        """
        while len(t):
            n_new = self.integrator.algorithm.samples
            first = n_new - len(self._open_rho) - 1           # piece index of the first update end
            cut, limited = len(t), False
            if first < len(t):
                # the first update end (first + k·n_new) whose stamp is past the block's length
                past = int(np.searchsorted(t, self._block_t0 + self.block_length, side='right'))
                end = first + max(0, -((first - past) // n_new)) * n_new
                if end < len(t):
                    cut, limited = end + 1, True
            self._push_part(d[:cut], t[:cut])
            if limited:
                self._commit()
                self._checkpoint()
            d, t = d[cut:], t[cut:]

    def _compensate(self, d: np.ndarray, t: np.ndarray, dt: np.ndarray) -> np.ndarray:
        """
        Compensate increments with the estimated gyro effects.

        Gauss–Markov states: the estimate decayed to the middle of its cell (cells of 5 % of the
        shortest correlation time, counted from the last fix).
        """
        if not self._markov:
            if self._bias_only:                           # the bias alone: ρ = ρ̃ − b̂·T
                return d - self._x[3:6] * dt[:, None]
            if self._effects is None:
                self._effects = self._gyro_effects(self._x)
            return self._effects.compensate(d, t, dt)
        cells = np.floor((t - self._x_time) / self._cell)
        cuts = np.flatnonzero(np.diff(cells)) + 1
        out = []
        for dd, tt, hh, cc in zip(np.split(d, cuts), np.split(t, cuts), np.split(dt, cuts),
                                  cells[np.concatenate(([0], cuts))]):
            if self._effects is None or self._effects_cell != cc:
                self._effects = self._gyro_effects(self._decayed((cc + 0.5) * self._cell))
                self._effects_cell = cc
            out.append(self._effects.compensate(dd, tt, hh))
        return np.concatenate(out)

    def _partials(self, c, rho, h, t_mid) -> np.ndarray:
        """Return ``C_j J_j`` (m, 3, q) of the gyro states over m updates."""
        if self._bias_only:              # the bias alone: J_j = h_j·I, so C_j J_j = h_j C_j
            return c * h[:, None, None]
        return c @ self._gyro_partials(rho, h, t_mid)

    def _gyro_partials(self, rho, h, t_mid) -> np.ndarray:
        """Return ``J_j = ∂ρ̃_j/∂c`` (m, 3, q) of the gyro states over m updates."""
        J = [e.filter_partials(rho, h, t_mid) for e, _ in self.layout.gyro]
        return J[0] if len(J) == 1 else np.concatenate(J, axis=2)

    def _push_part(self, d: np.ndarray, t: np.ndarray) -> None:
        self._log.append(d, t)
        t_start, t_end = self._last_stamp, float(t[-1])
        dt = np.empty(len(t))                            # the lengths of the pieces
        dt[0] = t[0] - t_start
        np.subtract(t[1:], t[:-1], out=dt[1:])
        rho = self._compensate(d, t, dt)
        self._last_rate = rho[-1] / dt[-1]
        q_before = self.integrator.q
        p = len(self._open_rho)
        if p or rho is d:                        # (the open rest, or a copy of the caller's)
            work_rho = np.concatenate([self._open_rho, rho])
            work_dt = np.concatenate([self._open_dt, dt])
        else:
            work_rho, work_dt = rho, dt
        batch = self.integrator.push(rho, t)
        self._last_stamp = t_end
        n_new = self.integrator.algorithm.samples
        m = len(batch)
        held = self._pending[0].epoch if self._pending else np.inf   # marks from there: held
        marks = [s for s in self._marks if t_start < s <= t_end and s < held]
        if self._compiled:
            self._push_compiled(batch, marks, t, p, n_new, q_before, work_rho, work_dt)
            self._open_rho, self._open_dt = work_rho[m * n_new:], work_dt[m * n_new:]
            return
        run = None
        if m:
            c = quat_to_dcm(batch.attitude)
            rho_sum = batch.mean_rate * batch.interval[:, None]
            A = self._partials(c, rho_sum, batch.interval,
                               batch.stamps - 0.5 * batch.interval - self.epoch)
            run = self._block.add(c, A, batch.interval, running=bool(marks))
        self._open_rho, self._open_dt = work_rho[m * n_new:], work_dt[m * n_new:]
        if marks:
            self._report(marks, t, p, n_new, q_before, batch, run, work_rho, work_dt)

    def _push_compiled(self, batch, marks, t, p, n_new, q_before, work_rho, work_dt) -> None:
        """
        Add a push's updates to the block and report its marks: one compiled call.

        The same numbers as :meth:`BlockSums.add` and :meth:`_report` (filter_kernel).
        """
        m = len(batch)
        if m:
            att, h = batch.attitude, batch.interval
            J = _NO_PARTIALS if self._bias_only else self._gyro_partials(
                batch.mean_rate * h[:, None], h, batch.stamps - 0.5 * h - self.epoch)
        else:
            att, h, J = _NO_ATTITUDE, _NO_LENGTHS, _NO_PARTIALS
        stamps = np.asarray(marks, dtype=float) if marks else _NO_LENGTHS
        out = filter_kernel.push_block(att, J, h, self._bias_only, self._block, stamps, t, p,
                                       n_new, q_before, self._sqrt_p, self.sigma_v)
        if out is None:             # a mark inside an update: its lumped rest (as _report's)
            w = p + np.searchsorted(t, stamps)                    # work index of each mark
            done = (w + 1) // n_new                               # updates of this push up to it
            q_out = (np.concatenate([q_before[None], att])[done] if m
                     else np.repeat(q_before[None], len(stamps), axis=0))
            inside = np.flatnonzero(done * n_new < w + 1)
            c_v, A_v, h_v = self._lumped_rests(stamps, w, done, n_new, q_out, inside, work_rho,
                                               work_dt)
            P = filter_kernel.push_block(att, J, h, self._bias_only, self._block, stamps, t, p,
                                         n_new, q_before, self._sqrt_p, self.sigma_v,
                                         rests=(done, c_v, A_v, h_v))[0]
        else:
            P, q_out = out
        if marks:
            self._store_reports(stamps, q_out, P)

    def _lumped_rests(self, stamps, w, done, n_new, q_out, inside, work_rho, work_dt):
        """
        Return the lumped rest of the unfinished update at each mark (h 0: none).

        The attitudes ``q_out`` of the marks inside an update are advanced over their rests.
        """
        K = len(stamps)
        h_v = np.zeros(K)
        rho_v = np.zeros((K, 3))
        for k in inside:
            piece = work_rho[done[k] * n_new:w[k] + 1]
            q_out[k] = quat_cumprod(q_out[k], rotvec_to_quat(piece))[-1]
            rho_v[k] = piece.sum(0)
            h_v[k] = work_dt[done[k] * n_new:w[k] + 1].sum()
        c_v = quat_to_dcm(q_out)
        A_v = self._partials(c_v, rho_v, np.where(h_v > 0, h_v, 1.0),
                             stamps - 0.5 * h_v - self.epoch) * (h_v > 0)[:, None, None]
        return c_v, A_v, h_v

    def _held(self, stamp: float) -> bool:
        """Tell whether a mark waits for a fix of its epoch (reported after it)."""
        return bool(self._pending) and self._pending[0].epoch <= stamp

    def _report(self, marks, t, p, n_new, q_before, batch, run, work_rho, work_dt) -> None:
        """
        Report the state at marks inside the piece just pushed (not committing anything).

        ``run``: the block's running sums of this push (row 0: before it), None when it
        completed no update.
        """
        stamps = np.asarray(marks)
        K = len(stamps)
        w = p + np.searchsorted(t, stamps)                        # work index of each mark
        done = (w + 1) // n_new                                   # updates of this push up to it
        if run is None:
            q_out = np.repeat(q_before[None], K, axis=0)
            base = tuple(np.repeat(b, K, axis=0) for b in self._block.state())
        else:
            q_out = np.concatenate([q_before[None], batch.attitude])[done]
            base = tuple(None if r is None else r[done] for r in run)
        inside = np.flatnonzero(done * n_new < w + 1)            # inside an update: a lumped rest
        if len(inside):
            c_v, A_v, h_v = self._lumped_rests(stamps, w, done, n_new, q_out, inside, work_rho,
                                               work_dt)
            sums = self._block.extended(base, c_v, A_v, h_v)
        else:                        # every mark at an update's end: the sums there as they are
            sums = base
        phi, Q, _ = self._block.transition(sums, self.sigma_v)
        self._add_reports(stamps, q_out, phi, Q)

    def _add_reports(self, stamps, q, phi, Q) -> None:
        """Report the states at K stamps: attitudes q (K, 4), the open block's Φ and Q there."""
        k = 3 + self._nq
        K = len(stamps)
        S = self._sqrt_p
        if k == len(S):                                # Φ covers the whole state
            F = phi @ S                                # the factor propagated to each stamp
        else:
            F = np.empty((K,) + S.shape)
            F[:, :k] = phi @ S[:k]
            F[:, k:] = S[k:]
        P = F @ np.swapaxes(F, -1, -2)
        P[:, :k, :k] += Q
        self._store_reports(stamps, q, 0.5 * (P + np.swapaxes(P, -1, -2)))

    def _store_reports(self, stamps, q, P) -> None:
        """Report the states at K stamps: attitudes q (K, 4), covariances P (K, n, n)."""
        K = len(stamps)
        x = np.repeat(self._x[None], K, axis=0)        # each report its own row (no copies)
        if self._markov:
            x[:, 3:3 + self._nq] *= np.exp(-np.outer(stamps - self._x_time, 1.0 / self._g_tau))
        stamps = np.array(stamps, dtype=float)
        self._reports.append(ReportBatch(stamps, np.array(q, dtype=float), P, x,
                                         np.repeat(self.boresight[None], K, axis=0)))
        done = set(stamps.tolist())
        self._marks = [m for m in self._marks if m not in done]

    def _report_held(self) -> None:
        """Report the marks at the newest stamp once its fixes are applied (committed state)."""
        held = [s for s in self._marks if s <= self._last_stamp and not self._held(s)]
        if not held:
            return
        K = len(held)
        k = 3 + self._nq
        phi = np.broadcast_to(np.eye(k), (K, k, k))
        Q = np.zeros((K, k, k))
        q = np.broadcast_to(self.integrator.q, (K, 4))
        if self._block.m or len(self._open_rho):
            raise RuntimeError('attitude filter: a held mark with an open block')   # never
        self._add_reports(np.asarray(held), q, phi, Q)

    def _commit(self) -> None:
        """Commit the open block to the covariance factor and start a new block."""
        if self._block.m and self._compiled:
            self._sqrt_p = filter_kernel.update(self._sqrt_p, self._block, self.sigma_v, True)[0]
        elif self._block.m:
            phi, Q, _ = self._block.transition(self._block.state(), self.sigma_v)
            k = 3 + self._nq
            if k == len(self._sqrt_p):                   # Φ covers the whole state
                S, Qf = phi[0] @ self._sqrt_p, psd_factor(Q[0])
            else:
                S = self._sqrt_p.copy()
                S[:k] = phi[0] @ self._sqrt_p[:k]
                Qf = np.zeros((len(S), k))
                Qf[:k] = psd_factor(Q[0])
            self._sqrt_p = triangular_factor(S, Qf)       # P ← ΦPΦᵀ + Q
        self._new_block()

    def _new_block(self, c0=None) -> None:
        """Start a new block at the current attitude (its DCM ``c0`` when known)."""
        if c0 is None:
            c0 = quat_to_dcm(self.integrator.q)
        if self._block is None:
            self._block = BlockSums(c0, self._nq, self._g_noise, self._g_tau)
        else:
            self._block.restart(c0)
        self._block_t0 = self._last_stamp

    def _flush(self, commit: bool = True) -> None:
        """
        Complete the unfinished update and commit: attitude and covariance at the newest stamp.

        The unfinished update's increments are applied one by one, the integrator's rule when
        the algorithm changes, as one lumped update of the block.  ``commit`` False: the block
        is left open (the compiled update commits it).
        """
        if len(self._open_rho):
            self.integrator.set_algorithm(self.integrator.algorithm_name)
            h = np.array([self._open_dt.sum()])
            c = quat_to_dcm(self.integrator.q)[None]
            rho = self._open_rho.sum(0)[None]
            A = self._partials(c, rho, h, np.array([self._last_stamp - 0.5 * h[0] - self.epoch]))
            self._block.add(c, A, h)
            self.integrator.time = self._last_stamp
            self._open_rho, self._open_dt = np.zeros((0, 3)), np.zeros(0)
        if commit:
            self._commit()

    def _decayed(self, elapsed: float) -> np.ndarray:
        """Return the estimates ``elapsed`` s after the last fix (Gauss–Markov states decay)."""
        x = self._x.copy()
        if self._markov:
            x[3:3 + self._nq] *= np.exp(-elapsed / self._g_tau)
        return x

    def _settle(self, epoch: float) -> None:
        """Make the estimates those at ``epoch`` (the decay since the last fix applied)."""
        if self._markov and epoch != self._x_time:
            self._x = self._decayed(epoch - self._x_time)
            self._effects = None
        self._x_time = float(epoch)

    def _divergence(self, nis: float, gated: bool) -> str | None:
        """
        Update the divergence rule with one fix; return why the filter diverged, or None.

        Divergence: ``divergence_gated_fixes`` consecutive gated fixes (a lock-out), or the sum of
        the NIS of the last ``divergence_nis_window`` fixes that pass the gate above their
        χ²(3·window) quantile of ``divergence_nis_probability`` (fixes applied, but the filter's
        σ far too small for them).  A gated fix does not enter the sum: one outlier does not
        declare divergence.
        """
        self._gated_run = self._gated_run + 1 if gated else 0
        self._fixes_since_reset += 1
        if self.gated_limit and self._gated_run >= self.gated_limit:
            return (f'{self._gated_run} consecutive fixes gated (NIS {nis:.4g} > gate '
                    f'{self.gate:.4g})')
        if self.nis_window and not gated:
            self._nis_recent.append(nis)
            if len(self._nis_recent) == self.nis_window:
                total = float(sum(self._nis_recent))
                if total > self.nis_limit:
                    return (f'NIS sum {total:.4g} of the last {self.nis_window} fixes passing '
                            f'the gate above {self.nis_limit:.4g}')
        return None

    def _reset(self, fix: CameraFix, z, nis, S, reason: str) -> FixResult:
        """Re-initialise the attitude from the fix, inflate its covariance, keep the rest."""
        self.integrator.q = quat_normalize(quat_multiply(fix.attitude,
                                                         quat_conjugate(self.boresight)))
        n = self.layout.size
        sq = np.zeros((n, n))
        sq[:3, :3] = self.reset_sigma * np.eye(3)
        sq[3:, 3:] = triangular_factor(self._sqrt_p[3:, :])   # the other states: P kept
        self._sqrt_p = sq
        self._gated_run, self._fixes_since_reset = 0, 0
        self._nis_recent.clear()
        self._new_block()
        if not fix.counted:
            self.counters.resets += 1
            self.counters.last_reset = fix.epoch
        fix.counted = True
        res = self._record(fix, 'reset', z, nis, S, reason)
        self._checkpoint()
        return res

    @property
    def fixes_since_reset(self) -> int | None:
        """Return the fixes processed since the last divergence reset (None: none yet)."""
        return self._fixes_since_reset if self.counters.resets else None

    def _apply(self, fix: CameraFix) -> FixResult:
        """Measurement update at the newest stamp (= the fix epoch)."""
        self._flush(commit=not self._compiled)     # compiled: the commit in the update's call
        self._settle(fix.epoch)
        lay = self.layout
        c_bv = quat_to_dcm(self.boresight)                 # C_MF^VF
        H = np.zeros((3, lay.size))
        H[:, :3] = c_bv.T
        if lay.boresight is not None:
            H[:, lay.boresight] = np.eye(3)
        if lay.time_offset is not None:
            H[:, lay.time_offset] = EFFECTS['time_offset'].fix_jacobian(self._last_rate, c_bv.T)
        if self._compiled:     # the commit and the numerics below, resets included, compiled
            (self._sqrt_p, nis, z, S, K, dx, finite, joseph, q_new, bv_new,
             c_new) = filter_kernel.update(
                self._sqrt_p, self._block, self.sigma_v, self._block.m > 0,
                (H, fix.covariance, self.integrator.q, self.boresight, fix.attitude,
                 -1 if lay.boresight is None else lay.boresight.start))
        else:
            q_pred = quat_multiply(self.integrator.q, self.boresight)
            z = quat_to_rotvec(quat_multiply(quat_conjugate(fix.attitude), q_pred))
            P = self._sqrt_p @ self._sqrt_p.T
            P = 0.5 * (P + P.T)
            HP = H @ P
            S = HP @ H.T + fix.covariance
            S = 0.5 * (S + S.T)
            # S⁻¹ [z, HP] in one solve: the NIS, and the gain when the fix is applied
            solved = np.linalg.solve(S, np.column_stack((z, HP)))
            nis = float(z @ solved[:, 0])
        self._applied.append(fix)
        fix.order = self._order
        self._order += 1
        self._trim_applied()
        gated = not nis <= self.gate
        reason = self._divergence(nis, gated)
        if reason is not None:
            return self._reset(fix, z, nis, S, reason)
        if gated:
            if self._compiled:
                self._new_block()                  # (the numpy path's, at its commit)
            res = self._record(fix, 'gated', z, nis, S)
            res.jacobian = H
            if not fix.counted:
                self.counters.gated += 1
            fix.counted = True
            self._checkpoint()
            return res
        if not self._compiled:
            K = solved[:, 1:].T
            dx = K @ z
            finite = np.isfinite(K).all() and np.isfinite(dx).all()
        if not finite:
            if self._compiled:
                self._new_block()                  # (the numpy path's, at its commit)
            raise FloatingPointError('attitude filter: non-finite gain in the update (numerical '
                                     'failure, not bad input); the state is not corrected')
        if self._compiled:
            self._sqrt_p, self.integrator.q, self.boresight = joseph, q_new, bv_new
            self._new_block(c_new)
        else:
            IKH = self._identity - K @ H
            # Joseph form P ← (I − KH)P(I − KH)ᵀ + KRKᵀ, as the factor of [(I − KH)S, K R^½]
            self._sqrt_p = triangular_factor(IKH @ self._sqrt_p,
                                             K @ np.linalg.cholesky(fix.covariance))
            self.integrator.q = quat_normalize(quat_multiply(self.integrator.q,
                                                             rotvec_to_quat(-dx[:3])))
            self._new_block()
            if lay.boresight is not None:
                self.boresight = quat_normalize(quat_multiply(
                    self.boresight, rotvec_to_quat(-dx[lay.boresight])))
        self._x[3:] -= dx[3:]
        self._effects = None
        if lay.boresight is not None:
            self._x[lay.boresight] = 0.0          # the boresight estimate lives in the quaternion
        if not fix.counted:
            self.counters.applied += 1
            if self.layout.implausible(self._x):
                self.counters.implausible += 1
        fix.counted = True
        res = self._record(fix, 'applied', z, nis, S)
        res.jacobian, res.gain = H, K
        self._checkpoint()
        return res

    def _record(self, fix: CameraFix, status: str, z=None, nis=None, S=None,
                reason: str = '') -> FixResult:
        res = FixResult(fix.stamp, fix.epoch, status, fix.lateness, z, nis, S, reason=reason)
        self.results.append(res)
        return res

    # ------------------------------------------------------------------ history
    def _checkpoint(self) -> None:
        while self._checkpoints and self._checkpoints[0].pieces < self._log.base:
            self._checkpoints.popleft()                   # its increments are forgotten
        self._checkpoints.append(Checkpoint(
            self._last_stamp, self._log.next, self._order,
            self.integrator.checkpoint(), self._x.copy(), self.boresight.copy(), self._sqrt_p,
            self._open_rho, self._open_dt, self._last_rate, self._last_stamp, self._x_time,
            (self._gated_run, tuple(self._nis_recent), self._fixes_since_reset)))

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
        self._x_time = cp.state_time
        self._gated_run, recent, self._fixes_since_reset = cp.divergence
        self._nis_recent = deque(recent, maxlen=self._nis_recent.maxlen)
        self._effects = None
        self._new_block()
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
