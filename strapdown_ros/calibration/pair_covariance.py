"""
The covariance of the increment residuals of chained camera fixes, banded, and its whitening.

Consecutive increment pairs (n−1, n) and (n, n+1) share camera fix n, so their residuals
f_n ≈ Cᵀε_imu,n − ε_avu,n are correlated: ε_avu,n = θ_n − R_nᵀ θ_{n−1} (004 §3.3) with
θ the error of a fix and R_n = ΔS_avu,n.  Everything white between fixes makes a block
tridiagonal covariance B:

* diagonal blocks ``Cᵀ E_white C + P_n + R_nᵀ P_{n−1} R_n``;
* ``cov(f_n, f_{n+1}) = −P_n R_{n+1}`` between pairs that share fix n.

Its Cholesky factor is banded (bandwidth 5), so whitening N pairs, and the information
``Hᵀ B⁻¹ H`` of any few parameters, cost O(N) time and memory; no matrix over all pairs is
formed.  The boresight solver (:mod:`strapdown_ros.calibration.boresight`), its observability
(:mod:`strapdown_ros.calibration.boresight_observability`) and the discrepancy workflow
(:mod:`strapdown_ros.discrepancy.linear_model`) share it.  No ROS imports.
"""
from __future__ import annotations

import numpy as np

__all__ = ['band_covariance', 'Whitener', 'chain_segments']


def band_covariance(fix_P: np.ndarray, R_cam: np.ndarray, adjacent: np.ndarray,
                    white_diag: np.ndarray) -> np.ndarray:
    """
    Return the covariance B of the white residual part in lower band storage.

    Parameters
    ----------
    fix_P : (N, 2, 3, 3) ndarray
        Covariances of the start and end fix of each pair (VF, rad²), after the noise effects.
    R_cam : (N, 3, 3) ndarray
        The camera increments ΔS_avu as rotation matrices.
    adjacent : (N−1,) ndarray
        1 where pairs n, n+1 share a fix, else 0.
    white_diag : (N, 3, 3) ndarray
        The white gyro part Cᵀ E_white C, rad².

    Returns
    -------
    (6, 3N) ndarray
        The lower band of B (scipy's ``cholesky_banded`` storage).

    """
    N = len(R_cam)
    Rt = np.swapaxes(R_cam, 1, 2)
    diag = white_diag + fix_P[:, 1] + Rt @ fix_P[:, 0] @ R_cam
    full_lower = np.zeros((6, 3 * N))
    blocks = full_lower.reshape(6, N, 3)          # [band row, pair, column within the pair]
    for a in range(3):                            # within-block lower triangle
        for b in range(a + 1):
            blocks[a - b, :, b] = diag[:, a, b]
    if N > 1:
        # cov(f_{n+1}, f_n) = (−P_n R_{n+1})ᵀ = −R_{n+1}ᵀ P_n: rows of pair n+1, columns of n
        cross = -np.swapaxes(R_cam[1:], 1, 2) @ fix_P[1:, 0]
        cross = cross * np.asarray(adjacent, dtype=float)[:, None, None]
        for a in range(3):
            for b in range(3):
                blocks[3 + a - b, :N - 1, b] = cross[:, a, b]     # row 3(n+1)+a, column 3n+b
    return full_lower


class Whitener:
    """
    Banded Cholesky factor L of B (B = L Lᵀ): ``apply(X)`` = L⁻¹ X, ``logdet`` = log det B.

    Parameters
    ----------
    band_lower : (6, 3N) ndarray
        B in lower band storage (:func:`band_covariance`).

    Raises
    ------
    numpy.linalg.LinAlgError
        B has non-finite entries, is not positive definite, or its factor has a diagonal so
        small that L⁻¹ is not finite.

    """

    def __init__(self, band_lower: np.ndarray):
        from scipy.linalg import cholesky_banded

        if not np.all(np.isfinite(band_lower)):
            raise np.linalg.LinAlgError('residual covariance has non-finite entries')
        self.L = cholesky_banded(band_lower, lower=True)
        d = self.L[0]
        if not np.all(d > 1e-150 * max(float(np.max(d)), 1e-300)):
            raise np.linalg.LinAlgError('residual covariance is numerically singular')
        self.logdet = 2.0 * float(np.sum(np.log(d)))
        self.n = band_lower.shape[1]

    def apply(self, X: np.ndarray) -> np.ndarray:
        """
        Whiten: return L⁻¹ X.

        Parameters
        ----------
        X : (3N,) or (3N, k) ndarray
            Residuals or columns.

        Returns
        -------
        ndarray
            L⁻¹ X, the same shape.

        """
        from scipy.linalg.lapack import dtbtrs

        X = np.asarray(X, dtype=float)
        if X.shape[0] == 0:
            return X.copy()
        out, info = dtbtrs(self.L, X if X.ndim == 2 else X[:, None], uplo='L')
        if info != 0:
            raise np.linalg.LinAlgError(f'banded triangular solve failed (LAPACK info {info})')
        return out if X.ndim == 2 else out[:, 0]


def chain_segments(adjacent: np.ndarray, n: int) -> np.ndarray:
    """
    Return the chain of each pair: pairs linked by shared fixes carry the same number.

    Parameters
    ----------
    adjacent : (n−1,) array_like of bool
        True where pair k+1 starts at the fix where pair k ends.
    n : int
        Number of pairs.

    Returns
    -------
    (n,) int ndarray
        Chain number of each pair, 0, 1, … in order.

    """
    if n == 0:
        return np.zeros(0, dtype=int)
    breaks = ~np.asarray(adjacent, dtype=bool)[:n - 1]
    return np.concatenate([[0], np.cumsum(breaks)]).astype(int)
