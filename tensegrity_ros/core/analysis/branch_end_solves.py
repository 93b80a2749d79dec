"""Where a stable branch ends, exactly: Newton on regular extended systems.

The end of a branch of one module's equilibria in rho is a fold, ``{G = 0, det H = 0}``
in (t1, t2, rho), or a symmetric branch point, regular only on its symmetry's
restricted system: a swap symmetry's ``{g1(t, +-t) = 0, psi^T H psi = 0}`` in (t, rho),
the mirror symmetry's flat configurations' ``det H(flat; rho) = 0`` (a quadratic in
rho).  Each is solved here to ~1e-12 for :func:`.analysis.operation_range.operation_range`, on the
raw parameters ``P = (rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y)``.
"""
from __future__ import annotations

import math

import numpy as np


def _local_terms(P, t1, t2):
    """(s1, c1, s2, c2, g1, g2, h11, h12, h22, k12) at (t1, t2) for raw parameters P:
    the gradient, the Hessian and k12 = kc L1 L2 sin(t1 + t2) (their third-derivative
    building block), shared by the branch and extended-system solvers."""
    rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = P
    a1 = (ka + kc) * rho + f3x
    a2 = (kb + kc) * rho - f4x
    s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
    s12 = s1 * c2 + c1 * s2
    c12 = c1 * c2 - s1 * s2
    g1 = L1 * (a1 * s1 - kc * L2 * s12 - f3y * c1)
    g2 = L2 * (a2 * s2 - kc * L1 * s12 - f4y * c2)
    h11 = L1 * (a1 * c1 - kc * L2 * c12 + f3y * s1)
    h22 = L2 * (a2 * c2 - kc * L1 * c12 + f4y * s2)
    h12 = -kc * L1 * L2 * c12
    return s1, c1, s2, c2, g1, g2, h11, h12, h22, kc * L1 * L2 * s12


def _fold_newton(P, t1, t2, rho, max_iter=16):
    """Newton on {G = 0, det H = 0} in (t1, t2, rho), analytic Jacobian."""
    P = P.copy()
    for _ in range(max_iter):
        P[0] = rho
        _, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = P
        a1 = (ka + kc) * rho + f3x
        a2 = (kb + kc) * rho - f4x
        s1, c1, s2, c2, g1, g2, h11, h12, h22, k12 = _local_terms(P, t1, t2)
        h11_1, h11_2, h11_r = -g1, k12, L1 * (ka + kc) * c1
        h22_1, h22_2, h22_r = k12, -g2, L2 * (kb + kc) * c2
        ddet = [h11_1 * h22 + h11 * h22_1 - 2 * h12 * k12,
                h11_2 * h22 + h11 * h22_2 - 2 * h12 * k12,
                h11_r * h22 + h11 * h22_r]
        s = max(abs(h11), abs(h22), abs(h12), 1e-300)
        s_g = max(L1, L2) * max(abs(a1), abs(a2), abs(f3y), abs(f4y), kc * L1, kc * L2)
        J = np.array([[h11, h12, L1 * (ka + kc) * s1],
                      [h12, h22, L2 * (kb + kc) * s2],
                      [ddet[0] / s, ddet[1] / s, ddet[2] / s]])
        F = np.array([g1, g2, (h11 * h22 - h12 * h12) / s])
        try:
            d = np.linalg.solve(J, -F)
        except np.linalg.LinAlgError:
            return t1, t2, rho, False
        t1, t2, rho = t1 + d[0], t2 + d[1], rho + d[2]
        if not np.all(np.isfinite(d)) or abs(d[0]) + abs(d[1]) > 2.0:
            return t1, t2, rho, False
        size = abs(d[0]) + abs(d[1]) + abs(d[2]) / max(rho, 1e-300)
        if size < 1e-14:
            return t1, t2, rho, True
        # ill-conditioned (a nearly symmetric branch point nearby): accept a point
        # whose residual is at rounding level once the steps are small
        if size < 1e-8 and max(abs(F[0]), abs(F[1])) <= 1e-13 * s_g and abs(F[2]) <= 1e-11 * s:
            return t1, t2, rho, True
    return t1, t2, rho, False


def _swap_newton(P, t, rho, mirror, max_iter=16):
    """Newton on the restricted branch-point system of a swap symmetry, (t, rho).

    ``mirror`` False: theta = (t, t), breaking mode (1, -1);
    True: theta = (t, -t), breaking mode (1, 1)."""
    P = P.copy()
    sg = -1.0 if mirror else 1.0
    for _ in range(max_iter):
        P[0] = rho
        _, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = P
        t1, t2 = t, sg * t
        s1, c1, s2, c2, g1, g2, h11, h12, h22, k12 = _local_terms(P, t1, t2)
        # f1 = g1(t, sg t); f2 = (h11 + h22)/2 - sg h12
        f1, f2 = g1, 0.5 * (h11 + h22) - sg * h12
        j11 = h11 + sg * h12
        j12 = L1 * (ka + kc) * s1
        dh11 = -g1 + sg * k12
        dh22 = k12 + sg * (-g2)
        dh12 = k12 * (1 + sg)
        j21 = 0.5 * (dh11 + dh22) - sg * dh12
        j22 = 0.5 * (L1 * (ka + kc) * c1 + L2 * (kb + kc) * c2)
        det = j11 * j22 - j12 * j21
        if det == 0.0:
            return t, rho, False
        dt = -(j22 * f1 - j12 * f2) / det
        dr = -(j11 * f2 - j21 * f1) / det
        t, rho = t + dt, rho + dr
        if not (math.isfinite(dt) and math.isfinite(dr)) or abs(dt) > 2.0:
            return t, rho, False
        if abs(dt) + abs(dr) / max(abs(rho), 1e-300) < 1e-14:
            return t, rho, True
    return t, rho, abs(dt) + abs(dr) < 1e-11


def _flat_degenerate_rhos(P, flat):
    """All rho with det H(flat; rho) = 0 (a quadratic in rho)."""
    _, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = P
    c1, c2 = math.cos(flat[0]), math.cos(flat[1])
    c12 = c1 * c2
    al1, be1 = L1 * (ka + kc) * c1, L1 * (f3x * c1 - kc * L2 * c12)
    al2, be2 = L2 * (kb + kc) * c2, L2 * (-f4x * c2 - kc * L1 * c12)
    h12 = -kc * L1 * L2 * c12
    a, b, c = al1 * al2, al1 * be2 + al2 * be1, be1 * be2 - h12 * h12
    if a == 0.0:
        return [] if b == 0.0 else [-c / b]
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        return []
    q = -0.5 * (b + math.copysign(math.sqrt(disc), b))     # stable quadratic formula
    roots = [q / a]
    if q != 0.0:
        roots.append(c / q)
    return roots
