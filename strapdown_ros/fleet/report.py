"""
The fleet report: the effects table, the changes, the population, plots and a summary.

Written into the fleet's directory by :func:`write_report` (every file atomically):

* ``effects.csv`` and ``effects.parquet``: one row per recording, effect and component —
  ``unit, recording, start_time, effect, parameter, index, value, sigma, verdict`` (registry
  names, SI units; the boresight is effect ``boresight``, parameter ``boresight``, index 0–2
  = ψ, ϑ, γ in rad; ``verdict`` is the recording's); a recording that failed is one row with
  effect ``error`` and verdict ``error`` (its reason in ``recordings.csv``);
* ``recordings.csv``: one row per recording — status, verdict, the reason of an error, whether
  it was analysed in this run or taken from the cache, what the analyses found, time, memory;
* ``changes.csv``: one row per change detected — ``unit, effect, parameter, index, recording,
  kind, size, sigma, p_value`` (:mod:`strapdown_ros.fleet.changes`);
* ``population.csv``: per effect component — units, median, spread, outlier units;
* ``trend_<effect>.png`` (each unit's series with ±σ error bars, changes marked),
  ``population_<effect>.png`` (histograms of the units' latest values), ``verdicts.png``
  (unit × recording map of verdicts);
* ``summary.md``: every sentence computed from the numbers above.
"""
from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os

import numpy as np

from strapdown_ros.cli import write_text
from strapdown_ros.files import atomic_savefig, atomic_write_bytes
from strapdown_ros.fleet.analysis import VERDICTS
from strapdown_ros.fleet.changes import OUTLIER_Z
from strapdown_ros.sensors.effects import EFFECTS

__all__ = ['write_report', 'EFFECT_COLUMNS', 'CHANGE_COLUMNS', 'RECORDING_COLUMNS',
           'POPULATION_COLUMNS', 'REPORT_FILES', 'effect_table', 'latest_rows', 'display_scale',
           'MAX_UNITS_PLOTTED']

EFFECT_COLUMNS = ('unit', 'recording', 'start_time', 'effect', 'parameter', 'index', 'value',
                  'sigma', 'verdict')
CHANGE_COLUMNS = ('unit', 'effect', 'parameter', 'index', 'recording', 'kind', 'size', 'sigma',
                  'p_value')
RECORDING_COLUMNS = ('unit', 'recording', 'start_time', 'status', 'verdict', 'reason',
                     'analysed', 'found', 'gyro_messages', 'camera_fixes', 'duration_s',
                     'seconds', 'peak_rss_mib', 'hash')
POPULATION_COLUMNS = ('effect', 'parameter', 'index', 'units', 'median', 'spread',
                      'repeatability', 'outlier_units')
#: the report's files of fixed name (the plots are named after the effects)
REPORT_FILES = ('effects.csv', 'effects.parquet', 'recordings.csv', 'changes.csv',
                'population.csv', 'verdicts.png', 'summary.md', 'fleet.json')
#: units drawn in one trend plot (the flagged ones first); the others are counted in its title
MAX_UNITS_PLOTTED = 12
#: units drawn in the verdict map
MAX_UNITS_MAPPED = 60
VERDICT_COLOURS = {'model_adequate': '#4caf50', 'explained': '#ffc107',
                   'unexplained_structure': '#e53935', 'unobservable': '#9e9e9e',
                   'error': '#212121'}
ARCSEC = 180.0 / math.pi * 3600.0


def display_scale(effect: str, parameter: str) -> tuple[float, str]:
    """
    Return the factor and unit a value of an effect parameter is shown in.

    Parameters
    ----------
    effect : str
        Registry effect name (or ``boresight``).
    parameter : str
        Its parameter.

    Returns
    -------
    (float, str)
        SI value × factor = shown value; e.g. rad → ″, rad/s → °/h, 1 → ppm.

    """
    unit = 'rad'
    if effect in EFFECTS:
        unit = next((p.unit for p in EFFECTS[effect].parameters if p.name == parameter), '')
    return {'rad': (ARCSEC, '″'), 'rad/s': (ARCSEC, '°/h'), '1': (1e6, 'ppm'),
            'rad/s²': (ARCSEC, '°/h/s'), 's': (1e3, 'ms')}.get(unit, (1.0, unit))


def _name(effect: str, parameter: str, index) -> str:
    return f'{parameter}[{index}]' if effect == parameter else f'{effect} {parameter}[{index}]'


