"""
Benchmark every coning algorithm on exact coning motion: drift, order of accuracy and cost.

The command ``coning_bench``: the figures set beside the analytic theory, an independent
ODE reference and the claims of Aksyonenko 2014 (003); the report is ``coning_report``.

With no options it runs the three cases of 003 §2.3 — (α, ν) = (0.087, 1), (0.5, 1),
(0.087, 0.5), 3600 s — at τ = 0.01 s and τ = 0.001 s, an order sweep per algorithm at small
α, and the cost per update; it prints a summary and, with --json/--plots/--report, writes
the JSON records, PNG plots and the Markdown report.

Method (strapdown_ros/attitude/coning_analysis.py): drift = least-squares slope of the cone-axis
error over whole cone periods; floor = the same arithmetic fed exact rotation vectors;
peer = a DOP853 solution of the quaternion kinematics used as the truth instead of the
closed form.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

from strapdown_ros.attitude.coning import ALGORITHMS, theory_drift
from strapdown_ros.attitude.coning_analysis import (cost_per_update, FLOOR_FACTOR, measure_case,
                                                    order_sweep, THESIS_CASES, THESIS_STEPS)
from strapdown_ros.bench.coning_derivation_checks import derivation_checks, derivation_report
from strapdown_ros.bench.coning_report import fmt, write_report
from strapdown_ros.cli import check_outputs, DIRECTORY, FILE, write_figure, write_text
from strapdown_ros.motion.profiles import ConingProfile
from strapdown_ros.rotation import quat_to_dcm, rotvec_to_dcm
from strapdown_ros.sensors import DEG_PER_HOUR


def parse_args(argv):
    """
    Parse and check the command line of ``coning_bench``.

    Parameters
    ----------
    argv : list of str
        Arguments without the program name.

    Returns
    -------
    argparse.Namespace
        The options, with ``names`` (algorithms), ``cases`` ((α, ν) pairs) and ``steps``.

    """
    ap = argparse.ArgumentParser(prog='coning_bench', description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--alpha', type=float,
                    help='coning half-angle, rad (default: the three 003 cases)')
    ap.add_argument('--nu', type=float, help='coning frequency, rad/s (with --alpha)')
    ap.add_argument('--step', type=float, action='append',
                    help='gyro interval τ, s (repeatable; default 0.01 and 0.001)')
    ap.add_argument('--duration', type=float, default=3600.0,
                    help='simulated seconds per case (default 3600)')
    ap.add_argument('--algorithms', help='comma-separated names (default: all)')
    ap.add_argument('--json', help='write the results to this JSON file '
                    '(documented run: doc/results/coning_bench/coning.json)')
    ap.add_argument('--plots', help='write PNG plots into this directory '
                    '(documented run: doc/results/coning_bench)')
    ap.add_argument('--report', help='write the Markdown report to this file '
                    '(documented run: doc/results/coning_bench/coning.md)')
    ap.add_argument('--force', action='store_true', help='overwrite existing outputs')
    ap.add_argument('--no-ode', action='store_true', help='skip the ODE peer reference')
    ap.add_argument('--sweep-periods', type=int, default=20,
                    help='cone periods per order-sweep point')
    ap.add_argument('--derivation-checks', metavar='FILE',
                    help='only write the figures of doc/coning_derivations.md to this Markdown '
                         'file (documented run: doc/results/coning_bench/'
                         'coning_derivation_checks.md; a few seconds)')
    args = ap.parse_args(argv)
    names = args.algorithms.split(',') if args.algorithms else list(ALGORITHMS)
    bad = [n for n in names if n not in ALGORITHMS]
    if bad:
        ap.error(f"unknown algorithm(s) {', '.join(bad)}; valid names: {', '.join(ALGORITHMS)}")
    args.names = names
    if (args.alpha is None) != (args.nu is None):
        ap.error('give --alpha and --nu together')
    args.cases = [(args.alpha, args.nu)] if args.alpha is not None else THESIS_CASES
    args.steps = args.step or THESIS_STEPS
    for a, v in args.cases:
        if not (0 < a < np.pi and v > 0):
            ap.error('need 0 < alpha < π and nu > 0')
    if any(s <= 0 for s in args.steps) or args.duration <= 0:
        ap.error('--step and --duration must be > 0')
    return args


def run(args) -> dict:
    """
    Measure every case and algorithm: drift, order sweep, cost, model checks.

    Parameters
    ----------
    args : argparse.Namespace
        Options of ``parse_args``.

    Returns
    -------
    dict
        ``results`` (one record per case, step and algorithm; rad/s and °/h), ``cases``,
        ``order_sweeps``, ``model_checks`` and ``wall_s``.

    """
    t0 = time.perf_counter()
    cases = []
    for alpha, nu in args.cases:
        for step in args.steps:
            cases.append(
                measure_case(args.names, alpha, nu, step, args.duration, with_ode=not args.no_ode))
            print(f'  case α={alpha:g} ν={nu:g} τ={step:g}: {cases[-1].wall_s:.1f} s',
                  file=sys.stderr)
    sweeps = {n: order_sweep(n, periods=args.sweep_periods) for n in args.names}
    costs = {n: cost_per_update(n) for n in args.names}
    records = []
    for c in cases:
        for n in args.names:
            a = ALGORITHMS[n]
            d = c.drift[n]
            th = theory_drift(a, c.nu * c.step * a.samples)
            records.append(
                {
                    'algorithm': n,
                    'alpha': c.alpha,
                    'nu': c.nu,
                    'step': c.step,
                    'samples_per_update': a.samples,
                    'drift_rad_per_s': d,
                    'drift_deg_per_h': d / DEG_PER_HOUR,
                    'theory_rad_per_s': None if th is None else float(th * c.alpha**2 * c.nu),
                    'order_measured': sweeps[n]['order_measured'],
                    'order_theory': a.order_expected,
                    'floor': bool(abs(d) <= FLOOR_FACTOR * max(c.floor.values())),
                    'ns_per_update': costs[n],
                    # extra fields (the schema's fields come first)
                    'floor_rad_per_s': max(c.floor.values()),
                    'drift_ode_rad_per_s': c.drift_ode.get(n),
                    'cross_products': a.cross_products,
                    'additions': a.additions,
                    'scalings': a.scalings,
                    'order_claimed': a.order_intended,
                }
            )
    case_records = [{'alpha': c.alpha, 'nu': c.nu, 'step': c.step, 'duration': c.duration,
                     'fitted_until_s': c.fitted_until,
                     'floor_rad_per_s': {str(k): v for k, v in c.floor.items()},
                     'ode_truth_max_gap_rad': c.truth_gap, 'wall_s': c.wall_s}
                    for c in cases]
    return {'results': records, 'cases': case_records, 'order_sweeps': sweeps,
            'model_checks': model_checks(), 'wall_s': time.perf_counter() - t0}


def model_checks() -> dict:
    """
    Return the numerical evidence for the misprints of the coning model, 003 §2.2.

    Returns
    -------
    dict
        Largest differences between the printed formulas and the exact ones (α = 0.5, ν = 1).

    """
    alpha, nu = 0.5, 1.0
    p = ConingProfile(alpha, nu)
    t = np.linspace(0.0, 7.0, 701)
    c, s, v = np.cos(alpha), np.sin(alpha), nu * t
    U = quat_to_dcm(p.attitude(t))
    u12_printed = -0.5 * (1 - c) * np.sin(2 * v)
    u22_printed = c + (1 - c) * np.sin(v) ** 2
    tk = t[1:]
    q_printed = np.stack(
        [-s * (np.sin(v[1:]) - np.sin(v[:-1])), -s * (np.cos(v[1:]) - np.cos(v[:-1]))], -1)
    exact = p.delta_theta(t[:-1], tk)[:, :2]
    # (2.9) vs U^T dU/dt by central differences
    h = 1e-6
    om = np.einsum('nji,njk->nik', U,
                   (quat_to_dcm(p.attitude(t + h)) - quat_to_dcm(p.attitude(t - h))) / (2 * h))
    w_num = np.stack([om[:, 2, 1], om[:, 0, 2], om[:, 1, 0]], -1)
    rod = rotvec_to_dcm(alpha * np.stack([np.sin(v), np.cos(v), np.zeros_like(v)], -1))
    return {'alpha': alpha, 'nu': nu,
            'U_vs_rodrigues_max': float(np.abs(U - rod).max()),
            'u12_printed_max_error': float(np.abs(u12_printed - U[:, 0, 1]).max()),
            'u22_printed_max_error': float(np.abs(u22_printed - U[:, 1, 1]).max()),
            'omega_29_max_error': float(np.abs(w_num - p.body_rate(t)).max()),
            'omega_27_row3_sign_error': float(np.abs(om[:, 2, 0] - w_num[:, 1]).max()),
            'increments_210_printed_max_error': float(np.abs(q_printed - exact).max()),
            'increments_210_printed_equals_minus_exact': float(np.abs(q_printed + exact).max())}


# ------------------------------------------------------------------------------- output
def summary_table(res: dict, args) -> str:
    """
    Format the console table of drifts, theory, ODE peer, order and floor per case.

    Parameters
    ----------
    res : dict
        Result of ``run``.
    args : argparse.Namespace
        Options; the table does not use them.

    Returns
    -------
    str
        The table.

    """
    recs = res['results']
    lines = []
    for case in res['cases']:
        lines.append(
            f"\nα = {case['alpha']:g} rad, ν = {case['nu']:g} rad/s, τ = {case['step']:g} s, "
            f"{case['duration']:g} s (fit over {case['fitted_until_s']:.1f} s)")
        lines.append(
            f"{'algorithm':<24}{'drift °/h':>12}{'theory °/h':>12}{'ODE peer °/h':>14}"
            f"{'order':>7}{'floor':>7}")
        for r in recs:
            if (r['alpha'], r['nu'], r['step']) != (case['alpha'], case['nu'], case['step']):
                continue
            th = None if r['theory_rad_per_s'] is None else r['theory_rad_per_s'] / DEG_PER_HOUR
            ode = r['drift_ode_rad_per_s']
            ode = None if ode is None else ode / DEG_PER_HOUR
            lines.append(
                f"{r['algorithm']:<24}{fmt(r['drift_deg_per_h']):>12}{fmt(th):>12}{fmt(ode):>14}"
                f"{fmt(r['order_measured'], 2):>7}{('yes' if r['floor'] else ''):>7}")
    return '\n'.join(lines)


def write_plots(res: dict, outdir: str) -> list[str]:
    """
    Write the drift bars per case and the order-of-accuracy plot.

    Parameters
    ----------
    res : dict
        Result of ``run``.
    outdir : str
        Directory for ``coning_drift.png`` and ``coning_order.png`` (created).

    Returns
    -------
    list of str
        Paths of the files written.

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    os.makedirs(outdir, exist_ok=True)
    files = []
    recs = res['results']
    names = list(dict.fromkeys(r['algorithm'] for r in recs))
    fig, axes = plt.subplots(len(res['cases']), 1, figsize=(11, 3.2 * len(res['cases'])),
                             squeeze=False)
    for ax, case in zip(axes[:, 0], res['cases']):
        rs = [
            r for r in recs
            if (r['alpha'], r['nu'], r['step']) == (case['alpha'], case['nu'], case['step'])
        ]
        x = np.arange(len(rs))
        vals = np.array([abs(r['drift_deg_per_h']) for r in rs])
        colors = [
            'tab:gray' if r['floor'] else
            ('tab:red' if 'printed' in r['algorithm'] else 'tab:blue') for r in rs
        ]
        ax.bar(x, np.maximum(vals, 1e-30), color=colors)
        th = [
            abs(r['theory_rad_per_s']) / DEG_PER_HOUR if r['theory_rad_per_s'] else np.nan
            for r in rs
        ]
        ax.plot(x, th, 'k_', markersize=14, label='small-α theory')
        fl = [r['floor_rad_per_s'] / DEG_PER_HOUR for r in rs]
        ax.plot(x, fl, 'g.', label='round-off floor')
        ax.set_yscale('log')
        ax.set_xticks(x)
        ax.set_xticklabels([r['algorithm'] for r in rs], rotation=60, ha='right', fontsize=7)
        ax.set_ylabel('|drift|, °/h')
        ax.set_title(f"α = {case['alpha']:g}, ν = {case['nu']:g} rad/s, τ = {case['step']:g} s "
                     '(blue: algorithms, red: printed forms, gray: at the floor)', fontsize=9)
        ax.legend(fontsize=7, loc='upper right')
    fig.tight_layout()
    f = os.path.join(outdir, 'coning_drift.png')
    write_figure(fig, f, dpi=110)
    plt.close(fig)
    files.append(f)

    fig, ax = plt.subplots(figsize=(9, 6.5))
    cmap = plt.get_cmap('tab20')
    for i, n in enumerate(names):
        s = res['order_sweeps'][n]
        x = np.array(s['omega_h'])
        d = np.abs(np.array(s['drift']))
        used = np.array(s['used'])
        ax.loglog(x[used], d[used], 'o', color=cmap(i % 20), ms=4)
        if s['theory'] is not None:
            ax.loglog(x, np.abs(s['theory']), '-', color=cmap(i % 20), lw=0.8,
                      label=f"{n} (p = {fmt(s['order_measured'], 3)})")
        else:
            ax.loglog(x[used], d[used], ':', color=cmap(i % 20), lw=0.8,
                      label=f"{n} (p = {fmt(s['order_measured'], 3)})")
    ax.set_xlabel('Ωh')
    ax.set_ylabel('|ε| / (α²Ω)')
    ax.set_title('Order of accuracy on exact coning: measured (dots) vs small-α theory (lines)')
    ax.legend(fontsize=6, ncol=2)
    ax.grid(True, which='both', alpha=0.3)
    fig.tight_layout()
    f = os.path.join(outdir, 'coning_order.png')
    write_figure(fig, f, dpi=110)
    plt.close(fig)
    files.append(f)
    return files


