"""Exact bifurcation analysis of one module: what the paper did in Maple (sections 4-5).

Three tools, numpy/scipy only (no ROS):

:func:`degenerate_curves`
    In the plane of two parameters, the curves where some equilibrium is
    degenerate (``G = 0`` and ``det H = 0``), traced by pseudo-arclength
    continuation of the extended system, not read off pixel edges.  Each point
    carries the degenerate configuration, the Hessian eigenvalues there and
    whether a *minimum* degenerates (``lambda_max > 0``: the stable count
    changes across the curve there) or only a saddle/maximum.
:func:`operation_range`
    The rho interval (everything else fixed) over which the stable branch
    through a given configuration stays stable, and what ends it at each side
    (``'fold'``, ``'branch_point'`` or the search ``'limit'``), each end located
    by Newton on a regular extended system to ~1e-12.
:func:`two_stable_limit`
    Point C of the paper's fig. 6: the tip of the 2-stable region of the
    (rho, F3, F4) space, where the second stable equilibrium is born out of a
    totally degenerate one (``H = 0``, an umbilic).

Notation.  ``G = dU/dtheta`` and ``H = d2U/dtheta2`` of :mod:`.module`
(unscaled, SI).  The vertical forces used throughout include the rod weights
(``f3y - m1 g / 2``), exactly as the solver does.

Symmetries and why they are special-cased
-----------------------------------------
The generic extended system ``{G = 0, det H = 0}`` in (theta1, theta2, x, y) is
regular at folds, cusps and at the points where a fold curve crosses a line of
exact symmetry.  It is *singular* along curves of symmetry-breaking pitchforks,
which only exist when a symmetry holds on the whole parameter plane: there the
equilibrium set itself self-intersects (``[H | G_x G_y]`` has rank 1), Newton
converges linearly and continuation stalls.  Three symmetries of the model
occur (DESIGN.md section 2):

``'swap'``        (t1, t2) -> (t2, t1); needs L1 = L2, ka = kb, F3 = F4, f3x = -f4x.
                  Fixed set t1 = t2; breaking mode (1, -1).  Curve: eq. (15).
``'swap_mirror'`` (t1, t2) -> (-t2, -t1); needs L1 = L2, ka = kb, F3 = -F4,
                  f3x = -f4x.  Fixed set t1 = -t2; breaking mode (1, 1).
``'mirror'``      (t1, t2) -> (-t1, -t2); needs F3 = F4 = 0 (unloaded).  Fixed
                  points: the four flat configurations, equilibria for every
                  parameter value; their degeneracy is ``det H(flat) = 0``, the
                  three lines of DESIGN section 2 when L1 = 1.

When a symmetry holds on the whole plane (checked exactly on the affine
parameter map) a seed that lies on its fixed set with a breaking critical mode
is traced on the *restricted* system instead: ``{g1(t, +-t) = 0,
psi^T H psi = 0}`` in (t, x, y) for the swap symmetries, ``{det H(flat; x, y) =
0}`` in (x, y) for the mirror one.  Both are regular.  The same restricted
systems locate symmetric branch points in :func:`operation_range`.

Parameters of a plane
---------------------
An axis is a name or a dict of coefficients over the raw parameters
(``{'f3y': 1, 'f4y': 0.5}`` is the ray F4 = F3/2).  Names: ``rho``, ``L1``,
``L2``, ``ka``, ``kb``, ``kc``, ``k`` (all three springs), ``f3x``, ``f4x``,
``F3``/``f3y``, ``F4``/``f4y``, ``F`` (f3y = f4y together).  The value of an axis
*replaces* the components it touches (weights are still subtracted from the
vertical forces); all other parameters come from ``base``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import linalg as sla
from scipy.optimize import root

from .module import ModuleParams, InvalidParameterError
from .batch_solver import equilibria_batch
from .classification import DEGENERACY_TOL, hessian_eigenvalues
from .polynomial_solver import equilibria

__all__ = [
    'Curve', 'degenerate_curves', 'RangeEnd', 'OperationRange', 'operation_range',
    'TwoStableLimit', 'two_stable_limit', 'AXES', 'FOLD', 'BRANCH_POINT', 'LIMIT',
]

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


# ---------------------------------------------------------------------------
# Pseudo-arclength continuation of a curve F(z) = 0, F: R^n -> R^(n-1)

def _tangent(J, previous=None):
    """Unit null vector of the (n-1) x n Jacobian, oriented along ``previous``."""
    basis = sla.null_space(J)
    if basis.shape[1] == 0:
        basis = np.linalg.svd(J)[2][-1:].T
    if previous is None:
        t = basis[:, -1]
    else:
        t = basis @ (basis.T @ previous)      # the null direction closest to previous
        if np.linalg.norm(t) < 1e-12:
            t = basis[:, -1]
    if previous is not None and t @ previous < 0:
        t = -t
    return t / np.linalg.norm(t)


@dataclass
class _Trace:
    points: list
    end: str


def _continue(system, z0, t0, h0, hmax, hmin, max_steps, start=None):
    """Follow the solution curve of ``system`` from z0 along +t0 until it leaves the
    unit box of the plane coordinates, closes, or fails.  Returns a _Trace."""
    nt = system.nt
    t0 = np.array(t0, float)
    z, t, h = np.array(z0, float), t0.copy(), h0
    pts = [z.copy()]
    start = z.copy() if start is None else start
    travelled = 0.0
    for _ in range(max_steps):
        accepted = False
        while h >= hmin:
            zp = z + h * t
            extra = (t[None, :], np.array([t @ zp]))
            zc, ok = _newton(system.fj, zp, extra, tol=1e-12, max_iter=8)
            if ok and np.linalg.norm(zc - zp) < 0.25 * h + 1e-12:
                _, J = system.fj(zc)
                tn = _tangent(J, t)
                if tn @ t > math.cos(0.35):
                    accepted = True
                    break
            h *= 0.5
        if not accepted:
            return _Trace(pts, 'failed')
        u = zc[nt:]
        if np.any(u < 0.0) or np.any(u > 1.0) or not system.family.valid(system.q(u)):
            zb = _to_box_edge(system, z, zc, t, h)
            if zb is not None:
                pts.append(zb)
            return _Trace(pts, 'box')
        step = np.linalg.norm(zc - z)
        travelled += step
        # closed loop: the new chord passes the starting point, in the starting direction
        if (travelled > 4 * hmax and tn @ t0 > 0.5
                and _segment_distance(start, z, zc) < 1e-6 + 0.25 * step):
            pts.append(start.copy())
            return _Trace(pts, 'closed')
        z, t = zc, tn
        pts.append(z.copy())
        h = min(hmax, 1.5 * h)
    return _Trace(pts, 'max_steps')


def _segment_distance(p, a, b):
    ab = b - a
    denom = ab @ ab
    s = 0.0 if denom == 0 else min(1.0, max(0.0, (p - a) @ ab / denom))
    return float(np.linalg.norm(a + s * ab - p))


def _to_box_edge(system, z_in, z_out, t_in, h):
    """The curve point on the box edge between an inside point z_in and the next
    corrector point z_out (step h along the tangent t_in)."""
    nt = system.nt
    u_in, u_out = z_in[nt:], z_out[nt:]
    best = None
    for i in range(system.nq):
        for edge in (0.0, 1.0):
            if (u_out[i] - edge) * (u_in[i] - edge) <= 0 and u_in[i] != edge:
                s = (edge - u_in[i]) / (u_out[i] - u_in[i])
                if best is None or s < best[0]:
                    best = (s, i, edge)
    if best is None:
        return None
    s, i, edge = best
    guess = z_in + s * (z_out - z_in)
    A = np.zeros((1, z_in.size))
    A[0, nt + i] = 1.0
    zb, ok = _newton(system.fj, guess, (A, np.array([edge])), max_iter=10)
    if ok and np.all(zb[nt:] >= -1e-9) and np.all(zb[nt:] <= 1 + 1e-9) \
            and np.linalg.norm(zb - guess) < np.linalg.norm(z_out - z_in) + 1e-9:
        zb[nt:] = np.clip(zb[nt:], 0.0, 1.0)
        return zb
    # tangential crossing (e.g. a cusp on the edge): bisect along the arc instead

    def corrected(step):
        zp = z_in + step * t_in
        zc, good = _newton(system.fj, zp, (t_in[None, :], np.array([t_in @ zp])),
                           tol=1e-13, max_iter=12)
        return zc, good

    a, b = 0.0, h
    za = z_in
    for _ in range(60):
        m = 0.5 * (a + b)
        zm, good = corrected(m)
        if not good:
            break
        if (zm[nt + i] - edge) * (u_in[i] - edge) > 0:
            a, za = m, zm
        else:
            b = m
        if b - a < 1e-14:
            break
    zb = za.copy()
    zb[nt + i] = edge
    return zb


# ---------------------------------------------------------------------------
# Public result of degenerate_curves

@dataclass(frozen=True)
class Curve:
    """One curve of degenerate equilibria in a parameter plane.

    ``points`` (N, 2): plane coordinates (x, y).  Per point: ``theta`` (N, 2) the
    degenerate equilibrium (wrapped to [-pi, pi)), ``eigenvalues`` (N, 2) its
    Hessian eigenvalues (ascending; one of them is zero), and ``stable_boundary``
    (N,) True where the other eigenvalue is positive: a minimum degenerates
    there (merges with a saddle, or changes type at a pitchfork), so the number
    of *stable* equilibria changes across the curve.  False: only unstable
    equilibria are created/destroyed.

    ``kind`` is ``'fold'`` (generic: two equilibria merge) or ``'branch_point'``
    (a symmetric equilibrium has a symmetry-breaking critical mode; ``symmetry``
    says which: ``'swap'``, ``'swap_mirror'`` or ``'mirror'``).  ``closed``: the
    curve is a loop inside the box.  ``ends``: why tracing stopped at the first
    and last point (``'box'``: on the box edge; ``'closed'``; ``'failed'``: the
    corrector could not continue, e.g. at a point where H = 0; ``'max_steps'``).
    """

    x_name: str
    y_name: str
    points: np.ndarray
    theta: np.ndarray
    eigenvalues: np.ndarray
    stable_boundary: np.ndarray
    kind: str
    symmetry: str = None
    closed: bool = False
    ends: tuple = ('box', 'box')

    @property
    def changes_stable_count(self):
        """True if the stable count changes across some part of the curve."""
        return bool(np.any(self.stable_boundary))

    def segments(self, stable_boundary=True):
        """Maximal runs of points with the given ``stable_boundary`` flag, as (M, 2) arrays."""
        flag = self.stable_boundary == bool(stable_boundary)
        out, start = [], None
        for i, f in enumerate(np.append(flag, False)):
            if f and start is None:
                start = i
            elif not f and start is not None:
                if i - start >= 2:
                    out.append(self.points[start:i])
                start = None
        return out

    def __len__(self):
        return len(self.points)


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def _make_curve(system, zs, x_name, y_name, closed, ends):
    qs, ths, evs = [], [], []
    for z in zs:
        q, th, ev = system.point(z)
        qs.append(q)
        ths.append(th)
        evs.append(ev)
    ev = np.array(evs)
    # the non-zero eigenvalue is positive: a minimum degenerates
    stable = ev[:, 1] > STABLE_BOUNDARY_TOL * system.s
    return Curve(x_name=x_name, y_name=y_name, points=np.array(qs), theta=_wrap(np.array(ths)),
                 eigenvalues=ev, stable_boundary=stable,
                 kind=FOLD if system.kind is None else BRANCH_POINT,
                 symmetry=system.kind, closed=closed, ends=tuple(ends))


# ---------------------------------------------------------------------------
# Seeds: count changes on a coarse grid, bisected, then Newton on the extended system

def _keys(batch):
    return batch.num_equilibria.astype(np.int64) * 8 + batch.num_stable


def _batch_at(family, q):
    """equilibria_batch at plane points q (M, nq) (raw totals, weights folded in)."""
    P = family.raw(q)
    return equilibria_batch(P[:, 0], P[:, 1], P[:, 2], P[:, 3], P[:, 4], P[:, 5],
                            P[:, 6], P[:, 7], P[:, 8], P[:, 9])


def _locate_changes(family, a, b, rounds=4, sub=24):
    """Bisect the segments a[i] -> b[i] (plane coordinates) where the equilibrium key
    changes; returns (a', b') pairs of tiny width straddling a change."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    for _ in range(rounds):
        if not len(a):
            break
        s = np.linspace(0.0, 1.0, sub + 1)
        pts = a[:, None, :] + s[None, :, None] * (b - a)[:, None, :]
        keys = _keys(_batch_at(family, pts.reshape(-1, a.shape[1]))).reshape(len(a), sub + 1)
        na, nb = [], []
        for i in range(len(a)):
            change = np.nonzero(keys[i, 1:] != keys[i, :-1])[0]
            for j in change:
                na.append(pts[i, j])
                nb.append(pts[i, j + 1])
        a, b = np.array(na).reshape(-1, a.shape[1]), np.array(nb).reshape(-1, a.shape[1])
    return a, b


