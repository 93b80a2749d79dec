"""The neck's elastic gradient flow per evaluation, compiled (numba): the inner loop of a
landing, a release and a start settle, called ~1,000 times a neck path's first jump.

Why compiled: the flow integrator (LSODA) calls the velocity once per stage, one small
state at a time, so numpy's per-call overhead is the whole cost: ~20 numpy and LAPACK
calls of ~1 us each make :meth:`.neck.flows.StackFlows.descent` ~25 us on a neck of 3;
compiled, ~2 us.  The equations are :meth:`~.neck.flows.StackFlows.descent`'s and
:meth:`~.neck.flows.StackFlows.damped`'s, written loop by loop (its own Cholesky
factorisation: the same numbers to rounding, test/test_stack_flow_kernel.py).

Used only where a caller asks (``TrackerSettings(compiled_flows=True)``: the tolerance
study's neck questions); numba is imported only by :func:`compiled`, so a quasi-static
node never loads it.  Without numba, or with ``TENSEGRITY_NO_NUMBA=1``, :func:`compiled`
returns None and the numpy flows run.
"""
from __future__ import annotations

import numpy as np

from ..numerics.numba_kernels import compile_kernels


def _cholesky(a, m):
    """The lower Cholesky factor of a[:m, :m] in place; False where it is not positive
    definite."""
    for j in range(m):
        d = a[j, j]
        for k in range(j):
            d -= a[j, k] * a[j, k]
        if not d > 0.0:
            return False
        d = np.sqrt(d)
        a[j, j] = d
        for i in range(j + 1, m):
            v = a[i, j]
            for k in range(j):
                v -= a[i, k] * a[j, k]
            a[i, j] = v / d
    return True


def _cho_solve(factor, b, m):
    """factor factor^T x = b (b (m,), overwritten with x)."""
    for i in range(m):
        v = b[i]
        for k in range(i):
            v -= factor[i, k] * b[k]
        b[i] = v / factor[i, i]
    for i in range(m - 1, -1, -1):
        v = b[i]
        for k in range(i + 1, m):
            v -= factor[k, i] * b[k]
        b[i] = v / factor[i, i]


def _rods(y, n, rod):
    """The rod vectors (complex, n)."""
    rods = np.empty(n, dtype=np.complex128)
    for r in range(n):
        rods[r] = rod[r] * np.exp(1j * y[r])
    return rods


def _elements(y, rods, element_rods_c, shift, weights0, weight_map):
    """Element differences (complex) and weights (stiffnesses, chord multipliers)."""
    elements, n = element_rods_c.shape
    diff = np.empty(elements, dtype=np.complex128)
    weights = np.empty(elements)
    for e in range(elements):
        v = 0j
        for r in range(n):
            v += element_rods_c[e, r] * rods[r]
        diff[e] = v + shift[e]
        w = weights0[e]
        for j in range(weight_map.shape[1]):
            w += weight_map[e, j] * y[j]
        weights[e] = w
    return diff, weights


def _metric_factor(rods, mobility, n):
    metric = np.empty((n, n))
    for r in range(n):
        for q in range(n):
            metric[r, q] = mobility[r, q] * (rods[r] * np.conj(rods[q])).real
    ok = _cholesky(metric, n)
    return metric, ok


def _chord_gram(rods, diff, ns, chord_rods_scaled, factor, n):
    """(jc, metric^-1 jc^T (n x nc), their Gram matrix)."""
    nc = chord_rods_scaled.shape[0]
    jc = np.empty((nc, n))
    mobility_jc = np.empty((n, nc))
    column = np.empty(n)
    for c in range(nc):
        chord = np.conj(diff[ns + c])
        for r in range(n):
            jc[c, r] = (chord * rods[r]).imag * chord_rods_scaled[c, r]
            column[r] = jc[c, r]
        _cho_solve(factor, column, n)
        for r in range(n):
            mobility_jc[r, c] = column[r]
    gram = np.empty((nc, nc))
    for a in range(nc):
        for b in range(nc):
            v = 0.0
            for r in range(n):
                v += jc[a, r] * mobility_jc[r, b]
            gram[a, b] = v
    return jc, mobility_jc, gram


