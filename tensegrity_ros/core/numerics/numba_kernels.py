"""numba for the compiled kernels (:mod:`.dynamics.neck_kernel`, :mod:`.neck.flow_kernel`):
whether it is used, and a module's kernels compiled with it.  numba is imported only on the first
compilation, so a process that asks for no kernel (a quasi-static node) never loads it."""
from __future__ import annotations

from importlib import metadata
import os
from types import SimpleNamespace


def engine():
    """'numba <version>' where the kernels compile, else 'numpy' (numba not installed, or
    TENSEGRITY_NO_NUMBA set): the two round differently."""
    if os.environ.get('TENSEGRITY_NO_NUMBA', '') not in ('', '0'):
        return 'numpy'
    try:
        return 'numba ' + metadata.version('numba')
    except metadata.PackageNotFoundError:
        return 'numpy'


def compile_kernels(namespace, names):
    """The functions ``names`` of a module's ``namespace`` (its globals) compiled by numba,
    its on-disk cache reused, as a SimpleNamespace; None where :func:`engine` is numpy.
    Each is rebound in ``namespace``, callees first, so that callers compile against the
    compiled callees."""
    if engine() == 'numpy':
        return None
    try:
        from numba import njit
    except ImportError:
        return None
    for name in names:
        namespace[name] = njit(cache=True)(namespace[name])
    return SimpleNamespace(**{name: namespace[name] for name in names})
