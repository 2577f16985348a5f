"""
The SINS core of ``sins_node`` and ``sins_bag``: from raw increments to published numbers.

:class:`SinsCore` takes the unit's sensor model
(:class:`~strapdown_ros.sensors.sensor_model.SensorModel`), its own :class:`SinsSettings` and the
raw stream of ``imu/delta_theta`` and
``imu/delta_velocity`` values (header stamp in integer nanoseconds, the vector, the header
frame id) and owns everything between them and the published numbers:

* input validation: the frame rule (``frame_id``/``frame_mismatch``) and the stream rules of
  :class:`strapdown_ros.streams.checks.StreamCheck`, one per stream;
* the blocks: increments are integrated in blocks covering ``batch_period`` of stamp time (or
  :data:`MAX_BATCH` messages); :meth:`SinsCore.offer_gyro` / :meth:`~SinsCore.offer_accel`
  say when a block is due, :meth:`SinsCore.process` integrates it;
* the :class:`~strapdown_ros.attitude.integrator.AttitudeIntegrator`, the compensation of the
  gyro effects of the parameters (:class:`~strapdown_ros.sensors.effects.GyroEffects`), the
  non-finite rule (an update whose attitude or covariance is not finite is never output: the
  block is redone sample by sample from the state before it, the offending update is dropped
  and the state returns to the last good update with :data:`NONFINITE_INFLATION` rad added to
  its σ);
* the accelerometer accumulator of ``sins/imu`` (mean specific force over each update, which
  waits up to ``accel_wait`` stamp seconds for the accelerometer data);
* the :class:`~strapdown_ros.navigation.channel.NavigationChannel` (parameter ``navigation``)
  with its start: the given attitude, or the static alignment, after which the integrator
  restarts from the aligned attitude.

The outputs are those of :mod:`strapdown_ros.sins.outputs`; the input of a whole recording
is added by :class:`strapdown_ros.sins.system.SinsSystem`.  Processing the same messages in
the same order gives the same numbers, whoever calls it.  No ROS imports.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, fields
import math
import time
from typing import Callable

import numpy as np

from strapdown_ros.attitude import kernel as attitude_kernel
from strapdown_ros.attitude.increment_sums import IncrementAccumulator
from strapdown_ros.attitude.integrator import AttitudeIntegrator
from strapdown_ros.navigation import recursion as nav_recursion
from strapdown_ros.navigation.channel import NavigationChannel, NavigationSettings
from strapdown_ros.rotation import dcm_to_quat, from_ros_xyzw
from strapdown_ros.sensors.sensor_model import SensorModel
from strapdown_ros.sins.outputs import (accel_stall_limits, AccelStall, AttitudeOutput,
                                        ImuOutput, NavigationOutput, NO_OUTPUT, SinsOutput)
from strapdown_ros.streams.checks import StreamCheck
from strapdown_ros.text import bounded

#: rad per axis added to σ after a non-finite update is discarded
NONFINITE_INFLATION = 0.01
#: a block is processed when it holds this many messages, whatever its span
MAX_BATCH = 4096
#: Δθ per block of a whole recording (feed)
FEED_BLOCK = 16384
#: Δv per block of a whole recording (below the accumulator's bound)
FEED_ACCEL_BLOCK = 32768


def _finite_update(q: np.ndarray, cov: np.ndarray) -> bool:
    """Tell whether one update's attitude and covariance are finite (scalar reads: cheap)."""
    return math.isfinite(q[0] + q[1] + q[2] + q[3] + cov[0, 0] + cov[0, 1] + cov[0, 2]
                         + cov[1, 1] + cov[1, 2] + cov[2, 2])


