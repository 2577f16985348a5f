"""
The live model check's per-fix arithmetic as compiled loops (optional, with numba).

:class:`~strapdown_ros.estimation.model_check.ModelCheck` runs these when numba is installed
and :func:`~strapdown_ros.attitude.kernel.kernels_allowed` (``STRAPDOWN_KERNEL=numpy`` switches
them off) and its effects' partials are linear in the registry's features
(:func:`~strapdown_ros.sensors.effect_base.linear_partials`); otherwise it runs its numpy path.
Both compute the same mathematics (the tests run both on the same fixes and compare them).

**Signatures of one fix interval** (``accumulate``).  The increments d_i (lengths h_i, end
stamps t_i) since the last fix, ``lump`` at a time (the last lump takes the rest)::

    ρ_k = Σ d_i − b Σ h_i,   T_k = Σ h_i,   t_k = t_last − T_k/2 − epoch    bias-compensated lump
    q_k = q_{k−1} ⊗ exp(ρ_k),   C_k = C(q_k)              body at the last fix ← body at its end
    u_k = [ρ_k, |ρ_k|, T_k, T_k t_k]        features (effect_base.partial_features)
    J_k = Σ_f u_kf B_f                       every effect's filter partials (B: linear_partials)
    J_k[:, c] *= exp(−s_k λ_c)               a decaying filter state (s_k: the lump's middle
                                             since the interval's start)
    Σ += C_k J_k,   elapsed += T_k

**One fix** (``fix``), with Ce = C_mᵀ (body at the fix ← body at the last fix), Σ = [Σ_e,
Σ_s] (the candidates' columns, the filter's gyro states' columns)::

    Φ = I;  Φ[ε, ε] = Ce;  Φ[ε, s] = −Ce Σ_s;  Φ[s, s] = diag(exp(−elapsed λ))
    E⁻ = Φ E⁺;  E⁻[ε, e] += Ce Σ_e;  G = H E⁻ (+ C_VF^MF ω in the time offset's column)
    E⁺ = E⁻ − K G  (an applied fix)
    S = L Lᵀ;  w = L⁻¹ z;  A = L⁻¹ G                       written to two rows of the window
    q = 1, C = I, Σ = 0                                      the next interval starts

**One window** (``fix``, once the window is full): the band energies of
window_tests.band_energies, the NIS sum of the whitened innovations w_k of its n rows and the
whiteness p-value (window_tests.whiteness_of_bands, compiled into the loop)::

    E_j = v_j Σ_axes ((M w)_j² + (M w)_{J+j}²),   T = Σ_k |w_k|²     (M, v: band_tables(n))

The loops take the check's state as one array (:func:`workspace`, cut by :func:`views`): a
compiled call costs about half a microsecond per array argument, more than the arithmetic of a
six-state filter.  No ROS imports.
"""
from __future__ import annotations

import math

import numpy as np

from strapdown_ros.attitude.kernel import jitable_optional, kernels_allowed, njit_optional
from strapdown_ros.estimation.window_tests import (beta_log_sf, compiled_helpers,
                                                   whiteness_of_bands)

__all__ = ['compiled', 'workspace', 'views', 'sparse_basis', 'chain_step', 'dcm_entries',
           'lower_cholesky_inverse', 'HEADER']


def chain_step(pw: float, px: float, py: float, pz: float, r0: float, r1: float,
               r2: float) -> tuple:
    """
    Return one step of the signatures' attitude chain, ``p ⊗ exp(ρ)``, on floats.

    Parameters
    ----------
    pw, px, py, pz : float
        The chain so far (unnormalised).
    r0, r1, r2 : float
        The increment ρ, rad.

    Returns
    -------
    tuple of 8 float
        ``p ⊗ exp(ρ)`` as it goes on (unnormalised), then normalised.

    """
    angle = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    s = math.sin(0.5 * angle) / angle if angle > 0.0 else 0.5
    qw, qx, qy, qz = math.cos(0.5 * angle), r0 * s, r1 * s, r2 * s
    pw, px, py, pz = (pw * qw - px * qx - py * qy - pz * qz,
                      pw * qx + px * qw + py * qz - pz * qy,
                      pw * qy - px * qz + py * qw + pz * qx,
                      pw * qz + px * qy - py * qx + pz * qw)
    r = 1.0 / math.sqrt(pw * pw + px * px + py * py + pz * pz)
    return pw, px, py, pz, pw * r, px * r, py * r, pz * r


