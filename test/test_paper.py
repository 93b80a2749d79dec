"""Every statement of docs/model.md section 2 (what the paper states), as a test.

Paper: Wenger & Chablat, "Kinetostatic analysis and solution classification of a
class of planar tensegrity mechanisms" (seeds/000_32577c4bb2d10654.txt).  The
paper normalises L1 = 1 and k = 100; several statements are checked for other
L1 and k too, since they are scale-free.
"""
import math

import numpy as np
import pytest

from tensegrity_ros.core import equilibria, equilibria_batch, hessian, ModuleParams, node_positions
from tensegrity_ros.core.module.equilibria import DEGENERACY_TOL

TWO_PI = 2 * math.pi
FLATS = [(0.0, 0.0), (0.0, math.pi), (math.pi, 0.0), (math.pi, math.pi)]


def torus_distance(a, b):
    d = np.abs(np.asarray(a, float) - np.asarray(b, float)) % TWO_PI
    return float(np.max(np.minimum(d, TWO_PI - d)))


def is_flat(e, tol=1e-9):
    return min(torus_distance(e.theta, f) for f in FLATS) <= tol


def has_degenerate(ev):
    """Batch eigenvalue rows (..., 2) -> any |lambda| <= DEGENERACY_TOL * max|lambda|."""
    scale = np.max(np.abs(ev), axis=-1)
    return np.abs(ev[..., 0]) <= DEGENERACY_TOL * scale


# ---------------------------------------------------------------------------
# 1. At most 6 equilibria, of which 1 or 2 are stable.

def paper_grid():
    rho = np.linspace(0.01, 2.0, 60)
    L2 = np.array([0.5, 0.9, 1.0, 1.2, 1.5, 2.0])
    F = np.array([-40, -10, -3, -0.5, 0, 0.5, 3, 10, 40])
    return [a.ravel() for a in np.meshgrid(rho, L2, F, F, indexing='ij')]


def test_at_most_six_equilibria_one_or_two_stable_paper_ranges():
    rho, L2, F3, F4 = paper_grid()
    b = equilibria_batch(rho, L2=L2, f3y=F3, f4y=F4)
    assert not b.continuum.any()
    assert b.num_equilibria.max() <= 6
    assert b.num_equilibria.min() >= 2                       # a maximum and a minimum at least
    assert b.num_stable.max() <= 2
    degenerate = (has_degenerate(b.eigenvalues) & b.valid).any(axis=1)
    assert set(np.unique(b.num_stable[~degenerate])) <= {1, 2}
    assert degenerate.mean() < 0.01                          # the grid is not built on boundaries
    # both counts occur, with the two-stable region a sizeable part of the grid
    assert 0.1 < np.mean(b.num_stable == 2) < 0.9


def test_at_most_six_equilibria_one_or_two_stable_general_parameters():
    """Also with horizontal loads, three stiffnesses and rod weights (single solver)."""
    rng = np.random.default_rng(20)
    for _ in range(400):
        k = rng.uniform(10, 500, 3)
        p = ModuleParams(rho=rng.uniform(0.01, 3), L1=rng.uniform(0.2, 3), L2=rng.uniform(0.2, 3),
                         ka=k[0], kb=k[1], kc=k[2], f3x=rng.normal(0, 50), f3y=rng.normal(0, 50),
                         f4x=rng.normal(0, 50), f4y=rng.normal(0, 50), m1=rng.uniform(0, 2),
                         m2=rng.uniform(0, 2))
        s = equilibria(p)
        assert s.status == 'ok'
        assert 2 <= len(s) <= 6
        assert s.num_stable <= 2
        if not any(e.kind == 'degenerate' for e in s):
            assert s.num_stable in (1, 2)
            assert sum(e.kind == 'maximum' for e in s) >= 1


# ---------------------------------------------------------------------------
# 2. Unloaded.

def in_two_stable_region(rho, L1, L2):
    return abs(L1 - L2) < 2 * rho < L1 + L2


