"""calibrate_bag: star-camera boresight C_MF^VF from a rosbag2 bag, offline and without ROS.

Reads ``imu/delta_theta`` (geometry_msgs/msg/Vector3Stamped) and the camera attitude — from
``star_camera/attitude_with_covariance`` (geometry_msgs/msg/PoseWithCovarianceStamped, rotation
block = camera covariance in VF axes) when the bag has it and ``use_camera_covariance`` is true,
otherwise from ``star_camera/attitude`` (geometry_msgs/msg/QuaternionStamped) with the assumed
``camera_sigma_xy``/``camera_sigma_z`` — and feeds the same ``BoresightCalibrator`` as
``calibrator_node``, in stamp order.  Topic names match with or without the leading slash, under
``--namespace`` when given; a bag with a single namespace is found without it.  MCAP and
sqlite3 storage (a bag directory or a single .mcap/.db3 file).  Other formats
(``strapdown_ros.recording``): ``--gyro-topic`` of sensor_msgs/msg/Imu rates (increments by
``--rate-rule``), ``--reference-topic`` of PoseStamped, PoseWithCovarianceStamped,
nav_msgs/msg/Odometry or QuaternionStamped, or TF with ``--reference-frames PARENT CHILD``.

Header stamps are the time base.  Input validation is ``calibrator_node``'s, per topic in bag
order: messages with NaN/Inf values, duplicate stamps or stamps older than the previous accepted
one are dropped and counted; a gyro gap (a step above 1.5/``gyro_rate``: increments missing, their
rotation lost) is counted and every increment pair spanning it is discarded; a camera quaternion
that is not unit is normalised, a zero one dropped; an all-zero camera covariance (ROS "unknown")
is replaced by the ``camera_sigma_*`` diagonal, one that is not positive semi-definite is dropped.

Output (``--json FILE``, also printed as a human summary)::

    {"q_mf_vf_xyzw": [x, y, z, w], "rotation_covariance_mf_rad2": 3×3, "beta_rad": [ψ, ϑ, γ],
     "beta_sigma_rad": [...], "covariance_rad2": 3×3, "pairs": n, "observable": bool,
     "unobservable_axes": [...], "residual_rms_rad": r, "weighted": bool, ...extra keys}

``q_mf_vf_xyzw`` is C_MF^VF (maps VF coordinates to MF coordinates) as a ROS quaternion;
``rotation_covariance_mf_rad2`` is the covariance of its error in MF axes (004 eq. 8);
``covariance_rad2`` that of β.  Not observable: those are null and the exit status is 3.
Exit status: 0 solved, 2 bad arguments/parameters/bag, 3 not observable, 4 no convergence.
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from ..calibrator import BoresightCalibrator
from ..config import CALIBRATOR_PARAMS, check_all, load_parameter_file
from ..rotation import to_ros_xyzw
# the reader moved to strapdown_ros.recording; its names stay importable from here
from ..recording import (CAMERA_COV_TOPIC, CAMERA_TOPIC, GYRO_TOPIC, Accepted,  # noqa: F401
                         BagError, add_input_arguments, check_input_arguments, input_lines,
                         input_options, input_summary, input_warnings, open_reader, read_bag,
                         resolve_topic)
from .record_sim import parse_overrides

__all__ = ["main", "read_bag", "calibrate", "calibrator_parameters", "make_calibrator", "solution_json", "BagError"]

ARCSEC_PER_RAD = 180.0 / np.pi * 3600.0
_resolve = resolve_topic          # the former private name (tools/sins_bag.py imports it)


# --- parameters -------------------------------------------------------------------------------
def calibrator_parameters(params_file: str | None = None, overrides: dict | None = None) -> dict:
    """calibrator_node parameters from a ROS 2 parameter YAML (+ overrides), validated."""
    raw = load_parameter_file(params_file, "calibrator_node") if params_file else {}
    raw.update(overrides or {})
    return check_all(CALIBRATOR_PARAMS, raw)


def make_calibrator(p: dict) -> BoresightCalibrator:
    """The calibrator exactly as built from calibrator_node parameters."""
    return BoresightCalibrator.from_params(p)


def calibrate(data: dict, p: dict):
    """Feed the calibrator as calibrator_node is fed — gyro and fixes interleaved in stamp order —
    and solve; returns (solution, calibrator, pairs discarded over gyro gaps and stamp jumps).
    The calibrator's buffer stays bounded on recordings of any length."""
    g, c = data["gyro"], data["camera"]
    t0 = min(g.stamps[0], c.stamps[0])                 # origin: float seconds keep ns resolution
    cal = make_calibrator(p)
    tg = (np.asarray(g.stamps, dtype=np.int64) - t0) * 1e-9
    vg = np.asarray(g.values, dtype=float).reshape(-1, 3)
    gaps = [((a - t0) * 1e-9, (b - t0) * 1e-9) for a, b in g.gaps]
    period = data.get("gyro_period_s") or 1.0 / float(p["gyro_rate"])
    h = 1.5 * period                                    # the in-interval polynomial reads the neighbours
    discarded = 0
    k = 0
    for ns, (q, P) in zip(c.stamps, c.values):
        t = (ns - t0) * 1e-9
        k1 = int(np.searchsorted(tg, t + 3 * period + abs(float(p["camera_time_offset"])), side="right"))
        if k1 > k:
            new_g = cal.add_gyro(tg[k:k1], vg[k:k1])
            k = k1
        else:
            new_g = 0
        new = new_g + cal.add_camera(t, q, P)
        if new and gaps:                               # as calibrator_node._discard_pairs_over_gaps
            tail = cal.pairs[len(cal.pairs) - new:]
            keep = [pr for pr in tail if not any(pr.t_start - h < b and a < pr.t_end + h for a, b in gaps)]
            discarded += len(tail) - len(keep)
            del cal.pairs[len(cal.pairs) - new:]
            cal.pairs.extend(keep)
    if k < len(tg):
        cal.add_gyro(tg[k:], vg[k:])
    return cal.solve(), cal, discarded


