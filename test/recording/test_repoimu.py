"""
The discrepancy workflow on a real recording: RepoIMU (IMU + Vicon), one T-stick trial.

The data set is not shipped (no licence to redistribute it; see test/data/README.md).  The
tests on it run when ``$STRAPDOWN_REALDATA`` names a directory with ``TStick/`` and are skipped
with the reason otherwise (the shipped real-data excerpt, gaitmap's, is tested in
test/recording/test_gaitmap.py and never skipped).  The tests at the end (the converter on a
synthetic file in RepoIMU's layout, the tools' argument errors) need no data and run
everywhere.

Truth here is never the tool's own output: the gyro bias is checked against the mean rate over
the rest segment at the start (found from the Vicon attitude, not from the gyro), the lag against
a cross-correlation of the gyro rate magnitude with the rate of the Vicon attitude computed in
this file, and injected perturbations (reference stamps +30 ms, +0.5 °/s on gyro x, a 37°
rotation of the reference frame) against their injected values.

The effects looked for are stated: ``time_offset`` and ``gyro_bias`` (``CANDIDATES`` below),
through the library call ``analyse(..., candidates=...)``; the full library runs in the CLI test.
"""
from __future__ import annotations

import dataclasses
import inspect
import json
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from strapdown_ros.recording.repoimu import find_repoimu, read_repoimu_csv, write_bag
from strapdown_ros.rotation import (quat_angle_between, quat_conjugate, quat_multiply, quat_to_dcm,
                                    quat_to_rotvec, rotvec_to_quat, ypr_to_dcm)
from strapdown_ros.tools.realdata_report import NOMINAL_MODEL

pytest.importorskip('rosbags')

TRIAL = 'TStick/TStick_Test08_Trial1.csv'
CANDIDATES = ('time_offset', 'gyro_bias')
DEG = np.pi / 180.0


@pytest.fixture(scope='module')
def workdir(tmp_path_factory):
    """Give a scratch directory for the module."""
    return tmp_path_factory.mktemp('realdata')


@pytest.fixture(scope='module')
def trial():
    """Give the RepoIMU trial, or skip when the data set is not there."""
    root = find_repoimu()
    if root is None or not (root / TRIAL).is_file():
        pytest.skip(f'RepoIMU not found: set STRAPDOWN_REALDATA to a directory with {TRIAL} '
                    '(the data set is not shipped; see test/data/README.md)')
    return read_repoimu_csv(root / TRIAL)


@pytest.fixture(scope='module')
def model_file(workdir):
    """Give the nominal model file of the trial."""
    p = workdir / 'nominal.yaml'
    p.write_text(NOMINAL_MODEL)
    return p


_runs = {}
REAL_TOPICS = {'gyro_topic': '/imu/data', 'reference_topic': '/mocap/pose'}


def _reads_real_formats() -> bool:
    """Check that discrepancy's reader takes --gyro-topic and --reference-topic."""
    from strapdown_ros.discrepancy.bag_input import load_recording
    params = inspect.signature(load_recording).parameters.values()
    return any(p.kind is p.VAR_KEYWORD or p.name == 'gyro_topic' for p in params)


def _analyse(trial, workdir, model_file, tag, real=None):
    """
    Write the trial as a bag, read it as discrepancy does, run the workflow.

    The bag is in the real formats (sensor_msgs/Imu + PoseStamped) when the installed tools read
    them, else in the package's own (Δθ + QuaternionStamped); ``real`` forces one.
    """
    real = _reads_real_formats() if real is None else real
    key = (tag, real)
    if key in _runs:
        return _runs[key]
    from strapdown_ros.discrepancy.bag_input import load_recording
    from strapdown_ros.discrepancy.workflow import analyse, DiscrepancySettings
    from strapdown_ros.params import load_model_file

    bag = workdir / f"bag_{tag}_{'real' if real else 'own'}"
    if real:
        write_bag(bag, trial, gyro_format='imu', reference_format='pose')
    else:
        write_bag(bag, trial, gyro_format='delta_theta', reference_format='quaternion')
    mf = load_model_file(str(model_file), 'calibrator_node')
    rec, _ = load_recording(str(bag), mf.model, mf.settings, **(REAL_TOPICS if real else {}))
    res = analyse(rec, mf.model, DiscrepancySettings.from_values(
        {**mf.settings, 'candidates': CANDIDATES}))
    _runs[key] = res
    return res


def _step(res, effect):
    for s in res.steps:
        if s.effect == effect:
            return s
    pytest.fail(f'{effect} not named: steps {[s.effect for s in res.steps]}, '
                f'rejected {res.rejected}, not separable {res.not_separable}')


