"""The bifurcation analysis's common ground: the module in raw form, its symmetries, planes
of two parameters, and the extended systems solved for degenerate equilibria.

Notation.  ``G = dU/dtheta`` and ``H = d2U/dtheta2`` of :mod:`.module` (unscaled, SI)
on a raw parameter vector (``RAW_NAMES``; the vertical forces include the rod weights,
``f3y - m1 g / 2``, exactly as the solver does).  The raw form works on real or complex
arrays, so that Jacobians can be taken by complex step.  Symmetries and axes: see
:mod:`.analysis`.
"""
from __future__ import annotations

import math

import numpy as np

from ..module.classification import hessian_eigenvalues
from ..module.model import ModuleParams

FOLD = 'fold'
BRANCH_POINT = 'branch_point'
LIMIT = 'limit'

#: Raw parameter vector used internally; f3y/f4y are totals (weights included).
RAW_NAMES = ('rho', 'L1', 'L2', 'ka', 'kb', 'kc', 'f3x', 'f3y', 'f4x', 'f4y')
_INDEX = {n: i for i, n in enumerate(RAW_NAMES)}
_POSITIVE = (0, 1, 2, 3, 4, 5)

#: Named plane axes and the raw components they set (coefficients).
AXES = {
    'rho': {'rho': 1.0}, 'L1': {'L1': 1.0}, 'L2': {'L2': 1.0},
    'ka': {'ka': 1.0}, 'kb': {'kb': 1.0}, 'kc': {'kc': 1.0},
    'k': {'ka': 1.0, 'kb': 1.0, 'kc': 1.0},
    'f3x': {'f3x': 1.0}, 'f4x': {'f4x': 1.0},
    'F3': {'f3y': 1.0}, 'f3y': {'f3y': 1.0},
    'F4': {'f4y': 1.0}, 'f4y': {'f4y': 1.0},
    'F': {'f3y': 1.0, 'f4y': 1.0},
}

SWAP, SWAP_MIRROR, MIRROR = 'swap', 'swap_mirror', 'mirror'
_FLATS = ((0.0, 0.0), (0.0, math.pi), (math.pi, 0.0), (math.pi, math.pi))
_CSTEP = 1e-30
#: operation_range: a branch still stable within BOUND_TOL * (L1 + L2) of a search
#: bound ends there with kind 'limit'.
BOUND_TOL = 1e-8
#: A degenerate point bounds a stable equilibrium if lambda_max > this * scale.
STABLE_BOUNDARY_TOL = 1e-7


# ---------------------------------------------------------------------------
# The model in raw form (works on real or complex arrays: complex-step Jacobians)

def _raw(p: ModuleParams):
    return np.array([p.rho, p.L1, p.L2, p.ka, p.kb, p.kc,
                     p.f3x, p.f3y_total, p.f4x, p.f4y_total])


def _gh(P, t1, t2):
    """(g1, g2, h11, h12, h22) of module.gradient / module.hessian, raw parameters."""
    P = np.asarray(P)
    rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = (P[..., i] for i in range(10))
    s1, c1, s2, c2 = np.sin(t1), np.cos(t1), np.sin(t2), np.cos(t2)
    s12, c12 = np.sin(t1 + t2), np.cos(t1 + t2)
    a1 = (ka + kc) * rho + f3x
    a2 = (kb + kc) * rho - f4x
    g1 = L1 * (a1 * s1 - kc * L2 * s12 - f3y * c1)
    g2 = L2 * (a2 * s2 - kc * L1 * s12 - f4y * c2)
    h11 = L1 * (a1 * c1 - kc * L2 * c12 + f3y * s1)
    h22 = L2 * (a2 * c2 - kc * L1 * c12 + f4y * s2)
    h12 = -kc * L1 * L2 * c12
    return g1, g2, h11, h12, h22