def off_lines(rho, L1, L2, margin):
    return min(abs(2 * rho - abs(L1 - L2)), abs(2 * rho - (L1 + L2))) > margin


UNLOADED_CASES = [(rho, L1, L2, k)
                  for L1, k in [(1.0, 100.0), (0.6, 100.0), (2.5, 7.0), (1.0, 3000.0)]
                  for rho in np.linspace(0.05, 4.0, 14) * L1
                  for L2 in np.linspace(0.1, 4.0, 9) * L1
                  if off_lines(rho, L1, L2, 0.02 * L1)]


@pytest.mark.numerics
@pytest.mark.parametrize('rho, L1, L2, k', UNLOADED_CASES)
def test_unloaded_flat_configurations_and_parallelogram(rho, L1, L2, k):
    p = ModuleParams(rho=rho, L1=L1, L2=L2, ka=k, kb=k, kc=k)
    s = equilibria(p)
    assert s.status == 'ok'
    # the four flat configurations are always equilibria
    for f in FLATS:
        assert min(torus_distance(e.theta, f) for e in s) <= 1e-12, f
    non_flat = [e for e in s if not is_flat(e)]
    if in_two_stable_region(rho, L1, L2):
        assert len(s) == 6 and len(non_flat) == 2
        assert s.num_stable == 2
        assert all(e.stable for e in non_flat)               # two stable, non-flat
        a, b = non_flat
        assert torus_distance(a.theta, -b.theta) <= 1e-12    # a mirrored pair
        for e in non_flat:
            _, _, (x3, y3), (x4, y4) = node_positions(p, e.theta)
            assert y3 == pytest.approx(y4, abs=1e-12 * L1)   # parallelogram, even if L1 != L2
            assert x3 - x4 == pytest.approx(rho, abs=1e-12 * L1)
            # eq. (13), in its geometric form: A3 and A4 are the apex of the
            # triangle with sides L1, L2, 2 rho (the printed eq. (13) has lost
            # the square root and normalisation of Q).
            q = ((L1 + L2) ** 2 - 4 * rho ** 2) * ((L1 - L2) ** 2 - 4 * rho ** 2)
            assert q < 0
            assert abs(y3) == pytest.approx(math.sqrt(-q) / (4 * rho), abs=1e-12 * L1)
            assert L1 * math.cos(e.theta1) == pytest.approx(
                (L1 ** 2 - L2 ** 2 + 4 * rho ** 2) / (4 * rho), abs=1e-12 * L1)
            assert L2 * math.cos(e.theta2) == pytest.approx(
                (L2 ** 2 - L1 ** 2 + 4 * rho ** 2) / (4 * rho), abs=1e-12 * L1)
            assert math.atan2(abs(y3), x3) == pytest.approx(
                math.atan2(math.sqrt(-q), L1 ** 2 - L2 ** 2 + 4 * rho ** 2), abs=1e-12)
    else:
        assert len(s) == 4 and not non_flat                  # only the flat ones
        assert s.num_stable == 1
        assert is_flat(s.stable[0])
    # "three of the four flat solutions are always unstable" (section 3.2)
    assert sum(e.stable for e in s if is_flat(e)) <= 1


def test_unloaded_region_on_a_fine_grid():
    """The lines 2rho - L2 - 1 = 0, 2rho - L2 + 1 = 0, 2rho + L2 - 1 = 0 (L1 = 1), fig. 3."""
    rho, L2 = [a.ravel() for a in np.meshgrid(np.linspace(0.005, 4, 250),
                                              np.linspace(0.005, 4, 250))]
    lines = np.minimum.reduce([abs(2 * rho - L2 - 1), abs(2 * rho - L2 + 1),
                               abs(2 * rho + L2 - 1)])
    keep = lines > 1e-3
    rho, L2 = rho[keep], L2[keep]
    b = equilibria_batch(rho, L2=L2)
    inside = np.abs(1 - L2) < 2 * rho
    inside &= 2 * rho < 1 + L2
    assert np.array_equal(b.num_stable, np.where(inside, 2, 1))
    assert np.array_equal(b.num_equilibria, np.where(inside, 6, 4))
    # the region has width 1 in rho for L2 > 1 and 2 rho in (1 - L2, 1 + L2) below
    assert inside.any() and (~inside).any()


