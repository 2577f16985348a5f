"""
000 (Tkachenko 1983; paper 000) §6 for ``reproduce_seeds``: the simulated experiment, the
Monte Carlo over
the pulse generator's initial remainders, the ablations that look for what makes the paper's
errors larger than ours, and the report section.  Research code: the estimator itself is
:mod:`strapdown_ros.calibration.drifting_reference`; nothing here is needed to use it.

    python -m strapdown_ros.reproductions.tkachenko1983 [reproduce_seeds options]   # = reproduce_seeds --only 000

No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass
import sys
import time as _time
from typing import Sequence

import numpy as np

from strapdown_ros.calibration.drifting_reference import error_at_epochs, estimate
from strapdown_ros.calibration.drifting_reference_model import (ErrorStructure,
                                                                GyrostabilizerReference,
                                                                PAPER_000, PAPER_000_C,
                                                                PAPER_000_D, PAPER_000_PHI0,
                                                                PAPER_000_W0, psi_matrix,
                                                                SCALE_MISALIGNMENT_BIAS)
from strapdown_ros.figures import save_figure
from strapdown_ros.motion.profiles import PiecewiseRateProfile, Segment, tkachenko_profile
from strapdown_ros.reproductions.reproduce_seeds import main
from strapdown_ros.rotation import (aircraft_angles_to_quat, quat_conjugate, quat_multiply,
                                    quat_normalize, quat_to_rotvec, rotvec_to_quat)
from strapdown_ros.sensors import IntegratingSensor, SensorErrorModel

__all__ = ['Simulation000', 'simulate_000', 'run_tkachenko_experiment', 'monte_carlo_000', 'agreement',
           'ablations_000', 'float32_recursion_increments', 'section_000', 'report_000', 'plots_000']

QUANTUM = 2e-5


def _vec(x):
    return [float(v) for v in np.asarray(x).ravel()]


# --------------------------------------------------------------------------- the §6 experiment
@dataclass
class Simulation000:
    profile: PiecewiseRateProfile
    reference: GyrostabilizerReference
    h: float
    meas: np.ndarray            # θ* (N, 3)
    true_inc: np.ndarray        # θ (N, 3)
    M0: np.ndarray              # M(t0)
    epochs: np.ndarray          # sample indices of the equations
    ref_q0: np.ndarray
    ref_q: np.ndarray
    truth_epochs: np.ndarray    # Λ(t_j)
    x_true: np.ndarray


def simulate_000(quantum: float = 0.0, seed: int | None = 0, profile=None, c=PAPER_000_C, d=PAPER_000_D,
                 w0=PAPER_000_W0, phi0=PAPER_000_PHI0, h: float = 0.02, t_first: float = 4.0,
                 t_step: float = 0.2, t_f: float = 30.0, structure: ErrorStructure = SCALE_MISALIGNMENT_BIAS,
                 angle_noise: float = 0.0, initial_remainder: str = 'random',
                 t_star: float = 0.0, mounting=None) -> Simulation000:
    """
    Simulate 000 §6: exact truth, gyro with Δω = D(ω)c (and pulses of weight ``quantum``),
    computed-attitude start ``M(0) = normalize([1, w0])*⊗Λ(0)``, the drifting reference read as
    aircraft angles from φ0.

    Randomness: the pulse generator's initial remainder Δθ_0 of each axis is drawn uniformly in
    (−σ, σ) from ``seed`` (``initial_remainder='random'``); 000 takes Δθ_0 = 0 (``'zero'``, or
    ``seed=None``), which makes the quantized run deterministic.  Δθ_0 only rotates M(0) by a
    constant (absorbed by w0); what it randomises is the phase of all later remainders.
    ``t_star`` ≤ 0: the moment L was aligned with I (000 §3: t* < t0 = 0).  With φ0 given at
    t0 the mounting then absorbs L(t0) ≠ I, so Λ(0) stays as printed.  ``mounting`` (q_E_J)
    overrides that choice (φ0 is then not the angle at t0).
    """
    prof = profile if profile is not None else tkachenko_profile()
    n = int(round(t_f / h))
    v0 = rotvec_to_quat(psi_matrix(structure, np.array(0.0), t_star) @ np.asarray(d, dtype=float))
    q_E_J = quat_multiply(quat_conjugate(prof.attitude(0.0)),
                          quat_multiply(v0, aircraft_angles_to_quat(np.asarray(phi0)))) if mounting is None \
        else np.asarray(mounting, dtype=float)
    ref = GyrostabilizerReference(prof, d, structure, mounting=q_E_J, t_star=t_star, angle_noise=angle_noise,
                                  seed=None if seed is None else seed + 7919)
    err = SensorErrorModel.from_scale_misalignment_bias(c, quantum=quantum) if structure is SCALE_MISALIGNMENT_BIAS \
        else SensorErrorModel()
    sensor = IntegratingSensor(prof, 'gyro', 1.0 / h, err, seed=seed)
    if quantum > 0 and initial_remainder == 'random' and seed is not None:
        sensor.quantizer.integral[:] = np.random.default_rng(seed).uniform(-quantum, quantum, 3)
    _, meas, true_inc = sensor.sample(n)
    if structure is not SCALE_MISALIGNMENT_BIAS:      # user structure: add D(ω)c exactly per interval
        meas = true_inc + np.einsum('nij,j->ni', structure.D(true_inc / h, h * (np.arange(n) + 0.5)), c) * h
    M0 = quat_multiply(quat_conjugate(quat_normalize(np.concatenate([[1.0], w0]))), prof.attitude(0.0))
    epochs = np.rint(np.arange(t_first, t_f + 1e-9, t_step) / h).astype(int)
    ref_q0 = ref.quaternion(np.array(0.0))
    ref_q = ref.quaternion(h * epochs)
    return Simulation000(prof, ref, h, meas, true_inc, M0, epochs, ref_q0, ref_q,
                         prof.attitude(h * epochs), np.concatenate([w0, c, d]))


def run_tkachenko_experiment(quantum: float = 0.0, mode: str = 'raw', seed: int | None = 0,
                             iterate: bool = False, weighted: bool = False, algorithm: str = '2',
                             quadrature: str = 'exact', profile=None, full: bool = False,
                             coefficients: str = 'identity', precision=None,
                             recursion: str = 'float64', **kw) -> dict:
    """
    Reproduce 000 §6 (m = 3, n = 1, D = [D_I D_II E3], G = E3, h = 0.02 s, epochs 4, 4.2 … 30 s).

    Returns the errors in the paper's terms: ``w0`` = w⁰, the corrected attitude error at t_f
    (vector part of Λ⊗Λ̂*, absolute units — multiply by 1e5 for the paper's print),
    ``dc`` = c* − c (9), ``dd`` = d* − d (3), and ``dw0`` = ŵ0 − w0, ``w_rms`` (RMS of w⁰ over the
    epochs), ``iterations``, ``seconds``; ``full=True`` adds the solution and the simulation.
    ``precision`` (e.g. ``np.float32``): the estimator's inputs (increments, M(t0), reference
    quaternions) are rounded to that type first (an ablation: data stored in single precision).
    ``recursion='float32'``: the computed attitude M(t) is the single-precision recursion of
    :func:`float32_recursion_increments` (use with ``algorithm='1'``; an ablation).
    """
    if recursion not in ('float64', 'float32'):
        raise ValueError(f'unknown recursion {recursion!r}; valid: float64, float32')
    t = _time.perf_counter()
    sim = simulate_000(quantum=quantum, seed=seed, profile=profile, **kw)
    inputs = [sim.meas, sim.M0, sim.ref_q0, sim.ref_q]
    if precision is not None:
        inputs = [np.asarray(a, dtype=precision).astype(float) for a in inputs]
    if recursion == 'float32':
        inputs[1], inputs[0] = float32_recursion_increments(inputs[1], inputs[0])
    sol = estimate(inputs[0], sim.h, inputs[1], inputs[2], inputs[3], sim.epochs, algorithm=algorithm,
                   quadrature=quadrature, mode=mode, quantum=quantum, iterate=iterate, weighted=weighted,
                   t_star=sim.reference.t_star, angle_noise=sim.reference.angle_noise,
                   coefficients=coefficients)
    err = sol.x - sim.x_true
    w_err = error_at_epochs(sol.refined_attitude, sim.truth_epochs)
    out = {'w0': w_err[-1].tolist(), 'dc': err[3:12].tolist(), 'dd': err[12:15].tolist(),
           'dw0': err[:3].tolist(), 'w_rms': float(np.sqrt(np.mean(w_err ** 2))),
           'iterations': sol.iterations, 'observable': sol.observability.observable,
           'seconds': _time.perf_counter() - t}
    if full:
        out['solution'] = sol
        out['simulation'] = sim
    return out


def monte_carlo_000(seeds: Sequence[int] = range(100), quantum: float = QUANTUM,
                    cases: Sequence[tuple] = (('raw', False, False), ('centred', False, False),
                                              ('corrected', False, False), ('raw', True, False),
                                              ('raw', False, True), ('raw', True, True)),
                    profile=None, coefficients: str = 'identity') -> dict:
    """
    Monte Carlo of the quantized §6 experiment over the initial remainders (one per seed).

    ``cases``: (mode, iterate, weighted).  Returns per case the errors (seeds × 15:
    δw0, δc, δd), their mean, std and RMS per component, the (absolute) RMS over the c and d
    groups, and the w⁰ RMS.
    """
    res = {}
    for mode, it, wt in cases:
        errs, wrms, wf = [], [], []
        for s in seeds:
            r = run_tkachenko_experiment(quantum, mode, s, iterate=it, weighted=wt, profile=profile,
                                         coefficients=coefficients)
            errs.append(r['dw0'] + r['dc'] + r['dd'])
            wrms.append(r['w_rms'])
            wf.append(r['w0'])
        e = np.array(errs)
        key = f"{mode}{'+iter' if it else ''}{'+weighted' if wt else ''}"
        res[key] = {'errors': e, 'mean': e.mean(0), 'std': e.std(0, ddof=1),
                    'rms': np.sqrt(np.mean(e ** 2, 0)),
                    'rms_c': float(np.sqrt(np.mean(e[:, 3:12] ** 2))),
                    'rms_c_scale': float(np.sqrt(np.mean(e[:, 3:9] ** 2))),
                    'rms_c_bias': float(np.sqrt(np.mean(e[:, 9:12] ** 2))),
                    'rms_d': float(np.sqrt(np.mean(e[:, 12:15] ** 2))),
                    'w0_final': np.array(wf), 'w_rms': float(np.sqrt(np.mean(np.square(wrms))))}
    return res


# --------------------------------------------------------------------------- comparison
def agreement(ours, paper) -> dict:
    """
    How a set of our errors (δc, δd: 12 numbers) compares with the paper's.

    ``rms_ratio`` = RMS(paper)/RMS(ours) (> 1: the paper's errors are larger), ``signs`` = how many
    of the 12 components have the paper's sign, ``corr`` = the cosine between the two vectors,
    ``scale`` = the least-squares factor a in paper ≈ a·ours and ``misfit`` = |paper − a·ours|/|paper|
    (what no common scale explains), ``max_ratio`` = max |ours_i/paper_i|.
    """
    o, p = np.asarray(ours, dtype=float), np.asarray(paper, dtype=float)
    a = float(o @ p / (o @ o)) if o @ o > 0 else 0.0
    return {'rms_ratio': float(np.sqrt(np.mean(p ** 2)) / max(np.sqrt(np.mean(o ** 2)), 1e-300)),
            'signs': int(np.sum(np.sign(o) == np.sign(p))), 'n': int(len(p)),
            'corr': float(o @ p / max(np.linalg.norm(o) * np.linalg.norm(p), 1e-300)),
            'scale': a, 'misfit': float(np.linalg.norm(p - a * o) / np.linalg.norm(p)),
            'max_ratio': float(np.max(np.abs(o / p)))}


def _cd(r) -> np.ndarray:
    return np.r_[r['dc'], r['dd']]


def _paper_cd(case: str) -> np.ndarray:
    return np.r_[PAPER_000[case]['dc'], PAPER_000[case]['dd']]


def _variant_profile(segment: int, axis: int, rate: float) -> PiecewiseRateProfile:
    base = tkachenko_profile()
    segs = [Segment(s.duration, s.rate.copy()) for s in base.segments]
    segs[segment].rate[axis] = rate
    return PiecewiseRateProfile(segs, initial_attitude=(0.64, 0.48, 0.36, -0.48), name='tkachenko-variant')


def float32_recursion_increments(M0, meas) -> tuple[np.ndarray, np.ndarray]:
    """
    The attitude recursion ``M_k+1 = normalize(M_k ⊗ exp(θ_k))`` run in single precision.

    Every operation (half-angle, sin/cos, quaternion product, normalisation) is float32, as in a
    1983-era single-precision computer.  Returns ``(M0_32, increments)``: M(t0) rounded to
    float32 and the float64 increments ``log(M32_k* ⊗ M32_k+1)`` that an exact 1-sample
    integration turns into the float32 attitudes (to float64 round-off), so the estimator,
    fed with them and ``algorithm='1'``, sees the float32 recursion's attitude.

    Parameters
    ----------
    M0 : (4,) computed attitude at t0, scalar first.
    meas : (N, 3) measured increments θ*, rad.

    Returns
    -------
    (4,) float64 copy of the float32 M0 and (N, 3) equivalent increments, rad.
    """
    f = np.float32
    q = np.asarray(M0, dtype=f)
    q = q / np.sqrt(np.sum(q * q, dtype=f), dtype=f)
    out = np.empty((len(meas) + 1, 4), dtype=f)
    out[0] = q
    th = np.asarray(meas, dtype=f)
    for k in range(len(th)):
        half = th[k] * f(0.5)
        a = np.sqrt(np.sum(half * half, dtype=f), dtype=f)
        sa = np.sin(a, dtype=f) / a if a > 0 else f(1.0)
        dq = np.concatenate([[np.cos(a, dtype=f)], half * f(sa)]).astype(f)
        w0, v0, w1, v1 = q[0], q[1:], dq[0], dq[1:]
        q = np.concatenate([[w0 * w1 - np.dot(v0, v1)],
                            w0 * v1 + w1 * v0 + np.cross(v0, v1)]).astype(f)
        q = (q / np.sqrt(np.sum(q * q, dtype=f), dtype=f)).astype(f)
        out[k + 1] = q
    q64 = out.astype(float)
    inc = quat_to_rotvec(quat_multiply(quat_conjugate(q64[:-1]), q64[1:]))
    return q64[0], inc


#: the estimators the ablations run: 000's first-order method as printed (every coefficient at
#: the reference p) and this project's modification (coefficients moved to ½(p+p*) and p*)
ESTIMATORS = {'printed': "000's method as printed",
              'identity': 'modified estimator (this project)'}


def _knobs() -> dict:
    return {
        'none': ('no change (§6 as printed)', {}),
        'quadrature_trapezoid': ("integration scheme: Θ by the paper's O(H³) trapezoid, H = 2h",
                                 dict(quadrature='trapezoid')),
        'algorithm_1': ('integration scheme: attitude by the 1-sample algorithm instead of 2-sample',
                        dict(algorithm='1')),
        'algorithm_4': ('integration scheme: attitude by the 4-sample algorithm', dict(algorithm='4')),
        'float32_inputs': ('increments and quaternions rounded to single precision', dict(precision=np.float32)),
        'float32_recursion': ('attitude recursion computed in single precision (1-sample)',
                              dict(recursion='float32', algorithm='1')),
        'w0_half': ('misprint: w(0) = 1e-3 read as a rotation angle (half-angle 5e-4)',
                    dict(w0=0.5 * PAPER_000_W0)),
        'w0_double': ('misprint: w(0) twice as large (2e-3 per axis)', dict(w0=2.0 * PAPER_000_W0)),
        'w0_1e-2': ('misprint of the exponent: w(0) = 1e-2 per axis',
                    dict(w0=10.0 * PAPER_000_W0)),
        'w0_sign': ('sign convention: w0 = −1e-3 per axis (error of the other basis)', dict(w0=-PAPER_000_W0)),
        'c_sign': ('sign convention: c → −c (gyro error as truth − measured)', dict(c=-PAPER_000_C)),
        'c6_sign': ('misprint: c6 = +5e-4 (c4 = c5 = c6)', dict(c=PAPER_000_C * np.r_[1, 1, 1, 1, 1, -1, 1, 1, 1])),
        'rate_0.032': ('misprint: ω2 = 0.032 instead of 0.32 on 5–10 s', dict(profile=_variant_profile(1, 1, 0.032))),
        'mounting_J_is_E': ('misprint: J = E (φ0 then not consistent with Λ(0))',
                            dict(mounting=np.array([1.0, 0.0, 0.0, 0.0]))),
        'epochs_from_0.2s': ('equations from t = 0.2 s instead of 4 s', dict(t_first=0.2)),
    }


def ablations_000(noise_seeds: int = 10) -> dict:
    """
    Unquantized §6, first order: one knob changed at a time, each compared with the paper.

    Every knob is run with both estimators of :data:`ESTIMATORS` (000's method as printed and
    the modified one), and its RMS ratio, sign agreement and correlation with the paper's
    errors are recorded.  Whether a knob explains the paper's errors is judged by fixed
    thresholds (:data:`EXPLAINS_WITHIN`, :data:`SAME_PATTERN`), never against the pattern of
    one of our own estimators.
    """
    paper = _paper_cd('unquantized')
    out = {'knobs': {}}
    for key, (label, kw) in _knobs().items():
        rec = {'label': label}
        for est in ESTIMATORS:
            run = run_tkachenko_experiment(seed=None, coefficients=est, **kw)
            rec[est] = agreement(_cd(run), paper)
        out['knobs'][key] = rec
    out['baseline'] = out['knobs']['none']['identity']
    out['baseline_printed'] = out['knobs']['none']['printed']
    # diagnostic, not a candidate cause: w0 = 0 leaves the c² part of the remainder alone
    out['w0_zero'] = {est: agreement(_cd(run_tkachenko_experiment(seed=None, w0=np.zeros(3),
                                                                  coefficients=est)), paper)
                      for est in ESTIMATORS}
    # noise on the reference angles: how much is needed for the paper's RMS, and its signs there
    out['noise'] = {}
    for est in ESTIMATORS:
        base_ms = float(np.mean(_cd(run_tkachenko_experiment(seed=None, coefficients=est)) ** 2))
        probe = 1e-6
        ms = np.mean([np.mean(_cd(run_tkachenko_experiment(seed=s, angle_noise=probe,
                                                           coefficients=est)) ** 2)
                      for s in range(noise_seeds)])
        gain = np.sqrt(max(ms - base_ms, 1e-300)) / probe      # RMS error per rad of angle noise
        sigma_eq = float(np.sqrt(max(np.mean(paper ** 2) - base_ms, 0.0)) / gain)
        ag = [agreement(_cd(run_tkachenko_experiment(seed=s, angle_noise=sigma_eq,
                                                     coefficients=est)), paper)
              for s in range(noise_seeds)]
        out['noise'][est] = {'seeds': noise_seeds, 'probe_rad': probe, 'rms_per_rad': float(gain),
                             'sigma_for_paper_rms_rad': sigma_eq,
                             'rms_ratio_mean': float(np.mean([a['rms_ratio'] for a in ag])),
                             'signs_mean': float(np.mean([a['signs'] for a in ag])),
                             'corr_mean': float(np.mean([a['corr'] for a in ag])),
                             'corr_std': float(np.std([a['corr'] for a in ag], ddof=1))}
    return out


# --------------------------------------------------------------------------- the section
def section_000(n_seeds: int, quick: bool = False) -> dict:
    quantum = QUANTUM
    out = {'cases': {}}
    spec = {'unquantized': dict(quantum=0.0, mode='raw'),
            'quantized_raw': dict(quantum=quantum, mode='raw'),
            'quantized_centred': dict(quantum=quantum, mode='centred')}
    mc = monte_carlo_000(range(n_seeds), quantum, (('raw', False, False), ('centred', False, False),
                                                   ('raw', True, False), ('centred', True, False),
                                                   ('raw', False, True), ('centred', False, True),
                                                   ('centred', True, True)))
    out['headline'] = {}
    for case, kw in spec.items():
        first = run_tkachenko_experiment(seed=None, **kw)                 # Δθ0 = 0, as the paper
        printed = run_tkachenko_experiment(seed=None, coefficients='printed', **kw)
        iterated = run_tkachenko_experiment(seed=None, iterate=True, **kw)
        rec = {'paper': {k: _vec(v) for k, v in PAPER_000[case].items()},
               'ours': {k: _vec(first[k]) for k in ('w0', 'dc', 'dd')},
               'ours_as_printed': {k: _vec(printed[k]) for k in ('w0', 'dc', 'dd')},
               'ours_iterated': {k: _vec(iterated[k]) for k in ('w0', 'dc', 'dd')}}
        paper = _paper_cd(case)
        head = {'ours': agreement(_cd(first), paper), 'ours_as_printed': agreement(_cd(printed), paper),
                'ours_iterated': agreement(_cd(iterated), paper)}
        if kw['quantum'] > 0:
            m = mc[kw['mode']]
            e, wf = m['errors'], np.asarray(m['w0_final'])
            rec['ours_mc_mean'] = {'w0': _vec(wf.mean(0)), 'dc': _vec(e[:, 3:12].mean(0)), 'dd': _vec(e[:, 12:].mean(0))}
            rec['ours_mc_std'] = {'w0': _vec(wf.std(0, ddof=1)), 'dc': _vec(e[:, 3:12].std(0, ddof=1)),
                                  'dd': _vec(e[:, 12:].std(0, ddof=1))}
            rec['ours_mc_rms'] = {'c': m['rms_c'], 'c_scale_misalignment': m['rms_c_scale'], 'c_bias': m['rms_c_bias'],
                                  'd': m['rms_d']}
            # the initial remainder: is the paper's set a plausible draw of our Monte Carlo?
            z = (paper - e[:, 3:].mean(0)) / e[:, 3:].std(0, ddof=1)
            mc_rms = float(np.sqrt(np.mean(e[:, 3:] ** 2)))
            head['monte_carlo'] = {'rms_ratio': float(np.sqrt(np.mean(paper ** 2)) / mc_rms),
                                   'z_rms': float(np.sqrt(np.mean(z ** 2))),
                                   'within_2sigma': int(np.sum(np.abs(z) <= 2)), 'n': int(len(z)),
                                   'seeds': n_seeds}
        else:   # no randomness without quantization: the single run is the distribution
            rec['ours_mc_mean'] = rec['ours']
            rec['ours_mc_std'] = {k: [0.0] * len(v) for k, v in rec['ours'].items()}
        out['cases'][case] = rec
        out['headline'][case] = head
    raw, cen = mc['raw'], mc['centred']
    out['beyond_paper'] = {k: {'rms_c': v['rms_c'], 'rms_c_bias': v['rms_c_bias'], 'rms_d': v['rms_d'],
                               'rms_w': v['w_rms']} for k, v in mc.items()}
    mcp = monte_carlo_000(range(n_seeds), quantum, (('raw', False, False), ('centred', False, False)),
                          coefficients='printed')
    out['centring_gain'] = {'rms_c_raw': raw['rms_c'], 'rms_c_centred': cen['rms_c'],
                            'printed_rms_c_raw': mcp['raw']['rms_c'],
                            'printed_rms_c_centred': mcp['centred']['rms_c'],
                            'rms_c_bias_raw': raw['rms_c_bias'], 'rms_c_bias_centred': cen['rms_c_bias'],
                            'rms_d_raw': raw['rms_d'], 'rms_d_centred': cen['rms_d'], 'seeds': n_seeds}
    un = out['cases']['unquantized']
    paper_cd = np.abs(_paper_cd('unquantized'))
    out['unquantized_ratio_to_paper'] = {
        'ours': _vec(np.abs(np.r_[un['ours']['dc'], un['ours']['dd']]) / paper_cd),
        'ours_as_printed': _vec(np.abs(np.r_[un['ours_as_printed']['dc'], un['ours_as_printed']['dd']]) / paper_cd)}
    out['ablations'] = ablations_000(noise_seeds=3 if quick else 10)
    return out


# --------------------------------------------------------------------------- report
def _verdict(ok: bool, yes: str, no: str) -> str:
    return yes if ok else no


#: an ablation "explains" the paper's errors if it brings the RMS ratio within this factor of 1
#: while the correlation with the paper's errors reaches :data:`SAME_PATTERN`
EXPLAINS_WITHIN = 2.0
#: an ablation "changes nothing" if the RMS ratio moves by less than this fraction
NO_EFFECT = 0.05
#: correlation (cosine) at or above which two error vectors are said to share a pattern; a fixed
#: threshold, not the correlation of one of our estimators (that test would be circular)
SAME_PATTERN = 0.9


def ablation_verdict(k: dict, base: dict) -> tuple[str, bool]:
    """
    The verdict on one knob for one estimator, with its thresholds stated beside it.

    Parameters
    ----------
    k : the knob's :func:`agreement` with the paper.
    base : the same estimator's :func:`agreement` without the knob.

    Returns
    -------
    (verdict text, explains) — explains is True when the RMS ratio is within
    :data:`EXPLAINS_WITHIN` of 1 and the correlation is at least :data:`SAME_PATTERN`.
    """
    change = abs(k['rms_ratio'] / base['rms_ratio'] - 1)
    size_ok = abs(np.log(k['rms_ratio'])) <= np.log(EXPLAINS_WITHIN)
    pattern_ok = k['corr'] >= SAME_PATTERN
    if size_ok and pattern_ok:
        return (f'explains size and pattern (ratio within {EXPLAINS_WITHIN:g}× of 1, corr ≥ {SAME_PATTERN:g})',
                True)
    if change < NO_EFFECT:
        return f'size unchanged: ratio moves {100 * change:.1f}% (< {100 * NO_EFFECT:g}%)', False
    if size_ok:
        return (f"size only: ratio within {EXPLAINS_WITHIN:g}× of 1, corr {k['corr']:+.3f} < {SAME_PATTERN:g}",
                False)
    if pattern_ok:
        return (f"pattern only: corr ≥ {SAME_PATTERN:g}, ratio {k['rms_ratio']:.2g} not within "
                f'{EXPLAINS_WITHIN:g}× of 1', False)
    return (f"neither: ratio {k['rms_ratio']:.2g} not within {EXPLAINS_WITHIN:g}× of 1, corr "
            f"{k['corr']:+.3f} < {SAME_PATTERN:g}", False)


def _ablation_lines(a: dict) -> list[str]:
    L = ["### What makes the paper's unquantized errors larger: ablations", '',
         "One knob changed at a time on the unquantized first-order run (Δθ0 = 0), with 000's "
         'method as '
         'printed and with the modified estimator; RMS ratio = RMS(paper)/RMS(ours) over δc, δd; '
         'corr = '
         "cosine between our 12 errors and the paper's. Thresholds: a knob explains the paper's "
         'errors '
         f'if its ratio is within {EXPLAINS_WITHIN:g}× of 1 and its corr ≥ {SAME_PATTERN:g} '
         '(fixed, not '
         f'the corr of either estimator); the size is unchanged if the ratio moves less than '
         f'{100 * NO_EFFECT:g}% from the same estimator without the knob.', '']
    head = '| knob |'
    for est, name in ESTIMATORS.items():
        head += f' {name}: ratio | signs | corr | verdict |'
    L += [head, '|---|' + '---|---|---|---|' * len(ESTIMATORS)]
    base = {est: a['knobs']['none'][est] for est in ESTIMATORS}
    explained = []
    for key, k in a['knobs'].items():
        row = f"| {k['label']} |"
        for est, name in ESTIMATORS.items():
            v = k[est]
            verdict, ok = (('— (reference row)', False) if key == 'none'
                           else ablation_verdict(v, base[est]))
            if ok:
                explained.append(f"{k['label']} ({name})")
            row += f" {v['rms_ratio']:.2f} | {v['signs']}/{v['n']} | {v['corr']:+.3f} | {verdict} |"
        L.append(row)
    L.append('')
    for est, name in ESTIMATORS.items():
        n = a['noise'][est]
        noise_ok = (n['corr_mean'] >= SAME_PATTERN
                    and abs(np.log(n['rms_ratio_mean'])) <= np.log(EXPLAINS_WITHIN))
        if noise_ok:
            explained.append(f'noise on the reference angles ({name})')
        L.append(f'* Noise, {name}: white noise on the aircraft angles raises the RMS error of δc, δd by '
                 f"{n['rms_per_rad']:.3g} per rad of angle noise (probe {n['probe_rad']:.0e} rad, "
                 f"{n['seeds']} "
                 f"seeds); the paper's RMS needs σ_φ ≈ {n['sigma_for_paper_rms_rad']:.2g} rad. At "
                 'that σ the ratio '
                 f"is {n['rms_ratio_mean']:.2f} on average, with {n['signs_mean']:.1f}/12 signs "
                 'and corr '
                 f"{n['corr_mean']:+.2f} ± {n['corr_std']:.2f}: "
                 + _verdict(noise_ok, f'explains size and pattern (corr ≥ {SAME_PATTERN:g}).',
                            f'not the pattern (corr < {SAME_PATTERN:g}).'))
    if explained:
        L.append("* Knobs that explain the paper's errors by these thresholds: " + '; '.join(explained) + '.')
    else:
        bp, bi = base['printed'], base['identity']
        z = a['w0_zero']['identity']
        best = max(((key, est) for key in a['knobs'] for est in ESTIMATORS if key != 'none'),
                   key=lambda ke: a['knobs'][ke[0]][ke[1]]['corr']
                   - 10 * max(abs(np.log(a['knobs'][ke[0]][ke[1]]['rms_ratio'])) - np.log(EXPLAINS_WITHIN), 0))
        kb = a['knobs'][best[0]][best[1]]
        L.append(f'* No knob tried, with either estimator, brings the ratio within {EXPLAINS_WITHIN:g}× of 1 with '
                 f"corr ≥ {SAME_PATTERN:g}. 000's method as printed gives ratio "
                 f"{bp['rms_ratio']:.2f}, "
                 f"{bp['signs']}/{bp['n']} signs, corr {bp['corr']:+.2f}; the modified "
                 "estimator's remainder "
                 f"(second order: w0·c and c²) has corr {bi['corr']:+.2f} with the paper but is "
                 f"{bi['rms_ratio']:.1f}× smaller (paper ≈ {bi['scale']:.1f}·ours, "
                 f"{100 * bi['misfit']:.0f}% of "
                 f"the paper's vector left over); with w0 = 0 its corr is {z['corr']:+.2f}. "
                 'Closest knob by '
                 f"these thresholds: {a['knobs'][best[0]]['label']} with the "
                 f'{ESTIMATORS[best[1]]} '
                 f"(ratio {kb['rms_ratio']:.2f}, {kb['signs']}/{kb['n']} signs, corr "
                 f"{kb['corr']:+.2f}). "
                 "Which step of the 1983 computation produced the paper's errors is not "
                 'identified.')
    return L + ['']


#: the rows of the error tables: the paper's published set first, then 000's method as printed
ROW_NAMES = {'paper': "paper (000's published errors)", 'ours_as_printed': "ours: 000's method as printed",
             'ours': 'ours: modified estimator', 'ours_iterated': 'ours: Gauss–Newton',
             'ours_mc_mean': 'ours: modified, Monte Carlo mean', 'ours_mc_std': 'ours: modified, Monte Carlo std'}


def report_000(r: dict) -> str:
    L = ['## 000 — gyro errors against a drifting reference (Tkachenko 1983, §6)', '']
    h = r['headline']
    L += ['Headline — first order, Δθ0 = 0 as in 000 (RMS ratio = RMS(paper)/RMS(ours) over δc1…δc9, δd1…δd3; '
          "signs = components with the paper's sign; corr = cosine between the two 12-vectors). "
          "First 000's "
          'method as printed (every coefficient of (5.7) at the reference increment p), then this '
          "project's "
          'modified estimator (w0 columns at ½(p + p*), c columns at p*; see below):', '']

    def _agree(o: dict) -> str:
        return (f"the paper's errors are {o['rms_ratio']:.3g}× ours in RMS "
                f"({_verdict(o['rms_ratio'] > 1, 'ours smaller', 'ours larger')}), {o['signs']}/{o['n']} signs agree, "
                f"corr {o['corr']:+.2f}")

    for case, hc in h.items():
        o, op = hc['ours'], hc['ours_as_printed']
        line = (f"* **{case}**, 000's method as printed: {_agree(op)}. Modified estimator: {_agree(o)}; "
                f"largest |ours/paper| {o['max_ratio']:.2g}.")
        if 'monte_carlo' in hc:
            m = hc['monte_carlo']
            line += (f" Against our Monte Carlo (modified estimator) over {m['seeds']} initial remainders: paper "
                     f"RMS / our RMS {m['rms_ratio']:.2f}, {m['within_2sigma']}/{m['n']} paper "
                     'values within 2σ of '
                     f"our mean (RMS z {m['z_rms']:.2f}; plausible if RMS z ≤ 2) — the paper's "
                     'set '
                     + _verdict(m['z_rms'] <= 2.0, 'is a plausible draw of the quantization noise.',
                                'is not a plausible draw of our quantization noise.'))
        L.append(line)
    L += ['', "Errors estimate − truth (w0: corrected attitude error w⁰ at t_f; dc, dd in the paper's units).", '']
    for case, rec in r['cases'].items():
        L += [f'### {case}', '', '| | w0 ×1e-5 | δc1…δc9 | δd1…δd3 |', '|---|---|---|---|']
        for key in ('paper', 'ours_as_printed', 'ours', 'ours_iterated', 'ours_mc_mean', 'ours_mc_std'):
            v = rec[key]
            L.append(f'| {ROW_NAMES[key]} | ' + ' '.join(f'{x * 1e5:+.2f}' for x in v['w0']) + ' | '
                     + ' '.join(f'{x:+.1e}' for x in v['dc']) + ' | ' + ' '.join(f'{x:+.1e}' for x in v['dd']) + ' |')
        L.append('')
    un, hu = r['cases']['unquantized'], h['unquantized']
    L += ["* 'ours: modified estimator' is 000's first-order method — one linear least-squares solve of "
          '(2.7)/(5.7), no iteration — with its coefficients moved to where the exact quaternion '
          'identity '
          'p° − q = w0 × (p° + q) puts them: the w0 columns at ½(p + p*), the c columns at the computed '
          'increment p*, the d columns at the reference p (derivation: strapdown_ros/calibration/drifting_reference.py, '
          "'Where to evaluate the coefficients'). '000's method as printed' evaluates everything "
          'at p, '
          'as 000 prints.',
          f'* Unquantized, printed coefficients: the w0² term 2w0 × (w0 × p*) stays in z; RMS ratio '
          f"{hu['ours_as_printed']['rms_ratio']:.2f}, {hu['ours_as_printed']['signs']}/12 signs, δc6 = "
          f"{un['ours_as_printed']['dc'][5]:+.1e} against the paper's {un['paper']['dc'][5]:+.1e} "
          f"({abs(un['ours_as_printed']['dc'][5] / un['paper']['dc'][5]):.0f}×).",
          f'* Iterated (Gauss–Newton on the exact model), unquantized: largest |error| '
          f"{max(abs(v) for v in un['ours_iterated']['dc'] + un['ours_iterated']['dd']):.1e}, "
          f"{1 / hu['ours_iterated']['max_ratio']:.1e}× below the paper's component for component at least."]
    q, hq = r['cases']['quantized_raw'], h['quantized_raw']['ours']
    q_ratio = np.array(q['ours']['dc']) / np.array(q['paper']['dc'])
    L += ['* Quantized, raw, Δθ0 = 0: ours/paper for δc1…δc9 = ' + ', '.join(f'{v:+.2f}' for v in q_ratio)
          + f" ({hq['signs']}/12 signs over δc, δd; RMS ratio {hq['rms_ratio']:.2f})."]
    g = r['centring_gain']
    gc, gd = 1 - g['rms_c_centred'] / g['rms_c_raw'], 1 - g['rms_d_centred'] / g['rms_d_raw']
    gp = 1 - g['printed_rms_c_centred'] / g['printed_rms_c_raw']
    gb = 1 - g['rms_c_bias_centred'] / g['rms_c_bias_raw']
    L += [f"* Centring (5.5), Monte Carlo over {g['seeds']} seeds: RMS of c {g['rms_c_raw']:.2e} → "
          f"{g['rms_c_centred']:.2e} ({100 * abs(gc):.0f}% {_verdict(gc > 0, 'less', 'more')}), of the biases c7–9 "
          f"{g['rms_c_bias_raw']:.2e} → {g['rms_c_bias_centred']:.2e} ({100 * abs(gb):.0f}% "
          f"{_verdict(gb > 0, 'less', 'more')}), of d {g['rms_d_raw']:.2e} → {g['rms_d_centred']:.2e} "
          f"({100 * abs(gd):.0f}% {_verdict(gd > 0, 'less', 'more')}). 000 says centring brings the errors towards "
          f"the unquantized ones: {_verdict(gc > 0 and gd > 0, 'agrees', 'does not agree')}. With the printed "
          f'coefficients the gain on c is {100 * gp:.1f}%.',
          "* Corrections to 000's §2/§5 print used here, each checked in test/calibration/test_drifting_reference.py: (2.5) sign of "
          'p×(w+w0); q_F = −½Δθ in (5.2); z = z′ − δz in (5.4); R(q_K) = σ²/48, not σ²/12.', '']
    L += _ablation_lines(r['ablations'])
    b = r.get('beyond_paper')
    if b:
        base = b['raw']
        L += [f"### Beyond the paper (σ = 2e-5, Monte Carlo over {g['seeds']} seeds)", '',
              "RMS errors, and in brackets the ratio to the paper's method without centring (raw, first order).", '',
              '| method | c | c7–9 | d | w⁰ (attitude at the epochs) |', '|---|---|---|---|---|']
        names = {'raw': 'raw (5.4), first order', 'centred': 'centred (5.5), first order',
                 'raw+iter': 'raw, Gauss–Newton', 'centred+iter': 'centred, Gauss–Newton',
                 'raw+weighted': 'raw, weighted R(δz)⁻¹', 'centred+weighted': 'centred, weighted',
                 'centred+iter+weighted': 'centred, Gauss–Newton, weighted'}
        for k, v in b.items():
            L.append(f'| {names.get(k, k)} | ' + ' | '.join(
                f'{v[qq]:.2e} ({v[qq] / base[qq]:.2f})' for qq in ('rms_c', 'rms_c_bias', 'rms_d', 'rms_w')) + ' |')
        it_gain = 1 - b['centred+iter']['rms_c'] / b['centred']['rms_c']
        w_gain = 1 - b['centred+weighted']['rms_c'] / b['centred']['rms_c']
        best = min(b, key=lambda k: b[k]['rms_c'])
        L += ['', f'* On c, from the centred first-order solution: Gauss–Newton {100 * it_gain:+.1f}%, weighting by '
              f"R(δz)⁻¹ {100 * w_gain:+.1f}%; weighting {_verdict(w_gain > it_gain, 'gains more', 'gains less')} "
              f'than iteration. Lowest RMS of c: {names.get(best, best)}.', '']
    return '\n'.join(L)


# --------------------------------------------------------------------------- plots
def plots_000(r: dict, outdir: str) -> list[str]:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt


    paths = []
    labels = [f'c{i}' for i in range(1, 10)] + [f'd{i}' for i in range(1, 4)]
    x = np.arange(len(labels))
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2), sharey=True)
    for ax, (case, rec) in zip(axes, r['cases'].items()):
        def mag(key):
            return np.abs(np.r_[rec[key]['dc'], rec[key]['dd']])
        ax.semilogy(x, mag('paper'), 'ks', ms=7, label='000 (paper)')
        ax.semilogy(x, mag('ours'), 'o', color='C0', label='ours, modified estimator')
        ax.semilogy(x, mag('ours_as_printed'), 'x', color='C3', ms=7, label="ours, 000's method as printed")
        if any(v > 0 for v in rec['ours_mc_std']['dc']):
            rms = np.sqrt(np.square(np.r_[rec['ours_mc_mean']['dc'], rec['ours_mc_mean']['dd']])
                          + np.square(np.r_[rec['ours_mc_std']['dc'], rec['ours_mc_std']['dd']]))
            ax.semilogy(x, rms, '_', color='C2', ms=14, mew=2, label='ours (modified), Monte Carlo RMS')
        ho, hp = r['headline'][case]['ours'], r['headline'][case]['ours_as_printed']
        ax.set_xticks(x, labels)
        ax.set_title(f"{case}: paper/ours RMS, signs\nas printed {hp['rms_ratio']:.2g}, {hp['signs']}/{hp['n']}; "
                     f"modified {ho['rms_ratio']:.2g}, {ho['signs']}/{ho['n']}", fontsize=10)
        ax.grid(True, which='both', alpha=0.3)
    axes[0].set_ylabel('|estimate − truth| (c1–6: 1; c7–9, d: rad/s)')
    axes[0].legend(fontsize=8, loc='lower left')
    fig.suptitle('000 §6: estimation errors, paper against ours (iterated: off scale below)')
    paths.append(save_figure(fig, outdir, 'seeds_000_errors.png'))
    g = r['centring_gain']
    fig, ax = plt.subplots(figsize=(6.5, 4))
    raw = [g['rms_c_raw'], g['rms_c_bias_raw'], g['rms_d_raw']]
    cen = [g['rms_c_centred'], g['rms_c_bias_centred'], g['rms_d_centred']]
    xx = np.arange(3)
    ax.bar(xx - 0.2, raw, 0.4, label='raw (5.4)')
    ax.bar(xx + 0.2, cen, 0.4, label='centred (5.5)')
    for i in range(3):
        ax.annotate(f'{-100 * (1 - cen[i] / raw[i]):+.0f}%', (xx[i] + 0.2, cen[i]), ha='center', va='bottom')
    ax.set_xticks(xx, ['c', 'c7–9 (biases)', 'd'])
    ax.set_ylabel('RMS error over seeds')
    ax.set_title(f"000 §6, σ = 2e-5: centring, Monte Carlo over {g['seeds']} seeds")
    ax.legend()
    paths.append(save_figure(fig, outdir, 'seeds_000_centring.png'))
    a = r['ablations']
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5), sharey=True)
    names = list(a['knobs'])
    yy = np.arange(len(names))
    for ax, (est, title) in zip(axes, ESTIMATORS.items()):
        vals = [a['knobs'][k][est] for k in names]
        ax.barh(yy, [v['rms_ratio'] for v in vals],
                color=['C0' if v['corr'] >= SAME_PATTERN else 'C7' for v in vals])
        for y, v in zip(yy, vals):
            ax.annotate(f" corr {v['corr']:+.3f}, {v['signs']}/{v['n']}", (v['rms_ratio'], y), va='center',
                        fontsize=7)
        ax.axvline(1.0, color='k', lw=1)
        ax.axvspan(1 / EXPLAINS_WITHIN, EXPLAINS_WITHIN, color='C2', alpha=0.12)
        ax.set_xscale('log')
        ax.set_xlim(min(0.3 * min(v['rms_ratio'] for v in vals), 0.3), 20 * max(v['rms_ratio'] for v in vals))
        ax.set_title(title)
        ax.set_xlabel("RMS(paper)/RMS(ours), unquantized δc, δd (1 = the paper's size)")
    axes[0].set_yticks(yy, names, fontsize=8)
    fig.suptitle(f"000 §6 ablations: green band = within {EXPLAINS_WITHIN:g}× of the paper's size; "
                 f'blue bar = corr ≥ {SAME_PATTERN:g}, grey = below')
    paths.append(save_figure(fig, outdir, 'seeds_000_ablations.png'))
    return paths


if __name__ == '__main__':                     # the former ``python -m strapdown_ros.calibration.drifting_reference``
    sys.exit(main(['--only', '000'] + sys.argv[1:]))
