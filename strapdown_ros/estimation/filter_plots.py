"""
Plots of one run of the attitude filter (``filter_bag --plots DIR``).

From the filter's outputs (:class:`~strapdown_ros.estimation.filter_system.FilterOutput`) and
fix results (:class:`~strapdown_ros.estimation.filter_system.FixOutput`): the innovation of
every fix with its ±3σ (σ from S = HPHᵀ + R), the gyro bias and the augmented states with
their ±1σ and ±3σ, the NIS with its χ²(3) band and the gate, and the fixes applied, gated and
reset over time with the attitude σ, and (given a reference agreement) the residual against
the reference with its ±3σ.  Divergence resets are drawn in every plot but the last.  matplotlib
is imported here only (an optional extra); no ROS imports.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.estimation.chi_square import chi2_3_quantile
from strapdown_ros.estimation.filter_system import FilterOutputs
from strapdown_ros.figures import save_figure
from strapdown_ros.rotation import quat_to_rotvec
from strapdown_ros.sensors.effects import EFFECTS

__all__ = ['PLOT_NAMES', 'write_filter_plots']

#: the files :func:`write_filter_plots` writes (the output rule checks them)
PLOT_NAMES = ('innovation.png', 'states.png', 'nis.png', 'resets.png', 'reference.png')

_MARK = {'applied': ('C0', '.', 'applied'), 'gated': ('C3', 'x', 'gated'),
         'reset': ('m', 'v', 'reset (divergence)')}


def _resets(ax, t_reset) -> None:
    for k, t in enumerate(t_reset):
        ax.axvline(t, color='m', lw=0.8, alpha=0.6, label='divergence reset' if k == 0 else None)


def _unit_scale(name: str) -> tuple[float, str]:
    """Return the factor and unit a state group is drawn in."""
    if name == 'gyro_bias':
        return 1e6, 'µrad/s'
    if name == 'time_offset':
        return 1e3, 'ms'
    if name == 'boresight':
        return 1e3, 'mrad'
    unit = EFFECTS[name].value_parameter.unit if name in EFFECTS else ''
    return 1.0, unit


def write_filter_plots(outdir: str, outputs, fixes, gate_probability: float,
                       agreement=None) -> list[str]:
    """
    Write the plots of one filter run.

    Parameters
    ----------
    outdir : str
        The directory (it exists).
    outputs : FilterOutputs or list of FilterOutput
        The filter's outputs, in stamp order.
    fixes : list of FixOutput
        The fix results, in processing order.
    gate_probability : float
        The χ²(3) probability of the gate.
    agreement : ReferenceAgreement, optional
        The outputs against the reference
        (:func:`strapdown_ros.estimation.reference_check.agreement_with_fixes`): with its
        series, ``reference.png`` shows the residual per VF axis with the ±3σ stated.

    Returns
    -------
    list of str
        The paths written (:data:`PLOT_NAMES`; ``reference.png`` with an agreement only).

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    outputs = FilterOutputs.of(outputs)               # the arrays
    stamps = outputs.stamps_ns.tolist() + [f.stamp_ns for f in fixes]
    t0 = min(stamps) if stamps else 0
    used = [f for f in fixes if f.nis is not None and f.innovation is not None]
    tf = np.array([(f.stamp_ns - t0) * 1e-9 for f in used])
    status = np.array([f.status for f in used])
    t_reset = [(f.stamp_ns - t0) * 1e-9 for f in fixes if f.status == 'reset']
    paths = []

    # innovation with ±3σ of S
    fig, axs = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    z = np.array([f.innovation for f in used]).reshape(-1, 3)
    sig = np.array([np.sqrt(np.diag(f.innovation_covariance))
                    if f.innovation_covariance is not None else [np.nan] * 3
                    for f in used]).reshape(-1, 3)
    for i, ax in enumerate(axs):
        if len(tf):
            ax.vlines(tf, -3e6 * sig[:, i], 3e6 * sig[:, i], color='C0', alpha=0.35, lw=3,
                      label='±3σ of each fix (S = HPHᵀ + R)')
        for st, (col, mk, lab) in _MARK.items():
            sel = status == st
            if sel.any():
                ax.plot(tf[sel], 1e6 * z[sel, i], mk, color=col, ms=4, label=lab)
        _resets(ax, t_reset)
        ax.set_ylabel(f"z_{'xyz'[i]} (VF), µrad")
        ax.grid(alpha=0.3)
    axs[0].legend(fontsize=8, loc='lower left', bbox_to_anchor=(0.0, 1.02), ncol=5,
                  borderaxespad=0.0)
    axs[-1].set_xlabel('time since the first stamp, s')
    fig.suptitle('Innovation of each fix (predicted minus measured) with ±3σ', y=0.995)
    paths.append(save_figure(fig, outdir, PLOT_NAMES[0]))

    # bias and augmented states with their σ
    to = (outputs.stamps_ns - t0) * 1e-9
    groups = [('gyro_bias', outputs.bias,
               np.sqrt(np.diagonal(outputs.bias_covariance, axis1=1, axis2=2)))]
    for name, (v, s) in outputs.augmented.items():
        if name == 'boresight':                 # the quaternion as a rotation vector
            v = quat_to_rotvec(v)
        groups.append((name, v.reshape(len(outputs), -1), s.reshape(len(outputs), -1)))
    fig, axs = plt.subplots(len(groups), 1, figsize=(10, 2.8 * len(groups) + 1), sharex=True,
                            squeeze=False)
    for ax, (name, v, s) in zip(axs[:, 0], groups):
        k, unit = _unit_scale(name)
        for j in range(v.shape[1]):
            col = f'C{j % 10}'
            ax.plot(to, k * v[:, j], color=col, lw=1, label=f'{name}[{j}]')
            ax.fill_between(to, k * (v[:, j] - s[:, j]), k * (v[:, j] + s[:, j]), color=col,
                            alpha=0.25, lw=0)
            ax.fill_between(to, k * (v[:, j] - 3 * s[:, j]), k * (v[:, j] + 3 * s[:, j]),
                            color=col, alpha=0.08, lw=0)
        _resets(ax, t_reset)
        ax.set_ylabel(f'{name}, {unit}' if unit else name)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc='upper right', ncol=min(v.shape[1], 6))
    axs[-1, 0].set_xlabel('time since the first stamp, s')
    fig.suptitle('Estimated states with ±1σ (dark) and ±3σ (light)')
    paths.append(save_figure(fig, outdir, PLOT_NAMES[1]))

    # NIS with its band and the gate
    fig, ax = plt.subplots(figsize=(11, 4.5))
    ax.axhspan(chi2_3_quantile(0.025), chi2_3_quantile(0.975), color='C0', alpha=0.12,
               label='χ²₃ 95 % band')
    nis = np.array([f.nis for f in used])
    for st, (col, mk, lab) in _MARK.items():
        sel = status == st
        if sel.any():
            ax.semilogy(tf[sel], nis[sel], mk, color=col, ms=4, label=lab)
    ax.axhline(chi2_3_quantile(gate_probability), color='C3', ls='--', lw=1,
               label=f'gate (χ²₃ {gate_probability:g})')
    ax.set_yscale('log')
    _resets(ax, t_reset)
    ax.set_xlabel('time since the first stamp, s')
    ax.set_ylabel('NIS')
    ax.grid(alpha=0.3, which='major')
    ax.legend(fontsize=8, loc='upper left', bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    ax.set_title('Normalised innovation squared of each fix')
    paths.append(save_figure(fig, outdir, PLOT_NAMES[2]))

    # fixes applied, gated, reset over time; the attitude σ
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True)
    for st, (col, _, lab) in _MARK.items():
        sel = status == st
        ax.step(tf, np.cumsum(sel), where='post', color=col, label=f'{lab}: {int(sel.sum())}')
    _resets(ax, t_reset)
    ax.set_ylabel('fixes (cumulative)')
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc='upper left')
    ax.set_title(f'Fixes applied, gated and reset: {len(t_reset)} divergence reset(s)')
    if outputs:
        sa = np.sqrt(np.diagonal(outputs.attitude_covariance, axis1=1, axis2=2))
        for i in range(3):
            ax2.semilogy(to, sa[:, i], lw=1, label=f"σ_{'xyz'[i]}")
    _resets(ax2, t_reset)
    ax2.set_ylabel('attitude σ (body), rad')
    ax2.set_xlabel('time since the first stamp, s')
    ax2.grid(alpha=0.3, which='both')
    ax2.legend(fontsize=8, loc='upper right')
    paths.append(save_figure(fig, outdir, PLOT_NAMES[3]))
    if agreement is not None and agreement.series is not None:
        paths.append(_reference_plot(plt, outdir, agreement, (outputs[0].stamp_ns - t0) * 1e-9))
    return paths


