"""
Runs of ``model_check_bench``: the live model check's false alarms and naming.

* :func:`null_windows`: the window tests on white Gaussian windows (the exact null);
* :func:`direct_hours`: :class:`~strapdown_ros.estimation.model_check.ModelCheck` fed white
  innovations directly, many hours;
* :func:`clean_runs`: the real filter (``FilterSystem``, the core of ``attitude_filter_node``
  and ``filter_bag``) on clean simulated recordings across motions, with the rule before this
  check (Ljung–Box against χ², the NIS band, each at 0.001) on the same innovations;
* :func:`naming_runs`: single hidden effects under three-axis motion;
* :func:`bag_run`: ``record_sim`` then ``filter_bag`` on one clean recording.

The recordings are the simulators' (``simulated_imu``, ``StarCameraModel``, the parameters of
``record_sim``), fed to the filter in stamp order as ``filter_bag`` does.
"""
from __future__ import annotations

import csv
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from strapdown_ros.estimation.chi_square import chi2_band, chi2_sf
from strapdown_ros.estimation.filter_system import FilterSettings, FilterSystem
from strapdown_ros.estimation.model_check import ljung_box, ModelCheck
from strapdown_ros.estimation.window_tests import spectral_whiteness
from strapdown_ros.motion.profile_base import MotionProfile
from strapdown_ros.motion.profiles import (bench_profile, ConingProfile, PiecewiseRateProfile,
                                           Segment)
from strapdown_ros.params import model_and_settings, simulator_parameters
from strapdown_ros.rotation import quat_conjugate, quat_multiply, quat_to_rotvec, rotvec_to_quat
from strapdown_ros.sensors.simulated import simulated_imu
from strapdown_ros.sensors.star_camera import StarCameraModel

_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
#: the window and per-window level of the check before this one (Ljung–Box with χ², NIS band)
OLD_WINDOW, OLD_ALPHA = 30, 0.001
#: the simulator's random scale and misalignment constants off: the filter's model is right
CLEAN = {'gyro_scale_sigma': 0.0, 'gyro_misalignment_sigma': 0.0}


class ThreeAxisSinusoid(MotionProfile):
    """
    Three-axis sinusoidal motion: ``q(t) = q0 ⊗ exp(φ(t))``, ``φ_i = a_i sin(ν_i t + p_i)``.

    Every body axis turns both ways, with its own frequency.  The body rate is exact,
    ``ω = J_r(φ) φ̇`` with the right Jacobian of the rotation vector; the increments are its
    8-point Gauss–Legendre integral over each interval (error below 1e-15 rad at 100 Hz).

    Parameters
    ----------
    amplitude : sequence of 3 float
        a_i, rad.
    frequency : sequence of 3 float
        ν_i, rad/s.
    phase : sequence of 3 float
        p_i, rad.

    """

    def __init__(self, amplitude=(0.3, 0.25, 0.2), frequency=(0.31, 0.47, 0.73),
                 phase=(0.0, 1.0, 2.0)):
        self.a, self.nu, self.p = (np.asarray(v, dtype=float).reshape(3)
                                   for v in (amplitude, frequency, phase))
        self.q0 = rotvec_to_quat(np.array([0.2, -0.4, 0.9]))

    def _phi(self, t):
        arg = self.nu * np.asarray(t, dtype=float)[..., None] + self.p
        return self.a * np.sin(arg), self.a * self.nu * np.cos(arg)

    def attitude(self, t) -> np.ndarray:
        """
        Return ``q_ref_body``.

        Parameters
        ----------
        t : float or ndarray
            Times, s.

        Returns
        -------
        (..., 4) ndarray
            Quaternions, scalar-first.

        """
        return quat_multiply(self.q0, rotvec_to_quat(self._phi(t)[0]))

    def body_rate(self, t) -> np.ndarray:
        """
        Return the body rate ``J_r(φ) φ̇``.

        Parameters
        ----------
        t : float or ndarray
            Times, s.

        Returns
        -------
        (..., 3) ndarray
            Rate, rad/s, body axes.

        """
        phi, dphi = self._phi(t)
        th = np.linalg.norm(phi, axis=-1)[..., None]
        th = np.where(th > 1e-8, th, 1e-8)
        x1 = np.cross(phi, dphi)
        return (dphi - (1.0 - np.cos(th)) / th ** 2 * x1
                + (th - np.sin(th)) / th ** 3 * np.cross(phi, x1))

    def delta_theta(self, t0, t1) -> np.ndarray:
        """
        Return ∫ω dt over [t0, t1] (Gauss–Legendre).

        Parameters
        ----------
        t0, t1 : float or ndarray
            Interval ends, s.

        Returns
        -------
        (..., 3) ndarray
            Increments, rad.

        """
        t0, t1 = np.broadcast_arrays(np.asarray(t0, dtype=float), np.asarray(t1, dtype=float))
        half, mid = 0.5 * (t1 - t0), 0.5 * (t1 + t0)
        w = self.body_rate(mid[..., None] + half[..., None] * _GL_X)
        return half[..., None] * np.einsum('k,...kj->...j', _GL_W, w)


