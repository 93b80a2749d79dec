"""Degenerate parameters, explicitly (docs/model.md section 3: "not optional").

Unloaded and horizontal-only loads (the flat configurations share t1 in {0, pi}),
exact symmetry, tiny rho, huge forces, a continuum of equilibria, and points on
(or within rounding of) the bifurcation sets: the unloaded boundary lines and
the symmetric-case boundaries of eqs. (15)-(16).  On and near those sets the
positions of merging equilibria are only defined to about the square (fold) or
cube (pitchfork) root of the rounding, so the tests there check what must hold
regardless: at most 6 equilibria, at most 2 stable, the exact flat equilibria
present, the symmetries of the set, tiny residuals, batch == single.
"""
import math

import numpy as np
import pytest

from oracle_solver import oracle_equilibria, torus_distance
from tensegrity_ros.core import (equilibria, equilibria_batch, gradient, ModuleParams,
                                 node_positions)

#: Numerically sensitive throughout: `make test-numerics` runs it under other CPUs' arithmetic.
pytestmark = pytest.mark.numerics


FLATS = [(0.0, 0.0), (0.0, math.pi), (math.pi, 0.0), (math.pi, math.pi)]
RESIDUAL = 1e-13          # Equilibrium.residual is max |g| / scale


def batch_of(p):
    return equilibria_batch(p.rho, L1=p.L1, L2=p.L2, ka=p.ka, kb=p.kb, kc=p.kc, f3x=p.f3x,
                            f3y=p.f3y, f4x=p.f4x, f4y=p.f4y, m1=p.m1, m2=p.m2, g=p.g)


def contains(s, theta, tol):
    return any(torus_distance(e.theta, theta) <= tol for e in s)


def check_invariants(p, s, mirror_tol=None, swap_tol=None):
    """What holds at every parameter point, degenerate or not."""
    assert s.status == 'ok'
    assert 1 <= len(s) <= 6
    assert s.num_stable <= 2
    kinds = [e.kind for e in s]
    if 'degenerate' not in kinds:
        assert s.num_stable >= 1 and 'maximum' in kinds
        assert len(s) % 2 == 0                                  # Poincare-Hopf parity
    for e in s:
        assert e.residual <= RESIDUAL
        assert -math.pi <= e.theta1 < math.pi and -math.pi <= e.theta2 < math.pi
    for a in s:                                                 # distinct
        assert sum(torus_distance(a.theta, b.theta) <= 1e-7 for b in s) == 1
    if mirror_tol is not None:                                  # the set is its own mirror image
        for e in s:
            assert contains(s, -e.theta, mirror_tol), e
    if swap_tol is not None:
        for e in s:
            assert contains(s, e.theta[::-1], swap_tol), e
    b = batch_of(p)
    assert b.num_equilibria[0] == len(s) and b.num_stable[0] == s.num_stable


# ---------------------------------------------------------------------------
# No vertical load: unloaded, horizontal-only forces

def horizontal_points(n, seed, unloaded):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        k = rng.uniform(5, 500, 3)
        fx = (0.0, 0.0) if unloaded else rng.normal(0, 80, 2)
        out.append(ModuleParams(rho=rng.uniform(0.01, 3), L1=rng.uniform(0.2, 3),
                                L2=rng.uniform(0.2, 3), ka=k[0], kb=k[1], kc=k[2],
                                f3x=fx[0], f4x=fx[1]))
    return out


@pytest.mark.parametrize('p', horizontal_points(40, 30, True) + horizontal_points(40, 31, False))
def test_no_vertical_load(p):
    s = equilibria(p)
    check_invariants(p, s, mirror_tol=1e-12)
    for f in FLATS:                                             # exact, whatever the springs
        assert contains(s, f, 1e-14), f
    non_flat = [e for e in s if not any(torus_distance(e.theta, f) <= 1e-9 for f in FLATS)]
    assert len(non_flat) in (0, 2)
    if non_flat:                                                # a mirrored pair
        assert torus_distance(non_flat[0].theta, -non_flat[1].theta) <= 1e-12
    for e in s:
        assert (np.max(np.abs(gradient(p, e.theta)))
                <= 1e-12 * (p.ka + p.kb + p.kc) * (p.rho + p.L1 + p.L2) ** 2)


