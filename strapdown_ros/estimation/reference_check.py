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

import numpy as np

from strapdown_ros.rotation import (dcm_to_ypr, quat_conjugate, quat_multiply, quat_normalize,
                                    quat_to_dcm, quat_to_rotvec, rotvec_to_quat)

__all__ = ['ReferenceAgreement', 'reference_agreement', 'MAX_LAG_S']

#: the lag window searched, s (either sign)
MAX_LAG_S = 0.2


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

    """

    samples: int
    lag_s: float
    boresight_ypr_rad: list
    rms_rad: list
    sigma_rad: list
    rms_ratio: list
    within_3_sigma: float

    def as_dict(self) -> dict:
        """Return the record as plain JSON values."""
        return dict(self.__dict__)


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


def reference_agreement(t_out, q_out, sigma_out, t_ref, q_ref, sigma_ref,
                        max_lag: float = MAX_LAG_S) -> ReferenceAgreement | None:
    """
    Compare a filter's attitude with a reference, the lag and a constant boresight taken out.

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
    sigma_ref : (3,) array_like
        The reference's σ about VF x, y, z, rad.
    max_lag : float
        The lag window searched, s.

    Returns
    -------
    ReferenceAgreement or None
        None when fewer than 10 reference samples fall inside the filter's outputs.

    """
    t_out = np.asarray(t_out, dtype=float)
    q_out = quat_normalize(np.asarray(q_out, dtype=float))
    sig_out = np.asarray(sigma_out, dtype=float).reshape(-1, 3)
    t_ref = np.asarray(t_ref, dtype=float)
    q_ref = quat_normalize(np.asarray(q_ref, dtype=float))
    if len(t_out) < 2:
        return None
    # sign continuity of the filter's quaternions for the slerp
    for i in range(1, len(q_out)):
        if np.dot(q_out[i], q_out[i - 1]) < 0:
            q_out[i] = -q_out[i]

    def cost(lag):
        t = t_ref - lag
        sel = (t >= t_out[0]) & (t <= t_out[-1])
        if sel.sum() < 10:
            return np.inf, None
        q_f, s_f = _interp(t_out, q_out, sig_out, t[sel])
        q_b = _boresight(q_f, q_ref[sel])
        r = _residuals(q_f, q_ref[sel], q_b)
        return float(np.mean(np.sum(r ** 2, axis=1))), (sel, q_f, s_f, q_b, r)

    lags = np.linspace(-max_lag, max_lag, 81)
    costs = [cost(x)[0] for x in lags]
    k = int(np.argmin(costs))
    if not np.isfinite(costs[k]):
        return None
    lo, hi = lags[max(k - 1, 0)], lags[min(k + 1, len(lags) - 1)]
    for _ in range(30):                                # golden-section refinement
        a = hi - 0.618 * (hi - lo)
        b = lo + 0.618 * (hi - lo)
        if cost(a)[0] < cost(b)[0]:
            hi = b
        else:
            lo = a
    lag = 0.5 * (lo + hi)
    _, (sel, q_f, s_f, q_b, r) = cost(lag)
    # the filter's σ in VF axes: C_VF^body diag(σ²) C_body^VF (its diagonal), with the reference's
    C = quat_to_dcm(q_b)                              # VF → body
    var_vf = np.einsum('ji,nj,ji->ni', C, s_f ** 2, C)
    sig = np.sqrt(var_vf + np.asarray(sigma_ref, dtype=float) ** 2)
    z = r / sig
    return ReferenceAgreement(
        samples=int(sel.sum()), lag_s=float(lag),
        boresight_ypr_rad=[float(x) for x in dcm_to_ypr(quat_to_dcm(q_b))],
        rms_rad=[float(x) for x in np.sqrt(np.mean(r ** 2, axis=0))],
        sigma_rad=[float(x) for x in np.sqrt(np.mean(sig ** 2, axis=0))],
        rms_ratio=[float(x) for x in np.sqrt(np.mean(z ** 2, axis=0))],
        within_3_sigma=float(np.mean(np.abs(z) <= 3.0)))
