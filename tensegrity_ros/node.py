"""Deprecated: the node moved to :mod:`tensegrity_ros.ros.node` (issue 42).

This alias re-exports :class:`TensegrityNode` and :func:`main` for one release; import
them from ``tensegrity_ros.ros.node`` (the console script ``tensegrity_node`` already
runs it, and so does ``python -m tensegrity_ros.ros.node``).
"""
import os
import signal
import sys
import warnings

if __name__ == '__main__':
    # As tensegrity_ros.ros.node does when started as a program: a quiet exit 0 on
    # Ctrl-C or SIGTERM while the imports below load.
    signal.signal(signal.SIGINT, lambda *_: os._exit(0))
    signal.signal(signal.SIGTERM, lambda *_: os._exit(0))

warnings.warn('tensegrity_ros.node is deprecated: use tensegrity_ros.ros.node (the node '
              'moved there; this alias goes in the next release)', DeprecationWarning,
              stacklevel=2)

from tensegrity_ros.ros.node import main, TensegrityNode  # noqa: E402

__all__ = ['TensegrityNode', 'main']

if __name__ == '__main__':
    sys.exit(main())