def dcm_entries(w: float, x: float, y: float, z: float) -> tuple:
    """
    Return the DCM of a unit quaternion, row-major, on floats (as rotation.quat_to_dcm).

    Parameters
    ----------
    w, x, y, z : float
        The unit quaternion, scalar first.

    Returns
    -------
    tuple of 9 float
        C(q), row by row.

    """
    return (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y))


def lower_cholesky_inverse(a: float, b: float, c: float, d: float, e: float,
                           f: float) -> tuple:
    """
    Return L⁻¹ for the 3×3 ``S = L Lᵀ``, L lower triangular, on floats.

    Parameters
    ----------
    a, b, c, d, e, f : float
        The lower triangle of S: S00, S10, S11, S20, S21, S22.

    Returns
    -------
    tuple
        ``(ok, m00, m10, m11, m20, m21, m22)``: ok False (and zeros) when S is not positive
        definite; else the lower triangle of L⁻¹, the factor numpy's Cholesky would give.

    """
    if not a > 0.0:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    l00 = math.sqrt(a)
    l10, l20 = b / l00, d / l00
    c -= l10 * l10
    if not c > 0.0:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    l11 = math.sqrt(c)
    l21 = (e - l20 * l10) / l11
    f -= l20 * l20 + l21 * l21
    if not f > 0.0:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    l22 = math.sqrt(f)
    m00, m11, m22 = 1.0 / l00, 1.0 / l11, 1.0 / l22
    m10 = -l10 * m00 * m11
    m21 = -l21 * m11 * m22
    m20 = -(l20 * m00 + l21 * m10) * m22
    return True, m00, m10, m11, m20, m21, m22


#: the workspace's header: size, width, fitted, columns, first state row, window, basis rows
HEADER = 7


def workspace(size: int, width: int, fitted: int, columns: int, first: int, window: int,
              basis_rows: int) -> np.ndarray:
    """
    Return a zeroed workspace of the compiled loops, its header written.

    One array holds the check's state, so that a compiled call takes few arguments (each array
    argument costs the call more than the arithmetic of a small filter); :func:`views` cuts it.

    Parameters
    ----------
    size : int
        The filter's error states n.
    width : int
        The signatures' columns (the candidates', then the time offset's).
    fitted : int
        Of which the candidate effects'.
    columns : int
        Columns of the interval's sums (the candidates', then the filter's gyro states').
    first : int
        Row of the first gyro state in the filter's layout.
    window : int
        Fixes N in the window.
    basis_rows : int
        Rows of the sparse basis (:func:`sparse_basis`).

    Returns
    -------
    ndarray
        The workspace.

    """
    bands = window // 2 + 1
    n = (HEADER + 4 + 9 + 1 + 3 * columns + size * width + columns + bands + 2 * bands * window
         + bands + 3 + 2 * window * 3 + 2 * window * 3 * width + 4 * basis_rows)
    ws = np.zeros(n)
    ws[:HEADER] = size, width, fitted, columns, first, window, basis_rows
    return ws


