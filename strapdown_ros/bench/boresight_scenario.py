"""
Scenario, noise model and Cramér–Rao bounds of the boresight benchmark.

The bench of Vasilyuk et al. 2024 (004) §6 in spirit: a bench on the rotating Earth, its fixes,
rotations and sensor errors; the pair residuals written independently of
``calibration.boresight``; the linear map of the gyro constants into the pair errors, the
full covariance of the stacked residuals and the bounds.  Used by the Monte Carlo
(``boresight_monte_carlo``), the summary and the ``boresight_bench`` command.
"""
from __future__ import annotations

from dataclasses import dataclass
import time

import numpy as np

from strapdown_ros.calibration.boresight_increments import gyro_increment
from strapdown_ros.motion.profiles import EARTH_RATE, PiecewiseRateProfile, Segment
from strapdown_ros.rotation import (dcm_to_quat, quat_to_dcm, ypr_error_to_rotation,
                                    ypr_to_dcm)
from strapdown_ros.sensors import ARCSEC, NAVIGATION_GRADE_GYRO, SensorSigmas

ANGLES = ('psi', 'theta', 'gamma')
ANGLE_LABELS = ('ψ (yaw)', 'ϑ (pitch)', 'γ (roll)')
BETA_DEG = (40.0, -25.0, 120.0)
CAMERA_SIGMA_ARCSEC = (0.6, 0.6, 6.0)
GYRO_RATE = 200.0
INTERVAL = 20.0013
FIRST_EXPOSURE = 10.0023
N_FIXES = 71
LATITUDE_DEG = 50.45
ROTATION_START = 6.0            # s after the exposure that opens the interval
ROTATION_TIME = 5.0
#: (interval index 1..70, body axis, angle °): about x, y, z and two oblique axes, varied order,
#: intervals 8–9 and 26–27 back to back
ROTATIONS = ((3, (0, 0, 1), 15.0), (8, (1, 0, 0), 12.0), (9, (0, 1, 0), -10.0),
             (15, (0, 0, 1), -13.0), (21, (0, 1, 0), 14.0), (26, (1, 0, 0), -11.0),
             (27, (1, 1, 0), 12.0), (33, (0, 0, 1), 10.0), (40, (0, 1, 0), 12.0),
             (46, (1, 0, 0), 15.0), (52, (0, 1, 1), -12.0), (58, (0, 0, 1), -14.0),
             (64, (1, 0, 0), -13.0))


def wrap_angles(a):
    """
    Wrap angles to [−π, π).

    Parameters
    ----------
    a : array_like
        Angles, rad.

    Returns
    -------
    ndarray
        The same angles wrapped, rad.

    """
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def rotation_angle(R):
    """
    Return the rotation angle of a DCM, accurate for tiny angles too (via the quaternion).

    Parameters
    ----------
    R : (3, 3) ndarray
        Direction cosine matrix.

    Returns
    -------
    float
        Rotation angle, rad, in [0, π].

    """
    q = dcm_to_quat(R)
    return float(2.0 * np.arctan2(np.linalg.norm(q[1:]), abs(q[0])))


def _vee_skew(F):
    return 0.5 * np.stack(
        [F[..., 2, 1] - F[..., 1, 2], F[..., 0, 2] - F[..., 2, 0], F[..., 1, 0] - F[..., 0, 1]],
        -1)


def residuals(beta, A_imu, A_cam):
    """
    Return the stacked pair residuals f_n(β) of Kuzmina et al. 2015 (004) eqs. (5)–(6).

    Written independently of ``calibration.boresight``: the vee of the skew part of
    ΔS_avuᵀ Cᵀ ΔS_imu C for every pair.

    Parameters
    ----------
    beta : (3,) ndarray
        Boresight angles (ψ, ϑ, γ), rad.
    A_imu : (P, 3, 3) ndarray
        Gyro attitude increments ΔS_imu (MF axes).
    A_cam : (P, 3, 3) ndarray
        Camera attitude increments ΔS_avu (VF axes).

    Returns
    -------
    (3P,) ndarray
        The stacked residuals, rad.

    """
    C = ypr_to_dcm(*beta)
    return _vee_skew(np.swapaxes(A_cam, 1, 2) @ (C.T @ A_imu @ C)).reshape(-1)


