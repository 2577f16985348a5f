"""
The linear-Gaussian model of the increment residuals, with a banded whitening.

The statistical core under :mod:`strapdown_ros.discrepancy.linearisation`.  Near the current model
the stacked residual r (3N, VF axes) of N increment pairs is

    r = J z + U x + e,     e ~ N(0, B),     x ~ N(0, P_x)

* z: free parameters (boresight correction, the effects being estimated);
* x: the gyro constants of the nominal model (bias, scale, misalignment), random constants
  common to all pairs with the prior covariance the model's ``*_sigma`` give;
* B: the covariance of everything white between fixes: per pair ``Cᵀ E_white C + P_n +
  R_nᵀ P_{n−1} R_n`` on the diagonal and ``−P_n R_{n+1}`` between pairs that share fix n
  (004 §3.3, as the calibrator's correlated covariance in
  :mod:`strapdown_ros.calibration.boresight`).  It is block tridiagonal, so its Cholesky factor is
  banded (bandwidth 5) and whitening costs O(N)
  (:mod:`strapdown_ros.calibration.pair_covariance`, re-exported here).

Marginalising x exactly, the residual covariance is Σ = B + U P_x Uᵀ, the calibrator's
correlated covariance.  :func:`fit` returns the GLS estimate of z, the whitened residual and
the Gaussian negative log-likelihood (up to a constant) that the model-selection tests compare.
No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strapdown_ros.calibration.pair_covariance import band_covariance, Whitener

__all__ = ['band_covariance', 'Whitener', 'Fit', 'fit', 'hac_covariance']


@dataclass
class Fit:
    """
    One GLS fit of the residuals (:func:`fit`).

    Parameters
    ----------
    z : ndarray (nz,)
        The free parameters.
    x : ndarray (nx,)
        The gyro constants (posterior mean).
    cov_z : ndarray (nz, nz)
        Posterior covariance of z (x marginalised).
    whitened : ndarray (3N,)
        L⁻¹ (r − J z − U x).
    chi2 : float
        |whitened|² + xᵀ P⁻¹ x.
    nll : float
        χ² + log det Σ (−2 log-likelihood up to a constant).
    dof : int
        Residuals minus the rank of the free columns.
    design : ndarray (3N, nz + nx), optional
        L⁻¹ [J U], for the sandwich.
    cov_all : ndarray (nz + nx, nz + nx), optional
        Posterior covariance of (z, x).
    prior_precision : ndarray (nx,), optional
        1 / prior variance of x.

    """

    z: np.ndarray
    x: np.ndarray
    cov_z: np.ndarray
    whitened: np.ndarray
    chi2: float
    nll: float
    dof: int
    design: np.ndarray | None = None
    cov_all: np.ndarray | None = None
    prior_precision: np.ndarray | None = None


def fit(r: np.ndarray, J: np.ndarray, U: np.ndarray, prior_var: np.ndarray, W: Whitener) -> Fit:
    """
    Fit r = J z + U x + e by GLS, with x ~ N(0, diag(prior_var)) and e ~ N(0, B).

    Columns of U with zero prior variance are dropped (a constant the model says is exactly 0).

    Parameters
    ----------
    r : (3N,) ndarray
        Stacked residuals, VF axes, rad.
    J : (3N, nz) ndarray
        Columns of the free parameters.
    U : (3N, nx) ndarray
        Columns of the gyro constants.
    prior_var : (nx,) ndarray
        Prior variances of the gyro constants.
    W : Whitener
        The whitening of B.

    Returns
    -------
    Fit
        Estimates, covariances, whitened residual, χ² and −2 log L.

    Raises
    ------
    numpy.linalg.LinAlgError
        Non-finite inputs or results.

    """
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(J)) and np.all(np.isfinite(U))):
        raise np.linalg.LinAlgError('the residuals or their columns have non-finite values')
    keep = prior_var > 0
    U, pv = U[:, keep], prior_var[keep]
    nz, nx = J.shape[1], U.shape[1]
    A = W.apply(np.hstack([J, U, r[:, None]]))
    Aj, ar = A[:, :nz], A[:, -1]
    # the stacked system with prior rows for x, [Aj Au; 0 P^-1/2] [z; x] ≈ [ar; 0], through its
    # normal equations: one product AᵀA over all the rows (O(N), no copy of the design)
    G = A.T @ A
    N = G[:-1, :-1].copy()
    N[nz:, nz:] += np.diag(1.0 / pv)
    g = G[:-1, -1]
    sol = np.linalg.lstsq(N, g, rcond=1e-13)[0]
    z, x = sol[:nz], sol[nz:]
    white = ar - A[:, :-1] @ sol
    chi2 = float(white @ white + np.sum(x * x / pv))
    cov = np.linalg.pinv(N, rcond=1e-13, hermitian=True)
    # log det Σ = log det B + log det(I + P Uᵀ B⁻¹ U) (matrix determinant lemma)
    if nx:
        Sx = np.eye(nx) + G[nz:nz + nx, nz:nz + nx] * pv[None, :]
        logdet = W.logdet + float(np.linalg.slogdet(Sx)[1])
    else:
        logdet = W.logdet
    if not (np.isfinite(chi2) and np.isfinite(logdet) and np.all(np.isfinite(z))):
        raise np.linalg.LinAlgError('the fit has non-finite values')
    rank = int(np.linalg.matrix_rank(Aj)) if nz else 0
    return Fit(z=z, x=x, cov_z=cov[:nz, :nz], whitened=white, chi2=chi2, nll=chi2 + logdet,
               dof=len(r) - rank, design=A[:, :nz + nx], cov_all=cov, prior_precision=1.0 / pv)


def hac_covariance(f: Fit, lags: int) -> np.ndarray:
    """
    Return the Newey–West (Bartlett-kernel HAC) sandwich covariance of the free parameters z.

    The model covariance (HᵀH)⁻¹ assumes the whitened residual is white with unit variance.  The
    sandwich H⁻¹ S H⁻¹ does not: S = Σ_{|l| ≤ L} (1 − |l|/(L+1)) Σ_n g_n g_{n−l}ᵀ, with
    g_n = A_nᵀ w_n the score of pair n (A_n its three rows of the whitened design, w_n its
    whitened residual), plus the prior precision of the gyro constants as the model states it.
    When the residuals are white with unit variance S ≈ HᵀH and the two agree.

    Parameters
    ----------
    f : Fit
        A fit from :func:`fit` (it carries the whitened design).
    lags : int
        Bandwidth L in pairs (≥ 0).

    Returns
    -------
    numpy.ndarray
        (nz, nz) covariance of z, in the units of z.

    """
    nz = len(f.z)
    A, w = f.design, f.whitened
    N = len(w) // 3
    g = (A * w[:, None]).reshape(N, 3, -1).sum(axis=1)
    S = g.T @ g
    for lag in range(1, min(int(lags), N - 1) + 1):
        G = g[lag:].T @ g[:-lag]
        S += (1.0 - lag / (lags + 1.0)) * (G + G.T)
    if len(f.prior_precision):
        S[nz:, nz:] += np.diag(f.prior_precision)
    C = f.cov_all @ S @ f.cov_all
    return 0.5 * (C[:nz, :nz] + C[:nz, :nz].T)
