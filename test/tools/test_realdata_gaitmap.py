"""
The offline tools on a real recording that ships with the repository (test/data/gaitmap/).

A foot IMU (sensor_msgs/Imu, 204.8 Hz) and the shoe's marker frame from motion capture
(PoseStamped at the full 100 Hz), gaitmap's example recording.  The reference is poor on
purpose: the markers sit on a flexing shoe, not rigidly on the IMU.  What is checked, each
through the command's ``main(argv)`` and its JSON:

* ``calibrate_bag`` on each half of the recording: it runs, and its IMU-to-marker rotation is
  checked against independent truth — gravity at the final rest, seen by the accelerometer in
  IMU axes and by the marker frame in mocap axes — and against the other half.  Where the two
  halves differ by more than their σ, the tool must have said that its fit is not consistent
  (``WARNING`` on stderr, ``UNTRUSTED`` in the summary); a traceback is never acceptable.
* ``discrepancy --write-model`` on the whole recording, then ``filter_bag`` with the model it
  wrote (the loop of the README's four commands): it applies at least 95% of the fixes it
  takes in motion, and its attitude agrees with the fixes it never applied (the reference
  at 100 Hz; the filter takes one fix per ``reference_spacing``) within 3 times the σ stated
  by the filter and the reference together, once the lag and a constant rotation are taken
  out.  The fixes are the independent truth; the check is computed here from the CSV, not
  taken from the tool's own line.

The 5° bounds are the requirement of a sensor-to-segment alignment in IMU gait analysis, not
fitted to the result; the figures found are printed (``pytest -s``).
"""
from __future__ import annotations

import json

import numpy as np
import pytest
from realdata_helpers import (cut_window, DATA, final_rest, imu_arrays, NS, pose_arrays,
                              read_messages, run_tool)

from strapdown_ros.estimation.chi_square import chi2_quantile
from strapdown_ros.estimation.reference_check import reference_agreement
from strapdown_ros.rotation import (from_ros_xyzw, quat_conjugate, quat_multiply, quat_rotate,
                                    quat_to_dcm, quat_to_rotvec, ypr_to_dcm)
from strapdown_ros.tools import calibrate_bag, discrepancy, filter_bag

yaml = pytest.importorskip('yaml')

pytest.importorskip('rosbags')

BAG = DATA / 'gaitmap_left'
MODEL = DATA / 'nominal_left.yaml'
TOPICS = ['--gyro-topic', '/imu/data', '--reference-topic', '/mocap/pose']
REQUIRED_DEG = 5.0


@pytest.fixture(scope='module')
def left():
    """Give the stamps, rates, accelerations and poses of the shipped left-foot bag."""
    msgs = read_messages(BAG)
    st_i, w, a = imu_arrays(msgs)
    st_r, q, p = pose_arrays(msgs)
    return {'st_i': st_i, 'w': w, 'a': a, 'st_r': st_r, 'q': q, 'rest': final_rest(st_r, q)}


@pytest.fixture(scope='module')
def work(tmp_path_factory):
    """Give a scratch directory for the module."""
    return tmp_path_factory.mktemp('gaitmap')


def gravity_angle_deg(c_imu_foot, left) -> float:
    """
    Return the angle between gravity in IMU axes and gravity predicted by a rotation.

    The accelerometer's mean at the final rest (specific force: +g up, IMU axes) against the
    mocap vertical (z) in the marker frame at the same rest, mapped by ``c_imu_foot``.
    """
    rest_i, rest_r = left['st_i'] >= left['rest'], left['st_r'] >= left['rest']
    f = left['a'][rest_i].mean(axis=0)
    q = left['q'][rest_r]
    up_foot = quat_rotate(quat_conjugate(q), np.broadcast_to([0.0, 0.0, 1.0], (len(q), 3)))
    up_foot = up_foot.mean(axis=0)
    pred = c_imu_foot @ (up_foot / np.linalg.norm(up_foot))
    return float(np.degrees(np.arccos(np.clip(pred @ f / np.linalg.norm(f), -1.0, 1.0))))


@pytest.fixture(scope='module')
def halves(left, work):
    """Run calibrate_bag on the first and the second half of the recording."""
    t0, t1 = int(left['st_i'][0]), int(left['st_i'][-1]) + 1
    mid = (t0 + t1) // 2
    out = []
    for k, (a, b) in enumerate(((t0, mid), (mid, t1))):
        bag = work / f'half{k}'
        cut_window(BAG, bag, a, b)
        js = work / f'half{k}.json'
        rc, o, e = run_tool(calibrate_bag.main, [bag, '--params', MODEL, '--json', js] + TOPICS)
        out.append({'rc': rc, 'out': o, 'err': e,
                    'json': json.loads(js.read_text()) if js.is_file() else None})
    return out