# --- output -----------------------------------------------------------------------------------------
def _num(x):
    x = float(x)
    return x if np.isfinite(x) else None


def _mat(m):
    return None if m is None else [[_num(v) for v in row] for row in np.asarray(m, dtype=float)]


def solution_json(sol, weighted: bool) -> dict:
    """The JSON record of a BoresightSolution (schema in the module docstring)."""
    ok = bool(sol.observable and sol.beta is not None)
    unobs = list(sol.unobservable_axes) if not ok else []
    if not ok and not unobs:                   # too few pairs: nothing is observable
        unobs = [f"rotation about VF axis ({', '.join('1.00' if i == j else '0.00' for j in range(3))})"
                 for i in range(3)]
    out = {
        "q_mf_vf_xyzw": [float(c) for c in to_ros_xyzw(sol.q_mf_vf)] if ok else None,
        "rotation_covariance_mf_rad2": _mat(sol.rotation_covariance_mf) if ok else None,
        "beta_rad": [float(b) for b in sol.beta] if ok else None,
        "beta_sigma_rad": [float(s) for s in np.sqrt(np.diag(sol.covariance_beta))] if ok else None,
        "covariance_rad2": _mat(sol.covariance_beta) if ok else None,
        "pairs": int(sol.pairs),
        "observable": ok,
        "unobservable_axes": unobs,
        "residual_rms_rad": _num(sol.residual_rms),
        "weighted": bool(sol.weighted if ok else weighted),
        # extra keys
        "message": sol.message,
        "converged": bool(sol.converged),
        "iterations": int(sol.iterations),
        "chi2_per_dof": _num(sol.chi2_per_dof),
    }
    rep = sol.observability
    if rep is not None:
        out["observability"] = {"eigenvalues": [_num(v) for v in rep.eigenvalues],
                                "predicted_sigma_rad": [_num(v) for v in rep.predicted_sigma],
                                "condition": _num(rep.condition), "weak": list(rep.weak)}
    return out


