"""
Model files: one ROS 2 parameter file holds a unit's sensor model and the nodes' settings.

:func:`load_model_file` reads one into the typed
:class:`~strapdown_ros.sensors.sensor_model.SensorModel` every node and command applies, plus the
validated settings of one node; :func:`write_model_file` writes a model back with the same keys
(each value with the rule that produced it as a comment); :func:`model_from_parameters` builds the
same model from a node's declared ROS parameters; :func:`check_against_recording` refuses a model
whose stated rate or frames contradict a recording.  No ROS imports.

The rules of a model file:

* Blocks: ``/**`` (every node) and the blocks of the package's nodes
  (:data:`~strapdown_ros.params.tables.NODE_PARAMS`), with or without a leading ``/``.
* A **model key** (:func:`~strapdown_ros.sensors.sensor_model.model_keys`: rates, frames, clip
  levels, noise, every registry effect's value and σ, the boresight and ``augment``) describes
  the unit, so it has one value in the whole file: the same key with two different values in
  two blocks is an error naming both.
* Any other key is a **setting** of the node whose block holds it (``/**``: of every node that
  declares it).  A setting of another node is checked by that node's table and not used.
* A key no node declares is refused by name, with the nearest known name.  A renamed key
  (:data:`~strapdown_ros.sensors.sensor_model.MODEL_ALIASES`) is accepted under its old name,
  with a warning.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import json
import re

import numpy as np

from strapdown_ros.files import atomic_write_text
from strapdown_ros.params.spec import load_parameter_file, ParamSpec
from strapdown_ros.params.tables import (ALIAS_PARAMS, IMU_SIM_PARAMS, NODE_PARAMS,
                                         NODE_SETTINGS, spec_of, STAR_CAMERA_PARAMS)
from strapdown_ros.params.validation import check_all, combination_error
from strapdown_ros.sensors.sensor_model import (key_group, MODEL_ALIASES, model_keys,
                                                nearest_key, SensorModel)
from strapdown_ros.text import bounded

__all__ = ['ModelFile', 'load_model_file', 'model_of_document', 'write_model_file',
           'model_from_parameters', 'settings_from_parameters', 'model_and_settings',
           'check_against_recording', 'filled_in', 'not_applied_note', 'simulator_parameters',
           'MODEL_BLOCK',
           'RATE_TOLERANCE']

#: the block a written model puts its keys in
MODEL_BLOCK = '/**'
#: ``    key: value  # rule`` in a model file
_COMMENTED = re.compile(r'^\s+([A-Za-z_]\w*)\s*:[^#]*\s#\s+(.+)$')
#: relative difference between a stated gyro_rate and the rate of a recording's stamps beyond
#: which the two contradict each other
RATE_TOLERANCE = 0.1


@dataclass
class ModelFile:
    """
    What a model file gave: the sensor model, one node's settings, the warnings.

    Attributes
    ----------
    model : SensorModel
        The unit's model (defaults where the file is silent; ``stated`` names the keys given).
    settings : dict
        The validated settings of the node asked for (every one of its non-model parameters,
        defaults filled); empty when no node was asked for.
    warnings : list of str
        Deprecated names used, one line each.
    doc : dict
        The parsed document (the writer keeps its other blocks' settings).
    path : str or None
        The file.

    """

    model: SensorModel
    settings: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    doc: dict = field(default_factory=dict)
    path: str | None = None


def _model_specs() -> dict[str, ParamSpec]:
    return {k.name: spec_of(k) for k in model_keys()}


def _setting_specs() -> dict[str, dict[str, ParamSpec]]:
    """Node → its setting specs (the non-model parameters every node of the package declares)."""
    model = {k.name for k in model_keys()}
    alias = {s.name for s in ALIAS_PARAMS}
    return {node: {s.name: s for s in specs if s.name not in model and s.name not in alias}
            for node, specs in NODE_PARAMS.items()}


def _read_doc(path: str | None) -> dict:
    import yaml

    if path is None:
        return {}
    try:
        with open(path, 'r', encoding='utf-8') as fh:
            doc = yaml.safe_load(fh)
    except yaml.YAMLError as exc:
        raise ValueError(f'{path}: not valid YAML ({str(exc).splitlines()[0]})') from None
    except OSError as exc:
        raise ValueError(f'{path}: {exc.strerror or exc}') from None
    except UnicodeDecodeError:
        raise ValueError(f'{path}: not a UTF-8 text file') from None
    if doc is None:
        return {}
    if not isinstance(doc, dict):
        raise ValueError(f'{path}: expected a ROS 2 parameter file (a mapping of node names to '
                         'ros__parameters)')
    return doc


def _blocks(doc: dict, path) -> list[tuple[str, dict]]:
    """Return the blocks of a document in merge order, as (node or '/**', parameters)."""
    nodes = list(NODE_PARAMS)
    order = {'/**': '/**', '**': '/**'}
    order.update({n: n for n in nodes})
    order.update({'/' + n: n for n in nodes})
    for key in doc:
        if key not in order:
            raise ValueError(f'{path}: block {str(key)[:80]!r} names no node of the package '
                             f"(known: /**, {', '.join(nodes)}){nearest_key(key, order)}")
    out = []
    for key in ['/**', '**'] + [k for n in nodes for k in (n, '/' + n)]:
        block = doc.get(key)
        if block is None:
            continue
        params = block.get('ros__parameters') if isinstance(block, dict) else None
        if not isinstance(block, dict) or not isinstance({} if params is None else params, dict):
            raise ValueError(f"{path}: block {key!r} must hold a 'ros__parameters' mapping")
        out.append((order[key], dict(params or {})))
    return out


def _same(a, b) -> bool:
    if isinstance(a, (list, tuple)) or isinstance(b, (list, tuple)):
        return np.shape(a) == np.shape(b) and bool(np.all(np.asarray(a) == np.asarray(b)))
    return a == b


def load_model_file(path: str | None, node: str | None = None,
                    overrides: dict | None = None, source: str | None = None) -> ModelFile:
    """
    Read a model file into the sensor model and one node's settings.

    Parameters
    ----------
    path : str or None
        The ROS 2 parameter file (None: every default).
    node : str, optional
        The node whose settings are wanted (a key of ``NODE_SETTINGS``), e.g.
        ``'attitude_filter_node'`` for ``filter_bag``.
    overrides : dict, optional
        ``-p NAME:=VALUE`` values: they win over the file, model keys and settings alike.
    source : str, optional
        The model's source for reports (default: the path).

    Returns
    -------
    ModelFile
        The model, the node's settings, the warnings and the document.

    Raises
    ------
    ValueError
        One line: an unreadable file, a block naming no node, a key no node declares (with the
        nearest known name), an invalid value, a model key with two values, a broken rule
        between parameters.

    """
    mf = model_of_document(_read_doc(path), path, node, overrides, source)
    rules = _comment_rules(path)
    if rules:                   # a written model keeps the rule behind each value
        prov = dict(mf.model.provenance)
        prov.update({k: r for k, r in rules.items()
                     if k in mf.model.stated and prov.get(k, '').startswith('stated in')})
        mf.model = SensorModel.from_values(mf.model.values(), stated=mf.model.stated,
                                           provenance=prov, source=mf.model.source)
    return mf


def _comment_rules(path: str | None) -> dict:
    """Key → the comment after its value (the rule a writer put there), for each commented key."""
    if path is None:
        return {}
    out = {}
    try:
        with open(path, 'r', encoding='utf-8') as fh:
            for line in fh:
                m = _COMMENTED.match(line)
                if m:
                    out.setdefault(m.group(1), m.group(2).strip())
    except (OSError, UnicodeDecodeError):
        return {}
    return out


def model_of_document(doc: dict, path: str | None = None, node: str | None = None,
                      overrides: dict | None = None, source: str | None = None) -> ModelFile:
    """
    Read a parsed model file (:func:`load_model_file` after the YAML).

    Parameters
    ----------
    doc : dict
        The parsed ROS 2 parameter document.
    path : str or None
        Its file, named in the errors (None: ``model``).
    node : str, optional
        The node whose settings are wanted.
    overrides : dict, optional
        ``-p`` values that win over the document.
    source : str, optional
        The model's source for reports (default: the path).

    Returns
    -------
    ModelFile
        The model, the node's settings, the warnings and the document.

    """
    where = path or 'model'
    model_specs = _model_specs()
    setting_specs = _setting_specs()
    any_setting = {n: s for specs in setting_specs.values() for n, s in specs.items()}
    model_values: dict = {}
    given_in: dict = {}
    settings: dict = {}
    warnings: list = []
    blocks = _blocks(doc, where)
    if overrides:
        blocks.append(('-p', dict(overrides)))
    for block, params in blocks:
        for name, value in params.items():
            name = str(name)
            label = 'the -p overrides' if block == '-p' else f'block {block}'
            if name in MODEL_ALIASES:
                new = MODEL_ALIASES[name]
                warnings.append(f'{where}: {name} is the old name of {new}; read as {new}')
                if new in params:
                    raise ValueError(f'{where}: {label} gives both {name} and its new name {new}')
                name = new
            if name in model_specs:
                s = model_specs[name]
                v = s.normalise(value)
                err = s.check(v)
                if err:
                    raise ValueError(f'{where}: {err}')
                if name in model_values and block != '-p' and not _same(model_values[name], v):
                    raise ValueError(
                        f'{where}: {name} is {model_values[name]!r} in {given_in[name]} and '
                        f'{v!r} in {label}: a sensor model key has one value in the file')
                model_values[name] = v
                given_in[name] = label
                continue
            if block in ('/**', '-p'):
                owners = [n for n, specs in setting_specs.items() if name in specs]
            else:
                owners = [block] if name in setting_specs[block] else []
            if not owners:
                known = set(model_specs) | (set(any_setting) if block in ('/**', '-p')
                                            else set(setting_specs[block]))
                owner = 'any node' if block in ('/**', '-p') else block
                raise ValueError(f'{where}: {label}: {name[:80]!r} is not a parameter of '
                                 f'{owner} of the package{nearest_key(name, known)}')
            for owner in owners:
                s = setting_specs[owner][name]
                v = s.normalise(value)
                err = s.check(v)
                if err:
                    raise ValueError(f'{where}: {err}')
                if node is not None and owner == node:
                    settings[name] = v
    model = SensorModel.from_values(model_values, stated=set(model_values),
                                    provenance={k: f'stated in {given_in[k]} of {where}'
                                                if given_in[k] != 'the -p overrides'
                                                else 'given with -p' for k in model_values},
                                    source=source or (path or 'defaults'))
    out_settings = {}
    if node is not None:
        if node not in NODE_SETTINGS:
            raise ValueError(f'no settings table for {node!r}')
        out_settings = check_all(NODE_SETTINGS[node], settings)
        err = combination_error({**model.values(), **out_settings})
        if err:
            raise ValueError(f'{where}: {err}')
    return ModelFile(model, out_settings, warnings, doc, path)


def model_and_settings(node: str, values: dict | None = None) -> tuple[SensorModel, dict]:
    """
    Split parameter values into the sensor model and one node's settings (tests, benchmarks).

    Parameters
    ----------
    node : str
        The node whose settings are wanted.
    values : dict, optional
        Model keys and settings of any node, as in a model file's ``/**`` block.

    Returns
    -------
    (SensorModel, dict)
        The model, and the node's validated settings.

    """
    mf = model_of_document({'/**': {'ros__parameters': dict(values or {})}}, None, node,
                           source='parameters')
    return mf.model, mf.settings


def model_from_parameters(values: dict, source: str = 'ROS parameters'
                          ) -> tuple[SensorModel, list[str]]:
    """
    Build the sensor model from a node's declared, validated parameters (the nodes' edge).

    Parameters
    ----------
    values : dict
        The node's parameters: every model key (and the old names of renamed keys, −1 when not
        given), plus its settings (not read here).
    source : str
        The model's source for reports.

    Returns
    -------
    model : SensorModel
        The model.  Every key counts as stated (a node cannot tell a default from a value).
    warnings : list of str
        One line per old name given.

    Raises
    ------
    ValueError
        An invalid value.

    """
    names = {k.name for k in model_keys()}
    v = {k: values[k] for k in names if k in values}
    warnings = []
    for old, new in MODEL_ALIASES.items():
        if float(values.get(old, -1.0)) >= 0.0:
            warnings.append(f'{old} is the old name of {new}; read as {new}')
            v[new] = float(values[old])
    return SensorModel.from_values(v, stated=set(v), source=source), warnings


def settings_from_parameters(node: str, values: dict) -> dict:
    """
    Return a node's settings (its non-model parameters) from its declared parameters.

    Parameters
    ----------
    node : str
        The node (a key of ``NODE_SETTINGS``).
    values : dict
        Its validated parameters.

    Returns
    -------
    dict
        Setting name → value.

    """
    return {s.name: values[s.name] for s in NODE_SETTINGS[node] if s.name in values}


def check_against_recording(model: SensorModel, facts: dict) -> SensorModel:
    """
    Refuse a model whose stated rate or frames contradict a recording; fill in what it measured.

    Parameters
    ----------
    model : SensorModel
        The model read from a file.
    facts : dict
        What the recording shows: ``gyro_rate_hz`` (from the stamps), ``gyro_frames`` and
        ``reference_frames`` (the header frame ids seen), ``reference_child_frame`` (TF or
        Odometry), any of them None or absent.

    Returns
    -------
    SensorModel
        The model, with ``gyro_rate`` set from the stamps where the model does not state it.

    Raises
    ------
    ValueError
        One line naming the model's value and the recording's.

    """
    src = model.source or 'the model'
    rate = facts.get('gyro_rate_hz')
    if rate and 'gyro_rate' in model.stated \
            and abs(rate - model.gyro_rate) > RATE_TOLERANCE * model.gyro_rate:
        raise ValueError(f'gyro_rate {model.gyro_rate:g} Hz in {src} contradicts the recording: '
                         f'its gyro stamps step at {rate:.6g} Hz (state the right rate, or leave '
                         'gyro_rate out to take it from the stamps)')
    for key, fact in (('frame_id', 'gyro_frames'), ('reference_frame_id', 'reference_frames')):
        seen = [f for f in (facts.get(fact) or ()) if f]
        if key in model.stated and seen and getattr(model, key) not in seen:
            raise ValueError(f'{key} {bounded(getattr(model, key))!r} in {bounded(src)} '
                             'contradicts the recording: its messages say '
                             f"{', '.join(repr(bounded(f)) for f in seen[:3])} "
                             f'(state the right frame, or leave {key} out)')
    child = facts.get('reference_child_frame')
    if child and 'camera_frame_id' in model.stated and model.camera_frame_id != child:
        raise ValueError(f'camera_frame_id {bounded(model.camera_frame_id)!r} in {bounded(src)} '
                         'contradicts the recording: its reference gives the attitude of '
                         f'{bounded(child)!r}')
    if rate and 'gyro_rate' not in model.stated:
        model = model.with_values({'gyro_rate': float(rate)},
                                  rule='the median step of the gyro stamps')
    return model


def filled_in(before: SensorModel, after: SensorModel) -> list[str]:
    """
    Return one line per model key :func:`check_against_recording` took from the recording.

    Parameters
    ----------
    before, after : SensorModel
        The model as read, and as checked against the recording.

    Returns
    -------
    list of str
        E.g. ``gyro_rate 200 Hz: the median step of the gyro stamps``.

    """
    out = []
    a, b = before.values(), after.values()
    for k in b:
        if a.get(k) != b[k]:
            unit = next((x.unit for x in model_keys() if x.name == k), '')
            v = b[k]
            text = f'{v:.6g}' if isinstance(v, float) else bounded(v)
            out.append(f"{k} {text}{' ' + unit if unit and unit != '1' else ''}: "
                       f"{after.provenance.get(k, 'from the recording')}")
    return out


def not_applied_note(model: SensorModel, groups, who: str) -> str | None:
    """
    Return the note naming the stated model keys a consumer does not apply, or None.

    Parameters
    ----------
    model : SensorModel
        The model.
    groups : iterable of str
        What the consumer applies (:func:`~strapdown_ros.sensors.sensor_model.key_group`).
    who : str
        The consumer, for the text.

    Returns
    -------
    str or None
        E.g. ``the model states boresight, camera_time_offset, which sins_bag does not apply
        (no reference input)``.

    """
    keys = model.not_applied(groups)
    if not keys:
        return None
    why = {'accel': 'no accelerometer input', 'reference': 'no reference input',
           'filter': 'no online estimation'}
    missing = sorted({key_group(k) for k in keys})
    shown = ', '.join(keys[:8]) + (f', … ({len(keys)} keys)' if len(keys) > 8 else '')
    return (f'the model states {shown}, which {who} does not apply '
            f"({'; '.join(why.get(g, g) for g in missing)})")


def _yaml_value(v) -> str:
    import yaml

    text = yaml.safe_dump(v, default_flow_style=True, allow_unicode=True, width=10**6)
    return text.strip().removesuffix('...').strip()


def write_model_file(path: str, model: SensorModel, comment: str, doc: dict | None = None,
                     keys=None, setting_rules: dict | None = None) -> None:
    """
    Write a sensor model as a model file, atomically; each value with its rule as a comment.

    The model's keys go into ``/**`` (so that every node reads the same value); the settings of
    ``doc``'s blocks are kept, and model keys are removed from the node blocks (so that none
    overrides the new value).  :func:`load_model_file` reads it back to the same model.

    Parameters
    ----------
    path : str
        The file.
    model : SensorModel
        The model to write.
    comment : str
        The first line's comment (without ``#``); may hold several lines.
    doc : dict, optional
        The document the model was read from (its settings are kept).
    keys : iterable of str, optional
        The model keys to write (default: the stated ones and every key that is not at its
        default, in key order).
    setting_rules : dict, optional
        Setting name → the rule that produced it, written as its comment.

    """
    values = model.values()
    wanted = set(keys) if keys is not None else (set(model.stated)
                                                 | set(model.differs_from_default()))
    model_names = {k.name for k in model_keys()}
    lines = [f'# {line}' for line in str(comment).splitlines() or ['']]
    lines += ['/**:', '  ros__parameters:']
    settings_root = {}
    doc = json.loads(json.dumps(doc or {}))             # a deep copy of plain data
    for key in ('/**', '**'):
        settings_root.update({k: v for k, v in
                              ((doc.get(key) or {}).get('ros__parameters') or {}).items()
                              if k not in model_names and k not in MODEL_ALIASES})
    for k in (k.name for k in model_keys()):
        if k not in wanted:
            continue
        rule = model.provenance.get(k)
        note = f'  # {rule}' if rule else ''
        lines.append(f'    {k}: {_yaml_value(values[k])}{note}'.rstrip())
    notes = setting_rules or {}

    def setting_line(k, v):
        note = f'  # {notes[k]}' if k in notes else ''
        return f'    {k}: {_yaml_value(v)}{note}'
    for k, v in settings_root.items():
        lines.append(setting_line(k, v))
    for key, block in doc.items():
        if key in ('/**', '**') or not isinstance(block, dict):
            continue
        params = {k: v for k, v in (block.get('ros__parameters') or {}).items()
                  if k not in model_names and k not in MODEL_ALIASES}
        if not params:
            continue
        lines += [f'{_yaml_value(key)}:', '  ros__parameters:']
        lines += [setting_line(k, v) for k, v in params.items()]
    atomic_write_text(path, '\n'.join(lines) + '\n')


# ------------------------------------------------------------------ the simulators
def simulator_parameters(params_file: str | None = None, overrides: dict | None = None,
                         duration: float | None = None) -> tuple[dict, dict]:
    """
    Return the validated parameters of imu_sim_node and star_camera_sim_node.

    Parameters
    ----------
    params_file : str or None
        A ROS 2 parameter file (None: defaults, profile ``bench``).
    overrides : dict or None
        Parameter values that win over the file (both nodes).
    duration : float or None
        Simulated seconds (both nodes), or None for the file's value.

    Returns
    -------
    (dict, dict)
        The parameters of imu_sim_node and of star_camera_sim_node.

    Raises
    ------
    ValueError
        An invalid value, naming the valid ones.

    """
    imu_raw, cam_raw = {'profile': 'bench'}, {'profile': 'bench'}
    if params_file:
        imu_raw.update(load_parameter_file(params_file, 'imu_sim_node'))
        cam_raw.update(load_parameter_file(params_file, 'star_camera_sim_node'))
    for raw in (imu_raw, cam_raw):
        raw.update(overrides or {})
        if duration is not None:
            raw['duration'] = float(duration)
    return check_all(IMU_SIM_PARAMS, imu_raw), check_all(STAR_CAMERA_PARAMS, cam_raw)
