"""
OpenCV hand-eye peers of the boresight benchmark.

``cv2.calibrateHandEye`` (Tsai, Park, Horaud, Andreff, Daniilidis) on absolute poses chained
from the same increment pairs as the package's estimator; OpenCV is an optional extra.
"""
from __future__ import annotations

import numpy as np

from strapdown_ros.rotation import quat_cumprod, quat_to_dcm

OPENCV_METHODS = ('TSAI', 'PARK', 'HORAUD', 'ANDREFF', 'DANIILIDIS')
#: methods also run with "pivot" translations (they degenerate on zero translations)
OPENCV_PIVOT_METHODS = ('ANDREFF', 'DANIILIDIS')
PIVOT_T_X = np.array([0.1, -0.2, 0.3])     # m, arbitrary camera offset of the pivot translations


def opencv_available() -> tuple[bool, str]:
    """
    Tell whether OpenCV's hand-eye calibration can be called.

    ``cv2.calibrateHandEye`` is missing from the Python bindings of opencv-python 5.0.0
    (opencv/opencv#29565, fixed upstream after that release).

    Returns
    -------
    available : bool
        True when ``cv2.calibrateHandEye`` exists.
    info : str
        The cv2 version, or why it is unavailable and what to install.

    """
    try:
        import cv2
    except ImportError as exc:
        return False, f"OpenCV not installed ({exc}); pip install 'opencv-python-headless<5'"
    if not hasattr(cv2, 'calibrateHandEye'):
        return False, (f'cv2 {cv2.__version__} has no calibrateHandEye in its Python bindings '
                       "(opencv/opencv#29565); install 'opencv-python-headless<5'")
    return True, f'cv2 {cv2.__version__}'


def opencv_handeye(pairs, fixes, methods=OPENCV_METHODS, translations: str = 'zero') -> dict:
    """
    Estimate R_cam2gripper = C_MF^VF with OpenCV's hand-eye methods from absolute poses.

    Gripper→base = Π ΔS_imu (MF at t_n → MF at t_1), target→camera = (S_GCRS^VF,n)ᵀ.

    Parameters
    ----------
    pairs : list of IncrementPair
        The increment pairs (their ``dq_imu`` are chained).
    fixes : list
        The camera fixes, one more than the pairs.
    methods : sequence of str, optional
        OpenCV method names (``CALIB_HAND_EYE_<name>``).
    translations : {'zero', 'pivot'}, optional
        ``'zero'``: the rotation-only problem as given.  ``'pivot'``: t_g2b,n = −R_g2b,n t_X
        with an arbitrary t_X and t_t2c = 0, so the camera centre stays at the base origin;
        these satisfy the translation equations for any rotation and add no information,
        but lift the degeneracy of methods that solve rotation and translation together.

    Returns
    -------
    dict
        Method → (C_MF^VF as a (3, 3) ndarray, or None; message).

    """
    avail, why = opencv_available()
    if not avail:
        return {m: (None, why) for m in methods}
    import cv2
    q_g = quat_cumprod(np.array([1.0, 0.0, 0.0, 0.0]), np.array([p.dq_imu for p in pairs]))
    R_g2b = [np.eye(3)] + list(quat_to_dcm(q_g))
    R_t2c = [quat_to_dcm(f.attitude).T for f in fixes]
    zeros = [np.zeros((3, 1)) for _ in R_g2b]
    t_g2b = zeros if translations == 'zero' else [(-R @ PIVOT_T_X).reshape(3, 1) for R in R_g2b]
    out = {}
    for m in methods:
        try:
            with np.errstate(invalid='ignore'):
                R, t = cv2.calibrateHandEye(R_g2b, t_g2b, R_t2c, zeros,
                                            method=getattr(cv2, f'CALIB_HAND_EYE_{m}'))
            R = np.asarray(R, dtype=float)
            if not np.all(np.isfinite(R)):
                out[m] = (None, 'degenerate output (NaN rotation)')
            elif abs(np.linalg.det(R) - 1.0) > 1e-6:
                out[m] = (None, f'degenerate output (det {np.linalg.det(R):.3g})')
            else:
                out[m] = (R, 'ok' if np.all(np.isfinite(t)) else 'ok (translation not finite)')
        except cv2.error as exc:  # pragma: no cover - depends on the OpenCV build
            text = str(exc).strip().splitlines()[-1]
            out[m] = (None, 'cv2.error: ' +
                      (text.split(' error: ', 1)[-1] if ' error: ' in text else text))
    return out


def all_opencv(pairs, fixes) -> dict:
    """
    Run every OpenCV method, with zero translations and (where needed) pivot ones.

    Parameters
    ----------
    pairs : list of IncrementPair
        The increment pairs.
    fixes : list
        The camera fixes.

    Returns
    -------
    dict
        ``opencv_<method>`` and ``opencv_<method>_pivot`` → (C or None, message).

    """
    out = {f'opencv_{m}': v for m, v in opencv_handeye(pairs, fixes).items()}
    out.update(
        {
            f'opencv_{m}_pivot': v
            for m, v in opencv_handeye(pairs, fixes, OPENCV_PIVOT_METHODS, 'pivot').items()
        }
    )
    return out
