"""Worst single simulator call on hard in-range inputs (issue 10: bounded work per command).

Every case builds a :class:`~tensegrity_ros.core.simulation.simulator.Simulator` (not timed) and
sends one or a few hard commands: rho jumps across folds and branch points, forces at
the largest supported load (load/(k L) = 1e4), head-load ramps on necks of 3 and 10
paper modules (one with m0 ka = 100.0000001, which buckles near-continuously),
parameter changes next to the branch point C1, and resets of loaded necks (a settle).
Each command is followed by ``advance`` calls (10 ms of simulated time apart) while
motion is pending, as the node's timer would make them.  Every call is timed; the table shows per
case the worst single call and the sum, for

* unbounded: ``time_budget=None``, every command tracked to its end in one call
  (what the simulator did before issue 10's bounded work);
* bounded: the default ``DEFAULT_TIME_BUDGET`` (a command that runs out of time goes
  on in the following calls),

side by side in the same process, with the ratio of the worst calls, and checks that
both end in the same state with the same number of jumps.  Wall times on a shared
machine are noisy: compare the ratio, not the absolute figures.

    python benchmarks/bench_worst_case.py [--only SUBSTRING]
"""
import argparse
import inspect
import time

import numpy as np

from tensegrity_ros.core import ModuleParams
from tensegrity_ros.core.simulation import simulator as simulator_module
from tensegrity_ros.core.simulation.simulator import ModuleLimits, Simulator

TICK_NS = 10_000_000            # simulated time between calls (a 100 Hz timer)
MAX_CALLS = 100_000             # a case that needs more is reported as not finished
MAX_LOAD = 1e4 * 100.0 * 1.0    # the supported load/(k L) at k = 100 N/m, L = 1 m
BOUNDED = 'time_budget' in inspect.signature(Simulator).parameters


def module(rho, F3=0.0, F4=0.0, **changes):
    return ModuleParams.paper(rho, F3=F3, F4=F4).with_(**changes)


def neck(n, rho=0.75, **first):
    """n paper modules, upright; ``first`` changes module 0 (e.g. ka=100.0000001)."""
    modules = [ModuleParams.paper(rho) for _ in range(n)]
    modules[0] = modules[0].with_(**first)
    return modules, None


def one(rho, theta, **changes):
    return [module(rho, **changes)], [theta]


def rho_to(index, rho):
    return lambda sim, now: sim.command_rho(index, rho, now)


def rhos_to(targets):
    return lambda sim, now: sim.command_rhos(targets, now)


def force(index, node, value):
    return lambda sim, now: sim.set_force(index, node, value, now)


def params(index, **fields):
    return lambda sim, now: sim.set_parameters({index: fields}, now, 'parameters')


def head_load(n, total):
    """Half of ``total`` (N, vertical) at each node of the top chord, in one change."""
    return params(n - 1, f3y=0.5 * total, f4y=0.5 * total)


def reset_with_head_load(n, total):
    """Start over with half of ``total`` (N) at each node of the top chord (a settle)."""
    modules = [ModuleParams.paper(0.75) for _ in range(n - 1)]
    modules.append(ModuleParams.paper(0.75, F3=0.5 * total, F4=0.5 * total))
    return lambda sim, now: sim.reset(modules, None)


WIDE = [ModuleLimits(rho_min=0.01, rho_max=3.0)]

