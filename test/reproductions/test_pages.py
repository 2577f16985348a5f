"""
Each reproduction page is what its command makes of its numbers, and its numbers are the command's.

Regenerating the pages from scratch takes about a quarter of an hour (``reproduce_seeds`` about
ten minutes, the 004 page about four), far beyond a test's budget, so each page is tied to its
command in two cheap steps:

1. **Text.**  The Markdown of each committed page — ``reproduce_seeds.md``,
   ``observability_001.md``, ``boresight_004.md`` in ``doc/results/reproductions/`` — is
   rendered again from its committed JSON by the command's own page function (figure links by
   the names each section declares; nothing is drawn) and must equal the committed page byte
   for byte.  A hand edit of a page, or a change of the report code without regenerating the
   page, fails here.
2. **Numbers.**  Parts of each committed JSON are recomputed at full size by the command's own
   functions and must agree to 1e-9 (relative): for 000 the deterministic runs of the three
   cases (Δθ0 = 0, both estimators, Gauss–Newton, (5.6)) and seed 0 of every Monte Carlo case;
   for 001 the whole section; for 002 run 0; for 003 case 1 at τ = 0.01 s over the committed
   duration (every drift, the floor and its marks); for 004 the check of the printed D1, D2
   and the turn count of §6 (from the camera increments of the Fig. 3 run).  Quantities that
   measure float64 round-off (a Gauss–Newton error of 1e-16, a null eigenvalue, the coning
   floor) are compared to their own size, not to 1e-9 of it: they are reproducible on one
   machine, not across machines.  A change of the computation without regenerating the JSON
   fails here.  The rest — the other Monte Carlo runs and the gyro simulations of 004 — is not
   recomputed; their regeneration commands are in doc/reproductions.md.

The coning derivation page (doc/results/coning_bench/coning_derivation_checks.md, the figures
of doc/coning_derivations.md) is cheap enough to be regenerated whole and compared byte for byte;
a few of its figures are round-off (1e-16, 1e-22), so that comparison holds on the machine and
numpy that generated it.

Runtime: about 15 s, most of it the 003 case (4 s) and the 001 section (4 s).
"""
import json
import os
import warnings

import numpy as np
import pytest

from strapdown_ros.attitude.coning_analysis import FLOOR_FACTOR, measure_case
from strapdown_ros.bench.coning_derivation_checks import derivation_checks, derivation_report
from strapdown_ros.reproductions import reproduce_seeds
from strapdown_ros.reproductions import vasilyuk2024 as seeds_004
from strapdown_ros.reproductions import vavilov1982 as seeds_001
from strapdown_ros.reproductions.ilyushenko2009 import section_002
from strapdown_ros.reproductions.tkachenko1983 import (MC_CASES, MC_CASES_PRINTED,
                                                       monte_carlo_000, QUANTUM,
                                                       run_tkachenko_experiment)
from strapdown_ros.sensors import DEG_PER_HOUR

DOC = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
                   'doc', 'results', 'reproductions')
REL = 1e-9


def _read(name):
    with open(os.path.join(DOC, name), encoding='utf-8') as fh:
        return fh.read()


def _json(name):
    return json.loads(_read(name))


@pytest.fixture(scope='module')
def seeds():
    """Return the committed reproduce_seeds.json."""
    return _json('reproduce_seeds.json')


def _figures(names):
    return [os.path.join(DOC, n) for n in names]


# ------------------------------------------------------------------------------ 1. the text
def test_reproduce_seeds_page_is_its_json_rendered(seeds):
    """reproduce_seeds.md is the report of reproduce_seeds.json, byte for byte."""
    text = reproduce_seeds.report(seeds, reproduce_seeds.figure_paths(seeds, DOC), DOC)
    assert text == _read('reproduce_seeds.md'), \
        'regenerate with the reproduce_seeds command of doc/reproductions.md'


def test_001_page_is_its_json_rendered():
    """observability_001.md is the page of observability_001.json, byte for byte."""
    res = _json('observability_001.json')
    text = seeds_001.page(res, _figures(seeds_001.FIGURES), DOC)
    assert text == _read('observability_001.md'), \
        'regenerate with the vavilov1982 command of doc/reproductions.md'


def test_004_page_is_its_json_rendered():
    """boresight_004.md is the page of boresight_004.json, byte for byte."""
    res = _json('boresight_004.json')
    text = seeds_004.page(res, _figures(seeds_004.FIGURES), DOC)
    assert text == _read('boresight_004.md'), \
        'regenerate with the vasilyuk2024 command of doc/reproductions.md'


def test_declared_figures_are_committed(seeds):
    """Every figure a page links is a committed PNG."""
    names = [os.path.basename(p) for ps in reproduce_seeds.figure_paths(seeds, DOC).values()
             for p in ps] + list(seeds_001.FIGURES) + list(seeds_004.FIGURES)
    for n in names:
        with open(os.path.join(DOC, n), 'rb') as fh:
            assert fh.read(8) == b'\x89PNG\r\n\x1a\n', n


def test_coning_derivation_page_is_its_command():
    """doc/results/coning_bench/coning_derivation_checks.md is what its command prints."""
    page = os.path.join(os.path.dirname(DOC), 'coning_bench', 'coning_derivation_checks.md')
    with open(page, encoding='utf-8') as fh:
        committed = fh.read()
    assert derivation_report(derivation_checks()) == committed, \
        'regenerate with: coning_bench --derivation-checks ' \
        'doc/results/coning_bench/coning_derivation_checks.md --force'


