"""Neck-stack tracker cost per small command, N = 1, 2, 3, 5, 10 modules, beside baselines.

A command changes one module's actuator length by 1e-3 m (a random module, a
random sign; 50 successive commands from the previous state, as a node would
see them).  Each is timed as ``track_stack(current, moved, state)`` -- path set-up,
tracking, verification and the final record -- and side by side, on the same
command, with:

* naive: ``scipy.optimize.root`` on the KKT residual at the end point, started from
  the previous state (path set-up included; blind to jumps: it can land on a saddle
  or another branch silently);
* before: the node-coordinate formulation the stack used before (7N - 1 unknowns,
  test/stack_cartesian_reference.py) on the generic tracker;
* module (N = 1 only): the single-module tracker ``track_module`` on the same move.

Then the floor of a verified small step for N = 3 (``floor``): the parts any
verified step needs, each timed alone in a tight loop (so cheaper than in the
step, where the caches are colder), summed, beside the naive root and the whole
step timed the same way.

Each command is timed ``REPEAT`` times (env BENCH_REPEAT, default 3) and the best
kept (the machine is shared; the best of a few is the cost of the code, not of the
neighbours); medians and p90 are over the commands.  BENCH_CLOCK=cpu times with this
thread's CPU clock instead of the wall clock (on a loaded machine the wall clock also
counts the time spent waiting for a CPU; both columns of a run use the same clock).  Targets
(issue 14): N = 3 at most 0.15 ms and faster than naive; N = 10 at most 0.5 ms; N = 1 within
1.5x of the module tracker.

    python benchmarks/bench_stack.py
"""
import math
import os
from pathlib import Path
import statistics
import sys
import time

import numpy as np
from scipy.optimize import root

from tensegrity_ros.core import continuation, ModuleParams, track_module
from tensegrity_ros.core.neck.fast_step import _dgesv, _dgetrf, _start_point
from tensegrity_ros.core.neck.stack import _end_record, settle_stack, Stack, StackPath, track_stack

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))
# the "before"; I100: it cannot sort with the imports above, it needs test/ on sys.path first
from stack_cartesian_reference import CartesianStackPath  # noqa: E402, I100

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

SIZES = (1, 2, 3, 5, 10)
COMMANDS = 50
REPEAT = int(os.environ.get('BENCH_REPEAT', 3))
CLOCK = time.thread_time if os.environ.get('BENCH_CLOCK') == 'cpu' else time.perf_counter
STEP = 1e-3           # m, one module's rho per command
TARGETS_MS = {3: 0.15, 10: 0.5}
MODULE_RATIO = 1.5    # N = 1 against the single-module tracker


def neck(n, rho=0.75):
    """n paper modules (L1 = L2 = 1 m, k = 100 N/m), upright, a small head load."""
    modules = [ModuleParams.paper(rho) for _ in range(n - 1)]
    return Stack(tuple(modules + [ModuleParams.paper(rho, F3=-1.0, F4=-1.0)]))


def naive(start, end, state):
    path = StackPath(start, end)
    return root(lambda y: path.residual(y, 1.0), state, jac=lambda y: path.jacobian(y, 1.0),
                method='hybr').x


def before(start, end, theta):
    """The node-coordinate formulation on the generic tracker (its state from angles is
    set up outside the timing: a node would keep it between commands)."""
    path = CartesianStackPath(start, end)
    y = path.state_from_angles(theta, 0.0)
    return lambda: continuation.track(CartesianStackPath(start, end), y)


def best_of(fn, repeat):
    best, value = None, None
    for _ in range(repeat):
        t0 = CLOCK()
        value = fn()
        dt = CLOCK() - t0
        best = dt if best is None else min(best, dt)
    return best * 1e3, value


def run(n, rng):
    stack = neck(n)
    state = settle_stack(stack, np.full((n, 2), 0.72))
    assert state.stable
    times = {'tracker': [], 'naive': [], 'before': [], 'module': []}
    disagree, steps = 0, []
    for _ in range(COMMANDS):
        i = int(rng.integers(n))
        rho = stack.modules[i].rho
        sign = rng.choice((-1.0, 1.0)) if 0.70 < rho < 0.80 else (1.0 if rho <= 0.70 else -1.0)
        moved = stack.with_module(i, rho=rho + sign * STEP)
        t_track, result = best_of(lambda: track_stack(stack, moved, state), REPEAT)
        t_naive, y = best_of(lambda: naive(stack, moved, state.state), REPEAT)
        t_before, old = best_of(before(stack, moved, state.theta), REPEAT)
        assert result.status == 'ok' and result.final.stable and not result.jumps
        assert old.status == 'ok' and not old.events
        if np.max(np.abs(y[:2 * n] - result.final.state[:2 * n])) > 1e-8:
            disagree += 1
        if n == 1:
            t_module, _ = best_of(lambda: track_module(stack.modules[0], moved.modules[0],
                                                       state.theta[0]), REPEAT)
            times['module'].append(t_module)
        times['tracker'].append(t_track)
        times['naive'].append(t_naive)
        times['before'].append(t_before)
        steps.append(result.steps)
        stack, state = moved, result.final
    return times, disagree, steps


