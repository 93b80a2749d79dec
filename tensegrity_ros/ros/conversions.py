"""Message builders for the node: core results (numpy, dataclasses) <-> ROS messages:
``joint_states``, the diagnostic statuses (``~/equilibrium``, ``~/jumps``, ``~/motion``),
``joint_trajectory`` (what RViz and tf draw: :mod:`tensegrity_ros.ros.visuals`).

Kept apart from :mod:`tensegrity_ros.ros.node` so that the node stays a thin layer of
callbacks.  Nothing here talks to the ROS graph; every function only fills messages.

Floats in ``diagnostic_msgs/KeyValue`` strings use :func:`fmt` (17 significant digits,
enough to round-trip a double exactly): parse them with ``float(value)``.
"""
from __future__ import annotations

import array
import math
import struct

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

from tensegrity_ros.core.simulation.trajectory import ABORTED, Trajectory

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
    """``sensor_msgs/JointState`` of every hosted module, kept serialized and updated in place.

    The message is serialized once (by rclpy) with marker values; the bytes of the
    stamp and of the position, effort (and velocity) arrays are then overwritten per
    publication, and the publisher sends the bytes as they are: no message object is
    converted per command (about 8 us less per ``joint_states`` than publishing the
    message).  Where the markers are not found once each (never expected), the message
    itself is published.
    """

    def __init__(self, modules, velocity=False):
        names = [name for m in modules for name in joint_names(m)]
        self.msg = JointState(name=names)
        self.msg.position = array.array('d', [0.0] * len(names))
        self.msg.effort = array.array('d', [0.0] * len(names))
        if velocity:                # dynamics mode: rho', theta1', theta2'
            self.msg.velocity = array.array('d', [0.0] * len(names))
        self._position = self.msg.position      # the message's own arrays, updated in place
        self._effort = self.msg.effort
        self._velocity = self.msg.velocity if velocity else None
        self._layout = _serialized_layout(self.msg, self._arrays())

    def _arrays(self):
        return [a for a in (self._position, self._effort, self._velocity) if a is not None]

    def set_module(self, index: int, rho: float, theta1: float, theta2: float,
                   actuator_force: float):
        base = 3 * index
        position = self._position
        position[base] = rho
        position[base + 1] = theta1
        position[base + 2] = theta2
        self._effort[base] = actuator_force

    def set_velocity(self, index: int, rho_dot: float, theta1_dot: float, theta2_dot: float):
        base = 3 * index
        velocity = self._velocity
        velocity[base] = rho_dot
        velocity[base + 1] = theta1_dot
        velocity[base + 2] = theta2_dot

    def stamped(self, nanoseconds: int):
        """The message stamped ``nanoseconds``: serialized bytes (what ``publish`` sends
        as they are) or, without a layout, the message itself."""
        sec, nanosec = divmod(nanoseconds, 1_000_000_000)
        if self._layout is None:
            stamp = self.msg.header.stamp
            stamp.sec, stamp.nanosec = sec, nanosec
            return self.msg
        buffer, stamp_at, array_spans = self._layout
        _STAMP.pack_into(buffer, stamp_at, sec, nanosec)
        for values, (start, end) in zip(self._arrays(), array_spans):
            buffer[start:end] = values
        return bytes(buffer)


#: builtin_interfaces/Time in native byte order (int32 sec, uint32 nanosec).
_STAMP = struct.Struct('=iI')


