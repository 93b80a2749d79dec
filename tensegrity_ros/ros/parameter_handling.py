"""The node's parameters: declared at start-up, checked and applied at runtime, read back.

A mixin of :class:`tensegrity_ros.ros.node.TensegrityNode`, kept apart so that the node stays a
thin layer of message callbacks:

* start-up: declare the modules and every parameter (ros.parameters), refuse an unusable
  configuration (:class:`ConfigurationError`), and make the core simulator from the values;
* pre-set: count what rclpy will refuse (type, read-only, undeclared, delete, range);
* on-set: accept or refuse a set as a whole, with a reason, changing nothing
  (ros.parameters / module_parameters say what is refused);
* post-set: apply node settings, then every physical or force change of the set as one
  tracked path of the simulator;
* read back: the design and force parameters are set to the live values whatever changed
  them (a force message, a path stopped early), bypassing these callbacks.

It uses the node's simulator (``_sim``), its command report (``_command``, ``_events``)
and its counts of refused input and failures (``_incidents``).
"""
from __future__ import annotations

import re

from rcl_interfaces.msg import SetParametersResult
from rclpy.exceptions import (InvalidParameterTypeException, InvalidParameterValueException,
                              ParameterException)
from rclpy.parameter import Parameter

from tensegrity_ros.core.simulation.dynamic_simulator import DynamicSimulator
from tensegrity_ros.core.simulation.simulator import Simulator
from tensegrity_ros.log_text import shown
from tensegrity_ros.ros import parameters as params

_MODULE_NAME = re.compile(r'^[A-Za-z][A-Za-z0-9_]*$')


class ConfigurationError(RuntimeError):
    """The node's start-up configuration (parameters) cannot be used."""


