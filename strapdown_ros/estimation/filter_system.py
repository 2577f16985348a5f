"""
The attitude filter between validated streams and outputs, shared by the node and the tool.

``attitude_filter_node`` and the offline tool ``filter_bag`` both drive it (no ROS imports).

* Gyro increments pass the nodes' input rules
  (:class:`strapdown_ros.streams.checks.StreamCheck`) in :meth:`FilterSystem.offer_gyro` (the node)
  or arrive already validated by the recording reader (:meth:`FilterSystem.add_increments`, the
  tool, with the reader's gaps); both then take the same path.  A gap is the check's (rule 6:
  the period is the median step of the stamps, not ``gyro_rate``; ±30 % stamp jitter is no gap).
* Camera fixes (``q_GCRS_VF``, covariance in VF axes or none) pass THE screening of a reference
  fix (:class:`strapdown_ros.streams.fixes.FixScreen`, as calibrator_node and the reader) in
  :meth:`FilterSystem.offer_fix`: a non-finite or zero quaternion is dropped, a non-unit one
  normalised without overflow, an all-zero covariance replaced by the model's, one that is not
  symmetric, not positive definite or beyond its bounds dropped; each counted.  Then the stamp
  rules of a fix stream (:meth:`StreamCheck.for_fixes`): a lone fix stamped ahead is a stamp
  outlier (it never blinds the filter); a clock step of the fixes, confirmed by
  ``resync_count`` fixes (or, when the gyro's clock stepped too, by the first fix on the gyro's
  new timeline), restarts the filter.
* The filter starts at the first fix: ``q_ref_body = q_fix ⊗ q_MF_VF⁻¹`` at the newest
  increment stamp not after it.  A gyro gap or stamp resynchronisation loses the rotation in
  it: the filter restarts at the next fix (counted).
* Outputs: one :class:`FilterOutput` per ``output_period`` of stamp time, at the first
  increment stamp at or past each multiple of it after the start (one row per period, each at
  its own increment stamp; an increment that passes several multiples gives one row), with the
  state at exactly that stamp (inside an unfinished coning update: its increments applied one
  by one, as for a fix there); and one :class:`FixOutput` per fix processed.
* Divergence (``divergence_gated_fixes`` consecutive gated fixes, or the NIS of the last
  ``divergence_nis_window`` fixes that pass the gate above their χ² quantile of
  ``divergence_nis_probability``):
  the fix re-initialises the attitude with the covariance of ``initial_attitude_sigma``, the
  bias and the other states are kept; counted (``reset``) and listed (:attr:`FilterSystem.resets`).
* The live model check (:mod:`strapdown_ros.estimation.model_check`) sees every applied or
  gated fix with the filter's gain and Jacobian, and the increments between fixes (for the
  candidate effects' signatures); it only reports.  A divergence reset restarts the effects'
  responses and the interval's signatures there (:meth:`ModelCheck.restart`); its window goes on.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, fields
import math

import numpy as np

from strapdown_ros.attitude import kernel as attitude_kernel
from strapdown_ros.estimation.attitude_filter import AttitudeFilter
from strapdown_ros.estimation.filter_support import augment_error
from strapdown_ros.estimation.model_check import check_candidates, ModelCheck, ModelCheckResult
from strapdown_ros.rotation import (dcm_to_quat, quat_conjugate, quat_multiply, quat_normalize,
                                    quat_to_dcm, ypr_to_dcm)
from strapdown_ros.sensors.effects import EFFECTS, GyroEffects
from strapdown_ros.sensors.sensor_model import SensorModel
from strapdown_ros.streams.checks import StreamCheck
from strapdown_ros.streams.fixes import FixScreen

__all__ = ['FilterSystem', 'FilterSettings', 'FilterOutput', 'FilterOutputs', 'FixOutput',
           'warm_up']

#: the forward stamp limit of the fixes until their period is known, s (StreamCheck.for_fixes)
CAMERA_JUMP_S = StreamCheck.FIX_INITIAL_JUMP_S
#: increments lumped per step of the model check's signatures
SIGNATURE_LUMP = 8
#: increments held for the signatures before they are summed (bounds the buffer)
SIGNATURE_BUFFER = 4096
#: divergence resets listed (the latest; all are counted)
MAX_RESETS_KEPT = 1000
#: increments buffered before :meth:`FilterSystem.due` asks for processing in any case
MAX_BUFFERED = 4096


@dataclass
class FilterOutput:
    """
    The filter state at one output time.

    Parameters
    ----------
    stamp_ns : int
        Time of the state, ns.
    attitude : ndarray (4,)
        ``q_ref_body`` [w, x, y, z].
    attitude_covariance : ndarray (3, 3)
        Covariance of ε (body axes), rad².
    rate : ndarray (3,)
        Bias-compensated mean body rate since the previous output, rad/s.
    bias : ndarray (3,)
        Gyro bias estimate, rad/s.
    bias_covariance : ndarray (3, 3)
        Its covariance, (rad/s)².
    augmented : dict
        ``{name: (estimate, σ)}`` of the augmented states.

    """

    stamp_ns: int
    attitude: np.ndarray
    attitude_covariance: np.ndarray
    rate: np.ndarray
    bias: np.ndarray
    bias_covariance: np.ndarray
    augmented: dict


class FilterOutputs(Sequence):
    """
    The filter's outputs as arrays, one row per output: a sequence of :class:`FilterOutput`.

    Indexing or iterating gives one :class:`FilterOutput` per row (a node publishes them); a
    whole recording's tools read the arrays.

    Parameters
    ----------
    stamps_ns : ndarray (N,) of int
        Times of the states, ns.
    attitude : ndarray (N, 4)
        ``q_ref_body`` [w, x, y, z].
    attitude_covariance : ndarray (N, 3, 3)
        Covariance of ε (body axes), rad².
    rate : ndarray (N, 3)
        Bias-compensated mean body rate since the previous output, rad/s.
    bias : ndarray (N, 3)
        Gyro bias estimate, rad/s.
    bias_covariance : ndarray (N, 3, 3)
        Its covariance, (rad/s)².
    augmented : dict
        ``{name: (estimates (N, w), σ (N, w))}`` of the augmented states, in augment order.

    """

    FIELDS = ('stamps_ns', 'attitude', 'attitude_covariance', 'rate', 'bias',
              'bias_covariance')

    def __init__(self, stamps_ns, attitude, attitude_covariance, rate, bias, bias_covariance,
                 augmented: dict):
        self.stamps_ns = np.asarray(stamps_ns, dtype=np.int64).reshape(-1)
        self.attitude = np.asarray(attitude, dtype=float).reshape(-1, 4)
        self.attitude_covariance = np.asarray(attitude_covariance, dtype=float).reshape(-1, 3, 3)
        self.rate = np.asarray(rate, dtype=float).reshape(-1, 3)
        self.bias = np.asarray(bias, dtype=float).reshape(-1, 3)
        self.bias_covariance = np.asarray(bias_covariance, dtype=float).reshape(-1, 3, 3)
        self.augmented = dict(augmented)

    @classmethod
    def empty(cls) -> FilterOutputs:
        """
        Return no outputs.

        Returns
        -------
        FilterOutputs
            Zero rows (and no augmented columns).

        """
        return cls(np.zeros(0, np.int64), np.zeros((0, 4)), np.zeros((0, 3, 3)),
                   np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3, 3)), {})

    @classmethod
    def joined(cls, parts) -> FilterOutputs:
        """
        Return the rows of ``parts`` one after the other.

        Parameters
        ----------
        parts : list of FilterOutputs
            In order, with the same augmented states (at least one part).

        Returns
        -------
        FilterOutputs
            Their rows.

        """
        if len(parts) == 1:
            return parts[0]
        cols = [np.concatenate([getattr(p, f) for p in parts]) for f in cls.FIELDS]
        aug = {n: tuple(np.concatenate([p.augmented[n][k] for p in parts]) for k in (0, 1))
               for n in parts[0].augmented}
        return cls(*cols, aug)

    @classmethod
    def of(cls, outputs) -> FilterOutputs:
        """
        Return outputs as arrays: ``outputs`` itself, or the rows of FilterOutput objects.

        Parameters
        ----------
        outputs : FilterOutputs or sequence of FilterOutput
            The outputs.

        Returns
        -------
        FilterOutputs
            The same rows.

        """
        if isinstance(outputs, FilterOutputs):
            return outputs
        outputs = list(outputs)
        if not outputs:
            return cls.empty()
        aug = {n: tuple(np.array([o.augmented[n][k] for o in outputs]) for k in (0, 1))
               for n in outputs[0].augmented}
        return cls(*([getattr(o, 'stamp_ns' if f == 'stamps_ns' else f) for o in outputs]
                     for f in cls.FIELDS), aug)

    def __len__(self) -> int:
        """Return the number of outputs."""
        return len(self.stamps_ns)

    def __getitem__(self, i):
        """Return output ``i`` (a FilterOutput), or the outputs of a slice (FilterOutputs)."""
        if isinstance(i, slice):
            return FilterOutputs(*(getattr(self, f)[i] for f in self.FIELDS),
                                 {n: (e[i], s[i]) for n, (e, s) in self.augmented.items()})
        return FilterOutput(int(self.stamps_ns[i]), self.attitude[i],
                            self.attitude_covariance[i], self.rate[i], self.bias[i],
                            self.bias_covariance[i],
                            {n: (e[i], s[i]) for n, (e, s) in self.augmented.items()})

    def __iter__(self):
        """Iterate over the outputs, one FilterOutput each."""
        return (self[i] for i in range(len(self)))


@dataclass
class FixOutput:
    """
    One fix processed by the filter.

    Parameters
    ----------
    stamp_ns : int
        Stamp of the fix, ns.
    status : str
        ``applied``, ``gated``, ``reset``, ``pending``, ``too_old`` or ``overflow``.
    innovation : ndarray (3,), optional
        The residual z, VF axes, rad.
    nis : float, optional
        Its normalised innovation squared.
    lateness : float
        How late it arrived, s.
    check_text : str
        The live model check's verdict in words.
    check_ok : bool
        Whether the model check passes (no WARN episode on).
    check : ModelCheckResult, optional
        The model check's verdict of the window ending at this fix.
    innovation_covariance : ndarray (3, 3), optional
        S of the innovation, rad² (applied, gated or reset fixes).
    reason : str
        Why divergence was declared (status ``reset``).

    """

    stamp_ns: int
    status: str
    innovation: np.ndarray | None
    nis: float | None
    lateness: float
    check_text: str = ''
    check_ok: bool = True
    check: ModelCheckResult | None = None
    innovation_covariance: np.ndarray | None = None
    reason: str = ''


@dataclass(frozen=True)
class FilterSettings:
    """
    What ``attitude_filter_node`` and ``filter_bag`` take besides the sensor model.

    The field names are the nodes' parameter names (:data:`strapdown_ros.params.FILTER_PARAMS`).

    Attributes
    ----------
    coning_algorithm : str
        Coning algorithm of the filter's integrator.
    initial_attitude_sigma : float
        Prior 1σ of the attitude error per axis at the first fix, rad.
    boresight_source : str
        ``parameter`` (the model's boresight) or ``topic`` (fixes wait for a latched one).
    use_camera_covariance : bool
        Read each fix's covariance (false: the model's camera σ).
    gate_probability : float
        χ²(3) probability of the gate.
    history : int
        Increments kept for late fixes.
    output_period : float
        Stamp time between outputs, s.
    model_check_window : int
        Fixes in the live model check's window.
    model_check_alpha : float
        False-alarm probability of each model-check test.
    model_check_false_alarms_per_hour : float
        The live check's false WARN episodes per hour of clean data.
    max_stamp_jump : float
        A stamp step beyond this is a jump, s.
    resync_count : int
        Consecutive messages that confirm a new timeline.
    divergence_gated_fixes : int
        Consecutive gated fixes that declare divergence (0: not this rule).
    divergence_nis_window : int
        Fixes passing the gate whose NIS are summed for the divergence rule (0: not this rule).
    divergence_nis_probability : float
        Divergence when that sum exceeds its χ²(3·window) quantile of this probability.

    """

    coning_algorithm: str = '2'
    initial_attitude_sigma: float = 1e-3
    boresight_source: str = 'parameter'
    use_camera_covariance: bool = True
    gate_probability: float = 0.9999
    history: int = 20000
    output_period: float = 0.1
    model_check_window: int = 30
    model_check_alpha: float = 0.001
    model_check_false_alarms_per_hour: float = 0.1
    max_stamp_jump: float = 1.0
    resync_count: int = 5
    divergence_gated_fixes: int = 5
    divergence_nis_window: int = 10
    divergence_nis_probability: float = 0.999999999

    @classmethod
    def from_values(cls, values: dict) -> FilterSettings:
        """
        Build the settings from parameter values (other names are not read).

        Parameters
        ----------
        values : dict
            Validated parameters by name (defaults where absent).

        Returns
        -------
        FilterSettings
            The settings.

        """
        return cls(**{f.name: values[f.name] for f in fields(cls) if f.name in values})


class FilterSystem:
    """
    Streams → :class:`strapdown_ros.estimation.attitude_filter.AttitudeFilter` → outputs.

    The sensor model is applied whole: its gyro effects are compensated (those the filter
    estimates online start at the model's value with the model's σ as their prior), the bias
    starts at ``gyro_bias`` with prior ``gyro_bias_sigma`` and its process noise
    ``gyro_bias_random_walk`` / ``gyro_bias_correlation_time``, a fix is applied at its stamp
    minus ``camera_time_offset``, its covariance is scaled per VF axis by
    ``camera_noise_scale``, the fixes are taken at the model's ``reference_spacing`` (the others
    counted ``spaced``), and the boresight is the model's (or the latched topic's).

    Parameters
    ----------
    model : SensorModel
        The unit's sensor model.
    settings : FilterSettings, optional
        The filter's own settings (default: the defaults).

    Raises
    ------
    ValueError
        The model's camera σ is zero (a fix without covariance would take it), or an active
        effect needs the accelerometer.

    """

    def __init__(self, model: SensorModel, settings: FilterSettings | None = None):
        if isinstance(model, dict):
            raise TypeError('FilterSystem takes a SensorModel and FilterSettings '
                            '(strapdown_ros.params.load_model_file), not a parameter dict')
        s = self.settings = settings or FilterSettings()
        self.model = model
        self.augment = model.augment
        err = augment_error(','.join(self.augment))
        if err:
            raise ValueError(err)
        if min(model.camera_sigma_xy, model.camera_sigma_z) <= 0.0:
            raise ValueError('camera_sigma_xy and camera_sigma_z must be > 0 for the filter: a '
                             'fix without a covariance takes them')
        self.period = model.gyro_period
        self.gyro_check = StreamCheck(self.period,
                                      max_norm=2.0 * self.period * model.gyro_max_rate,
                                      jump_limit=float(s.max_stamp_jump),
                                      resync_count=int(s.resync_count))
        self.camera_check = StreamCheck.for_fixes(float(s.max_stamp_jump), int(s.resync_count))
        self._gyro_steps_used = 0      # gyro clock steps that confirmed a step of the fixes
        # the gap rule of increments handed over without their gaps (add_increments)
        self._increment_gaps = StreamCheck(self.period, jump_limit=math.inf)
        self.default_covariance = np.diag(model.camera_sigma ** 2)
        self.use_covariance = bool(s.use_camera_covariance)
        self.fix_screen = FixScreen(self.default_covariance, self.use_covariance)
        self.camera_effects = model.camera_effects()
        #: the fixes' covariance is scaled (camera_noise_scale other than 1)
        self._scaled_noise = self.camera_effects.noise_scale is not None \
            and bool(np.any(self.camera_effects.noise_scale != 1.0))
        # the model's gyro effects the filter does not estimate (the bias is always a state)
        fixed = {n: model.effect_value(n) for n in model.active('gyro')
                 if n not in self.augment and n != 'gyro_bias'
                 and EFFECTS[n].kind in ('systematic', 'coupled')}
        self.compensation = GyroEffects(values=fixed) if fixed else None
        #: the effect epoch: the end stamp of the first increment taken, s
        self.effect_epoch: float | None = None
        self.boresight = None
        if s.boresight_source == 'parameter':
            self.boresight = dcm_to_quat(ypr_to_dcm(*np.asarray(model.boresight, dtype=float)))
        self.output_ns = int(round(float(s.output_period) * 1e9))
        self.filter: AttitudeFilter | None = None
        self.check: ModelCheck | None = None
        self.counts = {'fixes_received': 0, 'dropped_zero_quaternion': 0, 'normalised': 0,
                       'dropped_bad_covariance': 0, 'covariance_substituted': 0,
                       'dropped_nan': 0, 'dropped_not_unit': 0, 'dropped_no_boresight': 0,
                       'increments_before_start': 0, 'restarts': 0, 'gaps': 0,
                       'camera_resyncs': 0, 'applied': 0, 'gated': 0, 'reset': 0,
                       'too_old': 0, 'overflow': 0, 'spaced': 0}
        #: the reference spacing rule (the model's ``reference_spacing``), ns; 0: every fix
        self.spacing_ns = int(round(float(model.reference_spacing) * 1e9))
        self._spaced_last: int | None = None   # the last fix taken under the spacing rule, ns
        self._fix_prev: int | None = None      # the last fix offered to it, ns
        self._fix_interval = 0                 # the latest interval between them, ns
        #: the divergences declared, (stamp ns of the fix, why), the latest MAX_RESETS_KEPT
        self.resets: deque = deque(maxlen=MAX_RESETS_KEPT)
        self._buf_t: list = []          # accepted increments not yet processed (ns, value)
        self._buf_d: list = []
        self._chunks: list = []         # ... and arrays of them, (ns (n,), values (n, 3))
        self._chunked = 0
        self._last_ns: int | None = None   # newest increment stamp given to the filter
        self._out0: int | None = None      # the outputs' origin: the filter's start, ns
        self._due_ns = 0                   # the next output time, ns
        self._pending: list = []        # epochs (s) of fixes waiting for increments
        self._rate_sum = np.zeros(3)
        self._rate_time = 0.0
        self._last_rate = np.zeros(3)
        self._sig_buf: list = []        # (Δθ, h, t) not yet given to the model check
        self._sig_len = 0
        self._output_parts: list = []          # FilterOutputs of each call, not yet taken
        self.fix_outputs: list = []

    # ------------------------------------------------------------------ input
    def offer_gyro(self, stamp_ns: int, value) -> None:
        """
        Take one Δθ from a live stream: the input rules, then buffered.

        Parameters
        ----------
        stamp_ns : int
            Header stamp, ns.
        value : array_like (3,)
            The increment, rad, body axes.

        """
        g = self.gyro_check
        out = g.offer(stamp_ns, value)
        if g.resynced:
            self._restart()
        marks = g.gap_marks
        for ns, v in out:
            if marks and ns in marks:          # rule 6 of the check: the rotation in it is lost
                self.counts['gaps'] += 1
                self._restart()
            self._buf_t.append(int(ns))
            self._buf_d.append(v)

    def add_increments(self, stamps_ns, values, breaks=None) -> None:
        """
        Take increments already validated (the recording reader), buffered as in offer_gyro.

        A gap or stamp jump restarts the filter before the increment that follows it, as there.
        Arrays are taken whole (no per-increment work when the breaks are given).

        Parameters
        ----------
        stamps_ns : sequence of int
            Stamps, ns.
        values : sequence of (3,) array_like
            Increments, rad, body axes.
        breaks : collection of int, optional
            The stamps that follow a gap or a stamp jump (the ends of the reader's gap
            intervals, judged by the check's rule 6); None: judged here by the same rule
            (a :class:`~strapdown_ros.streams.checks.StreamCheck` over the stamps of every
            call).

        """
        t = np.asarray(stamps_ns, dtype=np.int64).reshape(-1)
        if not len(t):
            return
        v = np.asarray(values, dtype=float).reshape(-1, 3)
        if breaks is None:                     # judged here, by the same rule, across calls
            rule = self._increment_gaps
            cuts = [i for i, ns in enumerate(t.tolist())
                    if rule.offer(ns, (0.0, 0.0, 0.0)) and rule.gap_marks]
        else:
            b = breaks if isinstance(breaks, np.ndarray) else np.fromiter(breaks, np.int64)
            cuts = np.flatnonzero(np.isin(t, b)).tolist() if len(b) else []
        edges = sorted(set([0] + cuts)) + [len(t)]
        for lo, hi in zip(edges[:-1], edges[1:]):
            if lo in cuts:
                self.process()
                self.counts['gaps'] += 1
                self._restart()
            self._hold()
            self._chunks.append((t[lo:hi], v[lo:hi]))
            self._chunked += hi - lo

    def _hold(self) -> None:
        """Move the single increments of offer_gyro into the chunks (their order kept)."""
        if self._buf_t:
            self._chunks.append((np.asarray(self._buf_t, dtype=np.int64),
                                 np.asarray(self._buf_d, dtype=float).reshape(-1, 3)))
            self._chunked += len(self._buf_t)
            self._buf_t, self._buf_d = [], []

    def offer_fix(self, stamp_ns: int, q_wxyz, covariance=None) -> FixOutput | None:
        """
        Take one camera fix from a live stream: the screening and stamp rules, then the filter.

        THE screening of a reference fix (:class:`~strapdown_ros.streams.fixes.FixScreen`:
        each drop counted ``dropped_<reason>``), then the stamp rules of a fix stream; a
        confirmed clock step of the fixes restarts the filter (``camera_resyncs``): confirmed by
        ``resync_count`` fixes, or at once by the first fix on the new timeline of the gyro when
        the gyro's clock stepped too (both clocks stepped: the gyro's ``resync_count``
        increments confirmed it).  The filter takes the fix after the buffered increments.

        Parameters
        ----------
        stamp_ns : int
            Header stamp, ns.
        q_wxyz : array_like (4,)
            ``q_GCRS_VF``, scalar-first.
        covariance : array_like (3, 3), optional
            Its covariance, VF axes, rad² (None: the model σ).

        Returns
        -------
        FixOutput or None
            The result, or None when the fix is dropped, starts the filter or waits.

        """
        self.counts['fixes_received'] += 1
        got = self._screen(q_wxyz, covariance)
        if got is None:
            return None
        q, P = got
        c = self.camera_check
        out = c.offer(int(stamp_ns), list(q) + list(np.ravel(P)))
        g = self.gyro_check
        if not out and c.held and g.resyncs > self._gyro_steps_used and g.last_ns is not None \
                and abs(int(stamp_ns) - g.last_ns) <= g.jump_ns:
            # both clocks stepped: the gyro's step, confirmed by its increments, confirms the
            # fixes' at the first fix on the gyro's new timeline
            self._gyro_steps_used = g.resyncs
            out = c.confirm()
        if c.resynced:                         # a confirmed clock step of the fixes
            self.resync_fixes()
        res = None
        for ns, v in out:
            res = self._apply_fix(ns, np.asarray(v[:4]), np.asarray(v[4:]).reshape(3, 3))
        return res

    def _screen(self, q_wxyz, covariance):
        """Screen a fix (THE screening; drops counted ``dropped_<reason>``): (q, P) or None."""
        screen = self.fix_screen
        got = screen.screen(q_wxyz, covariance)
        if got is None:
            self.counts[f'dropped_{screen.last_reason}'] += 1
        self.counts['normalised'] = screen.normalised
        self.counts['covariance_substituted'] = screen.covariance_substituted
        return got

    def add_fix(self, stamp_ns: int, q_wxyz, covariance, screened: bool = False
                ) -> FixOutput | None:
        """
        Take a fix that passed the stamp rules (the recording reader's), in stamp order.

        It passes THE screening of a fix too, unless it has passed it already (``screened``:
        the recording reader's fixes, whose screening is counted in the reader's summary), so
        no caller can hand the filter a fix it cannot take.

        Parameters
        ----------
        stamp_ns : int
            Stamp, ns.
        q_wxyz : array_like (4,)
            ``q_GCRS_VF``, scalar-first.
        covariance : array_like (3, 3) or None
            VF axes, rad² (None: the model σ).
        screened : bool
            The fix passed :class:`~strapdown_ros.streams.fixes.FixScreen` already: a unit
            quaternion and its covariance, used as they are.

        Returns
        -------
        FixOutput or None
            The result, or None when the fix is dropped, starts the filter or waits.

        """
        if screened and covariance is not None:
            return self._apply_fix(stamp_ns, q_wxyz, covariance)
        got = self._screen(q_wxyz, covariance)
        if got is None:
            return None
        return self._apply_fix(stamp_ns, *got)

    def _spaced_out(self, stamp_ns: int) -> bool:
        """
        Return whether the reference spacing rule leaves this fix out (counted ``spaced``).

        The reference's errors are correlated over less than the model's ``reference_spacing``,
        so the filter takes the first fix and then one fix a spacing later: a fix is left out
        while it is less than the spacing, less half the interval between fixes, after the
        last one taken (regular fixes: one in ``round(spacing / interval)``, the slots of
        :func:`strapdown_ros.calibration.reference_spacing.thin_fixes`).  A fix that starts the
        filter is always taken.
        """
        prev, self._fix_prev = self._fix_prev, int(stamp_ns)
        if self.spacing_ns <= 0:
            return False
        if prev is not None and stamp_ns > prev:
            self._fix_interval = int(stamp_ns) - prev
        last = self._spaced_last
        if self.filter is not None and last is not None and \
                0 <= stamp_ns - last < self.spacing_ns - self._fix_interval // 2:
            self.counts['spaced'] += 1
            return True
        self._spaced_last = int(stamp_ns)
        return False

    def _apply_fix(self, stamp_ns: int, q_wxyz, covariance) -> FixOutput | None:
        if self.boresight is None:
            self.counts['dropped_no_boresight'] += 1
            return None
        if self._spaced_out(stamp_ns):
            return None
        if self._scaled_noise:
            covariance = self.camera_effects.covariance(covariance)
        self.process()
        t = stamp_ns * 1e-9
        if self.filter is None:
            self._start(stamp_ns, q_wxyz)
            return None
        self._flush_signature()
        res = self.filter.update(t, q_wxyz, covariance)
        if res.status == 'pending':
            self._pending.append(res.epoch)
            self._pending.sort()
            return None
        return self._fix_result(res)

    def resync_fixes(self) -> None:
        """
        Restart at a confirmed clock step of the fixes (counted ``camera_resyncs``).

        The fixes after it lie on another timeline than the filter's history: the filter
        restarts at the next one (the gyro's own steps restart it through its check).
        """
        self.counts['camera_resyncs'] += 1
        self._restart()

    def set_boresight(self, q_wxyz) -> None:
        """
        Set a new known boresight (the latched calibration/boresight).

        Parameters
        ----------
        q_wxyz : array_like (4,)
            ``q_MF_VF``, scalar-first.

        """
        q = quat_normalize(np.asarray(q_wxyz, dtype=float))
        self.boresight = q
        if self.filter is not None and 'boresight' not in self.augment:
            self.filter.boresight = q

    def due(self) -> bool:
        """
        Tell whether :meth:`process` has work to publish: an output or a fix is reached.

        True when the newest buffered increment reaches the next output time or a waiting
        fix's epoch, or when :data:`MAX_BUFFERED` increments wait.  A node processes then: the
        outputs go out as soon as their increments are in, and a burst of increments costs one
        processing (the numbers do not depend on when it is called).

        Returns
        -------
        bool
            Whether to call :meth:`process` now.

        """
        n = self.buffered
        if n >= MAX_BUFFERED:
            return True
        if not self._buf_t:
            return False
        if self.filter is None:                     # before the start: counted, not kept
            return n > 64
        newest = self._buf_t[-1]
        return newest >= self._due_ns or (bool(self._pending)
                                          and newest * 1e-9 >= self._pending[0])

    @property
    def buffered(self) -> int:
        """Increments accepted and not yet processed (:meth:`process` takes them)."""
        return len(self._buf_t) + self._chunked

    # ------------------------------------------------------------------ processing
    def process(self) -> None:
        """
        Propagate over the buffered increments.

        Outputs are emitted at output times and fix results as pending fixes are reached.
        """
        self._hold()
        if not self._chunks:
            return
        chunks, self._chunks, self._chunked = self._chunks, [], 0
        t_ns = np.concatenate([c[0] for c in chunks]) if len(chunks) > 1 else chunks[0][0]
        d = np.concatenate([c[1] for c in chunks]) if len(chunks) > 1 else chunks[0][1]
        self._take(t_ns, d)

    def _take(self, t_ns: np.ndarray, d: np.ndarray) -> None:
        """Propagate over accepted increments (arrays), cut at the waiting fixes' epochs."""
        if self.effect_epoch is None:          # the end stamp of the first increment taken
            self.effect_epoch = float(t_ns[0]) * 1e-9
            if self.compensation is not None:
                self.compensation.epoch = self.effect_epoch
        if self.filter is None:
            self.counts['increments_before_start'] += len(t_ns)
            self._last_ns = int(t_ns[-1])
            return
        keep = t_ns > self._last_ns
        if not keep.all():
            t_ns, d = t_ns[keep], d[keep]
        while len(t_ns):
            cut = len(t_ns)
            if self._pending:      # the model check's signature ends at the fix
                cut = min(cut, int(np.searchsorted(t_ns * 1e-9, self._pending[0],
                                                   side='left')) + 1)
            self._propagate(d[:cut], t_ns[:cut])
            t_ns, d = t_ns[cut:], d[cut:]

    def _propagate(self, d, t_ns) -> None:
        f = self.filter
        t = t_ns * 1e-9
        h = np.empty(len(t))                   # the increments' lengths, s
        h[0] = t[0] - self._last_ns * 1e-9
        np.subtract(t[1:], t[:-1], out=h[1:])
        if self.compensation is not None:
            d = self.compensation.compensate(d, t, h)
        self._signature(d, h, t)
        if self._pending:                      # a fix may be applied in this call
            self._flush_signature()
        # one output per output period: at the first stamp of each period after the start
        cells = (t_ns - self._out0) // self.output_ns
        prev = (self._last_ns - self._out0) // self.output_ns
        marks = np.flatnonzero(np.diff(np.concatenate([[prev], cells])) > 0)
        results = f.propagate(d, t, marks=marks)
        reports = f.take_report_batch()
        self._last_ns = int(t_ns[-1])
        self._due_ns = self._out0 + ((self._last_ns - self._out0) // self.output_ns + 1) \
            * self.output_ns
        self._last_rate = d[-1] / h[-1]
        if len(marks):
            # the increments and seconds since the previous output, at each mark: the sums
            # carried from earlier calls, then this call's increments up to each mark
            end = int(marks[-1]) + 1
            starts = np.concatenate(([0], marks[:-1] + 2))
            rho = np.add.reduceat(np.vstack([self._rate_sum[None], d[:end]]), starts, axis=0)
            sec = np.add.reduceat(np.concatenate([[self._rate_time], h[:end]]), starts)
            self._emit(t_ns[marks], reports, rho, sec)
            self._rate_sum = d[end:].sum(0)
            self._rate_time = float(h[end:].sum())
        else:
            self._rate_sum = self._rate_sum + d.sum(0)
            self._rate_time += float(h.sum())
        for r in results:
            if r.epoch in self._pending:
                self._pending.remove(r.epoch)
            self._fix_result(r)
        while self._pending and self._pending[0] <= f.newest_stamp:
            self._pending.pop(0)               # applied by re-processing, or not reached

    def _signature(self, d, h, t) -> None:
        """
        Keep the increments for the model check's signatures.

        They are summed in one vectorised pass (:meth:`_flush_signature`) before the next fix
        is applied.
        """
        if self.check is None:
            return
        self._sig_buf.append((d, h, t))
        self._sig_len += len(d)
        if self._sig_len >= SIGNATURE_BUFFER:
            self._flush_signature()

    def _flush_signature(self) -> None:
        """Give the model check the increments since the last fix, lumped and compensated."""
        buf = self._sig_buf
        if not buf:
            return
        if len(buf) == 1:
            d, h, t = buf[0]
        else:
            d = np.concatenate([b[0] for b in buf])
            h = np.concatenate([b[1] for b in buf])
            t = np.concatenate([b[2] for b in buf])
        self._sig_buf, self._sig_len = [], 0
        self.check.accumulate(d, h, t, SIGNATURE_LUMP, self.filter.estimate('gyro_bias'),
                              self.filter.epoch)

    def _fix_result(self, r) -> FixOutput:
        f = self.filter
        self.counts[r.status] = self.counts.get(r.status, 0) + 1
        out = FixOutput(int(round(r.stamp * 1e9)), r.status, r.residual, r.nis, r.lateness,
                        innovation_covariance=r.innovation_covariance, reason=r.reason)
        if r.status == 'reset':
            self.resets.append((out.stamp_ns, r.reason))
            if self.check is not None:         # the attitude re-initialised: the check restarts
                self._sig_buf, self._sig_len = [], 0
                self.check.restart()
                out.check_text, out.check_ok = self.check.last.text(), self.check.last.ok
        elif r.status in ('applied', 'gated') and self.check is not None \
                and r.innovation_covariance is not None:
            self._flush_signature()
            c_vf_mf = quat_to_dcm(f.boresight).T
            v = self.check.add(r.stamp, r.residual, r.innovation_covariance, c_vf_mf,
                               self._last_rate - f.estimate('gyro_bias'),
                               gain=r.gain if r.status == 'applied' else None,
                               jacobian=r.jacobian)
            out.check_text, out.check_ok, out.check = v.text(), v.ok, v
        self.fix_outputs.append(out)
        return out

    def _emit(self, stamps_ns, reports, rho_sums, seconds) -> None:
        """Append the outputs of the K reports of a batch (arrays, then one row each)."""
        K = min(len(reports), len(stamps_ns))             # (equal: every mark is reported)
        if K == 0:
            return
        lay = self.filter.layout
        q, x, P = reports.attitude[:K], reports.states[:K], reports.covariance[:K]
        stamps_ns, rho_sums, seconds = stamps_ns[:K], rho_sums[:K], seconds[:K]
        bias = x[:, 3:6]                                  # the bias: always the first gyro state
        moved = seconds > 0                               # no time since the last output: rate 0
        rate = np.divide(rho_sums, seconds[:, None], out=np.zeros_like(rho_sums),
                         where=moved[:, None]) - bias * moved[:, None]
        att_cov, bias_cov = P[:, :3, :3].copy(), P[:, 3:6, 3:6].copy()
        aug = []                                          # (name, estimates (K, w), σ (K, w))
        if self.augment:
            sigma = np.sqrt(np.diagonal(P, axis1=1, axis2=2))        # (K, n)
            for name in self.augment:
                if name == 'boresight':
                    aug.append((name, reports.boresight[:K], sigma[:, lay.boresight]))
                else:
                    s = lay.slice_of(name)
                    aug.append((name, x[:, s], sigma[:, s]))
        self._output_parts.append(FilterOutputs(stamps_ns, q, att_cov, rate, bias, bias_cov,
                                                {name: (est, sig) for name, est, sig in aug}))

    def _start(self, stamp_ns: int, q_fix) -> None:
        m, s = self.model, self.settings
        start_ns = self._last_ns if self._last_ns is not None and self._last_ns <= stamp_ns \
            else stamp_ns
        q0 = quat_normalize(quat_multiply(np.asarray(q_fix, dtype=float),
                                          quat_conjugate(self.boresight)))
        # each online state starts at the model's value with the model's σ as its prior
        sig = {n: (m.boresight_sigma if n == 'boresight' else m.effect_sigma(n))
               for n in self.augment}
        for n, v in sig.items():
            if not v > 0.0:
                key = 'boresight_sigma' if n == 'boresight' else EFFECTS[n].sigma_parameter
                raise ValueError(f'the filter estimates {n} online (augment) but its prior '
                                 f'{key} is 0: give the σ of its value')
        init = {'gyro_bias': m.effect_value('gyro_bias')}
        init.update({n: self._filter_values(n) for n in self.augment if n != 'boresight'})
        bias = m.effects['gyro_bias']
        epoch = self.effect_epoch if self.effect_epoch is not None else start_ns * 1e-9
        self.filter = AttitudeFilter(
            q0, start_ns * 1e-9, algorithm=str(s.coning_algorithm),
            gyro_random_walk=m.gyro.random_walk,
            gyro_bias_random_walk=float(bias.option('gyro_bias_random_walk', 0.0)),
            gyro_bias_correlation_time=float(bias.option('gyro_bias_correlation_time', 0.0)),
            initial_sigma=float(s.initial_attitude_sigma),
            bias_sigma=m.effect_sigma('gyro_bias'), augment=self.augment,
            augment_sigma=sig, initial_values=init, boresight=self.boresight,
            gate_probability=float(s.gate_probability), history=int(s.history),
            epoch=epoch, model=m, divergence_gated_fixes=int(s.divergence_gated_fixes),
            divergence_nis_window=int(s.divergence_nis_window),
            divergence_nis_probability=float(s.divergence_nis_probability),
            time_offset=0.0 if 'time_offset' in self.augment else self.camera_effects.time_offset)
        cands, offset = check_candidates(self.augment)
        f = self.filter
        tau = [e.filter_correlation_time(f.noise) for e, _ in f.layout.gyro]
        previous = self.check
        self.check = ModelCheck(int(s.model_check_window), float(s.model_check_alpha),
                                cands, time_offset=offset,
                                false_alarms_per_hour=float(s.model_check_false_alarms_per_hour),
                                layout=f.layout, state_tau=np.concatenate(tau))
        self.check.continue_counts(previous)
        self._last_ns = start_ns
        self._out0 = start_ns
        self._due_ns = start_ns + self.output_ns
        self._rate_sum, self._rate_time = np.zeros(3), 0.0
        self._pending = []
        self._sig_buf, self._sig_len = [], 0

    def _filter_values(self, name: str) -> np.ndarray:
        """Return the filter states of an effect at the model's value (its combinations)."""
        e = EFFECTS[name]
        v = self.model.effect_value(name)
        S = e.fit_basis()
        return v if S is None else np.linalg.lstsq(S, v, rcond=None)[0]

    def _restart(self) -> None:
        if self.filter is not None:
            self.process()
            self.counts['restarts'] += 1
        self.filter = None

    def take(self) -> tuple[list, list]:
        """
        Return the outputs and fix results produced since the last call.

        Returns
        -------
        outputs : FilterOutputs
            The filter states (a sequence of FilterOutput, and its arrays).
        fixes : list of FixOutput
            The fixes processed.

        """
        out, fixes = self.outputs, self.fix_outputs
        self._output_parts, self.fix_outputs = [], []
        return out, fixes

    @property
    def outputs(self) -> FilterOutputs:
        """Return the outputs produced since the last :meth:`take` (FilterOutput rows)."""
        if not self._output_parts:
            return FilterOutputs.empty()
        self._output_parts = [FilterOutputs.joined(self._output_parts)]
        return self._output_parts[0]

    def status(self) -> dict:
        """
        Return the counts for /diagnostics and the tool's summary.

        Returns
        -------
        dict
            Input counts, filter counters and the model check's windows.

        """
        g = self.gyro_check
        out = dict(self.counts)
        out.update(g.as_dict('gyro'))
        if self.filter is not None:
            c = self.filter.counters
            out.update({'late_fixes': c.late, 'max_lateness_s': c.max_lateness,
                        'reprocessed_increments': c.reprocessed_increments,
                        'implausible': c.implausible})
            since = self.filter.fixes_since_reset
            if since is not None:
                out['fixes_since_reset'] = since
        if self.check is not None:
            out.update({'model_check_windows': self.check.windows,
                        'model_check_failed': self.check.failed,
                        'model_check_episodes': self.check.episodes})
        return out


def warm_up(model: SensorModel, settings: FilterSettings | None = None) -> None:
    """
    Run a throw-away filter of this model through a few seconds of synthetic data.

    The compiled integrator kernel (numba's cache), numpy's linear algebra and every code path
    of a fix are loaded before the first real message, so that a node does not stall at its
    first fix.

    Parameters
    ----------
    model : SensorModel
        The unit's sensor model.
    settings : FilterSettings, optional
        The filter's settings.

    """
    attitude_kernel.warm_up()
    s = FilterSystem(model, settings)
    if s.boresight is None:
        s.set_boresight([1.0, 0.0, 0.0, 0.0])
    n = max(4, int(round(1.0 / model.gyro_period)))
    t0 = 1_000_000_000
    step = int(round(model.gyro_period * 1e9))
    for k in range(3):                     # start, then two fixes, each after a second of data
        s.add_fix(t0 + k * n * step, np.array([1.0, 0.0, 0.0, 0.0]), s.default_covariance)
        s.add_increments(t0 + (k * n + np.arange(1, n + 1)) * step, np.zeros((n, 3)))
        s.process()
