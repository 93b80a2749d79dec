"""``tensegrity``: the offline command line of tensegrity_ros (docs/cli.md).

Subcommands::

    tensegrity solve   --rho R [params] [--json]
    tensegrity solve   --modules N --rho R | --rhos R0 .. RN-1 [params] [--json]   (neck stack)
    tensegrity solve   --config FILE.yaml [params] [--json]                         (neck stack)
    tensegrity track   --rho R0 --to-rho R1 [--to-F3 ...] [--theta1 T1 --theta2 T2] [--json]
    tensegrity track   --modules N | --config FILE ... --to-rhos .. [--theta T ..] [--json]
    tensegrity map     --x NAME MIN MAX COUNT --y NAME MIN MAX COUNT [params] [--csv F] [--png F]
                       [--boundaries] [--boundaries-csv F]
    tensegrity diagram --from-rho A --to-rho B [--count N] [params] --png F [--csv F]
                       [--track R0 R1 ...]
    tensegrity range   --rho R [--theta1 T1 --theta2 T2] [params] [--json]
    tensegrity limit   --L2 X [--pushing] [--json]
    tensegrity snap    --rho R0 --to-rho R1 --rate V --damping C --m1 M --m2 M [...]  (dynamics)

Units are SI (m, N, N/m, kg); angles are radians on input and in JSON/CSV, the
human-readable tables show degrees.  The paper's F3, F4 are the vertical force
components (positive pulls up).  ``--k`` sets all three springs, ``--ka/--kb/--kc``
override it; ``--F`` sets F3 = F4, ``--F3/--F4`` override it.

Stack (several modules, docs/model.md section 4): geometry, stiffness and mass options
apply to every module, ``--rho`` to every module (``--rhos`` one per module), the
force options to the top module (the head).  ``--config`` reads a node parameter
file; options given with it override the file in the same way.

Bad arguments give a one-line message on stderr and exit status 2.  The module
does not import rclpy (nor matplotlib unless a PNG is requested).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

from . import snap as snap_command, tolerance as tolerance_command
from ..core import equilibria, InvalidParameterError, ModuleParams, track_module
from ..core.start_state import start_state, upright_guess
from .passage_records import (stack_passage_line, stack_passage_record, theta_text,
                              undecided_line, undecided_record)
from ..problem import (APPLY_ORDER, DEFAULT_FIELDS, describe, describe_modules, PARAMETERS,
                      resolve_fields)

#: Names whose value must be > 0, resp. >= 0.
_POSITIVE = {'rho', 'L1', 'L2', 'k', 'ka', 'kb', 'kc'}
_NON_NEGATIVE = {'m1', 'm2'}
#: Names that overlap: giving both as a map axis and a fixed value is refused.
_OVERLAPS = {'k': {'k', 'ka', 'kb', 'kc'}, 'F': {'F', 'F3', 'F4'}}

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_USAGE = 2


class UsageError(Exception):
    """A bad command line: reported in one line, exit status 2."""


def canonical_name(name):
    """The CLI parameter name matching ``name`` (case-insensitive), or UsageError."""
    for known in PARAMETERS:
        if known.lower() == str(name).lower():
            return known
    raise UsageError(f'unknown parameter {name!r} (choose from {", ".join(PARAMETERS)})')


def overlapping(a, b):
    """True if parameter names a and b set a common field (e.g. F and F3)."""
    return bool(set(PARAMETERS[a][0]) & set(PARAMETERS[b][0]))


def check_domain(name, value):
    """UsageError if ``value`` is outside the physical range of parameter ``name``."""
    if not math.isfinite(value):
        raise UsageError(f'{name} must be finite, got {value!r}')
    if name in _POSITIVE and not value > 0.0:
        raise UsageError(f'{name} must be positive, got {value:g}')
    if name in _NON_NEGATIVE and not value >= 0.0:
        raise UsageError(f'{name} must be non-negative, got {value:g}')


def make_params(values):
    """A validated ModuleParams from CLI-named values (needs 'rho')."""
    if values.get('rho') is None:
        raise UsageError('--rho is required')
    return ModuleParams(**resolve_fields(values))


# ---------------------------------------------------------------------------
# Argument parsing

class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (exit status 2, no usage block)."""

    def error(self, message):
        self.exit(EXIT_USAGE, f'{self.prog}: error: {message} (see {self.prog} --help)\n')


