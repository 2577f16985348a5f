"""
000 (Tkachenko 1983), the estimator: gyro errors c, reference drift d and initial error w0.

From quaternion increments: the measurement equation (2.7), the §6 experiment beside the
published numbers, quantization (§5) and the refined attitude.
"""
import numpy as np
import pytest

from strapdown_ros.calibration.drifting_reference import (error_at_epochs, estimate,
                                                          measurement_rows, NormalEquations)
from strapdown_ros.calibration.drifting_reference_model import (bias_D, ErrorStructure,
                                                                integrate_attitude, PAPER_000,
                                                                PAPER_000_C, PAPER_000_D,
                                                                PAPER_000_W0, psi_matrix,
                                                                SCALE_MISALIGNMENT_BIAS,
                                                                scale_misalignment_bias_D,
                                                                theta_quadrature)
from strapdown_ros.reproductions.tkachenko1983 import (monte_carlo_000, run_tkachenko_experiment,
                                                       simulate_000)
from strapdown_ros.rotation import (quat_angle_between, quat_conjugate, quat_multiply,
                                    quat_normalize, quat_to_dcm, rotvec_to_quat, skew)


H = 0.02
SIGMA = 2e-5


def _paper(case):
    p = PAPER_000[case]
    return np.array(p['dc']), np.array(p['dd'])


# ----------------------------------------------------------------------------- (2.7)
def _linearisation_residual(eps, printed_25=False):
    sim = simulate_000(seed=None, c=np.zeros(9), w0=np.zeros(3), d=np.zeros(3))
    ep = sim.epochs[::10]
    x = eps * np.concatenate([PAPER_000_W0, PAPER_000_C, PAPER_000_D])
    w0, c, d = SCALE_MISALIGNMENT_BIAS.split(x)
    D = scale_misalignment_bias_D(sim.true_inc / H)
    meas = sim.true_inc + np.einsum('nij,j->ni', D, c) * H
    L0 = sim.profile.attitude(0.0)
    M0 = quat_multiply(quat_conjugate(quat_normalize(np.r_[1.0, w0])), L0)
    P = quat_multiply(quat_conjugate(rotvec_to_quat((H * ep)[:, None] * d)),
                      quat_multiply(sim.profile.attitude(H * ep), quat_conjugate(L0)))
    M = integrate_attitude(M0, meas, H, '2', ep)
    Ps = quat_multiply(M[ep], quat_conjugate(M0))
    Th = theta_quadrature(M, meas, H)
    r = []
    for j, e in enumerate(ep):
        U = measurement_rows(P[j], Th[e], psi_matrix(SCALE_MISALIGNMENT_BIAS, H * e, 0.0))
        if printed_25:     # (2.5) as printed, +p×(w + w0): w0 block −2Φ(p), Θ block ½(p0E + Φ(p))
            p0, p = P[j, 0], P[j, 1:]
            U[:, :3] = -2 * skew(p)
            U[:, 3:12] = 0.5 * (p0 * np.eye(3) + skew(p)) @ Th[e]
        r.append(Ps[j, 1:] - P[j, 1:] - U @ x)
    return np.sqrt(np.mean(np.square(r)))


def test_measurement_equation_27_is_second_order_exact():
    """
    Test (2.7) as printed: it predicts p* − p to second order in (w0, c, d).

    Halving the errors quarters the remainder.  With the sign of (2.5) as printed the remainder
    is first order (halves).
    """
    r = [_linearisation_residual(e) for e in (1.0, 0.5, 0.25)]
    assert r[0] / r[1] == pytest.approx(4.0, rel=0.02)
    assert r[1] / r[2] == pytest.approx(4.0, rel=0.02)
    assert r[0] < 3e-6                          # vs |p* − p| ≈ 1e-3
    rp = [_linearisation_residual(e, printed_25=True) for e in (1.0, 0.5)]
    assert rp[0] / rp[1] == pytest.approx(2.0, rel=0.02) and rp[0] > 300 * r[0]


