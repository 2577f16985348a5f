"""coning_bench at reduced duration: the JSON schema, the report, and agreement with theory."""
from fractions import Fraction
import json

import pytest

from strapdown_ros.attitude.coning import ALGORITHMS
from strapdown_ros.bench import coning_bench
from strapdown_ros.bench.coning_derivation_checks import (measure_drift, series_coefficients,
                                                          SEVEN_OPTIMAL)

SCHEMA = {
    'algorithm': str,
    'alpha': float,
    'nu': float,
    'step': float,
    'samples_per_update': int,
    'drift_rad_per_s': float,
    'drift_deg_per_h': float,
    'theory_rad_per_s': (float, type(None)),
    'order_measured': (float, type(None)),
    'order_theory': (int, type(None)),
    'floor': bool,
    'ns_per_update': float,
}


@pytest.fixture(scope='module')
def bench(tmp_path_factory):
    """Run coning_bench once on one short case; the output directory and its JSON."""
    pytest.importorskip('scipy')
    pytest.importorskip('matplotlib')
    d = tmp_path_factory.mktemp('bench')
    # α small, Ωh = 0.2 per update for both algorithms: τ = 0.1 s (2 samples), 0.2 s (1 sample)
    args = [
        '--alpha', '0.01', '--nu', '1.0', '--step', '0.1', '--step', '0.2', '--duration', '200',
        '--algorithms', 'two_sample,one_plus_previous,3,3_as_printed', '--sweep-periods', '8',
        '--json',
        str(d / 'c.json'), '--plots',
        str(d / 'plots'), '--report',
        str(d / 'coning.md')
    ]
    assert coning_bench.main(args) == 0
    return d, json.loads((d / 'c.json').read_text())


def test_json_schema(bench):
    """Every record has the fields of the schema."""
    _, res = bench
    assert len(res['results']) == 2 * 4
    for r in res['results']:
        for key, typ in SCHEMA.items():
            assert key in r, key
            assert isinstance(r[key], typ), (key, r[key])
        assert r['drift_deg_per_h'] == pytest.approx(r['drift_rad_per_s'] * 180 /
                                                     3.141592653589793 * 3600)


@pytest.mark.parametrize('name,step', [('two_sample', 0.1), ('one_plus_previous', 0.2)])
def test_drift_and_order_agree_with_theory(bench, name, step):
    """Measured drift and order agree with the small-α theory."""
    _, res = bench
    r = next(r for r in res['results'] if r['algorithm'] == name and r['step'] == step)
    assert not r['floor']
    assert r['drift_rad_per_s'] == pytest.approx(r['theory_rad_per_s'], rel=0.05)
    assert r['order_measured'] == pytest.approx(r['order_theory'], abs=0.2)


def test_report_and_plots(bench):
    """The report has its sections, the plots exist, printed forms lose."""
    d, res = bench
    text = (d / 'coning.md').read_text()
    for needle in ('## Round-off floor', '## Order of accuracy and verdict',
                   '## The claims of 003', '## Misprints in 003', '(2.6) U12',
                   '## Cost per update', 'coning_drift.png', 'coning_order.png'):
        assert needle in text, needle
    assert (d / 'plots' / 'coning_drift.png').stat().st_size > 10_000
    assert (d / 'plots' / 'coning_order.png').stat().st_size > 10_000
    printed = next(r for r in res['results'] if r['algorithm'] == '3_as_printed')
    corrected = next(r for r in res['results']
                     if r['algorithm'] == '3' and r['step'] == printed['step'])
    assert abs(printed['drift_rad_per_s']) > 100 * abs(corrected['drift_rad_per_s'])
    # the verdict on the printed (1.78) is computed from the measured order, not fixed prose
    order = res['order_sweeps']['3_as_printed']['order_measured']
    row = next(line for line in text.splitlines()
               if line.startswith('| `3` |') and 'as printed' in line)
    assert (
        f"as printed: order {coning_bench.fmt(order, 2)}, {'below' if order < 3.5 else 'reaches'}"
        ' the claimed 4'
        in row
    )


def test_unknown_algorithm_is_refused(capsys):
    """An unknown algorithm name is refused with the valid names."""
    with pytest.raises(SystemExit):
        coning_bench.main(['--algorithms', '2,bogus'])
    assert 'valid names: 1, 2' in capsys.readouterr().err


def test_derivation_checks_against_the_literature():
    """
    The derivation page's series and drifts against the seed guide's published coefficients.

    Exact series coefficients: two_sample c3 = 0, c5 = 1/30 ((Ωh)⁴/960 with N = 2);
    four_sample_optimal c3 = c5 = c7 = 0, c9 = 1/315; the optimal two-previous-sample form
    c3 = c5 = 0, c7 = 1/280.  Measured drift of two_sample at Ωh = 0.2, α = 0.01: (Ωh)⁴/960
    within 1%.
    """
    assert series_coefficients(ALGORITHMS['two_sample'])[:2] == [0, Fraction(1, 30)]
    assert series_coefficients(ALGORITHMS['four_sample_optimal']) == [0, 0, 0, Fraction(1, 315)]
    assert series_coefficients(SEVEN_OPTIMAL)[:3] == [0, 0, Fraction(1, 280)]
    d = measure_drift(ALGORITHMS['two_sample'], 0.2)['drift']
    assert d == pytest.approx(0.2 ** 4 / 960, rel=0.01)


def test_derivation_checks_output_rule(tmp_path, capsys):
    """--derivation-checks keeps an existing file without --force (exit 2, one line)."""
    out = tmp_path / 'checks.md'
    out.write_text('old')
    assert coning_bench.main(['--derivation-checks', str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('coning_bench: error:')
    assert out.read_text() == 'old'
