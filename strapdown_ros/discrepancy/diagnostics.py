"""
Residual diagnostics of the discrepancy workflow: verdict tests, remaining structure, Allan.

The verdict tests, a description of what structure remains, a check for a gyro wiring fault,
and the Allan deviation of the gyro on static segments (measured against the model simulated
on the same segment).  Used by :mod:`strapdown_ros.discrepancy.workflow` and the report.
No ROS imports.

Verdict tests on the whitened residual w (3 per pair, ≈ iid N(0, 1) under an adequate model),
each at α/3 (Bonferroni over the three; the workflow passes its α/2 for the tests):

* **NIS**: Σ w² against χ²(n) two-sided;
* **whiteness**: Ljung–Box Q = n(n+2) Σ_{k≤h} ρ_k²/(n−k) per component, summed over the three
  components, against χ²(3h);
* **outliers**: the largest |w| against the maximum of n standard normals,
  p = 1 − (1 − 2Φ(−max|w|))ⁿ (004 Fig. 2a's spikes).
"""
from __future__ import annotations

import itertools

import numpy as np

from strapdown_ros.sensors.effects import EFFECTS, GyroEffects
from strapdown_ros.sensors.model import PulseQuantizer

__all__ = ['verdict_tests', 'autocorrelation', 'describe_remaining', 'static_segments',
           'allan_comparison', 'axis_swap_check', 'white_rate_variance', 'SWAP_RATIO']

#: a signed permutation of the gyro axes "explains" the residual when the axis-alignment RMS
#: with it is below this fraction of the RMS with the axes as wired
SWAP_RATIO = 0.3


def autocorrelation(x: np.ndarray, lags: int) -> np.ndarray:
    """
    Return the sample autocorrelation of a series at lags 1 … ``lags``.

    Parameters
    ----------
    x : (n,) array_like
        The series (its mean is removed).
    lags : int
        Largest lag.

    Returns
    -------
    (lags,) ndarray
        ρ_k; zeros for a constant or too short series.

    """
    x = np.asarray(x, dtype=float) - np.mean(x)
    d = float(x @ x)
    if d == 0 or len(x) < 2:
        return np.zeros(lags)
    return np.array([float(x[:-k] @ x[k:]) / d for k in range(1, lags + 1)])