def jacobian(beta, A_imu, A_cam, dx=1e-7):
    """
    Return the central-difference Jacobian ∂f/∂β of ``residuals``, as in 004 §4.2.

    Parameters
    ----------
    beta : (3,) ndarray
        Boresight angles (ψ, ϑ, γ), rad.
    A_imu : (P, 3, 3) ndarray
        Gyro attitude increments ΔS_imu.
    A_cam : (P, 3, 3) ndarray
        Camera attitude increments ΔS_avu.
    dx : float, optional
        Full difference step, rad.

    Returns
    -------
    (3P, 3) ndarray
        The Jacobian.

    """
    H = np.empty((3 * len(A_imu), 3))
    for j in range(3):
        d = np.zeros(3)
        d[j] = 0.5 * dx
        H[:, j] = (residuals(beta + d, A_imu, A_cam) - residuals(beta - d, A_imu, A_cam)) / dx
    return H


# ----------------------------------------------------------------------------- scenario
@dataclass
class Scenario:
    """
    The bench scenario: motion, true boresight, sensor increments and noise model.

    Built by ``build_scenario``; ``Sigma`` and ``K_gyro`` are set from ``bounds``.

    Attributes
    ----------
    profile : PiecewiseRateProfile
        Body motion on the rotating Earth.
    beta : (3,) ndarray
        True boresight angles (ψ, ϑ, γ), rad.
    epochs : (N,) ndarray
        Exposure stamps of the fixes, s.
    stamps : (K,) ndarray
        Ends of the gyro intervals, s.
    u : (K, 3) ndarray
        Exact gyro increments, rad.
    gyro : SensorSigmas
        Gyro error sigmas.
    cam_sigma : (3,) ndarray
        Camera noise σ about VF x, y, z, rad.
    A_imu, A_cam : (P, 3, 3) ndarray
        True ΔS_imu and ΔS_avu of the P = N − 1 pairs.
    E_imu : (P, 3, 3) ndarray
        The calibrator's ``random_constant`` E_imu from the true increments, rad².
    E_imu_004 : (P, 3, 3) ndarray
        The calibrator's ``004`` E_imu from the true increments, rad².
    E_cam : (P, 3, 3) ndarray
        E_avu of every pair, rad².
    G : (P, 3, 12) ndarray
        ∂ε_n/∂x with x = (b, vec M), MF axes at t_n.
    white_var : (P,) ndarray
        White-noise variance of ε_n per axis, rad².
    angles_deg : (P,) ndarray
        Rotation angle of each pair, degrees.
    build_s : float
        Time taken to build the scenario, s.
    Sigma : (3P, 3P) ndarray or None
        Full covariance of the stacked residuals at the truth, rad².
    K_gyro : (3P, 3P) ndarray or None
        Covariance of the stacked gyro pair errors ε, rad².

    """

    profile: PiecewiseRateProfile
    beta: np.ndarray
    epochs: np.ndarray
    stamps: np.ndarray
    u: np.ndarray
    gyro: SensorSigmas
    cam_sigma: np.ndarray
    A_imu: np.ndarray
    A_cam: np.ndarray
    E_imu: np.ndarray
    E_imu_004: np.ndarray
    E_cam: np.ndarray
    G: np.ndarray
    white_var: np.ndarray
    angles_deg: np.ndarray
    build_s: float = 0.0
    Sigma: np.ndarray | None = None
    K_gyro: np.ndarray | None = None

    @property
    def pairs_count(self) -> int:
        """Return the number of increment pairs, N − 1."""
        return len(self.epochs) - 1

    @property
    def C(self) -> np.ndarray:
        """Return the true boresight DCM C_MF^VF."""
        return ypr_to_dcm(*self.beta)


def build_profile(earth_rate: bool = True) -> tuple[PiecewiseRateProfile, np.ndarray]:
    """
    Build the bench motion: holds, and the rotations of ``ROTATIONS`` between fixes.

    Parameters
    ----------
    earth_rate : bool, optional
        Whether the bench turns with the Earth at ``LATITUDE_DEG``.

    Returns
    -------
    profile : PiecewiseRateProfile
        The motion.
    epochs : (N,) ndarray
        Exposure stamps of the ``N_FIXES`` fixes, s.

    """
    epochs = FIRST_EXPOSURE + INTERVAL * np.arange(N_FIXES)
    segs, cur = [], 0.0
    for idx, axis, ang in ROTATIONS:
        a = epochs[idx - 1] + ROTATION_START
        axis = np.asarray(axis, dtype=float)
        segs += [
            Segment(a - cur),
            Segment(ROTATION_TIME, axis / np.linalg.norm(axis) * np.radians(ang) / ROTATION_TIME)
        ]
        cur = a + ROTATION_TIME
    segs.append(Segment(epochs[-1] + 2.0 - cur))
    lat = np.radians(LATITUDE_DEG)
    omega = EARTH_RATE * np.array([0.0, np.cos(lat), np.sin(lat)]) if earth_rate else np.zeros(3)
    return PiecewiseRateProfile(segs, earth_rate=omega, name='boresight_bench'), epochs


