"""
Run the whole strapdown chain over an Earth profile and compare with its exact truth.

The profile is a :class:`~strapdown_ros.motion.earth_profiles.EarthProfile`; the chain is
increments → :class:`~strapdown_ros.attitude.integrator.AttitudeIntegrator` (attitude q_I_B,
I = E at t0) → :class:`~.navigator.Navigator` (position and velocity in E) → errors.  Used by
``nav_bench`` and the navigation tests.

* :func:`generate_increments`: the gyro Δθ and accelerometer Δv of a profile on uniform grids,
  sampled by :class:`strapdown_ros.sensors.model.IntegratingSensor` (perfect sensors, or the
  sensor errors of a :class:`~strapdown_ros.sensors.model.SensorErrorModel`, applied exactly as
  the simulator applies them; :class:`~strapdown_ros.sensors.model.SensorSigmas` are drawn the
  way :func:`~strapdown_ros.sensors.simulated.simulated_imu` draws them: gyro first, then
  accelerometer, from ``default_rng(seed)``; noise streams seed+1 and seed+2).
* :func:`navigate`: the chain over given increments, in blocks, timed (data generation is not).
* :func:`run_profile`: both, plus the truth at the update stamps and the errors.
* :func:`specific_force_drift`: the drift of the specific-force integral Δv of a form of
  :mod:`.update` against the exact ∫C f dt (used for the sculling check; no navigation, so
  neither the Schuler loop nor the vertical channel distorts it).

Frames: the navigator starts at ``t0 = 0`` (the profile's origin), where I = E, so the
integrator's initial attitude is ``q_E_B(0)`` and the attitude at the *start* of each update is
the previous update's attitude.  No ROS imports.
"""
from __future__ import annotations

import time

import numpy as np

from strapdown_ros.attitude.coning import get_algorithm
from strapdown_ros.attitude.integrator import AttitudeIntegrator
from strapdown_ros.earth import ecef_to_geodetic, enu_rotation
from strapdown_ros.navigation import recursion
from strapdown_ros.navigation.covariance import NavigationCovariance
from strapdown_ros.navigation.navigator import Navigator
from strapdown_ros.navigation.update import specific_force_integrals, step_layout
from strapdown_ros.rotation import quat_angle_between, quat_to_dcm
from strapdown_ros.sensors.model import (IntegratingSensor, NAVIGATION_GRADE_ACCEL,
                                         NAVIGATION_GRADE_GYRO, SensorErrorModel, SensorSigmas)

__all__ = ['Increments', 'generate_increments', 'navigate', 'run_profile', 'summarize',
           'specific_force_drift', 'steps_per_update']


_EPS = 1e-9          # stamps at or below this are before the start t0 = 0


class Increments:
    """
    Sensor increments of one run, with the rates and the error models used.

    Parameters
    ----------
    tg : (n_g,) ndarray
        End stamps of the gyro increments, s.
    dth : (n_g, 3) ndarray
        Gyro increments, body axes, rad.
    ta : (n_a,) ndarray
        End stamps of the accelerometer increments, s.
    dv : (n_a, 3) ndarray
        Accelerometer increments, body axes, m/s.
    gyro_rate, accel_rate : float
        Sample rates, Hz.
    gyro_errors, accel_errors : SensorErrorModel or None
        The error models applied (None: perfect sensors).

    """

    def __init__(self, tg, dth, ta, dv, gyro_rate, accel_rate, gyro_errors, accel_errors):
        self.tg, self.dth, self.ta, self.dv = tg, dth, ta, dv
        self.gyro_rate, self.accel_rate = float(gyro_rate), float(accel_rate)
        self.gyro_errors, self.accel_errors = gyro_errors, accel_errors

    @property
    def duration(self) -> float:
        """
        Return the length of the run after t0 = 0.

        Returns
        -------
        float
            Seconds of gyro data after the start.

        """
        return float(np.sum(self.tg > _EPS)) / self.gyro_rate


def _errors(gyro_errors, accel_errors, seed: int):
    """Return a SensorErrorModel pair from models, sigmas (drawn as simulated_imu does) or None."""
    rng = np.random.default_rng(seed)
    out = []
    for e in (gyro_errors, accel_errors):
        if isinstance(e, SensorSigmas):
            e = e.draw(rng)
        elif e is not None and not isinstance(e, SensorErrorModel):
            raise TypeError('sensor errors must be a SensorErrorModel, SensorSigmas or None, '
                            f'got {type(e).__name__}')
        out.append(e)
    return out


