"""
Validation of a node's parameter values: every value, then the rules between parameters.

:func:`check_all` fills the defaults of a table (:mod:`strapdown_ros.params.tables`) and
validates each value and :func:`combination_error`; the nodes call the same rules at start-up
and on every set.  No ROS imports.
"""
from __future__ import annotations

from typing import Sequence

from strapdown_ros.attitude.coning import algorithm_names, ALGORITHMS
from strapdown_ros.estimation.filter_support import augment_error
from strapdown_ros.params.spec import ParamSpec
from strapdown_ros.params.tables import ALL_PARAMETER_NAMES


def combination_error(values: dict) -> str | None:
    """
    Check the rules between parameters, in one place.

    The rules between parameters, in one place (nodes at start-up and on set, tools through
    :func:`check_all`); each rule applies when ``values`` holds all its parameters.  Returns an
    error message naming the valid combinations, or None.

    * ``velocity_update: printed`` (with ``navigation``) is 003's scheme: one gyro and three
      accelerometer increments per step, so a coning algorithm with 1 sample per update and
      ``accel_rate`` = 3 × ``gyro_rate``.

    Parameters
    ----------
    values : dict
        Parameter values (normalised), any subset of any node's.

    Returns
    -------
    str or None
        The error message, or None when every applicable rule holds.

    """
    if 'augment' in values and augment_error(values['augment']):
        return augment_error(values['augment'])
    need = ('navigation', 'velocity_update', 'coning_algorithm', 'gyro_rate', 'accel_rate')
    if all(n in values for n in need) and values['navigation'] \
            and values['velocity_update'] == 'printed':
        samples = ALGORITHMS[str(values['coning_algorithm'])].samples
        ratio = float(values['accel_rate']) / float(values['gyro_rate'])
        accel_per_step = max(1, int(round(samples * ratio)))
        if samples != 1 or accel_per_step != 3:
            one = ', '.join(n for n in algorithm_names() if ALGORITHMS[n].samples == 1)
            return (f"velocity_update=printed is 003's scheme: 1 gyro and 3 accelerometer "
                    f"increments per step, got coning_algorithm={values['coning_algorithm']} "
                    f'({samples} sample(s) per update) with accel_rate/gyro_rate = {ratio:.6g} '
                    f'({accel_per_step} accelerometer increment(s) per step); valid: '
                    f'coning_algorithm one of {one} with accel_rate = 3 × gyro_rate, or '
                    f'velocity_update=derived (any combination)')
    return None


def check_all(specs: Sequence[ParamSpec], values: dict) -> dict:
    """
    Fill in the defaults and validate a node's parameter values.

    Names that another node of the package declares are ignored (a shared parameter file
    serves several nodes, as ROS itself ignores undeclared parameters); any other name is
    an error, so a typo does not pass silently.

    Parameters
    ----------
    specs : sequence of ParamSpec
        The node's table.
    values : dict
        Parameter name → value, any subset.

    Returns
    -------
    dict
        Every parameter of ``specs``, normalised.

    Raises
    ------
    ValueError
        An unknown name, an invalid value or combination, naming the valid values.

    """
    out = {}
    known = {s.name for s in specs}
    for k in values:
        if k not in known and k not in ALL_PARAMETER_NAMES:
            raise ValueError(f"unknown parameter {k!r}; known: {', '.join(sorted(known))}")
    for s in specs:
        v = s.normalise(values.get(s.name, s.default))
        err = s.check(v)
        if err:
            raise ValueError(err)
        out[s.name] = v
    err = combination_error(out)
    if err:
        raise ValueError(err)
    return out
