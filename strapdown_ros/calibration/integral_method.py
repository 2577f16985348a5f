"""
Integral method of gyro calibration from star-tracker attitudes (Ilyushenko 2009; paper 002).

Sensor model (002, "Модель ДУС")::

    s = B·w + s0                       B 3×3, s0 3-vector: 12 parameters

with s the measured rate signal and w the true body rate (body axes).  Our integrating gyro
(:class:`~strapdown_ros.sensors.IntegratingSensor`) outputs Δθ = (I+M)·u + b·T + noise, i.e.
s = (I+M)·w + b, so **B = I + M and s0 = b** (:meth:`IntegralResult.to_error_model`).

Averaging the model over an interval [t0, t1] (002 eq. (2)/(3)) gives, exactly,

    B·w̄ + s0 = s̄,     w̄ = ∫w dt / T,   s̄ = ∫s dt / T,   T = t1 − t0,

one vector equation (three scalar ones) per interval.  s̄ is the sum of the gyro increments
over the interval divided by T (:func:`mean_measured_rate`); w̄ is recovered from the
star-tracker attitudes a_n = q_ref_body(t_n) by inverting a quaternion integration formula
step by step (:func:`step_increments`, :func:`mean_true_rate`).  K ≥ 4 intervals with
affinely independent w̄ give the 12 parameters by linear least squares
(:func:`integral_calibration`); :func:`calibrate_from_measurements` runs the whole chain on
raw gyro increments and camera fixes.

Inversion formulas (002, "Определение средних векторов ..."), as verified here
-------------------------------------------------------------------------------
Kinematics 2ȧ = a∘w (body rate multiplied on the right, our ``q_k = q_{k−1} ⊗ exp(φ_k)``);
V_n = ∫_{t_{n−1}}^{t_n} w dt; Δa_n = a_{n−1}⁻¹ ∘ a_n (the inverse sign is lost in the print; for
the unit quaternions of a star tracker it is the conjugate; with the *inverse* the printed
|V_n|² = −8·scal(Δa_n) + 12 − 4|a_{n−1}|² is exact for the norm-corrected integration, with the
conjugate only to first order in |a|² − 1 — tested).  The scalar part of Δa_n is made ≥ 0,
i.e. each step is taken as the shortest rotation.

* Second order, the modified Euler formula with norm correction
  ``a_n = a_{n−1}∘(1 + ½V_n − ⅛|V_n|² + ½(1 − |a_{n−1}|²))``, inverted:
  **V_n = 2·vect(Δa_n)**.  Per step this misses the coning term ½∫θ×w dt and the
  −|V|²V/24 of sin(φ/2), both O(h³), so the mean rate is accurate to **O(h²)** (slope measured on exact
  coning in test/calibration/test_integral_method.py).
* Third order, the printed forward formula
  ``a_n = a_{n−1}∘(1 + ½V_n − ⅛|V_n|² + (1/24)[V_n × ∇V_n] − (1/48)|V_n|²V_n + ½(1 − |a_{n−1}|²))``
  with ∇V_n = V_n − V_{n−1} (the print's V²_n = V¹_n − V¹_{n−1}), so
  V_n × ∇V_n = V_{n−1} × V_n: the coning correction of the "one plus previous" algorithm
  φ ≈ V_n + (1/12)V_{n−1}×V_n, halved in the quaternion.  Every coefficient of this print
  (½, −⅛, 1/24, −1/48 and the operand order) is confirmed: integrated forward with exact V
  it is of third order (:func:`forward_step`, tested), and with the operands reversed it
  drops to second order with twice the error of the second-order formula.  Its vector part
  is linear in V_n once |V_n|² is taken from the scalar part (the print's
  |V_n|² = −8·scal(Δa_n) + 12 − 4|a_{n−1}|², i.e. 8(1 − scal) for unit quaternions):

      24·vect(Δa_n) = c·V_n + V_{n−1} × V_n,      c = 12 − ½|V_n|²,

  a 3×3 system (cI + [p×])V = b, p = V_{n−1}, b = 24·vect(Δa_n), whose closed-form solution
  is **V_n = (c²b + (p·b)p − c·p×b) / (c(c² + |p|²))**.  The printed closed form of the
  inversion (with "12 − 0,5|V|²", "11/24", "1/96") is illegible in the scan; the formula
  above is the exact algebraic inverse of the (verified) forward formula — a round trip
  through :func:`forward_step` reproduces V to round-off (1e-15).  The mean rate is accurate to
  **O(h³)** on any interval (slope measured on exact coning in the tests); over whole cone periods
  the periodic terms cancel and the cone-axis error falls to O(h⁴) (the (Ωh)⁴/60 drift of the
  one-plus-previous coning algorithm, 003 table), the cross-axis error to O(h⁵).
  For the first step of a run (no V_{n−1}) the next increment is used instead:
  (1/12)V_n × V_{n+1} has the same leading term for a rate linear in time.
  The paper's recursion uses the *computed* V_{n−1}; here it is evaluated by vectorised
  fixed-point passes (each multiplies the difference from the recursion by ~|V|/12; 4–6
  passes at |V| ≈ 0.05 rad), which equal the sequential recursion to round-off (tested).
* ``form="rotvec"`` (not in the paper) replaces 2·vect(Δa) and the |V|² terms by the exact
  rotation vector log(Δa): same orders, slightly different constants.

Rate jumps.  The orders assume a smooth rate.  At a jump of the rate from ω_A to ω_B (the
piecewise-constant profiles of this package, thruster pulses) falling a fraction f into a
step, the exact coning term of the steps around it totals ½f(1−f)h²·ω_A×ω_B, which the
order-2 formula ignores and the paper's order-3 correction replaces by (1/12)h²·ω_A×ω_B
whatever f is: a one-off angle error of at most h²|ω_A×ω_B|/12 per jump (zero on average
over f).  ``neighbour="adaptive"`` (not in the paper) takes the correction from the neighbour
closer to V_n; it is exact when the jumps fall on fixes (f = 0, as in the simulated 000
profile on a 0.1-s camera grid) but, averaged over f, worse than the paper's choice (both are
measured in test/calibration/test_integral_method.py), so the paper's choice is the default.  On smooth
motion both are of order 3.

What the inversion error costs in the calibration is measured without noise by
``test_noise_free_bias_of_B_by_order``: the orders carry over to B and s0, and at the rates of
the package's profiles order 2 biases B by about one σ of a 1e-5-rad camera, so order 3 is
the default.

Noise and covariance
--------------------
Camera fixes a_n carry a right-perturbation θ_n (camera axes, :class:`StarCameraModel`).
To first order δV_n = (cI + [v×])θ_n + (−cI + [v×])θ_{n−1} with (c, v) = Δa_n
(the second-order Jacobian; the third-order terms change it by O(|V|/12)), so within an
interval the noise of the interior fixes almost cancels (telescopes) and consecutive
intervals that share a boundary fix have *correlated* errors (correlation ≈ −½).  The model
weighting (``weighting="model"``) builds that full covariance of the stacked equations,
camera part through the Jacobians and gyro part σ_rw²·overlap/(T_i T_j), and solves by
generalised least squares — honest for any interval layout (Monte Carlo in the tests).
The residual weightings (``"residual"`` per axis, ``"pooled"``) are the textbook
σ²(AᵀA)⁻¹ of 002's unweighted system; they assume independent, equally noisy intervals,
which holds for disjoint intervals of equal length; with consecutive intervals they are
conservative (the shared-boundary noise telescopes); the Monte Carlo of the tests checks RMS
error against the reported σ for each weighting and layout.  Not modelled:
pulse quantization of the gyro and the partial gyro intervals at unaligned interval ends.

Errors-in-variables: w̄ is a noisy regressor; the attenuation bias of B is about
σ_w̄²/mean(w̄²) (≈ 1e-9 relative for 1e-5 rad camera noise over 1-s intervals at 0.1 rad/s),
negligible here and not corrected.  Where 002 stands against the 000 estimator on the same data
is measured by ``reproduce_seeds --only 002`` (doc/seeds/reproduce_seeds.md).  The figures the
tests measured (orders, jump errors, noise-free bias, σ honesty) are listed in
doc/integral_method.md.

Observability (001) is reported through :func:`~strapdown_ros.estimation.observability.analyze_information`
on the information matrix of the 12 parameters, with s0 expressed in units of the RMS mean
rate so that one σ limit applies to all (labels ``B11 … B33, s0_1 … s0_3``).  A trajectory
whose mean rates all share one direction u leaves B·(directions ⊥ u) unobservable (6
combinations), and with a single rate magnitude also B·u against s0 (3 more).

No ROS imports; numpy only (plus the package's numpy-only modules).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from strapdown_ros.estimation.observability import analyze_information, ObservabilityReport
from strapdown_ros.rotation import (quat_conjugate, quat_multiply, quat_normalize, quat_to_dcm,
                                    quat_to_rotvec, skew)
from strapdown_ros.sensors import SensorErrorModel

__all__ = ['PARAMETER_LABELS', 'forward_step', 'invert_step', 'step_increments', 'interval_boundaries',
           'mean_true_rate', 'mean_measured_rate', 'camera_rate_covariance', 'gyro_rate_covariance',
           'IntervalMeans', 'IntegralResult', 'integral_calibration', 'calibrate_from_measurements',
           'design_matrix']

#: parameter order of x, covariance and sigma: B row by row, then s0
PARAMETER_LABELS = tuple(f'B{i}{j}' for i in (1, 2, 3) for j in (1, 2, 3)) + ('s0_1', 's0_2', 's0_3')

ORDERS = (2, 3)
FORMS = ('paper', 'rotvec')


# ------------------------------------------------------------------ quaternion formulas
def forward_step(a_prev: np.ndarray, V: np.ndarray, V_prev: np.ndarray | None = None, order: int = 2,
                 reverse_cross: bool = False) -> np.ndarray:
    """
    002's modified Euler step with norm correction: a_n from a_{n−1} and V_n = ∫w dt.

    order 2: ``a_{n−1}∘(1 + ½V − ⅛|V|² + ½(1 − |a_{n−1}|²))``;
    order 3: adds ``(1/24)V_n × (V_n − V_{n−1}) − (1/48)|V_n|²V_n`` (needs ``V_prev``).
    ``reverse_cross`` swaps the operands of the cross product (a hypothesis the tests reject).
    Not normalised: the norm correction keeps |a| near 1, as in the paper.  Vectorised.
    """
    a_prev = np.asarray(a_prev, dtype=float)
    V = np.asarray(V, dtype=float)
    v2 = np.sum(V * V, axis=-1, keepdims=True)
    a2 = np.sum(a_prev * a_prev, axis=-1, keepdims=True)
    scal = 1.0 - v2 / 8.0 + 0.5 * (1.0 - a2)
    vec = 0.5 * V
    if order == 3:
        if V_prev is None:
            raise ValueError('order 3 needs V_prev (the previous increment)')
        cross = np.cross(V, V - np.asarray(V_prev, dtype=float))
        vec = vec + (-cross if reverse_cross else cross) / 24.0 - v2 * V / 48.0
    elif order != 2:
        raise ValueError(f'order must be 2 or 3, got {order!r}')
    return quat_multiply(a_prev, np.concatenate([scal, vec], axis=-1))


def _solve_third_order(b: np.ndarray, c: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Solve (c·I + [p×])·V = b for V, row-wise: V = (c²b + (p·b)p − c·p×b)/(c(c² + |p|²))."""
    c = c[..., None]
    pb = np.sum(p * b, axis=-1, keepdims=True)
    pp = np.sum(p * p, axis=-1, keepdims=True)
    return (c * c * b + pb * p - c * np.cross(p, b)) / (c * (c * c + pp))