# ---------------------------------------------------------------------------- 2. the numbers
def _close(ours, committed, where='', roundoff=0.0):
    """Compare a recomputed structure with the committed one: numbers to REL, or ``roundoff``."""
    if isinstance(committed, dict):
        assert set(ours) == set(committed), where
        for k in committed:
            _close(ours[k], committed[k], f'{where}/{k}', roundoff)
    elif isinstance(committed, (list, tuple)):
        assert len(ours) == len(committed), where
        for i, (a, b) in enumerate(zip(ours, committed)):
            _close(a, b, f'{where}[{i}]', roundoff)
    elif isinstance(committed, (bool, str)) or committed is None:
        assert ours == committed, where
    else:
        assert ours == pytest.approx(committed, rel=REL, abs=roundoff), where


def test_000_numbers(seeds):
    """The Δθ0 = 0 runs of every case, and seed 0 of every Monte Carlo case."""
    r = seeds['000']
    runs = {'unquantized': ({'quantum': 0.0, 'mode': 'raw'}, None),
            'quantized_raw': ({'quantum': QUANTUM, 'mode': 'raw'}, None),
            'quantized_centred': ({'quantum': QUANTUM, 'mode': 'centred'}, 'corrected')}
    for case, (kw, other) in runs.items():
        rows = {'ours': dict(kw), 'ours_as_printed': dict(kw, coefficients='printed'),
                'ours_iterated': dict(kw, iterate=True)}
        if other:
            rows['ours_corrected'] = dict(kw, mode=other)
            rows['ours_as_printed_corrected'] = dict(kw, mode=other, coefficients='printed')
        for key, args in rows.items():
            run = run_tkachenko_experiment(seed=None, **args)
            # errors of 1e-7 and more; Gauss–Newton without quantization leaves 1e-16 of round-off
            _close({k: list(map(float, run[k])) for k in ('w0', 'dc', 'dd')},
                   r['cases'][case][key], f'000/{case}/{key}', roundoff=1e-13)
    for cases, est, where in ((MC_CASES, 'identity', 'beyond_paper'),
                              (MC_CASES_PRINTED, 'printed', 'beyond_paper_printed')):
        with warnings.catch_warnings():          # one seed: its spread is undefined, not used
            warnings.simplefilter('ignore', RuntimeWarning)
            mc = monte_carlo_000(range(1), QUANTUM, cases, coefficients=est)
        for key, v in mc.items():
            assert v['rms_c_per_seed'][0] == pytest.approx(
                r[where][key]['rms_c_per_seed'][0], rel=REL), f'000/{where}/{key}'


def test_001_numbers(seeds):
    """The whole 001 section, in both committed JSONs."""
    res = seeds_001.section_001(quick=False)
    # below 1e-11: round-off (a null eigenvalue, the residuals of (4.1), (4.3))
    _close(res, _json('observability_001.json'), '001', roundoff=1e-11)
    committed = dict(seeds['001'])
    committed.pop('wall_s')
    _close(res, committed, 'reproduce_seeds/001', roundoff=1e-11)


def test_002_numbers(seeds):
    """Run 0 of the 002 section: the RMS error of c of the three estimators."""
    res = section_002(1)
    for key, v in res['rms_c_per_run'].items():
        assert v[0] == pytest.approx(seeds['002']['rms_c_per_run'][key][0], rel=REL), key


def test_003_numbers(seeds):
    """Case 1 at τ = 0.01 s over the committed duration: every drift, the floor, the marks."""
    r = seeds['003']
    case = next(c for c in r['cases']
                if (c['alpha'], c['nu'], c['step']) == (0.087, 1.0, 0.01))
    names = list(case['drift_deg_per_h'])
    m = measure_case(names, 0.087, 1.0, 0.01, r['duration_s'])
    floor = FLOOR_FACTOR * max(m.floor.values()) / DEG_PER_HOUR
    committed = case['floor_deg_per_h']
    # the floor measures round-off: its size, not its digits, is what a rerun reproduces
    assert committed / 10 < floor < 10 * committed
    for n in names:
        drift = m.drift[n] / DEG_PER_HOUR
        assert drift == pytest.approx(case['drift_deg_per_h'][n], rel=REL, abs=committed), n
        if not floor / 3 < abs(drift) < 3 * floor:              # a mark near the line may flip
            assert (abs(drift) <= floor) == case['at_floor'][n], n


def test_004_numbers(seeds):
    """The check of the printed D1, D2 and the turn count, in both committed JSONs."""
    page = _json('boresight_004.json')
    dq = seeds_004.camera_increments_004(0)
    turns = seeds_004.turn_conditioning(dq, np.zeros(3))
    for res, where in ((page, 'boresight_004'), (seeds['004_extras'], 'reproduce_seeds')):
        _close(turns, res['turns'], f'{where}/turns')
        # finite differences: errors of 1e-10 that carry round-off
        _close(seeds_004.d_matrix_check(res['d_matrices']['count']), res['d_matrices'],
               f'{where}/d_matrices', roundoff=1e-12)
