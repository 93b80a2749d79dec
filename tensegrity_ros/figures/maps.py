"""Maps: the number of stable equilibria over a grid of two parameters (the paper's
figures 3, 4, 7), computed with the vectorised exact solver
:func:`~tensegrity_ros.core.equilibria_batch` in chunks, on several processes for large
grids; written as CSV, drawn as PNG (with the exact boundaries of :mod:`.boundaries`
over it, if asked).
"""
from __future__ import annotations

from dataclasses import dataclass
import math
import os
import time

import numpy as np

from .boundaries import draw_boundaries
from .canvas import new_figure
from ..core import equilibria_batch
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


def _edges(values):
    """Cell edges around sample values (for images)."""
    if values.size == 1:
        return values[0] - 0.5, values[0] + 0.5
    half = 0.5 * (values[1] - values[0])
    return values[0] - half, values[-1] + half


def plot_map(result, path, title=None, curves=None):
    """Write a PNG of the map: discrete colours for 0 / 1 / 2 stable equilibria.

    ``curves``: :class:`~.core.analysis.Curve` list (e.g. ``compute_boundaries(...).curves``)
    drawn over the map with :func:`draw_boundaries`.
    """
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.patches import Patch
    fig = new_figure((6.4, 5.2))
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
