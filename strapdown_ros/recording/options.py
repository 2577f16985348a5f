"""
Command-line options and reports of the input of the offline tools (:mod:`.reader`).

``add_input_arguments`` makes ``--gyro-topic``, ``--reference-topic``, ``--reference-frames`` and
``--rate-rule`` once for every tool; ``input_summary``, ``input_lines`` and ``input_warnings`` say
what was read and how (JSON, stdout, stderr).
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
        f'bag (default {GYRO_TOPIC} under --namespace)',
    )
    g.add_argument(
        '--reference-topic',
        metavar='TOPIC',
        help='attitude reference topic (q_ref_body): QuaternionStamped, PoseStamped, '
        'PoseWithCovarianceStamped, nav_msgs/Odometry or tf2_msgs/TFMessage (default: '
        f'{CAMERA_COV_TOPIC} or {CAMERA_TOPIC}; /tf with --reference-frames)',
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
