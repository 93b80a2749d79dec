"""Simulator overhead per command: ``Simulator.command_rho`` vs the bare core calls it makes.

The baseline does by hand what a command costs without the simulator (what the node
did inline before it had one): the operation-range early warning (cached, hinted),
``ModuleParams.with_``, ``track_module`` and the positive-definiteness check.  Both
run the same 1000 small steps (|d rho| <= 1e-3 m, no jump); best of 9 each.  The
ratio is the simulator's bookkeeping (targets, outcomes, events) on top.

    python benchmarks/bench_simulator.py
"""
import math
import time

from tensegrity_ros.core import ModuleParams, settle, track_module
from tensegrity_ros.core.analysis import operation_range
from tensegrity_ros.core.simulation.simulator import ModuleLimits, Simulator

START = ModuleParams.paper(0.8)
RHOS = [0.8 + 0.1 * math.sin(i * 0.01) for i in range(1000)]
REPEAT = 9


def with_simulator():
    sim = Simulator([START], [[0.7, 0.7]], [ModuleLimits(0.05, 1.95)])
    for i, rho in enumerate(RHOS):
        sim.command_rho(0, rho, i)


def bare_core_calls():
    params, eq = START, settle(START, [0.7, 0.7])
    cache = None
    for rho in RHOS:
        if not (math.isfinite(rho) and 0.05 <= rho <= 1.95):
            continue
        key = (params, eq.theta1, eq.theta2)
        if cache is None or cache[0] != key:
            hint = cache[1] if cache is not None else None
            cache = (key, operation_range(params, eq.theta, hint=hint))
        track = track_module(params, params.with_(rho=rho), eq.theta)
        ev = track.final.eigenvalues
        if not ev[0] > 1e-9 * abs(ev[-1]):
            raise AssertionError('unverified state')
        params, eq = track.end, track.final


def main():
    best = {}
    for name, run in (('bare core calls', bare_core_calls), ('simulator', with_simulator)) \
            * REPEAT:
        t0 = time.perf_counter()
        run()
        per_command = (time.perf_counter() - t0) / len(RHOS) * 1e6
        best[name] = min(best.get(name, math.inf), per_command)
    for name, value in best.items():
        print(f'{name:16s} {value:8.1f} us/command (best of {REPEAT}, {len(RHOS)} commands)')
    print(f'ratio simulator / bare core calls: {best["simulator"] / best["bare core calls"]:.3f}')


if __name__ == '__main__':
    main()
