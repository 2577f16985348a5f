"""
Command-line options and reports of the input of the offline tools (:mod:`.reader`).

``add_input_arguments`` makes ``--gyro-topic``, ``--reference-topic``, ``--reference-frames`` and
``--rate-rule`` once for every tool; ``input_summary``, ``input_lines`` and ``input_warnings`` say
what was read and how (JSON, stdout, stderr).

THE summary of what was read and dropped is :func:`read_record` (in ``input_summary``'s record
under ``read``, so in every tool's JSON under ``input.read``) and :func:`read_lines` (in
``input_lines``, so in every tool's printout), with the same keys and wording in
``calibrate_bag``, ``calibrate_gyro_bag``, ``discrepancy``, ``filter_bag`` and ``nominal_model``:
the messages read per topic, per stream the messages kept and those dropped per reason, the
gaps, dropouts, bursts and resynchronisations, and the header frame ids with their counts.
:func:`frame_warnings` warns of frames the model does not expect (a stray frame is used, not
refused); :func:`usable_error` is the one error of a stream with nothing usable in it.
"""

from __future__ import annotations

from strapdown_ros.recording.reader import (bounded, bounded_list, CAMERA_COV_TOPIC, CAMERA_TOPIC,
                                            DELTA_THETA_TYPE, GYRO_TOPIC, IMU_TYPE)
from strapdown_ros.streams.checks import clip_text
from strapdown_ros.streams.rate_increments import RATE_RULES

#: frame ids named per stream in the facts of a recording
MAX_FRAMES = 8

__all__ = [
    'recording_facts',
    'read_record',
    'read_lines',
    'frame_warnings',
    'usable_error',
    'input_summary',
    'input_warnings',
    'input_lines',
    'add_input_arguments',
    'check_input_arguments',
    'input_options',
]


def recording_facts(data: dict) -> dict:
    """
    Return what a recording shows of the sensor model: its gyro rate and its frames.

    :func:`strapdown_ros.params.check_against_recording` compares them with the model.

    Parameters
    ----------
    data : dict
        The result of :func:`read_bag`.

    Returns
    -------
    dict
        ``gyro_rate_hz`` (from the median step of the stamps; None when unknown),
        ``gyro_frames`` and ``reference_frames`` (header frame ids seen, most frequent first),
        ``reference_child_frame`` (TF: the child frame read; else None).

    """
    period = data.get('gyro_period_s')
    rate = 1.0 / period if period and 0 < period < float('inf') else None
    frames = data.get('frames') or {}
    tf = data.get('reference_frames') or {}
    child = tf.get('child')
    return {'gyro_rate_hz': rate,
            'gyro_frames': [bounded(f) for f in list(frames.get('gyro', ()))[:MAX_FRAMES]],
            'reference_frames': [bounded(f) for f in list(frames.get('camera', ()))[:MAX_FRAMES]],
            'reference_child_frame': None if child is None else bounded(child)}


def _drops(dropped: dict) -> dict:
    return {k: int(v) for k, v in dropped.items() if v}


def read_record(data: dict) -> dict:
    """
    Return THE summary of what was read and dropped, JSON-ready (``input.read`` of every tool).

    Parameters
    ----------
    data : dict
        The result of :func:`~strapdown_ros.recording.reader.read_bag`.

    Returns
    -------
    dict
        ``messages`` {topic: messages read}; ``gyro`` and ``reference``: ``topic``,
        ``received``, ``kept``, ``dropped`` {reason: n} (reasons with a count only), ``gaps``,
        ``missing``, ``dropouts``, ``bursts``, ``resyncs`` (the reference adds ``normalised``,
        ``covariance_substituted`` and ``bad_covariance`` {reason: n}); ``rate_samples`` (Imu
        input: ``received``, ``kept``, ``dropped``, ``gaps``, ``intervals_not_integrated``,
        ``resyncs``) or None; ``frames`` {``gyro``, ``reference``: {frame id: messages}}.

    """
    g, c = data['gyro'], data['camera']
    fx = data.get('camera_fixes') or {}
    rs = data.get('rate_samples')
    frames = data.get('frame_counts') or {k: dict.fromkeys(v)
                                          for k, v in (data.get('frames') or {}).items()}
    return {
        'messages': dict(data.get('messages_read') or {}),
        'gyro': {'topic': data['gyro_topic'], 'received': int(g.received),
                 'kept': len(g.stamps), 'dropped': _drops(g.dropped),
                 'gaps': int(g.check.gaps), 'missing': int(g.missing),
                 'dropouts': int(g.check.dropouts), 'bursts': int(g.check.bursts),
                 'resyncs': int(g.resyncs)},
        'rate_samples': None if not rs else {
            'received': int(rs['received']), 'kept': int(rs['accepted']),
            'dropped': _drops(rs['dropped']), 'gaps': int(rs.get('gaps', 0)),
            'intervals_not_integrated': int(rs['intervals_not_integrated']),
            'resyncs': int(rs.get('resyncs', 0))},
        'reference': {'topic': data['camera_topic'], 'received': int(c.received),
                      'kept': len(c.stamps), 'dropped': _drops(c.dropped),
                      'bad_covariance': _drops(fx.get('bad_covariance_reasons') or {}),
                      'normalised': int(fx.get('normalised', 0)),
                      'covariance_substituted': int(fx.get('covariance_substituted', 0)),
                      'dropouts': int(c.check.dropouts), 'resyncs': int(c.resyncs)},
        'frames': {'gyro': dict(frames.get('gyro') or {}),
                   'reference': dict(frames.get('camera') or {})},
    }


