"""
Conclusions, markdown text and report of the navigation benchmark.

Every sentence is computed from the numbers of the run (``nav_bench_runs``); the plots are
the position-error envelopes per profile.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from strapdown_ros.bench.nav_bench_runs import (ACCEL_RATE, earth_profile, FLOOR_RELATIVE,
                                                GYRO_RATE, HISTORY, SCULLING_TOLERANCE,
                                                STATIC_TARGET_M)
from strapdown_ros.bench.stats import median_range, stats
from strapdown_ros.cli import write_figure, write_text


def _e(x: float, digits: int = 2) -> str:
    return '—' if x is None or not math.isfinite(x) else f'{x:.{digits}e}'


def conclusions(res: dict) -> list[str]:
    """
    Return the conclusion sentences, each computed from the run's numbers.

    Parameters
    ----------
    res : dict
        The run's result.

    Returns
    -------
    list of str
        The sentences.

    """
    out = []
    nav = res.get('navigation', {})
    st = nav.get('static')
    if st:
        dur = st['2/exact']['duration']
        parts = []
        for key in ('2/exact', 'opp/exact', 'opp/exact/no_history'):
            s = st[key]
            parts.append(
                f"{s['label']}: final |δR| {s['final_position_m']:.2e} m (max"
                f" {s['max_position_m']:.2e} m)"
            )
        worst = max(st[k]['max_position_m']
                    for k in ('2/exact', 'opp/exact', 'opp/exact/no_history'))
        verdict = 'met' if worst < STATIC_TARGET_M else 'NOT met'
        scope = '' if abs(
            dur - 3600) < 1e-6 else f' (the target is stated for 3600 s; this run is {dur:g} s)'
        out.append(
            f"Static {dur:g} s, derived forms: {'; '.join(parts)} — target <"
            f' {STATIC_TARGET_M * 1e3:g} mm {verdict}{scope}. Printed 003:'
            f" {st['opp/printed']['final_position_m']:.2e} m."
        )
        rr = res.get('roundoff')
        if rr and len(rr) > 1:
            txt = ', '.join(f"block {r['block']}: {r['final_position_m']:.2e} m" for r in rr)
            f0, f1 = rr[0]['final_position_m'], min(r['final_position_m'] for r in rr[1:])
            if f0 > 2 * f1:
                out.append(
                    f'Round-off dominates the static error: coning 2, the same data fed in smaller'
                    f' blocks '
                    f"({txt}) — the navigator's cumulative increment sums are rebased once per"
                    ' block, so '
                    f'their rounding (a bias when the increments are constant) grows with the'
                    f' block.'
                )
            else:
                out.append(f'Block size does not change the static error materially ({txt}).')
    drift = {(r['profile'], r['step_s']): r for r in res.get('drift', [])}
    for alg, k_on, k_off, h in (('coning 2', '2/exact', '2/rotation_only', 0.02),
                                ('one+prev', 'opp/exact', 'opp/rotation_only', 0.01)):
        if 'sculling' not in nav:
            continue
        on = nav['sculling'][k_on]['final_position_m']
        off = nav['sculling'][k_off]['final_position_m']
        others = []
        for p in nav:
            if p == 'sculling':
                continue
            d = drift.get((p, h))
            ratio = nav[p][k_off]['final_position_m'] / max(nav[p][k_on]['final_position_m'],
                                                            1e-300)
            if d is not None and d['rotation_only'] <= d['float_floor']:
                others.append(
                    f"{p}: the rotation-only Δv drift ({d['rotation_only']:.1e} m/s²) is below the"
                    f' float floor, so the ratio {ratio:.2g}× is round-off'
                )
            elif d is not None:
                others.append(
                    f"{p}: {ratio:.3g}× (rotation-only Δv drift {d['rotation_only']:.2e} m/s², the"
                    ' omitted second-order rotation terms)'
                )
            else:
                others.append(f'{p}: {ratio:.3g}×')
        out.append(
            f'Sculling compensation ({alg}, h = {h:g} s): on the sculling profile the final |δR|'
            f' is {on:.3g} m with the exact Δv and {off:.3g} m with rotation only'
            f' ({off / on:.3g}×)'
            + (f"; rotation only ÷ exact elsewhere — {'; '.join(others)}." if others else '.')
        )
    vc = res.get('vertical_channel')
    if vc:
        tau = vc[0]['tau_s']
        good = [
            r for r in vc
            if abs(r['predicted_m']) > 0 and 0.8 <= r['measured_m'] / r['predicted_m'] <= 1.25
        ]
        rest = [r for r in vc if r not in good]
        other = ''
        if rest:
            ratios = ', '.join(f"{r['profile']} {r['key']} "
                               f"{r['measured_m'] / r['predicted_m']:.2g}" for r in rest)
            other = (f'; in the other {len(rest)} the measured vertical error (at most '
                     f"{max(abs(r['measured_m']) for r in rest):.1e} m) is not set by the Δv "
                     f'drift — measured ÷ predicted: {ratios}')
        out.append(
            f'Vertical channel (τ = √(R/2g) ≈ {tau:.0f} s): the Δv drift along up, amplified as '
            'δh = δa τ²(cosh(T/τ) − 1), predicts the final vertical error within 25 % in '
            f'{len(good)} of {len(vc)} runs ('
            + ', '.join(f"{r['profile']} {r['key']}" for r in good) + ')' + other + '.')
        sc_rows = [r for r in vc if r['profile'] == 'sculling' and r['key'].endswith('exact')]
        if sc_rows:
            wh = 2 * math.pi * earth_profile('sculling').parameters['frequency'] * 0.01
            out.append(
                'On the sculling profile even the exact Δv (the per-step model: linear rate,'
                ' quadratic specific force) drifts: '
                + ', '.join(f"{r['key']} {r['drift_up']:.2e} m/s²" for r in sc_rows)
                + " — the model's own error at wh ="
                f' {wh:.2f} (h = 0.01 s), not the sculling term.'
            )
    if nav:
        ratios = [(p, d['opp/printed']['final_position_m'] /
                   max(d['opp/exact']['final_position_m'], 1e-300)) for p, d in nav.items()]
        form_ratios = [(p, d['opp/printed_form']['final_position_m'] /
                        max(d['opp/series']['final_position_m'], 1e-300)) for p, d in nav.items()]
        worse = [p for p, r in ratios if r > 1]
        harmless = [p for p, r in form_ratios if r < 1.1]
        out.append(
            'Printed 003 (printed coefficients + printed recursion) ÷ derived (exact Δv + exact'
            ' recursion), final |δR|: '
            + ', '.join(f'{p} {r:.3g}×' for p, r in ratios)
            + f' — printed is worse on {len(worse)} of {len(ratios)} profiles. The printed'
            ' coefficients alone (in the exact recursion) ÷ the series with the derived'
            ' coefficients: '
            + ', '.join(f'{p} {r:.3g}×' for p, r in form_ratios)
            + '.'
            + (
                f" Where that ratio is near 1 ({', '.join(harmless)}) the printed recursion"
                ' (first-order Coriolis and gravity) makes the whole difference.'
                if harmless
                else ''
            )
        )
        ser = [(p, abs(d['opp/series']['final_position_m'] - d['opp/exact']['final_position_m']),
                d['opp/exact']['final_position_m']) for p, d in nav.items()]
        out.append(
            'The 003 series with the derived coefficients against the exact Δv (its expansion),'
            ' difference of the final |δR|: '
            + ', '.join(f'{p} {a:.1e} m of {b:.1e} m' for p, a, b in ser)
            + '.'
        )
        start = [(p, d['opp/exact/no_history']['final_position_m'],
                  d['opp/exact']['final_position_m']) for p, d in nav.items()]
        out.append(
            "Start-up of one+prev: without sensor data before t0 the navigator's first step"
            f" continues the first sample's rate backwards; final |δR| without → with {HISTORY}"
            ' periods of history: '
            + ', '.join(
                f'{p} {a:.2e} → {b:.2e} m ({a / max(b, 1e-300):.3g}×)' for p, a, b in start
            )
            + '.'
        )
        cmp_ = [(p, d['2/exact']['final_position_m'], d['opp/exact']['final_position_m'])
                for p, d in nav.items()]
        out.append(
            'Coning 2 (h = 0.02 s) against one+prev with history (h = 0.01 s), exact Δv, final'
            ' |δR|: '
            + ', '.join(f'{p} {a:.2e} m vs {b:.2e} m' for p, a, b in cmp_)
            + '.'
        )
    sc = res.get('sculling_check')
    if sc:
        ok = sum(r['within_tolerance'] for r in sc)
        odd = [r['ratio_odd'] for r in sc]
        ev = [r['ratio_even'] for r in sc if 'ratio_even' in r['checked']]
        be = [r['ratio_b_eff'] for r in sc]
        out.append(
            f'Sculling check: {ok} of {len(sc)} cases within {SCULLING_TOLERANCE * 100:g} % '
            f"({'met' if ok == len(sc) else 'NOT met'}). The drift odd in B is"
            f' {min(odd):.5f}–{max(odd):.5f} × '
            f'½AB(1 − sin wh/wh) with B the acceleration amplitude; the part even in B is '
            f'{min(ev):.5f}–{max(ev):.5f} × the gravity term ½gA²(sin wh/wh − ½(1 + cos wh)). '
            f"With trajectories' effective amplitude B + A·g in the formula the measured drift is"
            f' only '
            f'{min(be):.3f}–{max(be):.3f} of it: A·g is not the B of the formula in either frame '
            f"(body-axis drift ÷ formula with B: {min(r['ratio_body'] for r in sc):.5f}–"
            f"{max(r['ratio_body'] for r in sc):.5f})."
        )
    tm = res.get('timing')
    if tm:
        a = stats([r['wall_s'] for r in tm['algorithms']['2']])
        out.append(
            f"Run time: {tm['seconds']:g} s of 100 Hz gyro + 300 Hz accelerometer data through"
            f" attitude, navigation and both covariances takes {a['median']:.2f} s with coning 2"
            f" ({tm['seconds'] / a['median']:.0f}× real time; load {tm['load_at_start'][0]:.2f} at"
            ' the start).'
        )
    return out


def render(res: dict, argv) -> str:
    """
    Render the markdown text of the run (printed on stdout and put in the report).

    Parameters
    ----------
    res : dict
        The run's result, with its conclusions.
    argv : list of str
        The command line, quoted in the text.

    Returns
    -------
    str
        The markdown.

    """
    L = [
        f"$ nav_bench {' '.join(argv)}".rstrip(),
        '',
        (
            f"load average at start {res['load_at_start'][0]:.2f} {res['load_at_start'][1]:.2f}"
            f" {res['load_at_start'][2]:.2f} on {res['cpu_count']} cores; gyro {GYRO_RATE:g} Hz,"
            f' accelerometer {ACCEL_RATE:g} Hz, perfect sensors, errors against the exact truth;'
            f" block {res['settings']['block']} gyro intervals"
        ),
    ]
    nav = res.get('navigation', {})
    if nav:
        L += [
            '',
            '## Navigation errors',
            '',
            (
                '| profile | configuration | final \\|δR\\|, m | max \\|δR\\|, m | final \\|δW\\|,'
                ' m/s | max \\|δW\\|, m/s | final vertical, m | final attitude, rad | wall, s |'
            ),
            '|---|---|---:|---:|---:|---:|---:|---:|---:|',
        ]
        for p, d in nav.items():
            for key, s in d.items():
                L.append(
                    f"| {p} {s['duration']:g} s | {s['label']} | {_e(s['final_position_m'])} |"
                    f" {_e(s['max_position_m'])} | {_e(s['final_velocity_m_s'])} |"
                    f" {_e(s['max_velocity_m_s'])} | {_e(s['final_vertical_m'])} |"
                    f" {_e(s['final_attitude_rad'])} | {s['wall_s']:.2f} |"
                )
    rr = res.get('roundoff')
    if rr:
        L += [
            '',
            '## Round-off: static, coning 2, exact Δv, fed in blocks of different size',
            '',
            (
                '| block, gyro intervals | final \\|δR\\|, m | final vertical, m | final \\|δW\\|,'
                ' m/s |'
            ),
            '|---:|---:|---:|---:|',
        ]
        for r in rr:
            L.append(
                f"| {r['block']} | {_e(r['final_position_m'])} | {_e(r['final_vertical_m'])} | "
                f"{_e(r['final_velocity_m_s'])} |")
    sc = res.get('sculling_check')
    if sc:
        L += [
            '',
            f'## Sculling check: drift of the rotation-only Δv (m/s², along up, E frame), '
            f"{res['settings']['drift_seconds']:g} s each",
            '',
            (
                'A = angle amplitude, B = acceleration amplitude (±B runs give the odd and even'
                ' parts); formula = −½AB(1 − sin wh/wh) (`sculling_drift_rate`, sign: velocity'
                ' error along up); gravity = ½gA²(sin wh/wh − ½(1 + cos wh)).'
            ),
            '',
            (
                '| f, Hz | h, s | wh | measured | odd in B | formula | ratio | even in B | gravity'
                ' | ratio | measured ÷ (formula + gravity) | measured ÷ formula(B + A·g) | body z'
                ' ÷ formula | ok |'
            ),
            '|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|:---:|',
        ]
        for r in sc:
            L.append(
                f"| {r['frequency_hz']:g} | {r['step_s']:g} | {r['wh']:.3f} |"
                f" {_e(r['measured_up'], 4)} | {_e(r['odd'], 4)} | {_e(r['classical'], 4)} |"
                f" {r['ratio_odd']:.5f} | {_e(r['even'], 3)} | {_e(r['gravity_term'], 3)} |"
                f" {r['ratio_even']:.5f} | {r['ratio_total']:.5f} | {r['ratio_b_eff']:.4f} |"
                f" {r['ratio_body']:.5f} | {'yes' if r['within_tolerance'] else 'NO'} |"
            )
    dr = res.get('drift')
    if dr:
        L += [
            '', f'## Specific-force drift per profile (|slope| in E, m/s²; float floor '
            f"{FLOOR_RELATIVE:g} × mean specific force), {res['settings']['drift_seconds']:g} s",
            '', '| profile | h, s | rotation only | exact Δv | floor |',
            '|---|---:|---:|---:|---:|'
        ]
        for r in dr:
            L.append(
                f"| {r['profile']} | {r['step_s']:g} | {_e(r['rotation_only'])} | {_e(r['exact'])}"
                f" | {_e(r['float_floor'], 1)} |"
            )
    vc = res.get('vertical_channel')
    if vc:
        L += [
            '',
            (
                '## Vertical channel: the Δv drift along up (table above, sign kept) against the'
                ' final vertical error'
            ),
            '',
            (
                'predicted δh = δa τ²(cosh(T/τ) − 1), τ = √(R/2g): a constant drift from t0, no'
                ' other error'
            ),
            '',
            (
                '| profile | configuration | drift along up, m/s² | predicted vertical, m |'
                ' measured vertical, m |'
            ),
            '|---|---|---:|---:|---:|',
        ]
        for r in vc:
            L.append(
                f"| {r['profile']} {r['duration']:g} s | {r['label']} | {_e(r['drift_up'])} | "
                f"{_e(r['predicted_m'])} | {_e(r['measured_m'])} |")
    tm = res.get('timing')
    if tm:
        L += [
            '',
            (
                f"## Run time: {tm['seconds']:g} s of data ({tm['gyro_intervals']} gyro +"
                f" {tm['accel_intervals']} accelerometer intervals), attitude + navigation +"
                ' covariances'
            ),
            '',
            (
                f"median (min–max) of {tm['runs']} runs; load average at the start"
                f" {tm['load_at_start'][0]:.2f} {tm['load_at_start'][1]:.2f}"
                f" {tm['load_at_start'][2]:.2f}; data generation not timed; absolute times vary"
                ' from machine to machine'
            ),
            '',
            '| algorithm | wall, s | × real time | ns per gyro interval |',
            '|---|---:|---:|---:|',
        ]
        for alg, runs in tm['algorithms'].items():
            L.append(f"| {alg} | {median_range(stats([r['wall_s'] for r in runs]), '.3f')} | "
                     f"{median_range(stats([r['real_time_ratio'] for r in runs]), '.0f')} | "
                     f"{median_range(stats([r['ns_per_gyro_interval'] for r in runs]), '.0f')} |")
    L += ['', '## Conclusions', ''] + [f'* {c}' for c in res['conclusions']]
    return '\n'.join(L)


def write_report(outdir: str, res: dict, series: dict, text: str) -> str:
    """
    Write ``nav_bench.md`` and the position-error plots into a directory.

    Parameters
    ----------
    outdir : str
        Directory (created).
    res : dict
        The run's result.
    series : dict
        Profile → configuration → (t, |δR|) of ``navigation_runs``.
    text : str
        The markdown of ``render``.

    Returns
    -------
    str
        Path of the report.

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    d = Path(outdir)
    d.mkdir(parents=True, exist_ok=True)
    plots = []
    for name, runs in series.items():
        fig, ax = plt.subplots(figsize=(9, 5))
        for i, (key, (t, y)) in enumerate(runs.items()):
            label = res['navigation'][name][key]['label']
            style = '--' if 'printed' in key else ('-.' if 'rotation_only' in key else '-')
            ax.semilogy(t, np.maximum(y, 1e-12), style, lw=1.2, label=label, color=f'C{i}')
        ax.set_xlabel('time, s')
        ax.set_ylabel('|δR|, m (envelope, floor 1e-12)')
        ax.set_title(f'{name}: position error against exact truth, perfect sensors')
        ax.grid(True, which='both', alpha=0.3)
        ax.legend(fontsize=7, loc='best')
        fig.tight_layout()
        fn = f'position_error_{name}.png'
        write_figure(fig, d / fn, dpi=110)
        plt.close(fig)
        plots.append((name, fn))
    md = [
        '# nav_bench', '',
        'Generated by `nav_bench` (strapdown_ros/bench/nav_bench.py); every sentence below is '
        'computed from the numbers.', '', '```', res['settings']['command'], '```', '',
        text.split('\n', 2)[2] if text.count('\n') >= 2 else text, '', '## Plots', ''
    ]
    for name, fn in plots:
        md += [f'![{name}]({fn})', '']
    path = d / 'nav_bench.md'
    write_text(path, '\n'.join(md))
    return str(path)