def _smallest_below_onset(gram, onset):
    """The Gram matrix's smallest eigenvalue where below ``onset``, else +inf."""
    nc = gram.shape[0]
    shifted = gram.copy()
    for i in range(nc):
        shifted[i, i] -= onset
    if _cholesky(shifted, nc):
        return np.inf
    smallest = gram[0, 0] if nc == 1 else np.linalg.eigvalsh(gram)[0]
    return smallest if smallest < onset else np.inf


def descent(y, size, n, ns, rod, shift, weights0, weight_map, element_rods_c,
            element_rods_t, rod_loads, mobility, chord_rods_scaled, chord_squares,
            half_inv_l_ref, rate, damping, onset):
    """The elastic flow's velocity (size,); an empty array where the metric or the damped
    Gram matrix is not positive definite (the caller raises, as the numpy flow does)."""
    rods = _rods(y, n, rod)
    diff, weights = _elements(y, rods, element_rods_c, shift, weights0, weight_map)
    free = np.empty(n)
    for r in range(n):
        v = 0j
        for e in range(ns):
            v += element_rods_t[r, e] * weights[e] * diff[e]
        free[r] = (np.conj(rods[r]) * (v - rod_loads[r])).imag
    factor, ok = _metric_factor(rods, mobility, n)
    if not ok:
        return np.empty(0)
    _cho_solve(factor, free, n)
    out = np.zeros(size)
    nc = chord_rods_scaled.shape[0]
    if nc == 0:
        for r in range(n):
            out[r] = -free[r]
        return out
    jc, mobility_jc, gram = _chord_gram(rods, diff, ns, chord_rods_scaled, factor, n)
    smallest = _smallest_below_onset(gram, onset)
    if smallest < np.inf:
        extra = damping * (1.0 - smallest / onset) ** 2
        for i in range(nc):
            gram[i, i] += extra
    rhs = np.empty(nc)
    for c in range(nc):
        chord = diff[ns + c]
        squares = (np.conj(chord) * chord).real
        v = 0.0
        for r in range(n):
            v += jc[c, r] * free[r]
        rhs[c] = v - rate * ((squares - chord_squares[c]) * half_inv_l_ref)
    if not _cholesky(gram, nc):
        return np.empty(0)
    _cho_solve(gram, rhs, nc)
    for r in range(n):
        v = -free[r]
        for c in range(nc):
            v += mobility_jc[r, c] * rhs[c]
        out[r] = v
    return out


def damped(y, n, ns, rod, shift, weights0, weight_map, element_rods_c, mobility,
           chord_rods_scaled, onset):
    """Whether :func:`descent` damps its projection at y (1), or not (0); -1 where the
    metric is not positive definite."""
    if chord_rods_scaled.shape[0] == 0:
        return 0
    rods = _rods(y, n, rod)
    diff, _ = _elements(y, rods, element_rods_c, shift, weights0, weight_map)
    factor, ok = _metric_factor(rods, mobility, n)
    if not ok:
        return -1
    gram = _chord_gram(rods, diff, ns, chord_rods_scaled, factor, n)[2]
    return 1 if _smallest_below_onset(gram, onset) < np.inf else 0


KERNELS = ('_cholesky', '_cho_solve', '_rods', '_elements', '_metric_factor',
           '_chord_gram', '_smallest_below_onset', 'descent', 'damped')
_COMPILED = []


def compiled():
    """The kernels compiled by numba (its on-disk cache reused) as a namespace, made on the
    first call, or None where numba is not installed or TENSEGRITY_NO_NUMBA is set."""
    if not _COMPILED:
        _COMPILED.append(_compile())
    return _COMPILED[0]


def _compile():
    return compile_kernels(globals(), KERNELS)