def invert_step(delta_a: np.ndarray, V_prev: np.ndarray | None = None, order: int = 3,
                form: str = 'paper', norm2_prev=1.0) -> np.ndarray:
    """
    V_n = ∫w dt from the relative quaternion Δa_n = a_{n−1}⁻¹∘a_n, vectorised.

    order 2: 2·vect(Δa).  order 3: the exact inverse of :func:`forward_step` (order 3),
    ``V = (c²b + (p·b)p − c·p×b)/(c(c² + |p|²))`` with b = 24·vect(Δa), c = 12 − ½|V|²,
    p = V_prev and the printed |V|² = −8·scal(Δa) + 12 − 4|a_{n−1}|² (``norm2_prev`` = |a_{n−1}|²,
    1 for star-tracker quaternions).  ``form="rotvec"``: log(Δa) − (1/12)V_prev×log(Δa).
    Δa is used as given (not normalised), so a round trip through :func:`forward_step` is exact.
    """
    dq = np.asarray(delta_a, dtype=float)
    if order not in ORDERS:
        raise ValueError(f'order must be one of {ORDERS}, got {order!r}')
    if form not in FORMS:
        raise ValueError(f'form must be one of {FORMS}, got {form!r}')
    V0 = quat_to_rotvec(dq) if form == 'rotvec' else 2.0 * dq[..., 1:]
    if order == 2:
        return V0
    if V_prev is None:
        raise ValueError('order 3 needs V_prev (the previous increment)')
    p = np.broadcast_to(np.asarray(V_prev, dtype=float), V0.shape)
    if form == 'rotvec':
        return V0 - np.cross(p, V0) / 12.0
    v2 = -8.0 * dq[..., 0] + 12.0 - 4.0 * np.asarray(norm2_prev, dtype=float)
    return _solve_third_order(24.0 * dq[..., 1:], 12.0 - 0.5 * v2, p)


