"""
Rotations: quaternions, direction-cosine matrices (DCM), rotation vectors, Euler angles.

Conventions (stated once, used everywhere in the core)
------------------------------------------------------
* Quaternions are **Hamilton** quaternions, stored **scalar-first** ``[w, x, y, z]``
  as numpy arrays of shape ``(..., 4)``. ROS messages use ``x, y, z, w``; the
  conversion happens only at the edge (:func:`to_ros_xyzw`, :func:`from_ros_xyzw`).
* An attitude ``q_a_b`` (or DCM ``C_a_b``) **maps vectors from frame b to frame a**:
  ``v_a = q_a_b ⊗ v_b ⊗ q_a_b*`` and ``v_a = C_a_b @ v_b``.  The SINS attitude is
  ``q_ref_body`` (body → reference), exactly the thesis matrix ``U`` of 003
  (``dU/dt = U·[ω×]`` with ω the body rate in body axes) and 004's
  ``S_GCRS^MF`` (MF coordinates → GCRS coordinates).  It is also the ROS meaning
  of an orientation: the pose of the child (body) frame in the parent frame.
* Composition: ``q_a_c = q_a_b ⊗ q_b_c``.  A body-frame increment ``φ`` (rotation
  vector in body axes, from integrating gyros) updates ``q_k = q_{k-1} ⊗ exp(φ)``.
* Rotation vector ``φ = angle·axis`` (radians), right-handed.
  ``exp(φ) = [cos(|φ|/2), sin(|φ|/2)·φ/|φ|]``.
* Small attitude errors are right-perturbations in body axes:
  ``q_true = q_est ⊗ exp(-ε)``, equivalently ``C_est ≈ C_true (I + [ε×])``,
  the definition of ε in 004 §2.3.
* Units: radians, seconds (REP-103).
* Euler angles: 004's heading/pitch/roll ``C = R_z(−ψ) R_x(ϑ) R_y(γ)`` (:func:`ypr_to_dcm`)
  and 000's aircraft angles (:func:`aircraft_angles_to_quat`).

Everything is vectorised: functions accept arrays with any leading shape.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = [
    'skew', 'quat_multiply', 'quat_conjugate', 'quat_normalize', 'quat_identity',
    'rotvec_to_quat', 'quat_to_rotvec', 'quat_to_dcm', 'dcm_to_quat', 'rotvec_to_dcm',
    'quat_rotate', 'quat_angle_between', 'quat_error_rotvec', 'quat_cumprod',
    'to_ros_xyzw', 'from_ros_xyzw', 'elementary_dcm', 'ypr_to_dcm', 'dcm_to_ypr',
    'aircraft_angles_to_quat', 'ypr_error_to_rotation',
]


#: the signs that conjugate a quaternion
_CONJUGATE_SIGNS = np.array([1.0, -1.0, -1.0, -1.0])


def _dcm_terms():
    """Return the terms of C(q) in the products q_i q_j (index 4 i + j of q qᵀ, w x y z)."""
    w, x, y, z = range(4)
    rows = [  # (a, b, sign): C_ij is 1 − 2(a + b) on the diagonal, 2(a + sign·b) off it
        (y * 4 + y, z * 4 + z, 1.0), (x * 4 + y, w * 4 + z, -1.0), (x * 4 + z, w * 4 + y, 1.0),
        (x * 4 + y, w * 4 + z, 1.0), (x * 4 + x, z * 4 + z, 1.0), (y * 4 + z, w * 4 + x, -1.0),
        (x * 4 + z, w * 4 + y, -1.0), (y * 4 + z, w * 4 + x, 1.0), (x * 4 + x, y * 4 + y, 1.0)]
    a, b, sign = (np.array(c) for c in zip(*rows))
    diagonal = np.eye(3).reshape(9) > 0
    return a, b, sign, np.where(diagonal, -2.0, 2.0), np.where(diagonal, 1.0, 0.0)


#: quat_to_dcm's index and factor arrays (:func:`_dcm_terms`)
_DCM_TERMS = _dcm_terms()


def skew(v: np.ndarray) -> np.ndarray:
    """
    Return the cross-product matrix ``[v×]``, so that ``[v×] @ u == v × u``.

    Parameters
    ----------
    v : array_like (..., 3)
        Vectors.

    Returns
    -------
    ndarray (..., 3, 3)
        Skew-symmetric matrices.

    """
    v = np.asarray(v, dtype=float)
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([np.stack([z, -w, y], -1),
                     np.stack([w, z, -x], -1),
                     np.stack([-y, x, z], -1)], -2)


def quat_identity(shape=()) -> np.ndarray:
    """
    Return identity quaternions ``[1, 0, 0, 0]``.

    Parameters
    ----------
    shape : int or tuple of int
        Leading shape (``()``: one quaternion).

    Returns
    -------
    ndarray (*shape, 4)
        Scalar-first identity quaternions.

    """
    q = np.zeros(tuple(np.atleast_1d(shape)) + (4,) if shape != () else (4,))
    q[..., 0] = 1.0
    return q


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """
    Return ``a × b`` over the last axis (length 3), broadcasting.

    Computed by components: ``np.cross`` spends most of its time moving axes and casting, and is
    several times slower on long arrays.

    Parameters
    ----------
    a, b : array_like (..., 3)
        Vectors, broadcast against each other.

    Returns
    -------
    ndarray (..., 3)
        The cross products.

    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """
    Return the Hamilton product ``p ⊗ q`` (scalar-first), broadcasting over leading axes.

    Parameters
    ----------
    p, q : array_like (..., 4)
        Quaternions ``[w, x, y, z]``; ``q_a_b ⊗ q_b_c = q_a_c``.

    Returns
    -------
    ndarray (..., 4)
        The products.

    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    if p.shape == (4,) and q.shape == (4,):           # two quaternions: the same arithmetic, fast
        pw, px, py, pz = p.tolist()
        qw, qx, qy, qz = q.tolist()
        return np.array([pw * qw - px * qx - py * qy - pz * qz,
                         pw * qx + px * qw + py * qz - pz * qy,
                         pw * qy - px * qz + py * qw + pz * qx,
                         pw * qz + px * qy - py * qx + pz * qw])
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ], axis=-1)


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """
    Return the conjugate ``q*`` (the inverse of a unit quaternion).

    Parameters
    ----------
    q : array_like (..., 4)
        Scalar-first quaternions.

    Returns
    -------
    ndarray (..., 4)
        ``[w, −x, −y, −z]``.

    """
    q = np.asarray(q, dtype=float)
    if q.shape == (4,):                               # one quaternion: the same arithmetic, fast
        w, x, y, z = q.tolist()
        return np.array([w, -x, -y, -z])
    return q * _CONJUGATE_SIGNS


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """
    Return quaternions scaled to unit norm.

    Parameters
    ----------
    q : array_like (..., 4)
        Non-zero quaternions.

    Returns
    -------
    ndarray (..., 4)
        Unit quaternions.

    """
    q = np.asarray(q, dtype=float)
    if q.shape == (4,):         # one quaternion: the same sum of squares in the same order, fast
        w, x, y, z = q.tolist()
        n = math.sqrt(w * w + x * x + y * y + z * z)
        if 0.0 < n < math.inf:                        # (else numpy's NaN/inf, with its warning)
            return np.array([w / n, x / n, y / n, z / n])
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def rotvec_to_quat(phi: np.ndarray) -> np.ndarray:
    """
    Return ``exp(φ)``: rotation vectors to unit quaternions.

    Uses ``sin(a/2)/a = sinc(a/2π)/2``, exact to round-off at any angle, including zero.

    Parameters
    ----------
    phi : array_like (..., 3)
        Rotation vectors, rad.

    Returns
    -------
    ndarray (..., 4)
        Unit quaternions, scalar first.

    """
    phi = np.asarray(phi, dtype=float)
    if phi.shape == (3,):                             # one vector: the same formula, fast
        x, y, z = phi.tolist()
        a = math.sqrt(x * x + y * y + z * z)
        if a < math.inf:                              # (else numpy's NaN, with its warning)
            u = math.pi * (a / (2.0 * math.pi)) if a else math.pi * 1e-20   # np.sinc's argument
            half_sinc = 0.5 * (math.sin(u) / u)
            return np.array([math.cos(0.5 * a), x * half_sinc, y * half_sinc, z * half_sinc])
    angle = np.linalg.norm(phi, axis=-1, keepdims=True)
    half_sinc = 0.5 * np.sinc(angle / (2.0 * np.pi))   # sin(a/2)/a
    return np.concatenate([np.cos(0.5 * angle), phi * half_sinc], axis=-1)


def quat_to_rotvec(q: np.ndarray) -> np.ndarray:
    """
    Return ``log(q)``: unit quaternions to rotation vectors with angle in [0, π].

    Parameters
    ----------
    q : array_like (..., 4)
        Unit quaternions, scalar first (q and −q give the same vector).

    Returns
    -------
    ndarray (..., 3)
        Rotation vectors, rad.

    """
    q = np.asarray(q, dtype=float)
    if q.shape == (4,):                               # one quaternion: the same formula, fast
        w, x, y, z = q.tolist()
        if w < 0.0:
            w, x, y, z = -w, -x, -y, -z
        s = math.sqrt(x * x + y * y + z * z)
        if s > 1e-12:
            f = 2.0 * math.atan2(s, w) / s
            return np.array([x * f, y * f, z * f])
        if w > 0.0:                                   # the s → 0 limit (w = 0: numpy's NaN)
            f = 2.0 / w * (1.0 + s * s / (3.0 * (w * w)))
            return np.array([x * f, y * f, z * f])
    q = np.where(q[..., :1] < 0.0, -q, q)            # shortest rotation
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., :1])
    # angle / s, with the s → 0 limit 2/w (w ≈ 1 there); each branch sees only safe operands
    small = s <= 1e-12
    w = np.where(small, q[..., :1], 1.0)
    factor = np.where(small, 2.0 / w * (1.0 + s * s / (3.0 * w ** 2)),
                      angle / np.where(small, 1.0, s))
    return v * factor


def quat_to_dcm(q: np.ndarray) -> np.ndarray:
    """
    Convert unit quaternions ``q_a_b`` to DCMs ``C_a_b``.

    Parameters
    ----------
    q : array_like (..., 4)
        Unit quaternions, scalar first.

    Returns
    -------
    ndarray (..., 3, 3)
        ``C_a_b``, mapping b-coordinates to a-coordinates.

    """
    q = np.asarray(q, dtype=float)
    if q.shape == (4,):                               # one quaternion: the same arithmetic, fast
        w, x, y, z = q.tolist()
        return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                         [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                         [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    # the same arithmetic on every quaternion at once: each element is a ± b of two products
    # of the outer product q qᵀ, then 1 − 2(a + b) on the diagonal and 2(a ± b) off it
    # (:data:`_DCM_TERMS`), in 8 array operations instead of 40
    qq = (q[..., :, None] * q[..., None, :]).reshape(q.shape[:-1] + (16,))
    a, b, sign, scale, offset = _DCM_TERMS
    return (offset + scale * (qq[..., a] + sign * qq[..., b])).reshape(q.shape[:-1] + (3, 3))


def dcm_to_quat(C: np.ndarray) -> np.ndarray:
    """
    Convert DCMs to unit quaternions with w ≥ 0 (Shepperd's method, robust at any angle).

    Parameters
    ----------
    C : array_like (..., 3, 3)
        Rotation matrices ``C_a_b``.

    Returns
    -------
    ndarray (..., 4)
        ``q_a_b``, scalar first, w ≥ 0.

    """
    C = np.asarray(C, dtype=float)
    shape = C.shape[:-2]
    C = C.reshape(-1, 3, 3)
    tr = np.trace(C, axis1=1, axis2=2)
    diag = np.stack([C[:, 0, 0], C[:, 1, 1], C[:, 2, 2]], -1)
    choice = np.argmax(np.concatenate([tr[:, None], diag], 1), axis=1)
    q = np.empty((C.shape[0], 4))
    for i in range(C.shape[0]):          # branch per element; DCM conversion is not a hot path
        c = C[i]
        k = choice[i]
        if k == 0:
            s = 2.0 * np.sqrt(1.0 + tr[i])
            q[i] = [0.25 * s, (c[2, 1] - c[1, 2]) / s,
                    (c[0, 2] - c[2, 0]) / s, (c[1, 0] - c[0, 1]) / s]
        elif k == 1:
            s = 2.0 * np.sqrt(1.0 + c[0, 0] - c[1, 1] - c[2, 2])
            q[i] = [(c[2, 1] - c[1, 2]) / s, 0.25 * s,
                    (c[0, 1] + c[1, 0]) / s, (c[0, 2] + c[2, 0]) / s]
        elif k == 2:
            s = 2.0 * np.sqrt(1.0 + c[1, 1] - c[0, 0] - c[2, 2])
            q[i] = [(c[0, 2] - c[2, 0]) / s, (c[0, 1] + c[1, 0]) / s,
                    0.25 * s, (c[1, 2] + c[2, 1]) / s]
        else:
            s = 2.0 * np.sqrt(1.0 + c[2, 2] - c[0, 0] - c[1, 1])
            q[i] = [(c[1, 0] - c[0, 1]) / s, (c[0, 2] + c[2, 0]) / s,
                    (c[1, 2] + c[2, 1]) / s, 0.25 * s]
    q = np.where(q[:, :1] < 0, -q, q)
    return quat_normalize(q).reshape(shape + (4,))


def rotvec_to_dcm(phi: np.ndarray) -> np.ndarray:
    """
    Return the DCM of rotation vectors (Rodrigues' formula, 003 eq. 1.26/1.42/1.63).

    ``E + sin φ/φ·Φ + (1-cos φ)/φ²·Φ²``, computed through the quaternion.

    Parameters
    ----------
    phi : array_like (..., 3)
        Rotation vectors, rad.

    Returns
    -------
    ndarray (..., 3, 3)
        Rotation matrices.

    """
    return quat_to_dcm(rotvec_to_quat(phi))


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """
    Rotate vectors: ``q ⊗ v ⊗ q*``.

    Parameters
    ----------
    q : array_like (..., 4)
        Unit quaternions ``q_a_b``, scalar first.
    v : array_like (..., 3)
        Vectors in b-coordinates.

    Returns
    -------
    ndarray (..., 3)
        The vectors in a-coordinates.

    """
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    qv = q[..., 1:]
    t = 2.0 * cross(qv, v)
    return v + q[..., :1] * t + cross(qv, t)


def quat_error_rotvec(q_est: np.ndarray, q_true: np.ndarray, frame: str = 'body') -> np.ndarray:
    """
    Return the attitude error as a rotation vector.

    Parameters
    ----------
    q_est, q_true : array_like (..., 4)
        Estimated and true attitudes ``q_ref_body``, scalar first.
    frame : {'body', 'reference'}
        ``'body'``: ε with ``q_est = q_true ⊗ exp(ε)`` (body axes, 004's definition);
        ``'reference'``: e with ``q_est = exp(e) ⊗ q_true`` (reference axes).

    Returns
    -------
    ndarray (..., 3)
        The error, rad.

    Raises
    ------
    ValueError
        For another ``frame``.

    """
    if frame == 'body':
        d = quat_multiply(quat_conjugate(q_true), q_est)
    elif frame == 'reference':
        d = quat_multiply(q_est, quat_conjugate(q_true))
    else:
        raise ValueError(f"frame must be 'body' or 'reference', got {frame!r}")
    return quat_to_rotvec(d)


def quat_angle_between(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """
    Return the angle of the rotation between two attitudes.

    Parameters
    ----------
    q1, q2 : array_like (..., 4)
        Unit quaternions, scalar first.

    Returns
    -------
    ndarray (...)
        The angle, rad, in [0, π].

    """
    d = quat_multiply(quat_conjugate(q1), q2)
    return 2.0 * np.arctan2(np.linalg.norm(d[..., 1:], axis=-1), np.abs(d[..., 0]))


def quat_cumprod(q0: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """
    Return the running attitude ``q_k = q0 ⊗ dq_1 ⊗ … ⊗ dq_k``, vectorised.

    A blocked scan with O(n) work (blocks of 16, the block totals scanned recursively), each
    result renormalised at the end; mathematically identical to the sequential update
    (003 eq. 1.64).

    Parameters
    ----------
    q0 : array_like (4,)
        Initial attitude, scalar first.
    dq : array_like (n, 4)
        Attitude increments, in order.

    Returns
    -------
    ndarray (n, 4)
        ``q_1 … q_n``, unit norm.

    """
    q0 = np.asarray(q0, dtype=float)
    x = np.asarray(dq, dtype=float)
    n = x.shape[0]
    if n <= 16:                                       # short: sequential, quat_multiply's
        pw, px, py, pz = q0.reshape(4).tolist()       # arithmetic on floats
        rows = []
        for qw, qx, qy, qz in x.tolist():
            pw, px, py, pz = (pw * qw - px * qx - py * qy - pz * qz,
                              pw * qx + px * qw + py * qz - pz * qy,
                              pw * qy - px * qz + py * qw + pz * qx,
                              pw * qz + px * qy - py * qx + pz * qw)
            rows.append((pw, px, py, pz))
        out = np.array(rows, dtype=float).reshape(n, 4)
        return out / np.linalg.norm(out, axis=-1, keepdims=True)
    b = 16                                            # block length: few passes, long vectors
    m = -(-n // b)                                    # number of blocks
    blocks = np.empty((m * b, 4))
    blocks[:n] = x
    blocks[n:] = (1.0, 0.0, 0.0, 0.0)                 # identity padding
    blocks = blocks.reshape(m, b, 4)
    for i in range(1, b):                             # prefix inside every block at once
        blocks[:, i] = quat_multiply(blocks[:, i - 1], blocks[:, i])
    head = np.empty((m, 4))                           # q0 ⊗ (product of all earlier blocks)
    head[0] = q0
    if m > 1:
        head[1:] = quat_cumprod(q0, blocks[:-1, -1])
    out = quat_multiply(head[:, None, :], blocks).reshape(m * b, 4)[:n]
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


# --- ROS edge helpers -------------------------------------------------------------
def to_ros_xyzw(q: np.ndarray) -> np.ndarray:
    """
    Reorder scalar-first ``[w,x,y,z]`` to the ROS order ``[x,y,z,w]``.

    Parameters
    ----------
    q : array_like (..., 4)
        Scalar-first quaternions.

    Returns
    -------
    ndarray (..., 4)
        The same quaternions, ROS order.

    """
    q = np.asarray(q, dtype=float)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def from_ros_xyzw(q: np.ndarray) -> np.ndarray:
    """
    Reorder the ROS order ``[x,y,z,w]`` to scalar-first ``[w,x,y,z]``.

    Parameters
    ----------
    q : array_like (..., 4)
        Quaternions in ROS order.

    Returns
    -------
    ndarray (..., 4)
        The same quaternions, scalar first.

    """
    q = np.asarray(q, dtype=float)
    return np.concatenate([q[..., 3:], q[..., :3]], axis=-1)


# --- Euler sequences of the seeds --------------------------------------------------
def elementary_dcm(axis: int, angle) -> np.ndarray:
    """
    Return the active rotation by ``angle`` about a coordinate axis: ``exp([angle·e ×])``.

    Parameters
    ----------
    axis : {0, 1, 2}
        x, y or z.
    angle : float or array_like (...)
        Angle, rad.

    Returns
    -------
    ndarray (..., 3, 3)
        Rotation matrices.

    """
    angle = np.asarray(angle, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(angle), np.zeros_like(angle)
    if axis == 0:
        rows = [[one, zero, zero], [zero, c, -s], [zero, s, c]]
    elif axis == 1:
        rows = [[c, zero, s], [zero, one, zero], [-s, zero, c]]
    elif axis == 2:
        rows = [[c, -s, zero], [s, c, zero], [zero, zero, one]]
    else:
        raise ValueError('axis must be 0, 1 or 2')
    return np.stack([np.stack(r, -1) for r in rows], -2)


# 004 §1, eq. (1): C_MF^VF = R_ψ(β_ψ) R_ϑ(β_ϑ) R_γ(β_γ), heading/pitch/roll of VF relative to MF.
# The axes are those of an ENU-like parent (x east/right, y north/forward — the longitudinal
# axis — z up).  004's own D matrices (§5) fix the signs: D2 = C·D1 has columns
# [0, 0, −1], [cos ψ, −sin ψ, 0], [sin ψ cos ϑ, cos ψ cos ϑ, sin ϑ], i.e. the heading ψ turns
# *clockwise* seen from +z (compass heading, R_ψ = R_z(−ψ)), pitch ϑ is about the once-turned
# x axis (R_x(ϑ)), roll γ about the twice-turned y axis (R_y(γ)).  The matrix maps child (VF)
# coordinates to parent (MF) coordinates.


def ypr_to_dcm(yaw, pitch, roll) -> np.ndarray:
    """
    Return ``C_parent_child = R_z(−ψ) R_x(ϑ) R_y(γ)`` (004 eq. 1).

    Parameters
    ----------
    yaw, pitch, roll : float or array_like (...)
        ψ, ϑ, γ, rad.

    Returns
    -------
    ndarray (..., 3, 3)
        The DCM mapping child to parent coordinates.

    """
    return (elementary_dcm(2, -np.asarray(yaw, dtype=float)) @ elementary_dcm(0, pitch)
            @ elementary_dcm(1, roll))


def dcm_to_ypr(C: np.ndarray) -> np.ndarray:
    """
    Return the angles of :func:`ypr_to_dcm`; pitch in [-π/2, π/2].

    Parameters
    ----------
    C : array_like (..., 3, 3)
        ``C_parent_child``.

    Returns
    -------
    ndarray (..., 3)
        [ψ, ϑ, γ], rad.

    """
    C = np.asarray(C, dtype=float)
    # R_z(−ψ)R_x(ϑ)R_y(γ): C[2,1] = sin ϑ, C[0,1] = sin ψ cos ϑ, C[1,1] = cos ψ cos ϑ,
    # C[2,0] = −cos ϑ sin γ, C[2,2] = cos ϑ cos γ
    pitch = np.arcsin(np.clip(C[..., 2, 1], -1.0, 1.0))
    yaw = np.arctan2(C[..., 0, 1], C[..., 1, 1])
    roll = np.arctan2(-C[..., 2, 0], C[..., 2, 2])
    return np.stack([yaw, pitch, roll], -1)


def ypr_error_to_rotation(yaw, pitch, roll) -> tuple[np.ndarray, np.ndarray]:
    """
    Map a perturbation of (ψ, ϑ, γ) into the rotation error of C (004 §5).

    The small-angle maps ``θ_child = D1 δβ`` and ``θ_parent = D2 δβ = C D1 δβ``, with
    ``C ≈ C̆(I + [θ_child×])``.

    Parameters
    ----------
    yaw, pitch, roll : float
        ψ, ϑ, γ of C, rad.

    Returns
    -------
    (ndarray (3, 3), ndarray (3, 3))
        D1 (child axes) and D2 (parent axes).

    """
    sy, cy = np.sin(yaw), np.cos(yaw)
    sp, cp = np.sin(pitch), np.cos(pitch)
    d2 = np.array([[0.0, cy, cp * sy], [0.0, -sy, cp * cy], [-1.0, 0.0, sp]])
    C = ypr_to_dcm(yaw, pitch, roll)
    return C.T @ d2, d2


# 000 §6: "aircraft" angles (Lurie, Analytical mechanics): yaw φ1, pitch φ2, roll φ3.
# Lurie's aircraft axes: x longitudinal (forward), y normal (up), z lateral (right).
# Sequence: yaw about y, then pitch about the new z, then roll about the new x;
# the quaternion maps body (J) coordinates to the reference basis (L).
AIRCRAFT_AXES = (1, 2, 0)


def aircraft_angles_to_quat(angles) -> np.ndarray:
    """
    Return ``N_L_J(φ) = exp(φ1·e_y/2) ⊗ exp(φ2·e_z/2) ⊗ exp(φ3·e_x/2)`` (000 §6).

    Parameters
    ----------
    angles : array_like (..., 3)
        Aircraft angles φ1 (yaw), φ2 (pitch), φ3 (roll), rad.

    Returns
    -------
    ndarray (..., 4)
        ``q_L_J``, scalar first: body (J) coordinates to the reference basis (L).

    """
    angles = np.asarray(angles, dtype=float)
    q = None
    for axis, k in zip(AIRCRAFT_AXES, range(3)):
        rv = np.zeros(angles.shape[:-1] + (3,))
        rv[..., axis] = angles[..., k]
        e = rotvec_to_quat(rv)
        q = e if q is None else quat_multiply(q, e)
    return q