@pytest.mark.numerics
def test_fig3_two_mirrored_stable_solutions():
    """Fig. 3 (right): rho = 1, L2 = 3/2."""
    s = equilibria(ModuleParams.paper(1.0, L2=1.5))
    a, b = s.stable
    assert torus_distance(a.theta, -b.theta) < 1e-12 and not is_flat(a)
    y = [node_positions(s.params, e.theta)[2][1] for e in (a, b)]
    assert sorted(np.sign(y)) == [-1, 1]


# ---------------------------------------------------------------------------
# 3. Symmetric design and load.

SYMMETRIC_CASES = [(rho, F, L, k) for L, k in [(1.0, 100.0), (0.5, 100.0), (2.0, 30.0)]
                   for rho in np.linspace(0.02, 2.0, 12) * L
                   for F in (-40.0, -10.0, -2.0, 1.0, 7.0, 25.0)]


@pytest.mark.numerics
@pytest.mark.parametrize('rho, F, L, k', SYMMETRIC_CASES)
def test_symmetric_case_asymmetric_equilibria_are_unstable(rho, F, L, k):
    """Eq. (10): det H < 0 for the equilibria with t1 != t2 (at most two, swapped)."""
    p = ModuleParams.paper(rho, L1=L, L2=L, F3=F, F4=F, k=k)
    s = equilibria(p)
    asymmetric = [e for e in s if torus_distance([e.theta1], [e.theta2]) > 1e-6]
    assert len(asymmetric) in (0, 2)
    for e in asymmetric:
        assert e.kind == 'saddle' and not e.stable
        assert np.linalg.det(hessian(p, e.theta)) < 0
        assert any(torus_distance(e.theta, o.theta[::-1]) < 1e-9 for o in asymmetric)
    # the stable ones are symmetric: y3 = y4 (Arsenault's assumption holds for them)
    for e in s.stable:
        assert e.theta1 == pytest.approx(e.theta2, abs=1e-9)


def _real_positive_roots_in_rho(coefficients_in_rho2):
    out = []
    for x in np.roots(coefficients_in_rho2):
        if abs(x.imag) <= 1e-9 * abs(x) and x.real > 0:
            out.append(math.sqrt(x.real))
    return sorted(out)


def eq15_roots(F):
    """Eq. (15) (L = 1, k = 100) as a cubic in rho^2."""
    return _real_positive_roots_in_rho([64e12, 48e8 * F ** 2, 12e4 * F ** 4 - 16e8 * F ** 2,
                                        F ** 6])


def eq16_roots(F):
    """Eq. (16) (L = 1, k = 100) as a cubic in rho^2."""
    return _real_positive_roots_in_rho([64e12, 48e8 * F ** 2 - 192e12,
                                        12e4 * F ** 4 + 336e8 * F ** 2 + 192e12,
                                        F ** 6 - 12e4 * F ** 4 + 48e8 * F ** 2 - 64e12])


