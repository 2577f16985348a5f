"""Covariance of the navigation errors, propagated from the sensor error model.

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

import numpy as np

from ..sensors.covariance import constant_jacobian, constant_variances
from ..sensors.model import SensorSigmas
from ..rotation import skew

__all__ = ["NavigationCovariance"]

OMEGA = 7.292115e-5
MU = 3.986004418e14


class NavigationCovariance:
    def __init__(self, gyro: SensorSigmas, accel: SensorSigmas, p0: np.ndarray, period: float = 1.0):
        p0 = np.asarray(p0, dtype=float)
        if p0.shape != (9, 9) or not np.all(np.isfinite(p0)):
            raise ValueError("initial navigation covariance must be a finite 9×9 matrix")
        if not (np.isfinite(period) and period > 0):
            raise ValueError(f"covariance period must be > 0, got {period}")
        self.gyro, self.accel = gyro, accel
        self.p_w = 0.5 * (p0 + p0.T)
        self.j = np.zeros((9, 24))
        self.var = np.concatenate([constant_variances(gyro), constant_variances(accel)])
        self.period = float(period)
        self._acc = self._zero_acc()
        self.current = self.p_w.copy()

    @staticmethod
    def _zero_acc():
        return {"dt": 0.0, "b": np.zeros((9, 24)), "fdt": np.zeros(3)}

    def propagate(self, positions, v_start, dv_body, theta, h) -> np.ndarray:
        """Feed K steps; returns (K, 9, 9): for each step the covariance of the latest epoch."""
        k_steps = len(h)
        out = np.empty((k_steps, 9, 9))
        jg = constant_jacobian(theta, h)                       # (K, 3, 12) ∂δθ/∂[b_g, vec M_g]
        ja = constant_jacobian(dv_body, h)                     # (K, 3, 12) ∂δv/∂[b_a, vec M_a]
        vjg = np.einsum("kij,kjl->kil", v_start, jg)
        vja = np.einsum("kij,kjl->kil", v_start, ja)
        fdt = np.einsum("kij,kj->ki", v_start, dv_body)
        cum = np.cumsum(h)
        start = 0
        while start < k_steps:
            base = (cum[start - 1] if start else 0.0) - self._acc["dt"]      # time at the epoch's start
            idx = int(np.searchsorted(cum, base + self.period - 1e-12))     # first step that reaches it
            end = min(max(idx + 1, start + 1), k_steps)
            a = self._acc
            a["dt"] += float(h[start:end].sum())
            a["b"][3:6, 12:] += vja[start:end].sum(0)
            a["b"][6:9, :12] += vjg[start:end].sum(0)
            a["fdt"] += fdt[start:end].sum(0)
            if a["dt"] >= self.period - 1e-12:
                self._epoch(positions[end - 1])
            out[start:end] = self.current
            start = end
        return out

    def _epoch(self, r: np.ndarray) -> None:
        a = self._acc
        dt = a["dt"]
        f = a["fdt"] / dt
        rn = np.linalg.norm(r)
        u = r / rn
        gamma = MU / rn ** 3 * (3.0 * np.outer(u, u) - np.eye(3)) + OMEGA ** 2 * np.diag([1.0, 1.0, 0.0])
        om = skew(np.array([0.0, 0.0, OMEGA]))
        F = np.zeros((9, 9))
        F[0:3, 3:6] = np.eye(3)
        F[3:6, 0:3] = gamma
        F[3:6, 3:6] = -2.0 * om
        F[3:6, 6:9] = -skew(f)
        F[6:9, 6:9] = -om
        fd = F * dt
        phi = np.eye(9) + fd + fd @ fd / 2.0 + fd @ fd @ fd / 6.0
        g = np.eye(9) + fd / 2.0
        q = np.zeros((9, 9))
        q[3:6, 3:6] = self.accel.random_walk ** 2 * dt * np.eye(3)
        q[6:9, 6:9] = self.gyro.random_walk ** 2 * dt * np.eye(3)
        self.p_w = phi @ self.p_w @ phi.T + g @ q @ g.T
        self.j = phi @ self.j + g @ a["b"]
        p = self.p_w + (self.j * self.var) @ self.j.T
        self.current = 0.5 * (p + p.T)
        self._acc = self._zero_acc()
