"""
The coning-algorithm registry: the body rotation vector φ of one update from gyro increments.

Every algorithm forms φ from integrating-gyro increments q_i (Aksyonenko 2014, paper 003,
§1.4 and §2.2; literature forms after Miller 1983, Savage 1998 and Lee et al. 1990;
doc/references.md).  ``ALGORITHMS`` is the one home of the formulas: the attitude integrator,
its compiled kernel, the parameters of the nodes and the benchmarks all read it, so a new
algorithm is one ``phi`` function and one entry here (doc/architecture.md).

Every algorithm has the form ``φ = Σ q_i + Σ k_ij q_i × q_j`` over a *window* of
increments, oldest first.  A window holds ``history`` previous increments (already
used by earlier updates: the accelerating, "разгонные", algorithms 6 and 7) followed
by the ``samples`` new increments of this update.  The attitude update is then
``q_k = q_{k−1} ⊗ exp(φ)`` (003 eqs. 1.63/1.64 in quaternion form).

Cross-product convention: ``q_i × q_j`` with ``i`` earlier than ``j`` (the increment
multiplied on the right is the later one).  With it, the classical 2-sample
correction is ``+2/3 q1 × q2``.

Order of accuracy means the exponent p of the cone-axis drift ``ε ∝ α²Ω(Ωh)^p`` under
classical coning (h = update interval), the meaning the thesis uses ("algorithm 2 is of 4th
order"); p is always even.  The verdicts on the printed formulas of 003 and the derivations
of the corrected forms are in doc/coning_derivations.md.

All ``phi`` functions are vectorised: ``window`` has shape (M, history + samples, 3).
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache
from math import factorial
from typing import Callable

import numpy as np

from strapdown_ros.rotation import cross

__all__ = ['ConingAlgorithm', 'ALGORITHMS', 'get_algorithm', 'algorithm_names',
           'SEED_ALGORITHMS', 'LITERATURE_DRIFT', 'LITERATURE_DRIFT_TEXT',
           'spacing_coefficients', 'theory_drift', 'bilinear_form']


@dataclass(frozen=True)
class ConingAlgorithm:
    """
    One coning algorithm of the registry: its formula and what is known about it.

    Parameters
    ----------
    name : str
        Registry key, e.g. ``'2'`` (003's numbering) or ``'two_sample'``.
    samples : int
        New increments per update (N).
    history : int
        Previous increments used (accelerating algorithms), taken from earlier updates.
    phi : callable
        ``phi(window) -> (M, 3)`` rotation vector, rad, from ``window`` (M, history + samples,
        3), oldest increment first.
    cross_products : int
        Vector cross products per update.
    additions : int
        Vector additions and subtractions per update (Σq included).
    scalings : int
        Vector-by-scalar products per update.  The three counts are for the cheapest
        evaluation order, the attitude update itself not included.
    order_intended : int or None
        Order of accuracy claimed by the source (thesis or literature).
    order_expected : int or None
        Order of this form, from the moment conditions (doc/coning_derivations.md).
    source : str
        Equation or literature reference.
    formula : str
        The formula as implemented, for tables.
    note : str, optional
        Verdict on the printed form, or the published drift.

    """

    name: str
    samples: int
    history: int
    phi: Callable[[np.ndarray], np.ndarray]
    cross_products: int
    additions: int
    scalings: int
    order_intended: int | None
    order_expected: int | None
    source: str
    formula: str
    note: str = ''

    @property
    def window(self) -> int:
        """
        Return the number of increments one update reads, ``history + samples``.

        Returns
        -------
        int
            Window length.

        """
        return self.history + self.samples


def _x(a, b):
    return cross(a, b)


def _q(w, i):
    return w[:, i, :]


def _sum(w, start, n):
    return w[:, start:start + n, :].sum(axis=1)


# ---- 003 §1.4.5 / §2.2 non-accelerating ("безразгонные") algorithms --------------------
def _alg1(w):                                    # (1.76)/(2.14)
    return _q(w, 0)


def _alg2(w):                                    # (1.77)/(2.15)
    q1, q2 = _q(w, 0), _q(w, 1)
    return q1 + q2 + (2.0 / 3.0) * _x(q1, q2)


def _alg3(w):                                    # (1.78)/(2.16) corrected: operands in time order
    q1, q3 = _q(w, 0), _q(w, 2)
    return _sum(w, 0, 3) + (9.0 / 8.0) * _x(q1, q3)


def _alg3_printed(w):                            # (1.78) as printed: 9/8 q3 × q1
    q1, q3 = _q(w, 0), _q(w, 2)
    return _sum(w, 0, 3) + (9.0 / 8.0) * _x(q3, q1)


def _alg31(w):                                   # (1.79)/(2.17) corrected
    q1, q2, q3 = _q(w, 0), _q(w, 1), _q(w, 2)
    return _sum(w, 0, 3) + (9.0 / 20.0) * _x(q1 + 1.5 * q2, q3 - q1)


def _alg31_printed(w):                           # as printed: 9/20 (q3 − q1) × (q1 + 3/2 q2)
    q1, q2, q3 = _q(w, 0), _q(w, 1), _q(w, 2)
    return _sum(w, 0, 3) + (9.0 / 20.0) * _x(q3 - q1, q1 + 1.5 * q2)


def _alg4(w):                                    # (1.80)/(2.18)
    q1, q2, q3, q4 = (_q(w, i) for i in range(4))
    return q1 + q2 + q3 + q4 + (2.0 / 3.0) * _x(q1 + q2, q3 + q4)


def _alg4plus(w):
    # (1.81)/(2.19) corrected (doc/coning_derivations.md §4+)
    q1, q2, q3, q4 = (_q(w, i) for i in range(4))
    return (q1 + q2 + q3 + q4 + (22.0 / 15.0) * (_x(q1, q3) + _x(q2, q4))
            - (8.0 / 15.0) * _x(q2, q3))


def _alg4plus_runge(w):                          # Richardson (Runge) form of the thesis derivation
    q1, q2, q3, q4 = (_q(w, i) for i in range(4))
    return (q1 + q2 + q3 + q4 + (32.0 / 45.0) * (_x(q1, q2) + _x(q3, q4))
            + (22.0 / 45.0) * _x(q1 + q2, q3 + q4))


def _alg4plus_printed(w):
    # as printed: q2 + q2 + q3 + q3 + 4/3 [q1×q3 + q2×q3 + q2×q4]
    q1, q2, q3, q4 = (_q(w, i) for i in range(4))
    return q2 + q2 + q3 + q3 + (4.0 / 3.0) * (_x(q1, q3) + _x(q2, q3) + _x(q2, q4))


def _alg5(w):                                    # (1.82)/(2.20) corrected: operands in time order
    q1, q2, q3, q4, q5 = (_q(w, i) for i in range(5))
    return (q1 + q2 + q3 + q4 + q5 - (1375.0 / 432.0) * _x(q2, q4) - (1625.0 / 864.0) * _x(q1, q5)
            + (875.0 / 216.0) * (_x(q1, q4) + _x(q2, q5)))


def _alg5_printed(w):                            # as printed: later × earlier
    q1, q2, q3, q4, q5 = (_q(w, i) for i in range(5))
    return (q1 + q2 + q3 + q4 + q5 - (1375.0 / 432.0) * _x(q4, q2) - (1625.0 / 864.0) * _x(q5, q1)
            + (875.0 / 216.0) * (_x(q4, q1) + _x(q5, q2)))


# ---- 003 accelerating ("разгонные") algorithms: window = [previous..., current] ---------
def _alg6(w):                                    # (1.83)/(2.21): q2 + 1/12 q1 × q2
    q1, q2 = _q(w, 0), _q(w, 1)
    return q2 + (1.0 / 12.0) * _x(q1, q2)


def _alg7(w):
    # (1.84)/(2.22), causal reading (doc/coning_derivations.md §7)
    q1, q2, q3 = _q(w, 0), _q(w, 1), _q(w, 2)    # q3 current, q2, q1 previous
    return q3 + (1.0 / 6.0) * _x(q2, q3) - (1.0 / 24.0) * _x(q1, q3)


def _alg7_printed(w):
    # Literal time-ordered reading of "φ3 = q1 + 1/6 (q2×q1) − 1/24 (q3×q1)" with the
    # thesis's own index convention (q1 oldest, as in (1.83)): the rotation over the
    # newest interval is taken as the oldest increment plus corrections.
    q1, q2, q3 = _q(w, 0), _q(w, 1), _q(w, 2)
    return q1 + (1.0 / 6.0) * _x(q2, q1) - (1.0 / 24.0) * _x(q3, q1)


# ---- literature (seed-guide reference table) --------------------------------------------
def _three_poly(w):
    q1, q2, q3 = _q(w, 0), _q(w, 1), _q(w, 2)
    return q1 + q2 + q3 + (33.0 / 80.0) * _x(q1, q3) + (57.0 / 80.0) * _x(q2, q3 - q1)


def _three_opt(w):
    q1, q2, q3 = _q(w, 0), _q(w, 1), _q(w, 2)
    return q1 + q2 + q3 + (9.0 / 20.0) * _x(q1, q3) + (27.0 / 40.0) * _x(q2, q3 - q1)


def _four_opt(w):
    q1, q2, q3, q4 = (_q(w, i) for i in range(4))
    return q1 + q2 + q3 + q4 + _x((54.0 * q1 + 92.0 * q2 + 214.0 * q3) / 105.0, q4)


_T = '003'
_C = ConingAlgorithm
ALGORITHMS: dict[str, ConingAlgorithm] = {a.name: a for a in [
    _C('1', 1, 0, _alg1, 0, 0, 0, 2, 2, f'{_T} (1.76), (2.14)', 'φ = q1',
       'single sample; no coning correction'),
    _C('2', 2, 0, _alg2, 1, 2, 1, 4, 4, f'{_T} (1.77), (2.15)',
       'φ = q1 + q2 + 2/3 q1×q2', 'as printed: OK; identical to two_sample'),
    _C('3', 3, 0, _alg3, 1, 3, 1, 4, 4, f'{_T} (1.78), (2.16)',
       'φ = q1 + q2 + q3 + 9/8 q1×q3',
       'printed 9/8 q3×q1 has the operands reversed (order 2); corrected form is order 4'),
    _C('3_as_printed', 3, 0, _alg3_printed, 1, 3, 1, 4, 2, f'{_T} (1.78) as printed',
       'φ = q1 + q2 + q3 + 9/8 q3×q1', 'doubles the uncorrected drift'),
    _C('3.1', 3, 0, _alg31, 1, 5, 2, 4, 6, f'{_T} (1.79), (2.17)',
       'φ = q1 + q2 + q3 + 9/20 (q1 + 3/2 q2)×(q3 − q1)',
       'printed (q3 − q1)×(q1 + 3/2 q2) has the operands reversed (order 2); corrected form '
       'equals three_sample_optimal and reaches order 6 (the thesis claims 4)'),
    _C('3.1_as_printed', 3, 0, _alg31_printed, 1, 5, 2, 4, 2, f'{_T} (1.79) as printed',
       'φ = q1 + q2 + q3 + 9/20 (q3 − q1)×(q1 + 3/2 q2)', ''),
    _C('4', 4, 0, _alg4, 1, 4, 1, 4, 4, f'{_T} (1.80), (2.18)',
       'φ = Σq + 2/3 (q1 + q2)×(q3 + q4)',
       'as printed: OK; the 2-sample algorithm on pairs of increments'),
    _C('4+', 4, 0, _alg4plus_runge, 3, 6, 2, 5, 6, f'{_T} (1.81), (2.19); §1.4.4',
       'φ = Σq + 32/45 (q1×q2 + q3×q4) + 22/45 (q1 + q2)×(q3 + q4)',
       'printed form is garbled (sum q2+q2+q3+q3, order 2). This is the Runge (Richardson) '
       'extrapolation §1.4.4 describes, (16·fine − coarse)/15 with fine = two 2-sample '
       'updates and coarse = algorithm 4: 3 cross products, order 6 (odd orders cannot '
       'occur)'),
    _C('4+_printed_terms', 4, 0, _alg4plus, 3, 6, 2, 5, 6, f'{_T} (1.81) cross-product set',
       'φ = Σq + 22/15 (q1×q3 + q2×q4) − 8/15 q2×q3',
       'keeps the printed cross-product set and solves the two coning moment conditions; '
       'order 6 but a 20× larger coefficient than 4+'),
    _C('4+_as_printed', 4, 0, _alg4plus_printed, 3, 6, 1, 5, 2, f'{_T} (1.81) as printed',
       'φ = q2 + q2 + q3 + q3 + 4/3 [q1×q3 + q2×q3 + q2×q4]', ''),
    _C('5', 5, 0, _alg5, 4, 8, 3, 4, 6, f'{_T} (1.82), (2.20)',
       'φ = Σq − 1375/432 q2×q4 − 1625/864 q1×q5 + 875/216 (q1×q4 + q2×q5)',
       'printed later×earlier products have the operands reversed (order 2); corrected form '
       'reaches order 6 (the thesis claims 4)'),
    _C('5_as_printed', 5, 0, _alg5_printed, 4, 8, 3, 4, 2, f'{_T} (1.82) as printed',
       'φ = Σq − 1375/432 q4×q2 − 1625/864 q5×q1 + 875/216 (q4×q1 + q5×q2)', ''),
    _C('6', 1, 1, _alg6, 1, 1, 1, 3, 4, f'{_T} (1.83), (2.21)',
       'φ = q2 + 1/12 q1×q2 (q1 previous)',
       'as printed: OK; order 4, better than the claimed 3; identical to one_plus_previous'),
    _C('7', 1, 2, _alg7, 2, 2, 2, 4, 4, f'{_T} (1.84), (2.22)',
       'φ = q3 + 1/6 q2×q3 − 1/24 q1×q3 (q1, q2 previous)',
       'printed with newest-first indices; read causally it is order 4 as claimed, but its '
       'error coefficient is 1.5× that of algorithm 6'),
    _C('7_as_printed', 1, 2, _alg7_printed, 2, 2, 2, 4, 2, f'{_T} (1.84) as printed',
       'φ = q1 + 1/6 q2×q1 − 1/24 q3×q1 (q1 oldest)',
       'corrections of the wrong sign (order 2, twice the uncorrected drift); the attitude '
       'also lags by two samples'),
    # literature
    _C('one_plus_previous', 1, 1, _alg6, 1, 1, 1, 4, 4, 'Miller 1983; Savage 1998',
       'φ = q_k + 1/12 q_{k−1}×q_k', 'drift (Ωh)^4/60'),
    _C('two_sample', 2, 0, _alg2, 1, 2, 1, 4, 4, 'Miller 1983',
       'φ = q1 + q2 + 2/3 q1×q2', 'drift (Ωh)^4/960'),
    _C('three_sample_polynomial', 3, 0, _three_poly, 2, 5, 2, 4, 4, 'Lee et al. 1990',
       'φ = Σq + 33/80 q1×q3 + 57/80 q2×(q3 − q1)', 'drift −(Ωh)^4/6480'),
    _C('three_sample_optimal', 3, 0, _three_opt, 2, 5, 2, 6, 6, 'Miller 1983',
       'φ = Σq + 9/20 q1×q3 + 27/40 q2×(q3 − q1)', 'drift (Ωh)^6/204120'),
    _C('four_sample_optimal', 4, 0, _four_opt, 1, 6, 3, 8, 8, 'Lee et al. 1990',
       'φ = Σq + (54 q1 + 92 q2 + 214 q3)/105 × q4', 'drift (Ωh)^8/82575360'),
]}

#: the thesis's algorithms (corrected forms), in the thesis's numbering
SEED_ALGORITHMS = ('1', '2', '3', '3.1', '4', '4+', '5', '6', '7')

#: leading term of the cone-axis drift ε/(α²Ω) in Ωh, small α (seed-guide reference table)
LITERATURE_DRIFT = {
    '1': lambda x: x ** 2 / 12.0,
    'one_plus_previous': lambda x: x ** 4 / 60.0,
    'two_sample': lambda x: x ** 4 / 960.0,
    'three_sample_polynomial': lambda x: -x ** 4 / 6480.0,
    'three_sample_optimal': lambda x: x ** 6 / 204120.0,
    'four_sample_optimal': lambda x: x ** 8 / 82575360.0,
}

#: the same leading terms as printed in tables (the keys of :data:`LITERATURE_DRIFT`)
LITERATURE_DRIFT_TEXT = {
    '1': '(Ωh)²/12',
    'one_plus_previous': '(Ωh)⁴/60',
    'two_sample': '(Ωh)⁴/960',
    'three_sample_polynomial': '−(Ωh)⁴/6480',
    'three_sample_optimal': '(Ωh)⁶/204120',
    'four_sample_optimal': '(Ωh)⁸/82575360',
}


def spacing_coefficients(alg: ConingAlgorithm) -> dict[int, float] | None:
    """
    Return the net cross-product coefficient K_m of each index spacing m.

    K_m sums the coefficients of all ``q_i × q_j`` with ``j − i = m`` that involve at least
    one new increment.  They are read off ``alg.phi`` on unit vectors (every φ here is Σq
    plus a bilinear antisymmetric form).

    Parameters
    ----------
    alg : ConingAlgorithm
        The algorithm.

    Returns
    -------
    dict of int to float, or None
        ``{m: K_m}``; None when the linear part of φ is not the sum of the new increments (a
        garbled form).

    """
    n = alg.window
    new = list(range(alg.history, n))
    # linear part: one increment e_x at slot i must give e_x iff i is new
    for i in range(n):
        w = np.zeros((1, n, 3))
        w[0, i, 0] = 1.0
        expect = 1.0 if i in new else 0.0
        if abs(alg.phi(w)[0, 0] - expect) > 1e-12:
            return None
    k: dict[int, float] = {}
    for i in range(n):
        for j in range(i + 1, n):
            w = np.zeros((1, n, 3))
            w[0, i, 0] = 1.0
            w[0, j, 1] = 1.0
            c = alg.phi(w)[0, 2]              # z of k_ij e_x × e_y
            if abs(c) > 0:
                k[j - i] = k.get(j - i, 0.0) + c
    return k


@lru_cache(maxsize=None)
def bilinear_form(name: str) -> tuple[np.ndarray, np.ndarray] | None:
    """
    Return φ of an algorithm as a coefficient table, for the compiled block kernel.

    ``φ = Σ_i lin_i q_i + Σ_p k_p q_{i_p} × q_{j_p}`` over the window slots, oldest first.
    The table is read off ``phi`` itself, so the registry stays the one home of the formulas:
    ``lin_i`` from a unit x increment in slot i, ``k_ij`` from the z component of e_x in slot
    i and e_y in slot j.  It is then checked on random windows with increments from 1e-6 to
    1 rad: it must reproduce ``phi`` to 1e-13 relative.  A form that is not linear plus
    bilinear cross products is refused and evaluated by ``phi`` in numpy.

    Parameters
    ----------
    name : str
        Key of :data:`ALGORITHMS`.

    Returns
    -------
    tuple of ndarray, or None
        ``(lin (W,), pairs (P, 3))``, read-only; rows of ``pairs`` are ``(i_p, j_p, k_p)``
        with the slot indices as floats (:mod:`strapdown_ros.attitude.kernel`).  None when
        the table does not reproduce ``phi``.

    """
    alg = ALGORITHMS[name]
    n = alg.window
    lin = np.zeros(n)
    for i in range(n):
        w = np.zeros((1, n, 3))
        w[0, i, 0] = 1.0
        lin[i] = alg.phi(w)[0, 0]
    pairs = []
    for i in range(n):
        for j in range(i + 1, n):
            w = np.zeros((1, n, 3))
            w[0, i, 0] = 1.0
            w[0, j, 1] = 1.0
            c = float(alg.phi(w)[0, 2])
            if c != 0.0:
                pairs.append((i, j, c))
    table = np.array(pairs, dtype=float).reshape(-1, 3)
    pi, pj, kk = table[:, 0].astype(int), table[:, 1].astype(int), table[:, 2]
    rng = np.random.default_rng(12345)
    for scale in (1e-6, 1e-3, 1.0):
        w = scale * rng.normal(size=(16, n, 3))
        products = kk[None, :, None] * cross(w[:, pi], w[:, pj])
        rebuilt = np.einsum('i,mia->ma', lin, w) + products.sum(1)
        ref = alg.phi(w)
        if np.max(np.abs(rebuilt - ref)) > 1e-13 * np.max(np.abs(ref)):
            return None
    for a in (lin, table):
        a.setflags(write=False)
    return lin, table


def theory_drift(alg: ConingAlgorithm, omega_h) -> float | None:
    """
    Return the cone-axis drift ε/(α²Ω) to leading order in α, exact in Ωh.

    Under classical coning with x = Ωτ the z component of ``q_i × q_j`` is
    ``−sin²α·4 sin²(x/2)·sin((j−i)x)`` and Σq_z over an update of N increments exceeds
    the z component of the true rotation vector by ``½ sin²α (Nx − sin Nx)``.  With the
    error taken as computed minus true, per update
    ``e = α²[½(Nx − sin Nx) − Σ_m K_m 4 sin²(x/2) sin(mx)]`` and ``ε/(α²Ω) = e/(α² Nx)``.
    The bracket is evaluated as its Taylor series with exact rational coefficients, because
    the closed form cancels catastrophically for high orders at small Ωh
    (doc/coning_derivations.md).  Expanding in x reproduces :data:`LITERATURE_DRIFT`.

    Parameters
    ----------
    alg : ConingAlgorithm
        The algorithm.
    omega_h : float or ndarray
        Cone rate times update interval, Ωh, rad.

    Returns
    -------
    float or ndarray or None
        ε/(α²Ω), dimensionless, the shape of ``omega_h``; None for a form whose spacing
        coefficients cannot be read (:func:`spacing_coefficients`).

    """
    coeffs = _series_coefficients(alg)
    if coeffs is None:
        return None
    x = np.asarray(omega_h, dtype=float) / alg.samples
    total = np.zeros_like(x)
    x2 = x * x
    power = x ** 3
    for c in coeffs:                      # c_j multiplies x^(2j+1), j = 1, 2, ...
        total = total + c * power
        power = power * x2
    out = total / (alg.samples * x)
    return float(out) if out.ndim == 0 else out


@lru_cache(maxsize=None)
def _series_coefficients(alg: ConingAlgorithm, terms: int = 40):
    """Return the exact series coefficients of the drift bracket (cached per algorithm)."""
    k = spacing_coefficients(alg)
    if k is None:
        return None
    kf = {m: Fraction(v).limit_denominator(1_000_000) for m, v in k.items()}
    n = alg.samples

    def s(j, a):                          # coefficient of x^(2j+1) in sin(a x)
        return Fraction((-1) ** j * a ** (2 * j + 1), factorial(2 * j + 1))
    out = []
    for j in range(1, terms + 1):
        c = -Fraction(1, 2) * s(j, n)     # from ½(Nx − sin Nx); the x term cancels
        for m, km in kf.items():
            c -= km * (2 * s(j, m) - s(j, m + 1) - s(j, m - 1))
        out.append(float(c))
    return tuple(out)


def algorithm_names() -> list[str]:
    """
    Return the names of the registered algorithms, in registry order.

    Returns
    -------
    list of str
        Keys of :data:`ALGORITHMS`.

    """
    return list(ALGORITHMS)


def get_algorithm(name: str) -> ConingAlgorithm:
    """
    Return the registered algorithm of a name.

    Parameters
    ----------
    name : str
        Key of :data:`ALGORITHMS`.

    Returns
    -------
    ConingAlgorithm
        The algorithm.

    Raises
    ------
    ValueError
        For an unknown name; the message lists the valid names.

    """
    try:
        return ALGORITHMS[name]
    except KeyError:
        raise ValueError(f'unknown coning algorithm {name!r}; valid names: '
                         f"{', '.join(ALGORITHMS)}") from None
