"""Cost of the exact analysis: degenerate-curve tracing, operation ranges, point C.

    python benchmarks/bench_analysis.py

degenerate_curves on the paper's planes (figs. 3, 4a, 4b, 7 and a fig. 5 slice);
operation_range for the fig. 8 branches (cold, and with the previous range as
hint after a rho-only command change) and over random stable states (what a
node calling it after every command would see); two_stable_limit (point C).
"""
import statistics
import time

import numpy as np

from tensegrity_ros.core.analysis import degenerate_curves, operation_range, two_stable_limit
from tensegrity_ros.core.module.equilibria import equilibria
from tensegrity_ros.core.module.model import ModuleParams


def timed(fn, repeat):
    samples = []
    result = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = fn()
        samples.append(time.perf_counter() - t0)
    return result, np.array(samples)


def bench_curves():
    planes = [
        ('fig. 4a  (rho, F)  F <= 0', ModuleParams.paper(1.0),
         'rho', (0.001, 2.0), 'F', (-10.0, 0.0)),
        ('fig. 4b  (rho, F)  F >= 0', ModuleParams.paper(1.0),
         'rho', (0.001, 2.0), 'F', (0.0, 10.0)),
        ('fig. 3   (rho, L2) F = 0', ModuleParams.paper(1.0),
         'rho', (0.001, 4.0), 'L2', (0.001, 4.0)),
        ('fig. 7   (rho, L2) F = -10', ModuleParams.paper(1.0, F3=-10, F4=-10),
         'rho', (0.005, 2.0), 'L2', (0.005, 2.0)),
        ('fig. 5b slice (rho, F4) F3=5', ModuleParams.paper(1.0, F3=5.0),
         'rho', (0.005, 2.0), 'F4', (0.0, 10.0)),
        ('(F3, F4) at rho = 0.4, L2 = 1.5', ModuleParams.paper(0.4, L2=1.5),
         'F3', (0.0, 150.0), 'F4', (0.0, 100.0)),
    ]
    print('degenerate_curves (default grid 48x48, 400 samples per box edge), best of 3:')
    for label, base, x, xr, y, yr in planes:
        curves, t = timed(lambda: degenerate_curves(base, x, xr, y, yr), 3)
        points = sum(len(c) for c in curves)
        kinds = ', '.join(f'{c.kind}{"/" + c.symmetry if c.symmetry else ""}'
                          f'{"*" if c.changes_stable_count else ""}' for c in curves)
        print(f'  {label:32s} {1e3 * t.min():7.1f} ms  {len(curves)} curves, {points:4d} points '
              f'[{kinds}]')
    print('  (* = changes the number of stable equilibria somewhere)')


def bench_ranges():
    print('\noperation_range, best of 20 (ms):')
    cases = [
        ('fig. 8a lower branch (C1 pitchfork, C2 fold)', ModuleParams.paper(0.5, F3=5, F4=5),
         (-1.0, -1.0)),
        ('fig. 8a upper branch (stable to the bounds)', ModuleParams.paper(0.5, F3=5, F4=5),
         (1.0, 1.0)),
        ('fig. 8b lower branch (two folds)', ModuleParams.paper(0.5, L2=1.05, F3=5, F4=5),
         (-1.0, -1.0)),
        ('unloaded, L2 = 1.5 (flat pitchforks)', ModuleParams.paper(0.7, L2=1.5), (1.0, 1.0)),
    ]
    for label, p, theta in cases:
        r, t = timed(lambda: operation_range(p, theta), 20)
        q = p.with_(rho=p.rho + 0.01)
        th = r.theta_at(q.rho)
        _, th_hint = timed(lambda: operation_range(q, th, hint=r), 20)
        print(f'  {label:46s} cold {1e3 * t.min():6.2f}  hint {1e3 * th_hint.min():6.3f}   '
              f'({r.rho_min:.12f} {r.lower.kind}, {r.rho_max:.12f} {r.upper.kind})')

    rng = np.random.default_rng(0)
    samples = []
    while len(samples) < 300:
        p = ModuleParams(rho=rng.uniform(0.1, 1.5), L2=rng.uniform(0.5, 2.0),
                         f3y=rng.uniform(-40, 40), f4y=rng.uniform(-40, 40))
        for e in equilibria(p).stable:
            _, t = timed(lambda: operation_range(p, e.theta), 3)
            samples.append(t.min())
    s = np.array(samples) * 1e3
    print(f'  random stable states ({len(s)}): median {statistics.median(s):.2f} ms, '
          f'p90 {np.percentile(s, 90):.2f} ms, max {s.max():.2f} ms')


def bench_point_c():
    print('\ntwo_stable_limit (point C, L1 = 1, k = 100, pulling):')
    for L2 in (0.5, 1.0, 1.5):
        c, t = timed(lambda: two_stable_limit(L2), 20)
        print(f'  L2 = {L2:3.1f}: F3 = {c.F3:.10f}  F4 = {c.F4:.10f}  rho = {c.rho:.10f}  '
              f'theta = ({c.theta[0]:+.6f}, {c.theta[1]:+.6f})   {1e3 * t.min():.2f} ms')


if __name__ == '__main__':
    bench_curves()
    bench_ranges()
    bench_point_c()
