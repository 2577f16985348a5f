"""
reproduce_seeds in quick mode: the JSON schema it fixes, and the comparisons it reports.

Every comparison the report states is recomputed here from the numbers the JSON records (the
paper's published values and ours), independently of the report code.
"""
import json

import numpy as np
import pytest

from strapdown_ros.attitude.coning_analysis import THESIS_RANKING
from strapdown_ros.calibration.drifting_reference_model import (integrate_attitude, PAPER_000,
                                                                PAPER_000_W0)
from strapdown_ros.reproductions import reproduce_seeds
from strapdown_ros.reproductions.tkachenko1983 import (EXPLAINS_WITHIN,
                                                       float32_recursion_increments, NO_EFFECT,
                                                       run_tkachenko_experiment, SAME_PATTERN,
                                                       simulate_000)
from strapdown_ros.rotation import quat_conjugate, quat_multiply, quat_to_rotvec, rotvec_to_quat


@pytest.fixture(scope='module')
def result(tmp_path_factory):
    """Run reproduce_seeds --quick on 000, 002 and 003 once; return its JSON, report, dir."""
    d = tmp_path_factory.mktemp('seeds')
    assert reproduce_seeds.main(['--only', '000,002,003', '--quick', '--json', str(d / 'r.json'),
                                 '--report', str(d / 'r.md'), '--plots', str(d / 'plots')]) == 0
    return json.loads((d / 'r.json').read_text()), (d / 'r.md').read_text(), d


def _cd(rec):
    return np.r_[rec['dc'], rec['dd']]


def test_000_schema(result):
    """The 000 JSON holds every row of the three cases; the paper's column is untouched."""
    res, _, _ = result
    cases = res['000']['cases']
    assert set(cases) == {'unquantized', 'quantized_raw', 'quantized_centred'}
    for case in cases.values():
        for key in ('paper', 'ours', 'ours_as_printed', 'ours_iterated', 'ours_mc_mean',
                    'ours_mc_std'):
            assert (len(case[key]['w0']) == 3 and len(case[key]['dc']) == 9
                    and len(case[key]['dd']) == 3)
    for name, case in cases.items():       # the paper's column is the transcription, untouched
        assert (case['paper']['dc'] == PAPER_000[name]['dc']
                and case['paper']['dd'] == PAPER_000[name]['dd'])


def test_000_headline_is_rms_ratio_and_signs(result):
    """
    The headline is the RMS ratio and the sign count, 000's method as printed first.

    The headline numbers, recomputed from the error vectors: RMS(paper)/RMS(ours) and the count
    of components with the paper's sign; the report states them, not the largest ratio alone.
    """
    res, text, _ = result
    for name, case in res['000']['cases'].items():
        ours, paper = _cd(case['ours']), _cd(case['paper'])
        h = res['000']['headline'][name]['ours']
        assert h['rms_ratio'] == pytest.approx(np.sqrt(np.mean(paper ** 2) / np.mean(ours ** 2)),
                                               rel=1e-12)
        assert h['signs'] == int(np.sum(np.sign(ours) == np.sign(paper)))
        hp = res['000']['headline'][name]['ours_as_printed']
        printed = _cd(case['ours_as_printed'])
        ratio = np.sqrt(np.mean(paper ** 2) / np.mean(printed ** 2))
        assert hp['rms_ratio'] == pytest.approx(ratio, rel=1e-12)
        assert hp['signs'] == int(np.sum(np.sign(printed) == np.sign(paper)))
        cosine = printed @ paper / np.linalg.norm(printed) / np.linalg.norm(paper)
        assert hp['corr'] == pytest.approx(cosine)
        # 000's method as printed is stated first, then the modified estimator
        first = (f"**{name}**, 000's method as printed: the paper's errors are "
                 f"{hp['rms_ratio']:.3g}× ours in RMS")
        assert first in text
        second = f"Modified estimator: the paper's errors are {h['rms_ratio']:.3g}× ours in RMS"
        assert text.index(first) < text.index(second)
        assert f"{h['signs']}/12 signs agree" in text
    un = res['000']['headline']['unquantized']['ours']
    assert un['rms_ratio'] > 5 and un['signs'] >= 9          # ~15× smaller, same signs mostly
    up = res['000']['headline']['unquantized']['ours_as_printed']
    # the audit's numbers for 000's method as printed: 1.53, 5/12, 0.58
    assert 1.2 < up['rms_ratio'] < 2 and up['signs'] <= 6 and up['corr'] < 0.7
    assert 'within 2.9×' not in text


