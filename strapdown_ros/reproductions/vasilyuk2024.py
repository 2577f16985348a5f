"""
Vasilyuk et al. 2024 (paper 004): the §6 σ_β pattern, the Fig. 3 θ_diff check, the ablation.

    python -m strapdown_ros.reproductions.vasilyuk2024 [--quick] [--runs N] [--report FILE]
                                                       [--json FILE] [--plots DIR]
                                                       [--from-json FILE]

* Fig. 3: on a 004 §6-like simulation (73 exposures 21 s apart, 004's gyro, camera 0.6″/0.6″/6″
  about VF x, y, z — our choice: 004 gives only σ ≤ 1″ for its camera attitudes — looking up)
  the boresight is estimated with unit weights as 004 does, a SINS is aligned from the first
  camera fix through that boresight and integrated, and θ_diff between the SINS and the
  camera-derived IMU attitude is checked against its predicted covariance
  (:func:`strapdown_ros.calibration.consistency.theta_diff_check`), in 004's printed form and in
  the derived one; a deliberately wrong boresight is checked too.
* §6: the σ_β pattern of 004's experiment, beside a simulated one with 004's sensor parameters,
  and the §4.2 solver's convergence (:func:`section_004`).
* §6 ablation: the σ_β published by 004's unit-weight estimator (§4.3) for variations of the
  camera and the trajectory, each row computed; the explanation is built from the rows it
  compares.

For reproduce_seeds: ``section_004(runs, quick)`` and ``section_004_extras(quick)`` here; their
text and figures are in :mod:`.vasilyuk2024_report`.  No ROS imports.
"""
from __future__ import annotations

import argparse
from itertools import combinations
import json
from math import comb
import os
import sys

import numpy as np

from strapdown_ros.calibration.boresight import increment_residuals, solve_boresight
from strapdown_ros.calibration.boresight_increments import (camera_increment, gyro_increment,
                                                            IncrementPair)
from strapdown_ros.calibration.consistency import (d1_finite_difference, d_matrices,
                                                   sins_from_camera, theta_diff_check)
from strapdown_ros.cli import check_outputs, DIRECTORY, FILE, write_text
from strapdown_ros.motion.profiles import (EARTH_RATE, PiecewiseRateProfile, Segment,
                                           STANDARD_GRAVITY)
from strapdown_ros.reproductions.markdown import place_figures
from strapdown_ros.reproductions.vasilyuk2024_report import (plots_004_extras,
                                                             report_004_extras)
from strapdown_ros.rotation import (dcm_to_quat, quat_angle_between, quat_conjugate, quat_multiply,
                                    quat_to_dcm, quat_to_rotvec, rotvec_to_quat, ypr_to_dcm)
from strapdown_ros.sensors import ARCSEC, NAVIGATION_GRADE_GYRO
from strapdown_ros.sensors.covariance import constant_variances
from strapdown_ros.sensors.star_camera import StarCameraModel

__all__ = ['section_004', 'experiment_004_pairs', 'convergence_004', 'section_004_extras',
           'simulate_004', 'camera_increments_004', 'trajectory_sigma', 'constants_covariance',
           'increment_angles', 'd_matrix_check',
           'turn_conditioning', 'ROWS', 'TURN_DEG', 'OUTLIER_SIGMA', 'CONDITIONED_WITHIN',
           'FIGURES', 'main', 'page']

#: 004 §6: the turns are the increments of more than 0.5° (Fig. 1, Fig. 2 markers)
TURN_DEG = 0.5
#: an increment-angle difference or a residual is an outlier beyond this many σ
OUTLIER_SIGMA = 3.0
#: k turns "condition the system" when every trajectory-only σ_β with them alone (and the static
#: pairs) is within this factor of its value with every turn
CONDITIONED_WITHIN = 1.5

#: 004 §6-like trajectory: 12 rotations between static segments (004's Fig. 1a: heading within
#: 50°…300°, pitch within ±7°, roll within ±15°; the order and sizes here are ours), as
#: (axis, degrees); axis 2 = heading (MF z, vertical), 0 = pitch, 1 = roll
TURNS = ((2, 40.0), (0, 5.0), (2, 60.0), (1, 12.0), (2, -30.0), (0, -10.0),
         (2, 80.0), (1, -25.0), (2, -50.0), (0, 7.0), (2, 45.0), (1, 15.0))
LATITUDE = np.radians(55.75)
TURN_S = 10.0
_PROFILES: dict = {}


def _trajectory(n_fixes: int, interval: float, tilt_scale: float) -> PiecewiseRateProfile:
    """Return the 004 §6-like motion: the turns of :data:`TURNS` between equal static holds."""
    span = n_fixes * interval + 5.0
    hold = (span - len(TURNS) * TURN_S) / (len(TURNS) + 1)
    segs = [Segment(hold)]
    for axis, deg in TURNS:
        r = np.zeros(3)
        r[axis] = np.radians(deg * (1.0 if axis == 2 else tilt_scale)) / TURN_S
        segs += [Segment(TURN_S, r), Segment(hold)]
    earth = EARTH_RATE * np.array([0.0, np.cos(LATITUDE), np.sin(LATITUDE)])
    return PiecewiseRateProfile(segs, earth_rate=earth, gravity=(0.0, 0.0, STANDARD_GRAVITY))