def _degenerate_candidate(family, qa, qb):
    """The degenerate equilibrium at a tiny key change between plane points qa, qb:
    on the side with more equilibria, the one with the smallest |lambda_min|."""
    best = None
    sets = [equilibria(family.params(q)) for q in (qa, qb)]
    side = 0 if len(sets[0]) >= len(sets[1]) else 1
    for e in sets[side]:
        lam = min(abs(e.eigenvalues[0]), abs(e.eigenvalues[1]))
        if best is None or lam < best[0]:
            best = (lam, e)
    return None if best is None else (best[1], (qa, qb)[side])


def _critical_mode(h11, h12, h22):
    lo, hi = hessian_eigenvalues(h11, h12, h22)
    lam = lo if abs(lo) <= abs(hi) else hi
    v = np.array([h12, lam - h11]) if abs(lam - h11) + abs(h12) > abs(lam - h22) + abs(h12) \
        else np.array([lam - h22, h12])
    n = np.linalg.norm(v)
    return v / n if n > 0 else np.array([1.0, 0.0])


def _system_for(family, q, theta, lo, hi):
    """Choose the extended system for a degenerate equilibrium at plane point q."""
    t1, t2 = theta
    sym = family.symmetries
    if MIRROR in sym:
        for f in _FLATS:
            if abs(_wrap(t1 - f[0])) < 1e-6 and abs(_wrap(t2 - f[1])) < 1e-6:
                return _System(family, lo, hi, MIRROR, f), np.array([])
    P = family.raw(np.asarray(q, float))
    _, _, h11, h12, h22 = _gh(P, t1, t2)
    v = _critical_mode(h11, h12, h22)
    if SWAP in sym and abs(_wrap(t1 - t2)) < 1e-6 and abs(v[0] + v[1]) < 0.1:
        return _System(family, lo, hi, SWAP), np.array([0.5 * (t1 + t2)])
    if SWAP_MIRROR in sym and abs(_wrap(t1 + t2)) < 1e-6 and abs(v[0] - v[1]) < 0.1:
        return _System(family, lo, hi, SWAP_MIRROR), np.array([0.5 * (t1 - t2)])
    return _System(family, lo, hi, None), np.array([t1, t2])


