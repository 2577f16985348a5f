"""
Smoke test of filter_bench: tiny settings, every output written.

No figure is asserted: the bench prints figures, it does not assert them.
"""
import json

from strapdown_ros.bench.filter_bench import main


def test_filter_bench_runs_and_writes_its_outputs(tmp_path, capsys):
    """Tiny settings run and write JSON, report and plots."""
    out = tmp_path / 'out'
    args = ['--runs', '3', '--fixes', '5', '--timing-seconds', '0.2', '--timing-runs', '1',
            '--blocks', '1,10', '--no-realdata', '--quiet', '--json', str(tmp_path / 'f.json'),
            '--report', str(tmp_path / 'f.md'), '--plots', str(out)]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert 'posterior Cramér–Rao bound' in text and 'real data: skipped' in text
    res = json.loads((tmp_path / 'f.json').read_text())
    assert {'summary', 'timing', 'conclusions'} <= set(res)
    assert sorted(p.name for p in out.iterdir()) == ['attitude_error.png', 'bias_convergence.png',
                                                     'nis.png']
    assert '![nis.png]' in (tmp_path / 'f.md').read_text()


def test_filter_bench_refuses_an_existing_output_without_force(tmp_path, capsys):
    """An existing output needs --force."""
    (tmp_path / 'f.json').write_text('{}')
    try:
        main(['--runs', '2', '--fixes', '2', '--json', str(tmp_path / 'f.json')])
    except SystemExit as exc:
        assert exc.code == 2
    else:
        raise AssertionError('no exit 2')
    assert 'exists' in capsys.readouterr().err
