"""
The verdict sentences of ``discrepancy``, each computed from the numbers it states.

One home for the words that both the summary (``strapdown_ros.tools.discrepancy``) and
report.md (:mod:`strapdown_ros.discrepancy.report`) print: the consistency warning, why the σ
are what they are, the boresight σ beside ``calibrate_bag``'s rule, whether an effect repeats
across the time blocks, and what structure is left, in plain words, with whether the found
effects can be used anyway.  Every direction (too large / too small, faster / slower) is decided
by the number printed beside it.  No ROS imports.
"""
from __future__ import annotations

import numpy as np

__all__ = ['consistency_warning', 'sigma_sentence', 'boresight_sigma_sentence',
           'repeatability_sentence', 'remaining_sentences', 'angle_text', 'AXES',
           'SIGMA_AGREEMENT']

AXES = ('VF x', 'VF y', 'VF z')
ARCSEC = 180.0 / np.pi * 3600.0
#: two σ of one quantity "agree" when their ratio is within 1 ± this
SIGMA_AGREEMENT = 0.2
#: a mean squared whitened residual this many times another is "larger" in words
_NOTABLE = 1.5


def angle_text(rad: float) -> str:
    """
    Return an angle in ″, ′ or ° as fits its size.

    Parameters
    ----------
    rad : float
        The angle, rad.

    Returns
    -------
    str
        E.g. ``12.3″``, ``4.5′``, ``1.2°``.

    """
    a = abs(float(rad)) * ARCSEC
    if not np.isfinite(a):
        return f'{a}'
    if a < 600.0:
        return f'{float(rad) * ARCSEC:.3g}″'
    if a < 36000.0:
        return f'{float(rad) * ARCSEC / 60.0:.3g}′'
    return f'{np.degrees(float(rad)):.3g}°'


def consistency_warning(res) -> str | None:
    """
    Return the ``WARNING:`` sentence of a fit whose χ²/dof is outside its band.

    Parameters
    ----------
    res : DiscrepancyResult
        The result.

    Returns
    -------
    str or None
        The sentence (above the band: the residuals are larger than the stated noise; below:
        smaller, the σ pessimistic); None when χ²/dof is inside its band.

    """
    if res.fit_consistent:
        return None
    lo, hi = res.chi2_per_dof_band
    c = res.chi2_per_dof
    if c > hi:
        where = (f'above [{lo:.3g}, {hi:.3g}] at the test level: the residuals are larger than '
                 'the stated noise and the effects found')
    else:
        where = (f'below [{lo:.3g}, {hi:.3g}] at the test level: the residuals are smaller than '
                 'the stated noise says (the stated noise is too large; σ from it are '
                 'pessimistic)')
    return (f'WARNING: the fit is not consistent with its stated noise: χ²/dof {c:.4g} {where}; '
            'the values below are not plain results')


def sigma_sentence(res) -> str | None:
    """
    Return why the σ are the sandwich (or the jackknife), in words that match the tests.

    Each failed test gives its own reason: whiteness (residuals correlated in time: the model's
    σ, which assumes independent pairs, would be too small), NIS above its band (residuals larger
    than stated: too small), NIS below its band (smaller than stated: the model's σ are
    pessimistic, kept as the floor), outliers (a few pairs far out).

    Parameters
    ----------
    res : DiscrepancyResult
        The result.

    Returns
    -------
    str or None
        The sentence; None when the σ are the model's.

    """
    if res.sigma_method == 'model':
        return None
    ta = res.tests_after
    reasons = []
    failed = ta.get('failed', [])
    if 'whiteness' in failed:
        reasons.append(f'the residuals are correlated in time (Ljung–Box p '
                       f"{ta['whiteness']['p_value']:.3g}): the model's σ, which assume "
                       'independent pairs, would be too small')
    if 'nis' in failed:
        c = ta['nis']['per_dof']
        if c > 1.0:
            reasons.append(f'the residuals are larger than the model says (χ²/dof {c:.3g}): the '
                           "model's σ would be too small")
        else:
            reasons.append(f'the residuals are smaller than the model says (χ²/dof {c:.3g}): the '
                           "model's σ are pessimistic and are kept as the floor")
    if 'outliers' in failed:
        reasons.append(f'a few pairs lie far out (largest |whitened residual| '
                       f"{ta['outliers']['statistic']:.3g})")
    jk = (', raised to the leave-one-block-out jackknife (each block weighted by its own '
          'information) where that is larger' if res.sigma_method == 'hac_jackknife' else '')
    why = '; '.join(reasons) or 'the residuals fail a test'
    return (f"σ: Newey–West sandwich over {res.hac_lags} pairs{jk}, never below the model's "
            f'({why})')


