"""The neck-stack form of ``solve`` and ``track`` (docs/model.md section 4): its options,
when they select it, and the modules they describe (a --config file, --modules N,
--rhos), with the mechanism options applied (forces to the head, the rest to all).
"""
from __future__ import annotations

import sys

from .common import check_domain, check_input, finite_float, positive_int, UsageError
from ..core import InvalidParameterError, ModuleParams
from ..problem import APPLY_ORDER, DEFAULT_FIELDS, PARAMETERS

#: Options that load the head (the top module of a stack).  All other parameter
#: options apply to every module (``--rho`` too; ``--rhos`` sets one per module).
HEAD_OPTIONS = ('F', 'F3', 'F4', 'F3x', 'F4x')
#: ModuleParams fields a CLI module is made of.
MODULE_FIELDS = ('rho', 'L1', 'L2', 'ka', 'kb', 'kc', 'f3x', 'f3y', 'f4x', 'f4y', 'm1', 'm2')
_STACK_OPTIONS = (('modules', '--modules'), ('rhos', '--rhos'), ('config', '--config'),
                  ('node', '--node'), ('to_rhos', '--to-rhos'), ('theta', '--theta'))


def add_stack_options(parser, track=False):
    """The option group of the stack form (``track``: its path and guess too)."""
    group = parser.add_argument_group(
        'neck stack (docs/model.md section 4)',
        '--modules, --rhos, --config' + (', --to-rhos, --theta' if track else '')
        + ' select the stack form. Module 0 is at the bottom. Geometry, stiffness and mass '
        'options and --rho apply to every module; the force options load the top module '
        '(the head).')
    group.add_argument('--modules', type=positive_int, metavar='N',
                       help='N identical modules (geometry, stiffness and mass options apply '
                            'to every module)')
    group.add_argument('--rhos', type=finite_float, nargs='+', metavar='R',
                       help='actuator length of every module, bottom to top (m; instead of '
                            '--rho, which sets all of them)')
    group.add_argument('--config', metavar='FILE.yaml',
                       help='the modules of a tensegrity_node parameter file (e.g. '
                            'config/neck.yaml); other options override it')
    group.add_argument('--node', metavar='NAME',
                       help='node entry of --config to read when the file has several')
    if track:
        group.add_argument('--to-rhos', type=finite_float, nargs='+', metavar='R',
                           help='actuator length of every module at the end of the path')
        group.add_argument('--theta', type=finite_float, nargs='+', metavar='RAD',
                           help='start guess: theta1 theta2 of every module, bottom to top '
                                '(2N angles, rad)')
    return group


def stack_mode(args):
    """True when a stack option is given (the stack form of solve / track)."""
    return any(getattr(args, name, None) is not None for name, _ in _STACK_OPTIONS)


class StackSpec:
    """The modules of a stack command before the CLI overrides: names, base fields, guess."""

    def __init__(self, names, base, config=None):
        self.names = names
        self.base = base
        self.config = config

    def __len__(self):
        return len(self.names)


def _fields_of(p):
    return {name: getattr(p, name) for name in MODULE_FIELDS}


def stack_spec(args):
    """The :class:`StackSpec` of the stack options; UsageError if they disagree."""
    n = args.modules
    config = None
    if args.config is not None:
        from ..params_file import ConfigError, load_stack_config
        check_input(args.config, '--config')
        try:
            config = load_stack_config(args.config, args.node)
        except ConfigError as exc:
            raise UsageError(str(exc)) from None
        if n is not None and n != len(config.modules):
            raise UsageError(f'--modules {n} does not match the {len(config.modules)} '
                             f'module(s) of {args.config}')
        n = len(config.modules)
        for name in config.ignored:
            sys.stderr.write(f'tensegrity: {args.config}: ignoring unknown parameter '
                             f'{name!r}\n')
    elif args.node is not None:
        raise UsageError('--node selects an entry of --config: give --config too')
    lists = [('--rhos', args.rhos), ('--to-rhos', getattr(args, 'to_rhos', None))]
    for option, values in lists:
        if values is None:
            continue
        for v in values:
            check_domain('rho', v)
        if n is None:
            n = len(values)
        elif len(values) != n:
            raise UsageError(f'{option} needs {n} values (one per module, bottom to top), '
                             f'got {len(values)}')
    theta = getattr(args, 'theta', None)
    if theta is not None:
        if n is None:
            if len(theta) % 2:
                raise UsageError(f'--theta needs two angles per module, got {len(theta)}')
            n = len(theta) // 2
        elif len(theta) != 2 * n:
            raise UsageError(f'--theta needs {2 * n} angles (theta1 theta2 of each of the '
                             f'{n} modules), got {len(theta)}')
    if n is None:
        n = 1
    if n > 50:
        raise UsageError(f'--modules {n} is too many (at most 50)')
    if config is not None:
        return StackSpec(config.names, [_fields_of(m.params) for m in config.modules], config)
    return StackSpec([f'm{i}' for i in range(n)],
                     [dict(DEFAULT_FIELDS, rho=None) for _ in range(n)])


def override(fields_list, values, rhos):
    """Per-module fields with CLI-named values applied: forces to the head, the rest to all."""
    top = len(fields_list) - 1
    out = []
    for i, fields in enumerate(fields_list):
        f = dict(fields)
        for name in APPLY_ORDER:
            if name == 'rho' or values.get(name) is None:
                continue
            if name in HEAD_OPTIONS and i != top:
                continue
            for field in PARAMETERS[name][0]:
                f[field] = values[name]
        if rhos is not None:
            f['rho'] = rhos[i]
        elif values.get('rho') is not None:
            f['rho'] = values['rho']
        out.append(f)
    return out


def make_stack(fields_list, names):
    from ..core.neck.stack import Stack
    modules = []
    for name, fields in zip(names, fields_list):
        if fields.get('rho') is None:
            n = len(names)
            raise UsageError('give --rho (every module)' + (
                f' or --rhos R0 ... R{n - 1} (one per module, bottom to top)' if n > 1 else ''))
        try:
            modules.append(ModuleParams(**fields))
        except InvalidParameterError as exc:
            raise UsageError(f'module {name}: {exc}') from None
    return Stack(tuple(modules))
