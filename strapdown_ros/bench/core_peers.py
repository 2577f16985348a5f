"""
The core attitude path beside its peers, for ``sins_bench``.

One run times, in turn,

* **A**, strapdown_ros: :class:`~strapdown_ros.attitude.integrator.AttitudeIntegrator` with the
  one-plus-previous coning term, covariance propagation included, pushed in 60 s blocks;
* **B**, pyins 1.0.1 (PyPI ``python-ins``, optional): the same coning term,
  θ_k + θ_{k−1} × θ_k / 12, computed as its ``compute_increments_from_imu`` does, and its
  numba-compiled integration kernel (which also integrates velocity and position; no
  covariance).  Its public API around the same kernel (``compute_increments_from_imu`` +
  ``Integrator.integrate``, pandas in and out) is timed too, for information;
* **C**, a compiled reference: the 20-line quaternion loop below, numba-compiled (optional):
  the same coning term, q ← q ⊗ exp(φ), renormalised; nothing else.

on the same 360 000 Δθ intervals (one hour at 100 Hz).  Compilation is excluded (one warm-up
call before timing).  Ratios A/B and A/C are formed within each run.
"""
from __future__ import annotations

import math
import time

import numpy as np

from strapdown_ros.attitude.integrator import AttitudeIntegrator
from strapdown_ros.rotation import quat_angle_between
from strapdown_ros.sensors import NAVIGATION_GRADE_GYRO


def _reference_loop():
    """Return the compiled reference loop (numba), or None without numba."""
    try:
        from numba import njit
    except ImportError:
        return None

    @njit(cache=False)
    def loop(theta, q0):                                   # pragma: no cover - compiled
        n = theta.shape[0]
        out = np.empty((n, 4))
        w, x, y, z = q0[0], q0[1], q0[2], q0[3]
        p0, p1, p2 = theta[0, 0], theta[0, 1], theta[0, 2]
        for k in range(n):
            a0, a1, a2 = theta[k, 0], theta[k, 1], theta[k, 2]
            f0 = a0 + (p1 * a2 - p2 * a1) / 12.0
            f1 = a1 + (p2 * a0 - p0 * a2) / 12.0
            f2 = a2 + (p0 * a1 - p1 * a0) / 12.0
            ang = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
            s = math.sin(0.5 * ang) / ang if ang > 1e-12 else 0.5
            dw, dx, dy, dz = math.cos(0.5 * ang), f0 * s, f1 * s, f2 * s
            w, x, y, z = (w * dw - x * dx - y * dy - z * dz, w * dx + x * dw + y * dz - z * dy,
                          w * dy - x * dz + y * dw + z * dx, w * dz + x * dy - y * dx + z * dw)
            r = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
            w, x, y, z = w * r, x * r, y * r, z * r
            out[k, 0], out[k, 1], out[k, 2], out[k, 3] = w, x, y, z
            p0, p1, p2 = a0, a1, a2
        return out
    return loop


def _pyins():
    try:
        import pandas as pd
        import pyins.strapdown as sd
    except ImportError:
        return None
    return pd, sd