def test_eq15_eq16_as_transcribed():
    """The cubic forms above are eqs. (15) and (16) of the paper, term by term."""
    rng = np.random.default_rng(21)
    for F, rho in rng.uniform([-10, 0], [10, 2], (20, 2)):
        e15 = (F ** 6 + 12e4 * F ** 4 * rho ** 2 + 48e8 * F ** 2 * rho ** 4 + 64e12 * rho ** 6
               - 16e8 * F ** 2 * rho ** 2)
        e16 = (F ** 6 + 12e4 * F ** 4 * rho ** 2 + 48e8 * F ** 2 * rho ** 4 + 64e12 * rho ** 6
               - 12e4 * F ** 4 + 336e8 * F ** 2 * rho ** 2 - 192e12 * rho ** 4 + 48e8 * F ** 2
               + 192e12 * rho ** 2 - 64e12)
        x = rho ** 2
        assert np.polyval([64e12, 48e8 * F ** 2, 12e4 * F ** 4 - 16e8 * F ** 2, F ** 6],
                          x) == pytest.approx(e15, rel=1e-9, abs=1e-3)
        assert np.polyval([64e12, 48e8 * F ** 2 - 192e12, 12e4 * F ** 4 + 336e8 * F ** 2 + 192e12,
                           F ** 6 - 12e4 * F ** 4 + 48e8 * F ** 2 - 64e12],
                          x) == pytest.approx(e16, rel=1e-9, abs=1e-3)


def stable_count(rho, F):
    return equilibria(ModuleParams.paper(rho, F3=F, F4=F)).num_stable


def transitions(F, lo=0.002, hi=2.0, n=200, width=1e-12):
    """Every rho in (lo, hi) where num_stable changes, bisected on ``equilibria``."""
    grid = np.linspace(lo, hi, n)
    counts = [stable_count(r, F) for r in grid]
    found = []
    for i in range(n - 1):
        if counts[i] == counts[i + 1]:
            continue
        a, b = grid[i], grid[i + 1]
        while b - a > width:
            mid = 0.5 * (a + b)
            if stable_count(mid, F) == counts[i]:
                a = mid
            else:
                b = mid
        found.append((0.5 * (a + b), counts[i], counts[i + 1]))
    return found


@pytest.mark.numerics
@pytest.mark.parametrize('F', [-10.0, -7.5, -4.0, -1.0, -0.2, 0.2, 1.0, 4.0, 7.5, 10.0])
def test_symmetric_two_stable_boundary_is_eq15_and_eq16(F):
    found = transitions(F)
    # one two-stable interval: 1 -> 2 at its left end, 2 -> 1 at its right end
    assert [(a, b) for _, a, b in found] == [(1, 2), (2, 1)]
    (left, _, _), (right, _, _) = found
    # the left end (a pitchfork, C1 of fig. 8a) is a real root of eq. (15),
    # the right end (a fold, C2) a real root of eq. (16)
    assert min(abs(left - r) for r in eq15_roots(F)) < 1e-6
    assert min(abs(right - r) for r in eq16_roots(F)) < 1e-6
    # mirror symmetry of the (rho, F) plane: same boundaries for -F
    assert eq15_roots(F) == pytest.approx(eq15_roots(-F))


def test_symmetric_boundary_roots_that_are_not_stability_boundaries():
    """Eq. (15) has a second real root near rho = 0 that only changes the unstable set."""
    small, big = eq15_roots(-10.0)
    assert small < 0.01 < big
    for rho in (small * 0.5, small * 2):
        assert stable_count(rho, -10.0) == 1
    n_below = len(equilibria(ModuleParams.paper(small * 0.9, F3=-10, F4=-10)))
    n_above = len(equilibria(ModuleParams.paper(small * 1.1, F3=-10, F4=-10)))
    assert {n_below, n_above} == {4, 6}


@pytest.mark.parametrize('F', [-10.0, 10.0])
def test_fig4_force_ten(F):
    """F = +-10: two stable at rho = 3/4, one at rho = 0.2 and 1.5 (figs. 4a-4d)."""
    assert stable_count(0.75, F) == 2
    for rho in (0.2, 1.5):
        s = equilibria(ModuleParams.paper(rho, F3=F, F4=F))
        assert s.num_stable == 1
        (e,) = s.stable
        _, _, a3, a4 = node_positions(s.params, e.theta)
        # y3, y4 < 0 under pushing (F < 0), > 0 under pulling (F > 0)
        assert np.sign(a3[1]) == np.sign(a4[1]) == np.sign(F)
    # fig. 4a/4b right: the two stable solutions at rho = 3/4 are not mirror images
    a, b = equilibria(ModuleParams.paper(0.75, F3=F, F4=F)).stable
    assert abs(abs(a.theta1) - abs(b.theta1)) > 0.05


