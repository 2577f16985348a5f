"""
Observability of the drifting-reference calibration (Tkachenko 1983, paper 000, §3 and §4).

The rank condition (3.1) over chosen points of a trajectory, and the four-point test of the
simplest case m = n = 1 (4.1), (4.2), for the error structures of
:mod:`strapdown_ros.calibration.drifting_reference_model`.  No ROS; numpy only.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.calibration.drifting_reference_model import (ErrorStructure,
                                                                SCALE_MISALIGNMENT_BIAS)
from strapdown_ros.rotation import dcm_to_quat, quat_to_dcm, quat_to_rotvec, skew

__all__ = ['rank_test', 'simple_case_test']


# ------------------------------------------------------------------ observability (§3, §4)
def rank_test(omegas, attitudes, times, structure: ErrorStructure = SCALE_MISALIGNMENT_BIAS,
              rel_tol: float = 1e-9) -> dict:
    """
    Test 000 (3.1): the rank of the rows ``[Φ(ω_j), D(ω_j, t_j), A(t_j)G(t_j)]``.

    Full observability ⇔ rank = 3(m + n + 1).  The columns are scaled to unit norm before the
    SVD (they carry different units); rank = number of singular values > rel_tol·max.

    Parameters
    ----------
    omegas : (r, 3) ndarray
        Body rates at the chosen points, rad/s.
    attitudes : (r, 4) ndarray
        ``Λ(t_j) = q_I_E`` at the points (A = C_E_I), scalar first.
    times : (r,) ndarray
        Times t_j, s.
    structure : ErrorStructure
        The error structure D, G.
    rel_tol : float
        Relative singular-value threshold.

    Returns
    -------
    dict
        'rank', 'required', 'observable', 'singular_values' and the stacked 'rows'.

    """
    om = np.asarray(omegas, dtype=float)
    A = np.swapaxes(quat_to_dcm(np.asarray(attitudes, dtype=float)), -1, -2)
    t = np.asarray(times, dtype=float)
    D = np.asarray(structure.D(om, t), dtype=float)
    G = np.asarray(structure.G(t), dtype=float)
    rows = np.concatenate([skew(om), D, A @ G], axis=-1).reshape(-1, structure.size)
    norms = np.linalg.norm(rows, axis=0)
    scaled = rows / np.where(norms > 0, norms, 1.0)
    sv = np.linalg.svd(scaled, compute_uv=False)
    rank = int(np.sum(sv > rel_tol * sv[0])) if sv.size and sv[0] > 0 else 0
    return {'rank': rank, 'required': structure.size, 'observable': rank == structure.size,
            'singular_values': sv, 'rows': rows}


def simple_case_test(omegas, attitudes, rel_tol: float = 1e-9) -> dict:
    """
    Test 000 §4's simplest case, m = n = 1, D = G = E3, at four points t1..t4.

    * (4.1): rank of ``[Φ(ω_j) − Φ(ω1), A_j − A1]`` (j = 2, 3, 4) must be 6;
    * (4.2) sufficient conditions: the vectors ``ν_j × (ω_j − ω1)`` are independent (no ω ≠ 0
      solves (4.2)) and ``(ω_j − ω1) × ν_j sin α_j + [(ω_j − ω1) × ν_j] × ν_j (1 − cos α_j)``
      are independent (no v ≠ 0), with ``A_j = S(t_j, t1)A1``,
      ``S = E3 + Φ(ν)sin α + (1 − cos α)Φ²(ν)``: ν α = log(A_j A1ᵀ) (our rotation vector of S).

    Parameters
    ----------
    omegas : (4, 3) ndarray
        Body rates at t1..t4, rad/s.
    attitudes : (4, 4) ndarray
        ``Λ(t_j) = q_I_E`` at t1..t4, scalar first.
    rel_tol : float
        Relative singular-value threshold.

    Returns
    -------
    dict
        'rank_41', 'condition_41', 'omega_vectors_independent', 'v_vectors_independent' and
        'sufficient'.

    """
    om = np.asarray(omegas, dtype=float).reshape(4, 3)
    A = np.swapaxes(quat_to_dcm(np.asarray(attitudes, dtype=float).reshape(4, 4)), -1, -2)
    M41 = np.vstack([np.hstack([skew(om[j]) - skew(om[0]), A[j] - A[0]]) for j in (1, 2, 3)])
    sv = np.linalg.svd(M41 / np.maximum(np.linalg.norm(M41, axis=0), 1e-300), compute_uv=False)
    rank = int(np.sum(sv > rel_tol * sv[0]))
    vw, vv = [], []
    for j in (1, 2, 3):
        S = A[j] @ A[0].T
        rv = quat_to_rotvec(dcm_to_quat(S))
        alpha = np.linalg.norm(rv)
        nu = rv / alpha if alpha > 0 else np.zeros(3)
        dw = om[j] - om[0]
        vw.append(np.cross(nu, dw))
        a = np.cross(dw, nu)
        vv.append(a * np.sin(alpha) + np.cross(a, nu) * (1.0 - np.cos(alpha)))

    def independent(vs):
        m = np.array(vs)
        s = np.linalg.svd(m, compute_uv=False)
        return bool(s[0] > 0 and s[-1] > rel_tol * max(s[0], 1e-300) and s[-1] > 1e-14)

    return {'rank_41': rank, 'condition_41': rank == 6,
            'omega_vectors_independent': independent(vw),
            'v_vectors_independent': independent(vv),
            'sufficient': independent(vw) and independent(vv)}
