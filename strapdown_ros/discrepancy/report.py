"""
The report of ``discrepancy``: report.md and its PNG plots.

Every sentence is computed from the result it describes
(:class:`strapdown_ros.discrepancy.result.DiscrepancyResult` and its JSON).

Plots (before = the nominal model, after = with the effects found):

* ``residuals.png`` (the main plot): the residual of each increment pair against time, per VF
  axis, before and after on separate axes, each in ″, ′ or ° as fits its size, with the ±3σ of
  the model as found (its noise terms applied), and the normalised residual the tests judge;
* ``autocorrelation.png``: autocorrelation of the whitened residuals with the 95% band;
* ``cross_correlation.png``: squared whitened residual against the body rate at the fix epochs
  and against the accumulated rotation angle;
* ``fig2a.png``: the difference of the angles turned (camera − gyro) against the angle the gyro
  turned between the fixes (Σ|Δθ|; 004 Fig. 2a), before and after on separate axes;
* ``allan.png``: Allan deviation of the gyro on static segments, measured against the model
  simulated on the same segments.
"""
from __future__ import annotations

from pathlib import Path
import textwrap

import numpy as np

from strapdown_ros.cli import write_figure, write_text
from strapdown_ros.discrepancy.diagnostics import autocorrelation
from strapdown_ros.discrepancy.sentences import (AXES, boresight_sigma_sentence,
                                                 consistency_warning, remaining_sentences,
                                                 repeatability_sentence, sigma_sentence)

__all__ = ['write_report', 'angle_unit', 'after_title']

ARCSEC = 180.0 / np.pi * 3600.0


def _plt():
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def angle_unit(values_rad) -> tuple[float, str]:
    """
    Choose a unit that fits the size of the angles.

    Arcseconds below 10′, arcminutes below 10°, degrees above (judged on the 99th percentile
    of |value|).

    Parameters
    ----------
    values_rad : array_like
        The angles, rad (non-finite values ignored).

    Returns
    -------
    factor : float
        Factor from rad to the unit.
    symbol : str
        ″, ′ or °.

    """
    v = np.abs(np.asarray(values_rad, dtype=float))
    v = v[np.isfinite(v)]
    big = float(np.percentile(v, 99)) if v.size else 0.0
    deg = float(np.degrees(big))
    if deg < 10.0 / 60.0:
        return ARCSEC, '″'
    if deg < 10.0:
        return ARCSEC / 60.0, '′'
    return 180.0 / np.pi, '°'


def _effects_words(res) -> str:
    return ', '.join(s.effect for s in res.steps) or 'nothing added'


def _wrap(text: str, width: int) -> str:
    """Return a title wrapped to lines of at most ``width`` characters (it fits its axes)."""
    return '\n'.join(textwrap.wrap(text, width)) or text


def after_title(res, width: int = 60) -> str:
    """
    Return the title of an "after" panel, wrapped so that it fits its axes.

    Parameters
    ----------
    res : DiscrepancyResult
        The result (its effects are named).
    width : int
        Most characters per line.

    Returns
    -------
    str
        The title.

    """
    return _wrap(f'after: with {_effects_words(res)}', width)


