"""
Reproduce Vavilov 1982 (paper 001): observability in gyro-horizon-compass correction.

    python -m strapdown_ros.reproductions.vavilov1982 [--quick] [--report FILE.md] [--json FILE]
                                                      [--plots DIR]

Computes, from :mod:`strapdown_ros.estimation.gyrocompass` and
:mod:`strapdown_ros.estimation.observability`: the misprint checks of §3, the checks of
(4.1)/(4.3) against exact geometry, the measures of observability of the ship case (4.6), the
aircraft case (4.8) and the circulation (4.11) beside the paper's statements, the full
time-varying model's Gramian, and the steady-state filter of the ship case with a Monte Carlo of
its NEES.  Every sentence of the report is computed from the numbers, except the derivation text
appended from :mod:`.vavilov1982_text`, which is labelled as such and names the test command
that checks each part.

For reproduce_seeds: ``section_001(quick) -> dict``, ``report_001(res) -> str``,
``plots_001(res, outdir) -> list[str]``.  No ROS imports; matplotlib only inside plots_001.
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

from strapdown_ros.cli import check_outputs, DIRECTORY, FILE, write_text
from strapdown_ros.estimation import gyrocompass as gc
from strapdown_ros.estimation.chi_square import chi2_quantile
from strapdown_ros.estimation.observability import (analyze_information, measures_of_observability,
                                                    observability_gramian, stationary_measures)
from strapdown_ros.estimation.steady_filter import (constant_gain_covariance, discretize,
                                                    pole_placement_gain, simulate_constant_gain,
                                                    steady_state_gain)
from strapdown_ros.figures import save_figure
from strapdown_ros.reproductions.markdown import place_figures
from strapdown_ros.reproductions.vavilov1982_text import DERIVATIONS_001

LATITUDE_DEG = 55.0              # "moderate latitudes"
SHIP_SPEED = 15.0                # V0 for the ship [m/s] (001: μ1 ≈ 0.03)
CIRCULATION_PERIOD = 420.0       # 7 min (001: 6–8 min)
INCLINATION_DEG = 60.0           # orthodrome inclination ϑ, passing LATITUDE at τ = 0
X0 = 1.5e-3                      # 001's characteristic error x° [rad]
#: a shorter interval "suffices" for a variable when its Gramian measure reaches this fraction
#: of the measure on 001's τ1 ∈ (0, 1/λ1)
SUFFICES = 0.9
#: a measured gain ratio "follows" a predicted one when within this factor of it
GAIN_WITHIN = 1.1
SHIP_NAMES = ('y1', 'y2', 'y3', 'y4', 'Δ')             # the ship's variables, (4.6)
AIRCRAFT_NAMES = ('s1', 's2', 's3', 's4', 's5')        # the aircraft's variables, (4.8)
FULL_NAMES = ('x1', 'x2', 'x3', 'x4', 'z', 'Δ')         # states of the full time-varying model


def _f(x):
    return [float(v) for v in np.asarray(x, float).ravel()]


def _orthodrome_at(params, lat):
    th = np.radians(INCLINATION_DEG)
    return gc.orthodrome(params, th, float(np.arcsin(np.sin(lat) / np.sin(th))))


# ----------------------------------------------------------------------------- checks
def _misprint_checks(ship) -> dict:
    mu, mu1 = ship.mu, ship.mu1
    lat, V1, V2 = np.radians(LATITUDE_DEG), 0.6, 0.8
    w2 = mu1 * V1 + np.sqrt(np.cos(lat) ** 2 - mu1 ** 2 * V2 ** 2)
    eps = 1e-6
    args = (mu, mu1, V1, V2, w2, 2 * eps, 0.03 * eps, np.sin(lat), 0.0)
    exact, lin = gc.exact_measurement(*args), gc.linear_measurement(*args)
    z = 1e-6
    dz = gc.exact_measurement(mu, mu1, V1, V2, w2, 0, 0, np.sin(lat), z)
    # (4.5): the log's 0.1 m/s error along either axis, as an error of σ in units of μx°
    dv = 0.1 / ship.speed
    base = gc.exact_measurement(mu, mu1, V1, V2, w2, 0, 0, np.sin(lat), 0)
    d_sigma = max(abs(gc.exact_measurement(mu, mu1, V1 + dv, V2, w2, 0, 0, np.sin(lat), 0) - base),
                  abs(gc.exact_measurement(mu, mu1, V1, V2 + dv, w2, 0, 0, np.sin(lat), 0) - base))
    return {'delta_sigma_over_mu_x0': d_sigma / (mu * X0),
            'h1_corrected_rel_error': abs(exact - lin) / abs(lin),
            'h1_printed_prefactor_rel_error': abs(exact * mu1 / mu - lin) / abs(lin),
            'z_coefficient_exact': dz / z, 'z_coefficient_corrected': -mu * mu1 * np.sin(lat),
            'z_coefficient_printed': -mu1 * mu1 * np.sin(lat)}


def _geometry_checks(ship) -> dict:
    mu, mu1 = ship.mu, ship.mu1
    m = _orthodrome_at(ship, np.radians(LATITUDE_DEG))
    worst_41, worst_43 = 0.0, 0.0
    for tau in (0.0, 0.5, 1.0):
        k = m.kinematics(tau)
        v, s = k['omega2'], k['sin_lat']
        worst_41 = max(worst_41, abs(k['lam_omega3'] / (mu * s * (1 + mu1 * k['V1'] / v)) - 1),
                       abs(k['omega2_rate_ratio'] * v / (-mu * mu1 * s * k['V2']) - 1))
        h = 1e-4

        def G(t):
            kk = m.kinematics(t)
            h1, h2 = gc.measurement_vectors(kk['V1'], kk['V2'], kk['omega2'], mu1)
            return gc.transform(h1), gc.transform(h2)
        G1, G2 = G(tau)
        G1d = (G(tau + h)[0] - G(tau - h)[0]) / (2 * h)
        B, b = gc.error_matrices(k['lam_omega3'], k['omega2_rate_ratio'])
        c = mu * s
        printed = gc.B2 + c * gc.B1 + c * mu1 * G2 @ np.linalg.inv(G1)
        worst_43 = max(worst_43, np.abs((G1 @ B + G1d) @ np.linalg.inv(G1) - printed).max(),
                       np.abs(G1 @ b - c * np.array([0, v - mu1 ** 2 / v, 0, 2 * mu1 * k['V2']]))
                       .max())
    return {'eq_4_1_max_rel_error': worst_41, 'eq_4_3_max_abs_residual': worst_43}


# ----------------------------------------------------------------------------- cases
def _ship(ship, quick) -> dict:
    lat = np.radians(LATITUDE_DEG)
    c = ship.mu * np.sin(lat)
    m = _orthodrome_at(ship, lat)
    k = m.kinematics(0.0)
    b12, b14 = k['omega2'] - ship.mu1 ** 2 / k['omega2'], 2 * ship.mu1 * k['V2']
    A, H = gc.ship_system(c, b12, b14)
    deriv = stationary_measures(A, H, 1.0)
    closed = [1.0, 2 / np.sqrt(10), np.sqrt(2) * c, np.sqrt(2) * c, c * b12 / np.sqrt(6)]
    g_unit = observability_gramian(lambda t: A, lambda t: H, 0, 1.0, 2)
    g_per = observability_gramian(lambda t: A, lambda t: H, 0, 2 * np.pi, 2)
    # the full LTV model (x1..x4, z, Δ) over one Schuler period
    F, Hf = gc.full_system(m)
    steps = 100 if quick else 400
    gf = observability_gramian(F, Hf, 0, 2 * np.pi, steps)
    rep = analyze_information(gf.mean, labels=['x1', 'x2', 'x3', 'x4', 'z', 'Δ'], rel_tol=1e-12)
    h1, _ = gc.measurement_vectors(k['V1'], k['V2'], k['omega2'], ship.mu1)
    keep = [0, 1, 2, 3, 5]
    combos = np.zeros((5, 5))
    combos[:4, :4] = gc.transform(h1)
    combos[4, 4] = 1.0
    full_zknown = measures_of_observability(gf.mean[np.ix_(keep, keep)], combos)
    return {'c': c, 'b12': b12, 'paper': [1.0, 1.0, c, c, c], 'derivative': _f(deriv),
            'closed_form': _f(closed),
            'gramian_unit': _f(measures_of_observability(g_unit.mean, np.eye(5))),
            'gramian_period': _f(measures_of_observability(g_per.mean, np.eye(5))),
            'full_period_z_known': _f(full_zknown), 'full_gramian_rel_error': gf.relative_error,
            'full_period_z_known_states': _f(
                measures_of_observability(gf.mean[np.ix_(keep, keep)], np.eye(5))),
            'full_eigenvalues': _f(rep.eigenvalues),
            'full_weakest_direction': _f(rep.directions[:, 0]),
            'full_weakest_ratio': float(rep.eigenvalues[0] / rep.eigenvalues[-1])}


def _aircraft(quick) -> dict:
    air = gc.Parameters(gc.EARTH_RATE * gc.EARTH_RADIUS)            # μ1 = 1
    lat = np.radians(LATITUDE_DEG)
    c = air.mu * np.sin(lat)
    D, H = gc.aircraft_matrix(c)
    deriv = stationary_measures(D, H, 1.0)
    g_per = observability_gramian(lambda t: D, lambda t: H, 0, 2 * np.pi, 2)
    m = _orthodrome_at(air, lat)
    F, Hf = gc.full_system(m)
    gf = observability_gramian(F, Hf, 0, 2 * np.pi, 100 if quick else 400)
    full = measures_of_observability(gf.mean, np.eye(6), rel_tol=1e-14)
    lam, vec = np.linalg.eigh(gf.mean)
    return {'c': c, 'mu1': air.mu1, 'paper': [1.0, 1.0, 1.0, c, c], 'derivative': _f(deriv),
            'closed_form': _f([1, np.sqrt(2), np.sqrt(2), np.sqrt(2) * c, np.sqrt(2) * c]),
            'gramian_period': _f(measures_of_observability(g_per.mean, np.eye(5))),
            'full_state_measures': _f(full), 'full_weakest_direction': _f(vec[:, 0]),
            'full_weakest_ratio': float(lam[0] / lam[-1])}


def _circulation(ship, quick) -> dict:
    lam1 = ship.schuler_rate * CIRCULATION_PERIOD / (2 * np.pi)
    mu1 = ship.mu1
    A, H = gc.circulation_ship_system(lam1, mu1)
    intervals = {'unit': 1.0, 'one_period': 2 * np.pi, 'schuler_unit': 1 / lam1}
    out = {'lam1': lam1, 'mu1': mu1, 'paper_short': lam1 * mu1, 'intervals_tau1': intervals,
           'derivative': {}, 'gramian': {}, 'full_delta': {}}
    for name, T1 in intervals.items():
        out['derivative'][name] = _f(stationary_measures(A, H, T1))
        g = observability_gramian(lambda t: A, lambda t: H, 0, T1, 2)
        out['gramian'][name] = _f(measures_of_observability(g.mean, np.eye(4)))
    # the full model (z known) on the real circulation: measure of Δ itself
    m = gc.circulation(ship, np.radians(LATITUDE_DEG), CIRCULATION_PERIOD)
    F, Hf = gc.full_system(m)
    keep = [0, 1, 2, 3, 5]
    sub_F = lambda t: F(t)[np.ix_(keep, keep)]                  # noqa: E731
    sub_H = lambda t: Hf(t)[:, keep]                            # noqa: E731
    for name, T1 in intervals.items():
        steps = int(max(40, (20 if quick else 60) * T1)) // 4 * 4
        g = observability_gramian(sub_F, sub_H, 0, T1 * lam1, steps)
        g_half = observability_gramian(sub_F, sub_H, 0, T1 * lam1, steps // 2)
        # accuracy of the (Richardson) Gramian: its relative change when the step is doubled;
        # eigenvalues below that (relative to the largest) are not resolved: unobservable
        acc = float(np.linalg.norm(g.gramian - g_half.gramian) / np.linalg.norm(g.gramian))
        m_delta = measures_of_observability(g.mean, np.eye(5)[4:], rel_tol=max(1e-14, acc))
        out['full_delta'][name] = float(m_delta[0])
        out.setdefault('full_gramian_accuracy', {})[name] = acc
    return out


# ----------------------------------------------------------------------------- filters
def _filters(ship, quick) -> dict:
    poles = [-1.0, -1.5, -2.0, -2.5, -3.0]
    obs = {}
    for name, latd in (('lat', LATITUDE_DEG), ('lat_low', 20.0)):
        c = ship.mu * np.sin(np.radians(latd))
        A, H = gc.ship_system(c, np.cos(np.radians(latd)))
        obs[name] = {'latitude_deg': latd, 'c': c, 'gain': _f(pole_placement_gain(A, H, poles))}
    # steady-state Kalman filter; units of x°: Δσ = 0.1 μ (eq. 4.5) as white noise of that
    # intensity
    ds, h, q = 0.1 * ship.mu, 0.05, 1e-2
    runs = 40 if quick else 200
    steps = int(round(200.0 / h))
    kal = {'delta_sigma': ds, 'step': h, 'process_noise': q, 'runs': runs, 'duration': steps * h}
    for name, latd in (('lat', LATITUDE_DEG), ('lat_low', 20.0)):
        c = ship.mu * np.sin(np.radians(latd))
        A, H = gc.ship_system(c, np.cos(np.radians(latd)))
        Phi, Q = discretize(A, np.eye(5) * q ** 2, h)
        R = np.array([[ds ** 2 / h]])
        P, K, Pf = steady_state_gain(Phi, H, Q, R)
        ev, evec = np.linalg.eig((np.eye(5) - K @ H) @ Phi)
        order = np.argsort(-h / np.log(np.abs(ev)))
        tconst = (-h / np.log(np.abs(ev)))[order]
        states = ['y1', 'y2', 'y3', 'y4', 'Δ']
        dominant = [states[int(np.argmax(np.abs(evec[:, j])))] for j in order]
        Ps = constant_gain_covariance(Phi, H, Q, R, K, np.eye(5), steps)
        sig_t = np.sqrt(np.einsum('kii->ki', Ps))
        ss = np.sqrt(np.diag(Pf))
        rec = {'c': c, 'gain': _f(K), 'steady_sigma': _f(ss), 'time_constants': _f(tconst),
               'mode_dominant_state': dominant,
               'final_over_steady': _f(sig_t[-1] / ss),
               'measures': _f(stationary_measures(A, H, 1.0))}
        if name == 'lat':
            err = simulate_constant_gain(Phi, H, Q, R, K, np.eye(5), steps, runs,
                                         np.random.default_rng(1))
            nees = np.einsum('rki,kij,rkj->rk', err, np.linalg.inv(Ps), err).mean(axis=0)
            lo, hi = chi2_quantile(0.025, 5 * runs) / runs, chi2_quantile(0.975, 5 * runs) / runs
            every = max(1, steps // 400)
            rec.update({'nees_mean': float(nees.mean()), 'nees_band': [lo, hi],
                        'nees_fraction_in_band': float(np.mean((nees >= lo) & (nees <= hi))),
                        'time': _f(np.arange(0, steps + 1, every) * h), 'nees': _f(nees[::every]),
                        'sigma_predicted': [_f(sig_t[::every, i]) for i in range(5)],
                        'sigma_mc': [_f(err[:, ::every, i].std(axis=0)) for i in range(5)]})
        kal[name] = rec
    return {'observer_poles': poles, 'observer': obs, 'kalman': kal}


def section_001(quick: bool = False) -> dict:
    """
    Compute all numbers of the 001 section.

    Parameters
    ----------
    quick : bool
        Fewer steps and Monte Carlo runs (for tests).

    Returns
    -------
    dict
        Parameters, misprint and geometry checks, the ship, aircraft and circulation measures
        and the filters (JSON-able).

    """
    ship = gc.Parameters(SHIP_SPEED)
    return {'parameters': {'mu': ship.mu, 'mu1_ship': ship.mu1, 'latitude_deg': LATITUDE_DEG,
                           'schuler_rate': ship.schuler_rate,
                           'circulation_period_s': CIRCULATION_PERIOD,
                           'unit_interval_s': 1 / ship.schuler_rate, 'quick': quick},
            'misprints': _misprint_checks(ship), 'geometry': _geometry_checks(ship),
            'ship': _ship(ship, quick), 'aircraft': _aircraft(quick),
            'circulation': _circulation(ship, quick),
            'filters': _filters(ship, quick)}


# ----------------------------------------------------------------------------- report
def order_verdict(m: float, ref: float) -> str:
    """
    Word a measure against the paper's order, with the threshold: same order if within 10×.

    Parameters
    ----------
    m : float
        Our measure.
    ref : float
        The paper's order at the same latitude.

    Returns
    -------
    str
        For example ``'same order (×0.82, within 10×)'``.

    """
    r = m / ref
    if 0.1 <= r <= 10:
        return f'same order (×{r:.2g}, within 10×)'
    return f"{'smaller' if r < 1 else 'larger'} by ×{r:.2g} (not within 10×)"


def _table(names, paper, columns: dict, paper_label: str = 'paper') -> list[str]:
    head = f'| variable | {paper_label} | ' + ' | '.join(columns) + ' |'
    lines = [head, '|' + '---|' * (2 + len(columns))]
    for i, n in enumerate(names):
        lines.append(f'| {n} | {paper[i]:.3g} | '
                     + ' | '.join(f'{col[i]:.3g}' for col in columns.values()) + ' |')
    return lines


def _two_periods_verdict(ci: dict) -> str:
    """001's "two circulation periods are needed", judged by the Gramian measures."""
    g1, gl = ci['gramian']['one_period'], ci['gramian']['schuler_unit']
    d1, dl = ci['full_delta']['one_period'], ci['full_delta']['schuler_unit']
    fr = {'p1': g1[2] / gl[2], 'p2': g1[3] / gl[3], 'Δ (full model)': d1 / dl if dl else 0.0}
    enough = [k for k, v in fr.items() if v >= SUFFICES]
    short = [k for k, v in fr.items() if v < SUFFICES]
    periods = ci['intervals_tau1']['schuler_unit'] / (2 * np.pi)
    return ('001 says p1, p2 need τ1∈(0,1/λ1), "two circulation periods" (1/λ1 is '
            f'{periods:.2f} periods here). After one period the measure is, as a fraction of '
            'that on τ1∈(0,1/λ1): ' + ', '.join(f'{k} {v:.2f}' for k, v in fr.items())
            + f'. Verdict (one period suffices for a variable that reaches ≥ {SUFFICES:g} of '
            'it): ' + (f"one period suffices for {', '.join(enough)}" if enough else
                       'one period suffices for none')
            + ('' if not short else f"; it does not for {', '.join(short)}")
            + '.')