def boresight_sigma_sentence(res) -> str | None:
    """
    Return the boresight σ beside ``calibrate_bag``'s rule, and why they differ when they do.

    ``calibrate_bag`` fits the boresight alone with the stated noise and scales its σ by
    √(χ²/dof) when above 1 (``boresight_sigma_calibrate_bag_rule_rad``).  When the reported σ
    differs from that by more than :data:`SIGMA_AGREEMENT`, the sentence names the causes from
    their own ratios: the effects added (the model's σ with them over the model's σ without),
    the noise terms found (χ²/dof of the fit with no effect against 1), and the sandwich or
    jackknife (the σ reported over the model's).

    Parameters
    ----------
    res : DiscrepancyResult
        The result.

    Returns
    -------
    str or None
        The sentence; None when the rule's σ is not known.

    """
    cal = np.asarray(res.boresight_sigma_calibrate_bag_rule_rad, dtype=float)
    if cal.size != 3 or not np.all(cal > 0):
        return None
    rep = np.asarray(res.boresight_sigma_rad, dtype=float)
    model = np.asarray(res.boresight_sigma_model_rad, dtype=float)
    base = np.asarray(res.boresight_sigma_base_model_rad, dtype=float)
    ratio = rep / cal
    shown = ', '.join(angle_text(v) for v in cal)
    worst = int(np.argmax(np.abs(np.log(ratio))))
    head = (f"boresight σ by calibrate_bag's rule on the same pairs (the boresight alone, the "
            f'stated noise, × √(χ²/dof) = √{max(1.0, res.chi2_per_dof_base):.3g}): ({shown}); '
            f'reported ÷ that: {", ".join(f"{r:.2f}" for r in ratio)}')
    if np.all(np.abs(ratio - 1.0) <= SIGMA_AGREEMENT):
        return head + f' (agree within {100 * SIGMA_AGREEMENT:.0f}%)'
    why = []
    systematic = ('model', 'hac', 'hac_jackknife')
    names = ', '.join(s.effect for s in res.steps if s.sigma_method in systematic)
    r_eff = model[worst] / base[worst] if base[worst] > 0 else float('nan')
    if names and abs(r_eff - 1.0) > 0.05:
        why.append(f"the effects added ({names}) share part of the boresight's signature: the "
                   f"model's σ with them is {r_eff:.2f}× that without")
    noise = [s.effect for s in res.steps if s.sigma_method.startswith('fisher')]
    r_scale = (model[worst] / base[worst]) / np.sqrt(max(1.0, res.chi2_per_dof_base)) \
        if base[worst] > 0 else float('nan')
    if noise:
        why.append(f"the noise terms found ({', '.join(noise)}) replace the √(χ²/dof) scaling "
                   f'by a fitted noise model (together with the effects: {r_scale:.2f}× the '
                   "rule's σ before the sandwich)")
    r_hac = rep[worst] / model[worst] if model[worst] > 0 else float('nan')
    if res.sigma_method != 'model' and abs(r_hac - 1.0) > 0.05:
        why.append(f'the residuals fail {", ".join(res.tests_after["failed"])}: the sandwich'
                   + (' and the jackknife' if res.sigma_method == 'hac_jackknife' else '')
                   + f" give {r_hac:.2f}× the model's σ, which √(χ²/dof) scaling cannot (it "
                   'assumes independent pairs)')
    if not why:
        why.append('the pairs differ (the spacing of the fixes or the fixes dropped)')
    return (head + f'; they differ by more than {100 * SIGMA_AGREEMENT:.0f}% (most about '
            f"{('yaw', 'pitch', 'roll')[worst]}) because " + '; '.join(why))


def repeatability_sentence(step) -> str | None:
    """
    Return the sentence of an effect that is not the same in every time block.

    Parameters
    ----------
    step : Step
        An accepted effect.

    Returns
    -------
    str or None
        The sentence, with the test's statistic, dof and p-value and the block that departs
        most; None when the effect repeats (or was not tested).

    """
    if step.repeatable is not False:
        return None
    t = step.repeatability
    if not t:
        sp = '; '.join(f'{n} ± {_fmt(v)}' for n, v in step.spread.items())
        return (f'not repeatable across time blocks: leave-one-block-out spread {sp} '
                f'({step.spread_ratio:.3g}× the σ the model or sandwich alone gives): not a '
                'plain finding')
    form = ('the Newey–West form, for correlated residuals' if t['method'] == 'hac'
            else "the model's form")
    text = (f"not repeatable across time blocks: the blocks differ by more than each block's "
            f"own information allows (χ² {t['statistic']:.4g} on {t['dof']} dof, p "
            f"{t['p_value']:.3g} < {t['level']:.3g}; {form})")
    blocks = [b for b in t['blocks'] if b['dof'] > 0]
    if blocks:
        b = min(blocks, key=lambda b: b['p_value'])
        name = next(iter(step.parameters), '')
        diff, sig = b['difference'], b['difference_sigma']
        text += (f"; block {b['block']} (t {b['t_start_s']:.1f}–{b['t_end_s']:.1f} s) departs "
                 f'most: {name} there differs from the other blocks by {_fmt(diff)} ± '
                 f'{_fmt(sig)}')
    return text + ': not a plain finding'


def _fmt(v):
    if isinstance(v, (list, tuple, np.ndarray)):
        v = list(v)
        return _fmt(v[0]) if len(v) == 1 else '[' + ', '.join(f'{x:.3g}' for x in v) + ']'
    return f'{v:.4g}'


