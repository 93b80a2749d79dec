"""Maps and bifurcation diagrams of one module (the paper's figures 3-5, 7, 8).

Computation is numpy-only; matplotlib is imported (Agg, no display) only by the
``plot_*`` functions.  The ``tensegrity map`` and ``tensegrity diagram``
commands are thin wrappers around this module.

Maps count the stable equilibria over a grid of two parameters with the
vectorised exact solver :func:`~tensegrity_ros.core.equilibria_batch`, in chunks,
on several processes for large grids.

Diagrams solve every equilibrium (:func:`~tensegrity_ros.core.equilibria`) on a
rho grid, locate every change in the number of equilibria and every change of
stability by bisection (to ~1e-9 of the rho range), connect the equilibria of
neighbouring rho values into branches (minimum-cost assignment on the torus),
and classify each event: a *fold* where two equilibria meet and vanish, a
*branch point* where two equilibria meet on a third that continues (the
symmetric pitchfork C1 of the paper's fig. 8a), or where a continuing branch
changes stability.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
import os
import time

import numpy as np

from ..core import equilibria, equilibria_batch, ModuleParams, track_module
from ..core.start_state import start_state
from ..problem import describe, resolve_fields

#: Points per chunk of a map (measured: ~20k points minimise the cost per point).
MAP_CHUNK = 20000
#: Maps with at least this many points use several processes (when jobs = 0):
#: ~0.6 s of work, against ~0.05 s to fork the workers.
PARALLEL_THRESHOLD = 50_000
#: Maps with at least this many points show a progress bar (on a terminal).
PROGRESS_THRESHOLD = 100_000

#: Axis labels of map parameters.
AXIS_LABELS = {
    'rho': r'$\rho$ (m)', 'L1': r'$L_1$ (m)', 'L2': r'$L_2$ (m)',
    'k': r'$k = k_a = k_b = k_c$ (N/m)',
    'ka': r'$k_a$ (N/m)', 'kb': r'$k_b$ (N/m)', 'kc': r'$k_c$ (N/m)',
    'F': r'$F = F_3 = F_4$ (N)', 'F3': r'$F_3$ (N)', 'F4': r'$F_4$ (N)',
    'F3x': r'$F_{3x}$ (N)', 'F4x': r'$F_{4x}$ (N)', 'm1': r'$m_1$ (kg)', 'm2': r'$m_2$ (kg)',
}
#: Colours of 0, 1, 2 (, 3...) stable equilibria: the paper's blue (1) and red (2).
COUNT_COLOURS = ('#9e9e9e', '#3567c8', '#d7301f', '#2ca02c', '#ff7f0e', '#9467bd', '#8c564b')
COUNT_LABELS = ('0 (degenerate)', '1 stable', '2 stable', '3 stable', '4 stable', '5 stable',
                '6 stable')


# ---------------------------------------------------------------------------
# Maps

@dataclass
class MapResult:
    """Number of stable equilibria on a grid; ``num_stable[iy, ix]``."""

    fixed: dict
    xname: str
    xs: np.ndarray
    yname: str
    ys: np.ndarray
    num_stable: np.ndarray
    seconds: float = 0.0
    jobs: int = 1

    def histogram(self):
        values, counts = np.unique(self.num_stable, return_counts=True)
        return {int(v): int(c) for v, c in zip(values, counts)}


def _map_chunk(task):
    """Worker: number of stable equilibria at flat grid indices [start, stop)."""
    fixed, xname, xs, yname, ys, start, stop = task
    iy, ix = np.divmod(np.arange(start, stop), xs.size)
    values = dict(fixed)
    values[xname] = xs[ix]
    values[yname] = ys[iy]
    batch = equilibria_batch(**resolve_fields(values))
    return start, batch.num_stable.astype(np.uint8)


def _usable_cores():
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:           # not Linux
        return os.cpu_count() or 1


def compute_map(fixed, xaxis, yaxis, jobs=0, progress=True, chunk=MAP_CHUNK):
    """Count stable equilibria over ``linspace(MIN, MAX, COUNT)`` of two parameters.

    ``fixed`` holds CLI-named fixed values; the axes are ``(name, min, max, count)``.
    ``jobs`` = 0 picks all usable cores when the map has at least
    ``PARALLEL_THRESHOLD`` points, else 1.
    """
    xname, xlo, xhi, nx = xaxis
    yname, ylo, yhi, ny = yaxis
    xs = np.linspace(xlo, xhi, nx)
    ys = np.linspace(ylo, yhi, ny)
    total = nx * ny
    if jobs <= 0:
        jobs = min(_usable_cores(), 8) if total >= PARALLEL_THRESHOLD else 1
    jobs = max(1, min(jobs, math.ceil(total / chunk)))
    tasks = [(fixed, xname, xs, yname, ys, s, min(s + chunk, total))
             for s in range(0, total, chunk)]
    out = np.empty(total, dtype=np.uint8)
    t0 = time.perf_counter()
    bar = None
    pool = None
    try:
        if jobs > 1:
            import concurrent.futures as cf
            import multiprocessing as mp
            try:
                context = mp.get_context('fork')        # cheap start, Linux
            except ValueError:
                context = None
            pool = cf.ProcessPoolExecutor(max_workers=jobs, mp_context=context)
            futures = [pool.submit(_map_chunk, t) for t in tasks]   # forks here
            results = (f.result() for f in cf.as_completed(futures))
        else:
            results = map(_map_chunk, tasks)
        bar = _progress_bar(total, progress)
        for start, counts in results:
            out[start:start + counts.size] = counts
            if bar is not None:
                bar.update(counts.size)
    finally:
        if bar is not None:
            bar.close()
        if pool is not None:
            pool.shutdown(cancel_futures=True)
    seconds = time.perf_counter() - t0
    return MapResult(fixed=dict(fixed), xname=xname, xs=xs, yname=yname, ys=ys,
                     num_stable=out.reshape(ny, nx), seconds=seconds, jobs=jobs)


def _progress_bar(total, progress):
    if not progress or total < PROGRESS_THRESHOLD:
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    tqdm.monitor_interval = 0        # no monitor thread
    # disable=None: no bar when stderr is not a terminal (logs, tests).
    return tqdm(total=total, unit='pt', unit_scale=True, disable=None, leave=False,
                desc='map')


def write_map_csv(result, stream):
    """Header ``x,y,num_stable`` then one row per point (x varies fastest)."""
    stream.write(f'{result.xname},{result.yname},num_stable\n')
    ny, nx = result.num_stable.shape
    xs = np.char.mod('%.12g', result.xs)
    for iy in range(ny):
        prefix = ',%.12g,' % result.ys[iy]
        row = result.num_stable[iy]
        stream.write('\n'.join(x + prefix + str(int(c)) for x, c in zip(xs, row.tolist())))
        stream.write('\n')


def read_map_csv(path):
    """(header, array of rows) of a map CSV written by :func:`write_map_csv`."""
    with open(path, encoding='ascii') as f:
        header = f.readline().strip().split(',')
    data = np.loadtxt(path, delimiter=',', skiprows=1, ndmin=2)
    return header, data


# --- exact boundaries over a map ------------------------------------------------

#: CLI axis names that the exact curves support, and the analysis axis each one is.
#: (Mass axes are not affine in the raw parameters the curves are traced in.)
BOUNDARY_AXES = {'rho': 'rho', 'L1': 'L1', 'L2': 'L2', 'k': 'k', 'ka': 'ka', 'kb': 'kb',
                 'kc': 'kc', 'F': 'F', 'F3': 'F3', 'F4': 'F4', 'F3x': 'f3x', 'F4x': 'f4x'}
#: Styles of the overlay: where the stable count changes, and elsewhere.
#: Continuation step along the curves (arclength in the box scaled to the unit square):
#: at least 200 points per box side, smooth at figure resolution (~0.2-0.7 s per map).
BOUNDARY_STEP = 0.005
BOUNDARY_STYLE = {'color': 'k', 'linestyle': '-', 'linewidth': 1.6}
OTHER_CURVE_STYLE = {'color': '#7a7a7a', 'linestyle': (0, (4, 3)), 'linewidth': 0.8}


@dataclass
class Boundaries:
    """Curves of degenerate equilibria over a map box (``degenerate_curves``)."""

    xname: str
    yname: str
    box: tuple                 # ((xmin, xmax), (ymin, ymax))
    curves: list
    seconds: float = 0.0

    @property
    def points(self):
        return sum(len(c) for c in self.curves)

    def summary(self):
        kinds = {}
        for c in self.curves:
            kinds[c.kind] = kinds.get(c.kind, 0) + 1
        text = ', '.join(f'{n} {k}' for k, n in sorted(kinds.items())) or 'none'
        stable = sum(c.changes_stable_count for c in self.curves)
        n = len(self.curves)
        return (f'boundaries: {n} curve{"" if n == 1 else "s"} ({text}; {stable} change'
                f'{"s" if stable == 1 else ""} the stable count), {self.points} points traced '
                f'by continuation; {self.seconds:.2f} s')


def compute_boundaries(fixed, xaxis, yaxis):
    """Exact curves where an equilibrium is degenerate (G = 0, det H = 0) over a map box.

    ``fixed`` and the axes as for :func:`compute_map` (only the names and ranges of
    the axes are used: the curves are traced by continuation, not sampled).
    """
    from ..core.analysis import degenerate_curves
    xname, xlo, xhi, _ = xaxis
    yname, ylo, yhi, _ = yaxis
    for name in (xname, yname):
        if name not in BOUNDARY_AXES:
            raise ValueError(f'{name} is not an axis of degenerate_curves')
    values = dict(fixed)
    values[xname], values[yname] = xhi, yhi          # replaced along the axes anyway
    base = ModuleParams(**resolve_fields(values))
    t0 = time.perf_counter()
    curves = degenerate_curves(base, BOUNDARY_AXES[xname], (xlo, xhi),
                               BOUNDARY_AXES[yname], (ylo, yhi),
                               step=BOUNDARY_STEP, max_step=BOUNDARY_STEP)
    return Boundaries(xname=xname, yname=yname, box=((xlo, xhi), (ylo, yhi)), curves=curves,
                      seconds=time.perf_counter() - t0)


def write_boundaries_csv(boundaries, stream):
    """Header ``curve,x,y,stable_boundary,kind``, one row per traced point (curves in order)."""
    stream.write('curve,x,y,stable_boundary,kind\n')
    for i, c in enumerate(boundaries.curves):
        for (x, y), flag in zip(c.points, c.stable_boundary):
            stream.write(f'{i},{x:.12g},{y:.12g},{int(bool(flag))},{c.kind}\n')


def _flag_runs(flags):
    """Maximal runs [(flag, start, stop)] of a boolean sequence; neighbouring runs share
    their boundary point so that the drawn curve has no gaps."""
    runs = []
    start = 0
    for i in range(1, len(flags) + 1):
        if i == len(flags) or flags[i] != flags[start]:
            runs.append((bool(flags[start]), start, min(i + 1, len(flags))))
            start = i
    return runs


def draw_boundaries(ax, curves):
    """Overlay the curves: solid black where the stable count changes, thin grey dashed
    elsewhere; returns the legend handles of the styles drawn."""
    from matplotlib.lines import Line2D
    used = set()
    for c in curves:
        pts = np.asarray(c.points)
        if c.closed and len(pts) > 2:
            pts = np.vstack([pts, pts[:1]])
            flags = np.append(c.stable_boundary, c.stable_boundary[:1])
        else:
            flags = np.asarray(c.stable_boundary)
        for flag, a, b in _flag_runs(flags):
            style = BOUNDARY_STYLE if flag else OTHER_CURVE_STYLE
            ax.plot(pts[a:b, 0], pts[a:b, 1], zorder=4, solid_capstyle='round', **style)
            used.add(flag)
    handles = []
    if True in used:
        handles.append(Line2D([], [], **BOUNDARY_STYLE, label='stable count changes (exact)'))
    if False in used:
        handles.append(Line2D([], [], **OTHER_CURVE_STYLE, label='only unstable ones degenerate'))
    return handles


def _edges(values):
    """Cell edges around sample values (for images)."""
    if values.size == 1:
        return values[0] - 0.5, values[0] + 0.5
    half = 0.5 * (values[1] - values[0])
    return values[0] - half, values[-1] + half


def _new_figure(size):
    import matplotlib
    matplotlib.use('Agg', force=False)
    from matplotlib.figure import Figure
    return Figure(figsize=size, dpi=100, layout='constrained')


def plot_map(result, path, title=None, curves=None):
    """Write a PNG of the map: discrete colours for 0 / 1 / 2 stable equilibria.

    ``curves``: :class:`~.core.analysis.Curve` list (e.g. ``compute_boundaries(...).curves``)
    drawn over the map with :func:`draw_boundaries`.
    """
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.patches import Patch
    fig = _new_figure((6.4, 5.2))
    ax = fig.add_subplot()
    top = max(2, int(result.num_stable.max()))
    cmap = ListedColormap(COUNT_COLOURS[:top + 1])
    norm = BoundaryNorm(np.arange(-0.5, top + 1.5), cmap.N)
    x0, x1 = _edges(result.xs)
    y0, y1 = _edges(result.ys)
    ax.imshow(result.num_stable, origin='lower', extent=(x0, x1, y0, y1), aspect='auto',
              interpolation='nearest', cmap=cmap, norm=norm)
    present = result.histogram()
    handles = [Patch(facecolor=COUNT_COLOURS[n], edgecolor='k', linewidth=0.5,
                     label=COUNT_LABELS[n] if n < len(COUNT_LABELS) else f'{n} stable')
               for n in range(top + 1) if n in present or n in (1, 2)]
    if curves is not None:
        handles += draw_boundaries(ax, curves)
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
    ax.legend(handles=handles, loc='upper right', fontsize=8, framealpha=0.9)
    ax.set_xlabel(AXIS_LABELS.get(result.xname, result.xname))
    ax.set_ylabel(AXIS_LABELS.get(result.yname, result.yname))
    fixed = describe(result.fixed, skip=(result.xname, result.yname))
    ax.set_title(title or f'Number of stable equilibria\n{fixed}', fontsize=10)
    fig.savefig(path, format='png')


# ---------------------------------------------------------------------------
# Bifurcation diagrams

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


# --- tracked path overlay --------------------------------------------------

@dataclass
class TrackLeg:
    rho0: float
    rho1: float
    jumps: tuple
    status: str
    message: str


@dataclass
class TrackedPath:
    """Continuous pieces (rho, theta) of the quasi-static path and its jumps."""

    pieces: list               # list of (rhos (m,), thetas (m, 2))
    jumps: list                # list of (rho, from_theta, to_theta, kind)
    legs: list


def track_path(fixed, rhos, guess, diagram=None):
    """Follow the stable equilibrium through the rho values (``track_module`` per leg),
    from the start state :func:`start_state` settles ``guess`` into (None: the upper one).

    Jumps come from the tracker; between them the path is drawn through the
    stable equilibria nearest to the previous point (at most half the diagram's
    step apart in rho), which is the branch the tracker followed.
    """
    solve = _Solver(fixed)
    step = 0.0025
    if diagram is not None:
        step = 0.5 * (diagram.rho_max - diagram.rho_min) / max(diagram.samples, 2)
    first = start_state([solve.params(rhos[0])], None if guess is None else [guess])
    theta = first.theta
    pieces, jumps, legs = [], [], []
    for r0, r1 in zip(rhos[:-1], rhos[1:]):
        track = track_module(solve.params(r0), solve.params(r1), theta)
        legs.append(TrackLeg(r0, r1, tuple(track.jumps), track.status, track.message))
        rho_a, cur = r0, theta
        for jump in track.jumps:
            pieces.append(_follow(solve, rho_a, jump.params.rho, cur, jump.from_theta, step))
            jumps.append((jump.params.rho, np.asarray(jump.from_theta, float),
                          np.asarray(jump.to_theta, float), jump.kind))
            rho_a, cur = jump.params.rho, np.asarray(jump.to_theta, float)
        r_end = track.end.rho
        pieces.append(_follow(solve, rho_a, r_end, cur, track.final.theta, step))
        theta = track.final.theta
        if track.status != 'ok':
            break
    return TrackedPath(pieces=pieces, jumps=jumps, legs=legs)


def _follow(solve, rho_a, rho_b, theta_a, theta_b, step):
    m = max(2, int(math.ceil(abs(rho_b - rho_a) / step)) + 1)
    rs = np.linspace(rho_a, rho_b, m)
    out = [np.asarray(theta_a, float)]
    for r in rs[1:-1]:
        s = solve(r)
        cand = s.theta[s.stable] if s.stable.any() else s.theta
        if len(cand) == 0:
            out.append(out[-1])
            continue
        d = _torus_sq_dist(out[-1][None], cand)[0]
        out.append(cand[int(np.argmin(d))])
    out.append(np.asarray(theta_b, float))
    return rs, np.array(out)


# --- drawing ------------------------------------------------------------------

def _continuous(values):
    """Unwrapped angle sequence, shifted so that its first value is in [-pi, pi)."""
    u = np.unwrap(np.asarray(values, dtype=float))
    return u - 2.0 * np.pi * np.round((u[0] - _wrap(u[0])) / (2.0 * np.pi))


def _draw_periodic(ax, x, y, **kw):
    """Plot y(x) and its copies shifted by +-2 pi (the axis clips to one period)."""
    line = None
    for shift in (0.0, -2.0 * np.pi, 2.0 * np.pi):
        if line is not None:
            kw.pop('label', None)
        line = ax.plot(x, y + shift, **kw)[0]
    return line


STABLE_STYLE = {'color': '#1f4fbf', 'linestyle': '-', 'linewidth': 2.0}
UNSTABLE_STYLE = {'color': '#d62728', 'linestyle': '--', 'linewidth': 1.2}


def _styled_runs(branch):
    """Runs of consecutive points drawn with one style: [(stable, indices)]."""
    n = len(branch.rho)
    runs = []
    for k in range(n - 1):
        s0, s1 = branch.stable[k], branch.stable[k + 1]
        flag = s0 if s1 is None else s1 if s0 is None else (s0 and s1)
        if flag is None:
            flag = False
        if runs and runs[-1][0] == flag and runs[-1][1][-1] == k:
            runs[-1][1].append(k + 1)
        else:
            runs.append((flag, [k, k + 1]))
    if n == 1:
        runs.append((bool(branch.stable[0]), [0]))
    return runs


def plot_diagram(diagram, path, tracked=None, title=None):
    """Two panels (theta1, theta2 against rho); stable solid blue, unstable dashed red."""
    from matplotlib.lines import Line2D
    fig = _new_figure((7.0, 7.4))
    axes = fig.subplots(2, 1, sharex=True)
    ticks = [-np.pi, -np.pi / 2, 0.0, np.pi / 2, np.pi]
    tick_labels = [r'$-\pi$', r'$-\pi/2$', '0', r'$\pi/2$', r'$\pi$']
    for c, ax in enumerate(axes):
        for br in diagram.branches:
            rho = np.array(br.rho)
            ang = _continuous([t[c] for t in br.theta])
            for flag, idx in _styled_runs(br):
                style = STABLE_STYLE if flag else UNSTABLE_STYLE
                _draw_periodic(ax, rho[idx], ang[idx], **style)
        for ev in diagram.events:
            marker = 'o' if ev.kind == 'fold' else 'D'
            y = float(_wrap(ev.theta[c]))
            ys = [y, y + 2.0 * np.pi] if y < -np.pi + 0.05 else [y]     # -pi is also +pi
            ax.plot([ev.rho] * len(ys), ys, marker=marker, markersize=7,
                    markerfacecolor='white' if ev.kind == 'fold' else '#ffd000',
                    markeredgecolor='k', zorder=5, linestyle='none', clip_on=False)
        if tracked is not None:
            _draw_track(ax, tracked, c)
        ax.set_ylim(-np.pi - 0.08, np.pi + 0.08)
        ax.set_xlim(diagram.rho_min, diagram.rho_max)
        ax.set_yticks(ticks, tick_labels)
        ax.set_ylabel(rf'$\theta_{c + 1}$ (rad)')
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel(r'$\rho$ (m)')
    handles = [Line2D([], [], **STABLE_STYLE, label='stable'),
               Line2D([], [], **UNSTABLE_STYLE, label='unstable')]
    kinds = {ev.kind for ev in diagram.events}
    if 'fold' in kinds:
        handles.append(Line2D([], [], marker='o', markerfacecolor='white', markeredgecolor='k',
                              linestyle='none', label='fold'))
    if 'branch_point' in kinds:
        handles.append(Line2D([], [], marker='D', markerfacecolor='#ffd000',
                              markeredgecolor='k', linestyle='none', label='branch point'))
    if tracked is not None:
        handles += [Line2D([], [], color='#2ca02c', linewidth=3.5, alpha=0.6,
                           label='tracked path'),
                    Line2D([], [], color='k', marker=r'$\uparrow$', linestyle='none',
                           markersize=10, label='jump')]
    axes[0].legend(handles=handles, loc='upper right', fontsize=8, ncol=3, framealpha=0.9)
    axes[0].set_title(title or f'Equilibria against rho: {describe(diagram.fixed)}', fontsize=10)
    fig.savefig(path, format='png')


def _draw_track(ax, tracked, c):
    for rs, th in tracked.pieces:
        ang = _continuous(th[:, c])
        _draw_periodic(ax, rs, ang, color='#2ca02c', linewidth=3.5, alpha=0.6, zorder=3,
                       solid_capstyle='round')
        if len(rs) >= 3 and abs(rs[-1] - rs[0]) > 1e-9:
            k = len(rs) // 2
            y0, y1 = _wrap(ang[k - 1]), _wrap(ang[k - 1]) + (ang[k] - ang[k - 1])
            ax.annotate('', xy=(rs[k], y1), xytext=(rs[k - 1], y0), zorder=4,
                        arrowprops={'arrowstyle': '-|>', 'color': '#1a7a1a', 'lw': 1.5,
                                    'mutation_scale': 16})
    for rho, t_from, t_to, kind in tracked.jumps:
        y0, y1 = _wrap(t_from[c]), _wrap(t_to[c])
        ax.annotate('', xy=(rho, y1), xytext=(rho, y0), zorder=6,
                    arrowprops={'arrowstyle': '-|>', 'color': 'k', 'lw': 1.6, 'mutation_scale': 14,
                                'shrinkA': 0, 'shrinkB': 0})