@pytest.mark.parametrize('p', horizontal_points(6, 32, True) + horizontal_points(6, 33, False))
def test_no_vertical_load_against_oracle(p):
    o = oracle_equilibria(p)
    assert not o.ill_conditioned
    s = equilibria(p)
    assert len(s) == len(o.points) and s.num_stable == o.num_stable
    for q in o.points:
        assert contains(s, q, 1e-8)


def test_unloaded_unequal_springs_is_not_a_parallelogram():
    """The parallelogram of eq. (13) needs ka = kb = kc; otherwise (ka+kc) y3 = (kb+kc) y4."""
    p = ModuleParams(rho=0.7, L1=1.0, L2=1.2, ka=50.0, kb=150.0, kc=100.0)
    non_flat = [e for e in equilibria(p) if abs(math.sin(e.theta1)) > 1e-6]
    assert len(non_flat) == 2 and all(e.stable for e in non_flat)
    for e in non_flat:
        _, _, (x3, y3), (x4, y4) = node_positions(p, e.theta)
        assert (p.ka + p.kc) * y3 == pytest.approx((p.kb + p.kc) * y4, abs=1e-12)
        assert abs(y3 - y4) > 0.01


# ---------------------------------------------------------------------------
# Exact symmetry

@pytest.mark.parametrize('rho', [0.05, 0.3, 0.75, 1.0, 1.4, 2.5])
@pytest.mark.parametrize('F', [-30.0, -10.0, -1e-9, 0.0, 1e-9, 5.0, 30.0])
def test_exactly_symmetric(rho, F):
    p = ModuleParams(rho=rho, L1=1.3, L2=1.3, ka=80.0, kb=80.0, kc=120.0, f3x=2.0, f4x=-2.0,
                     f3y=F, f4y=F)
    s = equilibria(p)
    # swap (t1, t2) -> (t2, t1) maps the set to itself; so does the mirror when F = 0
    check_invariants(p, s, swap_tol=1e-12, mirror_tol=1e-12 if F == 0 else None)
    mirrored = equilibria(p.with_(f3y=-F, f4y=-F))
    assert len(mirrored) == len(s) and mirrored.num_stable == s.num_stable
    for e in s:
        assert contains(mirrored, -e.theta, 1e-12)


# ---------------------------------------------------------------------------
# Tiny rho, huge forces

@pytest.mark.parametrize('rho', [1e-3, 1e-5, 1e-7, 1e-9])
@pytest.mark.parametrize('loads', [(0.0, -5.0, 0.0, -3.5), (1.0, 4.0, -2.0, 1.0)])
def test_tiny_rho(rho, loads):
    f3x, f3y, f4x, f4y = loads
    p = ModuleParams(rho=rho, L1=1.0, L2=1.3, f3x=f3x, f3y=f3y, f4x=f4x, f4y=f4y)
    s = equilibria(p)
    check_invariants(p, s)
    assert len(s) == 4 and s.num_stable == 1
    # with A1 = A2 the springs only see t1 + t2, so the stable state balances the loads
    # against spring c, with a margin of order rho in one direction (a "soft" mode)
    (e,) = s.stable
    assert e.eigenvalues[0] < 50.0


def test_tiny_rho_unloaded():
    p = ModuleParams(rho=1e-3, L1=1.0, L2=1.3)
    s = equilibria(p)
    check_invariants(p, s, mirror_tol=1e-12)
    assert len(s) == 4 and s.num_stable == 1
    o = oracle_equilibria(p)
    assert len(o.points) == 4 and all(contains(s, q, 1e-8) for q in o.points)


@pytest.mark.parametrize('F', [1e4, 1e6, 1e9, 1e12])
@pytest.mark.parametrize('direction', [(0.3, -1.0, -0.2, -0.5), (1.0, 0.0, 1.0, 0.0),
                                       (0.0, 2.0, 0.5, -1.0)])