def x_prior(g: SensorSigmas, misalignment: str = 'all') -> np.ndarray:
    """
    Return the prior covariance of the gyro constants x = (b, vec M).

    M[i, j] sits at 3 + 3i + j: diagonal entries are scale factors, off-diagonal ones
    misalignments, all independent as ``SensorSigmas.draw`` makes them.

    Parameters
    ----------
    g : SensorSigmas
        Gyro error sigmas.
    misalignment : {'all', 'symmetric', 'antisymmetric'}, optional
        ``'symmetric'`` keeps only the symmetric part (M + Mᵀ)/2 of the misalignments;
        ``'antisymmetric'`` only (M − Mᵀ)/2 = [a×], a small rotation of the whole gyro triad
        (σ_a = σ_φ/√2 per axis) that no boresight estimator can tell from β.

    Returns
    -------
    (12, 12) ndarray
        The covariance (rad/s)² for b, dimensionless for M.

    """
    P = np.zeros((12, 12))
    P[:3, :3] = np.eye(3) * g.bias_sigma ** 2
    s2 = g.misalignment_sigma ** 2
    for i in range(3):
        P[3 + 4 * i, 3 + 4 * i] = g.scale_sigma ** 2
        for j in range(i + 1, 3):
            a, b = 3 + 3 * i + j, 3 + 3 * j + i
            if misalignment == 'all':
                P[a, a] = P[b, b] = s2
            else:
                sign = 1.0 if misalignment == 'symmetric' else -1.0
                P[a, a] = P[b, b] = s2 / 2
                P[a, b] = P[b, a] = sign * s2 / 2
    return P


def build_scenario(beta_deg=BETA_DEG, gyro: SensorSigmas = NAVIGATION_GRADE_GYRO,
                   cam_sigma_arcsec=CAMERA_SIGMA_ARCSEC) -> Scenario:
    """
    Build the scenario: motion, exact increments, pair covariances, gyro sensitivity.

    Parameters
    ----------
    beta_deg : tuple of float, optional
        True boresight (ψ, ϑ, γ), degrees.
    gyro : SensorSigmas, optional
        Gyro error sigmas.
    cam_sigma_arcsec : tuple of float, optional
        Camera noise σ about VF x, y, z, arc seconds.

    Returns
    -------
    Scenario
        The scenario, without ``Sigma`` and ``K_gyro`` (see ``bounds``).

    """
    t0 = time.perf_counter()
    prof, epochs = build_profile()
    T = 1.0 / GYRO_RATE
    K = int(np.ceil((epochs[-1] + 1.0) / T))
    tg = np.arange(K + 1) * T
    u = prof.delta_theta(tg[:-1], tg[1:])
    stamps = tg[1:]
    beta = np.radians(beta_deg)
    C = ypr_to_dcm(*beta)
    q_mf = prof.attitude(epochs)                                  # S_GCRS^MF at the fixes
    S = quat_to_dcm(q_mf)
    A_imu = np.swapaxes(S[:-1], 1, 2) @ S[1:]
    A_cam = C.T @ A_imu @ C
    P = N_FIXES - 1
    E_imu = np.empty((P, 3, 3))
    E_imu_004 = np.empty((P, 3, 3))
    for n in range(P):
        E_imu[n] = gyro_increment(stamps, u, epochs[n], epochs[n + 1], gyro, 'random_constant')[1]
        E_imu_004[n] = gyro_increment(stamps, u, epochs[n], epochs[n + 1], gyro, '004')[1]
    cam_sigma = np.asarray(cam_sigma_arcsec, dtype=float) * ARCSEC
    Pc = np.diag(cam_sigma ** 2)
    E_cam = Pc + np.swapaxes(A_cam, 1, 2) @ Pc @ A_cam
    # linear map of the gyro constants into the pair errors: ε_n = Σ_k w_k S(t_n)ᵀ S(t_k) δρ_k,
    # δρ_k = M u_k + b T_k + w_k, w_k = fraction of interval k inside [t_{n−1}, t_n]
    D = quat_to_dcm(prof.attitude(stamps))                        # S_GCRS^MF at the interval ends
    G = np.empty((P, 3, 12))
    white = np.empty(P)
    for n in range(P):
        a, b = epochs[n], epochs[n + 1]
        k0 = int(np.searchsorted(stamps, a, side='right'))
        k1 = int(np.searchsorted(stamps, b, side='left'))
        w = np.ones(k1 - k0 + 1)
        w[0] = (stamps[k0] - a) / T
        w[-1] = (b - (stamps[k1] - T)) / T if k1 > k0 else (b - a) / T
        Dk = S[n + 1].T @ D[k0:k1 + 1]                             # (k, 3, 3) MF(t_k) → MF(t_n)
        G[n, :, :3] = np.einsum('k,kij->ij', w * T, Dk)
        G[n, :, 3:] = np.einsum('k,kai,kj->aij', w, Dk, u[k0:k1 + 1]).reshape(3, 9)
        white[n] = gyro.random_walk ** 2 * T * np.sum(w)
    angles = np.degrees([rotation_angle(a) for a in A_cam])
    return Scenario(prof, beta, epochs, stamps, u, gyro, cam_sigma, A_imu, A_cam, E_imu, E_imu_004,
                    E_cam, G, white, angles,
                    time.perf_counter() - t0)