def test_two_stable_width_is_one_when_unloaded_and_shrinks_with_force():
    """Section 4.2: the operation range is 1 for F = 0 and decreases with |F|."""
    rho = np.linspace(0.0005, 2.0, 4000)
    widths = []
    for F in (0.0, 1.0, 2.5, 5.0, 10.0):
        b = equilibria_batch(rho, f3y=-F, f4y=-F)
        widths.append(np.mean(b.num_stable == 2) * (rho[-1] - rho[0]))
    assert widths[0] == pytest.approx(1.0, abs=2e-3)
    assert all(w1 > w2 for w1, w2 in zip(widths, widths[1:]))


# ---------------------------------------------------------------------------
# 4. Fig. 7: F3 = F4 = -10, L2 = 3/2.

def test_fig7():
    assert equilibria(ModuleParams.paper(0.7, L2=1.5, F3=-10, F4=-10)).num_stable == 2
    s = equilibria(ModuleParams.paper(1.5, L2=1.5, F3=-10, F4=-10))
    assert s.num_stable == 1


def test_fig7_operation_range_is_widest_for_l2_one():
    """Section 4.3: for F3 = F4 = -10 the two-stable range in rho is widest at L2 = 1,
    where it equals the symmetric-case range (the gap between eqs. (15) and (16))."""
    rho = np.linspace(0.0005, 2.0, 4000)
    width = {}
    for L2 in (0.6, 0.8, 1.0, 1.2, 1.5):
        b = equilibria_batch(rho, L2=L2, f3y=-10, f4y=-10)
        width[L2] = np.mean(b.num_stable == 2) * (rho[-1] - rho[0])
    assert max(width, key=width.get) == 1.0
    assert width[1.0] == pytest.approx(eq16_roots(-10)[0] - eq15_roots(-10)[-1], abs=2e-3)
    # decreases slowly above L2 = 1, much faster below
    assert width[1.0] - width[1.2] < width[1.0] - width[0.8]


# ---------------------------------------------------------------------------
# 5. Fig. 6: the two-stable region shrinks and vanishes as forces grow.

@pytest.mark.parametrize('L2', [0.5, 1.0, 1.5])
def test_fig6_two_stable_region_shrinks_and_vanishes(L2):
    rho = np.linspace(0.002, 3.0, 300)
    directions = [(1.0, 1.0), (1.0, 0.4), (0.3, 1.0)]          # F3, F4 >= 0 as in figs. 5-6
    scales = np.array([0.0, 5, 10, 20, 40, 60, 80, 120, 200, 400])
    R, S, D = np.meshgrid(rho, scales, np.arange(len(directions)), indexing='ij')
    d = np.array(directions)[D]
    b = equilibria_batch(R, L2=L2, f3y=S * d[..., 0], f4y=S * d[..., 1])
    two = (b.num_stable == 2).reshape(R.shape)
    measure = two.mean(axis=0)                                  # (scales, directions)
    assert np.all(measure[0] > 0.15)
    assert np.all(np.diff(measure, axis=0) <= 1e-12)            # shrinks ...
    assert np.all(measure[-3:] == 0)                            # ... and vanishes
    # and not only along rays: the volume in the box [0, s]^2 of (F3, F4) shrinks too
    F = np.linspace(0, 400, 21)
    R2, F3, F4 = [a.ravel() for a in np.meshgrid(rho[::3], F, F, indexing='ij')]
    two = (equilibria_batch(R2, L2=L2, f3y=F3, f4y=F4).num_stable == 2)
    assert not two[np.maximum(F3, F4) >= 200].any()


