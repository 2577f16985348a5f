"""
The starting sensor model of one's own recording, read off the recording itself.

``nominal_model`` runs :func:`nominal_model`; every value it writes carries the rule that
produced it (the model's provenance, written as a comment beside the value), and where the data
cannot support a value it says so and writes a stated default.  The rules:

* **rate and frames**: the gyro rate from the median step of the stamps; ``frame_id`` and
  ``reference_frame_id`` from the most frequent header frame ids; ``camera_frame_id`` from the
  child frame of a TF or Odometry reference.
* **clip level** (:func:`clip_level`): samples that sit at one rail (at least
  :data:`RAIL_COUNT` rates within 1e-6 of the largest |rate| of an axis, above 1 rad/s) name
  the gyro's range (a top reached within 0.2 % in several separate visits, :func:`noisy_rail`,
  is reported as a possible clip level); ``gyro_max_rate``
  is then 1.05 × the rail, so that the clipped samples are read (their rotation is
  underestimated, and said so).  Otherwise 1.5 × the largest rate seen, at least the MEMS default
  of :data:`DEFAULT_MAX_RATE`.
* **rest**: segments where the rate is constant within its noise
  (:func:`~strapdown_ros.discrepancy.diagnostics.static_segments`, at least
  :data:`MIN_REST_S`), whose mean rate is below :data:`MAX_REST_RATE` and over which the reference
  turns by less than :data:`MAX_REST_TURN_DEG`.
* **angle random walk** (``gyro_random_walk``): from the overlapping Allan deviation of the rate
  on the rest segments (allantools): N = σ_A(τ)·√τ, the geometric mean over the τ where the slope
  is −½ (τ up to a tenth of the segment and at most 1 s).
* **bias instability** (``gyro_bias_random_walk``, ``gyro_bias_correlation_time``): from the
  minimum of the Allan deviation when the rest lasts at least :data:`MIN_INSTABILITY_REST_S`:
  a first-order Gauss–Markov bias whose Allan deviation peaks there (τ_c = τ_min / 1.89, σ_b =
  σ_A,min / 0.437, σ_u = σ_b √(2/τ_c)); otherwise from the change of the rest means between rest
  segments (a random walk, σ_u = RMS(Δb) / √Δt); otherwise not identifiable: 0 (a random
  constant), said so.
* **bias prior** (``gyro_bias``, ``gyro_bias_sigma``): the mean rate on the rest segments minus
  the reference's own rate there (an Earth-fixed reference sees the Earth's rate as bias); its σ
  the largest of the mean's standard error, the spread of the segments' means and √2 × the change
  between the halves of the longest segment.  No rest: 0 ± :data:`DEFAULT_BIAS_SIGMA`.
* **reference noise** (``camera_sigma_xy``, ``camera_sigma_z``): increment pairs of the reference
  against the gyro at growing spacings (1, 2, 4, … samples), the boresight from the axis
  alignment of the pairs; the robust variance of the pair residuals per VF axis, less the gyro's
  random walk over the pair, is 2σ²(1 − ρ(spacing)): its plateau gives σ and the spacing where it
  is reached the reference's correlation time.
* **boresight**: that axis alignment, written as the starting boresight (discrepancy and
  calibrate_bag refine it), so that the filter can run on the nominal model.
* what the nominal model cannot know (scale factors, misalignments: the discrepancy workflow
  finds them) gets σ 0 and says so.

No ROS imports; allantools is an optional extra, imported where it is used.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from strapdown_ros.calibration.boresight import axis_alignment
from strapdown_ros.calibration.pairs import build_pairs, GyroRecord, pair_residuals
from strapdown_ros.discrepancy.diagnostics import static_segments
from strapdown_ros.rotation import (dcm_to_ypr, quat_conjugate, quat_multiply, quat_to_dcm,
                                    quat_to_rotvec)
from strapdown_ros.sensors.sensor_model import model_keys, SensorModel

__all__ = ['NominalModel', 'nominal_model', 'clip_level', 'noisy_rail', 'RAIL_COUNT',
           'RAIL_TOLERANCE',
           'RAIL_VISITS', 'DEFAULT_MAX_RATE', 'MIN_REST_S',
           'MAX_REST_RATE', 'MAX_REST_TURN_DEG', 'MIN_INSTABILITY_REST_S', 'DEFAULT_BIAS_SIGMA']

#: rates at one rail that name the gyro's clip level
RAIL_COUNT = 3
#: a rail with noise on it: the samples within this fraction of the axis' largest |rate| ...
RAIL_TOLERANCE = 2e-3
#: ... reached in at least this many separate visits
RAIL_VISITS = 3
#: gyro range of a MEMS gyro when the data show none, rad/s (about 2000 °/s)
DEFAULT_MAX_RATE = 35.0
#: a quiet window: the rate varies by less than this, rad/s (used when nothing is still)
QUIET_RATE = 0.02
#: shortest rest segment used, s
MIN_REST_S = 1.0
#: largest mean rate of a rest segment, rad/s (a MEMS bias is below 1 °/s)
MAX_REST_RATE = 0.05
#: largest turn of the reference over a rest segment, degrees
MAX_REST_TURN_DEG = 1.0
#: rest needed to see the bias instability (the minimum of the Allan deviation), s
MIN_INSTABILITY_REST_S = 100.0
#: prior σ of the bias without a rest segment, rad/s (a MEMS turn-on bias is below 0.5 °/s)
DEFAULT_BIAS_SIGMA = 0.01
#: a boresight direction is observable when its predicted σ is below this many reference σ
MAX_SIGMA_FACTOR = 20.0
#: a plateau of the reference-noise variance: the next spacing grows it by less than this factor
PLATEAU_GROWTH = 1.3


@dataclass
class NominalModel:
    """
    The starting model of a recording, the rules behind it and what was measured.

    Attributes
    ----------
    model : SensorModel
        The model; its ``provenance`` holds the rule of every value.
    settings : dict
        Settings of the consumers written beside it (``max_sigma`` of the calibrator).
    setting_rules : dict
        The rule of each setting.
    notes : list of str
        What the data could not support, and warnings (clipping), one line each.
    measured : dict
        The numbers behind the rules (JSON-ready): rest segments, Allan curve, noise by spacing.

    """

    model: SensorModel
    settings: dict = field(default_factory=dict)
    setting_rules: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    measured: dict = field(default_factory=dict)


def _most_common(frames) -> str | None:
    frames = [f for f in (frames or ()) if f]
    return Counter(frames).most_common(1)[0][0] if frames else None


def clip_level(rates: np.ndarray):
    """
    Return the gyro's clip level as the rate samples show it, or None.

    An axis clips when its largest |rate| (above 1 rad/s) is reached by :data:`RAIL_COUNT`
    samples within 1e-6: a flat rail.

    Parameters
    ----------
    rates : (n, 3) ndarray
        Rate samples, rad/s.

    Returns
    -------
    rail : float or None
        The clip level, rad/s (the largest |rate| of that axis).
    axis : int or None
        Its axis.
    count : int
        The samples at it.
    top : float
        The largest |rate| of any axis, rad/s.

    """
    a = np.abs(np.asarray(rates, dtype=float)).reshape(-1, 3)
    if len(a) == 0:
        return None, None, 0, 0.0
    top = a.max(axis=0)
    best = (None, None, 0)
    for ax in range(3):
        if top[ax] <= 1.0:
            continue
        n = int(np.sum(a[:, ax] >= top[ax] * (1.0 - 1e-6)))
        if n >= RAIL_COUNT and n > best[2]:
            best = (float(top[ax]), ax, n)
    return best[0], best[1], best[2], float(top.max())


def noisy_rail(rates: np.ndarray):
    """
    Return a level the rate keeps returning to, within :data:`RAIL_TOLERANCE`, or None.

    A gyro whose output near saturation carries a little noise sits on no flat rail, but the
    motion returns to the same top, within 0.2 %, in :data:`RAIL_VISITS` or more separate visits
    (a natural motion seldom does; a rate table of constant amplitude does too).  It is reported
    as a possible clip level, not used as the gyro's range.

    Parameters
    ----------
    rates : (n, 3) ndarray
        Rate samples, rad/s.

    Returns
    -------
    level : float or None
        The largest |rate| of that axis, rad/s.
    axis : int or None
        Its axis.
    count : int
        The samples within the tolerance.
    visits : int
        The separate visits.

    """
    a = np.abs(np.asarray(rates, dtype=float)).reshape(-1, 3)
    best = (None, None, 0, 0)
    for ax in range(3 if len(a) else 0):
        top = a[:, ax].max()
        if top <= 1.0:
            continue
        near = a[:, ax] >= top * (1.0 - RAIL_TOLERANCE)
        visits = int(np.sum(near[1:] & ~near[:-1]) + near[0])
        if visits >= RAIL_VISITS and int(near.sum()) > best[2]:
            best = (float(top), ax, int(near.sum()), visits)
    return best


def _adev(rate: np.ndarray, fs: float, taus: np.ndarray):
    import allantools
    t2, ad, _, _ = allantools.oadev(rate, rate=fs, data_type='freq', taus=taus)
    return np.asarray(t2), np.asarray(ad)


def _quiet_segments(t, dth, T):
    """Return the index ranges where the rate varies by less than QUIET_RATE (0.25-s windows)."""
    n = max(4, int(round(0.25 / T)))
    m = len(t) // n
    if m < 1:
        return []
    W = dth[: m * n].reshape(m, n, 3) / T
    quiet = np.all(W.std(axis=1) < QUIET_RATE, axis=1)
    out, i = [], 0
    while i < m:
        if not quiet[i]:
            i += 1
            continue
        j = i + 1
        while j < m and quiet[j]:
            j += 1
        if t[j * n - 1] - t[i * n] >= MIN_REST_S:
            out.append((i * n, j * n))
        i = j
    return out


def _rest_segments(t, dth, q_ref_at, T):
    """
    Return the index ranges of rest, their mean rates, the reference's rate, and the rule.

    Rest where the rate is constant within its noise (:func:`static_segments`); where there is
    none (a person standing sways), where the rate varies by less than :data:`QUIET_RATE`.
    """
    segs = static_segments(t, dth, None, min_duration=MIN_REST_S, window=0.25)
    rule = 'static'
    if not segs:
        segs, rule = _quiet_segments(t, dth, T), 'quiet'
    out = []
    for a, b in segs:
        w = dth[a:b].sum(axis=0) / (t[b - 1] - t[a] + T)
        if np.linalg.norm(w) > MAX_REST_RATE:
            continue
        q0, q1 = q_ref_at(t[a]), q_ref_at(t[b - 1])
        if q0 is None or q1 is None:
            continue
        turn = quat_to_rotvec(_rel(q0, q1))
        if np.degrees(np.linalg.norm(turn)) > MAX_REST_TURN_DEG:
            continue
        out.append((a, b, w, turn / (t[b - 1] - t[a] + T)))
    return out, rule


def _rel(q0, q1):
    return quat_multiply(quat_conjugate(q0), q1)


def nominal_model(stamps_ns, delta_theta, fix_stamps_ns, fix_q, facts: dict,
                  progress=None) -> NominalModel:
    """
    Read the starting sensor model off a recording (the rules of the module docstring).

    Parameters
    ----------
    stamps_ns : (n,) array_like of int
        Gyro increment end stamps, ns.
    delta_theta : (n, 3) array_like
        Gyro increments, rad (read with no clip level, so that clipped samples are seen).
    fix_stamps_ns : (m,) array_like of int
        Reference stamps, ns.
    fix_q : (m, 4) array_like
        Reference attitudes q_ref_VF, scalar first.
    facts : dict
        :func:`strapdown_ros.recording.recording_facts` of the recording (frames).
    progress : callable, optional
        ``progress(text)`` between the stages.

    Returns
    -------
    NominalModel
        The model with its rules, the settings, the notes, the numbers measured.

    Raises
    ------
    ValueError
        Fewer than 100 gyro increments or 10 reference fixes.

    """
    say = progress or (lambda s: None)
    st = np.asarray(stamps_ns, dtype=np.int64)
    dth = np.asarray(delta_theta, dtype=float).reshape(-1, 3)
    ft = np.asarray(fix_stamps_ns, dtype=np.int64)
    q = np.asarray(fix_q, dtype=float).reshape(-1, 4)
    if len(st) < 100 or len(ft) < 10:
        raise ValueError(f'{len(st)} gyro increments and {len(ft)} reference fixes: a nominal '
                         'model needs at least 100 and 10')
    origin = int(min(st[0], ft[0]))
    t = (st - origin) * 1e-9
    tf = (ft - origin) * 1e-9
    steps = np.diff(t)
    T = float(np.median(steps))
    values, rules, notes, measured = {}, {}, [], {}
    settings, setting_rules = {}, {}

    bounds = {k.name: (k.minimum, k.maximum) for k in model_keys()}

    def put(key, value, rule):
        lo, hi = bounds.get(key, (None, None))
        if isinstance(value, float) and hi is not None and value > hi:
            notes.append(f'{key}: the data say {value:.6g}, beyond the largest value the key '
                         f'takes ({hi:g}): {hi:g} is written; such a value means the data break '
                         'the rule behind it (a clipping gyro, a reference that jumps)')
            rule = f"{rule}; {value:.6g} from the data, above the key's range: its maximum"
            value = float(hi)
        elif isinstance(value, float) and lo is not None and value < lo:
            notes.append(f"{key}: the data say {value:.6g}, below the key's range: {lo:g} is "
                         'written')
            rule = f"{rule}; {value:.6g} from the data, below the key's range: its minimum"
            value = float(lo)
        values[key] = value
        rules[key] = rule

    # ---- rate and frames
    put('gyro_rate', round(1.0 / T, 6), f'the median step of the gyro stamps ({T * 1e3:.6g} ms, '
        f'{len(st)} increments)')
    for key, fact, what in (('frame_id', 'gyro_frames', 'the gyro messages'),
                            ('reference_frame_id', 'reference_frames', 'the reference messages')):
        f = _most_common(facts.get(fact))
        if f:
            put(key, f, f'the header frame id of {what}')
        else:
            notes.append(f'{key}: the messages name no frame; not stated (the default applies)')
    child = facts.get('reference_child_frame')
    if child:
        put('camera_frame_id', child, 'the child frame of the reference transforms')

    # ---- clip level
    h = np.concatenate([[T], steps])
    rates = dth / h[:, None]
    rail, axis, count, top = clip_level(rates)
    measured['largest_rate_rad_s'] = top
    if rail is not None:
        put('gyro_max_rate', round(1.05 * rail, 6),
            f'{count} samples sit at a rail of {rail:.6g} rad/s on axis {"xyz"[axis]}: the gyro '
            'clips there; 1.05 × the rail, so that the clipped samples are read')
        notes.append(f'CLIPPING: {count} gyro samples at {rail:.6g} rad/s (axis {"xyz"[axis]}): '
                     'the rotation in them is underestimated; the model cannot compensate it')
        measured['clip_level_rad_s'] = rail
    else:
        put('gyro_max_rate', round(max(DEFAULT_MAX_RATE, 1.5 * top), 6),
            f'1.5 × the largest rate seen ({top:.4g} rad/s), at least {DEFAULT_MAX_RATE:g} '
            '(no rail in the data)')
        level, ax, n, visits = noisy_rail(rates)
        if level is not None:
            notes.append(f'POSSIBLE CLIPPING: the rate about {"xyz"[ax]} returns to {level:.6g} '
                         f'rad/s within {100 * RAIL_TOLERANCE:g} % in {visits} separate visits '
                         f'({n} samples): a gyro that saturates with noise on its output, or a '
                         'motion of constant amplitude; if the gyro clips there, its rotation is '
                         'underestimated there and the fits will show it')
            measured['possible_clip_level_rad_s'] = level

    # ---- the reference at any time (nearest fix within two reference steps)
    fix_step = float(np.median(np.diff(tf))) if len(tf) > 1 else np.inf

    def q_ref_at(time):
        k = int(np.clip(np.searchsorted(tf, time), 1, len(tf) - 1))
        k = k if abs(tf[k] - time) < abs(tf[k - 1] - time) else k - 1
        return q[k] if abs(tf[k] - time) <= 2.0 * fix_step else None

    # ---- boresight (axis alignment) for the reference rate at rest and the noise
    say('boresight by axis alignment')
    gyro = GyroRecord(t, dth)
    C, spacing_rows = _reference_noise(gyro, tf, q, T, say)
    measured['reference_noise_by_spacing'] = spacing_rows
    measured['boresight_axis_alignment_rad'] = dcm_to_ypr(C).tolist() if C is not None else None
    if C is not None:                  # a starting boresight, so the filter can use this model
        put('boresight', [float(x) for x in dcm_to_ypr(C)],
            'axis alignment: the rotation that best maps the rotation vectors of the gyro onto '
            "those of the reference over pairs that turn (a start; discrepancy's fit refines it)")

    # ---- rest, ARW, bias instability, bias
    say('rest segments')
    rest, rest_rule = _rest_segments(t, dth, q_ref_at, T)
    rest_s = [float(t[b - 1] - t[a] + T) for a, b, _, _ in rest]
    measured['rest_segments_s'] = [[float(t[a]), float(t[b - 1])] for a, b, _, _ in rest]
    if rest:
        say(f'Allan deviation on {len(rest)} rest segment(s), {sum(rest_s):.3g} s')
        arw, curve = _arw(t, dth, rest, T)
        measured['allan'] = curve
        measured['rest_rule'] = rest_rule
        how = ('' if rest_rule == 'static' else
               f' (no still rest: segments where the rate varies by less than {QUIET_RATE:g} '
               'rad/s, so motion may add to it: an upper bound)')
        put('gyro_random_walk', float(arw),
            f'the Allan deviation of the rate on {len(rest)} rest segment(s) '
            f'({sum(rest_s):.3g} s): N = σ_A(τ)√τ on its −½ slope{how}')
        if rest_rule == 'quiet':
            notes.append(f'no still rest (the rate constant within its noise for '
                         f'{MIN_REST_S:g} s): quiet segments (the rate varying by less than '
                         f'{QUIET_RATE:g} rad/s) stand for rest; the angle random walk is an '
                         'upper bound')
    else:
        w = np.diff(dth, axis=0) / np.sqrt(2.0)             # white part, motion mostly removed
        arw = float(1.4826 * np.median(np.abs(w - np.median(w, axis=0))) / np.sqrt(T))
        put('gyro_random_walk', arw, 'no rest segment: the robust spread of the differences of '
            'consecutive increments (an upper bound: motion adds to it)')
        notes.append('no rest segment (rate constant and below '
                     f'{MAX_REST_RATE:g} rad/s for {MIN_REST_S:g} s while the reference keeps '
                     'still): the angle random walk is an upper bound; no bias prior from rest')
    sigma_u, tau_c = 0.0, 0.0
    longest = max(rest_s) if rest else 0.0
    if longest >= MIN_INSTABILITY_REST_S and 'allan' in measured:
        taus = np.asarray(measured['allan']['taus_s'])
        ad = np.asarray(measured['allan']['adev_rad_s'])
        sel = taus >= 1.0
        if np.any(sel):
            k = int(np.argmin(np.where(sel, ad, np.inf)))
            tau_c = float(taus[k] / 1.89)
            sigma_b = float(ad[k] / 0.437)
            sigma_u = float(sigma_b * np.sqrt(2.0 / tau_c))
            rule = (f'the minimum of the Allan deviation ({ad[k]:.3g} rad/s at τ '
                    f'{taus[k]:.3g} s): a Gauss–Markov bias, τ_c = τ_min/1.89, '
                    'σ_b = σ_A,min/0.437')
            put('gyro_bias_correlation_time', tau_c, rule)
            put('gyro_bias_random_walk', sigma_u, rule + ', σ_u = σ_b √(2/τ_c)')
    elif len(rest) >= 2:
        means = np.array([w for _, _, w, _ in rest])
        mids = np.array([0.5 * (t[a] + t[b - 1]) for a, b, _, _ in rest])
        db = np.diff(means, axis=0)
        dt = np.diff(mids)
        sigma_u = float(np.sqrt(np.mean(np.sum(db ** 2, axis=1) / 3.0 / dt)))
        put('gyro_bias_random_walk', sigma_u,
            f'the change of the rest means between {len(rest)} rest segments: a random walk, '
            'σ_u = RMS(Δb)/√Δt')
        put('gyro_bias_correlation_time', 0.0, 'a random walk (no correlation time)')
    else:
        put('gyro_bias_random_walk', 0.0,
            f'not identifiable: {longest:.3g} s of rest (the bias instability needs '
            f'{MIN_INSTABILITY_REST_S:g} s, or two rest segments): a random constant')
        notes.append(f'bias instability not identifiable from {longest:.3g} s of rest (needs '
                     f'{MIN_INSTABILITY_REST_S:g} s, or two rest segments): the bias is a random '
                     'constant in this model')
    duration = float(t[-1] - t[0])
    if rest:
        wsum = np.array([w * s for (_, _, w, _), s in zip(rest, rest_s)]).sum(axis=0)
        ref_rate = np.array([r * s for (_, _, _, r), s in zip(rest, rest_s)]).sum(axis=0)
        tot = float(sum(rest_s))
        ref_body = (C @ (ref_rate / tot)) if C is not None else ref_rate / tot
        bias = wsum / tot - ref_body
        se = arw / np.sqrt(tot)
        spread = float(np.std([w for _, _, w, _ in rest], axis=0).max()) if len(rest) > 1 else 0.0
        a, b = max(((a, b) for a, b, _, _ in rest), key=lambda ab: t[ab[1] - 1] - t[ab[0]])
        mid = (a + b) // 2
        half = float(np.max(np.abs(dth[a:mid].mean(axis=0) - dth[mid:b].mean(axis=0)) / T))
        wander = sigma_u * np.sqrt(duration)
        sig = float(max(se, spread, np.sqrt(2.0) * half / 2.0, wander))
        put('gyro_bias', [float(x) for x in bias],
            f'the mean rate on the rest segments ({tot:.3g} s) minus the reference own rate '
            'there')
        put('gyro_bias_sigma', sig,
            'the largest of: the standard error of the rest mean, the spread of the means of the '
            'segments, the change between the halves of the longest, the random walk over the '
            'recording')
    else:
        put('gyro_bias', [0.0, 0.0, 0.0], 'no rest segment: a stated default')
        put('gyro_bias_sigma', DEFAULT_BIAS_SIGMA,
            f'no rest segment: a stated default ({DEFAULT_BIAS_SIGMA:g} rad/s: a MEMS turn-on '
            'bias is below 0.5 °/s)')
    for key in ('gyro_scale_sigma', 'gyro_misalignment_sigma'):
        put(key, 0.0, 'not known before the discrepancy workflow, which estimates it: 0')

    # ---- reference noise: per VF axis, the first spacing whose variance the next one does
    # not grow by PLATEAU_GROWTH (no plateau: the largest value, an upper bound)
    if spacing_rows:
        sig, corr, flat = np.zeros(3), np.zeros(3), np.zeros(3, dtype=bool)
        for ax in range(3):
            v = [r['residual_variance_rad2'][ax] for r in spacing_rows]
            k = next((k for k in range(len(v) - 1) if v[k + 1] < PLATEAU_GROWTH * v[k]), None)
            if k is None:
                k = int(np.argmax([r['sigma_rad'][ax] for r in spacing_rows]))
            else:
                flat[ax] = True
            sig[ax] = spacing_rows[k]['sigma_rad'][ax]
            corr[ax] = spacing_rows[k]['seconds']
        where = ', '.join(f'{c:.3g}' for c in corr)
        how = ('the reference against the gyro: the robust variance of the pair residuals per VF '
               'axis at the spacing where it stops growing, less the random walk of the gyro, '
               f'is 2σ² (plateau at {where} s about x, y, z)')
        if not np.all(flat):
            axes = ', '.join('xyz'[a] for a in range(3) if not flat[a])
            how += f'; no plateau about {axes}: the largest value, an upper bound'
            notes.append(f'reference noise about VF {axes}: the pair residuals grow with the '
                         'spacing without a plateau (gyro errors are in them): the σ written is '
                         'an upper bound')
        put('camera_sigma_xy', float(np.sqrt(0.5 * (sig[0] ** 2 + sig[1] ** 2))), how)
        put('camera_sigma_z', float(sig[2]), how)
        measured['reference_correlation_time_s'] = float(corr.max())
    else:
        notes.append('reference noise: too few pairs with rotation to align the axes; the '
                     'default camera σ is not stated')
    if 'camera_sigma_xy' in values:
        cam = max(values['camera_sigma_xy'], values['camera_sigma_z'])
        # within the setting's range (≤ 1 rad: a direction known worse is no estimate)
        settings['max_sigma'] = float(min(max(1e-3, MAX_SIGMA_FACTOR * cam), 1.0))
        setting_rules['max_sigma'] = (f'calibrator and discrepancy: a boresight direction counts '
                                      f'as observable when known to {MAX_SIGMA_FACTOR:g} × the '
                                      'reference σ (at least 1e-3 rad, the star-camera default; '
                                      'at most 1 rad)')
    model = SensorModel.from_values(values, stated=set(values), provenance=rules,
                                    source='nominal_model')
    return NominalModel(model, settings, setting_rules, notes, measured)


def _arw(t, dth, rest, T):
    """Return the angle random walk from the Allan deviation at rest, and the curve."""
    fs = 1.0 / T
    longest = max(rest, key=lambda r: r[1] - r[0])
    n_long = longest[1] - longest[0]
    taus = np.unique(np.round(np.geomspace(T, max(2 * T, n_long * T / 4.0), 30) / T)) * T
    est, weights = [], []
    for a, b, _, _ in rest:
        n = b - a
        sel_taus = taus[taus <= min(1.0, n * T / 10.0)]
        if len(sel_taus) == 0:
            sel_taus = taus[:1]
        for c in range(3):
            tt, ad = _adev(dth[a:b, c] / T, fs, sel_taus)
            if len(ad):
                est.append(np.exp(np.mean(np.log(ad) + 0.5 * np.log(tt))))
                weights.append(n)
    arw = float(np.exp(np.average(np.log(est), weights=weights)))
    a, b = longest[0], longest[1]
    curves = [_adev(dth[a:b, c] / T, fs, taus) for c in range(3)]
    tt = curves[0][0]
    ad = np.mean([np.interp(tt, cv[0], cv[1]) for cv in curves], axis=0)
    return arw, {'taus_s': tt.tolist(), 'adev_rad_s': ad.tolist(),
                 'segment_s': float((b - a) * T)}


def _reference_noise(gyro: GyroRecord, tf, q, T, say):
    """Return the boresight by axis alignment and the pair residual variances by spacing."""
    m = len(tf)
    ref_step = float(np.median(np.diff(tf)))
    spacings = []
    s = 1
    while s * ref_step <= max(2.0, 4 * ref_step) and s < m // 4:
        spacings.append(s)
        s *= 2
    if not spacings:
        return None, []
    # the boresight from pairs that turn: at the spacing nearest 0.5 s
    s_align = min(spacings, key=lambda x: abs(x * ref_step - 0.5))
    idx = np.arange(0, m, s_align)
    pairs = build_pairs(gyro, tf[idx], q[idx], 0.0, [])
    if len(pairs) < 10:
        return None, []
    turn = np.linalg.norm(quat_to_rotvec(pairs.dq_imu), axis=1)
    keep = turn > np.radians(1.0)
    if keep.sum() < 10:
        return None, []
    C = axis_alignment(quat_to_dcm(pairs.dq_imu[keep]), quat_to_dcm(pairs.dq_cam[keep]))
    rw2 = None
    rows = []
    for s in spacings:
        variances = []
        for phase in range(min(s, 4)):
            idx = np.arange(phase, m, s)
            p = build_pairs(gyro, tf[idx], q[idx], 0.0, [])
            if len(p) < 10:
                continue
            r = pair_residuals(C, p)
            med = np.median(r, axis=0)
            variances.append((1.4826 * np.median(np.abs(r - med), axis=0)) ** 2)
        if not variances:
            continue
        v = np.mean(variances, axis=0)
        rows.append({'spacing': int(s), 'seconds': float(s * ref_step), 'variance_rad2': v})
    if not rows:
        return C, []
    # the gyro's white noise over one pair: the smallest spacing's growth is reference noise
    # and gyro noise; estimate the gyro part from the increments' own white noise
    w = np.diff(gyro.rho, axis=0) / np.sqrt(2.0)
    rw2 = float((1.4826 * np.median(np.abs(w - np.median(w, axis=0)))) ** 2 / T)
    out = []
    for k, row in enumerate(rows):
        ref_var = np.maximum(row['variance_rad2'] - rw2 * row['seconds'], 0.0)
        nxt = rows[k + 1]['variance_rad2'] if k + 1 < len(rows) else None
        flat = nxt is not None and np.all(nxt < PLATEAU_GROWTH * row['variance_rad2'])
        out.append({'spacing': row['spacing'], 'seconds': row['seconds'],
                    'residual_variance_rad2': row['variance_rad2'].tolist(),
                    'sigma_rad': np.sqrt(ref_var / 2.0).tolist(), 'plateau': bool(flat)})
    say(f'reference noise at {len(out)} spacings')
    return C, out
