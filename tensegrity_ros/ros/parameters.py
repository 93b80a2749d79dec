"""The node's parameters as ROS declares them: descriptors, types, node-wide settings.

The per-module parameters and the way from their values to the simulator's
configuration are ROS-free, in :mod:`tensegrity_ros.module_parameters` (shared with the
parameter files of the offline tools); their names are re-exported here so that the
node reads all of its parameters through this module.  ``MODULE_PARAMETERS`` (per
module, ``<m>.<name>``) and ``NODE_PARAMETERS`` are the parameter contract (README's
parameter table and ``ros2 param describe`` show them).
"""
from __future__ import annotations

import re

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.parameter import Parameter

from tensegrity_ros.module_parameters import (check_dynamics_values, check_module_values,
                                              design_changes, FORCE, INITIAL, initial_params,
                                              kind_of, LIMIT, live_values, module_getter,
                                              module_limits, MODULE_PARAMETERS, module_params,
                                              PHYSICAL, SETTING)

__all__ = [
    'MAX_MODULES', 'BOOL', 'DOUBLE', 'DOUBLE_ARRAY', 'STRING', 'STRING_ARRAY', 'NODE_PARAMETERS',
    'frame_problem', 'frame_names', 'descriptor', 'declarations', 'parameter_types',
    'check_node_values',
    # per-module parameters (module_parameters), for the node
    'FORCE', 'INITIAL', 'LIMIT', 'MODULE_PARAMETERS', 'PHYSICAL', 'SETTING',
    'check_dynamics_values', 'check_module_values', 'design_changes', 'initial_params', 'kind_of',
    'live_values', 'module_getter', 'module_limits', 'module_params',
]

#: How many modules one node hosts at most (a stack of N modules has 4N coupled unknowns;
#: a command costs ~N^2 * 0.1 ms).
MAX_MODULES = 20


def descriptor(description, *, type_, constraints='', read_only=False, range_=None):
    d = ParameterDescriptor(description=description, type=type_.value,
                            additional_constraints=constraints, read_only=read_only)
    if range_ is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float(range_[0]),
                                                     to_value=float(range_[1]), step=0.0)]
    return d


BOOL = Parameter.Type.BOOL
DOUBLE = Parameter.Type.DOUBLE
DOUBLE_ARRAY = Parameter.Type.DOUBLE_ARRAY
STRING = Parameter.Type.STRING
STRING_ARRAY = Parameter.Type.STRING_ARRAY
#: ROS parameter type of a type name of the module parameter table.
ROS_TYPES = {'double': DOUBLE, 'double_array': DOUBLE_ARRAY}

#: Slowest markers rate other than 0 (off): a slower one is a typo (5e-324 would give a
#: timer period that cannot be represented).
MIN_MARKERS_RATE = 0.01

#: Node-wide parameters: (name, default, type, description, constraints, range, read_only).
NODE_PARAMETERS = (
    ('publish_rate', 50.0, DOUBLE,
     'Rate (Hz) of the joint_states timer; also the segment rate of speed-limited motion and '
     'the highest rate of equilibrium updates.', '1..1000 Hz', (1.0, 1000.0), False),
    ('markers_rate', 10.0, DOUBLE,
     'Rate (Hz) of the markers topic; 0 = off. Served by the publish_rate timer, so at most '
     'publish_rate.', f'0 (off) or {MIN_MARKERS_RATE:g}..100 Hz, <= publish_rate',
     (0.0, 100.0), False),
    ('diagnostics_rate', 1.0, DOUBLE,
     'Rate (Hz) of /diagnostics. Served by the publish_rate timer, so at most publish_rate.',
     '0.1..100 Hz, <= publish_rate', (0.1, 100.0), False),
    ('frame_id', 'tensegrity_base', STRING,
     'Frame of the markers, head_pose and the root of the TF chain on /tf: the base frame of '
     'the bottom module (origin A1, x along A1->A2, y up). A TF frame id: names of letters, '
     'digits and _, separated by single /, no leading /.',
     'a TF frame id, e.g. tensegrity_base or robot1/neck_base', None, False),
    ('frame_prefix', '', STRING,
     'Prepended to every frame name the node uses (frame_id, <m>_top_chord, head), as '
     "robot_state_publisher's frame_prefix: e.g. robot1/ for two necks in one TF tree.",
     "'' or a prefix that makes frame names TF frame ids, e.g. robot1/", None, False),
    ('dynamics', False, BOOL,
     'false: quasi-static (the state jumps to the end of each tracked path). true: the rods '
     'move with their inertia, integrated in real time at publish_rate (a module or a neck; '
     'needs every <m>.m1, m2, damping, max_rho_rate > 0). Read-only: switching in the middle '
     'of a transient has no verified state to start the other mode from.',
     'every module with m1, m2, damping, max_rho_rate > 0',
     None, True),
)
_NODE_SPEC = {p[0]: p for p in NODE_PARAMETERS}


