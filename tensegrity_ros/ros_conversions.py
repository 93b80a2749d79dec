"""Message builders for the node: core results (numpy, dataclasses) <-> ROS messages.

Kept apart from :mod:`tensegrity_ros.node` so that the node stays a thin layer of
callbacks.  Nothing here talks to the ROS graph; every function only fills messages.

Floats in ``diagnostic_msgs/KeyValue`` strings use :func:`fmt` (17 significant digits,
enough to round-trip a double exactly): parse them with ``float(value)``.
"""
from __future__ import annotations

import array

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
import math

from geometry_msgs.msg import Point, PoseStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

OK = DiagnosticStatus.OK
WARN = DiagnosticStatus.WARN
ERROR = DiagnosticStatus.ERROR

#: Text used in ``KeyValue`` strings for "no value" (e.g. no jump yet).
NONE = 'none'


def fmt(value) -> str:
    """A ``KeyValue`` string: repr-precision float, 'true'/'false', integers as such."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, int):
        return str(value)
    if value is None:
        return NONE
    if isinstance(value, str):
        return value
    return format(float(value), '.17g')


def fmt_vector(values) -> str:
    """Several floats as a bracketed, comma-separated list: ``[a, b]``."""
    return '[' + ', '.join(fmt(float(v)) for v in values) + ']'


def key_values(pairs) -> list:
    return [KeyValue(key=key, value=fmt(value)) for key, value in pairs]


def joint_names(module: str):
    """The three joint names of a module, in the order they are published."""
    return (f'{module}_rho', f'{module}_theta1', f'{module}_theta2')


class JointStateBuffer:
    """One pre-built ``sensor_msgs/JointState`` for every hosted module, updated in place.

    Publishing serialises the message at once, so the same object is reused for every
    publication: no message or array allocation per command.
    """

    def __init__(self, modules):
        self.msg = JointState()
        names = []
        for m in modules:
            names.extend(joint_names(m))
        self.msg.name = names
        self.msg.position = array.array('d', [0.0] * len(names))
        self.msg.effort = array.array('d', [0.0] * len(names))
        self._position = self.msg.position
        self._effort = self.msg.effort
        self._stamp = self.msg.header.stamp

    def set_module(self, index: int, rho: float, theta1: float, theta2: float,
                   actuator_force: float):
        base = 3 * index
        position = self._position
        position[base] = rho
        position[base + 1] = theta1
        position[base + 2] = theta2
        self._effort[base] = actuator_force

    def stamped(self, nanoseconds: int) -> JointState:
        self._stamp.sec, self._stamp.nanosec = divmod(nanoseconds, 1_000_000_000)
        return self.msg


def normalized_margin(params, eq) -> float:
    """Stability margin (smallest Hessian eigenvalue) over the module's stiffness scale.

    The scale ``min(ka, kb, kc) * L1 * L2`` (J/rad^2) is the size of the Hessian's
    spring terms: 1 is a stiff, well-conditioned module, 0 is a fold or branch point.
    """
    return float(eq.stability_margin) / (min(params.ka, params.kb, params.kc)
                                         * params.L1 * params.L2)


def equilibrium_status(*, name, hardware_id, module, params, eq, level, message,
                       num_equilibria, num_stable, last_jump, jumps_total,
                       tracking_status, warn_margin, operation_range=None, normalized=None):
    """``equilibrium`` DiagnosticStatus of one module (values: DESIGN section 5).

    ``normalized``: the normalized stability margin if it is not the one-module
    :func:`normalized_margin` (a stack: see :class:`StackModuleState`).
    """
    if normalized is None:
        normalized = normalized_margin(params, eq)
    if last_jump is None:
        last_kind, last_rho, last_s = NONE, NONE, NONE
    else:
        last_kind, last_rho = last_jump.kind, float(last_jump.params.rho)
        last_s = float(last_jump.s)
    status = DiagnosticStatus(level=level, name=name, message=message,
                              hardware_id=hardware_id)
    status.values = key_values((
        ('module', module),
        ('stable', bool(eq.stable)),
        ('rho', params.rho),
        ('theta1', eq.theta1),
        ('theta2', eq.theta2),
        ('stability_margin', eq.stability_margin),
        ('stability_margin_normalized', normalized),
        ('warn_margin', warn_margin),
        ('eigenvalues', fmt_vector(eq.eigenvalues)),
        ('energy', eq.energy),
        ('residual', float(eq.residual)),
        ('actuator_force', eq.actuator_force),
        ('num_equilibria', num_equilibria),
        ('num_stable', num_stable),
        ('L1', params.L1),
        ('L2', params.L2),
        ('ka', params.ka),
        ('kb', params.kb),
        ('kc', params.kc),
        ('m1', params.m1),
        ('m2', params.m2),
        ('f3x', params.f3x),
        ('f3y', params.f3y),
        ('f4x', params.f4x),
        ('f4y', params.f4y),
        ('rho_stable_min', NONE if operation_range is None else operation_range.lower.rho),
        ('rho_stable_max', NONE if operation_range is None else operation_range.upper.rho),
        ('rho_stable_min_end', NONE if operation_range is None else operation_range.lower.kind),
        ('rho_stable_max_end', NONE if operation_range is None else operation_range.upper.kind),
        ('last_jump_kind', last_kind),
        ('last_jump_rho', last_rho),
        ('last_jump_s', last_s),
        ('jumps_total', jumps_total),
        ('tracking', tracking_status),
    ))
    return status


def _jump_message(*, name, hardware_id, jump, params, module, from_theta, to_theta, cause,
                  index, where, label):
    """The ``jumps`` DiagnosticStatus common to one module and a stack: the module's kind,
    rho, angles before and after, path parameter, forces, cause and running index."""
    rho = float(params.rho)
    f1, f2 = (float(v) for v in from_theta)
    t1, t2 = (float(v) for v in to_theta)
    message = (f'{jump.kind}{where} rho={rho:.6g}: {label}theta '
               f'({f1:.4f}, {f2:.4f}) -> ({t1:.4f}, {t2:.4f}) rad')
    if jump.ambiguous:
        message += ' (ambiguous landing)'
    status = DiagnosticStatus(level=WARN, name=name, message=message,
                              hardware_id=hardware_id)
    pairs = [
        ('module', module),
        ('kind', jump.kind),
        ('rho', rho),
        ('from_theta1', f1),
        ('from_theta2', f2),
        ('to_theta1', t1),
        ('to_theta2', t2),
        ('s', float(jump.s)),
        ('ambiguous', bool(jump.ambiguous)),
        ('f3x', params.f3x),
        ('f3y', params.f3y),
        ('f4x', params.f4x),
        ('f4y', params.f4y),
        ('cause', cause),
        ('index', index),
    ]
    return status, pairs


def jump_status(*, name, hardware_id, module, jump, cause, index):
    """One ``jumps`` message: a fold or branch point crossed, and where the module landed."""
    status, pairs = _jump_message(name=name, hardware_id=hardware_id, jump=jump,
                                  params=jump.params, module=module,
                                  from_theta=jump.from_theta, to_theta=jump.to_theta,
                                  cause=cause, index=index, where=' at', label='')
    status.values = key_values(pairs)
    return status


def stack_jump_status(*, name, hardware_id, modules, index, jump, cause, count):
    """One ``jumps`` message of a stack (N >= 2): a fold or branch point of the whole stack.

    ``modules``: every module's name, bottom to top; ``index``: the module whose command
    triggered the path.  ``rho``, ``from_theta1/2``, ``to_theta1/2`` and the forces are
    that module's; ``from_<m>_theta1`` ... ``to_<m>_theta2`` give every module's angles
    before (critical configuration) and after (landing).
    """
    module = modules[index]
    status, pairs = _jump_message(name=name, hardware_id=hardware_id, jump=jump,
                                  params=jump.stack.modules[index], module=module,
                                  from_theta=jump.from_theta[index],
                                  to_theta=jump.to_theta[index], cause=cause, index=count,
                                  where=f' of the stack at {module}', label=f'{module} ')
    for i, m in enumerate(modules):
        pairs.append((f'{m}_rho', float(jump.stack.modules[i].rho)))
    for side, theta in (('from', jump.from_theta), ('to', jump.to_theta)):
        for i, m in enumerate(modules):
            pairs.append((f'{side}_{m}_theta1', float(theta[i][0])))
            pairs.append((f'{side}_{m}_theta2', float(theta[i][1])))
    status.values = key_values(pairs)
    return status


class StackModuleState:
    """One module's view of a verified stack equilibrium, with the attributes the node
    reads from a one-module ``Equilibrium`` (theta1, theta2, actuator_force, stable ...).

    Stability is the whole stack's: ``stability_margin`` is the smallest reduced-Hessian
    eigenvalue (N/m), ``eigenvalues`` all of them; ``normalized`` is the margin over
    ``scale`` (the smallest spring stiffness of the stack, N/m).
    """

    __slots__ = ('stack', 'index', 'theta', 'theta1', 'theta2', 'actuator_force', 'stable',
                 'stability_margin', 'eigenvalues', 'energy', 'residual', 'normalized')

    def __init__(self, stack_eq, index, scale):
        self.stack = stack_eq
        self.index = index
        self.theta = stack_eq.theta[index]
        self.theta1 = float(self.theta[0])
        self.theta2 = float(self.theta[1])
        self.actuator_force = float(stack_eq.actuator_forces[index])
        self.stable = stack_eq.stable
        self.stability_margin = stack_eq.stability_margin
        self.eigenvalues = stack_eq.eigenvalues
        self.energy = float(stack_eq.energy)
        self.residual = float(stack_eq.residual)
        self.normalized = float(self.stability_margin) / scale


def stack_module_nodes(nodes, index):
    """A1..A4 of module ``index`` from a stack's node table (A1(0), A2(0), A3(i), A4(i))."""
    a3, a4 = 2 + 2 * index, 3 + 2 * index
    a1, a2 = (0, 1) if index == 0 else (a4 - 2, a3 - 2)
    return nodes[[a1, a2, a3, a4]]


