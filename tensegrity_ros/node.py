"""The ``tensegrity_node``: one node hosting a stack of tensegrity modules (DESIGN.md section 5).

The node always sits on a verified stable equilibrium.  Every command (``<m>/rho_cmd``,
``<m>/force_a3``, ``<m>/force_a4``, ``joint_commands``, or a runtime parameter change)
moves the module's parameters along a straight path that the core tracker follows;
every fold or branch point crossed on the way is published on ``jumps`` and logged.

One module (``modules: ['m0']``) runs on the fast one-module path (``track_module``).
A stack of N >= 2 modules (a neck, ``modules: [m0, m1, ...]`` bottom to top) runs on the
coupled stack core: the live state is one ``StackEquilibrium``; every change builds the end
``Stack`` from all modules' live parameters and ``track_stack`` follows it from the live
state (all changes of one message on one straight path).  The node is a thin layer:
messages are converted to arrays, the core (:mod:`tensegrity_ros.core`) does the work,
results are converted back (:mod:`tensegrity_ros.ros_conversions`).

Run:  ``python -m tensegrity_ros.node --ros-args --params-file config/default.yaml``
"""
from __future__ import annotations

import math
import os
import re
import signal
import sys
import traceback

if __name__ == '__main__' or os.path.basename(sys.argv[0]) == 'tensegrity_node':
    # Started as a program: Ctrl-C or SIGTERM while the heavy imports below load (about
    # half a second) is a plain, quiet exit 0; main() installs the real handling.
    signal.signal(signal.SIGINT, lambda *_: os._exit(0))
    signal.signal(signal.SIGTERM, lambda *_: os._exit(0))

import numpy as np
import rclpy
import rclpy.executors
import rclpy.logging
import rclpy.utilities
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped, Vector3
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
from rclpy.exceptions import (InvalidParameterTypeException, InvalidParameterValueException,
                              ParameterException)
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from tensegrity_ros import ros_conversions as conv
from tensegrity_ros.core import (InvalidParameterError, ModuleParams, TrackingError,
                                 ModuleJump, equilibria, node_positions, settle, track_module)
from tensegrity_ros.core.analysis import operation_range
from tensegrity_ros.core.stack import Stack, settle_stack, track_stack
from tensegrity_ros.core.supported_range import check_supported

# ---------------------------------------------------------------------------
# QoS (documented in msg_docs/ and README.md)

#: Commands: reliable + volatile, so ``ros2 topic pub`` (and any default publisher)
#: matches.  Depth 100 = 0.1 s of a 1 kHz stream: every command is a path segment
#: and is processed in order, none is dropped while the node keeps up.
COMMAND_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
#: Latched status (``stable``, ``equilibrium``): a late subscriber gets the current one.
STATUS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: ``jumps``: the last 10 jumps are kept for late subscribers.
JUMPS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: ``joint_states`` and ``/diagnostics``: the usual reliable, volatile stream.
STATE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
#: ``head_pose``: latched (depth 1), like the status topics: a late subscriber gets the
#: current head pose at once.  Published on every publish_rate tick, at start-up and reset.
HEAD_QOS = STATUS_QOS
#: ``markers``: latched too, so RViz started later still draws the mechanism.
MARKERS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)

DEFAULT_NODE_NAME = 'tensegrity'
#: Rejected input and failures are logged at most once per this many seconds per reason.
WARN_THROTTLE_SEC = 2.0
#: A published state must have lambda_min > this * |lambda_max| (a verified minimum).
DEFINITENESS_TOL = 1e-9
#: How many modules one node hosts at most (a stack of N modules has 4N coupled unknowns;
#: a command costs ~N^2 * 0.1 ms).
MAX_MODULES = 20

#: Reasons counted in ``/diagnostics`` (``rejected_<reason>``).
REJECT_REASONS = (
    'non_finite',            # NaN or inf in a command
    'out_of_range',          # rho outside [rho_min, rho_max]
    'size_mismatch',         # JointState: no names, or len(position) != len(name)
    'unknown_joint',         # JointState: a name that is not a commandable <m>_rho
    'duplicate_joint',       # JointState: the same joint twice
    'parameter_type',        # parameter set with the wrong type
    'parameter_read_only',   # parameter set on a read-only parameter
    'parameter_undeclared',  # parameter set on a name the node does not have
    'parameter_value',       # parameter value refused (range, physics, limits)
)

_MODULE_NAME = re.compile(r'^[A-Za-z][A-Za-z0-9_]*$')


class ConfigurationError(RuntimeError):
    """The node's start-up configuration (parameters) cannot be used."""


# ---------------------------------------------------------------------------
# Parameters


def _descriptor(description, *, type_, constraints='', read_only=False, range_=None):
    d = ParameterDescriptor(description=description, type=type_.value,
                            additional_constraints=constraints, read_only=read_only)
    if range_ is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float(range_[0]),
                                                     to_value=float(range_[1]), step=0.0)]
    return d


_D = Parameter.Type.DOUBLE
_DA = Parameter.Type.DOUBLE_ARRAY
_S = Parameter.Type.STRING
_SA = Parameter.Type.STRING_ARRAY

# Kinds of per-module parameters: what a runtime change does.
PHYSICAL = 'physical'    # geometry, stiffness, masses: tracked like a command
FORCE = 'force'          # force_a3/a4: tracked like a force command
INITIAL = 'initial'      # used at start-up and by reset
LIMIT = 'limit'          # rho_min/rho_max: command validation
SETTING = 'setting'      # rates and thresholds