def test_000_iterated_unquantized_is_1000x_below_the_paper(result):
    """Gauss–Newton without quantization is 1000× below the paper in every component."""
    res, _, _ = result
    c = res['000']['cases']['unquantized']
    for k in ('dc', 'dd'):
        for ours, paper in zip(c['ours_iterated'][k], c['paper'][k]):
            assert abs(ours) <= 1e-3 * abs(paper)


def test_000_ablations_verdicts_follow_fixed_thresholds(result):
    """
    Ablation verdicts follow fixed thresholds, for both estimators.

    Each ablation's verdict follows from its numbers and fixed thresholds (ratio within 2× of 1,
    corr ≥ 0.9), not from the correlation of one of our estimators; both estimators are run.
    """
    res, text, _ = result
    a = res['000']['ablations']
    h = res['000']['headline']['unquantized']
    none = a['knobs']['none']
    assert none['identity']['rms_ratio'] == pytest.approx(h['ours']['rms_ratio'], rel=1e-12)
    printed = h['ours_as_printed']['rms_ratio']
    assert none['printed']['rms_ratio'] == pytest.approx(printed, rel=1e-12)
    # the paper's own method is the reference column, not a knob that is "ruled out"
    assert 'coefficients_printed' not in a['knobs'] and 'ruled out' not in text
    # the profile's rates are constant on each step, so the integration scheme cannot matter
    for key in ('algorithm_1', 'algorithm_4', 'quadrature_trapezoid'):
        for est in ('printed', 'identity'):
            change = abs(a['knobs'][key][est]['rms_ratio'] / none[est]['rms_ratio'] - 1)
            assert change < 0.05
            assert f'size unchanged: ratio moves {100 * change:.1f}%' in text
    for key, k in a['knobs'].items():
        for est in ('printed', 'identity'):
            v = k[est]
            explains = (abs(np.log(v['rms_ratio'])) <= np.log(EXPLAINS_WITHIN)
                        and v['corr'] >= SAME_PATTERN)
            if explains:
                assert 'explains size and pattern' in text
    assert f'within {EXPLAINS_WITHIN:g}× of 1 and its corr ≥ {SAME_PATTERN:g}' in text


def test_000_new_ablations_compute_what_the_text_says(result):
    """
    The float32-recursion and w0 = 1e-2 rows compute what the text says.

    The float32-recursion and w0 = 1e-2 rows: the table's numbers are the agreement of a run
    with that change, recomputed here from an independent run of the experiment.
    """
    res, text, _ = result
    a = res['000']['ablations']['knobs']
    paper = np.r_[PAPER_000['unquantized']['dc'], PAPER_000['unquantized']['dd']]
    for key, kw in (('w0_1e-2', {'w0': np.full(3, 1e-2)}),
                    ('float32_recursion', {'recursion': 'float32', 'algorithm': '1'})):
        assert key in a
        for est in ('printed', 'identity'):
            r = run_tkachenko_experiment(seed=None, coefficients=est, **kw)
            ours = np.r_[r['dc'], r['dd']]
            ratio = np.sqrt(np.mean(paper ** 2) / np.mean(ours ** 2))
            corr = ours @ paper / np.linalg.norm(ours) / np.linalg.norm(paper)
            v = a[key][est]
            assert v['rms_ratio'] == pytest.approx(ratio, rel=1e-9)
            assert v['corr'] == pytest.approx(corr, abs=1e-9)
            assert v['signs'] == int(np.sum(np.sign(ours) == np.sign(paper)))
            assert f"| {v['rms_ratio']:.2f} | {v['signs']}/12 | {v['corr']:+.3f} |" in text
    assert np.allclose(PAPER_000_W0 * 10, 1e-2)
    # audit's numbers for the exponent misprint with the modified estimator: 1.66, 0.79, 9/12
    v = a['w0_1e-2']['identity']
    assert v['rms_ratio'] == pytest.approx(1.66, abs=0.01)
    assert v['corr'] == pytest.approx(0.79, abs=0.01)
    assert v['signs'] == 9