def test_huge_forces_rods_align_with_the_loads(F, direction):
    d3x, d3y, d4x, d4y = direction
    p = ModuleParams(rho=0.7, L1=1.2, L2=0.8, ka=40.0, kb=90.0, kc=60.0,
                     f3x=d3x * F, f3y=d3y * F, f4x=d4x * F, f4y=d4y * F)
    s = equilibria(p)
    check_invariants(p, s)
    assert len(s) == 4 and s.num_stable == 1                      # each rod: along or against
    along1, along2 = math.atan2(d3y, d3x), math.atan2(d4y, -d4x)  # A4 - A2 = L2 (-cos t2, sin t2)
    tol = 10 * 100 * (p.rho + p.L1 + p.L2) / F
    (e,) = s.stable
    assert torus_distance(e.theta, (along1, along2)) < tol
    kinds = {tuple(np.round(np.abs(np.cos((np.array(x.theta) - (along1, along2)) / 2)))): x.kind
             for x in s}
    assert kinds == {(1.0, 1.0): 'minimum', (0.0, 1.0): 'saddle', (1.0, 0.0): 'saddle',
                     (0.0, 0.0): 'maximum'}


# ---------------------------------------------------------------------------
# A continuum of equilibria

CONTINUUM = [{'rho': rho, 'ka': ka, 'kb': kb, 'kc': kc, 'L1': L1, 'L2': L2}
             for rho, ka, kb, kc, L1, L2 in [(0.3, 100, 100, 100, 1, 1),
                                             (1.7, 20, 300, 55, 0.4, 2.2),
                                             (0.01, 5, 7, 9, 3, 0.2)]]


@pytest.mark.parametrize('d', CONTINUUM)
def test_continuum(d):
    rho, ka, kb, kc = d['rho'], d['ka'], d['kb'], d['kc']
    p = ModuleParams(**d, f3x=-(ka + kc) * rho, f4x=(kb + kc) * rho)
    s = equilibria(p)
    assert s.status == 'continuum' and len(s) == 0 and s.num_stable == 0
    b = batch_of(p)
    assert b.continuum[0] and not b.valid[0].any() and b.num_stable[0] == 0
    # and it is one: every point of t1 + t2 in {0, pi} is an equilibrium
    t1 = np.linspace(-math.pi, math.pi, 50)
    scale = (ka + kb + kc) * (rho + d['L1'] + d['L2']) ** 2
    for offset in (0.0, math.pi):
        theta = np.stack([t1, offset - t1], -1)
        assert np.max(np.abs(gradient(p, theta))) <= 1e-12 * scale
    # rod weights cancelled by upward forces are the same continuum
    w = p.with_(m1=2.0, m2=0.5, f3y=1.0 * p.g, f4y=0.25 * p.g)
    assert equilibria(w).status == 'continuum'


@pytest.mark.parametrize('d', CONTINUUM)
@pytest.mark.parametrize('eps', [1e-3, -1e-4])
def test_near_continuum_is_solved(d, eps):
    rho, ka, kb, kc = d['rho'], d['ka'], d['kb'], d['kc']
    p = ModuleParams(**d, f3x=-(ka + kc) * rho * (1 + eps), f4x=(kb + kc) * rho * (1 - 2 * eps),
                     f3y=0.5 * eps * kc * d['L1'])
    s = equilibria(p)
    check_invariants(p, s)
    o = oracle_equilibria(p)
    if not o.ill_conditioned:
        assert len(s) == len(o.points) and s.num_stable == o.num_stable


def test_continuum_in_a_batch_does_not_disturb_the_others():
    rho = np.array([0.3, 0.3, 0.5])
    b = equilibria_batch(rho, f3x=[-60.0, -60.0 * (1 + 1e-3), 0.0], f4x=[60.0, 60.0, 0.0])
    assert list(b.continuum) == [True, False, False]
    assert b.num_equilibria[0] == 0 and b.num_equilibria[1] >= 2 and b.num_stable[2] == 2


# ---------------------------------------------------------------------------
# On and near the unloaded boundary lines |L1 - L2| = 2 rho, L1 + L2 = 2 rho

ON_LINES = [(0.75, 1.0, 0.5), (0.25, 1.0, 0.5), (0.25, 1.0, 1.5), (1.0, 1.0, 1.0),
            (1.25, 1.0, 1.5), (0.5, 2.0, 1.0), (1.5, 2.0, 1.0), (0.375, 0.5, 0.25)]