def _serialized_layout(msg, arrays):
    """(bytearray of ``msg`` serialized, offset of its stamp, (start, end) of every array's
    doubles) found with marker values, or None unless each marker occurs exactly once."""
    sec, nanosec = 0x5A5A1234, 0x2A5B3C4D
    markers = [array.array('d', (math.pi * (k + 1) * 10.0 ** (37 * (n + 1))
                                 for k in range(len(a)))) for n, a in enumerate(arrays)]
    probe = JointState(name=msg.name, position=markers[0], effort=markers[1])
    if len(markers) > 2:
        probe.velocity = markers[2]
    probe.header.stamp.sec, probe.header.stamp.nanosec = sec, nanosec
    buffer = bytearray(serialize_message(probe))
    wanted = [_STAMP.pack(sec, nanosec)] + [m.tobytes() for m in markers]
    if any(not w or buffer.count(w) != 1 for w in wanted):
        return None
    starts = [buffer.find(w) for w in wanted]
    spans = tuple((s, s + len(w)) for s, w in zip(starts[1:], wanted[1:]))
    # effort, the last field, ends the message: what the serializer leaves after it (a
    # few bytes of its buffer) is not sent
    return buffer[:max(end for _, end in spans)], starts[0], spans


#: DiagnosticStatus level of a simulator status level.
LEVELS = {'ok': OK, 'warn': WARN, 'error': ERROR}


def equilibrium_status(*, name, hardware_id, module, status):
    """``equilibrium`` DiagnosticStatus of one module from its simulator
    :class:`~tensegrity_ros.core.simulation.simulator.ModuleStatus` (values:
    msg_docs/equilibrium.md)."""
    msg = DiagnosticStatus(level=LEVELS[status.level], name=name, message=status.message,
                           hardware_id=hardware_id)
    msg.values = key_values(_equilibrium_pairs(module, status))
    return msg


class EquilibriumStatusBuffer:
    """The ``equilibrium`` status of one module, kept and filled in place.

    A command stream makes the node republish every module's status at publish_rate (a
    neck: 3 statuses of 34 values per tick); most values (the design, loads, counts) do
    not change, so only the values that did are formatted again, into the message's own
    ``KeyValue`` objects.  :attr:`msg` is the last status made (published as it is)."""

    def __init__(self):
        self.msg = None
        self._values = ()           # the raw values behind msg's strings

    def update(self, *, name, hardware_id, module, status):
        """The status of ``status`` (what :func:`equilibrium_status` makes), in place."""
        pairs = _equilibrium_pairs(module, status)
        msg = self.msg
        if msg is None:
            self.msg = msg = equilibrium_status(name=name, hardware_id=hardware_id,
                                                module=module, status=status)
        else:
            msg.level, msg.name, msg.message = LEVELS[status.level], name, status.message
            msg.hardware_id = hardware_id
            for kv, (_, value), old in zip(msg.values, pairs, self._values):
                if type(value) is not type(old) or value != old:
                    kv.value = fmt(value)
        self._values = tuple(value for _, value in pairs)
        return msg


def _equilibrium_pairs(module, status):
    """(key, value) of an ``equilibrium`` status, in the published order."""
    params, eq, last_jump = status.params, status.eq, status.last_jump
    found = status.operation_range
    if last_jump is None:
        last_kind, last_rho, last_s = NONE, NONE, NONE
    else:
        last_kind, last_rho = last_jump.kind, float(last_jump.params.rho)
        last_s = float(last_jump.s)
    return (
        ('module', module),
        ('stable', bool(eq.stable)),
        ('rho', params.rho),
        ('theta1', eq.theta1),
        ('theta2', eq.theta2),
        ('stability_margin', eq.stability_margin),
        ('stability_margin_normalized', status.normalized),
        ('warn_margin', status.warn_margin),
        ('eigenvalues', fmt_vector(eq.eigenvalues)),
        ('energy', eq.energy),
        ('residual', float(eq.residual)),
        ('actuator_force', eq.actuator_force),
        ('num_equilibria', status.num_equilibria),
        ('num_stable', status.num_stable),
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
        ('rho_stable_min', NONE if found is None else found.lower.rho),
        ('rho_stable_max', NONE if found is None else found.upper.rho),
        ('rho_stable_min_end', NONE if found is None else found.lower.kind),
        ('rho_stable_max_end', NONE if found is None else found.upper.kind),
        ('last_jump_kind', last_kind),
        ('last_jump_rho', last_rho),
        ('last_jump_s', last_s),
        ('jumps_total', status.jumps_total),
        ('tracking', status.tracking),
    )


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


