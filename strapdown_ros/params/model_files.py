"""
Model files: the nominal model of a recording as one ROS 2 parameter file of every node.

:func:`load_model` reads and validates one, :func:`write_model` writes one back (the
calibration and discrepancy tools write their estimates into it), and
:func:`simulator_parameters` gives the validated parameters of the two simulators.
No ROS imports.
"""
from __future__ import annotations

import json

from strapdown_ros.files import atomic_write_text
from strapdown_ros.params.spec import load_parameter_file, ParamSpec
from strapdown_ros.params.tables import IMU_SIM_PARAMS, NODE_PARAMS, STAR_CAMERA_PARAMS
from strapdown_ros.params.validation import check_all


def load_model(path: str | None) -> tuple[dict, dict]:
    """
    Read a nominal model from a ROS 2 parameter file of the package's nodes.

    The ``/**`` block and the blocks of the package's nodes are merged (``/**`` first, then
    imu_sim_node, star_camera_sim_node, sins_node, calibrator_node), every key validated by the
    node that declares it.

    Parameters
    ----------
    path : str or None
        The parameter file (None: every default).

    Returns
    -------
    (dict, dict)
        ``values``: every parameter of every node (defaults where the file is silent), and
        ``raw``: the parsed document.

    Raises
    ------
    ValueError
        Naming a key that no node of the package knows, a block that names no node, or an
        invalid value.

    """
    import yaml

    try:
        if path is None:                      # no file: every default
            doc = {}
        else:
            with open(path, 'r', encoding='utf-8') as fh:
                doc = yaml.safe_load(fh)
    except yaml.YAMLError as exc:
        raise ValueError(f'{path}: not valid YAML ({str(exc).splitlines()[0]})') from None
    except OSError as exc:
        raise ValueError(f'{path}: {exc.strerror or exc}') from None
    if doc is None:
        doc = {}
    if not isinstance(doc, dict):
        raise ValueError(
            f'{path}: expected a ROS 2 parameter file '
            '(a mapping of node names to ros__parameters)')
    specs: dict[str, ParamSpec] = {}
    for lst in NODE_PARAMS.values():
        for s in lst:
            specs.setdefault(s.name, s)
    merged: dict = {}
    order = ['/**', '**'] + [n for node in NODE_PARAMS for n in (node, '/' + node)]
    for key in doc:
        if key not in order:
            raise ValueError(f'{path}: block {key!r} names no node of the package '
                             f"(known: /**, {', '.join(NODE_PARAMS)})")
    for key in order:
        block = doc.get(key)
        if block is None:
            continue
        if not isinstance(block, dict) or not isinstance(block.get('ros__parameters', {}), dict):
            raise ValueError(f"{path}: block {key!r} must hold a 'ros__parameters' mapping")
        for name, value in (block.get('ros__parameters') or {}).items():
            if name not in specs:
                raise ValueError(
                    f'{path}: model key {name!r} is not a parameter of any node of the package')
            err = specs[name].check(specs[name].normalise(value))
            if err:
                raise ValueError(f'{path}: {err}')
            merged[name] = specs[name].normalise(value)
    values = {n: s.default for n, s in specs.items()}
    values.update(merged)
    return values, doc


def write_model(path: str, doc: dict | None, updates: dict, comment: str) -> None:
    """
    Write a model file with ``updates`` set, atomically.

    ``updates`` are set in ``/**`` and in every node block that sets the same key (so the block
    does not override the new value); the file starts with a ``# comment`` line.  Plain copies:
    no YAML anchors.

    Parameters
    ----------
    path : str
        The model file to write.
    doc : dict or None
        The parsed parameter document (not modified).
    updates : dict
        Parameter name → new value (plain JSON values).
    comment : str
        The first line's comment, without ``#``.

    """
    import yaml

    doc = json.loads(json.dumps(doc or {}))                   # a deep copy of plain data
    root = doc.setdefault('/**', {}).setdefault('ros__parameters', {})
    for name, value in updates.items():
        root[name] = json.loads(json.dumps(value))
        for key, block in doc.items():
            sets_it = isinstance(block, dict) and name in (block.get('ros__parameters') or {})
            if key != '/**' and sets_it:
                block['ros__parameters'][name] = json.loads(json.dumps(value))
    atomic_write_text(path, f'# {comment}\n'
                      + yaml.safe_dump(doc, sort_keys=False, allow_unicode=True))


def node_parameters(node: str, specs, params_file: str | None = None,
                    overrides: dict | None = None) -> dict:
    """
    Return the validated parameters of one node, as an offline tool reads them.

    Parameters
    ----------
    node : str
        The node's name: its block of the parameter file (``/**`` applies too).
    specs : list of ParamSpec
        The node's parameter declarations (e.g. ``SINS_PARAMS``).
    params_file : str or None
        A ROS 2 parameter file (None: the defaults).
    overrides : dict or None
        Values that win over the file (name → value).

    Returns
    -------
    dict
        Every parameter of the node, name → checked value.

    Raises
    ------
    ValueError
        An invalid value, naming the valid ones.

    """
    raw = load_parameter_file(params_file, node) if params_file else {}
    raw.update(overrides or {})
    return check_all(specs, raw)


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