#: Per-module parameters ``<m>.<name>``: (name, default, type, kind, description, constraints,
#: FloatingPointRange or None).  The README parameter table mirrors this.
MODULE_PARAMETERS = (
    ('L1', 1.0, _D, PHYSICAL, 'Length of rod A1A3 (m).', '> 0', None),
    ('L2', 1.0, _D, PHYSICAL, 'Length of rod A2A4 (m).', '> 0', None),
    ('k', 100.0, _D, PHYSICAL,
     'Stiffness of all three springs a, b, c (N/m), unless ka/kb/kc override it.', '> 0', None),
    ('ka', 0.0, _D, PHYSICAL, 'Stiffness of spring a = A2A3 (N/m); 0.0 = use k.', '>= 0', None),
    ('kb', 0.0, _D, PHYSICAL, 'Stiffness of spring b = A1A4 (N/m); 0.0 = use k.', '>= 0', None),
    ('kc', 0.0, _D, PHYSICAL, 'Stiffness of spring c = A3A4 (N/m); 0.0 = use k.', '>= 0', None),
    ('m1', 0.0, _D, PHYSICAL,
     'Mass of rod A1A3 (kg); its weight acts along -y of the base frame.', '>= 0', None),
    ('m2', 0.0, _D, PHYSICAL, 'Mass of rod A2A4 (kg).', '>= 0', None),
    ('force_a3', [0.0, 0.0], _DA, FORCE,
     'Force [fx, fy] at A3 (N, base frame; fy > 0 pulls up) at start-up and on reset; '
     'setting it at runtime applies it at once, tracked like a force_a3 message.',
     'two finite numbers', None),
    ('force_a4', [0.0, 0.0], _DA, FORCE,
     'Force [fx, fy] at A4 (N), as force_a3.', 'two finite numbers', None),
    ('rho_initial', 0.75, _D, INITIAL,
     'Actuator length at start-up and on reset (m).', 'rho_min <= rho_initial <= rho_max', None),
    ('initial_theta', [0.7, 0.7], _DA, INITIAL,
     'Start guess [theta1, theta2] (rad): the node starts (and resets) in the stable '
     'equilibrium whose basin holds it; picks the branch.', 'two finite numbers', None),
    ('rho_min', 0.05, _D, LIMIT, 'Smallest accepted actuator command (m).',
     '0 < rho_min < rho_max; current and initial rho must stay inside', None),
    ('rho_max', 1.95, _D, LIMIT, 'Largest accepted actuator command (m).',
     'rho_max > rho_min; current and initial rho must stay inside', None),
    ('max_rho_rate', 0.0, _D, SETTING,
     'Actuator speed limit (m/s). 0 = no limit: a command is one straight path. '
     'Otherwise the actuator moves toward the latest target at this speed, one tracked '
     'segment per timer tick (publish_rate) and per command.', '>= 0', (0.0, 100.0)),
    ('warn_margin', 0.05, _D, SETTING,
     'equilibrium is WARN (near a jump) when the stability margin (smallest Hessian '
     'eigenvalue, J/rad^2) is below warn_margin * min(ka, kb, kc) * L1 * L2.', '0..1',
     (0.0, 1.0)),
)
_MODULE_SPEC = {p[0]: p for p in MODULE_PARAMETERS}

#: Node-wide parameters: (name, default, type, description, constraints, range, read_only).
NODE_PARAMETERS = (
    ('publish_rate', 50.0, _D,
     'Rate (Hz) of the joint_states timer; also the segment rate of speed-limited motion and '
     'the highest rate of equilibrium updates.', '1..1000 Hz', (1.0, 1000.0), False),
    ('markers_rate', 10.0, _D, 'Rate (Hz) of the markers topic; 0 = off.', '0..100 Hz',
     (0.0, 100.0), False),
    ('diagnostics_rate', 1.0, _D, 'Rate (Hz) of /diagnostics.', '0.1..100 Hz',
     (0.1, 100.0), False),
    ('frame_id', 'tensegrity_base', _S,
     'Frame of the markers and head_pose: the base frame of the bottom module (origin A1, '
     'x along A1->A2, y up).',
     'non-empty', None, False),
)
_NODE_SPEC = {p[0]: p for p in NODE_PARAMETERS}


def _effective_stiffness(k, override):
    """``<m>.ka/kb/kc`` of 0.0 means "use ``<m>.k``"."""
    return override if override > 0.0 else k


def _finite_pair(value):
    return (value is not None and len(value) == 2
            and all(isinstance(v, float) and math.isfinite(v) for v in value))


class ModuleSlot:
    """State of one hosted module: configuration, the live verified equilibrium, motion, stats."""

    def __init__(self, name: str, index: int, in_stack: bool = False):
        self.name = name
        self.index = index
        self.in_stack = in_stack                    # part of a stack of N >= 2 modules
        self.prefix = name + '.'
        self.params: ModuleParams | None = None    # live parameters (rho = actuator now)
        self.eq = None                              # live verified stable Equilibrium
        # limits and settings (mirrors of the parameters, for the hot path)
        self.rho_min = 0.0
        self.rho_max = math.inf
        self.max_rho_rate = 0.0
        self.warn_margin = 0.05
        # speed-limited motion
        self.target = None                          # pending rho target, None = idle
        self.target_cause = ''
        self.motion_stamp_ns = 0
        # status
        self.jumps_total = 0
        self.last_jump = None
        self.tracking_status = 'ok'
        self.dirty = True                           # equilibrium status out of date
        self.last_status = None
        self._count_cache = None
        self._range_cache = None
        self.markers = conv.ModuleMarkers(name)

    def counts(self):
        """(num_equilibria, num_stable) of the live parameters (exact, cached); (None, None)
        in a stack (the exact solver is a one-module tool)."""
        if self.in_stack:
            return None, None
        if self._count_cache is None or self._count_cache[0] != self.params:
            found = equilibria(self.params)
            if found.status == 'ok':
                counts = (len(found), found.num_stable)
            else:
                counts = (found.status, found.num_stable)
            self._count_cache = (self.params, counts)
        return self._count_cache[1]

    def operation_range(self):
        """Operation range of the live branch: the rho interval, everything else fixed, over
        which it stays stable, with what ends it (exact; cached, the last range as a hint so
        that a pure rho move costs ~20 us).  ``None`` if it cannot be computed, or in a stack."""
        if self.in_stack:
            return None
        key = (self.params, self.eq.theta1, self.eq.theta2)
        if self._range_cache is None or self._range_cache[0] != key:
            hint = self._range_cache[1] if self._range_cache is not None else None
            try:
                found = operation_range(self.params, self.eq.theta, hint=hint)
            except (ValueError, ArithmeticError, np.linalg.LinAlgError):
                found = None           # degenerate point: no range; the status says 'unknown'
            self._range_cache = (key, found)
        return self._range_cache[1]

    def status_level(self):
        eq = self.eq
        if not eq.stable:
            return conv.ERROR, 'not a stable equilibrium'
        if self.tracking_status != 'ok':
            return conv.WARN, f'tracking stopped early: {self.tracking_status}'
        normalized = self.normalized_margin()
        if normalized < self.warn_margin:
            unit = 'N/m' if self.in_stack else 'J/rad^2'
            return conv.WARN, (f'stable, near a jump: stability margin '
                               f'{eq.stability_margin:.4g} {unit} (normalized {normalized:.3g} '
                               f'< warn_margin {self.warn_margin:g})')
        return conv.OK, f'stable, stability margin {eq.stability_margin:.4g}'

    def normalized_margin(self):
        if self.in_stack:
            return self.eq.normalized
        return conv.normalized_margin(self.params, self.eq)