@dataclass(frozen=True)
class SinsSettings:
    """
    What ``sins_node`` and ``sins_bag`` take besides the sensor model.

    The field names are the node's parameter names (:data:`strapdown_ros.params.SINS_PARAMS`,
    where each is described).

    Attributes
    ----------
    coning_algorithm : str
        The coning algorithm at the start (it may change later: the integrator holds it).
    initial_orientation : tuple of float
        q_ref_body as ROS x, y, z, w.
    initial_attitude_sigma : float
        1σ initial attitude error per axis, rad.
    covariance_model : str
        Gyro error model of the covariance.
    quantization_correction : bool
        Apply 000 eq. (5.6) with the model's gyro_quantum.
    accel_wait : float
        How long sins/imu waits for accelerometer data, stamp s.
    navigation : bool
        Run the navigation channel.
    navigation_settings : NavigationSettings
        Its settings.
    earth_frame_id : str
        Frame id of sins/odometry.
    batch_period : float
        Stamp time of a block, s.
    max_stamp_jump : float
        A stamp step beyond this is a jump, s.
    resync_count : int
        Consecutive messages that confirm a new timeline.
    frame_mismatch : str
        ``reject`` or ``accept`` a message in another frame.

    """

    coning_algorithm: str = '2'
    initial_orientation: tuple = (0.0, 0.0, 0.0, 1.0)
    initial_attitude_sigma: float = 0.0
    covariance_model: str = 'random_constant'
    quantization_correction: bool = False
    accel_wait: float = 0.1
    navigation: bool = False
    navigation_settings: NavigationSettings = NavigationSettings()
    earth_frame_id: str = 'earth'
    batch_period: float = 0.01
    max_stamp_jump: float = 1.0
    resync_count: int = 5
    frame_mismatch: str = 'reject'

    @classmethod
    def from_values(cls, values) -> SinsSettings:
        """
        Build the settings from parameter values (other names are not read).

        Parameters
        ----------
        values : mapping
            Parameter name → value (defaults where absent).

        Returns
        -------
        SinsSettings
            The settings.

        """
        out = {f.name: values[f.name] for f in fields(cls) if f.name in values}
        if 'initial_orientation' in out:
            out['initial_orientation'] = tuple(float(x) for x in out['initial_orientation'])
        return cls(**out, navigation_settings=NavigationSettings.from_values(values))


