"""
The numbers of doc/coning_derivations.md, computed: ``coning_bench --derivation-checks FILE``.

The derivation page states the misprints of 003's coning model (§2.2), the identities and series
behind ``theory_drift`` (§3), the measured drift of each of 003's algorithms against its
leading term (§4–§5) and the notes on the α⁴ floor, the start-up transient and the periodic
leakage.  Every figure there is what :func:`derivation_checks` computes and
:func:`derivation_report` prints; the page's text is the derivation.

Method of the measured drifts (§5 of the page): exact classical coning, α = 0.01, ν = 1 rad/s
(α = 1e-3 for the 8th-order algorithm), τ = Ωh/(Nν), about 10 cone periods from the true
attitude; the attitude is the product of exp(φ) over the updates, the history of an
accelerating algorithm padded with the first increment (as ``AttitudeIntegrator``); the drift
is the least-squares slope of the cone-axis error 2·(q ⊗ q_true*)_z over the update epochs,
divided by α²ν; the order is the log–log slope over Ωh ∈ {0.6, 0.4, 0.3, 0.2}.  No ROS imports.
"""
from __future__ import annotations

from fractions import Fraction
from math import factorial

import numpy as np

from strapdown_ros.attitude.coning import (ALGORITHMS, ConingAlgorithm, spacing_coefficients,
                                           theory_drift)
from strapdown_ros.attitude.coning_analysis import FLOOR_FACTOR
from strapdown_ros.motion.profiles import ConingProfile
from strapdown_ros.rotation import (quat_conjugate, quat_cumprod, quat_multiply, quat_to_dcm,
                                    quat_to_rotvec, rotvec_to_dcm, rotvec_to_quat)

__all__ = ['derivation_checks', 'derivation_report', 'measure_drift', 'series_coefficients',
           'SEVEN_OPTIMAL', 'FOUR_PLUS_PRINTED_PRODUCTS', 'GRID', 'GRID_8']

#: the Ωh grid of the order fit, and the 8th-order algorithm's (its drift is at the floor below)
GRID = (0.6, 0.4, 0.3, 0.2)
GRID_8 = (1.6, 1.2, 1.0, 0.8)


def _phi_7opt(w):
    return w[:, 2] + 7 / 60 * np.cross(w[:, 1], w[:, 2]) - 1 / 60 * np.cross(w[:, 0], w[:, 2])


def _phi_4plus_products(w):
    q1, q2, q3, q4 = w[:, 0], w[:, 1], w[:, 2], w[:, 3]
    return (q1 + q2 + q3 + q4
            + 4 / 3 * (np.cross(q1, q3) + np.cross(q2, q3) + np.cross(q2, q4)))


#: the optimal two-previous-sample form (not in 003): q_k + 7/60 q_{k−1}×q_k − 1/60 q_{k−2}×q_k
SEVEN_OPTIMAL = ConingAlgorithm('7 opt.', 1, 2, _phi_7opt, 2, 2, 2, None, 6, 'derived',
                                'q_k + 7/60 q_{k−1}×q_k − 1/60 q_{k−2}×q_k')
#: the bilinear part of the printed 4+ alone: Σq + 4/3 [q1×q3 + q2×q3 + q2×q4]
FOUR_PLUS_PRINTED_PRODUCTS = ConingAlgorithm('4+ printed products', 4, 0, _phi_4plus_products,
                                             3, 6, 1, None, 2, '003 (1.81), products only',
                                             'Σq + 4/3 [q1×q3 + q2×q3 + q2×q4]')
#: leads derived by hand where the linear part is not Σq (the page's §4)
HAND_LEADS = {'4+_as_printed': (Fraction(-5, 96), 2), '7_as_printed': (Fraction(1, 6), 2)}
#: the rows of the measured table, in the page's order
TABLE = ('1', '2', '3_as_printed', '3', '3.1_as_printed', '3.1', '4', '4+_as_printed', '4+',
         '4+_printed_terms', '5_as_printed', '5', '6', '7', '7_as_printed', '7 opt.',
         'three_sample_polynomial', 'four_sample_optimal')
#: literature algorithms that are the same formula as one of 003's
SAME_AS = {'one_plus_previous': '6', 'two_sample': '2', 'three_sample_optimal': '3.1'}
LITERATURE = ('1', 'one_plus_previous', 'two_sample', 'three_sample_polynomial',
              'three_sample_optimal', 'four_sample_optimal')