def verdict_tests(whitened: np.ndarray, pairs: int, alpha: float, lags: int) -> dict:
    """
    Run the three verdict tests on the whitened residuals, each at ``alpha``/3.

    Parameters
    ----------
    whitened : array_like
        Whitened residuals w, 3 per pair.
    pairs : int
        Number of increment pairs.
    alpha : float
        Level of the three tests together (Bonferroni).
    lags : int
        Ljung–Box lags (at most a quarter of the pairs are used).

    Returns
    -------
    dict
        ``nis``, ``whiteness``, ``outliers`` (statistic, dof, p-value each), ``level``,
        ``passed`` (all three pass) and ``failed`` (their names).

    """
    from scipy.stats import chi2, norm

    w = np.asarray(whitened, dtype=float).reshape(-1)
    n = len(w)
    level = alpha / 3.0
    s = float(w @ w)
    p_nis = float(2.0 * min(chi2.cdf(s, n), chi2.sf(s, n)))
    W = w[: 3 * pairs].reshape(pairs, 3)
    m = len(W)
    h = max(1, min(lags, m // 4))
    Q = 0.0
    for c in range(3):
        rho = autocorrelation(W[:, c], h)
        Q += m * (m + 2) * float(np.sum(rho ** 2 / (m - np.arange(1, h + 1))))
    p_lb = float(chi2.sf(Q, 3 * h))
    zmax = float(np.max(np.abs(w))) if n else 0.0
    p_out = float(-np.expm1(n * np.log1p(-2.0 * norm.sf(zmax)))) if n else 1.0
    tests = {'nis': {'statistic': s, 'dof': n, 'p_value': p_nis, 'per_dof': s / max(n, 1)},
             'whiteness': {'statistic': Q, 'dof': 3 * h, 'lags': h, 'p_value': p_lb},
             'outliers': {'statistic': zmax, 'n': n, 'p_value': p_out}}
    tests['level'] = level
    tests['passed'] = bool(all(t['p_value'] >= level
                               for t in (tests['nis'], tests['whiteness'], tests['outliers'])))
    tests['failed'] = [k for k in ('nis', 'whiteness', 'outliers') if tests[k]['p_value'] < level]
    return tests


def describe_remaining(series: dict, lin=None) -> dict:
    """
    Describe the structure left in the residuals.

    Parameters
    ----------
    series : dict
        Per-pair arrays (:func:`strapdown_ros.discrepancy.result.residual_series`).
    lin : Linearisation, optional
        Unused; kept for the callers that pass it.

    Returns
    -------
    dict
        Dominant period and lag, correlation with rate, accumulated angle and rotation angle,
        where the largest whitened residuals are; its size per VF axis (``residual_rms_rad``,
        ``expected_rms_rad``, ``whitened_ms_by_axis``, ``largest_axis`` 0–2); its correlation
        in time per VF axis (``autocorrelation_by_axis``: the largest at lags 1–3,
        ``correlated_axis``); during fast
        motion (``fast_motion``: the fastest third of the pairs against the slowest) and at
        reversals of the turning sense (``reversals``).

    """
    t = np.asarray(series['t'], dtype=float)
    w = np.asarray(series['whitened'], dtype=float)
    out: dict = {}
    # dominant period: Lomb–Scargle over the three components
    if len(t) >= 8 and t[-1] > t[0]:
        from scipy.signal import lombscargle
        span = t[-1] - t[0]
        dt = float(np.median(np.diff(t)))
        periods = np.geomspace(max(4 * dt, 1e-3), span / 1.5, 300)
        power = np.zeros(len(periods))
        for c in range(3):
            y = w[:, c] - w[:, c].mean()
            if np.any(y):
                power += lombscargle(t, y, 2 * np.pi / periods, normalize=True)
        i = int(np.argmax(power))
        out['dominant_period_s'] = float(periods[i])
        out['dominant_period_power'] = float(power[i] / 3.0)
    lags = max(1, min(20, len(t) // 4))
    ac = np.mean([autocorrelation(w[:, c], lags) for c in range(3)], axis=0)
    k = int(np.argmax(np.abs(ac)))
    out['dominant_lag_pairs'] = k + 1
    out['dominant_lag_autocorrelation'] = float(ac[k])
    mag = np.linalg.norm(w, axis=1)
    for key, name in (('rate', 'correlation_with_rate'),
                      ('accumulated_angle', 'correlation_with_accumulated_angle'),
                      ('phi_cam', 'correlation_with_rotation_angle')):
        x = np.asarray(series.get(key, []), dtype=float)
        if len(x) == len(mag) and np.std(x) > 0 and np.std(mag) > 0:
            out[name] = float(np.corrcoef(x, mag ** 2)[0, 1])
    big = np.argsort(mag)[::-1][:5]
    out['largest_whitened_at_s'] = [float(t[i]) for i in big]
    out['largest_whitened'] = [float(mag[i]) for i in big]
    out.update(_where_it_is(series))
    return out


def _where_it_is(series: dict) -> dict:
    """
    Return the size, the axis and the motion of the structure left.

    Size per VF axis: the RMS residual against the RMS the model predicts, and the mean
    squared whitened residual (1 as the model predicts); the axis with the largest.  When: the
    mean squared whitened residual (per component) of the fastest third of the pairs (peak rate
    between the fixes) against the slowest third, and of the pairs with a reversal of the turning
    sense against those without.
    """
    out: dict = {}
    w = np.asarray(series['whitened'], dtype=float)
    if 'residual' in series and 'sigma' in series:
        r = np.asarray(series['residual'], dtype=float)
        sg = np.asarray(series['sigma'], dtype=float)
        out['residual_rms_rad'] = np.sqrt(np.mean(r ** 2, axis=0)).tolist()
        out['expected_rms_rad'] = np.sqrt(np.mean(sg ** 2, axis=0)).tolist()
    ms = np.mean(w ** 2, axis=0)
    out['whitened_ms_by_axis'] = ms.tolist()
    out['largest_axis'] = int(np.argmax(ms))
    # the correlated part: the autocorrelation at lags 1–3 per axis, and the share of the
    # residual's variance it implies (ρ of an AR(1) is the share of a slow part in white noise)
    lag = max(1, min(3, len(w) // 4))
    rho = np.array([np.max(autocorrelation(w[:, c], lag)) if len(w) > lag + 1 else 0.0
                    for c in range(3)])
    out['autocorrelation_by_axis'] = rho.tolist()
    out['correlated_axis'] = int(np.argmax(rho))
    per = np.mean(w ** 2, axis=1)
    peak = np.asarray(series.get('rate_peak', []), dtype=float)
    if len(peak) == len(per) and len(per) >= 6 and np.ptp(peak) > 0:
        lo, hi = np.percentile(peak, [100.0 / 3.0, 200.0 / 3.0])
        fast, slow = per[peak >= hi], per[peak <= lo]
        if len(fast) and len(slow):
            out['fast_motion'] = {'rate_above_rad_s': float(hi), 'rate_below_rad_s': float(lo),
                                  'ms_fast': float(np.mean(fast)),
                                  'ms_slow': float(np.mean(slow)),
                                  'ratio': float(np.mean(fast) / max(np.mean(slow), 1e-300))}
    rev = np.asarray(series.get('reversals', []), dtype=float)
    if len(rev) == len(per) and len(per):
        with_r = rev > 0
        entry = {'pairs': int(np.sum(with_r)), 'fraction': float(np.mean(with_r))}
        if 0 < np.sum(with_r) < len(per):
            entry.update({'ms_with': float(np.mean(per[with_r])),
                          'ms_without': float(np.mean(per[~with_r])),
                          'ratio': float(np.mean(per[with_r])
                                         / max(np.mean(per[~with_r]), 1e-300))})
        out['reversals'] = entry
    return out


# ----------------------------------------------------------------------------- wiring
def axis_swap_check(rotvec_imu: np.ndarray, rotvec_cam: np.ndarray) -> dict:
    """
    Check whether a gyro wiring fault (axes swapped or a sign reversed) explains the residual.

    Re-fits the closed-form axis alignment (Wahba/SVD, a proper rotation C: min Σ|C·P·u − v|²)
    of the gyro pair increments u, their axes mapped by each of the 47 non-identity signed
    permutations P, to the camera increments v, and compares the RMS misfit with that of the
    axes as wired.  A proper P is a rotation the boresight absorbs; an improper one (a swap or a
    single sign) is what no boresight can; which axis is at fault the camera cannot tell (all
    improper mappings are equal up to a rotation), only that the triad as wired is left-handed.

    Parameters
    ----------
    rotvec_imu, rotvec_cam : numpy.ndarray
        (N, 3) rotation vectors of the gyro (MF axes) and camera (VF axes) pair increments, rad.

    Returns
    -------
    dict
        ``gyro_axis_swap_sign``: {``explains``, ``permutation`` (rows: new axis from old, signed;
        of the mappings equal up to a rotation, the one with the fewest axes changed),
        ``mapping`` (in words, e.g. "x ← +y, y ← +x, z ← +z"), ``rms_as_wired_rad``,
        ``rms_best_rad``, ``ratio``}; when it explains,
        ``candidate_explanations`` = ["gyro axis swap/sign"].

    """
    u = np.asarray(rotvec_imu, dtype=float)
    v = np.asarray(rotvec_cam, dtype=float)

    def misfit(x):
        U, _, Vt = np.linalg.svd(v.T @ x)
        d = np.sign(np.linalg.det(U @ Vt)) or 1.0
        C = U @ np.diag([1.0, 1.0, d]) @ Vt           # v ≈ C x
        return float(np.sqrt(np.mean(np.sum((x @ C.T - v) ** 2, axis=1))))
    wired = misfit(u)
    tried = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            P = np.zeros((3, 3))
            P[range(3), perm] = signs
            if not np.allclose(P, np.eye(3)):
                tried.append((misfit(u @ P.T), P))
    best = min(m for m, _ in tried)
    # mappings that differ by a rotation fit equally well (the boresight absorbs it), so the
    # camera cannot tell a swap of two axes from a sign: every improper mapping is one of them
    # times a rotation.  Named: one closest to the wiring as it is (largest trace)
    ties = [(m, P) for m, P in tried if m <= 1.01 * best + 1e-15]
    best, best_P = max(ties, key=lambda t: (np.trace(t[1]), -t[0]))
    ratio = best / wired if wired > 0 else 1.0
    explains = bool(ratio < SWAP_RATIO)
    names = 'xyz'
    words = ', '.join(f"{names[i]} ← {'+' if best_P[i].sum() > 0 else '−'}"
                      f'{names[int(np.argmax(np.abs(best_P[i])))]}' for i in range(3))
    out = {'gyro_axis_swap_sign': {'explains': explains, 'permutation': best_P.tolist(),
                                   'mapping': words, 'rms_as_wired_rad': wired,
                                   'rms_best_rad': best, 'ratio': ratio}}
    if explains:
        out['candidate_explanations'] = ['gyro axis swap/sign']
    return out


# ----------------------------------------------------------------------------- Allan deviation
def white_rate_variance(params: dict, period: float) -> float:
    """
    Return the variance of one increment of the model's white rate noise.

    The random walk N²·T plus the quantization remainder's σ_q²/6 (the MA(1) of the carried
    remainder).

    Parameters
    ----------
    params : dict
        The model (``gyro_random_walk`` rad/√s, ``gyro_quantum`` rad).
    period : float
        Increment period T, s.

    Returns
    -------
    float
        Variance, rad².

    """
    rw, q = _noise(params)
    return rw ** 2 * period + q ** 2 / 6.0


def _noise(params) -> tuple[float, float]:
    """Return the random walk (rad/√s) and the pulse weight (rad) of a model (registry)."""
    return (float(EFFECTS['gyro_random_walk'].value(params)[0]),
            float(EFFECTS['gyro_quantization'].value(params)[0]))


def static_segments(stamps: np.ndarray, delta_theta: np.ndarray, params: dict | None = None,
                    min_duration: float = 15.0, window: float = 1.0, alpha: float = 1e-3,
                    info: dict | None = None) -> list[tuple[int, int]]:
    """
    Find the index ranges [i, j) where the rate is constant within the noise.

    Whatever its mean (a gyro bias of any size, Earth rate): rest on a bench, or a
    constant-rate turn.  Windows of ``window`` seconds: the sample variance of the increments
    in a window, its mean removed, about each axis, against the white rate noise of one
    increment with a χ²(n−1) bound at ``alpha`` per window and axis.  The reference variance is the
    model's (:func:`white_rate_variance` of ``params``) or, when the data are noisier than the
    model says, the data's own floor: the smallest window variance over the χ²(n−1) quantile at
    1/(number of windows), i.e. what the quietest window implies.  A segment: consecutive passing
    windows whose means agree (|difference| within the normal bound at ``alpha`` of √(2·ref/n)),
    covering at least ``min_duration`` seconds.

    Parameters
    ----------
    stamps : numpy.ndarray
        (n,) increment end stamps, s.
    delta_theta : numpy.ndarray
        (n, 3) increments, rad.
    params : dict, optional
        The model (``gyro_random_walk``, ``gyro_quantum``); None: the data floor alone.
    min_duration, window : float
        Seconds.
    alpha : float
        Level of the variance test per window and axis.
    info : dict, optional
        Filled with ``reference_variance_rad2`` (per axis) and ``reference`` ("model"/"data").

    Returns
    -------
    list of (int, int)
        The segments, as index ranges of the increments.

    """
    from scipy.stats import chi2, norm

    st = np.asarray(stamps, dtype=float)
    dth = np.asarray(delta_theta, dtype=float).reshape(-1, 3)
    if len(st) < 3:
        return []
    T = float(np.median(np.diff(st)))
    n = max(8, int(round(window / max(T, 1e-9))))
    m = len(st) // n
    if m < 1:
        return []
    W = dth[: m * n].reshape(m, n, 3)
    var = W.var(axis=1, ddof=1)                              # (m, 3)
    nu = n - 1
    model_var = white_rate_variance(params or {}, T)
    floor = var.min(axis=0) / (chi2.ppf(1.0 / max(m, 2), nu) / nu)
    ref = np.maximum(model_var, floor)
    if info is not None:
        info['reference_variance_rad2'] = ref.tolist()
        info['reference'] = 'model' if np.all(model_var >= floor) else 'data'
    bound = ref * chi2.isf(alpha, nu) / nu
    still = np.all(var <= bound, axis=1)
    # the same constant rate in consecutive windows: their means agree within √(2·ref/n)
    mean = W.mean(axis=1)
    jump = np.zeros(m, dtype=bool)
    step_bound = norm.isf(0.5 * alpha) * np.sqrt(2.0 * ref / n)
    jump[1:] = np.any(np.abs(np.diff(mean, axis=0)) > step_bound, axis=1)
    out = []
    i = 0
    while i < m:
        if not still[i]:
            i += 1
            continue
        j = i + 1
        while j < m and still[j] and not jump[j]:
            j += 1
        a, b = i * n, j * n
        if st[b - 1] - st[a] >= min_duration:
            out.append((a, b))
        i = j
    return out


def _adev(rate: np.ndarray, fs: float, taus: np.ndarray):
    import allantools
    t2, ad, _, _ = allantools.oadev(rate, rate=fs, data_type='freq', taus=taus)
    return np.asarray(t2), np.asarray(ad)


def allan_comparison(stamps, delta_theta, params_before: dict, params_after: dict | None = None,
                     seed: int = 0, segments: int = 5) -> dict | None:
    """
    Compare the Allan deviation of the measured gyro rate with the model's on static segments.

    The overlapping Allan deviation on the static segments (the longest ``segments`` of them,
    each axis, averaged over axes and segments) against the same for the model simulated on the
    same segments: the measured mean rate plus the model's random walk, quantization and bias
    drift, fed through the package's own sensor model.  Segments: where the rate is constant
    within the noise (:func:`static_segments`, from the data: a gyro bias of any size does not
    hide them).

    Parameters
    ----------
    stamps : (n,) array_like
        Increment end stamps, s.
    delta_theta : (n, 3) array_like
        Increments, rad.
    params_before : dict
        The model before the workflow.
    params_after : dict, optional
        The model with the effects the workflow added.
    seed : int
        Seed of the simulated noise.
    segments : int
        Most static segments used.

    Returns
    -------
    dict or None
        τ, the measured and simulated curves, the static noise against the model's, the excess
        region; None when the recording has no static segment of 15 s.

    """
    st = np.asarray(stamps, dtype=float)
    dth = np.asarray(delta_theta, dtype=float)
    found: dict = {}
    segs = sorted(static_segments(st, dth, params_before, info=found),
                  key=lambda s: s[1] - s[0], reverse=True)[:segments]
    if not segs:
        return None
    T = float(np.median(np.diff(st)))
    fs = 1.0 / T
    shortest = min(j - i for i, j in segs)
    taus = np.unique(np.round(np.geomspace(T, shortest * T / 4.0, 24) / T)) * T
    rng = np.random.default_rng(seed)

    def simulate(params, i, j):
        n = j - i
        mean = dth[i:j].mean(axis=0)
        rw, q = _noise(params)
        sim = np.tile(mean, (n, 1)) + rng.normal(0.0, rw * np.sqrt(T), (n, 3))
        # the model's time-varying bias at rest (drift, periodic): every effect's bias term on
        # zero rotation, its mean over the segment removed (the segment's mean is the data's)
        eff = GyroEffects(params, epoch=float(st[0]))
        if eff.active:
            b = eff.apply(np.zeros((n, 3)), st[i:j], T)
            sim = sim + (b - b.mean(axis=0))
        if q > 0:
            sim = PulseQuantizer(q)(sim)
        return sim

    def curve(getter):
        acc = []
        for i, j in segs:
            x = getter(i, j) / T
            ads = []
            for c in range(3):
                tt, ad = _adev(x[:, c], fs, taus)
                ads.append(np.interp(taus, tt, ad))
            acc.append(np.mean(ads, axis=0))
        return np.mean(acc, axis=0)

    measured = curve(lambda i, j: dth[i:j])
    # noise statistics of the rate on the static segments, each segment's mean removed, against
    # the model's white rate noise: random walk σ_w/√T and quantization σ_q/(T√6) (the MA(1)
    # of the carried remainder: Var = 2σ_q²/12 per increment)
    resid = np.vstack([dth[i:j] - dth[i:j].mean(axis=0) for i, j in segs]) / T

    def model_std(params):
        rw, q = _noise(params)
        return float(np.sqrt(rw ** 2 / T + q ** 2 / (6.0 * T ** 2)))
    out = {'static_noise': {'rate_std_rad_s': resid.std(axis=0).tolist(),
                            'model_rate_std_rad_s_before': model_std(params_before),
                            'model_rate_std_rad_s_after': model_std(params_after
                                                                    or params_before)},
           'taus_s': taus.tolist(), 'measured': measured.tolist(),
           'simulated_before': curve(lambda i, j: simulate(params_before, i, j)).tolist(),
           'static_segments': len(segs),
           'static_seconds': float(sum(st[j - 1] - st[i] for i, j in segs)),
           'static_detection': {'rule': 'window variance of the increments ≤ χ² bound of the '
                                        'white rate noise, window means agree (1 s windows, '
                                        'α = 1e-3 per window and axis)', **found}}
    if params_after is not None:
        out['simulated_after'] = curve(lambda i, j: simulate(params_after, i, j)).tolist()
    ratio = measured / np.maximum(np.asarray(out['simulated_before']), 1e-300)
    hi = ratio > 1.5
    if np.any(hi):
        idx = np.where(hi)[0]
        a, b = int(idx[0]), int(idx[-1])
        sl = slice(a, b + 1)
        if b > a:
            slope = float(np.polyfit(np.log(taus[sl]), np.log(measured[sl]), 1)[0])
        else:
            slope = float('nan')
        out['excess_region_s'] = [float(taus[a]), float(taus[b])]
        out['excess_slope'] = slope
        out['excess_ratio_max'] = float(ratio.max())
    return out