# --- the system ---------------------------------------------------------------------------------
class SinsCore:
    """
    The processing of ``sins_node``: input rules, blocks, integration and navigation.

    Feeding: :meth:`offer_gyro` / :meth:`offer_accel` for every message, in arrival order; when
    one returns True a block is due: call :meth:`process`, which integrates what is buffered and
    returns everything produced since the last call (:class:`SinsOutput`).  :meth:`process` may
    also be called at any other time (the node's wall-clock timer does).  :attr:`has_output`
    tells that outputs are waiting without a block being due (a stamp resynchronisation
    processed the old time base).  :meth:`finish` (end of a recording) releases the outputs
    still waiting for accelerometer data, as ``accel_wait`` would.

    Attributes used by the whole-recording input (:class:`~strapdown_ros.sins.system.
    SinsSystem`): ``own_frames`` (the frame ids taken as the body frame), ``gyro_period_ns`` and
    ``batch_span_ns`` (the nominal gyro period and ``batch_period``, ns), ``gyro_blocks`` and
    ``accel_blocks`` (screened arrays waiting for :meth:`process`: Δθ as (stamps_ns, values),
    Δv as (t s from the origin, values)).

    Parameters
    ----------
    model : SensorModel
        The unit's sensor model: rates, clip levels, frame, the gyro statistics of the
        covariance and the gyro effects compensated per increment.
    settings : SinsSettings, optional
        The SINS's own settings (default: the defaults).
    log : callable(level, text), optional
        Where messages go (level ``info``, ``warn`` or ``error``; repeated warnings are
        throttled here).  None: messages are dropped.
    imu_wanted : callable() -> bool, optional
        Asked once per block whether ``sins/imu`` records are wanted (False: none are made and
        the accelerometer data only feed the navigation).  None: always wanted.

    Raises
    ------
    ValueError
        ``initial_orientation`` is the zero quaternion.

    """

    def __init__(self, model: SensorModel, settings: SinsSettings | None = None,
                 log: Callable[[str, str], None] | None = None,
                 imu_wanted: Callable[[], bool] | None = None):
        if isinstance(model, dict):
            raise TypeError('SinsCore takes a SensorModel and SinsSettings '
                            '(strapdown_ros.params.load_model_file), not a parameter dict')
        s = self.settings = settings or SinsSettings()
        self.model = model
        q0_xyzw = np.asarray(s.initial_orientation, dtype=float)
        if np.linalg.norm(q0_xyzw) < 1e-6:
            raise ValueError('initial_orientation must not be the zero quaternion')
        self.initial_normalised = abs(np.linalg.norm(q0_xyzw) - 1.0) > 1e-6
        period = model.gyro_period
        self.integrator = AttitudeIntegrator(
            s.coning_algorithm, initial_attitude=from_ros_xyzw(q0_xyzw), nominal_period=period,
            gyro=model.gyro, initial_sigma=float(s.initial_attitude_sigma),
            covariance_model=s.covariance_model,
            quantization_correction=bool(s.quantization_correction))
        # known systematic gyro effects of the model (sensors.effects), compensated per increment
        self.gyro_effects = model.gyro_effects()
        self.compensating = self.gyro_effects.names()
        self._last_gyro_t: float | None = None
        jump, resync = float(s.max_stamp_jump), int(s.resync_count)
        self.gyro_check = StreamCheck(period, max_norm=2.0 * period * model.gyro_max_rate,
                                      jump_limit=jump,
                                      resync_count=resync)
        a_period = 1.0 / model.accel_rate
        self.accel_check = StreamCheck(a_period, max_norm=2.0 * a_period * model.accel_max,
                                       jump_limit=jump,
                                       resync_count=resync)
        # updates whose output was not finite (never output)
        self.nonfinite = 0
        self.rate_checks: dict = {}                # sensor_msgs/Imu rate samples (screen_imu)
        self.frame_mismatch = {'gyro': 0, 'accel': 0}
        self.frame_id = model.frame_id
        self.reject_frames = s.frame_mismatch == 'reject'
        self.own_frames = ('', self.frame_id)
        self._good = self.integrator.snapshot()
        self.accel = IncrementAccumulator()
        self.accel_seen = False
        self.origin_ns: int | None = None          # stamps are handled relative to the first one
        self.pending_imu: deque = deque()          # updates waiting for accelerometer data
        # input blocks (offer_*: validate and append; process() does the numerical work)
        self._gyro_in: list = []                   # (stamp_ns, (x, y, z))
        self._accel_in: list = []                  # (t, (x, y, z))
        self.gyro_blocks: list = []               # screened arrays (feed): (stamps_ns, values)
        self.accel_blocks: list = []              # (t, values)
        self.batch_span = float(s.batch_period)
        self._gyro_period = period
        self._block_end_ns: int | None = None      # stamp of the last sample processed
        self.batch_span_ns = int(round(self.batch_span * 1e9))
        self.gyro_period_ns = int(round(period * 1e9))
        g = self.integrator.gyro.random_walk ** 2 / max(period, 1e-12)
        # per axis, (rad/s)², of the mean rate of sins/imu
        self.rate_variance = g
        # (m/s²)²
        self.accel_variance = model.accel.random_walk ** 2 * model.accel_rate
        self._log_fn = log
        self._imu_wanted = imu_wanted or (lambda: True)
        self._throttle: dict[str, float] = {}
        self._out: tuple[list, list, list] = ([], [], [])
        self.has_output = False
        attitude_kernel.warm_up()      # compiled before the first message, if numba is there
        self.nav: NavigationChannel | None = None
        if s.navigation:
            self.nav = NavigationChannel(s.navigation_settings, model.gyro, model.accel,
                                         period, a_period,
                                         self.integrator.algorithm.samples)
            nav_recursion.warm_up()
            self._nav_prev_q = self.integrator.q.copy()

    # --- messages -----------------------------------------------------------------------------
    def emit(self, level: str, text, throttle: float = 0.0, key: str | None = None) -> None:
        """
        Emit ``text`` to the log at most once per ``throttle`` seconds per ``key``.

        Parameters
        ----------
        level : {'info', 'warn', 'error'}
            The level.
        text : str or callable() -> str
            The message, or what makes it (built only when emitted).
        throttle : float
            Least wall seconds between two emissions of ``key`` (0: every time).
        key : str, optional
            What the throttle counts (None: ``text``).

        """
        if self._log_fn is None:
            return
        if throttle > 0:
            now = time.monotonic()
            k = key or text
            if now - self._throttle.get(k, -np.inf) < throttle:
                return
            self._throttle[k] = now
        self._log_fn(level, text() if callable(text) else text)

    # --- input --------------------------------------------------------------------------------
    def frame_text(self, stream: str, frame_id: str, count: int = 1) -> str:
        """
        Return the frame-mismatch warning, frame ids bounded.

        Parameters
        ----------
        stream : {'gyro', 'accel'}
            The stream.
        frame_id : str
            The foreign frame id.
        count : int
            How many messages had it.

        Returns
        -------
        str
            One line.

        """
        many = f'{count} {stream} messages' if count > 1 else f'{stream} message'
        return (f'{many} in frame {bounded(frame_id)!r}, expected {bounded(self.frame_id)!r}: '
                f"{'rejected' if self.reject_frames else 'used'}")

    def _rel(self, stamp_ns: int) -> float:
        if self.origin_ns is None:
            self.origin_ns = stamp_ns
        return (stamp_ns - self.origin_ns) * 1e-9

    def _wrong_frame(self, frame_id: str, stream: str) -> bool:
        """
        Apply the frame rule; True when the message is rejected.

        The frame rule: an empty frame_id is unspecified; another frame than ``frame_id`` is
        counted and WARNed, and rejected unless ``frame_mismatch`` is accept.
        """
        self.frame_mismatch[stream] += 1
        self.emit('warn', lambda: self.frame_text(stream, frame_id), throttle=10.0,
                  key='frame_' + stream)
        return self.reject_frames

    def frame_accepted(self, frame_id: str, stream: str = 'gyro') -> bool:
        """
        Apply the frame rule alone, for input checked before :meth:`offer_gyro`.

        Used for a ``sensor_msgs/Imu`` rate sample, before it is made into increments.

        Parameters
        ----------
        frame_id : str
            The message's header.frame_id.
        stream : {'gyro', 'accel'}
            The counter a foreign frame is counted under.

        Returns
        -------
        bool
            True when ``frame_id`` is empty or the body frame, or another frame that is counted and
            accepted (``frame_mismatch`` accept).

        """
        return frame_id in self.own_frames or not self._wrong_frame(frame_id, stream)

    def offer_gyro(self, stamp_ns: int, value, frame_id: str = '') -> bool:
        """
        Validate and append one imu/delta_theta message.

        Parameters
        ----------
        stamp_ns : int
            Header stamp, ns.
        value : sequence of float
            Δθ, rad, body axes.
        frame_id : str
            The message's header.frame_id.

        Returns
        -------
        bool
            True when a block is due (call :meth:`process`).

        """
        if frame_id not in self.own_frames and self._wrong_frame(frame_id, 'gyro'):
            return False
        out = self.gyro_check.offer(stamp_ns, value)
        if not out:
            return False
        if self.gyro_check.resynced:
            self._run()                                    # the old time base, first
            self.integrator.restart_clock()
            self._last_gyro_t = None
            self._block_end_ns = None
            self.origin_ns = None
            self.emit('error', f'gyro stamps jumped by {self.gyro_check.last_jump_s:.6g} s and '
                      'stayed: resynchronised to the new time base; the rotation during the jump '
                      'is lost')
        if self.origin_ns is None:
            self.origin_ns = out[0][0]
        self._gyro_in += out                               # (stamp_ns, (x, y, z)); times in _run
        # the stamp time the block covers, from the end of the previous block (at 100 Hz with
        # batch_period 0.01 every message is processed at once; at 1 kHz, blocks of 10), whatever
        # gyro_rate says
        start = (self._block_end_ns if self._block_end_ns is not None
                 else self._gyro_in[0][0] - self.gyro_period_ns)
        return (self._gyro_in[-1][0] - start >= self.batch_span_ns - 1
                or len(self._gyro_in) >= MAX_BATCH)

    def offer_accel(self, stamp_ns: int, value, frame_id: str = '') -> bool:
        """
        Validate and append one imu/delta_velocity message.

        Parameters
        ----------
        stamp_ns : int
            Header stamp, ns.
        value : sequence of float
            Δv, m/s, body axes.
        frame_id : str
            The message's header.frame_id.

        Returns
        -------
        bool
            True when a block is due (call :meth:`process`).

        """
        if frame_id not in self.own_frames and self._wrong_frame(frame_id, 'accel'):
            return False
        out = self.accel_check.offer(stamp_ns, value)
        if not out:
            return False
        if self.accel_check.resynced:
            self._accel_in.clear()
            self.accel = IncrementAccumulator()           # the old time base is gone
        self.accel_seen = True
        for ns_i, val in out:
            self._accel_in.append((self._rel(ns_i), val))
        return len(self._accel_in) >= MAX_BATCH or self.batch_span == 0.0

    @property
    def processed_until_ns(self) -> int | None:
        """Header stamp (ns) of the last Δθ integrated (None before the first block)."""
        return self._block_end_ns

    # --- a whole recording at once -------------------------------------------------------------
    def set_algorithm(self, name: str) -> bool:
        """
        Switch the coning algorithm at runtime (attitude only).

        The increments buffered so far are integrated with the old algorithm first.

        Parameters
        ----------
        name : str
            A name of :data:`strapdown_ros.attitude.coning.ALGORITHMS`.

        Returns
        -------
        bool
            True when it changed.

        Raises
        ------
        ValueError
            While the navigation channel runs.

        """
        if name == self.integrator.algorithm_name:
            return False
        if self.nav is not None:
            raise ValueError('the coning algorithm cannot change while navigation runs')
        if self._gyro_in or self._accel_in or self.gyro_blocks or self.accel_blocks:
            self._run()
        self.integrator.set_algorithm(name)
        return True

    # --- processing ---------------------------------------------------------------------------
    def process(self) -> SinsOutput:
        """
        Integrate the buffered increments as one block.

        Integrate the buffered increments as one block through the vectorised core; returns
        every output produced since the last call.  The result equals message-by-message
        processing to round-off
        (test/ros/test_nodes.py::test_sins_node_batches_equal_per_message_processing).
        """
        self._run()
        return self.take_output()

    def finish(self) -> SinsOutput:
        """
        Integrate what is buffered and release every waiting update (end of the data).

        End of the data: integrate what is buffered and release the updates still waiting for
        accelerometer data, as ``accel_wait`` would once the stream had gone on (sins/imu without
        specific force where none covered the update; navigation steps with the accelerometer
        data extrapolated).
        """
        self._run()
        self._flush_imu(final=True)
        self._flush_nav(final=True)
        return self.take_output()

    def take_output(self) -> SinsOutput:
        """
        Return the outputs produced since the last call, and forget them.

        Returns
        -------
        SinsOutput
            Attitude updates, sins/imu records and navigation steps, in stamp order per stream.

        """
        if not self.has_output:
            return NO_OUTPUT
        att, imu, nav = self._out
        out = SinsOutput(AttitudeOutput.concat(att), ImuOutput.concat(imu),
                         NavigationOutput.concat(nav))
        self._out = ([], [], [])
        self.has_output = False
        return out

    def _take_accel(self):
        """Take the buffered Δv as arrays; the buffer is emptied."""
        if self._accel_in:
            n = len(self._accel_in)
            self.accel_blocks.append((np.fromiter((a[0] for a in self._accel_in), float, n),
                                      np.array([a[1] for a in self._accel_in], dtype=float)))
            self._accel_in.clear()
        blocks, self.accel_blocks = self.accel_blocks, []
        if len(blocks) == 1:
            return blocks[0]
        return np.concatenate([b[0] for b in blocks]), np.concatenate([b[1] for b in blocks])

    def _take_gyro(self):
        """Take the buffered Δθ as arrays; the buffer is emptied."""
        if self._gyro_in:
            n = len(self._gyro_in)
            self.gyro_blocks.append((np.fromiter((g[0] for g in self._gyro_in), np.int64, n),
                                     np.array([g[1] for g in self._gyro_in], dtype=float)))
            self._gyro_in = []
        blocks, self.gyro_blocks = self.gyro_blocks, []
        if len(blocks) == 1:
            return blocks[0]
        return np.concatenate([b[0] for b in blocks]), np.concatenate([b[1] for b in blocks])

    def _run(self) -> None:
        if self._accel_in or self.accel_blocks:
            t, dv = self._take_accel()
            self.accel.add(dv, t)
            if self.nav is not None:
                self.nav.add_accel(dv, t)
        if self._gyro_in or self.gyro_blocks:
            stamps_ns, inc = self._take_gyro()
            self._block_end_ns = int(stamps_ns[-1])
            t = (stamps_ns - self.origin_ns) * 1e-9          # as (s - origin) * 1e-9 per message
            if self.nav is not None and self._navigation_start(inc, t):
                self._flush_imu()
                return
            before = self.integrator.checkpoint()
            last_t = self._last_gyro_t
            if not self._integrate(inc, t, stamps_ns):
                # a non-finite update inside the block: redo it sample by sample, from the state
                # before it, so that exactly the offending update is discarded
                self.integrator.rollback(before)
                self._last_gyro_t = last_t
                for k in range(len(t)):
                    self._integrate(inc[k:k + 1], t[k:k + 1], stamps_ns[k:k + 1], per_sample=True)
        self._flush_imu()
        self._flush_nav()

    def _navigation_start(self, inc: np.ndarray, t: np.ndarray) -> bool:
        """Before navigation runs: True when the block was consumed by the static alignment."""
        nav = self.nav
        if nav.navigator is not None:
            return False
        if nav.mode == 'given':
            nav.start(float(t[0]) - self.integrator.nominal_period,
                      attitude_sigma=float(self.settings.initial_attitude_sigma))
            return False
        periods = np.full(len(t), self.integrator.nominal_period)
        comp = self.gyro_effects.compensate(inc, t, periods) if self.compensating else inc
        nav.align_gyro(comp, t)
        done, c_e_b, t_end = nav.try_align()
        if nav.alignment is not None and not nav.alignment.ok:
            self.emit('error', f'static alignment refused: {nav.alignment.reason}; trying again',
                      throttle=5.0, key='alignment')
        if done:
            sigma = float(np.sqrt(np.trace(nav.alignment.covariance) / 3.0))
            self.integrator = AttitudeIntegrator(
                self.integrator.algorithm_name, initial_attitude=dcm_to_quat(c_e_b),
                initial_time=t_end, nominal_period=self.integrator.nominal_period,
                gyro=self.model.gyro, initial_sigma=sigma,
                covariance_model=self.settings.covariance_model,
                quantization_correction=bool(self.settings.quantization_correction))
            self._good = self.integrator.snapshot()
            self._nav_prev_q = self.integrator.q.copy()
            self._last_gyro_t = t_end
            self.emit('info', f'static alignment done at t = {t_end:.3f} s: tilt σ '
                      f'{np.degrees(nav.alignment.tilt_sigma) * 3600:.1f}″, heading σ '
                      f'{np.degrees(nav.alignment.heading_sigma):.4f}°')
        return True

    def _stamps_ns(self, t: np.ndarray) -> np.ndarray:
        return self.origin_ns + np.rint(np.asarray(t, dtype=float) * 1e9).astype(np.int64)

    def _integrate(self, inc: np.ndarray, t: np.ndarray, stamps_ns,
                   per_sample: bool = False) -> bool:
        """
        Compensate and integrate a block, collecting its outputs.

        Compensate and integrate a block (``stamps_ns``: the header stamps of ``t``), collecting
        its outputs; False (nothing output) if an update is not finite, unless ``per_sample``,
        which
        restores the last good state instead.
        """
        if self.compensating:
            prev = (self._last_gyro_t if self._last_gyro_t is not None
                    else t[0] - self.integrator.nominal_period)
            T = np.diff(t, prepend=prev)
            inc = self.gyro_effects.compensate(inc, t, T)
        self._last_gyro_t = float(t[-1])
        batch = self.integrator.push(inc, t)
        # a NaN or ±Inf anywhere in a block reaches its last update: q, P and J are carried from
        # update to update, and every entry of T enters every entry of Cᵀ T C (NaN·0 and ∞·0 are
        # NaN)
        if len(batch) and not _finite_update(batch.attitude[-1], batch.covariance[-1]):
            if not per_sample:
                return False
            # never output a non-finite state: back to the last good one, covariance inflated
            self.nonfinite += 1
            self.integrator.restore(self._good, inflate_sigma=NONFINITE_INFLATION)
            self.emit('error', 'non-finite attitude: not published; state reset to the last good '
                      f'update with {NONFINITE_INFLATION} rad added to its σ',
                      throttle=5.0, key='nonfinite')
            return True
        if len(batch):
            self._good = self.integrator.snapshot()
        if self.nav is not None:
            self.nav.add_gyro(inc, t)
            if len(batch):
                starts = np.vstack([self._nav_prev_q[None], batch.attitude[:-1]])
                self._nav_prev_q = batch.attitude[-1].copy()
                self.nav.add_updates(batch.stamps, batch.interval, batch.attitude, starts)
        imu_on = self._imu_wanted()                 # asked once per block
        if len(batch):
            step = self.integrator.algorithm.samples
            ns = np.array(stamps_ns[batch.first_end::step], dtype=np.int64)
            self._out[0].append(AttitudeOutput(ns, batch.attitude, batch.covariance,
                                               batch.mean_rate, batch.interval))
            self.has_output = True
            if imu_on:
                for k in range(len(batch)):
                    self.pending_imu.append((batch.stamps[k], batch.interval[k], int(ns[k]),
                                             batch.attitude[k], batch.covariance[k],
                                             batch.mean_rate[k]))
        if not imu_on and len(batch) and not self.pending_imu:
            self.accel.discard_through(float(batch.stamps[-1]))     # no sins/imu wants the Δv
        return True

    def _flush_imu(self, final: bool = False) -> None:
        """
        Make the sins/imu records of the updates that are ready.

        sins/imu records of the updates whose interval is covered by accelerometer data, or
        that waited longer than ``accel_wait`` (stamp time) for it (``final``: all of them).
        """
        if not self.pending_imu:
            return
        wait = float(self.settings.accel_wait)
        newest = self.integrator.time if self.integrator.time is not None else -np.inf
        covered = self.accel.covered_until() + 1e-9
        ready = 0
        for item in self.pending_imu:      # stamps increase: the ready ones are a prefix
            if not final and item[0] > covered and newest - item[0] < wait:
                break
            ready += 1
        if not ready:
            return
        items = [self.pending_imu.popleft() for _ in range(ready)]
        t = np.array([it[0] for it in items])
        h = np.array([it[1] for it in items])
        dv, n = self.accel.take_sequence(t - h - 1e-9, t + 1e-9)
        has = n > 0
        f = np.zeros((ready, 3))
        f[has] = dv[has] / h[has, None]
        self._out[1].append(ImuOutput(np.array([it[2] for it in items], dtype=np.int64),
                                      np.array([it[3] for it in items]),
                                      np.array([it[4] for it in items]),
                                      np.array([it[5] for it in items]), f, has))
        self.has_output = True

    def _flush_nav(self, final: bool = False) -> None:
        if self.nav is None or self.nav.navigator is None:
            return
        newest = self.integrator.time if self.integrator.time is not None else -np.inf
        nb = self.nav.process(np.inf if final else newest, float(self.settings.accel_wait))
        if nb is None or not len(nb):
            return
        self._out[2].append(NavigationOutput(self._stamps_ns(nb.stamps), nb.position, nb.velocity,
                                             nb.attitude, nb.covariance, nb.extrapolated))
        self.has_output = True

    # --- state --------------------------------------------------------------------------------
    def accel_stall_s(self) -> float | None:
        """
        Return the stamp seconds the gyro stream ran beyond the newest Δv.

        Stamp seconds the gyro stream has run beyond the newest accepted Δv (the first gyro
        stamp when none arrived); None when no accelerometer stream is expected (none seen and
        navigation off) or no gyro data arrived.
        """
        g, a = self.gyro_check, self.accel_check
        if g.last_ns is None or (not self.accel_seen and self.nav is None):
            return None
        ref = a.last_ns if a.last_ns is not None else g.first_ns
        return None if ref is None else max(0.0, (g.last_ns - ref) * 1e-9)

    def accel_stall(self, accel_topic: str = 'imu/delta_velocity') -> AccelStall | None:
        """
        Return the accelerometer stall, or None when there is none.

        The accelerometer stall by the rule of :func:`accel_stall_limits` (WARN beyond
        ``accel_wait``, ERROR beyond max(1 s, 10 ``accel_wait``)), or None when there is none.

        Parameters
        ----------
        accel_topic : str
            The name of the accelerometer stream in the text.

        """
        stall = self.accel_stall_s()
        warn_s, error_s = accel_stall_limits(self.settings.accel_wait)
        if stall is None or not stall > warn_s:
            return None
        what = 'no accelerometer increments received' if self.accel_check.last_ns is None else \
            f'accelerometer increments ({bounded(accel_topic, 80)}) stopped'
        effect = 'sins/odometry stalls' if self.nav is not None \
            else 'sins/imu has no specific force'
        return AccelStall(stall, 'error' if stall > error_s else 'warn',
                          f'{what}: the gyro stream ran {stall:.3g} s beyond the last Δv; '
                          f'{effect} (WARN beyond {warn_s:g} s, ERROR beyond {error_s:g} s)')

    def status(self) -> dict:
        """
        Return the counters and state of the system.

        The counters and state of the system (the node's /diagnostics values, without what the
        node itself counts).
        """
        g, a = self.gyro_check, self.accel_check
        values = {'coning_algorithm': self.integrator.algorithm_name,
                  'samples_per_update': self.integrator.algorithm.samples,
                  'covariance_model': self.integrator.covariance_model,
                  'updates': self.integrator.updates, **g.as_dict('gyro'), **a.as_dict('accel'),
                  'compensated_effects': ', '.join(self.compensating) or 'none',
                  'initial_orientation_normalised': self.initial_normalised,
                  'nonfinite_updates_discarded': self.nonfinite,
                  'gyro_frame_mismatch': self.frame_mismatch['gyro'],
                  'accel_buffer_overflowed': self.accel.overflowed,
                  'accel_frame_mismatch': self.frame_mismatch['accel']}
        if self.nav is not None:
            values.update(self.nav.status())
        if self.integrator.time is not None:
            sig = np.sqrt(np.diag(self.integrator.covariance()))
            values.update({'attitude_sigma_x_rad': sig[0], 'attitude_sigma_y_rad': sig[1],
                           'attitude_sigma_z_rad': sig[2]})
        return values
