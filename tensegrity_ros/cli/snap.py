"""``tensegrity snap``: the snap-through dynamics of one module from the command line.

    tensegrity snap --rho R0 --to-rho R1 --rate V --damping C --m1 M --m2 M
                    [params] [--theta1 T1 --theta2 T2] [--hold S]
                    [--json] [--csv FILE] [--plot FILE.png]

The module flags and the start equilibrium are the ``track`` command's (the helpers of
:mod:`.common`); this file adds the dynamic options, runs
:func:`~..core.dynamics.simulate_snap` and writes the summary, the history (CSV)
and the plot (matplotlib, Agg, imported only when a plot is asked for).
"""
from __future__ import annotations

import csv
import json
import math

from .common import (add_parameter_options, finite_float, make_params, parameter_values,
                     start_equilibrium, start_guess)
from ..core.dynamics import MAX_HOLD, simulate_snap

HELP = 'simulate the motion of a snap-through (rods with mass, pivot damping)'
DESCRIPTION = (
    'Start at rest in the stable equilibrium of --theta1/--theta2 (as track), drive rho to '
    "--to-rho at --rate, then hold; integrate I theta'' = -dU/dtheta - c theta' "
    '(I = m L^2 / 3, --m1/--m2 required). Reports the onset of the snap, peak speed, peak '
    'actuator force, overshoot, settling time and the rest state, beside the quasi-static '
    'prediction of track.')
CSV_COLUMNS = ('t', 'rho', 'theta1', 'theta2', 'theta1_dot', 'theta2_dot', 'actuator_force')


def add_parser(subparsers):
    """Register ``snap``: the module flags plus the dynamic options."""
    p = subparsers.add_parser('snap', help=HELP, description=DESCRIPTION)
    add_parameter_options(p)
    p.add_argument('--to-rho', dest='to_rho', type=finite_float, metavar='R1', required=True,
                   help='rho at the end of the ramp (m)')
    p.add_argument('--theta1', type=finite_float, metavar='RAD',
                   help='start guess for theta1 (rad); needs --theta2')
    p.add_argument('--theta2', type=finite_float, metavar='RAD',
                   help='start guess for theta2 (rad); needs --theta1')
    p.add_argument('--rate', type=finite_float, metavar='V', required=True,
                   help='actuator speed of the ramp (m/s, > 0)')
    p.add_argument('--damping', type=finite_float, metavar='C', required=True,
                   help='viscous damping at each pivot (N m s/rad, >= 0)')
    p.add_argument('--hold', type=finite_float, metavar='S',
                   help=f'seconds held at --to-rho (default: until settled, at most '
                        f'{MAX_HOLD:g} s)')
    p.add_argument('--json', action='store_true', help='the summary as JSON')
    p.add_argument('--csv', metavar='FILE', help='write the time history as CSV')
    p.add_argument('--plot', metavar='FILE.png',
                   help="write theta, theta' and the actuator force against time as PNG")
    p.set_defaults(func=run)


def run(args, out):
    """``tensegrity snap``: the module and start as ``track`` parses them; exit status 0."""
    start = make_params(parameter_values(args))
    return run_snap(args, out, start, start_equilibrium(start, start_guess(args)).theta)


def run_snap(args, out, start, start_theta):
    """Simulate from ``start`` (ModuleParams) at rest at ``start_theta``; exit status 0."""
    snap = simulate_snap(start, args.to_rho, args.rate, args.damping, start_theta,
                         hold=args.hold)
    if args.csv:
        write_history_csv(snap.history, args.csv)
    if args.plot:
        plot_snap(snap, args.plot)
    if args.json:
        out.write(json.dumps(snap.summary, indent=2) + '\n')
    else:
        out.write(summary_text(snap.summary))
    return 0


def write_history_csv(history, path):
    """One row per sample: CSV_COLUMNS, SI units and radians."""
    with open(path, 'w', newline='') as f:
        writer = csv.writer(f)
        writer.writerow(CSV_COLUMNS)
        for i in range(len(history.t)):
            writer.writerow([repr(float(v)) for v in (
                history.t[i], history.rho[i], *history.theta[i], *history.theta_dot[i],
                history.actuator_force[i])])


