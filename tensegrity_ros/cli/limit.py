"""``tensegrity limit``: point C, the tip of the 2-stable region (the paper's fig. 6):
the largest forces with two stable equilibria.
"""
from __future__ import annotations

import json
import math

from .common import check_domain, EXIT_OK, finite_float
from .records import params_record
from ..problem import describe, PARAMETERS


def add_parser(subparsers):
    """Register ``limit`` and its options on ``subparsers``."""
    p = subparsers.add_parser(
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
    p.set_defaults(func=run)


def run(args, out):
    """``tensegrity limit``: returns the exit status."""
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