def _gain_verdict(o1: dict, o2: dict, ratio: list, kal: dict) -> str:
    """001's "gains of the last three variables ∝ 1/(μ sin φ)", judged per variable."""
    pred = o1['c'] / o2['c']
    meas = [x / y for x, y in zip(kal['lat']['measures'][2:], kal['lat_low']['measures'][2:])]
    names = ('y3', 'y4', 'Δ')
    follows = [abs(np.log(r / pred)) <= np.log(GAIN_WITHIN) for r in ratio[2:]]
    by_measure = [abs(np.log(r / m)) <= np.log(GAIN_WITHIN) for r, m in zip(ratio[2:], meas)]
    yes = [n for n, f in zip(names, follows) if f]
    instead = '; it follows 1/measure instead'
    no = [f'{n} (×{r:.3f}, {r / pred:.2f} of it' + (instead if m else '') + ')'
          for n, f, r, m in zip(names, follows, ratio[2:], by_measure) if not f]
    return ('001: the observer gains of y3, y4, Δ are ∝ 1/(μ sin φ), i.e. ×'
            f'{pred:.3f} from {o1["latitude_deg"]:g}° to {o2["latitude_deg"]:g}°. Verdict '
            f'(a gain follows when within {GAIN_WITHIN:g}× of that): '
            + (f"holds for {', '.join(yes)}" if yes else 'holds for none')
            + (f"; does not hold for {'; '.join(no)}" if no else '') + '.')