def _scale(P):
    """Force-times-length scale of G and H (J/rad) for normalising residuals."""
    rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = P
    return max(L1, L2) * max(abs((ka + kc) * rho + f3x), abs((kb + kc) * rho - f4x),
                             kc * max(L1, L2), abs(f3y), abs(f4y))


def _symmetries(P, directions=()):
    """Symmetries that hold at P and stay exact along every direction (affine family)."""
    def holds(v, zero_terms):
        return all(v[i] - s * v[j] == 0.0 for i, j, s in zero_terms)
    swap = ((1, 2, 1.0), (3, 4, 1.0), (7, 9, 1.0), (6, 8, -1.0))
    swap_mirror = ((1, 2, 1.0), (3, 4, 1.0), (7, 9, -1.0), (6, 8, -1.0))
    out = []
    for name, terms in ((SWAP, swap), (SWAP_MIRROR, swap_mirror)):
        if holds(P, terms) and all(holds(d, terms) for d in directions):
            out.append(name)
    if P[7] == 0.0 and P[9] == 0.0 and all(d[7] == 0.0 and d[9] == 0.0 for d in directions):
        out.append(MIRROR)
    return tuple(out)


def _axis(spec):
    if isinstance(spec, str):
        if spec not in AXES:
            raise ValueError(f'unknown parameter axis {spec!r}; use one of {sorted(AXES)} '
                             f'or a dict over {RAW_NAMES}')
        spec = AXES[spec]
    d = np.zeros(10)
    for name, c in dict(spec).items():
        if name not in _INDEX:
            raise ValueError(f'unknown raw parameter {name!r} in axis {spec!r}')
        d[_INDEX[name]] = float(c)
    if not np.any(d):
        raise ValueError(f'axis {spec!r} is empty')
    return d


def _axis_label(spec):
    if isinstance(spec, str):
        return spec
    return '+'.join(f'{c:g}*{n}' for n, c in dict(spec).items())


class _Family:
    """Affine parameter family P(q) = P0 + sum_i q_i d_i (q in physical units)."""

    def __init__(self, base: ModuleParams, axes):
        self.base = base
        self.dirs = [_axis(a) for a in axes]
        touched = np.zeros(10, dtype=bool)
        for d in self.dirs:
            if np.any(touched & (d != 0)):
                raise ValueError('plane axes must not set the same parameter twice')
            touched |= d != 0
        P0 = _raw(base)
        offsets = np.zeros(10)
        offsets[7] = base.f3y_total - base.f3y     # weights stay applied
        offsets[9] = base.f4y_total - base.f4y
        self.P0 = np.where(touched, offsets, P0)
        self.D = np.array(self.dirs)               # (nq, 10)
        self.symmetries = _symmetries(self.P0, self.dirs)

    def raw(self, q):
        """Raw parameter vector(s) at plane point(s) q (..., nq); complex allowed."""
        return self.P0 + np.asarray(q) @ self.D

    def params(self, q):
        """ModuleParams at q (validated)."""
        P = self.raw(np.asarray(q, dtype=float))
        b = self.base
        return ModuleParams(rho=P[0], L1=P[1], L2=P[2], ka=P[3], kb=P[4], kc=P[5],
                            f3x=P[6], f3y=P[7] + 0.5 * b.m1 * b.g, f4x=P[8],
                            f4y=P[9] + 0.5 * b.m2 * b.g, m1=b.m1, m2=b.m2, g=b.g)

    def valid(self, q):
        P = self.raw(np.asarray(q, dtype=float))
        return bool(np.all(P[list(_POSITIVE)] > 0))


# ---------------------------------------------------------------------------
# Extended systems.  Each maps z (..., n) to residuals (..., n - 1); the last
# nq entries of z are the *scaled* plane coordinates u (q = lo + u * (hi - lo)).

