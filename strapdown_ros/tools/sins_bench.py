"""sins_bench: performance figures of the SINS (printed; nothing is asserted).

1. Core: one hour of 100 Hz gyro and 300 Hz accelerometer increments (360 000 gyro
   intervals) through the chosen coning algorithm with covariance propagation and
   accelerometer binning, pushed in 60 s blocks.  Data generation is not timed.
2. Node (``--node-seconds S``, default 60; 0 skips): a separate ``sins_node`` process fed
   at ``--node-rate`` Hz (default 2000) over loopback; counts of accepted, dropped and
   missing messages from the node's /diagnostics, and outputs received back.

Both figures are printed with their ratio to real time.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from ..integrator import AttitudeIntegrator, IncrementAccumulator
from ..profiles import ConingProfile, STANDARD_GRAVITY
from ..sensors import NAVIGATION_GRADE_GYRO


def core_benchmark(algorithm: str = "2", hours: float = 1.0, covariance_model: str = "random_constant",
                   repeats: int = 3) -> dict:
    prof = ConingProfile(0.087, 1.0, gravity=(0.0, 0.0, STANDARD_GRAVITY))
    n_g = int(round(hours * 3600 * 100))
    tg = np.arange(n_g + 1) * 0.01
    ta = np.arange(3 * n_g + 1) / 300.0
    dth = prof.delta_theta(tg[:-1], tg[1:])
    dv = prof.delta_v(ta[:-1], ta[1:])
    block = 6000                                            # 60 s of gyro data
    best = np.inf
    for _ in range(repeats):
        integ = AttitudeIntegrator(algorithm, prof.attitude(0.0), 0.0, gyro=NAVIGATION_GRADE_GYRO,
                                   covariance_model=covariance_model)
        acc = IncrementAccumulator()
        t0 = time.perf_counter()
        for k in range(0, n_g, block):
            out = integ.push(dth[k:k + block], tg[k + 1:k + block + 1])
            acc.add(dv[3 * k:3 * (k + block)], ta[3 * k + 1:3 * (k + block) + 1])
            edges = np.concatenate([[out.stamps[0] - out.interval[0]], out.stamps])
            acc.take_many(edges)
        best = min(best, time.perf_counter() - t0)
    simulated = n_g * 0.01
    return {"algorithm": algorithm, "covariance_model": covariance_model, "gyro_intervals": n_g,
            "accel_intervals": 3 * n_g, "updates": integ.updates, "wall_s": best,
            "real_time_ratio": simulated / best, "ns_per_gyro_interval": best / n_g * 1e9,
            "final_sigma_arcsec": (np.sqrt(np.diag(integ.covariance())) * 206264.806).tolist()}


def main(argv=None):
    ap = argparse.ArgumentParser(prog="sins_bench", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--algorithm", default="2")
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--node-seconds", type=float, default=60.0)
    ap.add_argument("--node-rate", type=float, default=2000.0)
    ap.add_argument("--json", help="write the figures to this JSON file")
    args = ap.parse_args(argv)
    res = {"core": [core_benchmark(args.algorithm, args.hours, m) for m in ("random_constant", "004")]}
    for c in res["core"]:
        print(f"core  {c['algorithm']:>4} cov={c['covariance_model']:<15} {c['gyro_intervals']} gyro + "
              f"{c['accel_intervals']} accel intervals in {c['wall_s']:.3f} s "
              f"= {c['real_time_ratio']:.0f}× real time ({c['ns_per_gyro_interval']:.0f} ns per gyro interval)")
    if args.node_seconds > 0:
        from ..nodes.loopback_bench import run_loopback       # ROS only for this part
        n = run_loopback(args.node_rate, args.node_seconds, args.algorithm)
        res["node"] = n
        lost = n["sent"] - n["accepted_by_node"]
        print(f"node  sins_node fed {n['sent']} Δθ at {n['achieved_input_hz']:.0f} Hz for {n['send_wall_s']:.1f} s "
              f"(target {n['rate_hz']:.0f} Hz): accepted {n['accepted_by_node']}, lost {lost}, "
              f"dropped {n['dropped_in_node']}, missing {n['missing_in_node']}; outputs received "
              f"{n['attitude_outputs_received']}/{n['attitude_outputs_expected']}; "
              f"{n['achieved_input_hz'] / 100.0:.1f}× the real-time rate of a 100 Hz IMU")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(res, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
