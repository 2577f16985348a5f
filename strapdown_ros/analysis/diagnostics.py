"""Residual diagnostics of the discrepancy workflow: the verdict tests, a description of what
structure remains, and the Allan deviation of the gyro on static segments (measured against the
model simulated on the same segment).  No ROS imports.

Verdict tests on the whitened residual w (3 per pair, ≈ iid N(0, 1) under an adequate model),
each at α/3 (Bonferroni over the three; the workflow passes its α/2 for the tests):

* **NIS**: Σ w² against χ²(n) two-sided;
* **whiteness**: Ljung–Box Q = n(n+2) Σ_{k≤h} ρ_k²/(n−k) per component, summed over the three
  components, against χ²(3h);
* **outliers**: the largest |w| against the maximum of n standard normals,
  p = 1 − (1 − 2Φ(−max|w|))ⁿ (004 Fig. 2a's spikes).
"""
from __future__ import annotations

import numpy as np

__all__ = ["verdict_tests", "autocorrelation", "describe_remaining", "static_segments", "allan_comparison"]


def autocorrelation(x: np.ndarray, lags: int) -> np.ndarray:
    x = np.asarray(x, dtype=float) - np.mean(x)
    d = float(x @ x)
    if d == 0 or len(x) < 2:
        return np.zeros(lags)
    return np.array([float(x[:-k] @ x[k:]) / d for k in range(1, lags + 1)])


def verdict_tests(whitened: np.ndarray, pairs: int, alpha: float, lags: int) -> dict:
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
    tests = {"nis": {"statistic": s, "dof": n, "p_value": p_nis, "per_dof": s / max(n, 1)},
             "whiteness": {"statistic": Q, "dof": 3 * h, "lags": h, "p_value": p_lb},
             "outliers": {"statistic": zmax, "n": n, "p_value": p_out}}
    tests["level"] = level
    tests["passed"] = bool(all(t["p_value"] >= level for t in (tests["nis"], tests["whiteness"], tests["outliers"])))
    tests["failed"] = [k for k in ("nis", "whiteness", "outliers") if tests[k]["p_value"] < level]
    return tests


