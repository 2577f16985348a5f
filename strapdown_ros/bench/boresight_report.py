"""
Plots, markdown report and console tables of the boresight benchmark.

Every number comes from the run's result dictionary (``boresight_bench.main``); nothing is
computed here beyond formatting, except the NEES histograms of the plots.
"""
from __future__ import annotations

import os

import numpy as np

from strapdown_ros.bench.boresight_scenario import ANGLE_LABELS, BETA_DEG, Scenario
from strapdown_ros.bench.boresight_summary import nees_values
from strapdown_ros.cli import write_figure, write_text
from strapdown_ros.sensors import ARCSEC

#: the files ``make_plots`` writes into its directory
PLOT_FILES = ('boresight_errors.png', 'boresight_nees.png', 'boresight_ratios.png')


def make_plots(sc: Scenario, bnd: dict, mc: dict, summary: dict, outdir: str) -> list[str]:
    """
    Write the error scatter, NEES histogram and efficiency bar plots.

    Parameters
    ----------
    sc : Scenario
        The scenario; the current plots do not use it.
    bnd : dict
        Result of ``bounds`` (the 95 % ellipses).
    mc : dict
        Result of ``monte_carlo``.
    summary : dict
        Result of ``summarize``.
    outdir : str
        Directory of the ``PLOT_FILES`` (created).

    Returns
    -------
    list of str
        Paths of the files written.

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from scipy.stats import chi2
    os.makedirs(outdir, exist_ok=True)
    files = []
    best_cv = summary['acceptance'].get('weighted_le_best_opencv', {}).get('best_opencv')
    show = [('unweighted', 'tab:orange', 'x'), ('weighted', 'tab:blue', 'o'),
            ('correlated_gls', 'tab:green', '^')]
    if best_cv:
        show.append((best_cv, 'tab:red', 's'))
    k95 = np.sqrt(chi2.ppf(0.95, 2))
    fig, axes = plt.subplots(1, 3, figsize=(16, 5.2))
    t = np.linspace(0, 2 * np.pi, 200)
    for ax, (i, j) in zip(axes, ((0, 1), (0, 2), (1, 2))):
        for name, col, mk in show:
            e = mc['errors'][name] / ARCSEC
            ax.scatter(e[:, i], e[:, j], s=9, c=col, marker=mk, alpha=0.55, label=name,
                       linewidths=0.6)
        for key, ls, lab in (('exact', '-', 'exact CRLB 95%'), ('independent_pairs', '--',
                                                                'independent-pairs bound 95%')):
            P = bnd['crlb'][key][np.ix_([i, j], [i, j])] / ARCSEC ** 2
            w, V = np.linalg.eigh(P)
            pts = V @ (np.sqrt(w)[:, None] * k95 * np.stack([np.cos(t), np.sin(t)]))
            ax.plot(pts[0], pts[1], 'k' + ls, lw=1.4, label=lab)
        ax.set_xlabel(f'error {ANGLE_LABELS[i]}, ″')
        ax.set_ylabel(f'error {ANGLE_LABELS[j]}, ″')
        ax.grid(alpha=0.3)
        ax.axhline(0, c='0.6', lw=0.5)
        ax.axvline(0, c='0.6', lw=0.5)
    axes[0].legend(fontsize=7, loc='best')
    fig.suptitle(f"Boresight errors over {len(mc['chi2'])} Monte Carlo runs, β = {BETA_DEG}°")
    fig.tight_layout()
    p = os.path.join(outdir, 'boresight_errors.png')
    write_figure(fig, p, dpi=110)
    plt.close(fig)
    files.append(p)

    keys = [('weighted', 'weighted', 'weighted.covariance_beta'),
            ('weighted', 'weighted_floor', 'weighted.covariance_beta+triad_floor'),
            ('weighted', 'weighted_residual', 'weighted.covariance_beta_residual'),
            ('unweighted', 'unweighted', 'unweighted.covariance_beta'),
            ('weighted_004cov', 'weighted_004cov', 'weighted_004cov.covariance_beta'),
            ('correlated_gls', 'correlated_gls', 'correlated_gls.model')]
    fig, axes = plt.subplots(2, 3, figsize=(14, 7.2), sharey=True)
    xs = np.linspace(0, 20, 300)
    for ax, (ek, ck, name) in zip(axes.ravel(), keys):
        v = nees_values(mc['errors'][ek], mc['covs'][ck])
        s = summary['nees'][name]
        ax.hist(np.clip(v, 0, 20), bins=30, range=(0, 20), density=True, color='tab:blue',
                alpha=0.6)
        ax.plot(xs, chi2.pdf(xs, 3), 'k-', lw=1.2, label='χ²(3) pdf')
        ax.axvline(s['mean'], color='tab:red', lw=1.5, label=f"mean {s['mean']:.2f}")
        ax.axvspan(*s['band95'], color='0.7', alpha=0.6, label='95% band of the mean')
        ax.set_title(name, fontsize=9)
        ax.set_xlabel('NEES (clipped at 20)')
        ax.legend(fontsize=7)
    axes[0, 0].set_ylabel('density')
    axes[1, 0].set_ylabel('density')
    fig.tight_layout()
    p = os.path.join(outdir, 'boresight_nees.png')
    write_figure(fig, p, dpi=110)
    plt.close(fig)
    files.append(p)

    names = [k for k, v in summary['estimators'].items() if v.get('rms_arcsec')]
    fig, axes = plt.subplots(1, 3, figsize=(19, 4.8), sharey=True)
    for ax, key, title in ((axes[0], 'efficiency_vs_exact_crlb', 'RMS / √(exact CRLB)'),
                           (axes[1], 'efficiency_vs_independent_pairs_bound',
                            'RMS / √(independent-pairs bound)'),
                           (axes[2], 'efficiency_vs_bound_without_triad_rotation',
                            'vs the gyro-triad frame: RMS / √(CRLB without triad rotation)')):
        x = np.arange(len(names))
        for i in range(3):
            vals = [summary['estimators'][k][key][i] for k in names]
            ax.bar(x + (i - 1) * 0.27, vals, 0.27, label=ANGLE_LABELS[i])
        ax.axhline(1.0, c='k', lw=1)
        ax.axhline(1.2, c='k', ls='--', lw=1, label='1.2 (target)')
        ax.set_xticks(x)
        ax.set_xticklabels([n.replace('opencv_', 'cv ') for n in names], rotation=30, ha='right',
                           fontsize=8)
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3, axis='y', which='both')
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    p = os.path.join(outdir, 'boresight_ratios.png')
    write_figure(fig, p, dpi=110)
    plt.close(fig)
    files.append(p)
    return files


# ----------------------------------------------------------------------------------- report
def _f(v, nd=2):
    return '—' if v is None else f'{v:.{nd}f}'


def write_report(path: str, res: dict, plots: list[str]):
    """
    Write the markdown report of one benchmark run.

    Parameters
    ----------
    path : str
        Markdown file to write.
    res : dict
        The run's result (what ``--json`` writes).
    plots : list of str
        Plot files, linked relative to the report.

    """
    sm = res['summary']
    cfg = res['config']
    L = [
        '# boresight_bench — 004 boresight estimator vs Cramér–Rao bound and OpenCV',
        '',
        (
            f"Generated by `{res['command']}` ({cfg['runs']} Monte Carlo runs, seed {cfg['seed']},"
            f" {res['timing']['total_s']:.0f} s wall; OpenCV: {res['opencv']['info']}). Numbers in"
            ' arc seconds.'
        ),
        '',
        '## Scenario',
        '',
        (
            f"* {cfg['fixes']} star-camera fixes every {cfg['interval_s']} s ({cfg['pairs']}"
            f" increment pairs), gyro {cfg['gyro_rate_hz']:.0f} Hz, bench on the rotating Earth at"
            f" {cfg['latitude_deg']}° N."
        ),
        (
            f"* {len(cfg['rotations'])} rotations of 10–15° ({cfg['rotation_time_s']} s each)"
            ' about body x, y, z and two oblique axes, holds elsewhere; pair rotation angles:'
            f" {cfg['pairs_above_0p5deg']} pairs > 0.5°, the rest {cfg['hold_angle_deg']:.3f}°"
            ' (Earth rate).'
        ),
        f"* True β = {tuple(cfg['beta_deg'])}° (ψ, ϑ, γ), C_MF^VF = R_z(−ψ) R_x(ϑ) R_y(γ).",
        (
            f"* Gyro per run: M (σ_k = {cfg['gyro']['scale_sigma']:.0e}, σ_φ = 3″), b (σ_b ="
            ' 0.007°/h) drawn, white noise 0.0012°/√h; no quantization. Camera σ ='
            f" {tuple(cfg['camera_sigma_arcsec'])}″ (VF x, y, z)."
        ),
        '',
        '## Bounds',
        '',
        (
            'The **exact CRLB** is (Hᵀ Σ⁻¹ H)⁻¹ for the stacked pair residuals f = (f_1 … f_P)'
            ' linearised at the truth, with the full Gaussian noise covariance Σ of the'
            ' simulation: adjacent pairs share a camera fix (e_n = θ_n − R_nᵀ θ_{n−1}, so blocks'
            ' (n, n+1) = −P R_{n+1}), and the gyro constants b, M are common to all pairs (rank-12'
            ' term G P_x Gᵀ, treated as Gaussian nuisance with their known prior). The camera'
            ' fixes and the gyro data enter only through the pairs, and the unknown initial'
            ' attitude is eliminated exactly by differencing, so this is the bound of the whole'
            ' (linearised) problem. Neglected: the white noise of the one gyro interval that'
            ' straddles each epoch (1/4000 of a pair).'
        ),
        '',
        (
            'The **independent-pairs bound** Σ H_nᵀ (Cᵀ E_imu,n C + E_avu,n)⁻¹ H_n uses only the'
            " diagonal blocks (E_imu from the calibrator's `random_constant` model on the true"
            ' increments). It is the covariance the weighted estimator assumes; it is *not* a'
            ' lower bound when pairs are correlated.'
        ),
        '',
        '| bound | σ ψ | σ ϑ | σ γ | total angle RMS | σ about VF x, y, z (z = optical axis) |',
        '|---|---|---|---|---|---|',
    ]
    for k, v in sm['crlb'].items():
        s, a = v['sigma_arcsec'], v['sigma_vf_axes_arcsec']
        L.append(
            f"| {k} | {_f(s[0])} | {_f(s[1])} | {_f(s[2])} | {_f(v['total_angle_rms_arcsec'])} | "
            f'{_f(a[0])}, {_f(a[1])}, {_f(a[2])} |')
    L += [
        '',
        'Variants (all with the same H): `camera_correlation_only` — gyro pair errors taken'
        ' independent '
        '(marginal blocks kept); `gyro_constants_correlation_only` — camera pair errors taken'
        ' independent; '
        '`white_gyro_only` — a gyro without constant errors; `without_triad_rotation` — the gyro'
        ' misalignment '
        'without its antisymmetric part (M − Mᵀ)/2 = [a×]; `triad_rotation_floor` — that part'
        ' alone. [a×] rotates '
        'the whole gyro triad: every ΔS_imu becomes R_a ΔS_imu R_aᵀ, so the data are those of the'
        ' boresight '
        'R_a C and no estimator can separate a from β (σ_a = σ_φ/√2 = '
        f"{cfg['gyro']['misalignment_sigma'] / ARCSEC / np.sqrt(2):.2f}″ per MF axis). The exact"
        ' CRLB is the sum '
        'of `without_triad_rotation` and `triad_rotation_floor` (checked to 1e-3 in the tests).'
        ' The table '
        "\"errors relative to the gyro triad frame\" below removes each run's a from the truth and"
        ' compares '
        'with `without_triad_rotation`.',
        '',
        '## Estimators over the Monte Carlo runs',
        '',
        (
            'RMS about the truth; efficiency = RMS / √CRLB per angle; *pred.* = σ predicted for'
            ' the linear estimator with the true Σ (sandwich K Σ Kᵀ).'
        ),
        '',
        (
            '| estimator | RMS ψ | RMS ϑ | RMS γ | total | pred. σ ψ, ϑ, γ | RMS/√CRLB exact |'
            ' RMS/√bound indep. | fails |'
        ),
        '|---|---|---|---|---|---|---|---|---|',
    ]
    for k, v in sm['estimators'].items():
        if not v.get('rms_arcsec'):
            L.append(f"| {k} | — | — | — | — | — | — | — | {v['failure_count']} |")
            continue
        r = v['rms_arcsec']
        pr = ', '.join(
            _f(x) for x in v['predicted_sigma_arcsec']) if 'predicted_sigma_arcsec' in v else '—'
        ee = ', '.join(_f(x) for x in v['efficiency_vs_exact_crlb'])
        ei = ', '.join(_f(x) for x in v['efficiency_vs_independent_pairs_bound'])
        L.append(
            f"| {k} | {_f(r[0])} | {_f(r[1])} | {_f(r[2])} | {_f(v['total_angle_rms_arcsec'])} |"
            f" {pr} | {ee} | {ei} | {v['failure_count']} |"
        )
    L += [
        '', 'Errors relative to the gyro triad frame exp([a×]) C (what the data can determine):',
        '', '| estimator | RMS ψ | RMS ϑ | RMS γ | RMS / √CRLB without triad rotation |',
        '|---|---|---|---|---|'
    ]
    for k, v in sm['estimators'].items():
        if v.get('rms_vs_gyro_triad_frame_arcsec'):
            r = v['rms_vs_gyro_triad_frame_arcsec']
            L.append(
                f'| {k} | {_f(r[0])} | {_f(r[1])} | {_f(r[2])} | '
                f"{', '.join(_f(x) for x in v['efficiency_vs_bound_without_triad_rotation'])} |")
    acc = sm['acceptance']
    a1 = acc['weighted_rms_le_1.2_crlb']
    ac = acc['calibrator_rms_le_1.2_crlb']['vs_exact_crlb']
    cv = acc.get('calibrator_le_best_opencv')
    L += [
        '',
        '## Acceptance checks',
        '',
        f'* **The calibrator** (correlated weighting, what `calibrator_node` and `calibrate_bag`'
        f' publish for up to '
        '200 pairs): RMS ≤ 1.2 × √(exact CRLB): ratios'
        f" {', '.join(_f(x) for x in ac['ratios'])} → "
        f"**{'PASS' if ac['pass'] else 'FAIL'}**; mean NEES"
        f" {_f(sm['nees']['calibrator.covariance_beta']['mean'])}"
        + (
            f"; against the best OpenCV method ({cv['best_opencv']}) total-angle RMS ratio"
            f" {_f(cv['ratio_total_angle'])} → **{'PASS' if cv['pass'] else 'FAIL'}**."
            if cv
            else '.'
        ),
        '* The pairwise-weighted estimator (independent pairs; used beyond 200 pairs) below:',
        f'* Weighted RMS ≤ 1.2 × √CRLB: vs the exact CRLB ratios '
        f"{', '.join(_f(x) for x in a1['vs_exact_crlb']['ratios'])} →"
        f" **{'PASS' if a1['vs_exact_crlb']['pass'] else 'FAIL'}** "
        '(analytic prediction, no Monte Carlo noise:'
        f" {', '.join(_f(x) for x in a1['vs_exact_crlb']['predicted_ratios'])} → "
        f"{'PASS' if a1['vs_exact_crlb']['predicted_pass'] else 'FAIL'}); "
        'vs the independent-pairs bound'
        f" {', '.join(_f(x) for x in a1['vs_independent_pairs_bound']['ratios'])} → "
        f"**{'PASS' if a1['vs_independent_pairs_bound']['pass'] else 'FAIL'}**.",
    ]
    if 'weighted_le_best_opencv' not in acc:
        L.append(f"* Weighted ≤ best OpenCV: not evaluated ({res['opencv']['info']}).")
    else:
        a2 = acc['weighted_le_best_opencv']
        L.append(
            f"* Weighted ≤ best OpenCV ({a2['best_opencv']}): RMS ratio weighted/OpenCV per angle"
            f" {', '.join(_f(x) for x in a2['ratio_per_angle'])}, total angle"
            f" {_f(a2['ratio_total_angle'])} → **{'PASS' if a2['pass'] else 'FAIL'}**."
        )
    wu = sm['weighted_vs_unweighted']
    L.append(
        f'* Weighting gain (unweighted RMS / weighted RMS): '
        f"{', '.join(_f(x) for x in wu['rms_ratio_unweighted_over_weighted'])} (ψ, ϑ, γ), total"
        ' angle '
        f"{_f(wu['total_angle_ratio'])}."
    )
    L += [
        '',
        '## Covariance consistency (NEES)',
        '',
        (
            'Mean NEES (β̂ − β)ᵀ P⁻¹ (β̂ − β) over the runs; consistent if inside the 95% band of'
            ' the mean of χ²(3).'
        ),
        '',
        '| estimate · covariance | mean NEES | 95% band | inside | mean published σ ψ, ϑ, γ |',
        '|---|---|---|---|---|',
    ]
    for k, v in sm['nees'].items():
        L.append(
            f"| {k} | {_f(v['mean'])} | {_f(v['band95'][0])}–{_f(v['band95'][1])} |"
            f" {'yes' if v['inside'] else 'no'} |"
            f" {', '.join(_f(x) for x in v['mean_published_sigma_arcsec'])} |"
        )
    nm = sm['noise_model_check']
    L += [
        '',
        (
            'Noise-model check at the truth: mean fᵀΣ⁻¹f / 3P ='
            f" {nm['residual_at_truth_normalised_full_sigma_mean']:.3f} with the full Σ,"
            f" {nm['residual_at_truth_normalised_blockdiag_sigma_mean']:.3f} with the"
            f" block-diagonal Σ (band {nm['band95_full'][0]:.3f}–{nm['band95_full'][1]:.3f}); the"
            f" weighted χ²/dof averages {nm['weighted_chi2_per_dof_mean']:.3f}. Both"
            ' normalisations are ≈ 1 by construction (same diagonal blocks), so the χ² test of'
            ' the weighted solver cannot see the correlation between pairs. Calibrator E_imu vs'
            ' the linear gyro model: max relative difference'
            f" {nm['E_imu_calibrator_vs_linear_model_max_rel_diff']:.2e}."
        ),
        '',
    ]
    L += [
        (
            'Rotation-error RMS about the camera axes (VF x, y, z; z = optical axis; 004 §6'
            ' reports σ 0.6″ across and 6.0″ about the optical axis for its real trajectory):'
        ),
        '',
        '| estimator | VF x | VF y | VF z |',
        '|---|---|---|---|',
    ]
    for k, v in sm['estimators'].items():
        if v.get('rms_vf_axes_arcsec'):
            a = v['rms_vf_axes_arcsec']
            L.append(f'| {k} | {_f(a[0])} | {_f(a[1])} | {_f(a[2])} |')
    L += ['']
    L += [
        '## OpenCV hand-eye',
        '',
        f"OpenCV: {res['opencv']['info']}.",
        '',
        'Poses: gripper→base R_g2b,n = Π ΔS_imu (MF at t_n → MF at the first fix), target→camera '
        'R_t2c,n = (S_GCRS^VF,n)ᵀ, zero translations; the output R_cam2gripper is C_MF^VF. OpenCV'
        ' forms all '
        f"N(N−1)/2 = {cfg['fixes'] * (cfg['fixes'] - 1) // 2} relative motions (i < j), not only"
        ' consecutive ones.',
        '',
        'Noise-free convention check (total angle error, ″): '
        + ', '.join(
            f'{k} {v:.2e}' if isinstance(v, float) else f'{k}: {v}'
            for k, v in res['convention_check'].items()
        ),
        '',
    ]
    cc = res['calibrator_check']
    L += [
        '## Pipeline checks',
        '',
        (
            f"* BoresightCalibrator fed the same stream: {cc['pairs_calibrator']} pairs (bench"
            f" {cc['pairs_bench']}), max ΔS_imu difference {cc['max_dq_imu_diff_arcsec']:.1e}″,"
            f" E_imu relative difference {cc['max_E_imu_rel_diff']:.1e} (measured vs true"
            f" increments), β difference {', '.join(f'{x:.1e}' for x in cc['beta_diff_arcsec'])}″."
        ),
        (
            '* Vectorised gyro draw vs IntegratingSensor.sample: max |Δ| ='
            f" {cc['gyro_draw_vs_IntegratingSensor_max_abs']:.1e} rad."
        ),
        '',
    ]
    pf = res['performance']
    L += [
        '## Performance',
        '',
        (
            f"* `BoresightCalibrator.solve()` warm start with {pf['pairs']} pairs + 1 new: median"
            f" **{pf['warm_solve_ms_median']:.1f} ms** (max {pf['warm_solve_ms_max']:.1f} ms,"
            f" iterations {sorted(set(pf['warm_iterations']))}; target < {pf['target_ms']:.0f} ms"
            f" → {'PASS' if pf['meets_target'] else 'FAIL'}); cold start"
            f" {pf['cold_solve_ms']:.1f} ms."
        ),
        f'* Forming one pair from 20 s of 200 Hz gyro data (`gyro_increment` with E_imu): '
        f"{pf['pair_formation_ms_median']:.1f} ms.",
        (
            f"* Monte Carlo: {res['timing']['monte_carlo_s']:.1f} s for {cfg['runs']} runs on"
            f" {res['timing'].get('scheduler') or str(res['timing']['jobs']) + ' process(es)'}"
            f" on {res['timing']['cpu_count']} cores, 1-minute"
            f" load average {res['timing']['load_average_1min'][0]:.1f} at the start and"
            f" {res['timing']['load_average_1min'][1]:.1f} at the end (other processes share the"
            ' machine; all estimators per run; the pair formation, 70 × `gyro_increment` over'
            ' 4000 gyro intervals, and the OpenCV calls dominate).'
        ),
        '',
    ]
    if res.get('findings'):
        L += ['## Conclusions', ''] + [f'* {x}' for x in res['findings']] + ['']
    if plots:
        L += ['## Plots', '']
        base = os.path.dirname(os.path.abspath(path))
        for p in plots:
            L.append(f'![{os.path.basename(p)}]({os.path.relpath(os.path.abspath(p), base)})')
        L.append('')
    write_text(path, '\n'.join(L))


def print_checks(sc: Scenario, cv_info: str, conv: dict, calc: dict) -> None:
    """
    Print the scenario size and the pipeline checks on stdout.

    Parameters
    ----------
    sc : Scenario
        The bench scenario.
    cv_info : str
        OpenCV version, or why its hand-eye calibration is unavailable.
    conv : dict
        Result of ``convention_check``: total angle error per estimator, arc seconds.
    calc : dict
        Result of ``calibrator_check``.

    """
    print(f'scenario: {sc.pairs_count} pairs, {len(sc.u)} gyro intervals, '
          f'{int(np.sum(sc.angles_deg > 0.5))} pairs > 0.5°, built in {sc.build_s:.1f} s')
    print(f'OpenCV hand-eye: {cv_info}')
    print('noise-free convention check (total angle error, ″): '
          + ', '.join(f'{k} {v:.1e}' if isinstance(v, float) else f'{k}: {v}'
                      for k, v in conv.items()))
    print(f"calibrator check: pairs {calc['pairs_calibrator']}/{calc['pairs_bench']}, "
          f"max ΔS_imu diff {calc['max_dq_imu_diff_arcsec']:.1e}″, "
          f"β diff {np.max(np.abs(calc['beta_diff_arcsec'])):.1e}″, gyro draw vs "
          f"IntegratingSensor {calc['gyro_draw_vs_IntegratingSensor_max_abs']:.1e}")


def _ratios(values) -> str:
    return ', '.join(f'{x:.2f}' for x in values)


def _verdict(ok) -> str:
    return ' PASS' if ok else ' FAIL'


def print_summary(sm: dict, perf: dict, mc: dict, runs: int, jobs: int) -> None:
    """
    Print the bounds, estimator, NEES, acceptance and timing tables on stdout.

    Parameters
    ----------
    sm : dict
        Result of ``summarize``.
    perf : dict
        Result of ``performance``.
    mc : dict
        Result of ``monte_carlo`` (its wall time is printed).
    runs : int
        Monte Carlo runs.
    jobs : int
        Worker processes of the Monte Carlo.

    """
    where = mc.get('scheduler') or f'{jobs} process(es)'
    print(f"\n{runs} runs in {mc['wall_s']:.1f} s on {where} "
          f"({mc['wall_s'] / runs * 1e3:.0f} ms/run)")
    print(f"{'bound':<34}{'σψ″':>9}{'σϑ″':>9}{'σγ″':>9}{'total″':>9}")
    for k, v in sm['crlb'].items():
        s = v['sigma_arcsec']
        print(f"{k:<34}{s[0]:9.3f}{s[1]:9.3f}{s[2]:9.3f}{v['total_angle_rms_arcsec']:9.3f}")
    print(f"\n{'estimator':<24}{'RMSψ″':>8}{'RMSϑ″':>8}{'RMSγ″':>8}{'total″':>8}   "
          f"{'eff. vs exact':<20}{'eff. vs indep.':<20}fails")
    for k, v in sm['estimators'].items():
        if not v.get('rms_arcsec'):
            print(f"{k:<24}  all runs failed: {v['failures'][:1]}")
            continue
        r = v['rms_arcsec']
        ee = ' '.join(f'{x:5.2f}' for x in v['efficiency_vs_exact_crlb'])
        ei = ' '.join(f'{x:5.2f}' for x in v['efficiency_vs_independent_pairs_bound'])
        print(f"{k:<24}{r[0]:8.3f}{r[1]:8.3f}{r[2]:8.3f}{v['total_angle_rms_arcsec']:8.3f}   "
              f"{ee:<20}{ei:<20}{v['failure_count']}")
    print("\nerrors relative to the gyro triad's own frame exp([a×])·C "
          '(a = antisymmetric misalignment of the run):')
    for k, v in sm['estimators'].items():
        if v.get('rms_arcsec'):
            r = v['rms_vs_gyro_triad_frame_arcsec']
            eff = ' '.join(f'{x:5.2f}' for x in v['efficiency_vs_bound_without_triad_rotation'])
            print(f'  {k:<24}{r[0]:8.3f}{r[1]:8.3f}{r[2]:8.3f}   '
                  f'eff. vs CRLB without triad rotation {eff}')
    print('\nNEES means (95% band of the mean of χ²(3)):')
    for k, v in sm['nees'].items():
        print(f"  {k:<40}{v['mean']:8.3f}   [{v['band95'][0]:.3f}, {v['band95'][1]:.3f}]  "
              f"{'inside' if v['inside'] else 'OUTSIDE'}")
    wu = sm['weighted_vs_unweighted']
    print('weighting gain (unweighted/weighted RMS): '
          + _ratios(wu['rms_ratio_unweighted_over_weighted'])
          + f"; total {wu['total_angle_ratio']:.2f}")
    acc = sm['acceptance']
    a1 = acc['weighted_rms_le_1.2_crlb']
    ac = acc['calibrator_rms_le_1.2_crlb']['vs_exact_crlb']
    print('acceptance calibrator (correlated) ≤ 1.2·√CRLB: exact ' + _ratios(ac['ratios'])
          + _verdict(ac['pass'])
          + f"; NEES {sm['nees']['calibrator.covariance_beta']['mean']:.2f}")
    if 'calibrator_le_best_opencv' in acc:
        a3 = acc['calibrator_le_best_opencv']
        print(f"acceptance calibrator ≤ best OpenCV ({a3['best_opencv']}): ratio per angle "
              + _ratios(a3['ratio_per_angle']) + f", total {a3['ratio_total_angle']:.2f}"
              + _verdict(a3['pass']))
    ex, ind = a1['vs_exact_crlb'], a1['vs_independent_pairs_bound']
    print('acceptance weighted ≤ 1.2·√CRLB: exact ' + _ratios(ex['ratios'])
          + _verdict(ex['pass']) + ' (predicted ' + _ratios(ex['predicted_ratios'])
          + _verdict(ex['predicted_pass']) + '); independent-pairs ' + _ratios(ind['ratios'])
          + _verdict(ind['pass']))
    if 'weighted_le_best_opencv' in acc:
        a2 = acc['weighted_le_best_opencv']
        print(f"acceptance weighted ≤ best OpenCV ({a2['best_opencv']}): ratio per angle "
              + _ratios(a2['ratio_per_angle']) + f", total {a2['ratio_total_angle']:.2f}"
              + _verdict(a2['pass']))
    print(f"solve() warm start with {perf['pairs']} pairs: median "
          f"{perf['warm_solve_ms_median']:.1f} ms per update "
          f"(max {perf['warm_solve_ms_max']:.1f}, "
          f"iterations {sorted(set(perf['warm_iterations']))}; "
          f"cold {perf['cold_solve_ms']:.1f} ms); "
          f"one pair from 20 s of gyro data {perf['pair_formation_ms_median']:.1f} ms")