def _level_text(effect: str, parameter: str, x: float) -> str:
    """Show a value: angles of a degree or more in degrees, the rest by display_scale."""
    scale, unit = display_scale(effect, parameter)
    if unit == '″' and abs(x) * scale >= 3600.0:
        return f'{x * 180.0 / math.pi:.6f}°'
    return f'{x * scale:.4g} {unit}'


def _fmt(x) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return ''
    if isinstance(x, float):
        return f'{x:.10g}'
    return str(x)


def _csv(columns, rows) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator='\n')
    w.writerow(columns)
    for r in rows:
        w.writerow([_fmt(r.get(c)) for c in columns])
    return buf.getvalue()


def effect_table(entries, results: dict) -> list[dict]:
    """
    Return the rows of the effects table, sorted by unit, effect, parameter, index, time.

    Parameters
    ----------
    entries : list of FleetEntry
        The manifest.
    results : dict
        Entry path → the record of :func:`strapdown_ros.fleet.analysis.analyse_recording`.

    Returns
    -------
    list of dict
        :data:`EFFECT_COLUMNS`, and ``t_days`` (days since the fleet's first recording).

    """
    t0 = min((e.start_time for e in entries), default=None)
    rows = []
    for e in entries:
        r = results[e.path]
        base = {'unit': e.unit, 'recording': e.recording, 'start_time': e.start_iso,
                't_days': (e.start_time - t0).total_seconds() / 86400.0,
                'verdict': r.get('verdict') or 'error'}
        if r.get('status') != 'ok':
            rows.append({**base, 'effect': 'error', 'parameter': '', 'index': None,
                         'value': float('nan'), 'sigma': float('nan'), 'verdict': 'error'})
            continue
        for x in r.get('effects', []):
            rows.append({**base, 'effect': x['effect'], 'parameter': x['parameter'],
                         'index': int(x['index']), 'value': float(x['value']),
                         'sigma': float(x['sigma'])})
    rows.sort(key=lambda x: (x['unit'], x['effect'], x['parameter'],
                             -1 if x['index'] is None else x['index'], x['t_days']))
    return rows


def _parquet(rows) -> bytes:
    import pyarrow as pa                                    # optional extra (fleet)
    import pyarrow.parquet as pq
    cols = {c: [r.get(c) for r in rows] for c in EFFECT_COLUMNS}
    table = pa.table({
        'unit': pa.array(cols['unit'], pa.string()),
        'recording': pa.array(cols['recording'], pa.string()),
        'start_time': pa.array(cols['start_time'], pa.string()),
        'effect': pa.array(cols['effect'], pa.string()),
        'parameter': pa.array(cols['parameter'], pa.string()),
        'index': pa.array(cols['index'], pa.int64()),
        'value': pa.array(cols['value'], pa.float64()),
        'sigma': pa.array(cols['sigma'], pa.float64()),
        'verdict': pa.array(cols['verdict'], pa.string())})
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink)
    return sink.getvalue().to_pybytes()


def _recording_rows(entries, results, analysed_now) -> list[dict]:
    out = []
    for e in entries:
        r = results[e.path]
        mem = (r.get('memory') or {}).get('peak_rss_bytes')
        msgs = r.get('messages') or {}
        out.append({'unit': e.unit, 'recording': e.recording, 'start_time': e.start_iso,
                    'status': r.get('status'), 'verdict': r.get('verdict') or 'error',
                    'reason': r.get('reason', ''),
                    'analysed': 'now' if e.path in analysed_now else 'cached',
                    'found': ';'.join((r.get('discrepancy') or {}).get('found', [])),
                    'gyro_messages': msgs.get('gyro'), 'camera_fixes': msgs.get('camera'),
                    'duration_s': r.get('duration_s'),
                    'seconds': (r.get('seconds') or {}).get('total'),
                    'peak_rss_mib': None if mem is None else mem / 2 ** 20,
                    'hash': r.get('hash', '')})
    return out


def latest_rows(rows) -> list[dict]:
    """
    Return each unit's latest row of each effect component.

    Parameters
    ----------
    rows : list of dict
        The effects table (:func:`effect_table`).

    Returns
    -------
    list of dict
        One row per unit and component.

    """
    last: dict = {}
    for r in rows:
        if r['effect'] == 'error':
            continue
        key = (r['unit'], r['effect'], r['parameter'], r['index'])
        if key not in last or r['t_days'] >= last[key]['t_days']:
            last[key] = r
    return list(last.values())


