"""Neck-stack tracker cost per small command, N = 1, 2, 3, 5, 10 modules.

A command changes one module's actuator length by 1e-3 m (a random module, a
random sign; 50 successive commands from the previous state, as a node would
see them).  Each is timed as ``track_stack(current, moved, state)`` -- path set-up,
tracking, verification and the final record -- and side by side with the naive
baseline a node might otherwise use: ``scipy.optimize.root`` on the KKT residual
at the end point, started from the previous state (path set-up included; fast,
but blind to jumps: it can land on a saddle or another branch silently).

Each command is timed ``REPEAT`` times and the best kept (the machine is
shared; the best of a few is the cost of the code, not of the neighbours);
median and p90 are over the commands.  Target: N = 10 within 5 ms.

    python benchmarks/bench_stack.py
"""
import os
import statistics
import time

import numpy as np
from scipy.optimize import root

from tensegrity_ros.core import ModuleParams
from tensegrity_ros.core.stack import Stack, StackPath, settle_stack, track_stack

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

SIZES = (1, 2, 3, 5, 10)
COMMANDS = 50
REPEAT = int(os.environ.get("BENCH_REPEAT", 3))
STEP = 1e-3           # m, one module's rho per command
TARGET_MS = 5.0       # N = 10


def neck(n, rho=0.75):
    """n paper modules (L1 = L2 = 1 m, k = 100 N/m), upright, a small head load."""
    modules = [ModuleParams.paper(rho) for _ in range(n - 1)]
    return Stack(tuple(modules + [ModuleParams.paper(rho, F3=-1.0, F4=-1.0)]))


def naive(start, end, state):
    path = StackPath(start, end)
    return root(lambda y: path.residual(y, 1.0), state, jac=lambda y: path.jacobian(y, 1.0),
                method='hybr').x


def best_of(fn, repeat):
    best, value = None, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        value = fn()
        dt = time.perf_counter() - t0
        best = dt if best is None else min(best, dt)
    return best * 1e3, value


def run(n, rng):
    stack = neck(n)
    state = settle_stack(stack, np.full((n, 2), 0.72))
    assert state.stable
    tracker_ms, naive_ms, disagree, steps = [], [], 0, []
    for _ in range(COMMANDS):
        i = int(rng.integers(n))
        rho = stack.modules[i].rho
        sign = rng.choice((-1.0, 1.0)) if 0.70 < rho < 0.80 else (1.0 if rho <= 0.70 else -1.0)
        moved = stack.with_module(i, rho=rho + sign * STEP)
        t_track, result = best_of(lambda: track_stack(stack, moved, state), REPEAT)
        t_naive, y = best_of(lambda: naive(stack, moved, state.state), REPEAT)
        assert result.status == 'ok' and result.final.stable and not result.jumps
        if np.max(np.abs(y[:4 * n] - result.final.state[:4 * n])) > 1e-8:
            disagree += 1
        tracker_ms.append(t_track)
        naive_ms.append(t_naive)
        steps.append(result.steps)
        stack, state = moved, result.final
    return tracker_ms, naive_ms, disagree, steps


def main():
    rng = np.random.default_rng(0)
    print(f'small command: one module\'s rho +-{STEP:g} m, {COMMANDS} successive commands per N, '
          f'best of {REPEAT} each; times in ms')
    print(f'{"N":>3}  {"tracker med":>11}  {"p90":>6}  {"naive med":>9}  {"p90":>6}  '
          f'{"ratio":>5}  {"steps":>5}  naive != tracker')
    rows = {}
    for n in SIZES:
        tracker, base, disagree, steps = run(n, rng)
        med_t, med_b = statistics.median(tracker), statistics.median(base)
        rows[n] = (med_t, float(np.percentile(tracker, 90)))
        print(f'{n:>3}  {med_t:>11.2f}  {np.percentile(tracker, 90):>6.2f}  {med_b:>9.2f}  '
              f'{np.percentile(base, 90):>6.2f}  {med_t / med_b:>5.1f}  '
              f'{statistics.median(steps):>5.0f}  {disagree}/{COMMANDS}')
    med, p90 = rows[10]
    verdict = 'met' if p90 <= TARGET_MS else ('met by the median' if med <= TARGET_MS else 'MISSED')
    print(f'target: N = 10 within {TARGET_MS:g} ms per command: {verdict} '
          f'(median {med:.2f} ms, p90 {p90:.2f} ms)')


if __name__ == '__main__':
    main()