def test_normal_equations_recursive_equal_batch():
    """The row-by-row accumulation (5.8) equals the batch least squares."""
    rng = np.random.default_rng(0)
    U, z = rng.normal(size=(60, 5)), rng.normal(size=60)
    W = [np.diag(rng.uniform(0.5, 2.0, 3)) for _ in range(20)]
    ne = NormalEquations(5)
    for k in range(20):
        ne.add(U[3 * k:3 * k + 3], z[3 * k:3 * k + 3], W[k])
    Wb = np.zeros((60, 60))
    for k in range(20):
        Wb[3 * k:3 * k + 3, 3 * k:3 * k + 3] = W[k]
    x = np.linalg.solve(U.T @ Wb @ U, U.T @ Wb @ z)
    np.testing.assert_allclose(ne.solve(), x, rtol=1e-10)
    assert ne.rows == 60
    assert ne.residual_ss(x) == pytest.approx((U @ x - z) @ Wb @ (U @ x - z), rel=1e-9)


# ----------------------------------------------------------------------------- §6, unquantized
def test_a_unquantized_first_order_within_10x_of_paper():
    """
    Test the first-order method (one linear solve of (2.7)) against 000's published errors.

    Every δc_i, δd_i within 10× of 000's published error (in fact within 3×).  The
    coefficients are evaluated exactly in w0 ('identity'); with 000's printed choice
    (everything at the reference p) the w0² term 2w0 × (w0 × p*) stays in z and δc6 becomes
    3e-6, 125× the paper's −2.4e-8 — the one component that breaks the 10× bound.  The
    remaining errors are second order in (w0, c); how they compare with the paper's (RMS
    ratio, signs, ablations) is reported by ``reproduce_seeds --only 000``.
    """
    r = run_tkachenko_experiment(seed=None)
    pc, pd = _paper('unquantized')
    dc, dd = np.abs(r['dc']), np.abs(r['dd'])
    assert np.all(dc <= 10 * np.abs(pc)), dc / np.abs(pc)
    assert np.all(dd <= 10 * np.abs(pd)), dd / np.abs(pd)
    assert np.max(np.abs(r['w0'])) < 10 * np.max(np.abs(PAPER_000['unquantized']['w0']))
    printed = run_tkachenko_experiment(seed=None, coefficients='printed')
    assert abs(printed['dc'][5]) > 10 * abs(pc[5])
    # the paper's O(H³) trapezoid quadrature changes nothing that matters here
    rt = run_tkachenko_experiment(seed=None, quadrature='trapezoid')
    assert np.max(np.abs(np.subtract(rt['dc'], r['dc']))) < 1e-8


def test_identity_coefficients_are_exact_in_w0():
    """
    Recover w0 exactly with the identity coefficients when c = d = 0.

    With no gyro or reference errors the only unknown is the initial attitude error w0, a
    constant conjugation P° = W0∘P*∘W0*.  The identity coefficients recover it exactly, even
    for w0 = 1e-2 per axis; the printed ones leave an error quadratic in w0.
    """
    zero_c, zero_d = np.zeros(9), np.zeros(3)
    err = {}
    for w in (1e-2, 5e-3):
        for co in ('identity', 'printed'):
            r = run_tkachenko_experiment(seed=None, c=zero_c, d=zero_d, w0=np.full(3, w),
                                         coefficients=co)
            err[w, co] = np.max(np.abs(np.r_[r['dw0'], r['dc'], r['dd']]))
    assert err[1e-2, 'identity'] < 1e-13 and err[5e-3, 'identity'] < 1e-13
    assert err[1e-2, 'printed'] > 1e-4
    assert err[1e-2, 'printed'] / err[5e-3, 'printed'] == pytest.approx(4.0, rel=0.05)
    with pytest.raises(ValueError, match='identity, printed'):
        run_tkachenko_experiment(seed=None, coefficients='midpoint')


def test_b_unquantized_iterated_reaches_round_off():
    """Gauss–Newton on the exact model: every error ≤ 1/1000 of the paper's (in fact ~1e-15)."""
    r = run_tkachenko_experiment(seed=None, iterate=True)
    pc, pd = _paper('unquantized')
    assert np.all(np.abs(r['dc']) <= 1e-3 * np.abs(pc)), np.abs(r['dc']) / np.abs(pc)
    assert np.all(np.abs(r['dd']) <= 1e-3 * np.abs(pd))
    assert np.all(np.abs(r['w0']) <= 1e-3 * np.abs(PAPER_000['unquantized']['w0']))
    assert np.max(np.abs(r['dc'])) < 1e-13 and r['w_rms'] < 1e-13
    assert r['iterations'] <= 8


