"""Bifurcation diagrams of one module (the paper's figure 8): every equilibrium on a
rho grid, connected into branches, with its folds and branch points.

Every change in the number of equilibria and every change of stability is located by
bisection (to ~1e-9 of the rho range); the equilibria of neighbouring rho values are
connected into branches (minimum-cost assignment on the torus), and each event is
classified: a *fold* where two equilibria meet and vanish, a *branch point* where two
equilibria meet on a third that continues (the symmetric pitchfork C1 of the paper's
fig. 8a), or where a continuing branch changes stability.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from ..core import equilibria, ModuleParams
from ..problem import resolve_fields


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def _torus_sq_dist(a, b):
    """Squared distances between two sets of angle pairs, shape (len(a), len(b))."""
    d = _wrap(a[:, None, :] - b[None, :, :])
    return np.sum(d * d, axis=-1)


@dataclass
class _Sample:
    rho: float
    theta: np.ndarray          # (n, 2)
    lam: np.ndarray            # (n,) smallest Hessian eigenvalue
    stable: np.ndarray         # (n,) bool

    @property
    def n(self):
        return len(self.lam)


@dataclass
class DiagramEvent:
    """A fold or branch point of the equilibrium set, at rho with configuration theta."""

    kind: str                  # 'fold' | 'branch_point'
    rho: float
    theta: np.ndarray


@dataclass
class Branch:
    """One branch: points (rho, theta1, theta2) with the smallest eigenvalue and stability.

    ``stable`` is None for event points (folds, branch points), where the branch
    changes or ends.
    """

    rho: list = field(default_factory=list)
    theta: list = field(default_factory=list)
    lam: list = field(default_factory=list)
    stable: list = field(default_factory=list)
    point: list = field(default_factory=list)     # 'sample' or the event kind

    def add(self, rho, theta, lam, stable, point='sample', front=False):
        i = 0 if front else len(self.rho)
        self.rho.insert(i, float(rho))
        self.theta.insert(i, np.asarray(theta, dtype=float))
        self.lam.insert(i, float(lam))
        self.stable.insert(i, stable)
        self.point.insert(i, point)


@dataclass
class Diagram:
    fixed: dict
    rho_min: float
    rho_max: float
    branches: list
    events: list
    samples: int


class _Solver:
    """Cached ``equilibria`` on rho at fixed other parameters."""

    def __init__(self, fixed):
        self.fields = resolve_fields(fixed)
        self.cache = {}

    def params(self, rho):
        return ModuleParams(**dict(self.fields, rho=float(rho)))

    def __call__(self, rho):
        rho = float(rho)
        s = self.cache.get(rho)
        if s is None:
            result = equilibria(self.params(rho))
            eqs = list(result)
            s = _Sample(rho=rho,
                        theta=np.array([[e.theta1, e.theta2] for e in eqs]).reshape(-1, 2),
                        lam=np.array([e.eigenvalues[0] for e in eqs], dtype=float),
                        stable=np.array([e.stable for e in eqs], dtype=bool))
            self.cache[rho] = s
        return s


def _match(a, b, gate=1.0):
    """Pairs (i, j) matching equilibria of neighbouring samples a -> b."""
    if a.n == 0 or b.n == 0:
        return []
    from scipy.optimize import linear_sum_assignment
    cost = _torus_sq_dist(a.theta, b.theta)
    rows, cols = linear_sum_assignment(cost)
    return [(int(i), int(j)) for i, j in zip(rows, cols) if cost[i, j] <= gate * gate]


def compute_diagram(fixed, rho_min, rho_max, count, rel_tol=1e-9):
    """Every equilibrium on [rho_min, rho_max], connected into branches, with events."""
    solve = _Solver(fixed)
    tol = rel_tol * (rho_max - rho_min)

    def bisect_count(a, b):
        sa, sb = solve(a), solve(b)
        if b - a <= tol:
            return
        m = 0.5 * (a + b)
        sm = solve(m)
        if sm.n != sa.n:
            bisect_count(a, m)
        if sm.n != sb.n:
            bisect_count(m, b)

    grid = np.linspace(rho_min, rho_max, count)
    for r in grid:
        solve(r)
    for a, b in zip(grid[:-1], grid[1:]):
        if solve(a).n != solve(b).n:
            bisect_count(a, b)

    # Stability changes on continuing branches between samples: bisect along the branch.
    for _ in range(2):
        rhos = sorted(solve.cache)
        added = False
        for a, b in zip(rhos[:-1], rhos[1:]):
            if b - a <= tol:
                continue
            sa, sb = solve(a), solve(b)
            for i, j in _match(sa, sb):
                if sa.stable[i] != sb.stable[j]:
                    _bisect_stability(solve, a, sa.theta[i], sa.stable[i], b, sb.theta[j], tol)
                    added = True
        if not added:
            break

    rhos = sorted(solve.cache)
    samples = [solve(r) for r in rhos]
    branches, events = _connect(samples, tol)
    return Diagram(fixed=dict(fixed), rho_min=rho_min, rho_max=rho_max, branches=branches,
                   events=events, samples=len(samples))


def _bisect_stability(solve, a, ta, flag_a, b, tb, tol):
    """Refine where the branch through (a, ta) .. (b, tb) changes stability."""
    while b - a > tol:
        m = 0.5 * (a + b)
        sm = solve(m)
        if sm.n == 0:
            return
        guess = ta + 0.5 * _wrap(tb - ta)
        j = int(np.argmin(_torus_sq_dist(guess[None, :], sm.theta)[0]))
        if sm.stable[j] == flag_a:
            a, ta = m, sm.theta[j]
        else:
            b, tb = m, sm.theta[j]


def _connect(samples, tol):
    """Branches through consecutive samples, and the events between them."""
    branches = []
    events = []
    ids = [np.full(s.n, -1) for s in samples]
    for j in range(samples[0].n):
        ids[0][j] = len(branches)
        branches.append(Branch())
        s = samples[0]
        branches[-1].add(s.rho, s.theta[j], s.lam[j], bool(s.stable[j]))
    for k in range(len(samples) - 1):
        a, b = samples[k], samples[k + 1]
        pairs = _match(a, b)
        for i, j in pairs:
            ids[k + 1][j] = ids[k][i]
            branches[ids[k][i]].add(b.rho, b.theta[j], b.lam[j], bool(b.stable[j]))
        for j in range(b.n):
            if ids[k + 1][j] < 0:
                ids[k + 1][j] = len(branches)
                branches.append(Branch())
                branches[-1].add(b.rho, b.theta[j], b.lam[j], bool(b.stable[j]))
        gap_events = []
        if b.rho - a.rho <= 2.0 * tol:
            gap_events = _classify_gap(a, b, pairs, ids[k], ids[k + 1], branches)
        events.extend(gap_events)
        if not gap_events and b.rho - a.rho <= 2.0 * tol:
            # A continuing branch changes stability without a count change.
            for i, j in pairs:
                if a.stable[i] != b.stable[j]:
                    rho = 0.5 * (a.rho + b.rho)
                    events.append(DiagramEvent('branch_point', rho, b.theta[j].copy()))
    return branches, _distinct(events, 1e3 * tol)


def _distinct(events, rho_tol, theta_tol=1e-3):
    """Events without repeats (a pitchfork's count change and stability change coincide)."""
    kept = []
    for ev in events:
        if not any(abs(ev.rho - k.rho) <= rho_tol
                   and _torus_sq_dist(ev.theta[None], k.theta[None])[0, 0] <= theta_tol ** 2
                   for k in kept):
            kept.append(ev)
    return kept


def _classify_gap(a, b, pairs, ids_a, ids_b, branches):
    """Events in a tiny rho gap where the number of equilibria changes."""
    if a.n == b.n:
        return []
    more, ids_more, matched = (a, ids_a, {i for i, _ in pairs}) if a.n > b.n else \
        (b, ids_b, {j for _, j in pairs})
    ends_here = more is a          # the vanishing branches end at a (else they start at b)
    rho = 0.5 * (a.rho + b.rho)
    lonely = [i for i in range(more.n) if i not in matched]
    survivors = sorted(matched)
    events = []
    while len(lonely) >= 2:
        # The closest pair of vanishing equilibria meet at the event.
        best = None
        for x in range(len(lonely)):
            for y in range(x + 1, len(lonely)):
                d = _torus_sq_dist(more.theta[[lonely[x]]], more.theta[[lonely[y]]])[0, 0]
                if best is None or d < best[0]:
                    best = (d, lonely[x], lonely[y])
        _, u, v = best
        lonely = [i for i in lonely if i not in (u, v)]
        tu, tv = more.theta[u], more.theta[v]
        mid = tu + 0.5 * _wrap(tv - tu)
        sep = math.sqrt(_torus_sq_dist(tu[None], tv[None])[0, 0])
        kind, point = 'fold', mid
        if survivors:
            d = _torus_sq_dist(mid[None], more.theta[survivors])[0]
            s = int(np.argmin(d))
            if math.sqrt(d[s]) < 0.25 * sep + 1e-9:
                kind, point = 'branch_point', more.theta[survivors[s]].copy()
        events.append(DiagramEvent(kind, rho, point))
        for i in (u, v):
            branches[ids_more[i]].add(rho, point, 0.0, None, point=kind, front=not ends_here)
    return events


def write_diagram_csv(diagram, stream):
    """Rows ``branch,rho,theta1,theta2,lambda_min,stable,point`` (point: sample or event kind)."""
    stream.write('branch,rho,theta1,theta2,lambda_min,stable,point\n')
    for b_id, br in enumerate(diagram.branches):
        for rho, th, lam, st, pt in zip(br.rho, br.theta, br.lam, br.stable, br.point):
            stable = '' if st is None else str(int(st))
            stream.write(f'{b_id},{rho:.12g},{th[0]:.12g},{th[1]:.12g},{lam:.8g},{stable},{pt}\n')
