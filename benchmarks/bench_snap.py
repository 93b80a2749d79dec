"""Cost of snap-through simulation: the live dynamics mode's real-time factors, each with
its accuracy, side by side with a baseline tree in the same run; then the offline
transients beside the quasi-static tracker.

Live (the node's ``dynamics`` mode, a DynamicSimulator advanced in 20 ms ticks, the
joint states read at every tick as the node publishes them):

* ``module``: fig. 8a's fold (rho 0.5 -> 0.9 at 0.1 m/s, 50 g rods, c = 0.05), 16 s;
* ``neck3``: config/neck.yaml's fold (m2's rho 0.08 -> 0.12 at 0.05 m/s, c = 0.01), 2 s
  (the snap rests after ~1.3 s);
* ``neck10``: ten config/neck.yaml modules (rho 0.09, 0.085, 0.08 ...; 1.0 / 1.02 N down
  on the head) with m0's rho 0.09 -> 0.05 at 0.05 m/s across the neck's fold (0.0613), 3 s.

The real-time factor is simulated seconds per CPU second (``time.process_time``: the
machine is shared; wall-clock figures beside), ticks only (the construction, which
settles the start state, excluded; one warm-up run first: numba loads its compiled code).
The DynamicSimulator's includes, once per snap, the quasi-static tracker's path (the
early warning and the prediction beside the jump) and the verification at rest; the bare
loop (MovingModule / MovingNeck) beside it is the integration alone.  Accuracy: the
largest |theta - theta_ref| (rad) over the ticks, theta_ref the same ticks integrated at
rtol 1e-13 (atol 1e-15).

``--baseline DIR`` runs the same live scenarios with the ``tensegrity_ros`` package found
in DIR (e.g. an export of an earlier commit: ``git archive 8db3247 tensegrity_ros | tar -x
-C DIR``) in a subprocess, alternating with this tree, and prints the ratios (medians of
``--repeat`` runs each).

    python benchmarks/bench_snap.py [--baseline DIR] [--repeat 3] [--skip-offline]
"""
import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time

import numpy as np

SCENARIOS = ('module', 'neck3', 'neck10')
TICK = 0.02


def _problem(name):
    """(modules, start angles, limits, damping, (index, rho), ticks) of a live scenario."""
    from tensegrity_ros.core import ModuleParams
    from tensegrity_ros.core.simulation.simulator import ModuleLimits
    if name == 'module':
        p = ModuleParams.paper(0.5, F3=5.0, F4=5.0).with_(m1=0.05, m2=0.05)
        return [p], [[-1.0, -1.0]], [ModuleLimits(0.05, 1.95, 0.1)], [0.05], (0, 0.9), 800
    base = {'L1': 0.12, 'L2': 0.12, 'ka': 300.0, 'kb': 300.0, 'kc': 300.0, 'm1': 0.02, 'm2': 0.02}
    if name == 'neck3':
        modules = [ModuleParams(rho=0.09, **base), ModuleParams(rho=0.085, **base),
                   ModuleParams(rho=0.08, f3y=-0.5, f4y=-0.5, **base)]
        upright = [[0.754, 0.754], [0.813, 0.813], [0.831, 0.831]]
        return (modules, upright, [ModuleLimits(0.05, 0.15, 0.05)] * 3, [0.01] * 3, (2, 0.12),
                100)
    rhos = [0.09, 0.085] + [0.08] * 8
    modules = [ModuleParams(rho=r, **base) for r in rhos]
    modules[-1] = modules[-1].with_(f3y=-1.0, f4y=-1.02)
    upright = [[math.acos((a + b) / 0.24)] * 2 for a, b in zip(rhos, rhos[1:] + [0.08])]
    return modules, upright, [ModuleLimits(0.04, 0.15, 0.05)] * 10, [0.01] * 10, (0, 0.05), 150


def live_costs(name):
    """{'sim_cpu', 'sim_wall', 'bare_cpu', 'bare_wall', 'simulated'}: one run of each."""
    from tensegrity_ros.core.simulation.dynamic_simulator import DynamicSimulator
    modules, start, limits, damping, (index, rho), ticks = _problem(name)
    sim = DynamicSimulator(modules, start, limits, damping=damping)
    n = len(modules)
    wall, cpu = time.perf_counter(), time.process_time()
    sim.command_rho(index, rho, 0)
    for k in range(1, ticks + 1):
        sim.advance(k * 20_000_000)
        [sim.live(i) for i in range(n)]
    out = {'sim_cpu': time.process_time() - cpu, 'sim_wall': time.perf_counter() - wall,
           'simulated': ticks * TICK}
    live = _bare(name)
    wall, cpu = time.perf_counter(), time.process_time()
    for k in range(1, ticks + 1):
        live.advance(k * TICK)
        live.theta, live.theta_dot
    out.update(bare_cpu=time.process_time() - cpu, bare_wall=time.perf_counter() - wall)
    return out


