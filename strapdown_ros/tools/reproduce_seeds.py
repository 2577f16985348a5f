"""reproduce_seeds: rerun the experiments of the seed papers and set our numbers beside theirs.

    reproduce_seeds [--only 000,002,003,004] [--seeds N] [--json FILE] [--report FILE] [--plots DIR] [--quick]

* 000 (Tkachenko 1983, §6): the three published error sets — unquantized; σ = 2e-5 rad without
  centring; with centring — beside our first-order method (the paper's equations, coefficients
  evaluated exactly in w0; also as printed), our Gauss–Newton
  solution, and the Monte Carlo mean ± std over ``--seeds`` quantization seeds (the pulse
  generator's initial remainder).  Errors are estimate − truth in the paper's units.
* 002 (Ilyushenko 2009): the integral method on star-tracker data (B, s0 against truth and
  their σ), and its accuracy against the 000 estimator on the same data.
* 003 (coning, §2.3): the three cases, the thesis's claims (errors below 1e-3 °/h except
  algorithm 1 in case 1; the ranking) against our measured drift.
* 004 (boresight, §6): the σ_β pattern (6.0″ about the optical axis, 0.6″, 0.6″) from a
  simulated experiment with 004's sensor parameters.

Differences are explained in the report, not hidden.  No ROS imports.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

SECTIONS = ("000", "002", "003", "004")


def _vec(x):
    return [float(v) for v in np.asarray(x).ravel()]


# ------------------------------------------------------------------------------------- 000
def section_000(n_seeds: int) -> dict:
    from ..tkachenko import PAPER_000, monte_carlo_000, run_tkachenko_experiment

    quantum = 2e-5
    out = {"cases": {}, "notes": []}
    spec = {"unquantized": dict(quantum=0.0, mode="raw"),
            "quantized_raw": dict(quantum=quantum, mode="raw"),
            "quantized_centred": dict(quantum=quantum, mode="centred")}
    mc = monte_carlo_000(range(n_seeds), quantum, (("raw", False, False), ("centred", False, False),
                                                   ("raw", True, False), ("centred", True, False),
                                                   ("raw", False, True), ("centred", False, True),
                                                   ("centred", True, True)))
    for case, kw in spec.items():
        first = run_tkachenko_experiment(seed=None, **kw)                 # Δθ0 = 0, as the paper
        printed = run_tkachenko_experiment(seed=None, coefficients="printed", **kw)
        iterated = run_tkachenko_experiment(seed=None, iterate=True, **kw)
        rec = {"paper": {k: _vec(v) for k, v in PAPER_000[case].items()},
               "ours": {k: _vec(first[k]) for k in ("w0", "dc", "dd")},
               "ours_as_printed": {k: _vec(printed[k]) for k in ("w0", "dc", "dd")},
               "ours_iterated": {k: _vec(iterated[k]) for k in ("w0", "dc", "dd")}}
        if kw["quantum"] > 0:
            m = mc[kw["mode"]]
            e, wf = m["errors"], np.asarray(m["w0_final"])
            rec["ours_mc_mean"] = {"w0": _vec(wf.mean(0)), "dc": _vec(e[:, 3:12].mean(0)), "dd": _vec(e[:, 12:].mean(0))}
            rec["ours_mc_std"] = {"w0": _vec(wf.std(0, ddof=1)), "dc": _vec(e[:, 3:12].std(0, ddof=1)),
                                  "dd": _vec(e[:, 12:].std(0, ddof=1))}
            rec["ours_mc_rms"] = {"c": m["rms_c"], "c_scale_misalignment": m["rms_c_scale"], "c_bias": m["rms_c_bias"],
                                  "d": m["rms_d"]}
        else:   # no randomness without quantization: the single run is the distribution
            rec["ours_mc_mean"] = rec["ours"]
            rec["ours_mc_std"] = {k: [0.0] * len(v) for k, v in rec["ours"].items()}
        out["cases"][case] = rec
    raw, cen = mc["raw"], mc["centred"]
    # item 3 of the issue: what iteration (Gauss–Newton) and weighting by R(δz)⁻¹ gain
    out["beyond_paper"] = {k: {"rms_c": v["rms_c"], "rms_c_bias": v["rms_c_bias"], "rms_d": v["rms_d"],
                               "rms_w": v["w_rms"]} for k, v in mc.items()}
    mcp = monte_carlo_000(range(n_seeds), quantum, (("raw", False, False), ("centred", False, False)),
                          coefficients="printed")
    out["centring_gain"] = {"rms_c_raw": raw["rms_c"], "rms_c_centred": cen["rms_c"],
                            "printed_rms_c_raw": mcp["raw"]["rms_c"],
                            "printed_rms_c_centred": mcp["centred"]["rms_c"],
                            "rms_c_bias_raw": raw["rms_c_bias"], "rms_c_bias_centred": cen["rms_c_bias"],
                            "rms_d_raw": raw["rms_d"], "rms_d_centred": cen["rms_d"], "seeds": n_seeds}
    un = out["cases"]["unquantized"]
    paper_cd = np.abs(np.r_[un["paper"]["dc"], un["paper"]["dd"]])
    ratio = np.abs(np.r_[un["ours"]["dc"], un["ours"]["dd"]]) / paper_cd
    ratio_printed = np.abs(np.r_[un["ours_as_printed"]["dc"], un["ours_as_printed"]["dd"]]) / paper_cd
    out["unquantized_ratio_to_paper"] = {"ours": _vec(ratio), "ours_as_printed": _vec(ratio_printed)}
    rq = out["cases"]["quantized_raw"]
    q_ratio = np.array(rq["ours"]["dc"]) / np.array(rq["paper"]["dc"])
    g = out["centring_gain"]
    out["notes"] = [
        "'ours' is the first-order method of 000 — one linear least-squares solve of (2.7)/(5.7), no "
        "iteration — with its coefficients evaluated where the exact quaternion identity "
        "p° − q = w0 × (p° + q) puts them: the w0 columns at ½(p + p*), the c columns at the computed "
        "increment p*, the d columns at the reference p (derivation: strapdown_ros/tkachenko.py, "
        "'Where to evaluate the coefficients'). 'ours_as_printed' evaluates everything at p, as 000 prints. "
        "The two agree to first order; they differ in the second-order remainder.",
        "Unquantized, first order: max |ours|/|paper| over δc, δd = "
        f"{ratio.max():.2g} (δc{1 + int(np.argmax(ratio[:9]))}); per δc: "
        + ", ".join(f"{r:.2g}" for r in ratio[:9]) + ". With the printed coefficients the w0² term "
        "2w0 × (w0 × p*) stays in z and the least squares puts it into c: max ratio "
        f"{ratio_printed.max():.3g} (δc6 = {un['ours_as_printed']['dc'][5]:+.1e} against the paper's "
        f"{un['paper']['dc'][5]:+.1e}). The remaining first-order errors are w0·c and c² terms; their "
        "component pattern depends on details 000 does not give, so signs are not expected to match.",
        "Iterated (Gauss–Newton on the exact model): errors at round-off (~1e-15), far below 1/1000 of 000.",
        "Quantized single runs use Δθ0 = 0 as 000 (the Monte Carlo draws the initial remainder per seed). "
        "The quantization bias then dominates, and the raw first-order run matches the printed raw set: "
        "ours/paper for δc1…δc9 = " + ", ".join(f"{r:+.2f}" for r in q_ratio) + ".",
        f"Centring (5.5), Monte Carlo over {g['seeds']} seeds: RMS error of c "
        f"{100 * (1 - g['rms_c_centred'] / g['rms_c_raw']):.0f}% lower, of d "
        f"{100 * (1 - g['rms_d_centred'] / g['rms_d_raw']):.0f}% lower (000: 'the errors approach the "
        "unquantized values'). With the printed coefficients the w0² bias of c hides the gain on c "
        f"({100 * (1 - g['printed_rms_c_centred'] / g['printed_rms_c_raw']):.1f}%).",
        "Verified corrections to 000's §2/§5 print (test/test_tkachenko.py): (2.5) sign of p×(w+w0); "
        "q_F = −½Δθ in (5.2); z = z′ − δz in (5.4); R(q_K) = σ²/48, not σ²/12.",
    ]
    return out


# ------------------------------------------------------------------------------------- 002
def _c_errors_from_B(B, s0, c_true):
    """Map the integral method's B = I + M, s0 onto 000's c (scale, symmetric misalignment, bias)."""
    M = np.asarray(B) - np.eye(3)
    c = np.array([M[0, 0], M[1, 1], M[2, 2], 0.5 * (M[0, 1] + M[1, 0]), 0.5 * (M[1, 2] + M[2, 1]),
                  0.5 * (M[0, 2] + M[2, 0]), *np.asarray(s0)])
    return c - np.asarray(c_true)


def section_002(n_runs: int) -> dict:
    from ..integral_method import calibrate_from_measurements
    from ..tkachenko import TKACHENKO_C, estimate, simulate_000

    sigma = 1e-5                                           # rad, star tracker noise
    errs_000, errs_002, errs_002a, chi2, chi2a = [], [], [], [], []
    for seed in range(n_runs):
        # one data set: the §6 trajectory and gyro errors, a star tracker (no drift, d = 0) read
        # every 0.2 s; both estimators see the same increments and the same fixes
        sim = simulate_000(quantum=0.0, seed=seed, d=np.zeros(3), angle_noise=sigma, t_first=0.2)
        est = estimate(sim.meas, sim.h, sim.M0, sim.ref_q0, sim.ref_q, sim.epochs, angle_noise=sigma,
                       weighted=True, iterate=True)
        errs_000.append(est.x[3:12] - TKACHENKO_C)
        stamps = np.concatenate([[0.0], sim.h * sim.epochs])
        quats = np.vstack([sim.ref_q0[None], sim.ref_q])
        gyro_t = sim.h * np.arange(1, len(sim.meas) + 1)
        for neighbour, errs, ch in (("previous", errs_002, chi2), ("adaptive", errs_002a, chi2a)):
            r = calibrate_from_measurements(gyro_t, sim.meas, stamps, quats, camera_sigma=sigma,
                                            q_body_camera=sim.reference.mounting, steps_per_interval=1,
                                            neighbour=neighbour)
            errs.append(_c_errors_from_B(r.B, r.s0, TKACHENKO_C))
            ch.append(r.chi2_per_dof)
    e0, e2, e2a = np.array(errs_000), np.array(errs_002), np.array(errs_002a)
    groups = {"scale c1-3": slice(0, 3), "misalignment c4-6": slice(3, 6), "bias c7-9": slice(6, 9)}
    out = {"runs": n_runs, "star_tracker_sigma_rad": sigma, "fix_interval_s": 0.2,
           "rms_000": {g: float(np.sqrt(np.mean(e0[:, s] ** 2))) for g, s in groups.items()},
           "rms_002": {g: float(np.sqrt(np.mean(e2[:, s] ** 2))) for g, s in groups.items()},
           "rms_002_adaptive": {g: float(np.sqrt(np.mean(e2a[:, s] ** 2))) for g, s in groups.items()},
           "chi2_per_dof_002_mean": float(np.nanmean(chi2)), "chi2_per_dof_002_adaptive_mean": float(np.nanmean(chi2a)),
           "notes": ["Same data: 000 §6 trajectory and gyro errors c, a drift-free star tracker (σ = 1e-5 rad) "
                     "every 0.2 s; 000 estimator (iterated, weighted by the angle noise) and the 002 integral "
                     "method (3rd-order inversion, one interval per fix pair, model weighting). The integral "
                     "method estimates a general B (9) and s0; its errors are mapped onto 000's symmetric c "
                     "(the mean of the two off-diagonal entries).",
                     "The 3rd-order inversion of 002 uses the previous increment; the rate table of 000 jumps "
                     "exactly on fix epochs, where that makes a one-off error (χ²/dof ≈ 2). Taking the "
                     "neighbour on the side without a jump ('adaptive') removes it; with it the integral method "
                     "is more accurate than the 000 estimator on these data."]}
    out["ratio_002_over_000"] = {g: out["rms_002"][g] / out["rms_000"][g] for g in groups}
    out["ratio_002_adaptive_over_000"] = {g: out["rms_002_adaptive"][g] / out["rms_000"][g] for g in groups}
    return out


# ------------------------------------------------------------------------------------- 003
def section_003(duration: float) -> dict:
    from ..coning import SEED_ALGORITHMS
    from ..coning_analysis import measure_case
    from ..sensors import DEG_PER_HOUR

    names = list(SEED_ALGORITHMS)
    out = {"duration_s": duration, "cases": []}
    for (a, nu) in ((0.087, 1.0), (0.5, 1.0), (0.087, 0.5)):
        for step in (0.01, 0.001):
            r = measure_case(names, a, nu, step, duration)
            floor = 3 * max(r.floor.values())
            out["cases"].append({"alpha": a, "nu": nu, "step": step,
                                 "drift_deg_per_h": {n: r.drift[n] / DEG_PER_HOUR for n in names},
                                 "floor_deg_per_h": floor / DEG_PER_HOUR})
    claims = {}
    for step in (0.001, 0.01):
        c1 = next(c for c in out["cases"] if c["alpha"] == 0.087 and c["nu"] == 1.0 and c["step"] == step)
        d = c1["drift_deg_per_h"]
        claims[str(step)] = {"others_below_1e-3": all(abs(v) < 1e-3 for n, v in d.items() if n != "1"),
                             "algorithm_1_above_1e-3": abs(d["1"]) > 1e-3, "algorithm_1_deg_per_h": d["1"]}
    out["claim_case1"] = claims
    out["notes"] = ["003 publishes no drift table, only plots, the statement that in case 1 every algorithm "
                    "but (1) stays below 1e-3 °/h, and a ranking; doc/coning.md (coning_bench) has the full "
                    "comparison, including why the ranking does not hold."]
    return out


# ------------------------------------------------------------------------------------- 004
#: 004 §6: 12 rotations of the INS between static segments, heading within 50°…300°, pitch
#: within ±7°, roll within ±15° (its Fig. 1a); the order and sizes here are ours
TURNS_004 = [(2, 40.0), (0, 5.0), (2, 60.0), (1, 12.0), (2, -30.0), (0, -10.0),
             (2, 80.0), (1, -25.0), (2, -50.0), (0, 7.0), (2, 45.0), (1, 15.0)]


def experiment_004_pairs(seed: int, n_fixes: int = 73, interval: float = 21.0, _cache={}):
    """One run of a 004 §6-like experiment: 73 exposures 21 s apart, 200 Hz navigation-grade
    gyro (004 §6 values), camera 0.6″/0.6″/6″ looking up (β = 0: VF z, the optical axis, is MF z,
    the vertical), 12 turns (mostly in heading) between static segments, Earth rate on."""
    from ..boresight import camera_increment, gyro_increment
    from ..profiles import EARTH_RATE, STANDARD_GRAVITY, PiecewiseRateProfile, Segment
    from ..sensors import NAVIGATION_GRADE_GYRO
    from ..star_camera import StarCameraModel

    if "profile" not in _cache:
        span = n_fixes * interval + 5.0
        turn = 10.0
        hold = (span - len(TURNS_004) * turn) / (len(TURNS_004) + 1)
        segs = [Segment(hold)]
        for axis, deg in TURNS_004:
            r = np.zeros(3)
            r[axis] = np.radians(deg) / turn
            segs += [Segment(turn, r), Segment(hold)]
        lat = np.radians(55.75)
        _cache["profile"] = PiecewiseRateProfile(segs, earth_rate=EARTH_RATE * np.array([0.0, np.cos(lat), np.sin(lat)]),
                                                 gravity=(0.0, 0.0, STANDARD_GRAVITY))
        p = _cache["profile"]
        tg = np.arange(int(span * 200) + 1) / 200.0
        _cache["t"], _cache["u"] = tg[1:], p.delta_theta(tg[:-1], tg[1:])
    prof, t, u = _cache["profile"], _cache["t"], _cache["u"]
    rng = np.random.default_rng(seed)
    err = NAVIGATION_GRADE_GYRO.draw(rng)
    y = u @ (np.eye(3) + err.matrix).T + err.bias / 200.0 + rng.normal(0, err.random_walk * np.sqrt(1 / 200.0), u.shape)
    cam = StarCameraModel(boresight=np.zeros(3), interval=interval, seed=1000 + seed)
    fixes = cam.fixes(prof, n_fixes)
    pairs = []
    from ..boresight import IncrementPair
    for f0, f1 in zip(fixes[:-1], fixes[1:]):
        dq_i, E_i = gyro_increment(t, y, f0.stamp, f1.stamp, NAVIGATION_GRADE_GYRO)
        dq_c, E_c = camera_increment(f0.attitude, f0.covariance, f1.attitude, f1.covariance)
        pairs.append(IncrementPair(f0.stamp, f1.stamp, dq_i, dq_c, E_i, E_c))
    return pairs, np.zeros(3)


def section_004(runs: int) -> dict:
    from ..boresight import solve_boresight
    from ..sensors import ARCSEC

    paper = {"sigma_beta_arcsec": [6.0, 0.6, 0.6], "N": 73, "interval_s": 21.0}
    sig_u, sig_w, err_u, err_w = [], [], [], []
    for seed in range(runs):
        pairs, beta_true = experiment_004_pairs(seed)
        for weighted, sig, err in ((False, sig_u, err_u), (True, sig_w, err_w)):
            sol = solve_boresight(pairs, weighted=weighted,
                                  common_rotation_sigma=0.0 if not weighted else 3 * ARCSEC / np.sqrt(2))
            sig.append(np.sqrt(np.diag(sol.covariance_beta)) / ARCSEC)
            err.append((sol.beta - beta_true) / ARCSEC)
    out = {"paper": paper,
           "ours_unweighted_sigma_arcsec_mean": _vec(np.mean(sig_u, 0)),
           "ours_unweighted_rms_error_arcsec": _vec(np.sqrt(np.mean(np.square(err_u), 0))),
           "ours_weighted_sigma_arcsec_mean": _vec(np.mean(sig_w, 0)),
           "ours_weighted_rms_error_arcsec": _vec(np.sqrt(np.mean(np.square(err_w), 0))),
           "runs": runs,
           "notes": ["Simulated with 004 §6's sensor parameters (N = 73 exposures 21 s apart, T_IMU = 5 ms, "
                     "σ_φG = 3″, σ_kG = 1e-5, σ_wG = 0.0012°/√h, σ_bG = 0.007°/h, camera 0.6″/0.6″/6″ looking up) "
                     "on a trajectory like 004's Fig. 1a: 12 turns, mostly in heading (about the optical axis), "
                     "small pitch and roll changes. 004's trajectory is not published in full, so the pattern is "
                     "what can be compared, not the digits.",
                     "The pattern comes from the trajectory, not from the camera's anisotropy: turns about the "
                     "optical axis say nothing about a boresight rotation about that axis (004 §4.1), so with "
                     "mostly-heading turns the heading component is the weakly observed one.",
                     "004's σ_β are the residual-based P_β of §4.3, which cannot see errors common to all pairs; the "
                     "RMS errors here include the gyro-triad rotation (σ_φ/√2 ≈ 2.1″ per axis), which no boresight "
                     "estimator can remove (boresight_bench), so they cannot reach 0.6″."]}
    return out


# ---------------------------------------------------------------------------------- report
def report(res: dict) -> str:
    L = ["# Seed experiments reproduced", "", "Generated by `reproduce_seeds`; every number comes from that run.", ""]
    if "000" in res:
        r = res["000"]
        L += ["## 000 — gyro errors against a drifting reference (Tkachenko 1983, §6)", "",
              "Errors estimate − truth (w0: corrected attitude error w⁰ at t_f; dc, dd in the paper's units).", ""]
        for case, rec in r["cases"].items():
            L += [f"### {case}", "", "| | w0 ×1e-5 | δc1…δc9 | δd1…δd3 |", "|---|---|---|---|"]
            for key in ("paper", "ours", "ours_as_printed", "ours_iterated", "ours_mc_mean", "ours_mc_std"):
                v = rec[key]
                L.append(f"| {key} | " + " ".join(f"{x * 1e5:+.2f}" for x in v["w0"]) + " | "
                         + " ".join(f"{x:+.1e}" for x in v["dc"]) + " | " + " ".join(f"{x:+.1e}" for x in v["dd"]) + " |")
            L.append("")
        g = r["centring_gain"]
        L += [f"Centring (5.5) against raw, Monte Carlo over {g['seeds']} seeds: RMS of c "
              f"{g['rms_c_raw']:.2e} → {g['rms_c_centred']:.2e} "
              f"({100 * (1 - g['rms_c_centred'] / g['rms_c_raw']):.0f}% less), of the biases c7–9 {g['rms_c_bias_raw']:.2e} → "
              f"{g['rms_c_bias_centred']:.2e} ({100 * (1 - g['rms_c_bias_centred'] / g['rms_c_bias_raw']):.0f}% less), "
              f"of d {g['rms_d_raw']:.2e} → {g['rms_d_centred']:.2e} "
              f"({100 * (1 - g['rms_d_centred'] / g['rms_d_raw']):.0f}% less).", ""]
        L += [f"* {n}" for n in r["notes"]] + [""]
        b = r.get("beyond_paper")
        if b:
            base = b["raw"]
            L += [f"Beyond the paper (σ = 2e-5, Monte Carlo over {g['seeds']} seeds): RMS errors, and in brackets "
                  "the ratio to the paper's method without centring (raw, first order).", "",
                  "| method | c | c7–9 | d | w⁰ (attitude at the epochs) |", "|---|---|---|---|---|"]
            names = {"raw": "raw (5.4), first order", "centred": "centred (5.5), first order",
                     "raw+iter": "raw, Gauss–Newton", "centred+iter": "centred, Gauss–Newton",
                     "raw+weighted": "raw, weighted R(δz)⁻¹", "centred+weighted": "centred, weighted",
                     "centred+iter+weighted": "centred, Gauss–Newton, weighted"}
            for k, v in b.items():
                L.append(f"| {names.get(k, k)} | " + " | ".join(
                    f"{v[q]:.2e} ({v[q] / base[q]:.2f})" for q in ("rms_c", "rms_c_bias", "rms_d", "rms_w")) + " |")
            L += ["", "Iteration removes the linearisation error, which is small beside the quantization noise "
                  "here (unquantized it is the whole error: see above); weighting by R(δz)⁻¹ (000 §5) "
                  "takes the most off c.", ""]
    if "002" in res:
        r = res["002"]
        L += ["## 002 — integral method against the 000 estimator on the same data", "",
              "| parameters | RMS error, 000 estimator | integral method (002 as printed) | ratio | "
              "integral method, adaptive neighbour | ratio |", "|---|---|---|---|---|---|"]
        for gname in r["rms_000"]:
            L.append(f"| {gname} | {r['rms_000'][gname]:.2e} | {r['rms_002'][gname]:.2e} | "
                     f"{r['ratio_002_over_000'][gname]:.2f} | {r['rms_002_adaptive'][gname]:.2e} | "
                     f"{r['ratio_002_adaptive_over_000'][gname]:.2f} |")
        L += ["", f"{r['runs']} runs; integral method mean χ²/dof {r['chi2_per_dof_002_mean']:.2f} (as printed), "
              f"{r['chi2_per_dof_002_adaptive_mean']:.2f} (adaptive).", ""]
        L += [f"* {n}" for n in r["notes"]] + [""]
    if "003" in res:
        r = res["003"]
        L += [f"## 003 — coning, §2.3 ({r['duration_s']:g} s per case)", "",
              "| case | τ | " + " | ".join(r["cases"][0]["drift_deg_per_h"]) + " | floor |",
              "|---|---|" + "---|" * (len(r["cases"][0]["drift_deg_per_h"]) + 1)]
        for c in r["cases"]:
            L.append(f"| α={c['alpha']:g}, ν={c['nu']:g} | {c['step']:g} | "
                     + " | ".join(f"{v:.2e}" for v in c["drift_deg_per_h"].values()) + f" | {c['floor_deg_per_h']:.1e} |")
        L.append("")
        for step, cl in r["claim_case1"].items():
            L.append(f"* Case 1, τ = {step} s: every algorithm but (1) below 1e-3 °/h — "
                     f"{'holds' if cl['others_below_1e-3'] else 'does not hold'}; algorithm (1) above it — "
                     f"{'holds' if cl['algorithm_1_above_1e-3'] else 'does not hold'} "
                     f"({cl['algorithm_1_deg_per_h']:.2g} °/h).")
        L.append("")
        L += [f"* {n}" for n in r["notes"]] + [""]
    if "004" in res:
        r = res["004"]
        L += ["## 004 — boresight σ pattern, §6", "",
              "| | σ_ψ (optical axis) ″ | σ_ϑ ″ | σ_γ ″ |", "|---|---|---|---|",
              "| paper | " + " | ".join(f"{v:.1f}" for v in r["paper"]["sigma_beta_arcsec"]) + " |",
              "| ours, unit weights (as 004): mean published σ | " + " | ".join(f"{v:.2f}" for v in r["ours_unweighted_sigma_arcsec_mean"]) + " |",
              "| ours, unit weights: RMS error | " + " | ".join(f"{v:.2f}" for v in r["ours_unweighted_rms_error_arcsec"]) + " |",
              "| ours, weighted: mean published σ | " + " | ".join(f"{v:.2f}" for v in r["ours_weighted_sigma_arcsec_mean"]) + " |",
              "| ours, weighted: RMS error | " + " | ".join(f"{v:.2f}" for v in r["ours_weighted_rms_error_arcsec"]) + " |",
              ""]
        L += [f"* {n}" for n in r["notes"]] + [""]
    return "\n".join(L)


# ----------------------------------------------------------------------------------- plots
def write_plots(res: dict, outdir: str) -> list[str]:
    """PNG figures beside the report (matplotlib, from the ``tools`` extra).  Returns the paths."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(outdir, exist_ok=True)
    paths = []
    labels = [f"c{i}" for i in range(1, 10)] + [f"d{i}" for i in range(1, 4)]
    x = np.arange(len(labels))
    if "000" in res:
        cases = res["000"]["cases"]
        fig, axes = plt.subplots(1, 3, figsize=(15, 4.2), sharey=True)
        for ax, (case, rec) in zip(axes, cases.items()):
            def mag(key):
                return np.abs(np.r_[rec[key]["dc"], rec[key]["dd"]])
            ax.semilogy(x, mag("paper"), "ks", ms=7, label="000 (paper)")
            ax.semilogy(x, mag("ours"), "o", color="C0", label="ours, first order")
            ax.semilogy(x, mag("ours_as_printed"), "x", color="C3", ms=7, label="ours, printed coefficients")
            if any(v > 0 for v in rec["ours_mc_std"]["dc"]):
                rms = np.sqrt(np.square(np.r_[rec["ours_mc_mean"]["dc"], rec["ours_mc_mean"]["dd"]])
                              + np.square(np.r_[rec["ours_mc_std"]["dc"], rec["ours_mc_std"]["dd"]]))
                ax.semilogy(x, rms, "_", color="C2", ms=14, mew=2, label="ours, Monte Carlo RMS")
            ax.set_xticks(x, labels)
            ax.set_title(case)
            ax.grid(True, which="both", alpha=0.3)
        axes[0].set_ylabel("|estimate − truth| (c1–6: 1; c7–9, d: rad/s)")
        axes[0].legend(fontsize=8, loc="lower left")
        fig.suptitle("000 §6: estimation errors, paper against ours (iterated: ~1e-15, off scale)")
        fig.tight_layout()
        paths.append(os.path.join(outdir, "seeds_000_errors.png"))
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)
        g = res["000"]["centring_gain"]
        fig, ax = plt.subplots(figsize=(6.5, 4))
        groups = ["c", "c7–9 (biases)", "d"]
        raw = [g["rms_c_raw"], g["rms_c_bias_raw"], g["rms_d_raw"]]
        cen = [g["rms_c_centred"], g["rms_c_bias_centred"], g["rms_d_centred"]]
        xx = np.arange(3)
        ax.bar(xx - 0.2, raw, 0.4, label="raw (5.4)")
        ax.bar(xx + 0.2, cen, 0.4, label="centred (5.5)")
        for i in range(3):
            ax.annotate(f"−{100 * (1 - cen[i] / raw[i]):.0f}%", (xx[i] + 0.2, cen[i]), ha="center", va="bottom")
        ax.set_xticks(xx, groups)
        ax.set_ylabel("RMS error over seeds")
        ax.set_title(f"000 §6, σ = 2e-5: centring, Monte Carlo over {g['seeds']} seeds")
        ax.legend()
        fig.tight_layout()
        paths.append(os.path.join(outdir, "seeds_000_centring.png"))
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)
    if "004" in res:
        r = res["004"]
        fig, ax = plt.subplots(figsize=(6.5, 4))
        xx = np.arange(3)
        series = [("paper σ_β", r["paper"]["sigma_beta_arcsec"]),
                  ("ours, unit weights: mean σ", r["ours_unweighted_sigma_arcsec_mean"]),
                  ("ours, unit weights: RMS error", r["ours_unweighted_rms_error_arcsec"]),
                  ("ours, weighted: RMS error", r["ours_weighted_rms_error_arcsec"])]
        for k, (name, v) in enumerate(series):
            ax.bar(xx + (k - 1.5) * 0.2, v, 0.2, label=name)
        ax.set_xticks(xx, ["ψ (optical axis)", "ϑ", "γ"])
        ax.set_ylabel("arcsec")
        ax.set_title("004 §6: boresight σ pattern")
        ax.legend(fontsize=8)
        fig.tight_layout()
        paths.append(os.path.join(outdir, "seeds_004_sigma.png"))
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)
    return paths


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="reproduce_seeds", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", default=",".join(SECTIONS), help="comma-separated subset of 000,002,003,004")
    ap.add_argument("--seeds", type=int, default=100, help="Monte Carlo runs for 000 (≥ 100 for the record)")
    ap.add_argument("--runs", type=int, default=20, help="runs for the 002 and 004 sections")
    ap.add_argument("--coning-duration", type=float, default=600.0, help="seconds per coning case")
    ap.add_argument("--quick", action="store_true", help="few runs (for tests)")
    ap.add_argument("--json", help="write the results as JSON")
    ap.add_argument("--report", help="write a Markdown report")
    ap.add_argument("--plots", help="write PNG figures to this directory (needs matplotlib)")
    a = ap.parse_args(argv)
    only = [s.strip() for s in a.only.split(",") if s.strip()]
    bad = [s for s in only if s not in SECTIONS]
    if bad:
        ap.error(f"unknown section(s) {', '.join(bad)}; valid: {', '.join(SECTIONS)}")
    from .paths import check_output_dir, check_output_file
    try:                                       # everything that can fail, before minutes of work
        for flag, v in (("--seeds", a.seeds), ("--runs", a.runs)):
            if v < 1:
                raise ValueError(f"{flag} must be >= 1, got {v}")
        if not (np.isfinite(a.coning_duration) and a.coning_duration > 0):
            raise ValueError(f"--coning-duration must be > 0, got {a.coning_duration}")
        check_output_file(a.json, "--json")
        check_output_file(a.report, "--report")
        check_output_dir(a.plots, "--plots")
    except ValueError as exc:
        print(f"reproduce_seeds: error: {exc}", file=sys.stderr)
        return 2
    if a.quick:
        a.seeds, a.runs, a.coning_duration = min(a.seeds, 8), min(a.runs, 3), min(a.coning_duration, 60.0)
    res, t0 = {}, time.perf_counter()
    for s in only:
        t = time.perf_counter()
        res[s] = {"000": lambda: section_000(a.seeds), "002": lambda: section_002(a.runs),
                  "003": lambda: section_003(a.coning_duration), "004": lambda: section_004(a.runs)}[s]()
        res[s]["wall_s"] = time.perf_counter() - t
        print(f"[reproduce_seeds] {s}: {res[s]['wall_s']:.1f} s", file=sys.stderr)
    text = report(res)
    if a.plots:
        pngs = write_plots(res, a.plots)
        base = os.path.dirname(os.path.abspath(a.report)) if a.report else os.getcwd()
        text += "\n## Figures\n\n" + "\n".join(
            f"![{os.path.basename(pth)}]({os.path.relpath(os.path.abspath(pth), base)})" for pth in pngs) + "\n"
    print(text)
    if a.json:
        with open(a.json, "w", encoding="utf-8") as fh:
            json.dump(res, fh, indent=1, default=float)
    if a.report:
        with open(a.report, "w", encoding="utf-8") as fh:
            fh.write(text)
    print(f"[reproduce_seeds] total {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
