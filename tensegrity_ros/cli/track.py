"""``tensegrity track``: follow the stable equilibrium along a straight parameter path
and report every jump, for one module or a neck stack.
"""
from __future__ import annotations

import json
import math

import numpy as np

from .common import (add_parameter_options, EXIT_FAILURE, EXIT_OK, finite_float, make_params,
                     parameter_values, start_equilibrium, start_guess, UsageError)
from .passage_records import (stack_passage_line, stack_passage_record, theta_text, undecided_line,
                              undecided_record)
from .records import head_text, params_record, stack_equilibrium_record
from .stack_options import add_stack_options, make_stack, override, stack_mode, stack_spec
from ..core import track_module
from ..core.simulation.start_state import upright_guess
from ..problem import describe_modules


def add_parser(subparsers):
    """Register ``track`` and its options on ``subparsers``."""
    p = subparsers.add_parser(
        'track', help='follow the stable equilibrium along a straight parameter path',
        description='Start in the stable equilibrium whose basin holds the start guess '
                    '(--theta1/--theta2; default: the stable equilibrium with the largest '
                    'y3 + y4, i.e. the upper one), move all parameters together along the '
                    'straight path to the --to-* values and report every jump. With '
                    '--modules, --rhos, --config or --theta: a neck stack (start guess: '
                    '--theta, else the initial_theta of the --config file, else upright).')
    add_parameter_options(p)
    add_parameter_options(p, prefix='to-')
    p.add_argument('--theta1', type=finite_float, metavar='RAD',
                   help='start guess for theta1 (rad); needs --theta2')
    p.add_argument('--theta2', type=finite_float, metavar='RAD',
                   help='start guess for theta2 (rad); needs --theta1')
    add_stack_options(p, track=True)
    p.add_argument('--json', action='store_true', help='machine-readable output')
    p.set_defaults(func=run)


def run_track(start, end, guess):
    """(start Equilibrium, ModuleTrack) for one straight path."""
    first = start_equilibrium(start, guess)
    return first, track_module(start, end, first.theta)


def jump_record(jump):
    """JSON-ready dict of one jump."""
    return {'kind': jump.kind, 's': float(jump.s), 'rho': float(jump.params.rho),
            'theta1': float(jump.from_theta[0]), 'theta2': float(jump.from_theta[1]),
            'landing': {'theta1': float(jump.to_theta[0]), 'theta2': float(jump.to_theta[1])},
            'ambiguous': bool(jump.ambiguous),
            'F3': float(jump.params.f3y), 'F4': float(jump.params.f4y)}


def run(args, out):
    """``tensegrity track``: returns the exit status."""
    if stack_mode(args):
        return run_stack(args, out)
    start_values = parameter_values(args)
    end_values = dict(start_values)
    end_values.update(parameter_values(args, prefix='to_'))
    start = make_params(start_values)
    end = make_params(end_values)
    guess = start_guess(args)
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


def _stack_guess(args, spec, stack):
    if args.theta is not None:
        if args.theta1 is not None or args.theta2 is not None:
            raise UsageError('give --theta or --theta1/--theta2, not both')
        return np.reshape(args.theta, (len(spec), 2)).tolist(), 'given (--theta)'
    if args.theta1 is not None or args.theta2 is not None:
        if len(spec) != 1:
            raise UsageError('--theta1/--theta2 are for one module: give --theta with '
                             f'{2 * len(spec)} angles')
        return [list(start_guess(args))], 'given (--theta1/--theta2)'
    if spec.config is not None:
        return spec.config.initial_theta, f'initial_theta of {args.config}'
    if len(spec) == 1:
        return [list(start_equilibrium(stack.modules[0], None).theta)], 'upright'
    return upright_guess(stack.modules), 'upright'


def stack_jump_record(jump):
    """JSON-ready dict of one jump of a stack."""
    head = jump.stack.modules[-1]
    return {'kind': jump.kind, 's': float(jump.s),
            'rho': [float(m.rho) for m in jump.stack.modules],
            'theta': [[float(a), float(b)] for a, b in jump.from_theta],
            'landing': {'theta': [[float(a), float(b)] for a, b in jump.to_theta]},
            'ambiguous': bool(jump.ambiguous), 'F3': float(head.f3y), 'F4': float(head.f4y)}


def run_stack(args, out):
    """The stack form of ``track``."""
    from ..core.neck.stack import settle_stack, track_stack
    spec = stack_spec(args)
    if args.rho is not None and args.rhos is not None:
        raise UsageError('give --rho (every module) or --rhos (one per module), not both')
    if args.to_rho is not None and args.to_rhos is not None:
        raise UsageError('give --to-rho (every module) or --to-rhos (one per module), not both')
    start_fields = override(spec.base, parameter_values(args), args.rhos)
    end_fields = override(start_fields, parameter_values(args, prefix='to_'), args.to_rhos)
    start = make_stack(start_fields, spec.names)
    end = make_stack(end_fields, spec.names)
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
              f'{head_text(first)}; margin {first.stability_margin:.4g} N/m\n')
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
    out.write(f'final: theta [deg] {theta_text(final.theta, names)}; {head_text(final)}; '
              f'{"stable" if final.stable else "UNSTABLE"}, margin '
              f'{final.stability_margin:.4g} N/m; status {track.status}'
              + (f': {track.message}' if track.message else '') + '\n')
    return code
