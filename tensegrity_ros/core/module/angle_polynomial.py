"""The elimination's polynomial: the first angles t1 of one module's equilibria.

The equilibrium equations, scaled by L1, L2, take the reduced constants
``(a1, b1, a2, b2, kcL1, kcL2)``; eliminating t2 leaves a trigonometric polynomial
of degree 3 in t1, a degree-6 polynomial in ``z = exp(i t1)`` whose roots on the unit
circle are the t1 of the equilibria (derivation: :mod:`.module.polynomial_solver`).  Here
are its coefficients (batched and for one point), its roots, and the closed form that
replaces it when no vertical load acts (double roots root finding cannot separate).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.linalg.lapack import zgeev as _zgeev


def _reduced_coefficients(rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y):
    """(a1, b1, a2, b2, kcL1, kcL2): the constants of the scaled equations."""
    return ((ka + kc) * rho + f3x, f3y, (kb + kc) * rho - f4x, f4y, kc * L1, kc * L2)


def _polynomial(a1, b1, a2, b2, kcL1, kcL2):
    """Coefficients of z^3 P(z), highest power first, shape (..., 7), complex."""
    u = 0.5 * (-b1 + 1j * a1)            # r = u/z + conj(u) z
    v = 0.5 * (b2 + 1j * a2)             # D = v/z + conj(v) z
    w = -kcL1 * (a2 - 1j * b2)           # Q = w/z + q0 + conj(w) z
    q0 = a2 * a2 + b2 * b2 + kcL1 * kcL1
    K = kcL2 * kcL2
    uu = np.abs(u) ** 2
    pm3 = u * u * w
    pm2 = u * u * q0 - K * v * v
    pm1 = u * u * np.conj(w) + 2.0 * uu * w
    p0 = 2.0 * uu * q0 - 2.0 * K * np.abs(v) ** 2 + 0j
    return np.stack([np.conj(pm3), np.conj(pm2), np.conj(pm1), p0, pm1, pm2, pm3], -1)


def _scale(a1, b1, a2, b2, kcL1, kcL2):
    return np.maximum.reduce([np.abs(a1), np.abs(b1), np.abs(a2), np.abs(b2),
                              np.abs(kcL1), np.abs(kcL2)])


def _polynomial_roots(coefficients):
    """Roots of one polynomial, near-zero leading/trailing coefficients stripped.

    The eigenvalues of the companion matrix, from LAPACK's zgeev called directly:
    numpy's eigvals runs the same routine behind a wrapper that adds about 40 %
    at this size (17 vs 12 us for 6x6), and this runs on every solve.
    """
    peak = max(abs(c) for c in coefficients)
    keep = [i for i, c in enumerate(coefficients) if abs(c) > 1e-14 * peak]
    coefficients = coefficients[keep[0]:keep[-1] + 1]
    degree = len(coefficients) - 1
    if degree < 1:
        return []
    companion = np.zeros((degree, degree), dtype=complex, order='F')
    lead = coefficients[0]
    companion[0, :] = [-c / lead for c in coefficients[1:]]
    companion.flat[degree::degree + 1] = 1.0                     # the subdiagonal
    roots, _, _, info = _zgeev(companion, compute_vl=0, compute_vr=0, overwrite_a=1)
    if info != 0:                                   # QR did not converge: numpy raises
        return np.linalg.eigvals(companion).tolist()
    return roots.tolist()


def _polynomial_scalar(a1, b1, a2, b2, kcL1, kcL2):
    """:func:`_polynomial` for one point, as a list (no numpy overhead)."""
    u = complex(-0.5 * b1, 0.5 * a1)
    v = complex(0.5 * b2, 0.5 * a2)
    w = complex(-kcL1 * a2, kcL1 * b2)
    q0 = a2 * a2 + b2 * b2 + kcL1 * kcL1
    K = kcL2 * kcL2
    uu = u.real ** 2 + u.imag ** 2
    u2 = u * u
    pm3 = u2 * w
    pm2 = u2 * q0 - K * v * v
    pm1 = u2 * w.conjugate() + 2.0 * uu * w
    p0 = complex(2.0 * uu * q0 - 2.0 * K * (v.real ** 2 + v.imag ** 2))
    return [pm3.conjugate(), pm2.conjugate(), pm1.conjugate(), p0, pm1, pm2, pm3]


def _horizontal_cosine(a1, a2, kcL1, kcL2):
    """cos t1 of the non-flat equilibria when no vertical load acts (b1 = b2 = 0).

    Then P(t1) = sin(t1)^2 R(t1) with R linear in cos t1, so the equilibria are
    the four flat configurations and the pair t1 = +-acos(C); returns C (nan if
    a1 a2 = 0: no non-flat equilibrium).
    """
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.divide(a1 * a1 * (a2 * a2 + kcL1 * kcL1) - kcL2 * kcL2 * a2 * a2,
                         2.0 * a1 * a1 * a2 * kcL1)


def _horizontal_load_first_angles(a1, a2, kcL1, kcL2):
    """Every t1 of an equilibrium when b1 = b2 = 0, in closed form.

    The polynomial has double roots at t1 = 0 and pi there (the flat
    configurations share them), which merge with the non-flat pair on the
    boundary lines: root finding cannot separate them, the closed form can.
    """
    angles = [0.0, math.pi]
    cosine = float(_horizontal_cosine(a1, a2, kcL1, kcL2))
    if abs(cosine) < 1.0:
        t1 = math.acos(cosine)
        angles += [t1, -t1]
    return angles
