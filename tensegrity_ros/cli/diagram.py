"""``tensegrity diagram``: the bifurcation diagram in rho (PNG, CSV), with a tracked
path over it (:mod:`..figures`, imported when run).
"""
from __future__ import annotations

import math

from .common import (add_parameter_options, check_domain, check_output, EXIT_OK, finite_float,
                     make_params, parameter_values, positive_int, start_equilibrium, start_guess,
                     UsageError)
from ..problem import describe


def add_parser(subparsers):
    """Register ``diagram`` and its options on ``subparsers``."""
    p = subparsers.add_parser(
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
    add_parameter_options(p, skip=('rho',))
    p.add_argument('--png', metavar='FILE', required=True, help='output image')
    p.add_argument('--csv', metavar='FILE', help='write the branches as CSV')
    p.add_argument('--track', type=finite_float, nargs='+', metavar='R',
                   help='overlay the tracked path through these rho values (at least 2)')
    p.add_argument('--theta1', type=finite_float, metavar='RAD', help='start guess for --track')
    p.add_argument('--theta2', type=finite_float, metavar='RAD', help='start guess for --track')
    p.add_argument('--title', help='plot title (default: the parameters)')
    p.set_defaults(func=run)


def run(args, out):
    """``tensegrity diagram``: returns the exit status."""
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
    fixed = parameter_values(args)
    fixed.pop('rho', None)
    make_params(dict(fixed, rho=lo))
    guess = start_guess(args)
    if args.track is not None:
        if len(args.track) < 2:
            raise UsageError('--track needs at least two rho values')
        for v in args.track:
            check_domain('rho', v)
        guess = start_equilibrium(make_params(dict(fixed, rho=args.track[0])), guess).theta
    elif guess is not None:
        raise UsageError('--theta1/--theta2 are only used with --track')
    check_output(args.png, '--png')
    check_output(args.csv, '--csv')
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