# ---------------------------------------------------------------------- noise model, bounds
def gyro_covariance(sc: Scenario, constants: bool = True, white: bool = True,
                    misalignment: str = 'all') -> np.ndarray:
    """
    Return the covariance of the stacked gyro pair errors ε (MF axes at each t_n).

    Parameters
    ----------
    sc : Scenario
        The scenario.
    constants : bool, optional
        Include the random constants b, M (common to all pairs).
    white : bool, optional
        Include the white noise.
    misalignment : str, optional
        Part of the misalignment prior, as in ``x_prior``.

    Returns
    -------
    (3P, 3P) ndarray
        Covariance, rad².

    """
    P = sc.pairs_count
    K = np.zeros((3 * P, 3 * P))
    if constants:
        Gs = sc.G.reshape(3 * P, 12)
        K += Gs @ x_prior(sc.gyro, misalignment) @ Gs.T
    if white:
        K += np.diag(np.repeat(sc.white_var, 3))
    return K


def camera_covariance(sc: Scenario, R: np.ndarray | None = None,
                      correlated: bool = True) -> np.ndarray:
    """
    Return the covariance of the stacked camera pair errors e_cam,n = θ_n − R_nᵀ θ_{n−1}.

    Diagonal blocks P + R_nᵀ P R_n, off-diagonal (n, n+1) blocks −P R_{n+1}: adjacent pairs
    share the fix θ_n.

    Parameters
    ----------
    sc : Scenario
        The scenario.
    R : (P, 3, 3) ndarray, optional
        Camera increments; the true ones when None.
    correlated : bool, optional
        Keep the off-diagonal blocks.

    Returns
    -------
    (3P, 3P) ndarray
        Covariance, rad².

    """
    R = sc.A_cam if R is None else R
    P = len(R)
    Pc = np.diag(sc.cam_sigma ** 2)
    S = np.zeros((3 * P, 3 * P))
    for n in range(P):
        S[3 * n:3 * n + 3, 3 * n:3 * n + 3] = Pc + R[n].T @ Pc @ R[n]
        if correlated and n + 1 < P:
            B = -Pc @ R[n + 1]
            S[3 * n:3 * n + 3, 3 * n + 3:3 * n + 6] = B
            S[3 * n + 3:3 * n + 6, 3 * n:3 * n + 3] = B.T
    return S


def residual_covariance(sc: Scenario, C: np.ndarray, K_gyro: np.ndarray,
                        S_cam: np.ndarray) -> np.ndarray:
    """
    Return Σ of the stacked residuals f_n = Cᵀ ε_n − e_cam,n.

    Parameters
    ----------
    sc : Scenario
        The scenario.
    C : (3, 3) ndarray
        Boresight DCM C_MF^VF at which Σ is evaluated.
    K_gyro : (3P, 3P) ndarray
        Covariance of the stacked gyro pair errors, rad².
    S_cam : (3P, 3P) ndarray
        Covariance of the stacked camera pair errors, rad².

    Returns
    -------
    (3P, 3P) ndarray
        Covariance, rad².

    """
    P = sc.pairs_count
    K4 = K_gyro.reshape(P, 3, P, 3)
    Kg = np.einsum('ai,namb,bk->nimk', C, K4, C).reshape(3 * P, 3 * P)
    return Kg + S_cam