def describe_remaining(series: dict, lin=None) -> dict:
    """What structure is left: dominant period and lag, correlation with rate and with
    accumulated angle, where the largest residuals are."""
    t = np.asarray(series["t"], dtype=float)
    w = np.asarray(series["whitened"], dtype=float)
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
        out["dominant_period_s"] = float(periods[i])
        out["dominant_period_power"] = float(power[i] / 3.0)
    lags = max(1, min(20, len(t) // 4))
    ac = np.mean([autocorrelation(w[:, c], lags) for c in range(3)], axis=0)
    k = int(np.argmax(np.abs(ac)))
    out["dominant_lag_pairs"] = k + 1
    out["dominant_lag_autocorrelation"] = float(ac[k])
    mag = np.linalg.norm(w, axis=1)
    for key, name in (("rate", "correlation_with_rate"), ("accumulated_angle", "correlation_with_accumulated_angle"),
                      ("phi_cam", "correlation_with_rotation_angle")):
        x = np.asarray(series.get(key, []), dtype=float)
        if len(x) == len(mag) and np.std(x) > 0 and np.std(mag) > 0:
            out[name] = float(np.corrcoef(x, mag ** 2)[0, 1])
    big = np.argsort(mag)[::-1][:5]
    out["largest_whitened_at_s"] = [float(t[i]) for i in big]
    out["largest_whitened"] = [float(mag[i]) for i in big]
    return out


# ----------------------------------------------------------------------------- Allan deviation
def static_segments(stamps: np.ndarray, delta_theta: np.ndarray, rate_limit: float = 2e-4,
                    min_duration: float = 15.0) -> list[tuple[int, int]]:
    """Index ranges [i, j) where the body is at rest: every increment's rate below ``rate_limit``
    (rad/s; Earth rate is 7.3e-5) for at least ``min_duration`` seconds."""
    st = np.asarray(stamps, dtype=float)
    if len(st) < 3:
        return []
    T = np.diff(st, prepend=st[0] - (st[1] - st[0]))
    # smooth over ~0.1 s so noise does not break a segment
    rate = np.linalg.norm(delta_theta, axis=1) / T
    n = max(1, int(round(0.1 / max(float(np.median(T)), 1e-6))))
    if n > 1:
        rate = np.convolve(rate, np.ones(n) / n, mode="same")
    still = rate < rate_limit
    out = []
    i = 0
    N = len(st)
    while i < N:
        if not still[i]:
            i += 1
            continue
        j = i
        while j < N and still[j]:
            j += 1
        if st[j - 1] - st[i] >= min_duration:
            out.append((i, j))
        i = j
    return out


def _adev(rate: np.ndarray, fs: float, taus: np.ndarray):
    import allantools
    t2, ad, _, _ = allantools.oadev(rate, rate=fs, data_type="freq", taus=taus)
    return np.asarray(t2), np.asarray(ad)


def allan_comparison(stamps, delta_theta, params_before: dict, params_after: dict | None = None,
                     seed: int = 0, segments: int = 5) -> dict | None:
    """Overlapping Allan deviation of the measured gyro rate on the static segments (the longest
    ``segments`` of them, each axis, averaged over axes and segments) against the same for the
    model simulated on the same segments: the measured mean rate plus the model's random walk,
    quantization and bias drift, fed through the package's own sensor model.  None when the
    recording has no static segment of 15 s."""
    from ..sensors.effects import GyroEffects
    from ..sensors.model import PulseQuantizer

    st = np.asarray(stamps, dtype=float)
    dth = np.asarray(delta_theta, dtype=float)
    segs = sorted(static_segments(st, dth), key=lambda s: s[1] - s[0], reverse=True)[:segments]
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
        rw = float(params.get("gyro_random_walk", 0.0))
        sim = np.tile(mean, (n, 1)) + rng.normal(0.0, rw * np.sqrt(T), (n, 3))
        eff = GyroEffects({k: v for k, v in params.items() if k in ("gyro_bias_drift",)}, epoch=float(st[0]))
        if eff.active:
            sim = sim + (eff.apply(np.zeros((n, 3)), st[i:j], T))
        q = float(params.get("gyro_quantum", 0.0))
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
        rw, q = float(params.get("gyro_random_walk", 0.0)), float(params.get("gyro_quantum", 0.0))
        return float(np.sqrt(rw ** 2 / T + q ** 2 / (6.0 * T ** 2)))
    out = {"static_noise": {"rate_std_rad_s": resid.std(axis=0).tolist(),
                            "model_rate_std_rad_s_before": model_std(params_before),
                            "model_rate_std_rad_s_after": model_std(params_after or params_before)},
           "taus_s": taus.tolist(), "measured": measured.tolist(),
           "simulated_before": curve(lambda i, j: simulate(params_before, i, j)).tolist(),
           "static_segments": len(segs), "static_seconds": float(sum(st[j - 1] - st[i] for i, j in segs))}
    if params_after is not None:
        out["simulated_after"] = curve(lambda i, j: simulate(params_after, i, j)).tolist()
    ratio = measured / np.maximum(np.asarray(out["simulated_before"]), 1e-300)
    hi = ratio > 1.5
    if np.any(hi):
        idx = np.where(hi)[0]
        a, b = int(idx[0]), int(idx[-1])
        sl = slice(a, b + 1)
        if b > a:
            slope = float(np.polyfit(np.log(taus[sl]), np.log(measured[sl]), 1)[0])
        else:
            slope = float("nan")
        out["excess_region_s"] = [float(taus[a]), float(taus[b])]
        out["excess_slope"] = slope
        out["excess_ratio_max"] = float(ratio.max())
    return out