def head_of(positions):
    """Midpoint (x, y) and direction angle (rad) of the top chord A4 -> A3 of one module."""
    a3, a4 = positions[2], positions[3]
    return ((float(a3[0] + a4[0]) * 0.5, float(a3[1] + a4[1]) * 0.5),
            math.atan2(float(a3[1] - a4[1]), float(a3[0] - a4[0])))


class HeadPose:
    """The pre-built ``head_pose`` message (geometry_msgs/PoseStamped), updated in place:
    position = the top chord's midpoint (z = 0), orientation = rotation about z by the
    chord's direction angle, in the frame ``frame_id`` (the stack's base frame)."""

    def __init__(self):
        self.msg = PoseStamped()

    def update(self, position, angle, frame_id, stamp):
        msg = self.msg
        msg.header.frame_id = frame_id
        msg.header.stamp = stamp
        p = msg.pose.position
        p.x, p.y, p.z = float(position[0]), float(position[1]), 0.0
        q = msg.pose.orientation
        q.x, q.y = 0.0, 0.0
        q.z, q.w = math.sin(0.5 * angle), math.cos(0.5 * angle)
        return msg


def _color(r, g, b, a=1.0):
    return ColorRGBA(r=float(r), g=float(g), b=float(b), a=float(a))


#: Rod / node colour by status level: green stable, orange near a jump, red otherwise.
LEVEL_COLORS = {
    OK: _color(0.1, 0.75, 0.2),
    WARN: _color(1.0, 0.55, 0.0),
    ERROR: _color(0.9, 0.1, 0.1),
}
SPRING_COLOR = _color(0.2, 0.45, 0.95, 0.9)
ACTUATOR_COLOR = _color(0.55, 0.55, 0.55)