def views(ws: np.ndarray) -> tuple:
    """
    Return the parts of a :func:`workspace`, views into it.

    Parameters
    ----------
    ws : ndarray
        The workspace.

    Returns
    -------
    tuple
        ``rot`` (4,) the attitude since the last fix; ``dcm`` (3, 3) its DCM; ``clock`` (1,) the
        seconds since the last fix; ``sums`` (3, columns); ``E`` (size, width) the effects'
        error responses; ``lam`` (columns,) the decay rate of each column of the sums; ``v``
        (J,) and ``m`` (2J, N) the band tables; ``energy`` (J + 3,) the window's band
        energies, NIS sum, whiteness p-value and its band; ``white`` (2N, 3) and ``sig``
        (2N, 3, width) the window's rows (each twice); ``basis`` (rows, 4) the sparse basis;
        then ``fitted`` and ``first``.

    """
    size, width, fitted, columns = int(ws[0]), int(ws[1]), int(ws[2]), int(ws[3])
    first, window, rows = int(ws[4]), int(ws[5]), int(ws[6])
    bands = window // 2 + 1
    o = HEADER
    rot = ws[o:o + 4]
    o += 4
    dcm = ws[o:o + 9].reshape((3, 3))
    o += 9
    clock = ws[o:o + 1]
    o += 1
    sums = ws[o:o + 3 * columns].reshape((3, columns))
    o += 3 * columns
    E = ws[o:o + size * width].reshape((size, width))
    o += size * width
    lam = ws[o:o + columns]
    o += columns
    v = ws[o:o + bands]
    o += bands
    m = ws[o:o + 2 * bands * window].reshape((2 * bands, window))
    o += 2 * bands * window
    energy = ws[o:o + bands + 3]
    o += bands + 3
    white = ws[o:o + 6 * window].reshape((2 * window, 3))
    o += 6 * window
    sig = ws[o:o + 6 * window * width].reshape((2 * window, 3, width))
    o += 6 * window * width
    basis = ws[o:o + 4 * rows].reshape((rows, 4))
    return rot, dcm, clock, sums, E, lam, v, m, energy, white, sig, basis, fitted, first


def _accumulate_py(ws, d, h, t, lump, bias, epoch):
    """Add the lumps of d to the workspace's sums, attitude and clock."""
    rot, dcm, clock, sums, _, lam, _, _, _, _, _, basis, _, _ = _views(ws)
    m = d.shape[0]
    cols = sums.shape[1]
    elapsed = clock[0]
    u = np.empty(8)
    J = np.empty((3, cols))
    pw, px, py, pz = rot[0], rot[1], rot[2], rot[3]
    w, x, y, z = pw, px, py, pz
    cum = 0.0
    decays = False
    for c in range(cols):
        if lam[c] != 0.0:
            decays = True
    start = 0
    while start < m:
        stop = min(start + lump, m)
        r0 = r1 = r2 = T = 0.0
        for i in range(start, stop):
            r0 += d[i, 0]
            r1 += d[i, 1]
            r2 += d[i, 2]
            T += h[i]
        r0 -= bias[0] * T
        r1 -= bias[1] * T
        r2 -= bias[2] * T
        tm = t[stop - 1] - 0.5 * T - epoch
        # the attitude chain
        pw, px, py, pz, w, x, y, z = _step(pw, px, py, pz, r0, r1, r2)
        (dcm[0, 0], dcm[0, 1], dcm[0, 2], dcm[1, 0], dcm[1, 1], dcm[1, 2], dcm[2, 0], dcm[2, 1],
         dcm[2, 2]) = _dcm(w, x, y, z)
        # the partials: J = Σ_f u_f B_f (B sparse: rows feature, row, column, value)
        u[0], u[1], u[2] = r0, r1, r2
        u[3], u[4], u[5] = abs(r0), abs(r1), abs(r2)
        u[6], u[7] = T, T * tm
        for i in range(3):
            for c in range(cols):
                J[i, c] = 0.0
        for e in range(basis.shape[0]):
            J[int(basis[e, 1]), int(basis[e, 2])] += basis[e, 3] * u[int(basis[e, 0])]
        cum += T
        if decays:
            mid = elapsed + cum - 0.5 * T
            for c in range(cols):
                if lam[c] != 0.0:
                    g = math.exp(-mid * lam[c])
                    J[0, c] *= g
                    J[1, c] *= g
                    J[2, c] *= g
        for i in range(3):
            a0, a1, a2 = dcm[i, 0], dcm[i, 1], dcm[i, 2]
            for c in range(cols):
                sums[i, c] += a0 * J[0, c] + a1 * J[1, c] + a2 * J[2, c]
        start = stop
    rot[0], rot[1], rot[2], rot[3] = w, x, y, z
    clock[0] = elapsed + cum