def read_lines(read: dict) -> list[str]:
    """
    Return the printed lines of :func:`read_record`: the same wording in every tool.

    Parameters
    ----------
    read : dict
        The record of :func:`read_record`.

    Returns
    -------
    list of str
        ``  read: …``, ``  gyro: …`` (and ``  gyro rate samples: …``), ``  reference: …``,
        ``  frames: …``; every echoed name bounded.

    """
    def dropped(d, detail=None):
        parts = [f'{k.replace("_", " ")} {v}' for k, v in d.items()]
        if detail:
            parts = [p + (' (' + ', '.join(f'{k.replace("_", " ")} {v}'
                                           for k, v in detail.items()) + ')'
                          if p.startswith('bad covariance') else '') for p in parts]
        return 'dropped ' + (', '.join(parts) if parts else 'none')

    msgs = read.get('messages') or {}
    lines = ['  read: ' + (bounded_list(f'{t} {n}' for t, n in msgs.items()) + ' message(s)'
                           if msgs else 'no messages')]
    rs = read.get('rate_samples')
    if rs:
        lines.append(f"  gyro rate samples: {rs['kept']} of {rs['received']} kept; "
                     f"{dropped(rs['dropped'])}; gaps {rs['gaps']} "
                     f"({rs['intervals_not_integrated']} interval(s) not integrated); "
                     f"resyncs {rs['resyncs']}")
    g = read['gyro']
    extra = ''.join(f', {k} {g[k]}' for k in ('dropouts', 'bursts') if g.get(k))
    lines.append(f"  gyro: {g['kept']} of {g['received']} "
                 f"{'increments' if rs else 'messages'} kept; {dropped(g['dropped'])}; "
                 f"gaps {g['gaps']} ({g['missing']} missing){extra}; resyncs {g['resyncs']}")
    r = read['reference']
    notes = ''.join(f'; {k.replace("_", " ")} {r[k]}'
                    for k in ('normalised', 'covariance_substituted') if r.get(k))
    extra = f", dropouts {r['dropouts']}" if r.get('dropouts') else ''
    lines.append(f"  reference: {r['kept']} of {r['received']} fixes kept; "
                 f"{dropped(r['dropped'], r.get('bad_covariance'))}{notes}{extra}; "
                 f"resyncs {r['resyncs']}")
    fr = read.get('frames') or {}

    def frame_list(d):
        return bounded_list((f'{bounded(f)!r} {n}' if n is not None else repr(bounded(f)))
                            for f, n in sorted(d.items(), key=lambda x: -(x[1] or 0)))
    lines.append(f"  frames: gyro {frame_list(fr.get('gyro') or {})}; reference "
                 f"{frame_list(fr.get('reference') or {})}")
    return lines


def frame_warnings(prog: str, data: dict, frame_id: str, reference_frame_id: str) -> list[str]:
    """
    Return ``warning:`` lines for header frame ids the model does not expect (used, not refused).

    Parameters
    ----------
    prog : str
        Tool name, the lines' prefix.
    data : dict
        The result of :func:`~strapdown_ros.recording.reader.read_bag`, or the record of
        :func:`input_summary`.
    frame_id, reference_frame_id : str
        The model's frames of the gyro and of the reference.

    Returns
    -------
    list of str
        One bounded line per stream with other frames.

    """
    out = []
    if data.get('read'):                       # an input_summary record
        fr = data['read'].get('frames') or {}
        counts = {'gyro': fr.get('gyro') or {}, 'camera': fr.get('reference') or {}}
    else:
        counts = data.get('frame_counts') or {}
    for kind, name, want in (('gyro', 'gyro', frame_id), ('camera', 'reference',
                                                          reference_frame_id)):
        seen = counts.get(kind) or dict.fromkeys((data.get('frames') or {}).get(kind, ()))
        other = {f: n for f, n in seen.items() if f and f != bounded(want, 200)}
        if other:
            listed = bounded_list(f'{bounded(f)!r}' + (f' ({n})' if n is not None else '')
                                  for f, n in other.items())
            out.append(f'{prog}: warning: {name} messages in frame {listed}, the model expects '
                       f'{bounded(want)!r} (used)')
    return out


