"""
SINS attitude integrator: gyro increments → attitude and its error covariance.

The attitude room's streaming core, under ``sins_node``, the calibrator and the attitude filter;
it reads its formulas from the coning registry and runs them in :mod:`.kernel` when compiled.

:class:`AttitudeIntegrator` consumes integrating-gyro increments ``Δθ_k`` (body axes,
rad) stamped at the end of their intervals and produces, at every update of the
selected coning algorithm (:mod:`strapdown_ros.attitude.coning`):

* the attitude ``q_ref_body`` (``q_k = q_{k−1} ⊗ exp(φ_k)``, 003 eqs. 1.63/1.64 in
  quaternion form, renormalised);
* the attitude-error covariance ``P_k`` of ε (body axes, ``C_est = C_true(I + [ε×])``,
  the definition of 004 §2.3).

Covariance propagation
----------------------
004 eq. (2) propagates ``E_k = (I − [ρ_k×]) E_{k−1} (I + [ρ_k×]) + P_ρk``.  The factor
``I − [ρ×]`` is the first-order form of ``ΔC_kᵀ`` (the transpose of the update
rotation); we use the exact ``ΔC_kᵀ``.  Written in reference axes, ``e_k = C_k ε_k``,
the recursion becomes a plain sum, ``e_k = e_{k−1} + C_k δρ_k``, because
``C_k ΔC_kᵀ = C_{k−1}``.  So the covariance is a cumulative sum over updates of
``C_k Q_k C_kᵀ``, which numpy evaluates for a whole batch at once; the body-axis
covariance is ``P_k = C_kᵀ P^ref_k C_k``.

Two error models (parameter ``covariance_model``):

``"004"``
    Exactly 004: every term of P_ρk (misalignment, scale factor, bias, noise) is
    treated as white from one increment to the next.  The bias then contributes
    ``(σ_b T)²`` per step: the attitude error grows like √t.

``"random_constant"`` (default)
    Only the random walk is white.  Bias ``b`` and the scale/misalignment matrix M
    are random constants (as they are in the sensor and in the simulator):
    ``e_k = Σ C_j (M ρ_j + b h_j + w_j)``, so ``P^ref = S P_b Sᵀ + J P_M Jᵀ + Σ C Q_w Cᵀ``
    with ``S = Σ C_j h_j`` and ``J = Σ C_j ∂(Mρ_j)/∂vec M``.  The bias error then
    grows like t, as it physically does.  The published covariance is the one a
    navigation user can trust.

In both models increments inside one multi-sample update are lumped (their P_ρ
are added and rotated with the update's end attitude): the rotation within one
update is first order in ρ and enters the covariance at second order.

Pulse quantization does not accumulate (the remainder is carried, 000 eq. 5.1);
it adds ``σ²/12`` per axis to the body covariance at every epoch.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.attitude import kernel as attitude_kernel
from strapdown_ros.attitude.coning import bilinear_form, ConingAlgorithm, get_algorithm
from strapdown_ros.rotation import quat_cumprod, quat_normalize, quat_to_dcm, rotvec_to_quat
from strapdown_ros.sensors import increment_correction, SensorSigmas
from strapdown_ros.sensors.covariance import constant_jacobian
from strapdown_ros.sensors.covariance import COVARIANCE_MODELS as _MODELS
from strapdown_ros.sensors.covariance import get_covariance_model
from strapdown_ros.sensors.effects import EFFECTS

__all__ = ['AttitudeIntegrator', 'UpdateBatch', 'COVARIANCE_MODELS']

#: names of the covariance models (the registry is strapdown_ros.sensors.covariance)
COVARIANCE_MODELS = tuple(_MODELS)

_NO_INCREMENTS, _NO_INTERVALS = np.zeros((0, 3)), np.zeros(0)       # shared, never written
_RECENT = 4                  # used increments kept as history (more if an algorithm reads more)


@dataclass
class UpdateBatch:
    """
    Outputs of one :meth:`AttitudeIntegrator.push`: M attitude updates.

    Parameters
    ----------
    stamps : (M,) ndarray
        End time of each update, s.
    attitude : (M, 4) ndarray
        ``q_ref_body``, Hamilton, scalar first.
    covariance : (M, 3, 3) ndarray
        Attitude error covariance, body axes, rad² (NaN without covariance propagation).
    rotation_vector : (M, 3) ndarray
        φ of each update, body axes, rad.
    mean_rate : (M, 3) ndarray
        Σq / h, rad/s.
    interval : (M,) ndarray
        Update interval h, s.
    first_end : int, optional
        Index, in the pushed arrays, of the first update's last increment; the M updates end
        at ``first_end + k·samples`` (the stamps above are those increments' stamps).

    """

    stamps: np.ndarray
    attitude: np.ndarray
    covariance: np.ndarray
    rotation_vector: np.ndarray
    mean_rate: np.ndarray
    interval: np.ndarray
    first_end: int = 0

    def __len__(self):
        return len(self.stamps)


class AttitudeIntegrator:
    """
    Streaming strapdown attitude integrator (vectorised over each pushed block).

    Parameters
    ----------
    algorithm : str
        Name in :data:`strapdown_ros.attitude.coning.ALGORITHMS`.
    initial_attitude : (4,) array_like
        ``q_ref_body`` at ``initial_time``, scalar first.
    initial_time : float or None
        Stamp of the initial attitude, s; None: the start of the first increment,
        ``stamp_1 − nominal_period``.
    nominal_period : float
        Expected gyro interval T, s, used only for the first sample.
    gyro : SensorSigmas or None
        Statistics of the gyro errors for P_ρk (zeros: the covariance stays at P0).
    initial_sigma : float
        1σ of the initial attitude error per axis, rad.
    covariance_model : str
        A name in :data:`strapdown_ros.sensors.covariance.COVARIANCE_MODELS`.
    quantization_correction : bool
        Apply 000 eq. (5.6) with the pulse weight ``gyro.quantum``.
    propagate_covariance : bool
        False skips the covariance (published as NaN), for benchmarks of the attitude
        algorithm alone.

    """

    def __init__(self, algorithm: str = '2', initial_attitude=(1.0, 0.0, 0.0, 0.0),
                 initial_time: float | None = None, nominal_period: float = 0.01,
                 gyro: SensorSigmas | None = None, initial_sigma: float = 0.0,
                 covariance_model: str = 'random_constant', quantization_correction: bool = False,
                 propagate_covariance: bool = True):
        self.cov_model = get_covariance_model(covariance_model)
        if not (np.isfinite(nominal_period) and nominal_period > 0):
            raise ValueError(f'nominal_period must be > 0, got {nominal_period}')
        if not (np.isfinite(initial_sigma) and initial_sigma >= 0):
            raise ValueError(f'initial_sigma must be >= 0, got {initial_sigma}')
        q0 = np.asarray(initial_attitude, dtype=float)
        if q0.shape != (4,) or not np.all(np.isfinite(q0)) or np.linalg.norm(q0) < 0.5:
            raise ValueError('initial_attitude must be a finite quaternion [w, x, y, z]')
        self.algorithm: ConingAlgorithm = get_algorithm(algorithm)
        self.q = quat_normalize(q0)
        self.time = initial_time
        self.nominal_period = float(nominal_period)
        self.gyro = gyro or SensorSigmas()
        self.covariance_model = covariance_model
        self.quantization_correction = bool(quantization_correction)
        self.propagate_covariance = bool(propagate_covariance)
        self._last_sign = np.zeros(3)
        self._last_stamp = initial_time
        self._pending = _NO_INCREMENTS           # increments of the update in progress
        self._pending_dt = _NO_INTERVALS
        self._recent = np.zeros((0, 3))          # last few used increments (history for 6, 7)
        c0 = quat_to_dcm(self.q)
        self._p_ref = c0 @ (initial_sigma ** 2 * np.eye(3)) @ c0.T   # white + initial part
        # Σ C_j ∂ρ_j/∂x, x = [b, vec M] (random constants)
        self._j_const = np.zeros((3, 12))
        self.updates = 0
        self.samples = 0
        self._constant_var = self.cov_model.constant_variances(self.gyro)
        # the isotropic white part per second of interval (the compiled kernel's form)
        self._white_rate = (float(self.cov_model.white_variance(1.0, self.gyro))
                            if self.cov_model.isotropic_white else None)
        # the compiled block kernel, if numba is there and STRAPDOWN_KERNEL allows it (read once)
        self._kernel = attitude_kernel.available()

    # -------------------------------------------------------------------------------
    @property
    def algorithm_name(self) -> str:
        """
        Return the name of the coning algorithm in use.

        Returns
        -------
        str
            Key of the coning registry.

        """
        return self.algorithm.name

    def set_algorithm(self, name: str) -> None:
        """
        Switch the coning algorithm between updates.

        Increments of an unfinished update are applied one by one (φ = q) so that no
        rotation is lost.

        Parameters
        ----------
        name : str
            Key of the coning registry.

        """
        new = get_algorithm(name)
        if len(self._pending):
            phi = self._pending
            dq = rotvec_to_quat(phi)
            q = quat_cumprod(self.q, dq)
            self.q = q[-1]
            self._accumulate_covariance(quat_to_dcm(q), phi, self._pending, self._pending_dt)
            self._pending = np.zeros((0, 3))
            self._pending_dt = np.zeros(0)
        self.algorithm = new

    def restart_clock(self) -> None:
        """
        Start a new time base after a confirmed stamp jump or clock reset.

        The next increment is taken as one nominal period long.  The attitude carries on; the
        rotation during the jump is lost (the caller reports it).
        """
        self._last_stamp = None
        self.time = None

    def snapshot(self) -> tuple:
        """
        Return the state needed to come back to this point (:meth:`restore`).

        No copies: :meth:`push` and :meth:`set_algorithm` replace these arrays, they never
        write into them.

        Returns
        -------
        tuple
            Opaque state for :meth:`restore`.

        """
        return (self.q, self.time, self._last_stamp, self._p_ref, self._j_const, self.updates,
                self.samples)

    def restore(self, snap: tuple, inflate_sigma: float = 0.0) -> None:
        """
        Return to a :meth:`snapshot`, dropping the unfinished update and the history.

        Parameters
        ----------
        snap : tuple
            A :meth:`snapshot`.
        inflate_sigma : float
            Added as ``inflate_sigma``² per axis to the attitude covariance, rad (what was
            skipped is unknown).

        """
        self.q, self.time, self._last_stamp, p_ref, j_const, self.updates, self.samples = snap
        self._p_ref = p_ref + inflate_sigma ** 2 * np.eye(3)
        self._j_const = j_const.copy()
        self._pending, self._pending_dt = np.zeros((0, 3)), np.zeros(0)
        self._recent = np.zeros((0, 3))

    def checkpoint(self) -> tuple:
        """
        Return the whole state, for :meth:`rollback`.

        Cheap: :meth:`push` replaces its arrays, it never writes into them.

        Returns
        -------
        tuple
            Opaque state for :meth:`rollback`.

        """
        return (self.q, self.time, self._last_stamp, self._p_ref, self._j_const, self.updates,
                self.samples, self._pending, self._pending_dt, self._recent, self._last_sign,
                self.algorithm)

    def rollback(self, cp: tuple) -> None:
        """
        Return exactly to a :meth:`checkpoint`, unfinished update and history included.

        Parameters
        ----------
        cp : tuple
            A :meth:`checkpoint`.

        """
        (self.q, self.time, self._last_stamp, self._p_ref, self._j_const, self.updates,
         self.samples, self._pending, self._pending_dt, self._recent, self._last_sign,
         self.algorithm) = cp

    def covariance(self) -> np.ndarray:
        """
        Return the current attitude error covariance.

        Returns
        -------
        (3, 3) ndarray
            Body axes, rad².

        """
        c = quat_to_dcm(self.q)[None]
        return self._body_covariance(c, self._p_ref[None], self._j_const[None])[0]

    # -------------------------------------------------------------------------------
    def push(self, delta_theta: np.ndarray, stamps: np.ndarray) -> UpdateBatch:
        """
        Consume gyro increments and return the attitude updates they complete.

        The caller guarantees finite values and strictly increasing stamps (the ROS
        node checks and counts violations before calling).

        Parameters
        ----------
        delta_theta : (n, 3) array_like
            Increments Δθ, body axes, rad.
        stamps : (n,) array_like
            End of each increment's interval, s.

        Returns
        -------
        UpdateBatch
            The updates completed by these increments (possibly none).

        """
        dth = np.asarray(delta_theta, dtype=float).reshape(-1, 3)
        stamps = np.asarray(stamps, dtype=float).reshape(-1)
        if len(dth) != len(stamps):
            raise ValueError('delta_theta and stamps must have the same length')
        if len(dth) == 0:
            return self._empty()
        if self.quantization_correction and self.gyro.quantum > 0:
            dth, self._last_sign = increment_correction(dth, self.gyro.quantum, self._last_sign)
        prev = self._last_stamp
        if prev is None:
            prev = stamps[0] - self.nominal_period
        if self.time is None:
            self.time = prev
        n = len(stamps)
        dt = np.empty(n)
        dt[0] = stamps[0] - prev
        np.subtract(stamps[1:], stamps[:-1], out=dt[1:])
        self._last_stamp = float(stamps[-1])
        self.samples += n

        alg = self.algorithm
        n_new, hist = alg.samples, alg.history
        first_end = n_new - 1 - len(self._pending)
        if len(self._pending):       # the increments of an unfinished update come first
            work = np.concatenate((self._pending, dth))
            work_dt = np.concatenate((self._pending_dt, dt))
            work_t = np.concatenate((np.full(len(self._pending), np.nan), stamps))
        else:
            work, work_dt, work_t = dth, dt, stamps
        m = len(work) // n_new
        used = m * n_new
        if m == 0:                   # (a copy: work may be the caller's array)
            self._pending, self._pending_dt = work.copy(), work_dt.copy()
            return self._empty()
        # history: previous increments; at start-up repeat the first one (zero cross products)
        if hist == 0:
            seq = work[:used]
        elif len(self._recent) >= hist:
            seq = np.concatenate((self._recent[len(self._recent) - hist:], work[:used]))
        else:   # start-up: repeat the earliest increment seen so far
            first = self._recent[:1] if len(self._recent) else work[:1]
            pad = np.repeat(first, hist - len(self._recent), axis=0)
            recent = np.concatenate((pad, self._recent))
            seq = np.concatenate((recent, work[:used]))
        dts = work_dt[:used]
        table = bilinear_form(alg.name)
        if table is not None and self._kernel:            # with or without the covariance
            q, cov, phi, mean_rate, h = self._compiled_update(seq, dts, m, table)
        else:
            phi = alg.phi(self._windows(seq, m))
            blocks = work[:used].reshape(m, n_new, 3)
            h = dts.reshape(m, n_new).sum(1)
            q, cov = self._vectorised_update(phi, blocks, dts.reshape(m, n_new))
            mean_rate = blocks.sum(1) / h[:, None]

        self.q = q[-1]
        self.time = float(work_t[used - 1])
        self.updates += m
        if used < len(work):
            self._pending, self._pending_dt = work[used:].copy(), work_dt[used:].copy()
        elif len(self._pending):
            self._pending, self._pending_dt = _NO_INCREMENTS, _NO_INTERVALS
        # the history of the next update: the last used increments, at least those it reads
        keep = max(_RECENT, hist)
        self._recent = (work[used - keep:used].copy() if used >= keep
                        else np.concatenate((self._recent, work[:used]))[-keep:])
        return UpdateBatch(stamps=work_t[n_new - 1:used:n_new], attitude=q, covariance=cov,
                           rotation_vector=phi, mean_rate=mean_rate, interval=h,
                           first_end=first_end)

    def _windows(self, seq: np.ndarray, m: int) -> np.ndarray:
        """Return the m coning windows (m, window, 3) of history + new increments."""
        alg = self.algorithm
        idx = np.arange(m)[:, None] * alg.samples + np.arange(alg.window)[None, :]
        return seq[idx]

    def _compiled_update(self, seq, dts, m, table):
        """
        Run a block as one compiled call (:mod:`strapdown_ros.attitude.kernel`).

        Coning term from the algorithm's table, attitude, covariance (NaN without
        ``propagate_covariance``), mean rate.
        """
        g, model, alg = self.gyro, self.cov_model, self.algorithm
        q_white = None
        cov_on = self.propagate_covariance
        if cov_on and not model.isotropic_white:
            new = seq[alg.history:]
            q_white = model.white(new, dts, g).reshape(m, alg.samples, 3, 3).sum(1)
        q, cov, phi, rate, h, self._p_ref, self._j_const = attitude_kernel.block_update(
            self.q, seq, dts, alg.samples, alg.history, table, self._p_ref, self._j_const,
            self._constant_var, self._white_rate, q_white, model.constants, compiled=True,
            covariance=cov_on)
        if cov_on and g.quantum > 0:   # the remainder at this epoch (000 §5)
            cov = EFFECTS['gyro_quantization'].fix_covariance(cov, np.array([g.quantum]))
        return q, cov, phi, rate, h

    def _vectorised_update(self, phi, blocks, dts):
        """Run the recursion of a block in numpy: a quaternion scan and cumulative sums."""
        m = len(phi)
        q = quat_cumprod(self.q, rotvec_to_quat(phi))
        c = quat_to_dcm(q)
        if self.propagate_covariance:
            p_ref, j_const = self._accumulate_covariance(c, blocks.sum(1), blocks, dts)
            cov = self._body_covariance(c, p_ref, j_const)
        else:                                     # attitude only (algorithm benchmarks)
            cov = np.full((m, 3, 3), np.nan)
        return q, cov

    # -------------------------------------------------------------------------------
    def _accumulate_covariance(self, c, rho_sum, blocks, dts):
        """
        Advance the reference-axis accumulators over m updates.

        Return their running values after every update: (m, 3, 3) and (m, 3, 12).  What is
        white and what is a random constant is the covariance model's
        (strapdown_ros.sensors.covariance).
        """
        g, model = self.gyro, self.cov_model
        blocks = np.asarray(blocks).reshape(len(c), -1, 3)
        dts = np.asarray(dts).reshape(len(c), -1)
        n_new = blocks.shape[1]
        if model.isotropic_white:
            # q I in any axes: C (q I) Cᵀ = q I, no rotation needed
            q = model.white_variance(dts.sum(1), g)
            p_ref = self._p_ref + np.cumsum(q)[:, None, None] * np.eye(3)
        else:
            q_white = model.white(blocks.reshape(-1, 3), dts.reshape(-1), g)
            q_white = q_white.reshape(len(c), n_new, 3, 3).sum(1)
            p_ref = self._p_ref + np.cumsum(c @ q_white @ np.swapaxes(c, -1, -2), axis=0)
        self._p_ref = p_ref[-1]
        if model.constants:
            # increments inside one update are lumped: ∂ρ/∂x of the update's sum over its length
            jac = constant_jacobian(rho_sum, dts.sum(1))
            j_const = self._j_const + np.cumsum(c @ jac, axis=0)
            self._j_const = j_const[-1]
        else:
            j_const = np.broadcast_to(self._j_const, (len(c), 3, 12))
        return p_ref, j_const

    def _body_covariance(self, c, p_ref, j_const):
        g = self.gyro
        total = p_ref
        var = self.cov_model.constant_variances(g)
        if np.any(var > 0):
            total = total + (j_const * var) @ np.swapaxes(j_const, -1, -2)
        cov = np.swapaxes(c, -1, -2) @ total @ c
        if g.quantum > 0:              # the remainder at this epoch (000 §5)
            cov = EFFECTS['gyro_quantization'].fix_covariance(cov, np.array([g.quantum]))
        return 0.5 * (cov + np.swapaxes(cov, -1, -2))

    @staticmethod
    def _empty() -> UpdateBatch:
        return UpdateBatch(np.zeros(0), np.zeros((0, 4)), np.zeros((0, 3, 3)), np.zeros((0, 3)),
                           np.zeros((0, 3)), np.zeros(0))
