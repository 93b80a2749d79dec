"""Cost of a snap-through simulation, side by side with the quasi-static tracker.

The fig. 8a fold (rho 0.5 -> 0.9 at 0.1 m/s, 50 g rods) with light and heavy damping,
held until settled, against track_module on the same path (which the simulation also
runs, for its prediction beside the dynamic figures).

    python benchmarks/bench_snap.py
"""
import time

from tensegrity_ros.core import ModuleParams, settle, simulate_snap, track_module


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


if __name__ == '__main__':
    main()