def _relative_quats(quats: np.ndarray) -> np.ndarray:
    q = quat_normalize(np.asarray(quats, dtype=float))
    dq = quat_multiply(quat_conjugate(q[:-1]), q[1:])
    return np.where(dq[:, :1] < 0.0, -dq, dq)                 # shortest rotation per step


def step_increments(quats: np.ndarray, order: int = 3, form: str = 'paper',
                    breaks: np.ndarray | None = None, neighbour: str = 'previous',
                    max_passes: int = 30) -> np.ndarray:
    """
    ∫w dt over each star-tracker step, (N−1, 3), from N attitudes q_ref_body (scalar-first).

    order 2: V_n = 2·vect(a_{n−1}*∘a_n); order 3: the inverse of 002's third-order formula
    (module docstring).  ``form="rotvec"`` uses log(a_{n−1}*∘a_n) instead of 2·vect and drops
    the |V|² factor.  ``breaks`` (bool, N−1): steps not to be used as a neighbour of the
    coning correction (e.g. across a data gap); a step whose previous one is a break (or the
    first step) takes its correction from the next step.

    ``neighbour``: ``"previous"`` is the paper (V_{n−1}; the next step only where no previous
    one exists); ``"adaptive"`` takes whichever of V_{n−1}, V_{n+1} differs less from V_n
    (module docstring, *Rate jumps*: exact when the jumps fall on fixes, worse on average
    otherwise).
    """
    if order not in ORDERS:
        raise ValueError(f'order must be one of {ORDERS}, got {order!r}')
    if form not in FORMS:
        raise ValueError(f'form must be one of {FORMS}, got {form!r}')
    dq = _relative_quats(quats)
    n = len(dq)
    if n == 0:
        return np.zeros((0, 3))
    V0 = invert_step(dq, order=2, form=form)
    if order == 2:
        return V0
    brk = np.zeros(n, dtype=bool) if breaks is None else np.asarray(breaks, dtype=bool).reshape(n)
    # neighbour used by the coning correction: previous step, else the next one
    has_prev = np.zeros(n, dtype=bool)
    has_prev[1:] = ~brk[:-1] & ~brk[1:]
    has_next = np.zeros(n, dtype=bool)
    has_next[:-1] = ~brk[1:] & ~brk[:-1]
    use_next = ~has_prev & has_next
    if neighbour == 'adaptive':
        both = has_prev & has_next
        d_prev = np.full(n, np.inf)
        d_next = np.full(n, np.inf)
        d_prev[1:] = np.linalg.norm(V0[1:] - V0[:-1], axis=1)
        d_next[:-1] = np.linalg.norm(V0[1:] - V0[:-1], axis=1)
        swap = both & (d_next < d_prev)
        use_next |= swap
        has_prev = has_prev & ~swap
    elif neighbour != 'previous':
        raise ValueError(f"neighbour must be 'adaptive' or 'previous', got {neighbour!r}")

    def neighbour(V):
        # (1/12)V_{n−1}×V_n with p = V_{n−1}, or (1/12)V_n×V_{n+1} = (1/12)(−V_{n+1})×V_n
        p = np.zeros_like(V)
        p[1:][has_prev[1:]] = V[:-1][has_prev[1:]]
        p[:-1][use_next[:-1]] = -V[1:][use_next[:-1]]
        return p

    V = V0 if form == 'rotvec' else V0 * (1.0 + 8.0 * (1.0 - dq[:, :1]) / 24.0)   # start: the |V|² term
    for _ in range(max(1, max_passes)):                    # fixed point of the recursion
        V_new = invert_step(dq, neighbour(V), order=3, form=form)   # p = 0 where no neighbour exists
        done = np.max(np.abs(V_new - V)) <= 1e-16 * max(float(np.max(np.abs(V_new))), 1e-300)
        V = V_new
        if done:
            break
    return V