#: Marker ids within a module's namespace.
MARKER_RODS, MARKER_ACTUATOR, MARKER_SPRINGS, MARKER_NODES = 0, 1, 2, 3


class ModuleMarkers:
    """The four markers of one module (rods, actuator, springs, nodes), updated in place.

    Points are in the module's base frame (origin A1, x along A1->A2, y up, z = 0):
    the ``frame_id`` parameter names that frame.
    """

    def __init__(self, module: str):
        def marker(kind, ident, color):
            m = Marker(ns=module, id=ident, type=kind, action=Marker.ADD)
            m.pose.orientation.w = 1.0
            m.color = color
            return m

        self.rods = marker(Marker.LINE_LIST, MARKER_RODS, LEVEL_COLORS[OK])
        self.actuator = marker(Marker.LINE_LIST, MARKER_ACTUATOR, ACTUATOR_COLOR)
        self.springs = marker(Marker.LINE_LIST, MARKER_SPRINGS, SPRING_COLOR)
        self.nodes = marker(Marker.SPHERE_LIST, MARKER_NODES, LEVEL_COLORS[OK])
        self.markers = [self.rods, self.actuator, self.springs, self.nodes]

    def update(self, positions, level, frame_id, stamp, size):
        """``positions``: A1..A4 as a (4, 2) array; ``size``: a length scale (m)."""
        a1, a2, a3, a4 = (Point(x=float(p[0]), y=float(p[1]), z=0.0) for p in positions)
        color = LEVEL_COLORS.get(level, LEVEL_COLORS[ERROR])
        self.rods.points = [a1, a3, a2, a4]
        self.rods.color = color
        self.rods.scale.x = 0.02 * size
        self.actuator.points = [a1, a2]
        self.actuator.scale.x = 0.03 * size
        self.springs.points = [a2, a3, a1, a4, a3, a4]     # springs a, b, c
        self.springs.scale.x = 0.008 * size
        self.nodes.points = [a1, a2, a3, a4]
        self.nodes.color = color
        self.nodes.scale.x = self.nodes.scale.y = self.nodes.scale.z = 0.05 * size
        for m in self.markers:
            m.header.frame_id = frame_id
            m.header.stamp = stamp
        return self.markers


def marker_array(markers) -> MarkerArray:
    return MarkerArray(markers=list(markers))