def _residuals(plt, res, path):
    """
    Plot the residual of each pair against time (the main plot).

    Before and after on separate columns, each in a unit that fits its size, with the ±3σ the
    model predicts (its noise terms as found); the last row is the normalised (whitened)
    residual the tests judge, with its ±3 band: where the raw residuals sit inside their
    per-pair band but the fixes' errors are correlated, this row shows what the tests see.
    """
    fig, axs = plt.subplots(4, 2, figsize=(12, 9.5), sharex=True)
    for col, (name, colour) in enumerate((('before', '0.35'), ('after', 'C0'))):
        s = res.series[name]
        k, unit = angle_unit(s['residual'])
        for c in range(3):
            ax = axs[c, col]
            ax.plot(s['t'], s['residual'][:, c] * k, '.', ms=3, color=colour,
                    label='residual' if (c, col) == (0, 0) else None)
            band = 3 * s['sigma'][:, c] * k
            ax.fill_between(s['t'], -band, band, color='C1', alpha=0.2,
                            label='±3σ the model predicts (each pair alone)'
                            if (c, col) == (0, 0) else None)
            ax.set_ylabel(f'about {AXES[c]}, {unit}')
            ax.grid(True, alpha=0.3)
        ax = axs[3, col]
        w = np.asarray(s['whitened'])
        for c in range(3):
            ax.plot(s['t'], w[:, c], '.', ms=2, color=f'C{c + 2}',
                    label=f'normalised, about {AXES[c]}' if col == 0 else None)
        ax.axhspan(-3.0, 3.0, color='C1', alpha=0.2)
        ax.set_ylabel('normalised residual\n(÷ what the model predicts)')
        ax.grid(True, alpha=0.3)
        ms = float(np.mean(w ** 2))
        ax.set_title(f'normalised residual the tests judge: mean square {ms:.3g} (1 as '
                     'predicted)', fontsize=9)
        axs[0, col].set_title('before: the nominal model' if name == 'before' else
                              after_title(res), fontsize=10)
        axs[-1, col].set_xlabel('time, s')
    fig.suptitle(_wrap('Residual of each increment pair (camera vs gyro) before and after adding '
                       f"the found effects — verdict: {res.verdict.replace('_', ' ')}", 100),
                 fontsize=11)
    fig.legend(loc='lower center', ncol=5, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    write_figure(fig, path, dpi=110)
    plt.close(fig)


def _autocorrelation(plt, res, path):
    fig, ax = plt.subplots(figsize=(9, 4))
    for name, col in (('before', '0.5'), ('after', 'C0')):
        w = res.series[name]['whitened']
        lags = max(2, min(30, len(w) // 4))
        ac = np.mean([autocorrelation(w[:, c], lags) for c in range(3)], axis=0)
        ax.plot(np.arange(1, lags + 1), ac, 'o-', color=col, ms=3, label=name)
    n = len(res.series['after']['t'])
    band = 1.96 / np.sqrt(3 * n)
    ax.axhspan(-band, band, color='C1', alpha=0.2, label='95% band (white)')
    ax.axhline(0, color='k', lw=0.5)
    ax.set_xlabel('lag, pairs')
    ax.set_ylabel('autocorrelation (mean of 3 axes)')
    ax.set_title('Does a residual predict the next ones? '
                 '(normalised residuals; inside the band: no)',
                 fontsize=10)
    ax.legend(fontsize=8, loc='upper left', bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    write_figure(fig, path, dpi=110)
    plt.close(fig)


def _cross(plt, res, path):
    fig, axs = plt.subplots(1, 2, figsize=(11, 4.6))
    for ax, key, label in ((axs[0], 'rate', 'body rate at the fix epochs, °/s'),
                           (axs[1], 'accumulated_angle', 'accumulated rotation angle, °')):
        for name, col in (('before', '0.55'), ('after', 'C0')):
            s = res.series[name]
            x = np.degrees(s[key])
            y = np.sum(s['whitened'] ** 2, axis=1) / 3.0
            r = np.corrcoef(x, y)[0, 1] if np.std(x) > 0 and np.std(y) > 0 else float('nan')
            ax.semilogy(x, np.maximum(y, 1e-6), '.', ms=3, color=col,
                        label=f'{name} (r = {r:.2f})')
        ax.axhline(1.0, color='C1', lw=1)
        ax.set_xlabel(label)
        ax.set_ylabel('residual² ÷ expected (mean of 3 axes)')
        ax.legend(fontsize=8, loc='upper center', bbox_to_anchor=(0.5, -0.16), ncol=2,
                  frameon=False)
    fig.suptitle('Does the residual grow with the turning rate or with the angle turned so far?')
    fig.tight_layout()
    write_figure(fig, path, dpi=110)
    plt.close(fig)


def _fig2a(plt, res, path):
    """
    Plot the difference of the rotation angles (camera − gyro) against the angle turned.

    004 Fig. 2a, with the angle the gyro turned between the two fixes (Σ|Δθ| of its increments)
    on the x axis: the net angle between two fixes cannot exceed 180° however fast the motion.
    Before and after on separate axes, each in a unit that fits.
    """
    fig, axs = plt.subplots(1, 2, figsize=(12, 5))
    for ax, (name, colour) in zip(axs, (('before', '0.35'), ('after', 'C0'))):
        s = res.series[name]
        d = s['phi_cam'] - s['phi_imu']
        x = np.degrees(s.get('path_angle', s['phi_cam']))
        sig = np.sqrt(np.sum(s['sigma'] ** 2, axis=1) / 3.0)
        k, unit = angle_unit(np.concatenate([d, 3 * sig]))
        ax.plot(x, d * k, '.', ms=4, color=colour, label='pairs' if name == 'before' else None)
        order = np.argsort(x)
        ax.plot(x[order], 3 * sig[order] * k, color='C1', lw=1,
                label='±3σ the model predicts' if name == 'before' else None)
        ax.plot(x[order], -3 * sig[order] * k, color='C1', lw=1)
        ax.set_xlabel('angle turned between the two fixes (Σ|Δθ| of the gyro), °')
        ax.set_ylabel(f'camera angle − gyro angle, {unit}')
        ax.set_title('before: the nominal model' if name == 'before'
                     else after_title(res), fontsize=10)
        ax.grid(True, alpha=0.3)
    fig.suptitle('Does the gyro turn by the angle the camera saw? Difference per pair against '
                 'the angle turned', fontsize=11)
    fig.legend(loc='lower center', ncol=2, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    write_figure(fig, path, dpi=110)
    plt.close(fig)


def _allan(plt, allan, path) -> bool:
    if not allan or 'taus_s' not in allan:
        return False
    fig, ax = plt.subplots(figsize=(8.5, 4.5))
    t = np.asarray(allan['taus_s'])
    ax.loglog(t, np.asarray(allan['measured']), 'o-', ms=3, label='measured')
    ax.loglog(t, np.asarray(allan['simulated_before']), '--', color='0.5', label='model, before')
    if allan.get('simulated_after') is not None:
        ax.loglog(t, np.asarray(allan['simulated_after']), '-', color='C2', label='model, after')
    ax.set_xlabel('τ, s')
    ax.set_ylabel('Allan deviation of the rate, rad/s')
    ax.set_title(f"Gyro noise at rest ({allan['static_segments']} segment(s), "
                 f"{allan['static_seconds']:.0f} s): measured vs the model", fontsize=10)
    ax.legend(fontsize=8, loc='upper left', bbox_to_anchor=(1.01, 1.0))
    ax.grid(True, which='both', alpha=0.3)
    fig.tight_layout()
    write_figure(fig, path, dpi=110)
    plt.close(fig)
    return True


def _fmt(v):
    if isinstance(v, (list, tuple)):
        return '[' + ', '.join(f'{x:.4g}' for x in v) + ']'
    return f'{v:.4g}'


def write_report(outdir: str, res, out: dict) -> str:
    """
    Write report.md and the PNG plots into a directory.

    Parameters
    ----------
    outdir : str
        The directory (created when missing).
    res : DiscrepancyResult
        The result (:func:`strapdown_ros.discrepancy.workflow.analyse`).
    out : dict
        Its JSON document as the ``discrepancy`` tool writes it (with ``input`` and
        ``allan``).

    Returns
    -------
    str
        The path of report.md.

    """
    d = Path(outdir)
    d.mkdir(parents=True, exist_ok=True)
    plt = _plt()
    _residuals(plt, res, d / 'residuals.png')
    _autocorrelation(plt, res, d / 'autocorrelation.png')
    _cross(plt, res, d / 'cross_correlation.png')
    _fig2a(plt, res, d / 'fig2a.png')
    has_allan = _allan(plt, out.get('allan'), d / 'allan.png')
    L = (_summary_lines(res, out) + _step_lines(res, out) + _test_lines(res, out)
         + _remaining_lines(res) + _allan_lines(out.get('allan'))
         + _boresight_and_plot_lines(res, has_allan))
    path = d / 'report.md'
    write_text(path, '\n'.join(L) + '\n')
    return str(path)


def _summary_lines(res, out: dict) -> list:
    """Return the recording, the verdict, the selection rule, warnings and why it stopped."""
    info = out.get('input', {})
    L = ['# Discrepancy report', '']
    L.append(f"Recording: {info.get('gyro_messages')} gyro increments at "
             f"{info.get('gyro_rate_from_stamps_hz') or float('nan'):.6g} Hz (from the stamps), "
             f"{info.get('camera_fixes')} camera fixes, {res.pairs} increment pairs over "
             f"{info.get('duration_s', float('nan')):.1f} s.")
    L.append('')
    added = ', '.join(f'`{s.effect}`' for s in res.steps) or 'none'
    L.append(f'**Verdict: `{res.verdict}`.** Effects added: {added}. Whitened residual RMS '
             f'{res.rms_before:.3g} → {res.rms_after:.3g} on all pairs and '
             f'{res.heldout_rms_before:.3g} → {res.heldout_rms_after:.3g} on the held-out '
             'blocks (1 is what the model predicts).')
    L.append('')
    L.append(f'Selection: likelihood-ratio tests at α/2 = {res.alpha / 2:g} with a Bonferroni '
             'correction over the candidates left at each step (the other α/2 goes to the tests '
             'below); an effect is added only if the held-out −2 log L per residual also '
             'improves; signatures with |correlation| above '
             f"{out['selection']['separability_bound']} are reported as not separable.")
    warning = consistency_warning(res)
    if warning:
        L += ['', '**' + warning.replace('WARNING: ', 'WARNING:** ', 1) + '.']
    sigma = sigma_sentence(res)
    if sigma:
        L += ['', sigma + '.  Noise terms: their Fisher σ, raised to the leave-one-block-out '
              'jackknife.']
    stop = {'max_steps': f"the step limit ({out.get('max_steps')} accepted effects) stopped the "
                         'search: more effects may be missing',
            'no_significant_candidate': 'the search stopped because no candidate left passes its '
                                        'test',
            'no_candidates_left': 'the search stopped because every candidate was added, excluded '
                                  'or failed',
            'iteration_limit': 'the search stopped at its turn limit'}.get(out.get('stopped_by'),
                                                                           '')
    if stop:
        L += ['', stop[0].upper() + stop[1:] + '.']
    return L


def _step_lines(res, out: dict) -> list:
    """Return the table of steps, repeatability, failures, first-step scores, rejections."""
    L = ['', '## Steps', '',
         '| step | effect | parameters (SI) | σ | LR statistic | dof | p-value | held-out gain |',
         '|---|---|---|---|---|---|---|---|']
    for k, s in enumerate(res.steps, 1):
        pv = '; '.join(f'`{n}` = {_fmt(v)}' for n, v in s.parameters.items())
        sv = '; '.join(_fmt(v) for v in s.sigma.values())
        L.append(f'| {k} | `{s.effect}` | {pv} | {sv} | {s.statistic:.4g} | {s.dof} | '
                 f'{s.p_value:.3g} | {s.heldout_gain:.3g} |')
    if not res.steps:
        L.append('| – | none passed | | | | | | |')
    for k, s in enumerate(res.steps, 1):
        text = repeatability_sentence(s)
        if text:
            L += ['', f'Step {k} (`{s.effect}`) is **' + text.replace(
                'across time blocks:', 'across time blocks**:', 1) + '.']
    if out.get('failed_candidates'):
        seen: dict = {}
        for f in out['failed_candidates']:
            seen.setdefault((f['effect'], f['reason']), []).append(str(f['step']))
        L += ['', 'Not fitted (dropped from the step named): ' + '; '.join(
            f"`{e}` at step {', '.join(at)}: {r}" for (e, r), at in seen.items()) + '.']
    L += ['', 'First-step scores of every candidate:', '',
          '| candidate | LR statistic | dof | p-value | note |', '|---|---|---|---|---|']
    for c in out['candidates_first_step']:
        L.append(f"| `{c['effect']}` | {c['statistic']:.4g} | {c['dof']} | {c['p_value']:.3g} | "
                 f"{c.get('direct_check', '')} |")
    if res.not_separable:
        L += ['', 'Not separable on this trajectory: '
              + '; '.join(f'`{a}` and `{b}`' for a, b in res.not_separable) + '.']
    if res.rejected:
        L += ['', 'Not added: '
              + '; '.join(f"`{r['effect']}` ({r['reason']})" for r in res.rejected) + '.']
    return L


def _test_lines(res, out: dict) -> list:
    """Return the table of the verdict tests before and after."""
    tb, ta = out['tests_before'], out['tests_after']
    L = ['', '## Tests', '', f"Each at (α/2)/3 = {ta['level']:.3g}.", '',
         '| test | before: statistic | p | after: statistic | p | after |',
         '|---|---|---|---|---|---|']
    for k, label in (('nis', 'NIS (χ²)'), ('whiteness', 'Ljung–Box whiteness'),
                     ('outliers', 'largest |residual|')):
        ok = 'pass' if ta[k]['p_value'] is not None and ta[k]['p_value'] >= ta['level'] else 'FAIL'
        L.append(f"| {label} | {tb[k]['statistic']:.4g} | {tb[k]['p_value']:.3g} | "
                 f"{ta[k]['statistic']:.4g} | {ta[k]['p_value']:.3g} | {ok} |")
    return L


def _remaining_lines(res) -> list:
    """Return what structure remains (empty when the tests pass)."""
    rm = res.remaining
    if not rm:
        return []
    L = ['', '## What remains', ''] + remaining_sentences(res) + ['']
    if 'dominant_period_s' in rm:
        L.append(f"- dominant period {rm['dominant_period_s']:.4g} s (normalised periodogram "
                 f"power {rm['dominant_period_power']:.2f});")
    L.append(f"- largest autocorrelation {rm['dominant_lag_autocorrelation']:.2f} at lag "
             f"{rm['dominant_lag_pairs']} pair(s);")
    for key, label in (('correlation_with_rate', 'body rate'),
                       ('correlation_with_accumulated_angle', 'accumulated angle'),
                       ('correlation_with_rotation_angle', 'rotation angle of the increment')):
        if key in rm:
            L.append(f'- correlation of the squared residual with the {label}: {rm[key]:.2f};')
    sw = rm.get('gyro_axis_swap_sign')
    if sw and sw.get('explains'):
        L.append('- candidate explanation outside the library: **gyro axis swap/sign** — '
                 f"the gyro triad as wired is left-handed: read as e.g. {sw['mapping']}, the "
                 f"axis-alignment RMS drops to {sw['ratio']:.2g}× that of the axes as wired "
                 '(which axis is swapped or reversed the camera cannot tell: any rotation '
                 'of the triad goes into the boresight);')
    L.append('- largest whitened residuals at t = '
             + ', '.join(f'{t:.1f}' for t in rm['largest_whitened_at_s']) + ' s.')
    return L


def _allan_lines(allan) -> list:
    """Return the Allan-deviation comparison, or why there is none."""
    if not (allan and 'taus_s' in allan):
        if allan and 'error' in allan:
            return ['', f"Allan deviation not computed: {allan['error']}"]
        return ['', 'No static segment of 15 s or more: no Allan-deviation comparison.']
    L = ['', '## Allan deviation (static segments)', '']
    if 'excess_region_s' in allan:
        a, b = allan['excess_region_s']
        slope = (f" (log–log slope {allan['excess_slope']:.2f} there)."
                 if allan.get('excess_slope') is not None else '.')
        L.append("The measured Allan deviation exceeds the nominal model's by up to "
                 f"{allan['excess_ratio_max']:.2f}× for τ from {a:.3g} to {b:.3g} s" + slope)
    else:
        L.append("The measured Allan deviation stays within 1.5× of the nominal model's at "
                 'every τ.')
    sn = allan.get('static_noise')
    if sn:
        m = np.asarray(sn['rate_std_rad_s'])
        after = sn['model_rate_std_rad_s_after']
        L.append('')
        L.append("Rate noise on the static segments (each segment's mean removed): "
                 f"{', '.join(f'{v:.3g}' for v in m)} rad/s about x, y, z; the model predicts "
                 f"{sn['model_rate_std_rad_s_before']:.3g} before and "
                 f"{sn['model_rate_std_rad_s_after']:.3g} after "
                 f"(measured ÷ model after: {', '.join(f'{v / after:.2f}' for v in m)}).")
    return L


def _boresight_and_plot_lines(res, has_allan: bool) -> list:
    """Return the boresight estimate and the plots with their captions."""
    b = np.degrees(res.boresight_rad)
    s = np.asarray(res.boresight_sigma_rad) * ARCSEC
    L = ['', '## Boresight (estimated in every fit)', '',
         f'β = ({b[0]:.6f}°, {b[1]:.6f}°, {b[2]:.6f}°) ± '
         f'({s[0]:.3g}″, {s[1]:.3g}″, {s[2]:.3g}″) (σ: {res.sigma_method}).', '']
    compare = boresight_sigma_sentence(res)
    if compare:
        L += [compare[0].upper() + compare[1:] + '.', '']
    L += ['## Plots', '',
          'Residual of each increment pair (camera vs gyro) against time, before and after '
          'adding the found effects; the shaded band is ±3σ of what the model (its noise terms '
          'as found) predicts for each pair alone; the last row is the normalised residual the '
          'tests judge (the fixes shared by consecutive pairs taken into account), with its ±3 '
          'band:', '',
          '![residual against time](residuals.png)', '',
          'Difference of the angles the camera and the gyro turned between two fixes, against '
          'the angle the gyro turned between them (Σ|Δθ|; 004 Fig. 2a):', '',
          '![angle difference against angle](fig2a.png)', '',
          'Autocorrelation of the normalised residuals (white: inside the band):', '',
          '![autocorrelation](autocorrelation.png)', '',
          'Normalised residual against the turning rate and the angle turned so far:', '',
          '![cross-correlation](cross_correlation.png)', '']
    if has_allan:
        L += ['Allan deviation of the gyro at rest, measured and simulated from the model:', '',
              '![Allan deviation](allan.png)', '']
    return L