def test_float32_recursion_is_single_precision_roundoff():
    """
    The float32 recursion differs from float64 by single-precision round-off.

    The float32 recursion's attitude differs from the float64 one by float32 round-off
    (≫ float64's, ≪ the increments), and its equivalent increments reproduce it.
    """
    rng = np.random.default_rng(1)
    theta = rng.normal(0, 5e-3, (1500, 3))
    q0 = np.array([0.64, 0.48, 0.36, -0.48])
    q0_32, inc = float32_recursion_increments(q0, theta)
    d = np.linalg.norm(inc - theta, axis=1)
    assert 1e-10 < np.max(d) < 1e-5                       # float32 round-off per step
    # exact float64 recursion of the equivalent increments vs of the true ones: a random walk of
    # float32 round-off, far above float64's 1e-15
    q_true = q0.copy()
    q_32 = q0_32.copy()
    for k in range(len(theta)):
        q_true = quat_multiply(q_true, rotvec_to_quat(theta[k]))
        q_32 = quat_multiply(q_32, rotvec_to_quat(inc[k]))
    err = np.linalg.norm(quat_to_rotvec(quat_multiply(quat_conjugate(q_true), q_32)))
    assert 1e-8 < err < 1e-4


def test_000_centring_sentence_computed(result):
    """
    The centring verdict is computed, 000's method as printed first.

    For each estimator the line states the (5.5) change of the RMS of c computed from the Monte
    Carlo, and its verdict follows the stated threshold (c and d each fall by at least
    NO_EFFECT, by (5.5) and by (5.6)); the paper's own method comes first.
    """
    res, text, _ = result
    r = res['000']
    assert r['centring_gain']['printed_rms_c_raw'] == r['beyond_paper_printed']['raw']['rms_c']
    where = []
    for name, b in (("000's method as printed", r['beyond_paper_printed']),
                    ('modified estimator', r['beyond_paper'])):
        raw, cen = b['raw']['rms_c'], b['centred']['rms_c']
        line = next(ln for ln in text.splitlines() if ln.startswith(f'* Centring, {name},'))
        assert f'RMS of c {raw:.4g} → {cen:.4g} ({100 * (cen / raw - 1):+.2g}%)' in line
        holds = all(b[m][k] <= (1 - NO_EFFECT) * b['raw'][k]
                    for m in ('centred', 'corrected') for k in ('rms_c', 'rms_d'))
        assert (': holds' if holds else ': does not hold') in line
        where.append(text.index(line))
    assert where[0] < where[1]


def test_000_w0_verdict_computed(result):
    """The w⁰ verdict states the norms of the paper's and our w⁰, recomputed here."""
    res, text, _ = result
    line = next(ln for ln in text.splitlines() if ln.startswith('* w⁰, the attitude error'))
    for case, rec in res['000']['cases'].items():
        pn = np.linalg.norm(PAPER_000[case]['w0'])
        on = np.linalg.norm(rec['ours_as_printed']['w0'])
        assert f"{case}: paper {pn:.2e}, 000's method as printed {on:.2e} " \
               f'(paper/ours {pn / on:.2f}' in line


def test_002_and_003_sections(result):
    """The 002 and 003 sections are present, with their numbers."""
    res, text, _ = result
    r = res['002']
    assert set(r['rms_000']) == set(r['rms_002']) == set(r['rms_002_adaptive'])
    assert all(v > 0 for v in r['rms_000'].values())
    assert res['003']['claim_case1']['0.01']['algorithm_1_above_1e-3']
    for needle in ('## 000', '## 002', '## 003', "* Centring, 000's method as printed"):
        assert needle in text


def test_003_values_below_the_floor_are_marked(result):
    """Every 003 value at or below the round-off floor is marked, and only those."""
    res, text, _ = result
    marked = 0
    for c in res['003']['cases']:
        for n, v in c['drift_deg_per_h'].items():
            below = abs(v) <= c['floor_deg_per_h']
            assert c['at_floor'][n] == below
            marked += below
    assert text.count(' (floor) |') == marked
    assert f'{marked} of ' in text


def test_plots_written_and_linked(result):
    """The 000 figures are written and linked from the report."""
    _, text, d = result
    declared = next(s for s in reproduce_seeds.sections() if s.key == '000').figures
    assert sorted(p.name for p in (d / 'plots').glob('*.png')) == sorted(declared)
    for name in declared:
        png = d / 'plots' / name
        assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and png.stat().st_size > 10_000
        assert f'(plots/{name})' in text


def test_000_beyond_the_paper_gains_reported(result):
    """
    The quantized table has both estimators; its ratios are to 000's method as printed, raw.

    Centring and weighting gains beyond the paper are reported.
    """
    res, text, _ = result
    b, bp = res['000']['beyond_paper'], res['000']['beyond_paper_printed']
    assert {'raw', 'centred', 'corrected', 'centred+iter', 'centred+weighted',
            'centred+iter+weighted'} <= set(b)
    assert {'raw', 'centred', 'corrected'} == set(bp)
    assert b['centred+weighted']['rms_c'] < b['centred']['rms_c'] < b['raw']['rms_c']
    assert '### Quantized, Monte Carlo' in text
    base = bp['raw']['rms_c']
    assert (f"| 000's method as printed: raw (5.4), first order | {base:.2e} (1.00) |"
            in text)
    v = b['raw']['rms_c']
    assert f'| modified: raw (5.4), first order | {v:.2e} ({v / base:.2f}) |' in text