def _profile(n_fixes: int, interval: float, tilt_scale: float, imu_rate: float):
    key = (n_fixes, interval, tilt_scale, imu_rate)
    if key not in _PROFILES:
        span = n_fixes * interval + 5.0
        prof = _trajectory(n_fixes, interval, tilt_scale)
        tg = np.arange(int(span * imu_rate) + 1) / imu_rate
        _PROFILES.clear()                                   # one at a time: 300k increments each
        _PROFILES[key] = (prof, tg[1:], prof.delta_theta(tg[:-1], tg[1:]))
    return _PROFILES[key]


def simulate_004(seed: int, n_fixes: int = 73, interval: float = 21.0, tilt_scale: float = 1.0,
                 camera_sigma=(0.6, 0.6, 6.0), boresight=(0.0, 0.0, 0.0), gyro: bool = True,
                 imu_rate: float = 200.0, sensitivity: bool = False) -> dict:
    """
    Simulate one 004 §6-like run: camera fixes and gyro/camera increment pairs.

    Camera fixes with 004's σ about the VF axes (optical axis VF z); increments from a gyro with
    004 §6's errors.

    Parameters
    ----------
    seed : int
        Seed of the gyro errors and noise and of the camera noise.
    n_fixes : int
        Number of exposures.
    interval : float
        Time between exposures, s.
    tilt_scale : float
        Factor on the tilt turns (pitch, roll) of the trajectory.
    camera_sigma : (3,) sequence of float
        Camera attitude σ about VF x, y, z, arcsec.
    boresight : (3,) sequence of float
        True boresight (yaw, pitch, roll), rad.
    gyro : bool
        False: error-free increments.
    imu_rate : float
        Gyro sample rate, Hz.
    sensitivity : bool
        Attach the gyro-constant sensitivities to each pair (for θ_diff's covariance).

    Returns
    -------
    dict
        ``pairs`` (list of IncrementPair), ``fixes``, ``beta_true`` (rad) and ``profile``.

    """
    prof, t, u = _profile(n_fixes, interval, tilt_scale, imu_rate)
    rng = np.random.default_rng(seed)
    g = NAVIGATION_GRADE_GYRO
    if gyro:
        err = g.draw(rng)
        noise = rng.normal(0, err.random_walk / np.sqrt(imu_rate), u.shape)
        y = u @ (np.eye(3) + err.matrix).T + err.bias / imu_rate + noise
    else:
        y = u
    fixes = _camera(seed, interval, camera_sigma, boresight).fixes(prof, n_fixes)
    pairs = []
    for f0, f1 in zip(fixes[:-1], fixes[1:]):
        out = gyro_increment(t, y, f0.stamp, f1.stamp, g if gyro else None,
                             sensitivity=sensitivity and gyro)
        dq_c, E_c = camera_increment(f0.attitude, f0.covariance, f1.attitude, f1.covariance)
        p = IncrementPair(f0.stamp, f1.stamp, out[0], dq_c, out[1], E_c)
        if sensitivity and gyro:
            p.imu_sensitivity, p.cov_imu_white = out[2], out[3]
        pairs.append(p)
    return {'pairs': pairs, 'fixes': fixes, 'beta_true': np.asarray(boresight, dtype=float),
            'profile': prof}


def _camera(seed: int, interval: float, camera_sigma, boresight) -> StarCameraModel:
    return StarCameraModel(boresight=np.asarray(boresight, dtype=float), interval=interval,
                           sigma=np.asarray(camera_sigma, dtype=float) * ARCSEC,
                           seed=1000 + seed)


def camera_increments_004(seed: int, n_fixes: int = 73, interval: float = 21.0,
                          tilt_scale: float = 1.0, camera_sigma=(0.6, 0.6, 6.0),
                          boresight=(0.0, 0.0, 0.0)) -> np.ndarray:
    """
    Return the camera increments ΔS_avu of one :func:`simulate_004` run, without the gyro.

    The same fixes as :func:`simulate_004` with the same arguments (the camera noise depends
    on ``seed`` only), for the trajectory-only checks, at no cost of gyro increments.

    Parameters
    ----------
    seed : int
        Seed of the run.
    n_fixes : int
        Number of exposures.
    interval : float
        Time between exposures, s.
    tilt_scale : float
        Factor on the tilt turns.
    camera_sigma : (3,) sequence of float
        Camera attitude σ about VF x, y, z, arcsec.
    boresight : (3,) sequence of float
        True boresight (yaw, pitch, roll), rad.

    Returns
    -------
    (n_fixes − 1, 4) ndarray
        ΔS_avu of each pair of successive fixes, scalar first.

    """
    prof = _trajectory(n_fixes, interval, tilt_scale)
    fixes = _camera(seed, interval, camera_sigma, boresight).fixes(prof, n_fixes)
    return np.array([camera_increment(f0.attitude, f0.covariance, f1.attitude, f1.covariance)[0]
                     for f0, f1 in zip(fixes[:-1], fixes[1:])])