def _rest_end(trial, angle_deg=0.5, margin_s=0.5):
    """
    Return the stamp (ns) where the rest at the start ends.

    Stamp (ns) where the rest at the start ends: the Vicon attitude first departs more than
    ``angle_deg`` from its first value, less ``margin_s``.  Uses the reference only.
    """
    q = trial.q_reference_marker
    ang = quat_angle_between(q, np.broadcast_to(q[0], q.shape))
    k = int(np.argmax(ang > angle_deg * DEG))
    assert k > 0, 'the trial does not start at rest'
    return int(trial.reference_stamps_ns[k]) - int(margin_s * 1e9)


def _xcorr_lag_s(trial):
    """
    Return the lag of the gyro behind the reference, s.

    Lag of the gyro behind the reference, s: peak of the cross-correlation of |ω_gyro| with
    |ω_ref| (the Vicon attitude differentiated, body-frame increments), parabolic
    interpolation.
    """
    assert np.array_equal(trial.stamps_ns, trial.reference_stamps_ns)  # one time base in RepoIMU
    t = trial.stamps_ns * 1e-9
    q = trial.q_reference_marker
    dq = quat_multiply(quat_conjugate(q[:-1]), q[1:])
    w_ref = np.linalg.norm(quat_to_rotvec(dq), axis=1) / np.diff(t)
    w_imu = np.linalg.norm(0.5 * (trial.gyro[:-1] + trial.gyro[1:]), axis=1)
    a, b = w_imu - w_imu.mean(), w_ref - w_ref.mean()
    lags = np.arange(-30, 31)
    cc = np.array([np.dot(a[max(0, L):len(a) + min(0, L)], b[max(0, -L):len(b) - max(0, L)])
                   for L in lags])
    k = int(np.argmax(cc))
    y0, y1, y2 = cc[k - 1], cc[k], cc[k + 1]
    frac = 0.5 * (y0 - y2) / (y0 - 2.0 * y1 + y2)
    return float((lags[k] + frac) * np.median(np.diff(t)))


