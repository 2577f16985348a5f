"""
Covariance of the navigation errors, propagated from the sensor error model.

Carried by the :class:`~.navigator.Navigator` beside the position and velocity.

Error state (E axes): ``x = [δR, δW, ψ]`` with ``V_est = (I + [ψ×]) V_true``.  Linearised
e-frame error equations (Groves, *Principles of GNSS, Inertial and Multisensor Integrated
Navigation*, 2nd ed., §14.2.3)::

    δṘ = δW
    δẆ = Γ δR − 2[Ω×] δW − [f_E×] ψ + V δf
    ψ̇  = −[Ω×] ψ + V δω

``Γ = ∂g/∂R`` (normal gravity gradient: (μ/r³)(3 r̂r̂ᵀ − I) + Ω² diag(1, 1, 0)), ``f_E = V f``.
The sensor errors follow :mod:`strapdown_ros.sensors.model` exactly as the attitude covariance
does (model ``random_constant``): per increment ``δ = M u + b T + w`` with the 24 constants
``p = [b_g, vec M_g, b_a, vec M_a]`` random constants (their Jacobians from
:func:`strapdown_ros.sensors.covariance.constant_jacobian`, variances from
:func:`~strapdown_ros.sensors.covariance.constant_variances`) and the random walks white.  So

    P = P_w + J diag(var p) Jᵀ,   P_w ← Φ P_w Φᵀ + G Q Gᵀ,   J ← Φ J + G B,

evaluated once per ``period`` (default 1 s) with the forcing B summed exactly over the steps
inside it (``Σ V_j ∂(M u_j + b h_j)/∂p``); ``Φ = exp(FΔ)`` to third order and ``G = I + FΔ/2``
(forcing and noise taken at mid-interval).  The attitude integrator keeps its own body-axis
attitude covariance; this one carries ψ because velocity errors depend on it.
"""
from __future__ import annotations

import math

import numpy as np

from strapdown_ros.attitude.kernel import kernels_allowed, njit_optional
from strapdown_ros.earth import GM, OMEGA
from strapdown_ros.sensors.covariance import constant_jacobian_basis, constant_variances
from strapdown_ros.sensors.model import SensorSigmas

__all__ = ['NavigationCovariance', 'contract_blocks']

_BASIS = constant_jacobian_basis()


def contract_blocks(w: np.ndarray) -> np.ndarray:
    """
    Turn per-epoch sums of ``V·[u, T]`` into the sums of ``V J(u, T)``.

    The Jacobian of an increment on the sensor constants is linear in (u, T),
    ``J(u, T) = Σ_i u_i E_i + T E_T`` (E: ``sensors.covariance.constant_jacobian_basis``), so
    only the products are summed and the basis is applied once.

    Parameters
    ----------
    w : (E, 3, 12) ndarray
        Sums of ``V[a, m]·[u, T]_i`` at index 4m + i.

    Returns
    -------
    (E, 3, 12) ndarray
        Sums of ``V J(u, T)``.

    """
    w = w.reshape(len(w), 3, 3, 4)                                # [e, a, m, i]
    return np.einsum('eami,imc->eac', w, _BASIS)