def trajectory_sigma(pairs, beta) -> np.ndarray:
    """
    Return the relative σ_β that the trajectory alone allows.

    Normal matrix Σ 2(1 − cos φ)(I − k kᵀ) of the camera increments in VF axes (004 §4.1 in
    numbers), unit isotropic noise, mapped through D1.

    Parameters
    ----------
    pairs : list of IncrementPair
        The increment pairs (their camera increments are used).
    beta : (3,) array_like
        Boresight (yaw, pitch, roll) at which D1 is evaluated, rad.

    Returns
    -------
    (3,) ndarray
        σ of (ψ, ϑ, γ) for unit noise.

    """
    return _sigma_from_normal(_normal_terms(np.array([p.dq_cam for p in pairs])).sum(0), beta)


def _normal_terms(dq_cam) -> np.ndarray:
    """Each camera increment's term 2(1 − cos φ)(I − k kᵀ) of the normal matrix (VF axes)."""
    rv = quat_to_rotvec(np.asarray(dq_cam, dtype=float))
    ang = np.linalg.norm(rv, axis=1)
    k = rv / np.maximum(ang, 1e-300)[:, None]
    across = np.eye(3)[None] - k[:, :, None] * k[:, None, :]          # I − k kᵀ per increment
    return (2 * (1 - np.cos(ang)))[:, None, None] * across


def _sigma_from_normal(N, beta) -> np.ndarray:
    D1, _ = d_matrices(beta)
    D1i = np.linalg.inv(D1)
    return np.sqrt(np.diag(D1i @ np.linalg.inv(N) @ D1i.T))


def increment_angles(pairs, sol) -> dict:
    """
    Return the numbers of 004's Fig. 2: increment angles before calibration, residuals after.

    Fig. 2a: φ^avu − φ^imu, the difference of the rotation angles of the camera and gyro
    increments (no boresight needed), beside σ = √(σ_avu² + σ_imu²), each σ the projection of
    E_avu, E_imu on the increment's axis.  Fig. 2b: the residuals f_n (004 (5)–(6)) at the
    solution, beside their σ from Cᵀ E_imu C + E_avu.

    Parameters
    ----------
    pairs : list of IncrementPair
        The increment pairs.
    sol : BoresightSolution
        The boresight solved from them.

    Returns
    -------
    dict
        ``t`` (end of each pair, s), ``angle_deg``, ``diff_arcsec``, ``sigma_arcsec``, ``turn``
        (angle above :data:`TURN_DEG`), ``residual_arcsec`` and ``residual_sigma_arcsec``
        (n × 3, VF axes), with the thresholds :data:`TURN_DEG` and :data:`OUTLIER_SIGMA`
        (JSON-able).

    """
    dq_c = np.array([p.dq_cam for p in pairs])
    dq_i = np.array([p.dq_imu for p in pairs])
    rc, ri = quat_to_rotvec(dq_c), quat_to_rotvec(dq_i)
    ac, ai = np.linalg.norm(rc, axis=1), np.linalg.norm(ri, axis=1)
    kc, ki = rc / ac[:, None], ri / ai[:, None]
    E_c = np.array([p.cov_cam for p in pairs])
    E_i = np.array([p.cov_imu for p in pairs])
    s_c = np.sqrt(np.einsum('ni,nij,nj->n', kc, E_c, kc))
    s_i = np.sqrt(np.einsum('ni,nij,nj->n', ki, E_i, ki))
    C = sol.c_mf_vf
    f = increment_residuals(C, quat_to_dcm(dq_i), quat_to_dcm(dq_c))
    P_f = np.einsum('ji,njk,kl->nil', C, E_i, C) + E_c
    return {'t': [float(p.t_end) for p in pairs], 'angle_deg': _vec(np.degrees(ac)),
            'diff_arcsec': _vec((ac - ai) / ARCSEC),
            'sigma_arcsec': _vec(np.hypot(s_c, s_i) / ARCSEC),
            'turn': [bool(a > np.radians(TURN_DEG)) for a in ac],
            'residual_arcsec': (f / ARCSEC).tolist(),
            'residual_sigma_arcsec': (np.sqrt(np.einsum('nii->ni', P_f)) / ARCSEC).tolist(),
            'turn_deg': TURN_DEG, 'outlier_sigma': OUTLIER_SIGMA}


