"""
The calibrator's state file: identity, replay, lock, paths, temporaries.

No ROS: strapdown_ros.calibration.state is core code; calibrator_node only calls it.
"""
import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from strapdown_ros.calibration.state import CalibratorStateFile, state_identity, StateFileError
from strapdown_ros.calibration.streaming import BoresightCalibrator, CalibratorSettings
from strapdown_ros.motion.profiles import bench_profile
from strapdown_ros.params import CALIBRATOR_PARAMS, check_all, model_from_parameters
from strapdown_ros.sensors import IntegratingSensor
from strapdown_ros.sensors.star_camera import StarCameraModel

STREAMS = {'gyro': '/imu/delta_theta', 'camera': '/star_camera/attitude_with_covariance'}


@pytest.fixture(scope='module')
def recording():
    """Return gyro increments and camera fixes of the bench profile."""
    prof = bench_profile()
    t, dth, _ = IntegratingSensor(prof, 'gyro', 100.0).sample(int(prof.duration * 100) - 1)
    cam = StarCameraModel(boresight=np.radians([40.0, -25.0, 120.0]), interval=5.0, seed=1)
    fixes = cam.fixes(prof, int(prof.duration / 5.0) - 1)
    return t, dth, fixes


def _params(**over):
    return check_all(CALIBRATOR_PARAMS, over)


def _feed(cal, recording):
    """Gyro and fixes interleaved in stamp order, as a node receives them."""
    t, dth, fixes = recording
    k = 0
    for f in fixes:
        k1 = int(np.searchsorted(t, f.stamp + 0.05))
        cal.add_gyro(t[k:k1], dth[k:k1])
        k = k1
        cal.add_camera(f.stamp, f.attitude, f.covariance)


def _fresh(p):
    model, _ = model_from_parameters(p)
    return BoresightCalibrator.from_model(model, CalibratorSettings.from_values(p))


def test_replaying_the_same_recording_adds_nothing(tmp_path, recording):
    """
    Replay a recording into a resumed calibrator: no pair is added twice.

    Parameters
    ----------
    tmp_path : pathlib.Path
        pytest's temporary directory.
    recording : tuple
        Gyro increments and camera fixes of the bench profile (fixture).

    """
    p = _params()
    path = str(tmp_path / 'state.npz')
    sf = CalibratorStateFile(path, state_identity(p, STREAMS))
    sf.acquire()
    cal = _fresh(p)
    _feed(cal, recording)
    n = len(cal.pairs)
    assert n == len(recording[2]) - 1
    sf.save(cal, 0)
    sf.close()
    for _ in range(3):                        # a kill loop replaying the same data
        sf = CalibratorStateFile(path, state_identity(p, STREAMS))
        sf.acquire()
        cal = _fresh(p)
        assert sf.load(cal) == 0 and len(cal.pairs) == n
        _feed(cal, recording)
        assert len(cal.pairs) == n and cal.replayed_pairs == n
        sf.save(cal, 0)
        sf.close()
    assert sorted(os.listdir(tmp_path)) == ['state.npz', 'state.npz.lock']    # no temporaries


@pytest.mark.parametrize('change', [{'camera_frame_id': 'camera2'},
                                    {'gyro_scale_factor': [1e-3, 0.0, 0.0]},
                                    {'covariance_model': '004'}, 'stream'])
