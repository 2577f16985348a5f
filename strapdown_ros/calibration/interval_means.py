"""
Mean true and mean measured rates over averaging intervals (Ilyushenko 2009, paper 002).

The data of 002's system B·w̄ + s0 = s̄: the averaging intervals between star-tracker fixes,
the mean true rate w̄ from the fixes (through
:mod:`strapdown_ros.calibration.star_tracker_increments`), the mean measured rate s̄ from the
gyro increments, and the covariances of both from camera noise and gyro random walk.  Solved
by :mod:`strapdown_ros.calibration.integral_method`; the noise model is derived in
doc/integral_method.md.  No ROS; numpy only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.calibration.star_tracker_increments import noise_jacobians, step_increments

__all__ = ['IntervalMeans', 'camera_rate_covariance', 'gyro_nodes', 'gyro_rate_covariance',
           'interval_boundaries', 'mean_measured_rate', 'mean_true_rate']


# ------------------------------------------------------------------ intervals and means
def interval_boundaries(stamps: np.ndarray, steps_per_interval: int | None = None,
                        interval_length: float | None = None,
                        gap_factor: float = 3.0) -> np.ndarray:
    """
    Return consecutive averaging intervals as fix-index pairs.

    Give exactly one of ``steps_per_interval`` and ``interval_length``.  A short remainder
    before a gap or at the end is dropped.

    Parameters
    ----------
    stamps : (N,) ndarray
        Strictly increasing stamps of the camera fixes, s.
    steps_per_interval : int, optional
        Camera steps per interval.
    interval_length : float, optional
        Interval length, s: an interval ends at the first fix at least that long after its
        start.
    gap_factor : float
        Steps longer than this many median steps are data gaps; no interval spans one.

    Returns
    -------
    (K, 2) int ndarray
        Interval i spans fixes a..b.

    """
    stamps = np.asarray(stamps, dtype=float)
    if len(stamps) < 2:
        return np.zeros((0, 2), dtype=int)
    if (steps_per_interval is None) == (interval_length is None):
        raise ValueError('give exactly one of steps_per_interval and interval_length')
    dt = np.diff(stamps)
    if np.any(dt <= 0):
        raise ValueError('camera stamps must be strictly increasing')
    gap = dt > gap_factor * np.median(dt)
    out = []
    a, n = 0, len(stamps)
    while a < n - 1:
        if gap[a]:
            a += 1
            continue
        b, full = a, False
        while b < n - 1 and not gap[b]:
            b += 1
            long_enough = (interval_length is not None
                           and stamps[b] - stamps[a] >= interval_length * (1 - 1e-9))
            if (steps_per_interval is not None and b - a >= steps_per_interval) or long_enough:
                full = True
                break
        if full:
            out.append((a, b))
        a = b                          # a short remainder before a gap or the end is dropped
    return np.array(out, dtype=int).reshape(-1, 2)


def mean_true_rate(stamps: np.ndarray, quats: np.ndarray, intervals=None, order: int = 3,
                   form: str = 'paper', steps_per_interval: int | None = None,
                   interval_length: float | None = None, gap_factor: float = 3.0,
                   neighbour: str = 'previous'):
    """
    Return the mean true body rate w̄ over averaging intervals, from star-tracker attitudes.

    w̄_i = Σ_{n=a+1}^{b} V_n / (t_b − t_a), V_n from
    :func:`~strapdown_ros.calibration.star_tracker_increments.step_increments`.

    Parameters
    ----------
    stamps : (N,) ndarray
        Stamps of the fixes, s.
    quats : (N, 4) ndarray
        Attitudes q_ref_body of the fixes, scalar first.
    intervals : (K, 2) int ndarray, optional
        Fix-index pairs; default :func:`interval_boundaries` with ``steps_per_interval`` or
        ``interval_length`` (one step per interval if neither is given).  Must not span a gap.
    order, form, neighbour
        Passed to ``step_increments``.
    steps_per_interval : int, optional
        Camera steps per interval.
    interval_length : float, optional
        Interval length, s.
    gap_factor : float
        Steps longer than this many median steps are data gaps: the coning correction does
        not reach across them.

    Returns
    -------
    tuple
        ``(t0 (K,), t1 (K,), w̄ (K, 3) rad/s, intervals (K, 2))``.

    """
    stamps = np.asarray(stamps, dtype=float)
    if intervals is None:
        if steps_per_interval is None and interval_length is None:
            steps_per_interval = 1
        intervals = interval_boundaries(stamps, steps_per_interval, interval_length, gap_factor)
    intervals = np.asarray(intervals, dtype=int).reshape(-1, 2)
    dt = np.diff(stamps)
    gap = dt > gap_factor * np.median(dt) if len(dt) else np.zeros(0, dtype=bool)
    V = step_increments(quats, order=order, form=form, breaks=gap, neighbour=neighbour)
    cum = np.vstack([np.zeros((1, 3)), np.cumsum(V, axis=0)])
    t0, t1 = stamps[intervals[:, 0]], stamps[intervals[:, 1]]
    if np.any(t1 <= t0):
        raise ValueError('every interval needs t1 > t0')
    w = (cum[intervals[:, 1]] - cum[intervals[:, 0]]) / (t1 - t0)[:, None]
    return t0, t1, w, intervals


def gyro_nodes(gyro_stamps: np.ndarray, delta_theta: np.ndarray):
    """
    Return the epochs and the cumulative angle of a run of gyro increments.

    Parameters
    ----------
    gyro_stamps : (n,) ndarray
        Strictly increasing stamps, s, each at the end of its increment.
    delta_theta : (n, 3) ndarray
        Gyro increments, rad.

    Returns
    -------
    nodes : (n + 1,) ndarray
        Epochs, s: the start of the first increment (one period before its stamp), then
        the stamps.
    cum : (n + 1, 3) ndarray
        Σ Δθ up to each epoch, rad.

    Raises
    ------
    ValueError
        Fewer than two increments, or stamps not increasing.

    """
    s = np.asarray(gyro_stamps, dtype=float)
    d = np.asarray(delta_theta, dtype=float).reshape(-1, 3)
    if len(s) != len(d) or len(s) < 2:
        raise ValueError('need at least two gyro increments with one stamp each')
    if np.any(np.diff(s) <= 0):
        raise ValueError('gyro stamps must be strictly increasing')
    first = s[0] - (s[1] - s[0])       # the first increment covers one period before its stamp
    nodes = np.concatenate([[first], s])
    cum = np.vstack([np.zeros((1, 3)), np.cumsum(d, axis=0)])
    return nodes, cum


def mean_measured_rate(gyro_stamps: np.ndarray, delta_theta: np.ndarray, t0, t1,
                       interpolation: str = 'linear') -> np.ndarray:
    """
    Return s̄ = ∫s dt / T over [t0, t1] from gyro increments.

    The cumulative angle Θ(t) = Σ Δθ is known exactly at the gyro epochs and interpolated
    between them.  When t0, t1 fall on gyro epochs the result is the exact sum of the
    increments.  Vectorised over t0, t1.

    Parameters
    ----------
    gyro_stamps : (n,) ndarray
        Stamps, s, each at the end of its increment.
    delta_theta : (n, 3) ndarray
        Gyro increments, rad.
    t0, t1 : float or (K,) ndarray
        Interval ends, s, inside the span of the gyro data.
    interpolation : {'linear', 'quadratic'}
        'linear': rate constant within a gyro interval (error ≤ |ṡ|h_g²/8 at each end);
        'quadratic': through the three nearest epochs (error O(s̈ h_g³)).

    Returns
    -------
    (K, 3) ndarray
        s̄, rad/s.

    """
    nodes, cum = gyro_nodes(gyro_stamps, delta_theta)
    t0 = np.atleast_1d(np.asarray(t0, dtype=float))
    t1 = np.atleast_1d(np.asarray(t1, dtype=float))
    tol = 1e-9 * (nodes[-1] - nodes[0])
    if np.any(t0 < nodes[0] - tol) or np.any(t1 > nodes[-1] + tol):
        raise ValueError('interval outside the span of the gyro data')
    return (_cumulative_angle(nodes, cum, t1, interpolation)
            - _cumulative_angle(nodes, cum, t0, interpolation)) / (t1 - t0)[:, None]


def _cumulative_angle(nodes, cum, t, interpolation):
    t = np.clip(t, nodes[0], nodes[-1])
    j = np.clip(np.searchsorted(nodes, t, side='right') - 1, 0, len(nodes) - 2)
    # snap to a node within round-off (camera and gyro epochs often coincide)
    span = nodes[j + 1] - nodes[j]
    x = (t - nodes[j]) / span
    x = np.where(np.abs(x) < 1e-9, 0.0, np.where(np.abs(x - 1) < 1e-9, 1.0, x))
    if interpolation == 'linear' or len(nodes) < 3:
        return cum[j] + x[:, None] * (cum[j + 1] - cum[j])
    if interpolation != 'quadratic':
        raise ValueError(f"interpolation must be 'linear' or 'quadratic', got {interpolation!r}")
    # three nodes k, k+1, k+2 around t: prefer the neighbour on the side of t
    k = np.where(x < 0.5, j - 1, j)
    k = np.clip(k, 0, len(nodes) - 3)
    ta, tb, tc = nodes[k], nodes[k + 1], nodes[k + 2]
    la = (t - tb) * (t - tc) / ((ta - tb) * (ta - tc))
    lb = (t - ta) * (t - tc) / ((tb - ta) * (tb - tc))
    lc = (t - ta) * (t - tb) / ((tc - ta) * (tc - tb))
    out = la[:, None] * cum[k] + lb[:, None] * cum[k + 1] + lc[:, None] * cum[k + 2]
    exact = (x == 0.0) | (x == 1.0)
    out[exact] = np.where((x[exact] == 0.0)[:, None], cum[j[exact]], cum[j[exact] + 1])
    return out


# ------------------------------------------------------------------ noise covariances
def _camera_covariances(n: int, camera_sigma=None, camera_covariance=None, c_body_camera=None):
    if camera_covariance is not None:
        P = np.asarray(camera_covariance, dtype=float)
        P = np.broadcast_to(P, (n, 3, 3)) if P.shape == (3, 3) else P.reshape(n, 3, 3)
    else:
        sig = np.asarray(0.0 if camera_sigma is None else camera_sigma, dtype=float)
        sig = np.broadcast_to(sig, (3,))
        P = np.broadcast_to(np.diag(sig ** 2), (n, 3, 3))
    if c_body_camera is not None:
        C = np.asarray(c_body_camera, dtype=float)
        P = C @ P @ C.T
    return P


def camera_rate_covariance(quats: np.ndarray, intervals: np.ndarray, stamps: np.ndarray,
                           camera_sigma=None, camera_covariance=None,
                           c_body_camera: np.ndarray | None = None) -> np.ndarray:
    """
    Return the covariance of the errors of the mean true rates w̄ caused by camera noise.

    Camera noise: right-perturbations θ_n of the fixes.  Linearised through
    :func:`~strapdown_ros.calibration.star_tracker_increments.noise_jacobians`, exact in the
    interval structure: intervals sharing fixes are correlated.

    Parameters
    ----------
    quats : (N, 4) ndarray
        Attitudes q_ref_body of the fixes, scalar first.
    intervals : (K, 2) int ndarray
        Fix-index pairs.
    stamps : (N,) ndarray
        Stamps of the fixes, s.
    camera_sigma : float or (3,) array_like, optional
        1σ per camera axis, rad.
    camera_covariance : (3, 3) or (N, 3, 3) array_like, optional
        Covariance of θ_n, camera axes, rad² (instead of ``camera_sigma``).
    c_body_camera : (3, 3) ndarray, optional
        DCM rotating camera axes into body axes.

    Returns
    -------
    (3K, 3K) ndarray
        Covariance of the stacked w̄, (rad/s)².

    """
    quats = np.asarray(quats, dtype=float)
    intervals = np.asarray(intervals, dtype=int).reshape(-1, 2)
    stamps = np.asarray(stamps, dtype=float)
    N = len(quats)
    P = _camera_covariances(N, camera_sigma, camera_covariance, c_body_camera)
    Jp, Jm = noise_jacobians(quats)                       # per step n = 1..N−1 at index n−1
    K = len(intervals)
    T = stamps[intervals[:, 1]] - stamps[intervals[:, 0]]
    blocks = []
    for a, b in intervals:                                  # G_ik for fixes k = a..b
        G = np.zeros((b - a + 1, 3, 3))
        G[1:] += Jp[a:b]                                    # fix k ends step k (k > a)
        G[:-1] += Jm[a:b]                                   # fix k starts step k+1 (k < b)
        blocks.append(G)
    R = np.zeros((3 * K, 3 * K))
    a_all, b_all = intervals[:, 0], intervals[:, 1]
    for i in range(K):
        lo = np.maximum(a_all[i], a_all[i:])
        hi = np.minimum(b_all[i], b_all[i:])
        for jj in np.nonzero(lo <= hi)[0]:
            j = i + jj
            l, h = lo[jj], hi[jj]
            Gi = blocks[i][l - a_all[i]:h - a_all[i] + 1]
            Gj = blocks[j][l - a_all[j]:h - a_all[j] + 1]
            blk = np.einsum('kab,kbc,kdc->ad', Gi, P[l:h + 1], Gj) / (T[i] * T[j])
            R[3 * i:3 * i + 3, 3 * j:3 * j + 3] = blk
            R[3 * j:3 * j + 3, 3 * i:3 * i + 3] = blk.T
    return R


def gyro_rate_covariance(t0: np.ndarray, t1: np.ndarray, random_walk: float) -> np.ndarray:
    """
    Return the covariance of the mean measured rates from angle random walk.

    σ_rw²·|overlap(i, j)|/(T_i T_j) per axis; partial gyro intervals are ignored.

    Parameters
    ----------
    t0, t1 : (K,) ndarray
        Interval ends, s.
    random_walk : float
        Angle random walk σ_rw, rad/√s.

    Returns
    -------
    (3K, 3K) ndarray
        Covariance of the stacked s̄, (rad/s)².

    """
    t0 = np.asarray(t0, dtype=float)
    t1 = np.asarray(t1, dtype=float)
    ov = np.clip(np.minimum(t1[:, None], t1[None]) - np.maximum(t0[:, None], t0[None]), 0.0, None)
    T = t1 - t0
    return np.kron(random_walk ** 2 * ov / np.outer(T, T), np.eye(3))


# ------------------------------------------------------------------ the data of the system
@dataclass
class IntervalMeans:
    """
    The data of 002's system: per interval, mean true and mean measured rates.

    Attributes
    ----------
    t0, t1 : (K,) ndarray
        Interval ends, s.
    w_bar : (K, 3) ndarray
        Mean true rate from the star tracker, body axes, rad/s.
    s_bar : (K, 3) ndarray
        Mean measured rate from the gyro, rad/s.
    camera_covariance : (3K, 3K) ndarray or None
        Covariance of the errors of w̄, (rad/s)².
    gyro_covariance : (3K, 3K) ndarray or None
        Covariance of the errors of s̄, (rad/s)².
    intervals : (K, 2) int ndarray or None
        Fix indices of the intervals.
    w_bar_exact : (K, 3) ndarray or None
        Exact ∫w dt / T when a motion profile is known, rad/s.

    """

    t0: np.ndarray
    t1: np.ndarray
    w_bar: np.ndarray
    s_bar: np.ndarray
    camera_covariance: np.ndarray | None = None
    gyro_covariance: np.ndarray | None = None
    intervals: np.ndarray | None = None
    w_bar_exact: np.ndarray | None = None

    def __len__(self):
        return len(self.t0)