def turn_conditioning(dq_cam, beta, exhaustive: int = 20000) -> dict:
    """
    Return how many turns condition the calibration equations (004 §6: "only three of 12").

    For k = 1, 2, … the k turn pairs (increments above :data:`TURN_DEG`) which, with the
    static pairs, give the trajectory-only σ_β (:func:`trajectory_sigma`) closest to that of
    every pair: the largest ratio of the three σ is minimised over every k-subset while there
    are at most ``exhaustive`` of them, then by adding one turn at a time (greedy).

    Parameters
    ----------
    dq_cam : (n, 4) array_like
        The camera increments ΔS_avu of the pairs, scalar first.
    beta : (3,) array_like
        Boresight at which D1 is evaluated, rad.
    exhaustive : int
        Largest number of k-subsets searched in full.

    Returns
    -------
    dict
        ``turns`` (pairs rotating by more than :data:`TURN_DEG`), ``static``, ``sigma_all``
        (relative σ_β with every pair), ``steps`` (per k up to ``needed``: the turn pairs used,
        their angles, the σ_β ratios to ``sigma_all``, ``exhaustive``) and ``needed`` (the
        smallest k with every ratio ≤ :data:`CONDITIONED_WITHIN`), with the two thresholds
        (JSON-able).

    """
    dq = np.asarray(dq_cam, dtype=float)
    terms = _normal_terms(dq)
    ang = np.degrees(np.linalg.norm(quat_to_rotvec(dq), axis=1))
    turn = [int(i) for i in np.flatnonzero(ang > TURN_DEG)]
    static = [i for i in range(len(dq)) if i not in set(turn)]
    D1, _ = d_matrices(beta)
    D1i = np.linalg.inv(D1)
    full = _sigma_from_normal(terms.sum(0), beta)
    base = terms[static].sum(0)

    def ratios(subsets):
        N = base[None] + terms[np.array(subsets)].sum(1)
        with np.errstate(all='ignore'):
            cov = D1i[None] @ np.linalg.pinv(N, hermitian=True) @ D1i.T[None]
            r = np.sqrt(np.abs(np.einsum('nii->ni', cov))) / full
        bad = np.linalg.matrix_rank(N, hermitian=True) < 3
        return np.where(bad[:, None], np.inf, r)
    steps, needed, best = [], None, ()
    for k in range(1, len(turn) + 1):
        full_search = comb(len(turn), k) <= exhaustive
        cands = (list(combinations(turn, k)) if full_search else
                 [best + (i,) for i in turn if i not in best])
        r = ratios(cands)
        j = int(np.argmin(r.max(1)))
        best = tuple(cands[j])
        steps.append({'pairs': list(best), 'angles_deg': [float(ang[i]) for i in best],
                      'sigma_ratio': _vec(r[j]), 'exhaustive': bool(full_search)})
        if np.max(r[j]) <= CONDITIONED_WITHIN:
            needed = k
            break
    return {'turns': len(turn), 'static': len(static), 'sigma_all': _vec(full),
            'steps': steps, 'needed': needed, 'turn_deg': TURN_DEG,
            'conditioned_within': CONDITIONED_WITHIN}


ROWS = (  # name, description, simulate_004 keywords
    ('baseline', '004-like: camera 0.6″/0.6″/6″ (our choice) looking up, 12 turns (6 heading '
                 '30°–80°, 6 tilts 5°–25°), N = 73, gyro on', {}),
    ('camera_isotropic_0.6', 'camera 0.6″ about every axis', {'camera_sigma': (0.6, 0.6, 0.6)}),
    ('camera_isotropic_6', 'camera 6″ about every axis', {'camera_sigma': (6.0, 6.0, 6.0)}),
    ('gyro_off', 'error-free gyro increments', {'gyro': False}),
    ('exposures_37', 'N = 37 exposures (same turns, shorter holds)', {'n_fixes': 37}),
    ('tilts_x0.3', 'tilt turns (pitch, roll) scaled ×0.3', {'tilt_scale': 0.3}),
    ('tilts_x3', 'tilt turns scaled ×3', {'tilt_scale': 3.0}),
    ('camera_horizontal', 'camera looking horizontally (β = (0°, 0°, 90°): optical axis along MF '
                          'x)',
     {'boresight': (0.0, 0.0, np.pi / 2)}),
)


def _ablation(runs: int, imu_rate: float, rows) -> list[dict]:
    out = []
    for name, desc, kw in rows:
        sig, err, traj = [], [], None
        for seed in range(runs):
            sim = simulate_004(seed, imu_rate=imu_rate, **kw)
            sol = solve_boresight(sim['pairs'], weighting='unit')
            sig.append(np.sqrt(np.diag(sol.covariance_beta)) / ARCSEC)
            err.append((sol.beta - sim['beta_true'] + np.pi) % (2 * np.pi) - np.pi)
            if traj is None:
                traj = trajectory_sigma(sim['pairs'], sim['beta_true'])
        s = np.mean(sig, 0)
        out.append({'name': name, 'description': desc, 'sigma_beta_arcsec': [float(v) for v in s],
                    'ratio': float(s[0] / np.mean(s[1:])),
                    'rms_error_arcsec': [float(v) for v
                                         in np.sqrt(np.mean(np.square(err), 0)) / ARCSEC],
                    'trajectory_ratio': float(traj[0] / np.mean(traj[1:])), 'runs': runs})
    return out