class ParameterHandling:
    """The node's parameters (a mixin: see the module docstring)."""

    # -- start-up: parameters -> simulator ---------------------------------------------

    def _declare_modules(self):
        try:
            names = self.declare_parameter(
                'modules', ['m0'],
                params.descriptor(
                    'Hosted modules, bottom to top (names of topics and parameter '
                    'prefixes). Read-only. One module, or a stack (neck) of up to '
                    f'{params.MAX_MODULES}: module i+1 sits on the top chord of module i.',
                    type_=params.STRING_ARRAY, read_only=True,
                    constraints=f'1..{params.MAX_MODULES} distinct module names')).value
        except ParameterException as exc:
            raise ConfigurationError(f'parameter modules: {exc}') from None
        names = list(names or [])
        if not 1 <= len(names) <= params.MAX_MODULES:
            raise ConfigurationError(
                f'modules: {len(names)} modules given; a node hosts 1 to {params.MAX_MODULES} '
                f'modules (bottom to top), e.g. [m0] or [m0, m1, m2]')
        if len(set(names)) != len(names):
            raise ConfigurationError(f'modules={names}: module names must be distinct')
        for m in names:
            if not _MODULE_NAME.match(m):
                raise ConfigurationError(
                    f'module name {shown(m)}: use a letter followed by letters, digits or _')
        return names

    def _coerce_overrides(self, types):
        """Integers given for double parameters (``L1: 1`` in YAML) are taken as doubles."""
        overrides = self._parameter_overrides
        for name, type_ in types.items():
            p = overrides.get(name)
            if p is None:
                continue
            if type_ == params.DOUBLE and p.type_ == Parameter.Type.INTEGER:
                overrides[name] = Parameter(name, params.DOUBLE, float(p.value))
            elif type_ == params.DOUBLE_ARRAY and p.type_ == Parameter.Type.INTEGER_ARRAY:
                overrides[name] = Parameter(name, params.DOUBLE_ARRAY,
                                            [float(v) for v in p.value])

    def _declare_parameters(self):
        self._coerce_overrides(params.parameter_types(self._names))
        declarations = params.declarations(self._names)
        self._declared = [name for name, _, _ in declarations]
        for name, default, descriptor in declarations:
            try:
                self.declare_parameter(name, default, descriptor)
            except (InvalidParameterTypeException, InvalidParameterValueException,
                    ParameterException) as exc:
                raise ConfigurationError(f'parameter {name}: {exc}') from None
        values = self._current_values()
        reason = params.check_node_values(values, self._names) or next(
            (r for r in (params.check_module_values(m, params.module_getter(m, values))
                         for m in self._names) if r), '')
        if reason:
            raise ConfigurationError(reason)

    def _warn_unknown_overrides(self):
        known = set(self._declared) | {'modules', 'use_sim_time'}
        for name in sorted(set(self._parameter_overrides) - known):
            self.get_logger().warning(f'ignoring unknown parameter {shown(name)}')

    def _initial_configuration(self):
        """(modules at rho_initial, initial_theta of each) from the parameter values."""
        getters = [params.module_getter(m, self._current_values()) for m in self._names]
        return ([params.initial_params(get) for get in getters],
                [get('initial_theta') for get in getters])

    def _start_simulator(self):
        modules, thetas = self._initial_configuration()
        values = self._current_values()
        limits = [params.module_limits(params.module_getter(m, values)) for m in self._names]
        try:
            if self._dynamics:
                return DynamicSimulator(modules, thetas, limits, names=self._names,
                                        damping=[params.module_getter(m, values)('damping')
                                                 for m in self._names])
            return Simulator(modules, thetas, limits, names=self._names)
        except ValueError as exc:
            raise ConfigurationError(
                f'{", ".join(self._names)} at rho_initial {[m.rho for m in modules]}, '
                f'initial_theta {thetas}: {exc}') from None

    # -- parameters at runtime ----------------------------------------------------------

    def _watch_parameters(self):
        """The rates served by the node's timer, the live designs the parameters read back,
        and the set callbacks."""
        self._periodic = {}         # name -> [period_ns or 0 (off), next due ns]
        now = self._now_ns()
        for name in ('markers_rate', 'diagnostics_rate'):
            self._periodic[name] = [0, now]
            self._set_periodic(name, self.get_parameter(name).value, now)
        self._designs = [self._sim.design(i) for i in range(len(self._names))]
        self.add_pre_set_parameters_callback(self._pre_set_parameters)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)

    def _current_values(self):
        return {p.name: p.value for p in self.get_parameters(self._declared)}

    def _pre_set_parameters(self, parameters):
        """Runs before rclpy's own checks: coerce int -> double, count what rclpy will refuse."""
        if self._mirroring:
            return parameters
        reject = self._incidents.reject
        try:
            out = []
            for p in parameters:
                if not self.has_parameter(p.name):
                    reject('parameter_undeclared', f'no parameter named {shown(p.name)}')
                    out.append(p)
                    continue
                if p.type_ == Parameter.Type.NOT_SET:
                    # rclpy refuses it too ("Static parameter cannot be undeclared")
                    reject('parameter_delete',
                           f'{p.name}: parameters of this node cannot be deleted (each '
                           f'is declared with a type and a descriptor); set a value')
                    out.append(p)
                    continue
                d = self.describe_parameter(p.name)
                if d.type == params.DOUBLE.value and p.type_ == Parameter.Type.INTEGER:
                    p = Parameter(p.name, params.DOUBLE, float(p.value))
                elif d.type == params.DOUBLE_ARRAY.value and \
                        p.type_ == Parameter.Type.INTEGER_ARRAY:
                    p = Parameter(p.name, params.DOUBLE_ARRAY, [float(v) for v in p.value])
                if d.read_only:
                    reject('parameter_read_only', f'{p.name} is read-only')
                elif p.type_.value != d.type:
                    reject('parameter_type',
                           f'{p.name}: wrong type {p.type_.name}, expected '
                           f'{Parameter.Type(d.type).name}')
                elif d.floating_point_range and p.type_ == params.DOUBLE:
                    r = d.floating_point_range[0]
                    if not r.from_value <= p.value <= r.to_value:
                        reject('parameter_value',
                               f'{p.name}={p.value!r} outside [{r.from_value}, '
                               f'{r.to_value}]')
                out.append(p)
            return out
        except Exception as exc:        # never raise into rclpy
            self._incidents.exception('pre-set parameters', exc)
            return parameters

    def _validate_parameters(self, parameters):
        """on-set callback: accept or refuse (with a reason) without changing any state."""
        if self._mirroring:
            return SetParametersResult(successful=True)
        try:
            reason = self._refusal(parameters)
        except Exception as exc:
            self._incidents.exception('parameter validation', exc)
            reason = f'internal error while validating: {exc!r}'
        if reason:
            self._incidents.reject('parameter_value', f'parameter change refused: {reason}')
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _refusal(self, parameters):
        values = self._current_values()
        for p in parameters:
            if p.type_ == Parameter.Type.NOT_SET:
                return f'{p.name} cannot be unset'
            values[p.name] = p.value
        reason = params.check_node_values(values, self._names)
        if reason:
            return reason
        for i in self._affected_modules(parameters):
            m = self._names[i]
            get = params.module_getter(m, values)
            reason = params.check_module_values(m, get)
            if reason:
                return reason
            reason = self._sim.limits_refusal(i, get('rho_min'), get('rho_max'))
            if reason:
                return f'{m}: {reason}'
        return ''

    def _affected_modules(self, parameters):
        """{module index: [changed keys]} of the module parameters in ``parameters``."""
        affected = {}
        for p in parameters:
            m, _, key = p.name.partition('.')
            if key and m in self._names:
                affected.setdefault(self._names.index(m), []).append(key)
        return affected

    def _apply_parameters(self, parameters):
        """post-set callback: node settings; module settings; then every physical or
        force change of the set on one tracked path."""
        if self._mirroring:
            return
        try:
            names = {p.name for p in parameters}
            if 'publish_rate' in names:
                self._tick_timer.timer_period_ns = int(1e9 / self.get_parameter(
                    'publish_rate').value)
            for name in ('markers_rate', 'diagnostics_rate'):
                if name in names:
                    self._set_periodic(name, self.get_parameter(name).value, self._now_ns())
            if names & {'frame_id', 'frame_prefix'}:
                self._set_frames()
            values, now = self._current_values(), self._now_ns()
            changes, changed_names = {}, []
            for i, keys in self._affected_modules(parameters).items():
                m = self._names[i]
                get = params.module_getter(m, values)
                self._events.report(self._sim.set_limits(i, params.module_limits(get), now))
                if self._dynamics and 'damping' in keys:
                    self._events.report(self._sim.set_damping(i, get('damping'), now))
                moving = [k for k in keys
                          if params.kind_of(k) in (params.PHYSICAL, params.FORCE)]
                if moving:
                    changes[i] = params.design_changes(get, self._sim.design(i), moving)
                    changed_names += [f'{m}.{k}' for k in moving]
            if changes:
                cause = 'parameter ' + ', '.join(sorted(changed_names))
                self._command(self._sim.set_parameters(changes, now, cause), 'parameters',
                              now, loads=True)
            self._publish_statuses_if_changed()
        except Exception as exc:
            self._incidents.exception('parameter change', exc)

    def _sync_parameters(self):
        """The design and force parameters read back the live values, whatever set them (a
        force message, a parameter, a path stopped early): set those that differ (one
        /parameter_events message), bypassing the set callbacks."""
        changed = []
        values = None
        for i, m in enumerate(self._names):
            design = self._sim.design(i)
            if design == self._designs[i]:
                continue
            self._designs[i] = design
            values = values or self._current_values()
            for key, value in params.live_values(params.module_getter(m, values),
                                                 design).items():
                changed.append(Parameter(f'{m}.{key}', value=value))
        if changed:
            self._mirroring = True
            try:
                self.set_parameters_atomically(changed)
            finally:
                self._mirroring = False

    def _set_periodic(self, name, rate, now_ns):
        """markers_rate / diagnostics_rate: served by the publish_rate timer (0 = off)."""
        entry = self._periodic[name]
        entry[0] = int(1e9 / rate) if rate > 0.0 else 0
        entry[1] = now_ns + entry[0]