class TensegrityNode(Node):
    """ROS 2 node: tracks the stable equilibrium of each hosted module and reports jumps.

    ``kwargs`` go to :class:`rclpy.node.Node` (``parameter_overrides``, ``namespace``,
    ``cli_args``, ``context`` ...).  Raises :class:`ConfigurationError` if the
    configuration cannot be used (no traceback is printed by :func:`main` then).
    """

    def __init__(self, node_name: str = DEFAULT_NODE_NAME, **kwargs):
        super().__init__(node_name, **kwargs)
        try:
            self._setup()
        except ConfigurationError:
            self.destroy_node()
            raise

    def _setup(self):
        self._node_clock = self.get_clock()
        self._counters = {f'rejected_{r}': 0 for r in REJECT_REASONS}
        self._counters.update(commands_processed=0, callback_exceptions=0, jump_warnings=0,
                              tracking_failures=0, jumps_total=0)
        self._level_events = set()          # what happened since the last /diagnostics
        self._loggers = {}
        self._last_stable = None
        self._hardware_id = self.get_fully_qualified_name()

        names = self._declare_modules()
        in_stack = len(names) >= 2
        self._slots = [ModuleSlot(m, i, in_stack) for i, m in enumerate(names)]
        self._stack = None              # N >= 2: live Stack (its modules = the slots' params)
        self._stack_eq = None           # N >= 2: live verified StackEquilibrium
        self._stack_jumps = 0
        self._declare_parameters()
        self._warn_unknown_overrides()
        for slot in self._slots:
            self._configure_slot(slot)
        if in_stack:
            stack = Stack(tuple(slot.params for slot in self._slots))
            eq, why = self._settle_stack(stack, self._current_values())
            if eq is None:
                raise ConfigurationError(
                    f'stack {names}: no stable equilibrium from the modules\' initial_theta '
                    f'at rho_initial: {why}')
            self._set_stack(stack, eq)
        self._head = conv.HeadPose()
        self._rho_joints = {f'{s.name}_rho': s for s in self._slots}
        self._js = conv.JointStateBuffer(names)

        # Publishers (names relative so that namespaces and remapping work;
        # /diagnostics is absolute by ROS convention).
        # No per-endpoint QoS event handlers: each is a waitable that the rclpy executor
        # re-adds to its wait set before every callback (about 20 us each).  QoS mismatches
        # are still reported by the peer (ros2 topic pub/echo warn about them).
        def publisher(msg_type, topic, qos):
            return self.create_publisher(
                msg_type, topic, qos,
                event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))

        def subscription(msg_type, topic, callback):
            return self.create_subscription(
                msg_type, topic, self._guard(callback, topic), COMMAND_QOS,
                event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))

        self._js_pub = publisher(JointState, 'joint_states', STATE_QOS)
        self._stable_pub = publisher(Bool, 'stable', STATUS_QOS)
        # one latched status per module: a stack publishes all N together, depth N keeps
        # every module's latest for a late subscriber (N = 1: depth 1, as STATUS_QOS)
        eq_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=len(self._slots),
                            reliability=ReliabilityPolicy.RELIABLE,
                            durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._eq_pub = publisher(DiagnosticStatus, 'equilibrium', eq_qos)
        self._jumps_pub = publisher(DiagnosticStatus, 'jumps', JUMPS_QOS)
        self._diag_pub = publisher(DiagnosticArray, '/diagnostics', STATE_QOS)
        self._markers_pub = publisher(MarkerArray, 'markers', MARKERS_QOS)
        self._head_pub = publisher(PoseStamped, 'head_pose', HEAD_QOS)

        for slot in self._slots:
            subscription(Float64, f'{slot.name}/rho_cmd', self._make_rho_callback(slot))
            for which in ('a3', 'a4'):
                subscription(Vector3, f'{slot.name}/force_{which}',
                             self._make_force_callback(slot, which))
        subscription(JointState, 'joint_commands', self._on_joint_commands)
        self.create_service(Trigger, 'reset', self._on_reset)

        # One timer serves joint_states, speed-limited motion, markers and /diagnostics
        # (fewer wait-set entities = less executor overhead per command).
        self._tick_timer = self.create_timer(
            1.0 / self.get_parameter('publish_rate').value, self._guard(self._on_tick, 'timer'))
        self._periodic = {}         # name -> [period_ns or 0 (off), next due ns]
        now = self._now_ns()
        for name in ('markers_rate', 'diagnostics_rate'):
            self._periodic[name] = [0, now]
            self._set_periodic(name, self.get_parameter(name).value, now)
        self._frame_id = self.get_parameter('frame_id').value

        self.add_pre_set_parameters_callback(self._pre_set_parameters)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)

        self._publish_joint_states()
        self._publish_head_pose()
        for slot in self._slots:
            self._publish_status(slot)
        self._on_markers_tick()
        for slot in self._slots:
            eq = slot.eq
            self.get_logger().info(
                f'{slot.name}: rho={slot.params.rho:.6g} m, theta=({eq.theta1:.6g}, '
                f'{eq.theta2:.6g}) rad, stable, margin {eq.stability_margin:.4g}')

    # -- start-up --------------------------------------------------------------------------

    def _declare_modules(self):
        try:
            names = self.declare_parameter(
                'modules', ['m0'],
                _descriptor('Hosted modules, bottom to top (names of topics and parameter '
                            'prefixes). Read-only. One module, or a stack (neck) of up to '
                            f'{MAX_MODULES}: module i+1 sits on the top chord of module i.',
                            type_=_SA, read_only=True,
                            constraints=f'1..{MAX_MODULES} distinct module names')).value
        except ParameterException as exc:
            raise ConfigurationError(f'parameter modules: {exc}') from None
        names = list(names or [])
        if not 1 <= len(names) <= MAX_MODULES:
            raise ConfigurationError(
                f'modules: {len(names)} modules given; a node hosts 1 to {MAX_MODULES} '
                f'modules (bottom to top), e.g. [m0] or [m0, m1, m2]')
        if len(set(names)) != len(names):
            raise ConfigurationError(f'modules={names}: module names must be distinct')
        for m in names:
            if not _MODULE_NAME.match(m):
                raise ConfigurationError(
                    f'module name {m!r}: use a letter followed by letters, digits or _')
        return names

    def _coerce_overrides(self, types):
        """Integers given for double parameters (``L1: 1`` in YAML) are taken as doubles."""
        overrides = self._parameter_overrides
        for name, type_ in types.items():
            p = overrides.get(name)
            if p is None:
                continue
            if type_ == _D and p.type_ == Parameter.Type.INTEGER:
                overrides[name] = Parameter(name, _D, float(p.value))
            elif type_ == _DA and p.type_ == Parameter.Type.INTEGER_ARRAY:
                overrides[name] = Parameter(name, _DA, [float(v) for v in p.value])

    def _parameter_types(self):
        types = {name: spec[2] for name, spec in _NODE_SPEC.items()}
        for slot in self._slots:
            types.update({slot.prefix + name: spec[2] for name, spec in _MODULE_SPEC.items()})
        return types

    def _declare_parameters(self):
        self._coerce_overrides(self._parameter_types())
        declarations = []
        for name, default, type_, description, constraints, range_, read_only in NODE_PARAMETERS:
            declarations.append((name, default, _descriptor(
                description, type_=type_, constraints=constraints, range_=range_,
                read_only=read_only)))
        for slot in self._slots:
            for name, default, type_, _kind, description, constraints, range_ in MODULE_PARAMETERS:
                declarations.append((slot.prefix + name, default, _descriptor(
                    description, type_=type_, constraints=constraints, range_=range_)))
        self._declared = [name for name, _, _ in declarations]
        for name, default, descriptor in declarations:
            try:
                self.declare_parameter(name, default, descriptor)
            except (InvalidParameterTypeException, InvalidParameterValueException,
                    ParameterException) as exc:
                raise ConfigurationError(f'parameter {name}: {exc}') from None
        reason = self._check_node_values(self._current_values())
        if reason:
            raise ConfigurationError(reason)

    def _warn_unknown_overrides(self):
        known = set(self._declared) | {'modules', 'use_sim_time'}
        for name in sorted(set(self._parameter_overrides) - known):
            self.get_logger().warning(f'ignoring unknown parameter {name!r}')

    def _configure_slot(self, slot):
        values = self._current_values()
        get = self._module_getter(slot, values)
        reason = self._check_module_values(slot, get, live_rho=get('rho_initial'), target=None)
        if reason:
            raise ConfigurationError(reason)
        self._mirror_settings(slot, get)
        params = self._module_params(get, get('rho_initial'), get('force_a3'), get('force_a4'))
        if slot.in_stack:
            slot.params = params            # the stack settles as a whole (_setup)
            return
        try:
            eq = settle(params, get('initial_theta'))
        except (TrackingError, ValueError) as exc:
            eq, why = None, str(exc)
        else:
            why = 'settled on a state that is not a stable equilibrium'
        if eq is None or not eq.stable:
            raise ConfigurationError(
                f'{slot.name}: no stable equilibrium from initial_theta '
                f'{list(get("initial_theta"))} at rho={params.rho}: {why}')
        slot.eq = eq
        slot.params = params

    def _settle_stack(self, stack, values):
        """(stable StackEquilibrium from every module's initial_theta, '') or (None, why)."""
        guess = [self._module_getter(slot, values)('initial_theta') for slot in self._slots]
        try:
            eq = settle_stack(stack, guess)
        except (TrackingError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            return None, str(exc)
        if not eq.stable:
            return None, 'settled on a state that is not a stable equilibrium'
        return eq, ''

    def _set_stack(self, stack, eq):
        """Make (stack, eq) the live state of a stack and of every module's slot."""
        self._stack, self._stack_eq = stack, eq
        scale = min(min(m.ka, m.kb, m.kc) for m in stack.modules)
        for slot, params in zip(self._slots, stack.modules):
            slot.params = params
            slot.eq = conv.StackModuleState(eq, slot.index, scale)
            slot.dirty = True

    # -- parameter values and checks ------------------------------------------------------

    def _current_values(self):
        return {p.name: p.value for p in self.get_parameters(self._declared)}

    @staticmethod
    def _module_getter(slot, values):
        def get(key):
            value = values[slot.prefix + key]
            if _MODULE_SPEC[key][2] == _DA and value is not None:
                return [float(v) for v in value]
            return value
        return get

    @staticmethod
    def _module_params(get, rho, force_a3, force_a4):
        k = get('k')
        return ModuleParams(
            rho=rho, L1=get('L1'), L2=get('L2'),
            ka=_effective_stiffness(k, get('ka')), kb=_effective_stiffness(k, get('kb')),
            kc=_effective_stiffness(k, get('kc')),
            f3x=force_a3[0], f3y=force_a3[1], f4x=force_a4[0], f4y=force_a4[1],
            m1=get('m1'), m2=get('m2'))

    @staticmethod
    def _mirror_settings(slot, get):
        slot.rho_min = get('rho_min')
        slot.rho_max = get('rho_max')
        slot.max_rho_rate = get('max_rho_rate')
        slot.warn_margin = get('warn_margin')

    def _check_module_values(self, slot, get, live_rho, target):
        """Why these module parameter values are refused, or '' if they are fine."""
        m = slot.name
        for key in ('L1', 'L2', 'k'):
            v = get(key)
            if not (math.isfinite(v) and v > 0.0):
                return f'{m}.{key} must be finite and > 0, got {v!r}'
        for key, meaning in (('ka', '0.0 = use k'), ('kb', '0.0 = use k'),
                             ('kc', '0.0 = use k'), ('m1', 'kg'), ('m2', 'kg')):
            v = get(key)
            if not (math.isfinite(v) and v >= 0.0):
                return f'{m}.{key} must be finite and >= 0 ({meaning}), got {v!r}'
        for key in ('force_a3', 'force_a4', 'initial_theta'):
            v = get(key)
            if not _finite_pair(v):
                return f'{m}.{key} must be two finite numbers, got {v!r}'
        lo, hi, initial = get('rho_min'), get('rho_max'), get('rho_initial')
        if not (math.isfinite(lo) and lo > 0.0):
            return f'{m}.rho_min must be finite and > 0, got {lo!r}'
        if not (math.isfinite(hi) and hi > lo):
            return f'{m}.rho_max must be finite and > rho_min ({lo!r}), got {hi!r}'
        if not (math.isfinite(initial) and lo <= initial <= hi):
            return f'{m}.rho_initial={initial!r} must lie in [rho_min, rho_max] = [{lo!r}, {hi!r}]'
        if not lo <= live_rho <= hi:
            return (f'{m}: the actuator is at rho={live_rho!r}, outside the requested '
                    f'[rho_min, rho_max] = [{lo!r}, {hi!r}]')
        if target is not None and not lo <= target <= hi:
            return (f'{m}: the pending target rho={target!r} is outside the requested '
                    f'[rho_min, rho_max] = [{lo!r}, {hi!r}]')
        try:
            self._module_params(get, live_rho, get('force_a3'), get('force_a4'))
            for rho in (lo, hi):            # every length the actuator may reach
                check_supported(self._module_params(get, rho, get('force_a3'), get('force_a4')))
        except InvalidParameterError as exc:
            return f'{m}: {exc}'
        return ''

    @staticmethod
    def _check_node_values(values):
        if not values['frame_id']:
            return 'frame_id must not be empty'
        return ''

    def _pre_set_parameters(self, parameters):
        """Runs before rclpy's own checks: coerce int -> double, count what rclpy will refuse."""
        try:
            out = []
            for p in parameters:
                if not self.has_parameter(p.name):
                    self._reject('parameter_undeclared', f'no parameter named {p.name!r}')
                    out.append(p)
                    continue
                d = self.describe_parameter(p.name)
                if d.type == _D.value and p.type_ == Parameter.Type.INTEGER:
                    p = Parameter(p.name, _D, float(p.value))
                elif d.type == _DA.value and p.type_ == Parameter.Type.INTEGER_ARRAY:
                    p = Parameter(p.name, _DA, [float(v) for v in p.value])
                if d.read_only:
                    self._reject('parameter_read_only', f'{p.name} is read-only')
                elif p.type_.value != d.type:
                    self._reject('parameter_type',
                                 f'{p.name}: wrong type {p.type_.name}, expected '
                                 f'{Parameter.Type(d.type).name}')
                elif d.floating_point_range and p.type_ == _D:
                    r = d.floating_point_range[0]
                    if not r.from_value <= p.value <= r.to_value:
                        self._reject('parameter_value',
                                     f'{p.name}={p.value!r} outside [{r.from_value}, '
                                     f'{r.to_value}]')
                out.append(p)
            return out
        except Exception as exc:        # never raise into rclpy
            self._count_exception('pre-set parameters', exc)
            return parameters

    def _validate_parameters(self, parameters):
        """on-set callback: accept or refuse (with a reason) without changing any state."""
        try:
            reason = self._refusal(parameters)
        except Exception as exc:
            self._count_exception('parameter validation', exc)
            reason = f'internal error while validating: {exc!r}'
        if reason:
            self._reject('parameter_value', f'parameter change refused: {reason}')
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _refusal(self, parameters):
        values = self._current_values()
        for p in parameters:
            if p.type_ == Parameter.Type.NOT_SET:
                return f'{p.name} cannot be unset'
            values[p.name] = p.value
        reason = self._check_node_values(values)
        if reason:
            return reason
        for slot in self._affected_slots(parameters):
            reason = self._check_module_values(slot, self._module_getter(slot, values),
                                               live_rho=slot.params.rho, target=slot.target)
            if reason:
                return reason
        return ''

    def _affected_slots(self, parameters):
        names = [p.name for p in parameters]
        return [s for s in self._slots if any(n.startswith(s.prefix) for n in names)]

    def _apply_parameters(self, parameters):
        """post-set callback: the new values are stored; move the mechanism accordingly."""
        try:
            names = {p.name for p in parameters}
            if 'publish_rate' in names:
                self._tick_timer.timer_period_ns = int(1e9 / self.get_parameter(
                    'publish_rate').value)
            for name in ('markers_rate', 'diagnostics_rate'):
                if name in names:
                    self._set_periodic(name, self.get_parameter(name).value, self._now_ns())
            if 'frame_id' in names:
                self._frame_id = self.get_parameter('frame_id').value
            values = self._current_values()
            affected = self._affected_slots(parameters)
            if self._stack is not None:
                return self._apply_stack_parameters(parameters, affected, values)
            for slot in affected:
                get = self._module_getter(slot, values)
                self._mirror_settings(slot, get)
                slot.dirty = True
                keys = {n[len(slot.prefix):] for n in names if n.startswith(slot.prefix)}
                kinds = {_MODULE_SPEC[k][3] for k in keys}
                if kinds & {PHYSICAL, FORCE}:
                    self._advance(slot, self._now_ns())
                    live = slot.params
                    f3 = get('force_a3') if 'force_a3' in keys else (live.f3x, live.f3y)
                    f4 = get('force_a4') if 'force_a4' in keys else (live.f4x, live.f4y)
                    end = self._module_params(get, live.rho, f3, f4)
                    self._move(slot, end, 'parameter ' + ', '.join(sorted(keys)))
                    self._counters['commands_processed'] += 1
                    self._publish_joint_states()
                self._publish_status(slot)
        except Exception as exc:
            self._count_exception('parameter change', exc)

    def _apply_stack_parameters(self, parameters, affected, values):
        """Stack (N >= 2): every physical/force change of one parameter set is one path.

        The jump reports name the module of the first parameter named in the set."""
        now = self._now_ns()
        for slot in affected:
            self._mirror_settings(slot, self._module_getter(slot, values))
            slot.dirty = True
            self._advance(slot, now)
        changes, keys_all, trigger = {}, [], None
        for p in parameters:
            slot = next((s for s in affected if p.name.startswith(s.prefix)), None)
            if slot is None:
                continue
            key = p.name[len(slot.prefix):]
            if _MODULE_SPEC[key][3] not in (PHYSICAL, FORCE):
                continue
            if trigger is None:
                trigger = slot
            keys_all.append(p.name)
            if slot.index not in changes:
                changes[slot.index] = set()
            changes[slot.index].add(key)
        if changes:
            ends = {}
            for index, keys in changes.items():
                slot = self._slots[index]
                get = self._module_getter(slot, values)
                live = slot.params
                f3 = get('force_a3') if 'force_a3' in keys else (live.f3x, live.f3y)
                f4 = get('force_a4') if 'force_a4' in keys else (live.f4x, live.f4y)
                ends[index] = self._module_params(get, live.rho, f3, f4)
            self._move_stack(ends, 'parameter ' + ', '.join(sorted(keys_all)), trigger)
            self._counters['commands_processed'] += 1
            self._publish_joint_states()
        self._publish_dirty_statuses()

    def _set_periodic(self, name, rate, now_ns):
        """markers_rate / diagnostics_rate: served by the publish_rate timer (0 = off)."""
        entry = self._periodic[name]
        entry[0] = int(1e9 / rate) if rate > 0.0 else 0
        entry[1] = now_ns + entry[0]

    # -- input handling -------------------------------------------------------------------

    def _guard(self, callback, what):
        """Wrap a ROS callback: an unexpected exception is logged and counted, never raised."""
        def guarded(*args):
            try:
                return callback(*args)
            except Exception as exc:
                self._count_exception(what, exc)
        return guarded

    def _count_exception(self, what, exc):
        self._counters['callback_exceptions'] += 1
        self._level_events.add('exception')
        self._throttled('exception').error(
            f'{what}: unexpected {type(exc).__name__}: {exc} (state unchanged; '
            f'{self._counters["callback_exceptions"]} so far)',
            throttle_duration_sec=WARN_THROTTLE_SEC)
        self.get_logger().debug(traceback.format_exc())

    def _throttled(self, key):
        """A logger of this node's name with its own throttle state (one per reason)."""
        logger = self._loggers.get(key)
        if logger is None:
            logger = self._loggers[key] = rclpy.logging.get_logger(self.get_logger().name)
        return logger

    def _reject(self, reason, text):
        key = f'rejected_{reason}'
        self._counters[key] += 1
        self._level_events.add('rejected')
        self._throttled(reason).warning(
            f'{text}: dropped ({key} = {self._counters[key]})',
            throttle_duration_sec=WARN_THROTTLE_SEC)

    def _make_rho_callback(self, slot):
        topic = f'{slot.name}/rho_cmd'

        def on_rho_cmd(msg):
            value = msg.data
            if not math.isfinite(value):
                return self._reject('non_finite', f'{topic}: {value!r} is not finite')
            if not slot.rho_min <= value <= slot.rho_max:
                return self._reject('out_of_range', f'{topic}: {value!r} outside [rho_min, '
                                                    f'rho_max] = [{slot.rho_min}, {slot.rho_max}]')
            self._publish_joint_states(self._command_rho(slot, value, 'rho_cmd'))
        return on_rho_cmd

    def _make_force_callback(self, slot, which):
        topic = f'{slot.name}/force_{which}'
        fields = ('f3x', 'f3y') if which == 'a3' else ('f4x', 'f4y')

        def on_force(msg):
            x, y = msg.x, msg.y          # z is ignored (planar mechanism)
            if not (math.isfinite(x) and math.isfinite(y)):
                return self._reject('non_finite', f'{topic}: ({x!r}, {y!r}) is not finite')
            forces = {fields[0]: x, fields[1]: y}
            try:
                end = check_supported(slot.params.with_(**forces))
            except InvalidParameterError as exc:     # beyond the supported magnitudes
                return self._reject('out_of_range', f'{topic}: {exc}')
            self._counters['commands_processed'] += 1
            now = self._now_ns()
            live = slot.params
            self._advance(slot, now)
            if slot.params is not live:              # a pending motion moved rho first
                end = slot.params.with_(**forces)
            self._move(slot, end, f'force_{which}')
            self._publish_joint_states(now)
        return on_force

    def _on_joint_commands(self, msg):
        names, positions = msg.name, msg.position
        if not names:
            return self._reject('size_mismatch', 'joint_commands: no joint names')
        if len(names) != len(positions):
            return self._reject('size_mismatch', f'joint_commands: {len(names)} names but '
                                                 f'{len(positions)} positions')
        targets = {}
        for name, value in zip(names, positions):
            slot = self._rho_joints.get(name)
            if slot is None:
                return self._reject('unknown_joint', f'joint_commands: unknown joint {name!r} '
                                                     f'(commandable: {sorted(self._rho_joints)})')
            if slot.name in targets:
                return self._reject('duplicate_joint', f'joint_commands: {name!r} given twice')
            if not math.isfinite(value):
                return self._reject('non_finite', f'joint_commands: {name} = {value!r} '
                                                  f'is not finite')
            if not slot.rho_min <= value <= slot.rho_max:
                return self._reject('out_of_range', f'joint_commands: {name} = {value!r} outside '
                                                    f'[{slot.rho_min}, {slot.rho_max}]')
            targets[slot.name] = (slot, value)
        if self._stack is not None and not any(s.max_rho_rate > 0.0 for s, _ in
                                               targets.values()):
            # a stack: every target on one straight path; jumps name the first joint's module
            self._counters['commands_processed'] += len(targets)
            ends = {}
            for slot, value in targets.values():
                slot.target = None
                if value != slot.params.rho:
                    ends[slot.index] = slot.params.with_(rho=value)
            if ends:
                trigger = next(iter(targets.values()))[0]
                self._move_stack(ends, 'joint_commands', trigger)
            return self._publish_joint_states()
        # one message, one start time: every speed-limited target starts moving at the time
        # the published state is stamped with (not one clock reading per joint)
        now = self._now_ns()
        for slot, value in targets.values():
            self._command_rho(slot, value, 'joint_commands', now)
        self._publish_joint_states(now)

    def _on_reset(self, request, response):
        try:
            values = self._current_values()
            if self._stack is not None:
                return self._reset_stack(values, response)
            settled = []
            for slot in self._slots:
                get = self._module_getter(slot, values)
                params = self._module_params(get, get('rho_initial'), get('force_a3'),
                                             get('force_a4'))
                try:
                    eq = settle(params, get('initial_theta'))
                except (TrackingError, ValueError) as exc:
                    eq, why = None, str(exc)
                else:
                    why = 'not a stable equilibrium'
                if eq is None or not eq.stable:
                    response.success = False
                    response.message = (f'reset failed, state unchanged: {slot.name}: no stable '
                                        f'equilibrium from initial_theta: {why}')
                    self.get_logger().error(response.message)
                    return response
                settled.append((slot, params, eq))
            parts = []
            self._last_stable = None            # republish stable too
            for slot, params, eq in settled:
                slot.params, slot.eq = params, eq
                slot.target = None
                slot.jumps_total, slot.last_jump = 0, None
                slot.tracking_status = 'ok'
                self._publish_status(slot)
                parts.append(f'{slot.name}: rho={params.rho!r} theta=({eq.theta1!r}, '
                             f'{eq.theta2!r})')
            self._publish_joint_states()
            self._publish_head_pose()
            self._on_markers_tick()
            response.success = True
            response.message = 'reset to the initial state; ' + '; '.join(parts)
            self.get_logger().info(response.message)
        except Exception as exc:
            self._count_exception('reset', exc)
            response.success = False
            response.message = f'reset failed, state unchanged: {type(exc).__name__}: {exc}'
        return response

    def _reset_stack(self, values, response):
        """Reset of a stack: settle the initial stack from every module's initial_theta."""
        modules = []
        for slot in self._slots:
            get = self._module_getter(slot, values)
            modules.append(self._module_params(get, get('rho_initial'), get('force_a3'),
                                               get('force_a4')))
        stack = Stack(tuple(modules))
        eq, why = self._settle_stack(stack, values)
        if eq is None:
            response.success = False
            response.message = (f'reset failed, state unchanged: no stable equilibrium of the '
                                f'stack from initial_theta: {why}')
            self.get_logger().error(response.message)
            return response
        self._set_stack(stack, eq)
        self._stack_jumps = 0
        self._last_stable = None
        for slot in self._slots:
            slot.target = None
            slot.jumps_total, slot.last_jump = 0, None
            slot.tracking_status = 'ok'
            self._publish_status(slot)
        self._publish_joint_states()
        self._publish_head_pose()
        self._on_markers_tick()
        response.success = True
        response.message = 'reset to the initial state; ' + '; '.join(
            f'{slot.name}: rho={slot.params.rho!r} theta=({slot.eq.theta1!r}, '
            f'{slot.eq.theta2!r})' for slot in self._slots)
        self.get_logger().info(response.message)
        return response

    # -- motion ---------------------------------------------------------------------------

    def _now_ns(self):
        return self._node_clock.now().nanoseconds

    def _command_rho(self, slot, value, cause, now=None):
        """Apply an actuator target received at ``now`` (ns, default: now); returns the time
        (ns) the new state holds for."""
        self._counters['commands_processed'] += 1
        self._warn_if_jump_ahead(slot, value, cause)
        if slot.max_rho_rate > 0.0:
            now = self._now_ns() if now is None else now
            self._advance(slot, now)
            slot.target = None if value == slot.params.rho else value
            slot.target_cause = cause
            slot.motion_stamp_ns = now
            return now
        slot.target = None
        if value != slot.params.rho:
            self._move(slot, slot.params.with_(rho=value), cause)
        return None

    def _warn_if_jump_ahead(self, slot, target, cause):
        """WARN (throttled, counted) before a command that leaves the live branch's
        operation range: the mechanism will jump at the fold or branch point on the way."""
        found = slot.operation_range()
        if found is None:
            return
        end = found.lower if target < found.lower.rho else (
            found.upper if target > found.upper.rho else None)
        if end is None or end.kind == 'limit':
            return
        self._counters['jump_warnings'] += 1
        self._throttled('jump_ahead').warning(
            f'{slot.name}: {cause} to rho={target!r} leaves the stable branch at '
            f'rho={end.rho!r} ({end.kind}): the mechanism will jump there',
            throttle_duration_sec=WARN_THROTTLE_SEC)

    def _advance(self, slot, now_ns):
        """Speed-limited motion: move toward the pending target by max_rho_rate * elapsed."""
        target = slot.target
        if target is None:
            return
        dt = max(0, now_ns - slot.motion_stamp_ns) * 1e-9
        rate = slot.max_rho_rate
        rho = slot.params.rho
        if rate <= 0.0 or abs(target - rho) <= rate * dt:
            new_rho = target
            slot.target = None
        elif dt <= 0.0:
            return
        else:
            new_rho = rho + math.copysign(rate * dt, target - rho)
        slot.motion_stamp_ns = now_ns
        self._move(slot, slot.params.with_(rho=new_rho), slot.target_cause)
        if slot.tracking_status != 'ok':
            slot.target = None

    def _move(self, slot, end, cause):
        """Track the live equilibrium from the live parameters to ``end`` (one straight path)."""
        if end == slot.params:
            return
        if self._stack is not None:
            return self._move_stack({slot.index: end}, cause, slot)
        try:
            track = track_module(slot.params, end, slot.eq.theta)
        except TrackingError as exc:
            self._tracking_failed(slot, f'{cause}: {exc}')
            return
        final = track.final
        if not self._verified_minimum(final, slot, cause):
            return
        slot.params, slot.eq = track.end, final
        slot.dirty = True
        for jump in track.jumps:
            self._report_jump(slot, jump, cause)
        if track.status != 'ok':
            self._tracking_failed(slot, f'{cause}: stopped at rho={track.end.rho!r}: '
                                        f'{track.message}')
        elif slot.tracking_status != 'ok':
            slot.tracking_status = 'ok'

    def _verified_minimum(self, final, slot, cause):
        """The tracker guarantees a verified minimum; never publish anything else (a
        failure counted against ``slot`` otherwise)."""
        low, high = final.eigenvalues[0], final.eigenvalues[-1]
        if low > DEFINITENESS_TOL * abs(high):
            return True
        self._tracking_failed(slot, f'{cause}: tracker returned an unstable state')
        return False

    def _move_stack(self, ends, cause, trigger):
        """Stack: track the live StackEquilibrium from the live stack to the stack whose
        modules ``ends`` (index -> ModuleParams) replace the live ones, on one straight path.
        Jumps are reported as triggered by the slot ``trigger``."""
        start = self._stack
        end = Stack(tuple(ends.get(slot.index, slot.params) for slot in self._slots))
        if end == start:
            return
        try:
            track = track_stack(start, end, self._stack_eq)
        except (TrackingError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            self._tracking_failed(trigger, f'{cause}: {exc}')
            return
        final = track.final
        if not self._verified_minimum(final, trigger, cause):
            return
        self._set_stack(track.end, final)
        for jump in track.jumps:
            self._report_stack_jump(trigger, jump, cause)
        if track.status != 'ok':
            self._tracking_failed(trigger, f'{cause}: stopped at {trigger.name} '
                                           f'rho={trigger.params.rho!r}: {track.message}')
        else:
            for slot in self._slots:
                slot.tracking_status = 'ok'
        if track.jumps:
            for slot in self._slots:
                self._publish_status(slot)

    def _report_stack_jump(self, trigger, jump, cause):
        self._stack_jumps += 1
        self._counters['jumps_total'] += 1
        for slot in self._slots:        # the whole stack jumped: every module records it
            slot.jumps_total = self._stack_jumps
            slot.last_jump = ModuleJump(kind=jump.kind, s=jump.s,
                                        params=jump.stack.modules[slot.index],
                                        from_theta=jump.from_theta[slot.index],
                                        to_theta=jump.to_theta[slot.index],
                                        ambiguous=jump.ambiguous)
        msg = conv.stack_jump_status(
            name=f'{self.get_name()}: {trigger.name} jump', hardware_id=self._hardware_id,
            modules=self.modules, index=trigger.index, jump=jump, cause=cause,
            count=self._stack_jumps)
        self._jumps_pub.publish(msg)
        self.get_logger().warning(f'{trigger.name}: stack jump ({cause}): {msg.message}')

    def _tracking_failed(self, slot, text):
        self._counters['tracking_failures'] += 1
        self._level_events.add('tracking')
        slot.tracking_status = text
        slot.dirty = True
        self._throttled('tracking').warning(
            f'{slot.name}: tracking failed ({text}); holding the last verified equilibrium',
            throttle_duration_sec=WARN_THROTTLE_SEC)

    def _report_jump(self, slot, jump, cause):
        slot.jumps_total += 1
        slot.last_jump = jump
        self._counters['jumps_total'] += 1
        msg = conv.jump_status(name=f'{self.get_name()}: {slot.name} jump',
                               hardware_id=self._hardware_id, module=slot.name, jump=jump,
                               cause=cause, index=slot.jumps_total)
        self._jumps_pub.publish(msg)
        self.get_logger().warning(f'{slot.name}: jump ({cause}): {msg.message}')
        self._publish_status(slot)

    # -- publishing -----------------------------------------------------------------------

    def _publish_joint_states(self, now_ns=None):
        """Publish the live state, stamped ``now_ns`` (the time it holds for) or now."""
        js = self._js
        for slot in self._slots:
            eq = slot.eq
            js.set_module(slot.index, slot.params.rho, eq.theta1, eq.theta2, eq.actuator_force)
        self._js_pub.publish(js.stamped(self._now_ns() if now_ns is None else now_ns))

    def _publish_status(self, slot):
        level, message = slot.status_level()
        num, num_stable = slot.counts()
        status = conv.equilibrium_status(
            name=f'{self.get_name()}: {slot.name}', hardware_id=self._hardware_id,
            module=slot.name, params=slot.params, eq=slot.eq, level=level, message=message,
            num_equilibria=num, num_stable=num_stable, last_jump=slot.last_jump,
            jumps_total=slot.jumps_total, tracking_status=slot.tracking_status,
            warn_margin=slot.warn_margin, operation_range=slot.operation_range(),
            normalized=slot.normalized_margin())
        slot.last_status = status
        slot.dirty = False
        self._eq_pub.publish(status)
        stable = all(s.eq.stable for s in self._slots)
        if stable != self._last_stable:
            self._last_stable = stable
            self._stable_pub.publish(Bool(data=stable))

    def _publish_dirty_statuses(self):
        """equilibrium of every module whose status is out of date; in a stack all N
        together (in module order) as soon as one is, so the last N latched are one each."""
        slots = self._slots
        if self._stack is not None:
            if any(slot.dirty for slot in slots):
                for slot in slots:
                    self._publish_status(slot)
            return
        for slot in slots:
            if slot.dirty:
                self._publish_status(slot)

    def _on_tick(self):
        now = self._now_ns()
        for slot in self._slots:
            if slot.target is not None:
                self._advance(slot, now)
        self._publish_joint_states(now)
        self._publish_head_pose()
        self._publish_dirty_statuses()
        for name, action in (('markers_rate', self._on_markers_tick),
                             ('diagnostics_rate', self._publish_diagnostics)):
            entry = self._periodic[name]
            if entry[0] and now >= entry[1]:
                # next due time on the period grid, skipping missed ticks
                entry[1] += entry[0] * max(1, (now - entry[1]) // entry[0] + 1)
                action()

    def _on_markers_tick(self):
        stamp = self._node_clock.now().to_msg()
        markers = []
        for slot in self._slots:
            level, _ = slot.status_level()
            if self._stack is not None:
                positions = conv.stack_module_nodes(self._stack_eq.nodes, slot.index)
            else:
                positions = node_positions(slot.params, slot.eq.theta)
            size = max(slot.params.L1, slot.params.L2)
            markers.extend(slot.markers.update(positions, level, self._frame_id, stamp, size))
        self._markers_pub.publish(conv.marker_array(markers))

    def _publish_head_pose(self):
        """head_pose: midpoint and direction of the top chord A4 -> A3, in the base frame."""
        if self._stack is not None:
            position, angle = self._stack_eq.head_position, self._stack_eq.head_angle
        else:
            slot = self._slots[0]
            position, angle = conv.head_of(node_positions(slot.params, slot.eq.theta))
        self._head_pub.publish(self._head.update(position, angle, self._frame_id,
                                                 self._node_clock.now().to_msg()))

    def _publish_diagnostics(self):
        events, self._level_events = self._level_events, set()
        if 'exception' in events:
            level, message = conv.ERROR, 'unexpected exception in a callback (see log)'
        elif events:
            parts = []
            if 'rejected' in events:
                parts.append('input rejected')
            if 'tracking' in events:
                parts.append('tracking failed')
            level, message = conv.WARN, ', '.join(parts) + ' since the last report'
        else:
            level, message = conv.OK, 'ok'
        node_status = DiagnosticStatus(level=level, name=f'{self.get_name()}: node',
                                       message=message, hardware_id=self._hardware_id)
        counters = dict(self._counters)
        counters['rejected_total'] = sum(v for k, v in counters.items()
                                         if k.startswith('rejected_'))
        node_status.values = conv.key_values(sorted(counters.items()))
        statuses = [node_status]
        self._publish_dirty_statuses()
        for slot in self._slots:
            if slot.last_status is None:
                self._publish_status(slot)
            statuses.append(slot.last_status)
        msg = DiagnosticArray(status=statuses)
        msg.header.stamp = self._node_clock.now().to_msg()
        self._diag_pub.publish(msg)

    # -- introspection (tests, tools) ----------------------------------------------------

    @property
    def modules(self):
        return [s.name for s in self._slots]

    def module_state(self, name='m0'):
        """(live ModuleParams, live verified Equilibrium) of a module (in a stack: a
        :class:`~tensegrity_ros.ros_conversions.StackModuleState`)."""
        slot = next(s for s in self._slots if s.name == name)
        return slot.params, slot.eq

    def stack_state(self):
        """(live Stack, live verified StackEquilibrium) of a stack; (None, None) for N = 1."""
        return self._stack, self._stack_eq

    @property
    def counters(self):
        return dict(self._counters)


def _make_executor(kind):
    """The executor ``main`` spins: ``events`` (default) or ``single``.

    ``events`` is rclpy's C++ events executor (``rclpy.experimental.EventsExecutor``,
    shipped with Jazzy's rclpy): it dispatches a callback for a fraction of the Python
    SingleThreadedExecutor's per-callback cost, which is what lets the node keep up with
    1 kHz commands.  ``single`` is the classic ``rclpy.spin`` executor.
    """
    if kind == 'events':
        try:
            from rclpy.experimental import EventsExecutor
            return EventsExecutor()
        except ImportError:           # an rclpy without it: fall back
            pass
    return rclpy.executors.SingleThreadedExecutor()


def _parse_cli(argv):
    import argparse
    parser = argparse.ArgumentParser(
        prog='tensegrity_node',
        description='Tensegrity module node: tracks the stable equilibrium, reports jumps. '
                    'ROS arguments follow --ros-args (e.g. --params-file config/default.yaml).')
    parser.add_argument('--executor', choices=('events', 'single'), default='events',
                        help='events: rclpy EventsExecutor (fast, default); '
                             'single: SingleThreadedExecutor (rclpy.spin)')
    return parser.parse_args(rclpy.utilities.remove_ros_args(argv)[1:])


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def main(args=None):
    """Entry point of ``tensegrity_node``: 0 on normal exit or Ctrl-C, 2 on a bad configuration."""
    argv = sys.argv if args is None else args
    options = _parse_cli(argv)
    node = None
    executor = None
    try:
        # SIGINT and SIGTERM both end in KeyboardInterrupt here (rclpy's handlers, installed
        # by rclpy.init, shut the context down first and then chain to these).
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, _interrupt)
        rclpy.init(args=argv)
        node = TensegrityNode()
        executor = _make_executor(options.executor)
        executor.add_node(node)
        # spin_once in a loop rather than spin(): the events executor's spin() does not
        # return on a shutdown from the SIGINT/SIGTERM handler, spin_once does.
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    except ConfigurationError as exc:
        rclpy.logging.get_logger(DEFAULT_NODE_NAME).fatal(f'invalid configuration: {exc}')
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        # A SIGINT/SIGTERM that arrives while the node is starting shuts the context down
        # under it (e.g. "publisher's context is invalid"): that is a normal exit.
        if rclpy.ok():
            raise
    finally:
        _quietly(executor.shutdown if executor is not None else None)
        _quietly(node.destroy_node if node is not None else None)
        _quietly(rclpy.try_shutdown)
    return 0


def _quietly(cleanup):
    """Run a clean-up step; tolerate the signal handler shutting the context concurrently.

    rclpy's SIGINT/SIGTERM handler shuts the context down from its own thread: a
    ``try_shutdown`` racing with it can raise "rcl_shutdown already called".
    """
    if cleanup is None:
        return
    try:
        cleanup()
    except Exception:
        if rclpy.ok():
            raise


if __name__ == '__main__':
    sys.exit(main())