# ----------------------------------------------------------------------------- plots
def _save(fig, out_dir, name: str) -> str:
    """Write and close a figure (its layout set by the caller: tight_layout costs seconds)."""
    import matplotlib.pyplot as plt
    path = os.path.join(out_dir, name)
    atomic_savefig(fig, path, dpi=90)
    plt.close(fig)
    return path


def _distinct_components(rows, effect) -> list:
    """Return an effect's (parameter, index), less those equal to an earlier one throughout."""
    series: dict = {}
    for r in rows:
        if r['effect'] == effect:
            series.setdefault((r['parameter'], r['index']), []).append(
                (r['unit'], r['recording'], r['value']))
    out, seen = [], []
    for key in sorted(series):
        values = sorted(series[key])
        if values in seen:
            continue
        seen.append(values)
        out.append(key)
    return out


def _grid(n: int, width: float, height: float):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    ncol = min(3, n)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(width * ncol, height * nrow + 0.6),
                             squeeze=False)
    fig.subplots_adjust(left=0.09, right=0.98, bottom=0.14 / nrow + 0.04,
                        top=1.0 - 0.55 / (height * nrow + 0.6), wspace=0.32, hspace=0.55)
    return fig, axes


def _units_to_plot(units, flagged) -> tuple[list, int]:
    order = sorted(units, key=lambda u: (u not in flagged, u))
    return order[:MAX_UNITS_PLOTTED], max(0, len(order) - MAX_UNITS_PLOTTED)


