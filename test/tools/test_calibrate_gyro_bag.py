"""
calibrate_gyro_bag: 000 and 002 on recordings.

Truth is what record_sim injected through the effect parameters (the random constants of the
simulated gyro are switched off), never the tool's own output.  The written model is judged by
the discrepancy workflow on a fresh simulation and by the compensation sins_node applies.
"""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from strapdown_ros.calibration import gyro as gc
from strapdown_ros.discrepancy.bag_input import load_recording
from strapdown_ros.discrepancy.synthetic import simulate_recording
from strapdown_ros.discrepancy.workflow import analyse, DiscrepancySettings
from strapdown_ros.motion.from_config import profile_from_config
from strapdown_ros.params import check_all, IMU_SIM_PARAMS, load_model_file, STAR_CAMERA_PARAMS
from strapdown_ros.rotation import quat_conjugate, quat_multiply, rotvec_to_quat
from strapdown_ros.sensors.effects import GyroEffects
from strapdown_ros.tools import calibrate_gyro_bag, discrepancy, record_sim


BIN = os.path.dirname(sys.executable)
BETA = [0.698, -0.436, 2.094]
SCENARIO = {'profile': 'bench', 'bench_repeat': 1, 'gyro_rate': 100.0, 'boresight': BETA,
            'gyro_bias_sigma': 0.0, 'gyro_scale_sigma': 0.0, 'gyro_misalignment_sigma': 0.0}
INJECTED = {'gyro_scale_factor': [5e-4, -3e-4, 4e-4],
            # M_xy, M_xz, M_yx, M_yz, M_zx, M_zy: not symmetric (the antisymmetric part is a
            # triad rotation)
            'gyro_misalignment': [2e-4, -1e-4, 3e-4, 1.5e-4, -2e-4, 1e-4],
            'gyro_bias': [1e-5, -2e-5, 1.5e-5]}
M = INJECTED['gyro_misalignment']
TRUTH = dict(zip(('scale_x', 'scale_y', 'scale_z', 'mis_xy', 'mis_xz', 'mis_yz', 'bias_x',
                  'bias_y', 'bias_z'),
                 INJECTED['gyro_scale_factor'] + [(M[0] + M[2]) / 2, (M[1] + M[4]) / 2,
                                                  (M[3] + M[5]) / 2]
                 + INJECTED['gyro_bias']))
NOMINAL = {'/**': {'ros__parameters': {'gyro_rate': 100.0}}}


def _record(path, over, duration):
    args = [str(path), '--no-accel', '--duration', str(duration)]
    for k, v in over.items():
        args += ['-p', f'{k}:={json.dumps(v)}']
    assert record_sim.main(args) == 0
    return path


def _run(*argv):
    return calibrate_gyro_bag.main([str(a) for a in argv] + ['--quiet'])


@pytest.fixture(scope='module')
def recording(tmp_path_factory):
    """Record the scenario with the injected gyro errors, and the nominal model."""
    d = tmp_path_factory.mktemp('gyro')
    bag = _record(d / 'bag', {**SCENARIO, **INJECTED, 'camera_interval': 0.5, 'seed': 11}, 170.0)
    model = d / 'nominal.yaml'
    model.write_text(json.dumps(NOMINAL))
    return d, bag, model


@pytest.fixture(scope='module', params=['integral', 'tkachenko'])
def calibrated(request, recording):
    """Run calibrate_gyro_bag by each method on the recording."""
    d, bag, model = recording
    out, js = d / f'{request.param}.yaml', d / f'{request.param}.json'
    assert _run(bag, '--method', request.param, '--model', model, '--write-model', out, '--json',
                js) == 0
    return request.param, out, json.loads(js.read_text())


def test_injected_errors_recovered_within_3_sigma(calibrated):
    method, _, r = calibrated
    assert r['observable'] and r['method'] == method
    est, sig = r['estimate'], r['sigma']
    for name, true in TRUTH.items():
        assert abs(est[name] - true) <= 3 * sig[name], (method, name, est[name], true, sig[name])
        # σ small enough to mean something
        assert sig[name] < 0.2 * abs(true), (method, name, sig[name])
    cov = np.array(r['covariance'])
    assert np.allclose(np.sqrt(np.diag(cov)), [sig[n] for n in r['labels']])
    # the noise model fits the data
    assert 0.7 < r['details']['chi2_per_dof'] < 1.4
    lo, hi = r['chi2_per_dof_band']
    assert r['fit_consistent'] is True and lo <= r['chi2_per_dof'] <= hi


