"""
Rotation increments from star-tracker attitudes (Ilyushenko 2009, paper 002).

The integral method needs V_n = ∫w dt over each step between two star-tracker fixes.  002
integrates attitude with a modified Euler formula of order 2 or 3 with norm correction; this
module holds that forward step and its exact inverse, which recovers V_n from the relative
quaternion of two fixes, vectorised over a whole run, plus the Jacobians of V_n with respect to
the fix errors.  Used by :mod:`strapdown_ros.calibration.interval_means`; the derivation and the
measured orders are in doc/integral_method.md.  No ROS; numpy only.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.rotation import (quat_conjugate, quat_multiply, quat_normalize,
                                    quat_to_rotvec, skew)

__all__ = ['FORMS', 'ORDERS', 'forward_step', 'invert_step', 'noise_jacobians',
           'relative_quaternions', 'step_increments']

ORDERS = (2, 3)
FORMS = ('paper', 'rotvec')


# ------------------------------------------------------------------ quaternion formulas
def forward_step(a_prev: np.ndarray, V: np.ndarray, V_prev: np.ndarray | None = None,
                 order: int = 2, reverse_cross: bool = False) -> np.ndarray:
    """
    Take 002's modified Euler step with norm correction: a_n from a_{n−1} and V_n = ∫w dt.

    Order 2: ``a_{n−1}∘(1 + ½V − ⅛|V|² + ½(1 − |a_{n−1}|²))``; order 3 adds
    ``(1/24)V_n × (V_n − V_{n−1}) − (1/48)|V_n|²V_n``.  Not normalised: the norm correction
    keeps |a| near 1, as in the paper.  Vectorised.

    Parameters
    ----------
    a_prev : (..., 4) ndarray
        Attitude a_{n−1}, q_ref_body, scalar first.
    V : (..., 3) ndarray
        Rotation increment V_n of the step, body axes, rad.
    V_prev : (..., 3) ndarray, optional
        The previous increment V_{n−1}, rad; needed by order 3.
    order : {2, 3}
        Order of the formula.
    reverse_cross : bool
        Swap the operands of the cross product (a hypothesis the tests reject).

    Returns
    -------
    (..., 4) ndarray
        a_n, not normalised.

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
    Recover V_n = ∫w dt from the relative quaternion Δa_n = a_{n−1}⁻¹∘a_n, vectorised.

    Order 2: 2·vect(Δa).  Order 3: the exact inverse of :func:`forward_step` (order 3),
    ``V = (c²b + (p·b)p − c·p×b)/(c(c² + |p|²))`` with b = 24·vect(Δa), c = 12 − ½|V|²,
    p = V_prev and the printed |V|² = −8·scal(Δa) + 12 − 4|a_{n−1}|².  ``form='rotvec'``:
    log(Δa) − (1/12)V_prev×log(Δa).  Δa is used as given (not normalised), so a round trip
    through :func:`forward_step` is exact.

    Parameters
    ----------
    delta_a : (..., 4) ndarray
        Relative quaternion Δa_n, scalar first.
    V_prev : (..., 3) ndarray, optional
        The neighbour increment of the coning term, rad; needed by order 3.
    order : {2, 3}
        Order of the inverted formula.
    form : {'paper', 'rotvec'}
        002's vector part, or the exact rotation vector log(Δa).
    norm2_prev : float or ndarray
        |a_{n−1}|², 1 for star-tracker quaternions.

    Returns
    -------
    (..., 3) ndarray
        V_n, body axes, rad.

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


def relative_quaternions(quats: np.ndarray) -> np.ndarray:
    """
    Return the relative quaternions a_{n−1}*∘a_n of consecutive attitudes, shortest rotation.

    Parameters
    ----------
    quats : (N, 4) ndarray
        Attitudes q_ref_body, scalar first (normalised here).

    Returns
    -------
    (N−1, 4) ndarray
        Δa_n with scalar part ≥ 0.

    """
    q = quat_normalize(np.asarray(quats, dtype=float))
    dq = quat_multiply(quat_conjugate(q[:-1]), q[1:])
    return np.where(dq[:, :1] < 0.0, -dq, dq)                 # shortest rotation per step


def step_increments(quats: np.ndarray, order: int = 3, form: str = 'paper',
                    breaks: np.ndarray | None = None, neighbour: str = 'previous',
                    max_passes: int = 30) -> np.ndarray:
    """
    Return ∫w dt over each star-tracker step from N attitudes.

    Order 2: V_n = 2·vect(a_{n−1}*∘a_n); order 3: the inverse of 002's third-order formula,
    solved by vectorised fixed-point passes (doc/integral_method.md).  A step whose previous
    one is a break (or the first step) takes its coning correction from the next step.

    Parameters
    ----------
    quats : (N, 4) ndarray
        Attitudes q_ref_body, scalar first.
    order : {2, 3}
        Order of the inverted formula.
    form : {'paper', 'rotvec'}
        002's 2·vect(Δa) and |V|² terms, or the exact rotation vector log(Δa).
    breaks : (N−1,) bool ndarray, optional
        Steps not to be used as a neighbour of the coning correction (a data gap).
    neighbour : {'previous', 'adaptive'}
        'previous' is the paper (V_{n−1}); 'adaptive' takes whichever of V_{n−1}, V_{n+1}
        differs less from V_n (exact when rate jumps fall on fixes, worse on average).
    max_passes : int
        Limit of fixed-point passes of the order-3 recursion.

    Returns
    -------
    (N−1, 3) ndarray
        V_n, body axes, rad.

    """
    if order not in ORDERS:
        raise ValueError(f'order must be one of {ORDERS}, got {order!r}')
    if form not in FORMS:
        raise ValueError(f'form must be one of {FORMS}, got {form!r}')
    dq = relative_quaternions(quats)
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

    # start from the |V|² term of the scalar part
    V = V0 if form == 'rotvec' else V0 * (1.0 + 8.0 * (1.0 - dq[:, :1]) / 24.0)
    for _ in range(max(1, max_passes)):     # fixed point; p = 0 where no neighbour exists
        V_new = invert_step(dq, neighbour(V), order=3, form=form)
        done = np.max(np.abs(V_new - V)) <= 1e-16 * max(float(np.max(np.abs(V_new))), 1e-300)
        V = V_new
        if done:
            break
    return V


def noise_jacobians(quats: np.ndarray):
    """
    Return ∂V_n/∂θ_n and ∂V_n/∂θ_{n−1} for right-perturbations θ of the fixes.

    The second-order form: δV_n = (cI + [v×])θ_n + (−cI + [v×])θ_{n−1}, (c, v) = Δa_n.

    Parameters
    ----------
    quats : (N, 4) ndarray
        Attitudes q_ref_body of the fixes, scalar first.

    Returns
    -------
    tuple of two (N−1, 3, 3) ndarray
        The Jacobians with respect to the fix ending and the fix starting each step.

    """
    dq = relative_quaternions(quats)
    c = dq[:, 0][:, None, None]
    S = skew(dq[:, 1:])
    I3 = np.eye(3)
    return c * I3 + S, -c * I3 + S