def _refine_seed(system, theta_part, qa, qb):
    """Newton on the extended system restricted to the segment qa -> qb."""
    ua = (np.asarray(qa) - system.lo) / system.span
    ub = (np.asarray(qb) - system.lo) / system.span
    nt = system.nt
    d = ub - ua
    # unknowns: z (n); constraint: the plane point lies on the line through ua, ub
    # (normal to d), i.e. one linear row.
    normal = np.array([-d[1], d[0]]) if system.nq == 2 else np.ones(1)
    A = np.zeros((1, system.n))
    A[0, nt:] = normal
    b = np.array([normal @ ua])
    z0 = np.concatenate([theta_part, 0.5 * (ua + ub)])
    z, ok = _newton(system.fj, z0, (A, b), tol=1e-13, max_iter=30)
    if not ok:
        sol = root(lambda z: np.concatenate([system.fj(z)[0], A @ z - b]), z0,
                   jac=lambda z: np.vstack([system.fj(z)[1], A]), method='hybr',
                   options={'xtol': 1e-14})
        z, ok = sol.x, bool(sol.success or np.max(np.abs(sol.fun)) < 1e-10)
    if not ok:
        return None
    u = z[nt:]
    if np.linalg.norm(u - 0.5 * (ua + ub)) > 10 * np.linalg.norm(d) + 1e-6:
        return None          # converged elsewhere along the line
    return z


def _grid_edges(nx, ny):
    """Index pairs of neighbouring grid nodes (flattened i * ny + j)."""
    idx = np.arange(nx * ny).reshape(nx, ny)
    e1 = np.stack([idx[:-1, :].ravel(), idx[1:, :].ravel()], 1)   # along x
    e2 = np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], 1)   # along y
    return np.concatenate([e1, e2])


def _crossed_edges(uv, nx, ny):
    """Grid edges (node index pairs) crossed by a polyline in unit box coordinates."""
    out = set()
    gx, gy = (nx - 1), (ny - 1)
    for (u0, v0), (u1, v1) in zip(uv[:-1], uv[1:]):
        # vertical grid lines u = i / gx (edges along y)
        for i in range(int(math.ceil(min(u0, u1) * gx - 1e-12)),
                       int(math.floor(max(u0, u1) * gx + 1e-12)) + 1):
            if u1 == u0:
                continue
            s = (i / gx - u0) / (u1 - u0)
            if -1e-12 <= s <= 1 + 1e-12 and 0 <= i < nx:
                v = v0 + s * (v1 - v0)
                j = min(max(int(math.floor(v * gy)), 0), ny - 2)
                out.add((i * ny + j, i * ny + j + 1))
        for j in range(int(math.ceil(min(v0, v1) * gy - 1e-12)),
                       int(math.floor(max(v0, v1) * gy + 1e-12)) + 1):
            if v1 == v0:
                continue
            s = (j / gy - v0) / (v1 - v0)
            if -1e-12 <= s <= 1 + 1e-12 and 0 <= j < ny:
                u = u0 + s * (u1 - u0)
                i = min(max(int(math.floor(u * gx)), 0), nx - 2)
                out.add((i * ny + j, (i + 1) * ny + j))
    return out