def steps_per_update(algorithm: str, gyro_rate: float, accel_rate: float) -> tuple[int, int]:
    """
    Return the gyro and accelerometer increments per navigation step.

    Parameters
    ----------
    algorithm : str
        Coning algorithm (its samples per update make one step).
    gyro_rate, accel_rate : float
        Sample rates, Hz; the accelerometer rate must be an integer multiple of the gyro rate.

    Returns
    -------
    tuple of int
        ``(gyro, accelerometer)`` increments per step.

    Raises
    ------
    ValueError
        When the rates are not in an integer ratio of at least 1.

    """
    n = get_algorithm(algorithm).samples
    ratio = accel_rate / gyro_rate
    if not (np.isfinite(ratio) and ratio >= 1 and abs(ratio - round(ratio)) < 1e-9):
        raise ValueError('the accelerometer rate must be an integer multiple of the gyro rate, '
                         f'got {accel_rate:g} and {gyro_rate:g} Hz')
    return n, n * int(round(ratio))


def generate_increments(profile, duration: float, gyro_rate: float = 100.0,
                        accel_rate: float = 300.0, gyro_errors=None, accel_errors=None,
                        seed: int = 0, block: int = 36000, history: int = 0) -> Increments:
    """
    Sample the increments of a profile over ``[0, duration]`` by two integrating sensors.

    Parameters
    ----------
    profile : EarthProfile
        The motion, with exact truth.
    duration : float
        Length, s.
    gyro_rate, accel_rate : float
        Sample rates, Hz, in an integer ratio.
    gyro_errors, accel_errors : SensorErrorModel, SensorSigmas or None
        Sensor errors: a model, statistics to draw one from, or None (perfect sensors).
    seed : int
        Seed of the draws and of the noise streams (seed+1, seed+2).
    block : int
        Gyro intervals sampled at a time, to bound the quadrature's memory.
    history : int
        The sensors start that many gyro periods before t = 0 (the navigator then has the
        increments before its start that its fits reach back to; the attitude integrator
        still starts at t = 0).

    Returns
    -------
    Increments
        The sampled increments.

    Raises
    ------
    ValueError
        For a duration that is not positive or rates not in an integer ratio.

    """
    if not (np.isfinite(duration) and duration > 0):
        raise ValueError(f'duration must be > 0, got {duration}')
    ratio = accel_rate / gyro_rate
    if not (np.isfinite(ratio) and ratio >= 1 and abs(ratio - round(ratio)) < 1e-9):
        raise ValueError('the accelerometer rate must be an integer multiple of the gyro rate, '
                         f'got {accel_rate:g} and {gyro_rate:g} Hz')
    ge, ae = _errors(gyro_errors, accel_errors, seed)
    history = max(0, int(history))
    start = -history / gyro_rate
    gyro = IntegratingSensor(profile, 'gyro', gyro_rate, ge, seed=seed + 1, start_time=start)
    accel = IntegratingSensor(profile, 'accel', accel_rate, ae, seed=seed + 2, start_time=start)
    n_g = int(round(duration * gyro_rate)) + history
    n_a = int(round(duration * accel_rate)) + history * int(round(ratio))
    ratio = max(1, int(round(accel_rate / gyro_rate)))
    tg, dth, ta, dv = [], [], [], []
    for s in range(0, n_g, block):
        k = min(block, n_g - s)
        t, m, _ = gyro.sample(k)
        tg.append(t)
        dth.append(m)
    for s in range(0, n_a, block * ratio):
        k = min(block * ratio, n_a - s)
        t, m, _ = accel.sample(k)
        ta.append(t)
        dv.append(m)
    return Increments(np.concatenate(tg), np.concatenate(dth), np.concatenate(ta),
                      np.concatenate(dv), gyro_rate, accel_rate, ge, ae)


