"""Cost of a snap-through simulation, side by side with the quasi-static tracker.

The fig. 8a fold (rho 0.5 -> 0.9 at 0.1 m/s, 50 g rods) with light and heavy damping,
held until settled, against track_module on the same path (which the simulation also
runs, for its prediction beside the dynamic figures).  Then the neck simulator on the
same one-module problem (node coordinates, ratio vs the module simulator) and on 2 and 3
modules, and the real-time factor of a MovingModule driven in 10 ms ticks (simulated
seconds per wall-clock second: above 1 a node could integrate live); last the node's
dynamics mode, a DynamicSimulator in 20 ms ticks (publish_rate 50 Hz) through the same
snap, side by side with the bare MovingModule in the same ticks (the ratio is the
simulator's bookkeeping: status, the verified rest state, the jump beside the tracker).
Last the live neck: config/neck.yaml's fold (m2's rho 0.08 -> 0.12 at 0.05 m/s) in 20 ms
ticks, a MovingNeck and a DynamicSimulator, real-time factors beside the module's.

Every live real-time factor is stated with its accuracy: the largest |theta - theta_ref|
(rad) over the ticks, theta_ref the same ticks integrated at rtol 1e-13 (atol 1e-15).

    python benchmarks/bench_snap.py
"""
import time

import numpy as np

from tensegrity_ros.core import ModuleParams, settle, simulate_snap, track_module
from tensegrity_ros.core.dynamic_simulator import DynamicSimulator
from tensegrity_ros.core.moving_module import MovingModule
from tensegrity_ros.core.moving_neck import MovingNeck
from tensegrity_ros.core.neck_dynamics import simulate_neck_snap
from tensegrity_ros.core.simulator import ModuleLimits
from tensegrity_ros.core.stack import Stack
from tensegrity_ros.core.transient import SolverSettings

#: The reference of the accuracy figures: the same ticks, integrated far more tightly.
TIGHT = SolverSettings(rtol=1e-13, atol=1e-15)


def ticked(make, ticks, dt, settings=SolverSettings()):
    """Angles (ticks, k) of a live motion ``make(settings)`` advanced in ``ticks`` of ``dt`` s."""
    live = make(settings)
    out = []
    for k in range(1, ticks + 1):
        live.advance(k * dt)
        out.append(np.ravel(live.theta))
    return np.array(out)


def accuracy(make, ticks, dt):
    """max |theta - theta_ref| (rad) over the ticks, the reference at rtol 1e-13."""
    return float(np.max(np.abs(ticked(make, ticks, dt) - ticked(make, ticks, dt, TIGHT))))


def best_of(fn, repeat=3):
    samples = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return min(samples)


def main():
    p = ModuleParams.paper(0.5, F3=5.0, F4=5.0).with_(m1=0.05, m2=0.05)
    start = settle(p, [-1.0, -1.0])
    tracker = best_of(lambda: track_module(p, p.with_(rho=0.9), start.theta), 20)
    print(f'track_module fig. 8a fold (quasi-static): {tracker * 1e3:8.2f} ms')
    for damping in (0.01, 0.05, 5.0):
        snap = simulate_snap(p, 0.9, 0.1, damping, [-1.0, -1.0])
        cost = best_of(lambda: simulate_snap(p, 0.9, 0.1, damping, [-1.0, -1.0]))
        s = snap.summary
        print(f'simulate_snap c={damping:<5g} {cost * 1e3:8.1f} ms  ratio vs tracker '
              f'{cost / tracker:7.0f}  simulated {snap.history.t[-1]:6.2f} s, '
              f'{len(snap.solution.ts) - 1} solver steps, settle_time {s["settle_time"]:.3g} s')
    neck_vs_module(p)
    real_time_factor(p)
    dynamics_mode_vs_moving_module(p)
    live_neck()