def peer_runs(dth: np.ndarray, stamps: np.ndarray, q0: np.ndarray, runs: int = 5,
              block: int = 6000, progress=None) -> dict:
    """
    Time ``runs`` rounds of A, B and C in turn on the same increments.

    Parameters
    ----------
    dth : (n, 3) ndarray
        Gyro increments Δθ, rad.
    stamps : (n + 1,) ndarray
        Interval edges, s.
    q0 : (4,) ndarray
        Initial attitude, scalar-first quaternion.
    runs : int, optional
        Rounds.
    block : int, optional
        Increments per ``push`` of the strapdown_ros integrator.
    progress : callable, optional
        Called with one line of text per round.

    Returns
    -------
    dict
        ``intervals``, ``runs`` (per round: wall times in s, ratios, final attitude
        difference in rad), ``pyins_available``, ``compiled_loop_available``.

    """
    n = len(dth)
    loop = _reference_loop()
    pyins = _pyins()
    imu = pva = None
    if pyins is not None:
        pd, sd = pyins
        # pyins's increment convention: one extra "before" row; accelerometers zero (attitude only)
        data = np.zeros((n + 1, 6))
        data[1:, :3] = dth
        imu = pd.DataFrame(data, index=stamps,
                           columns=['gyro_x', 'gyro_y', 'gyro_z', 'accel_x', 'accel_y', 'accel_z'])
        pva = pd.Series({'lat': 50.45, 'lon': 30.52, 'alt': 0.0, 'VN': 0.0, 'VE': 0.0, 'VD': 0.0,
                         'roll': 0.0, 'pitch': 0.0, 'heading': 0.0})
        sd.Integrator(pva).integrate(sd.compute_increments_from_imu(imu.iloc[:100],
                                                                    'increment'))  # compile
    if loop is not None:
        loop(dth[:10], q0)  # compile
    AttitudeIntegrator('one_plus_previous', q0, stamps[0],
                       gyro=NAVIGATION_GRADE_GYRO).push(dth[:10], stamps[1:11])

    def a():
        integ = AttitudeIntegrator('one_plus_previous', q0, stamps[0],
                                   nominal_period=stamps[1] - stamps[0],
                                   gyro=NAVIGATION_GRADE_GYRO)
        t0 = time.perf_counter()
        for k in range(0, n, block):
            integ.push(dth[k:k + block], stamps[k + 1:k + block + 1])
        return time.perf_counter() - t0, integ.q

    def b():
        """
        Time pyins's compiled kernel alone.

        The coning term is computed as its ``compute_increments_from_imu`` does (numpy); its
        DataFrame wrapping is left out.
        """
        from pyins._numba_integrate import integrate
        t0 = time.perf_counter()
        gyro = np.vstack([np.zeros((1, 3)), dth])
        theta = gyro[1:] + np.cross(gyro[:-1], gyro[1:]) / 12
        lla = np.zeros((n + 1, 3))
        lla[0] = (50.45, 30.52, 0.0)
        vel = np.zeros((n + 1, 3))
        mat = np.empty((n + 1, 3, 3))
        mat[0] = np.eye(3)
        integrate(np.diff(stamps), lla, vel, mat, theta, np.zeros((n, 3)), 0, True)
        return time.perf_counter() - t0

    def b_api():
        pd, sd = pyins
        t0 = time.perf_counter()
        sd.Integrator(pva).integrate(sd.compute_increments_from_imu(imu, 'increment'))
        return time.perf_counter() - t0

    def c():
        t0 = time.perf_counter()
        q = loop(dth, q0)
        return time.perf_counter() - t0, q[-1]

    if pyins is not None:
        b()  # the kernel compiles for these argument types
    rows = []
    for r in range(runs):
        ta, qa = a()
        tb = b() if pyins is not None else math.nan
        tb_api = b_api() if pyins is not None else math.nan
        tc, qc = c() if loop is not None else (math.nan, None)
        row = {'strapdown_ros_s': ta, 'pyins_s': tb, 'pyins_api_s': tb_api, 'compiled_loop_s': tc,
               'ratio_to_pyins': ta / tb if math.isfinite(tb) else math.nan,
               'ratio_to_compiled': ta / tc if math.isfinite(tc) else math.nan}
        if qc is not None:        # the same attitude at the end (independent implementations)
            row['final_attitude_difference_rad'] = float(quat_angle_between(qa, qc))
        rows.append(row)
        if progress:
            progress(
                f'peer run {r + 1}/{runs}: A {ta:.3f} s, B {tb:.3f} s (API {tb_api:.3f} s), C'
                f' {tc:.4f} s'
            )
    return {'intervals': n, 'runs': rows, 'pyins_available': pyins is not None,
            'compiled_loop_available': loop is not None}
