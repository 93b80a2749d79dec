"""Read a ``tensegrity_node`` parameter file (ROS 2 params YAML) without ROS.

The layout is the node's (``config/default.yaml``, ``config/neck.yaml``)::

    /**:                          # node name key ('/**', 'tensegrity', '/ns/tensegrity', ...)
      ros__parameters:
        modules: [m0, m1, m2]     # bottom to top (default [m0])
        m0:                       # nested, or flat keys 'm0.L1: 0.12'
          L1: 0.12                # m
          L2: 0.12
          k: 300.0                # N/m, all three springs ...
          ka: 0.0                 # ... unless overridden (0 or absent = use k)
          m1: 0.02                # kg (optional)
          force_a3: [0.0, 0.0]    # N, [fx, fy] in the stack's base frame
          force_a4: [0.0, 0.0]
          rho_initial: 0.09       # m
          initial_theta: [0.75, 0.75]   # rad, start guess of the node

Absent keys take the node's defaults (``module_parameters.MODULE_DEFAULTS``), and the
modules are built by the node's rule (``module_parameters.initial_params``: ``k`` for
every spring unless ``ka``/``kb``/``kc`` override it).  Node-wide
settings (rates, frame) and per-module limits are read but not used by the
offline analysis; unknown per-module keys are reported in
:attr:`StackConfig.ignored` (the node ignores them with a warning too).

Used by the ``tensegrity`` CLI (``--config``); imports neither rclpy nor any ROS package.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
import re

from .core import InvalidParameterError, ModuleParams
from .module_parameters import initial_params, MODULE_DEFAULTS

_PAIRS = ('force_a3', 'force_a4', 'initial_theta')
_POSITIVE = ('L1', 'L2', 'k', 'rho_initial')
_NON_NEGATIVE = ('ka', 'kb', 'kc', 'm1', 'm2')
_MODULE_NAME = re.compile(r'^[A-Za-z][A-Za-z0-9_]*$')


class ConfigError(ValueError):
    """The parameter file cannot be used (one-line message naming the file and key)."""


@dataclass(frozen=True)
class ModuleConfig:
    """One module of the file: its parameters at ``rho_initial`` and the node's start guess."""

    name: str
    params: ModuleParams
    initial_theta: tuple
    rho_min: float
    rho_max: float


@dataclass(frozen=True)
class StackConfig:
    """The modules of a parameter file, bottom to top."""

    path: str
    node: str
    modules: tuple
    ignored: tuple = ()

    @property
    def names(self):
        return [m.name for m in self.modules]

    def stack(self):
        from .core.neck.stack import Stack
        return Stack(tuple(m.params for m in self.modules))

    @property
    def initial_theta(self):
        return [list(m.initial_theta) for m in self.modules]


def _flatten(tree, prefix=''):
    out = {}
    for key, value in tree.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            out.update(_flatten(value, name + '.'))
        else:
            out[name] = value
    return out


def _number(path, key, value):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f'{path}: {key} must be a number, got {value!r}')
    value = float(value)
    if not math.isfinite(value):
        raise ConfigError(f'{path}: {key} must be finite, got {value!r}')
    return value


def _pair(path, key, value):
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ConfigError(f'{path}: {key} must be a list of two numbers, got {value!r}')
    return tuple(_number(path, key, v) for v in value)


def _node_entries(path, doc):
    """The node entries (name -> mapping with ``ros__parameters``) of a parameter file."""
    if not isinstance(doc, dict) or not doc:
        raise ConfigError(f'{path}: not a ROS 2 parameter file (expected a mapping '
                          f'"<node name>: {{ros__parameters: ...}}", got '
                          f'{type(doc).__name__})')
    entries = {k: v for k, v in doc.items()
               if isinstance(v, dict) and isinstance(v.get('ros__parameters'), dict)}
    if not entries:
        raise ConfigError(f'{path}: no "<node name>: ros__parameters:" entry')
    return entries


