"""
Streaming boresight calibrator: gyro increments and camera fixes to pairs to an estimate.

Used by ``calibrator_node`` (live) and ``calibrate_bag`` (offline) alike, so both give the same
answer on the same data.  No ROS imports.

Feed it in any interleaving (stamps in seconds, any origin):

* :meth:`add_gyro` — increments Δθ with the stamps of the ends of their intervals;
* :meth:`add_camera` — a camera attitude q_GCRS_VF (scalar-first) with its 3×3 covariance
  (VF axes).

Known effects (:mod:`strapdown_ros.sensors.effects`) are compensated on the way in: the
systematic gyro effects of ``effects`` (bias, drift, scale, asymmetry, misalignment) on the
increments, and the camera's ``camera_time_offset`` (a fix stamped t belongs to t − offset) and
``camera_noise_scale`` (P → K P K) on the fixes.

A pair (n−1, n) is formed as soon as the gyro increment whose interval contains t_{E,n} has
arrived.  :meth:`solve` runs the estimator over all pairs, warm-started from the previous
solution, and returns a :class:`~strapdown_ros.calibration.boresight.BoresightSolution`
(which says whether the boresight is observable, and why not).
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, fields

import numpy as np

from strapdown_ros.calibration.boresight import BoresightSolution, solve_boresight
from strapdown_ros.calibration.boresight_increments import (angle_consistencies,
                                                            angle_consistency, camera_increment,
                                                            camera_increments, gyro_increment,
                                                            gyro_increments, IncrementPair)
from strapdown_ros.sensors import SensorSigmas
from strapdown_ros.sensors.covariance import get_covariance_model
from strapdown_ros.sensors.effects import CameraEffects, GyroEffects
from strapdown_ros.sensors.sensor_model import SensorModel
from strapdown_ros.streams.buffers import StampedBuffer

__all__ = ['BoresightCalibrator', 'CalibratorSettings']


@dataclass(frozen=True)
class CalibratorSettings:
    """
    What ``calibrator_node`` and ``calibrate_bag`` take besides the sensor model.

    The field names are the node's parameter names (:data:`strapdown_ros.params.CALIBRATOR_PARAMS`,
    where each is described).

    Attributes
    ----------
    weighted : bool
        Weight the pairs by E_imu and E_avu.
    covariance_model : str
        Gyro error model of E_imu.
    initial_boresight : tuple of float
        β0 of the solver, rad; all zero: the model's boresight.
    min_rotation_deg : float
        Smallest increment angle that counts as a rotation, degrees.
    max_sigma : float
        Largest predicted σ of a published direction, rad.
    max_pairs : int
        Keep at most this many latest pairs (0: all).
    outlier_gate : float
        Outlier-fix gate, σ (0: off).
    max_chi2_per_dof : float
        χ²/dof above which the fit is called inconsistent.
    use_camera_covariance : bool
        Read each fix's covariance (false: the model's camera σ).
    state_file : str
        Where the node persists its pairs ('' off).
    max_stamp_jump : float
        A stamp step beyond this is a jump, s.
    resync_count : int
        Consecutive messages that confirm a new timeline.
    frame_mismatch : str
        ``reject`` or ``accept`` a message in another frame.

    """

    weighted: bool = True
    covariance_model: str = 'random_constant'
    initial_boresight: tuple = (0.0, 0.0, 0.0)
    min_rotation_deg: float = 0.5
    max_sigma: float = 1e-3
    max_pairs: int = 0
    outlier_gate: float = 6.0
    max_chi2_per_dof: float = 3.0
    use_camera_covariance: bool = True
    state_file: str = ''
    max_stamp_jump: float = 1.0
    resync_count: int = 5
    frame_mismatch: str = 'reject'

    @classmethod
    def from_values(cls, values) -> CalibratorSettings:
        """
        Build the settings from parameter values (other names are not read).

        Parameters
        ----------
        values : mapping
            Parameter name → value (defaults where absent).

        Returns
        -------
        CalibratorSettings
            The settings.

        """
        out = {f.name: values[f.name] for f in fields(cls) if f.name in values}
        if 'initial_boresight' in out:
            out['initial_boresight'] = tuple(float(x) for x in out['initial_boresight'])
        return cls(**out)


class BoresightCalibrator:
    """
    The streaming boresight calibrator of ``calibrator_node`` and ``calibrate_bag``.

    Parameters
    ----------
    gyro : SensorSigmas, optional
        Gyro error sigmas (E_imu and the correlated weighting); None: no gyro covariance.
    covariance_model : str
        Gyro covariance model (:mod:`strapdown_ros.sensors.covariance`).
    weighted : bool
        Weight the pairs (else 004's unit weights).
    initial_boresight : (3,) array_like
        Start of the first solve with ``init='given'``, rad (the default start is the
        closed-form axis alignment).
    min_rotation : float
        Smallest rotation between exposures that counts for observability, rad.
    max_sigma : float
        Predicted σ above which a direction is unobservable, rad.
    max_pairs : int
        Keep at most this many latest pairs (0: all).
    effects : GyroEffects, optional
        Known gyro effects compensated on the increments.
    camera : CameraEffects, optional
        Camera time offset and noise scale applied to the fixes.
    outlier_gate : float
        Gate of the outlier-fix rule in σ (0: off).
    max_buffer : int, optional
        Bound of the gyro history, samples (default MAX_BUFFER).

    """

    def __init__(self, gyro: SensorSigmas | None = None,
                 covariance_model: str = 'random_constant', weighted: bool = True,
                 initial_boresight=(0.0, 0.0, 0.0), min_rotation: float = np.radians(0.5),
                 max_sigma: float = 1e-3, max_pairs: int = 0, effects: GyroEffects | None = None,
                 camera: CameraEffects | None = None, outlier_gate: float = 6.0,
                 max_buffer: int | None = None):
        self.outlier_gate = float(outlier_gate)
        self.outlier_fixes = 0                      # camera fixes dropped by the outlier rule
        self.outlier_stamps: deque = deque(maxlen=100)
        # normalised angle residuals of the latest pairs
        self._angle_ratios: deque = deque(maxlen=self.ROBUST_WINDOW)
        self._checks: deque = deque(maxlen=2)      # (pair, (d, σ)): the latest angle checks
        self._prev_fix = None                       # the fix before _last_fix (for the skip pair)
        self.effects = effects if effects is not None and effects.active else None
        self.camera = camera
        self._last_stamp = None
        self.gyro = gyro
        self.covariance_model = covariance_model
        self.weighted = weighted
        self.initial_boresight = np.asarray(initial_boresight, dtype=float)
        self.min_rotation = min_rotation
        self.max_sigma = max_sigma
        self.max_pairs = int(max_pairs)
        # gyro history: bounded, amortised O(1) appends, trimmed to what the next pairs need
        self._gyro = StampedBuffer(3, max_len=int(max_buffer or self.MAX_BUFFER))
        self._cams: deque = deque()     # fixes waiting for gyro coverage: (stamp, q, P)
        self._last_fix = None           # the fix that starts the next pair
        self.pairs: list[IncrementPair] = []
        self._pair_keys: set = set()    # (t_start, t_end), ns, of the pairs held
        self.replayed_pairs = 0         # pairs not added because a pair with their stamps is held
        self.solution: BoresightSolution | None = None

    @classmethod
    def from_model(cls, model: SensorModel,
                   settings: CalibratorSettings | None = None) -> 'BoresightCalibrator':
        """
        Build the calibrator of ``calibrator_node`` and ``calibrate_bag``.

        The model's gyro statistics weight the pairs, its gyro effects are compensated on the
        increments and its camera effects (time offset, noise scale) on the fixes; the solver
        starts at ``initial_boresight``, or at the model's boresight when that is all zero.

        Parameters
        ----------
        model : SensorModel
            The unit's sensor model.
        settings : CalibratorSettings, optional
            The calibrator's settings (default: the defaults).

        Returns
        -------
        BoresightCalibrator
            The calibrator.

        """
        s = settings or CalibratorSettings()
        start = np.asarray(s.initial_boresight, dtype=float)
        if not np.any(start):
            start = np.asarray(model.boresight, dtype=float)
        return cls(gyro=model.gyro, covariance_model=s.covariance_model,
                   weighted=bool(s.weighted), initial_boresight=start,
                   min_rotation=np.radians(float(s.min_rotation_deg)),
                   max_sigma=float(s.max_sigma), max_pairs=int(s.max_pairs),
                   effects=model.gyro_effects(), camera=model.camera_effects(),
                   outlier_gate=float(s.outlier_gate))

    # --- input -----------------------------------------------------------------------------
    def add_gyro(self, stamps, delta_theta) -> int:
        """
        Append gyro increments.

        Parameters
        ----------
        stamps : (n,) array_like
            End stamps of the increments, s, strictly increasing.
        delta_theta : (n, 3) array_like
            Increments, rad.

        Returns
        -------
        int
            The number of new pairs.

        """
        st = np.atleast_1d(np.asarray(stamps, dtype=float))
        v = np.asarray(delta_theta, dtype=float).reshape(-1, 3)
        if self.effects is not None and len(st):
            prev = self._last_stamp if self._last_stamp is not None else (
                st[0] - (st[1] - st[0]) if len(st) > 1 else st[0] - 0.01)
            v = self.effects.compensate(v, st, np.diff(np.concatenate([[prev], st])))
        if len(st):
            self._last_stamp = float(st[-1])
        self._gyro.extend(st, v)           # bounded by MAX_BUFFER: the oldest go first
        return self._form_pairs()

    def add_gyro_sample(self, stamp: float, delta_theta) -> int:
        """
        Append one increment (the live path of calibrator_node).

        The same as :meth:`add_gyro` with one sample, without its array conversions.

        Parameters
        ----------
        stamp : float
            End stamp of the increment, s.
        delta_theta : (3,) array_like
            The increment, rad.

        Returns
        -------
        int
            The number of new pairs.

        """
        if self.effects is not None:
            return self.add_gyro([stamp], [delta_theta])
        self._last_stamp = stamp
        self._gyro.append(stamp, delta_theta)
        return self._form_pairs() if self._cams else 0

    def restart_gyro(self) -> None:
        """
        Start a new gyro time base (a confirmed stamp jump).

        The buffered increments and the fix that would start the next pair are dropped, since
        no pair may span the jump.
        """
        self._gyro.clear()
        self._last_stamp = None
        self._last_fix = None
        self._cams.clear()

    def discard_new_pairs_over(self, new: int, gaps, margin: float) -> int:
        """
        Discard the latest pairs whose interval reaches a gyro gap (the node's rule).

        Parameters
        ----------
        new : int
            How many of the latest pairs to look at (those just formed).
        gaps : sequence of (float, float)
            Gyro gaps (start, end), s: the rotation in them is lost.
        margin : float
            A pair within this of a gap is discarded too (the in-interval polynomial reads the
            neighbours), s.

        Returns
        -------
        int
            Pairs discarded.

        """
        if not new or not gaps:
            return 0
        tail = self.pairs[len(self.pairs) - new:]
        keep = [pr for pr in tail
                if not any(pr.t_start - margin < b and a < pr.t_end + margin for a, b in gaps)]
        del self.pairs[len(self.pairs) - new:]
        self.pairs.extend(keep)
        return len(tail) - len(keep)

    def restart_camera(self) -> None:
        """Start a new camera time base: no pair may span the jump."""
        self._last_fix = None
        self._cams.clear()

    #: hard bound of the gyro history, samples (1e6 ≈ 24 MB: 8 min at 2 kHz, 2.8 h at 100 Hz
    #: between two fixes); beyond it the oldest are dropped and a pair that needed them is not
    #: formed
    MAX_BUFFER = 1_000_000

    def add_camera(self, stamp: float, q_gcrs_vf, covariance) -> int:
        """
        Append one camera fix.

        With camera effects the fix is placed at its IMU-clock epoch and its covariance
        corrected.

        Parameters
        ----------
        stamp : float
            Stamp of the fix, s.
        q_gcrs_vf : (4,) array_like
            Camera attitude q_GCRS_VF, scalar first.
        covariance : (3, 3) array_like
            Its covariance, VF axes, rad².

        Returns
        -------
        int
            The number of new pairs.

        """
        P = np.asarray(covariance, dtype=float)
        if self.camera is not None:
            stamp, P = self.camera.epoch(float(stamp)), self.camera.covariance(P)
        self._cams.append((float(stamp), np.asarray(q_gcrs_vf, dtype=float), P))
        return self._form_pairs()

    def add_cameras(self, stamps, q_gcrs_vf, covariance) -> int:
        """
        Append many camera fixes at once (offline: ``calibrate_bag``), in stamp order.

        The same as :meth:`add_camera` for each fix in turn — the same pairs, outlier rule,
        replay rule and gyro trimming — with the increments of consecutive fixes computed for
        all of them together (:func:`~.boresight_increments.gyro_increments`), so the cost per
        fix is a few scalar operations, not a pass of numpy calls.

        Parameters
        ----------
        stamps : (m,) array_like
            Stamps of the fixes, s, ascending.
        q_gcrs_vf : (m, 4) array_like
            Camera attitudes, scalar first.
        covariance : (m, 3, 3) array_like
            Their covariances, VF axes, rad².

        Returns
        -------
        int
            The number of new pairs.

        """
        st = np.atleast_1d(np.asarray(stamps, dtype=float))
        q = np.asarray(q_gcrs_vf, dtype=float).reshape(-1, 4)
        P = np.asarray(covariance, dtype=float).reshape(-1, 3, 3)
        if self.camera is not None:
            st, P = self.camera.epoch(st), self.camera.covariance(P)
        for k in range(len(st)):
            self._cams.append((float(st[k]), q[k], P[k]))
        return self._form_pairs_batch()

    def _form_pairs_batch(self) -> int:
        """Form the pairs of every waiting fix the gyro covers (the rule of _form_pairs)."""
        last = self._gyro.last_stamp
        ready = []
        while self._cams and (self._last_fix is None or (last is not None
                                                         and last >= self._cams[0][0])):
            if self._last_fix is None:
                self._last_fix = self._cams.popleft()
                continue
            ready.append(self._cams.popleft())
        if not ready:
            return 0
        starts = [self._last_fix] + ready[:-1]
        pre, checks = self._pairs_between(starts, ready)
        new = 0
        for k, fix in enumerate(ready):
            if self._last_fix is starts[k]:
                pair, check = pre[k], checks[k]         # consecutive fixes: computed above
            else:
                pair = self._pair(self._last_fix, fix)  # after an outlier: its own pair
                check = angle_consistency(pair) if pair is not None else None
            if pair is None:
                self._prev_fix, self._last_fix = None, fix
                continue
            key = self.pair_key(pair)
            if key in self._pair_keys:
                self.replayed_pairs += 1
                self._prev_fix, self._last_fix = None, fix
                continue
            self._pair_keys.add(key)
            self._append(pair, check)
            new += 1
            self._drop_outlier_fix(fix)
            self._prev_fix, self._last_fix = self._last_fix, fix
        keep = self._prev_fix[0] if self._prev_fix is not None else ready[-1][0]
        self._gyro.drop_first(int(np.searchsorted(self._gyro.stamps, keep)) - 3)
        if self.max_pairs and len(self.pairs) > self.max_pairs:
            del self.pairs[:len(self.pairs) - self.max_pairs]
        if len(self._pair_keys) > 2 * len(self.pairs) + 1000:
            self._pair_keys = {self.pair_key(pr) for pr in self.pairs}
        return new

    def _pairs_between(self, starts, ends) -> list:
        """Return the pairs (start k, end k) for all k at once (None where not covered)."""
        t0 = np.array([f[0] for f in starts])
        t1 = np.array([f[0] for f in ends])
        valid, dq, cov, G, white = gyro_increments(self._gyro.stamps, self._gyro.values, t0, t1,
                                                   self.gyro, self.covariance_model)
        q0 = np.array([f[1] for f in starts])
        q1 = np.array([f[1] for f in ends])
        P0 = np.array([f[2] for f in starts])
        P1 = np.array([f[2] for f in ends])
        dq_c, E_c = camera_increments(q0, P0, q1, P1)
        d, sig = angle_consistencies(dq_c, E_c, np.where(valid[:, None], dq, 1.0), cov)
        out = []
        for k in range(len(ends)):
            if not valid[k]:
                out.append(None)
                continue
            extra = {}
            if self.gyro is not None:
                extra = {'imu_sensitivity': G[k], 'cov_imu_white': white[k]}
            out.append(IncrementPair(float(t0[k]), float(t1[k]), dq[k], dq_c[k], cov[k], E_c[k],
                                     cov_fix_start=P0[k], cov_fix_end=P1[k], **extra))
        return out, list(zip(d.tolist(), sig.tolist()))

    def _append(self, pair, check=None, residual: bool = True) -> None:
        """Hold a new pair, its angle check (d, σ) and (a new residual) its normalised angle."""
        d, sig = angle_consistency(pair) if check is None else check
        self.pairs.append(pair)
        self._checks.append((pair, (d, sig)))
        if residual:
            self._angle_ratios.append(d / sig if sig > 0 else 0.0)

    def _check_of(self, pair) -> tuple[float, float]:
        """Return the angle check of a held pair (kept for the latest ones)."""
        for held, check in self._checks:
            if held is pair:
                return check
        return angle_consistency(pair)

    def _pair(self, fix_a, fix_b):
        """Return the increment pair between two fixes, or None without gyro data around them."""
        t0, q0, P0 = fix_a
        stamp, q, P = fix_b
        t = self._gyro.stamps
        lo = max(0, int(np.searchsorted(t, t0)) - 2)
        hi = int(np.searchsorted(t, stamp, side='right')) + 1
        r = gyro_increment(t[lo:hi], self._gyro.values[lo:hi], t0, stamp, self.gyro,
                           self.covariance_model, sensitivity=self.gyro is not None)
        if r is None:
            return None
        dq_c, E_c = camera_increment(q0, P0, q, P)
        extra = {}
        if self.gyro is not None:
            extra = {'imu_sensitivity': r[2], 'cov_imu_white': r[3]}
        return IncrementPair(t0, stamp, r[0], dq_c, r[1], E_c, cov_fix_start=P0, cov_fix_end=P,
                             **extra)

    #: the robust scale of the outlier gate is taken over at most this many of the latest pairs
    ROBUST_WINDOW = 200
    #: ... and only once this many pairs exist: before, the scatter is unknown and no fix is gated
    ROBUST_MIN_PAIRS = 5

    def angle_scale(self) -> float:
        """
        Return the robust scale s of the normalised angle residuals of the latest pairs.

        r = (φ_avu − φ_imu)/σ; s = 1.4826 · median |r − median r| (the MAD, σ for Gaussian r),
        at least 1.  With the stated noise right, s ≈ 1; with the camera σ stated 100× too
        small, s ≈ 100.  inf (no gate) with fewer than ``ROBUST_MIN_PAIRS`` pairs.
        """
        r = np.asarray(self._angle_ratios, dtype=float)
        if len(r) < self.ROBUST_MIN_PAIRS:
            return float('inf')
        return max(1.0, 1.4826 * float(np.median(np.abs(r - np.median(r)))))

    def _inconsistent(self, pair, scale: float = 1.0) -> bool:
        d, sigma = angle_consistency(pair)
        return abs(d) > self.outlier_gate * scale * sigma

    def _form_pairs(self) -> int:
        new = 0
        while self._cams:
            stamp, q, P = self._cams[0]
            if self._last_fix is None:
                self._last_fix = self._cams.popleft()
                continue
            last = self._gyro.last_stamp
            if last is None or last < stamp:
                break                                   # wait for the gyro to cover t_E,n
            pair = self._pair(self._last_fix, (stamp, q, P))
            fix = self._cams.popleft()
            if pair is None:               # not enough gyro data around t0: skip this pair
                self._prev_fix, self._last_fix = None, fix
                continue
            key = self.pair_key(pair)
            if key in self._pair_keys:                  # the same stamps again (a replay)
                self.replayed_pairs += 1
                self._prev_fix, self._last_fix = None, fix
                continue
            self._pair_keys.add(key)
            self._append(pair)
            new += 1
            # the last pair may become the skip pair: still new
            self._drop_outlier_fix(fix)
            self._prev_fix, self._last_fix = self._last_fix, fix
            # drop gyro data no longer needed (a margin before the fix that may start a skip pair)
            keep = self._prev_fix[0] if self._prev_fix is not None else stamp
            self._gyro.drop_first(int(np.searchsorted(self._gyro.stamps, keep)) - 3)
        if self.max_pairs and len(self.pairs) > self.max_pairs:
            del self.pairs[:len(self.pairs) - self.max_pairs]
        if len(self._pair_keys) > 2 * len(self.pairs) + 1000:    # bounded: the keys of pairs held
            self._pair_keys = {self.pair_key(pr) for pr in self.pairs}
        return new

    # --- identity of pairs and the fix chain (the state file) -----------------------------------
    @staticmethod
    def pair_key(pair: IncrementPair) -> tuple[int, int]:
        """
        Return (t_start, t_end) of a pair in integer ns: its identity across restarts.

        Parameters
        ----------
        pair : IncrementPair
            The pair.

        Returns
        -------
        tuple of int
            The key.

        """
        return int(round(pair.t_start * 1e9)), int(round(pair.t_end * 1e9))

    def add_pair_keys(self, pairs) -> None:
        """
        Hold the keys of pairs restored from a state file: those stamps are not paired again.

        Parameters
        ----------
        pairs : iterable of IncrementPair
            The restored pairs.

        """
        self._pair_keys.update(self.pair_key(pr) for pr in pairs)

    @property
    def gyro_history(self):
        """Return the bounded gyro history (a :class:`~.streams.buffers.StampedBuffer`)."""
        return self._gyro

    @property
    def gyro_history_overflowed(self) -> bool:
        """Return whether the bounded gyro history has dropped its oldest increments."""
        return bool(self._gyro.overflowed)

    @property
    def last_fix(self):
        """Return (stamp s, q_GCRS_VF, P) of the fix that starts the next pair, or None."""
        return self._last_fix

    def restore_last_fix(self, stamp: float, q_gcrs_vf, covariance) -> None:
        """
        Resume the fix chain from a stored fix (the state file).

        Parameters
        ----------
        stamp : float
            Stamp of the fix, s.
        q_gcrs_vf : (4,) array_like
            Camera attitude, scalar first.
        covariance : (3, 3) array_like
            Its covariance, VF axes, rad².

        """
        self._last_fix = (float(stamp), np.asarray(q_gcrs_vf, dtype=float),
                          np.asarray(covariance, dtype=float))
        self._prev_fix = None

    def _drop_outlier_fix(self, fix) -> int:
        """
        Apply the outlier rule to fix n (= _last_fix); return 1 when it was dropped, else 0.

        Fix n is an outlier when both its pairs, (n−1, n) and
        (n, n+1), disagree in rotation angle by more than the gate while the pair (n−1, n+1)
        that skips it agrees.  The gate is ``outlier_gate`` × max(1, s) × the stated σ of the
        angle difference, s the robust scale of the normalised angle residuals of the latest
        pairs (:meth:`angle_scale`): when the stated noise is right s ≈ 1 and the gate is
        ``outlier_gate`` σ; when the stated σ is too small by a factor s, the gate widens by s,
        so a wrong σ never turns good fixes into outliers while a fix off by far more than the
        actual scatter is still gated.  Then both pairs give way to the skip pair (the newest
        pair in the list).
        """
        if self.outlier_gate <= 0 or self._prev_fix is None or len(self.pairs) < 2:
            return 0
        a, b = self.pairs[-2], self.pairs[-1]
        if not (a.t_end == b.t_start == self._last_fix[0] and a.t_start == self._prev_fix[0]):
            return 0
        if not all(abs(d) > self.outlier_gate * sig
                   for d, sig in (self._check_of(a), self._check_of(b))):
            return 0                     # consistent at the narrowest gate (scale ≥ 1): no outlier
        scale = self.angle_scale()
        if not np.isfinite(scale):
            return 0                                    # too few pairs to know the scatter
        if not (self._inconsistent(a, scale) and self._inconsistent(b, scale)):
            return 0
        skip = self._pair(self._prev_fix, fix)
        if skip is None or self._inconsistent(skip, scale):
            return 0                     # not one bad fix: leave it to the estimator
        del self.pairs[-2:]
        self._append(skip, residual=False)
        self._pair_keys.add(self.pair_key(skip))
        self.outlier_fixes += 1
        self.outlier_stamps.append(self._last_fix[0])
        self._last_fix = self._prev_fix                 # the bad fix never starts a pair
        return 1

    # --- estimate ------------------------------------------------------------------------------
    def solve(self) -> BoresightSolution:
        """
        Estimate the boresight from all pairs.

        Warm start: once a converged solution exists, Gauss–Newton starts from it (the
        closed-form axis alignment is only needed the first time).

        Returns
        -------
        BoresightSolution
            The estimate, or why there is none.

        """
        prev = self.solution
        if prev is not None and prev.observable and prev.converged:
            sol = solve_boresight(self.pairs, beta0=prev.beta, init='given',
                                  **self._solver_options())
            if not (sol.observable and sol.converged):
                sol = self._cold()
        else:
            sol = self._cold()
        self.solution = sol
        return sol

    def _cold(self) -> BoresightSolution:
        return solve_boresight(self.pairs, beta0=self.initial_boresight, init='axes',
                               **self._solver_options())

    def _solver_options(self) -> dict:
        """
        Return the options of ``solve_boresight``.

        Weighting: unit when ``weighted`` is off; with the random-constant gyro model the
        correlated solution (shared fixes, common gyro constants; banded, O(n), at any number
        of pairs); with 004's white model pairwise weights.
        """
        if not self.weighted:
            weighting = 'unit'
        elif get_covariance_model(self.covariance_model).constants and self.gyro is not None:
            weighting = 'auto'
        else:
            weighting = 'pairwise'
        return {'weighting': weighting, 'gyro': self.gyro, 'max_sigma': self.max_sigma,
                'min_rotation': self.min_rotation,
                'common_rotation_sigma': self.common_rotation_sigma}

    @property
    def common_rotation_sigma(self) -> float:
        """Return σ per axis of the gyro-triad rotation (antisymmetric misalignment), σ_φ/√2."""
        return self.gyro.misalignment_sigma / np.sqrt(2.0) if self.gyro is not None else 0.0