def constants_covariance(absorb_triad_rotation: bool = True) -> np.ndarray:
    """
    Return the 12×12 covariance of the gyro constants x = [b, vec M] of 004 §6's gyro.

    vec M is column-major.

    The antisymmetric part of M rotates the whole triad; the boresight estimated from the same
    gyro absorbs it (C_est ≈ A C̆ with A = I + [a×]), and the camera-derived attitude S^VF C_estᵀ
    then follows the triad exactly as the SINS does, so θ_diff does not contain it.  With
    ``absorb_triad_rotation`` it is projected out: vec M → vec((M + Mᵀ)/2).

    Parameters
    ----------
    absorb_triad_rotation : bool
        Project the triad rotation (antisymmetric part of M) out.

    Returns
    -------
    (12, 12) ndarray
        Covariance of [b (rad/s), vec M].

    """
    var = constant_variances(NAVIGATION_GRADE_GYRO)
    T = np.eye(12)
    if absorb_triad_rotation:
        Pi = np.zeros((9, 9))
        for i in range(3):
            for j in range(3):
                Pi[i + 3 * j, i + 3 * j] += 0.5
                Pi[i + 3 * j, j + 3 * i] += 0.5
        T[3:, 3:] = Pi
    return T @ np.diag(var) @ T.T


def _theta_diff(seed: int, imu_rate: float, wrong_arcsec=(0.0, 30.0, 0.0), n_fixes: int = 73,
                absorb_triad_rotation: bool = True, figures: bool = False) -> dict:
    """
    Check Fig. 3 on one run: unit-weight boresight (004), SINS aligned at fix 1 through it.

    With ``figures`` the same run also gives 004's Fig. 2 (:func:`increment_angles`) and the
    turn count of §6 (:func:`turn_conditioning`).
    """
    sim = simulate_004(seed, imu_rate=imu_rate, sensitivity=True, n_fixes=n_fixes)
    pairs, fixes = sim['pairs'], sim['fixes']
    sol = solve_boresight(pairs, weighting='unit')
    q_vf = np.array([f.attitude for f in fixes])
    P_avu = np.array([f.covariance for f in fixes])
    dq = np.array([p.dq_imu for p in pairs])
    var = constants_covariance(absorb_triad_rotation)
    res = {'t': [float(f.stamp) for f in fixes],
           'beta_error_arcsec': [float(v) for v in (sol.beta - sim['beta_true']) / ARCSEC],
           'sigma_beta_arcsec': [float(v) for v in np.sqrt(np.diag(sol.covariance_beta)) / ARCSEC]}
    for label, beta in (('estimated', sol.beta), ('wrong',
                                                  sol.beta + np.asarray(wrong_arcsec) * ARCSEC)):
        q_ins, P_ins, J = sins_from_camera(q_vf, beta, dq,
                                           sensitivity=[p.imu_sensitivity for p in pairs],
                                           white=[p.cov_imu_white for p in pairs],
                                           constant_variances=var,
                                           return_sensitivity=True)
        for form in ('derived', 'printed'):
            chk = theta_diff_check(q_vf, P_avu, beta, sol.covariance_beta, q_ins, P_ins,
                                   aligned_at=0, covariance=form,
                                   imu_sensitivity=J, imu_constants_cov=var)
            rec = chk.as_dict()
            if label == 'estimated':
                rec.update(theta_arcsec=(chk.theta / ARCSEC).tolist(),
                           sigma3_arcsec=(3 * np.sqrt(np.einsum('nii->ni', chk.P_diff))
                                          / ARCSEC).tolist(),
                           sigma_diff_arcsec=(chk.sigma_diff / ARCSEC).tolist(),
                           sigma_mfa_arcsec=(chk.sigma_mfa / ARCSEC).tolist(),
                           sigma_avu_arcsec=(chk.sigma_avu / ARCSEC).tolist())
            res[f'{label}_{form}'] = rec
    res['wrong_offset_arcsec'] = [float(v) for v in wrong_arcsec]
    if figures:
        res['fig2'] = increment_angles(pairs, sol)
        res['turns'] = turn_conditioning([p.dq_cam for p in pairs], sim['beta_true'])
    # 004 §6's first-order log against the exact one
    q_ins, P_ins = sins_from_camera(q_vf, sol.beta, dq)
    a = theta_diff_check(q_vf, P_avu, sol.beta, sol.covariance_beta, q_ins, P_ins)
    b = theta_diff_check(q_vf, P_avu, sol.beta, sol.covariance_beta, q_ins, P_ins, log='printed')
    res['printed_log_max_difference_arcsec'] = float(np.nanmax(np.abs(a.theta - b.theta)) / ARCSEC)
    return res