def degenerate_curves(base: ModuleParams, x, x_range, y, y_range, *, grid=(48, 48),
                      edge_points=400, step=0.01, max_step=0.02, min_step=1e-9,
                      max_steps=20000):
    """Curves of degenerate equilibria in the (x, y) plane, clipped to the box.

    ``x``, ``y``: parameter axes (names of :data:`AXES`, or dicts of raw
    coefficients, see the module docstring); ``x_range``, ``y_range``: the box.
    All other parameters come from ``base`` (its own value of x and y is ignored).

    Algorithm.  Seeds: the equilibrium count (total and stable) is computed on a
    ``grid`` of the box and, finer (``edge_points``), along its four edges with
    :func:`equilibria_batch`; on every grid edge where it changes, the change is
    bracketed (to ~1e-6 of the edge), the degenerate equilibrium identified (the
    one with the smallest |lambda| on the side with more equilibria) and solved
    for by Newton on the extended system restricted to the grid edge.  Each seed
    not on an already traced curve is followed both ways by pseudo-arclength
    continuation in (theta, x, y), box coordinates scaled to [0, 1] (arclength
    steps ``step``..``max_step``; tangent from the null space of the Jacobian,
    which is exact by complex-step differentiation; Newton corrector on the
    bordered system), until the curve leaves the box (the last point is put on
    the edge by Newton, or by bisection along the arc where the curve meets the
    edge tangentially, e.g. at a cusp), closes, or the corrector fails.  Seeds on
    the fixed set of a plane-wide symmetry with a symmetry-breaking critical
    mode are traced on the restricted, regular system (module docstring): the
    symmetric pitchfork curves (eq. (15)) and, unloaded, the flat-configuration
    lines, on which the generic system is singular.

    Returns a list of :class:`Curve`, every point solved to ~1e-12.  Found are:
    every curve reaching the box boundary (crossing it between two of the
    ``edge_points`` samples with a count change) and every curve crossing a grid
    edge with a count change.  Not guaranteed: closed curves smaller than a grid
    cell, and a curve that only ever crosses grid edges together with another
    curve that cancels its count change.
    """
    if not isinstance(base, ModuleParams):
        raise TypeError('base must be ModuleParams')
    family = _Family(base, (x, y))
    lo = np.array([x_range[0], y_range[0]], float)
    hi = np.array([x_range[1], y_range[1]], float)
    if not np.all(hi > lo):
        raise ValueError('ranges must be increasing')
    for corner in ((lo[0], lo[1]), (lo[0], hi[1]), (hi[0], lo[1]), (hi[0], hi[1])):
        if not family.valid(corner):
            raise InvalidParameterError(f'box corner {corner} gives invalid parameters')
    xl, yl = _axis_label(x), _axis_label(y)
    nx, ny = grid

    # grid nodes and their keys
    us, vs = np.linspace(0, 1, nx), np.linspace(0, 1, ny)
    U, V = np.meshgrid(us, vs, indexing='ij')
    nodes = lo + np.stack([U.ravel(), V.ravel()], 1) * (hi - lo)
    keys = _keys(_batch_at(family, nodes))
    edges = _grid_edges(nx, ny)
    changed = edges[keys[edges[:, 0]] != keys[edges[:, 1]]]
    seg_a = [nodes[changed[:, 0]]]
    seg_b = [nodes[changed[:, 1]]]
    edge_ids = [('grid', (int(e[0]), int(e[1]))) for e in changed]
    # the four box edges, finer
    s = np.linspace(0, 1, edge_points)
    for fixed_axis in (0, 1):
        for val in (0.0, 1.0):
            uv = np.zeros((edge_points, 2))
            uv[:, fixed_axis] = val
            uv[:, 1 - fixed_axis] = s
            q = lo + uv * (hi - lo)
            k = _keys(_batch_at(family, q))
            ch = np.nonzero(k[1:] != k[:-1])[0]
            seg_a.append(q[ch])
            seg_b.append(q[ch + 1])
            edge_ids.extend([('box', fixed_axis, val)] * len(ch))
    seg_a = np.concatenate(seg_a)
    seg_b = np.concatenate(seg_b)

    curves, traced_z, covered, box_ends = [], [], set(), []
    spacing = 1.0 / (edge_points - 1)
    for i in range(len(seg_a)):
        eid = edge_ids[i]
        if eid[0] == 'box':
            # a box-edge seed: skip if a traced curve already ends on this stretch
            ua, ub = (seg_a[i] - lo) / (hi - lo), (seg_b[i] - lo) / (hi - lo)
            _, axis, val = eid
            lo_s = min(ua[1 - axis], ub[1 - axis]) - spacing
            hi_s = max(ua[1 - axis], ub[1 - axis]) + spacing
            if any(ax == axis and v == val and lo_s <= w <= hi_s for ax, v, w in box_ends):
                continue
        elif eid[1] in covered:
            continue
        a, b = _locate_changes(family, seg_a[i:i + 1], seg_b[i:i + 1])
        for qa, qb in zip(a, b):
            cand = _degenerate_candidate(family, qa, qb)
            if cand is None:
                continue
            e, q_side = cand
            system, theta_part = _system_for(family, q_side, (e.theta1, e.theta2), lo, hi)
            z = _refine_seed(system, theta_part, qa, qb)
            if z is None:
                continue
            if _on_traced(system, z, traced_z):
                continue
            curve_z, closed, ends = _trace_both(system, z, step, max_step, min_step, max_steps)
            if len(curve_z) < 2:
                continue
            traced_z.append((system, np.array(curve_z)))
            curve = _make_curve(system, curve_z, xl, yl, closed, ends)
            curves.append(curve)
            uv = (curve.points - lo) / (hi - lo)
            covered |= _crossed_edges(uv, nx, ny)
            for end in (uv[0], uv[-1]):
                for axis in (0, 1):
                    for val in (0.0, 1.0):
                        if abs(end[axis] - val) < 1e-9:
                            box_ends.append((axis, val, end[1 - axis]))
    return curves


def _full_coordinates(system, zs):
    """(t1, t2, u, v) rows for any system's solution rows (for de-duplication)."""
    zs = np.atleast_2d(zs)
    t1, t2 = system.theta(zs)
    return np.column_stack([t1, t2, zs[:, system.nt:]])


def _on_traced(system, z, traced, tol=1e-5):
    p = _full_coordinates(system, z)[0]
    for other, zs in traced:
        full = _full_coordinates(other, zs)
        d = full - p
        d[:, :2] = _wrap(d[:, :2])
        a, b = d[:-1], d[1:]
        ab = b - a
        denom = np.maximum(np.einsum('ij,ij->i', ab, ab), 1e-300)
        s = np.clip(-np.einsum('ij,ij->i', a, ab) / denom, 0.0, 1.0)
        dist = np.linalg.norm(a + s[:, None] * ab, axis=1)
        if len(dist) and dist.min() < tol:
            return True
        if len(d) == 1 and np.linalg.norm(d[0]) < tol:
            return True
    return False


def _trace_both(system, z, h0, hmax, hmin, max_steps):
    _, J = system.fj(z)
    t = _tangent(J)
    fwd = _continue(system, z, t, h0, hmax, hmin, max_steps)
    if fwd.end == 'closed':
        return fwd.points, True, ('closed', 'closed')
    bwd = _continue(system, z, -t, h0, hmax, hmin, max_steps)
    pts = bwd.points[::-1] + fwd.points[1:]
    return pts, False, (bwd.end, fwd.end)