def main(argv=None):
    """
    Run ``coning_bench``.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name; ``sys.argv[1:]`` when None.

    Returns
    -------
    int
        0 on success, 2 for bad arguments or outputs (one line on stderr).

    """
    args = parse_args(sys.argv[1:] if argv is None else argv)
    if args.derivation_checks:
        try:
            check_outputs([('--derivation-checks', args.derivation_checks, FILE)], [],
                          args.force)
        except ValueError as exc:
            print(f'coning_bench: error: {exc}', file=sys.stderr)
            return 2
        text = derivation_report(derivation_checks())
        write_text(args.derivation_checks, text)
        print(text)
        return 0
    try:                                       # everything that can fail, before minutes of work
        check_outputs([('--json', args.json, FILE), ('--report', args.report, FILE),
                       ('--plots', args.plots, DIRECTORY,
                        ('coning_drift.png', 'coning_order.png'))],
                      [], args.force)
        if not (np.isfinite(args.duration) and args.duration > 0):
            raise ValueError(f'--duration must be > 0, got {args.duration}')
        for st in args.steps:
            if not (np.isfinite(st) and 0 < st < args.duration):
                raise ValueError(f'--step must be > 0 and below --duration, got {st}')
        for alpha, nu in args.cases:
            period = 2 * np.pi / nu
            if args.duration < period:
                raise ValueError(f'--duration {args.duration:g} s is shorter than one cone period '
                                 f'{period:.4g} s (ν = {nu:g})')
    except ValueError as exc:
        print(f'coning_bench: error: {exc}', file=sys.stderr)
        return 2
    print(
        f'coning_bench: {len(args.names)} algorithms, {len(args.cases)} case(s) ×'
        f' {len(args.steps)} step(s), {args.duration:g} s each',
        file=sys.stderr,
    )
    res = run(args)
    print(summary_table(res, args))
    if args.json:
        write_text(args.json, json.dumps(res, indent=1))
    plots = write_plots(res, args.plots) if args.plots else []
    if args.report:
        write_report(res, args, args.report, plots)
    print(f"\ntotal {res['wall_s']:.0f} s", file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
