"""
Measuring coning algorithms on exact coning motion: drift, round-off floor, order, cost.

The library under ``coning_bench`` and the reproduction of 003 §2.3; the measured figures are
in doc/coning.md.

Drift
    The cone-axis (reference Z) component of the attitude error
    ``e = 2·vec(q_est ⊗ q_true*)_z`` is fitted with a least-squares line over the update
    epochs of a whole number of cone periods; the slope is the drift (rad/s).  The periodic
    error largely cancels over whole periods.  Sums are accumulated chunk by chunk, so an
    hour at 1 kHz never sits in memory.  Accelerating algorithms start with padded history;
    their first ``history + 1`` epochs are left out.

Round-off floor
    The same arithmetic path (rotation vector → quaternion → product → renormalise) fed
    with the *exact* rotation vector of every update, ``φ_k = log(q_true(t_{k−1})* ⊗
    q_true(t_k))``, has no algorithmic error: its fitted slope is pure float64 round-off.
    The floor reported is ``|slope| + 3σ_slope`` of that run (σ from the residual scatter),
    one per update interval.  A result with ``|drift| ≤ floor`` is marked ``floor``.

Reference ("peer")
    Besides the closed-form truth of :class:`~strapdown_ros.motion.profiles.ConingProfile`, the
    attitude can come from a direct numerical solution of ``dq/dt = ½ q ⊗ (0, ω)`` by
    scipy's DOP853 (8th order, rtol 1e-13) — an independent reference.

No ROS imports; scipy only for the ODE reference.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import time

import numpy as np

from strapdown_ros.attitude.coning import ALGORITHMS, theory_drift
from strapdown_ros.attitude.integrator import AttitudeIntegrator
from strapdown_ros.motion.profiles import ConingProfile
from strapdown_ros.rotation import (quat_conjugate, quat_cumprod, quat_multiply, quat_normalize,
                                    quat_to_rotvec, rotvec_to_quat)

__all__ = ['LineFit', 'ode_reference', 'measure_case', 'order_sweep', 'cost_per_update',
           'CaseResult']

#: the three coning cases of 003 §2.3 (α rad, ν rad/s) and its two update periods (s)
THESIS_CASES = [(0.087, 1.0), (0.5, 1.0), (0.087, 0.5)]
THESIS_STEPS = [0.01, 0.001]
THESIS_RANKING = ['7', '6', '4+', '5', '4', '3.1', '3', '2', '1']       # best first, 003 §2.3
#: a drift within this factor of the case's round-off floor estimate is marked ``floor``
FLOOR_FACTOR = 3.0


class LineFit:
    """
    Streaming least-squares line e(t) = a + b·(t − t0), with residual scatter.

    Parameters
    ----------
    t0 : float
        Time origin of the fit, s (the middle of the span keeps the sums well conditioned).

    """

    def __init__(self, t0: float):
        self.t0 = t0
        self.n = 0
        self.st = self.se = self.stt = self.ste = self.see = 0.0

    def add(self, t: np.ndarray, e: np.ndarray):
        """
        Add points to the fit.

        Parameters
        ----------
        t : (n,) array_like
            Times, s.
        e : (n,) array_like
            Values at those times.

        """
        x = np.asarray(t, dtype=float) - self.t0
        e = np.asarray(e, dtype=float)
        self.n += len(x)
        self.st += x.sum()
        self.se += e.sum()
        self.stt += x @ x
        self.ste += x @ e
        self.see += e @ e

    def slope(self) -> tuple[float, float]:
        """
        Return the fitted slope and its 1σ.

        Returns
        -------
        tuple of float
            (slope, 1σ of the slope from the residual scatter), per second.

        """
        n = self.n
        sxx = self.stt - self.st ** 2 / n
        sxe = self.ste - self.st * self.se / n
        b = sxe / sxx
        see = self.see - self.se ** 2 / n
        resid = max(see - b * sxe, 0.0) / max(n - 2, 1)
        return b, float(np.sqrt(resid / sxx))


def ode_reference(profile: ConingProfile, duration: float, rtol: float = 1e-13,
                  atol: float = 1e-15):
    """
    Solve the quaternion kinematics of a coning profile by DOP853 (scipy), densely.

    Parameters
    ----------
    profile : ConingProfile
        The motion.
    duration : float
        End of the solution, s (from 0).
    rtol, atol : float
        Tolerances of the solver.

    Returns
    -------
    callable
        ``attitude(t) -> (n, 4)`` ``q_ref_body``, scalar first; its ``nfev`` attribute is the
        number of right-hand-side evaluations.

    Raises
    ------
    RuntimeError
        When the solver fails.

    """
    from scipy.integrate import solve_ivp

    def rhs(t, q):
        w = profile.body_rate(t)
        return 0.5 * quat_multiply(q, np.concatenate([[0.0], w]))

    sol = solve_ivp(rhs, (0.0, duration), profile.attitude(0.0), method='DOP853', rtol=rtol,
                    atol=atol, dense_output=True)
    if not sol.success:
        raise RuntimeError(f'ODE reference failed: {sol.message}')

    def attitude(t):
        return quat_normalize(sol.sol(np.asarray(t, dtype=float)).T)
    attitude.nfev = sol.nfev
    return attitude


def _cone_error(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    d = quat_multiply(q_est, quat_conjugate(q_true))
    return 2.0 * d[:, 3] * np.sign(d[:, 0])


@dataclass
class CaseResult:
    """
    Drift of the algorithms on one coning case (:func:`measure_case`).

    Parameters
    ----------
    alpha : float
        Cone half-angle α, rad.
    nu : float
        Cone frequency ν, rad/s.
    step : float
        Gyro sample interval τ, s.
    duration : float
        Length of the run, s.
    fitted_until : float
        End of the fitted span (whole cone periods), s.
    drift : dict
        Algorithm name → drift against the analytic truth, rad/s.
    drift_ode : dict
        Algorithm name → drift against the ODE truth, rad/s, when computed.
    floor : dict
        Samples per update N → round-off floor, rad/s.
    truth_gap : float
        Largest angle between the analytic and the ODE truth, rad (NaN without the ODE).
    wall_s : float
        Wall time of the case, s.

    """

    alpha: float
    nu: float
    step: float
    duration: float
    fitted_until: float
    drift: dict = field(default_factory=dict)
    drift_ode: dict = field(default_factory=dict)
    floor: dict = field(default_factory=dict)
    truth_gap: float = float('nan')
    wall_s: float = 0.0


def measure_case(names, alpha: float, nu: float, step: float, duration: float,
                 with_ode: bool = False, chunk: int = 120_000) -> CaseResult:
    """
    Measure the drift of algorithms on one coning case, with the round-off floors.

    Parameters
    ----------
    names : sequence of str
        Algorithms of the coning registry.
    alpha : float
        Cone half-angle α, rad.
    nu : float
        Cone frequency ν, rad/s.
    step : float
        Gyro sample interval τ, s.
    duration : float
        Length of the run, s; at least one cone period.
    with_ode : bool
        Also measure against the DOP853 reference (:func:`ode_reference`).
    chunk : int
        Samples generated at a time (bounds the memory).

    Returns
    -------
    CaseResult
        Drifts, floors and timing.

    Raises
    ------
    ValueError
        When ``duration`` is shorter than one cone period.

    """
    t_wall = time.perf_counter()
    prof = ConingProfile(alpha, nu)
    n_total = int(round(duration / step))
    period = prof.cone_period
    t_fit = np.floor(n_total * step / period + 1e-9) * period
    if t_fit <= 0:
        raise ValueError(f'duration {duration} s is shorter than one cone period {period:.4g} s')
    algs = {n: ALGORITHMS[n] for n in names}
    integ = {n: AttitudeIntegrator(n, prof.attitude(0.0), 0.0, nominal_period=step,
                                   propagate_covariance=False)
             for n in names}
    fits = {n: LineFit(t_fit / 2) for n in names}
    fits_ode = {n: LineFit(t_fit / 2) for n in names}
    seen = dict.fromkeys(names, 0)
    ns = sorted({a.samples for a in algs.values()})
    floor_q = {n: prof.attitude(0.0) for n in ns}
    floor_fit = {n: LineFit(t_fit / 2) for n in ns}
    ref = ode_reference(prof, n_total * step) if with_ode else None
    gap = 0.0
    for start in range(0, n_total, chunk):
        stop = min(n_total, start + chunk)
        t = np.arange(start, stop + 1) * step
        dth = prof.delta_theta(t[:-1], t[1:])
        truth = prof.attitude(t)                       # t[0] is the previous epoch
        truth_ode = ref(t[1:]) if ref is not None else None
        if truth_ode is not None:
            diff = quat_multiply(quat_conjugate(truth[1:]), truth_ode)[:, 1:]
            angle = 2 * np.arcsin(np.minimum(1.0, np.linalg.norm(diff, axis=1)))
            gap = max(gap, float(np.max(angle)))
        for name, a in algs.items():
            out = integ[name].push(dth, t[1:])
            if len(out) == 0:
                continue
            # 1-based sample index in the chunk
            idx = np.rint(out.stamps / step).astype(int) - start
            skip = max(0, (a.history + 1 if a.history else 0) - seen[name])
            seen[name] += len(out)
            keep = (out.stamps <= t_fit + 1e-9)
            keep[:skip] = False
            if not np.any(keep):
                continue
            att = out.attitude[keep]
            fits[name].add(out.stamps[keep], _cone_error(att, truth[idx[keep]]))
            if truth_ode is not None:
                fits_ode[name].add(out.stamps[keep], _cone_error(att, truth_ode[idx[keep] - 1]))
        # floor: exact rotation vector of each N-sample update through the same arithmetic
        for n in ns:
            first = (-start) % n              # updates end at global sample multiples of n
            ends = np.arange(first + n, stop - start + 1, n)
            if len(ends) == 0:
                continue
            q_prev = truth[ends - n]
            phi = quat_to_rotvec(quat_multiply(quat_conjugate(q_prev), truth[ends]))
            q = quat_cumprod(floor_q[n], rotvec_to_quat(phi))
            floor_q[n] = q[-1]
            te = t[ends]
            keep = te <= t_fit + 1e-9
            if np.any(keep):
                floor_fit[n].add(te[keep], _cone_error(q[keep], truth[ends][keep]))
    res = CaseResult(alpha, nu, step, duration, t_fit, truth_gap=gap if with_ode else float('nan'))
    for name in names:
        res.drift[name] = fits[name].slope()[0]
        if with_ode:
            res.drift_ode[name] = fits_ode[name].slope()[0]
    for n in ns:
        b, s = floor_fit[n].slope()
        res.floor[n] = abs(b) + 3.0 * s
    res.wall_s = time.perf_counter() - t_wall
    return res


def order_sweep(name: str, omega_h=None, alpha: float | None = None, periods: int = 20,
                nu: float = 1.0):
    """
    Measure the drift ε/(α²Ω) at several Ωh (small α) and the order it shows.

    The order is fitted over the points above the round-off floor, beside the small-α theory
    at the same points.

    Parameters
    ----------
    name : str
        Algorithm of the coning registry.
    omega_h : sequence of float or None
        Points Ωh, rad; None: a grid suited to the expected order.
    alpha : float or None
        Cone half-angle, rad; None: small enough for the α⁴ term, large enough for the floor.
    periods : int
        Cone periods per point.
    nu : float
        Cone frequency, rad/s.

    Returns
    -------
    dict
        ``omega_h``, ``alpha``, ``drift``, ``floor``, ``used`` (above 10× the floor),
        ``theory``, ``order_measured`` and ``order_theory_fit`` (None with fewer than four
        points used).

    """
    alg = ALGORITHMS[name]
    order = alg.order_expected or 2
    if omega_h is None:
        omega_h = (0.8, 1.0, 1.2, 1.6) if order >= 8 else (0.1, 0.15, 0.2, 0.3, 0.4, 0.6)
    if alpha is None:
        # small enough that the α⁴ term stays below 1% of the drift, large enough that the
        # drift stays ≥ 10× above the round-off floor (~1e-18 rad/s)
        alpha = 3e-4 if order >= 8 else (2e-3 if order == 6 else 0.01)
    omega_h = np.asarray(omega_h, dtype=float)
    drift, floor = [], []
    for x in omega_h:
        step = x / alg.samples / nu
        dur = periods * 2 * np.pi / nu
        r = measure_case([name], alpha, nu, step, dur + step)
        drift.append(r.drift[name] / (alpha ** 2 * nu))
        floor.append(r.floor[alg.samples] / (alpha ** 2 * nu))
    drift, floor = np.array(drift), np.array(floor)
    used = np.abs(drift) > 10 * floor
    th = theory_drift(alg, omega_h)
    out = {'omega_h': omega_h.tolist(), 'alpha': alpha, 'drift': drift.tolist(),
           'floor': floor.tolist(), 'used': used.tolist(),
           'theory': None if th is None else np.asarray(th).tolist(),
           'order_measured': None, 'order_theory_fit': None}
    if used.sum() >= 4:
        log_x = np.log(omega_h[used])
        out['order_measured'] = float(np.polyfit(log_x, np.log(np.abs(drift[used])), 1)[0])
        if th is not None:
            log_th = np.log(np.abs(np.asarray(th)[used]))
            out['order_theory_fit'] = float(np.polyfit(log_x, log_th, 1)[0])
    return out


def cost_per_update(name: str, samples: int = 120_000, repeats: int = 3) -> float:
    """
    Measure the wall time per attitude update of the core, attitude only.

    Parameters
    ----------
    name : str
        Algorithm of the coning registry.
    samples : int
        Gyro samples per run (pushed in blocks of 12 000).
    repeats : int
        Runs; the fastest counts.

    Returns
    -------
    float
        Nanoseconds per update.

    """
    prof = ConingProfile(0.087, 1.0)
    t = np.arange(samples + 1) * 0.01
    dth = prof.delta_theta(t[:-1], t[1:])
    best = np.inf
    for _ in range(repeats):
        integ = AttitudeIntegrator(name, prof.attitude(0.0), 0.0, propagate_covariance=False)
        t0 = time.perf_counter()
        for k in range(0, samples, 12_000):
            integ.push(dth[k:k + 12_000], t[k + 1:k + 12_001])
        best = min(best, time.perf_counter() - t0)
    return best / integ.updates * 1e9
