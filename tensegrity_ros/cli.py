"""``tensegrity``: the offline command line of tensegrity_ros (DESIGN.md section 6).

Subcommands::

    tensegrity solve   --rho R [params] [--json]
    tensegrity track   --rho R0 --to-rho R1 [--to-F3 ...] [--theta1 T1 --theta2 T2] [--json]
    tensegrity map     --x NAME MIN MAX COUNT --y NAME MIN MAX COUNT [params] [--csv F] [--png F]
    tensegrity diagram --from-rho A --to-rho B [--count N] [params] --png F [--csv F]
                       [--track R0 R1 ...]

Units are SI (m, N, N/m, kg); angles are radians on input and in JSON/CSV, the
human-readable tables show degrees.  The paper's F3, F4 are the vertical force
components (positive pulls up).  ``--k`` sets all three springs, ``--ka/--kb/--kc``
override it; ``--F`` sets F3 = F4, ``--F3/--F4`` override it.

Bad arguments give a one-line message on stderr and exit status 2.  The module
does not import rclpy (nor matplotlib unless a PNG is requested).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys

from .core import InvalidParameterError, ModuleParams, equilibria

#: Parameters a user can set, by CLI name: (ModuleParams fields it sets, help).
#: Group names (k, F) set several fields; the specific names override them.
PARAMETERS = {
    'rho': (('rho',), 'actuated base length A1A2 (m)'),
    'L1': (('L1',), 'length of rod A1A3 (m, default 1)'),
    'L2': (('L2',), 'length of rod A2A4 (m, default 1)'),
    'k': (('ka', 'kb', 'kc'), 'stiffness of all three springs (N/m, default 100)'),
    'ka': (('ka',), 'stiffness of spring A2A3 (N/m; overrides --k)'),
    'kb': (('kb',), 'stiffness of spring A1A4 (N/m; overrides --k)'),
    'kc': (('kc',), 'stiffness of spring A3A4 (N/m; overrides --k)'),
    'F': (('f3y', 'f4y'), 'vertical force at A3 and at A4 (N, F3 = F4 = F; + pulls up)'),
    'F3': (('f3y',), 'vertical force at A3 (N, + pulls up, - pushes down; overrides --F)'),
    'F4': (('f4y',), 'vertical force at A4 (N, + pulls up, - pushes down; overrides --F)'),
    'F3x': (('f3x',), 'horizontal force at A3 (N, + along A1->A2)'),
    'F4x': (('f4x',), 'horizontal force at A4 (N, + along A1->A2)'),
    'm1': (('m1',), 'mass of rod A1A3 (kg, weight acts along -y)'),
    'm2': (('m2',), 'mass of rod A2A4 (kg, weight acts along -y)'),
}
#: Group names are applied first so that specific names override them.
_ORDER = ('rho', 'L1', 'L2', 'k', 'F', 'ka', 'kb', 'kc', 'F3', 'F4', 'F3x', 'F4x', 'm1', 'm2')
#: Names whose value must be > 0, resp. >= 0.
_POSITIVE = {'rho', 'L1', 'L2', 'k', 'ka', 'kb', 'kc'}
_NON_NEGATIVE = {'m1', 'm2'}
#: Default values of the fields (the paper's normalisation L1 = 1, k = 100).
DEFAULT_FIELDS = dict(L1=1.0, L2=1.0, ka=100.0, kb=100.0, kc=100.0,
                      f3x=0.0, f3y=0.0, f4x=0.0, f4y=0.0, m1=0.0, m2=0.0)
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


def resolve_fields(values):
    """ModuleParams keyword arguments from CLI-named values (scalars or arrays).

    Defaults are the paper's (L1 = L2 = 1, k = 100, no load); group names (k, F)
    are applied before the specific ones so that ``--ka`` overrides ``--k``.
    """
    fields = dict(DEFAULT_FIELDS)
    for name in _ORDER:
        if name in values and values[name] is not None:
            for field in PARAMETERS[name][0]:
                fields[field] = values[name]
    return fields


def make_params(values):
    """A validated ModuleParams from CLI-named values (needs 'rho')."""
    if values.get('rho') is None:
        raise UsageError('rho is required')
    return ModuleParams(**resolve_fields(values))


def describe(values, skip=()):
    """Compact text of the parameters, e.g. 'L1=1 L2=1 k=100 F3=F4=5' (for titles)."""
    f = resolve_fields(values)
    skip_fields = set()
    for name in skip:
        skip_fields.update(PARAMETERS[name][0])
    parts = []

    def num(v):
        return f'{v:g}'

    for field, label in (('rho', 'rho'), ('L1', 'L1'), ('L2', 'L2')):
        if field in f and field not in skip_fields and f.get(field) is not None:
            parts.append(f'{label}={num(f[field])}')
    springs = [(s, f[s]) for s in ('ka', 'kb', 'kc') if s not in skip_fields]
    if springs:
        if len(springs) == 3 and len({v for _, v in springs}) == 1:
            parts.append(f'k={num(springs[0][1])}')
        else:
            parts.extend(f'{s}={num(v)}' for s, v in springs)
    vertical = [(lab, f[fld]) for fld, lab in (('f3y', 'F3'), ('f4y', 'F4'))
                if fld not in skip_fields]
    if len(vertical) == 2 and vertical[0][1] == vertical[1][1]:
        parts.append(f'F3=F4={num(vertical[0][1])}')
    else:
        parts.extend(f'{lab}={num(v)}' for lab, v in vertical)
    for fld, lab in (('f3x', 'F3x'), ('f4x', 'F4x'), ('m1', 'm1'), ('m2', 'm2')):
        if fld not in skip_fields and f[fld] != 0.0:
            parts.append(f'{lab}={num(f[fld])}')
    return ' '.join(parts)


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

    p = sub.add_parser('solve', help='every equilibrium at one parameter point',
                       description='Print every equilibrium (at most 6) with its stability.')
    _add_parameter_options(p, required=('rho',))
    p.add_argument('--json', action='store_true', help='machine-readable output')
    p.set_defaults(func=cmd_solve)

    p = sub.add_parser(
        'track', help='follow the stable equilibrium along a straight parameter path',
        description='Start in the stable equilibrium whose basin holds the start guess '
                    '(--theta1/--theta2; default: the stable equilibrium with the largest '
                    'y3 + y4, i.e. the upper one), move all parameters together along the '
                    'straight path to the --to-* values and report every jump.')
    _add_parameter_options(p, required=('rho',))
    _add_parameter_options(p, prefix='to-')
    p.add_argument('--theta1', type=finite_float, metavar='RAD',
                   help='start guess for theta1 (rad); needs --theta2')
    p.add_argument('--theta2', type=finite_float, metavar='RAD',
                   help='start guess for theta2 (rad); needs --theta1')
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
    return parser


# ---------------------------------------------------------------------------
# solve

def equilibrium_record(p, e):
    """JSON-ready dict of one equilibrium (radians, SI)."""
    from .core import node_positions
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
    """The stable equilibrium the mechanism starts in.

    With a guess: the one whose basin holds it (``settle``).  Without: the stable
    equilibrium with the largest y3 + y4 (the upper one, as in the paper's figures).
    """
    if guess is not None:
        from .core.tracking import settle
        try:
            return settle(p, guess)
        except (ValueError, RuntimeError) as exc:
            raise UsageError(f'cannot settle from the start guess: {exc}') from None
    stable = equilibria(p).stable
    if not stable:
        raise UsageError(f'no stable equilibrium at the start ({describe_params(p)}): '
                         'the point is degenerate; move it slightly')
    return max(stable, key=lambda e: p.L1 * math.sin(e.theta1) + p.L2 * math.sin(e.theta2))


def describe_params(p):
    return describe({'rho': p.rho, 'L1': p.L1, 'L2': p.L2, 'ka': p.ka, 'kb': p.kb,
                     'kc': p.kc, 'F3': p.f3y, 'F4': p.f4y, 'F3x': p.f3x, 'F4x': p.f4x,
                     'm1': p.m1, 'm2': p.m2})


def _tracker():
    try:
        from .core import track_module, settle  # noqa: F401
    except ImportError:
        try:
            from .core.tracking import track_module, settle  # noqa: F401
        except ImportError:
            raise RuntimeError('the tracker (tensegrity_ros.core.track_module) is not '
                               'available in this build') from None
    return track_module


def run_track(start, end, guess):
    """(start Equilibrium, ModuleTrack) for one straight path."""
    track_module = _tracker()
    first = start_equilibrium(start, guess)
    return first, track_module(start, end, first.theta)


def jump_record(jump):
    return {'kind': jump.kind, 's': float(jump.s), 'rho': float(jump.params.rho),
            'theta1': float(jump.from_theta[0]), 'theta2': float(jump.from_theta[1]),
            'landing': {'theta1': float(jump.to_theta[0]), 'theta2': float(jump.to_theta[1])},
            'ambiguous': bool(jump.ambiguous),
            'F3': float(jump.params.f3y), 'F4': float(jump.params.f4y)}


def cmd_track(args, out):
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
    out.write(f'path: {describe_params(start)}  ->  {describe_params(end)}\n')
    out.write(f'start: theta = ({deg(first.theta1):.3f}, {deg(first.theta2):.3f}) deg, '
              f'{first.kind}\n')
    if not track.jumps:
        out.write('no jump: the mechanism stays on its branch\n')
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
    from . import figures
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
    # Validate the fixed parameters together with a point of the plane.
    probe = dict(fixed)
    probe[xname], probe[yname] = xhi, yhi
    make_params(probe)
    result = figures.compute_map(fixed, (xname, xlo, xhi, nx), (yname, ylo, yhi, ny),
                                 jobs=args.jobs, progress=not args.no_progress)
    counts = result.histogram()
    text = ', '.join(f'{n} stable: {c}' for n, c in sorted(counts.items()))
    msg_out = sys.stderr if args.csv == '-' else out
    msg_out.write(f'map {xname} x {yname} ({nx} x {ny} = {nx * ny} points) at '
                  f'{describe(fixed, skip=(xname, yname))}: {text}; '
                  f'{result.seconds:.2f} s on {result.jobs} process(es)\n')
    if args.csv:
        if args.csv == '-':
            figures.write_map_csv(result, out)
        else:
            with open(args.csv, 'w', encoding='ascii') as f:
                figures.write_map_csv(result, f)
            msg_out.write(f'wrote {args.csv}\n')
    if args.png:
        figures.plot_map(result, args.png, title=args.title)
        msg_out.write(f'wrote {args.png}\n')
    return EXIT_OK


# ---------------------------------------------------------------------------
# diagram

def cmd_diagram(args, out):
    from . import figures
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
    except (OSError, RuntimeError) as exc:
        sys.stderr.write(f'{prog}: error: {exc}\n')
        return EXIT_FAILURE


if __name__ == '__main__':
    sys.exit(main())