def remaining_sentences(res) -> list:
    """
    Return what is left, in plain words: its size, which axis, when, and the use of the effects.

    Parameters
    ----------
    res : DiscrepancyResult
        The result (its ``remaining``, ``steps`` and verdict).

    Returns
    -------
    list of str
        Empty unless the verdict is ``unexplained_structure``.

    """
    rm = res.remaining
    if res.verdict != 'unexplained_structure' or not rm:
        return []
    out = []
    ms = rm.get('whitened_ms_by_axis')
    if ms:
        out.append(_size_sentence(res, rm, ms))
    fm = rm.get('fast_motion')
    if fm:
        r = fm['ratio']
        if r >= _NOTABLE:
            when = (f'it happens mostly during fast motion: in the fastest third of the pairs '
                    f"(peak rate above {np.degrees(fm['rate_above_rad_s']):.3g}°/s) the "
                    f'normalised residual is {r:.2g}× its size in the slowest third')
        elif r <= 1.0 / _NOTABLE:
            when = (f'it happens mostly during slow motion or rest: in the slowest third of the '
                    f"pairs (peak rate below {np.degrees(fm['rate_below_rad_s']):.3g}°/s) the "
                    f'normalised residual is {1.0 / r:.2g}× its size in the fastest third')
        else:
            when = (f'it does not depend much on the rate: the fastest third of the pairs has '
                    f'{r:.2g}× the normalised residual of the slowest third')
        out.append(when[0].upper() + when[1:] + '.')
    rv = rm.get('reversals')
    if rv and 'ratio' in rv:
        r = rv['ratio']
        word = ('larger at reversals' if r >= _NOTABLE else
                'smaller at reversals' if r <= 1.0 / _NOTABLE else 'about the same at reversals')
        out.append(f"Pairs with a reversal of the turning sense ({rv['pairs']}, "
                   f"{100 * rv['fraction']:.0f}% of them): the normalised residual is {r:.2g}× "
                   f'that of the others ({word}).')
    out.append(_usable_sentence(res))
    return out


def _size_sentence(res, rm: dict, ms) -> str:
    """
    Return the size and the axis of what is left.

    When the NIS test fails, the size: the axis with the largest mean squared normalised
    residual and its RMS against what the model predicts.  When only whiteness fails, the
    residuals have the predicted size and what is left is their correlation in time: the axis
    with the largest autocorrelation, and the part of its residual that the correlation implies
    (√ρ × the RMS residual).
    """
    failed = res.tests_after.get('failed', [])
    k = int(rm.get('largest_axis', int(np.argmax(ms))))
    rr, er = rm.get('residual_rms_rad'), rm.get('expected_rms_rad')
    others = ', '.join(f'{AXES[i]} {ms[i]:.2g}' for i in range(3) if i != k)
    if 'nis' in failed or not rm.get('autocorrelation_by_axis'):
        size = (f': RMS residual {angle_text(rr[k])} where the model predicts '
                f'{angle_text(er[k])} per pair' if rr and er else '')
        return (f'What is left is largest about {AXES[k]}{size}; its mean squared normalised '
                f'residual is {ms[k]:.2g} (1 as the model predicts; {others}).')
    rho = rm['autocorrelation_by_axis']
    j = int(rm.get('correlated_axis', int(np.argmax(rho))))
    part = (f'; that is a slow part of about {angle_text(np.sqrt(max(rho[j], 0.0)) * rr[j])} '
            f'(√ρ × the RMS residual {angle_text(rr[j])})' if rr else '')
    period = (f", strongest period {rm['dominant_period_s']:.3g} s"
              if 'dominant_period_s' in rm else '')
    return (f'The residuals have about the size the model predicts (mean squared normalised '
            f"residual {', '.join(f'{v:.2g}' for v in ms)} about VF x, y, z; 1 as predicted); "
            f'what is left is their correlation in time, largest about {AXES[j]} '
            f'(autocorrelation {rho[j]:.2f} within 3 pairs{period}){part}.')


def _usable_sentence(res) -> str:
    """Return whether the found effects and the boresight can be used anyway."""
    if not res.steps:
        use = 'No library effect was found.'
    else:
        ok = [s.effect for s in res.steps if s.repeatable is not False]
        bad = [s.effect for s in res.steps if s.repeatable is False]
        parts = []
        if ok:
            parts.append(f"{', '.join(ok)} repeat{'s' if len(ok) == 1 else ''} across the time "
                         'blocks: usable with the σ given')
        if bad:
            parts.append(f"{', '.join(bad)} do{'es' if len(bad) == 1 else ''} not: do not use "
                         f"{'it' if len(bad) == 1 else 'them'} as calibrated")
        use = 'Can the found effects be used anyway? ' + '; '.join(parts) + '.'
    honest = ('The σ given cover this structure (the sandwich' + (
        ' and the time-block jackknife' if res.sigma_method == 'hac_jackknife' else '')
        + "), the boresight's too; " if res.sigma_method != 'model' else
        "The σ given are the model's; ")
    return (use + ' ' + honest + 'a filter run with this model will still see the structure '
            'left (its consistency tests will not pass).')