def navigate(inc: Increments, position0, velocity0, attitude0, algorithm: str = '2',
             form: str = 'exact', scheme: str = 'exact', covariance=False,
             block: int = 36000) -> dict:
    """
    Run the chain over given increments: attitude integrator, navigator, both covariances.

    Parameters
    ----------
    inc : Increments
        The sensor data.
    position0, velocity0 : (3,) array_like
        ECEF position (m) and velocity (m/s) at t0 = 0.
    attitude0 : (4,) array_like
        q_E_B at t0 = 0 (= q_I_B: I = E at t0), scalar first.
    algorithm : str
        Coning algorithm.
    form : str
        Specific-force form (:data:`.update.FORMS`).
    scheme : str
        Recursion scheme (:data:`.recursion.SCHEMES`).
    covariance : bool or tuple of SensorSigmas
        False, True (navigation-grade :data:`NAVIGATION_GRADE_GYRO` / ``_ACCEL`` statistics)
        or a (gyro, accel) pair.
    block : int
        Gyro increments pushed at a time.

    Returns
    -------
    dict
        Per update ``t``, ``position``, ``velocity``, ``attitude`` (q_E_B), ``sigma`` (K, 9)
        navigation 1σ [δR, δW, ψ] and ``attitude_sigma`` (K, 3) body-axis attitude 1σ (NaN
        without covariance); ``wall_s`` of the chain alone, step and update counts.

    """
    n_g_step, n_a_step = steps_per_update(algorithm, inc.gyro_rate, inc.accel_rate)
    ratio = n_a_step // n_g_step
    if covariance is True:
        sig_g, sig_a = NAVIGATION_GRADE_GYRO, NAVIGATION_GRADE_ACCEL
    elif covariance:
        sig_g, sig_a = covariance
    else:
        sig_g = sig_a = None
    recursion.warm_up()
    t0 = time.perf_counter()
    integ = AttitudeIntegrator(algorithm, initial_attitude=np.asarray(attitude0, dtype=float),
                               initial_time=0.0, nominal_period=1.0 / inc.gyro_rate, gyro=sig_g,
                               propagate_covariance=sig_g is not None)
    cov = NavigationCovariance(sig_g, sig_a, np.zeros((9, 9))) if sig_g is not None else None
    nav = Navigator(position0, velocity0, 0.0, n_g_step, n_a_step, 1.0 / inc.gyro_rate,
                    1.0 / inc.accel_rate, form=form, scheme=scheme, covariance=cov)
    q_prev = integ.q.copy()
    out = {k: [] for k in ('t', 'position', 'velocity', 'attitude', 'sigma', 'attitude_sigma')}
    att_sig = []
    # increments before t0: the navigator's history only
    g0 = int(np.sum(inc.tg <= _EPS))
    a0 = int(np.sum(inc.ta <= _EPS))
    if g0:
        nav.add_gyro(inc.dth[:g0], inc.tg[:g0])
        nav.add_accel(inc.dv[:a0], inc.ta[:a0])
    n_g = len(inc.tg) - g0
    for s in range(0, n_g, block):
        e = min(n_g, s + block)
        gs, ge_, as_, ae_ = g0 + s, g0 + e, a0 + s * ratio, a0 + e * ratio
        nav.add_gyro(inc.dth[gs:ge_], inc.tg[gs:ge_])
        nav.add_accel(inc.dv[as_:ae_], inc.ta[as_:ae_])
        b = integ.push(inc.dth[gs:ge_], inc.tg[gs:ge_])
        if len(b):
            q_start = np.vstack([q_prev[None], b.attitude[:-1]])
            q_prev = b.attitude[-1]
            nav.add_updates(b.stamps, b.interval, b.attitude, q_start)
            var = np.diagonal(b.covariance, axis1=1, axis2=2)
            att_sig.append(np.sqrt(np.clip(var, 0, None)))
        r = nav.process()
        if len(r):
            out['t'].append(r.stamps)
            out['position'].append(r.position)
            out['velocity'].append(r.velocity)
            out['attitude'].append(r.attitude)
            var = np.diagonal(r.covariance, axis1=1, axis2=2)
            out['sigma'].append(np.sqrt(np.clip(var, 0, None)))
    wall = time.perf_counter() - t0
    res = {k: np.concatenate(v) if v else np.zeros((0,))
           for k, v in out.items() if k != 'attitude_sigma'}
    a = np.concatenate(att_sig) if att_sig else np.zeros((0, 3))
    res['attitude_sigma'] = a[:len(res['t'])]
    res.update(wall_s=wall, steps=nav.steps, extrapolated_steps=nav.extrapolated_steps,
               updates=integ.updates, gyro_per_step=n_g_step, accel_per_step=n_a_step)
    return res