def noise_jacobians(quats: np.ndarray):
    """∂V_n/∂θ_n and ∂V_n/∂θ_{n−1} for right-perturbations θ of the fixes (second-order form)."""
    dq = _relative_quats(quats)
    c = dq[:, 0][:, None, None]
    S = skew(dq[:, 1:])
    I3 = np.eye(3)
    return c * I3 + S, -c * I3 + S


# ------------------------------------------------------------------ intervals and means
def interval_boundaries(stamps: np.ndarray, steps_per_interval: int | None = None,
                        interval_length: float | None = None, gap_factor: float = 3.0) -> np.ndarray:
    """
    Consecutive averaging intervals as fix-index pairs (K, 2): interval i spans fixes a..b.

    Either ``steps_per_interval`` (camera steps per interval) or ``interval_length`` (s; an
    interval ends at the first fix at least that long after its start).  Steps longer than
    ``gap_factor`` × the median step are data gaps: no interval spans one.
    """
    stamps = np.asarray(stamps, dtype=float)
    if len(stamps) < 2:
        return np.zeros((0, 2), dtype=int)
    if (steps_per_interval is None) == (interval_length is None):
        raise ValueError('give exactly one of steps_per_interval and interval_length')
    dt = np.diff(stamps)
    if np.any(dt <= 0):
        raise ValueError('camera stamps must be strictly increasing')
    gap = dt > gap_factor * np.median(dt)
    out = []
    a, n = 0, len(stamps)
    while a < n - 1:
        if gap[a]:
            a += 1
            continue
        b, full = a, False
        while b < n - 1 and not gap[b]:
            b += 1
            if (steps_per_interval is not None and b - a >= steps_per_interval) or \
                    (interval_length is not None and stamps[b] - stamps[a] >= interval_length * (1 - 1e-9)):
                full = True
                break
        if full:
            out.append((a, b))
        a = b                          # a short remainder before a gap or the end is dropped
    return np.array(out, dtype=int).reshape(-1, 2)


def mean_true_rate(stamps: np.ndarray, quats: np.ndarray, intervals=None, order: int = 3,
                   form: str = 'paper', steps_per_interval: int | None = None,
                   interval_length: float | None = None, gap_factor: float = 3.0,
                   neighbour: str = 'previous'):
    """
    Mean true body rate w̄ over averaging intervals, from star-tracker attitudes.

    ``intervals``: fix-index pairs (K, 2) (default: :func:`interval_boundaries` with
    ``steps_per_interval`` or ``interval_length``; one step per interval if neither is given).
    Returns ``(t0 (K,), t1 (K,), w̄ (K, 3), intervals (K, 2))``;
    w̄_i = Σ_{n=a+1}^{b} V_n / (t_b − t_a).  Steps longer than ``gap_factor`` × the median
    step are data gaps: the coning correction does not reach across them (explicit
    ``intervals`` must not span one).
    """
    stamps = np.asarray(stamps, dtype=float)
    if intervals is None:
        if steps_per_interval is None and interval_length is None:
            steps_per_interval = 1
        intervals = interval_boundaries(stamps, steps_per_interval, interval_length, gap_factor)
    intervals = np.asarray(intervals, dtype=int).reshape(-1, 2)
    dt = np.diff(stamps)
    gap = dt > gap_factor * np.median(dt) if len(dt) else np.zeros(0, dtype=bool)
    V = step_increments(quats, order=order, form=form, breaks=gap, neighbour=neighbour)
    cum = np.vstack([np.zeros((1, 3)), np.cumsum(V, axis=0)])
    t0, t1 = stamps[intervals[:, 0]], stamps[intervals[:, 1]]
    if np.any(t1 <= t0):
        raise ValueError('every interval needs t1 > t0')
    w = (cum[intervals[:, 1]] - cum[intervals[:, 0]]) / (t1 - t0)[:, None]
    return t0, t1, w, intervals


def _gyro_nodes(gyro_stamps: np.ndarray, delta_theta: np.ndarray):
    s = np.asarray(gyro_stamps, dtype=float)
    d = np.asarray(delta_theta, dtype=float).reshape(-1, 3)
    if len(s) != len(d) or len(s) < 2:
        raise ValueError('need at least two gyro increments with one stamp each')
    if np.any(np.diff(s) <= 0):
        raise ValueError('gyro stamps must be strictly increasing')
    first = s[0] - (s[1] - s[0])              # the first increment covers one period before its stamp
    nodes = np.concatenate([[first], s])
    cum = np.vstack([np.zeros((1, 3)), np.cumsum(d, axis=0)])
    return nodes, cum


def mean_measured_rate(gyro_stamps: np.ndarray, delta_theta: np.ndarray, t0, t1,
                       interpolation: str = 'linear') -> np.ndarray:
    """
    s̄ = ∫s dt / T over [t0, t1] from gyro increments (stamp = end of each increment).

    The cumulative angle Θ(t) = Σ Δθ is known exactly at the gyro epochs; at t0, t1 between
    epochs it is interpolated: ``"linear"`` (rate constant within a gyro interval; error
    ≤ |ṡ|h_g²/8 at each end) or ``"quadratic"`` (through the three nearest epochs: rate
    linear across two gyro intervals, error O(s̈ h_g³)).  When t0, t1 fall on gyro epochs
    the result is the exact sum of the increments.  Vectorised over t0, t1.
    """
    nodes, cum = _gyro_nodes(gyro_stamps, delta_theta)
    t0 = np.atleast_1d(np.asarray(t0, dtype=float))
    t1 = np.atleast_1d(np.asarray(t1, dtype=float))
    tol = 1e-9 * (nodes[-1] - nodes[0])
    if np.any(t0 < nodes[0] - tol) or np.any(t1 > nodes[-1] + tol):
        raise ValueError('interval outside the span of the gyro data')
    return (_cumulative_angle(nodes, cum, t1, interpolation)
            - _cumulative_angle(nodes, cum, t0, interpolation)) / (t1 - t0)[:, None]


