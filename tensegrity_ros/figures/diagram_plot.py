"""The PNG of a bifurcation diagram: theta1 and theta2 against rho, stable branches
solid blue, unstable ones dashed red, folds and branch points marked, and a tracked
path with its jumps over them.
"""
from __future__ import annotations

import numpy as np

from .canvas import new_figure
from .diagram import _wrap
from ..problem import describe


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
    fig = new_figure((7.0, 7.4))
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
