"""``tensegrity map``: the number of stable equilibria over a parameter plane (CSV,
PNG), with the exact boundaries over it if asked (:mod:`..figures`, imported when run).
"""
from __future__ import annotations

import argparse
import sys

from .common import (add_parameter_options, canonical_name, check_domain, check_output, EXIT_OK,
                     finite_float, make_params, overlapping, parameter_values, positive_int,
                     UsageError)
from ..problem import describe, PARAMETERS

#: Names that overlap: giving both as a map axis and a fixed value is refused.
_OVERLAPS = {'k': {'k', 'ka', 'kb', 'kc'}, 'F': {'F', 'F3', 'F4'}}


def add_parser(subparsers):
    """Register ``map`` and its options on ``subparsers``."""
    p = subparsers.add_parser(
        'map', help='number of stable equilibria over a parameter plane',
        description='Count the stable equilibria on a COUNT x COUNT grid (numpy.linspace, '
                    'both ends included) of two parameters. Axis names: '
                    + ', '.join(PARAMETERS) + ' (F = F3 = F4, k = ka = kb = kc).')
    p.add_argument('--x', nargs=4, required=True, metavar=('NAME', 'MIN', 'MAX', 'COUNT'),
                   help='horizontal axis')
    p.add_argument('--y', nargs=4, required=True, metavar=('NAME', 'MIN', 'MAX', 'COUNT'),
                   help='vertical axis')
    add_parameter_options(p)
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
    p.set_defaults(func=run)


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


def run(args, out):
    """``tensegrity map``: returns the exit status."""
    from .. import figures
    xaxis, yaxis, fixed, want_curves = _checked_plane(args, figures)
    (xname, _, _, nx), (yname, _, _, ny) = xaxis, yaxis
    result = figures.compute_map(fixed, xaxis, yaxis, jobs=args.jobs,
                                 progress=not args.no_progress)
    counts = result.histogram()
    text = ', '.join(f'{n} stable: {c}' for n, c in sorted(counts.items()))
    msg_out = sys.stderr if '-' in (args.csv, args.boundaries_csv) else out
    msg_out.write(f'map {xname} x {yname} ({nx} x {ny} = {nx * ny} points) at '
                  f'{describe(fixed, skip=(xname, yname))}: {text}; '
                  f'{result.seconds:.2f} s on {result.jobs} process(es)\n')
    curves = None
    if want_curves:
        curves = _write_boundaries(args, out, msg_out, figures.compute_boundaries(
            fixed, xaxis, yaxis))
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


def _checked_plane(args, figures):
    """(x axis, y axis, fixed values, whether the exact curves are wanted) of a checked
    command line: UsageError at the first thing wrong."""
    if args.jobs < 0:
        raise UsageError(f'--jobs must be >= 0 (0 = automatic), got {args.jobs}')
    xname, xlo, xhi, nx = parse_axis(args.x, '--x')
    yname, ylo, yhi, ny = parse_axis(args.y, '--y')
    if overlapping(xname, yname):
        raise UsageError(f'--x {xname} and --y {yname} set the same parameter')
    fixed = parameter_values(args)
    for axis in (xname, yname):
        for name in fixed:
            if overlapping(axis, name) and (axis in _OVERLAPS or name == axis):
                raise UsageError(f'{axis} is a map axis: do not also give --{name}')
    if 'rho' not in fixed and 'rho' not in (xname, yname):
        raise UsageError('rho is required: give --rho or use rho as an axis')
    if nx * ny > 16_000_000:
        raise UsageError(f'{nx} x {ny} points is too many (at most 16 million)')
    check_output(args.csv, '--csv')
    check_output(args.png, '--png')
    check_output(args.boundaries_csv, '--boundaries-csv')
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
    return (xname, xlo, xhi, nx), (yname, ylo, yhi, ny), fixed, want_curves


def _write_boundaries(args, out, msg_out, boundaries):
    """Report the exact curves and write their CSV if asked; returns the curves."""
    from .. import figures
    msg_out.write(boundaries.summary() + '\n')
    if args.boundaries_csv == '-':
        figures.write_boundaries_csv(boundaries, out)
    elif args.boundaries_csv:
        with open(args.boundaries_csv, 'w', encoding='ascii') as f:
            figures.write_boundaries_csv(boundaries, f)
        msg_out.write(f'wrote {args.boundaries_csv}\n')
    return boundaries.curves
