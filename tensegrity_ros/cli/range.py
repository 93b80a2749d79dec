"""``tensegrity range``: the operation range, the rho interval over which the stable
branch through the start lasts, and what ends it on each side (docs/model.md section 3).
"""
from __future__ import annotations

import json
import math

from .common import (add_parameter_options, EXIT_OK, finite_float, make_params, parameter_values,
                     start_equilibrium, start_guess, UsageError)
from .records import params_record
from ..problem import describe


def add_parser(subparsers):
    """Register ``range`` and its options on ``subparsers``."""
    p = subparsers.add_parser(
        'range', help='operation range: the rho interval over which a stable branch lasts',
        description='Follow the stable branch through the start configuration (the stable '
                    'equilibrium whose basin holds --theta1/--theta2; default: the upper '
                    'one) in rho, everything else fixed, and report where it ends on each '
                    'side and why: a fold, a branch point (symmetry-breaking pitchfork) or '
                    'the search bound (limit). Ends are solved on regular extended systems '
                    '(exact to rounding).')
    add_parameter_options(p)
    p.add_argument('--theta1', type=finite_float, metavar='RAD',
                   help='start guess for theta1 (rad); needs --theta2')
    p.add_argument('--theta2', type=finite_float, metavar='RAD',
                   help='start guess for theta2 (rad); needs --theta1')
    p.add_argument('--rho-bounds', type=finite_float, nargs=2, metavar=('MIN', 'MAX'),
                   help='search interval in rho (default 0 .. 2 (L1 + L2))')
    p.add_argument('--json', action='store_true', help='machine-readable output')
    p.set_defaults(func=run)


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


def run(args, out):
    """``tensegrity range``: returns the exit status."""
    from ..core.analysis import operation_range
    values = parameter_values(args)
    p = make_params(values)
    bounds = None
    if args.rho_bounds is not None:
        lo, hi = args.rho_bounds
        if not 0.0 <= lo < hi:
            raise UsageError(f'--rho-bounds must satisfy 0 <= MIN < MAX, got {lo:g} {hi:g}')
        if not lo <= p.rho <= hi:
            raise UsageError(f'--rho {p.rho:g} is outside --rho-bounds {lo:g} {hi:g}')
        bounds = (lo, hi)
    first = start_equilibrium(p, start_guess(args))
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
