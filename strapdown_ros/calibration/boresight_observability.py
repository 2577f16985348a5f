"""
Observability of the boresight from all the increment pairs together, in O(N).

Two conditions, both over the whole recording (never pair by pair, and without any matrix over
all the pairs):

* **Information.**  Near the solution the residual of pair n responds to a small rotation δ of
  C (VF axes) as f_n = (I − R_nᵀ) δ, R_n = ΔS_avu,n.  The Fisher information of δ from all
  the pairs together is F = Hᵀ B⁻¹ H, B the block-tridiagonal covariance of chained pairs
  (:mod:`strapdown_ros.calibration.pair_covariance`: consecutive pairs share a camera fix);
  every eigen-direction of F must have a predicted σ = 1/√λ at most ``max_sigma``.  With
  shared fixes the information of dense fixes is that of the attitude's excursions over the
  recording, not of the small rotation within one pair, so a reference at 100–300 Hz is
  judged by its motion, not by its rate.
* **Motion about two axes, above the noise** (004 §4.1: rotations about one axis say nothing
  about rotations of C about that axis).  The camera attitudes of each chain, relative to its
  first fix, scatter about their mean; about the second principal axis of that scatter the
  attitude must turn by at least ``min_rotation`` between two fixes of a chain (the range of
  its projections) and scatter at least :data:`NOISE_FLOOR_RATIO` times what the fix noise
  alone gives in that direction.  Without it the information could
  pass on noise alone (a noisy measured R_n has components about every axis).

No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.calibration.pair_covariance import band_covariance, chain_segments, Whitener
from strapdown_ros.estimation.observability import analyze_information, ObservabilityReport
from strapdown_ros.rotation import (quat_conjugate, quat_cumprod, quat_multiply, quat_to_dcm,
                                    quat_to_rotvec)

__all__ = ['NOISE_FLOOR_RATIO', 'RotationSpread', 'boresight_information', 'rotation_spread',
           'judge_observability']

#: the motion's second principal axis must scatter at least this many times the variance that
#: the fix noise alone gives in that direction (an RMS excursion of √10 ≈ 3.2 noise σ)
NOISE_FLOOR_RATIO = 10.0


@dataclass
class RotationSpread:
    """
    The spread of the camera attitudes about their mean, over all chains of pairs.

    Attributes
    ----------
    rms : (3,) ndarray
        RMS excursion about each principal axis, rad, largest first.
    extent : (3,) ndarray
        The largest rotation about each principal axis between two fixes of one chain (the
        range of the attitudes' projections on it), rad.
    axes : (3, 3) ndarray
        The principal axes (columns, VF axes at each chain's first fix), same order.
    noise_ratio : (3,) ndarray
        Generalised eigenvalues of the scatter against the scatter of the fix noise alone,
        largest first (1: what noise alone gives; inf without stated noise).
    points : int
        Attitudes in the scatter (the fixes of all chains).

    """

    rms: np.ndarray
    extent: np.ndarray
    axes: np.ndarray
    noise_ratio: np.ndarray
    points: int


def boresight_information(R_cam: np.ndarray, fix_P: np.ndarray, adjacent: np.ndarray,
                          white: np.ndarray) -> np.ndarray:
    """
    Return the Fisher information F = Hᵀ B⁻¹ H of a VF rotation δ of the boresight, O(N).

    Parameters
    ----------
    R_cam : (N, 3, 3) ndarray
        Camera increments ΔS_avu as rotation matrices.
    fix_P : (N, 2, 3, 3) ndarray
        Covariances of the start and end fix of each pair, VF axes, rad².
    adjacent : (N−1,) array_like of bool
        True where pairs n, n+1 share a fix.
    white : (N, 3, 3) ndarray
        The white gyro part of each pair in VF axes, rad².

    Returns
    -------
    (3, 3) ndarray
        F, rad⁻².

    """
    N = len(R_cam)
    H = (np.eye(3)[None] - np.swapaxes(R_cam, 1, 2)).reshape(3 * N, 3)
    W = Whitener(band_covariance(fix_P, R_cam, adjacent, white))
    A = W.apply(H)
    return A.T @ A


def rotation_spread(dq_cam: np.ndarray, fix_P: np.ndarray, adjacent: np.ndarray
                    ) -> RotationSpread:
    """
    Return the spread of the camera attitudes of each chain about its mean, O(N).

    Within a chain of pairs linked by shared fixes the attitude of fix j relative to the
    chain's first fix is the product of the camera increments; its rotation vector v_j (VF
    axes at the first fix) carries the fix noise A_j P_j A_jᵀ.  The scatter Σ (v − v̄)(v − v̄)ᵀ
    over every chain, against the same sum of the noise covariances, says how far the attitude
    moved about each axis and how far above the noise.  A pair that shares no fix with its
    neighbours is a chain of two attitudes.

    Parameters
    ----------
    dq_cam : (N, 4) ndarray
        Camera increments, scalar first.
    fix_P : (N, 2, 3, 3) ndarray
        Covariances of the start and end fix of each pair, VF axes, rad².
    adjacent : (N−1,) array_like of bool
        True where pairs n, n+1 share a fix.

    Returns
    -------
    RotationSpread
        The principal RMS excursions and their ratios to the noise.

    """
    N = len(dq_cam)
    chain = chain_segments(adjacent, N)
    nc = int(chain[-1]) + 1 if N else 0
    Q = quat_cumprod(np.array([1.0, 0.0, 0.0, 0.0]), dq_cam)
    first = np.flatnonzero(np.concatenate([[True], chain[1:] != chain[:-1]]))
    before = np.vstack([[1.0, 0.0, 0.0, 0.0], Q])[first]          # product before each chain
    rel = quat_multiply(quat_conjugate(before[chain]), Q)          # first fix → end fix of n
    v = quat_to_rotvec(rel)
    A = quat_to_dcm(rel)
    noise = A @ fix_P[:, 1] @ np.swapaxes(A, 1, 2)
    # every chain also holds its first fix: v = 0, noise P_start of its first pair
    count = np.bincount(chain, minlength=nc).astype(float) + 1.0
    s1 = np.zeros((nc, 3))
    np.add.at(s1, chain, v)
    s2 = np.einsum('ni,nj->ij', v, v)
    S = s2 - np.einsum('ci,cj,c->ij', s1, s1, 1.0 / count)
    keep = 1.0 - 1.0 / count                                       # noise about the chain mean
    Nf = (np.einsum('nij,n->ij', noise, keep[chain])
          + np.einsum('cij,c->ij', fix_P[first, 0], keep))
    points = int(np.sum(count))
    lam, vec = np.linalg.eigh(0.5 * (S + S.T))
    lam, vec = np.maximum(lam[::-1], 0.0), vec[:, ::-1]
    ratio = np.full(3, np.inf)
    Nf = 0.5 * (Nf + Nf.T)
    nl, nv = np.linalg.eigh(Nf)
    if nl[0] > 1e-30 * max(nl[-1], 1e-300):
        iw = nv @ np.diag(1.0 / np.sqrt(nl)) @ nv.T                # Nf^(−1/2)
        ratio = np.sort(np.maximum(np.linalg.eigvalsh(iw @ S @ iw), 0.0))[::-1]
    # range of the projections on each principal axis within each chain (its first fix at 0)
    proj = v @ vec
    hi = np.zeros((nc, 3))
    lo = np.zeros((nc, 3))
    np.maximum.at(hi, chain, proj)
    np.minimum.at(lo, chain, proj)
    extent = np.max(hi - lo, axis=0) if nc else np.zeros(3)
    return RotationSpread(np.sqrt(lam / max(points, 1)), extent, vec, ratio, points)


def _describe(v):
    v = v * np.sign(v[np.argmax(np.abs(v))])
    return f'rotation about VF axis ({v[0]:.2f}, {v[1]:.2f}, {v[2]:.2f})'


def judge_observability(dq_cam: np.ndarray, fix_P: np.ndarray, adjacent: np.ndarray,
                        white: np.ndarray, min_rotation: float = np.radians(0.5),
                        max_sigma: float = 1e-3, information: np.ndarray | None = None
                        ) -> ObservabilityReport:
    """
    Judge the observability of the boresight from all the pairs together (module docstring).

    Parameters
    ----------
    dq_cam : (N, 4) ndarray
        Camera increments, scalar first.
    fix_P : (N, 2, 3, 3) ndarray
        Covariances of the start and end fix of each pair, VF axes, rad².
    adjacent : (N−1,) array_like of bool
        True where pairs n, n+1 share a fix.
    white : (N, 3, 3) ndarray
        The white gyro part of each pair in VF axes, rad².
    min_rotation : float
        Smallest rotation about the motion's second principal axis, between two fixes of a
        chain, that counts, rad (the parameter ``min_rotation_deg``).
    max_sigma : float
        Directions whose predicted σ exceeds it (rad) are unobservable.
    information : (3, 3) ndarray, optional
        An information matrix to judge instead of F (e.g. with weights of the caller's).

    Returns
    -------
    ObservabilityReport
        In VF rotation axes (from F), the unobservable axes named and why in ``message``.

    """
    dq_cam = np.asarray(dq_cam, dtype=float)
    F = information
    if F is None:
        F = boresight_information(quat_to_dcm(dq_cam), fix_P, adjacent, white)
    rep = analyze_information(F, describe=_describe, sigma_limit=max_sigma)
    sp = rotation_spread(dq_cam, fix_P, adjacent)

    def short(k):
        return (f'{np.degrees(sp.extent[k]):.2g}° (RMS {np.degrees(sp.rms[k]):.2g}°) about the '
                f"{('first', 'second')[k]} axis, {sp.noise_ratio[k]:.3g}× the fix noise's "
                'scatter')
    need = (f'needs ≥ {np.degrees(min_rotation):.2g}° and ≥ {NOISE_FLOOR_RATIO:g}× '
            f'the noise')
    why, named = '', []
    if sp.extent[0] < min_rotation or sp.noise_ratio[0] < NOISE_FLOOR_RATIO:
        why = (f'no rotation above the noise and {np.degrees(min_rotation):.2g}° over the '
               f'recording (static motion: {short(0)}; {need})')
        named = [_describe(sp.axes[:, k]) for k in range(3)]
    elif sp.extent[1] < min_rotation or sp.noise_ratio[1] < NOISE_FLOOR_RATIO:
        why = (f'all increments share one axis (the attitude turns about one axis only: '
               f'{short(1)}; {need})')
        named = [_describe(sp.axes[:, 0])]
    if why:
        rep.observable = False
        rep.unobservable = named
        if why.startswith('no rotation'):
            rep.message = f'boresight not observable: {why}; weakest: {named[0]}'
        else:
            rep.message = f'{named[0]} not observable: {why}'
    elif not rep.observable:
        rep.message = (f'{rep.unobservable[0]} not observable: predicted σ '
                       f'{rep.predicted_sigma[0]:.2g} rad from the information of all '
                       f'{len(dq_cam)} pairs (limit max_sigma {max_sigma:.2g} rad)')
    return rep
