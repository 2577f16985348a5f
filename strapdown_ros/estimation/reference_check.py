"""
How well a filter's attitude agrees with an independent attitude reference, within its σ.

The filter publishes ``q_ref_body`` with the covariance of its error; a reference (a motion-capture
system at its full rate, most of whose samples the filter never saw) gives ``q_ref_VF``.  What
neither can tell apart is taken out first: a constant rotation between the two body frames (the
boresight, its chordal mean) and a lag between the two clocks (a scalar search over a stated
window).  The residual about each VF axis is then set beside the σ the two state together
(the filter's, rotated into VF axes, and the reference's): its RMS in units of that σ
(``rms_ratio``, 1 for a filter whose σ is honest) and the share of samples within 3σ.  No ROS
imports.
"""
from __future__ import annotations

from dataclasses import dataclass

import math

import numpy as np

from strapdown_ros.rotation import (dcm_to_ypr, quat_conjugate, quat_multiply, quat_normalize,
                                    quat_to_dcm, quat_to_rotvec, rotvec_to_quat)

__all__ = ['ReferenceAgreement', 'reference_agreement', 'agreement_with_fixes', 'MAX_LAG_S',
           'MIN_HELD_OUT']

#: the lag window searched, s (either sign)
MAX_LAG_S = 0.2
#: the fewest fixes the filter did not apply that make a held-out comparison
MIN_HELD_OUT = 10
#: samples × lags the lag grid computes at once (memory: 4 doubles each, and a few more)
GRID_ELEMENTS = 200_000
#: stamps the whole lag grid is costed on (every k-th); its best points again on all of them
GRID_SAMPLES = 600
#: the lag is refined to this, s (a microsecond: a thousandth of the shortest lag that matters)
LAG_RESOLUTION_S = 1e-6


@dataclass
class ReferenceAgreement:
    """
    The agreement of a filter's attitude with a reference.

    Attributes
    ----------
    samples : int
        Reference samples compared (inside the filter's output span).
    lag_s : float
        The reference's lag behind the filter taken out, s.
    boresight_ypr_rad : list of float
        The constant rotation taken out (β of VF relative to the body), rad.
    rms_rad : list of float
        RMS residual about VF x, y, z, rad.
    sigma_rad : list of float
        RMS of the σ the filter and the reference state together, per VF axis, rad.
    rms_ratio : list of float
        RMS of residual / σ per axis (1: the stated σ is honest).
    within_3_sigma : float
        Share of the axis samples within 3σ.
    held_out : bool
        The samples are fixes the filter never applied (:func:`agreement_with_fixes`).
    at : str
        Whose stamps the samples are: ``reference`` (the filter interpolated) or ``filter``
        (the reference interpolated to the outputs).
    series : dict or None
        The samples for a plot: ``t`` (n,) s, ``residual`` (n, 3) and ``sigma`` (n, 3) rad, VF
        axes (not in :meth:`as_dict`).

    """

    samples: int
    lag_s: float
    boresight_ypr_rad: list
    rms_rad: list
    sigma_rad: list
    rms_ratio: list
    within_3_sigma: float
    held_out: bool = False
    at: str = 'reference'
    series: dict | None = None

    def as_dict(self) -> dict:
        """Return the record as plain JSON values (without the series)."""
        return {k: v for k, v in self.__dict__.items() if k != 'series'}


def _interp(t_out, q_out, sig_out, t):
    """Return the filter's attitude and its per-axis σ at times t (slerp; σ linear)."""
    k = np.clip(np.searchsorted(t_out, t) - 1, 0, len(t_out) - 2)
    f = ((t - t_out[k]) / (t_out[k + 1] - t_out[k]))[:, None]
    step = quat_to_rotvec(quat_multiply(quat_conjugate(q_out[k]), q_out[k + 1]))
    q = quat_multiply(q_out[k], rotvec_to_quat(step * f))
    return q, sig_out[k] * (1.0 - f) + sig_out[k + 1] * f


def _residuals(q_f, q_ref, q_b):
    """Return the residual rotation vectors, VF axes: log((q_f ⊗ q_b)⁻¹ ⊗ q_ref)."""
    pred = quat_multiply(q_f, q_b)
    return quat_to_rotvec(quat_multiply(quat_conjugate(pred), q_ref))