def test_discrepancy_cli_runs_on_the_real_bags(trial, workdir, model_file):
    """No crash: the CLI on the full effect library, exit 0, a verdict, a model written."""
    bag = workdir / 'bag_cli'
    summary = write_bag(bag, trial, gyro_format='both', reference_format='both')
    assert summary['messages']['/imu/data'] == len(trial.stamps_ns)
    assert 80 <= summary['reference_fixes'] <= 95                    # ~1 Hz over ~90 s
    exe = Path(sys.executable).with_name('discrepancy')
    out = workdir / 'cli.json'
    found = workdir / 'found.yaml'
    topics = []
    if _reads_real_formats():
        topics = ['--gyro-topic', REAL_TOPICS['gyro_topic'],
                  '--reference-topic', REAL_TOPICS['reference_topic']]
    r = subprocess.run([str(exe), str(bag), '--model', str(model_file), '--json', str(out),
                        '--write-model', str(found), '--quiet'] + topics,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    j = json.loads(out.read_text())
    assert j['verdict'] in ('model_adequate', 'explained', 'unexplained_structure')
    assert j['input']['camera_fixes'] == summary['reference_fixes']
    assert found.is_file()


def test_named_bias_against_the_mean_rate_at_rest(trial, workdir, model_file):
    res = _analyse(trial, workdir, model_file, 'base')
    s = _step(res, 'gyro_bias')
    b, sb = np.asarray(s.parameters['gyro_bias']), np.asarray(s.sigma['gyro_bias'])
    rest = trial.stamps_ns < _rest_end(trial)
    n = int(rest.sum())
    assert n > 150                                                    # > 1.5 s at rest
    mean = trial.gyro[rest].mean(axis=0)
    s_mean = trial.gyro[rest].std(axis=0, ddof=1) / np.sqrt(n)
    diff = b - mean
    print('bias °/s', b / DEG, '± ', sb / DEG, 'rest mean', mean / DEG, '±', s_mean / DEG)
    assert np.all(np.abs(diff) <= 3.0 * np.hypot(sb, s_mean)), (diff / DEG, sb / DEG, s_mean / DEG)


def test_named_lag_against_a_cross_correlation(trial, workdir, model_file):
    res = _analyse(trial, workdir, model_file, 'base')
    s = _step(res, 'time_offset')
    tau, st = s.parameters['camera_time_offset'], s.sigma['camera_time_offset']
    lag = _xcorr_lag_s(trial)
    # camera_time_offset: a fix stamped t shows t − offset; a gyro lagging the reference by L
    # means the fix stamped t shows what the gyro reports at t + L, so offset = −L
    print(f'offset {tau * 1e3:.2f} ± {st * 1e3:.2f} ms, cross-correlation lag {lag * 1e3:.2f} ms')
    assert abs(tau + lag) <= max(3.0 * st, 0.002)


def test_injected_reference_stamp_shift_recovered(trial, workdir, model_file):
    base = _step(_analyse(trial, workdir, model_file, 'base'), 'time_offset')
    shifted = dataclasses.replace(trial, reference_stamps_ns=trial.reference_stamps_ns
                                  + 30_000_000)
    s = _step(_analyse(shifted, workdir, model_file, 'shift'), 'time_offset')
    change = s.parameters['camera_time_offset'] - base.parameters['camera_time_offset']
    sigma = s.sigma['camera_time_offset']
    print(f'offset change {change * 1e3:.3f} ms ± {sigma * 1e3:.3f} ms (injected 30 ms)')
    assert abs(change - 0.030) <= 3.0 * sigma
    assert abs(change - 0.030) <= 0.002


def test_injected_gyro_bias_recovered(trial, workdir, model_file):
    base = _step(_analyse(trial, workdir, model_file, 'base'), 'gyro_bias')
    add = np.array([0.5 * DEG, 0.0, 0.0])
    biased = dataclasses.replace(trial, gyro=trial.gyro + add)
    s = _step(_analyse(biased, workdir, model_file, 'bias'), 'gyro_bias')
    change = np.asarray(s.parameters['gyro_bias']) - np.asarray(base.parameters['gyro_bias'])
    sigma = np.asarray(s.sigma['gyro_bias'])
    print('bias change °/s', change / DEG, '±', sigma / DEG)
    assert np.all(np.abs(change - add) <= 3.0 * sigma)


def test_injected_boresight_recovered(trial, workdir, model_file):
    """
    Recover a fixed rotation of the marker frame as the boresight.

    The marker frame turned by a fixed 37° rotation R (q_vicon_marker' = q_vicon_marker ⊗ R):
    the boresight C_MF^VF' = C_MF^VF R.
    """
    base = _analyse(trial, workdir, model_file, 'base')
    axis = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
    q_r = rotvec_to_quat(37.0 * DEG * axis)
    turned = dataclasses.replace(trial, q_reference_marker=quat_multiply(
        trial.q_reference_marker, np.broadcast_to(q_r, trial.q_reference_marker.shape)))
    res = _analyse(turned, workdir, model_file, 'boresight')
    c_base = ypr_to_dcm(*base.boresight_rad)
    c_new = ypr_to_dcm(*res.boresight_rad)
    err = c_new.T @ (c_base @ quat_to_dcm(q_r))
    angle = np.arccos(np.clip(0.5 * (np.trace(err) - 1.0), -1.0, 1.0))
    sigma = float(np.linalg.norm(res.boresight_sigma_rad))
    print(f'boresight recovered to {angle / DEG:.4f}° (3σ = {3 * sigma / DEG:.3f}°)')
    assert angle <= max(3.0 * sigma, 0.2 * DEG)


def test_real_and_own_format_bags_give_the_same_result(trial, workdir, model_file):
    """
    Read real-format and own-format bags of one trial to the same result.

    sensor_msgs/Imu rates + PoseStamped read by the tools (trapezoid rule) give what the
    package's own Δθ + QuaternionStamped bag of the same trial gives.
    """
    if not _reads_real_formats():
        pytest.skip('the installed discrepancy reads no sensor_msgs/Imu + PoseStamped bag yet '
                    '(--gyro-topic/--reference-topic)')
    real = _analyse(trial, workdir, model_file, 'base', real=True)
    own = _analyse(trial, workdir, model_file, 'base', real=False)
    assert real.verdict == own.verdict
    assert [s.effect for s in real.steps] == [s.effect for s in own.steps]
    for a, b in zip(real.steps, own.steps):
        for name, v in a.parameters.items():
            np.testing.assert_allclose(v, b.parameters[name], rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(real.boresight_rad, own.boresight_rad, atol=1e-9)


# --- the converter and the tools' arguments, without the data set (these run everywhere) -------
def test_every_second_fix_agrees_with_every_fix_within_3_sigma(trial, workdir, model_file):
    """
    Agree within 3σ with every second fix and with every fix.

    Honest σ: the same trial with the reference decimated to one fix
    every 2 s instead of every 1 s; every estimate both runs make (boresight, time offset, gyro
    bias) agrees within 3 combined σ.
    """
    from strapdown_ros.tools.realdata_report import estimates_by_fix_interval

    (workdir / 'decimation').mkdir(exist_ok=True)
    runs = estimates_by_fix_interval(trial, model_file, workdir / 'decimation')
    one, two = runs['1'], runs['2']
    assert 'values' in one and 'values' in two, runs
    assert one['pairs'] > 1.8 * two['pairs']          # really every second fix
    common = [n for n in one['values'] if n in two['values']]
    assert 'boresight' in common and len(common) >= 2, common
    for name in common:
        a, b = one['values'][name], two['values'][name]
        d = np.asarray(a['value']) - np.asarray(b['value'])
        if name == 'boresight':
            d = (d + np.pi) % (2 * np.pi) - np.pi
        s = np.hypot(a['sigma'], b['sigma'])
        assert np.all(np.abs(d) <= 3.0 * s), (name, d, s)


def test_reference_with_added_noise_gives_no_confident_wrong_answer(trial, workdir,
                                                                    model_file):
    """
    Give no confident wrong answer on a noisy reference.

    0.3° (5.2e-3 rad) of white noise added to every Vicon fix, the nominal model (which states
    0.005 rad), the full effect library: the gyro bias is named and agrees with the mean rate at
    rest (reference-only rest segment) within 3 combined σ, and the boresight agrees with that of
    the clean recording within 3 combined σ; or the output says the fit is not consistent.
    """
    from strapdown_ros.discrepancy.bag_input import load_recording
    from strapdown_ros.discrepancy.workflow import analyse, DiscrepancySettings
    from strapdown_ros.params import load_model_file
    from strapdown_ros.recording.repoimu import rest_mean_rate

    rng = np.random.default_rng(20)
    q = quat_multiply(trial.q_reference_marker,
                      rotvec_to_quat(rng.normal(0.0, 5.2e-3, (len(trial.q_reference_marker), 3))))
    noisy = dataclasses.replace(trial, q_reference_marker=q)
    bag = workdir / 'bag_noisy_reference'
    write_bag(bag, noisy, gyro_format='delta_theta', reference_format='quaternion')
    mf = load_model_file(str(model_file), 'calibrator_node')
    rec, _ = load_recording(str(bag), mf.model, mf.settings)
    res = analyse(rec, mf.model, DiscrepancySettings.from_values(mf.settings))
    clean = _analyse(trial, workdir, model_file, 'base')
    d = (np.asarray(res.boresight_rad) - clean.boresight_rad + np.pi) % (2 * np.pi) - np.pi
    s = np.hypot(res.boresight_sigma_rad, clean.boresight_sigma_rad)
    if not res.fit_consistent:                      # said plainly: then no plain result to check
        assert res.sigma_method != 'model'
        return
    assert np.all(np.abs(d) <= 3.0 * s), (np.degrees(d), np.degrees(s))
    rest = rest_mean_rate(trial)
    b = _step(res, 'gyro_bias')
    z = (np.asarray(b.parameters['gyro_bias']) - rest['mean_rad_s']) / np.hypot(
        b.sigma['gyro_bias'], rest['sigma_rad_s'])
    assert np.all(np.abs(z) <= 3.0), z


def _synthetic_csv(path, n=501, period=0.01, t0=0.08):
    """Write a file in RepoIMU's layout: a rest, then a turn; Vicon exact."""
    t = t0 + period * np.arange(n)
    w = np.where(t > t0 + 1.0, 0.5, 0.0)
    angle = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * period)])
    q = np.stack([np.cos(angle / 2), 0 * angle, 0 * angle, np.sin(angle / 2)], axis=1)
    gyro = np.stack([0.001 + 0 * t, -0.002 + 0 * t, w], axis=1)
    acc = np.tile([0.0, 0.0, 9.81], (n, 1))
    mag = np.tile([0.3, 0.0, -0.8], (n, 1))
    rows = np.column_stack([t, q, acc, gyro, mag])
    with open(path, 'w', encoding='utf-8') as fh:
        fh.write('Time (s);Vicon Orientation;;;;IMU Acceleration;;;IMU Gyroscope;;;'
                 'IMU Magnetometer;;;\n;W;X;Y;Z;X;Y;Z;X;Y;Z;X;Y;Z;\n')
        for r in rows:
            fh.write(';'.join(f'{v:.9g}' for v in r) + '\n')
    return t, q, gyro, acc