#: name -> (modules, initial theta or None, limits per module or None, commands)
CASES = {
    'N1 F 5.001/5 lower branch rho 0.5 -> 0.1 (past C1)':
        (*one(0.5, [-1.0, -1.0], F3=5.001, F4=5.0), WIDE, [rho_to(0, 0.1)]),
    'N1 F 5/5 lower branch rho 0.5 -> 0.9 (past C2)':
        (*one(0.5, [-1.0, -1.0], F3=5.0, F4=5.0), WIDE, [rho_to(0, 0.9)]),
    'N1 unloaded rho 0.1 -> 1.9 -> 0.1':
        (*one(0.1, [1.5, 1.5]), WIDE, [rho_to(0, 1.9), rho_to(0, 0.1)]),
    'N1 force_a3 (0, -max load) and back to 0':
        (*one(0.75, [1.0, 1.0]), WIDE, [force(0, 'a3', (0.0, -MAX_LOAD)),
                                        force(0, 'a3', (0.0, 0.0))]),
    'N1 force_a3 (max load, 0) then (0, +max load)':
        (*one(0.75, [1.0, 1.0]), WIDE, [force(0, 'a3', (MAX_LOAD, 0.0)),
                                        force(0, 'a3', (0.0, MAX_LOAD))]),
    'N1 F 5/5 at rho 0.1556 lower: ka 100 -> 100.01 -> 99.99 -> 100.0000001':
        (*one(0.1556, [-1.4, -1.4], F3=5.0, F4=5.0), WIDE,
         [params(0, ka=100.01), params(0, ka=99.99), params(0, ka=100.0000001)]),
    'N1 rho 0.75 load ramp f3y = f4y 0 -> -40 -> 0':
        (*one(0.75, [1.0, 1.0]), WIDE, [params(0, f3y=-40.0, f4y=-40.0),
                                        params(0, f3y=0.0, f4y=0.0)]),
    'N3 head load 0 -> -40 N -> 0':
        (*neck(3), None, [head_load(3, -40.0), head_load(3, 0.0)]),
    'N3 m0 ka 100.0000001, head load 0 -> -40 N':
        (*neck(3, ka=100.0000001), None, [head_load(3, -40.0)]),
    'N3 m2/force_a3 (0, -max load) then (max load, 0)':
        (*neck(3), None, [force(2, 'a3', (0.0, -MAX_LOAD)), force(2, 'a3', (MAX_LOAD, 0.0))]),
    'N3 m0 rho 0.75 -> 0.2 -> 1.5':
        (*neck(3), None, [rho_to(0, 0.2), rho_to(0, 1.5)]),
    'N3 joint_commands all 0.75 -> 1.2 -> 0.4':
        (*neck(3), None, [rhos_to({0: 1.2, 1: 1.2, 2: 1.2}), rhos_to({0: 0.4, 1: 0.4, 2: 0.4})]),
    'N3 reset with a head load of -40 N':
        (*neck(3), None, [reset_with_head_load(3, -40.0)]),
    'N10 reset with a head load of -40 N':
        (*neck(10), None, [reset_with_head_load(10, -40.0)]),
    'N10 head load 0 -> -40 N':
        (*neck(10), None, [head_load(10, -40.0)]),
    'N10 m9/force_a3 (0, -max load)':
        (*neck(10), None, [force(9, 'a3', (0.0, -MAX_LOAD))]),
    'N10 m0 rho 0.75 -> 0.3':
        (*neck(10), None, [rho_to(0, 0.3)]),
}


def pending(sim):
    return BOUNDED and sim.pending


def run(case, budget):
    """(worst call s, total s, calls, jumps, failures, final angles) of one case."""
    modules, thetas, limits, commands = case
    limits = limits * len(modules) if limits is not None else None
    extra = {'time_budget': budget} if BOUNDED else {}
    sim = Simulator(modules, thetas, limits, **extra)
    worst = total = 0.0
    calls = jumps = failures = 0
    now = 0
    for command in commands:
        call = command
        while True:
            now += TICK_NS
            t0 = time.perf_counter()
            outcome = call(sim, now)
            elapsed = time.perf_counter() - t0
            worst, total, calls = max(worst, elapsed), total + elapsed, calls + 1
            jumps += sum(type(e).__name__ == 'Jump' for e in outcome.events)
            failures += sum(type(e).__name__ == 'TrackingFailure' for e in outcome.events)
            if not pending(sim) or calls >= MAX_CALLS:
                break
            call = lambda s, t: s.advance(t)      # noqa: E731  (the node's timer)
    final = np.array([[sim.module(i)[1].theta1, sim.module(i)[1].theta2]
                      for i in range(len(modules))])
    return worst, total, calls, jumps, failures, final


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--only', default='', help='run the cases whose name contains this')
    args = parser.parse_args()
    budget = getattr(simulator_module, 'DEFAULT_TIME_BUDGET', None)
    print(f'bounded work: {"budget " + format(budget, "g") + " s" if BOUNDED else "not built"}'
          ' (machine shared: compare ratios)')
    print(f'{"case":<68} {"unbounded worst/total ms":>25} {"bounded worst/total ms (calls)":>31}'
          f' {"ratio":>6} same')
    worst_before = worst_after = 0.0
    for name, case in CASES.items():
        if args.only not in name:
            continue
        before = run(case, None)
        after = run(case, budget) if BOUNDED else before
        same = (before[3] == after[3] and before[4] == after[4]
                and np.allclose(before[5], after[5], atol=1e-6))
        worst_before, worst_after = max(worst_before, before[0]), max(worst_after, after[0])
        print(f'{name:<68} {1e3 * before[0]:>11.1f} / {1e3 * before[1]:>9.1f} '
              f'{1e3 * after[0]:>11.1f} / {1e3 * after[1]:>9.1f} ({after[2]:>4}) '
              f'{before[0] / after[0]:>6.2f} {"yes" if same else "NO"}'
              f'  jumps {before[3]}/{after[3]} failures {before[4]}/{after[4]}')
    print(f'worst single call: unbounded {1e3 * worst_before:.1f} ms, '
          f'bounded {1e3 * worst_after:.1f} ms')


if __name__ == '__main__':
    main()