def _select_node(path, doc, node):
    entries = _node_entries(path, doc)
    if node is not None:
        for key in (node, '/' + node.lstrip('/'), node.lstrip('/')):
            if key in entries:
                return key, entries[key]['ros__parameters']
        listed = ', '.join(map(str, entries))
        raise ConfigError(f'{path}: no node entry {node!r} (entries: {listed})')
    if len(entries) == 1:
        key = next(iter(entries))
        return key, entries[key]['ros__parameters']
    with_modules = [k for k in entries if 'modules' in entries[k]['ros__parameters']]
    if len(with_modules) == 1:
        key = with_modules[0]
        return key, entries[key]['ros__parameters']
    raise ConfigError(f'{path}: several node entries ({", ".join(map(str, entries))}): '
                      f'choose one with --node')


def _loader():
    """PyYAML's safe loader that also reads ``!!python/tuple`` as a list: launch_ros
    writes a launch file's parameter dictionary with ``yaml.dump`` after turning its
    lists into tuples, and rcl reads such a file (it ignores the tag)."""
    import yaml

    class ParameterFileLoader(yaml.SafeLoader):
        pass
    ParameterFileLoader.add_constructor('tag:yaml.org,2002:python/tuple',
                                        ParameterFileLoader.construct_sequence)
    return ParameterFileLoader


def _read_yaml(path):
    """The YAML document of ``path``; :class:`ConfigError` (one line) if unreadable or invalid."""
    import yaml
    try:
        with open(path, encoding='utf-8') as f:
            return yaml.load(f, Loader=_loader())     # safe: only the tuple tag is added
    except OSError as exc:
        raise ConfigError(f'cannot read {path}: {exc.strerror or exc}') from None
    except yaml.YAMLError as exc:
        where = getattr(exc, 'problem_mark', None)
        at = f' (line {where.line + 1})' if where is not None else ''
        problem = getattr(exc, 'problem', None) or type(exc).__name__
        raise ConfigError(f'{path}: invalid YAML{at}: {problem}') from None


def check_parameter_file(path):
    """Refuse (:class:`ConfigError`) a ROS 2 parameter file the node cannot start from:
    unreadable, invalid YAML, or not a mapping of node entries with ``ros__parameters``.

    The node checks its ``--params-file`` arguments with this before rcl parses them, so
    that a broken file is one clear FATAL line rather than an rcl traceback."""
    _node_entries(path, _read_yaml(path))


def load_stack_config(path, node=None):
    """The :class:`StackConfig` of a node parameter file; :class:`ConfigError` if unusable."""
    key, params = _select_node(path, _read_yaml(path), node)
    flat = _flatten(params)
    names = flat.pop('modules', ['m0'])
    if isinstance(names, str) or not isinstance(names, (list, tuple)) or not names:
        raise ConfigError(f'{path}: modules must be a non-empty list of names, got {names!r}')
    names = [str(n) for n in names]
    for n in names:
        if not _MODULE_NAME.match(n):
            raise ConfigError(f'{path}: module name {n!r}: use a letter followed by letters, '
                              f'digits or _')
    if len(set(names)) != len(names):
        raise ConfigError(f'{path}: module names repeat: {names}')
    modules = []
    used = set()
    for name in names:
        values = {}
        for key_name, default in MODULE_DEFAULTS.items():
            full = f'{name}.{key_name}'
            if full in flat:
                used.add(full)
                raw = flat[full]
                values[key_name] = (_pair(path, full, raw) if key_name in _PAIRS
                                    else _number(path, full, raw))
            else:
                values[key_name] = default
        for key_name in _POSITIVE:
            if not values[key_name] > 0.0:
                raise ConfigError(f'{path}: {name}.{key_name} must be > 0, '
                                  f'got {values[key_name]!r}')
        for key_name in _NON_NEGATIVE:
            if not values[key_name] >= 0.0:
                raise ConfigError(f'{path}: {name}.{key_name} must be >= 0 (0 = use k), '
                                  f'got {values[key_name]!r}')
        try:
            params = initial_params(values.__getitem__)       # the node's rule, at rho_initial
        except InvalidParameterError as exc:
            raise ConfigError(f'{path}: module {name}: {exc}') from None
        modules.append(ModuleConfig(name=name, params=params,
                                    initial_theta=tuple(values['initial_theta']),
                                    rho_min=values['rho_min'], rho_max=values['rho_max']))
    prefixes = tuple(n + '.' for n in names)
    ignored = tuple(sorted(k for k in flat if k.startswith(prefixes) and k not in used))
    return StackConfig(path=str(path), node=str(key), modules=tuple(modules), ignored=ignored)