def _cumulative_angle(nodes, cum, t, interpolation):
    t = np.clip(t, nodes[0], nodes[-1])
    j = np.clip(np.searchsorted(nodes, t, side='right') - 1, 0, len(nodes) - 2)
    # snap to a node within round-off (camera and gyro epochs often coincide)
    span = nodes[j + 1] - nodes[j]
    x = (t - nodes[j]) / span
    x = np.where(np.abs(x) < 1e-9, 0.0, np.where(np.abs(x - 1) < 1e-9, 1.0, x))
    if interpolation == 'linear' or len(nodes) < 3:
        return cum[j] + x[:, None] * (cum[j + 1] - cum[j])
    if interpolation != 'quadratic':
        raise ValueError(f"interpolation must be 'linear' or 'quadratic', got {interpolation!r}")
    # three nodes k, k+1, k+2 around t: prefer the neighbour on the side of t
    k = np.where(x < 0.5, j - 1, j)
    k = np.clip(k, 0, len(nodes) - 3)
    ta, tb, tc = nodes[k], nodes[k + 1], nodes[k + 2]
    la = (t - tb) * (t - tc) / ((ta - tb) * (ta - tc))
    lb = (t - ta) * (t - tc) / ((tb - ta) * (tb - tc))
    lc = (t - ta) * (t - tb) / ((tc - ta) * (tc - tb))
    out = la[:, None] * cum[k] + lb[:, None] * cum[k + 1] + lc[:, None] * cum[k + 2]
    exact = (x == 0.0) | (x == 1.0)
    out[exact] = np.where((x[exact] == 0.0)[:, None], cum[j[exact]], cum[j[exact] + 1])
    return out


# ------------------------------------------------------------------ noise covariances
def _camera_covariances(n: int, camera_sigma=None, camera_covariance=None, c_body_camera=None):
    if camera_covariance is not None:
        P = np.asarray(camera_covariance, dtype=float)
        P = np.broadcast_to(P, (n, 3, 3)) if P.shape == (3, 3) else P.reshape(n, 3, 3)
    else:
        sig = np.broadcast_to(np.asarray(0.0 if camera_sigma is None else camera_sigma, dtype=float), (3,))
        P = np.broadcast_to(np.diag(sig ** 2), (n, 3, 3))
    if c_body_camera is not None:
        C = np.asarray(c_body_camera, dtype=float)
        P = C @ P @ C.T
    return P


def camera_rate_covariance(quats: np.ndarray, intervals: np.ndarray, stamps: np.ndarray,
                           camera_sigma=None, camera_covariance=None,
                           c_body_camera: np.ndarray | None = None) -> np.ndarray:
    """
    Covariance (3K × 3K) of the errors of the mean true rates w̄ caused by camera noise.

    Camera noise: right-perturbations θ_n with covariance ``diag(camera_sigma²)`` (camera
    axes; scalar or (3,)) or ``camera_covariance`` ((3, 3) or (N, 3, 3)); ``c_body_camera``
    rotates it into body axes.  Linearised through :func:`noise_jacobians`, exact in the
    interval structure: intervals sharing fixes are correlated.
    """
    quats = np.asarray(quats, dtype=float)
    intervals = np.asarray(intervals, dtype=int).reshape(-1, 2)
    stamps = np.asarray(stamps, dtype=float)
    N = len(quats)
    P = _camera_covariances(N, camera_sigma, camera_covariance, c_body_camera)
    Jp, Jm = noise_jacobians(quats)                       # per step n = 1..N−1 at index n−1
    K = len(intervals)
    T = stamps[intervals[:, 1]] - stamps[intervals[:, 0]]
    blocks = []
    for a, b in intervals:                                  # G_ik for fixes k = a..b
        G = np.zeros((b - a + 1, 3, 3))
        G[1:] += Jp[a:b]                                    # fix k ends step k (k > a)
        G[:-1] += Jm[a:b]                                   # fix k starts step k+1 (k < b)
        blocks.append(G)
    R = np.zeros((3 * K, 3 * K))
    a_all, b_all = intervals[:, 0], intervals[:, 1]
    for i in range(K):
        lo = np.maximum(a_all[i], a_all[i:])
        hi = np.minimum(b_all[i], b_all[i:])
        for jj in np.nonzero(lo <= hi)[0]:
            j = i + jj
            l, h = lo[jj], hi[jj]
            Gi = blocks[i][l - a_all[i]:h - a_all[i] + 1]
            Gj = blocks[j][l - a_all[j]:h - a_all[j] + 1]
            blk = np.einsum('kab,kbc,kdc->ad', Gi, P[l:h + 1], Gj) / (T[i] * T[j])
            R[3 * i:3 * i + 3, 3 * j:3 * j + 3] = blk
            R[3 * j:3 * j + 3, 3 * i:3 * i + 3] = blk.T
    return R


def gyro_rate_covariance(t0: np.ndarray, t1: np.ndarray, random_walk: float) -> np.ndarray:
    """
    Covariance (3K × 3K) of the mean measured rates from angle random walk σ_rw (rad/√s):
    σ_rw²·|overlap(i, j)|/(T_i T_j) per axis (partial gyro intervals ignored).
    """
    t0 = np.asarray(t0, dtype=float)
    t1 = np.asarray(t1, dtype=float)
    ov = np.clip(np.minimum(t1[:, None], t1[None]) - np.maximum(t0[:, None], t0[None]), 0.0, None)
    T = t1 - t0
    return np.kron(random_walk ** 2 * ov / np.outer(T, T), np.eye(3))