def test_written_model_compensates_with_the_right_sign(calibrated, recording):
    """
    Check: written model compensates with the right sign.

    The model's parameters, compensated as sins_node compensates (GyroEffects), turn the recorded
    increments back into the true ones (from the profile), up to the triad rotation.
    """
    _, out, _ = calibrated
    model = load_model_file(str(out)).model
    for name in INJECTED:
        assert name in model.stated
    rec, info = load_recording(str(recording[1]), model)
    st = rec.gyro_stamps
    t = st + info['stamp_origin_ns'] * 1e-9                        # profile time (start_time 0)
    true = profile_from_config({**SCENARIO, 'bench_latitude_deg': 50.45, 'bench_earth_rate': True}
                               ).delta_theta(t - 0.01, t)
    comp = GyroEffects(model).compensate(rec.delta_theta, st, np.full(len(st), 0.01))
    # symmetric truth: what remains is the injected antisymmetric part (a rotation) and noise
    A = np.zeros((3, 3))
    for v, (i, j) in zip(M, ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))):
        A[i, j] = v
    A = 0.5 * (A - A.T)
    turning = np.linalg.norm(true, axis=1) > 1e-4
    raw_err = rec.delta_theta[turning] - true[turning] @ (np.eye(3) + A).T
    comp_err = comp[turning] - true[turning] @ (np.eye(3) + A).T
    wrong = GyroEffects({k: (-np.asarray(model.get(k))).tolist()
                         for k in INJECTED}).compensate(
        rec.delta_theta, st, np.full(len(st), 0.01))[turning] - true[turning] @ (np.eye(3) + A).T
    rms = lambda e: float(np.sqrt(np.mean(e ** 2)))       # noqa: E731
    assert rms(comp_err) < 0.2 * rms(raw_err) < 0.2 * rms(wrong), (rms(comp_err), rms(raw_err),
                                                                   rms(wrong))


@pytest.fixture(scope='module')
def fresh(recording):
    """Record anew with the same injected errors: other seed, camera every 2 s."""
    return _record(recording[0] / 'fresh',
                   {**SCENARIO, **INJECTED, 'camera_interval': 2.0, 'seed': 12}, 170.0)


def test_written_model_is_adequate_on_a_fresh_simulation(calibrated, fresh, tmp_path):
    """
    Check: written model is adequate on a fresh simulation.

    Acceptance: the written model, through the discrepancy workflow, on a fresh simulation, gives
    model_adequate (the nominal model does not: the next test).
    """
    method, out, _ = calibrated
    bag = fresh
    js = tmp_path / 'd.json'
    assert discrepancy.main([str(bag), '--model', str(out), '--json', str(js), '--quiet']) == 0
    r = json.loads(js.read_text())
    assert r['verdict'] == 'model_adequate', (method, r['steps'], r['tests_after'])


def test_nominal_model_is_not_adequate_on_that_recording(recording, tmp_path):
    over = {**SCENARIO, **INJECTED, 'camera_interval': 2.0, 'seed': 12}
    rec = simulate_recording(check_all(IMU_SIM_PARAMS, over), check_all(STAR_CAMERA_PARAMS, over),
                             170.0)
    model = load_model_file(str(recording[2])).model
    assert analyse(rec, model, DiscrepancySettings(max_steps=1)).verdict != 'model_adequate'


@pytest.fixture(scope='module')
def z_only(tmp_path_factory):
    """
    Record turns about the gyro z axis only (and rests).

    Turns about the gyro z axis only (and rests): x/y scale and misalignment unobservable.
    """
    d = tmp_path_factory.mktemp('z_only')
    prof = d / 'z_only.yaml'
    prof.write_text(json.dumps({'segments': [{'duration': 8.0},
                                             {'duration': 5.0, 'rate': [0, 0, 0.05]},
                                             {'duration': 8.0},
                                             {'duration': 5.0, 'rate': [0, 0, -0.05]},
                                             {'duration': 8.0}]}))
    return _record(d / 'bag',
                   {**SCENARIO, **INJECTED, 'profile': 'piecewise', 'profile_file': str(prof),
                    'camera_interval': 0.5, 'seed': 3}, 34.0)