def _printed_alignment_check(imu_rate: float, boresight=(0.3, -0.2, np.pi / 2)) -> dict:
    """
    Check 004 §6's alignment S_1^MF = S_1^VF on a camera with a large boresight.

    004 §6 aligns the SINS with S_1^MF = S_1^VF; on a camera with a large boresight (here
    looking horizontally) compare the largest θ_diff with the one of S_1^MF = S_1^VF Cᵀ.
    """
    sim = simulate_004(0, imu_rate=imu_rate, boresight=boresight)
    sol = solve_boresight(sim['pairs'], weighting='unit')
    q_vf = np.array([f.attitude for f in sim['fixes']])
    P_avu = np.array([f.covariance for f in sim['fixes']])
    dq = np.array([p.dq_imu for p in sim['pairs']])
    cos_angle = np.clip((np.trace(ypr_to_dcm(*sol.beta)) - 1) / 2, -1, 1)
    out = {'boresight_deg': [float(v) for v in np.degrees(boresight)],
           'boresight_rotation_deg': float(np.degrees(np.arccos(cos_angle)))}
    for label, printed in (('printed', True), ('derived', False)):
        q_ins, P_ins = sins_from_camera(q_vf, sol.beta, dq, printed_alignment=printed)
        chk = theta_diff_check(q_vf, P_avu, sol.beta, sol.covariance_beta, q_ins, P_ins)
        largest = np.nanmax(np.linalg.norm(chk.theta, axis=1))
        out[f'{label}_max_theta_deg'] = float(np.degrees(largest))
    return out


def d_matrix_check(count: int = 200) -> dict:
    """
    Check the printed D1, D2 (004 §5) against finite differences of C(β) at random β.

    Parameters
    ----------
    count : int
        Random boresights (seed 0), each angle within ±1.5 rad.

    Returns
    -------
    dict
        ``count`` and the largest entry error of the printed and the derived D1, D2.

    """
    rng = np.random.default_rng(0)
    worst = {'printed': 0.0, 'derived': 0.0}
    for _ in range(count):
        b = rng.uniform(-1.5, 1.5, 3)
        C = ypr_to_dcm(*b)
        D1 = d1_finite_difference(b)
        for form in worst:
            E1, E2 = d_matrices(b, form)
            worst[form] = max(worst[form], float(np.max(np.abs(E1 - D1))),
                              float(np.max(np.abs(E2 - C @ D1))))
    return {'count': count, 'max_abs_error': worst}


def section_004_extras(quick: bool = False, runs: int | None = None) -> dict:
    """
    Run the Fig. 3 check and the §6 ablation.

    Parameters
    ----------
    quick : bool
        20 Hz gyro, one run per row and a subset of rows (for tests); the numbers are then
        indicative only.
    runs : int, optional
        Runs per ablation row (default 8; quick 1).

    Returns
    -------
    dict
        The Fig. 3 check, its Monte Carlo, Fig. 2 and the turn count of the same run, the
        printed-formula checks and the ablation rows (JSON-able).

    """
    imu_rate = 20.0 if quick else 200.0
    runs = runs if runs is not None else (1 if quick else 8)
    quick_rows = ('baseline', 'camera_isotropic_0.6', 'tilts_x0.3')
    rows = ROWS if not quick else tuple(r for r in ROWS if r[0] in quick_rows)
    fig3 = _theta_diff(0, imu_rate, figures=True)
    fig2, turns = fig3.pop('fig2'), fig3.pop('turns')
    mc_runs = 2 if quick else 20
    mc = {'derived': [], 'printed': [], 'wrong_derived': []}
    for seed in range(1, mc_runs + 1):
        r = _theta_diff(seed, imu_rate)
        for key in ('derived', 'printed'):
            e = r[f'estimated_{key}']
            mc[key].append(e['joint_nees'] / (3 * e['epochs_used']))
        mc['wrong_derived'].append(not r['wrong_derived']['consistent'])
    return {'imu_rate_hz': imu_rate, 'quick': quick,
            'paper': {'sigma_beta_arcsec': [6.0, 0.6, 0.6]},
            'fig3': fig3, 'fig2': fig2, 'turns': turns,
            'd_matrices': d_matrix_check(50 if quick else 200),
            'printed_alignment': _printed_alignment_check(imu_rate),
            'fig3_mc': {'runs': mc_runs, 'nees_per_dof_derived': mc['derived'],
                        'nees_per_dof_printed': mc['printed'],
                        'wrong_detected': [bool(v) for v in mc['wrong_derived']]},
            'ablation': _ablation(runs, imu_rate, rows)}


def _vec(x):
    return [float(v) for v in np.asarray(x).ravel()]