class NavigationCovariance:
    """
    The 9×9 covariance of ``[δR, δW, ψ]`` (E axes), propagated once per period.

    Parameters
    ----------
    gyro, accel : SensorSigmas
        Statistics of the sensor errors (random constants and random walks).
    p0 : (9, 9) array_like
        Initial covariance: m², (m/s)², rad².
    period : float
        Propagation period, s.

    Raises
    ------
    ValueError
        For a non-finite or wrongly shaped ``p0`` or a period that is not positive.

    """

    def __init__(self, gyro: SensorSigmas, accel: SensorSigmas, p0: np.ndarray,
                 period: float = 1.0):
        p0 = np.asarray(p0, dtype=float)
        if p0.shape != (9, 9) or not np.all(np.isfinite(p0)):
            raise ValueError('initial navigation covariance must be a finite 9×9 matrix')
        if not (np.isfinite(period) and period > 0):
            raise ValueError(f'covariance period must be > 0, got {period}')
        self.gyro, self.accel = gyro, accel
        self.p_w = 0.5 * (p0 + p0.T)
        self.j = np.zeros((9, 24))
        self.var = np.concatenate([constant_variances(gyro), constant_variances(accel)])
        self.period = float(period)
        self._acc = self._zero_acc()
        self._elapsed = 0.0                     # step time fed so far, s
        self.current = self.p_w.copy()

    @staticmethod
    def _zero_acc():
        return {'dt': 0.0, 'b': np.zeros((9, 24)), 'fdt': np.zeros(3)}

    def propagate(self, positions, v_start, dv_body, theta, h) -> np.ndarray:
        """
        Feed K navigation steps and return the covariance after each.

        Parameters
        ----------
        positions : (K, 3) ndarray
            ECEF position at the end of each step, m.
        v_start : (K, 3, 3) ndarray
            C_E_B at the start of each step.
        dv_body : (K, 3) ndarray
            Accelerometer increment of each step, body axes, m/s.
        theta : (K, 3) ndarray
            Gyro increment of each step, body axes, rad.
        h : (K,) ndarray
            Step lengths, s.

        Returns
        -------
        (K, 9, 9) ndarray
            For each step the covariance of the latest epoch completed at that step
            (independent of how the steps are blocked).

        """
        k_steps = len(h)
        out = np.empty((k_steps, 9, 9))
        if k_steps == 0:
            return out
        # V ∂δθ/∂[b_g, vec M_g] and V ∂δv/∂[b_a, vec M_a], summed per epoch below: the
        # Jacobian is linear in (u, T), J(u, T) = Σ_i u_i E_i + T E_T, so only the (K, 3, 4)
        # products V·[u, T] are formed per step and the sums are multiplied by the basis E
        # once per epoch
        vh = (v_start * h[:, None, None])[:, :, :, None]
        wg = np.concatenate([v_start[:, :, :, None] * theta[:, None, None, :], vh],
                            axis=-1).reshape(k_steps, 3, 12)
        wa = np.concatenate([v_start[:, :, :, None] * dv_body[:, None, None, :], vh],
                            axis=-1).reshape(k_steps, 3, 12)
        fdt = (v_start @ dv_body[:, :, None])[:, :, 0]
        # (an epoch ends at the first step reaching a multiple of the period since the start)
        tot = self._elapsed + np.cumsum(h)
        grid = np.floor(tot / self.period + 1e-9)
        first = np.floor(self._elapsed / self.period + 1e-9)
        ends = list(np.flatnonzero(np.diff(grid, prepend=first) > 0) + 1)
        self._elapsed = float(tot[-1])
        bounds = np.array([0] + ends + ([k_steps] if not ends or ends[-1] < k_steps else []))
        starts = bounds[:-1]
        sum_g = contract_blocks(np.add.reduceat(wg, starts, axis=0))
        sum_a = contract_blocks(np.add.reduceat(wa, starts, axis=0))
        sum_f = np.add.reduceat(fdt, starts, axis=0)
        sum_h = np.add.reduceat(h, starts)
        n_ep = len(ends)
        if n_ep:
            # the epochs' recursion, compiled when numba is there (else the same loop in Python)
            a = self._acc
            dts = sum_h[:n_ep].copy()
            dts[0] += a['dt']
            fs = sum_f[:n_ep].copy()
            fs[0] += a['fdt']
            bs = np.zeros((n_ep, 9, 24))
            bs[:, 3:6, 12:] = sum_a[:n_ep]
            bs[:, 6:9, :12] = sum_g[:n_ep]
            bs[0] += a['b']
            rs = positions[np.array(ends) - 1]
            q_rw = np.array([self.accel.random_walk ** 2, self.gyro.random_walk ** 2])
            cur = np.empty((n_ep, 9, 9))
            _epochs()(self.p_w, self.j, self.var, dts, fs / dts[:, None], rs, bs, q_rw, GM, OMEGA,
                      cur)
            # each step carries the latest epoch completed at it (the one it ends, or the one
            # before): the same whatever the blocks the steps arrive in
            before = self.current
            self.current = cur[-1]
            self._acc = self._zero_acc()
            for e, (lo, hi) in enumerate(zip(bounds[:n_ep], bounds[1:n_ep + 1])):
                out[lo:hi - 1] = cur[e - 1] if e else before
                out[hi - 1] = cur[e]
        if len(bounds) - 1 > n_ep:                  # the open epoch accumulates
            a = self._acc
            a['dt'] += float(sum_h[-1])
            a['b'][3:6, 12:] += sum_a[-1]
            a['b'][6:9, :12] += sum_g[-1]
            a['fdt'] += sum_f[-1]
            out[bounds[-2]:] = self.current
        return out


