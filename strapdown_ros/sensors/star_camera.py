"""
Star camera (astro-visual unit, AVU) model: attitude of the camera frame VF at exposure epochs.

The camera of ``star_camera_sim_node`` and ``record_sim``.  Frames (Vasilyuk et al. 2024;
paper 004, §1): MF is the IMU frame (the body frame of the SINS), VF the camera frame, GCRS the
inertial reference.  The boresight ``C_MF^VF`` maps VF coordinates to MF coordinates,
``C_MF^VF = R_z(−ψ) R_x(ϑ) R_y(γ)`` with β = (ψ, ϑ, γ)
(:func:`~strapdown_ros.rotation.ypr_to_dcm`), so ``S_GCRS^VF = S_GCRS^MF · C_MF^VF`` and, as
quaternions, ``q_GCRS_VF = q_GCRS_MF ⊗ q_MF_VF``.

Measurement error (004 §3.3): ``S_GCRS^VF ≈ S̆_GCRS^VF (I + [θ×])`` with θ in VF axes,
zero-mean Gaussian with covariance ``diag(σ_x², σ_y², σ_z²)``; the optical axis is VF z, where
004 measured 6″ against 0.6″ across it.

Optional timing effects (for the discrepancy workflow): ``time_offset`` (camera clock minus
IMU clock: a fix stamped t shows the attitude at t − time_offset) and ``exposure_time`` with
``stamp_at_exposure_start`` (the attitude belongs to mid-exposure, the stamp to its start).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from strapdown_ros.motion.profile_base import MotionProfile
from strapdown_ros.rotation import (dcm_to_quat, quat_multiply, quat_normalize, rotvec_to_quat,
                                    ypr_to_dcm)
from strapdown_ros.sensors.model import ARCSEC

__all__ = ['StarCameraModel', 'CameraFix']


@dataclass
class CameraFix:
    """
    One simulated camera fix.

    Attributes
    ----------
    stamp : float
        Header stamp, s (profile time).
    attitude : (4,) ndarray
        Measured q_GCRS_VF, scalar-first.
    covariance : (3, 3) ndarray
        Reported covariance, rad², VF axes.
    true_attitude : (4,) ndarray
        q_GCRS_VF at the instant the attitude belongs to.

    """

    stamp: float                 # header stamp, s (profile time)
    attitude: np.ndarray         # measured q_GCRS_VF, scalar-first
    covariance: np.ndarray       # 3×3, rad², VF axes
    true_attitude: np.ndarray    # q_GCRS_VF at the instant the attitude belongs to


@dataclass
class StarCameraModel:
    """
    The simulated star camera: boresight, exposure schedule, noise and timing effects.

    Attributes
    ----------
    boresight : (3,) ndarray
        β = (ψ, ϑ, γ), rad.
    interval : float
        Time between exposures, s.
    sigma : (3,) ndarray
        Reported noise σ about VF x, y, z, rad.
    first_exposure : float or None
        Stamp of the first exposure, s (None: one interval after t = 0).
    time_offset : float
        Camera clock minus IMU clock, s.
    exposure_time : float
        Exposure length, s.
    stamp_at_exposure_start : bool
        The stamp marks the start of the exposure (the attitude belongs to its middle).
    seed : int
        Seed of the noise stream.
    noise_scale : (3,) ndarray
        True noise σ ÷ reported σ per VF axis (effect ``camera_noise_anisotropy``).

    """

    boresight: np.ndarray = field(default_factory=lambda: np.zeros(3))   # β = (ψ, ϑ, γ), rad
    interval: float = 20.0                          # s between exposures
    sigma: np.ndarray = field(default_factory=lambda: np.array([0.6, 0.6, 6.0]) * ARCSEC)
    first_exposure: float | None = None             # default: one interval after t = 0
    time_offset: float = 0.0
    exposure_time: float = 0.0
    stamp_at_exposure_start: bool = False
    seed: int = 0
    #: true noise σ ÷ the reported σ per VF axis (effect camera_noise_anisotropy); the fix
    #: still reports ``sigma``
    noise_scale: np.ndarray = field(default_factory=lambda: np.ones(3))

    def __post_init__(self):
        self.boresight = np.asarray(self.boresight, dtype=float).reshape(3)
        self.sigma = np.asarray(self.sigma, dtype=float).reshape(3)
        self.noise_scale = np.asarray(self.noise_scale, dtype=float).reshape(3)
        if not np.all(np.isfinite(self.boresight)):
            raise ValueError('boresight angles must be finite')
        if not (np.isfinite(self.interval) and self.interval > 0):
            raise ValueError(f'interval must be > 0, got {self.interval}')
        if np.any(self.sigma < 0) or not np.all(np.isfinite(self.sigma)):
            raise ValueError('sigma must be finite and >= 0')
        if self.exposure_time < 0:
            raise ValueError('exposure_time must be >= 0')
        self.rng = np.random.default_rng(self.seed)
        self.count = 0

    @classmethod
    def from_params(cls, p: dict) -> 'StarCameraModel':
        """
        Build the camera of ``star_camera_sim_node`` / ``record_sim``.

        Parameters
        ----------
        p : dict
            Validated node parameters (``boresight``, ``camera_*``, ``seed``).

        Returns
        -------
        StarCameraModel
            The camera.

        """
        sxy, sz = float(p['camera_sigma_xy']), float(p['camera_sigma_z'])
        first = float(p['camera_first_exposure'])
        scale = p.get('camera_noise_scale', (1.0, 1.0, 1.0))
        return cls(boresight=np.asarray(p['boresight'], dtype=float),
                   interval=float(p['camera_interval']), sigma=np.array([sxy, sxy, sz]),
                   first_exposure=None if first == 0.0 else first,
                   time_offset=float(p['camera_time_offset']),
                   exposure_time=float(p['camera_exposure_time']),
                   stamp_at_exposure_start=bool(p['camera_stamp_at_exposure_start']),
                   seed=int(p['seed']), noise_scale=np.asarray(scale, dtype=float))

    @property
    def c_mf_vf(self) -> np.ndarray:
        """Boresight rotation C_MF^VF (VF → MF), 3×3."""
        return ypr_to_dcm(*self.boresight)

    @property
    def q_mf_vf(self) -> np.ndarray:
        """Boresight quaternion q_MF_VF, scalar-first."""
        return dcm_to_quat(self.c_mf_vf)

    @property
    def covariance(self) -> np.ndarray:
        """Fix covariance diag(σ²) the camera reports, rad², VF axes."""
        return np.diag(self.sigma ** 2)

    def epoch(self, n: int) -> float:
        """
        Return the stamp of exposure n.

        Parameters
        ----------
        n : int
            Exposure index, 0, 1, ...

        Returns
        -------
        float
            Stamp, s.

        """
        first = self.interval if self.first_exposure is None else self.first_exposure
        return first + n * self.interval

    def fixes(self, profile: MotionProfile, count: int) -> list[CameraFix]:
        """
        Simulate the next ``count`` camera exposures.

        Advances the exposure counter and the noise stream.

        Parameters
        ----------
        profile : MotionProfile
            The exact motion.
        count : int
            Number of fixes.

        Returns
        -------
        list of CameraFix
            The fixes.

        """
        out = []
        q_mf_vf = self.q_mf_vf
        for _ in range(count):
            stamp = self.epoch(self.count)
            t_att = stamp - self.time_offset
            if self.stamp_at_exposure_start:
                t_att += 0.5 * self.exposure_time
            q_true = quat_normalize(quat_multiply(profile.attitude(t_att), q_mf_vf))
            theta = self.rng.normal(0.0, 1.0, 3) * self.sigma * self.noise_scale
            q_meas = quat_normalize(quat_multiply(q_true, rotvec_to_quat(theta)))
            out.append(CameraFix(stamp, q_meas, self.covariance.copy(), q_true))
            self.count += 1
        return out