def jump_status(*, name, hardware_id, modules, jump):
    """One ``jumps`` message (msg_docs/jumps.md) from a simulator
    :class:`~tensegrity_ros.core.simulation.events.Jump`.

    ``modules``: every module's name, bottom to top.  ``rho``, ``from_theta1/2``,
    ``to_theta1/2`` and the forces are those of the module whose command caused the jump;
    a neck (N >= 2) adds ``<m>_rho`` and ``from_<m>_theta1`` ... ``to_<m>_theta2`` of
    every module, before (critical configuration) and after (landing).
    """
    index = jump.module
    module = modules[index]
    neck = len(modules) > 1
    status, pairs = _jump_message(
        name=name, hardware_id=hardware_id, jump=jump, params=jump.modules[index],
        module=module, from_theta=jump.from_theta[index], to_theta=jump.to_theta[index],
        cause=jump.cause, index=jump.count,
        where=f' of the stack at {module}' if neck else ' at', label=f'{module} ' if neck else '')
    landing = jump.landing
    pairs.append(('landing_rho', float(landing[index].rho)))
    if landing[index].rho != jump.modules[index].rho:
        status.message += f' (an equilibrium at rho={landing[index].rho:.6g})'
    if neck:
        for i, m in enumerate(modules):
            pairs.append((f'{m}_rho', float(jump.modules[i].rho)))
        for i, m in enumerate(modules):
            pairs.append((f'landing_{m}_rho', float(landing[i].rho)))
        for side, theta in (('from', jump.from_theta), ('to', jump.to_theta)):
            for i, m in enumerate(modules):
                pairs.append((f'{side}_{m}_theta1', float(theta[i][0])))
                pairs.append((f'{side}_{m}_theta2', float(theta[i][1])))
    if jump.dynamics is not None:
        pairs.extend(dynamic_figures(jump.dynamics, modules if neck else ()))
    status.values = key_values(pairs)
    return status


def undecided_status(*, name, hardware_id, modules, undecided):
    """One ``jumps`` message of kind ``undecided`` (msg_docs/jumps.md) from a simulator
    :class:`~tensegrity_ros.core.simulation.events.Undecided`: a branch point passed continuously
    whose side doubles cannot decide.  ``rho``, ``rho_uncertainty``, ``theta1/2`` and the
    forces are the commanding module's, ``s_uncertainty`` the command path's; a neck adds
    every module's ``<m>_rho``, ``<m>_rho_uncertainty`` and ``<m>_theta1/2``."""
    index = undecided.module
    params, theta = undecided.modules[index], undecided.theta
    span = float(undecided.rho_uncertainty[index])
    message = (f'undecided at {modules[index]} rho={params.rho:.6g}: passed a branch point '
               f'continuously to one side, which an imperfection within '
               f'{undecided.s_uncertainty:.2g} of the path'
               + (f' ({span:.2g} m of rho)' if span > 0.0 else '')
               + ' would decide (below what doubles resolve)')
    status = DiagnosticStatus(level=WARN, name=name, message=message, hardware_id=hardware_id)
    pairs = [('module', modules[index]), ('kind', 'undecided'), ('rho', float(params.rho)),
             ('rho_uncertainty', span), ('s_uncertainty', float(undecided.s_uncertainty)),
             ('theta1', float(theta[index][0])),
             ('theta2', float(theta[index][1])), ('f3x', params.f3x), ('f3y', params.f3y),
             ('f4x', params.f4x), ('f4y', params.f4y), ('cause', undecided.cause)]
    if len(modules) > 1:
        for i, m in enumerate(modules):
            pairs += [(f'{m}_rho', float(undecided.modules[i].rho)),
                      (f'{m}_rho_uncertainty', float(undecided.rho_uncertainty[i])),
                      (f'{m}_theta1', float(theta[i][0])), (f'{m}_theta2', float(theta[i][1]))]
    status.values = key_values(pairs)
    return status