@pytest.mark.parametrize('k', [100.0, 37.0])
@pytest.mark.parametrize('rho, L1, L2', ON_LINES)
def test_on_unloaded_boundary_line(rho, L1, L2, k):
    assert 2 * rho in (abs(L1 - L2), L1 + L2)                   # exactly on a line
    p = ModuleParams(rho=rho, L1=L1, L2=L2, ka=k, kb=k, kc=k)
    s = equilibria(p)
    check_invariants(p, s, mirror_tol=1e-12)
    # the non-flat pair has merged into one flat configuration: four equilibria,
    # the flat one where they merged is degenerate (a zero eigenvalue), and
    # nothing is reported in its neighbourhood (no rounding-smeared copies)
    assert len(s) == 4
    for f in FLATS:
        assert contains(s, f, 1e-14)
    degenerate = [e for e in s if e.kind == 'degenerate']
    assert len(degenerate) == 1
    assert s.num_stable == 0                                    # no strict minimum on the line
    for a in s:
        for b in s:
            assert a is b or torus_distance(a.theta, b.theta) > 1.0


@pytest.mark.parametrize('rel', [1e-3, 1e-6, 1e-9, 1e-12, 1e-15])
@pytest.mark.parametrize('side', [1, -1])
@pytest.mark.parametrize('rho, L1, L2', ON_LINES[:4])
def test_near_unloaded_boundary_line(rho, L1, L2, rel, side):
    p = ModuleParams(rho=rho * (1 + side * rel), L1=L1, L2=L2, ka=70.0, kb=70.0, kc=70.0)
    s = equilibria(p)
    check_invariants(p, s, mirror_tol=1e-12)
    for f in FLATS:
        assert contains(s, f, 1e-14)
    inside = abs(L1 - L2) < 2 * p.rho < L1 + L2
    assert len(s) in ((6, 4) if inside else (4,))
    if rel >= 1e-6:                                              # resolvable: the generic answer
        assert len(s) == (6 if inside else 4)
        assert s.num_stable == (2 if inside else 1)


# ---------------------------------------------------------------------------
# On and near the symmetric-case boundaries (pitchfork C1 on eq. (15), fold C2 on (16))

def _roots(coefficients):
    return sorted(math.sqrt(x.real) for x in np.roots(coefficients)
                  if abs(x.imag) <= 1e-9 * abs(x) and x.real > 0)


def boundary_points():
    out = []
    for F in np.linspace(-40, 40, 33):
        r15 = _roots([64e12, 48e8 * F ** 2, 12e4 * F ** 4 - 16e8 * F ** 2, F ** 6])
        r16 = _roots([64e12, 48e8 * F ** 2 - 192e12, 12e4 * F ** 4 + 336e8 * F ** 2 + 192e12,
                      F ** 6 - 12e4 * F ** 4 + 48e8 * F ** 2 - 64e12])
        for r in r15 + r16:
            for rel in (0.0, 1e-15, -1e-15, 1e-13, -1e-13, 1e-11, -1e-11, 1e-9, -1e-9,
                        1e-7, -1e-7):
                out.append((r * (1 + rel), F))
    return out


def test_on_and_near_symmetric_boundaries():
    points = boundary_points()
    assert len(points) > 600
    rho = np.array([r for r, _ in points])
    F = np.array([f for _, f in points])
    b = equilibria_batch(rho, f3y=F, f4y=F)
    assert b.num_equilibria.max() <= 6 and b.num_stable.max() <= 2
    for i, (r, f) in enumerate(points):
        p = ModuleParams.paper(r, F3=f, F4=f)
        s = equilibria(p)
        check_invariants(p, s)                 # includes Poincare-Hopf when none degenerate
        # the batch hands such rows to the scalar solver: the same answer
        assert (b.num_equilibria[i], b.num_stable[i]) == (len(s), s.num_stable)


