"""strapdown_ros.reproductions.vasilyuk2024: quick run, report, plots and arguments."""
import json

import numpy as np
import pytest

from strapdown_ros.calibration.boresight_increments import IncrementPair
from strapdown_ros.reproductions import vasilyuk2024 as seeds_004
from strapdown_ros.reproductions.vasilyuk2024_report import plots_004_extras, report_004_extras
from strapdown_ros.rotation import rotvec_to_quat


@pytest.fixture(scope='module')
def quick():
    """Return the quick run of the 004 extras."""
    return seeds_004.section_004_extras(quick=True)


def test_quick_run_is_json_and_reports(quick):
    """The quick run is JSON-able; the report states its numbers; Fig. 3 flags the wrong one."""
    json.dumps(quick)
    text = report_004_extras(quick)
    assert text.startswith('### 004 ')
    assert '### 004 §6' in text
    rows = {r['name']: r for r in quick['ablation']}
    # every ratio printed in the explanation is one of the table's
    for r in rows.values():
        assert f"{r['ratio']:.1f}" in text
    # the Fig. 3 check: estimated boresight within its derived covariance, the wrong one flagged
    f = quick['fig3']
    assert f['estimated_derived']['consistent']
    assert not f['wrong_derived']['consistent']
    first = f['estimated_derived']['theta_arcsec'][0]
    assert first == [0.0, 0.0, 0.0] or np.allclose(first, 0, atol=1e-9)
    # the trajectory sets the pattern: smaller tilt turns raise σ_ψ/σ_(ϑ,γ)
    assert rows['tilts_x0.3']['ratio'] > 2 * rows['baseline']['ratio']


def test_trajectory_sigma_matches_the_heading_only_limit():
    """
    Check the trajectory-only σ against independent truth.

    Increments all about VF z leave rotation about z unobservable; with one tilt the ratio is
    the ratio of the 2(1 − cos φ) sums.
    """
    big, small = np.radians(60.0), np.radians(6.0)

    def mk(rv):
        q = rotvec_to_quat(np.array(rv))
        return IncrementPair(0, 1, q, q, np.eye(3), np.eye(3))

    pairs = [mk([0, 0, big]), mk([small, 0, 0]), mk([0, small, 0])]
    s = seeds_004.trajectory_sigma(pairs, np.zeros(3))
    # β_ψ ↔ VF z (D2 column [0, 0, −1] at β = 0): information 2·2(1 − cos small);
    # x: 2(1−cos big) + 2(1−cos small)
    iz = 2 * 2 * (1 - np.cos(small))
    ix = 2 * (1 - np.cos(big)) + 2 * (1 - np.cos(small))
    assert s[0] == pytest.approx(1 / np.sqrt(iz), rel=1e-9)
    assert (s[1] == pytest.approx(1 / np.sqrt(ix), rel=1e-9)
            and s[2] == pytest.approx(1 / np.sqrt(ix), rel=1e-9))


def test_plots(quick, tmp_path):
    """The declared figures are written, in the declared order."""
    pytest.importorskip('matplotlib')
    paths = plots_004_extras(quick, str(tmp_path))
    assert [p.rsplit('/', 1)[-1] for p in paths] == list(seeds_004.FIGURES)
    assert all((tmp_path / p.rsplit('/', 1)[-1]).stat().st_size > 1000 for p in paths)


def test_turn_conditioning_against_independent_truth():
    """
    Check the turn count against the normal matrix written out by hand.

    A 60° turn about z, 10° turns about x and y, two static 0.1° pairs: the normal matrix is
    diagonal, diag Σ 2(1 − cos φ)(I − k kᵀ), so every σ ratio is a square root of a ratio of
    sums.  No single turn reaches 1.5× of the full σ; the z turn with either tilt does.
    """
    def q(axis, deg):
        v = np.zeros(3)
        v[axis] = np.radians(deg)
        return rotvec_to_quat(v)
    dq = [q(2, 60.0), q(0, 10.0), q(1, 10.0), q(0, 0.1), q(1, 0.1)]
    r = seeds_004.turn_conditioning(dq, np.zeros(3))
    a, b, s = (2 * (1 - np.cos(np.radians(x))) for x in (60.0, 10.0, 0.1))
    full = np.array([1 + b + s, 1 + b + s, 2 * b + 2 * s])       # diag N over VF x, y, z
    two = np.array([1 + s, 1 + b + s, b + 2 * s])                # z turn and the x tilt
    assert r['turns'] == 3 and r['static'] == 2 and r['needed'] == 2
    assert sorted(r['steps'][1]['angles_deg']) == pytest.approx([10.0, 60.0])
    expected = np.sqrt(full / two)
    if r['steps'][1]['pairs'] == [0, 2]:                         # the y tilt instead: swap x, y
        expected = expected[[1, 0, 2]]
    # D1 at β = 0 maps VF (x, y, z) onto (γ, ϑ, ψ) up to signs
    assert sorted(r['steps'][1]['sigma_ratio']) == pytest.approx(sorted(expected), rel=1e-9)


def test_increment_angles_against_injected_errors():
    """Fig. 2's angle difference and σ: injected angle error and covariance along the axis."""
    k = np.array([0.0, 0.6, 0.8])
    E_c, E_i = np.diag([1.0, 4.0, 9.0]) * 1e-12, np.diag([2.0, 2.0, 2.0]) * 1e-12
    pairs = [IncrementPair(0.0, 21.0, rotvec_to_quat(k * 0.2), rotvec_to_quat(k * (0.2 + 1e-5)),
                           E_i, E_c)]
    sol = type('S', (), {'c_mf_vf': np.eye(3)})()
    g = seeds_004.increment_angles(pairs, sol)
    arcsec = np.radians(1 / 3600)
    assert g['diff_arcsec'][0] == pytest.approx(1e-5 / arcsec, rel=1e-6)
    var = k @ E_c @ k + k @ E_i @ k
    assert g['sigma_arcsec'][0] == pytest.approx(np.sqrt(var) / arcsec, rel=1e-9)
    assert g['turn'] == [True]


@pytest.mark.parametrize('args', [['--runs', '0'], ['--report', '/nonexistent/dir/r.md'],
                                  ['--bogus']])
def test_main_argument_errors(args, capsys):
    """Bad arguments and outputs exit 2 with one line named after the command."""
    assert seeds_004.main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('vasilyuk2024: ')
