"""reproduce_seeds in quick mode: the JSON schema the issue fixes, and the comparisons it reports.

Every comparison the report states is recomputed here from the numbers the JSON records (the
paper's published values and ours), independently of the report code."""
import json

import numpy as np
import pytest

from strapdown_ros.tkachenko import PAPER_000
from strapdown_ros.tools import reproduce_seeds


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    d = tmp_path_factory.mktemp("seeds")
    assert reproduce_seeds.main(["--only", "000,002,003", "--quick", "--json", str(d / "r.json"),
                                 "--report", str(d / "r.md"), "--plots", str(d / "plots")]) == 0
    return json.loads((d / "r.json").read_text()), (d / "r.md").read_text(), d


def _cd(rec):
    return np.r_[rec["dc"], rec["dd"]]


def test_000_schema(result):
    res, _, _ = result
    cases = res["000"]["cases"]
    assert set(cases) == {"unquantized", "quantized_raw", "quantized_centred"}
    for case in cases.values():
        for key in ("paper", "ours", "ours_as_printed", "ours_iterated", "ours_mc_mean", "ours_mc_std"):
            assert len(case[key]["w0"]) == 3 and len(case[key]["dc"]) == 9 and len(case[key]["dd"]) == 3
    for name, case in cases.items():       # the paper's column is the transcription, untouched
        assert case["paper"]["dc"] == PAPER_000[name]["dc"] and case["paper"]["dd"] == PAPER_000[name]["dd"]


def test_000_headline_is_rms_ratio_and_signs(result):
    """The headline numbers, recomputed from the error vectors: RMS(paper)/RMS(ours) and the count
    of components with the paper's sign; the report states them, not the largest ratio alone."""
    res, text, _ = result
    for name, case in res["000"]["cases"].items():
        ours, paper = _cd(case["ours"]), _cd(case["paper"])
        h = res["000"]["headline"][name]["ours"]
        assert h["rms_ratio"] == pytest.approx(np.sqrt(np.mean(paper ** 2) / np.mean(ours ** 2)), rel=1e-12)
        assert h["signs"] == int(np.sum(np.sign(ours) == np.sign(paper)))
        assert f"**{name}**: the paper's errors are {h['rms_ratio']:.2g}× ours in RMS" in text
        assert f"{h['signs']}/12 signs agree" in text
    un = res["000"]["headline"]["unquantized"]["ours"]
    assert un["rms_ratio"] > 5 and un["signs"] >= 9          # ~15× smaller, same signs mostly
    assert "within 2.9×" not in text


def test_000_iterated_unquantized_is_1000x_below_the_paper(result):
    res, _, _ = result
    c = res["000"]["cases"]["unquantized"]
    for k in ("dc", "dd"):
        for ours, paper in zip(c["ours_iterated"][k], c["paper"][k]):
            assert abs(ours) <= 1e-3 * abs(paper)


def test_000_ablations_rule_out_with_numbers(result):
    """Each ablation's verdict follows from its numbers: a knob that moves the RMS ratio by less
    than 5% is reported as ruled out with that percentage."""
    res, text, _ = result
    a = res["000"]["ablations"]
    base = a["baseline"]["rms_ratio"]
    assert base == pytest.approx(res["000"]["headline"]["unquantized"]["ours"]["rms_ratio"], rel=1e-12)
    # the profile's rates are constant on each step, so the integration scheme cannot matter
    for key in ("algorithm_1", "algorithm_4", "quadrature_trapezoid"):
        change = abs(a["knobs"][key]["rms_ratio"] / base - 1)
        assert change < 0.05
        assert f"ruled out: RMS ratio moves by {100 * change:.1f}%" in text
    assert "What remains" in text or "Candidate explanations" in text


def test_000_centring_sentence_computed(result):
    res, text, _ = result
    g = res["000"]["centring_gain"]
    gain = 1 - g["rms_c_centred"] / g["rms_c_raw"]
    assert f"({100 * abs(gain):.0f}% {'less' if gain > 0 else 'more'})" in text


def test_002_and_003_sections(result):
    res, text, _ = result
    r = res["002"]
    assert set(r["rms_000"]) == set(r["rms_002"]) == set(r["rms_002_adaptive"])
    assert all(v > 0 for v in r["rms_000"].values())
    assert res["003"]["claim_case1"]["0.01"]["algorithm_1_above_1e-3"]
    for needle in ("## 000", "## 002", "## 003", "Centring (5.5), Monte Carlo"):
        assert needle in text


def test_003_values_below_the_floor_are_marked(result):
    res, text, _ = result
    marked = 0
    for c in res["003"]["cases"]:
        for n, v in c["drift_deg_per_h"].items():
            below = abs(v) <= c["floor_deg_per_h"]
            assert c["at_floor"][n] == below
            marked += below
    assert text.count(" (floor) |") == marked
    assert f"{marked} of " in text


def test_plots_written_and_linked(result):
    _, text, d = result
    for name in ("seeds_000_errors.png", "seeds_000_centring.png", "seeds_000_ablations.png"):
        png = d / "plots" / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
        assert f"(plots/{name})" in text


def test_000_beyond_the_paper_gains_reported(result):
    res, text, _ = result
    b = res["000"]["beyond_paper"]
    assert {"raw", "centred", "centred+iter", "centred+weighted", "centred+iter+weighted"} <= set(b)
    assert b["centred+weighted"]["rms_c"] < b["centred"]["rms_c"] < b["raw"]["rms_c"]
    assert "Beyond the paper" in text


def test_registry_is_table_driven():
    """Every available section is one registry entry with its run/report functions present;
    sections whose module is absent are skipped, not fatal."""
    names = reproduce_seeds.section_names()
    assert {"000", "002", "003", "004"} <= set(names)
    for s in reproduce_seeds.sections():
        assert callable(s.fn(s.run)) and callable(s.fn(s.report))
    missing = reproduce_seeds.Section("999", "999", ".no_such_seed_module", "a", "b", None, lambda a: ())
    assert not missing.available()