def test_on_and_near_general_folds():
    """The same on random (asymmetric, horizontally loaded) designs: folds in rho
    located by bisection on the number of equilibria, then +-1e-15 .. 1e-7 around."""
    rng = np.random.default_rng(34)
    points = []
    while len(points) < 400:
        k = rng.uniform(10, 300, 3)
        base = {'L1': rng.uniform(0.3, 2.5), 'L2': rng.uniform(0.3, 2.5),
                'ka': k[0], 'kb': k[1], 'kc': k[2],
                'f3x': rng.normal(0, 10), 'f3y': rng.normal(0, 20), 'f4x': rng.normal(0, 10),
                'f4y': rng.normal(0, 20)}
        rhos = np.linspace(0.01, 3, 40)
        counts = [len(equilibria(ModuleParams(rho=r, **base))) for r in rhos]
        for i in np.nonzero(np.diff(counts))[0]:
            lo, hi = rhos[i], rhos[i + 1]
            for _ in range(55):
                mid = 0.5 * (lo + hi)
                same = len(equilibria(ModuleParams(rho=mid, **base))) == counts[i]
                lo, hi = (mid, hi) if same else (lo, mid)
            for rel in (0.0, 1e-15, -1e-15, 1e-12, -1e-12, 1e-9, -1e-9, 1e-7, -1e-7):
                points.append(ModuleParams(rho=lo * (1 + rel), **base))
    for p in points:
        check_invariants(p, equilibria(p))


def test_past_a_fold_no_ghost_equilibrium():
    """Just past the fold C2 (F = 0.5) the merged pair is gone; no near-miss is reported."""
    p = ModuleParams.paper(0.9724973954374412, F3=0.5, F4=0.5)
    s = equilibria(p)
    check_invariants(p, s)
    assert len(s) == 4
    o = oracle_equilibria(p)
    assert len(o.points) == 4 and all(contains(s, q, 1e-8) for q in o.points)


def test_near_fold_with_unresolved_polynomial_roots():
    """F = -31: the polynomial returns the fold pair as a complex pair; the two real
    equilibria (1e-6 apart) or none, but never a single one or three minima."""
    for rel in (0.0, 1e-12, -1e-12, 1e-10, -1e-10, 1e-8, -1e-8):
        p = ModuleParams.paper(0.6000902119090877 * (1 + rel), F3=-31, F4=-31)
        s = equilibria(p)
        check_invariants(p, s)
        assert s.num_stable <= 2


def test_batch_blocks_join_seamlessly():
    """A batch larger than one block gives exactly what block-sized calls give."""
    from tensegrity_ros.core.module.equilibria import BATCH_BLOCK, equilibria_batch
    rng = np.random.default_rng(5)
    n = 2 * BATCH_BLOCK + 17
    args = {'rho': rng.uniform(0.05, 2, n), 'f3y': rng.uniform(-10, 10, n),
            'f4y': rng.uniform(-10, 10, n)}
    whole = equilibria_batch(**args)
    assert whole.theta.shape == (n, 6, 2)
    for start in (0, BATCH_BLOCK - 3, n - 20):
        part = equilibria_batch(**{k: a[start:start + 20] for k, a in args.items()})
        assert np.array_equal(part.valid, whole.valid[start:start + 20])
        assert np.array_equal(part.num_stable, whole.num_stable[start:start + 20])
        assert np.allclose(part.theta[part.valid], whole.theta[start:start + 20][part.valid])


def test_one_root_polished_twice_is_reported_once():
    """Found by hypothesis (mirror symmetry): a well-conditioned maximum reached from two
    candidates 1.8e-10 rad apart was listed twice, breaking Poincare-Hopf."""
    p = ModuleParams(rho=0.8045771465889175, L1=2.8359375, L2=1.75, ka=860.0, kb=20.48828125,
                     kc=1.1, f3y=-152.0, f4x=20.486328125)
    found = equilibria(p)
    kinds = [e.kind for e in found]
    assert len(found) == 4
    assert kinds.count('minimum') + kinds.count('maximum') == kinds.count('saddle')
    mirrored = equilibria(p.with_(f3y=152.0))
    assert sorted(np.round([e.theta1 for e in found], 9)) == \
        sorted(np.round([-e.theta1 for e in mirrored], 9))