# ------------------------------------------------------------------ least squares
@dataclass
class IntervalMeans:
    """The data of 002's system: per interval, mean true and mean measured rates."""
    t0: np.ndarray                                  # (K,) s
    t1: np.ndarray                                  # (K,) s
    w_bar: np.ndarray                               # (K, 3) mean true rate (star tracker), rad/s
    s_bar: np.ndarray                               # (K, 3) mean measured rate (gyro), rad/s
    camera_covariance: np.ndarray | None = None     # (3K, 3K) of the errors of w̄
    gyro_covariance: np.ndarray | None = None       # (3K, 3K) of the errors of s̄
    intervals: np.ndarray | None = None             # (K, 2) fix indices
    w_bar_exact: np.ndarray | None = None           # (K, 3) exact ∫w dt/T when a profile is known

    def __len__(self):
        return len(self.t0)


@dataclass
class IntegralResult:
    observable: bool
    message: str
    B: np.ndarray                                   # 3×3
    s0: np.ndarray                                  # (3,) rad/s
    covariance: np.ndarray                          # 12×12 in PARAMETER_LABELS order (the one published)
    sigma: np.ndarray                               # (12,) √diag; inf for unobservable parameters
    weighting: str
    residuals: np.ndarray                           # (K, 3) s̄ − B w̄ − s0, rad/s
    residual_rms: float                             # rad/s
    chi2_per_dof: float                             # model weighting only (nan otherwise)
    dof: int
    intervals: IntervalMeans
    observability: ObservabilityReport
    covariance_residual: np.ndarray | None = None   # σ²(AᵀA)⁻¹ per axis (when K > 4)
    covariance_model: np.ndarray | None = None      # (HᵀR⁻¹H)⁻¹ (when the noise is known)
    rate_scale: float = 1.0                         # RMS |w̄| used to scale s0 for observability
    unobservable_parameters: list = field(default_factory=list)   # labels lying wholly in the null space
    labels: tuple = PARAMETER_LABELS
    extra: dict = field(default_factory=dict)

    @property
    def x(self) -> np.ndarray:
        return np.concatenate([self.B.ravel(), self.s0])

    @property
    def M(self) -> np.ndarray:
        """B − I: scale factors on the diagonal, misalignments off it (sensors.SensorErrorModel.matrix)."""
        return self.B - np.eye(3)

    @property
    def bias(self) -> np.ndarray:
        return self.s0

    def to_error_model(self):
        """The estimate as a :class:`~strapdown_ros.sensors.SensorErrorModel` (M = B − I, b = s0)."""
        M = self.M
        return SensorErrorModel(bias=self.s0.copy(), scale_factor=np.diag(M).copy(),
                                misalignment=M - np.diag(np.diag(M)))

    def correct(self, delta_theta: np.ndarray, period) -> np.ndarray:
        """Apply the calibration to increments: u = B⁻¹(Δθ − s0·T)."""
        d = np.asarray(delta_theta, dtype=float)
        T = np.asarray(period, dtype=float)
        return (d - np.multiply.outer(T, self.s0) if T.ndim else d - self.s0 * T) @ np.linalg.inv(self.B).T


def design_matrix(w_bar: np.ndarray) -> np.ndarray:
    """H (3K × 12): row 3i+j is s̄_ij = B_j·w̄_i + s0_j in PARAMETER_LABELS order."""
    w = np.asarray(w_bar, dtype=float).reshape(-1, 3)
    K = len(w)
    H = np.zeros((K, 3, 12))
    for j in range(3):
        H[:, j, 3 * j:3 * j + 3] = w
        H[:, j, 9 + j] = 1.0
    return H.reshape(3 * K, 12)


_AXIS_PARAMS = [np.array([3 * j, 3 * j + 1, 3 * j + 2, 9 + j]) for j in range(3)]


def aligned_basis(V: np.ndarray) -> np.ndarray:
    """
    Orthonormal basis of span(V) (12 × m) aligned greedily with the parameter axes: each
    vector is the normalised projection of the parameter that the remaining subspace holds
    best, so a wholly unobservable parameter comes out as itself (e.g. ``+1.00·B12``).
    """
    rest = V.copy()
    out = []
    for _ in range(V.shape[1]):
        P = rest @ rest.T
        i = int(np.argmax(np.diag(P)))
        v = P[:, i] / np.sqrt(P[i, i])
        out.append(v)
        rest = rest - np.outer(v, v @ rest)
        U, S, _ = np.linalg.svd(rest, full_matrices=False)
        rest = U[:, S > 1e-8]
    out.sort(key=lambda v: int(np.argmax(np.abs(v))))
    return np.array(out).T


def _describe(v: np.ndarray) -> str:
    v = v * np.sign(v[np.argmax(np.abs(v))])
    terms = [f'{c:+.2f}·{n}' for c, n in zip(v, PARAMETER_LABELS) if abs(c) >= 0.005]
    return ' '.join(terms) if terms else '0'