def report_001(res: dict) -> str:
    """
    Write the 001 section of the report.

    Parameters
    ----------
    res : dict
        The result of :func:`section_001`.

    Returns
    -------
    str
        Markdown: the paper's orders beside our measures, the checks and the filters.

    """
    p, mp, geo = res['parameters'], res['misprints'], res['geometry']
    s, a, ci, fl = res['ship'], res['aircraft'], res['circulation'], res['filters']
    L = ['## 001 — Observability in gyro-horizon-compass correction (Vavilov 1982)', '']
    c = s['c']
    lm = ci['lam1'] * ci['mu1']
    L += ["**The paper's claim beside ours.** 001 prints orders of magnitude, not numbers "
          f"(evaluated here at {p['latitude_deg']:g}°). Ship (4.6): y1, y2 of order 1, y3, y4, Δ "
          f'of order μ sin φ = {c:.3g}; ours (derivative measure) '
          + ', '.join(f'{n} {v:.3g}' for n, v in zip(SHIP_NAMES, s['derivative']))
          + f". Aircraft (4.8): s1–s3 of order 1, s4, s5 of order μ sin φ = {a['c']:.3g}; ours "
          + ', '.join(f'{n} {v:.3g}' for n, v in zip(AIRCRAFT_NAMES, a['derivative']))
          + f'. Circulation (4.11): p1 of order λ1μ1 = {lm:.3g} on τ1∈(0,1); ours '
          f"{ci['derivative']['unit'][2]:.3g}. The tables below give the paper's orders as "
          'their first column.', '']
    L.append(f"μ = u/ω0 = {p['mu']:.4f}, ship μ1 = {p['mu1_ship']:.4f} (V0 = {SHIP_SPEED:g} m/s), "
             'latitude '
             f"{p['latitude_deg']:g}°, unit of dimensionless time 1/ω0 = "
             f"{p['unit_interval_s']:.0f} s. "
             'Derivations and the two readings of the measure: '
             '`doc/results/reproductions/observability_001.md`.')
    L += ['', '### Printed formulas checked against exact computations', '']
    L.append(f"- (3.7) with the prefactor μ: relative error {mp['h1_corrected_rel_error']:.1e} "
             'against the exact '
             'nonlinear σ; with the printed 0.5μ1 of (3.2): '
             f"{mp['h1_printed_prefactor_rel_error']:.2f}.")
    L.append(f"- Latitude coefficient in σ: exact {mp['z_coefficient_exact']:.4e}, μμ1 sinφ form "
             f"{mp['z_coefficient_corrected']:.4e}, printed μ1μ1 form "
             f"{mp['z_coefficient_printed']:.4e}.")
    L.append(f"- (4.5): a 0.1 m/s log error changes σ by {mp['delta_sigma_over_mu_x0']:.3f}·μx° "
             '(001: ~0.1·μx°, '
             f"{order_verdict(mp['delta_sigma_over_mu_x0'], 0.1)}).")
    L.append("- (4.1) against the orthodrome's exact geometry: largest relative error "
             f"{geo['eq_4_1_max_rel_error']:.1e}; "
             f"(4.3) (matrix and b1): largest residual {geo['eq_4_3_max_abs_residual']:.1e}.")
    L += ['', '### Ship on an orthodrome, (4.6)', '']
    names = ['y1', 'y2', 'y3', 'y4', 'Δ']
    columns = {'derivative measure': s['derivative'], 'closed form': s['closed_form'],
               'Gramian, τ∈(0,1)': s['gramian_unit'], 'Gramian, τ∈(0,2π)': s['gramian_period'],
               'full LTV, z known, (0,2π)': s['full_period_z_known']}
    L += _table(names, s['paper'], columns, f"001: order (1 or μ sin φ) at {p['latitude_deg']:g}°")
    c = s['c']
    dm = s['derivative']
    L.append('')
    L.append(f'Derivative reading: y1, y2 {order_verdict(dm[0], 1)}, {order_verdict(dm[1], 1)}; '
             f'y3, y4, Δ against μ sinφ = {c:.4f}: '
             f'{order_verdict(dm[2], c)}, {order_verdict(dm[3], c)}, {order_verdict(dm[4], c)}. '
             'Largest deviation from the closed form: '
             f"{max(abs(x / y - 1) for x, y in zip(dm, s['closed_form'])):.1e} (relative).")
    gu, gp = s['gramian_unit'], s['gramian_period']
    L.append('Gramian reading: on τ∈(0,1) y3, y4, Δ reach only '
             f'{min(gu[2:]) / c:.2g}–{max(gu[2:]) / c:.2g} of μ sinφ; '
             f'over one Schuler period {min(gp[2:]) / c:.2g}–{max(gp[2:]) / c:.2g} of it.')
    L.append('Full time-varying model (states x1..x4, z, Δ) over one Schuler period: weakest '
             'eigenvalue '
             f"{s['full_weakest_ratio']:.1e} of the largest, direction "
             + ', '.join(f'{n} {v:+.3f}' for n, v in zip(FULL_NAMES, s['full_weakest_direction']))
             + '; with z known (001 drops its term as below the noise) the measures agree with '
               '(4.6) within '
               f"{max(abs(x / y - 1) for x, y in zip(s['full_period_z_known'], gp)):.0%}.")
    xs = s['full_period_z_known_states']
    L.append(f'In the original variables (same Gramian): x1 {xs[0]:.3g}, x2 {xs[1]:.3g}, x3 '
             f'{xs[2]:.3g}, x4 {xs[3]:.3g}; '
             f'the weaker of x2, x4 is ×{min(xs[1], xs[3]) / max(xs[0], xs[2]):.2g} the stronger '
             'of x1, x3 '
             '(001: x2, x4 well observable, x1, x3 weakly).')
    L += ['', '### Aircraft, (4.8), μ1 = 1', '']
    columns = {'derivative measure': a['derivative'], 'closed form': a['closed_form'],
               'Gramian, τ∈(0,2π)': a['gramian_period']}
    L += _table(['s1', 's2', 's3', 's4', 's5'], a['paper'], columns,
                f"001: order (1 or μ sin φ) at {p['latitude_deg']:g}°")
    L.append('')
    L.append(f"s1–s3: {', '.join(order_verdict(x, 1) for x in a['derivative'][:3])}; s4, s5 "
             f"against μ sinφ = {a['c']:.4f}: "
             f"{', '.join(order_verdict(x, a['c']) for x in a['derivative'][3:])}.")
    fm = a['full_state_measures']
    L.append(f'Full model (z unknown) over a Schuler period: measures x1 {fm[0]:.2g}, x2 '
             f'{fm[1]:.2g}, x3 {fm[2]:.2g}, '
             f"x4 {fm[3]:.2g}; measure of Δ {fm[5]:.1e} (= {fm[5] / a['c']:.1e}·μ sinφ), of z "
             f'{fm[4]:.1e}; '
             f"weakest direction (eigenvalue ratio {a['full_weakest_ratio']:.1e}): "
             + ', '.join(f'{n} {v:+.2f}' for n, v in zip(FULL_NAMES, a['full_weakest_direction']))
             + '.')
    L += ['', '### Ship circulation, (4.11): one period against two', '']
    lam1, mu1 = ci['lam1'], ci['mu1']
    L.append(f'λ1 = ω0/Ω = {lam1:.4f}, μ1 = {mu1:.4f}, λ1μ1 = {lam1 * mu1:.2e}. Intervals in τ1 = '
             'Ωt: '
             + ', '.join(f'{k} = {v:.3g} ({v / (2 * np.pi):.2f} circulation periods)' for k,
                         v in ci['intervals_tau1'].items()) + '.')
    L.append('')
    L.append('| interval | derivative m(p1) | derivative m(p2) | Gramian m(p1) | Gramian m(p2) | '
             'full model m(Δ) |')
    L.append('|---|---|---|---|---|---|')
    for k in ci['intervals_tau1']:
        d, g = ci['derivative'][k], ci['gramian'][k]
        L.append(f'| {k} | {d[2]:.3g} | {d[3]:.3g} | {g[2]:.3g} | {g[3]:.3g} | '
                 f"{ci['full_delta'][k]:.3g} |")
    d0, g0, gl = ci['derivative']['unit'], ci['gramian']['unit'], ci['gramian']['schuler_unit']
    L.append('')
    L.append(f'On τ1∈(0,1) the derivative measure of p1 is {d0[2] / (lam1 * mu1):.3g}·λ1μ1 '
             f'({order_verdict(d0[2], lam1 * mu1)} '
             'with the paper). Going to τ1∈(0,1/λ1) raises the Gramian measure of p1 by '
             f'×{gl[2] / g0[2]:.3g} and of p2 '
             f'by ×{gl[3] / g0[3]:.3g} (one period alone: '
             f"×{ci['gramian']['one_period'][2] / g0[2]:.3g}, "
             f"×{ci['gramian']['one_period'][3] / g0[3]:.3g}); the derivative measures of p1, p2 "
             'on τ1∈(0,1/λ1) are '
             f"{ci['derivative']['schuler_unit'][2] / (lam1 * mu1):.3g} and "
             f"{ci['derivative']['schuler_unit'][3] / (lam1 * mu1):.3g} "
             f"times λ1μ1; the full model's measure of Δ (0 = below the "
             f"Gramian's accuracy) is {ci['full_delta']['unit']:.2g} on τ1∈(0,1), "
             f"{ci['full_delta']['one_period']:.2g} after one "
             f"period and {ci['full_delta']['schuler_unit']:.2g} on τ1∈(0,1/λ1).")
    L.append(_two_periods_verdict(ci))
    L += ['', '### Stationary filters for the ship', '']
    o1, o2 = fl['observer']['lat'], fl['observer']['lat_low']
    ratio = [x / y for x, y in zip(o2['gain'], o1['gain'])]
    L.append(f"Asymptotic observer (poles {fl['observer_poles']}): going from latitude "
             f"{o1['latitude_deg']:g}° to "
             f"{o2['latitude_deg']:g}° multiplies μ sinφ by {o2['c'] / o1['c']:.3f} and the gains "
             'of y3, y4, Δ by '
             + ', '.join(f'{r:.3f}' for r in ratio[2:]) + ' (001: ∝ 1/μ sinφ; ∝ 1/measure gives '
             + ', '.join(f'{x / y:.3f}' for x, y in zip(fl['kalman']['lat']['measures'][2:],
                                                        fl['kalman']['lat_low']['measures'][2:]))
             + ", Δ's measure carrying b12 = cos φ too); "
             'those of y1, y2 by ' + ', '.join(f'{r:.3f}' for r in ratio[:2]) + '.')
    L.append(_gain_verdict(o1, o2, ratio, fl['kalman']))
    k1, k2 = fl['kalman']['lat'], fl['kalman']['lat_low']
    L.append(f"Steady-state Kalman filter (Δσ = 0.1μ = {fl['kalman']['delta_sigma']:.2e} x° as "
             'white noise of that '
             f"intensity per unit τ, random walk {fl['kalman']['process_noise']:g} x°/√τ on every "
             'state, step '
             f"{fl['kalman']['step']:g}; gain from the Riccati equation by doubling) at "
             f"{o1['latitude_deg']:g}°: steady σ in x° = "
             + ', '.join(f'{n} {v:.2e}' for n, v in zip(names, k1['steady_sigma']))
             + '; closed-loop time constants '
             + ', '.join(f'{v:.1f}' for v in k1['time_constants']) + ' τ'
             + f" (at {o2['latitude_deg']:g}°: "
             + ', '.join(f'{v:.1f}' for v in k2['time_constants']) + ' τ).')

    def exponent(key, i, j=None):
        # d log(key) / d log(measure) between the two latitudes
        j = i if j is None else j
        return (np.log(k2[key][i] / k1[key][i])
                / np.log(k2['measures'][j] / k1['measures'][j]))

    ex_sig = [exponent('steady_sigma', i) for i in (2, 3, 4)]
    ex_pair = exponent('time_constants', 2)
    ex_slow = exponent('time_constants', 4)
    L.append('Between the two latitudes the steady σ of y3, y4, Δ scales as (derivative measure)^('
             + ', '.join(f'{e:.2f}' for e in ex_sig) + '), the slow oscillatory time constant as '
             f'm(y3)^({ex_pair:.2f}) '
             f'and the slowest one as m(Δ)^({ex_slow:.2f}); a random walk observed with measure m '
             'has steady σ ∝ m^(−1/2) '
             'and time constant ∝ m^(−1). Largest eigenvector component of each mode, fastest '
             'first: '
             + ', '.join(k1['mode_dominant_state']) + '.')
    L.append(f"After {fl['kalman']['duration']:g} τ the predicted σ is within a factor "
             f"{max(k1['final_over_steady']):.3f} of steady state.")
    inb = k1['nees_fraction_in_band']
    lo, hi = k1['nees_band']
    ok = lo <= k1['nees_mean'] <= hi and inb >= 0.8
    L.append(f"Monte Carlo, {fl['kalman']['runs']} runs over {fl['kalman']['duration']:g} τ: NEES "
             'averaged over runs and epochs '
             f"{k1['nees_mean']:.3f} (state dimension 5); {inb:.1%} of the epochs lie in the 95 % "
             'band '
             f'[{lo:.2f}, {hi:.2f}] of a run-mean of χ²(5) (expected 95 %, epochs correlated over '
             'the time constants). '
             f'Verdict (grand mean in the band and ≥ 80 % of epochs in it): the errors are '
             + ('consistent' if ok else 'not consistent') + " with the filter's propagated "
                                                            'covariance.')
    L.append('')
    return '\n'.join(L)


