"""Tracker cost: a small command step, and commands that cross a fold or a branch point.

Side by side with the naive baseline a node might otherwise use: one
scipy.optimize.root solve at the end point from the previous state (fast, but
blind to jumps: it can land on a saddle or another branch silently).

    python benchmarks/bench_track.py
"""
import os
import statistics
import time

import numpy as np
from scipy.optimize import root

from tensegrity_ros.core import gradient, hessian, ModuleParams, settle, track_module

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')


def fig8(rho):
    return ModuleParams.paper(rho, F3=5.0, F4=5.0)


def timed(fn, repeat):
    samples = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return np.array(samples) * 1e6


def naive_step(start_theta, end):
    return root(lambda t: gradient(end, t), start_theta, jac=lambda t: hessian(end, t),
                method='hybr').x


def main():
    theta = settle(fig8(0.5), [-1.0, -1.0]).theta
    rng = np.random.default_rng(0)
    steps = []
    for _ in range(400):
        rho = rng.uniform(0.3, 0.7)
        start = settle(fig8(rho), [-1.0, -1.0])
        steps.append((fig8(rho), fig8(rho + rng.uniform(-1e-3, 1e-3)), start.theta))

    tracker = []
    baseline = []
    for a, b, t in steps:
        tracker.append(timed(lambda: track_module(a, b, t), 3).min())
        baseline.append(timed(lambda: naive_step(t, b), 3).min())
    med_t, med_b = statistics.median(tracker), statistics.median(baseline)
    print('small command step (|d rho| <= 1e-3 m), 400 points, best of 3 each:')
    print(f'  track_module   median {med_t:8.1f} us   p90 {np.percentile(tracker, 90):8.1f} us')
    print(f'  naive root()   median {med_b:8.1f} us   p90 {np.percentile(baseline, 90):8.1f} us')
    print(f'  ratio tracker / naive: {med_t / med_b:.2f}  (target: tracker median <= 200 us)')

    for label, target in (('crosses the fold C2 (rho 0.5 -> 1.2)', 1.2),
                          ('crosses the branch point C1 (rho 0.5 -> 0.05)', 0.05),
                          ('long path, no event (rho 0.5 -> 0.16)', 0.16)):
        samples = timed(lambda: track_module(fig8(0.5), fig8(target), theta), 20)
        result = track_module(fig8(0.5), fig8(target), theta)
        print(f'{label}: median {np.median(samples) / 1e3:6.2f} ms, {result.steps} steps, '
              f'events {[j.kind for j in result.jumps]}')


if __name__ == '__main__':
    main()