def _fix_py(ws, H, K, has_gain, cvfmf, rate, offset, S, z, k1, k2, start):
    """
    Run one fix of the signatures, restart the interval, whiten; 1: S not positive definite.

    With start ≥ 0, write the window's energies and NIS sum from that row.
    """
    rot, dcm, clock, sums, E, lam, v, m, energy, white, sig, _, fitted, s0 = _views(ws)
    elapsed = clock[0]
    n, width = E.shape
    ns = sums.shape[1] - fitted
    En = np.empty((n, width))
    # Φ E⁺ (+ Γ): the attitude rows
    for i in range(3):
        c0, c1, c2 = dcm[0, i], dcm[1, i], dcm[2, i]            # row i of Ce = dcmᵀ
        for c in range(width):
            En[i, c] = c0 * E[0, c] + c1 * E[1, c] + c2 * E[2, c]
        for j in range(ns):
            phi = -(c0 * sums[0, fitted + j] + c1 * sums[1, fitted + j]
                    + c2 * sums[2, fitted + j])
            for c in range(width):
                En[i, c] += phi * E[s0 + j, c]
        for c in range(fitted):
            En[i, c] += c0 * sums[0, c] + c1 * sums[1, c] + c2 * sums[2, c]
    for r in range(3, n):
        g = 1.0
        if s0 <= r < s0 + ns and lam[fitted + r - s0] != 0.0:
            g = math.exp(-elapsed * lam[fitted + r - s0])
        for c in range(width):
            En[r, c] = g * E[r, c]
    # G = H E⁻ (+ D)
    G = np.empty((3, width))
    for i in range(3):
        for c in range(width):
            acc = 0.0
            for r in range(n):
                acc += H[i, r] * En[r, c]
            G[i, c] = acc
    if offset:
        for i in range(3):
            G[i, width - 1] += cvfmf[i, 0] * rate[0] + cvfmf[i, 1] * rate[1] \
                + cvfmf[i, 2] * rate[2]
    if has_gain:
        for r in range(n):
            k0, k1_, k2_ = K[r, 0], K[r, 1], K[r, 2]
            for c in range(width):
                En[r, c] -= k0 * G[0, c] + k1_ * G[1, c] + k2_ * G[2, c]
    for r in range(n):
        for c in range(width):
            E[r, c] = En[r, c]
    # the next interval starts at this fix
    _restart_interval(rot, dcm, clock, sums)
    # L⁻¹, S = L Lᵀ (the lower triangle of S)
    ok, m00, m10, m11, m20, m21, m22 = _chol(S[0, 0], S[1, 0], S[1, 1], S[2, 0], S[2, 1], S[2, 2])
    if not ok:
        return 1
    w0 = m00 * z[0]
    w1 = m10 * z[0] + m11 * z[1]
    w2 = m20 * z[0] + m21 * z[1] + m22 * z[2]
    white[k1, 0] = white[k2, 0] = w0
    white[k1, 1] = white[k2, 1] = w1
    white[k1, 2] = white[k2, 2] = w2
    for c in range(width):
        g0, g1, g2 = G[0, c], G[1, c], G[2, c]
        a0 = m00 * g0
        a1 = m10 * g0 + m11 * g1
        a2 = m20 * g0 + m21 * g1 + m22 * g2
        sig[k1, 0, c] = sig[k2, 0, c] = a0
        sig[k1, 1, c] = sig[k2, 1, c] = a1
        sig[k1, 2, c] = sig[k2, 2, c] = a2
    if start >= 0:
        bands = v.shape[0]
        _window(white, start, m.shape[1], m, v, energy)
        p, band = whiteness_of_bands(energy[:bands], m.shape[1])
        energy[bands + 1] = p
        energy[bands + 2] = band
    return 0


