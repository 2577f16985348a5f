"""
Rerun the experiments of the seed papers and set our numbers beside theirs (reproduce_seeds).

    reproduce_seeds [--only 000,001,002,003,004] [--seeds N] [--runs N] [--json FILE]
                    [--report FILE] [--plots DIR] [--quick] [--from-json FILE]

* 000 (Tkachenko 1983, §6): the three published error sets beside our first-order method, our
  Gauss–Newton solution and a Monte Carlo over ``--seeds`` quantization seeds; the headline is the
  RMS ratio and the sign agreement; ablations look for what makes the paper's errors larger
  (:mod:`.tkachenko1983`).
* 001 (Vavilov 1982): observability measures of the ship and aircraft cases (:mod:`.vavilov1982`,
  when present).
* 002 (Ilyushenko 2009): the integral method against the 000 estimator on the same data
  (:mod:`.ilyushenko2009`).
* 003 (Aksyonenko 2014, coning §2.3): the three cases, the thesis's claims, values at the
  round-off floor marked (:mod:`.aksyonenko2014`).
* 004 (Vasilyuk et al. 2024, boresight §6): the σ_β pattern from a simulated experiment with
  004's sensor parameters, the Fig. 3 check and the σ_β ablation (:mod:`.vasilyuk2024`).

Every section is one entry of :data:`REGISTRY`: a module with a run, a report and (optionally) a
plots function.  Each section opens with the paper's claim beside ours; every comparison
sentence is computed from the numbers it compares and prints its threshold; each figure follows
the table it illustrates.  This is the reproductions room: it uses the library (calibration,
estimation, attitude) and nothing uses it.  References: doc/references.md.  No ROS imports.
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass
import importlib
import importlib.util
import json
import os
import sys
import time
from typing import Callable

import numpy as np

from strapdown_ros.cli import check_outputs, DIRECTORY, FILE, write_text
from strapdown_ros.reproductions.markdown import place_figures


@dataclass(frozen=True)
class Section:
    """
    One part of the report: where its run, report and plots functions live.

    Parameters
    ----------
    only : str
        The name ``--only`` selects it by.
    key : str
        Its key in the results (JSON).
    module : str
        The module of ``run`` (and of ``report``/``plots`` unless ``report_module`` is given),
        relative to this package.
    run, report : str
        Names of the run function (command-line values → JSON-able dict) and of the report
        function (dict → Markdown).
    plots : str or None
        Name of the plots function (dict, directory → PNG paths), if any.
    args : callable
        The run function's positional arguments from the parsed command line.
    report_module : str, optional
        The module of ``report`` and ``plots`` when they live apart from ``run``.
    figures : tuple of str
        The PNG files ``plots`` writes, in its order (their links can be placed without
        drawing them: :func:`figure_paths`).

    """

    only: str
    key: str
    module: str
    run: str
    report: str
    plots: str | None
    args: Callable
    report_module: str | None = None
    figures: tuple = ()

    def available(self) -> bool:
        """Return True when the section's module can be imported."""
        name = importlib.util.resolve_name(self.module, __package__)
        return name == __name__ or importlib.util.find_spec(name) is not None

    def fn(self, attr: str):
        """
        Return a function of this section by name.

        Parameters
        ----------
        attr : str
            The name of the run, report or plots function; the report and plots functions
            are looked up in ``report_module`` when it is given.

        Returns
        -------
        callable
            The function.

        """
        module = self.module
        if self.report_module and attr in (self.report, self.plots):
            module = self.report_module
        return getattr(importlib.import_module(module, __package__), attr)


#: the report, in order; adding a section is one entry (modules not present are skipped)
REGISTRY = (
    Section('000', '000', '.tkachenko1983', 'section_000', 'report_000', 'plots_000',
            lambda a: (a.seeds, a.quick), '.tkachenko1983_report',
            ('seeds_000_errors.png', 'seeds_000_centring.png', 'seeds_000_ablations.png')),
    Section('001', '001', '.vavilov1982', 'section_001', 'report_001', 'plots_001',
            lambda a: (a.quick,), None, ('seeds_001_measures.png', 'seeds_001_filter.png')),
    Section('002', '002', '.ilyushenko2009', 'section_002', 'report_002', None,
            lambda a: (a.runs, a.quick)),
    Section('003', '003', '.aksyonenko2014', 'section_003', 'report_003', None,
            lambda a: (a.coning_duration,)),
    Section('004', '004', '.vasilyuk2024', 'section_004', 'report_004', 'plots_004',
            lambda a: (a.runs, a.quick), '.vasilyuk2024_report', ('seeds_004_sigma.png',)),
    Section('004', '004_extras', '.vasilyuk2024', 'section_004_extras', 'report_004_extras',
            'plots_004_extras', lambda a: (a.quick,), '.vasilyuk2024_report',
            ('seeds_004_theta_diff.png', 'seeds_004_fig2.png', 'seeds_004_ablation.png')),
)


def sections() -> list[Section]:
    """Return the sections of :data:`REGISTRY` whose module is present, in report order."""
    return [s for s in REGISTRY if s.available()]


def section_names() -> list[str]:
    """Return the names ``--only`` accepts, in report order."""
    return list(dict.fromkeys(s.only for s in sections()))