def test_batch_solves_generic_rows_itself_and_agrees_with_the_scalar_solver(monkeypatch):
    """The batch fast path must not hand generic rows to the scalar path (a second-angle
    candidate that passed CANDIDATE_TOL by coincidence is pruned by CANDIDATE_RATIO
    instead of failing Newton and marking its row delicate); where it answers, it
    answers what the scalar solver does."""
    import importlib
    eq_module = importlib.import_module('tensegrity_ros.core.module.batch_solver')
    rng = np.random.default_rng(11)
    n = 20_000
    args = {'rho': rng.uniform(0.01, 3, n), 'L1': rng.uniform(0.2, 3, n),
            'L2': rng.uniform(0.2, 3, n), 'ka': rng.uniform(10, 500, n),
            'kb': rng.uniform(10, 500, n), 'kc': rng.uniform(10, 500, n),
            'f3x': rng.normal(0, 20, n), 'f3y': rng.normal(0, 20, n), 'f4x': rng.normal(0, 20, n),
            'f4y': rng.normal(0, 20, n), 'm1': rng.uniform(0, 2, n), 'm2': rng.uniform(0, 2, n)}
    scalar_rows = []
    solve_scalar = eq_module._solve_scalar
    monkeypatch.setattr(eq_module, '_solve_scalar',
                        lambda consts: scalar_rows.append(consts) or solve_scalar(consts))
    b = equilibria_batch(**args)
    assert len(scalar_rows) <= 0.001 * n, len(scalar_rows)
    for i in rng.choice(n, size=400, replace=False):
        p = ModuleParams(**{k: float(a[i]) for k, a in args.items()})
        s = equilibria(p)
        assert b.num_equilibria[i] == len(s) and b.num_stable[i] == s.num_stable, i
        for t in b.theta[i][b.valid[i]]:
            assert contains(s, t, 1e-9), (i, t)


@pytest.mark.parametrize('f3x', [5.707168277935829e-07, 0.25])
def test_clustered_first_angles_keep_every_candidate(f3x):
    """Found by hypothesis (swap symmetry) while trying CANDIDATE_RATIO pruning in the
    scalar path: at rho = L1 = L2 = 2 with tiny loads three first angles cluster at
    t1 = 0, the near miss (0, 0) checks better than the genuine saddle (0, -pi), and
    pruning lost it.  The scalar path never prunes; the batch only prunes isolated roots."""
    p = ModuleParams(rho=2.0, L1=2.0, L2=2.0, ka=945.0, kb=945.0, kc=945.0, f3x=f3x,
                     f3y=5.707168277935829e-07, f4x=-f3x, f4y=5.707168277935829e-07)
    s = equilibria(p)
    check_invariants(p, s)
    for theta in ((0.0, -math.pi), (-math.pi, 0.0), (-math.pi, -math.pi)):
        assert contains(s, theta, 1e-9), theta
    b = batch_of(p)
    assert b.num_equilibria[0] == len(s) == 4 and b.num_stable[0] == s.num_stable == 1


@pytest.mark.parametrize('p', [ModuleParams.paper(0.5, F3=5, F4=5),          # 6 equilibria
                               ModuleParams.paper(1.5, F3=-10, F4=-10),       # 4 equilibria
                               ModuleParams(rho=0.7, L2=1.3, f3x=3, f3y=-4, f4x=1, f4y=2, m1=0.2)])
def test_batch_detects_lost_roots(monkeypatch, p):
    """If the fast path lost the candidates of one first angle (or two, of a set of four),
    Poincare-Hopf or the Morse inequalities (>= 1 minimum, >= 1 maximum, >= 2 saddles on
    the torus) no longer hold, and the row is solved by the scalar path: still the right
    answer.  (A minimum and a saddle lost from six leave a valid Morse count: that is why
    pruning is limited to isolated roots, see CANDIDATE_RATIO.)"""
    import importlib
    import itertools
    eq_module = importlib.import_module('tensegrity_ros.core.module.batch_solver')
    s = equilibria(p)
    candidate_limit = eq_module._candidate_limit
    lost = []

    def losing(check, scale, isolated):
        limit = candidate_limit(check, scale, isolated).copy()
        for i in lost:
            if i < limit.shape[0]:
                limit[i] = -1.0                 # no candidate of the i-th first angle passes
        return limit

    monkeypatch.setattr(eq_module, '_candidate_limit', losing)
    roots = len(s)                              # one first angle per equilibrium here
    for size in (1, 2) if roots == 4 else (1,):
        for lost[:] in itertools.combinations(range(roots), size):
            b = batch_of(p)
            assert b.num_equilibria[0] == len(s) and b.num_stable[0] == s.num_stable, lost
            for t in b.theta[0][b.valid[0]]:
                assert contains(s, t, 1e-9), (lost, t)