def run_profile(profile, duration: float, gyro_rate: float = 100.0, accel_rate: float = 300.0,
                algorithm: str = '2', form: str = 'exact', scheme: str = 'exact',
                gyro_errors=None, accel_errors=None, covariance=False, block: int = 36000,
                seed: int = 0, history: int = 0,
                increments: Increments | None = None) -> dict:
    """
    Navigate a profile and compare with its truth at every update stamp.

    Parameters
    ----------
    profile : EarthProfile
        The motion, with exact truth.
    duration : float
        Length, s.
    gyro_rate, accel_rate : float
        Sample rates, Hz, in an integer ratio.
    algorithm, form, scheme : str
        Coning algorithm, specific-force form and recursion scheme (:func:`navigate`).
    gyro_errors, accel_errors : SensorErrorModel, SensorSigmas or None
        Sensor errors (:func:`generate_increments`).
    covariance : bool or tuple of SensorSigmas
        As in :func:`navigate`.
    block : int
        Gyro intervals per block.
    seed : int
        Seed of the sensor errors.
    history : int
        Gyro periods of sensor data before t0 (:func:`generate_increments`; 0: the sensors
        start with the navigator, as in the node).
    increments : Increments or None
        Data already generated; then ``duration``, rates, errors, ``seed`` and ``history``
        are taken from it.

    Returns
    -------
    dict
        The arrays of :func:`navigate` plus ``true_position``, ``true_velocity``,
        ``true_attitude`` (q_E_B), ``position_error`` / ``velocity_error`` (K, 3, ECEF,
        estimate − truth), ``position_error_norm``, ``velocity_error_norm``,
        ``horizontal_error`` and ``vertical_error`` (along the geodetic up of the true
        position, m), ``attitude_error`` (rad), and the configuration.

    """
    inc = increments if increments is not None else generate_increments(
        profile, duration, gyro_rate, accel_rate, gyro_errors, accel_errors, seed, block, history)
    r0 = profile.position(0.0)
    w0 = profile.velocity(0.0)
    q0 = profile.attitude_ecef(0.0)
    res = navigate(inc, r0, w0, q0, algorithm, form, scheme, covariance, block)
    t = res['t']
    res['true_position'] = profile.position(t)
    res['true_velocity'] = profile.velocity(t)
    res['true_attitude'] = profile.attitude_ecef(t)
    dp = res['position'] - res['true_position']
    res['position_error'] = dp
    res['velocity_error'] = res['velocity'] - res['true_velocity']
    res['position_error_norm'] = np.linalg.norm(dp, axis=-1)
    res['velocity_error_norm'] = np.linalg.norm(res['velocity_error'], axis=-1)
    lat, lon, _ = ecef_to_geodetic(res['true_position'])
    up = enu_rotation(lat, lon)[..., :, 2]
    vert = np.einsum('ki,ki->k', dp, up)
    res['vertical_error'] = vert
    res['horizontal_error'] = np.linalg.norm(dp - vert[:, None] * up, axis=-1)
    res['attitude_error'] = quat_angle_between(res['attitude'], res['true_attitude'])
    res.update(profile=getattr(profile, 'name', 'profile'), duration=inc.duration,
               gyro_rate=inc.gyro_rate, accel_rate=inc.accel_rate, algorithm=algorithm,
               form=form, scheme=scheme, covariance=bool(covariance),
               history=int(np.sum(inc.tg <= _EPS)))
    return res


def summarize(res: dict) -> dict:
    """
    Return the final and maximum errors of a run.

    Parameters
    ----------
    res : dict
        A :func:`run_profile` result.

    Returns
    -------
    dict
        ``final_*`` and ``max_*`` of the position (m), velocity (m/s), horizontal and vertical
        (m) and attitude (rad) errors as plain floats, the configuration, and
        ``final_position_sigma_m`` when the covariance was propagated.

    """
    def fm(x):
        return (float(x[-1]), float(np.max(np.abs(x)))) if len(x) else (float('nan'), float('nan'))
    out = {}
    for key, name in (('position_error_norm', 'position_m'),
                      ('velocity_error_norm', 'velocity_m_s'),
                      ('horizontal_error', 'horizontal_m'), ('vertical_error', 'vertical_m'),
                      ('attitude_error', 'attitude_rad')):
        f, m = fm(res[key])
        out[f'final_{name}'], out[f'max_{name}'] = f, m
    for k in ('profile', 'algorithm', 'form', 'scheme', 'duration', 'steps',
              'extrapolated_steps', 'wall_s'):
        out[k] = res[k]
    if res.get('covariance') and len(res['sigma']):
        out['final_position_sigma_m'] = float(np.linalg.norm(res['sigma'][-1, :3]))
    return out


