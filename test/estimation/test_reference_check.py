"""
The agreement of a filter's attitude with a reference, against exact truth.

A smooth attitude history, a known boresight and lag, white noise of stated σ on both sides: the
lag and the boresight are recovered, and the RMS in units of the stated σ is 1 within its
sampling error.
"""
import numpy as np
import pytest

from strapdown_ros.estimation.reference_check import reference_agreement
from strapdown_ros.rotation import dcm_to_quat, quat_multiply, rotvec_to_quat, ypr_to_dcm


def _attitude(t):
    w = np.stack([0.3 * np.sin(0.7 * t), 0.2 * np.cos(0.5 * t), 0.25 * np.sin(0.3 * t + 1)], 1)
    return rotvec_to_quat(w)


def test_lag_boresight_and_honest_sigma_are_recovered():
    """Lag, boresight and an honest σ are recovered."""
    rng = np.random.default_rng(7)
    t_out = np.arange(0.0, 120.0, 0.1)
    sig_f = np.array([2e-4, 3e-4, 4e-4])
    noise = rotvec_to_quat(rng.normal(0.0, sig_f, (len(t_out), 3)))
    q_out = quat_multiply(_attitude(t_out), noise)
    beta = np.array([0.02, -0.04, 0.01])
    q_b = dcm_to_quat(ypr_to_dcm(*beta))
    lag, sig_r = 0.023, np.array([5e-4, 5e-4, 1e-3])
    t_ref = np.arange(1.0, 119.0, 0.01)
    q_ref = quat_multiply(quat_multiply(_attitude(t_ref - lag), q_b),
                          rotvec_to_quat(rng.normal(0.0, sig_r, (len(t_ref), 3))))
    a = reference_agreement(t_out, q_out, np.tile(sig_f, (len(t_out), 1)), t_ref, q_ref, sig_r)
    assert a.lag_s == pytest.approx(lag, abs=2e-3)
    assert np.allclose(a.boresight_ypr_rad, beta, atol=1e-4)
    # the filter's noise is per output, interpolated: the RMS is at most the stated σ's
    assert all(0.7 < r < 1.1 for r in a.rms_ratio), a.rms_ratio
    assert a.within_3_sigma > 0.99
