"""
Live model check of the attitude filter: its innovations against the filter's own model.

Are the innovations of the last N fixes what the model says they are, and if not, which effect
of the library do they look like?  :mod:`strapdown_ros.estimation.filter_system` feeds it every
applied or gated fix (a gated fix counts: an unmodelled effect makes the filter gate).

**Tests** (:mod:`strapdown_ros.estimation.window_tests`, exact at any N): over the window of the
whitened innovations ``w_k = L_k⁻¹ z_k`` (``S_k = L_k L_kᵀ``), the NIS sum against its χ²(3N)
band and the spectral whiteness test, at the window's level α = min(``alpha``,
r·Δt/3600) for a stated rate r of false WARN episodes per hour (Δt the mean time between the
window's fixes).

**Sequential rule.** A window ends at every fix.  A WARN episode starts at a failing window and
lasts until N windows in a row pass (the fixes of the failure have left the window); it counts
once.  Since an episode starts only at a failing window, the expected number of episodes per
hour of clean data is at most the expected number of failing windows, r.

**Naming** (a failing window; none when the NIS sum is below its band: the stated noise is too
large).  Each candidate, a library effect (``candidate`` in
:data:`strapdown_ros.sensors.effects.EFFECTS`) that is a systematic gyro effect the filter does
not carry, or the camera time offset when the filter does not estimate it, is fitted to the
window, ``w_k ≈ L_k⁻¹ G_k c``, where G_k is the effect's signature **in the innovations** of
this filter: the effect's error response run through the filter's own loop (Willsky & Jones
1976, the generalised likelihood ratio for a failure in a Kalman filter), from the start::

    E_k⁻ = Φ_k E_{k−1}⁺ + Γ_k,   G_k = H_k E_k⁻ + D_k,   E_k⁺ = E_k⁻ − K_k G_k

with Φ_k the filter's error transition over the interval before fix k, K_k its gain (0 for a
gated fix), H_k its fix Jacobian; Γ_k the gyro effect's increment partials integrated over the
interval (rotated to the body axes at the fix), D_k = C_VF^MF ω(t_k) the time offset's
(the camera shows the attitude τ earlier).  A filter that follows its fixes keeps only the
change of ω τ between fixes (the angular acceleration), while a scale asymmetry builds up with
the sign of the rate: with the full regressors the two separate under general motion.  The
share of the window's energy the effect explains, ``LR / Σ|w_k|²`` with
``LR = Σ|w_k|² − min_c Σ|w_k − A_k c|²``, is Beta(r/2, (3N − r)/2) without the effect (the F
test, r the rank of the regressors), whatever the true scale of the noise; the best match is
the candidate of the smallest p-value, named when that p-value is below α over the number of
candidates.  With no such candidate and white innovations above their band, the window names
the library's noise effect (``camera_noise_anisotropy``: stated noise too small).  The check
only reports; the filter's model is never changed by it.

**Cost.**  With numba the per-fix arithmetic (the signatures of the interval, the recursion, the
whitening, the window's energies and whiteness p-value) runs as two compiled loops
(:mod:`strapdown_ros.estimation.check_kernel`), the effects' partials read once as constant
combinations of the increments' features (``effect_base.linear_partials``); otherwise, or with
``STRAPDOWN_KERNEL=numpy``, the numpy path below runs: the same verdicts, the numbers to
round-off.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from strapdown_ros.estimation import check_kernel
from strapdown_ros.estimation.check_kernel import (chain_step, dcm_entries,
                                                   lower_cholesky_inverse)
from strapdown_ros.estimation.window_tests import (band_tables, beta_log_sf, judge_window,
                                                   window_level, WindowVerdict)
from strapdown_ros.rotation import quat_cumprod, quat_to_dcm, rotvec_to_quat
from strapdown_ros.sensors.effect_base import Effect, linear_partials, partial_features
from strapdown_ros.sensors.effects import EFFECTS

__all__ = ['ModelCheck', 'ModelCheckResult', 'ljung_box', 'check_candidates', 'NOISE_EFFECT']

#: the library's noise effect, named when white innovations are too large and no mean effect fits
NOISE_EFFECT = 'camera_noise_anisotropy'
#: increments up to which the signatures' attitude chain is computed on floats, not numpy
CHAIN_ON_FLOATS = 48


def ljung_box(x: np.ndarray, lags: int) -> float:
    """
    Return the Ljung–Box statistic ``n(n+2) Σ_{k=1}^{L} r_k²/(n−k)``, summed over columns.

    Its χ²(m L) reference is a large-sample one (at n = 30, L = 6, m = 3 it rejects 0.4 % of
    white windows at a nominal 0.1 %); the live check uses
    :func:`strapdown_ros.estimation.window_tests.spectral_whiteness`.

    Parameters
    ----------
    x : ndarray (n,) or (n, m)
        Series (whitened innovations), one per column.
    lags : int
        L ≥ 1.

    Returns
    -------
    float
        The statistic, χ²(m L) for long white series.

    """
    x = np.asarray(x, dtype=float)
    x = x.reshape(len(x), -1) - x.reshape(len(x), -1).mean(0)
    n = len(x)
    den = (x * x).sum(0)
    den = np.where(den > 0, den, np.inf)
    q = 0.0
    for k in range(1, lags + 1):
        r = (x[k:] * x[:-k]).sum(0) / den
        q += float((r * r).sum()) / (n - k)
    return n * (n + 2) * q


def check_candidates(augment=()) -> tuple[list, bool]:
    """
    Return the effects the live check may name for a filter carrying ``augment``.

    Parameters
    ----------
    augment : sequence of str
        The filter's augmented states.

    Returns
    -------
    effects : list of Effect
        Library candidates (``candidate``) that are systematic gyro effects with filter
        partials, neither the bias nor a state of the filter.
    time_offset : bool
        The camera time offset is a candidate (in the library and not a state).

    """
    effects = [e for n, e in EFFECTS.items()
               if e.candidate and e.sensor == 'gyro' and e.kind == 'systematic'
               and n != 'gyro_bias' and n not in augment and hasattr(e, 'filter_partials')]
    offset = EFFECTS['time_offset'].candidate and 'time_offset' not in augment
    return effects, offset


def _partials(effect) -> tuple:
    """
    Return ``(f, S)``: the effect's filter partials are ``f(ρ, T, t)``, times S unless None.

    The base class's :meth:`~strapdown_ros.sensors.effect_base.Effect.filter_partials` with its
    fit basis taken once (it does not change between fixes).
    """
    if type(effect).filter_partials is Effect.filter_partials:
        return effect.increment_jacobian, effect.fit_basis()
    return effect.filter_partials, None


def _attitude_chain(q0: np.ndarray, rho: np.ndarray) -> tuple:
    """
    Return the DCMs ``C(q_k)`` of ``q_k = q0 ⊗ exp(ρ_1) ⊗ … ⊗ exp(ρ_k)`` and ``q_m``.

    :func:`~strapdown_ros.rotation.quat_cumprod` of
    :func:`~strapdown_ros.rotation.rotvec_to_quat` and then
    :func:`~strapdown_ros.rotation.quat_to_dcm`, equal to round-off; for the few increments of
    one fix interval on floats (a few numpy calls cost more than the arithmetic).
    """
    if len(rho) > CHAIN_ON_FLOATS:
        q = quat_cumprod(q0, rotvec_to_quat(rho))
        return quat_to_dcm(q), q[-1]
    pw, px, py, pz = q0.tolist()
    w, x, y, z = pw, px, py, pz
    out = []
    for a, b, c in rho.tolist():
        pw, px, py, pz, w, x, y, z = chain_step(pw, px, py, pz, a, b, c)
        out.append(dcm_entries(w, x, y, z))
    return np.array(out).reshape(-1, 3, 3), np.array([w, x, y, z])


def _lower_cholesky_inverse(S) -> np.ndarray:
    """
    Return L⁻¹ for the 3×3 ``S = L Lᵀ`` (its lower triangle), L lower triangular.

    The Cholesky factor numpy's would be, on floats; LinAlgError as numpy's when S is not
    positive definite.
    """
    (a, _, _), (b, c, _), (d, e, f) = np.asarray(S, dtype=float).reshape(3, 3).tolist()
    ok, m00, m10, m11, m20, m21, m22 = lower_cholesky_inverse(a, b, c, d, e, f)
    if not ok:
        raise np.linalg.LinAlgError('Matrix is not positive definite')
    return np.array([[m00, 0.0, 0.0], [m10, m11, 0.0], [m20, m21, m22]])


@dataclass
class ModelCheckResult:
    """
    Verdict of one window (None fields: not computed).

    Parameters
    ----------
    fixes : int
        Fixes in the window.
    ok : bool
        True unless a WARN episode is on (a failing window starts one; N passing windows in a
        row end it).
    nis_sum : float
        Σ NIS over the window.
    nis_band : tuple of float
        Its two-sided band at the window's level.
    whiteness_p : float
        p-value of the spectral whiteness test.
    best_effect : str, optional
        The library effect the innovations match best (failing windows).
    best_p : float
        Its p-value (F test of its fit; small: the effect explains the innovations).
    best_estimate : ndarray, optional
        The fitted effect value, in its filter units.
    window_ok : bool
        This window passes both tests.
    verdict : str
        ``filling``, ``consistent``, ``noise_too_large``, ``noise_too_small``, ``effect`` or
        ``unexplained``.
    level : float
        α of the window.
    episodes : int
        WARN episodes so far.
    explained : bool
        The best effect's fit leaves a residual inside the NIS band.
    stamp : float
        Stamp of the window's last fix, s.

    """

    fixes: int
    ok: bool
    nis_sum: float = float('nan')
    nis_band: tuple = (float('nan'), float('nan'))
    whiteness_p: float = float('nan')
    best_effect: str | None = None
    best_p: float = float('nan')
    best_estimate: np.ndarray | None = None
    window_ok: bool = True
    verdict: str = 'filling'
    level: float = float('nan')
    episodes: int = 0
    explained: bool = False
    stamp: float = float('nan')

    def text(self) -> str:
        """Return the verdict as one line for /diagnostics and logs."""
        if self.verdict == 'filling':
            return f'model check: {self.fixes} fix(es) in the window, not yet full'
        head = (f'NIS sum {self.nis_sum:.4g} over {self.fixes} fixes (band '
                f'{self.nis_band[0]:.4g}–{self.nis_band[1]:.4g}), whiteness p = '
                f'{self.whiteness_p:.3g}, window level {self.level:.2g}')
        if self.verdict == 'consistent':
            if self.ok:
                return 'innovations consistent with the model: ' + head
            return (f'WARN episode {self.episodes} holds until a full window passes; this window '
                    'is consistent: ' + head)
        if self.verdict == 'noise_too_large':
            return f'stated noise too large (NIS sum below its band): {head}'
        if self.verdict == 'noise_too_small':
            return (f'stated noise too small: white innovations above their band and no mean '
                    f'effect matches ({self.best_effect}, or the gyro noise): {head}')
        if self.verdict == 'unexplained':
            return ('innovations inconsistent with the model, no library effect matches (an '
                    f'effect outside the library, or the stated noise): {head}')
        rest = '' if self.explained else '; the rest is still inconsistent'
        p = f'{self.best_p:.3g}' if self.best_p > 0 else '< 1e-300'
        return (f'innovations match {self.best_effect} (p = {p}{rest}); run discrepancy on a '
                f'recording ({head})')


class ModelCheck:
    """
    The sliding-window tests of the innovations, the WARN episodes and the naming.

    Parameters
    ----------
    window : int
        Fixes per window, N ≥ 5.
    alpha : float
        Largest false-alarm probability of one window (both tests together).
    effects : sequence of Effect
        Candidate gyro effects (registry objects with ``filter_partials``), not filter states
        (:func:`check_candidates`).
    time_offset : bool
        The camera time offset is a candidate.
    false_alarms_per_hour : float
        Stated rate r of false WARN episodes per hour of clean data (0: every window at
        ``alpha``).
    layout : StateLayout, optional
        The filter's error-state layout (``size``, ``gyro``): the loop the signatures run
        through.  None: the attitude error only.
    state_tau : array_like, optional
        Correlation time of each gyro state of the layout, s (inf: a random walk).

    """

    def __init__(self, window: int = 30, alpha: float = 0.001, effects=(), time_offset=False,
                 false_alarms_per_hour: float = 0.1, layout=None, state_tau=None):
        if int(window) < 5:
            raise ValueError('the model-check window needs at least 5 fixes')
        if not 0.0 < alpha < 0.5:
            raise ValueError('alpha must be in (0, 0.5)')
        if not (math.isfinite(false_alarms_per_hour) and false_alarms_per_hour >= 0.0):
            raise ValueError('false_alarms_per_hour must be finite and >= 0')
        self.window = int(window)
        self.alpha = float(alpha)
        self.rate = float(false_alarms_per_hour)
        self.effects = list(effects)
        self.time_offset = bool(time_offset)
        self.names = [e.name for e in self.effects] + (['time_offset'] if time_offset else [])
        self.size = 3 if layout is None else int(layout.size)
        self.states = [] if layout is None else [(e, sl) for e, sl in layout.gyro]
        cols = sum(sl.stop - sl.start for _, sl in self.states)
        tau = np.full(cols, np.inf) if state_tau is None else np.asarray(state_tau, dtype=float)
        if tau.shape != (cols,):
            raise ValueError('state_tau needs one correlation time per gyro state')
        self._lam = np.where(np.isfinite(tau) & (tau > 0), 1.0 / np.where(tau > 0, tau, 1.0),
                             0.0)
        self._decays = bool(np.any(self._lam > 0))
        sizes = [e.filter_size() for e in self.effects] + ([1] if time_offset else [])
        # every signature in one block of columns: the effects', then the time offset's
        self._width = int(sum(sizes))
        self._fitted = int(sum(sizes[:len(self.effects)]))
        starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int).tolist()
        self._columns = [slice(a, b) for a, b in zip(starts[:-1], starts[1:])]
        # the candidates by their number of columns (their SVDs one call per width)
        self._groups = [(w, [j for j, sz in enumerate(sizes) if sz == w])
                        for w in sorted(set(sizes))]
        self._partials = [_partials(e) for e in self.effects] \
            + [_partials(e) for e, _ in self.states]
        # every partial as one product of the increments' features, when the effects allow
        basis = linear_partials(self.effects + [e for e, _ in self.states])
        self._basis = None if basis is None else basis.reshape(len(basis), -1)
        self._eye = np.eye(self.size)
        self._eye3 = np.eye(3)
        if self.states:      # contiguous
            first, last = self.states[0][1].start, self.states[-1][1].stop
            self._state_slice = slice(first, last)
            self._state_diag = (np.arange(first, last), np.arange(first, last))
        # the window: each row written twice, at k mod N and k mod N + N, so that the last N
        # rows are always one contiguous slice, in order
        n = self.window
        self._stamps = np.zeros(2 * n)
        # the compiled loops (check_kernel) keep the state in one workspace, these views of it
        self._kernel = check_kernel.compiled() if basis is not None else None
        if self._kernel is not None:
            sparse = check_kernel.sparse_basis(basis)
            self._ws = check_kernel.workspace(
                self.size, self._width, self._fitted, self._fitted + cols,
                self.states[0][1].start if self.states else 0, n, len(sparse))
            (self._rot, self._dcm, self._clock, self._sums, self._E, lam, v, m, self._energy,
             self._white, self._signatures, basis_rows, _, _) = check_kernel.views(self._ws)
            lam[self._fitted:] = self._lam
            m[:], v[:] = band_tables(n)
            basis_rows[:] = sparse
            self._zero3 = np.zeros(3)
            self._no_gain = np.zeros((self.size, 3))
        else:
            self._E = np.zeros((self.size, self._width))
            self._white = np.zeros((2 * n, 3))
            self._signatures = np.zeros((2 * n, 3, self._width))
            self._rot, self._dcm = np.zeros(4), np.eye(3)
            self._clock, self._sums = np.zeros(1), np.zeros((3, self._fitted + cols))
        self._filled = 0
        self._next = 0
        self.last = ModelCheckResult(0, True)
        self.windows = self.failed = self.episodes = 0
        self.warn = False
        self._passing = 0
        self._start_interval()

    # ------------------------------------------------------------------ signatures
    def _start_interval(self) -> None:
        # body at the last fix ← body now, its DCM, the seconds since, the partials' sums (the
        # effects', then the filter's gyro states'): in place (the kernel's workspace)
        self._rot[:] = 1.0, 0.0, 0.0, 0.0
        self._dcm[:] = self._eye3
        self._clock[0] = 0.0
        self._sums[:] = 0.0

    def accumulate(self, d, h, t, lump: int = 1, bias=None, epoch: float = 0.0) -> None:
        """
        Add increments of the interval since the last fix to the signatures.

        The increments are lumped ``lump`` at a time (the last lump takes the rest), each lump
        compensated for the bias: ``ρ = Σ d − b Σ h``, at its middle ``t_end − Σ h / 2``.

        Parameters
        ----------
        d : ndarray (m, 3)
            Increments, rad, body axes.
        h : ndarray (m,)
            Their lengths, s.
        t : ndarray (m,)
            Their end stamps, s.
        lump : int
            Increments per lump, ≥ 1.
        bias : ndarray (3,), optional
            The rate b taken off, rad/s (None: none).
        epoch : float
            The effect epoch the times are counted from, s.

        """
        d = np.ascontiguousarray(d, dtype=float).reshape(-1, 3)
        m = len(d)
        h = np.ascontiguousarray(h, dtype=float).reshape(m)
        t = np.ascontiguousarray(t, dtype=float).reshape(m)
        if m == 0:
            return
        lump = max(1, int(lump))
        if self._kernel is not None:
            b = self._zero3 if bias is None else np.ascontiguousarray(bias, dtype=float).reshape(3)
            self._kernel[0](self._ws, d, h, t, lump, b, float(epoch))
            return
        n = len(d) // lump * lump
        rho = d[:n].reshape(-1, lump, 3).sum(1)
        hh = h[:n].reshape(-1, lump).sum(1)
        te = t[:n].reshape(-1, lump)[:, -1]
        if n < len(d):                         # the rest: one lump more
            rho = np.vstack([rho, d[n:].sum(0)[None]])
            hh = np.append(hh, h[n:].sum())
            te = np.append(te, t[-1])
        if bias is not None:
            rho = rho - np.asarray(bias, dtype=float).reshape(1, 3) * hh[:, None]
        self._lumps(rho, hh, te - 0.5 * hh - float(epoch))

    def _lumps(self, rho, h, t) -> None:
        """Add bias-compensated lumps (middle times t since the epoch) to the signatures."""
        c, self._rot = _attitude_chain(self._rot, rho)  # body at the last fix ← at each end
        self._dcm = c[-1]
        if self._partials:
            if self._basis is not None:                 # one product for every effect
                J = (partial_features(rho, h, t) @ self._basis).reshape(len(rho), 3, -1)
            else:
                J = np.concatenate([f(rho, h, t) if S is None else f(rho, h, t) @ S
                                    for f, S in self._partials], axis=2)
            if self._decays and self.states:
                u = self._clock[0] + np.cumsum(h) - 0.5 * h     # since the interval's start
                J[:, :, self._fitted:] *= np.exp(-u[:, None] * self._lam)[:, None, :]
            # Σ_k C_k J_k as one product: (3, 3m) by (3m, columns)
            self._sums += c.transpose(1, 0, 2).reshape(3, -1) @ J.reshape(-1, J.shape[2])
        self._clock[0] += float(h.sum())

    def _transition(self, ce: np.ndarray) -> np.ndarray:
        """Return the filter's error transition over the interval (body axes at both ends)."""
        phi = self._eye.copy()
        phi[:3, :3] = ce
        if self.states:
            sl = self._state_slice
            phi[:3, sl] = -ce @ self._sums[:, self._fitted:]
            if self._decays:                           # else exp(0) = 1: the identity's
                phi[self._state_diag] = np.exp(-float(self._clock[0]) * self._lam)
        return phi

    @property
    def compiled(self) -> bool:
        """Whether the check runs the compiled loops (check_kernel), not its numpy path."""
        return self._kernel is not None

    def window_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """
        Return the whitened rows of the fixes in the window, oldest first.

        Returns
        -------
        white : ndarray (m, 3)
            ``w_k = L_k⁻¹ z_k`` of the m ≤ N fixes so far.
        signatures : ndarray (m, 3, width)
            ``L_k⁻¹ G_k``: each candidate's columns (the time offset's last).

        """
        n, m = self.window, self._filled
        rows = slice(self._next + n - m, self._next + n)
        return self._white[rows].copy(), self._signatures[rows].copy()

    def restart_response(self) -> None:
        """Forget the effects' error responses (after the filter re-initialises its attitude)."""
        self._E[:] = 0.0

    def restart(self) -> None:
        """
        Go on after the filter re-initialised its attitude from a fix (a divergence reset).

        The attitude rows of the effects' error responses are zeroed (the attitude error is the
        fix's own noise, whatever the effects did before); the rows of the other states stay
        (the filter keeps those estimates).  The interval's signatures restart at that fix.  The
        window keeps its innovations (each was whitened with the responses of its time), so an
        effect that keeps the filter diverging is still named; the WARN state and the counts
        carry on.
        """
        self._E[:3] = 0.0
        self._start_interval()

    def continue_counts(self, previous: ModelCheck | None) -> None:
        """
        Carry the window, failure and episode counts of the check of a previous filter run.

        Parameters
        ----------
        previous : ModelCheck or None
            The check before a restart.

        """
        if previous is not None:
            self.windows, self.failed = previous.windows, previous.failed
            self.episodes = previous.episodes
            self.last.episodes = self.episodes

    # ------------------------------------------------------------------ fixes
    def add(self, stamp: float, z, S, c_vf_mf, rate_body, gain=None,
            jacobian=None) -> ModelCheckResult:
        """
        Add one applied or gated fix and judge the window ending at it.

        Parameters
        ----------
        stamp : float
            Stamp of the fix, s.
        z : array_like (3,)
            Residual, VF axes, rad.
        S : array_like (3, 3)
            Its innovation covariance, rad².
        c_vf_mf : ndarray (3, 3)
            C_VF^MF.
        rate_body : array_like (3,)
            The bias-compensated body rate at the fix, rad/s.
        gain : ndarray (n, 3), optional
            The filter's gain K (None: not applied, a gated fix).
        jacobian : ndarray (3, n), optional
            The filter's fix Jacobian H (None: ``[C_VF^MF, 0]``).

        Returns
        -------
        ModelCheckResult
            The verdict of the window ending at this fix.

        """
        if self._kernel is not None:
            return self._add_compiled(stamp, z, S, c_vf_mf, rate_body, gain, jacobian)
        c_vf_mf = np.asarray(c_vf_mf, dtype=float)
        ce = self._dcm.T                              # body at the fix ← body at the last fix
        phi = self._transition(ce)
        if jacobian is None:
            H = np.zeros((3, self.size))
            H[:, :3] = c_vf_mf
        else:
            H = np.asarray(jacobian, dtype=float).reshape(3, self.size)
        # every signature at once: E⁻ = Φ E⁺ + Γ, G = H E⁻ + D, E⁺ = E⁻ − K G
        E = phi @ self._E
        if self.effects:
            E[:3, :self._fitted] += ce @ self._sums[:, :self._fitted]
        G = H @ E
        if self.time_offset:                           # the camera time offset, the last column
            G[:, -1] += c_vf_mf @ np.asarray(rate_body, dtype=float)
        if gain is not None:
            E -= np.asarray(gain, dtype=float).reshape(self.size, 3) @ G
        self._E = E
        self._start_interval()
        # L⁻¹ applied to the residual and every signature
        inv = _lower_cholesky_inverse(S)
        k = self._next
        n = self.window
        self._white[k] = self._white[k + n] = inv @ np.asarray(z, dtype=float).reshape(3)
        self._signatures[k] = self._signatures[k + n] = inv @ G
        return self._advance(stamp)

    def _add_compiled(self, stamp, z, S, c_vf_mf, rate_body, gain, jacobian):
        """Run :meth:`add` compiled (check_kernel): the same numbers to round-off."""
        c_vf_mf = np.ascontiguousarray(c_vf_mf, dtype=float).reshape(3, 3)
        if jacobian is None:
            H = np.zeros((3, self.size))
            H[:, :3] = c_vf_mf
        else:
            H = np.ascontiguousarray(jacobian, dtype=float).reshape(3, self.size)
        K = self._no_gain if gain is None else \
            np.ascontiguousarray(gain, dtype=float).reshape(self.size, 3)
        k = self._next
        n = self.window
        full = self._filled + 1 >= n                 # the window's energies, in the same call
        bad = self._kernel[1](self._ws, H, K, gain is not None, c_vf_mf,
                              np.ascontiguousarray(rate_body, dtype=float).reshape(3),
                              self.time_offset,
                              np.ascontiguousarray(S, dtype=float).reshape(3, 3),
                              np.ascontiguousarray(z, dtype=float).reshape(3), k, k + n,
                              (k + 1) % n if full else -1)
        if bad:
            raise np.linalg.LinAlgError('Matrix is not positive definite')
        return self._advance(stamp, self._energy)

    def _advance(self, stamp, energy=None) -> ModelCheckResult:
        """Close the row of the fix just written; judge the window once it is full."""
        k = self._next
        n = self.window
        self._stamps[k] = self._stamps[k + n] = float(stamp)
        self._next = (k + 1) % n
        self._filled = min(self._filled + 1, n)
        if self._filled < n:
            self.last = ModelCheckResult(self._filled, True, episodes=self.episodes,
                                         stamp=float(stamp))
            return self.last
        self.last = self._test(energy)
        return self.last

    def _test(self, energy=None) -> ModelCheckResult:
        """Judge the window (``energy``: its band energies, NIS sum, whiteness p and band)."""
        n = self.window
        k = self._next
        rows = slice(k, k + n)                        # the last n fixes, in order
        first, last = float(self._stamps[k]), float(self._stamps[k + n - 1])
        level = window_level(self.rate, (last - first) / (n - 1), self.alpha)
        if energy is not None:      # the kernel's band energies, NIS sum, whiteness p and band
            *_, nis, p, band = energy.tolist()
            v = WindowVerdict(nis, 3 * n, level, p, int(band))
        else:
            v = judge_window(self._white[rows], level)
        self.windows += 1
        if v.ok:
            if self.warn:
                self._passing += 1
                if self._passing >= self.window:
                    self.warn = False
        else:
            self.failed += 1
            self._passing = 0
            if not self.warn:
                self.warn = True
                self.episodes += 1
        res = ModelCheckResult(n, not self.warn, v.nis_sum, v.nis_band, v.whiteness_p,
                               window_ok=v.ok, verdict='consistent', level=level,
                               episodes=self.episodes, stamp=last)
        if v.ok:
            return res
        if v.nis_low:
            res.verdict = 'noise_too_large'
            return res
        self._name(res, self._white[rows], self._signatures[rows].reshape(3 * n, -1), v)
        return res

    def _decompose(self, signatures: np.ndarray) -> list:
        """Return the thin SVD of each candidate's columns, those of equal width in one call."""
        out = [None] * len(self.names)
        for _, members in self._groups:
            if len(members) == 1:
                j = members[0]
                out[j] = np.linalg.svd(signatures[:, self._columns[j]], full_matrices=False)
                continue
            stack = np.stack([signatures[:, self._columns[j]] for j in members])
            U, s, Vt = np.linalg.svd(stack, full_matrices=False)
            for i, j in enumerate(members):
                out[j] = U[i], s[i], Vt[i]
        return out

    def _name(self, res: ModelCheckResult, white: np.ndarray, signatures: np.ndarray,
              v) -> None:
        """Fit every candidate's signature to the window; name the best if significant."""
        y = white.reshape(-1)
        total = float(y @ y)
        best = None
        log_sf = beta_log_sf if self._kernel is None else self._kernel[2]
        for j, (U, s, Vt) in enumerate(self._decompose(signatures)):
            name = self.names[j]
            rank = int(np.sum(s > 1e-9 * s[0])) if len(s) and s[0] > 0 else 0
            if rank == 0:
                continue
            proj = U[:, :rank].T @ y
            lr = float(proj @ proj)
            # the F test of the effect: its share of the window's energy, Beta(r/2, (3N − r)/2)
            # with no effect, whatever the noise's true scale
            score = log_sf(lr / total, 0.5 * rank, 0.5 * (len(y) - rank))
            if best is None or score < best[0]:
                c = Vt[:rank].T @ (proj / s[:rank])
                best = (score, lr, rank, name, c)
        if best is not None and best[0] < math.log(v.level / max(1, len(self.names))):
            score, lr, rank, name, c = best
            res.verdict, res.best_effect, res.best_estimate = 'effect', name, c
            res.best_p = math.exp(score)
            res.explained = total - lr <= res.nis_band[1]
            return
        if v.nis_high and not v.not_white and NOISE_EFFECT in EFFECTS \
                and EFFECTS[NOISE_EFFECT].candidate:
            res.verdict, res.best_effect = 'noise_too_small', NOISE_EFFECT
            return
        res.verdict = 'unexplained'