# ---------------------------------------------------------------------------------- report
def report(res: dict, figures: dict | None = None, base: str = '.') -> str:
    """
    Write the Markdown report.

    Each section opens with the paper's claim beside ours; its figures follow the table they
    illustrate (:func:`strapdown_ros.reproductions.markdown.place_figures`).

    Parameters
    ----------
    res : dict
        Section key → that section's results (the JSON of a run).
    figures : dict, optional
        Section key → PNG paths of that section.
    base : str
        Directory the figure links are relative to (the report's directory).

    Returns
    -------
    str
        The report.

    """
    L = ['# Seed experiments reproduced', '',
         'Generated by `reproduce_seeds`; every number and every comparison below comes from '
         "that run. Each section opens with the paper's published table, figure or claim "
         'beside ours, and its figures follow the table they illustrate; each verdict prints '
         'its threshold. The papers are listed in `doc/references.md`.', '']
    for s in sections():
        if s.key in res:
            paths = (figures or {}).get(s.key, [])
            L += [place_figures(s.fn(s.report)(res[s.key]), paths, base), '']
    return '\n'.join(L)


def figure_paths(res: dict, outdir: str) -> dict:
    """
    Return the paths :func:`write_plots` would write, without drawing anything.

    Parameters
    ----------
    res : dict
        Section key → that section's results.
    outdir : str
        Directory of the figures.

    Returns
    -------
    dict
        Section key → paths of its PNG files (the names its :class:`Section` declares).

    """
    return {s.key: [os.path.join(outdir, f) for f in s.figures]
            for s in sections() if s.key in res and s.plots}


def write_plots(res: dict, outdir: str) -> dict:
    """
    Write the PNG figures of every section that has a plots function (needs matplotlib).

    Parameters
    ----------
    res : dict
        Section key → that section's results.
    outdir : str
        Directory of the figures (created if missing).

    Returns
    -------
    dict
        Section key → paths of its PNG files.

    """
    os.makedirs(outdir, exist_ok=True)
    paths = {}
    for s in sections():
        if s.key in res and s.plots:
            paths[s.key] = list(s.fn(s.plots)(res[s.key], outdir))
    return paths


def main(argv=None) -> int:
    """
    Run the ``reproduce_seeds`` command.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success, 2 on a usage or output error (one line on stderr).

    """
    names = section_names()
    ap = argparse.ArgumentParser(prog='reproduce_seeds', description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--only', default=','.join(names), help='comma-separated subset of '
                                                            f"{','.join(names)}")
    ap.add_argument('--seeds', type=int, default=100, help='Monte Carlo runs for 000 (≥ 100 for '
                                                           'the record)')
    ap.add_argument('--runs', type=int, default=20, help='runs for the 002 and 004 sections')
    ap.add_argument('--coning-duration', type=float, default=3600.0,
                    help="seconds per coning case (default 3600, 003 §2.3's)")
    ap.add_argument('--quick', action='store_true', help='few runs (for tests)')
    ap.add_argument('--json', help='write the results as JSON')
    ap.add_argument('--report', help='write a Markdown report')
    ap.add_argument('--plots', help='write PNG figures to this directory (needs matplotlib)')
    ap.add_argument('--force', action='store_true', help='overwrite existing outputs')
    ap.add_argument('--from-json', metavar='FILE',
                    help="no runs: write the report and figures from an earlier run's --json")
    a = ap.parse_args(argv)
    only = [s.strip() for s in a.only.split(',') if s.strip()]
    bad = [s for s in only if s not in names]
    if bad:
        ap.error(f"unknown section(s) {', '.join(bad)}; valid: {', '.join(names)}")
    try:                                       # everything that can fail, before minutes of work
        for flag, v in (('--seeds', a.seeds), ('--runs', a.runs)):
            if v < 1:
                raise ValueError(f'{flag} must be >= 1, got {v}')
        if not (np.isfinite(a.coning_duration) and a.coning_duration > 0):
            raise ValueError(f'--coning-duration must be > 0, got {a.coning_duration}')
        check_outputs([('--json', a.json, FILE), ('--report', a.report, FILE),
                       ('--plots', a.plots, DIRECTORY)], [('--from-json', a.from_json)], a.force)
        saved = None
        if a.from_json:
            try:
                with open(a.from_json, encoding='utf-8') as fh:
                    saved = json.load(fh)
            except (OSError, json.JSONDecodeError) as exc:
                raise ValueError(f'--from-json {a.from_json}: {str(exc)[:200]}') from None
            if not isinstance(saved, dict):
                raise ValueError(f'--from-json {a.from_json}: not a reproduce_seeds result')
    except ValueError as exc:
        print(f'reproduce_seeds: error: {exc}', file=sys.stderr)
        return 2
    if a.quick:
        a.seeds, a.runs = min(a.seeds, 8), min(a.runs, 3)
        a.coning_duration = min(a.coning_duration, 60.0)
    res, t0 = {}, time.perf_counter()
    for s in sections():
        if s.only not in only:
            continue
        if saved is not None:                  # re-render an earlier run; nothing is recomputed
            if s.key in saved:
                res[s.key] = saved[s.key]
            continue
        t = time.perf_counter()
        res[s.key] = s.fn(s.run)(*s.args(a))
        res[s.key]['wall_s'] = time.perf_counter() - t
        print(f"[reproduce_seeds] {s.key}: {res[s.key]['wall_s']:.1f} s", file=sys.stderr)
    figures = write_plots(res, a.plots) if a.plots else {}
    base = os.path.dirname(os.path.abspath(a.report)) if a.report else os.getcwd()
    text = report(res, figures, base)
    print(text)
    try:
        if a.json:
            write_text(a.json, json.dumps(res, indent=1, default=float))
        if a.report:
            write_text(a.report, text)
    except OSError as exc:
        print(f'reproduce_seeds: error: {exc}', file=sys.stderr)
        return 2
    print(f'[reproduce_seeds] total {time.perf_counter() - t0:.1f} s', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
