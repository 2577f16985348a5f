"""
Small parts of the attitude filter (:mod:`strapdown_ros.estimation.attitude_filter`).

The names of its augmentable states and their layout in the error state, the square-root
covariance factors, and the result and counter records.  No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property, lru_cache
import math

import numpy as np

from strapdown_ros.sensors.effects import EFFECTS
from strapdown_ros.sensors.sensor_model import augment_choices

__all__ = ['AUGMENT_CHOICES', 'FILTER_STATES', 'augment_names', 'augment_error',
           'triangular_factor', 'psd_factor', 'FixResult', 'FilterCounters', 'StateLayout',
           'StateReport', 'ReportBatch', 'checked_fix']


def checked_fix(stamp: float, attitude, covariance):
    """
    Check a camera fix the attitude filter is given.

    Parameters
    ----------
    stamp : float
        Header stamp, s.
    attitude : array_like (4,)
        ``q_GCRS_VF``, scalar-first, unit within 1e-3.
    covariance : array_like (3, 3)
        Its covariance in VF axes, rad².

    Returns
    -------
    q : ndarray (4,)
        The attitude as given.
    R : ndarray (3, 3)
        The covariance, symmetrised.

    Raises
    ------
    ValueError
        The attitude is not a finite unit quaternion, the covariance not finite or not positive
        definite, or the stamp not finite.

    """
    q = np.asarray(attitude, dtype=float)
    R = np.asarray(covariance, dtype=float)
    if q.shape != (4,) or not all(map(math.isfinite, q.tolist())) \
            or abs(math.sqrt(float(q @ q)) - 1.0) > 1e-3:        # (np.linalg.norm's formula)
        raise ValueError('the fix attitude must be a finite unit quaternion [w, x, y, z]')
    if R.shape != (3, 3) or not all(map(math.isfinite, R.ravel().tolist())):
        raise ValueError('the fix covariance must be a finite 3x3 matrix')
    R = 0.5 * (R + R.T)
    if not _clearly_positive_definite(R.tolist()) and np.linalg.eigvalsh(R)[0] <= 0:
        raise ValueError('the fix covariance must be positive definite')
    if not math.isfinite(stamp):
        raise ValueError('the fix stamp must be finite')
    return q, R


def _clearly_positive_definite(e: list) -> bool:
    """
    Tell whether a symmetric 3×3 matrix (rows of floats) is positive definite by a wide margin.

    Gershgorin: every eigenvalue is at least min_i (e_ii − Σ_{j≠i} |e_ij|); above 1e-9 of the
    largest diagonal element, far above the round-off of an eigenvalue solver, so
    ``eigvalsh`` would find the smallest eigenvalue positive too (the answer is the same,
    without its cost).  False says nothing: the caller asks ``eigvalsh``.
    """
    top = max(e[0][0], e[1][1], e[2][2])
    low = min(e[0][0] - abs(e[0][1]) - abs(e[0][2]), e[1][1] - abs(e[1][0]) - abs(e[1][2]),
              e[2][2] - abs(e[2][0]) - abs(e[2][1]))
    return top > 0.0 and low > 1e-9 * top


def triangular_factor(*blocks: np.ndarray) -> np.ndarray:
    """
    Return a square factor S with S Sᵀ = Σ B Bᵀ, from the QR factorisation of [B₁ B₂ …]ᵀ.

    Parameters
    ----------
    *blocks : ndarray (n, k_i)
        Factors of the terms of a sum of covariances.

    Returns
    -------
    ndarray (n, n)
        S (lower triangular), so that S Sᵀ is positive semi-definite by construction.

    """
    # mode 'raw' is the factorisation of mode 'r' without its triu: LAPACK's output
    # transposed, Rᵀ in its lower triangle
    h, _ = np.linalg.qr(np.hstack(blocks).T, mode='raw')
    n, k = h.shape[0], min(h.shape)
    return np.where(_lower_triangle(n, k), h[:, :k], 0.0)


@lru_cache(maxsize=64)
def _lower_triangle(n: int, k: int) -> np.ndarray:
    """Return the (n, k) mask of the lower triangle (read-only: it is shared)."""
    mask = np.tri(n, k, dtype=bool)
    mask.flags.writeable = False
    return mask


def psd_factor(Q: np.ndarray) -> np.ndarray:
    """
    Return a factor B with B Bᵀ = Q of a symmetric positive semi-definite Q.

    Parameters
    ----------
    Q : ndarray (n, n)
        Covariance; eigenvalues below zero by round-off are taken as zero.

    Returns
    -------
    ndarray (n, n)
        B = V diag(√λ).

    """
    w, v = np.linalg.eigh(0.5 * (Q + Q.T))
    return v * np.sqrt(np.clip(w, 0.0, None))


@dataclass
class FixResult:
    """
    Outcome of one camera fix.

    Parameters
    ----------
    stamp : float
        Header stamp of the fix, s.
    epoch : float
        IMU-clock epoch it was applied at (stamp − τ̂), s.
    status : str
        ``applied``, ``gated``, ``reset`` (divergence: the attitude re-initialised from this
        fix), ``pending``, ``too_old`` or ``overflow``.
    lateness : float
        Newest increment stamp − epoch at arrival (0: not late), s.
    residual : ndarray (3,), optional
        The residual z, VF axes, rad.
    nis : float, optional
        zᵀ S⁻¹ z.
    innovation_covariance : ndarray (3, 3), optional
        S = H P Hᵀ + R, rad².
    jacobian : ndarray (3, n), optional
        The fix Jacobian H of the error state (applied or gated fixes).
    gain : ndarray (n, 3), optional
        The gain K the fix was applied with (applied fixes; the live model check runs the
        effects' signatures through it).
    reason : str
        Why divergence was declared (status ``reset``), else empty.

    """

    stamp: float
    epoch: float
    status: str
    lateness: float = 0.0
    residual: np.ndarray | None = None
    nis: float | None = None
    innovation_covariance: np.ndarray | None = None
    jacobian: np.ndarray | None = None
    gain: np.ndarray | None = None
    reason: str = ''


@dataclass(slots=True)
class StateReport:
    """
    The filter's state at one increment stamp (a mark of ``AttitudeFilter.propagate``).

    Parameters
    ----------
    stamp : float
        The increment's end stamp, s.
    attitude : ndarray (4,)
        ``q_ref_body`` there, scalar-first.
    covariance : ndarray (n, n)
        The error-state covariance there.
    states : ndarray (n,)
        The estimates of the filter states there (layout order).
    boresight : ndarray (4,)
        ``q_MF_VF``, scalar-first.

    """

    stamp: float
    attitude: np.ndarray
    covariance: np.ndarray
    states: np.ndarray
    boresight: np.ndarray


@dataclass(slots=True)
class ReportBatch:
    """
    The filter's states at K increment stamps, as arrays (rows in stamp order).

    Parameters
    ----------
    stamps : ndarray (K,)
        The increments' end stamps, s.
    attitude : ndarray (K, 4)
        ``q_ref_body`` there, scalar-first.
    covariance : ndarray (K, n, n)
        The error-state covariance there.
    states : ndarray (K, n)
        The estimates of the filter states there (layout order).
    boresight : ndarray (K, 4)
        ``q_MF_VF``, scalar-first.

    """

    stamps: np.ndarray
    attitude: np.ndarray
    covariance: np.ndarray
    states: np.ndarray
    boresight: np.ndarray

    def __len__(self) -> int:
        """Return K, the number of stamps."""
        return len(self.stamps)

    @classmethod
    def joined(cls, parts, n: int) -> ReportBatch:
        """
        Return the batches ``parts`` one after the other (an empty batch of n states if none).

        Parameters
        ----------
        parts : list of ReportBatch
            In stamp order.
        n : int
            The number of filter states.

        Returns
        -------
        ReportBatch
            Their rows, in order.

        """
        if len(parts) == 1:
            return parts[0]
        if not parts:
            return cls(np.zeros(0), np.zeros((0, 4)), np.zeros((0, n, n)), np.zeros((0, n)),
                       np.zeros((0, 4)))
        return cls(*(np.concatenate([getattr(b, f) for b in parts]) for f in cls.__slots__))

    def reports(self) -> list[StateReport]:
        """
        Return one :class:`StateReport` per row.

        Returns
        -------
        list of StateReport
            In stamp order.

        """
        return list(map(StateReport, self.stamps.tolist(), self.attitude, self.covariance,
                        self.states, self.boresight))


@dataclass
class FilterCounters:
    """
    Counts of what the filter did (reported; a node puts them on /diagnostics).

    Parameters
    ----------
    applied, gated, late, too_old, pending_overflow : int
        Fixes applied, gated, late, older than the history, dropped from a full queue.
    reprocessed_increments : int
        Increments processed again for late fixes.
    max_lateness, last_lateness : float
        Largest and last lateness of a late fix, s.
    implausible : int
        Updates after which an estimate left its registry range.
    resets : int
        Divergences declared (the attitude re-initialised from a fix).
    last_reset : float
        Epoch of the last reset, s (NaN: none).

    """

    applied: int = 0
    gated: int = 0
    late: int = 0
    too_old: int = 0
    pending_overflow: int = 0
    reprocessed_increments: int = 0
    max_lateness: float = 0.0
    last_lateness: float = 0.0
    implausible: int = 0
    resets: int = 0
    last_reset: float = float('nan')


#: names the ``augment`` argument accepts besides the registry's gyro effects
FILTER_STATES = ('time_offset', 'boresight')
#: names the filter's ``augment`` parameter accepts: the registry's filter states (the bias is
#: always a state), then the boresight (read from the registry when imported; the registry's
#: own :func:`~strapdown_ros.sensors.sensor_model.augment_choices` is read at each use)
AUGMENT_CHOICES = augment_choices()


def augment_names(text: str) -> tuple:
    """
    Return the names of a comma-separated ``augment`` value (blanks ignored).

    Parameters
    ----------
    text : str
        The parameter value, e.g. ``"gyro_scale_factor, time_offset"``.

    Returns
    -------
    tuple of str
        The names.

    """
    return tuple(n.strip() for n in str(text).split(',') if n.strip())


def augment_error(text: str) -> str | None:
    """
    Return the one-line error of an ``augment`` value naming the valid names.

    Parameters
    ----------
    text : str
        The parameter value.

    Returns
    -------
    str or None
        The error, or None when the value is valid.

    """
    names = augment_names(text)
    choices = augment_choices()
    bad = [n for n in names if n not in choices]
    if bad:
        return (f"augment: unknown state {bad[0][:80]!r}; valid: {', '.join(choices)}")
    if len(set(names)) != len(names):
        return 'augment: a name is given twice'
    return None


@dataclass
class StateLayout:
    """
    Where each group of states sits in the filter's error state.

    The order: ε (3), the gyro states contiguous (bias first), the time offset, the boresight.

    Parameters
    ----------
    gyro : list of (Effect, slice)
        The gyro effects with states and their slices, ``gyro_bias`` first.
    time_offset : slice, optional
        The camera time offset's state (1, s).
    boresight : slice, optional
        The boresight error's states (3, rad, VF axes).
    size : int
        Length of the error state.

    """

    gyro: list = field(default_factory=list)
    time_offset: slice | None = None
    boresight: slice | None = None
    size: int = 6

    @classmethod
    def build(cls, augment, params=None) -> StateLayout:
        """
        Lay out the attitude error, the bias and the augmented states.

        Parameters
        ----------
        augment : tuple of str
            Further states: systematic gyro effects of the registry, ``time_offset``,
            ``boresight`` (:data:`AUGMENT_CHOICES`).
        params : mapping or SensorModel, optional
            The model the effects are set up from (their other parameters, e.g. a period).

        Returns
        -------
        StateLayout
            The layout.

        Raises
        ------
        ValueError
            A name unknown, unsupported or given twice (the bias is always a state).

        """
        lay = cls(gyro=[(EFFECTS['gyro_bias'], slice(3, 6))], size=6)
        gyro = [n for n, e in EFFECTS.items() if e.sensor == 'gyro' and e.filter_state]
        if len(set(augment)) != len(augment) or 'gyro_bias' in augment:
            raise ValueError('augment: a name given twice (the bias is always a state)')
        valid = augment_choices()
        for name in augment:
            if name not in valid:
                raise ValueError(f'augment: unknown or unsupported state {name!r}; valid: '
                                 f"{', '.join(valid)}")
        for name in (n for n in augment if n in gyro):
            e = EFFECTS[name] if params is None else EFFECTS[name].configured(params)
            lay.gyro.append((e, slice(lay.size, lay.size + e.filter_size())))
            lay.size += e.filter_size()
        if 'time_offset' in augment:
            lay.time_offset = slice(lay.size, lay.size + 1)
            lay.size += 1
        if 'boresight' in augment:
            lay.boresight = slice(lay.size, lay.size + 3)
            lay.size += 3
        return lay

    @cached_property
    def _slices(self) -> dict:
        """Return the state groups by name (:meth:`named_slices`; fixed once built)."""
        return dict(self.named_slices())

    @cached_property
    def _bounded(self) -> list:
        """Return (effect, slice, registry parameter) of the states :meth:`implausible` checks."""
        named = [(e, sl) for e, sl in self.gyro]
        if self.time_offset is not None:
            named.append((EFFECTS['time_offset'], self.time_offset))
        return [(e, sl, e.value_parameter) for e, sl in named
                if e.value_parameter.minimum is not None
                or e.value_parameter.maximum is not None]

    def named_slices(self) -> list:
        """
        Return the augmented state groups by name, bias included, ε excluded.

        Returns
        -------
        list of (str, slice)
            ``(name, slice)`` in the layout's order.

        """
        out = [(e.name, sl) for e, sl in self.gyro]
        if self.time_offset is not None:
            out.append(('time_offset', self.time_offset))
        if self.boresight is not None:
            out.append(('boresight', self.boresight))
        return out

    def slice_of(self, name: str) -> slice:
        """
        Return the slice of one state group.

        Parameters
        ----------
        name : str
            ``gyro_bias``, an augmented gyro effect, ``time_offset`` or ``boresight``.

        Returns
        -------
        slice
            Its place in the error state.

        Raises
        ------
        ValueError
            ``name`` is not a state of this layout.

        """
        sl = self._slices.get(name)
        if sl is None:
            raise ValueError(f'{name!r} is not a state of this filter')
        return sl

    def implausible(self, x: np.ndarray) -> list:
        """
        Return the names of the estimates outside the valid range of their registry parameter.

        Parameters
        ----------
        x : ndarray (size,)
            The estimates of the filter states, in this layout.

        Returns
        -------
        list of str
            Effect names (gyro effects and the time offset).

        """
        out = []
        for e, sl, p in self._bounded:
            v = (e.filter_values(x[sl]) if e.sensor == 'gyro' else x[sl]).tolist()
            lo, hi = p.minimum, p.maximum              # (floats: a few values each)
            if (lo is not None and any(u < lo for u in v)) or \
                    (hi is not None and any(u > hi for u in v)):
                out.append(e.name)
        return out