def _restart_interval_py(rot, dcm, clock, sums):
    """Start the interval of the next fix: q = 1, C = I, no time, Σ = 0 (in place)."""
    rot[0], rot[1], rot[2], rot[3] = 1.0, 0.0, 0.0, 0.0
    clock[0] = 0.0
    for i in range(3):
        for j in range(3):
            dcm[i, j] = 1.0 if i == j else 0.0
        for c in range(sums.shape[1]):
            sums[i, c] = 0.0


def _window_py(white, start, n, m, v, out):
    """Write the band energies of rows start..start+n−1 and then their NIS sum into out."""
    bands = v.shape[0]
    total = 0.0
    for k in range(start, start + n):
        total += white[k, 0] * white[k, 0] + white[k, 1] * white[k, 1] \
            + white[k, 2] * white[k, 2]
    for j in range(bands):
        acc = 0.0
        for part in (j, bands + j):
            f0 = f1 = f2 = 0.0
            for k in range(n):
                c = m[part, k]
                f0 += c * white[start + k, 0]
                f1 += c * white[start + k, 1]
                f2 += c * white[start + k, 2]
            acc += f0 * f0 + f1 * f1 + f2 * f2
        out[j] = v[j] * acc
    out[bands] = total


def sparse_basis(basis: np.ndarray) -> np.ndarray:
    """
    Return the nonzeros of B (features, 3, columns) as rows (feature, row, column, value).

    Parameters
    ----------
    basis : (8, 3, c) ndarray
        :func:`~strapdown_ros.sensors.effect_base.linear_partials`.

    Returns
    -------
    (k, 4) ndarray
        One row per nonzero, the kernel's form of B.

    """
    nz = np.nonzero(basis)
    return np.ascontiguousarray(np.column_stack(nz + (basis[nz],)), dtype=float)


# what the compiled loops call (compiled before them, these names then bound to them)
_step, _dcm, _chol, _views = chain_step, dcm_entries, lower_cholesky_inverse, views
_window, _restart_interval = _window_py, _restart_interval_py
_compiled = None


def compiled():
    """
    Return the compiled ``(accumulate, fix)`` loops and window_tests.beta_log_sf, or None.

    Returns
    -------
    tuple of callable or None
        None without numba, when it cannot compile them, or with ``STRAPDOWN_KERNEL=numpy``.

    """
    global _compiled, _step, _dcm, _chol, _views, _window, _restart_interval
    if not kernels_allowed():
        return None
    if _compiled is None:
        got = None
        if jitable_optional(*compiled_helpers()):         # window_tests' p-value, compiled in
            got = njit_optional(chain_step, dcm_entries, lower_cholesky_inverse, views,
                                _window_py, _restart_interval_py)
        if got:
            _step, _dcm, _chol, _views, _window, _restart_interval = got
            got = njit_optional(_accumulate_py, _fix_py, beta_log_sf)
        _compiled = got if got and _runs(got) else False
    return _compiled or None


def _runs(loops) -> bool:
    """Compile (or load from the cache) the loops on a small case; False when numba fails."""
    accumulate, fix, log_sf = loops
    ws = workspace(3, 1, 0, 0, 0, 2, 0)
    rot, dcm = views(ws)[:2]
    rot[0], dcm[:] = 1.0, np.eye(3)
    h = np.full(2, 0.01)
    try:
        accumulate(ws, np.zeros((2, 3)), h, np.cumsum(h), 1, np.zeros(3), 0.0)
        for k in range(2):
            fix(ws, np.eye(3), np.zeros((3, 3)), True, np.eye(3), np.zeros(3), True, np.eye(3),
                np.ones(3), k, k + 2, (k + 1) % 2 if k else -1)
        log_sf(0.5, 1.5, 10.0)
    except Exception:                   # numba present but unable to compile them: numpy path
        return False
    return True
