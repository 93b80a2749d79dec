"""The neck paths of issue 32, generated from a seed (shared by its tests and
benchmarks/bench_neck_paths.py; written with the package's public model only).

Families (each path: (family, start Stack, end Stack, start angles N x 2)):

* ``rho``: random necks, N = 2..10, one actuator moves;
* ``all``: random necks, every actuator moves at once;
* ``head``: random necks, the head load changes (and a horizontal part);
* ``limit``: random necks driven towards a module's linkage limit (its flat crossing,
  rho(i) + rho(i+1) -> L1 + L2), stopping 1e-3 .. 0 short of it or crossing it;
* ``perfect``: upright necks of equal paper modules under a head load 0 -> F;
* ``imperfect``: the same with module 0's ka 1e-9 off.
"""
from __future__ import annotations

import numpy as np

from tensegrity_ros.core import equilibria, ModuleParams
from tensegrity_ros.core.neck.stack import Stack

FAMILIES = ('rho', 'all', 'head', 'limit', 'perfect', 'imperfect')


def random_module(rng, rho):
    """A module with random lengths and stiffnesses about the paper's, light loads."""
    return ModuleParams(rho=rho, L1=rng.uniform(0.8, 1.2), L2=rng.uniform(0.8, 1.2),
                        ka=rng.uniform(60, 140), kb=rng.uniform(60, 140),
                        kc=rng.uniform(60, 140), f3y=rng.uniform(-2, 2),
                        f4y=rng.uniform(-2, 2))


def random_neck(rng, n):
    return Stack(tuple(random_module(rng, rng.uniform(0.5, 0.9)) for _ in range(n)))


def upright(n, rho):
    top = equilibria(ModuleParams.paper(rho)).stable[-1].theta
    return np.tile(top, (n, 1))


def paper_neck(n, rho, head, ka_error=0.0):
    """n paper modules at chord rho, ``head`` (N) on each top node; module 0's ka off by
    the relative ``ka_error``."""
    modules = [ModuleParams.paper(rho) for _ in range(n - 1)]
    modules.append(ModuleParams.paper(rho, F3=head, F4=head))
    if ka_error:
        modules[0] = modules[0].with_(ka=100.0 * (1.0 + ka_error))
    return Stack(tuple(modules))


def _random_end(rng, family, start):
    n = len(start)
    if family == 'rho':
        return start.with_module(int(rng.integers(n)), rho=rng.uniform(0.3, 1.4))
    if family == 'all':
        end = start
        for i in range(n):
            end = end.with_module(i, rho=rng.uniform(0.3, 1.4))
        return end
    if family == 'head':
        f = rng.uniform(-15.0, 5.0)
        return start.with_module(n - 1, f3y=f, f4y=f, f3x=rng.uniform(-1, 1))
    i = int(rng.integers(n - 1))            # 'limit': module i towards its flat crossing
    m = start.modules[i]
    short = rng.choice([1e-3, 1e-6, 0.0, -1e-3])
    target = m.L1 + m.L2 - start.modules[i + 1].rho - short
    return start.with_module(i, rho=float(np.clip(target, 0.05, 3.0)))


def paths(seed, count=None):
    """The families' paths for one seed: ``count`` of each random family (N = 2..10 in
    turn) and the perfect and imperfect necks N = 2..10 under one head load each."""
    rng = np.random.default_rng(seed)
    count = 9 if count is None else count
    out = []
    for family in ('rho', 'all', 'head', 'limit'):
        for k in range(count):
            n = 2 + k % 9
            start = random_neck(rng, n)
            theta = np.full((n, 2), rng.uniform(0.6, 1.2))
            out.append((family, start, _random_end(rng, family, start), theta))
    for n in range(2, 11):
        head = -float(rng.choice([5.0, 10.0, 20.0, 40.0]))
        for family, error in (('perfect', 0.0), ('imperfect', 1e-9)):
            out.append((family, paper_neck(n, 0.6, 0.0, error), paper_neck(n, 0.6, head, error),
                        upright(n, 0.6)))
    return out
