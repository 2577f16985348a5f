"""
Specific-force integrals of one navigation step from integrating gyros and accelerometers.

The sensor side of a navigation step, under :mod:`.navigator`; :mod:`.recursion` takes its
output.

003 (Aksyonenko 2014) §1.5.2 integrates the navigation equation (1.93) over one step
``[t_{k−1}, t_k]`` of length
``h`` from the sensor *increments* (quasi-coordinates), never from rates.  The part that needs the
increments is the integral of the specific force rotated by the body motion within the step:

    Δv = ∫_0^h A(s) f(s) ds,            Δr = ∫_0^h (h − s) A(s) f(s) ds,

with ``A(s)`` the body rotation since ``t_{k−1}`` (body axes at ``t_{k−1}`` ← body axes at
``t_{k−1}+s``) and ``f(s)`` the specific force in body axes.  ``Δv`` enters the velocity, ``Δr``
the position (:mod:`.recursion` adds gravity, Earth rotation and the frame change).

The sensor model of 003 (derived and checked in doc/navigation.md):

* the angular rate is linear within the step, ``ω(s) = a₁ + a₂ s`` (1.49), fitted to the
  gyro increments ``q`` of the step and, when the step holds one, the previous one (1.52);
* the specific force is quadratic, ``f(s) = c + d s + e s²/2`` (1.97), fitted to the
  accelerometer increments ``u`` of the step (exact for three, 1.98; least squares for more;
  with fewer than three the previous step's increments complete the fit);
* the rotation vector within the step is the Bortz solution to third order,
  ``φ(s) = a₁s + a₂s²/2 + (a₁×a₂)s³/12`` (1.57), and ``A(s) = exp([φ(s)×])`` exactly.

Forms of the integral (``form``):

``"exact"`` (default)
    the integrals of the fitted model by 6-point Gauss–Legendre quadrature (exact to round-off
    for the model: the integrand is a polynomial of degree ≤ 11 up to terms of 6th order in the
    step's rotation angle).  Its error is the fit's: the stated order of the algorithm.
``"series"``
    the closed-form expansion of the same integrals in 003's basis (q_{k−1}, q_k,
    Q₁ = q_k + q_{k−1}, Q₂ = q_k − q_{k−1}, Q = q_{k−1} × q_k; u₁, u₂, u₃) with the
    coefficients *derived* here
    (:func:`derived_coefficients`, exact fractions); 003 layout only (one gyro, three
    accelerometer increments per step).
``"printed"``
    the same expansion with the coefficients as printed in (1.99)/(1.100) — misprints included,
    for comparison.
``"rotation_only"``
    rotation compensation without sculling: ``Δv = v + ½ θ × v`` (v = Σu, θ = Σq), the classical
    form whose sculling drift is ½AB(1 − sin(Ωh)/(Ωh)) (doc/navigation.md).
``"none"``
    ``Δv = v``: no rotation compensation.

No ROS imports; vectorised over steps.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from itertools import product
import math
from math import factorial

import numpy as np

from strapdown_ros.attitude.kernel import kernels_allowed, njit_optional
from strapdown_ros.rotation import cross

__all__ = ['FORMS', 'StepLayout', 'step_layout', 'specific_force_integrals',
           'derived_coefficients', 'PRINTED_COEFFICIENTS', 'coefficient_table',
           'markdown_coefficient_table', 'kernel_available']

FORMS = ('exact', 'series', 'printed', 'rotation_only', 'none')
_GL_X, _GL_W = np.polynomial.legendre.leggauss(6)
_GL_S = 0.5 * (_GL_X + 1.0)                # nodes on [0, 1]
_GL_W = 0.5 * _GL_W
_GL_WR = _GL_W * (1.0 - _GL_S)         # weights of ∫(1 − σ)·


def _fit_matrix(window: int, per_step: int, degree: int) -> np.ndarray:
    """
    Return the least-squares map from sub-interval integrals to polynomial coefficients.

    The map (exact when square) goes from the integrals over ``window`` equal
    sub-intervals ending at σ = 1 (``per_step`` of them per unit step) to the coefficients of
    ``p(σ) = Σ_i p_i σ^i / i!`` (i ≤ degree).  Computed in exact rational arithmetic: a float
    pseudo-inverse carries relative errors of ~1e-13 into every step's Δv, the same each step,
    which the vertical channel integrates (doc/navigation.md).
    """
    edges = [1 - Fraction(window - j, per_step) for j in range(window + 1)]
    rows = [[(b ** (i + 1) - a ** (i + 1)) / (i + 1) / factorial(i) for i in range(degree + 1)]
            for a, b in zip(edges[:-1], edges[1:])]
    n = degree + 1
    ata = [[sum(r[i] * r[j] for r in rows) for j in range(n)] for i in range(n)]
    inv = _inverse(ata)
    return np.array([[float(sum(inv[i][k] * r[k] for k in range(n))) for r in rows]
                     for i in range(n)])


@dataclass(frozen=True)
class StepLayout:
    """
    How many sensor sub-intervals one step holds and which ones each fit uses.

    Derived fields: ``gyro_window`` / ``accel_window``, the number of sub-intervals ending at
    ``t_k`` that the fits take (the step's own and, when there are too few, the previous ones);
    ``gyro_fit`` (2, Lg), the map from q to (a₁h, a₂h²); ``accel_fit`` (3, La), the map from u
    to (ch, dh², eh³).

    Parameters
    ----------
    gyro_per_step : int
        Gyro increments per step, at least 1.
    accel_per_step : int
        Accelerometer increments per step, at least 1.

    Raises
    ------
    ValueError
        For fewer than one increment of either sensor.

    """

    gyro_per_step: int
    accel_per_step: int
    gyro_window: int = field(init=False)
    accel_window: int = field(init=False)
    gyro_fit: np.ndarray = field(init=False, repr=False)
    accel_fit: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        n, m = int(self.gyro_per_step), int(self.accel_per_step)
        if n < 1 or m < 1:
            raise ValueError('a step needs at least one gyro and one accelerometer increment, '
                             f'got {n} and {m}')
        lg, la = max(n, 2), max(m, 3)
        object.__setattr__(self, 'gyro_window', lg)
        object.__setattr__(self, 'accel_window', la)
        object.__setattr__(self, 'gyro_fit', _fit_matrix(lg, n, 1))
        object.__setattr__(self, 'accel_fit', _fit_matrix(la, m, 2))

    @property
    def is_003(self) -> bool:
        """
        Tell whether the layout is 003's (§1.5).

        Returns
        -------
        bool
            True for one gyro and three accelerometer increments per step.

        """
        return self.gyro_per_step == 1 and self.accel_per_step == 3


def step_layout(gyro_per_step: int, accel_per_step: int) -> StepLayout:
    """
    Return the layout of a step with the given numbers of increments.

    Parameters
    ----------
    gyro_per_step, accel_per_step : int
        Gyro and accelerometer increments per step.

    Returns
    -------
    StepLayout
        The layout, with its fit matrices.

    """
    return StepLayout(int(gyro_per_step), int(accel_per_step))


def _rotation_part(phi: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Return ``(exp([φ×]) − I) v`` by Rodrigues' formula, exact at any angle, broadcasting."""
    a2 = np.einsum('...i,...i->...', phi, phi)
    a = np.sqrt(a2)
    small = a2 < 1e-8
    s1 = np.where(small, 1.0 - a2 / 6.0 + a2 * a2 / 120.0, np.sin(a) / np.where(small, 1.0, a))
    s2 = np.where(small, 0.5 - a2 / 24.0 + a2 * a2 / 720.0,
                  (1.0 - np.cos(a)) / np.where(small, 1.0, a2))
    pv = cross(phi, v)
    return s1[..., None] * pv + s2[..., None] * cross(phi, pv)


def specific_force_integrals(gyro_window: np.ndarray, accel_window: np.ndarray,
                             h: np.ndarray, layout: StepLayout,
                             form: str = 'exact') -> tuple[np.ndarray, np.ndarray]:
    """
    Return the specific-force integrals ``(Δv, Δr)`` of K steps.

    Sub-intervals are taken as equal (h / per_step).

    Parameters
    ----------
    gyro_window : (K, layout.gyro_window, 3) array_like
        Gyro increments ending at ``t_k``, oldest first, body axes, rad.
    accel_window : (K, layout.accel_window, 3) array_like
        Accelerometer increments ending at ``t_k``, oldest first, body axes, m/s.
    h : (K,) array_like
        Step lengths, s.
    layout : StepLayout
        Increments per step and the fits.
    form : str
        One of :data:`FORMS`; ``series`` and ``printed`` need 003's layout.

    Returns
    -------
    tuple of ndarray
        Δv (K, 3), m/s, and Δr (K, 3), m, body axes at the start of each step.

    Raises
    ------
    ValueError
        For an unknown form, or a series form on another layout.

    """
    if form not in FORMS:
        raise ValueError(f"unknown specific-force form {form!r}; valid: {', '.join(FORMS)}")
    q = np.asarray(gyro_window, dtype=float)
    u = np.asarray(accel_window, dtype=float)
    h = np.asarray(h, dtype=float)
    n, m = layout.gyro_per_step, layout.accel_per_step
    if form == 'exact' and kernel_available() and len(h):   # the same mathematics, compiled
        dv, dr = np.empty((len(h), 3)), np.empty((len(h), 3))
        _compiled(np.ascontiguousarray(q), np.ascontiguousarray(u), np.ascontiguousarray(h),
                  layout.gyro_fit, layout.accel_fit, n, m, _GL_S, _GL_W, _GL_WR, dv, dr)
        return dv, dr
    theta = q[:, -n:].sum(1)                   # the step's own increments
    v = u[:, -m:].sum(1)
    poly = layout.accel_fit @ u                   # (K, 3, 3): c', d', e' (per unit step)
    if form in ('series', 'printed'):
        if not layout.is_003:
            raise ValueError(f"the {form} form is 003's: one gyro and three accelerometer "
                             f'increments per step, got {n} and {m}')
        coefficients = PRINTED_COEFFICIENTS if form == 'printed' else derived_coefficients()
        return _series(q, u, h, coefficients)
    # ∫_0^1 (1 − σ) f'(σ) dσ of the fit, f' = c' + d'σ + e'σ²/2  → c'/2 + d'/6 + e'/24
    p_lin = poly[:, 0] / 2.0 + poly[:, 1] / 6.0 + poly[:, 2] / 24.0
    if form == 'none':
        return v, h[:, None] * p_lin
    if form == 'rotation_only':
        return v + 0.5 * cross(theta, v), h[:, None] * (p_lin + cross(theta, v) / 6.0)
    a = layout.gyro_fit @ q                                  # (K, 2, 3): a₁h, a₂h²
    a1, a2 = a[:, 0], a[:, 1]
    s = _GL_S[None, :, None]
    phi = a1[:, None] * s + a2[:, None] * s ** 2 / 2.0 + cross(a1, a2)[:, None] * s ** 3 / 12.0
    f = poly[:, None, 0] + poly[:, None, 1] * s + poly[:, None, 2] * s ** 2 / 2.0     # (K, 6, 3)
    af = _rotation_part(phi, f)
    # the step's own increments summed exactly, plus the quadrature of the rotation's part only
    dv = v + _GL_W @ af
    dr = h[:, None] * (p_lin + _GL_WR @ af)
    return dv, dr


def _exact_loop(q, u, h, gyro_fit, accel_fit, n, m, gl_s, gl_w, gl_wr, dv_out, dr_out):
    """
    Run the ``"exact"`` form step by step in scalar arithmetic.

    The vectorised code above, written as one loop without temporaries so that numba can
    compile it (optional; the tests compare the two paths).  ``n`` is unused (the gyro window
    is the fit's).
    """
    for k in range(h.shape[0]):
        for i in range(3):                  # the fits, column by column: a₁h, a₂h²; c', d', e'
            a1 = 0.0
            a2 = 0.0
            for j in range(q.shape[1]):
                a1 += gyro_fit[0, j] * q[k, j, i]
                a2 += gyro_fit[1, j] * q[k, j, i]
            dv_out[k, i] = a1               # parked here until the loop below
            dr_out[k, i] = a2
        a1x, a1y, a1z = dv_out[k, 0], dv_out[k, 1], dv_out[k, 2]
        a2x, a2y, a2z = dr_out[k, 0], dr_out[k, 1], dr_out[k, 2]
        cx = cy = cz = dx = dy = dz = ex = ey = ez = vx = vy = vz = 0.0
        for j in range(u.shape[1]):
            ux, uy, uz = u[k, j, 0], u[k, j, 1], u[k, j, 2]
            cx += accel_fit[0, j] * ux
            cy += accel_fit[0, j] * uy
            cz += accel_fit[0, j] * uz
            dx += accel_fit[1, j] * ux
            dy += accel_fit[1, j] * uy
            dz += accel_fit[1, j] * uz
            ex += accel_fit[2, j] * ux
            ey += accel_fit[2, j] * uy
            ez += accel_fit[2, j] * uz
            if j >= u.shape[1] - m:
                vx += ux
                vy += uy
                vz += uz
        bx, by, bz = a1y * a2z - a1z * a2y, a1z * a2x - a1x * a2z, a1x * a2y - a1y * a2x
        svx = svy = svz = srx = sry = srz = 0.0
        for g in range(gl_s.shape[0]):
            x = gl_s[g]
            x2 = 0.5 * x * x
            x3 = x * x * x / 12.0
            px = a1x * x + a2x * x2 + bx * x3
            py = a1y * x + a2y * x2 + by * x3
            pz = a1z * x + a2z * x2 + bz * x3
            fx, fy, fz = cx + dx * x + ex * x2, cy + dy * x + ey * x2, cz + dz * x + ez * x2
            t2 = px * px + py * py + pz * pz
            if t2 < 1e-8:
                s1 = 1.0 - t2 / 6.0 + t2 * t2 / 120.0
                s2 = 0.5 - t2 / 24.0 + t2 * t2 / 720.0
            else:
                t = math.sqrt(t2)
                s1 = math.sin(t) / t
                s2 = (1.0 - math.cos(t)) / t2
            qx, qy, qz = py * fz - pz * fy, pz * fx - px * fz, px * fy - py * fx
            rx, ry, rz = py * qz - pz * qy, pz * qx - px * qz, px * qy - py * qx
            ax, ay, az = s1 * qx + s2 * rx, s1 * qy + s2 * ry, s1 * qz + s2 * rz
            svx += gl_w[g] * ax
            svy += gl_w[g] * ay
            svz += gl_w[g] * az
            srx += gl_wr[g] * ax
            sry += gl_wr[g] * ay
            srz += gl_wr[g] * az
        dv_out[k, 0], dv_out[k, 1], dv_out[k, 2] = vx + svx, vy + svy, vz + svz
        dr_out[k, 0] = h[k] * (cx / 2.0 + dx / 6.0 + ex / 24.0 + srx)
        dr_out[k, 1] = h[k] * (cy / 2.0 + dy / 6.0 + ey / 24.0 + sry)
        dr_out[k, 2] = h[k] * (cz / 2.0 + dz / 6.0 + ez / 24.0 + srz)


_compiled = None


def kernel_available() -> bool:
    """
    Tell whether the ``exact`` form runs compiled.

    Returns
    -------
    bool
        True when numba is present, allowed (``STRAPDOWN_KERNEL`` ≠ ``numpy``) and able to
        compile the loop.

    """
    global _compiled
    if not kernels_allowed():
        return False
    if _compiled is None:
        got = njit_optional(_exact_loop)
        _compiled = got[0] if got else False
    return _compiled is not False


# --- the series of 003 (1.99)/(1.100) -----------------------------------------------------------
#: terms of the expansion: (name, builder of the vector operand from q_{k−1}, q_k) — each term is
#: ``X × (Y × w)`` or ``X × w`` or ``w`` with ``w = c₁u₁ + c₂u₂ + c₃u₃``
_TERMS = ('u', 'q_km1', 'q_k', 'Q1Q1', 'Q1Q2', 'Q2Q1', 'Q2Q2', 'Q', 'Q1Q', 'QQ1', 'Q2Q', 'QQ2')

#: 003 (1.99) bracket (velocity) and (1.100) bracket (position, ×τ), as printed.  Terms the
#: printed formula does not have are zero.
PRINTED_COEFFICIENTS = {
    'velocity': {
        'u': (10, -17, 10),
        'q_km1': (Fraction(11, 240), Fraction(19, 120), Fraction(11, 240)),
        'q_k': (Fraction(19, 240), Fraction(41, 120), Fraction(199, 240)),
        'Q1Q1': (Fraction(1, 240), Fraction(11, 480), Fraction(47, 480)),
        'Q1Q2': (Fraction(91, 320), Fraction(-179, 320), Fraction(59, 160)),
        'Q2Q1': (Fraction(91, 320), Fraction(-179, 320), Fraction(59, 160)),
        'Q2Q2': (Fraction(1, 280), Fraction(-1, 140), Fraction(11, 140)),
        'Q': (Fraction(1, 480), Fraction(-1, 480), Fraction(11, 120)),
        'Q1Q': (Fraction(1, 960), Fraction(-179, 960), Fraction(7, 240)),
        'Q2Q': (Fraction(11, 16128), Fraction(-17, 8064), Fraction(191, 16128)),
    },
    'position': {
        'u': (2, Fraction(-7, 4), Fraction(5, 4)),
        'q_km1': (Fraction(1, 24), Fraction(19, 240), Fraction(1, 240)),
        'q_k': (Fraction(1, 20), Fraction(19, 80), Fraction(7, 80)),
        'Q1Q1': (Fraction(1, 960), Fraction(19, 960), Fraction(1, 96)),
        'Q1Q2': (Fraction(-1, 2240), Fraction(23, 2240), Fraction(1, 112)),
        'Q2Q1': (Fraction(1, 480), Fraction(19, 480), Fraction(1, 480)),
        'Q2Q2': (Fraction(-1, 1920), Fraction(37, 6720), Fraction(101, 13446)),
    },
}


def _poly_mul(a: dict, b: dict) -> dict:
    out: dict = {}
    for i, x in a.items():
        for j, y in b.items():
            out[i + j] = out.get(i + j, 0) + x * y
    return out


def _poly_int01(a: dict) -> Fraction:
    return sum((Fraction(c) / (k + 1) for k, c in a.items()), Fraction(0))


_DERIVED: dict | None = None


def derived_coefficients() -> dict:
    """
    Return the coefficients of 003 (1.99)/(1.100) derived in exact rational arithmetic.

    With τ = 1, δτ = 1/3: f(σ) = Σ_j γ_j(σ) u_j from the exact solution of (1.98)'s system;
    the rotation vector φ(σ) = Q₁σ/2 + Q₂σ²/2 + Qσ³/12 (from (1.52), (1.57));
    A = I + [φ×] + ½[φ×]² + …; velocity coefficient of a term = ∫₀¹ (its σ-polynomial) γ_j dσ,
    position the same with the weight (1 − σ).  Terms of third order other than those with Q
    (e.g. Q₁×(Q₁×(Q₁×u))) are not in 003's basis and not listed.

    Returns
    -------
    dict
        ``{'velocity': {term: (c₁, c₂, c₃)}, 'position': {...}}``, Fractions, the terms of
        :data:`PRINTED_COEFFICIENTS`; computed once.

    """
    global _DERIVED
    if _DERIVED is not None:
        return _DERIVED
    layout = step_layout(1, 3)
    # exact inverse of the 3×3 system (the float pinv above equals it to round-off)
    d = Fraction(1, 3)
    rows = [[(i + 1) * d - i * d, (((i + 1) * d) ** 2 - (i * d) ** 2) / 2,
             (((i + 1) * d) ** 3 - (i * d) ** 3) / 6]
            for i in range(3)]
    inv = _inverse(rows)
    gamma = [{0: inv[0][j], 1: inv[1][j], 2: inv[2][j] / 2} for j in range(3)]
    beta = {'q_km1': {1: Fraction(1, 2), 2: Fraction(-1, 2)},
            'q_k': {1: Fraction(1, 2), 2: Fraction(1, 2)},
            'Q1': {1: Fraction(1, 2)}, 'Q2': {2: Fraction(1, 2)}, 'Q': {3: Fraction(1, 12)}}
    weights = (('velocity', {0: Fraction(1)}), ('position', {0: Fraction(1), 1: Fraction(-1)}))
    out = {}
    for kind, weight in weights:
        table = {'u': tuple(_poly_int01(_poly_mul(weight, g)) for g in gamma)}
        for x in ('q_km1', 'q_k', 'Q'):
            table[x] = tuple(_poly_int01(_poly_mul(weight, _poly_mul(beta[x], g)))
                             for g in gamma)
        for x, y in product(('Q1', 'Q2'), repeat=2):
            xy = _poly_mul(beta[x], beta[y])
            table[x + y] = tuple(Fraction(1, 2) * _poly_int01(_poly_mul(weight, _poly_mul(xy, g)))
                                 for g in gamma)
        for x in ('Q1', 'Q2'):  # ½(X×(Q×f) + Q×(X×f)): both orders carry the same coefficient
            xq = _poly_mul(beta[x], beta['Q'])
            c = tuple(Fraction(1, 2) * _poly_int01(_poly_mul(weight, _poly_mul(xq, g)))
                      for g in gamma)
            table[x + 'Q'] = c
            table['Q' + x] = c
        out[kind] = table
    del layout
    _DERIVED = out
    return out


def _inverse(rows):
    """Return the exact inverse of a small square matrix of Fractions (Gauss–Jordan)."""
    n = len(rows)
    a = [list(r) + [Fraction(int(i == j)) for j in range(n)] for i, r in enumerate(rows)]
    for c in range(n):
        p = next(r for r in range(c, n) if a[r][c] != 0)
        a[c], a[p] = a[p], a[c]
        pv = a[c][c]
        a[c] = [x / pv for x in a[c]]
        for r in range(n):
            if r != c:
                f = a[r][c]
                a[r] = [x - f * y for x, y in zip(a[r], a[c])]
    return [r[n:] for r in a]


def _series(q: np.ndarray, u: np.ndarray, h: np.ndarray,
            coefficients: dict) -> tuple[np.ndarray, np.ndarray]:
    qm, qk = q[:, -2], q[:, -1]
    ops = {'q_km1': qm, 'q_k': qk, 'Q1': qk + qm, 'Q2': qk - qm, 'Q': cross(qm, qk)}
    res = []
    for kind in ('velocity', 'position'):
        total = np.zeros((len(q), 3))
        for term, coef in coefficients[kind].items():
            w = sum(float(c) * u[:, -3 + j] for j, c in enumerate(coef))
            if term == 'u':
                total += w
            elif term in ('q_km1', 'q_k', 'Q'):
                total += cross(ops[term], w)
            else:
                x, y = (term[:2], term[2:]) if term[:2] in ('Q1', 'Q2') else (term[:1], term[1:])
                total += cross(ops[x], cross(ops[y], w))
        res.append(total)
    return res[0], h[:, None] * res[1]


def coefficient_table() -> list[dict]:
    """
    Compare the printed coefficients of 003 (1.99)/(1.100) with the derived ones.

    Returns
    -------
    list of dict
        One row per term: ``equation``, ``term``, ``derived`` and ``printed`` (text, None when
        003 has no such term) and ``agrees``.

    """
    derived = derived_coefficients()
    rows = []
    for kind in ('velocity', 'position'):
        for term in _TERMS:
            d = derived[kind].get(term)
            p = PRINTED_COEFFICIENTS[kind].get(term)
            if d is None:
                continue
            rows.append({'equation': '1.99' if kind == 'velocity' else '1.100', 'term': term,
                         'derived': [str(x) for x in d],
                         'printed': [str(x) for x in p] if p else None,
                         'agrees': p is not None
                         and all(Fraction(x) == y for x, y in zip(p, d))})
    return rows


def markdown_coefficient_table() -> str:
    """
    Return the coefficient table of doc/navigation.md as markdown.

    Printed by ``python -m strapdown_ros.navigation.update``.

    Returns
    -------
    str
        The table and a one-line count of agreements.

    """
    lines = ['| eq. | term | derived (u₁, u₂, u₃) | printed | |', '|---|---|---|---|---|']
    for r in coefficient_table():
        printed = ', '.join(r['printed']) if r['printed'] else '—'
        if r['agrees']:
            verdict = 'agrees'
        else:
            verdict = '**misprint**' if r['printed'] else 'absent in 003'
        lines.append(f"| {r['equation']} | {r['term']} | {', '.join(r['derived'])} | {printed} "
                     f'| {verdict} |')
    n_bad = sum(1 for r in coefficient_table() if r['printed'] and not r['agrees'])
    n_ok = sum(1 for r in coefficient_table() if r['agrees'])
    lines.append('')
    lines.append(f'{n_ok} printed coefficient triples agree with the derivation exactly; '
                 f'{n_bad} do not.')
    return '\n'.join(lines)


if __name__ == '__main__':
    print(markdown_coefficient_table())
