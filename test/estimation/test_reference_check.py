"""
The agreement of a filter's attitude with a reference, against exact truth.

A smooth attitude history, a known boresight and lag, white noise of stated σ on both sides: the
lag and the boresight are recovered, and the RMS in units of the stated σ is 1 within its
sampling error.
"""
import numpy as np
import pytest

from strapdown_ros.estimation import reference_check
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


def test_a_dense_reference_is_interpolated_to_sparse_outputs_in_fast_motion():
    """
    Fast motion, outputs 0.1 s apart, a reference at 100 Hz: interpolate the reference.

    The attitude turns at up to 10 rad/s and changes its rate within 0.3 s (a foot's swing).  A
    slerp across the outputs misses the curvature by far more than the σ (the RMS ratio is
    large); at the output stamps, with the reference interpolated over 10 ms, it is 1 within its
    sampling error.
    """
    rng = np.random.default_rng(11)

    def fast(t):
        w = np.stack([1.5 * np.sin(20.0 * t), 0.8 * np.cos(13.0 * t), 0.5 * np.sin(7.0 * t)], 1)
        return rotvec_to_quat(w)
    sig_f, sig_r = np.array([2e-3, 2e-3, 2e-3]), np.array([3e-3, 3e-3, 3e-3])
    t_out = np.arange(0.0, 60.0, 0.1)
    q_out = quat_multiply(fast(t_out), rotvec_to_quat(rng.normal(0.0, sig_f, (len(t_out), 3))))
    t_ref = np.arange(0.5, 59.5, 0.01)
    q_ref = quat_multiply(fast(t_ref), rotvec_to_quat(rng.normal(0.0, sig_r, (len(t_ref), 3))))
    s_out = np.tile(sig_f, (len(t_out), 1))
    at_ref = reference_agreement(t_out, q_out, s_out, t_ref, q_ref, sig_r, 0.05, 'reference')
    at_out = reference_agreement(t_out, q_out, s_out, t_ref, q_ref, sig_r, 0.05, 'filter')
    assert max(at_ref.rms_ratio) > 5.0
    # the reference's noise is interpolated between two fixes: at most its σ
    assert all(0.8 < r < 1.15 for r in at_out.rms_ratio), at_out.rms_ratio
    assert abs(at_out.lag_s) < 2e-3


def test_the_lag_grid_on_a_subsample_finds_the_lag_of_the_full_grid(monkeypatch):
    """
    Fast motion and a 37 ms lag, 5900 reference stamps: the grid costed on every k-th stamp.

    The lag and every number equal those of the grid costed on every stamp, and the lag is the
    true one.
    """
    rng = np.random.default_rng(5)

    def fast(t):
        w = np.stack([1.5 * np.sin(9.0 * t), 0.8 * np.cos(6.0 * t), 0.5 * np.sin(4.0 * t)], 1)
        return rotvec_to_quat(w)
    sig_f, sig_r, lag = np.array([2e-3, 2e-3, 2e-3]), np.array([3e-3, 3e-3, 3e-3]), 0.037
    t_out = np.arange(0.0, 60.0, 0.01)
    q_out = quat_multiply(fast(t_out), rotvec_to_quat(rng.normal(0.0, sig_f, (len(t_out), 3))))
    t_ref = np.arange(0.5, 59.5, 0.01)
    q_ref = quat_multiply(fast(t_ref - lag),
                          rotvec_to_quat(rng.normal(0.0, sig_r, (len(t_ref), 3))))
    s_out = np.tile(sig_f, (len(t_out), 1))
    sub = reference_agreement(t_out, q_out, s_out, t_ref, q_ref, sig_r, 0.2, 'reference')
    monkeypatch.setattr(reference_check, 'GRID_SAMPLES', 10 ** 9)
    full = reference_agreement(t_out, q_out, s_out, t_ref, q_ref, sig_r, 0.2, 'reference')
    assert sub.lag_s == pytest.approx(lag, abs=1e-3)
    assert sub.as_dict() == full.as_dict()