def test_iterated_with_drift_epoch_before_t0_and_other_structures():
    """t* < t0 (000 §3): v(t0) = ½Ψ(t0, t*)d handled in the d columns; D = E3 (m = 1)."""
    r = run_tkachenko_experiment(seed=None, iterate=True, t_star=-20.0)
    assert max(np.max(np.abs(r['dc'])), np.max(np.abs(r['dd'])), np.max(np.abs(r['w0']))) < 1e-13
    s = ErrorStructure(D=bias_D, m=1)
    sim = simulate_000(seed=None, structure=s, c=np.array([1e-5, -2e-5, 3e-5]))
    sol = estimate(sim.meas, H, sim.M0, sim.ref_q0, sim.ref_q, sim.epochs, structure=s,
                   iterate=True)
    np.testing.assert_allclose(sol.x, sim.x_true, atol=1e-14)
    assert sol.observability.observable


def test_algorithms_and_epochs_inside_updates():
    """Any coning algorithm: epochs that fall inside an update cut it there (exact truth kept)."""
    sim = simulate_000(seed=None, c=np.zeros(9), w0=np.zeros(3))
    truth = sim.profile.attitude(H * np.arange(1501))
    for alg in ('2', 'three_sample_optimal', 'four_sample_optimal'):
        q = integrate_attitude(sim.M0, sim.true_inc, H, alg, sim.epochs)
        assert quat_angle_between(q, truth).max() < 1e-14
    r = run_tkachenko_experiment(seed=None, iterate=True, algorithm='three_sample_optimal')
    assert np.max(np.abs(r['dc'])) < 1e-13


def test_input_validation():
    """Unknown modes, quadratures and coefficients, and missing noise, raise ValueError."""
    sim = simulate_000(seed=None)
    args = (sim.meas, H, sim.M0, sim.ref_q0, sim.ref_q, sim.epochs)
    with pytest.raises(ValueError, match='valid: raw, centred, corrected'):
        estimate(*args, mode='centered')
    with pytest.raises(ValueError, match='needs quantum'):
        estimate(*args, mode='centred')
    with pytest.raises(ValueError, match='weighted'):
        estimate(*args, weighted=True)
    with pytest.raises(ValueError, match='quadrature'):
        estimate(*args, quadrature='simpson')


# ----------------------------------------------------------------------------- §5 quantization
def test_quantization_error_model_by_monte_carlo():
    """
    Test the quantization error model of 000 §5 by Monte Carlo.

    The mean of δz = p' − p* is the jump C(t0)(Δθ0 − ½σρ) at the first step; the printed local
    model −¼σ[p0E3 − Φ(p)]Bᵀ(t)ρ differs from it only inside the w0 columns; the fluctuation has
    R(δz) = σ²/48 (E3 − ppᵀ).
    """
    sim0 = simulate_000(seed=None)
    ep = sim0.epochs
    M = integrate_attitude(sim0.M0, sim0.meas, H, '2', ep)
    Ps = quat_multiply(M[ep], quat_conjugate(M[0]))
    C, C0 = quat_to_dcm(M[ep]), quat_to_dcm(M[0])
    mu = 0.5 * SIGMA * np.sign(sim0.meas[0])
    A = np.array([P[0] * np.eye(3) - skew(P[1:]) for P in Ps])
    dz, jump = [], []
    for s in range(60):
        sim = simulate_000(SIGMA, seed=s)
        d0 = np.random.default_rng(s).uniform(-SIGMA, SIGMA, 3)      # the initial remainder drawn
        Mq = integrate_attitude(sim.M0, sim.meas, H, '2', ep)
        dz.append(quat_multiply(Mq[ep], quat_conjugate(Mq[0]))[:, 1:] - Ps[:, 1:])
        jump.append(A @ (0.5 * C0 @ (d0 - mu)))
    dz, jump = np.array(dz), np.array(jump)
    fluct = dz - jump
    printed = np.einsum('nij,nj->ni', A, -0.5 * C @ mu)
    printed_rms = np.sqrt(np.mean((dz.mean(0) - printed) ** 2))
    assert np.sqrt(np.mean(fluct.mean(0) ** 2)) < 0.1 * printed_rms
    # printed − jump (means) lies in the span of the w0 columns 2Φ(p)
    diff = (printed - jump.mean(0)).ravel()
    W = np.vstack([2 * skew(P[1:]) for P in Ps])
    k = np.linalg.lstsq(W, diff, rcond=None)[0]
    assert np.sqrt(np.mean((W @ k - diff) ** 2)) < 0.15 * np.sqrt(np.mean(diff ** 2))
    R = np.einsum('snk,snl->nkl', fluct, fluct) / len(fluct)
    R_th = np.array([SIGMA ** 2 / 48 * (np.eye(3) - np.outer(P[1:], P[1:])) for P in Ps])
    ratio = np.trace(R, axis1=1, axis2=2).mean() / np.trace(R_th, axis1=1, axis2=2).mean()
    assert ratio == pytest.approx(1.0, abs=0.15)