def tumble_profile(seconds: float, seed: int = 7) -> PiecewiseRateProfile:
    """
    Return a piecewise-constant three-axis tumble: 10-s segments, each rate uniform in ±0.1.

    Parameters
    ----------
    seconds : float
        Length, s.
    seed : int
        Seed of the rates.

    Returns
    -------
    PiecewiseRateProfile
        The profile (exact).

    """
    rng = np.random.default_rng(seed)
    n = int(math.ceil(seconds / 10.0)) + 1
    return PiecewiseRateProfile([Segment(10.0, rng.uniform(-0.1, 0.1, 3)) for _ in range(n)],
                                initial_attitude=rotvec_to_quat([0.3, 0.2, -0.5]),
                                name='tumble')


def motion(name: str, seconds: float) -> MotionProfile:
    """
    Return one of the bench's motions.

    Parameters
    ----------
    name : str
        ``coning`` (003 §2.2, α 0.087 rad, ν 1 rad/s), ``three_axis``
        (:class:`ThreeAxisSinusoid`), ``tumble`` (:func:`tumble_profile`) or ``bench`` (the
        004 bench sequence, repeated).
    seconds : float
        Length needed, s.

    Returns
    -------
    MotionProfile
        The profile.

    """
    if name == 'coning':
        return ConingProfile(0.087, 1.0)
    if name == 'three_axis':
        return ThreeAxisSinusoid()
    if name == 'tumble':
        return tumble_profile(seconds)
    if name == 'bench':
        return bench_profile(repeat=int(math.ceil(seconds / 170.0)) + 1)
    raise ValueError(f'unknown motion {name!r}')


def simulate(profile, seconds: float, sim: dict, filt: dict | None = None,
             chunk: float = 600.0, keep_every: int = 0) -> tuple[FilterSystem, list, list]:
    """
    Simulate a recording and run the filter over it in stamp order, as ``filter_bag`` does.

    Parameters
    ----------
    profile : MotionProfile
        The motion.
    seconds : float
        Length, s.
    sim : dict
        Overrides of the simulators' parameters (``record_sim``'s ``-p``).
    filt : dict, optional
        Overrides of ``attitude_filter_node``'s parameters (``gyro_rate`` follows the IMU's).
    chunk : float
        Seconds simulated at a time (bounds the memory).
    keep_every : int
        Keep every this many filter outputs (0: none).

    Returns
    -------
    system : FilterSystem
        The filter after the recording.
    fixes : list of FixOutput
        Every fix result.
    outputs : list of FilterOutput
        The outputs kept.

    """
    imu_p, cam_p = simulator_parameters(None, dict(sim))
    gyro, _ = simulated_imu(imu_p, profile)
    cam = StarCameraModel.from_params(cam_p)
    model, settings = model_and_settings('attitude_filter_node',
                                         dict({'gyro_rate': imu_p['gyro_rate']}, **(filt or {})))
    system = FilterSystem(model, FilterSettings.from_values(settings))
    rate = float(imu_p['gyro_rate'])
    fixes_out, outputs, t_done = [], [], 0.0
    while t_done < seconds - 1e-9:
        t_end = min(seconds, t_done + chunk)
        k = int(round(t_end * rate)) - gyro.count
        st, meas, _ = gyro.sample(k)
        ns = np.round(st * 1e9).astype(np.int64)
        fixes = []
        while cam.epoch(cam.count) <= t_end + 1e-9:
            fixes += cam.fixes(profile, 1)
        j0 = 0
        for fx in fixes:
            fns = int(round(fx.stamp * 1e9))
            j = int(np.searchsorted(ns, fns, side='right'))
            if j > j0:
                system.add_increments(ns[j0:j], meas[j0:j])
                j0 = j
            system.add_fix(fns, fx.attitude, fx.covariance)
        system.add_increments(ns[j0:], meas[j0:])
        system.process()
        out, fx = system.take()
        fixes_out += fx
        outputs += out[::keep_every] if keep_every else []
        t_done = t_end
    return system, fixes_out, outputs