def integral_calibration(data: IntervalMeans, weighting: str = 'auto', inflate: bool = True,
                         sigma_limit: float = 1e-2, rel_tol: float = 1e-9,
                         B_nominal: np.ndarray | None = None) -> IntegralResult:
    """
    Solve 002's system B·w̄_i + s0 = s̄_i over K ≥ 4 intervals by least squares.

    weighting:
      ``"residual"``: per axis j, A = [w̄ᵀ 1] (K × 4), unweighted LS, covariance σ_j²(AᵀA)⁻¹
      with σ_j² = RSS_j/(K − 4) (needs K > 4);
      ``"pooled"``: the same with one σ² = ΣRSS/(3K − 12);
      ``"model"``: generalised LS with the full covariance R = R_gyro + B R_cam Bᵀ of
      :class:`IntervalMeans` (needs camera and/or gyro covariance), covariance (HᵀR⁻¹H)⁻¹,
      multiplied by max(1, χ²/dof) when ``inflate``;
      ``"auto"``: model when a covariance is present, else residual.
    Unobservable combinations (:func:`analyze_information` with ``sigma_limit`` on the
    parameters with s0 in units of the RMS rate, and ``rel_tol``) are left at the nominal
    value (B = ``B_nominal`` or I, s0 = 0) by a minimum-norm solution; their σ is inf.
    """
    w = np.asarray(data.w_bar, dtype=float).reshape(-1, 3)
    s = np.asarray(data.s_bar, dtype=float).reshape(-1, 3)
    K = len(w)
    has_model = data.camera_covariance is not None or data.gyro_covariance is not None
    if weighting == 'auto':
        weighting = 'model' if has_model else 'residual'
    if weighting not in ('residual', 'pooled', 'model'):
        raise ValueError(f"weighting must be 'auto', 'residual', 'pooled' or 'model', got {weighting!r}")
    if weighting == 'model' and not has_model:
        raise ValueError("weighting='model' needs the camera or gyro covariance of the interval means")
    Bn = np.eye(3) if B_nominal is None else np.asarray(B_nominal, dtype=float)
    x_nom = np.concatenate([Bn.ravel(), np.zeros(3)])
    H = design_matrix(w)
    y = s.ravel() - H @ x_nom
    rate_scale = float(np.sqrt(np.mean(np.sum(w * w, axis=1)))) if K else 1.0
    rate_scale = rate_scale if rate_scale > 0 else 1.0
    D = np.concatenate([np.ones(9), np.full(3, rate_scale)])       # x = D·x_scaled

    def nan_result(msg):
        nan12 = np.full(12, np.nan)
        rep = analyze_information(np.zeros((12, 12)), labels=PARAMETER_LABELS)
        return IntegralResult(False, msg, Bn.copy(), np.zeros(3), np.full((12, 12), np.nan), nan12,
                              weighting, np.full((K, 3), np.nan), float('nan'), float('nan'), 0, data, rep,
                              rate_scale=rate_scale)

    if K < 4:
        return nan_result(f'{K} interval(s): 002 needs at least 4')

    A = np.hstack([w, np.ones((K, 1))])
    AtA = A.T @ A
    # --- per-axis residual variance of the unweighted system (002 as printed)
    rss = np.zeros(3)
    for j in range(3):
        r = y[j::3] - A @ np.linalg.lstsq(A, y[j::3], rcond=None)[0]
        rss[j] = r @ r
    var_res = None
    if K > 4:
        var_res = rss / (K - 4) if weighting != 'pooled' else np.full(3, rss.sum() / (3 * K - 12))
        floor = (1e-15 * max(float(np.max(np.abs(s))), 1e-300)) ** 2     # noise-free data
        var_res = np.maximum(var_res, floor)
    # --- whitened system for the chosen weighting
    info_model = None
    if has_model:
        R = np.zeros((3 * K, 3 * K))
        if data.gyro_covariance is not None:
            R += data.gyro_covariance
        if data.camera_covariance is not None:
            # e_i = n_i − B·δw̄_i: the camera part is rotated by B (taken from the unweighted solution)
            B_est = Bn.copy()
            for j in range(3):
                B_est[j] += np.linalg.lstsq(A, y[j::3], rcond=None)[0][:3]
            BB = np.kron(np.eye(K), B_est)
            R += BB @ data.camera_covariance @ BB.T
        scale = np.sqrt(np.maximum(np.diag(R), 0.0))
        scale = np.where(scale > 0, scale, max(float(scale.max()), 1e-300))
        Hs, ys = H / scale[:, None], y / scale
        X = np.linalg.solve(R / np.outer(scale, scale) + 1e-12 * np.eye(3 * K), np.column_stack([Hs, ys]))
        info_model, g_model = Hs.T @ X[:, :12], Hs.T @ X[:, 12]
        info_model = 0.5 * (info_model + info_model.T)
        yRy_model = float(ys @ X[:, 12])
    if weighting == 'model':
        info, g, yRy = info_model, g_model, yRy_model
    else:
        if var_res is None:
            return nan_result(f'{K} intervals: the residual weighting needs more than 4 (no residual '
                              f"degrees of freedom); use weighting='model' with the noise known")
        sd = np.tile(np.sqrt(var_res), K)
        Hw, yw = H / sd[:, None], y / sd
        info, g, yRy = Hw.T @ Hw, Hw.T @ yw, float(yw @ yw)
    # --- observability on the scaled parameters (s0 in units of the RMS rate)
    info_scaled = D[:, None] * info * D[None, :]
    rep = analyze_information(info_scaled, labels=PARAMETER_LABELS, rel_tol=rel_tol, sigma_limit=sigma_limit)
    lam, vec = rep.eigenvalues, rep.directions
    bad = (lam <= rel_tol * max(float(lam[-1]), 0.0)) | (rep.predicted_sigma > sigma_limit)
    good = vec[:, ~bad]
    Pg = good @ np.diag(1.0 / lam[~bad]) @ good.T            # pseudo-inverse on the observable subspace
    dx = D * (Pg @ (D * g))                                 # minimum-norm step from the nominal
    chi2_sum = max(yRy - 2.0 * float(dx @ g) + float(dx @ info @ dx), 0.0)   # weighted RSS
    dof = 3 * K - int(np.sum(~bad))
    cov = D[:, None] * Pg * D[None, :]
    if weighting != 'model':
        cov_res = cov.copy()
    elif var_res is not None:                               # 002's unweighted σ²(AᵀA)⁻¹, for comparison
        cov_res = np.zeros((12, 12))
        AtA_pinv = np.linalg.pinv(AtA)
        for j in range(3):
            cov_res[np.ix_(_AXIS_PARAMS[j], _AXIS_PARAMS[j])] = var_res[j] * AtA_pinv
    else:
        cov_res = None
    cov_model = None
    if weighting == 'model':
        chi2 = chi2_sum / dof if dof > 0 else float('nan')
        cov_model = cov.copy()
        if inflate and dof > 0:
            cov = cov * max(1.0, chi2)
    else:
        chi2 = float('nan')
        if info_model is not None:
            cov_model = np.linalg.pinv(info_model)
    x = x_nom + dx
    B, s0 = x[:9].reshape(3, 3), x[9:]
    resid = s - w @ B.T - s0
    sigma = np.sqrt(np.maximum(np.diag(cov), 0.0))
    touched = np.any(np.abs(vec[:, bad]) > 1e-3, axis=1) if np.any(bad) else np.zeros(12, dtype=bool)
    sigma = np.where(touched, np.inf, sigma)
    unobs_params = []
    if np.any(bad):
        # name the unobservable subspace in a parameter-aligned basis (eigh mixes degenerate directions)
        basis = aligned_basis(vec[:, bad])
        rep.unobservable = [_describe(v) for v in basis.T]
        rep.message = 'not observable: ' + '; '.join(rep.unobservable) + \
            (f" (weakly observable: {'; '.join(rep.weak)})" if rep.weak else '')
    if np.any(bad) or rep.weak:
        rep.message += f' [s0 in units of the RMS mean rate {rate_scale:.3g} rad/s]'
        Pu = vec[:, bad] @ vec[:, bad].T
        unobs_params = [PARAMETER_LABELS[i] for i in range(12) if Pu[i, i] > 0.99]
    return IntegralResult(
        observable=rep.observable, message=rep.message, B=B, s0=s0, covariance=cov, sigma=sigma, weighting=weighting,
        residuals=resid, residual_rms=float(np.sqrt(np.mean(resid ** 2))), chi2_per_dof=chi2, dof=dof,
        intervals=data, observability=rep, covariance_residual=cov_res, covariance_model=cov_model,
        rate_scale=rate_scale, unobservable_parameters=unobs_params)