def _alg(name: str) -> ConingAlgorithm:
    return {'7 opt.': SEVEN_OPTIMAL}.get(name) or ALGORITHMS[name]


# ------------------------------------------------------------------------------ measuring
def measure_drift(alg: ConingAlgorithm, omega_h: float, alpha: float = 0.01, nu: float = 1.0,
                  periods: float = 10, skip: int = 0, exact: bool = False) -> dict:
    """
    Measure the cone-axis drift of one algorithm on exact coning.

    Parameters
    ----------
    alg : ConingAlgorithm
        The algorithm (registered or not).
    omega_h : float
        Ωh = N ν τ.
    alpha, nu : float
        Cone half-angle, rad, and rate, rad/s.
    periods : float
        Cone periods simulated (rounded to whole updates).
    skip : int
        Update epochs left out at the start of the fit.
    exact : bool
        Feed the exact rotation vector of each update instead: the round-off floor.

    Returns
    -------
    dict
        ``drift`` = ε/(α²ν), ``rad_per_s`` (the slope itself) and its standard error
        ``rad_per_s_sigma``, ``updates`` and ``span_s`` (of the epochs fitted).

    """
    n_new, hist = alg.samples, alg.history
    tau = omega_h / n_new / nu
    prof = ConingProfile(alpha, nu)
    n = int(round(periods * prof.cone_period / tau / n_new)) * n_new
    t = np.arange(n + 1) * tau
    q0 = prof.attitude(0.0)
    stamps = t[n_new::n_new]
    if exact:
        q = prof.attitude(np.r_[0.0, stamps])
        phi = quat_to_rotvec(quat_multiply(quat_conjugate(q[:-1]), q[1:]))
    else:
        dth = prof.delta_theta(t[:-1], t[1:])
        idx = np.arange(n // n_new)[:, None] * n_new + np.arange(-hist, n_new)[None, :]
        phi = alg.phi(dth[np.maximum(idx, 0)])         # history padded with the first increment
    att = quat_cumprod(q0, rotvec_to_quat(phi))
    e = quat_multiply(att, quat_conjugate(prof.attitude(stamps)))
    ez = 2 * e[:, 3] * np.sign(e[:, 0])
    coef, cov = np.polyfit(stamps[skip:], ez[skip:], 1, cov=True)
    return {'drift': float(coef[0] / (alpha ** 2 * nu)), 'rad_per_s': float(coef[0]),
            'rad_per_s_sigma': float(np.sqrt(cov[0, 0])),
            'updates': int(len(stamps) - skip), 'span_s': float(stamps[-1] - stamps[skip])}


def _order(values, grid) -> float:
    return float(np.polyfit(np.log(grid), np.log(np.abs(values)), 1)[0])


# ------------------------------------------------------------------------------ the series
def _sin_coeff(j: int, a) -> Fraction:
    """Coefficient of x^(2j+1) in sin(a x)."""
    return Fraction((-1) ** j * Fraction(a) ** (2 * j + 1), factorial(2 * j + 1))


def series_coefficients(alg: ConingAlgorithm, terms: int = 4) -> list[Fraction] | None:
    """
    Return c3, c5, c7, … of e/sin²α = Σ c_(2j+1) x^(2j+1), exactly (the page's §3).

    e/sin²α = ½(Nx − sin Nx) − Σ_m K_m · 4 sin²(x/2) sin(mx), with
    4 sin²(x/2) sin(mx) = 2 sin(mx) − sin((m+1)x) − sin((m−1)x).

    Parameters
    ----------
    alg : ConingAlgorithm
        The algorithm.
    terms : int
        How many coefficients.

    Returns
    -------
    list of Fraction or None
        ``[c3, c5, …]``; None when the linear part is not Σq.

    """
    k = spacing_coefficients(alg)
    if k is None:
        return None
    kf = {m: Fraction(v).limit_denominator(1_000_000) for m, v in k.items()}
    out = []
    for j in range(1, terms + 1):
        c = -Fraction(1, 2) * _sin_coeff(j, alg.samples)
        for m, km in kf.items():
            c -= km * (2 * _sin_coeff(j, m) - _sin_coeff(j, m + 1) - _sin_coeff(j, m - 1))
        out.append(c)
    return out


def _lead(name: str):
    """(coefficient of (Ωh)^p, p) of the leading drift term, or None."""
    if name in HAND_LEADS:
        return HAND_LEADS[name]
    alg = _alg(name)
    cs = series_coefficients(alg)
    if cs is None:
        return None
    j = next(i for i, c in enumerate(cs) if c != 0)
    p = 2 * j + 2                                       # c_(2j+3) x^(2j+3) / (N x) → x^(2j+2)
    return cs[j] / alg.samples ** (p + 1), p


def _frac(f: Fraction) -> str:
    sign = '−' if f < 0 else ''
    if f.denominator == 1:
        return f'{sign}{abs(f.numerator)}'
    return f'{sign}{abs(f.numerator)}/{f.denominator}'


def _lead_text(lead) -> str:
    c, p = lead
    sup = {2: '²', 4: '⁴', 6: '⁶', 8: '⁸'}[p]
    if c.numerator in (1, -1):
        return ('−' if c < 0 else '') + f'(Ωh){sup}/{c.denominator}'
    return f'{_frac(c)}·(Ωh){sup}'


# ------------------------------------------------------------------------------ the checks
def _model_checks() -> dict:
    """003 §2.2: the printed (2.6), (2.7), (2.10) against the exact model."""
    alpha, nu = 0.5, 1.0
    p = ConingProfile(alpha, nu)
    t = np.linspace(0.0, 7.0, 701)
    ca, sa, v = np.cos(alpha), np.sin(alpha), nu * t
    U = quat_to_dcm(p.attitude(t))
    rod = rotvec_to_dcm(alpha * np.stack([np.sin(v), np.cos(v), np.zeros_like(v)], -1))
    z = np.zeros_like(v)

    def printed(u12_sign, u22):                         # (2.6) with the given U12 sign, U22
        return np.stack([
            np.stack([ca + (1 - ca) * np.sin(v) ** 2, u12_sign * 0.5 * (1 - ca) * np.sin(2 * v),
                      sa * np.cos(v)], -1),
            np.stack([0.5 * (1 - ca) * np.sin(2 * v), u22, -sa * np.sin(v)], -1),
            np.stack([-sa * np.cos(v), sa * np.sin(v), ca + z], -1)], -2)
    U_printed = printed(-1.0, ca + (1 - ca) * np.sin(v) ** 2)
    U_fixed = printed(1.0, ca + (1 - ca) * np.cos(v) ** 2)
    h = 1e-6
    om = np.einsum('nji,njk->nik', U,
                   (quat_to_dcm(p.attitude(t + h)) - quat_to_dcm(p.attitude(t - h))) / (2 * h))
    w = p.body_rate(t)
    # (2.10) against a 20-point Gauss–Legendre quadrature of (2.9) over one interval
    t0, t1 = 0.3, 0.55
    x, wt = np.polynomial.legendre.leggauss(20)
    ts = 0.5 * (t1 - t0) * x + 0.5 * (t1 + t0)
    quad = 0.5 * (t1 - t0) * (wt[:, None] * p.body_rate(ts)).sum(0)
    corrected = np.array([sa * (np.sin(nu * t1) - np.sin(nu * t0)),
                          sa * (np.cos(nu * t1) - np.cos(nu * t0))])
    # algorithm 2 fed the printed (mirrored) increments, against the truth (2.5)
    a2, oh = 0.01, 0.4
    pr = ConingProfile(a2, nu)
    tau = oh / 2 / nu
    n = int(round(10 * pr.cone_period / tau / 2)) * 2
    tt = np.arange(n + 1) * tau
    dth = pr.delta_theta(tt[:-1], tt[1:]) * np.array([-1.0, -1.0, 1.0])
    phi = ALGORITHMS['2'].phi(dth.reshape(-1, 2, 3))
    att = quat_cumprod(pr.attitude(0.0), rotvec_to_quat(phi))
    err = quat_to_rotvec(quat_multiply(att, quat_conjugate(pr.attitude(tt[2::2]))))
    return {'alpha': alpha, 'nu': nu, 'epochs': len(t),
            'u12_printed': float(np.abs(U_printed[:, 0, 1] - U[:, 0, 1]).max()),
            'u22_printed': float(np.abs(U_printed[:, 1, 1] - U[:, 1, 1]).max()),
            'one_minus_cos_alpha': float(1 - ca),
            'fixed_vs_rodrigues': float(np.abs(U_fixed - rod).max()),
            'printed_orthogonality': float(np.abs(np.einsum('nji,njk->nik', U_printed, U_printed)
                                                  - np.eye(3)).max()),
            'omega31_minus_wy': float(np.abs(om[:, 2, 0] + w[:, 1]).max()),
            'omega31_plus_wy': float(np.abs(om[:, 2, 0] - w[:, 1]).max()),
            'omega_29': float(np.abs(np.stack([om[:, 2, 1], om[:, 0, 2], om[:, 1, 0]], -1)
                                     - w).max()),
            'quadrature_vs_corrected': float(np.abs(quad[:2] - corrected).max()),
            'quadrature_vs_printed': float(np.abs(quad[:2] - (-corrected)).max()),
            'quadrature_plus_printed': float(np.abs(quad[:2] + (-corrected)).max()),
            'quadrature_x_y': [float(quad[0]), float(quad[1])],
            'alg2_printed_increments_max_exy_over_alpha': float(
                np.abs(err[:, :2]).max() / a2)}


def _identity_checks() -> dict:
    """§3: the cross products, the true rotation vector and the series truncation."""
    a, nu, x = 0.5, 1.0, 0.3
    p = ConingProfile(a, nu)
    t = np.arange(8) * x / nu
    q = p.delta_theta(t[:-1], t[1:])
    cross = {}
    for i, j in ((0, 1), (0, 3), (2, 6)):
        got = np.cross(q[i], q[j])[2]
        want = -np.sin(a) ** 2 * 4 * np.sin(x / 2) ** 2 * np.sin((j - i) * x)
        cross[f'{i},{j}'] = [float(got), float(want)]
    small = 1e-3
    ps = ConingProfile(small, nu)
    bortz = {}
    for nx in (0.3, 1.0, 2.0):
        sq = ps.delta_theta(np.array([0.0]), np.array([nx / nu]))[0, 2]
        phi = quat_to_rotvec(quat_multiply(quat_conjugate(ps.attitude(0.0)),
                                           ps.attitude(nx / nu)))[2]
        bortz[f'{nx:g}'] = [float((sq - phi) / np.sin(small) ** 2), 0.5 * (nx - np.sin(nx))]
    xs = 0.05
    res_m = max(abs((4 * np.sin(xs / 2) ** 2 * np.sin(m * xs)
                     - (m * xs ** 3 - (m / 12 + m ** 3 / 6) * xs ** 5
                        + (m / 360 + m ** 3 / 72 + m ** 5 / 120) * xs ** 7))
                    / (4 * np.sin(xs / 2) ** 2 * np.sin(m * xs))) for m in range(1, 5))
    res_n = max(abs((0.5 * (n * xs - np.sin(n * xs))
                     - (n ** 3 * xs ** 3 / 12 - n ** 5 * xs ** 5 / 240
                        + n ** 7 * xs ** 7 / 10080)) / (0.5 * (n * xs - np.sin(n * xs))))
                for n in range(1, 6))
    return {'cross_x': x, 'cross': cross, 'bortz_alpha': small, 'bortz': bortz,
            'series_x': xs, 'series_residual_m_le_4': float(res_m),
            'series_residual_n_le_5': float(res_n)}


def _literature() -> list[dict]:
    """§3's table: K_m, the first non-zero c, the lead, theory_drift/lead."""
    rows = []
    for name in LITERATURE:
        alg = ALGORITHMS[name]
        k = spacing_coefficients(alg)
        cs = series_coefficients(alg)
        j = next(i for i, c in enumerate(cs) if c != 0)
        lead = _lead(name)
        oh = 0.2 if name == 'four_sample_optimal' else 0.05
        ratio = theory_drift(alg, oh) / (float(lead[0]) * oh ** lead[1])
        rows.append({'name': name, 'N': alg.samples,
                     'K': {str(m): _frac(Fraction(v).limit_denominator(1_000_000))
                           for m, v in sorted(k.items())},
                     'first_c': f'c{2 * j + 3} = {_frac(cs[j])}', 'lead': _lead_text(lead),
                     'omega_h': oh, 'theory_over_lead': float(ratio),
                     'c3_c5_c7_zero': [c == 0 for c in cs[:3]]})
    return rows


def _measured() -> list[dict]:
    """§5's table, every row of :data:`TABLE`."""
    rows = []
    for name in TABLE:
        alg = _alg(name)
        eight = name == 'four_sample_optimal'
        grid, alpha = (GRID_8, 1e-3) if eight else (GRID, 0.01)
        m = [measure_drift(alg, oh, alpha)['drift'] for oh in grid]
        th = theory_drift(alg, np.array(grid))
        lead = _lead(name)
        last = grid[-1]
        rows.append({'name': name, 'claim': alg.order_intended, 'alpha': alpha,
                     'grid': list(grid), 'measured': m,
                     'order': _order(m, grid),
                     'order_theory': None if th is None else _order(th, grid),
                     'theory': None if th is None else [float(v) for v in th],
                     'lead': None if lead is None else _lead_text(lead),
                     'per_interval': None if lead is None else _per_interval(lead, alg.samples),
                     'measured_over_lead': None if lead is None else
                     float(m[-1] / (float(lead[0]) * last ** lead[1]))})
    same = {}
    for name, twin in SAME_AS.items():
        a = [measure_drift(ALGORITHMS[name], oh)['drift'] for oh in GRID]
        b = [measure_drift(_alg(twin), oh)['drift'] for oh in GRID]
        same[name] = {'twin': twin, 'max_relative_difference': float(
            max(abs(x / y - 1) for x, y in zip(a, b)))}
    return rows, same


def _per_interval(lead, samples: int) -> str:
    """Return the lead per gyro interval: c (Ωh)^p = c N^p x^p."""
    c, p = lead
    v = c * samples ** p
    sup = {2: '²', 4: '⁴', 6: '⁶', 8: '⁸'}[p]
    if v.numerator in (1, -1):
        return ('−' if v < 0 else '') + f'x{sup}/{v.denominator}'
    return f'{_frac(v)}·x{sup}'


def _notes() -> dict:
    """Measure the α⁴ floor, the start-up transient, the leakage, the 7/6 ratio, 7 opt."""
    out = {}
    a31, a4p = ALGORITHMS['3.1'], ALGORITHMS['4+']
    out['alpha4_31'] = {f'{a:g}': measure_drift(a31, 0.2, a)['drift'] / theory_drift(a31, 0.2) - 1
                        for a in (0.02, 0.01, 0.005, 0.0025)}
    out['alpha4_4plus'] = {f'{a:g}': measure_drift(a4p, 0.6, a)['drift'] / theory_drift(a4p, 0.6)
                           - 1 for a in (0.02, 0.01, 0.005)}
    fl = {}
    for name, oh, a in (('4+', 0.2, 0.0025), ('four_sample_optimal', 0.8, 1e-3)):
        alg = ALGORITHMS[name]
        ex = measure_drift(alg, oh, a, exact=True)
        fl[name] = {'omega_h': oh, 'alpha': a,
                    'rad_per_s': measure_drift(alg, oh, a)['rad_per_s'],
                    'theory_rad_per_s': float(theory_drift(alg, oh) * a ** 2),
                    'floor_rad_per_s': abs(ex['rad_per_s']) + 3 * ex['rad_per_s_sigma']}
    out['floor'] = fl
    st = {}
    # with the history padded by the first increment, update 1 misses x³(K1 + 2K2) and update 2
    # gets K1 + K2 where K1 + 2K2 belongs: the first epoch lies off the line through the later
    # ones by Δ = x³·|K2| … x³/24 for 7, x³/60 for 7 opt. (the page's note ᶜ)
    for name, outlier in (('7', Fraction(1, 24)), ('7 opt.', Fraction(1, 60))):
        alg = _alg(name)
        rec = {}
        for oh in (0.6, 0.2):
            full = measure_drift(alg, oh)
            late = measure_drift(alg, oh, skip=alg.history + 1)
            delta = float(outlier) * oh ** 3          # x = Ωτ = Ωh for N = 1
            rec[f'{oh:g}'] = {'all_epochs': full['drift'], 'from_epoch_4': late['drift'],
                              'observed_bias': full['drift'] - late['drift'],
                              'predicted_bias': -6 * delta / (full['updates'] * full['span_s']),
                              'theory': float(theory_drift(alg, oh))}
        st[name] = rec
    out['startup'] = st
    g = np.array(GRID)
    m7 = [measure_drift(ALGORITHMS['7'], oh, skip=3)['drift'] for oh in GRID]
    m6 = [measure_drift(ALGORITHMS['6'], oh, skip=2)['drift'] for oh in GRID]
    out['seven_over_six'] = {f'{oh:g}': abs(a / b) for oh, a, b in zip(GRID, m7, m6)}
    th7 = theory_drift(ALGORITHMS['7'], g)
    out['seven_local_slope'] = {'measured': _order(m7, GRID), 'theory': _order(th7, GRID)}
    opt = [measure_drift(SEVEN_OPTIMAL, oh, skip=3)['drift'] for oh in GRID]
    out['seven_opt'] = {'order': _order(opt, GRID),
                        'order_theory': _order(theory_drift(SEVEN_OPTIMAL, g), GRID),
                        'measured': {f'{oh:g}': v for oh, v in zip(GRID, opt)},
                        'theory': {f'{oh:g}': float(theory_drift(SEVEN_OPTIMAL, oh))
                                   for oh in GRID}}
    pr = ALGORITHMS['7_as_printed']
    out['leakage_7_as_printed'] = {
        f'{per}': {f'{oh:g}': measure_drift(pr, oh, periods=per)['drift'] / oh ** 2
                   for oh in (0.6, 0.2)} for per in (10, 40)}
    prod = [measure_drift(FOUR_PLUS_PRINTED_PRODUCTS, oh)['drift'] / oh ** 2
            for oh in (0.6, 0.2)]
    whole = [measure_drift(ALGORITHMS['4+_as_printed'], oh)['drift'] / oh ** 2
             for oh in (0.6, 0.2)]
    out['four_plus_printed'] = {'products_only': prod, 'as_printed': whole,
                                'products_only_lead': _lead_text(_lead_of(
                                    FOUR_PLUS_PRINTED_PRODUCTS)),
                                'as_printed_lead': _lead_text(HAND_LEADS['4+_as_printed'])}
    return out


def _lead_of(alg: ConingAlgorithm):
    cs = series_coefficients(alg)
    j = next(i for i, c in enumerate(cs) if c != 0)
    p = 2 * j + 2
    return cs[j] / alg.samples ** (p + 1), p


def _thesis_case() -> dict:
    """§5: what the x⁴ and x⁶ terms amount to over 003's case 1 (τ = 0.01 s, 3600 s)."""
    alpha, nu, tau, span = 0.087, 1.0, 0.01, 3600.0
    x = nu * tau
    out = {}
    for label, names in (('x4', ('2', '6', '7', '3', '4')),
                         ('x6', ('3.1', '7 opt.', '4+', '4+_printed_terms', '5'))):
        vals = []
        for n in names:
            c, p = _lead(n)
            per = abs(float(c * _alg(n).samples ** p))          # coefficient of x^p
            vals.append(per * x ** p * alpha ** 2 * nu * span)
        out[label] = [min(vals), max(vals)]
    return {'alpha': alpha, 'nu': nu, 'tau': tau, 'span_s': span, 'rad': out}


def derivation_checks() -> dict:
    """
    Compute every figure of doc/coning_derivations.md (a few seconds).

    Returns
    -------
    dict
        ``model`` (§2), ``identities`` and ``literature`` (§3), ``measured`` and ``same``
        (§5's table), ``notes`` (its notes and §4's measured leads) and ``thesis_case``
        (JSON-able).

    """
    measured, same = _measured()
    return {'model': _model_checks(), 'identities': _identity_checks(),
            'literature': _literature(), 'measured': measured, 'same': same,
            'notes': _notes(), 'thesis_case': _thesis_case()}


# ------------------------------------------------------------------------------ the page
def _g(x, d=5):
    return '—' if x is None else f'{x:+.{d - 1}e}'


def derivation_report(r: dict) -> str:
    """
    Write the figures of the derivation page as Markdown.

    Parameters
    ----------
    r : dict
        The result of :func:`derivation_checks`.

    Returns
    -------
    str
        The page ``doc/results/coning_bench/coning_derivation_checks.md``.

    """
    m, idn, nt = r['model'], r['identities'], r['notes']
    L = ['# Coning derivations: the figures', '',
         'Generated by `coning_bench --derivation-checks FILE` '
         '(`strapdown_ros/bench/coning_derivation_checks.py`); every number of '
         '[coning_derivations.md](../../coning_derivations.md) is one of these. Exact coning, '
         'no sensor errors, float64.', '',
         f"## §2 The coning model of 003 §2.2 (α = {m['alpha']:g}, ν = {m['nu']:g} rad/s, "
         f"{m['epochs']} epochs on [0, 7] s)", '',
         '| check | result |', '|---|---|',
         f"| printed (2.6) U12 − exact | max {m['u12_printed']:.4g} (1 − cos α = "
         f"{m['one_minus_cos_alpha']:.4g}) |",
         f"| printed (2.6) U22 − exact | max {m['u22_printed']:.4g} |",
         f"| (2.6) with U12, U22 fixed − Rodrigues (2.5) | max {m['fixed_vs_rodrigues']:.2g} |",
         f"| printed (2.6): UᵀU − I | max {m['printed_orthogonality']:.2g} |",
         f"| numerical UᵀdU/dt: Ω31 + ω_y (corrected row 3) | max {m['omega31_minus_wy']:.2g} |",
         f"| numerical UᵀdU/dt: Ω31 − ω_y (printed row 3) | max {m['omega31_plus_wy']:.2g} |",
         f"| (2.9) against UᵀdU/dt (central differences, step 1e-6) | max {m['omega_29']:.2g} |",
         '| 20-point Gauss quadrature of (2.9) over [0.3, 0.55] s − corrected (2.10) | max '
         f"{m['quadrature_vs_corrected']:.2g} |",
         '| the same quadrature − printed (2.10); + printed (2.10) | max '
         f"{m['quadrature_vs_printed']:.2g}; {m['quadrature_plus_printed']:.2g} |",
         '| algorithm 2 fed the printed (2.10), against (2.5), α = 0.01, Ωh = 0.4 | largest '
         f"xy error {m['alg2_printed_increments_max_exy_over_alpha']:.2f}·α |", '',
         '## §3 Identities and series', '',
         f"Cross products, x = {idn['cross_x']:g}: "
         + '; '.join(f'(q{k.replace(",", " × q")})_z = {v[0]:.8e} against {v[1]:.8e}'
                     for k, v in idn['cross'].items()) + '.', '',
         f"(Σq_z − φ_z)/sin²α on log(q(t0)* ⊗ q(t1)), α = {idn['bortz_alpha']:g}: "
         + '; '.join(f'Nx = {k}: {v[0]:.6f} (½(Nx − sin Nx) = {v[1]:.6f})'
                     for k, v in idn['bortz'].items()) + '.', '',
         f"Series truncated after x⁷ at x = {idn['series_x']:g}: largest relative residual "
         f"{idn['series_residual_m_le_4']:.2g} for 4 sin²(x/2) sin(mx), m ≤ 4; "
         f"{idn['series_residual_n_le_5']:.2g} for ½(Nx − sin Nx), N ≤ 5.", '',
         '| algorithm | N | K_m | first non-zero c | ε/(α²Ω) | theory_drift / lead | at Ωh |',
         '|---|---|---|---|---|---|---|']
    for row in r['literature']:
        k = ', '.join(f'K{m_} = {v}' for m_, v in row['K'].items()) or '—'
        L.append(f"| {row['name']} | {row['N']} | {k} | {row['first_c']} | {row['lead']} | "
                 f"{row['theory_over_lead']:.5f} | {row['omega_h']:g} |")
    L += ['', '## §5 Measured against theory', '',
          'α = 0.01 (α = 1e-3 for four_sample_optimal, on its own grid Ωh ∈ {1.6, 1.2, 1.0, '
          '0.8}), ν = 1 rad/s, ~10 cone periods, every epoch fitted. "order" is the log–log slope '
          'over the grid (theory: the same fit to `theory_drift`); "lead" the leading term '
          '(§3–§4).', '',
          '| name | claim | order meas. (theory fit) | ε/(α²Ω) at the first Ωh | at the last '
          '| theory at the last | meas./lead at the last | lead | per gyro interval |',
          '|---|---|---|---|---|---|---|---|---|']
    for row in r['measured']:
        th = row['theory']
        L.append(f"| {row['name']} | {row['claim'] if row['claim'] is not None else '—'} | "
                 f"{row['order']:.2f} ("
                 + ('—' if row['order_theory'] is None else f"{row['order_theory']:.2f}") + ') | '
                 f"{_g(row['measured'][0])} at {row['grid'][0]:g} | "
                 f"{_g(row['measured'][-1])} at {row['grid'][-1]:g} | "
                 f'{_g(None if th is None else th[-1])} | '
                 + ('—' if row['measured_over_lead'] is None
                    else f"{row['measured_over_lead']:.3f}")
                 + f" | {row['lead'] or '—'} | {row['per_interval'] or '—'} |")
    L += ['', 'Same formulas: ' + '; '.join(
        f"{k} against {v['twin']}: largest relative difference {v['max_relative_difference']:.1g}"
        for k, v in r['same'].items()) + '.', '',
          '### Notes', '',
          '* α⁴ floor: 3.1 at Ωh = 0.2, measured/theory − 1 = '
          + ', '.join(f'{100 * v:+.2g}% (α = {k})' for k, v in nt['alpha4_31'].items())
          + '; 4+ at Ωh = 0.6: '
          + ', '.join(f'{100 * v:+.2g}% (α = {k})' for k, v in nt['alpha4_4plus'].items())
          + '.',
          '* The smallest drifts against the float64 floor (|slope| + 3σ of the same arithmetic '
          f'fed exact rotation vectors; at the floor if within {FLOOR_FACTOR:g}× of it): '
          + '; '.join(
              f"{k} at α = {v['alpha']:g}, Ωh = {v['omega_h']:g}: drift {v['rad_per_s']:.2e} "
              f"rad/s, theory {v['theory_rad_per_s']:.2e}, floor {v['floor_rad_per_s']:.1e} — "
              + ('at the floor' if abs(v['rad_per_s']) <= FLOOR_FACTOR * v['floor_rad_per_s']
                 else 'above the floor') for k, v in nt['floor'].items()) + '.']
    for name, rec in nt['startup'].items():
        L.append(f'* Start-up transient of {name}: ' + '; '.join(
            f"Ωh = {oh}: every epoch {v['all_epochs']:+.5g}, from epoch 4 {v['from_epoch_4']:+.5g}"
            f" (theory {v['theory']:+.5g}); bias observed {v['observed_bias']:+.2g}, predicted "
            f"−6Δ/(nT) = {v['predicted_bias']:+.2g}" for oh, v in rec.items()) + '.')
    so, sl = nt['seven_over_six'], nt['seven_local_slope']
    L.append('* |7| / |6| (fitted from epoch 4): ' + ', '.join(
        f'{v:.3f} at Ωh = {k}' for k, v in so.items())
        + f"; local log–log slope of 7 {sl['measured']:.2f} (theory_drift {sl['theory']:.2f}).")
    o = nt['seven_opt']
    L.append(f"* 7 opt. (fitted from epoch 4): order {o['order']:.2f} "
             f"(theory {o['order_theory']:.2f}); "
             + ', '.join(f"{o['measured'][k]:.5g} at Ωh = {k} (theory {o['theory'][k]:.5g})"
                         for k in ('0.6', '0.2')) + '.')
    lk = nt['leakage_7_as_printed']
    L.append('* 7_as_printed, ε/(α²Ω)/(Ωh)² at Ωh = 0.6 / 0.2: ' + '; '.join(
        f"{per} periods {v['0.6']:.4f} / {v['0.2']:.4f}" for per, v in lk.items()) + '.')
    fp = nt['four_plus_printed']
    L.append('* 4+ printed, ε/(α²Ω)/(Ωh)² at Ωh = 0.6 / 0.2: products only '
             f"{fp['products_only'][0]:.5f} / {fp['products_only'][1]:.5f} (lead "
             f"{fp['products_only_lead']}); as printed {fp['as_printed'][0]:.4f} / "
             f"{fp['as_printed'][1]:.4f} (lead {fp['as_printed_lead']}).")
    tc = r['thesis_case']
    L.append(f"* 003's case 1 (α = {tc['alpha']:g}, ν = {tc['nu']:g}, τ = {tc['tau']:g} s) "
             f"over {tc['span_s']:g} s: the x⁴ terms give {tc['rad']['x4'][0]:.1e} … "
             f"{tc['rad']['x4'][1]:.1e} rad, the x⁶ terms {tc['rad']['x6'][0]:.1e} … "
             f"{tc['rad']['x6'][1]:.1e} rad.")
    L.append('')
    return '\n'.join(L)