def _reference_plot(plt, outdir: str, agreement, shift: float) -> str:
    """Write reference.png: the residual against the reference per VF axis, with ±3σ."""
    ser = agreement.series
    t = np.asarray(ser['t']) + shift
    r, sig = np.asarray(ser['residual']) * 1e3, np.asarray(ser['sigma']) * 1e3
    fig, axs = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    for i, ax in enumerate(axs):
        ax.fill_between(t, -3 * sig[:, i], 3 * sig[:, i], color='C0', alpha=0.2, lw=0,
                        label='±3σ stated (the filter and the reference)')
        ax.plot(t, r[:, i], '.', ms=2, color='C3', label='filter − reference')
        ax.set_ylabel(f"VF {'xyz'[i]}, mrad")
        ax.grid(alpha=0.3)
        ax.set_title(f'RMS / σ = {agreement.rms_ratio[i]:.3g}', fontsize=9, loc='right')
    axs[0].legend(fontsize=8, loc='lower left', bbox_to_anchor=(0.0, 1.02), ncol=2,
                  frameon=False)
    axs[-1].set_xlabel('time since the first stamp, s')
    which = 'fixes it did not apply' if agreement.held_out else 'every fix'
    fig.suptitle(f'Attitude against the reference ({which}; lag {agreement.lag_s * 1e3:.3g} ms '
                 f'and a constant rotation taken out): {100 * agreement.within_3_sigma:.1f}% '
                 'within 3σ', fontsize=10)
    return save_figure(fig, outdir, PLOT_NAMES[4])