# ------------------------------------------------------------------ the whole chain
def calibrate_from_measurements(gyro_stamps: np.ndarray, delta_theta: np.ndarray, camera_stamps: np.ndarray,
                                camera_quats: np.ndarray, camera_sigma=None, *, camera_covariance=None,
                                gyro_random_walk: float = 0.0, order: int = 3, form: str = 'paper',
                                steps_per_interval: int | None = None, interval_length: float | None = None,
                                intervals: np.ndarray | None = None, weighting: str = 'auto',
                                interpolation: str = 'linear', q_body_camera: np.ndarray | None = None,
                                profile=None, inflate: bool = True, sigma_limit: float = 1e-2,
                                neighbour: str = 'previous') -> IntegralResult:
    """
    002 end to end: gyro increments + star-tracker fixes → B, s0 with covariance and observability.

    gyro_stamps (n,), delta_theta (n, 3): integrating-gyro output, stamped at the end of each
    increment.  camera_stamps (N,), camera_quats (N, 4): fixes q_ref_camera (scalar-first);
    with ``q_body_camera`` (the boresight q_MF_VF) the body attitude is q_ref_camera ⊗
    q_body_camera*; default: camera = body.  camera_sigma: 1σ per camera axis (rad, scalar or
    (3,)) or camera_covariance ((3,3) or (N,3,3)).  gyro_random_walk: rad/√s.
    Intervals: ``intervals`` (fix-index pairs), ``steps_per_interval`` or ``interval_length``
    (default 10 camera steps).  Fixes outside the gyro data are dropped.
    ``profile`` (optional, a :class:`~strapdown_ros.motion.profiles.MotionProfile`): the exact mean rates
    are attached (``result.intervals.w_bar_exact``) and the error of the star-tracker w̄ against
    them is reported in ``result.extra``.
    """
    cs = np.asarray(camera_stamps, dtype=float)
    cq = quat_normalize(np.asarray(camera_quats, dtype=float).reshape(-1, 4))
    nodes, _ = _gyro_nodes(gyro_stamps, delta_theta)
    keep = (cs >= nodes[0] - 1e-9) & (cs <= nodes[-1] + 1e-9)
    if camera_covariance is not None and np.ndim(camera_covariance) == 3:
        camera_covariance = np.asarray(camera_covariance)[keep]
    if intervals is not None and not np.all(keep):
        raise ValueError('explicit intervals need every camera fix inside the gyro data span')
    cs, cq = cs[keep], cq[keep]
    C_bc = None
    if q_body_camera is not None:
        qbc = quat_normalize(np.asarray(q_body_camera, dtype=float))
        cq = quat_multiply(cq, quat_conjugate(qbc))
        C_bc = quat_to_dcm(qbc)
    if intervals is None and steps_per_interval is None and interval_length is None:
        steps_per_interval = 10
    t0, t1, w, iv = mean_true_rate(cs, cq, intervals=intervals, order=order, form=form,
                                   steps_per_interval=steps_per_interval, interval_length=interval_length,
                                   neighbour=neighbour)
    s = mean_measured_rate(gyro_stamps, delta_theta, t0, t1, interpolation=interpolation) if len(t0) else \
        np.zeros((0, 3))
    R_cam = None
    if camera_sigma is not None or camera_covariance is not None:
        R_cam = camera_rate_covariance(cq, iv, cs, camera_sigma, camera_covariance, C_bc)
    R_gyro = gyro_rate_covariance(t0, t1, gyro_random_walk) if gyro_random_walk > 0 else None
    data = IntervalMeans(t0, t1, w, s, R_cam, R_gyro, iv)
    extra = {}
    if profile is not None and len(t0):
        data.w_bar_exact = profile.delta_theta(t0, t1) / (t1 - t0)[:, None]
        err = w - data.w_bar_exact
        extra['w_bar_error_rms'] = float(np.sqrt(np.mean(err ** 2)))
        extra['w_bar_error_max'] = float(np.max(np.abs(err)))
    res = integral_calibration(data, weighting=weighting, inflate=inflate, sigma_limit=sigma_limit)
    dq = _relative_quats(cq) if len(cq) > 1 else np.zeros((0, 4))
    extra['max_step_rotation'] = float(np.max(np.linalg.norm(quat_to_rotvec(dq), axis=1))) if len(dq) else 0.0
    extra['order'], extra['form'], extra['neighbour'] = order, form, neighbour
    res.extra.update(extra)
    return res