# ---------------------------------------------------------------------------
# Operation range: continuation of one stable branch in rho

@dataclass(frozen=True)
class RangeEnd:
    """One end of an operation range.

    ``kind``: ``'fold'`` (the branch merges with a saddle and disappears),
    ``'branch_point'`` (a symmetric branch loses stability to a symmetry-breaking
    mode, or a non-symmetric branch merges into a symmetric one; ``symmetry``
    names the symmetry) or ``'limit'`` (the search bound was reached while still
    stable).  ``theta``: the critical configuration (at a limit: the
    equilibrium there).  ``eigenvalues``: Hessian eigenvalues at the end.
    """

    rho: float
    kind: str
    theta: tuple
    eigenvalues: tuple
    symmetry: str = None


@dataclass(frozen=True)
class OperationRange:
    """The rho interval over which one stable branch exists and stays stable.

    Iterating gives ``(rho_min, rho_max)``.  ``theta`` is the (polished) stable
    equilibrium at ``params.rho`` the branch was followed from; ``branch`` holds
    the accepted continuation points (rho, theta1, theta2), ascending in rho,
    ends included; pass the object back as ``hint`` to later calls.
    """

    params: ModuleParams
    theta: tuple
    lower: RangeEnd
    upper: RangeEnd
    branch: np.ndarray
    bounds: tuple

    @property
    def rho_min(self):
        return self.lower.rho

    @property
    def rho_max(self):
        return self.upper.rho

    @property
    def width(self):
        return self.upper.rho - self.lower.rho

    def __iter__(self):
        yield self.lower.rho
        yield self.upper.rho

    def __contains__(self, rho):
        return self.lower.rho < rho < self.upper.rho

    def theta_at(self, rho):
        """The branch's equilibrium at ``rho`` inside the range (interpolated, polished)."""
        if not self.lower.rho <= rho <= self.upper.rho:
            raise ValueError(f'rho {rho} outside the range ({self.lower.rho}, {self.upper.rho})')
        br = self.branch
        guess = (np.interp(rho, br[:, 0], br[:, 1]), np.interp(rho, br[:, 0], br[:, 2]))
        P = _raw(self.params)
        P[0] = rho
        t1, t2, ok = _newton_theta(P, *guess)
        return (t1, t2)


def _newton_theta(P, t1, t2, max_iter=12):
    """Newton on G = 0 at fixed parameters (scalar, fast).  Returns (t1, t2, converged).

    Converged: the step fell below 1e-13 rad, or the residual is at rounding level
    (|G| <= 1e-13 * scale: needed where H is nearly singular and the last steps
    only shuffle rounding noise)."""
    rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = P
    a1 = (ka + kc) * rho + f3x
    a2 = (kb + kc) * rho - f4x
    kl1, kl2 = kc * L1, kc * L2
    tiny = 1e-13 * max(L1, L2) * max(abs(a1), abs(a2), abs(f3y), abs(f4y), kl1, kl2)
    sin, cos = math.sin, math.cos
    residual = math.inf
    for _ in range(max_iter):
        s1, c1, s2, c2 = sin(t1), cos(t1), sin(t2), cos(t2)
        s12 = s1 * c2 + c1 * s2
        c12 = c1 * c2 - s1 * s2
        g1 = L1 * (a1 * s1 - kl2 * s12 - f3y * c1)
        g2 = L2 * (a2 * s2 - kl1 * s12 - f4y * c2)
        residual = max(abs(g1), abs(g2))
        h11 = L1 * (a1 * c1 - kl2 * c12 + f3y * s1)
        h22 = L2 * (a2 * c2 - kl1 * c12 + f4y * s2)
        h12 = -kl1 * L2 * c12
        det = h11 * h22 - h12 * h12
        if det == 0.0 or not math.isfinite(det):
            return t1, t2, residual <= tiny
        d1 = (h22 * g1 - h12 * g2) / det
        d2 = (h11 * g2 - h12 * g1) / det
        if residual <= tiny and abs(d1) + abs(d2) < 1e-6:
            t1 -= d1
            t2 -= d2
            return t1, t2, True
        t1 -= d1
        t2 -= d2
        if abs(d1) + abs(d2) < 1e-13:
            return t1, t2, True
        if abs(d1) + abs(d2) > 1.0:
            return t1, t2, False
    return t1, t2, residual <= 10 * tiny


def _eig2(h11, h12, h22):
    """Ascending eigenvalues of [[h11, h12], [h12, h22]] (pure float; small one accurate)."""
    mean = 0.5 * (h11 + h22)
    big = mean + math.copysign(math.hypot(0.5 * (h11 - h22), h12), mean)
    small = 0.0 if big == 0.0 else (h11 * h22 - h12 * h12) / big
    return (small, big) if small <= big else (big, small)


def _mode(h11, h12, h22, lam):
    """Unit eigenvector of eigenvalue lam."""
    if abs(lam - h11) >= abs(lam - h22):
        a, b = h12, lam - h11
    else:
        a, b = lam - h22, h12
    n = math.hypot(a, b)
    return (a / n, b / n) if n > 0 else (1.0, 0.0)


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


def _branch_state(P, t1, t2):
    """At an equilibrium: (lambda_min, lambda_max, mode, dtheta/drho, dlambda_min/drho)."""
    rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = P
    s1, c1, s2, c2, _, _, h11, h12, h22, k12 = _local_terms(P, t1, t2)
    g1r, g2r = L1 * (ka + kc) * s1, L2 * (kb + kc) * s2
    det = h11 * h22 - h12 * h12
    if det == 0.0:
        # exactly on a degeneracy (e.g. the flat branch on an unloaded boundary line,
        # where the numerators vanish too): lambda_min = 0 makes the caller end here
        dt1 = dt2 = 0.0
    else:
        dt1 = -(h22 * g1r - h12 * g2r) / det
        dt2 = -(h11 * g2r - h12 * g1r) / det
    lo, hi = _eig2(h11, h12, h22)
    v = _mode(h11, h12, h22, lo)
    # total derivative of H along the branch (third derivatives; dh11/dt1 = -g1 = 0)
    dh11 = L1 * (ka + kc) * c1 + k12 * dt2
    dh22 = L2 * (kb + kc) * c2 + k12 * dt1
    dh12 = k12 * (dt1 + dt2)
    dlam = v[0] * v[0] * dh11 + 2 * v[0] * v[1] * dh12 + v[1] * v[1] * dh22
    return lo, hi, v, (dt1, dt2), dlam