def test_a_state_of_another_calibration_is_refused_and_left_as_it_is(tmp_path, recording,
                                                                     change):
    """
    Refuse a state file written for another calibration and leave it untouched.

    Parameters
    ----------
    tmp_path : pathlib.Path
        pytest's temporary directory.
    recording : tuple
        Gyro increments and camera fixes of the bench profile (fixture).
    change : dict
        The parameters that differ.

    """
    p = _params()
    path = str(tmp_path / 'state.npz')
    sf = CalibratorStateFile(path, state_identity(p, STREAMS))
    sf.acquire()
    cal = _fresh(p)
    _feed(cal, recording)
    sf.save(cal, 0)
    sf.close()
    before = open(path, 'rb').read()
    if change == 'stream':
        q, name = p, 'gyro'
        ident = state_identity(p, {**STREAMS, 'gyro': '/robot2/imu/delta_theta'})
    else:
        q = _params(**change)
        ident, name = state_identity(q, STREAMS), next(iter(change))
    sf = CalibratorStateFile(path, ident)
    sf.acquire()
    cal = _fresh(q)
    with pytest.raises(StateFileError) as err:
        sf.load(cal)
    assert err.value.kind == 'identity' and name in str(err.value)
    assert cal.pairs == [] and cal.last_fix is None
    sf.close()
    assert open(path, 'rb').read() == before


def test_the_lock_refuses_a_second_user(tmp_path):
    """
    Refuse a second user of the same state file while the lock is held.

    Parameters
    ----------
    tmp_path : pathlib.Path
        pytest's temporary directory.

    """
    path = str(tmp_path / 'state.npz')
    a = CalibratorStateFile(path, state_identity(_params(), STREAMS))
    b = CalibratorStateFile(path, state_identity(_params(), STREAMS))
    a.acquire()
    with pytest.raises(StateFileError) as err:
        b.acquire()
    assert err.value.kind == 'locked' and 'in use' in str(err.value)
    a.close()
    b.acquire()
    b.close()


def test_a_directory_is_never_moved_and_a_trailing_slash_is_an_error(tmp_path):
    """
    Refuse a directory or a trailing separator as state file, moving nothing.

    Parameters
    ----------
    tmp_path : pathlib.Path
        pytest's temporary directory.

    """
    d = tmp_path / 'mydir'
    d.mkdir()
    (d / 'keep.txt').write_text('user data')
    for path in (str(d), str(tmp_path / 'state.npz') + os.sep,
                 str(tmp_path / 'missing' / 'state.npz')):
        sf = CalibratorStateFile(path, state_identity(_params(), STREAMS))
        with pytest.raises(StateFileError) as err:
            sf.acquire()
        assert err.value.kind == 'path', path
    assert (d / 'keep.txt').read_text() == 'user data'
    assert sorted(os.listdir(tmp_path)) == ['mydir']


def test_kill_9_temporary_removed_at_next_start_and_corrupt_file_moved(tmp_path):
    """
    Remove a killed writer's temporary at the next start; move a corrupt file aside.

    Parameters
    ----------
    tmp_path : pathlib.Path
        pytest's temporary directory.

    """
    path = str(tmp_path / 'state.npz')
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    # a writer killed with SIGKILL between writing its temporary and the rename
    code = textwrap.dedent(f"""
        import os, sys, numpy as np
        sys.path.insert(0, {repo!r})
        from strapdown_ros.calibration.state import CalibratorStateFile, state_identity
        from strapdown_ros.params import CALIBRATOR_PARAMS, check_all
        ident = state_identity(check_all(CALIBRATOR_PARAMS, {{}}), {STREAMS!r})
        sf = CalibratorStateFile({path!r}, ident)
        sf.acquire()
        os.replace = lambda a, b: (print("written", flush=True), os.kill(os.getpid(), 9))
        from strapdown_ros.calibration.streaming import BoresightCalibrator
        sf.save(BoresightCalibrator(), 0)
    """)
    res = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=60)
    assert res.returncode == -signal.SIGKILL and 'written' in res.stdout, res.stderr
    assert '.state.npz.tmp' in os.listdir(tmp_path)
    sf = CalibratorStateFile(path, state_identity(_params(), STREAMS))
    # the lock is free: the killed process is gone
    sf.acquire()
    assert '.state.npz.tmp' not in os.listdir(tmp_path)
    with open(path, 'wb') as fh:
        fh.write(b'not a state file')
    with pytest.raises(StateFileError) as err:
        sf.load(_fresh(_params()))
    assert err.value.kind == 'corrupt'
    assert sf.move_aside() == path + '.corrupt' and not os.path.exists(path)
    sf.close()