def tight(fn, number=400, rounds=15):
    """Best per-call time (us) of ``fn`` over ``rounds`` loops of ``number`` calls."""
    best = math.inf
    for _ in range(rounds):
        t0 = CLOCK()
        for _ in range(number):
            fn()
        best = min(best, (CLOCK() - t0) / number)
    return best * 1e6


def floor(n=3):
    """The parts every verified small step needs, timed alone, against the naive root."""
    stack = neck(n)
    state = settle_stack(stack, np.full((n, 2), 0.72))
    first = stack.with_module(0, rho=0.751)        # (the same Stack object as the next start:
    state = track_stack(stack, first, state).final  # its kept evaluation is reused, as in a
    stack = first                                   # stream of commands)
    moved = stack.with_module(n - 1, rho=0.752)
    path = StackPath(stack, moved)
    y, y1 = state.state, track_stack(stack, moved, state).final.state
    start, _ = _start_point(path, y, state)

    def fresh():
        return path.evaluate(y1, 1.0)
    point = tight(fresh)

    def unrated():                  # the start as a command finds it: its s-rates not made
        start.rates = None
        return start

    parts = {
        'path set-up': tight(lambda: StackPath(stack, moved)),
        'tangent (J, dF/ds, solve)': tight(lambda: _dgesv(path.jacobian_at(start),
                                                          path.residual_s_at(unrated()))),
        '2 iterates (evaluate, residual)': 2 * tight(lambda: path.residual_at(fresh())),
        'Jacobian + LU': tight(lambda: _dgetrf(path.prediction_jacobian_at(fresh()))) - point,
        'reduced eigenproblem': tight(lambda: path.eigenvalues_at(fresh())) - point,
        'energy check (E, dE/ds x 2)': tight(lambda: (path.energy_at(fresh()), path.energy_s_at(
            fresh()), path.energy_s_at(unrated()))) - 2 * point,
        'record': tight(lambda: _end_record(path, y1, state.eigenvalues, 0.0, 0.0, start)),
    }
    total = sum(parts.values())
    step = tight(lambda: track_stack(stack, moved, state))
    root_time = tight(lambda: naive(stack, moved, y))
    print(f'floor N = {n} (parts timed alone, us): ' + ', '.join(
        f'{k} {v:.1f}' for k, v in parts.items()))
    print(f'  sum {total:.1f} us; whole verified step {step:.1f} us; '
          f'naive root {root_time:.1f} us; '
          f'floor/naive {total / root_time:.2f}, step/naive {step / root_time:.2f}')


def main():
    rng = np.random.default_rng(0)
    load = os.getloadavg()[0]
    clock = 'thread CPU time' if CLOCK is time.thread_time else 'wall clock'
    print(f"small command: one module's rho +-{STEP:g} m, {COMMANDS} successive commands per N, "
          f'best of {REPEAT} each ({clock}); median (p90) in ms; {os.cpu_count()} CPUs, '
          f'load {load:.1f}')
    print(f'{"N":>3}  {"tracker":>13}  {"naive":>13}  {"before":>13}  {"naive/trk":>9}  '
          f'{"before/trk":>10}  {"steps":>5}  naive != tracker')
    medians = {}
    for n in SIZES:
        times, disagree, steps = run(n, rng)
        med = {k: statistics.median(v) for k, v in times.items() if v}
        p90 = {k: float(np.percentile(v, 90)) for k, v in times.items() if v}
        medians[n] = med

        def cell(k):
            return f'{med[k]:6.3f} ({p90[k]:5.2f})'
        print(f'{n:>3}  {cell("tracker")}  {cell("naive")}  {cell("before")}  '
              f'{med["naive"] / med["tracker"]:>9.2f}  {med["before"] / med["tracker"]:>10.1f}  '
              f'{statistics.median(steps):>5.0f}  {disagree}/{COMMANDS}')
        if n == 1:
            print(f'     single-module tracker on the same commands: {cell("module")}, '
                  f'stack/module {med["tracker"] / med["module"]:.2f} '
                  f'(target <= {MODULE_RATIO:g})')
    for n, target in TARGETS_MS.items():
        med = medians[n]
        verdict = 'met' if med['tracker'] <= target else 'MISSED'
        print(f'target N = {n}: median {med["tracker"]:.3f} ms <= {target:g} ms: {verdict}'
              + (f'; faster than naive: {"yes" if med["tracker"] < med["naive"] else "NO"}'
                 if n == 3 else ''))
    ratio = medians[1]['tracker'] / medians[1]['module']
    print(f'target N = 1: within {MODULE_RATIO:g}x of the module tracker: '
          f'{"met" if ratio <= MODULE_RATIO else "MISSED"} ({ratio:.2f}x)')
    floor()


if __name__ == '__main__':
    main()