def _read_bag(bag):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import get_typestore, Stores

    out = {}
    with AnyReader([Path(bag)], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
        for conn, ts, raw in r.messages():
            out.setdefault(conn.topic, []).append((ts, r.deserialize(raw, conn.msgtype)))
    return out


def test_converter_writes_what_the_file_says(tmp_path):
    t, q, gyro, acc = _synthetic_csv(tmp_path / 'Synthetic_Trial.csv')
    trial = read_repoimu_csv(tmp_path / 'Synthetic_Trial.csv')
    assert trial.name == 'Synthetic_Trial'
    np.testing.assert_array_equal(trial.stamps_ns, np.round(t * 1e9).astype(np.int64))
    summary = write_bag(tmp_path / 'bag', trial, gyro_format='both', reference_format='both')
    msgs = _read_bag(tmp_path / 'bag')
    imu = msgs['/imu/data']
    assert len(imu) == len(t) and summary['gyro_rate_hz'] == pytest.approx(100.0)
    for k in (0, 250, len(t) - 1):
        ts, m = imu[k]
        ns = m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
        assert ns == ts == int(round(t[k] * 1e9))
        assert m.header.frame_id == 'repoimu_imu'
        np.testing.assert_allclose([m.angular_velocity.x, m.angular_velocity.y,
                                    m.angular_velocity.z], gyro[k], rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose([m.linear_acceleration.x, m.linear_acceleration.y,
                                    m.linear_acceleration.z], acc[k], rtol=1e-8)
        assert m.orientation_covariance[0] == -1.0               # REP-145: no orientation
    # the reference: one fix per second of the data set's own stamps, q_vicon_marker as x,y,z,w
    pose = msgs['/mocap/pose']
    assert len(pose) == len(msgs['/star_camera/attitude']) == 6      # 0, 1, …, 5 s
    stamps = np.array([p.header.stamp.sec * 1e9 + p.header.stamp.nanosec for _, p in pose])
    np.testing.assert_allclose(np.diff(stamps), 1e9, atol=1.0)
    for _, p in pose:
        k = int(np.argmin(np.abs(t * 1e9 - (p.header.stamp.sec * 1e9 + p.header.stamp.nanosec))))
        o = p.pose.orientation
        np.testing.assert_allclose([o.w, o.x, o.y, o.z], q[k], atol=1e-8)
        assert p.header.frame_id == 'repoimu_vicon'
    # Δθ: the trapezoid rule over consecutive samples, stamped at the end of the interval
    dth = msgs['/imu/delta_theta']
    assert len(dth) == len(t) - 1
    k = 300
    ts, m = dth[k - 1]
    assert ts == int(round(t[k] * 1e9))
    np.testing.assert_allclose([m.vector.x, m.vector.y, m.vector.z],
                               0.5 * (gyro[k] + gyro[k - 1]) * 0.01, rtol=1e-6)


def test_rest_and_cross_correlation_on_exact_data(tmp_path):
    """
    Find the rest and the lag on a file whose answers are known.

    The library's rest-segment mean and cross-correlation lag (used by realdata_report) on a
    file whose answers are known: rest 1 s then a turn; the gyro then delayed by 30 ms.
    """
    from strapdown_ros.recording.repoimu import rest_mean_rate, xcorr_lag_s

    _synthetic_csv(tmp_path / 'T.csv', n=1001)
    trial = read_repoimu_csv(tmp_path / 'T.csv')
    rest = rest_mean_rate(trial)
    np.testing.assert_allclose(rest['mean_rad_s'], [0.001, -0.002, 0.0], atol=1e-12)
    # a turn that starts and stops so the rate magnitude has structure; gyro delayed by 30 ms
    t = trial.stamps_ns * 1e-9
    w = 0.5 * np.sin(2 * np.pi * 0.7 * t) * (t > t[0] + 1.0)
    angle = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * 0.01)])
    q = np.stack([np.cos(angle / 2), 0 * angle, 0 * angle, np.sin(angle / 2)], axis=1)
    delayed = np.interp(t - 0.030, t, np.abs(w))
    g = np.stack([0 * t, 0 * t, delayed], axis=1)
    tr = dataclasses.replace(trial, gyro=g, q_reference_marker=q)
    assert xcorr_lag_s(tr) == pytest.approx(0.030, abs=0.002)


def test_realdata_tools_refuse_bad_arguments_in_one_line(tmp_path):
    for args in (['realdata_report', '--data', str(tmp_path / 'none')],
                 ['realdata_bag', str(tmp_path / 'none.csv'), str(tmp_path / 'bag')]):
        exe = Path(sys.executable).with_name(args[0])
        r = subprocess.run([str(exe)] + args[1:], capture_output=True, text=True, timeout=60)
        assert r.returncode == 2
        assert len(r.stderr.strip().splitlines()) == 1 and 'error' in r.stderr