def _summary(bag: str, data: dict, result: dict, p: dict) -> str:
    g, c = data["gyro"], data["camera"]
    lines = [f"calibrate_bag: {bag}: {len(g.stamps)} Δθ from {data['gyro_topic']}, {len(c.stamps)} camera fixes "
             f"from {data['camera_topic']} ({'covariance from the bag' if data['camera_covariance_from_bag'] else 'assumed camera σ'})"]
    drops = {f"{k} {n}": v for k, d in result["dropped"].items() for n, v in d.items() if v}
    lines.append("  dropped: " + (", ".join(f"{k} {v}" for k, v in drops.items()) if drops else "none"))
    gg, fx = result["gyro_gaps"], result["camera_fixes"]
    if gg["gaps"]:
        lines.append(f"  GYRO GAPS: {gg['gaps']} gap(s), {gg['missing']} increment(s) missing (rotation lost); "
                     f"{gg['pairs_discarded']} pair(s) spanning them discarded")
    notes = [f"{n.replace('_', ' ')} {v}" for n, v in fx.items() if v and not isinstance(v, list)]
    if notes:
        lines.append("  camera fixes: " + ", ".join(notes))
    chi2 = result["chi2_per_dof"]
    lines.append(f"  pairs {result['pairs']}, {'weighted' if result['weighted'] else 'unweighted (004)'}, "
                 f"covariance model {p['covariance_model']}, "
                 + (f"{'converged' if result['converged'] else 'NOT converged'} in {result['iterations']} iterations, "
                    f"residual RMS {result['residual_rms_rad'] * ARCSEC_PER_RAD:.3g}″"
                    + (f", χ²/dof {chi2:.3g}" if chi2 is not None else "") if result["observable"] else "not observable"))
    if result["observable"]:
        names = ("heading ψ", "pitch ϑ", "roll γ")
        lines.append("  β: " + ", ".join(f"{n} {np.degrees(b):.6f}° ± {s * ARCSEC_PER_RAD:.3g}″"
                                        for n, b, s in zip(names, result["beta_rad"], result["beta_sigma_rad"])))
        sig_mf = np.sqrt(np.diag(result["rotation_covariance_mf_rad2"])) * ARCSEC_PER_RAD
        lines.append(f"  q_mf_vf (x, y, z, w) = [{', '.join(f'{v:.9f}' for v in result['q_mf_vf_xyzw'])}], "
                     f"σ about MF x, y, z = {', '.join(f'{s:.3g}' for s in sig_mf)}″")
    return "\n".join(lines)