def summary_text(s):
    """The summary for people: degrees for angles, the quasi-static prediction beside it."""
    deg = math.degrees
    lines = []
    for jump in s['quasi_static']['jumps']:
        lines.append(f"quasi-static: {jump['kind']} at rho={jump['rho']:.6g} m, lands at "
                     f"({deg(jump['landing']['theta1']):.3f}, "
                     f"{deg(jump['landing']['theta2']):.3f}) deg; static actuator force "
                     f"{jump['actuator_force']:.6g} N")
    if not s['quasi_static']['jumps']:
        lines.append('quasi-static: no jump')
    if s['onset_rho'] is None:
        lines.append("dynamic: no snap (|theta'| stays below 1 rad/s)")
    else:
        lines.append(f"dynamic: snap starts at rho={s['onset_rho']:.6g} m "
                     f"(t={s['onset_time']:.6g} s)")
    lines.append(f"peak speed {s['peak_speed']:.6g} rad/s, peak actuator force "
                 f"{s['peak_actuator_force']:.6g} N, overshoot {deg(s['overshoot']):.4g} deg")
    settle = (f"settled {s['settle_time']:.6g} s after the onset" if s['settled']
              and s['settle_time'] is not None else 'not settled at the end')
    final = s['final']
    lines.append(f"{settle}; final ({deg(final['theta1']):.4f}, {deg(final['theta2']):.4f}) "
                 f"deg, speed {final['speed']:.3g} rad/s")
    if s['lands_elsewhere']:
        lines.append('inertia lands the mechanism in another equilibrium than the '
                     'quasi-static prediction '
                     f"({deg(s['quasi_static']['final']['theta1']):.4f}, "
                     f"{deg(s['quasi_static']['final']['theta2']):.4f}) deg")
    return '\n'.join(lines) + '\n'


def plot_snap(snap, path):
    """theta, theta' and the actuator force against time; the static fold and the onset marked."""
    import matplotlib
    matplotlib.use('Agg', force=False)
    from matplotlib.figure import Figure
    h, s = snap.history, snap.summary
    fig = Figure(figsize=(8, 8), dpi=100, layout='constrained')
    axes = fig.subplots(3, 1, sharex=True)
    panels = ((h.theta, 'theta (rad)'), (h.theta_dot, "theta' (rad/s)"))
    for ax, (values, label) in zip(axes, panels):
        ax.plot(h.t, values[:, 0], label='rod 1')
        ax.plot(h.t, values[:, 1], '--', label='rod 2')
        ax.set_ylabel(label)
    axes[0].legend(loc='best')
    axes[2].plot(h.t, h.actuator_force, color='k')
    axes[2].set_ylabel('actuator force (N)')
    axes[2].set_xlabel('t (s)')
    fold_time = _time_at_rho(h, snap.static_fold_rho)
    for ax in axes:
        if fold_time is not None:
            ax.axvline(fold_time, color='r', lw=0.8, label='static fold')
        if s['onset_time'] is not None:
            ax.axvline(s['onset_time'], color='g', lw=0.8, ls=':', label='onset')
    axes[2].legend(loc='best')
    fig.suptitle(f"rho {h.rho[0]:g} -> {h.rho[-1]:g} m: peak {s['peak_speed']:.3g} rad/s")
    fig.savefig(path, format='png')


def _time_at_rho(history, rho):
    """First sample time at which the ramp reaches ``rho`` (None if never)."""
    if rho is None:
        return None
    lo, hi = history.rho[0], history.rho[-1]
    if not min(lo, hi) <= rho <= max(lo, hi) or lo == hi:
        return None
    fraction = (rho - lo) / (hi - lo)
    reached = [t for t, r in zip(history.t, history.rho) if (r - lo) / (hi - lo) >= fraction]
    return float(reached[0]) if reached else None