def finite_float(text):
    """argparse type: a finite real number (rejects nan, inf)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'not a number: {text!r}') from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f'must be a finite number, got {text!r}')
    return value


def positive_int(text):
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'not an integer: {text!r}') from None
    if value < 1:
        raise argparse.ArgumentTypeError(f'must be >= 1, got {value}')
    return value


def _add_parameter_options(parser, skip=(), prefix='', required=()):
    group = parser.add_argument_group(
        'mechanism parameters' if not prefix else 'end point of the path (default: start value)')
    for name, (_, text) in PARAMETERS.items():
        if name in skip:
            continue
        group.add_argument(f'--{prefix}{name}', dest=f'{prefix.replace("-", "_")}{name}',
                           type=finite_float, metavar='X', required=name in required,
                           help=text if not prefix else f'{name} at the end of the path')


def _values(args, prefix=''):
    """CLI-named parameter values given on the command line (None = not given)."""
    out = {}
    for name in PARAMETERS:
        value = getattr(args, f'{prefix}{name}', None)
        if value is not None:
            check_domain(name, value)
            out[name] = value
    return out


def build_parser():
    parser = _Parser(
        prog='tensegrity',
        description='Offline analysis of the planar tensegrity mechanism of Wenger & Chablat: '
                    'equilibria, tracking with jumps, stability maps, bifurcation diagrams. '
                    'SI units; angles in radians (tables show degrees).',
        epilog='Run "tensegrity COMMAND --help" for the options of a command.')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND', required=True)
    p = sub.add_parser(
        'solve', help='every equilibrium at one parameter point (one module or a stack)',
        description='Print every equilibrium (at most 6) with its stability. With --modules, '
                    '--rhos or --config: the equilibria of a neck stack (docs/model.md section 4) '
                    'by a multi-start search (exact for one module).')
    _add_parameter_options(p)
    group = _add_stack_options(p)
    group.add_argument('--method', choices=('auto', 'exact', 'multi-start'),
                       help='exact elimination (one module only) or the multi-start search '
                            '(default auto: exact for one module, multi-start otherwise)')
    group.add_argument('--starts', type=positive_int, metavar='K',
                       help='multi-start: K random Newton starts plus K/4 overdamped settles '
                            '(default 64)')
    group.add_argument('--seed', type=int, metavar='S',
                       help='multi-start: random seed (default 0)')
    group.add_argument('--stable-only', action='store_true',
                       help='list the stable equilibria only (numbered as in the full list, '
                            'which is sorted by energy)')
    p.add_argument('--json', action='store_true', help='machine-readable output')
    p.set_defaults(func=cmd_solve)

    p = sub.add_parser(
        'track', help='follow the stable equilibrium along a straight parameter path',
        description='Start in the stable equilibrium whose basin holds the start guess '
                    '(--theta1/--theta2; default: the stable equilibrium with the largest '
                    'y3 + y4, i.e. the upper one), move all parameters together along the '
                    'straight path to the --to-* values and report every jump. With '
                    '--modules, --rhos, --config or --theta: a neck stack (start guess: '
                    '--theta, else the initial_theta of the --config file, else upright).')
    _add_parameter_options(p)
    _add_parameter_options(p, prefix='to-')
    p.add_argument('--theta1', type=finite_float, metavar='RAD',
                   help='start guess for theta1 (rad); needs --theta2')
    p.add_argument('--theta2', type=finite_float, metavar='RAD',
                   help='start guess for theta2 (rad); needs --theta1')
    _add_stack_options(p, track=True)
    p.add_argument('--json', action='store_true', help='machine-readable output')
    p.set_defaults(func=cmd_track)

    p = sub.add_parser(
        'map', help='number of stable equilibria over a parameter plane',
        description='Count the stable equilibria on a COUNT x COUNT grid (numpy.linspace, '
                    'both ends included) of two parameters. Axis names: '
                    + ', '.join(PARAMETERS) + ' (F = F3 = F4, k = ka = kb = kc).')
    p.add_argument('--x', nargs=4, required=True, metavar=('NAME', 'MIN', 'MAX', 'COUNT'),
                   help='horizontal axis')
    p.add_argument('--y', nargs=4, required=True, metavar=('NAME', 'MIN', 'MAX', 'COUNT'),
                   help='vertical axis')
    _add_parameter_options(p)
    p.add_argument('--csv', metavar='FILE', help="write the grid as CSV ('-' for stdout)")
    p.add_argument('--png', metavar='FILE', help='write a PNG image of the map')
    p.add_argument('--title', help='plot title (default: the fixed parameters)')
    p.add_argument('--boundaries', action='store_true',
                   help='overlay the exact curves of degenerate equilibria (G = 0, det H = 0, '
                        'traced by continuation) on the PNG: solid black where the number of '
                        'stable equilibria changes, thin grey dashed elsewhere')
    p.add_argument('--boundaries-csv', metavar='FILE',
                   help="write the points of those curves as CSV ('-' for stdout): "
                        'curve,x,y,stable_boundary,kind')
    p.add_argument('--jobs', type=int, default=0, metavar='N',
                   help='worker processes (default 0: all cores for large maps)')
    p.add_argument('--no-progress', action='store_true', help='no progress bar')
    p.set_defaults(func=cmd_map)

    p = sub.add_parser(
        'diagram', help='bifurcation diagram: theta1, theta2 of all equilibria against rho',
        description='Plot every equilibrium against rho (stable: solid blue, unstable: dashed '
                    'red), connected into branches, with folds and branch points located by '
                    'bisection. --track overlays the quasi-static path through the listed rho '
                    'values (from --theta1/--theta2 or the upper stable equilibrium) with its '
                    'jumps drawn as vertical arrows.')
    p.add_argument('--from-rho', type=finite_float, required=True, metavar='A')
    p.add_argument('--to-rho', type=finite_float, required=True, metavar='B')
    p.add_argument('--count', type=positive_int, default=400, metavar='N',
                   help='number of rho samples before refinement (default 400)')
    _add_parameter_options(p, skip=('rho',))
    p.add_argument('--png', metavar='FILE', required=True, help='output image')
    p.add_argument('--csv', metavar='FILE', help='write the branches as CSV')
    p.add_argument('--track', type=finite_float, nargs='+', metavar='R',
                   help='overlay the tracked path through these rho values (at least 2)')
    p.add_argument('--theta1', type=finite_float, metavar='RAD', help='start guess for --track')
    p.add_argument('--theta2', type=finite_float, metavar='RAD', help='start guess for --track')
    p.add_argument('--title', help='plot title (default: the parameters)')
    p.set_defaults(func=cmd_diagram)

    p = sub.add_parser(
        'range', help='operation range: the rho interval over which a stable branch lasts',
        description='Follow the stable branch through the start configuration (the stable '
                    'equilibrium whose basin holds --theta1/--theta2; default: the upper '
                    'one) in rho, everything else fixed, and report where it ends on each '
                    'side and why: a fold, a branch point (symmetry-breaking pitchfork) or '
                    'the search bound (limit). Ends are solved on regular extended systems '
                    '(exact to rounding).')
    _add_parameter_options(p)
    p.add_argument('--theta1', type=finite_float, metavar='RAD',
                   help='start guess for theta1 (rad); needs --theta2')
    p.add_argument('--theta2', type=finite_float, metavar='RAD',
                   help='start guess for theta2 (rad); needs --theta1')
    p.add_argument('--rho-bounds', type=finite_float, nargs=2, metavar=('MIN', 'MAX'),
                   help='search interval in rho (default 0 .. 2 (L1 + L2))')
    p.add_argument('--json', action='store_true', help='machine-readable output')
    p.set_defaults(func=cmd_range)

    p = sub.add_parser(
        'limit', allow_abbrev=False,          # --F3 must not silently mean --F3x
        help='point C: the largest forces with two stable equilibria',
        description="Point C of the paper's fig. 6: the tip of the 2-stable region of "
                    '(rho, F3, F4) space, an equilibrium with H = 0. No point with F3 and F4 '
                    'both beyond C has two stable equilibria. --pushing: the mirror image '
                    '(negative forces).')
    group = p.add_argument_group('design parameters')
    for name in ('L1', 'L2', 'k', 'ka', 'kb', 'kc', 'F3x', 'F4x'):
        group.add_argument(f'--{name}', type=finite_float, metavar='X', help=PARAMETERS[name][1])
    p.add_argument('--pushing', action='store_true',
                   help='pushing forces (F3, F4 < 0) instead of pulling')
    p.add_argument('--json', action='store_true', help='machine-readable output')
    p.set_defaults(func=cmd_limit)

    snap_command.add_snap_parser(sub, _add_parameter_options, finite_float).set_defaults(
        func=cmd_snap)
    tolerance_command.add_parser(sub, _add_parameter_options, _values, finite_float, positive_int)
    return parser


def _add_stack_options(parser, track=False):
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


# ---------------------------------------------------------------------------
# solve

def equilibrium_record(p, e):
    """JSON-ready dict of one equilibrium (radians, SI)."""
    from ..core import node_positions
    nodes = node_positions(p, (e.theta1, e.theta2))
    return {
        'theta1': e.theta1, 'theta2': e.theta2, 'stable': bool(e.stable),
        'eigenvalues': [float(v) for v in e.eigenvalues],
        'energy': float(e.energy), 'actuator_force': float(e.actuator_force),
        'kind': e.kind, 'residual': float(e.residual),
        'A3': [float(v) for v in nodes[2]], 'A4': [float(v) for v in nodes[3]],
    }


def params_record(p):
    return {name: getattr(p, name) for name in
            ('rho', 'L1', 'L2', 'ka', 'kb', 'kc', 'f3x', 'f3y', 'f4x', 'f4y', 'm1', 'm2')}


def cmd_solve(args, out):
    if _stack_mode(args):
        return cmd_stack_solve(args, out)
    for option, value in (('--method', args.method), ('--starts', args.starts),
                          ('--seed', args.seed), ('--stable-only', args.stable_only or None)):
        if value is not None:
            raise UsageError(f'{option} is for a stack (give --modules N, --rhos or --config)')
    values = _values(args)
    p = make_params(values)
    result = equilibria(p)
    if args.json:
        doc = {'status': result.status, 'params': params_record(p),
               'num_equilibria': len(result), 'num_stable': result.num_stable,
               'equilibria': [equilibrium_record(p, e) for e in result]}
        out.write(json.dumps(doc, indent=2) + '\n')
        return EXIT_OK
    head = f'{describe(values)}: {len(result)} equilibria, {result.num_stable} stable'
    if result.status != 'ok':
        head += f' (status {result.status}: the equilibria are not isolated)'
    out.write(head + '\n')
    if len(result):
        out.write(format_table(p, result) + '\n')
    return EXIT_OK


def format_table(p, result):
    header = ('#', 'theta1[deg]', 'theta2[deg]', 'y3[m]', 'y4[m]', 'lambda1', 'lambda2',
              'kind', 'stable', 'energy[J]', 'actuator[N]')
    rows = []
    for i, e in enumerate(result, 1):
        rows.append((str(i), f'{math.degrees(e.theta1):.3f}', f'{math.degrees(e.theta2):.3f}',
                     f'{p.L1 * math.sin(e.theta1):.4f}', f'{p.L2 * math.sin(e.theta2):.4f}',
                     f'{e.eigenvalues[0]:.4g}', f'{e.eigenvalues[1]:.4g}', e.kind,
                     'yes' if e.stable else 'no', f'{e.energy:.4f}',
                     f'{e.actuator_force:.4f}'))
    widths = [max(len(r[c]) for r in rows + [header]) for c in range(len(header))]
    left = {7, 8}

    def line(r):
        return '  '.join(r[c].ljust(widths[c]) if c in left else r[c].rjust(widths[c])
                         for c in range(len(r))).rstrip()
    return '\n'.join([line(header)] + [line(r) for r in rows])


# ---------------------------------------------------------------------------
# track

def _start_guess(args):
    if (args.theta1 is None) != (args.theta2 is None):
        raise UsageError('give both --theta1 and --theta2, or neither')
    if args.theta1 is None:
        return None
    return (args.theta1, args.theta2)


def start_equilibrium(p, guess):
    """The stable equilibrium one module starts in (:func:`start_state`: the one whose
    basin holds ``guess``, or the upper one); UsageError if there is none."""
    try:
        return start_state([p], None if guess is None else [guess])
    except (ValueError, RuntimeError) as exc:
        if guess is None:
            raise UsageError(f'no stable equilibrium at the start ({describe_modules([p])}): '
                             'the point is degenerate; move it slightly') from None
        raise UsageError(f'cannot settle from the start guess: {exc}') from None


def run_track(start, end, guess):
    """(start Equilibrium, ModuleTrack) for one straight path."""
    first = start_equilibrium(start, guess)
    return first, track_module(start, end, first.theta)


def jump_record(jump):
    return {'kind': jump.kind, 's': float(jump.s), 'rho': float(jump.params.rho),
            'theta1': float(jump.from_theta[0]), 'theta2': float(jump.from_theta[1]),
            'landing': {'theta1': float(jump.to_theta[0]), 'theta2': float(jump.to_theta[1])},
            'ambiguous': bool(jump.ambiguous),
            'F3': float(jump.params.f3y), 'F4': float(jump.params.f4y)}


def cmd_track(args, out):
    if _stack_mode(args):
        return cmd_stack_track(args, out)
    start_values = _values(args)
    end_values = dict(start_values)
    end_values.update(_values(args, prefix='to_'))
    start = make_params(start_values)
    end = make_params(end_values)
    guess = _start_guess(args)
    first, track = run_track(start, end, guess)
    final = track.final
    doc = {
        'status': track.status, 'message': track.message,
        'start': {'theta1': first.theta1, 'theta2': first.theta2, 'stable': bool(first.stable),
                  'params': params_record(start)},
        'events': [jump_record(j) for j in track.jumps],
        'undecided': [undecided_record(u) for u in track.undecided],
        'final': {'theta1': final.theta1, 'theta2': final.theta2, 'stable': bool(final.stable),
                  'eigenvalues': [float(v) for v in final.eigenvalues],
                  'energy': float(final.energy), 'actuator_force': float(final.actuator_force),
                  'params': params_record(track.end)},
    }
    code = EXIT_OK if track.status == 'ok' else EXIT_FAILURE
    if args.json:
        out.write(json.dumps(doc, indent=2) + '\n')
        return code
    deg = math.degrees
    out.write(f'path: {describe_modules([start])}  ->  {describe_modules([end])}\n')
    out.write(f'start: theta = ({deg(first.theta1):.3f}, {deg(first.theta2):.3f}) deg, '
              f'{first.kind}\n')
    if not track.jumps:
        out.write('no jump: the mechanism stays on its branch\n')
    out.writelines(undecided_line(u) for u in track.undecided)
    for i, j in enumerate(track.jumps, 1):
        note = ' (ambiguous: the two sides land differently)' if j.ambiguous else ''
        out.write(f'event {i}: {j.kind} at s={j.s:.9f} rho={j.params.rho:.9g}: '
                  f'theta ({deg(j.from_theta[0]):.3f}, {deg(j.from_theta[1]):.3f}) deg '
                  f'-> lands at ({deg(j.to_theta[0]):.3f}, {deg(j.to_theta[1]):.3f}) deg'
                  f'{note}\n')
    out.write(f'final: theta = ({deg(final.theta1):.3f}, {deg(final.theta2):.3f}) deg at '
              f'rho={track.end.rho:g}, {final.kind}, status {track.status}'
              + (f': {track.message}' if track.message else '') + '\n')
    return code


# ---------------------------------------------------------------------------
# the neck stack: solve and track with several modules

#: Options that load the head (the top module of a stack).  All other parameter
#: options apply to every module (``--rho`` too; ``--rhos`` sets one per module).
HEAD_OPTIONS = ('F', 'F3', 'F4', 'F3x', 'F4x')
#: ModuleParams fields a CLI module is made of.
MODULE_FIELDS = ('rho', 'L1', 'L2', 'ka', 'kb', 'kc', 'f3x', 'f3y', 'f4x', 'f4y', 'm1', 'm2')
#: Default number of multi-start starts (as stack_equilibria).
DEFAULT_STARTS = 64
_STACK_OPTIONS = (('modules', '--modules'), ('rhos', '--rhos'), ('config', '--config'),
                  ('node', '--node'), ('to_rhos', '--to-rhos'), ('theta', '--theta'))


def _stack_mode(args):
    """True when a stack option is given (the stack form of solve / track)."""
    return any(getattr(args, name, None) is not None for name, _ in _STACK_OPTIONS)


class _StackSpec:
    """The modules of a stack command before the CLI overrides: names, base fields, guess."""

    def __init__(self, names, base, config=None):
        self.names = names
        self.base = base
        self.config = config

    def __len__(self):
        return len(self.names)


def _fields_of(p):
    return {name: getattr(p, name) for name in MODULE_FIELDS}


def _stack_spec(args):
    n = args.modules
    config = None
    if args.config is not None:
        from ..params_file import ConfigError, load_stack_config
        _check_input(args.config, '--config')
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
        return _StackSpec(config.names, [_fields_of(m.params) for m in config.modules], config)
    return _StackSpec([f'm{i}' for i in range(n)],
                      [dict(DEFAULT_FIELDS, rho=None) for _ in range(n)])


def _override(fields_list, values, rhos):
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


def _make_stack(fields_list, names):
    from ..core.stack import Stack
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


def _check_input(path, option):
    if not os.path.isfile(path):
        raise UsageError(f'{option}: no such file {path!r}')


def stack_equilibrium_record(e):
    """JSON-ready dict of a StackEquilibrium (radians, SI; eigenvalues in N/m)."""
    return {
        'theta': [[float(a), float(b)] for a, b in e.theta],
        'stable': bool(e.stable),
        'eigenvalues': [float(v) for v in e.eigenvalues],
        'energy': float(e.energy),
        'actuator_forces': [float(v) for v in e.actuator_forces],
        'head': {'x': float(e.head_position[0]), 'y': float(e.head_position[1]),
                 'angle': float(e.head_angle)},
        'residual': float(e.residual),
        'nodes': [[float(x), float(y)] for x, y in e.nodes],
    }


def _head_text(e):
    angle = round(math.degrees(e.head_angle), 3) + 0.0          # no '-0.000'
    return (f'head ({e.head_position[0]:.6g}, {e.head_position[1]:.6g}) m, '
            f'{angle:.3f} deg')


def exact_stack_equilibria(stack):
    """(records sorted by energy, status) of a one-module stack from the exact solver."""
    from ..core.stack import stack_equilibrium_at, StackPath
    result = equilibria(stack.modules[0])
    path = StackPath(stack, stack)
    records = [stack_equilibrium_at(stack, path.state_from_angles([[e.theta1, e.theta2]], 0.0))
               for e in result]
    return sorted(records, key=lambda r: r.energy), result.status


def cmd_stack_solve(args, out):
    import time

    from ..core.stack import stack_equilibria
    spec = _stack_spec(args)
    if args.rho is not None and args.rhos is not None:
        raise UsageError('give --rho (every module) or --rhos (one per module), not both')
    stack = _make_stack(_override(spec.base, _values(args), args.rhos), spec.names)
    n = len(spec)
    method = args.method or 'auto'
    if method == 'auto':
        method = 'exact' if n == 1 else 'multi-start'
    if method == 'exact' and n > 1:
        raise UsageError('--method exact needs one module: a stack has no polynomial '
                         'elimination (use the multi-start search)')
    if method == 'exact' and (args.starts is not None or args.seed is not None):
        raise UsageError('--starts/--seed are for the multi-start search (--method multi-start)')
    starts = DEFAULT_STARTS if args.starts is None else args.starts
    seed = 0 if args.seed is None else args.seed
    t0 = time.perf_counter()
    if method == 'exact':
        records, status = exact_stack_equilibria(stack)
    else:
        records, status = stack_equilibria(stack, starts=starts, seed=seed), 'ok'
    seconds = time.perf_counter() - t0
    num_stable = sum(r.stable for r in records)
    if method == 'exact':
        how = 'exact (polynomial elimination, complete)'
    else:
        how = (f'multi-start search, not guaranteed complete ({starts} Newton starts + '
               f'{max(4, starts // 4)} settles, seed {seed})')
    if args.json:
        doc = {'method': method, 'complete': method == 'exact' and status == 'ok',
               'status': status, 'note': how, 'modules': spec.names,
               'params': [params_record(m) for m in stack.modules],
               'num_equilibria': len(records), 'num_stable': num_stable,
               'equilibria': [stack_equilibrium_record(r) for r in records
                              if r.stable or not args.stable_only]}
        if method != 'exact':
            doc.update(starts=starts, seed=seed)
        out.write(json.dumps(doc, indent=2) + '\n')
        return EXIT_OK
    out.write(describe_modules(stack.modules, spec.names) + '\n')
    found = 'found' if method != 'exact' else ''
    head = (f'{how}: {len(records)} equilibria {found}'.rstrip()
            + f', {num_stable} stable ({seconds:.2f} s)')
    if status != 'ok':
        head += f' (status {status}: the equilibria are not isolated)'
    out.write(head + '\n')
    if records:
        out.write(format_stack_table(records, spec.names, args.stable_only) + '\n')
    return EXIT_OK


def format_stack_table(records, names, stable_only=False):
    """A block per equilibrium: summary line, then one row per module (angles in degrees)."""
    width = max(6, max(len(n) for n in names))
    lines = []
    for i, r in enumerate(records, 1):
        if stable_only and not r.stable:
            continue
        lines.append(f'#{i}  {"stable" if r.stable else "unstable"}  energy {r.energy:.6g} J  '
                     f'{_head_text(r)}  eigenvalues[N/m] '
                     + ' '.join(f'{v:.4g}' for v in r.eigenvalues))
        lines.append(f'    {"module".ljust(width)}  theta1[deg]  theta2[deg]  actuator[N]')
        for name, t, f in zip(names, r.theta, r.actuator_forces):
            lines.append(f'    {name.ljust(width)}  {math.degrees(t[0]):11.3f}  '
                         f'{math.degrees(t[1]):11.3f}  {f:11.4f}')
    return '\n'.join(lines)


def _stack_guess(args, spec, stack):
    if args.theta is not None:
        if args.theta1 is not None or args.theta2 is not None:
            raise UsageError('give --theta or --theta1/--theta2, not both')
        return np.reshape(args.theta, (len(spec), 2)).tolist(), 'given (--theta)'
    if args.theta1 is not None or args.theta2 is not None:
        if len(spec) != 1:
            raise UsageError('--theta1/--theta2 are for one module: give --theta with '
                             f'{2 * len(spec)} angles')
        return [list(_start_guess(args))], 'given (--theta1/--theta2)'
    if spec.config is not None:
        return spec.config.initial_theta, f'initial_theta of {args.config}'
    if len(spec) == 1:
        return [list(start_equilibrium(stack.modules[0], None).theta)], 'upright'
    return upright_guess(stack.modules), 'upright'


def stack_jump_record(jump):
    head = jump.stack.modules[-1]
    return {'kind': jump.kind, 's': float(jump.s),
            'rho': [float(m.rho) for m in jump.stack.modules],
            'theta': [[float(a), float(b)] for a, b in jump.from_theta],
            'landing': {'theta': [[float(a), float(b)] for a, b in jump.to_theta]},
            'ambiguous': bool(jump.ambiguous), 'F3': float(head.f3y), 'F4': float(head.f4y)}


def cmd_stack_track(args, out):
    from ..core.stack import settle_stack, track_stack
    spec = _stack_spec(args)
    if args.rho is not None and args.rhos is not None:
        raise UsageError('give --rho (every module) or --rhos (one per module), not both')
    if args.to_rho is not None and args.to_rhos is not None:
        raise UsageError('give --to-rho (every module) or --to-rhos (one per module), not both')
    start_fields = _override(spec.base, _values(args), args.rhos)
    end_fields = _override(start_fields, _values(args, prefix='to_'), args.to_rhos)
    start = _make_stack(start_fields, spec.names)
    end = _make_stack(end_fields, spec.names)
    guess, source = _stack_guess(args, spec, start)
    try:
        first = settle_stack(start, guess)
    except (ValueError, RuntimeError) as exc:
        raise UsageError(f'cannot settle from the start guess ({source}): {exc}') from None
    track = track_stack(start, end, first)
    final = track.final
    names = spec.names

    def state(e, stack):
        doc = stack_equilibrium_record(e)
        doc.pop('nodes')
        doc['rho'] = [float(m.rho) for m in stack.modules]
        return doc

    doc = {
        'status': track.status, 'message': track.message, 'modules': names,
        'start': dict(state(first, start), guess=[[float(a), float(b)] for a, b in guess],
                      guess_source=source, params=[params_record(m) for m in start.modules]),
        'events': [stack_jump_record(j) for j in track.jumps],
        'passages': [stack_passage_record(p) for p in track.passages],
        'undecided': [undecided_record(u) for u in track.undecided],
        'final': dict(state(final, track.end),
                      params=[params_record(m) for m in track.end.modules]),
    }
    code = EXIT_OK if track.status == 'ok' else EXIT_FAILURE
    if args.json:
        out.write(json.dumps(doc, indent=2) + '\n')
        return code
    out.write(f'path: {describe_modules(start.modules, names)}\n'
              f'  ->  {describe_modules(end.modules, names)}\n')
    out.write(f'start ({source}): theta [deg] {theta_text(first.theta, names)}; '
              f'{_head_text(first)}; margin {first.stability_margin:.4g} N/m\n')
    out.writelines(stack_passage_line(p, names) for p in track.passages)
    out.writelines(undecided_line(u, names) for u in track.undecided)
    if not track.jumps:
        out.write('no jump: the stack stays on its branch\n')
    for i, j in enumerate(track.jumps, 1):
        note = ' (ambiguous: the two sides land differently)' if j.ambiguous else ''
        rho = ', '.join(f'{m.rho:.9g}' for m in j.stack.modules)
        out.write(f'event {i}: {j.kind} at s={j.s:.9f} rho=({rho}): theta [deg] '
                  f'{theta_text(j.from_theta, names)} -> lands at '
                  f'{theta_text(j.to_theta, names)}{note}\n')
    out.write(f'final: theta [deg] {theta_text(final.theta, names)}; {_head_text(final)}; '
              f'{"stable" if final.stable else "UNSTABLE"}, margin '
              f'{final.stability_margin:.4g} N/m; status {track.status}'
              + (f': {track.message}' if track.message else '') + '\n')
    return code


# ---------------------------------------------------------------------------
# map

def parse_axis(spec, option):
    """(name, lo, hi, count) from a --x/--y spec, or UsageError."""
    name, lo, hi, count = spec
    name = canonical_name(name)
    try:
        lo, hi = finite_float(lo), finite_float(hi)
    except argparse.ArgumentTypeError as exc:
        raise UsageError(f'{option} {name}: {exc}') from None
    try:
        count = positive_int(count)
    except argparse.ArgumentTypeError as exc:
        raise UsageError(f'{option} {name}: COUNT {exc}') from None
    if count > 1 and not lo < hi:
        raise UsageError(f'{option} {name}: MIN must be below MAX, got {lo:g} {hi:g}')
    if count > 20000:
        raise UsageError(f'{option} {name}: COUNT {count} is too large (at most 20000)')
    for v in (lo, hi):
        try:
            check_domain(name, v)
        except UsageError as exc:
            raise UsageError(f'{option}: {exc} (the axis range must stay in the domain)') \
                from None
    return name, lo, hi, count


def _check_output(path, option):
    if path is None or path == '-':
        return
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        raise UsageError(f'{option}: directory {directory!r} does not exist')


def cmd_map(args, out):
    from .. import figures
    if args.jobs < 0:
        raise UsageError(f'--jobs must be >= 0 (0 = automatic), got {args.jobs}')
    xname, xlo, xhi, nx = parse_axis(args.x, '--x')
    yname, ylo, yhi, ny = parse_axis(args.y, '--y')
    if overlapping(xname, yname):
        raise UsageError(f'--x {xname} and --y {yname} set the same parameter')
    fixed = _values(args)
    for axis in (xname, yname):
        for name in fixed:
            if overlapping(axis, name) and (axis in _OVERLAPS or name == axis):
                raise UsageError(f'{axis} is a map axis: do not also give --{name}')
    if 'rho' not in fixed and 'rho' not in (xname, yname):
        raise UsageError('rho is required: give --rho or use rho as an axis')
    if nx * ny > 16_000_000:
        raise UsageError(f'{nx} x {ny} points is too many (at most 16 million)')
    _check_output(args.csv, '--csv')
    _check_output(args.png, '--png')
    _check_output(args.boundaries_csv, '--boundaries-csv')
    if args.csv == '-' and args.boundaries_csv == '-':
        raise UsageError('--csv and --boundaries-csv cannot both go to stdout')
    want_curves = args.boundaries or args.boundaries_csv is not None
    if want_curves:
        for name in (xname, yname):
            if name not in figures.BOUNDARY_AXES:
                raise UsageError(f'--boundaries: {name} cannot be an axis of the exact curves '
                                 f'(choose from {", ".join(figures.BOUNDARY_AXES)})')
        if args.boundaries and not args.png:
            raise UsageError('--boundaries draws on the PNG: give --png '
                             '(or --boundaries-csv for the points)')
    # Validate the fixed parameters together with a point of the plane.
    probe = dict(fixed)
    probe[xname], probe[yname] = xhi, yhi
    make_params(probe)
    result = figures.compute_map(fixed, (xname, xlo, xhi, nx), (yname, ylo, yhi, ny),
                                 jobs=args.jobs, progress=not args.no_progress)
    counts = result.histogram()
    text = ', '.join(f'{n} stable: {c}' for n, c in sorted(counts.items()))
    msg_out = sys.stderr if '-' in (args.csv, args.boundaries_csv) else out
    msg_out.write(f'map {xname} x {yname} ({nx} x {ny} = {nx * ny} points) at '
                  f'{describe(fixed, skip=(xname, yname))}: {text}; '
                  f'{result.seconds:.2f} s on {result.jobs} process(es)\n')
    curves = None
    if want_curves:
        boundaries = figures.compute_boundaries(fixed, (xname, xlo, xhi, nx),
                                                (yname, ylo, yhi, ny))
        curves = boundaries.curves
        msg_out.write(boundaries.summary() + '\n')
        if args.boundaries_csv == '-':
            figures.write_boundaries_csv(boundaries, out)
        elif args.boundaries_csv:
            with open(args.boundaries_csv, 'w', encoding='ascii') as f:
                figures.write_boundaries_csv(boundaries, f)
            msg_out.write(f'wrote {args.boundaries_csv}\n')
    if args.csv:
        if args.csv == '-':
            figures.write_map_csv(result, out)
        else:
            with open(args.csv, 'w', encoding='ascii') as f:
                figures.write_map_csv(result, f)
            msg_out.write(f'wrote {args.csv}\n')
    if args.png:
        figures.plot_map(result, args.png, title=args.title,
                         curves=curves if args.boundaries else None)
        msg_out.write(f'wrote {args.png}\n')
    return EXIT_OK


# ---------------------------------------------------------------------------
# diagram

def cmd_diagram(args, out):
    from .. import figures
    lo, hi = args.from_rho, args.to_rho
    for option, v in (('--from-rho', lo), ('--to-rho', hi)):
        if not v > 0.0:
            raise UsageError(f'{option} must be positive (rho = 0 is degenerate), got {v:g}')
    if not lo < hi:
        raise UsageError(f'--from-rho must be below --to-rho, got {lo:g} {hi:g}')
    if args.count < 2:
        raise UsageError('--count must be at least 2')
    if args.count > 100000:
        raise UsageError(f'--count {args.count} is too large (at most 100000)')
    fixed = _values(args)
    fixed.pop('rho', None)
    make_params(dict(fixed, rho=lo))
    guess = _start_guess(args)
    if args.track is not None:
        if len(args.track) < 2:
            raise UsageError('--track needs at least two rho values')
        for v in args.track:
            check_domain('rho', v)
        guess = start_equilibrium(make_params(dict(fixed, rho=args.track[0])), guess).theta
    elif guess is not None:
        raise UsageError('--theta1/--theta2 are only used with --track')
    _check_output(args.png, '--png')
    _check_output(args.csv, '--csv')
    diagram = figures.compute_diagram(fixed, lo, hi, args.count)
    tracked = None
    if args.track is not None:
        tracked = figures.track_path(fixed, args.track, guess, diagram)
    out.write(f'diagram rho {lo:g}..{hi:g} at {describe(fixed)}: {len(diagram.branches)} '
              f'branches, {len(diagram.events)} events\n')
    for e in diagram.events:
        out.write(f'  {e.kind} at rho={e.rho:.6f}: theta = ({math.degrees(e.theta[0]):.3f}, '
                  f'{math.degrees(e.theta[1]):.3f}) deg\n')
    if tracked is not None:
        for leg in tracked.legs:
            out.write(f'track rho {leg.rho0:g} -> {leg.rho1:g}: ')
            if not leg.jumps:
                out.write('no jump\n')
            else:
                out.write('; '.join(f'{j.kind} at rho={j.params.rho:.6f}, lands at '
                                    f'({math.degrees(j.to_theta[0]):.3f}, '
                                    f'{math.degrees(j.to_theta[1]):.3f}) deg'
                                    for j in leg.jumps) + '\n')
    if args.csv:
        with open(args.csv, 'w', encoding='ascii') as f:
            figures.write_diagram_csv(diagram, f)
        out.write(f'wrote {args.csv}\n')
    figures.plot_diagram(diagram, args.png, tracked=tracked, title=args.title)
    out.write(f'wrote {args.png}\n')
    return EXIT_OK


# ---------------------------------------------------------------------------
# range and limit (exact analysis, docs/model.md section 3 / the paper's sections 4-5)

def _end_record(end):
    return {'rho': float(end.rho), 'kind': end.kind,
            'theta1': float(end.theta[0]), 'theta2': float(end.theta[1]),
            'eigenvalues': [float(v) for v in end.eigenvalues], 'symmetry': end.symmetry}


def _end_text(end):
    what = end.kind + (f', {end.symmetry} symmetry' if end.symmetry else '')
    if end.kind == 'limit':
        what += ': still stable at the search bound'
    return (f'{end.rho:.10f}  ({what}); theta = ({math.degrees(end.theta[0]):.3f}, '
            f'{math.degrees(end.theta[1]):.3f}) deg')


def cmd_range(args, out):
    from ..core.analysis import operation_range
    values = _values(args)
    p = make_params(values)
    bounds = None
    if args.rho_bounds is not None:
        lo, hi = args.rho_bounds
        if not 0.0 <= lo < hi:
            raise UsageError(f'--rho-bounds must satisfy 0 <= MIN < MAX, got {lo:g} {hi:g}')
        if not lo <= p.rho <= hi:
            raise UsageError(f'--rho {p.rho:g} is outside --rho-bounds {lo:g} {hi:g}')
        bounds = (lo, hi)
    first = start_equilibrium(p, _start_guess(args))
    try:
        result = operation_range(p, first.theta, rho_bounds=bounds)
    except ValueError as exc:
        raise RuntimeError(f'operation range: {exc}') from None
    if args.json:
        doc = {'rho_min': float(result.rho_min), 'rho_max': float(result.rho_max),
               'width': float(result.width),
               'start': {'rho': p.rho, 'theta1': float(result.theta[0]),
                         'theta2': float(result.theta[1])},
               'lower': _end_record(result.lower), 'upper': _end_record(result.upper),
               'bounds': [float(v) for v in result.bounds], 'params': params_record(p)}
        out.write(json.dumps(doc, indent=2) + '\n')
        return EXIT_OK
    out.write(f'operation range of the stable branch through theta = '
              f'({math.degrees(result.theta[0]):.3f}, {math.degrees(result.theta[1]):.3f}) deg '
              f'at {describe(values)}:\n')
    out.write(f'  rho_min = {_end_text(result.lower)}\n')
    out.write(f'  rho_max = {_end_text(result.upper)}\n')
    out.write(f'  width   = {result.width:.10f}\n')
    return EXIT_OK


def cmd_limit(args, out):
    from ..core.analysis import two_stable_limit
    values = {}
    for name in ('L1', 'L2', 'k', 'ka', 'kb', 'kc', 'F3x', 'F4x'):
        v = getattr(args, name)
        if v is not None:
            check_domain(name, v)
            values[name] = v
    design = {'L1': values.get('L1', 1.0), 'L2': values.get('L2', 1.0),
              'k': values.get('k', 100.0), 'ka': values.get('ka'), 'kb': values.get('kb'),
              'kc': values.get('kc'), 'f3x': values.get('F3x', 0.0), 'f4x': values.get('F4x', 0.0)}
    c = two_stable_limit(design.pop('L2'), pushing=args.pushing, **design)
    side = 'pushing' if args.pushing else 'pulling'
    if args.json:
        doc = {'F3': float(c.F3), 'F4': float(c.F4), 'rho': float(c.rho),
               'theta1': float(c.theta[0]), 'theta2': float(c.theta[1]),
               'axis': [float(v) for v in c.axis], 'side': side, 'params': params_record(c.params)}
        out.write(json.dumps(doc, indent=2) + '\n')
        return EXIT_OK
    shown = describe(dict(values, rho=c.rho), skip=('rho', 'F3', 'F4'))
    out.write(f'point C ({side}), the tip of the 2-stable region, for {shown}:\n')
    out.write(f'  F3 = {c.F3:.10f} N, F4 = {c.F4:.10f} N at rho = {c.rho:.10f} m\n')
    out.write(f'  theta = ({math.degrees(c.theta[0]):.3f}, {math.degrees(c.theta[1]):.3f}) deg, '
              f'where the Hessian vanishes (H = 0)\n')
    out.write('  the 2-stable region reaches C along (d rho, d F3, d F4) = '
              f'({c.axis[0]:.6f}, {c.axis[1]:.6f}, {c.axis[2]:.6f})\n')
    return EXIT_OK


def cmd_snap(args, out):
    """``snap``: the module and start as ``track`` parses them; the rest in snap_command."""
    start = make_params(_values(args))
    return snap_command.run_snap(args, out, start,
                                 start_equilibrium(start, _start_guess(args)).theta)


# ---------------------------------------------------------------------------

def main(argv=None):
    """Entry point of the ``tensegrity`` console script; returns the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:            # argparse: --help (0) or a usage error (2)
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    prog = f'tensegrity {args.command}'
    try:
        return args.func(args, sys.stdout)
    except (UsageError, InvalidParameterError) as exc:
        sys.stderr.write(f'{prog}: error: {exc}\n')
        return EXIT_USAGE
    except BrokenPipeError:
        # Output piped into e.g. head: not an error of ours.
        try:
            sys.stdout = open(os.devnull, 'w')
        except OSError:
            pass
        return EXIT_OK
    except KeyboardInterrupt:
        sys.stderr.write(f'{prog}: interrupted\n')
        return 130
    except (OSError, RuntimeError, ImportError) as exc:     # ImportError: no tools extra
        sys.stderr.write(f'{prog}: error: {exc}\n')
        return EXIT_FAILURE
    except Exception as exc:             # a bug of ours: still one line, never a traceback
        sys.stderr.write(f'{prog}: internal error (please report): '
                         f'{type(exc).__name__}: {exc}\n')
        return EXIT_FAILURE


if __name__ == '__main__':
    sys.exit(main())