def usable_error(data: dict, min_gyro: int = 2, min_fixes: int = 1) -> str | None:
    """
    Return the one error of a recording with too little usable in a stream, or None.

    Parameters
    ----------
    data : dict
        The result of :func:`~strapdown_ros.recording.reader.read_bag`.
    min_gyro, min_fixes : int
        The fewest gyro increments and reference fixes the tool can use.

    Returns
    -------
    str or None
        E.g. ``no usable reference fixes on /star_camera/attitude: 0 of 60 kept (dropped nan
        60)``.

    """
    for key, what, topic, least in (('gyro', 'gyro increments', data['gyro_topic'], min_gyro),
                                    ('camera', 'reference fixes', data['camera_topic'],
                                     min_fixes)):
        a = data[key]
        if len(a.stamps) < least:
            d = _drops(a.dropped)
            why = ', '.join(f'{k} {v}' for k, v in d.items()) or 'none dropped'
            return (f'no usable {what} on {bounded(topic)}: {len(a.stamps)} of {a.received} '
                    f'kept, {least} needed ({why})')
    return None


def input_summary(data: dict) -> dict:
    """
    Return what was read and how, JSON-ready (the ``input`` record of the tools).

    Parameters
    ----------
    data : dict
        The result of :func:`read_bag`.

    Returns
    -------
    dict
        gyro and reference topics and types, ``gyro_input`` (``delta_theta`` | ``rates``), the
        rate rule and rate-sample counts, the TF frames, ``reference_covariance``
        (``from_messages`` | ``from_model`` | ``mixed``) and ``unread_messages`` {topic: n}.

    """
    return {
        'gyro_topic': data['gyro_topic'],
        'gyro_type': data['gyro_type'],
        'gyro_input': data['gyro_input'],
        'rate_rule': data['rate_rule'],
        'rate_samples': data['rate_samples'],
        'reference_topic': data['camera_topic'],
        'reference_type': data['reference_type'],
        'reference_frames': data['reference_frames'],
        'reference_covariance': data['reference_covariance'],
        'unread_messages': dict(data['unread_messages']),
        'gyro_clip': dict(data.get('gyro_clip') or {}),
        'read': read_record(data),
    }


def input_warnings(prog: str, info: dict) -> list[str]:
    """
    ``WARNING:`` lines for stderr about the input (:func:`input_summary` or :func:`read_bag`).

    Parameters
    ----------
    prog : str
        Tool name, the lines' prefix.
    info : dict
        Holds ``unread_messages`` and ``rate_samples``.

    Returns
    -------
    list of str
        One line per problem found, bounded in length; empty when there is nothing to say.

    """
    out = []
    unread = info.get('unread_messages') or {}
    if unread:
        parts = bounded_list(f'{t}: {n:+d}' for t, n in sorted(unread.items()))
        out.append(
            f"{prog}: WARNING: the messages read differ from the bag's own index (index − read: "
            f'{parts}): a corrupt or skipped chunk hides data; the result may be biased'
        )
    clip = info.get('gyro_clip') or {}
    if clip.get('count'):
        text = clip_text(clip['count'], clip['largest'], clip['parameter'], clip['limit'],
                         clip['unit'])
        out.append(f'{prog}: WARNING: gyro: {text}')
    rs = info.get('rate_samples')
    if rs:
        dropped = {k: v for k, v in rs['dropped'].items() if v}
        if dropped or rs['intervals_not_integrated']:
            out.append(
                f'{prog}: WARNING: gyro rate samples: dropped '
                f"{', '.join(f'{k} {v}' for k, v in dropped.items()) or 'none'}; "
                f"{rs['intervals_not_integrated']} interval(s) not integrated (gaps)"
            )
    return out