#: The snap figures a ``jumps`` message of the dynamics mode adds (msg_docs/jumps.md).
DYNAMIC_KEYS = ('onset_rho', 'onset_time', 'peak_speed', 'peak_actuator_force', 'overshoot',
                'settle_time', 'lands_elsewhere')


def dynamic_figures(figures, modules=()):
    """(key, value) pairs of a snap's figures: DYNAMIC_KEYS, ``final_theta1/2``,
    ``final_speed`` and the quasi-static landing ``quasi_static_theta1/2``; for a neck
    (``modules``: its names) also every module's ``onset_<m>_rho``, ``final_<m>_theta1/2``
    and ``quasi_static_<m>_theta1/2``."""
    pairs = [(key, figures[key]) for key in DYNAMIC_KEYS]
    final = figures['final']
    pairs += [('final_theta1', final['theta1']), ('final_theta2', final['theta2']),
              ('final_speed', final['speed'])]
    predicted = figures['quasi_static_final'] or {'theta1': None, 'theta2': None}
    pairs += [('quasi_static_theta1', predicted['theta1']),
              ('quasi_static_theta2', predicted['theta2'])]
    if modules:
        every = figures['modules']
        onsets = every['onset_rho'] or [None] * len(modules)
        pairs += [(f'onset_{m}_rho', rho) for m, rho in zip(modules, onsets)]
        for side, thetas in (('final', every['final_theta']),
                             ('quasi_static', every['quasi_static_theta'])):
            for m, theta in zip(modules, thetas or [(None, None)] * len(modules)):
                pairs += [(f'{side}_{m}_theta1', theta[0]), (f'{side}_{m}_theta2', theta[1])]
    return pairs


def trajectory(msg, joints):
    """A core :class:`~tensegrity_ros.core.simulation.trajectory.Trajectory` of a
    ``trajectory_msgs/JointTrajectory`` whose joint names are the modules ``joints``
    (indices), or (reason, text) if its arrays do not fit the names.  Positions only:
    velocities, accelerations and effort may be given (of the names' size) but are not
    used (the path between points is linear, as the controller's for positions)."""
    n = len(joints)
    times, rows = [], []
    for k, point in enumerate(msg.points):
        if len(point.positions) != n:
            return 'size_mismatch', (f'point {k} has {len(point.positions)} positions for '
                                     f'{n} joint names')
        for field in ('velocities', 'accelerations', 'effort'):
            size = len(getattr(point, field))
            if size not in (0, n):
                return 'size_mismatch', (f'point {k} has {size} {field} for {n} joint names '
                                         f'(0 or {n})')
        d = point.time_from_start
        times.append(int(d.sec) * 1_000_000_000 + int(d.nanosec))
        rows.append(tuple(float(v) for v in point.positions))
    stamp = msg.header.stamp
    start = int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
    return Trajectory(joints=tuple(joints), times_ns=tuple(times), positions=tuple(rows),
                      start_ns=start or None)


class MotionStatusBuffer:
    """The ``~/motion`` DiagnosticStatus (msg_docs/motion.md) of the trajectory player's
    :class:`~tensegrity_ros.core.simulation.trajectory.MotionStatus`, made again only when it
    changed."""

    def __init__(self):
        self.msg = None
        self.status = None          # the MotionStatus of msg

    def update(self, *, name, hardware_id, modules, status):
        if self.msg is not None and status is self.status:
            return self.msg
        self.status = status
        joints = [f'{modules[j]}_rho' for j in status.joints]
        self.msg = DiagnosticStatus(
            level=WARN if status.state == ABORTED else OK, name=name,
            message=f'{status.state}: {status.text}', hardware_id=hardware_id)
        self.msg.values = key_values([
            ('state', status.state),
            ('id', status.number),
            ('joints', '[' + ', '.join(joints) + ']'),
            ('goal', fmt_vector(status.goal)),
            ('duration', float(status.duration)),
            ('points', status.points),
        ])
        return self.msg