def test_calibrate_bag_runs_and_says_whether_its_fit_is_consistent(halves):
    for h in halves:
        assert h['rc'] == 0, h['err']
        assert 'Traceback' not in h['out'] + h['err']
        j = h['json']
        assert j['observable'] and j['converged']
        assert j['gyro_rate_from_stamps_hz'] == pytest.approx(204.8, rel=1e-6)
        assert j['messages']['camera'] >= 1930                 # every 100 Hz fix of ~19.35 s
        bad = not j['fit_consistent']
        assert bad == (j['chi2_per_dof'] > j['chi2_per_dof_band'][1]
                       or j['chi2_per_dof'] < j['chi2_per_dof_band'][0])
        assert bad == any(ln.startswith('WARNING:') for ln in h['err'].splitlines())
        assert bad == ('UNTRUSTED' in h['out'])
        print(f"calibrate_bag half: χ²/dof {j['chi2_per_dof']:.3g} "
              f"(band {j['chi2_per_dof_band'][0]:.3g}–{j['chi2_per_dof_band'][1]:.3g}), "
              f"β {np.degrees(j['beta_rad']).round(2)}° ± "
              f"{np.degrees(j['beta_sigma_rad']).round(2)}°")


def test_calibrate_bag_rotation_against_gravity_and_between_halves(halves, left):
    """
    Check the IMU-to-marker rotation against gravity at rest and between the halves.

    Each half's rotation maps the marker frame's vertical at the final rest onto the
    accelerometer's within the requirement; the halves agree within it; and where they differ
    by more than their stated σ (χ² of 3 dof above its 99 % quantile), a half says that its fit
    is not consistent.
    """
    qs = [from_ros_xyzw(np.asarray(h['json']['q_mf_vf_xyzw'])) for h in halves]
    for q, h in zip(qs, halves):
        ang = gravity_angle_deg(quat_to_dcm(q), left)
        print(f'gravity at rest against the half-recording rotation: {ang:.2f}°')
        assert ang <= REQUIRED_DEG
    d = quat_to_rotvec(quat_multiply(qs[1], quat_conjugate(qs[0])))       # MF axes
    cov = sum(np.asarray(h['json']['rotation_covariance_mf_rad2']) for h in halves)
    chi2 = float(d @ np.linalg.solve(cov, d))
    print(f'halves differ by {np.degrees(np.linalg.norm(d)):.2f}°, χ²(3) = {chi2:.1f} '
          f'(99 %: {chi2_quantile(0.99, 3):.2f})')
    assert np.degrees(np.linalg.norm(d)) <= REQUIRED_DEG
    if chi2 > chi2_quantile(0.99, 3):
        assert not all(h['json']['fit_consistent'] for h in halves)


@pytest.fixture(scope='module')
def found(left, work):
    """Run discrepancy --write-model on the whole recording."""
    bag = BAG
    js, model = work / 'found.json', work / 'found.yaml'
    rc, o, e = run_tool(discrepancy.main, [bag, '--model', MODEL, '--json', js, '--write-model',
                                           model, '--quiet'] + TOPICS)
    return {'bag': bag, 'rc': rc, 'out': o, 'err': e, 'model': model,
            'json': json.loads(js.read_text()) if js.is_file() else None}


def test_discrepancy_writes_a_model_on_the_real_recording(found, left):
    assert found['rc'] == 0, found['err']
    assert 'Traceback' not in found['out'] + found['err']
    j = found['json']
    assert j['verdict'] in ('model_adequate', 'explained', 'unexplained_structure')
    assert j['input']['gyro_rate_from_stamps_hz'] == pytest.approx(204.8, rel=1e-6)
    assert j['input']['camera_fixes'] >= 495                     # 100 Hz over 5 s
    # the fixes used: one per slot of the spacing the reference's correlation allows
    sp = j['reference_spacing']
    assert sp['step'] >= 1 and j['fixes'] <= j['input']['camera_fixes'] / sp['step'] + 2
    printed = (found['out'] + found['err']).splitlines()
    assert (not j['fit_consistent']) == any(ln.startswith('WARNING:') for ln in printed)
    print(f"discrepancy: verdict {j['verdict']}, effects "
          f"{[s['effect'] for s in j['steps']]}, χ²/dof {j['chi2_per_dof']:.3g}")
    written = yaml.safe_load(found['model'].read_text())['/**']['ros__parameters']
    assert written['frame_id'] == 'gaitmap_left_imu'
    assert written['reference_frame_id'] == 'gaitmap_mocap'
    assert written['gyro_rate'] == pytest.approx(204.8)
    # the boresight written: the same gravity check as calibrate_bag's
    ang = gravity_angle_deg(ypr_to_dcm(*written['boresight']), left)
    print(f'gravity at rest against the written boresight: {ang:.2f}°')
    assert ang <= REQUIRED_DEG