# ---------------------------------------------------------------- 004 §6: the σ_β pattern
def experiment_004_pairs(seed: int, n_fixes: int = 73, interval: float = 21.0, _cache={}):
    """
    Simulate one run of a 004 §6-like experiment and return its increment pairs.

    73 exposures 21 s apart, 200 Hz navigation-grade gyro (004 §6 values), camera 0.6″/0.6″/6″
    looking up (β = 0: VF z, the optical axis, is MF z, the vertical), 12 turns (mostly in
    heading) between static segments, Earth rate on.  The trajectory is computed once and kept
    in ``_cache``.

    Parameters
    ----------
    seed : int
        Seed of the gyro errors, the gyro noise and the camera noise.
    n_fixes : int
        Number of camera exposures.
    interval : float
        Time between exposures, s.

    Returns
    -------
    pairs : list of IncrementPair
        Gyro and camera attitude increments between successive exposures.
    beta_true : (3,) ndarray
        The true boresight (yaw, pitch, roll), rad: zero.

    """
    if 'profile' not in _cache:
        span = n_fixes * interval + 5.0
        turn = 10.0
        hold = (span - len(TURNS) * turn) / (len(TURNS) + 1)
        segs = [Segment(hold)]
        for axis, deg in TURNS:
            r = np.zeros(3)
            r[axis] = np.radians(deg) / turn
            segs += [Segment(turn, r), Segment(hold)]
        lat = np.radians(55.75)
        earth = EARTH_RATE * np.array([0.0, np.cos(lat), np.sin(lat)])
        _cache['profile'] = PiecewiseRateProfile(segs, earth_rate=earth,
                                                 gravity=(0.0, 0.0, STANDARD_GRAVITY))
        p = _cache['profile']
        tg = np.arange(int(span * 200) + 1) / 200.0
        _cache['t'], _cache['u'] = tg[1:], p.delta_theta(tg[:-1], tg[1:])
    prof, t, u = _cache['profile'], _cache['t'], _cache['u']
    rng = np.random.default_rng(seed)
    err = NAVIGATION_GRADE_GYRO.draw(rng)
    noise = rng.normal(0, err.random_walk * np.sqrt(1 / 200.0), u.shape)
    y = u @ (np.eye(3) + err.matrix).T + err.bias / 200.0 + noise
    cam = StarCameraModel(boresight=np.zeros(3), interval=interval, seed=1000 + seed)
    fixes = cam.fixes(prof, n_fixes)
    pairs = []
    for f0, f1 in zip(fixes[:-1], fixes[1:]):
        dq_i, E_i = gyro_increment(t, y, f0.stamp, f1.stamp, NAVIGATION_GRADE_GYRO)
        dq_c, E_c = camera_increment(f0.attitude, f0.covariance, f1.attitude, f1.covariance)
        pairs.append(IncrementPair(f0.stamp, f1.stamp, dq_i, dq_c, E_i, E_c))
    return pairs, np.zeros(3)


def convergence_004(n: int = 100, seed: int = 8) -> dict:
    """
    Compare 004 §4.2's Gauss–Newton start β0 = 0 with the closed-form axis start.

    ``init='given'`` (from β0 = 0, as 004) against ``init='axes'`` on ``n`` random boresights
    (pitch within ±89°), 20 noise-free pairs each.

    Parameters
    ----------
    n : int
        Number of random boresights.
    seed : int
        Seed of the boresights and the increments.

    Returns
    -------
    dict
        ``n`` and, per start, the number converged to 1e-6 rad and the median and largest
        iteration counts.

    """
    rng = np.random.default_rng(seed)
    out = {'n': n}
    res = {'given': [], 'axes': []}
    for _ in range(n):
        beta = rng.uniform([-np.pi, -1.55, -np.pi], [np.pi, 1.55, np.pi])
        qc = dcm_to_quat(ypr_to_dcm(*beta))
        pairs = []
        for k in range(20):
            axis = rng.normal(size=3)
            angle = np.radians(12.0) * (0.5 + rng.random())
            dq_vf = rotvec_to_quat(axis / np.linalg.norm(axis) * angle)
            dq_mf = quat_multiply(quat_multiply(qc, dq_vf), quat_conjugate(qc))
            pairs.append(IncrementPair(20.0 * k, 20.0 * (k + 1), dq_mf, dq_vf, 1e-24 * np.eye(3),
                                       1e-24 * np.eye(3)))
        for init, rec in res.items():
            sol = solve_boresight(pairs, init=init, max_iterations=50)
            ok = bool(sol.converged and quat_angle_between(dcm_to_quat(sol.c_mf_vf), qc) < 1e-6)
            rec.append((ok, sol.iterations))
    for init, rec in res.items():
        its = np.array([r[1] for r in rec])
        out[init] = {'converged': int(sum(r[0] for r in rec)),
                     'median_iterations': float(np.median(its)),
                     'max_iterations': int(its.max())}
    return out


