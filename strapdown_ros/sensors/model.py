"""
Integrating-sensor models: gyro angle increments Δθ and accelerometer velocity increments Δv.

The bottom of the sensors room: the simulators (``imu_sim_node``, ``record_sim``) sample a
motion profile through :class:`IntegratingSensor`; the SINS and the calibrator take the
statistics of :class:`SensorSigmas`.  Measurement model (per output interval k of length T,
body/sensor axes)::

    y_k = (I + M) · u_k + b · T + w_k,       w_k ~ N(0, σ_rw² · T · I)

* ``u_k``: exact increment of the motion profile (∫ω dt or ∫f dt).
* ``M``: scale-factor errors on the diagonal, axis misalignments off the diagonal.
  This is 004 §2.1's ``M_G`` (general 3×3).  Tkachenko (1983, 000) §6's structure
  ``Δω = D(ω)c`` with ``D = [D_I D_II E3]``, ``D_I = diag(ω)``,
  ``D_II = [[ω2,0,ω3],[ω1,ω3,0],[0,ω2,ω1]]`` is the special case
  ``M = [[c1,c4,c6],[c4,c2,c5],[c6,c5,c3]]``, ``b = (c7,c8,c9)``
  (see :meth:`SensorErrorModel.from_scale_misalignment_bias`).
* ``b``: bias (rad/s or m/s²), a random constant.
* ``σ_rw``: angle/velocity random walk (rad/√s or m/s/√s), so the increment noise
  has covariance ``σ_rw²·T`` (004: P_wG = (σ_wG √T_IMU)² I).

Level quantization (000 §5, eq. 5.1): each axis emits pulses of weight σ when the
integral of its (erroneous) signal since the previous pulse reaches ±σ; the output
over an interval is the sum of the pulses in it.  The remainder is carried, so

    θ*_k = θ_k + Δθ_{k-1} − Δθ_k,     Δθ_k = ∫_{τ_k}^{t_k} ω* dt  (|Δθ_k| < σ)

and the quantization error never accumulates.  The pulse generator is the play
(backlash) operator on the running integral A: the last pulse level P = mσ moves
by σ whenever |A − P| reaches σ.  The optional increment correction (5.6)
``θ⁰_k = θ*_k + ½σ(sign θ*_k − sign θ*_{k−1})`` removes the mean of the remainder.

All random draws come from one ``numpy.random.Generator`` seeded by the user.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ['SensorSigmas', 'SensorErrorModel', 'PulseQuantizer', 'IntegratingSensor',
           'increment_correction', 'increment_covariance', 'DEG_PER_HOUR', 'ARCSEC',
           'NAVIGATION_GRADE_GYRO', 'NAVIGATION_GRADE_ACCEL']

_SIGMA_FIELDS = ('bias_sigma', 'scale_sigma', 'misalignment_sigma', 'random_walk', 'quantum')

DEG_PER_HOUR = np.pi / 180.0 / 3600.0          # rad/s in one °/h
ARCSEC = np.pi / 180.0 / 3600.0                # rad in one arc second


@dataclass(frozen=True)
class SensorSigmas:
    """
    Statistics of a sensor triad's errors (what a data sheet or a calibration report gives).

    The simulator draws its constants from these; the SINS uses them for P_ρk (004 §2.1).

    Attributes
    ----------
    bias_sigma : float
        Bias σ per axis, rad/s (gyro) or m/s² (accelerometer).
    scale_sigma : float
        Relative scale-factor error σ_k.
    misalignment_sigma : float
        σ_φ of each off-diagonal element, rad.
    random_walk : float
        rad/√s or m/s/√s.
    quantum : float
        Pulse weight σ (0: not quantized), rad or m/s.

    """

    bias_sigma: float = 0.0            # rad/s (gyro) or m/s² (accel), per axis
    scale_sigma: float = 0.0           # relative scale-factor error σ_k
    misalignment_sigma: float = 0.0    # rad, each off-diagonal element σ_φ
    random_walk: float = 0.0           # rad/√s or m/s/√s
    quantum: float = 0.0               # pulse weight σ (0: not quantized)

    def __post_init__(self):
        for name in _SIGMA_FIELDS:
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f'{name} must be finite and >= 0, got {v}')

    @classmethod
    def from_params(cls, values: dict, prefix: str) -> 'SensorSigmas':
        """
        Build the statistics from node parameters.

        Parameters
        ----------
        values : dict
            Node parameters ``<prefix>_bias_sigma`` … ``<prefix>_quantum``.
        prefix : str
            'gyro' or 'accel'.

        Returns
        -------
        SensorSigmas
            The statistics.

        """
        return cls(**{f: float(values[f'{prefix}_{f}']) for f in _SIGMA_FIELDS})

    def draw(self, rng: np.random.Generator) -> 'SensorErrorModel':
        """
        Draw the random constants of one sensor triad.

        Parameters
        ----------
        rng : numpy.random.Generator
            Source of the draws.

        Returns
        -------
        SensorErrorModel
            Bias, scale factors and misalignments drawn with these σ.

        """
        return SensorErrorModel.random(rng, self.bias_sigma, self.scale_sigma,
                                       self.misalignment_sigma, self.random_walk, self.quantum)


#: Vasilyuk et al. (2024, 004) §6 navigation-grade gyro: σ_φG = 3″, σ_kG = 1e-5,
#: σ_wG = 0.0012°/√h, σ_bG = 0.007°/h
NAVIGATION_GRADE_GYRO = SensorSigmas(bias_sigma=0.007 * np.pi / 180 / 3600, scale_sigma=1e-5,
                                     misalignment_sigma=3.0 * np.pi / 180 / 3600,
                                     random_walk=0.0012 * np.pi / 180 / 60.0)
#: a matching navigation-grade accelerometer (typical data-sheet values; not from the seeds)
NAVIGATION_GRADE_ACCEL = SensorSigmas(bias_sigma=50e-6 * 9.80665, scale_sigma=50e-6,
                                      misalignment_sigma=5.0 * np.pi / 180 / 3600,
                                      random_walk=20e-6 * 9.80665)


@dataclass
class SensorErrorModel:
    """
    Constant errors plus white noise of a sensor triad (SI units).

    Attributes
    ----------
    bias : (3,) ndarray
        b, rad/s or m/s².
    scale_factor : (3,) ndarray
        Relative scale-factor errors, the diagonal of M.
    misalignment : (3, 3) ndarray
        Axis misalignments, rad (off-diagonal elements used).
    random_walk : float
        rad/√s (gyro) or m/s/√s (accelerometer).
    quantum : float
        Pulse weight σ; 0 disables quantization.

    """

    bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale_factor: np.ndarray = field(default_factory=lambda: np.zeros(3))
    misalignment: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    random_walk: float = 0.0                    # rad/√s (gyro) or m/s/√s (accelerometer)
    quantum: float = 0.0                        # pulse weight σ; 0 disables quantization

    def __post_init__(self):
        self.bias = np.asarray(self.bias, dtype=float).reshape(3)
        self.scale_factor = np.asarray(self.scale_factor, dtype=float).reshape(3)
        self.misalignment = np.asarray(self.misalignment, dtype=float).reshape(3, 3)
        for name in ('random_walk', 'quantum'):
            v = float(getattr(self, name))
            if not np.isfinite(v) or v < 0:
                raise ValueError(f'{name} must be finite and >= 0, got {v}')
            setattr(self, name, v)
        if not (np.all(np.isfinite(self.bias)) and np.all(np.isfinite(self.scale_factor))
                and np.all(np.isfinite(self.misalignment))):
            raise ValueError('sensor error constants must be finite')

    @property
    def matrix(self) -> np.ndarray:
        """``M``: scale factors on the diagonal, misalignments off it."""
        m = self.misalignment.copy()
        np.fill_diagonal(m, self.scale_factor)
        return m

    @classmethod
    def from_scale_misalignment_bias(cls, c, random_walk: float = 0.0,
                                     quantum: float = 0.0) -> 'SensorErrorModel':
        """
        Build the model of Tkachenko (1983, 000) §6: ``Δω = [D_I D_II E3]·c``.

        Parameters
        ----------
        c : (9,) array_like
            c1..c9: scale factors, symmetric misalignments, bias (rad/s).
        random_walk : float
            rad/√s.
        quantum : float
            Pulse weight, rad (0: none).

        Returns
        -------
        SensorErrorModel
            The model with ``M = [[c1,c4,c6],[c4,c2,c5],[c6,c5,c3]]``, ``b = (c7,c8,c9)``.

        """
        c = np.asarray(c, dtype=float).reshape(9)
        mis = np.array([[0.0, c[3], c[5]], [c[3], 0.0, c[4]], [c[5], c[4], 0.0]])
        return cls(bias=c[6:9], scale_factor=c[0:3], misalignment=mis,
                   random_walk=random_walk, quantum=quantum)

    @classmethod
    def random(cls, rng: np.random.Generator, bias_sigma: float = 0.0, scale_sigma: float = 0.0,
               misalignment_sigma: float = 0.0, random_walk: float = 0.0,
               quantum: float = 0.0) -> 'SensorErrorModel':
        """
        Draw the constants as zero-mean Gaussians with the given σ (004 §2.1).

        Parameters
        ----------
        rng : numpy.random.Generator
            Source of the draws (misalignment, then bias, then scale factor).
        bias_sigma, scale_sigma, misalignment_sigma : float
            σ of the bias (rad/s or m/s²), the relative scale factor and each misalignment
            (rad); 0 draws nothing.
        random_walk : float
            rad/√s or m/s/√s.
        quantum : float
            Pulse weight; 0 disables quantization.

        Returns
        -------
        SensorErrorModel
            The drawn model.

        """
        if misalignment_sigma > 0:
            mis = rng.normal(0.0, misalignment_sigma, (3, 3))
        else:
            mis = np.zeros((3, 3))
        np.fill_diagonal(mis, 0.0)
        bias = rng.normal(0.0, bias_sigma, 3) if bias_sigma > 0 else np.zeros(3)
        scale = rng.normal(0.0, scale_sigma, 3) if scale_sigma > 0 else np.zeros(3)
        return cls(bias=bias, scale_factor=scale, misalignment=mis, random_walk=random_walk,
                   quantum=quantum)


class PulseQuantizer:
    """
    Per-axis pulse generator with carried remainder (000 eq. 5.1).

    Parameters
    ----------
    quantum : float
        Pulse weight σ, > 0.

    """

    def __init__(self, quantum: float):
        if not quantum > 0:
            raise ValueError('quantum must be > 0')
        self.quantum = float(quantum)
        self.integral = np.zeros(3)        # running integral A of the continuous signal
        self.level = np.zeros(3)           # last pulse level P (a multiple of σ)

    def __call__(self, increments: np.ndarray) -> np.ndarray:
        """
        Quantize a block of continuous increments.

        The play operator is sequential by nature; it runs over plain Python floats, the only
        per-sample loop in the simulator.

        Parameters
        ----------
        increments : (n, 3) ndarray
            Continuous (erroneous) increments.

        Returns
        -------
        (n, 3) ndarray
            Pulse sums, multiples of the quantum.

        """
        inc = np.asarray(increments, dtype=float)
        out = np.empty_like(inc)
        sigma = self.quantum
        for axis in range(3):
            a = float(self.integral[axis])
            p = float(self.level[axis])
            col = inc[:, axis].tolist()
            res = [0.0] * len(col)
            for i, d in enumerate(col):
                a += d
                gap = a - p
                if gap >= sigma or gap <= -sigma:
                    n = int(gap / sigma)           # truncation toward zero: |A − P_new| < σ
                    p += n * sigma
                    res[i] = n * sigma
            out[:, axis] = res
            self.integral[axis] = a
            self.level[axis] = p
        return out

    @property
    def remainder(self) -> np.ndarray:
        """Δθ_k of (5.1): integral since the last pulse."""
        return self.integral - self.level


def increment_correction(pulses: np.ndarray, quantum: float, previous_sign=None):
    """
    Correct quantized increments, 000 eq. (5.6).

    ``θ⁰_k = θ*_k + ½σ(sign θ*_k − sign θ*_{k−1})``, sign θ*_0 = 0.

    Parameters
    ----------
    pulses : (n, 3) ndarray
        Quantized increments θ*.
    quantum : float
        Pulse weight σ.
    previous_sign : (3,) array_like or None
        sign θ*_{k−1} carried across blocks (None: zeros).

    Returns
    -------
    tuple of ((n, 3) ndarray, (3,) ndarray)
        The corrected increments and the last sign.

    """
    pulses = np.asarray(pulses, dtype=float)
    s = np.sign(pulses)
    prev = np.zeros(3) if previous_sign is None else np.asarray(previous_sign, dtype=float)
    s_prev = np.vstack([prev[None, :], s[:-1]]) if len(s) else s
    return pulses + 0.5 * quantum * (s - s_prev), (s[-1].copy() if len(s) else prev)


class IntegratingSensor:
    """
    A sensor triad sampling one profile quantity on a uniform time grid.

    Sample k covers ``[t0 + (k−1)T, t0 + kT]`` and is stamped at its end.

    Parameters
    ----------
    profile : MotionProfile
        The exact motion (:mod:`strapdown_ros.motion.profiles`).
    kind : str
        ``'gyro'`` (``profile.delta_theta``) or ``'accel'`` (``profile.delta_v``).
    rate_hz : float
        Output rate, Hz.
    errors : SensorErrorModel or None
        Constant errors and noise (None: none).
    seed : int or None
        Seed of the noise stream.
    start_time : float
        t0, s of profile time.
    effects : GyroEffects or None
        Systematic effects of the registry (:class:`~strapdown_ros.sensors.effects.GyroEffects`);
        their epoch defaults to the first stamp.  Coupled effects receive the exact specific
        force of the profile integrated over each sample's interval (``profile.delta_v``),
        whatever the accelerometer rate.

    """

    def __init__(self, profile, kind: str, rate_hz: float, errors: SensorErrorModel | None = None,
                 seed: int | None = 0, start_time: float = 0.0, effects=None):
        if kind not in ('gyro', 'accel'):
            raise ValueError(f"kind must be 'gyro' or 'accel', got {kind!r}")
        if not (np.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f'rate_hz must be > 0, got {rate_hz}')
        self.profile = profile
        self.kind = kind
        self.period = 1.0 / float(rate_hz)
        self.errors = errors or SensorErrorModel()
        self.rng = np.random.default_rng(seed)
        self.start_time = float(start_time)
        self.count = 0
        self.quantizer = PulseQuantizer(self.errors.quantum) if self.errors.quantum > 0 else None
        # systematic effects of the registry (sensors.effects.GyroEffects), epoch = first stamp
        self.effects = effects if effects is not None and effects.active else None
        if self.effects is not None and self.effects.epoch is None:
            self.effects.epoch = self.start_time + self.period

    def epochs(self, n: int) -> np.ndarray:
        """
        Return the end times of the next n samples (does not advance).

        Parameters
        ----------
        n : int
            Number of samples.

        Returns
        -------
        (n,) ndarray
            Stamps, s.

        """
        k = self.count + np.arange(1, n + 1)
        return self.start_time + k * self.period

    def _grid(self, n: int) -> np.ndarray:
        """Start of the next sample and the end times of the next n, s (n + 1,)."""
        return self.start_time + (self.count + np.arange(0, n + 1)) * self.period

    def true_increments(self, n: int):
        """
        Return the exact increments of the next n samples (does not advance).

        Parameters
        ----------
        n : int
            Number of samples.

        Returns
        -------
        tuple of ((n,) ndarray, (n, 3) ndarray)
            End stamps (s) and exact increments (rad or m/s).

        """
        t = self._grid(n)
        f = self.profile.delta_theta if self.kind == 'gyro' else self.profile.delta_v
        return t[1:], f(t[:-1], t[1:])

    def sample(self, n: int):
        """
        Advance by n samples.

        Parameters
        ----------
        n : int
            Number of samples.

        Returns
        -------
        tuple of ((n,) ndarray, (n, 3) ndarray, (n, 3) ndarray)
            End times (s), measured and true increments.

        """
        t_end, true = self.true_increments(n)
        e = self.errors
        u = true
        if self.effects is not None:
            dv = None
            if self.effects.needs_delta_v:
                t = self._grid(n)
                dv = self.profile.delta_v(t[:-1], t[1:])
            u = self.effects.apply(true, t_end, self.period, delta_v=dv)
        meas = u @ (np.eye(3) + e.matrix).T + e.bias * self.period
        if e.random_walk > 0:
            meas = meas + self.rng.normal(0.0, e.random_walk * np.sqrt(self.period), meas.shape)
        if self.quantizer is not None:
            meas = self.quantizer(meas)
        self.count += n
        return t_end, meas, true


def increment_covariance(increments: np.ndarray, period: float, bias_sigma: float,
                         scale_sigma: float, misalignment_sigma: float,
                         random_walk: float) -> np.ndarray:
    """
    Return the covariance P_ρk of the error of each increment, 004 §2.1.

    ``P_ρk = σ_φ² diag(ρy²+ρz², ρx²+ρz², ρx²+ρy²) + σ_k² diag(ρx², ρy², ρz²)
    + (σ_b T)² I + σ_w² T I``.

    Parameters
    ----------
    increments : (n, 3) ndarray
        Increments ρ_k, rad.
    period : float or (n,) ndarray
        Interval lengths T, s.
    bias_sigma, scale_sigma, misalignment_sigma, random_walk : float
        σ_b (rad/s), σ_k, σ_φ (rad), σ_w (rad/√s).

    Returns
    -------
    (n, 3, 3) ndarray
        The covariances, rad².

    """
    r2 = np.asarray(increments, dtype=float) ** 2
    total = r2.sum(-1, keepdims=True)
    period = np.asarray(period, dtype=float)[..., None]        # scalar or one per increment
    d = (misalignment_sigma ** 2 * (total - r2) + scale_sigma ** 2 * r2
         + (bias_sigma * period) ** 2 + random_walk ** 2 * period)
    out = np.zeros(r2.shape[:-1] + (3, 3))
    idx = np.arange(3)
    out[..., idx, idx] = d
    return out