def test_a_named_gyro_bias_agrees_with_the_final_rest(found, left):
    """
    Check a named gyro bias against the final rest, where discrepancy names one.

    Truth: the mean gyro rate over the final rest minus the marker frame's mean rate over it
    (the foot sways a little; mapped into IMU axes by the written boresight, a correction of
    ~0.3 °/s that a 5° boresight error changes by < 0.03 °/s), σ from the gyro's white noise
    and a reference error of 3e-3 rad at each end of the rest (3.5× the largest per-fix scatter
    of the marker frame at rest).  Where discrepancy names no gyro bias, the written model holds
    none either.
    """
    rest_i, rest_r = left['st_i'] >= left['rest'], left['st_r'] >= left['rest']
    g = left['w'][rest_i]
    q, st = left['q'][rest_r], left['st_r'][rest_r]
    span = (st[-1] - st[0]) / NS
    w_ref = quat_to_rotvec(quat_multiply(quat_conjugate(q[0]), q[-1])) / span
    written = yaml.safe_load(found['model'].read_text())['/**']['ros__parameters']
    bias = g.mean(axis=0) - ypr_to_dcm(*written['boresight']) @ w_ref
    white = np.diff(g, axis=0).std(axis=0, ddof=1) / np.sqrt(2.0)
    sigma = np.hypot(white / np.sqrt(len(g)), np.sqrt(2.0) * 3.0e-3 / span)
    print(f'final rest: {span:.2f} s, gyro bias {np.degrees(bias).round(3)} ± '
          f'{np.degrees(sigma).round(3)} °/s')
    assert 1.5 < span < 3.0
    step = [s for s in found['json']['steps'] if s['effect'] == 'gyro_bias']
    assert ('gyro_bias' in written) == bool(step)
    if step:
        b = np.asarray(step[0]['parameters']['gyro_bias'])
        s = np.asarray(step[0]['sigma']['gyro_bias'])
        assert np.all(np.abs(b - bias) <= 3.0 * np.hypot(s, sigma)), (b, s, bias, sigma)


def test_filter_bag_with_the_written_model_agrees_with_the_reference(found, left, work):
    """
    Check the filter with the found model against the fixes it never applied.

    Fixes in motion: the marker frame turning faster than 0.5 rad/s at the fix.  The agreement
    is computed here: the filter's attitude at each output against the reference interpolated
    there from two fixes 10 ms apart that the filter did not apply, with the lag (searched
    within ±0.2 s) and a constant rotation (the chordal mean) taken out, per VF axis in units
    of the σ the filter's CSV and the model state together.
    """
    out = work / 'filter.csv'
    rc, o, e = run_tool(filter_bag.main, [found['bag'], '--params', found['model'], '--output',
                                          out, '--json', work / 'filter.json'] + TOPICS)
    assert rc == 0, e
    assert 'Traceback' not in o + e
    written = yaml.safe_load(found['model'].read_text())['/**']['ros__parameters']
    assert written.get('reference_spacing', 0.0) > 0.0        # 100 Hz markers: correlated
    rows = np.loadtxt(out, delimiter=',', skiprows=1, ndmin=2)
    fixes = [ln.split(',') for ln in (work / 'filter_fixes.csv').read_text().splitlines()[1:]]
    t_fix = np.array([float(f[0]) for f in fixes])
    status = np.array([f[1] for f in fixes])
    # the rate of the reference at each fix taken (independent of the filter)
    st_r = left['st_r'] * 1e-9
    w = quat_to_rotvec(quat_multiply(quat_conjugate(left['q'][:-1]), left['q'][1:]))
    rate = np.linalg.norm(w, axis=1) / np.diff(st_r)
    k = np.clip(np.searchsorted(st_r, t_fix) - 1, 0, len(rate) - 1)
    moving = rate[k] > 0.5
    share = np.mean(status[moving] == 'applied')
    print(f'filter_bag: {moving.sum()} fixes taken in motion, {100 * share:.1f}% applied; '
          f"{np.sum(status == 'applied')} of {len(status)} in all")
    assert moving.sum() >= 20 and share >= 0.95
    # the reference at 100 Hz is denser than the outputs (10 Hz): it is interpolated to each
    # output stamp whose two neighbouring fixes the filter did not apply
    applied = np.isin(np.round(st_r, 6), np.round(t_fix[status == 'applied'], 6))
    t_out = rows[:, 0]
    k = np.clip(np.searchsorted(st_r, t_out) - 1, 0, len(st_r) - 2)
    use = ~(applied[k] | applied[k + 1])
    q_out = np.column_stack([rows[:, 4], rows[:, 1:4]])
    agree = reference_agreement(t_out - t_out[0], q_out, rows[:, 5:8], st_r - t_out[0],
                                left['q'], reference_sigma(written), at='filter', use=use)
    print(f'against the reference at {agree.samples} outputs: lag {agree.lag_s * 1e3:.2f} ms, '
          f'RMS / σ = {np.round(agree.rms_ratio, 2)}, {100 * agree.within_3_sigma:.1f}% within '
          '3σ')
    assert agree.samples >= 300                               # of 387 outputs
    assert max(agree.rms_ratio) <= 3.0


def reference_sigma(written: dict) -> np.ndarray:
    """Return the reference's σ about VF x, y, z that a model file states (noise scale applied)."""
    sig = np.array([written['camera_sigma_xy'], written['camera_sigma_xy'],
                    written['camera_sigma_z']])
    return sig * np.asarray(written.get('camera_noise_scale', [1.0, 1.0, 1.0]))