def _bare(name, settings=None):
    """The bare live loop of a scenario, commanded at t = 0."""
    from tensegrity_ros.core.dynamics.moving_module import MovingModule
    from tensegrity_ros.core.dynamics.moving_neck import MovingNeck
    from tensegrity_ros.core.neck.stack import Stack
    modules, start, limits, damping, (index, rho), _ = _problem(name)
    extra = {} if settings is None else {'settings': settings}
    if len(modules) == 1:
        live = MovingModule(modules[0], start[0], damping[0], limits[0].max_rho_rate, **extra)
        live.command(rho, 0.0)
        return live
    live = MovingNeck(Stack(tuple(modules)), start, damping, limits[0].max_rho_rate, **extra)
    targets = [m.rho for m in modules]
    targets[index] = rho
    live.command(tuple(targets), 0.0)
    return live


def accuracy(name):
    """max |theta - theta_ref| (rad) over the ticks, the reference at rtol 1e-13."""
    from tensegrity_ros.core.dynamics.transient import SolverSettings
    ticks = _problem(name)[-1]
    runs = []
    for settings in (None, SolverSettings(rtol=1e-13, atol=1e-15)):
        live, angles = _bare(name, settings), []
        for k in range(1, ticks + 1):
            live.advance(k * TICK)
            angles.append(np.ravel(live.theta))
        runs.append(np.unwrap(angles, axis=0))
    return float(np.max(np.abs(runs[0] - runs[1])))


def _in_subprocess(tree, name):
    """live_costs(name) with the package of ``tree`` (JSON over stdout)."""
    code = (f'import sys, json; sys.path.insert(0, {tree!r}); sys.path.insert(1, {HERE!r}); '
            f'import bench_snap; print(json.dumps(bench_snap.live_costs({name!r})))')
    env = dict(os.environ, PYTHONPATH=tree)
    done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, env=env,
                          check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


HERE = os.path.dirname(os.path.abspath(__file__))
TREE = os.path.dirname(HERE)


def live_table(baseline, repeat):
    print(f'live, 20 ms ticks (load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} '
          f'cores); real-time factor = simulated s / CPU s (wall in brackets)')
    for name in SCENARIOS:
        _in_subprocess(TREE, name)                   # warm-up: numba's cache, imports
        runs = {'this': [], 'baseline': []}
        for _ in range(repeat):
            runs['this'].append(_in_subprocess(TREE, name))
            if baseline:
                runs['baseline'].append(_in_subprocess(baseline, name))
        line = [f'{name:7s}']
        for label in ('this', 'baseline') if baseline else ('this',):
            rows = runs[label]
            simulated = rows[0]['simulated']
            for key in ('sim', 'bare'):
                cpu = statistics.median(r[f'{key}_cpu'] for r in rows)
                wall = statistics.median(r[f'{key}_wall'] for r in rows)
                line.append(f'{label} {"DynamicSimulator" if key == "sim" else "bare loop"} '
                            f'RTF {simulated / cpu:6.1f} ({simulated / wall:5.1f})')
        if baseline:
            for key in ('sim', 'bare'):
                ratio = (statistics.median(r[f'{key}_cpu'] for r in runs['baseline'])
                         / statistics.median(r[f'{key}_cpu'] for r in runs['this']))
                line.append(f'{key} speed-up x{ratio:.1f}')
        print('  ' + '; '.join(line))
        print(f'          accuracy (this tree): max |dtheta| {accuracy(name):.1e} rad')


def offline_table():
    from tensegrity_ros.core import ModuleParams, settle, simulate_snap, track_module
    p = ModuleParams.paper(0.5, F3=5.0, F4=5.0).with_(m1=0.05, m2=0.05)
    start = settle(p, [-1.0, -1.0])
    tracker = best_of(lambda: track_module(p, p.with_(rho=0.9), start.theta), 20)
    print(f'offline: track_module fig. 8a fold (quasi-static): {tracker * 1e3:8.2f} ms')
    for damping in (0.01, 0.05, 5.0):
        snap = simulate_snap(p, 0.9, 0.1, damping, [-1.0, -1.0])
        cost = best_of(lambda: simulate_snap(p, 0.9, 0.1, damping, [-1.0, -1.0]))
        s = snap.summary
        print(f'  simulate_snap c={damping:<5g} {cost * 1e3:8.1f} ms (CPU)  ratio vs tracker '
              f'{cost / tracker:7.0f}  simulated {snap.history.t[-1]:6.2f} s, '
              f'{len(snap.solution.ts) - 1} solver steps, settle_time {s["settle_time"]:.6g} s')


def best_of(fn, repeat=3):
    samples = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        samples.append(time.process_time() - t0)
    return min(samples)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--baseline', help='a directory holding a baseline tensegrity_ros')
    parser.add_argument('--repeat', type=int, default=3)
    parser.add_argument('--skip-offline', action='store_true')
    args = parser.parse_args()
    live_table(args.baseline, args.repeat)
    if not args.skip_offline:
        offline_table()


if __name__ == '__main__':
    main()
