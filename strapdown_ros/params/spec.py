"""
The parameter declaration: :class:`ParamSpec` and the readers of parameter files.

One :class:`ParamSpec` per parameter holds its default, meaning and valid values; the nodes
declare them as ROS parameters (``nodes/ros_io.py``), the offline tools read them from the
same ROS 2 parameter YAML file (:func:`load_parameter_file`, :func:`parse_overrides`) and
:func:`markdown_table` renders the tables of doc/nodes.md.  No ROS imports.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np


@dataclass(frozen=True)
class ParamSpec:
    """
    One parameter: default, unit and meaning, and its validation (range or choices).

    Parameters
    ----------
    name : str
        The ROS parameter name.
    default : bool, int, float, str or list of float
        Default value; its type is the parameter's type.
    description : str
        Meaning and unit (the table's "meaning" column).
    minimum, maximum : float or None
        Range of a number (None: unbounded).
    choices : sequence of str or None
        The valid names of a string parameter.
    exclusive_minimum : bool
        ``minimum`` itself is invalid.
    exclusive_maximum : bool
        ``maximum`` itself is invalid.
    length : int or None
        Length of an array parameter.
    element_ranges : tuple of (float or None, float or None), optional
        Arrays: (minimum, maximum) of each element, instead of minimum/maximum.
    element_names : tuple of str, optional
        Arrays: the names of the elements in the range text (e.g. ``('latitude °', ...)``).

    """

    name: str
    default: Any
    description: str
    minimum: float | None = None
    maximum: float | None = None
    choices: Sequence[str] | None = None
    exclusive_minimum: bool = False
    length: int | None = None            # arrays of fixed length
    #: arrays: (minimum, maximum) of each element (None: no bound), instead of minimum/maximum
    element_ranges: tuple | None = None
    #: the unit of the element ranges' text (e.g. ("°", "°", "m"))
    element_names: tuple | None = None
    exclusive_maximum: bool = False

    def normalise(self, value):
        """
        Return ``value`` in the type of the parameter, as the command line means it.

        Choices are strings; a name like ``2`` or ``3.1`` given unquoted on the command line
        (``-p coning_algorithm:=2``) arrives as a number and is read as its spelling (``2.0``
        stays ``"2.0"``, which is no name: refused, as an integer given a fraction is).
        A double array given as integers (``[0, 0, 9]``) or as the ``array('d')`` rclpy returns
        is read as a list of doubles; a double given as an integer as a double; an integer given
        as an integral double (``5.0``) as an integer; a number given as text that YAML did not
        read as one (``1.0e9``: YAML 1.1 wants ``1.0e+9``) as that number.

        Parameters
        ----------
        value : object
            The value as given (YAML, command line or rclpy).

        Returns
        -------
        object
            The value to check and use.

        """
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        numeric_default = (isinstance(self.default, (int, float))
                           and not isinstance(self.default, bool))
        if self.choices is not None and number:
            return str(value)
        if self.length is not None and not isinstance(value, (str, bytes, dict)) \
                and hasattr(value, '__len__') \
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            return [float(v) for v in value]
        if numeric_default and isinstance(value, str):
            try:
                value = float(value.strip())
            except ValueError:
                return value
        if isinstance(self.default, float) and isinstance(value, int) \
                and not isinstance(value, bool):
            return float(value)
        if numeric_default and isinstance(self.default, int) and isinstance(value, float) \
                and value.is_integer():
            return int(value)
        return value

    def check(self, value) -> str | None:
        """
        Return an error message that names the valid values, or None when valid.

        Parameters
        ----------
        value : object
            A value (normalised by :meth:`normalise` for choices).

        Returns
        -------
        str or None
            One line naming the parameter, the value and the valid values.

        """
        if self.choices is not None:
            value = self.normalise(value)
            if value not in self.choices:
                valid = ', '.join(map(str, self.choices))
                return f'{self.name}={value!r} is not valid; valid values: {valid}'
            return None
        if self.length is not None:
            try:
                arr = np.asarray(value, dtype=float)
            except (TypeError, ValueError):
                return f'{self.name} must be a list of {self.length} numbers, got {value!r}'
            if arr.shape != (self.length,) or not np.all(np.isfinite(arr)):
                return f'{self.name} must be a list of {self.length} finite numbers, got {value!r}'
            if self.element_ranges is not None:
                for i, (v, (lo, hi)) in enumerate(zip(arr, self.element_ranges)):
                    if (lo is not None and v < lo) or (hi is not None and v > hi):
                        return (f'{self.name}[{i}]={float(v):.6g} is out of range; '
                                f'valid: {self.range_text()}')
                return None
            for i, v in enumerate(arr):                 # one range for every element
                err = self._range_error(float(v), f'{self.name}[{i}]')
                if err:
                    return err
            return None
        if isinstance(self.default, bool):
            if isinstance(value, bool):
                return None
            return f'{self.name} must be true or false, got {value!r}'
        if isinstance(self.default, (int, float)):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                return f'{self.name} must be a number, got {value!r}'
            if isinstance(self.default, int) and not isinstance(value, int):
                return f'{self.name} must be an integer, got {value!r}'
            if not np.isfinite(value):
                return f'{self.name} must be finite, got {value!r}'
            return self._range_error(value)
        if isinstance(self.default, str) and not isinstance(value, str):
            return (f'{self.name} must be a string, got {type(value).__name__} '
                    f'{str(value)[:80]!r} '
                    '(quote it in YAML)')
        return None

    def _range_error(self, value, label: str | None = None) -> str | None:
        lo, hi = self.minimum, self.maximum
        bad = (lo is not None and (value < lo or (self.exclusive_minimum and value <= lo))) or \
              (hi is not None and (value > hi or (self.exclusive_maximum and value >= hi)))
        if not bad:
            return None
        shown = f'{label}={value:.6g}' if label else f'{self.name}={value!r}'
        return f'{shown} is out of range; valid: {self.range_text()}'

    def range_text(self) -> str:
        """Return the valid values as text (the table's "valid" column and the error messages)."""
        if self.choices is not None:
            return ', '.join(map(str, self.choices))

        def num(v):
            return str(v) if isinstance(v, int) else f'{v:g}'
        parts = []
        if self.element_ranges is not None:
            names = self.element_names or tuple(f'[{k}]' for k in range(len(self.element_ranges)))
            return ', '.join(f'{n} in [{num(lo)}, {num(hi)}]'
                             for n, (lo, hi) in zip(names, self.element_ranges))
        if self.minimum is not None:
            parts.append(('> ' if self.exclusive_minimum else '>= ') + num(self.minimum))
        if self.maximum is not None:
            parts.append(('< ' if self.exclusive_maximum else '<= ') + num(self.maximum))
        if self.length is not None:
            parts.append(f'{self.length} finite numbers')
        return ' and '.join(parts) if parts else 'any'


def load_parameter_file(path: str, node_name: str) -> dict:
    """
    Read the parameters of ``node_name`` from a ROS 2 parameter YAML file.

    ``/**`` wildcard and exact node names are merged (exact names win), as the nodes would
    see them.

    Parameters
    ----------
    path : str
        The parameter file.
    node_name : str
        The node, without namespace.

    Returns
    -------
    dict
        Parameter name → value, not validated.

    Raises
    ------
    ValueError
        An unreadable file or not a mapping of node names, in one line.

    """
    import yaml

    try:
        with open(path, 'r', encoding='utf-8') as fh:
            doc = yaml.safe_load(fh) or {}
    except OSError as exc:
        raise ValueError(f'parameter file {path}: {exc.strerror or exc}') from None
    except yaml.YAMLError as exc:
        raise ValueError(
            f'parameter file {path}: not valid YAML ({str(exc).splitlines()[0]})') from None
    if not isinstance(doc, dict):
        raise ValueError(
            f'parameter file {path}: expected a mapping of node names to ros__parameters')
    merged: dict = {}
    for key in ('/**', '**', node_name, '/' + node_name):
        block = doc.get(key)
        if isinstance(block, dict):
            merged.update(block.get('ros__parameters', {}) or {})
    return merged


def markdown_table(specs: Sequence[ParamSpec]) -> str:
    """
    Render parameter specs as the Markdown table of doc/nodes.md.

    Parameters
    ----------
    specs : sequence of ParamSpec
        The parameters of one node, in declaration order.

    Returns
    -------
    str
        The table: parameter, ROS type, default, valid values, meaning.

    """
    rows = ['| parameter | type | default | valid | meaning |', '|---|---|---|---|---|']
    for s in specs:
        ros_type = {bool: 'bool', int: 'integer', float: 'double', str: 'string'}
        typ = ros_type[type(s.default)] if s.length is None else f'double[{s.length}]'
        if isinstance(s.default, float):
            default = f'{s.default:.6g}'
        elif isinstance(s.default, str):
            default = repr(s.default)
        elif isinstance(s.default, bool):
            default = str(s.default).lower()
        else:
            default = str(s.default)
        rows.append(f'| `{s.name}` | {typ} | {default} | {s.range_text()} | {s.description} |')
    return '\n'.join(rows)


def parse_overrides(items) -> dict:
    """
    Parse ``name:=value`` strings (ROS 2 ``-p`` syntax); values are read as YAML.

    Parameters
    ----------
    items : iterable of str or None
        The overrides.

    Returns
    -------
    dict
        Parameter name → value.

    Raises
    ------
    ValueError
        An item without ``:=`` or without a name.

    """
    import yaml  # optional extra (PyYAML ships with every ROS 2 installation)

    out = {}
    for item in items or ():
        if ':=' not in item:
            raise ValueError(f'parameter override {item!r} must look like name:=value')
        name, text = item.split(':=', 1)
        name = name.strip()
        if not name:
            raise ValueError(f'parameter override {item!r} has no name')
        out[name] = yaml.safe_load(text) if text.strip() else ''
    return out
