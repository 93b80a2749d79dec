"""The ``tensegrity`` console script's entry point.

Importing the tool (:mod:`tensegrity_ros.cli`: numpy, scipy, the core) takes about a
second; a Ctrl-C in that second ends it as a Ctrl-C later does (``cli.main``): one line
and status 130, not a traceback.
"""
import sys


def main(argv=None):
    """Import the tool, then run it; returns the exit status."""
    try:
        from .cli import main as run
    except KeyboardInterrupt:
        sys.stderr.write('tensegrity: interrupted\n')
        return 130
    return run(argv)