@pytest.mark.parametrize('method, names, observable', [
    ('tkachenko', ('scale_x', 'scale_y', 'mis_xy'), ('scale_z', 'bias')),
    ('integral', ('B11', 'B22', 'B12', 'B21'), ('B33',)),
])
def test_unobservable_motion_is_refused_with_the_combinations_named(tmp_path, capsys, z_only,
                                                                    method, names,
                                                                    observable):
    out, js = tmp_path / 'out.yaml', tmp_path / 'r.json'
    assert _run(z_only, '--method', method, '--write-model', out, '--json', js) == 3
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1 and 'NOT observable' in lines[0], lines
    unobs = lines[0].split('unobservable:', 1)[1]
    for n in names:
        assert n in unobs, (n, lines[0])
    for n in observable:
        assert n not in unobs, (n, lines[0])
    assert not out.exists()                                        # no estimate published
    r = json.loads(js.read_text())
    assert r['observable'] is False and r['estimate'] is None and r['model_parameters'] is None


def test_arguments_and_files_are_checked_before_work(tmp_path, capsys, recording):
    d, bag, model = recording
    (tmp_path / 'exists.json').write_text('{}')
    (tmp_path / 'bad.yaml').write_text('/**: {ros__parameters: {no_such_parameter: 1}}')
    not_a_bag = tmp_path / 'notabag'
    not_a_bag.mkdir()
    cases = [
        ([str(tmp_path / 'missing'), '--method', 'integral'], 'does not exist'),
        ([str(bag)], '--method'),
        ([str(bag), '--method', 'kalman'], 'kalman'),
        ([str(bag), '--method', 'integral', '--drift'], '--drift'),
        ([str(bag), '--method', 'tkachenko', '--interval', '2'], '--interval'),
        ([str(bag), '--method', 'integral', '--interval', '-1'], '--interval'),
        ([str(bag), '--method', 'integral', '--sigma-limit', '0'], '--sigma-limit'),
        ([str(bag), '--method', 'integral', '--model', str(tmp_path / 'nomodel.yaml')], 'nomodel'),
        ([str(bag), '--method', 'integral', '--model', str(tmp_path / 'bad.yaml')],
         'no_such_parameter'),
        ([str(bag), '--method', 'integral', '--json', str(tmp_path / 'exists.json')], '--force'),
        ([str(bag), '--method', 'integral', '--json', '/nonexistent/r.json'], '/nonexistent'),
        ([str(bag), '--method', 'integral', '--write-model', str(tmp_path)], 'directory'),
        ([str(bag), '--method', 'integral', '--json', str(tmp_path / 'a'), '--write-model',
          str(tmp_path / 'a')],
         'same output'),
        ([str(not_a_bag), '--method', 'integral'], 'notabag'),
    ]
    for argv, needle in cases:
        try:
            # not --quiet: progress must not leak
            status = calibrate_gyro_bag.main(argv)
        except SystemExit as exc:                                  # argparse
            status = exc.code
        cap = capsys.readouterr()
        lines = [ln for ln in (cap.out + cap.err).splitlines() if ln.strip()]
        assert status == 2, (argv, cap.out, cap.err)
        assert len(lines) == 1 and 'error' in lines[0] and 'Traceback' not in cap.err, (argv,
                                                                                        lines)
        assert needle in lines[0], (argv, lines[0])
    # not overwritten without --force
    assert (tmp_path / 'exists.json').read_text() == '{}'


def test_an_estimate_beyond_its_key_range_writes_the_json_not_the_model(
        tmp_path, capsys, monkeypatch, recording):
    """
    An estimate no model file may hold: exit 3, one line naming the key, the JSON only.

    The estimate is replaced by a scale factor of 10 (the key's range is ±0.5).
    """
    _, bag, model = recording
    real = gc.model_parameters

    def beyond(cal):
        return {**real(cal), 'gyro_scale_factor': [10.0, 10.0, 10.0]}
    monkeypatch.setattr(gc, 'model_parameters', beyond)
    out, js = tmp_path / 'out.yaml', tmp_path / 'r.json'
    assert _run(bag, '--method', 'integral', '--model', model, '--write-model', out,
                '--json', js) == 3
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith('calibrate_gyro_bag: error: --write-model')
    assert 'gyro_scale_factor' in lines[0] and 'out of range' in lines[0], lines
    assert not out.exists()
    r = json.loads(js.read_text())
    assert r['observable'] and r['model_parameters']['gyro_scale_factor'] == [10.0, 10.0, 10.0]


def test_console_script_one_line_exit_2(tmp_path):
    p = subprocess.run([os.path.join(BIN, 'calibrate_gyro_bag'), str(tmp_path / 'none'),
                        '--method', 'tkachenko'],
                       capture_output=True, text=True, timeout=60)
    assert (p.returncode == 2 and p.stderr.count('\n') == 1
            and 'does not exist' in p.stderr), p.stderr