def test_c_quantized_monte_carlo_centring_reduces_rms():
    """
    Test centring (5.5) over 30 initial remainders.

    Centring removes the bias of the raw residual and lowers the RMS error of c by ~25% (of
    the biases c7..c9 by ~30%) and of d by ~8%, with or without iteration.
    (5.6) gives the same c and d as (5.5).  (100 seeds: ``reproduce_seeds --only 000``.)
    """
    cases = (('raw', False, False), ('centred', False, False), ('corrected', False, False),
             ('raw', True, False), ('centred', True, False))
    mc = monte_carlo_000(range(30), SIGMA, cases=cases)
    raw, cen, cor = mc['raw'], mc['centred'], mc['corrected']
    assert cen['rms_c'] < 0.8 * raw['rms_c'] and cen['rms_c_bias'] < 0.8 * raw['rms_c_bias']
    assert cen['rms_d'] < 0.95 * raw['rms_d']
    ri, ci = mc['raw+iter'], mc['centred+iter']
    assert ci['rms_c'] < 0.8 * ri['rms_c'] and ci['rms_d'] < 0.95 * ri['rms_d']
    # the raw errors are biased (t-statistic of the mean), the centred ones are not
    for r_, c_ in ((raw, cen), (ri, ci)):
        t_raw = np.abs(r_['mean'] / (r_['std'] / np.sqrt(30)))[3:]
        t_cen = np.abs(c_['mean'] / (c_['std'] / np.sqrt(30)))[3:]
        assert t_raw.max() > 5 and t_cen.max() < 4
    np.testing.assert_allclose(cor['errors'][:, 3:], cen['errors'][:, 3:],
                               atol=0.05 * cen['rms_c'])
    # every quantized error of the order of the paper's quantized errors
    assert raw['rms_d'] < 10 * np.max(np.abs(PAPER_000['quantized_raw']['dd']))
    assert raw['rms_c'] < 10 * np.max(np.abs(PAPER_000['quantized_raw']['dc']))


def test_weighting_by_quantization_covariance():
    """Weighting by R(δz)⁻¹ (000 §5) on the same 12 seeds: lower RMS of c than unweighted."""
    cases = (('centred', True, False), ('centred', True, True))
    mc = monte_carlo_000(range(12), SIGMA, cases=cases)
    assert mc['centred+iter+weighted']['rms_c'] < mc['centred+iter']['rms_c']


def test_corrected_attitude_error():
    """Λ̂(t) = (1 + w(t))∘M(t): the first-order refinement takes the 1.7e-3 error to ~1e-5."""
    r = run_tkachenko_experiment(seed=None, full=True)
    sim = r['simulation']
    M = integrate_attitude(sim.M0, sim.meas, H, '2', sim.epochs)[sim.epochs]
    before = np.abs(error_at_epochs(M, sim.truth_epochs)).max()
    after = np.abs(error_at_epochs(r['solution'].refined_attitude, sim.truth_epochs)).max()
    assert before > 1e-3 and after < 2e-5