def plots_001(res: dict, outdir: str) -> list[str]:
    """
    Draw the measures of observability and the filter's Monte Carlo.

    Parameters
    ----------
    res : dict
        The result of :func:`section_001`.
    outdir : str
        Directory of the figures (created if missing).

    Returns
    -------
    list of str
        Paths of ``seeds_001_measures.png`` and ``seeds_001_filter.png``.

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    os.makedirs(outdir, exist_ok=True)
    out = []
    s, a = res['ship'], res['aircraft']
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    x = np.arange(5)
    for axis, case, names, title in ((ax[0], s, ['y1', 'y2', 'y3', 'y4', 'Δ'], 'ship (4.6)'),
                                     (ax[1], a, ['s1', 's2', 's3', 's4', 's5'], 'aircraft (4.8)')):
        axis.bar(x - 0.3, case['paper'], 0.2, label='paper (order)')
        axis.bar(x - 0.1, case['derivative'], 0.2, label='derivative measure')
        axis.bar(x + 0.1, case['gramian_period'], 0.2, label='Gramian, one Schuler period')
        if 'gramian_unit' in case:
            axis.bar(x + 0.3, case['gramian_unit'], 0.2, label='Gramian, τ∈(0,1)')
        axis.set_yscale('log')
        axis.set_xticks(x, names)
        axis.set_title(title)
        axis.set_ylabel('measure of observability')
    ax[0].legend(fontsize=7)
    out.append(save_figure(fig, outdir, 'seeds_001_measures.png'))
    k = res['filters']['kalman']['lat']
    t = np.asarray(k['time'])
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for i, n in enumerate(['y1', 'y2', 'y3', 'y4', 'Δ']):
        line, = ax[0].semilogy(t, k['sigma_predicted'][i], label=f'{n} predicted')
        ax[0].semilogy(t, k['sigma_mc'][i], '.', ms=2, color=line.get_color())
    ax[0].set_xlabel('τ = ω0 t')
    ax[0].set_ylabel('error σ [x°]')
    ax[0].set_title('steady-state Kalman filter: predicted (lines) vs Monte Carlo (dots)')
    ax[0].legend(fontsize=7)
    ax[1].plot(t, k['nees'], lw=0.7)
    for b in k['nees_band']:
        ax[1].axhline(b, color='k', ls='--', lw=0.8)
    ax[1].set_xlabel('τ')
    ax[1].set_title(f"mean NEES over {res['filters']['kalman']['runs']} runs, 95 % band")
    out.append(save_figure(fig, outdir, 'seeds_001_filter.png'))
    return out


#: the figures :func:`plots_001` writes, in its order
FIGURES = ('seeds_001_measures.png', 'seeds_001_filter.png')


def page(res: dict, figures=(), base: str = '.') -> str:
    """
    Return the page ``observability_001.md`` of a :func:`section_001` result.

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
        The Markdown page: the report, then the derivation text.

    """
    text = '# 001 (Vavilov 1982) — observability, reproduced\n\n' + report_001(res)
    return place_figures(text, list(figures), base) + DERIVATIONS_001


def main(argv=None) -> int:
    """
    Run the 001 page command (``python -m strapdown_ros.reproductions.vavilov1982``).

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success; a usage or output error exits with 2 and one line on stderr.

    """
    ap = argparse.ArgumentParser(prog='vavilov1982', description=__doc__.split('\n\n')[0])
    ap.add_argument('--quick', action='store_true', help='fewer steps and Monte Carlo runs')
    ap.add_argument('--report', help='write the markdown section to this file')
    ap.add_argument('--json', help='write the numbers to this file')
    ap.add_argument('--plots', help='directory for seeds_001_*.png')
    ap.add_argument('--force', action='store_true', help='overwrite existing outputs')

    def _error(msg):
        print(f'vavilov1982: error: {msg}', file=sys.stderr)
        raise SystemExit(2)
    ap.error = _error
    args = ap.parse_args(argv)
    try:                                        # the tools' one output rule
        check_outputs([('--report', args.report, FILE), ('--json', args.json, FILE),
                       ('--plots', args.plots, DIRECTORY, FIGURES)],
                      [], args.force)
    except ValueError as exc:
        _error(str(exc))
    res = section_001(quick=args.quick)
    figures, base = [], os.getcwd()
    if args.plots:
        base = os.path.dirname(os.path.abspath(args.report)) if args.report else os.getcwd()
        figures = plots_001(res, args.plots)
    text = page(res, figures, base)
    if args.report:
        write_text(args.report, text)
    else:
        print(text)
    if args.json:
        write_text(args.json, json.dumps(res, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