def neck_vs_module(p):
    module = best_of(lambda: simulate_snap(p, 0.9, 0.5, 0.2, [-1.0, -1.0]), 2)
    neck = best_of(lambda: simulate_neck_snap(Stack((p,)), 0.9, 0.5, 0.2, [[-1.0, -1.0]]), 2)
    print(f'rho 0.5 -> 0.9 at 0.5 m/s, c=0.2: module {module * 1e3:8.1f} ms, neck N=1 '
          f'{neck * 1e3:8.1f} ms, ratio {neck / module:5.1f}')
    for n in (2, 3):
        modules = tuple(ModuleParams(rho=0.6, m1=0.05, m2=0.05) for _ in range(n))
        guess = [[1.2, 1.2]] + [[1.0, 1.0]] * (n - 1)
        cost = best_of(lambda: simulate_neck_snap(Stack(modules), [0.45] + [0.62] * (n - 1),
                                                  0.5, 0.3, guess), 1)
        print(f'neck N={n}: every rho ramps together, until settled: {cost * 1e3:8.1f} ms')


def real_time_factor(p):
    def make(settings=SolverSettings()):
        live = MovingModule(p, [-1.0, -1.0], damping=0.05, max_rate=0.1, settings=settings)
        live.command(0.9, 0.0)
        return live

    live = make()
    t0 = time.perf_counter()
    t = 0.0
    while t < 16.0:
        t += 0.01
        live.advance(t)
    wall = time.perf_counter() - t0
    print(f'MovingModule, 10 ms ticks through the fig. 8a snap: 16 s simulated in '
          f'{wall:.2f} s wall, real-time factor {16.0 / wall:.1f} at max |dtheta| '
          f'{accuracy(make, 1600, 0.01):.1e} rad')


def dynamics_mode_vs_moving_module(p, ticks=800):
    def bare():
        live = MovingModule(p, [-1.0, -1.0], damping=0.05, max_rate=0.1)
        live.command(0.9, 0.0)
        for k in range(1, ticks + 1):
            live.advance(k * 0.02)

    def simulator():
        sim = DynamicSimulator([p], [[-1.0, -1.0]], [ModuleLimits(0.05, 1.95, 0.1)],
                               damping=[0.05])
        sim.command_rho(0, 0.9, 0)
        for k in range(1, ticks + 1):
            sim.advance(k * 20_000_000)
            sim.live(0)

    wall_bare, wall_sim = best_of(bare, 2), best_of(simulator, 2)
    print(f'dynamics mode, {ticks} ticks of 20 ms (16 s simulated): DynamicSimulator '
          f'{wall_sim:.2f} s wall (real-time factor {ticks * 0.02 / wall_sim:.1f}), bare '
          f'MovingModule {wall_bare:.2f} s, ratio {wall_sim / wall_bare:.2f}')


def live_neck(ticks=100):
    """config/neck.yaml across m2's fold: 2 s simulated (the snap rests after ~1.3 s)."""
    base = dict(L1=0.12, L2=0.12, ka=300.0, kb=300.0, kc=300.0, m1=0.02, m2=0.02)
    modules = (ModuleParams(rho=0.09, **base), ModuleParams(rho=0.085, **base),
               ModuleParams(rho=0.08, f3y=-0.5, f4y=-0.5, **base))
    upright = [[0.754, 0.754], [0.813, 0.813], [0.831, 0.831]]

    def make(settings=SolverSettings()):
        live = MovingNeck(Stack(modules), upright, damping=0.01, max_rate=0.05,
                          settings=settings)
        live.command((0.09, 0.085, 0.12), 0.0)
        return live

    def bare():
        live = make()
        for k in range(1, ticks + 1):
            live.advance(k * 0.02)

    def simulator():
        sim = DynamicSimulator(modules, upright, [ModuleLimits(0.05, 0.15, 0.05)] * 3,
                               damping=[0.01] * 3)
        sim.command_rho(2, 0.12, 0)
        for k in range(1, ticks + 1):
            sim.advance(k * 20_000_000)
            [sim.live(i) for i in range(3)]

    wall_bare, wall_sim = best_of(bare, 2), best_of(simulator, 2)
    simulated = ticks * 0.02
    print(f'live neck (config/neck.yaml fold), {ticks} ticks of 20 ms: MovingNeck '
          f'{wall_bare:.2f} s wall (real-time factor {simulated / wall_bare:.2f}), '
          f'DynamicSimulator {wall_sim:.2f} s (real-time factor {simulated / wall_sim:.2f}), '
          f'ratio {wall_sim / wall_bare:.2f}; max |dtheta| {accuracy(make, ticks, 0.02):.1e} rad')


if __name__ == '__main__':
    main()