def declarations(names):
    """(name, default, ParameterDescriptor) of every node and module parameter."""
    out = []
    for name, default, type_, description, constraints, range_, read_only in NODE_PARAMETERS:
        out.append((name, default, descriptor(
            description, type_=type_, constraints=constraints, range_=range_,
            read_only=read_only)))
    for m in names:
        for name, default, type_, _kind, description, constraints, range_ in MODULE_PARAMETERS:
            out.append((f'{m}.{name}', default, descriptor(
                description, type_=ROS_TYPES[type_], constraints=constraints, range_=range_)))
    return out


def parameter_types(names):
    """{parameter name: Parameter.Type} of every declared parameter."""
    types = {name: spec[2] for name, spec in _NODE_SPEC.items()}
    for m in names:
        types.update({f'{m}.{name}': ROS_TYPES[spec[2]] for spec in MODULE_PARAMETERS
                      for name in (spec[0],)})
    return types


def check_node_values(values, modules=('m0',)):
    """Why the node-wide parameter values are refused, or '' if they are fine (with
    ``dynamics`` true: also the modules' dynamics values)."""
    if values['dynamics']:
        for m in modules:
            reason = check_dynamics_values(m, module_getter(m, values))
            if reason:
                return reason
    reason = frame_problem('frame_id', values['frame_id']) or (
        values['frame_prefix'] and frame_problem(
            'frame_prefix + frame_id', values['frame_prefix'] + values['frame_id']))
    if reason:
        return reason
    rate = values['markers_rate']
    if rate != 0.0 and not MIN_MARKERS_RATE <= rate <= 100.0:
        return (f'markers_rate must be 0 (off) or {MIN_MARKERS_RATE:g}..100 Hz (a period of '
                f'at most {1 / MIN_MARKERS_RATE:g} s), got {rate!r}')
    publish_rate = values['publish_rate']
    for name in ('markers_rate', 'diagnostics_rate'):
        if values[name] > publish_rate:
            return (f'{name}={values[name]!r} above publish_rate={publish_rate!r}: it is '
                    f'served by the publish_rate timer, so it cannot be faster (raise '
                    f'publish_rate first, or set both at once)')
    return ''


#: A TF frame id as tf2 and REP 105 use them: ROS name tokens (letters, digits, _)
#: separated by single slashes, no leading slash (tf2 refuses one), no spaces.
_FRAME_ID = re.compile(r'^[A-Za-z0-9_]+(/[A-Za-z0-9_]+)*$')


def frame_problem(what, frame):
    """Why ``frame`` is not a usable TF frame id ('' if it is); ``what`` names it."""
    if _FRAME_ID.match(frame):
        return ''
    if not frame:
        return f'{what} must not be empty'
    if frame.startswith('/'):
        return f'{what} {frame!r}: a TF frame id has no leading / (tf2 refuses it)'
    return (f'{what} {frame!r} is not a TF frame id: use letters, digits and _, in names '
            f'separated by single / (e.g. tensegrity_base, robot1/neck_base)')


def frame_names(prefix, frame_id, modules):
    """(root, [top-chord frame of each module], head): the frame names on /tf."""
    return (prefix + frame_id, [f'{prefix}{m}_top_chord' for m in modules], prefix + 'head')