def test_003_claims_follow_the_drift_table(result):
    """
    The 003 verdicts follow from the drift table, recomputed here.

    4+ against 4 where both are above the floor, algorithm (1) in case 2 against the
    instrument error, the growth with α and ν and the ranking.
    """
    res, text, _ = result
    r = res['003']
    cases = {(c['alpha'], c['nu'], c['step']): c for c in r['cases']}
    ratios = [abs(c['drift_deg_per_h']['4']) / abs(c['drift_deg_per_h']['4+'])
              for c in r['cases'] if not (c['at_floor']['4'] or c['at_floor']['4+'])]
    assert [x['ratio'] for x in r['runge_4_plus']] == pytest.approx(ratios, rel=1e-12)
    for step in (0.01, 0.001):
        d1 = abs(cases[(0.5, 1.0, step)]['drift_deg_per_h']['1'])
        assert r['algorithm_1_case2'][str(step)] == pytest.approx(d1, rel=1e-12)
        assert f'τ = {step} s: {d1:.2g} °/h, ×{d1 / 1e-3:.3g}' in text
    grows = 0
    for step in (0.01, 0.001):
        small, big = cases[(0.087, 1.0, step)], cases[(0.5, 1.0, step)]
        for n, v in small['drift_deg_per_h'].items():
            if not (small['at_floor'][n] or big['at_floor'][n]):
                grows += abs(big['drift_deg_per_h'][n]) > abs(v)
    assert len(r['growth']['alpha']['grows']) == grows
    held = 0
    for c in r['cases']:
        ranked = sorted((n for n in THESIS_RANKING if not c['at_floor'][n]),
                        key=lambda n: abs(c['drift_deg_per_h'][n]))
        held += ranked == [n for n in THESIS_RANKING if n in ranked]
    assert f"The thesis's order holds in {held} of {len(r['cases'])} (case, τ)." in text


def test_registry_is_table_driven():
    """
    The report is table-driven: one registry entry per section.

    Every available section is one registry entry with its run/report functions present;
    sections whose module is absent are skipped, not fatal.
    """
    names = reproduce_seeds.section_names()
    assert {'000', '002', '003', '004'} <= set(names)
    for s in reproduce_seeds.sections():
        assert callable(s.fn(s.run)) and callable(s.fn(s.report))
    missing = reproduce_seeds.Section('999', '999', '.no_such_seed_module', 'a', 'b', None,
                                      lambda a: ())
    assert not missing.available()


def test_from_json_rerenders_the_same_report(result, tmp_path, capsys):
    """
    --from-json re-renders the same report without rerunning.

    --from-json writes the report of an earlier run without rerunning it: same text; the
    input may not be an output (exit 2, one line).
    """
    _, text, d = result
    again = tmp_path / 'again'
    again.mkdir()
    argv = ['--only', '000,002,003', '--from-json', str(d / 'r.json'),
            '--report', str(again / 'r.md'), '--plots', str(again / 'plots')]
    assert reproduce_seeds.main(argv) == 0
    assert (again / 'r.md').read_text() == text
    capsys.readouterr()
    assert reproduce_seeds.main(['--from-json', str(d / 'r.json'), '--json', str(d / 'r.json'),
                                 '--force']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('reproduce_seeds: error:')


def test_estimator_integration_reproduces_the_float32_recursion():
    """
    The estimator's integration reproduces the float32 recursion.

    Fed the equivalent increments, the estimator's own 1-sample integration gives the float32
    attitudes (their exact product) to float64 round-off, so the ablation tests the recursion.
    """
    sim = simulate_000(seed=None)
    q0, inc = float32_recursion_increments(sim.M0, sim.meas)
    q = integrate_attitude(q0, inc, sim.h, '1')
    m = [q0]
    for t in inc:
        m.append(quat_multiply(m[-1], rotvec_to_quat(t)))
    err = quat_to_rotvec(quat_multiply(quat_conjugate(np.array(m)), q))
    assert np.abs(err).max() < 1e-12
    # and the float32 attitude really is off the float64 one by single-precision round-off
    q64 = integrate_attitude(sim.M0, sim.meas, sim.h, '1')
    drift = np.abs(quat_to_rotvec(quat_multiply(quat_conjugate(q64), q))).max()
    assert 1e-8 < drift < 1e-4
