"""Degenerate-equilibrium curves in the plane of two parameters (the paper's boundaries).

:func:`degenerate_curves` finds where some equilibrium is degenerate (``G = 0`` and
``det H = 0``): seeds from changes of the equilibrium count on a coarse grid, refined by
Newton on the extended system, then each curve traced by pseudo-arclength continuation
(not read off pixel edges).  Each point carries the degenerate configuration, the
Hessian eigenvalues there and whether a *minimum* degenerates (``lambda_max > 0``: the
stable count changes across the curve there) or only a saddle/maximum.  See
:mod:`.analysis` for the symmetries that are traced on restricted systems.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from scipy import linalg as sla
from scipy.optimize import root

from .bifurcation_model import (_axis_label, _critical_mode, _Family, _FLATS, _gh, _newton,
                                _System, _wrap, BRANCH_POINT, FOLD, MIRROR, STABLE_BOUNDARY_TOL,
                                SWAP, SWAP_MIRROR)
from ..module.batch_solver import equilibria_batch
from ..module.model import InvalidParameterError, ModuleParams
from ..module.polynomial_solver import equilibria

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
    family, lo, hi = _box(base, (x, y), x_range, y_range)
    xl, yl = _axis_label(x), _axis_label(y)
    seg_a, seg_b, edge_ids = _count_changes(family, lo, hi, grid, edge_points)
    found = _Found(lo, hi, grid, 1.0 / (edge_points - 1))
    for i in range(len(seg_a)):
        if found.skips(edge_ids[i], seg_a[i], seg_b[i]):
            continue
        a, b = _locate_changes(family, seg_a[i:i + 1], seg_b[i:i + 1])
        for qa, qb in zip(a, b):
            seed = _seed(family, qa, qb, lo, hi)
            if seed is None or _on_traced(*seed, found.traced_z):
                continue
            system, z = seed
            curve_z, closed, ends = _trace_both(system, z, step, max_step, min_step, max_steps)
            if len(curve_z) < 2:
                continue
            found.add(system, curve_z, _make_curve(system, curve_z, xl, yl, closed, ends))
    return found.curves


def _box(base, axes, x_range, y_range):
    """(family, lo, hi): the plane of ``axes`` through ``base`` and the box's corners;
    raises for a box that is empty or has a corner with invalid parameters."""
    if not isinstance(base, ModuleParams):
        raise TypeError('base must be ModuleParams')
    family = _Family(base, axes)
    lo = np.array([x_range[0], y_range[0]], float)
    hi = np.array([x_range[1], y_range[1]], float)
    if not np.all(hi > lo):
        raise ValueError('ranges must be increasing')
    for corner in ((lo[0], lo[1]), (lo[0], hi[1]), (hi[0], lo[1]), (hi[0], hi[1])):
        if not family.valid(corner):
            raise InvalidParameterError(f'box corner {corner} gives invalid parameters')
    return family, lo, hi


def _count_changes(family, lo, hi, grid, edge_points):
    """(a, b, ids): the segments [a, b] over which the equilibrium count (total and stable)
    changes, on the edges of a ``grid`` over the box (id ``('grid', (node, node))``) and,
    finer (``edge_points``), along its four edges (id ``('box', fixed axis, value)``)."""
    nx, ny = grid
    us, vs = np.linspace(0, 1, nx), np.linspace(0, 1, ny)
    U, V = np.meshgrid(us, vs, indexing='ij')
    nodes = lo + np.stack([U.ravel(), V.ravel()], 1) * (hi - lo)
    keys = _keys(_batch_at(family, nodes))
    edges = _grid_edges(nx, ny)
    changed = edges[keys[edges[:, 0]] != keys[edges[:, 1]]]
    seg_a = [nodes[changed[:, 0]]]
    seg_b = [nodes[changed[:, 1]]]
    edge_ids = [('grid', (int(e[0]), int(e[1]))) for e in changed]
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
    return np.concatenate(seg_a), np.concatenate(seg_b), edge_ids


def _seed(family, qa, qb, lo, hi):
    """(system, z): the degenerate equilibrium between the plane points ``qa`` and ``qb``
    (a count change) solved on the system that is regular there, or None."""
    cand = _degenerate_candidate(family, qa, qb)
    if cand is None:
        return None
    e, q_side = cand
    system, theta_part = _system_for(family, q_side, (e.theta1, e.theta2), lo, hi)
    z = _refine_seed(system, theta_part, qa, qb)
    return None if z is None else (system, z)


class _Found:
    """The curves traced so far, and what they account for: the grid edges they cross
    and where they end on the box's edges (seeds there need no tracing again)."""

    def __init__(self, lo, hi, grid, spacing):
        self.lo, self.hi, self.grid, self.spacing = lo, hi, grid, spacing
        self.curves, self.traced_z, self.covered, self.box_ends = [], [], set(), []

    def skips(self, eid, a, b):
        """Whether the count change on segment [a, b] (id ``eid``) is a traced curve's:
        a grid edge it crosses, or a box-edge stretch it ends on."""
        if eid[0] != 'box':
            return eid[1] in self.covered
        lo, hi = self.lo, self.hi
        ua, ub = (a - lo) / (hi - lo), (b - lo) / (hi - lo)
        _, axis, val = eid
        lo_s = min(ua[1 - axis], ub[1 - axis]) - self.spacing
        hi_s = max(ua[1 - axis], ub[1 - axis]) + self.spacing
        return any(ax == axis and v == val and lo_s <= w <= hi_s for ax, v, w in self.box_ends)

    def add(self, system, curve_z, curve):
        """Record a traced curve (solution rows ``curve_z`` of ``system``)."""
        self.traced_z.append((system, np.array(curve_z)))
        self.curves.append(curve)
        uv = (curve.points - self.lo) / (self.hi - self.lo)
        self.covered |= _crossed_edges(uv, *self.grid)
        for end in (uv[0], uv[-1]):
            for axis in (0, 1):
                for val in (0.0, 1.0):
                    if abs(end[axis] - val) < 1e-9:
                        self.box_ends.append((axis, val, end[1 - axis]))


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
