"""reproduce_seeds in quick mode: the JSON schema the issue fixes, and the comparisons it reports."""
import json

import pytest

from strapdown_ros.tools import reproduce_seeds


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    d = tmp_path_factory.mktemp("seeds")
    assert reproduce_seeds.main(["--only", "000,002,003", "--quick", "--json", str(d / "r.json"),
                                 "--report", str(d / "r.md"), "--plots", str(d / "plots")]) == 0
    return json.loads((d / "r.json").read_text()), (d / "r.md").read_text(), d


def test_000_schema(result):
    res, _, _ = result
    cases = res["000"]["cases"]
    assert set(cases) == {"unquantized", "quantized_raw", "quantized_centred"}
    for case in cases.values():
        for key in ("paper", "ours", "ours_as_printed", "ours_iterated", "ours_mc_mean", "ours_mc_std"):
            assert len(case[key]["w0"]) == 3 and len(case[key]["dc"]) == 9 and len(case[key]["dd"]) == 3


def test_000_first_order_unquantized_within_10x_of_the_paper(result):
    res, text, _ = result
    c = res["000"]["cases"]["unquantized"]
    for k in ("dc", "dd"):
        for ours, paper in zip(c["ours"][k], c["paper"][k]):
            assert abs(ours) <= 10 * abs(paper)
    assert max(res["000"]["unquantized_ratio_to_paper"]["ours"]) <= 10
    assert "ours_as_printed" in text and "w0 × (p° + q)" in text


def test_000_iterated_unquantized_is_1000x_below_the_paper(result):
    res, _, _ = result
    c = res["000"]["cases"]["unquantized"]
    for k in ("dc", "dd"):
        for ours, paper in zip(c["ours_iterated"][k], c["paper"][k]):
            assert abs(ours) <= 1e-3 * abs(paper)


def test_002_and_003_sections(result):
    res, text, _ = result
    r = res["002"]
    assert set(r["rms_000"]) == set(r["rms_002"]) == set(r["rms_002_adaptive"])
    assert all(v > 0 for v in r["rms_000"].values())
    assert res["003"]["claim_case1"]["0.01"]["algorithm_1_above_1e-3"]
    for needle in ("## 000", "## 002", "## 003", "Centring (5.5) against raw"):
        assert needle in text


def test_plots_written_and_linked(result):
    _, text, d = result
    for name in ("seeds_000_errors.png", "seeds_000_centring.png"):
        png = d / "plots" / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
        assert f"(plots/{name})" in text


def test_000_beyond_the_paper_gains_reported(result):
    res, text, _ = result
    b = res["000"]["beyond_paper"]
    assert {"raw", "centred", "centred+iter", "centred+weighted", "centred+iter+weighted"} <= set(b)
    assert b["centred+weighted"]["rms_c"] < b["centred"]["rms_c"] < b["raw"]["rms_c"]
    assert "Beyond the paper" in text
