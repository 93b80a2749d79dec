"""Exact one-module solver: single-point latency and batch throughput.

(a) Single exact solve (`equilibria`) over ~2000 varied parameter points, median
    and p90 latency, side by side with a multi-start scipy solver on the same
    points (the test oracle, test/oracle_solver.py: scipy.optimize.root from a
    grid of starts on the torus, polish, de-duplicate, classify), the ratio, and
    whether both find the same sets.
(b) Batch throughput (`equilibria_batch`) in points/s for 100k random points and
    for a 1000 x 400 (rho, F) grid of the paper's symmetric case (in one call,
    and in calls of 50k rows, which keeps the working set in cache), with a spot
    check against the single solver.

    python benchmarks/bench_solve.py [--points 2000] [--grid 12] [--quick]

A script, not a timed test; about a minute on two cores.
"""
import argparse
import math
import os
import platform
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'test'))
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

from oracle_solver import oracle_equilibria, torus_distance  # noqa: E402
from tensegrity_ros.core import equilibria, equilibria_batch, ModuleParams  # noqa: E402

NAMES = ('rho', 'L1', 'L2', 'ka', 'kb', 'kc', 'f3x', 'f3y', 'f4x', 'f4y', 'm1', 'm2')


def varied_points(n, seed=0):
    """Paper-like, general, symmetric, unloaded, horizontal-only, weighted, large loads."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        kind = i % 7
        k = rng.uniform(20, 300, 3)
        d = {'rho': rng.uniform(0.02, 2.5), 'L1': rng.uniform(0.3, 2.5),
             'L2': rng.uniform(0.3, 2.5), 'ka': k[0], 'kb': k[1], 'kc': k[2]}
        if kind == 0:                                           # the paper's setting
            d = {'rho': rng.uniform(0.01, 2), 'L2': rng.uniform(0.2, 2),
                 'f3y': rng.uniform(-10, 10), 'f4y': rng.uniform(-10, 10)}
        elif kind == 1:                                         # general loads
            d.update(zip(('f3x', 'f3y', 'f4x', 'f4y'), rng.normal(0, 20, 4)))
        elif kind == 2:                                         # symmetric design and load
            F = rng.uniform(-30, 30)
            d.update(L2=d['L1'], kb=d['ka'], f3y=F, f4y=F)
        elif kind == 3:                                         # unloaded
            pass
        elif kind == 4:                                         # horizontal loads only
            d.update(f3x=rng.normal(0, 30), f4x=rng.normal(0, 30))
        elif kind == 5:                                         # rod weights
            d.update(m1=rng.uniform(0, 3), m2=rng.uniform(0, 3), f3y=rng.normal(0, 5))
        else:                                                   # large loads
            d.update(zip(('f3x', 'f3y', 'f4x', 'f4y'), rng.normal(0, 2000, 4)))
        out.append(ModuleParams(**d))
    return out


def timed(fn, *args):
    t0 = time.perf_counter()
    result = fn(*args)
    return time.perf_counter() - t0, result


def compare(exact, oracle):
    """'same', or why not."""
    if len(exact) != len(oracle.points):
        return f'count {len(exact)} vs {len(oracle.points)}'
    for e in exact:
        j = min(range(len(oracle.points)), key=lambda j: torus_distance(e.theta, oracle.points[j]))
        if torus_distance(e.theta, oracle.points[j]) > 1e-8:
            return 'position'
        if e.stable != oracle.stable[j]:
            return 'stability'
    return 'same'


def single(points, grid):
    print(f'(a) single solve, {len(points)} varied points; multi-start scipy with a '
          f'{grid}x{grid} grid of starts ({grid * grid} root solves per point)')
    for p in points[:50]:                                       # warm up
        equilibria(p)
    exact_t, exact_sets = [], []
    for p in points:
        dt, s = timed(equilibria, p)
        exact_t.append(dt)
        exact_sets.append(s)
    multi_t, verdicts, ill = [], {}, 0
    for p, s in zip(points, exact_sets):
        dt, o = timed(oracle_equilibria, p, grid)
        multi_t.append(dt)
        if o.ill_conditioned:
            ill += 1
            continue
        verdict = compare(s, o)
        verdicts[verdict] = verdicts.get(verdict, 0) + 1
    us = lambda x: x * 1e6                                      # noqa: E731
    med_e, p90_e = us(statistics.median(exact_t)), us(np.percentile(exact_t, 90))
    med_m, p90_m = us(statistics.median(multi_t)), us(np.percentile(multi_t, 90))
    print(f'    exact (equilibria):      median {med_e:9.1f} us   p90 {p90_e:9.1f} us   '
          f'max {us(max(exact_t)):9.1f} us')
    print(f'    multi-start scipy:       median {med_m:9.1f} us   p90 {p90_m:9.1f} us')
    print(f'    ratio (multi / exact):   median {med_m / med_e:9.0f}x   p90 {p90_m / p90_e:9.0f}x')
    compared = sum(verdicts.values())
    print(f'    same sets (count, positions to 1e-8 rad, stability): {verdicts.get("same", 0)}'
          f' / {compared} compared; {ill} points skipped as ill-conditioned by the multi-start'
          f' solver itself')
    other = {k: v for k, v in verdicts.items() if k != 'same'}
    if other:
        print(f'    differences: {other}  (at {grid}x{grid} starts the multi-start solver can '
              f'miss equilibria with small basins; test/test_oracle.py uses 24x24)')
    return med_e, med_m, verdicts.get('same', 0), compared


def batch_random(n, seed=1):
    rng = np.random.default_rng(seed)
    args = {'rho': rng.uniform(0.01, 3, n), 'L1': rng.uniform(0.2, 3, n),
            'L2': rng.uniform(0.2, 3, n), 'ka': rng.uniform(10, 500, n),
            'kb': rng.uniform(10, 500, n), 'kc': rng.uniform(10, 500, n),
            'f3x': rng.normal(0, 20, n), 'f3y': rng.normal(0, 20, n), 'f4x': rng.normal(0, 20, n),
            'f4y': rng.normal(0, 20, n), 'm1': rng.uniform(0, 2, n), 'm2': rng.uniform(0, 2, n)}
    return args


def spot_check(args, b, count, seed=2):
    rng = np.random.default_rng(seed)
    idx = rng.choice(b.valid.shape[0], size=count, replace=False)
    agree = 0
    for i in idx:
        p = ModuleParams(**{
            k: float(np.broadcast_to(args.get(k, ModuleParams.__dataclass_fields__[k].default),
                                     b.valid.shape[:1])[i])
            for k in NAMES})
        s = equilibria(p)
        agree += (b.num_equilibria[i], b.num_stable[i]) == (len(s), s.num_stable)
    return agree, count


def throughput(label, args, n, repeat=2, chunk=None):
    """Best-of-``repeat`` rate of equilibria_batch on ``args`` (in chunks of ``chunk`` rows)."""
    equilibria_batch(**{k: np.asarray(v)[:1000] if np.ndim(v) else v for k, v in args.items()})
    chunk = chunk or n

    def run():
        parts = [equilibria_batch(**{k: np.asarray(v)[i:i + chunk] if np.ndim(v) else v
                                     for k, v in args.items()}) for i in range(0, n, chunk)]
        return parts[0] if len(parts) == 1 else _concat(parts)

    best, b = math.inf, None
    for _ in range(repeat):
        dt, b = timed(run)
        best = min(best, dt)
    rate = n / best
    counts = np.bincount(b.num_stable, minlength=3)
    how = 'one call' if chunk == n else f'calls of {chunk}'
    print(f'    {label:30s} {n:7d} points ({how:15s}) in {best:5.2f} s = {rate:8.0f} points/s'
          f'   (stable 0/1/2: {counts[0]}/{counts[1]}/{counts[2]})')
    return b, rate


class _concat:
    """The few EquilibriumBatch fields the benchmark reads, over several calls."""

    def __init__(self, parts):
        self.valid = np.concatenate([p.valid for p in parts])
        self.num_stable = np.concatenate([p.num_stable for p in parts])
        self.num_equilibria = np.concatenate([p.num_equilibria for p in parts])


def batch(quick):
    print('(b) batch throughput (equilibria_batch)')
    n = 20_000 if quick else 100_000
    args = batch_random(n)
    b, rate_random = throughput('random points', args, n)
    agree, count = spot_check(args, b, 300)
    print(f'        spot check vs single solver: {agree} / {count} agree '
          f'(counts and stable counts)')
    rho, F = np.meshgrid(np.linspace(0.005, 2.0, 1000),
                         np.linspace(-10, 10, 400 if not quick else 100))
    grid = {'rho': rho.ravel(), 'f3y': F.ravel(), 'f4y': F.ravel()}
    label = f'(rho, F) grid {rho.shape[1]}x{rho.shape[0]} (fig. 4)'
    throughput(label, grid, rho.size, repeat=1)
    b, rate_grid = throughput(label, grid, rho.size, repeat=1, chunk=50_000)
    agree, count = spot_check(grid, b, 300)
    print(f'        spot check vs single solver: {agree} / {count} agree')
    return rate_random, rate_grid


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--points', type=int, default=2000)
    parser.add_argument('--grid', type=int, default=12, help='multi-start grid per angle')
    parser.add_argument('--quick', action='store_true', help='smaller runs (smoke test)')
    a = parser.parse_args()
    if a.quick:
        a.points = min(a.points, 200)
    print(f'python {platform.python_version()}, numpy {np.__version__}, '
          f'{os.cpu_count()} cpus, load {os.getloadavg()[0]:.2f}')
    t0 = time.perf_counter()
    med_e, med_m, same, compared = single(varied_points(a.points), a.grid)
    rate_random, rate_grid = batch(a.quick)
    print(f'summary: single solve median {med_e:.0f} us ({med_m / med_e:.0f}x faster than '
          f'multi-start scipy, same sets on {same}/{compared}); batch {rate_random:.0f} points/s '
          f'(random), {rate_grid:.0f} points/s (grid, calls of 50k); '
          f'total {time.perf_counter() - t0:.0f} s')
    assert same >= 0.98 * compared, 'the exact and multi-start solvers disagree too often'


if __name__ == '__main__':
    main()