def _trend_plots(out_dir, rows, changes, flagged) -> list[str]:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    paths = []
    effects = sorted({r['effect'] for r in rows if r['effect'] != 'error'})
    for effect in effects:
        er = [r for r in rows if r['effect'] == effect]
        comps = _distinct_components(rows, effect)
        units, hidden = _units_to_plot({r['unit'] for r in er}, flagged)
        fig, axes = _grid(len(comps), 4.6, 3.0)
        colours = plt.cm.tab10(np.linspace(0, 1, 10))
        for ax, (param, idx) in zip(axes.ravel(), comps):
            scale, unit = display_scale(effect, param)
            for k, u in enumerate(units):
                ur = sorted((r for r in er if r['unit'] == u and r['parameter'] == param
                             and r['index'] == idx), key=lambda r: r['t_days'])
                if not ur:
                    continue
                t = np.array([r['t_days'] for r in ur])
                x = np.array([r['value'] for r in ur])
                s = np.array([r['sigma'] for r in ur])
                ref = float(np.median(x))
                c = colours[k % 10]
                ax.errorbar(t, (x - ref) * scale, yerr=s * scale, fmt='o-', ms=3, lw=0.8,
                            capsize=2, color=c, label=u)
                times = {r['recording']: r['t_days'] for r in ur}
                for ch in changes:
                    if (ch.unit, ch.effect, ch.parameter, ch.index) != (u, effect, param, idx):
                        continue
                    if ch.kind == 'jump' and ch.recording in times:
                        ax.axvline(times[ch.recording], color=c, ls='--', lw=0.8)
                    elif ch.kind == 'trend' and ch.start in times:
                        ta = np.array([times[ch.start], times[ch.recording]])
                        mid = x[(t >= ta[0]) & (t <= ta[1])]
                        tm = t[(t >= ta[0]) & (t <= ta[1])]
                        y0 = float(np.mean(mid) - ch.size * np.mean(tm))
                        ax.plot(ta, (y0 + ch.size * ta - ref) * scale, color=c, lw=2,
                                alpha=0.5)
            ax.set_title(f'{param}[{idx}]', fontsize=9)
            ax.set_xlabel('days since the first recording', fontsize=8)
            ax.set_ylabel(f"value − unit's median, {unit}", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.grid(alpha=0.3)
        for ax in axes.ravel()[len(comps):]:
            ax.axis('off')
        axes.ravel()[0].legend(fontsize=7, loc='best')
        more = f' ({hidden} more units not drawn)' if hidden else ''
        fig.suptitle(f'{effect}: each unit over time, ±1σ; dashed: jump, thick: trend{more}',
                     fontsize=10)
        paths.append(_save(fig, out_dir, f'trend_{effect}.png'))
    return paths


def _population_plots(out_dir, latest, pop) -> list[str]:
    paths = []
    by_effect: dict = {}
    for p in pop:
        by_effect.setdefault(p['effect'], []).append(p)
    for effect, comps in sorted(by_effect.items()):
        keep = set(_distinct_components(latest, effect))
        comps = [p for p in comps if (p['parameter'], p['index']) in keep]
        fig, axes = _grid(len(comps), 4.2, 2.8)
        for ax, p in zip(axes.ravel(), comps):
            scale, unit = display_scale(effect, p['parameter'])
            vals = [r for r in latest if (r['effect'], r['parameter'], r['index'])
                    == (effect, p['parameter'], p['index'])]
            x = (np.array([r['value'] for r in vals]) - p['median']) * scale
            ax.hist(x, bins=max(5, min(40, len(x) // 2)), color='#90a4ae')
            ax.axvline(0.0, color='k', lw=1, label='median')
            for r in vals:
                if r['unit'] in p['outlier_units']:
                    ax.axvline((r['value'] - p['median']) * scale, color='#e53935', ls='--',
                               lw=1)
            ax.set_title(f"{_name(effect, p['parameter'], p['index'])}: {p['units']} units, "
                         f"{len(p['outlier_units'])} outlier(s)", fontsize=9)
            ax.set_xlabel(f"value − median ({_level_text(effect, p['parameter'], p['median'])})"
                          f', {unit}', fontsize=8)
            ax.set_ylabel('units', fontsize=8)
            ax.tick_params(labelsize=7)
        for ax in axes.ravel()[len(comps):]:
            ax.axis('off')
        fig.suptitle(f"{effect}: each unit's latest value; black: median, red dashed: outlier "
                     f'(modified z > {OUTLIER_Z:g})', fontsize=10)
        paths.append(_save(fig, out_dir, f'population_{effect}.png'))
    return paths


def _verdict_map(out_dir, entries, results) -> str:
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch
    import matplotlib.pyplot as plt
    units = sorted({e.unit for e in entries})
    shown = units[:MAX_UNITS_MAPPED]
    per_unit = {u: [e for e in entries if e.unit == u] for u in shown}
    width = max((len(v) for v in per_unit.values()), default=1)
    grid = np.full((len(shown), width), np.nan)
    for i, u in enumerate(shown):
        for j, e in enumerate(per_unit[u]):
            grid[i, j] = VERDICTS.index(results[e.path].get('verdict') or 'error')
    cmap = ListedColormap([VERDICT_COLOURS[v] for v in VERDICTS])
    fig, ax = plt.subplots(figsize=(min(16, 4 + 0.45 * width), min(14, 1.5 + 0.3 * len(shown))))
    fig.subplots_adjust(left=0.12, right=0.70, bottom=0.15, top=0.88)
    ax.imshow(np.ma.masked_invalid(grid), cmap=cmap, vmin=-0.5, vmax=len(VERDICTS) - 0.5,
              aspect='auto', interpolation='nearest')
    ax.set_yticks(range(len(shown)))
    ax.set_yticklabels(shown, fontsize=8)
    ax.set_xticks(range(width))
    ax.set_xticklabels([str(k + 1) for k in range(width)], fontsize=8)
    ax.set_xlabel("the unit's recordings in start-time order", fontsize=9)
    more = f'; {len(units) - len(shown)} more units not drawn' if len(units) > len(shown) else ''
    ax.set_title(f'verdict of each recording{more}', fontsize=10)
    ax.legend(handles=[Patch(color=VERDICT_COLOURS[v], label=v) for v in VERDICTS],
              fontsize=7, loc='upper left', bbox_to_anchor=(1.01, 1.0))
    return _save(fig, out_dir, 'verdicts.png')


# ----------------------------------------------------------------------------- summary
def _summary(entries, results, changes, tests, pop, analysed_now, run_info) -> str:
    units = sorted({e.unit for e in entries})
    n = len(entries)
    errors = [e for e in entries if results[e.path].get('status') != 'ok']
    counts = {v: sum(1 for e in entries if (results[e.path].get('verdict') or 'error') == v)
              for v in VERDICTS}
    lines = ['# Fleet report', '']
    if n:
        first = min(entries, key=lambda e: e.start_time).start_iso
        last = max(entries, key=lambda e: e.start_time).start_iso
        lines.append(f'{len(units)} unit(s), {n} recording(s), from {first} to '
                     f'{last}.  This run analysed {len(analysed_now)} recording(s) '
                     f'(new or changed) and took {n - len(analysed_now)} from the cache; '
                     f'{len(errors)} recording(s) failed.')
    else:
        lines.append('The manifest names no recording.')
    lines += ['', '## Verdicts', '',
              'Per recording (the discrepancy workflow at family-wise level '
              f"{run_info.get('alpha', 0.01):g}): "
              + ', '.join(f'{counts[v]} {v}' for v in VERDICTS) + '.', '']
    lines += ['## Changes between recordings', '',
              f"{tests['series']} series (unit × effect × component with two recordings or more) "
              f"were tested against a constant at family-wise level {tests['level']:g}: a jump "
              'between consecutive recordings (scanned over the splits, Bonferroni) or a trend '
              '(weighted line), Holm step-down over all series.  '
              + _tau_text(tests.get('repeatability') or {})
              + (f'{len(changes)} change(s) found:' if changes else 'No change was found.'), '']
    for c in changes:
        scale, unit = display_scale(c.effect, c.parameter)
        if c.kind == 'jump':
            what, per, where = 'jumps by', '', f'at recording {c.recording}'
        else:
            what, per, where = 'drifts by', '/day', f'from {c.start} to {c.recording}'
        lines.append(f'* unit {c.unit}: {_name(c.effect, c.parameter, c.index)} {what} '
                     f'{c.size * scale:+.4g} ± {c.sigma * scale:.2g} {unit}{per} (1σ) {where}; '
                     f'adjusted p = {c.p_value:.3g}.')
    flagged = _flagged(entries, results, changes)
    lines += ['', '## Units flagged', '']
    if flagged:
        lines.append(f'{len(flagged)} of {len(units)} unit(s) need attention:')
        lines.append('')
        for u, why in sorted(flagged.items()):
            lines.append(f"* {u}: {'; '.join(why)}.")
    else:
        lines.append(f'None of the {len(units)} unit(s): no change, and every latest recording '
                     'is model_adequate.')
    lines += ['', '## Population', '',
              "Each unit's latest value per effect component: median, spread (1.4826 × MAD), the "
              'repeatability τ between recordings and the outlier units (modified z > '
              f'{OUTLIER_Z:g}, judged with three units or more).', '',
              '| effect | parameter | index | units | median | spread | repeatability τ | '
              'outliers |', '|---|---|---|---|---|---|---|---|']
    for p in pop:
        scale, unit = display_scale(p['effect'], p['parameter'])
        lines.append(f"| {p['effect']} | {p['parameter']} | {p['index']} | {p['units']} | "
                     f"{_level_text(p['effect'], p['parameter'], p['median'])} | "
                     f"{p['spread'] * scale:.3g} {unit} | {p['repeatability'] * scale:.3g} "
                     f"{unit} | {', '.join(p['outlier_units']) or 'none'} |")
    if errors:
        lines += ['', '## Errors', '', f'{len(errors)} recording(s) could not be analysed:', '']
        for e in errors:
            lines.append(f"* {e.unit} {e.recording}: {results[e.path].get('reason', '')}")
    secs = [results[e.path].get('seconds', {}).get('total') for e in entries
            if e.path in analysed_now and results[e.path].get('status') == 'ok']
    secs = [s for s in secs if s is not None]
    lines += ['', '## This run', '']
    where = run_info.get('scheduler') or f"a LocalCluster of {run_info.get('workers')} worker(s)"
    text = (f"{len(analysed_now)} task(s) on {where} in {run_info.get('wall_s', 0.0):.1f} s "
            f"(memory limit {run_info.get('memory_mib', 0):g} MiB per worker, one task at a "
            'time)')
    if secs:
        text += (f'; a recording took {np.median(secs):.2f} s (median; min {min(secs):.2f}, '
                 f'max {max(secs):.2f}) inside its task')
    lines.append(text + '.')
    return '\n'.join(lines) + '\n'


def _tau_text(tau: dict) -> str:
    wide = {k: v for k, v in tau.items() if v > 0}
    if not wide:
        return ('The per-recording σ account for the scatter between recordings of every '
                'component (repeatability τ = 0).  ')
    shown = ', '.join(f'{_name(*k)} τ = {v * display_scale(k[0], k[1])[0]:.3g} '
                      f'{display_scale(k[0], k[1])[1]}' for k, v in sorted(wide.items())[:6])
    more = f' and {len(wide) - 6} more' if len(wide) > 6 else ''
    return (f'{len(wide)} component(s) scatter between recordings beyond their σ; their σ were '
            f'widened by the repeatability τ in quadrature ({shown}{more}).  ')


def _flagged(entries, results, changes) -> dict:
    why: dict = {}
    for c in changes:
        why.setdefault(c.unit, []).append(f'{c.kind} of {_name(c.effect, c.parameter, c.index)}'
                                          f' at {c.recording}')
    last: dict = {}
    for e in entries:
        if e.unit not in last or e.start_time >= last[e.unit].start_time:
            last[e.unit] = e
    for u, e in last.items():
        v = results[e.path].get('verdict') or 'error'
        if v != 'model_adequate':
            why.setdefault(u, []).append(f'latest recording {e.recording}: {v}')
    return why


def _key(*parts) -> str:
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()


def write_report(out_dir, entries, results, rows, changes, tests, pop, analysed_now,
                 run_info, previous: dict | None = None) -> tuple[list[str], dict]:
    """
    Write the tables, plots and summary of a fleet run.

    The effects table and the plots are rewritten only when what they show changed (a rerun of
    an unchanged fleet rewrites the summary and ``recordings.csv``, not the PNGs).

    Parameters
    ----------
    out_dir : str or Path
        The fleet's directory.
    entries : list of FleetEntry
        The manifest.
    results : dict
        Entry path → record.
    rows : list of dict
        The effects table (:func:`effect_table`).
    changes : list of Change
        The changes detected.
    tests : dict
        What the change test tested (:func:`strapdown_ros.fleet.changes.detect_changes`).
    pop : list of dict
        The population (:func:`strapdown_ros.fleet.changes.population`).
    analysed_now : set of str
        Entry paths analysed in this run.
    run_info : dict
        ``scheduler``, ``workers``, ``memory_mib``, ``wall_s``, ``alpha``.
    previous : dict, optional
        The keys this function returned for the directory's last report.

    Returns
    -------
    files : list of str
        The report's files.
    keys : dict
        What the effects table and the plots showed (for the next run's ``previous``).

    """
    out_dir = str(out_dir)
    previous = previous or {}
    paths = []
    effects_text = _csv(EFFECT_COLUMNS, rows)
    keys = {'effects': _key(effects_text)}
    p, pq = os.path.join(out_dir, 'effects.csv'), os.path.join(out_dir, 'effects.parquet')
    if previous.get('effects') != keys['effects'] or not (os.path.isfile(p)
                                                          and os.path.isfile(pq)):
        write_text(p, effects_text)
        atomic_write_bytes(pq, _parquet(rows))
    paths += [p, pq]
    p = os.path.join(out_dir, 'recordings.csv')
    write_text(p, _csv(RECORDING_COLUMNS, _recording_rows(entries, results, analysed_now)))
    paths.append(p)
    change_rows = [c.__dict__ for c in changes]
    p = os.path.join(out_dir, 'changes.csv')
    write_text(p, _csv(CHANGE_COLUMNS, change_rows))
    paths.append(p)
    latest = latest_rows(rows)
    p = os.path.join(out_dir, 'population.csv')
    write_text(p, _csv(POPULATION_COLUMNS, [{**q, 'outlier_units': ';'.join(q['outlier_units'])}
                                            for q in pop]))
    paths.append(p)
    flagged = set(_flagged(entries, results, changes))
    verdicts = [(e.unit, e.recording, results[e.path].get('verdict')) for e in entries]
    keys['plots'] = _key(effects_text, change_rows, pop, verdicts, sorted(flagged))
    old = [os.path.join(out_dir, n) for n in previous.get('plot_files', [])]
    if keys['plots'] == previous.get('plots') and old and all(os.path.isfile(f) for f in old):
        plots = old
    else:
        plots = _trend_plots(out_dir, rows, changes, flagged)
        plots += _population_plots(out_dir, latest, pop)
        if entries:
            plots.append(_verdict_map(out_dir, entries, results))
        for f in set(old) - set(plots):                 # an effect no longer in the fleet
            if os.path.isfile(f):
                os.unlink(f)
    keys['plot_files'] = [os.path.basename(f) for f in plots]
    paths += plots
    p = os.path.join(out_dir, 'summary.md')
    write_text(p, _summary(entries, results, changes, tests, pop, analysed_now, run_info))
    paths.append(p)
    return paths, keys
