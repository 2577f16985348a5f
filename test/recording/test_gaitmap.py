"""
The shipped real-data excerpt (test/data/gaitmap/) and its converter (gaitmap_bag).

The excerpt is gaitmap's example recording (MIT licence, test/data/gaitmap/README.md): a foot
IMU at 204.8 Hz and three shoe markers at 100 Hz, as bags in driver formats.  These tests run
everywhere (nothing is skipped): the bag is read with rosbags directly, not with the package's
reader, and its content is checked against truths that do not come from the converter — the
stated rates, gravity at rest, the motion-capture attitude's own rate against the gyro's.  The
converter itself is checked on a file in gaitmap's layout written here with exact motion.
"""
from __future__ import annotations

import io
from pathlib import Path
import tarfile

import numpy as np
import pytest
from realdata_helpers import DATA, final_rest, imu_arrays, NS, pose_arrays, read_messages

from strapdown_ros.rotation import (quat_angle_between, quat_conjugate, quat_multiply,
                                    quat_normalize, quat_rotate, quat_to_dcm, quat_to_rotvec,
                                    rotvec_to_quat)
from strapdown_ros.tools import gaitmap_bag

pytest.importorskip('rosbags')

G = 9.80665


@pytest.fixture(scope='module')
def left():
    """Give the messages of the shipped left-foot bag."""
    return read_messages(DATA / 'gaitmap_left')


# --- the shipped excerpt -------------------------------------------------------------------
def test_excerpt_is_shipped_with_its_licence_and_fits_the_size_limit():
    files = [p for p in DATA.rglob('*') if p.is_file()]
    assert sum(p.stat().st_size for p in files) <= 5_000_000
    for foot in ('left', 'right'):
        assert (DATA / f'gaitmap_{foot}' / 'metadata.yaml').is_file()
        assert (DATA / f'nominal_{foot}.yaml').is_file()
    licence = (DATA / 'LICENSE').read_text(encoding='utf-8')
    assert licence.startswith('MIT License\n')
    assert 'Copyright (c) 2020 MaD-Lab Erlangen' in licence
    assert 'Permission is hereby granted, free of charge' in licence
    readme = (DATA / 'README.md').read_text(encoding='utf-8')
    assert 'gaitmap-2.6.0' in readme and 'Küderle' in readme and 'gaitmap_bag' in readme


def test_excerpt_is_written_as_a_driver_records_it(left):
    """Rates, clock, frames and compression as stated in the README."""
    import yaml

    meta = yaml.safe_load((DATA / 'gaitmap_left' / 'metadata.yaml').read_text())
    info = meta['rosbag2_bagfile_information']
    assert info['storage_identifier'] == 'mcap'
    assert set(left) == {'/imu/data', '/mocap/pose'}
    raw = (DATA / 'gaitmap_left' / 'gaitmap_left.mcap').read_bytes()
    assert b'zstd' in raw                                  # chunk compression named in the file
    st_i, w, a = imu_arrays(left)
    st_r, q, p = pose_arrays(left)
    assert len(st_i) == 7928 and len(st_r) == 3870
    for topic in left:                                     # log time = header stamp
        np.testing.assert_array_equal(left[topic][0], left[topic][1])
    assert set(left['/imu/data'][2]) == {'gaitmap_left_imu'}
    assert set(left['/mocap/pose'][2]) == {'gaitmap_mocap'}
    # one clock: row 0 of both streams at one instant, a realistic epoch (2020)
    assert st_i[0] == st_r[0]
    assert 1.5e9 < st_i[0] / NS < 1.7e9 and st_i[0] % NS != 0
    # the rates from the stamps: 204.8 Hz (period 4 882 812.5 ns, whole ns) and 100 Hz
    d = np.diff(st_i)
    assert set(d.tolist()) <= {4_882_812, 4_882_813}
    assert (st_i[-1] - st_i[0]) / (len(st_i) - 1) == pytest.approx(NS / 204.8, abs=0.01)
    assert set(np.diff(st_r).tolist()) == {10_000_000}
    # REP-145: no orientation from the IMU; unit quaternions from the markers
    m0 = left['/imu/data'][3][0]
    assert m0.orientation_covariance[0] == -1.0
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-9)