def _min_eig(P, t1, t2):
    rho, L1, L2, ka, kb, kc, f3x, f3y, f4x, f4y = P
    c1, s1, c2, s2 = math.cos(t1), math.sin(t1), math.cos(t2), math.sin(t2)
    c12 = c1 * c2 - s1 * s2
    h11 = L1 * (((ka + kc) * rho + f3x) * c1 - kc * L2 * c12 + f3y * s1)
    h22 = L2 * (((kb + kc) * rho - f4x) * c2 - kc * L1 * c12 + f4y * s2)
    return _eig2(h11, -kc * L1 * L2 * c12, h22)


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


def _theta_close(a, b, tol):
    return abs(_wrap(a[0] - b[0])) <= tol and abs(_wrap(a[1] - b[1])) <= tol


def _localise(P, sym, t1, t2, rho, sigma, est, dtheta, v):
    """Try to locate the end of the branch ahead of (t1, t2, rho) (estimated distance est).

    Returns (rho*, theta*, kind, symmetry) or None when no validated end is found."""
    flat = None
    for f in _FLATS:
        if _theta_close((t1, t2), f, 1e-9):
            flat = f
    candidates = []
    if MIRROR in sym:
        if flat is not None:
            for r in _flat_degenerate_rhos(P, flat):
                candidates.append((r, flat, BRANCH_POINT, MIRROR))
        else:
            # a non-flat branch of an unloaded module ends where it merges with a flat one
            for f in _FLATS:
                for r in _flat_degenerate_rhos(P, f):
                    d = r - rho
                    pred = (t1 + 2 * d * dtheta[0], t2 + 2 * d * dtheta[1])
                    if _theta_close(pred, f, 0.3 * max(abs(_wrap(t1 - f[0])),
                                                       abs(_wrap(t2 - f[1]))) + 1e-6):
                        candidates.append((r, f, BRANCH_POINT, MIRROR))
    if not candidates:
        if SWAP in sym and abs(_wrap(t1 - t2)) < 1e-9 and abs(v[0] + v[1]) < 0.2:
            t, r, ok = _swap_newton(P, 0.5 * (t1 + t2), rho, False)
            if ok:
                candidates.append((r, (t, t), BRANCH_POINT, SWAP))
        elif SWAP_MIRROR in sym and abs(_wrap(t1 + t2)) < 1e-9 and abs(v[0] - v[1]) < 0.2:
            t, r, ok = _swap_newton(P, 0.5 * (t1 - t2), rho, True)
            if ok:
                candidates.append((r, (t, -t), BRANCH_POINT, SWAP_MIRROR))
        else:
            a, b, r, ok = _fold_newton(P, t1, t2, rho)
            if ok:
                candidates.append((r, (a, b), FOLD, None))
    best = None
    for r, th, kind, symmetry in candidates:
        d = (r - rho) * sigma
        if not (-1e-12 * max(1.0, abs(rho)) <= d <= 3.0 * est + 1e-12):
            continue
        # the end of a stable branch: eigenvalues (0, +); a negative second eigenvalue
        # means the solve landed on another sheet (e.g. beyond an earlier fold)
        Q = list(P)
        Q[0] = r
        if not _min_eig(Q, th[0], th[1])[1] > 0.0:
            continue
        if kind == FOLD or (symmetry == MIRROR and flat is None):
            # theta - theta* ~ sqrt(distance): theta* ~ theta + 2 d dtheta/drho
            pred = (t1 + 2 * (r - rho) * dtheta[0], t2 + 2 * (r - rho) * dtheta[1])
            gap = max(abs(_wrap(t1 - th[0])), abs(_wrap(t2 - th[1])))
            if not _theta_close(pred, th, 0.35 * gap + 1e-7):
                continue
        else:
            pred = (t1 + (r - rho) * dtheta[0], t2 + (r - rho) * dtheta[1])
            if not _theta_close(pred, th, 0.1 + 1e-3):
                continue
        if best is None or d < best[0]:
            best = (d, r, th, kind, symmetry)
    if best is None:
        return None
    _, r, th, kind, symmetry = best
    if kind == FOLD:
        # a generic solve can still land on a non-symmetric branch point: classify
        Q = list(P)
        Q[0] = r
        kind = _kind_at(Q, th[0], th[1])
    return r, th, kind, symmetry


def _kind_at(P, t1, t2):
    """'fold' or 'branch_point' for a (nearly) critical equilibrium: is the critical
    mode orthogonal to dG/drho?"""
    _, L1, L2, ka, kb, kc = P[:6]
    _, _, h11, h12, h22 = _gh(P, t1, t2)
    psi = _critical_mode(h11, h12, h22)
    gr = np.array([L1 * (ka + kc) * math.sin(t1), L2 * (kb + kc) * math.sin(t2)])
    norm = np.linalg.norm(gr)
    return BRANCH_POINT if norm == 0 or abs(psi @ gr) <= 1e-7 * norm else FOLD


def _end_record(P, rho, theta, kind, symmetry):
    Q = P.copy()
    Q[0] = rho
    _, _, h11, h12, h22 = _gh(Q, theta[0], theta[1])
    lo, hi = hessian_eigenvalues(h11, h12, h22)
    return RangeEnd(rho=float(rho), kind=kind,
                    theta=(_wrap_float(float(theta[0])), _wrap_float(float(theta[1]))),
                    eigenvalues=(float(lo), float(hi)), symmetry=symmetry)


def _bisect_end(Q, t1, t2, rho, sigma, gap, scale_h):
    """Fallback localisation: bisection on 'the branch continues, stable' between rho
    (stable at (t1, t2)) and rho + sigma * gap (not), each trial a Newton solve from
    the last stable configuration.  Returns (rho_end, theta_end)."""
    a, b = 0.0, gap
    ta = (t1, t2)
    while b - a > 1e-14 * max(1.0, abs(rho)):
        m = 0.5 * (a + b)
        Q[0] = rho + sigma * m
        n1, n2, ok = _newton_theta(Q, *ta)
        if ok and _theta_close((n1, n2), ta, 0.05) and _min_eig(Q, n1, n2)[0] > 0.0:
            a, ta = m, (n1, n2)
        else:
            b = m
    return rho + sigma * a, ta