def _blockdiag_inv(blocks):
    P = len(blocks)
    W = np.zeros((3 * P, 3 * P))
    inv = np.linalg.inv(blocks)
    for n in range(P):
        W[3 * n:3 * n + 3, 3 * n:3 * n + 3] = inv[n]
    return W


def bounds(sc: Scenario) -> dict:
    """
    Return the Cramér–Rao bounds and the predicted covariance of the linear estimators.

    Parameters
    ----------
    sc : Scenario
        The scenario.

    Returns
    -------
    dict
        ``H`` (3P, 3) Jacobian at the truth; ``Sigma`` and ``K_gyro`` (3P, 3P); ``crlb``:
        name → (3, 3) bound, rad² (``exact``, its variants, ``independent_pairs``,
        ``triad_rotation_floor``); ``predicted``: estimator → sandwich covariance K Σ Kᵀ;
        ``E_imu_model_rel_diff``: the calibrator's E_imu against the linear gyro model.

    """
    C = sc.C
    H = jacobian(sc.beta, sc.A_imu, sc.A_cam)
    K_full = gyro_covariance(sc)
    S_cam = camera_covariance(sc)
    Sigma = residual_covariance(sc, C, K_full, S_cam)
    variants = {
        'exact': Sigma,
        'camera_correlation_only': residual_covariance(sc, C, _blockdiag_keep(K_full), S_cam),
        'gyro_constants_correlation_only': residual_covariance(
            sc, C, K_full, camera_covariance(sc, correlated=False)
        ),
        'white_gyro_only': residual_covariance(sc, C, gyro_covariance(sc, constants=False), S_cam),
        'without_triad_rotation': residual_covariance(
            sc, C, gyro_covariance(sc, misalignment='symmetric'), S_cam
        ),
    }
    out = {}
    for name, Sg in variants.items():
        out[name] = np.linalg.inv(H.T @ np.linalg.solve(Sg, H))
    blocks = np.swapaxes(C, 0, 1)[None] @ sc.E_imu @ C[None] + sc.E_cam
    W_ind = _blockdiag_inv(blocks)
    out['independent_pairs'] = np.linalg.inv(H.T @ W_ind @ H)
    # the triad-rotation floor: a = antisymmetric misalignment rotates the gyro frame, C' = R_a C;
    # in β it is D2⁻¹ a (D2: δβ → rotation of C in MF axes), σ_a² = σ_φ²/2 per axis
    D2 = ypr_error_to_rotation(*sc.beta)[1]
    D2i = np.linalg.inv(D2)
    out['triad_rotation_floor'] = D2i @ (np.eye(3) * sc.gyro.misalignment_sigma ** 2 / 2) @ D2i.T
    # predicted covariance of each linear estimator K f: K Σ Kᵀ (sandwich with the true Σ)
    pred = {}
    blocks004 = np.swapaxes(C, 0, 1)[None] @ sc.E_imu_004 @ C[None] + sc.E_cam
    for name, W in (('weighted', W_ind), ('unweighted', np.eye(len(H))),
                    ('weighted_004cov', _blockdiag_inv(blocks004)), ('correlated_gls',
                                                                     np.linalg.inv(Sigma))):
        N = H.T @ W @ H
        Kl = np.linalg.solve(N, H.T @ W)
        pred[name] = Kl @ Sigma @ Kl.T
    # the calibrator's E_imu against the diagonal blocks of the linear gyro model
    P = sc.pairs_count
    diag_blocks = np.array([K_full[3 * n:3 * n + 3, 3 * n:3 * n + 3] for n in range(P)])
    rel = np.max(np.abs(diag_blocks - sc.E_imu)) / np.max(np.abs(sc.E_imu))
    return {'H': H, 'Sigma': Sigma, 'K_gyro': K_full, 'crlb': out, 'predicted': pred,
            'E_imu_model_rel_diff': float(rel)}


def _blockdiag_keep(M):
    P = len(M) // 3
    out = np.zeros_like(M)
    for n in range(P):
        out[3 * n:3 * n + 3, 3 * n:3 * n + 3] = M[3 * n:3 * n + 3, 3 * n:3 * n + 3]
    return out