def test_units_against_gravity_and_the_reference(left):
    """
    Check the units against gravity and the reference.

    Accelerations in m/s² (|f| at rest is gravity), rates in rad/s (|ω| of the gyro against
    |ω| of the marker frame differentiated, the two are independent sensors), positions in m.
    """
    st_i, w, a = imu_arrays(left)
    st_r, q, p = pose_arrays(left)
    rest = final_rest(st_r, q)
    assert 1.5 < (st_r[-1] - rest) / NS < 3.0                 # ~2 s of rest at the end
    f = np.linalg.norm(a[st_i >= rest].mean(axis=0))
    assert f == pytest.approx(G, rel=0.02)
    dq = quat_multiply(quat_conjugate(q[:-1]), q[1:])
    w_ref = np.linalg.norm(quat_to_rotvec(dq), axis=1) / (np.diff(st_r) / NS)
    t_mid = 0.5 * (st_r[:-1] + st_r[1:])
    w_imu = np.interp(t_mid, st_i.astype(float), np.linalg.norm(w, axis=1))
    moving = w_ref > 1.0                                        # rad/s
    ratio = np.median(w_imu[moving] / w_ref[moving])
    assert 0.8 < ratio < 1.25, ratio                           # not °/s (57×)
    assert 5.0 < np.linalg.norm(w, axis=1).max() < 20.0         # walking: up to ~13 rad/s
    # markers on a shoe: a few cm above the floor at rest, metres walked
    assert 0.0 < p[st_r >= rest, 2].mean() < 0.2
    assert np.linalg.norm(np.ptp(p[:, :2], axis=0)) > 1.0


# --- the converter, on a file in gaitmap's layout with exact motion ---------------------------
LICENCE = ('AGPL3 License\nThis licence applies to the gaitmap_mad package\n\nnot ours\n\n\n'
           'MIT License\nThis licence applies to the gaitmap package and\nall other files except '
           'the ones found in the gaitmap_mad folder.\n\nCopyright (c) 2020 MaD-Lab Erlangen\n\n'
           'Permission is hereby granted, free of charge, to any person ...\n')


def _exact_motion(n_mocap=300):
    """Return mocap stamps (s), q_mocap_foot, foot origin (m) and the markers in the foot frame."""
    t = np.arange(n_mocap) / 100.0
    phi = np.stack([0.8 * np.sin(2.1 * t), 0.3 * np.cos(1.3 * t), 1.5 * t], axis=1)
    q = rotvec_to_quat(phi)
    origin = np.stack([0.4 * t, 0.1 * np.sin(t), 0.03 + 0 * t], axis=1)
    local = {'TOE': [0.25, 0.0, 0.0], 'FCC': [0.0, 0.0, 0.0], 'FM5': [0.18, 0.05, 0.0]}
    return t, q, origin, {k: np.array(v) for k, v in local.items()}


def _write_layout(root: Path):
    """Write gaitmap's two CSVs, LICENSE and PKG-INFO for exact motion; return the truth."""
    t, q, origin, local = _exact_motion()
    c = quat_to_dcm(q)
    (root / 'example_data').mkdir(parents=True)
    header = ['', '']
    cols = []
    for foot, side in (('L', 1.0), ('R', -1.0)):
        for name in ('TOE', 'FCC', 'FM5'):
            v = local[name] * np.array([1.0, side, 1.0])           # FM5 lateral on each foot
            cols.append(1000.0 * (origin + np.einsum('nij,j->ni', c, v)))
            header[0] += f',{foot}_{name},{foot}_{name},{foot}_{name}'
            header[1] += ',x,y,z'
    rows = np.column_stack([np.arange(len(t))] + cols)
    (root / 'example_data' / 'mocap_sample.csv').write_text(
        header[0] + '\n' + header[1] + '\n'
        + '\n'.join(','.join([str(int(r[0]))] + [repr(float(v)) for v in r[1:]]) for r in rows)
        + '\n')
    k = np.arange(612)                                      # ~3 s at 204.8 Hz
    gyr = np.stack([np.full(len(k), 10.0), -20.0 + 0.1 * k, 30.0 * np.sin(k / 50.0)], axis=1)
    acc = np.stack([np.zeros(len(k)), 0.01 * k, np.full(len(k), G)], axis=1)
    h1 = 'sensor' + ',left_sensor' * 6 + ',right_sensor' * 6
    h2 = 'axis' + ',acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z' * 2
    data = np.column_stack([k, acc, gyr, -acc, -gyr])
    (root / 'example_data' / 'imu_sample_not_rotated.csv').write_text(
        h1 + '\n' + h2 + '\n'
        + '\n'.join(','.join([str(int(r[0]))] + [repr(float(v)) for v in r[1:]]) for r in data)
        + '\n')
    (root / 'LICENSE').write_text(LICENCE)
    (root / 'PKG-INFO').write_text('Metadata-Version: 2.4\nName: gaitmap\nVersion: 2.6.0\n')
    centroid = origin + np.einsum('nij,j->ni', c, (local['TOE'] + local['FCC'] + local['FM5'])
                                  / 3.0)
    return {'q': q, 'centroid': centroid, 'k': k, 'gyr': gyr, 'acc': acc, 'mocap_n': len(t)}


