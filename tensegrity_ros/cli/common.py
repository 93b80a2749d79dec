"""What every command of the ``tensegrity`` command line shares: the exit statuses,
the one-line usage error, the argparse types, the mechanism's parameter options and
their checked values, the output paths' checks and one module's start equilibrium.
"""
from __future__ import annotations

import argparse
import math
import os

from ..core import ModuleParams
from ..core.simulation.start_state import start_state
from ..problem import describe_modules, PARAMETERS, resolve_fields

#: Names whose value must be > 0, resp. >= 0.
_POSITIVE = {'rho', 'L1', 'L2', 'k', 'ka', 'kb', 'kc'}
_NON_NEGATIVE = {'m1', 'm2'}

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


def add_parameter_options(parser, skip=(), prefix='', required=()):
    """The mechanism's parameter options (``prefix`` 'to-': a path's end values)."""
    group = parser.add_argument_group(
        'mechanism parameters' if not prefix else 'end point of the path (default: start value)')
    for name, (_, text) in PARAMETERS.items():
        if name in skip:
            continue
        group.add_argument(f'--{prefix}{name}', dest=f'{prefix.replace("-", "_")}{name}',
                           type=finite_float, metavar='X', required=name in required,
                           help=text if not prefix else f'{name} at the end of the path')


def parameter_values(args, prefix=''):
    """CLI-named parameter values given on the command line (None = not given)."""
    out = {}
    for name in PARAMETERS:
        value = getattr(args, f'{prefix}{name}', None)
        if value is not None:
            check_domain(name, value)
            out[name] = value
    return out


def check_output(path, option):
    """UsageError unless the directory of output ``path`` exists ('-': stdout)."""
    if path is None or path == '-':
        return
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        raise UsageError(f'{option}: directory {directory!r} does not exist')


def check_input(path, option):
    """UsageError unless input ``path`` is a file."""
    if not os.path.isfile(path):
        raise UsageError(f'{option}: no such file {path!r}')


def start_guess(args):
    """(theta1, theta2) of --theta1/--theta2, or None; both or neither."""
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
