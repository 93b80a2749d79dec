"""Exit 0 when a test-numerics config computes exactly as this machine does unasked.

Usage: python tools/same_arithmetic.py CORETYPE [FEATURE,FEATURE,...|-]

A config (OPENBLAS_CORETYPE, numpy's NPY_DISABLE_CPU_FEATURES) repeats `make test`'s own
arithmetic when OpenBLAS already picks that core here and every feature it disables is one
this CPU does not have: on an AVX2 machine without AVX-512, `Haswell:-` and
`Haswell:X86_V4,AVX512_ICL,AVX512_SPR` run the very same kernels and loops as the suite
did, so `make test-numerics` skips them (about 15 minutes each on a 2-core runner).  When
anything cannot be read, the answer is "different" (exit 1): the config runs.
"""
import ctypes
import sys


def native_cores():
    """The core names of every OpenBLAS loaded by numpy and scipy (empty if unknown)."""
    import numpy.linalg  # noqa: F401  (loads numpy's OpenBLAS)
    import scipy.linalg  # noqa: F401  (loads scipy's)
    with open('/proc/self/maps') as maps:
        paths = {line.split()[-1] for line in maps if 'openblas' in line.lower()}
    cores = set()
    for path in paths:
        library = ctypes.CDLL(path)
        names = [n for n in ('openblas_get_corename', 'openblas_get_corename64_',
                             'scipy_openblas_get_corename64_', 'scipy_openblas_get_corename')
                 if hasattr(library, n)]
        if not names:
            return set()
        corename = getattr(library, names[0])
        corename.restype = ctypes.c_char_p
        cores.add(corename().decode().lower())
    return cores


def present_features():
    """numpy's CPU features that this machine has."""
    from numpy._core._multiarray_umath import __cpu_features__
    return {name for name, present in __cpu_features__.items() if present}


def same_arithmetic(core, disabled):
    try:
        cores = native_cores()
        features = present_features()
    except (OSError, ImportError, AttributeError):
        return False
    return cores == {core.lower()} and not (set(disabled) & features)


if __name__ == '__main__':
    core, off = sys.argv[1], (sys.argv[2] if len(sys.argv) > 2 else '-')
    disabled = [] if off in ('', '-') else off.split(',')
    sys.exit(0 if same_arithmetic(core, disabled) else 1)