def test_converter_writes_what_the_files_say(tmp_path, capsys):
    src = tmp_path / 'gaitmap-2.6.0'
    truth = _write_layout(src)
    out = tmp_path / 'out'
    out.mkdir()
    assert gaitmap_bag.main([str(src), str(out)]) == 0
    assert 'gaitmap_left' in capsys.readouterr().out
    msgs = read_messages(out / 'gaitmap_left')
    st_i, w, a = imu_arrays(msgs)
    origin = st_i[0]
    # stamps: index · 1e9/204.8 ns from the origin, rounded half up; the same origin for mocap
    np.testing.assert_array_equal(st_i - origin, (truth['k'] * 9_765_625 + 1) // 2)
    np.testing.assert_allclose(w, np.radians(truth['gyr']), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(a, truth['acc'], rtol=1e-12)
    st_r, q, p = pose_arrays(msgs)
    np.testing.assert_array_equal(st_r - origin, np.arange(truth['mocap_n']) * 10_000_000)
    assert np.max(np.degrees(quat_angle_between(q, truth['q']))) < 1e-6
    np.testing.assert_allclose(p, truth['centroid'], atol=1e-9)
    assert (out / 'LICENSE').read_text() == LICENCE[LICENCE.index('MIT License'):]
    # the right foot: FM5 on the other side, so the marker frame's z points down
    st_r, q, p = pose_arrays(read_messages(out / 'gaitmap_right'))
    flip = np.broadcast_to(rotvec_to_quat(np.array([np.pi, 0.0, 0.0])), q.shape)
    assert np.max(np.degrees(quat_angle_between(q, quat_multiply(truth['q'], flip)))) < 1e-6
    # the archive gives the same bags, byte for byte
    tgz = tmp_path / 'gaitmap-2.6.0.tar.gz'
    with tarfile.open(tgz, 'w:gz') as tar:
        tar.add(src, arcname='gaitmap-2.6.0')
    out2 = tmp_path / 'out2'
    out2.mkdir()
    assert gaitmap_bag.main([str(tgz), str(out2), '--feet', 'left']) == 0
    assert (out2 / 'gaitmap_left' / 'gaitmap_left.mcap').read_bytes() == \
        (out / 'gaitmap_left' / 'gaitmap_left.mcap').read_bytes()


def test_converter_refuses_in_one_line(tmp_path, capsys):
    src = tmp_path / 'gaitmap-2.6.0'
    _write_layout(src)
    out = tmp_path / 'out'
    out.mkdir()
    assert gaitmap_bag.main([str(src), str(out), '--feet', 'left']) == 0
    capsys.readouterr()
    before = (out / 'gaitmap_left' / 'gaitmap_left.mcap').read_bytes()
    cases = ([str(src), str(out), '--feet', 'left'],            # exists without --force
             [str(src), str(out), '--feet', 'middle'],
             [str(tmp_path / 'none.tar.gz'), str(out)],
             [str(out / 'LICENSE'), str(tmp_path / 'x')],
             [str(src), str(src / 'example_data'), '--force'])  # output inside the input
    for argv in cases:
        assert gaitmap_bag.main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith('gaitmap_bag: error:'), (argv, err)
    assert (out / 'gaitmap_left' / 'gaitmap_left.mcap').read_bytes() == before
    bad = tmp_path / 'bad.tar.gz'
    with tarfile.open(bad, 'w:gz') as tar:
        info = tarfile.TarInfo('x/README')
        info.size = 2
        tar.addfile(info, io.BytesIO(b'hi'))
    assert gaitmap_bag.main([str(bad), str(out), '--force']) == 2
    assert 'not a gaitmap sdist' in capsys.readouterr().err


def test_foot_frame_of_three_markers():
    """fwd, side, n of exact markers: the rotation that placed them, and NaN for a bad row."""
    from strapdown_ros.recording.gaitmap import foot_frame

    q = quat_normalize(np.array([[0.9, 0.1, -0.3, 0.2], [1.0, 0.0, 0.0, 0.0]]))
    heel = np.array([[1.0, 2.0, 0.1], [0.0, 0.0, 0.0]])
    toe = heel + quat_rotate(q, np.array([0.26, 0.0, 0.0]))
    fm5 = heel + quat_rotate(q, np.array([0.19, -0.06, 0.0]))
    got, centroid = foot_frame(toe, heel, fm5)
    # FM5 on the −y side: n = fwd × (−y) = −z, so the frame is q turned by π about x
    want = quat_multiply(q, np.broadcast_to(rotvec_to_quat(np.array([np.pi, 0.0, 0.0])), q.shape))
    assert np.max(np.degrees(quat_angle_between(got, want))) < 1e-9
    np.testing.assert_allclose(centroid, (toe + heel + fm5) / 3.0)
    got, _ = foot_frame(np.array([[1.0, 0, 0], [np.nan, 0, 0]]), np.zeros((2, 3)),
                        np.array([[2.0, 0, 0], [1.0, 1.0, 0]]))       # collinear; missing
    assert np.all(np.isnan(got))