def section_004(runs: int, quick: bool = False) -> dict:
    """
    Run the 004 §6 section: the σ_β pattern of the boresight and the solver's convergence.

    Parameters
    ----------
    runs : int
        Simulated experiments (:func:`experiment_004_pairs`), each solved with unit weights
        (as 004) and with covariance weights.
    quick : bool
        Ten random boresights for the convergence check instead of 100.

    Returns
    -------
    dict
        The paper's values, the mean published σ and RMS error of β per estimator, arcsec,
        the common-rotation floor and the convergence record (JSON-able).

    """
    paper = {'sigma_beta_arcsec': [6.0, 0.6, 0.6], 'N': 73, 'interval_s': 21.0}
    sig_u, sig_w, err_u, err_w = [], [], [], []
    for seed in range(runs):
        pairs, beta_true = experiment_004_pairs(seed)
        for weighted, sig, err in ((False, sig_u, err_u), (True, sig_w, err_w)):
            common = 3 * ARCSEC / np.sqrt(2) if weighted else 0.0
            sol = solve_boresight(pairs, weighted=weighted, common_rotation_sigma=common)
            sig.append(np.sqrt(np.diag(sol.covariance_beta)) / ARCSEC)
            err.append((sol.beta - beta_true) / ARCSEC)
    floor = NAVIGATION_GRADE_GYRO.misalignment_sigma / np.sqrt(2) / ARCSEC
    return {'paper': paper, 'convergence': convergence_004(10 if quick else 100),
            'ours_unweighted_sigma_arcsec_mean': _vec(np.mean(sig_u, 0)),
            'ours_unweighted_rms_error_arcsec': _vec(np.sqrt(np.mean(np.square(err_u), 0))),
            'ours_weighted_sigma_arcsec_mean': _vec(np.mean(sig_w, 0)),
            'ours_weighted_rms_error_arcsec': _vec(np.sqrt(np.mean(np.square(err_w), 0))),
            'common_rotation_floor_arcsec': float(floor),
            'runs': runs}


#: the figures :func:`.vasilyuk2024_report.plots_004_extras` writes, in its order
FIGURES = ('seeds_004_theta_diff.png', 'seeds_004_fig2.png', 'seeds_004_ablation.png')


def page(res: dict, figures=(), base: str = '.') -> str:
    """
    Return the page ``boresight_004.md`` of a :func:`section_004_extras` result.

    Parameters
    ----------
    res : dict
        The result (this command's ``--json``).
    figures : sequence of str
        Paths of the PNG figures (:data:`FIGURES`), linked after the table each illustrates.
    base : str
        Directory the figure links are relative to (the page's directory).

    Returns
    -------
    str
        The Markdown page.

    """
    return ('# 004 (Vasilyuk et al. 2024) — boresight: the turns, Fig. 2, the Fig. 3 consistency '
            'check and the §6 σ_β pattern\n\n'
            'Generated by `python -m strapdown_ros.reproductions.vasilyuk2024`; every number '
            'comes from that run. Derivations of the corrected formulas: '
            '`strapdown_ros/calibration/consistency.py`.\n\n'
            + place_figures(report_004_extras(res), list(figures), base))


class _Parser(argparse.ArgumentParser):

    def error(self, message):                    # one line, exit 2
        print(f'{self.prog}: {message}', file=sys.stderr)
        raise SystemExit(2)


def main(argv=None) -> int:
    """
    Run the 004 extras and write their page (the ``vasilyuk2024`` command).

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success, 2 on a usage or output error (one line on stderr).

    """
    ap = _Parser(prog='vasilyuk2024', description=__doc__.split('\n\n')[0])
    ap.add_argument('--quick', action='store_true',
                    help='20 Hz gyro, one run per row, three rows')
    ap.add_argument('--runs', type=int, default=None,
                    help='runs per ablation row (default 8; quick 1)')
    ap.add_argument('--report', default='', help='write the markdown here')
    ap.add_argument('--json', default='', help='write the results here')
    ap.add_argument('--plots', default='', help='write PNG figures into this directory')
    ap.add_argument('--force', action='store_true', help='overwrite existing outputs')
    ap.add_argument('--from-json', default='', metavar='FILE',
                    help="no run: write the page from an earlier --json (this command's or "
                         "reproduce_seeds')")
    try:
        a = ap.parse_args(argv)
    except SystemExit as e:
        return int(e.code or 0)
    try:
        if a.runs is not None and a.runs < 1:
            raise ValueError(f'--runs must be >= 1, got {a.runs}')
        check_outputs([('--report', a.report, FILE), ('--json', a.json, FILE),
                       ('--plots', a.plots, DIRECTORY, FIGURES)],
                      [('--from-json', a.from_json)], a.force)
        res = None
        if a.from_json:
            try:
                with open(a.from_json, encoding='utf-8') as fh:
                    res = json.load(fh)
            except (OSError, json.JSONDecodeError) as exc:
                raise ValueError(f'--from-json {a.from_json}: {str(exc)[:200]}') from None
            res = res.get('004_extras', res) if isinstance(res, dict) else None
            if not isinstance(res, dict) or 'fig3' not in res:
                raise ValueError(f'--from-json {a.from_json}: not a vasilyuk2024 result')
    except ValueError as e:
        print(f'vasilyuk2024: error: {e}', file=sys.stderr)
        return 2
    if res is None:
        res = section_004_extras(a.quick, a.runs)
    figures, base = [], os.getcwd()
    if a.plots:
        base = os.path.dirname(os.path.abspath(a.report)) if a.report else os.getcwd()
        figures = plots_004_extras(res, a.plots)
    if a.report:
        write_text(a.report, page(res, figures, base))
    else:
        print(place_figures(report_004_extras(res), figures, base))
    if a.json:
        write_text(a.json, json.dumps(res, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