def test_tkachenko_with_a_drifting_reference_estimates_the_drift():
    """
    Check: tkachenko with a drifting reference estimates the drift.

    000's gyrostabilizer: the reference basis drifts at a constant rate d (reference axes).  On 000
    §6's motion (large turns about all axes, 30 s, fixes every 0.1 s) the drift option recovers d
    and the gyro errors within 3σ; without it the drift corrupts them.
    """
    over = {**SCENARIO, **INJECTED, 'profile': 'tkachenko', 'camera_interval': 0.1, 'seed': 21}
    rec = simulate_recording(check_all(IMU_SIM_PARAMS, over), check_all(STAR_CAMERA_PARAMS, over),
                             30.0)
    d = np.array([2e-5, -1e-5, 1.5e-5])                               # rad/s, about 4°/h
    t = rec.fix_stamps
    # q_L_VF
    rec.fix_q = quat_multiply(quat_conjugate(rotvec_to_quat(np.outer(t - t[0], d))), rec.fix_q)
    prep = gc.prepare(rec, load_model_file(None).model)
    r = gc.calibrate_drifting_reference(prep, drift=True)
    truth = np.array(list(TRUTH.values()) + list(d))
    assert r.observable and r.labels[-3:] == gc.DRIFT_LABELS
    assert np.all(np.abs(r.x - truth) <= 3 * r.sigma), np.round((r.x - truth) / r.sigma, 2)
    assert np.all(r.sigma[-3:] < 0.1 * np.abs(d))
    plain = gc.calibrate_drifting_reference(prep, drift=False)
    assert np.max(np.abs(plain.x - truth[:9]) / plain.sigma) > 5          # the drift matters here


def test_gyro_gap_is_not_spanned_and_both_methods_still_recover(recording):
    """
    Check: gyro gap is not spanned and both methods still recover.

    Increments missing for 1.5 s in mid-turn (the rotation in them is lost): nothing is formed
    across the gap — 002 drops the intervals spanning it, 000 uses the longer gap-free stretch.
    """
    model = load_model_file(str(recording[2])).model
    rec, _ = load_recording(str(recording[1]), model)
    st = rec.gyro_stamps
    # inside the first z turn (45–50 s)
    cut = (st > 46.0) & (st <= 47.5)
    a, b = st[np.nonzero(cut)[0][0] - 1], st[np.nonzero(cut)[0][-1] + 1]
    rec.gyro_stamps, rec.delta_theta, rec.gaps = st[~cut], rec.delta_theta[~cut], [(a, b)]
    prep = gc.prepare(rec, model)
    truth = np.array(list(TRUTH.values()))
    for r in (gc.calibrate_integral(prep), gc.calibrate_drifting_reference(prep)):
        assert r.observable, r.message
        assert np.all(np.abs(r.x - truth) <= 3 * r.sigma), (r.method,
                                                            np.round((r.x - truth) / r.sigma, 2))
    # 000: the stretch after the gap
    assert r.extra['segment_s'][0] > b


def test_camera_noise_100x_the_stated_sigma_is_an_inconsistent_fit(tmp_path, capsys):
    """
    Check: camera noise 100x the stated sigma is an inconsistent fit.

    002 with the camera noise 100× what its covariance states → χ²/dof far above its band,
    fit_consistent false, one WARNING line, exit 0; σ scaled by √(χ²/dof), the injected errors
    within 3 of those σ.
    """
    bag = _record(tmp_path / 'bag', {**SCENARIO, **INJECTED, 'camera_interval': 0.5, 'seed': 11,
                                     'camera_noise_scale': [100.0, 100.0, 100.0]}, 170.0)
    model = tmp_path / 'nominal.yaml'
    model.write_text(json.dumps(NOMINAL))
    js = tmp_path / 'r.json'
    capsys.readouterr()
    assert _run(bag, '--method', 'integral', '--model', model, '--json', js,
                '--sigma-limit', '1') == 0
    cap = capsys.readouterr()
    r = json.loads(js.read_text())
    lo, hi = r['chi2_per_dof_band']
    assert r['fit_consistent'] is False and r['chi2_per_dof'] > 10 * hi
    warn = [ln for ln in cap.err.splitlines() if ln.startswith('WARNING:')]
    assert len(warn) == 1 and 'band' in warn[0] and 'scaled' in warn[0] and 'UNTRUSTED' in cap.out
    k = np.sqrt(r['chi2_per_dof'])
    for name, true in TRUTH.items():
        assert abs(r['sigma'][name] - k * r['sigma_stated_noise'][name]) <= 1e-6 * r['sigma'][name]
        assert abs(r['estimate'][name] - true) <= 3 * r['sigma'][name], name