def _follow(P, sym, t1, t2, sigma, bound, scale_len, scale_h):
    """Follow the stable branch from (t1, t2, P[0]) in direction sigma up to ``bound``."""
    Q = P.copy()
    rho = P[0]
    samples = []
    hmax = 0.1 * scale_len
    shrink = 1.0
    first_fail = None        # smallest failed step since the last accepted one
    tried_here = False       # localisation already attempted from this point
    for _ in range(2000):
        Q[0] = rho
        lo, hi, v, dth, dlam = _branch_state(Q, t1, t2)
        rate = sigma * dlam
        est = lo / -rate if rate < 0 else math.inf
        remaining = sigma * (bound - rho)
        if remaining <= BOUND_TOL * scale_len:
            # at the bound (a degeneracy closer to it than BOUND_TOL counts as the bound)
            return _end_record(Q, bound, (t1, t2), LIMIT, None), samples
        if not tried_here and (est < 0.05 * scale_len or lo < 1e-3 * scale_h):
            tried_here = True
            end = _localise(Q, sym, t1, t2, rho, sigma, est, dth, v)
            if end is not None and sigma * (bound - end[0]) >= 0:
                r, th, kind, symmetry = end
                return _end_record(Q, r, th, kind, symmetry), samples
        speed = math.hypot(*dth)
        # lambda_min is predicted to vanish at or beyond the bound: do not creep up
        # on it, the bound ends the search first
        lam_room = 0.5 * est if est < remaining * (1.0 - 1e-9) else math.inf
        step = min(hmax, lam_room, 0.15 / max(speed, 1e-300)) * shrink
        at_bound = step >= remaining
        if at_bound:
            step = remaining
        if shrink < 1e-3 and first_fail is not None:
            # the corrector keeps failing (e.g. a nearly symmetric branch point, where
            # the fold system is ill-conditioned): bisect on stability instead
            r, th = _bisect_end(Q, t1, t2, rho, sigma, first_fail, scale_h)
            Q[0] = r
            if sigma * (bound - r) <= BOUND_TOL * scale_len:
                return _end_record(Q, bound, th, LIMIT, None), samples
            return _end_record(Q, r, th, _kind_at(Q, *th), None), samples
        r_new = rho + sigma * step
        pred = (t1 + sigma * step * dth[0], t2 + sigma * step * dth[1])
        Q[0] = r_new
        n1, n2, ok = _newton_theta(Q, *pred)
        good = ok and _theta_close((n1, n2), pred, 0.05 + 0.5 * step * speed)
        if good:
            lam_new = _min_eig(Q, n1, n2)[0]
            # on the bound itself a degeneracy (e.g. the continuum at rho = 0) is allowed
            good = lam_new > 0.0 or (at_bound and lam_new > -1e-12 * scale_h)
        if not good:
            first_fail = step if first_fail is None else min(first_fail, step)
            shrink *= 0.25
            continue
        shrink = min(1.0, shrink * 2.0)
        first_fail, tried_here = None, False
        rho, t1, t2 = r_new, n1, n2
        samples.append((rho, t1, t2))
    return _end_record(Q, rho, (t1, t2), LIMIT, None), samples


def operation_range(params: ModuleParams, theta, *, rho_bounds=None, hint=None) -> OperationRange:
    """The rho interval over which the stable branch through ``theta`` stays stable.

    ``params`` fixes everything but rho (``params.rho`` is where the branch is
    entered); ``theta`` is the stable equilibrium there or a close guess (it is
    polished by Newton; ``ValueError`` if that is not a stable equilibrium).
    The branch is followed both ways by continuation in rho (tangent predictor,
    Newton corrector; each step bounded so that lambda_min is predicted to at most
    halve and the angles move at most 0.15 rad).  When lambda_min is about to
    vanish the end is solved for on a regular extended system: a fold on
    ``{G = 0, det H = 0}`` in (theta, rho); a swap-symmetric branch point on the
    restricted system ``{g1(t, +-t) = 0, psi^T H psi = 0}``; for an unloaded
    module, the merge of the non-flat branch with a flat one at ``det H(flat) =
    0`` (a quadratic in rho).  The end is accepted only if it is consistent
    with the branch (ahead, near the predicted configuration).  Ends are exact to
    rounding (~1e-13).

    ``rho_bounds``: search interval (default ``(0, 2 (L1 + L2))``); reaching a
    bound while still stable gives an end of kind ``'limit'``.  ``hint``: a
    previous :class:`OperationRange`; if only rho changed and the new state is on
    the same branch, its ends are reused without any continuation.
    """
    if not isinstance(params, ModuleParams):
        raise TypeError('params must be ModuleParams')
    P = [float(v) for v in _raw(params)]
    L = params.L1 + params.L2
    if rho_bounds is None:
        lo_b, hi_b = 0.0, 2.0 * L
    else:
        lo_b, hi_b = float(rho_bounds[0]), float(rho_bounds[1])
    if not lo_b <= params.rho <= hi_b:
        raise ValueError(f'rho {params.rho} outside rho_bounds ({lo_b}, {hi_b})')
    th = np.asarray(theta, dtype=float)
    if th.shape != (2,) or not np.all(np.isfinite(th)):
        raise ValueError('theta must be two finite angles')
    t1, t2, ok = _newton_theta(P, float(th[0]), float(th[1]))
    if not ok:
        raise ValueError(f'no equilibrium near theta={tuple(th)}')
    lam = _min_eig(P, t1, t2)
    if not lam[0] > DEGENERACY_TOL * abs(lam[1]):
        raise ValueError(f'the equilibrium near theta={tuple(th)} is not stable '
                         f'(eigenvalues {float(lam[0])}, {float(lam[1])})')
    t1, t2 = _wrap_float(t1), _wrap_float(t2)

    if hint is not None and _hint_applies(hint, P, t1, t2, (lo_b, hi_b)):
        return OperationRange(params=params, theta=(t1, t2), lower=hint.lower, upper=hint.upper,
                              branch=hint.branch, bounds=(lo_b, hi_b))

    sym = _symmetries(P)
    scale_h = _scale(P)
    lower, below = _follow(P, sym, t1, t2, -1.0, lo_b, L, scale_h)
    upper, above = _follow(P, sym, t1, t2, +1.0, hi_b, L, scale_h)
    rows = ([(lower.rho, *lower.theta)] + below[::-1] + [(params.rho, t1, t2)] + above
            + [(upper.rho, *upper.theta)])
    branch = np.array(rows)
    branch[:, 1:] = _unwrap_rows(branch[:, 1:])
    return OperationRange(params=params, theta=(t1, t2), lower=lower, upper=upper,
                          branch=branch, bounds=(lo_b, hi_b))


