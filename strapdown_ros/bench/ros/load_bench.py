"""
Run the full node graph at 10× the nominal sensor rates, on loopback, for 10 minutes.

The command ``load_bench``; the graph and its monitor are in ``load_graph``.

``imu_sim_node`` (gyro 1000 Hz, accelerometer 3000 Hz), ``star_camera_sim_node`` (a fix every
2 s), ``sins_node`` and ``calibrator_node`` run as separate processes in real time; a monitor
in this process measures (see :mod:`strapdown_ros.bench.ros.load_graph`):

* messages lost on every path, from the publisher's and the subscriber's own counts
  (target: 0 on reliable paths; ``--streams reliable``, the default, makes every path reliable
  through the standard ``qos_overrides`` parameters; ``--streams best_effort`` keeps the
  nodes' default sensor-data QoS on the IMU streams);
* end-to-end latency percentiles (p50, p99, max) as a subscriber sees them: a Δθ received →
  the ``sins/attitude`` of the same stamp received; a camera fix received → the
  ``calibration/boresight`` solved with it received;
* resident memory of every node process at the end of the warm-up and at the end
  (target: growth under 10%), and its CPU load.

Prints a table; ``--json FILE`` writes the figures, ``--report DIR`` writes ``load_bench.md``
and ``load_bench.png`` (memory over time, latency distributions).  Every verdict sentence is
computed from the figures it states.  Exit status 0 whatever the figures (a benchmark, not a
test); 2 for bad arguments; 1 if the graph failed to run.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
import sys
import time

import numpy as np

from strapdown_ros.bench.ros.load_graph import node_parameters, run_graph
from strapdown_ros.cli import (check_outputs, DIRECTORY, FILE, OneLineParser, write_figure,
                               write_text)

RSS_GROWTH_TARGET = 0.10


def parse_args(argv):
    """
    Parse and check the command line of ``load_bench``.

    Parameters
    ----------
    argv : list of str
        Arguments without the program name.

    Returns
    -------
    argparse.Namespace
        The options.

    """
    ap = OneLineParser(prog='load_bench', description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--seconds', type=float, default=600.0,
                    help='sensor time to run, s (default 600)')
    ap.add_argument('--rate-factor', type=float, default=10.0,
                    help='multiple of the nominal rates: gyro 100 Hz, accel 300 Hz, '
                    'camera 1/20 Hz (default 10)')
    ap.add_argument('--streams', choices=('reliable', 'best_effort'), default='reliable',
                    help='QoS reliability of the IMU streams (default reliable)')
    ap.add_argument(
        '--warmup', type=float, default=30.0,
        help='memory growth is measured from this many seconds after the first Δθ (default 30)')
    ap.add_argument('--json', metavar='FILE', help='write the figures as JSON '
                    '(documented run: doc/results/load_bench/load_bench.json)')
    ap.add_argument('--report', metavar='DIR',
                    help='write load_bench.md and load_bench.png into DIR (created; '
                    'documented run: doc/results/load_bench)')
    ap.add_argument('--quiet', action='store_true', help='no progress on stderr')
    ap.add_argument('--force', action='store_true', help='overwrite existing outputs')
    args = ap.parse_args(argv)
    if not (math.isfinite(args.seconds) and 10.0 <= args.seconds <= 86400.0):
        ap.error(f'--seconds must be in [10, 86400], got {args.seconds}')
    if not (math.isfinite(args.rate_factor) and 0.01 <= args.rate_factor <= 30.0):
        ap.error(
            f'--rate-factor must be in [0.01, 30] (the accelerometer rate is capped at 10 kHz), '
            f'got {args.rate_factor}')
    if not (math.isfinite(args.warmup) and 0.0 <= args.warmup < args.seconds):
        ap.error(f'--warmup must be in [0, --seconds), got {args.warmup}')
    try:
        check_outputs([('--json', args.json, FILE),
                       ('--report', args.report, DIRECTORY, ('load_bench.md', 'load_bench.png'))],
                      [], args.force)
    except ValueError as exc:
        ap.error(str(exc))
    return args


# --- figures from the raw run -------------------------------------------------------------
def _int(d: dict, key: str) -> int | None:
    try:
        return int(float(d[key]))
    except (KeyError, ValueError, TypeError):
        return None


def loss_table(raw: dict) -> list[dict]:
    """
    Return the published and received counts of every path.

    From the nodes' own /diagnostics and the monitor.

    Parameters
    ----------
    raw : dict
        Result of ``load_graph.run_graph``.

    Returns
    -------
    list of dict
        One row per path: topic, path, QoS, published, received, lost.

    """
    d = raw.get('diagnostics', {})
    sim, cam, sins, cal = (d.get(n, {}) for n in ('imu_sim_node', 'star_camera_sim_node',
                                                  'sins_node', 'calibrator_node'))
    mon = raw.get('monitor', {})
    stream_qos = 'reliable' if raw['reliable_streams'] else 'best effort'
    rows = [
        ('imu/delta_theta', 'imu_sim_node → sins_node', stream_qos,
         _int(sim, 'delta_theta_published'), _int(sins, 'gyro_received')),
        ('imu/delta_theta', 'imu_sim_node → calibrator_node', stream_qos,
         _int(sim, 'delta_theta_published'), _int(cal, 'gyro_received')),
        ('imu/delta_theta', 'imu_sim_node → monitor', stream_qos,
         _int(sim, 'delta_theta_published'), mon.get('delta_theta', {}).get('received')),
        ('imu/delta_velocity', 'imu_sim_node → sins_node', stream_qos,
         _int(sim, 'delta_velocity_published'), _int(sins, 'accel_received')),
        ('star_camera/attitude_with_covariance', 'star_camera_sim_node → calibrator_node',
         'reliable', _int(cam, 'fixes_published'), _int(cal, 'camera_received')),
        ('star_camera/attitude_with_covariance', 'star_camera_sim_node → monitor', 'reliable',
         _int(cam, 'fixes_published'), mon.get('camera', {}).get('received')),
        ('sins/attitude', 'sins_node → monitor', stream_qos, _int(sins, 'attitude_published'),
         mon.get('attitude', {}).get('received')),
        ('sins/imu', 'sins_node → monitor', stream_qos, _int(sins, 'imu_published'),
         mon.get('imu', {}).get('received')),
        ('calibration/boresight', 'calibrator_node → monitor', 'reliable, latched (depth 1)',
         _int(cal, 'boresight_published'), mon.get('boresight', {}).get('received')),
    ]
    out = []
    for topic, path, qos, pub, rec in rows:
        lost = None if pub is None or rec is None else pub - rec
        out.append(
            {
                'topic': topic,
                'path': path,
                'qos': qos,
                'published': pub,
                'received': rec,
                'lost': lost,
                'reliable': qos.startswith('reliable'),
            }
        )
    return out


def latency_table(raw: dict) -> list[dict]:
    """
    Return the end-to-end latency percentiles of the measured paths.

    Parameters
    ----------
    raw : dict
        Result of ``load_graph.run_graph``.

    Returns
    -------
    list of dict
        One row per path: count and the p50, p99 and max latency, ms.

    """
    names = {'delta_theta_to_attitude': 'Δθ → sins/attitude (same stamp)',
             'fix_to_boresight': 'camera fix → calibration/boresight'}
    out = []
    for key, label in names.items():
        v = np.asarray(raw['latency_ns'].get(key, []), dtype=float) * 1e-6
        row = {'key': key, 'what': label, 'n': int(v.size)}
        if v.size:
            row.update(
                {
                    'p50_ms': float(np.percentile(v, 50)),
                    'p99_ms': float(np.percentile(v, 99)),
                    'max_ms': float(v.max()),
                }
            )
        out.append(row)
    return out


def memory_table(raw: dict) -> list[dict]:
    """
    Return the resident memory and CPU load of every node process.

    Parameters
    ----------
    raw : dict
        Result of ``load_graph.run_graph``.

    Returns
    -------
    list of dict
        One row per node: RSS at the start, after the warm-up, at the end and its maximum,
        MiB; the growth after the warm-up; CPU load, % of one core.

    """
    t = np.asarray(raw['rss_kib']['t'], dtype=float)
    out = []
    for node in ('imu_sim_node', 'star_camera_sim_node', 'sins_node', 'calibrator_node'):
        r = np.asarray(raw['rss_kib'].get(node, []), dtype=float)
        row = {
            'node': node,
            'cpu_percent_of_one_core': 100.0 * raw['cpu_s'].get(node, math.nan) / raw['wall_s'],
        }
        if r.size and t.size == r.size:
            k = int(np.searchsorted(t, raw['warmup_s']))
            k = min(k, r.size - 1)
            row.update(
                {
                    'rss_first_mib': r[0] / 1024,
                    'rss_start_mib': r[k] / 1024,
                    'start_at_s': float(t[k]),
                    'rss_end_mib': r[-1] / 1024,
                    'rss_max_mib': float(np.nanmax(r)) / 1024,
                    'growth': float(r[-1] / r[k] - 1.0),
                }
            )
        out.append(row)
    return out


def boresight_check(raw: dict) -> dict | None:
    """
    Compare the calibrator's final estimate with the simulated truth.

    A sanity check of the loaded graph.

    Parameters
    ----------
    raw : dict
        Result of ``load_graph.run_graph``.

    Returns
    -------
    dict or None
        Pairs, error and σ per angle (arc seconds) and error/σ; None without an estimate.

    """
    cal = raw.get('diagnostics', {}).get('calibrator_node', {})
    try:
        beta = np.radians([float(cal[f'beta_{a}_deg']) for a in ('yaw', 'pitch', 'roll')])
        sig = np.array([float(cal[f'beta_{a}_sigma_arcsec']) for a in ('yaw', 'pitch', 'roll')])
    except (KeyError, ValueError):
        return None
    truth = np.asarray(node_parameters('', 1.0, 1.0, False)['star_camera_sim_node']['boresight'])
    err = np.degrees(beta - truth) * 3600.0
    return {'pairs': _int(cal, 'pairs'), 'error_arcsec': err.tolist(),
            'sigma_arcsec': sig.tolist(), 'error_over_sigma': (err / sig).tolist()}


def summarise(raw: dict) -> dict:
    """
    Summarise the run: the loss, latency and memory tables and the verdicts.

    Parameters
    ----------
    raw : dict
        Result of ``load_graph.run_graph``.

    Returns
    -------
    dict
        The tables, the boresight check and the figures the verdicts use.

    """
    loss = loss_table(raw)
    mem = memory_table(raw)
    rel = [r for r in loss if r['reliable']]
    lost_rel = [r['lost'] for r in rel]
    known = all(v is not None for v in lost_rel)
    growth = [r.get('growth') for r in mem]
    d = raw.get('diagnostics', {})
    sim_t = float(d.get('imu_sim_node', {}).get('simulated_time_s', 'nan'))
    return {
        'loss': loss,
        'latency': latency_table(raw),
        'memory': mem,
        'boresight': boresight_check(raw),
        'simulated_s': sim_t,
        'real_time_factor': sim_t / raw['wall_s'] if raw.get('wall_s') else math.nan,
        'lost_on_reliable_paths': sum(lost_rel) if known else None,
        'loss_target_met': known and sum(abs(v) for v in lost_rel) == 0,
        'rss_growth_max': (
            max(g for g in growth if g is not None) if any(g is not None for g in growth) else None
        ),
        'rss_target_met': all(g is not None and g < RSS_GROWTH_TARGET for g in growth),
        'node_levels': {n: v.get('level') for n, v in d.items()},
        'node_messages': {n: v.get('message') for n, v in d.items()},
        'missing_in_nodes': {
            'sins_node': _int(d.get('sins_node', {}), 'gyro_missing_samples'),
            'calibrator_node': _int(d.get('calibrator_node', {}), 'gyro_missing_samples'),
        },
    }


def _fmt(v, spec=''):
    return '–' if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, spec)


def format_report(raw: dict, s: dict, command: str) -> str:
    """
    Format the markdown report; every verdict sentence is computed from its figures.

    Parameters
    ----------
    raw : dict
        Result of ``load_graph.run_graph``.
    s : dict
        Result of ``summarise``.
    command : str
        The command line, quoted in the report.

    Returns
    -------
    str
        The markdown.

    """
    r = raw['rates_hz']
    la = raw['load_at_start']
    lines = [
        f'$ {command}',
        (
            f"graph: imu_sim_node (gyro {r['gyro']:g} Hz, accel {r['accel']:g} Hz) +"
            f" star_camera_sim_node (fix every {1 / r['camera']:g} s) + sins_node +"
            f" calibrator_node, separate processes on loopback, {raw['rate_factor']:g}× nominal"
            f" rates, IMU streams {'reliable' if raw['reliable_streams'] else 'best effort'}"
        ),
        (
            f"{_fmt(s['simulated_s'], '.1f')} sensor s in {raw['wall_s']:.1f} wall s (real-time"
            f" factor {_fmt(s['real_time_factor'], '.3f')}); load average at start {la[0]:.2f}"
            f" {la[1]:.2f} {la[2]:.2f} on {raw['cpu_count']} cores"
        ),
        '',
        '| topic | path | QoS | published | received | lost |',
        '|---|---|---|---:|---:|---:|',
    ]
    for x in s['loss']:
        lines.append(f"| `{x['topic']}` | {x['path']} | {x['qos']} | {_fmt(x['published'])} | "
                     f"{_fmt(x['received'])} | {_fmt(x['lost'])} |")
    lines += [
        '', '| end-to-end latency | messages | p50 ms | p99 ms | max ms |',
        '|---|---:|---:|---:|---:|'
    ]
    for x in s['latency']:
        lines.append(
            f"| {x['what']} | {x['n']} | {_fmt(x.get('p50_ms'), '.2f')} |"
            f" {_fmt(x.get('p99_ms'), '.2f')} | {_fmt(x.get('max_ms'), '.2f')} |"
        )
    lines += [
        '',
        (
            f"| process | RSS at {raw['warmup_s']:g} s, MiB | RSS at end, MiB | growth | max, MiB"
            ' | CPU, % of a core |'
        ),
        '|---|---:|---:|---:|---:|---:|',
    ]
    for x in s['memory']:
        g = x.get('growth')
        lines.append(
            f"| {x['node']} | {_fmt(x.get('rss_start_mib'), '.1f')} |"
            f" {_fmt(x.get('rss_end_mib'), '.1f')} |"
            f" {_fmt(None if g is None else 100 * g, '+.1f')}% |"
            f" {_fmt(x.get('rss_max_mib'), '.1f')} | {_fmt(x['cpu_percent_of_one_core'], '.0f')} |"
        )
    lines.append('')
    n_rel = sum(1 for x in s['loss'] if x['reliable'])
    if s['lost_on_reliable_paths'] is None:
        lines.append(
            'Loss: some counts are missing (a node published no final /diagnostics); logs in'
            f" {raw.get('logs')}."
        )
    else:
        lines.append(
            f"Loss: {s['lost_on_reliable_paths']} message(s) lost on the {n_rel} reliable paths —"
            f" target 0 {'met' if s['loss_target_met'] else 'NOT met'}."
        )
    if s['rss_growth_max'] is not None:
        lines.append(
            f"Memory: largest growth from {raw['warmup_s']:g} s to the end"
            f" {100 * s['rss_growth_max']:+.1f}% — target under {100 * RSS_GROWTH_TARGET:.0f}%"
            f" {'met' if s['rss_target_met'] else 'NOT met'}."
        )
    miss = s['missing_in_nodes']
    lines.append(
        f"Gaps seen by the nodes' stream checks: sins_node {_fmt(miss['sins_node'])},"
        f" calibrator_node {_fmt(miss['calibrator_node'])} missing Δθ."
    )
    b = s['boresight']
    if b:
        lines.append(f"Calibrator at the end: {b['pairs']} pairs, boresight error/σ = "
                     + ', '.join(f'{v:+.2f}' for v in b['error_over_sigma']) + ' (ψ, ϑ, γ).')
    else:
        lines.append('Calibrator at the end: no published estimate.')
    names = ['OK', 'WARN', 'ERROR', 'STALE']
    lines.append('Node /diagnostics at the end: ' + '; '.join(
        f'{n} {names[lv] if isinstance(lv, int) and 0 <= lv < 4 else lv}'
        for n, lv in sorted(s['node_levels'].items())))
    lines.append('Exit status after SIGINT: ' +
                 ', '.join(f'{n} {c}' for n, c in raw['exit_codes_after_sigint'].items()))
    return '\n'.join(lines)


def write_plots(raw: dict, path) -> None:
    """
    Write ``load_bench.png``: memory over time and the latency distributions.

    Parameters
    ----------
    raw : dict
        Result of ``load_graph.run_graph``.
    path : str or pathlib.Path
        PNG file to write.

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.5))
    t = np.asarray(raw['rss_kib']['t'])
    for n in ('imu_sim_node', 'star_camera_sim_node', 'sins_node', 'calibrator_node'):
        r = np.asarray(raw['rss_kib'][n]) / 1024
        if r.size == t.size:
            a1.plot(t, r, label=n)
    a1.axvline(raw['warmup_s'], color='grey', ls=':', lw=1)
    a1.set_xlabel('time since the first Δθ, s')
    a1.set_ylabel('resident memory, MiB')
    a1.set_title('memory of the node processes')
    a1.legend(fontsize=8)
    labels = {'delta_theta_to_attitude': 'Δθ → sins/attitude',
              'fix_to_boresight': 'fix → calibration/boresight'}
    for k, lab in labels.items():
        v = np.sort(np.asarray(raw['latency_ns'][k], dtype=float) * 1e-6)
        if v.size:
            a2.plot(v, 1.0 - np.arange(v.size) / v.size, label=f'{lab} ({v.size})')
    a2.set_xscale('log')
    a2.set_yscale('log')
    a2.set_xlabel('latency, ms')
    a2.set_ylabel('fraction of messages slower')
    a2.set_title('end-to-end latency (complementary CDF)')
    a2.legend(fontsize=8)
    fig.tight_layout()
    write_figure(fig, path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    """
    Run ``load_bench``.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name; ``sys.argv[1:]`` when None.

    Returns
    -------
    int
        0 whatever the figures; 1 if the graph failed to run; bad arguments exit 2.

    """
    argv = sys.argv[1:] if argv is None else argv
    args = parse_args(argv)

    t0 = time.monotonic()

    def progress(text):
        if not args.quiet:
            print(f'load_bench: [{time.monotonic() - t0:6.1f} s] {text}', file=sys.stderr,
                  flush=True)
    try:
        raw = run_graph(args.seconds, args.rate_factor, args.streams == 'reliable', args.warmup,
                        progress)
    except (RuntimeError, OSError) as exc:
        print(f'load_bench: error: {exc}', file=sys.stderr)
        return 1
    s = summarise(raw)
    command = 'load_bench ' + ' '.join(argv) if argv else 'load_bench'
    text = format_report(raw, s, command)
    print(text)
    jraw = {k: v for k, v in raw.items() if k not in ('latency_ns', 'rss_kib')}
    jraw['rss_kib'] = {k: np.asarray(v).tolist() for k, v in raw['rss_kib'].items()}
    if args.json:
        write_text(args.json, json.dumps({'summary': s, 'raw': jraw}, indent=2, default=float))
    if args.report:
        d = Path(args.report)
        d.mkdir(parents=True, exist_ok=True)
        write_plots(raw, d / 'load_bench.png')
        head, _, body = text.partition('\n')
        write_text(d / 'load_bench.md', f'# load_bench\n\nCommand: `{head[2:]}`\n\n'
                   + body.replace('\n', '\n\n', 2)
                   + '\n\n![memory and latency](load_bench.png)\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
