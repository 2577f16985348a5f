"""
Node parameters in ROS: declared with descriptors, validated at start-up and at every set.

The specs and their checks live in :mod:`strapdown_ros.params` (no ROS); this module turns them
into ROS parameters of a node (``ros2 param describe``/``set``/``load``) with one message format
that lists the valid values.
"""
from __future__ import annotations

from typing import Callable, Sequence

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.parameter import Parameter

from strapdown_ros.nodes.ros_status import bounded
from strapdown_ros.params import ALL_PARAMETER_NAMES, combination_error, ParamSpec

__all__ = ['descriptor', 'declare_validated', 'InvalidParameter', 'ROS_OWN_PARAMETERS']


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """
    Return the ROS descriptor of a parameter spec (``ros2 param describe``).

    Ranges and choices are stated in ``additional_constraints`` and enforced by
    :func:`declare_validated` (one message format that lists the valid values), not by
    rclpy's numeric ranges, whose messages differ between start-up and runtime.

    Parameters
    ----------
    spec : ParamSpec
        The parameter's spec (:class:`strapdown_ros.params.ParamSpec`).

    Returns
    -------
    rcl_interfaces.msg.ParameterDescriptor
        Its description, the valid values, and dynamic typing where a number or a list may be
        given in another type.

    """
    d = ParameterDescriptor(description=spec.description,
                            additional_constraints='valid: ' + spec.range_text())
    # a YAML "50" for a double parameter must not be a type error: spec.check validates it
    # and an unquoted algorithm name "2" (an integer to the YAML parser) is accepted as well
    # and an integer list for a double array ([0, 0, 9]) is read as doubles
    d.dynamic_typing = spec.choices is not None or spec.length is not None or (
        isinstance(spec.default, (int, float)) and not isinstance(spec.default, bool))
    return d


class InvalidParameter(ValueError):
    """Raised at start-up for a parameter value that fails validation."""


#: parameters rclpy itself may be given (not the package's)
ROS_OWN_PARAMETERS = ('use_sim_time', 'start_type_description_service')


def _retyped(given, used) -> bool:
    """Tell whether the start-up value ``given`` was read as a number ``used`` of another type."""
    number = isinstance(used, (int, float)) and not isinstance(used, bool)
    return number and type(given) is not type(used)


def declare_validated(node, specs: Sequence[ParamSpec],
                      on_change: Callable[[dict], str | None] | None = None,
                      apply: Callable[[dict], None] | None = None):
    """
    Declare a node's parameters and validate them at start-up and at every runtime set.

    Setting a parameter to its current value is no change (so ``ros2 param load`` of the
    shipped file succeeds).  A start-up override that no node of the package declares is an
    error (a typo must not pass silently).

    Parameters
    ----------
    node : rclpy.node.Node
        The node that declares them.
    specs : sequence of ParamSpec
        The node's parameter specs (:mod:`strapdown_ros.params`).
    on_change : callable, optional
        ``on_change(values)`` may veto a valid runtime change by returning a reason (e.g. a
        read-only value); None accepts it.
    apply : callable, optional
        ``apply(values)`` makes an accepted change effective, in a post-set callback.

    Returns
    -------
    dict
        The current values, name → value, kept up to date.

    Raises
    ------
    InvalidParameter
        A start-up value fails validation (the message names the valid values), the values
        contradict each other, or an override names no parameter of the package.

    """
    by_name = {s.name: s for s in specs}
    values = {}
    for s in specs:
        p = node.declare_parameter(s.name, s.default, descriptor(s))
        v = s.normalise(p.value)
        err = s.check(v)
        if err:
            raise InvalidParameter(err)
        values[s.name] = v
        if _retyped(p.value, v):
            # a number given as text ("0.05", a quoted YAML value) or a double given as an
            # integer: stored with its proper type, so `ros2 param get` shows what is used
            node.set_parameters([Parameter(s.name, value=v)])
    err = combination_error(values)
    if err:
        raise InvalidParameter(err)
    unknown = sorted(n for n in getattr(node, '_parameter_overrides', {})
                     if n not in ALL_PARAMETER_NAMES and n not in ROS_OWN_PARAMETERS
                     and not n.startswith('qos_overrides.'))
    if unknown:
        raise InvalidParameter(f"unknown parameter(s) {', '.join(map(repr, unknown))} for "
                               f"{node.get_name()}; known: {', '.join(sorted(by_name))}")

    def _changes(params: list[Parameter]):
        new = {}
        for p in params:
            spec = by_name.get(p.name)
            if spec is None:
                continue
            v = spec.normalise(p.value)
            err = spec.check(v)
            if err:
                return None, err
            if isinstance(p.value, str) and _retyped(p.value, v):
                # at run time a number given as text would stay text in `ros2 param get`
                # (it cannot be re-set from inside the set callback): refused, as rclpy
                # refuses text for a typed double
                return None, (f'{p.name} must be set as a number, not as text '
                              f'{bounded(repr(p.value), 80)}')
            if v != values.get(p.name):
                new[p.name] = v
        err = combination_error({**values, **new}) if new else None
        return (None, err) if err else (new, None)

    def _on_set(params: list[Parameter]) -> SetParametersResult:
        new, err = _changes(params)
        if err:
            return SetParametersResult(successful=False, reason=err)
        if on_change is not None and new:
            reason = on_change(new)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _post_set(params: list[Parameter]) -> None:
        new, _ = _changes(params)
        if new:
            values.update(new)
            if apply is not None:
                apply(new)

    node.add_on_set_parameters_callback(_on_set)
    node.add_post_set_parameters_callback(_post_set)
    return values