def _wrap_float(a):
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def _unwrap_rows(th):
    return np.unwrap(th, axis=0)


def _hint_applies(hint, P, t1, t2, bounds):
    if not isinstance(hint, OperationRange) or tuple(hint.bounds) != tuple(bounds):
        return False
    Ph = _raw(hint.params)
    if not np.array_equal(Ph[1:], P[1:]):
        return False
    rho = P[0]
    if not hint.lower.rho < rho < hint.upper.rho:
        return False
    br = hint.branch
    guess = (np.interp(rho, br[:, 0], br[:, 1]), np.interp(rho, br[:, 0], br[:, 2]))
    a, b, ok = _newton_theta(P, float(guess[0]), float(guess[1]))
    return ok and _theta_close((a, b), (t1, t2), 1e-7)


# ---------------------------------------------------------------------------
# Point C of fig. 6: the tip of the 2-stable region

@dataclass(frozen=True)
class TwoStableLimit:
    """Point C of the paper's fig. 6 for one design.

    ``F3``, ``F4`` (N): the forces of C; ``rho`` and ``theta``: the actuator
    length and the configuration there, an equilibrium whose Hessian vanishes
    entirely (``H = 0``: an umbilic).  ``axis``: unit direction in (rho, F3, F4)
    along which the 2-stable region approaches C (its horn is tangent to it, of
    width O(distance^2)); ``params``: the module at C.
    """

    F3: float
    F4: float
    rho: float
    theta: tuple
    axis: np.ndarray
    params: ModuleParams

    @property
    def forces(self):
        return (self.F3, self.F4)


def _umbilic_guess(L1, L2, ka, kb, kc, sign):
    A, B = ka + kc, kb + kc
    rho = kc * L1 * L2 / math.sqrt(A * A * L1 * L1 + B * B * L2 * L2)
    F3 = math.sqrt(max(kc * kc * L2 * L2 - A * A * rho * rho, 0.0))
    F4 = math.sqrt(max(kc * kc * L1 * L1 - B * B * rho * rho, 0.0))
    t1, t2 = math.atan2(-A * rho, F3), math.atan2(-B * rho, F4)
    return np.array([sign * t1, sign * t2, rho, sign * F3, sign * F4])


def two_stable_limit(L2=1.0, *, L1=1.0, k=100.0, ka=None, kb=None, kc=None,
                     f3x=0.0, f4x=0.0, pushing=False) -> TwoStableLimit:
    """Point C of fig. 6: the largest vertical forces (F3, F4) for which two stable
    equilibria exist for some rho.

    Definition.  The 2-stable region of (rho, F3, F4) space ends, as the forces
    grow, in a thin horn whose tip C is an equilibrium with a totally degenerate
    Hessian, ``G = 0, H = 0`` (5 equations in theta1, theta2, rho, F3, F4: an
    isolated, regular solution).  No point with both F3 > C_F3 and F4 > C_F4 has
    two stable equilibria, and C is a limit of 2-stable points (along ``axis``):
    C is the corner of the 2-stable region's projection on the (F3, F4) plane.
    For L1 = L2 it is on the diagonal and is also the largest F = F3 = F4 with a
    2-stable rho (where the pitchfork curve (15) touches the fold curve (16)).

    Closed form for equal springs and no horizontal forces (derived from H12 = 0,
    H11 = H22 = 0, G = 0):  rho_C = L1 L2 / (2 sqrt(L1^2 + L2^2)),
    C = k (L2^2, L1^2) / sqrt(L1^2 + L2^2); with L1 = L2 = 1, k = 100:
    rho_C = 0.35355..., C = (70.7106..., 70.7106...).  The general case
    (ka, kb, kc, horizontal forces) is solved by Newton from the closed form.

    ``pushing``: the mirror image (negative forces, theta -> -theta).
    """
    ka = k if ka is None else ka
    kb = k if kb is None else kb
    kc = k if kc is None else kc
    sign = -1.0 if pushing else 1.0
    base = ModuleParams(rho=1.0, L1=L1, L2=L2, ka=ka, kb=kb, kc=kc, f3x=f3x, f4x=f4x)
    P0 = _raw(base)
    s = _scale(P0)

    def residual(z):
        z = np.asarray(z)
        P = np.broadcast_to(P0, z.shape[:-1] + (10,)).astype(z.dtype).copy()
        P[..., 0], P[..., 7], P[..., 9] = z[..., 2], z[..., 3], z[..., 4]
        return np.stack(_gh(P, z[..., 0], z[..., 1]), -1) / s

    def fj(z):
        Z = z[None, :] + (1j * _CSTEP) * np.eye(5)
        R = residual(Z)
        return R[0].real, (R.imag / _CSTEP).T

    z0 = _umbilic_guess(L1, L2, ka, kb, kc, sign)
    z, ok = _newton(fj, z0, tol=1e-15, max_iter=40)
    if not ok:
        sol = root(lambda v: fj(v)[0], z0, jac=lambda v: fj(v)[1], method='lm',
                   options={'xtol': 1e-15})
        z, ok = sol.x, bool(np.max(np.abs(fj(sol.x)[0])) < 1e-10)
    if not ok or z[2] <= 0:
        raise RuntimeError('no totally degenerate equilibrium found for these parameters')
    t1, t2, rho, F3, F4 = (float(v) for v in z)
    # the horn axis: kernel of dG/d(rho, F3, F4), on the side where dH is positive
    # definite (the degenerate point opens into a minimum)
    c1, s1, c2, s2 = math.cos(t1), math.sin(t1), math.cos(t2), math.sin(t2)
    A, B = ka + kc, kb + kc
    row1 = np.array([L1 * A * s1, -L1 * c1, 0.0])
    row2 = np.array([L2 * B * s2, 0.0, -L2 * c2])
    axis = np.cross(row1, row2)
    axis /= np.linalg.norm(axis)
    dh11 = L1 * (A * c1 * axis[0] + s1 * axis[1])
    dh22 = L2 * (B * c2 * axis[0] + s2 * axis[2])
    if dh11 + dh22 < 0:
        axis = -axis
    params = ModuleParams(rho=rho, L1=L1, L2=L2, ka=ka, kb=kb, kc=kc, f3x=f3x, f4x=f4x,
                          f3y=F3, f4y=F4)
    return TwoStableLimit(F3=F3, F4=F4, rho=rho, theta=(float(_wrap(t1)), float(_wrap(t2))),
                          axis=axis, params=params)