def old_rule(fixes: list, window: int = OLD_WINDOW, alpha: float = OLD_ALPHA) -> dict:
    """
    Judge the same innovations by the rule this check replaces.

    Σ NIS against the two-sided χ²(3N) band at ``alpha`` and the Ljung–Box statistic
    (lags min(10, N // 5)) against χ²(3L) at ``alpha``; a WARN episode is a run of failing
    windows.

    Parameters
    ----------
    fixes : list of FixOutput
        Applied or gated fixes with their innovation covariance.
    window : int
        N.
    alpha : float
        Level of each test.

    Returns
    -------
    dict
        ``windows``, ``failed``, ``episodes``.

    """
    white = [np.linalg.solve(np.linalg.cholesky(f.innovation_covariance), f.innovation)
             for f in fixes if f.innovation_covariance is not None]
    lags = max(1, min(10, window // 5))
    lo, hi = chi2_band(3 * window, alpha)
    failed = episodes = windows = 0
    prev = False
    for k in range(window, len(white) + 1):
        w = np.array(white[k - window:k])
        nis = float((w * w).sum())
        bad = not (lo * 3 * window <= nis <= hi * 3 * window) or \
            chi2_sf(ljung_box(w, lags), 3 * lags) < alpha
        windows += 1
        failed += bad
        episodes += bad and not prev
        prev = bad
    return {'windows': windows, 'failed': failed, 'episodes': episodes}


def _lb_many(x: np.ndarray, lags: int) -> np.ndarray:
    """Ljung–Box of many windows at once (``ljung_box`` per window, vectorised)."""
    x = x - x.mean(axis=1, keepdims=True)
    n = x.shape[1]
    den = (x * x).sum(axis=1)
    q = np.zeros(len(x))
    for k in range(1, lags + 1):
        r = (x[:, k:] * x[:, :-k]).sum(axis=1) / den
        q += (r * r).sum(axis=1) / (n - k)
    return n * (n + 2) * q


def null_windows(count: int, window: int, levels, seed: int, progress) -> dict:
    """
    Reject white Gaussian windows at nominal levels: the old and the new window tests.

    Parameters
    ----------
    count : int
        Windows.
    window : int
        Fixes per window N.
    levels : sequence of float
        Nominal levels.
    seed : int
        Seed.
    progress : callable
        Progress messages.

    Returns
    -------
    dict
        Per level the rejected share of: Ljung–Box against χ²(3L), the NIS band (two-sided),
        the spectral whiteness test, the combined window test; and the largest difference
        between the vectorised and the package's ``ljung_box``.

    """
    rng = np.random.default_rng(seed)
    lags = max(1, min(10, window // 5))
    lb_p, white_p, nis = [], [], []
    done = 0
    check = 0.0
    while done < count:
        m = min(20_000, count - done)
        x = rng.standard_normal((m, window, 3))
        q = _lb_many(x, lags)
        if done == 0:
            check = max(abs(q[i] - ljung_box(x[i], lags)) for i in range(min(200, m)))
        lb_p += [chi2_sf(v, 3 * lags) for v in q]
        white_p += [spectral_whiteness(w)[0] for w in x]
        nis += list((x * x).sum(axis=(1, 2)))
        done += m
        progress(f'null windows {done}/{count}')
    lb_p, white_p, nis = np.array(lb_p), np.array(white_p), np.array(nis)
    dof = 3 * window
    upper = np.array([chi2_sf(v, dof) for v in nis])
    rows = []
    for a in levels:
        nis_rej = (np.minimum(upper, 1.0 - upper) < 0.5 * a)
        comb = (np.minimum(upper, 1.0 - upper) < 0.25 * a) | (white_p < 0.5 * a)
        rows.append({'level': a, 'ljung_box_chi2': float(np.mean(lb_p < a)),
                     'nis_band': float(np.mean(nis_rej)),
                     'spectral_whiteness': float(np.mean(white_p < a)),
                     'window_test': float(np.mean(comb))})
    return {'windows': count, 'window': window, 'lags': lags, 'rows': rows,
            'ljung_box_vectorised_max_difference': float(check)}


def direct_hours(hours: float, fix_interval: float, window: int, rate: float, seed: int,
                 progress) -> dict:
    """
    Feed :class:`ModelCheck` white innovations for many hours: WARN episodes per hour.

    Parameters
    ----------
    hours : float
        Hours of fixes.
    fix_interval : float
        s between fixes.
    window : int
        Fixes per window.
    rate : float
        Stated false WARN episodes per hour.
    seed : int
        Seed.
    progress : callable
        Progress messages.

    Returns
    -------
    dict
        Fixes, windows, failed windows, episodes, the per-window level, episodes per hour.

    """
    rng = np.random.default_rng(seed)
    S = np.diag(np.array([0.7, 0.7, 6.1]) ** 2) * (4.8481368e-6) ** 2
    L = np.linalg.cholesky(S)
    n = int(round(hours * 3600.0 / fix_interval))
    chk = ModelCheck(window, 0.001, false_alarms_per_hour=rate)
    c = np.eye(3)
    zero = np.zeros(3)
    for k in range(n):
        res = chk.add(k * fix_interval, L @ rng.standard_normal(3), S, c, zero)
        if k % 100_000 == 0:
            progress(f'direct, {fix_interval:g} s fixes: {k}/{n}')
    return {'hours': hours, 'fix_interval_s': fix_interval, 'fixes': n,
            'windows': chk.windows, 'failed': chk.failed, 'episodes': chk.episodes,
            'window_level': res.level, 'episodes_per_hour': chk.episodes / hours,
            'failed_per_hour': chk.failed / hours}


def _nees(outputs, profile) -> float:
    """Mean NEES/3 of the attitude at the outputs (ε against exact truth)."""
    vals = []
    for o in outputs:
        q_true = profile.attitude(o.stamp_ns * 1e-9)
        e = quat_to_rotvec(quat_multiply(quat_conjugate(q_true), o.attitude))
        vals.append(float(e @ np.linalg.solve(o.attitude_covariance, e)) / 3.0)
    return float(np.mean(vals)) if vals else float('nan')


def _summary(name, hours, system, fixes, old, nees, wall) -> dict:
    checks = [f.check for f in fixes if f.check is not None and f.check.verdict != 'filling']
    named = {}
    for c in checks:
        if not c.window_ok:
            key = c.best_effect if c.best_effect else c.verdict
            named[key] = named.get(key, 0) + 1
    st = system.status()
    nis = [f.nis for f in fixes if f.nis is not None]
    return {'motion': name, 'hours': hours, 'fixes': len(nis), 'applied': st['applied'],
            'gated': st['gated'], 'mean_nis': float(np.mean(nis)), 'nees_over_3': nees,
            'windows': st['model_check_windows'], 'failed': st['model_check_failed'],
            'episodes': st['model_check_episodes'], 'named_when_failing': named,
            'level_median': float(np.median([c.level for c in checks])) if checks else None,
            'old': old, 'wall_s': wall}


def clean_runs(hours: float, motions, seed: int, progress, constants_hours: float = 0.0,
               keep_nees: bool = True) -> list:
    """
    Run the filter on clean recordings, ``hours`` split evenly over ``motions``.

    Clean: the simulators' defaults (navigation-grade gyro, 0.6″/0.6″/6″ camera) with a fix
    every second and the random scale and misalignment constants off (:data:`CLEAN`), so the
    filter's model is right.  With ``constants_hours`` > 0, one more three-axis run keeps the
    simulator's random navigation-grade scale (σ 1e-5) and misalignment (σ 3″) constants, which
    the filter does not model.

    Parameters
    ----------
    hours : float
        Total hours.
    motions : sequence of str
        Motion names (:func:`motion`).
    seed : int
        Seed of the first recording (one more per recording).
    progress : callable
        Progress messages.
    constants_hours : float
        Hours of the run with the random constants (0: none).
    keep_nees : bool
        Compute NEES/3 against the exact attitude.

    Returns
    -------
    list of dict
        Per recording: fixes, NIS, NEES/3, windows, failed windows, WARN episodes, what the
        failing windows named, and the old rule's figures on the same innovations.

    """
    out = []
    each = hours / len(motions)
    jobs = [(m, each, dict(CLEAN)) for m in motions]
    if constants_hours > 0:
        jobs.append(('three_axis (random scale and misalignment constants)', constants_hours,
                     {}))
    for k, (name, h, extra) in enumerate(jobs):
        t0 = time.perf_counter()
        prof = motion(name.split(' ')[0], h * 3600.0)
        system, fixes, outputs = simulate(prof, h * 3600.0,
                                          dict(extra, camera_interval=1.0, seed=seed + k),
                                          keep_every=10 if keep_nees else 0)
        used = [f for f in fixes if f.innovation_covariance is not None]
        nees = _nees(outputs, prof) if keep_nees else float('nan')
        out.append(_summary(name, h, system, fixes, old_rule(used), nees,
                            time.perf_counter() - t0))
        progress(f"clean {name}: {h:g} h, {out[-1]['episodes']} episode(s), old rule "
                 f"{out[-1]['old']['episodes']}")
    return out


#: hidden effects of the naming benchmark (simulator parameters, the right answer); sizes are
#: multiplied by the regime's factor (gyro effects only)
NAMING_CASES = [
    ('gyro_scale_factor', {'gyro_scale_factor': [3e-5, -3e-5, 3e-5]}, 'gyro_scale_factor'),
    ('gyro_misalignment (symmetric)',
     {'gyro_misalignment': [3e-5, 2e-5, 3e-5, -2e-5, 2e-5, -2e-5]}, 'gyro_misalignment'),
    ('gyro_bias_drift (bias ramp)', {'gyro_bias_drift': [2e-9, -2e-9, 2e-9]}, 'gyro_bias_drift'),
    ('gyro_scale_asymmetry', {'gyro_scale_asymmetry': [3e-5, -3e-5, 3e-5]},
     'gyro_scale_asymmetry'),
    ('time_offset 4 ms', {'camera_time_offset': 0.004}, 'time_offset'),
    ('time_offset 25 ms', {'camera_time_offset': 0.025}, 'time_offset'),
    ('camera noise ×2 (camera_noise_anisotropy)', {'camera_noise_scale': [2.0, 2.0, 2.0]},
     'camera_noise_anisotropy'),
    ('camera noise ×0.5 (stated noise too large)', {'camera_noise_scale': [0.5, 0.5, 0.5]},
     'noise_too_large'),
    ('gyro_bias_periodic (outside the library)',
     {'gyro_bias_periodic': [1e-6, -1e-6, 1e-6], 'gyro_bias_period': 300.0}, None),
]
#: the regimes: simulator and filter overrides, the motion's amplitude factor, the factor on the
#: gyro effects' sizes
REGIMES = {
    'navigation': {'sim': {}, 'filter': {}, 'gyro_factor': 1.0,
                   'text': 'navigation-grade gyro (ARW 3.5e-7 rad/√s), camera 0.6″/0.6″/6″: '
                           'the filter averages many fixes (low gain)'},
    'high_gain': {'sim': {'gyro_random_walk': 3e-5, 'camera_sigma_xy': 3e-5,
                          'camera_sigma_z': 3e-5},
                  'filter': {'gyro_random_walk': 3e-5}, 'gyro_factor': 30.0,
                  'text': 'gyro ARW 3e-5 rad/√s, camera σ 3e-5 rad per axis: the filter '
                          'follows its fixes (high gain); gyro effects 30× larger'},
}
_GYRO_EFFECTS = ('gyro_scale_factor', 'gyro_misalignment', 'gyro_bias_drift',
                 'gyro_scale_asymmetry', 'gyro_bias_periodic')


def _right(check, answer) -> bool:
    if answer == 'noise_too_large':
        return check.verdict == 'noise_too_large'
    return answer is not None and check.best_effect == answer


def naming_runs(seconds: float, seeds: int, regimes, progress) -> dict:
    """
    Name single hidden effects under three-axis sinusoidal motion, per regime.

    Parameters
    ----------
    seconds : float
        Length of each recording, s.
    seeds : int
        Recordings per effect and regime.
    regimes : sequence of str
        Keys of :data:`REGIMES`.
    progress : callable
        Progress messages.

    Returns
    -------
    dict
        Per regime, per effect: windows, failing windows, the windows naming the right effect,
        and every name given by the failing windows.

    """
    out = {}
    for reg in regimes:
        r = REGIMES[reg]
        rows = []
        for label, eff, answer in NAMING_CASES:
            eff = {k: (list(np.asarray(v) * r['gyro_factor']) if k in _GYRO_EFFECTS else v)
                   for k, v in eff.items()}
            tot = {'windows': 0, 'failed': 0, 'right': 0, 'right_when_failing': 0,
                   'applied': 0, 'gated': 0, 'names': {}}
            for s in range(seeds):
                t0 = time.perf_counter()
                sim = dict(CLEAN, camera_interval=1.0, seed=100 + s, **r['sim'], **eff)
                system, fixes, _ = simulate(ThreeAxisSinusoid(), seconds, sim, r['filter'])
                st = system.status()
                tot['applied'] += st['applied']
                tot['gated'] += st['gated']
                for f in fixes:
                    c = f.check
                    if c is None or c.verdict == 'filling':
                        continue
                    tot['windows'] += 1
                    ok = _right(c, answer)
                    tot['right'] += ok
                    if not c.window_ok:
                        tot['failed'] += 1
                        tot['right_when_failing'] += ok
                        key = c.best_effect if c.verdict == 'effect' else c.verdict
                        tot['names'][key] = tot['names'].get(key, 0) + 1
                progress(f'naming {reg} {label} seed {s}: {time.perf_counter() - t0:.0f} s')
            rows.append(dict(tot, effect=label, answer=answer, parameters=eff))
        out[reg] = {'text': r['text'], 'rows': rows}
    return out


def _command(cmd: list) -> subprocess.CompletedProcess:
    """Run a command; its failure as a ValueError with its last line of stderr."""
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        lines = (done.stderr or done.stdout).strip().splitlines() or ['(no output)']
        raise ValueError(f'{cmd[2]} exited {done.returncode}: {lines[-1]}')
    return done


def bag_run(hours: float, seed: int, workdir: str | None, progress) -> dict:
    """
    Write a clean recording with ``record_sim`` and run ``filter_bag`` on it (subprocesses).

    Coning, a fix every second, the random scale and misalignment constants off.

    Parameters
    ----------
    hours : float
        Length, h.
    seed : int
        Simulator seed.
    workdir : str or None
        Directory for the bag and CSVs (None: a temporary one, removed).
    progress : callable
        Progress messages.

    Returns
    -------
    dict
        Fixes, the WARN episodes (``check_ok`` 1 → 0 transitions of the fixes CSV), the mean
        NIS, the commands and ``filter_bag``'s summary lines.

    """
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        bag = os.path.join(tmp, 'clean')
        out = os.path.join(tmp, 'o.csv')
        rec = [sys.executable, '-m', 'strapdown_ros.tools.record_sim', bag, '--duration',
               f'{hours * 3600:g}', '--no-accel', '-p', 'profile:=coning', '-p',
               'camera_interval:=1.0', '-p', 'gyro_scale_sigma:=0.0', '-p',
               'gyro_misalignment_sigma:=0.0', '-p', f'seed:={seed}']
        filt = [sys.executable, '-m', 'strapdown_ros.tools.filter_bag', bag, '--output', out]
        t0 = time.perf_counter()
        _command(rec)
        progress(f'record_sim {hours:g} h: {time.perf_counter() - t0:.0f} s')
        t1 = time.perf_counter()
        done = _command(filt)
        progress(f'filter_bag: {time.perf_counter() - t1:.0f} s')
        with open(os.path.join(tmp, 'o_fixes.csv'), newline='') as fh:
            rows = list(csv.DictReader(fh))
    ok = [r['check_ok'] == '1' for r in rows if r['status'] in ('applied', 'gated')]
    episodes = sum(1 for a, b in zip([True] + ok[:-1], ok) if a and not b)
    nis = [float(r['nis']) for r in rows if r['status'] in ('applied', 'gated')]
    return {'hours': hours, 'fixes': len(ok), 'episodes': episodes,
            'mean_nis': float(np.mean(nis)) if nis else float('nan'),
            'record_sim': ' '.join(['record_sim'] + rec[3:]).replace(bag, 'BAG'),
            'filter_bag': 'filter_bag BAG --output OUT.csv',
            'filter_bag_summary': done.stdout.replace(tmp, 'DIR').strip().splitlines()}