def _epochs_py(p_w, j, var, dts, fs, rs, bs, q_rw, mu, omega, out):
    """
    Run the epochs' recursion; p_w and j are updated in place.

    For each epoch e: F from the mean specific force fs[e] and the position rs[e];
    Φ = I + FΔ + (FΔ)²/2 + (FΔ)³/6, G = I + FΔ/2; P_w ← Φ P_w Φᵀ + G Q Gᵀ, J ← Φ J + G B;
    out[e] = P_w + J diag(var) Jᵀ (symmetrised).  p_w is (9, 9), j (9, 24).
    """
    for e in range(dts.shape[0]):
        dt = dts[e]
        f = fs[e]
        r = rs[e]
        rn = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
        k = mu / (rn * rn * rn)
        F = np.zeros((9, 9))
        for i in range(3):
            F[i, 3 + i] = 1.0
            for c in range(3):
                F[3 + i, c] = k * (3.0 * r[i] * r[c] / (rn * rn) - (1.0 if i == c else 0.0))
        F[3, 0] += omega * omega
        F[4, 1] += omega * omega
        F[3, 4] = 2.0 * omega           # −2[Ω×]
        F[4, 3] = -2.0 * omega
        F[6, 7] = omega                 # −[Ω×]
        F[7, 6] = -omega
        F[3, 7], F[3, 8] = f[2], -f[1]  # −[f×]
        F[4, 6], F[4, 8] = -f[2], f[0]
        F[5, 6], F[5, 7] = f[1], -f[0]
        fd = F * dt
        fd2 = _mm(fd, fd)
        phi = fd + fd2 / 2.0 + _mm(fd2, fd) / 6.0
        g = fd / 2.0
        for i in range(9):
            phi[i, i] += 1.0
            g[i, i] += 1.0
        pw = _mm(_mm(phi, p_w), phi.T)
        for i in range(9):
            for c in range(9):
                # G Q Gᵀ with Q = diag(0, 0, 0, qa, qa, qa, qg, qg, qg)·dt
                acc = 0.0
                for m in range(3, 9):
                    acc += g[i, m] * g[c, m] * (q_rw[0] if m < 6 else q_rw[1])
                pw[i, c] += acc * dt
        jn = _mm(phi, j) + _mm(g, bs[e])
        for i in range(9):
            for c in range(9):
                p_w[i, c] = pw[i, c]
            for c in range(24):
                j[i, c] = jn[i, c]
        for i in range(9):
            for c in range(9):
                acc = 0.0
                for m in range(24):
                    acc += j[i, m] * var[m] * j[c, m]
                out[e, i, c] = acc + 0.5 * (p_w[i, c] + p_w[c, i])
        for i in range(9):
            for c in range(i):
                v = 0.5 * (out[e, i, c] + out[e, c, i])
                out[e, i, c] = v
                out[e, c, i] = v


def _mm_py(a, b):
    n, m, p = a.shape[0], a.shape[1], b.shape[1]
    out = np.zeros((n, p))
    for i in range(n):
        for k in range(m):
            x = a[i, k]
            if x != 0.0:
                for c in range(p):
                    out[i, c] += x * b[k, c]
    return out


_mm = _mm_py
_compiled = None


def _epochs():
    """Return the epoch loop, compiled when numba is present and allowed."""
    global _compiled, _mm
    if _compiled is None:
        got = njit_optional(_mm_py, _epochs_py) if kernels_allowed() else None
        _mm, _compiled = got if got else (_mm_py, _epochs_py)
    return _compiled