class _System:
    """One extended system on a family with a box scaling of its parameters."""

    def __init__(self, family, lo, hi, kind, theta_fixed=None):
        self.family, self.kind = family, kind
        self.lo, self.span = np.asarray(lo, float), np.asarray(hi, float) - np.asarray(lo, float)
        self.theta_fixed = theta_fixed
        self.nq = len(family.dirs)
        self.nt = {None: 2, SWAP: 1, SWAP_MIRROR: 1, MIRROR: 0}[kind]
        self.n = self.nt + self.nq
        mid = family.raw(self.lo + 0.5 * self.span)
        self.s = _scale(mid)

    def q(self, u):
        return self.lo + u * self.span

    def theta(self, z):
        z = np.asarray(z)
        if self.kind is None:
            return z[..., 0], z[..., 1]
        if self.kind == SWAP:
            return z[..., 0], z[..., 0]
        if self.kind == SWAP_MIRROR:
            return z[..., 0], -z[..., 0]
        t1, t2 = self.theta_fixed
        shape = z.shape[:-1]
        return np.full(shape, t1), np.full(shape, t2)

    def parts(self, z):
        P = self.family.raw(self.q(z[..., self.nt:]))
        t1, t2 = self.theta(z)
        return _gh(P, t1, t2)

    def residual(self, z):
        g1, g2, h11, h12, h22 = self.parts(z)
        s = self.s
        if self.kind is None:
            return np.stack([g1 / s, g2 / s, (h11 * h22 - h12 * h12) / (s * s)], -1)
        if self.kind == SWAP:
            return np.stack([g1 / s, (0.5 * (h11 + h22) - h12) / s], -1)
        if self.kind == SWAP_MIRROR:
            return np.stack([g1 / s, (0.5 * (h11 + h22) + h12) / s], -1)
        return ((h11 * h22 - h12 * h12) / (s * s))[..., None]

    def fj(self, z):
        """Residual and Jacobian (complex step: exact to rounding)."""
        z = np.asarray(z, dtype=float)
        Z = z[None, :] + (1j * _CSTEP) * np.eye(z.size)
        R = self.residual(Z)
        return R[0].real, (R.imag / _CSTEP).T

    def point(self, z):
        """(plane point, theta, eigenvalues) of a solution z."""
        q = self.q(z[self.nt:])
        P = self.family.raw(q)
        t1, t2 = (float(v) for v in self.theta(z))
        _, _, h11, h12, h22 = _gh(P, t1, t2)
        lo, hi = hessian_eigenvalues(h11, h12, h22)
        return q, (t1, t2), (float(lo), float(hi))


def _newton(fun_jac, z, extra=None, tol=1e-13, max_iter=12):
    """Newton on a square system: fun_jac's residual (m,) plus optional linear rows.

    ``extra = (A, b)`` appends ``A z - b = 0``.  Returns (z, converged).
    """
    z = np.array(z, dtype=float)
    for _ in range(max_iter):
        F, J = fun_jac(z)
        if extra is not None:
            A, b = extra
            F = np.concatenate([F, A @ z - b])
            J = np.vstack([J, A])
        try:
            dz = np.linalg.solve(J, -F)
        except np.linalg.LinAlgError:
            return z, False
        if not np.all(np.isfinite(dz)):
            return z, False
        z = z + dz
        if np.max(np.abs(dz)) <= tol * max(1.0, np.max(np.abs(z))):
            F, _ = fun_jac(z)
            return z, bool(np.max(np.abs(F)) < 1e-9)
    F, _ = fun_jac(z)
    return z, bool(np.max(np.abs(F)) < 1e-11)


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def _critical_mode(h11, h12, h22):
    lo, hi = hessian_eigenvalues(h11, h12, h22)
    lam = lo if abs(lo) <= abs(hi) else hi
    v = np.array([h12, lam - h11]) if abs(lam - h11) + abs(h12) > abs(lam - h22) + abs(h12) \
        else np.array([lam - h22, h12])
    n = np.linalg.norm(v)
    return v / n if n > 0 else np.array([1.0, 0.0])