def main(argv=None) -> int:
    from .paths import FILE, OneLineParser, check_outputs, write_json

    ap = OneLineParser(prog="calibrate_bag", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("bag", help="rosbag2 bag directory, or a .mcap / .db3 file")
    ap.add_argument("--params", metavar="FILE", help="ROS 2 parameter YAML (calibrator_node and /** blocks)")
    ap.add_argument("--json", metavar="FILE", help="write the result as JSON")
    ap.add_argument("--force", action="store_true", help="overwrite an existing --json file")
    ap.add_argument("--unweighted", action="store_true", help="unit weights, covariance from the residuals (004)")
    ap.add_argument("--covariance-model", choices=("004", "random_constant"),
                    help="gyro error model of E_imu (default: the parameter, random_constant)")
    ap.add_argument("--namespace", default="", help="topic namespace, e.g. /robot1")
    ap.add_argument("-p", "--param", action="append", default=[], metavar="NAME:=VALUE",
                    help="calibrator_node parameter override (repeatable)")
    add_input_arguments(ap)
    args = ap.parse_args(argv)
    try:
        check_input_arguments(args)
        over = parse_overrides(args.param)
        if args.unweighted:
            over["weighted"] = False
        if args.covariance_model:
            over["covariance_model"] = args.covariance_model
        p = calibrator_parameters(args.params, over)
        check_outputs([("--json", args.json, FILE)],
                      [("bag", args.bag), ("--params", args.params)], args.force)
        data = read_bag(args.bag, args.namespace, bool(p["use_camera_covariance"]),
                        (p["camera_sigma_xy"], p["camera_sigma_xy"], p["camera_sigma_z"]),
                        float(p["gyro_max_rate"]), float(p["max_stamp_jump"]),
                        int(p["resync_count"]), **input_options(args))
    except (ValueError, OSError, BagError) as exc:
        print(f"calibrate_bag: error: {exc}", file=sys.stderr)
        return 2
    for line in input_warnings("calibrate_bag", data):
        print(line, file=sys.stderr)
    for kind, want in (("gyro", p["frame_id"]), ("camera", p["reference_frame_id"])):
        other = [f for f in data["frames"][kind] if f != want]
        if other:
            print(f"calibrate_bag: warning: {kind} messages in frame {', '.join(map(repr, other))}, "
                  f"parameters expect {want!r}", file=sys.stderr)

    g, c = data["gyro"], data["camera"]
    if not g.stamps or not c.stamps:
        print(f"calibrate_bag: error: no usable {'gyro' if not g.stamps else 'camera'} messages", file=sys.stderr)
        return 2
    step = data["gyro_period_s"]
    if np.isfinite(step) and abs(step * float(p["gyro_rate"]) - 1.0) > 0.1:
        print(f"calibrate_bag: note: gyro stamps are {step:.6g} s apart ({1.0 / step:.6g} Hz); gaps are judged "
              f"against that, not gyro_rate = {p['gyro_rate']:g} Hz", file=sys.stderr)
    sol, cal, discarded = calibrate(data, p)
    result = solution_json(sol, bool(p["weighted"]))
    result["covariance_model"] = p["covariance_model"]
    result["dropped"] = {"gyro": dict(g.dropped),
                         "camera": {**c.dropped, "zero_quaternion": data["camera_fixes"]["zero_quaternion"],
                                    "bad_covariance": data["camera_fixes"]["bad_covariance"]}}
    result["gyro_gaps"] = {"gaps": len(g.gaps), "missing": g.missing, "pairs_discarded": discarded}
    result["stamp_resyncs"] = {"gyro": g.resyncs, "camera": c.resyncs}
    result["gyro_rate_from_stamps_hz"] = _num(1.0 / data["gyro_period_s"]) if np.isfinite(data["gyro_period_s"]) else None
    result["camera_fixes"] = {k: data["camera_fixes"][k] for k in ("normalised", "covariance_substituted")}
    result["camera_fixes"]["outliers_dropped"] = cal.outlier_fixes
    origin_s = min(g.stamps[0], c.stamps[0]) * 1e-9                     # calibrate()'s time origin
    result["camera_fixes"]["outlier_stamps_s"] = [float(t) + origin_s for t in cal.outlier_stamps]
    result["messages"] = {"gyro": len(g.stamps), "camera": len(c.stamps)}
    result["topics"] = {"gyro": data["gyro_topic"], "camera": data["camera_topic"]}
    result["camera_covariance_from_bag"] = data["camera_covariance_from_bag"]
    result["input"] = input_summary(data)
    result["unread_messages"] = dict(data["unread_messages"])
    if data["rate_samples"]:
        result["dropped"]["gyro_rate_samples"] = dict(data["rate_samples"]["dropped"])
    print(_summary(args.bag, data, result, p))
    print("\n".join(input_lines(result["input"])))
    if args.json:
        try:
            write_json(args.json, result, indent=2)
        except (OSError, ValueError) as exc:
            print(f"calibrate_bag: error: {exc}", file=sys.stderr)
            return 2
    if not result["observable"]:
        advice = ("Record rotations about at least two non-parallel axes between camera exposures."
                  if sol.pairs >= 2 else "Needs two camera fixes whose interval the gyro data covers without a gap.")
        print(f"calibrate_bag: boresight NOT observable from this bag: {sol.message}; unobservable: "
              f"{'; '.join(result['unobservable_axes'])}.  {advice}", file=sys.stderr)
        return 3
    if not result["converged"]:
        print(f"calibrate_bag: warning: {sol.message}", file=sys.stderr)
        return 4
    return 0


if __name__ == "__main__":
    sys.exit(main())
