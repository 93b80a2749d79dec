"""``tensegrity solve``: every equilibrium at one parameter point, of one module (the
exact solver) or of a neck stack (the multi-start search, or exact for one module).
"""
from __future__ import annotations

import json
import math

from .common import (add_parameter_options, EXIT_OK, make_params, parameter_values, positive_int,
                     UsageError)
from .records import head_text, params_record, stack_equilibrium_record
from .stack_options import add_stack_options, make_stack, override, stack_mode, stack_spec
from ..core import equilibria
from ..problem import describe, describe_modules

#: Default number of multi-start starts (as stack_equilibria).
DEFAULT_STARTS = 64


def add_parser(subparsers):
    """Register ``solve`` and its options on ``subparsers``."""
    p = subparsers.add_parser(
        'solve', help='every equilibrium at one parameter point (one module or a stack)',
        description='Print every equilibrium (at most 6) with its stability. With --modules, '
                    '--rhos or --config: the equilibria of a neck stack (docs/model.md section 4) '
                    'by a multi-start search (exact for one module).')
    add_parameter_options(p)
    group = add_stack_options(p)
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
    p.set_defaults(func=run)


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


def run(args, out):
    """``tensegrity solve``: returns the exit status."""
    if stack_mode(args):
        return run_stack(args, out)
    for option, value in (('--method', args.method), ('--starts', args.starts),
                          ('--seed', args.seed), ('--stable-only', args.stable_only or None)):
        if value is not None:
            raise UsageError(f'{option} is for a stack (give --modules N, --rhos or --config)')
    values = parameter_values(args)
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
    """One module's equilibria as a table (angles in degrees)."""
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


def exact_stack_equilibria(stack):
    """(records sorted by energy, status) of a one-module stack from the exact solver."""
    from ..core.neck.stack import stack_equilibrium_at, StackPath
    result = equilibria(stack.modules[0])
    path = StackPath(stack, stack)
    records = [stack_equilibrium_at(stack, path.state_from_angles([[e.theta1, e.theta2]], 0.0))
               for e in result]
    return sorted(records, key=lambda r: r.energy), result.status


def run_stack(args, out):
    """The stack form of ``solve``."""
    import time

    from ..core.neck.stack import stack_equilibria
    spec = stack_spec(args)
    if args.rho is not None and args.rhos is not None:
        raise UsageError('give --rho (every module) or --rhos (one per module), not both')
    stack = make_stack(override(spec.base, parameter_values(args), args.rhos), spec.names)
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
                     f'{head_text(r)}  eigenvalues[N/m] '
                     + ' '.join(f'{v:.4g}' for v in r.eigenvalues))
        lines.append(f'    {"module".ljust(width)}  theta1[deg]  theta2[deg]  actuator[N]')
        for name, t, f in zip(names, r.theta, r.actuator_forces):
            lines.append(f'    {name.ljust(width)}  {math.degrees(t[0]):11.3f}  '
                         f'{math.degrees(t[1]):11.3f}  {f:11.4f}')
    return '\n'.join(lines)