def input_lines(info: dict) -> list[str]:
    """
    Summary lines (stdout) saying what was read and how.

    Parameters
    ----------
    info : dict
        The record of :func:`input_summary`.

    Returns
    -------
    list of str
        One or two indented lines.

    """
    short = {t: t.rsplit('/', 1)[-1] for t in (info['gyro_type'], info['reference_type'])}
    if info['gyro_input'] == 'rates':
        rs = info['rate_samples']
        gyro = (
            f"{rs['accepted']} of {rs['received']} {short[info['gyro_type']]} rate samples on "
            f"{bounded(info['gyro_topic'])} → increments by the {info['rate_rule']} rule"
        )
    else:
        gyro = f"Δθ ({short[info['gyro_type']]}) on {bounded(info['gyro_topic'])}"
    ref = f"reference {short[info['reference_type']]} on {bounded(info['reference_topic'])}"
    fr = info.get('reference_frames')
    if fr:
        ref += f" ({bounded(fr['parent'])}→{bounded(fr['child'])}, {fr['transform']})"
    cov = {
        'from_messages': 'covariance from the messages',
        'from_model': 'σ from the model',
        'mixed': 'covariance from the messages, σ from the model where they have none',
    }
    lines = [f"  input: {gyro}; {ref}, {cov[info['reference_covariance']]}"]
    if info.get('read'):
        lines += read_lines(info['read'])
    if info.get('unread_messages'):
        lines.append(
            '  UNREAD: '
            + bounded_list(f'{t} {n:+d}' for t, n in sorted(info['unread_messages'].items()))
            + " message(s) in the bag's index but not returned by the reader (corrupt chunk?)"
        )
    return lines


# --- command-line options ------------------------------------------------------------------------
def add_input_arguments(parser) -> None:
    """
    Add ``--gyro-topic``, ``--reference-topic``, ``--reference-frames``, ``--rate-rule``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The tool's parser (an argument group is added to it).

    """
    g = parser.add_argument_group('input topics and formats')
    g.add_argument(
        '--gyro-topic',
        metavar='TOPIC',
        help=f'gyro topic: {DELTA_THETA_TYPE} increments or {IMU_TYPE} rates, by its type in the '
        f'bag (default {GYRO_TOPIC} under --namespace, else the one Imu topic of the bag)',
    )
    g.add_argument(
        '--reference-topic',
        metavar='TOPIC',
        help='attitude reference topic (q_ref_body): QuaternionStamped, PoseStamped, '
        'TransformStamped, PoseWithCovarianceStamped, nav_msgs/Odometry or tf2_msgs/TFMessage '
        '(default: '
        f'{CAMERA_COV_TOPIC} or {CAMERA_TOPIC}, else the one topic of these types; /tf with '
        '--reference-frames)',
    )
    g.add_argument(
        '--reference-frames',
        nargs=2,
        metavar=('PARENT', 'CHILD'),
        help='TF reference: transforms PARENT→CHILD (or the inverse of CHILD→PARENT)',
    )
    g.add_argument(
        '--rate-rule',
        choices=RATE_RULES,
        default='trapezoid',
        help='increments from Imu rate samples: trapezoid (rate at the stamp; default) or mean '
        '(mean rate over the interval ending at the stamp)',
    )


def check_input_arguments(args) -> None:
    """
    Check the input options before any work.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed options of :func:`add_input_arguments`.

    Raises
    ------
    ValueError
        One line: an empty topic name, empty or identical ``--reference-frames``.

    """
    for opt, v in (('--gyro-topic', args.gyro_topic), ('--reference-topic', args.reference_topic)):
        if v is not None and not v.strip('/').strip():
            raise ValueError(f'{opt} must name a topic, got {bounded(v)!r}')
    if args.reference_frames:
        parent, child = (f.lstrip('/') for f in args.reference_frames)
        if not parent or not child:
            raise ValueError('--reference-frames PARENT CHILD must be two frame names')
        if parent == child:
            raise ValueError(
                f'--reference-frames: PARENT and CHILD are the same frame {bounded(parent)!r}'
            )


def input_options(args) -> dict:
    """
    Keyword arguments of :func:`~strapdown_ros.recording.reader.read_bag` from the options.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed options of :func:`add_input_arguments`.

    Returns
    -------
    dict
        ``gyro_topic``, ``reference_topic``, ``reference_frames`` (tuple or None), ``rate_rule``.

    """
    return {
        'gyro_topic': args.gyro_topic,
        'reference_topic': args.reference_topic,
        'reference_frames': tuple(args.reference_frames) if args.reference_frames else None,
        'rate_rule': args.rate_rule,
    }