# ---------------------------------------------------------------------------
# 6. Fig. 8a/8b: static structure of the branches (tracking is tested elsewhere).

def test_fig8a_two_stable_lower_branch_symmetric_negative():
    s = equilibria(ModuleParams.paper(0.5, F3=5, F4=5))
    assert s.num_stable == 2
    lower, upper = sorted(s.stable, key=lambda e: e.theta1)
    assert lower.theta1 == pytest.approx(lower.theta2, abs=1e-12) and lower.theta1 < 0
    assert upper.theta1 == pytest.approx(upper.theta2, abs=1e-12) and upper.theta1 > 0


def lower_branch(rho, F=5.0, L2=1.0):
    s = equilibria(ModuleParams.paper(rho, L2=L2, F3=F, F4=F))
    return s, [e for e in s if -2.5 < e.theta1 < -0.2]


@pytest.mark.numerics
def test_fig8a_c1_is_a_symmetry_breaking_pitchfork():
    c1 = eq15_roots(5.0)[-1]
    for eps in (1e-2, 1e-3, 1e-4):
        # above C1: the lower symmetric minimum, flanked by the swapped asymmetric saddles
        s, near = lower_branch(c1 + eps)
        (minimum,) = [e for e in near if e.stable]
        assert minimum.theta1 == pytest.approx(minimum.theta2, abs=1e-12)
        saddles = [e for e in near if not e.stable]
        assert len(saddles) == 2 and all(e.kind == 'saddle' for e in saddles)
        gap = max(torus_distance(e.theta, minimum.theta) for e in saddles)
        assert gap < 6 * math.sqrt(eps)                         # merging like sqrt(rho - C1)
        # below C1: the symmetric equilibrium continues as a saddle, alone
        s, near = lower_branch(c1 - eps)
        assert len(near) == 1 and near[0].kind == 'saddle'
        assert near[0].theta1 == pytest.approx(near[0].theta2, abs=1e-12)
        assert torus_distance(near[0].theta, minimum.theta) < 10 * eps


def test_fig8a_c2_is_a_fold():
    c2 = eq16_roots(5.0)[0]
    for eps in (1e-2, 1e-3, 1e-4):
        s, near = lower_branch(c2 - eps)
        kinds = sorted(e.kind for e in near)
        assert kinds == ['minimum', 'saddle']                   # a minimum meets a saddle
        assert torus_distance(near[0].theta, near[1].theta) < 6 * math.sqrt(eps)
        s, near = lower_branch(c2 + eps)
        assert near == []                                       # and both are gone
        assert s.num_stable == 1 and s.stable[0].theta1 > 0     # the jump goes up


@pytest.mark.numerics
def test_fig8b_c1_becomes_a_fold_for_l2_1_05():
    rho = np.linspace(0.01, 1.2, 600)
    b = equilibria_batch(rho, L2=1.05, f3y=5, f4y=5)
    left = int(np.argmax(b.num_stable == 2))                   # first two-stable point
    lo, hi = rho[left - 1], rho[left]
    while hi - lo > 1e-11:
        mid = 0.5 * (lo + hi)
        if equilibria(ModuleParams.paper(mid, L2=1.05, F3=5, F4=5)).num_stable == 2:
            hi = mid
        else:
            lo = mid
    eps = 1e-6
    s, near = lower_branch(hi + eps, L2=1.05)
    (minimum,) = [e for e in near if e.stable]
    partner = min((e for e in near if not e.stable),
                  key=lambda e: torus_distance(e.theta, minimum.theta))
    assert partner.kind == 'saddle'
    assert torus_distance(partner.theta, minimum.theta) < 10 * math.sqrt(eps)
    # past the boundary nothing is left near the lost minimum: a fold, not a pitchfork
    s, near = lower_branch(lo - eps, L2=1.05)
    assert all(torus_distance(e.theta, minimum.theta) > 0.1 for e in s)
