"""The ``tensegrity`` parser, assembled from the command modules (each registers its
subcommand and runs it), and :func:`main`, which runs a command line and turns every
failure into one line on stderr and an exit status.
"""
from __future__ import annotations

import argparse
import os
import sys

from . import (diagram, limit, map as map_command, range as range_command, snap, solve, tolerance,
               track)
from .common import EXIT_FAILURE, EXIT_OK, EXIT_USAGE, UsageError
from ..core import InvalidParameterError

#: The commands in the order ``tensegrity --help`` lists them.
COMMANDS = (solve, track, map_command, diagram, range_command, limit, snap, tolerance)


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (exit status 2, no usage block)."""

    def error(self, message):
        self.exit(EXIT_USAGE, f'{self.prog}: error: {message} (see {self.prog} --help)\n')


def build_parser():
    """The ``tensegrity`` parser: one subparser per command of :data:`COMMANDS`."""
    parser = _Parser(
        prog='tensegrity',
        description='Offline analysis of the planar tensegrity mechanism of Wenger & Chablat: '
                    'equilibria, tracking with jumps, stability maps, bifurcation diagrams. '
                    'SI units; angles in radians (tables show degrees).',
        epilog='Run "tensegrity COMMAND --help" for the options of a command.')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND', required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    return parser


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
