"""An independent brute-force equilibrium solver (the test oracle).

It shares nothing with ``tensegrity_ros.core.module.equilibria``: the equilibrium
equations are derived here again from the node geometry (virtual work:
dU/dt_i = -(net force on the node) . d(node)/dt_i), solved with
``scipy.optimize.root`` from a regular grid of starts on the torus, polished
with a few Newton steps, de-duplicated on the torus and classified by the
eigenvalues of a Hessian obtained by central finite differences of that
gradient.  It is slow (hundreds of root solves per point) and only meant to
check the exact solver, which is what the tests and the benchmark use it for.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from scipy.optimize import root

TWO_PI = 2.0 * math.pi
#: Distinct oracle roots closer than this on the torus (rad, max norm) are one.
ORACLE_DUPLICATE_TOL = 1e-6
#: An oracle equilibrium with |lambda_min| below this times |lambda_max| is
#: ill-conditioned: its position and type are not reliably computable.
ILL_CONDITIONED = 1e-6


def wrap(angle):
    """Angle in [-pi, pi)."""
    return (angle + math.pi) % TWO_PI - math.pi


def torus_distance(a, b):
    """Max-norm distance between two angle pairs on the torus."""
    out = 0.0
    for x, y in zip(a, b):
        d = abs(x - y) % TWO_PI
        out = max(out, min(d, TWO_PI - d))
    return out


class Model:
    """Equilibrium equations of one module, from the node geometry alone."""

    def __init__(self, p):
        self.p = p
        self.f3 = (p.f3x, p.f3y - 0.5 * p.m1 * p.g)
        self.f4 = (p.f4x, p.f4y - 0.5 * p.m2 * p.g)

    def _nodes(self, t):
        p = self.p
        c1, s1, c2, s2 = math.cos(t[0]), math.sin(t[0]), math.cos(t[1]), math.sin(t[1])
        a3 = (p.L1 * c1, p.L1 * s1)
        a4 = (p.rho - p.L2 * c2, p.L2 * s2)
        d3 = (-p.L1 * s1, p.L1 * c1)          # dA3/dt1
        d4 = (p.L2 * s2, p.L2 * c2)           # dA4/dt2
        return a3, a4, d3, d4

    def net_forces(self, t):
        """Net force on A3 and on A4 (springs + external loads)."""
        p = self.p
        a3, a4, _, _ = self._nodes(t)
        a2 = (p.rho, 0.0)
        n3 = tuple(-p.ka * (a3[i] - a2[i]) - p.kc * (a3[i] - a4[i]) + self.f3[i]
                   for i in range(2))
        n4 = tuple(-p.kb * a4[i] - p.kc * (a4[i] - a3[i]) + self.f4[i] for i in range(2))
        return n3, n4

    def gradient(self, t):
        _, _, d3, d4 = self._nodes(t)
        n3, n4 = self.net_forces(t)
        return np.array([-(n3[0] * d3[0] + n3[1] * d3[1]),
                         -(n4[0] * d4[0] + n4[1] * d4[1])])

    def jacobian(self, t):
        """Analytic derivative of :meth:`gradient` (used by the root finder)."""
        p = self.p
        a3, a4, d3, d4 = self._nodes(t)
        n3, n4 = self.net_forces(t)
        dd3 = (-a3[0], -a3[1])                          # d2A3/dt1^2
        dd4 = (p.L2 * math.cos(t[1]), -p.L2 * math.sin(t[1]))   # d2A4/dt2^2
        dot = lambda u, v: u[0] * v[0] + u[1] * v[1]    # noqa: E731
        j11 = (p.ka + p.kc) * dot(d3, d3) - dot(n3, dd3)
        j22 = (p.kb + p.kc) * dot(d4, d4) - dot(n4, dd4)
        j12 = -p.kc * dot(d4, d3)
        return np.array([[j11, j12], [j12, j22]])

    def fd_hessian(self, t, h=1e-6):
        """Hessian by central differences of the gradient, symmetrised."""
        t = np.asarray(t, dtype=float)
        cols = []
        for i in range(2):
            e = np.zeros(2)
            e[i] = h
            cols.append((self.gradient(t + e) - self.gradient(t - e)) / (2 * h))
        m = np.array(cols).T
        return 0.5 * (m + m.T)

    def scale(self):
        p = self.p
        return max(abs(c) for c in ((p.ka + p.kc) * p.rho + p.f3x, self.f3[1],
                                    (p.kb + p.kc) * p.rho - p.f4x, self.f4[1],
                                    p.kc * p.L1, p.kc * p.L2)) * max(p.L1, p.L2)


@dataclass
class OracleResult:
    points: list            # [(t1, t2)] wrapped to [-pi, pi)
    eigenvalues: list       # [(low, high)] of the finite-difference Hessian
    residuals: list
    ill_conditioned: bool
    reason: str = ''

    @property
    def stable(self):
        return [bool(ev[0] > 0) for ev in self.eigenvalues]

    @property
    def num_stable(self):
        return sum(self.stable)


def oracle_equilibria(p, grid=24, tol=1e-14):
    """All equilibria found by multi-start root finding from a grid x grid torus grid."""
    model = Model(p)
    scale = model.scale()
    starts = np.linspace(-math.pi, math.pi, grid, endpoint=False) + math.pi / grid
    found = []
    for a in starts:
        for b in starts:
            sol = root(model.gradient, [a, b], jac=model.jacobian, method='hybr',
                       options={'xtol': 1e-13})
            t = np.array(sol.x, dtype=float)
            if not np.all(np.isfinite(t)):
                continue
            t = _newton(model, t)
            res = float(np.max(np.abs(model.gradient(t)))) / scale
            if res > tol:
                continue
            t = (wrap(t[0]), wrap(t[1]))
            if all(torus_distance(t, q) > ORACLE_DUPLICATE_TOL for q, _ in found):
                found.append((t, res))
    found.sort()
    points = [q for q, _ in found]
    residuals = [r for _, r in found]
    eigenvalues, reason = [], ''
    for q in points:
        ev = np.linalg.eigvalsh(model.fd_hessian(q))
        eigenvalues.append((float(ev[0]), float(ev[1])))
        if abs(ev).min() < ILL_CONDITIONED * abs(ev).max():
            reason = f'near-degenerate equilibrium at {q}: eigenvalues {ev}'
    for i, q in enumerate(points):       # two roots about to merge: a near fold
        for r in points[i + 1:]:
            if torus_distance(q, r) < 1e-4:
                reason = reason or f'nearly coincident equilibria {q} and {r}'
    return OracleResult(points, eigenvalues, residuals, bool(reason), reason)


def _newton(model, t, steps=6):
    for _ in range(steps):
        try:
            step = np.linalg.solve(model.jacobian(t), model.gradient(t))
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(step)) or np.max(np.abs(step)) > 0.1:
            break
        t = t - step
        if np.max(np.abs(step)) < 1e-15:
            break
    return t