def _boresight(q_f, q_ref):
    """Return the chordal mean of q_f⁻¹ ⊗ q_ref: the constant body-to-VF rotation."""
    d = quat_normalize(quat_multiply(quat_conjugate(q_f), q_ref))
    d = d * np.sign(d[:, :1] + (d[:, :1] == 0))
    M = d.T @ d
    w, v = np.linalg.eigh(M)
    q = v[:, -1]
    return q if q[0] >= 0 else -q


def _continuous(q: np.ndarray) -> np.ndarray:
    """Return quaternions with the sign of each chosen next to its predecessor (for a slerp)."""
    q = q.copy()
    flip = np.cumsum(np.concatenate([[0], np.sum(q[1:] * q[:-1], axis=1) < 0])) % 2 == 1
    q[flip] = -q[flip]
    return q


def reference_agreement(t_out, q_out, sigma_out, t_ref, q_ref, sigma_ref,
                        max_lag: float = MAX_LAG_S, at: str = 'reference',
                        use=None) -> ReferenceAgreement | None:
    """
    Compare a filter's attitude with a reference, the lag and a constant boresight taken out.

    The two are compared at the stamps of one of them, the other interpolated (slerp; σ
    linear): ``at='reference'`` interpolates the filter's outputs to the reference stamps,
    ``at='filter'`` the reference to the output stamps.  Interpolate the denser of the two:
    a slerp across outputs 0.1 s apart misses the attitude's curvature in fast motion by more
    than any σ (a foot swinging at 10 rad/s).

    Parameters
    ----------
    t_out : (n,) array_like
        Filter output stamps, s.
    q_out : (n, 4) array_like
        Its ``q_ref_body``, scalar first.
    sigma_out : (n, 3) array_like
        The σ of its attitude error about body x, y, z, rad.
    t_ref : (m,) array_like
        Reference stamps, s.
    q_ref : (m, 4) array_like
        The reference ``q_ref_VF``, scalar first.
    sigma_ref : (3,) or (m, 3) array_like
        The reference's σ about VF x, y, z, rad (one for all samples, or one per sample).
    max_lag : float
        The lag window searched, s.
    at : str
        ``reference`` or ``filter``: whose stamps the comparison is made at.
    use : (n,) or (m,) array_like of bool, optional
        Which of those stamps count (default: all).

    Returns
    -------
    ReferenceAgreement or None
        None when fewer than 10 samples can be compared.

    """
    if at not in ('reference', 'filter'):
        raise ValueError(f"at must be 'reference' or 'filter', not {at!r}")
    t_out = np.asarray(t_out, dtype=float)
    q_out = _continuous(quat_normalize(np.asarray(q_out, dtype=float).reshape(-1, 4)))
    sig_out = np.asarray(sigma_out, dtype=float).reshape(-1, 3)
    t_ref = np.asarray(t_ref, dtype=float)
    q_ref = quat_normalize(np.asarray(q_ref, dtype=float).reshape(-1, 4))
    s_ref = np.broadcast_to(np.asarray(sigma_ref, dtype=float), (len(t_ref), 3))
    if len(t_out) < 2 or len(t_ref) < 2:
        return None
    if at == 'filter':
        q_ref = _continuous(q_ref)
    n_at = len(t_ref) if at == 'reference' else len(t_out)
    use = np.ones(n_at, dtype=bool) if use is None else np.asarray(use, dtype=bool)

    def pairs(lag):
        """Return the filter and the reference at the comparison stamps, for a reference lag."""
        if at == 'reference':
            t = t_ref - lag
            sel = use & (t >= t_out[0]) & (t <= t_out[-1])
            q_f, s_f = _interp(t_out, q_out, sig_out, t[sel])
            return sel, q_f, s_f, q_ref[sel], s_ref[sel]
        t = t_out + lag
        sel = use & (t >= t_ref[0]) & (t <= t_ref[-1])
        q_r, s_r = _interp(t_ref, q_ref, s_ref, t[sel])
        return sel, q_out[sel], sig_out[sel], q_r, s_r

    def cost(lag):
        sel, q_f, s_f, q_r, s_r = pairs(lag)
        if sel.sum() < 10:
            return np.inf, None
        q_b = _boresight(q_f, q_r)
        r = _residuals(q_f, q_r, q_b)
        t_at = (t_ref - lag)[sel] if at == 'reference' else t_out[sel]   # filter time
        return float(np.mean(np.sum(r ** 2, axis=1))), (sel, s_f, s_r, q_b, r, t_at)

    def grid_costs(lags, every=1):
        """Return cost(lag)[0] for many lags at once (of every ``every``-th stamp), masked."""
        t_at, t_to = (t_ref, t_out) if at == 'reference' else (t_out, t_ref)
        q_to, sig_to = (q_out, sig_out) if at == 'reference' else (q_ref, s_ref)
        q_fixed = q_ref if at == 'reference' else q_out
        t_at, q_fixed, used = t_at[::every], q_fixed[::every], use[::every]
        sign = -1.0 if at == 'reference' else 1.0
        out = []
        step = max(1, GRID_ELEMENTS // max(len(t_at), 1))
        for a in range(0, len(lags), step):
            t = t_at[None, :] + sign * lags[a:a + step, None]                 # (L, n)
            w = (used & (t >= t_to[0]) & (t <= t_to[-1])).astype(float)
            q_i, _ = _interp(t_to, q_to, sig_to, t.reshape(-1))
            q_i = q_i.reshape(t.shape + (4,))
            q_f, q_r = (q_i, q_fixed[None]) if at == 'reference' else (q_fixed[None], q_i)
            d = quat_normalize(quat_multiply(quat_conjugate(q_f), q_r))
            d = d * np.sign(d[..., :1] + (d[..., :1] == 0))
            _, v = np.linalg.eigh(np.einsum('lni,ln,lnj->lij', d, w, d))
            q_b = v[:, :, -1]
            q_b = q_b * np.where(q_b[:, :1] >= 0, 1.0, -1.0)
            r = _residuals(q_f, q_r, q_b[:, None, :])
            n = w.sum(1)
            c = np.einsum('lni,ln->l', r * r, w) / np.where(n > 0, n, 1.0)
            out += np.where(n >= 10 / every, c, np.inf).tolist()
        return out

    # the grid on at most GRID_SAMPLES stamps finds where the minimum is; the grid points
    # around it are costed on every stamp, and the best of them brackets the refinement
    lags = np.linspace(-max_lag, max_lag, 81)
    every = max(1, n_at // GRID_SAMPLES)
    scan = grid_costs(lags, every)
    k = int(np.argmin(scan))
    near = np.arange(max(k - 2, 0), min(k + 3, len(lags)))
    costs = grid_costs(lags[near]) if every > 1 else [scan[j] for j in near]
    k = int(near[int(np.argmin(costs))])
    if not np.isfinite(min(costs)):
        return None
    lo, hi = lags[max(k - 1, 0)], lags[min(k + 1, len(lags) - 1)]
    g = 0.5 * (math.sqrt(5.0) - 1.0)                  # golden-section refinement: each step
    a, b = hi - g * (hi - lo), lo + g * (hi - lo)      # keeps one point and its cost
    fa, fb = cost(a)[0], cost(b)[0]
    while hi - lo > LAG_RESOLUTION_S:
        if fa < fb:
            hi, b, fb = b, a, fa
            a = hi - g * (hi - lo)
            fa = cost(a)[0]
        else:
            lo, a, fa = a, b, fb
            b = lo + g * (hi - lo)
            fb = cost(b)[0]
    lag = 0.5 * (lo + hi)
    _, (sel, s_f, s_r, q_b, r, t_at) = cost(lag)
    # the filter's σ in VF axes: C_VF^body diag(σ²) C_body^VF (its diagonal), with the reference's
    C = quat_to_dcm(q_b)                              # VF → body
    var_vf = np.einsum('ji,nj,ji->ni', C, s_f ** 2, C)
    sig = np.sqrt(var_vf + s_r ** 2)
    z = r / sig
    return ReferenceAgreement(
        samples=int(sel.sum()), lag_s=float(lag),
        boresight_ypr_rad=[float(x) for x in dcm_to_ypr(quat_to_dcm(q_b))],
        rms_rad=[float(x) for x in np.sqrt(np.mean(r ** 2, axis=0))],
        sigma_rad=[float(x) for x in np.sqrt(np.mean(sig ** 2, axis=0))],
        rms_ratio=[float(x) for x in np.sqrt(np.mean(z ** 2, axis=0))],
        within_3_sigma=float(np.mean(np.abs(z) <= 3.0)), at=at,
        series={'t': t_at, 'residual': r, 'sigma': sig})


def agreement_with_fixes(outputs, fix_stamps_ns, fixes, applied_ns=(), noise_scale=None,
                         max_lag: float = MAX_LAG_S) -> ReferenceAgreement | None:
    """
    Compare a filter's outputs with the reference fixes it did not apply.

    The fixes the filter applied pull its attitude towards themselves, so they are left out
    when at least :data:`MIN_HELD_OUT` others remain (``held_out`` True): a reference at its
    full rate, taken at the model's ``reference_spacing``, leaves most of its fixes to this
    check.  Otherwise every fix is compared (``held_out`` False).  The denser of the two is
    interpolated (:func:`reference_agreement`): fixes closer together than the outputs are
    interpolated to the output stamps, an output then counting when neither fix around it was
    applied.  Each fix's σ is the square root of its covariance's diagonal, scaled per VF axis
    by ``noise_scale`` as the filter scales it.

    Parameters
    ----------
    outputs : list of FilterOutput, or FilterOutputs
        The filter's outputs (stamp, ``q_ref_body``, its covariance in body axes); of a
        ``FilterOutputs``, its arrays are read.
    fix_stamps_ns : sequence of int
        The fixes' stamps, ns, ascending.
    fixes : sequence of (q, P)
        Each fix: ``q_ref_VF`` scalar-first (4,) and its covariance (3, 3), VF axes, rad².
    applied_ns : iterable of int
        The stamps of the fixes the filter applied.
    noise_scale : (3,) array_like, optional
        The model's ``camera_noise_scale`` (None: 1).
    max_lag : float
        The lag window searched, s.

    Returns
    -------
    ReferenceAgreement or None
        None when fewer than 10 samples can be compared.

    """
    if len(outputs) < 2 or len(fixes) < 2:
        return None
    if hasattr(outputs, 'stamps_ns'):                # the arrays of FilterOutputs
        t_out = np.asarray(outputs.stamps_ns, dtype=np.int64)
        q_out = np.asarray(outputs.attitude, dtype=float)
        cov_out = np.asarray(outputs.attitude_covariance, dtype=float)
    else:
        t_out = np.array([o.stamp_ns for o in outputs], dtype=np.int64)
        q_out = np.array([o.attitude for o in outputs], dtype=float)
        cov_out = np.array([o.attitude_covariance for o in outputs], dtype=float)
    origin = int(t_out[0])
    s_out = np.sqrt(np.maximum(np.diagonal(cov_out, axis1=1, axis2=2), 0.0))
    st = np.asarray(fix_stamps_ns, dtype=np.int64)
    q_ref = np.array([f[0] for f in fixes], dtype=float).reshape(-1, 4)
    var = np.diagonal(np.array([f[1] for f in fixes], dtype=float).reshape(-1, 3, 3),
                      axis1=1, axis2=2)
    scale = np.ones(3) if noise_scale is None else np.asarray(noise_scale, dtype=float)
    s_ref = np.sqrt(np.maximum(var, 0.0)) * scale
    applied = np.isin(st, np.fromiter(applied_ns, dtype=np.int64))
    dense = np.median(np.diff(st)) < np.median(np.diff(t_out))
    if dense:               # the fixes around each output stamp: neither of them applied
        k = np.clip(np.searchsorted(st, t_out) - 1, 0, len(st) - 2)
        use = ~(applied[k] | applied[k + 1])
    else:
        use = ~applied
    held = int(use.sum()) >= MIN_HELD_OUT
    if not held:
        use = None
    res = reference_agreement((t_out - origin) * 1e-9, q_out, s_out, (st - origin) * 1e-9,
                              q_ref, s_ref, max_lag, 'filter' if dense else 'reference', use)
    if res is not None:
        res.held_out = held
    return res