def specific_force_drift(profile, duration: float, gyro_rate: float = 100.0,
                         accel_rate: float = 300.0, gyro_per_step: int = 1,
                         form: str = 'rotation_only', skip: int = 4) -> dict:
    """
    Measure the drift of the specific-force integral Δv of a form against the exact ∫C f dt.

    Per navigation step ``[t_{k−1}, t_k]`` (``gyro_per_step`` gyro intervals, the accelerometer
    intervals in it): Δv_k of :func:`.update.specific_force_integrals` from the exact increments,
    rotated into E with the *true* attitude at the step start, minus the exact ``∫ C f dt`` over
    the step (the profile's own Gauss–Legendre quadrature of the truth, in the inertial frame of
    the step start = E there).  The differences are accumulated over the run and the slope of
    the running sum against time (least squares; the first ``skip`` steps, whose fit windows
    reach before t = 0, are left out) is the drift, m/s².  No navigation: neither the Schuler
    loop nor the vertical channel distorts it.

    Parameters
    ----------
    profile : EarthProfile
        The motion, with exact truth.
    duration : float
        Length, s.
    gyro_rate, accel_rate : float
        Sample rates, Hz, in an integer ratio.
    gyro_per_step : int
        Gyro intervals per step.
    form : str
        Specific-force form (:data:`.update.FORMS`).
    skip : int
        First steps left out of the fit.

    Returns
    -------
    dict
        ``slope_earth`` (ECEF axes, m/s²), ``slope_up`` (its component along the geodetic up
        of the start position: the navigation's vertical), ``slope_body`` (the same
        differences in body axes at each step start: differs from the E-frame slope at second
        order in the attitude oscillation, because an oscillating body-axis error correlated
        with the attitude has a mean in E), ``mean_specific_force``, ``per_step_rms``,
        ``form``, ``step`` and ``steps``.

    """
    ratio = int(round(accel_rate / gyro_rate))
    n, m = int(gyro_per_step), int(gyro_per_step) * ratio
    lay = step_layout(n, m)
    h = n / gyro_rate
    k_steps = int(round(duration / h))
    tg = np.arange(k_steps * n + 1) / gyro_rate
    ta = np.arange(k_steps * m + 1) / accel_rate
    dth = profile.delta_theta(tg[:-1], tg[1:])
    dv = profile.delta_v(ta[:-1], ta[1:])
    qp = np.vstack([np.zeros((lay.gyro_window - n, 3)), dth])
    up = np.vstack([np.zeros((lay.accel_window - m, 3)), dv])
    windows = np.lib.stride_tricks.sliding_window_view
    qw = np.moveaxis(windows(qp, lay.gyro_window, axis=0)[::n][:k_steps], -1, 1)
    uw = np.moveaxis(windows(up, lay.accel_window, axis=0)[::m][:k_steps], -1, 1)
    ts = tg[:-1:n][:k_steps]
    te = tg[n::n][:k_steps]
    dv_b, _ = specific_force_integrals(qw, uw, te - ts, lay, form)

    def c_f(t):
        c = quat_to_dcm(profile.attitude(t))
        return np.einsum('...ij,...j->...i', c, profile.specific_force(t))

    exact_i = profile.integrate(c_f, ts, te)              # ∫ C_I_B f dt, I axes
    exact_b = np.einsum('kji,kj->ki', quat_to_dcm(profile.attitude(ts)), exact_i)
    diff_b = (dv_b - exact_b)[skip:]
    diff_e = np.einsum('kij,kj->ki', quat_to_dcm(profile.attitude_ecef(ts[skip:])), diff_b)
    t = te[skip:]
    slope_b = np.polyfit(t, np.cumsum(diff_b, axis=0), 1)[0]
    slope_e = np.polyfit(t, np.cumsum(diff_e, axis=0), 1)[0]
    lat, lon, _ = ecef_to_geodetic(profile.position(0.0))
    up_dir = enu_rotation(lat, lon)[:, 2]
    mean_f = float(np.mean(np.linalg.norm(exact_b, axis=-1)) / h)
    return {'form': form, 'step': h, 'steps': k_steps, 'slope_earth': slope_e,
            'slope_up': float(slope_e @ up_dir), 'slope_body': slope_b,
            'mean_specific_force': mean_f,
            'per_step_rms': float(np.sqrt(np.mean(np.sum(diff_b ** 2, -1))))}
