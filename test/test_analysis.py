"""Exact analysis (tensegrity_ros.core.analysis): degenerate curves, operation ranges, point C.

References are independent of the code under test: the paper's closed forms
(eqs. (15), (16), the three lines of section 4.1), the exact solver
``equilibria`` / ``equilibria_batch`` (bisection on stable counts, maps), and a
multi-start Newton on ``module.gradient`` near the umbilic (where the polynomial
solver's root clustering limits its resolution).
"""
import math

import numpy as np
import pytest

from tensegrity_ros.core.analysis import (BRANCH_POINT, Curve, degenerate_curves, FOLD, LIMIT,
                                          operation_range, OperationRange, two_stable_limit)
from tensegrity_ros.core.module.equilibria import equilibria, equilibria_batch
from tensegrity_ros.core.module.model import gradient, hessian, InvalidParameterError, ModuleParams

K = 100.0


# ---------------------------------------------------------------------------
# helpers

def eq15_terms(rho, F):
    """Terms of the paper's eq. (15) (L = 1, k = 100): the symmetric pitchfork."""
    return np.array([F ** 6, 12e4 * F ** 4 * rho ** 2, 48e8 * F ** 2 * rho ** 4,
                     64e12 * rho ** 6, -16e8 * F ** 2 * rho ** 2])


def eq16_terms(rho, F):
    """Terms of the paper's eq. (16): the fold of the symmetric branch."""
    return np.array([F ** 6, 12e4 * F ** 4 * rho ** 2, 48e8 * F ** 2 * rho ** 4,
                     64e12 * rho ** 6, -12e4 * F ** 4, 336e8 * F ** 2 * rho ** 2,
                     -192e12 * rho ** 4, 48e8 * F ** 2, 192e12 * rho ** 2,
                     -64e12 + 0.0 * rho])


def relative(terms):
    """|sum| / sum |terms|: a scale-free residual of a polynomial equation."""
    return np.abs(terms.sum(axis=0)) / np.abs(terms).sum(axis=0)


def real_rhos(F, which):
    """Positive real rho on eq. (15) or (16) for one F (cubics in rho^2)."""
    if which == 15:
        c = [64e12, 48e8 * F ** 2, 12e4 * F ** 4 - 16e8 * F ** 2, F ** 6]
    else:
        c = [64e12, 48e8 * F ** 2 - 192e12, 12e4 * F ** 4 + 336e8 * F ** 2 + 192e12,
             F ** 6 - 12e4 * F ** 4 + 48e8 * F ** 2 - 64e12]
    return [math.sqrt(u.real) for u in np.roots(c) if abs(u.imag) <= 1e-9 * abs(u) and u.real > 0]


def distance_to_polyline(p, poly):
    a, b = poly[:-1], poly[1:]
    ab = b - a
    s = np.clip(np.einsum('ij,ij->i', p - a, ab)
                / np.maximum(np.einsum('ij,ij->i', ab, ab), 1e-300), 0.0, 1.0)
    return float(np.min(np.linalg.norm(a + s[:, None] * ab - p, axis=1)))


def bisect_stable_count(params, rho_in, rho_out, tol=1e-11):
    """The rho between rho_in and rho_out where equilibria()'s stable count changes."""
    n_in = equilibria(params.with_(rho=rho_in)).num_stable
    assert equilibria(params.with_(rho=rho_out)).num_stable != n_in
    while abs(rho_out - rho_in) > tol:
        mid = 0.5 * (rho_in + rho_out)
        if equilibria(params.with_(rho=mid)).num_stable == n_in:
            rho_in = mid
        else:
            rho_out = mid
    return 0.5 * (rho_in + rho_out)


def _torus_distance(a, b):
    return float(np.max(np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))))


def local_equilibria(params, center, radius, n=7):
    """Multi-start Newton on module.gradient around ``center`` (independent of the solvers)."""
    found = []
    for a in np.linspace(-radius, radius, n):
        for b in np.linspace(-radius, radius, n):
            th = np.array(center) + [a, b]
            converged = False
            for _ in range(80):
                step = np.linalg.solve(hessian(params, th), gradient(params, th))
                th = th - step
                if np.max(np.abs(step)) < 1e-15:
                    converged = True
                    break
            if (converged and np.max(np.abs(gradient(params, th))) < 1e-11
                    and np.max(np.abs(th - center)) < 3 * radius
                    and not any(np.max(np.abs(th - f)) < 2e-8 + 1e-3 * radius for f in found)):
                found.append(th)
    return [(f, np.linalg.eigvalsh(hessian(params, f))) for f in found]


# ---------------------------------------------------------------------------
# degenerate curves

@pytest.fixture(scope='module')
def symmetric_curves():
    base = ModuleParams.paper(1.0)
    return {box: degenerate_curves(base, 'rho', (0.001, 2.0), 'F', box)
            for box in ((-10.0, 0.0), (0.0, 10.0))}


@pytest.mark.parametrize('box', [(-10.0, 0.0), (0.0, 10.0)])
def test_symmetric_curves_lie_on_eqs_15_and_16(symmetric_curves, box):
    curves = symmetric_curves[box]
    assert curves and all(isinstance(c, Curve) for c in curves)
    stable_points = 0
    for c in curves:
        rho, F = c.points.T
        r15, r16 = relative(eq15_terms(rho, F)), relative(eq16_terms(rho, F))
        # every point of every curve, and in particular of the stable-count-changing ones
        assert np.all(np.minimum(r15, r16) < 1e-9), (c.kind, np.minimum(r15, r16).max())
        if c.kind == BRANCH_POINT:
            assert c.symmetry == 'swap'
            assert np.all(r15 < 1e-9)
            assert np.allclose(c.theta[:, 0], c.theta[:, 1], atol=1e-9)
        else:
            assert np.all(r16 < 1e-12)
        stable_points += int(c.stable_boundary.sum())
        # one eigenvalue vanishes at every point
        assert np.all(np.min(np.abs(c.eigenvalues), axis=1) < 1e-8 * np.max(np.abs(c.eigenvalues)))
    assert stable_points > 50
    assert sum(c.changes_stable_count for c in curves) == 2     # (15) outer branch and (16)


@pytest.mark.parametrize('box', [(-10.0, 0.0), (0.0, 10.0)])
def test_all_real_branches_of_eqs_15_16_are_covered(symmetric_curves, box):
    curves = symmetric_curves[box]
    lo, hi = np.array([0.001, box[0]]), np.array([2.0, box[1]])
    polys = [(c.points - lo) / (hi - lo) for c in curves]
    checked = 0
    for F in np.linspace(box[0], box[1], 201)[1:-1]:
        for which in (15, 16):
            for rho in real_rhos(F, which):
                if lo[0] < rho < hi[0]:
                    p = (np.array([rho, F]) - lo) / (hi - lo)
                    assert min(distance_to_polyline(p, q) for q in polys) < 2e-3, (which, rho, F)
                    checked += 1
    assert checked > 400          # three real branches (two of (15), one of (16))


def test_symmetric_paper_examples_on_the_right_side(symmetric_curves):
    """F = -10: two stable at rho = 3/4 (between the curves), one at 0.2 and 1.5."""
    curves = symmetric_curves[(-10.0, 0.0)]
    crossings = sorted(c.points[np.argmin(np.abs(c.points[:, 1] + 10.0)), 0]
                       for c in curves if c.changes_stable_count)
    lo, hi = crossings
    assert lo < 0.75 < hi and not lo < 0.2 < hi and not lo < 1.5 < hi
    assert equilibria(ModuleParams.paper(0.75, F3=-10, F4=-10)).num_stable == 2


def test_unloaded_boundaries_are_the_three_lines():
    curves = degenerate_curves(ModuleParams.paper(1.0), 'rho', (0.001, 2.0), 'L2', (0.001, 2.0))
    lines = {'2rho-L2-1': lambda r, L: 2 * r - L - 1, '2rho-L2+1': lambda r, L: 2 * r - L + 1,
             '2rho+L2-1': lambda r, L: 2 * r + L - 1}
    matched = set()
    for c in curves:
        assert c.kind == BRANCH_POINT and c.symmetry == 'mirror'
        assert c.changes_stable_count and np.all(c.stable_boundary)
        # flat configurations (t1, t2 in {0, pi})
        assert np.all(np.min(np.abs(np.stack([c.theta, np.abs(c.theta) - np.pi])), axis=0) < 1e-12)
        on = [name for name, f in lines.items() if np.all(np.abs(f(*c.points.T)) < 1e-12)]
        assert len(on) == 1, c.points
        matched.add(on[0])
        # the whole in-box segment of the line is traced: both ends on the box edge
        for end in (c.points[0], c.points[-1]):
            assert (np.isclose(end[0], 0.001) or np.isclose(end[0], 2.0)
                    or np.isclose(end[1], 0.001) or np.isclose(end[1], 2.0))
    assert matched == set(lines)


@pytest.mark.parametrize('base, x, xr, y, yr', [
    (ModuleParams.paper(1.0, L2=1.5), 'rho', (0.01, 2.0), 'F3', (-20.0, 20.0)),
    (ModuleParams.paper(0.5), 'F3', (0.0, 100.0), 'F4', (0.0, 100.0)),
    (ModuleParams.paper(1.0, F3=5.0, F4=5.0), 'rho', (0.01, 2.0), 'f3x', (-20.0, 20.0)),
])
def test_stable_boundaries_explain_every_stable_count_change(base, x, xr, y, yr):
    """On a fine map, every change of the stable count lies next to a curve point
    flagged stable_boundary; points off the flagged curves separate equal counts."""
    curves = degenerate_curves(base, x, xr, y, yr)
    lo, hi = np.array([xr[0], yr[0]]), np.array([xr[1], yr[1]])
    n = 100
    u = np.linspace(0.0, 1.0, n)
    U, V = np.meshgrid(u, u, indexing='ij')
    q = lo + np.stack([U.ravel(), V.ravel()], 1) * (hi - lo)
    args = {'rho': base.rho, 'L2': base.L2, 'f3y': base.f3y, 'f4y': base.f4y, 'f3x': base.f3x}
    names = {'rho': 'rho', 'F3': 'f3y', 'F4': 'f4y', 'f3x': 'f3x'}
    args[names[x]], args[names[y]] = q[:, 0], q[:, 1]
    stable = equilibria_batch(**args).num_stable.reshape(n, n)
    cells = set()
    for c in curves:
        uv = (c.points - lo) / (hi - lo)
        for i in range(len(c) - 1):
            if c.stable_boundary[i] or c.stable_boundary[i + 1]:
                for s in np.linspace(0, 1, 20):
                    point = uv[i] + s * (uv[i + 1] - uv[i])
                    cells.add(tuple(np.floor(point * (n - 1)).astype(int)))
    changes = 0
    for i in range(n - 1):
        for j in range(n - 1):
            if stable[i, j] != stable[i + 1, j] or stable[i, j] != stable[i, j + 1]:
                changes += 1
                assert any((i + a, j + b) in cells for a in (-1, 0, 1) for b in (-1, 0, 1)), \
                    (lo + np.array([i, j]) / (n - 1) * (hi - lo))
    assert changes > 10
    # crossing a flagged point changes the stable count; an unflagged one does not
    for c in curves:
        uv = (c.points - lo) / (hi - lo)
        for i in range(2, len(c) - 2, 7):
            t = uv[i + 1] - uv[i - 1]
            nrm = np.array([-t[1], t[0]]) / np.linalg.norm(t)
            sides = [equilibria(_plane_params(base, x, y,
                                              lo + (uv[i] + s * 1e-5 * nrm) * (hi - lo)))
                     for s in (1, -1)]
            if len(sides[0]) == len(sides[1]):
                continue                       # next to a cusp: both curves crossed
            assert (sides[0].num_stable != sides[1].num_stable) == bool(c.stable_boundary[i])


def _plane_params(base, x, y, q):
    names = {'rho': 'rho', 'F3': 'f3y', 'F4': 'f4y', 'f3x': 'f3x'}
    return base.with_(**{names[x]: float(q[0]), names[y]: float(q[1])})


def test_closed_curve_inside_the_box():
    """Near point C the 2-stable horn's cross-section is bounded by a closed fold curve."""
    curves = degenerate_curves(ModuleParams.paper(0.36), 'F3', (68.0, 72.0), 'F4', (68.0, 72.0))
    assert len(curves) == 1 and curves[0].closed and curves[0].ends == ('closed', 'closed')
    assert np.allclose(curves[0].points[0], curves[0].points[-1])
    assert curves[0].changes_stable_count


def test_custom_axis_and_swap_mirror_symmetry():
    """A ray F3 = -F4 keeps the (t1, t2) -> (-t2, -t1) symmetry: its pitchfork curve is
    traced on the restricted system (t1 = -t2)."""
    curves = degenerate_curves(ModuleParams.paper(1.0), 'rho', (0.01, 2.0),
                               {'f3y': 1.0, 'f4y': -1.0}, (-20.0, 20.0))
    bps = [c for c in curves if c.kind == BRANCH_POINT]
    assert bps and all(c.symmetry == 'swap_mirror' for c in bps)
    for c in bps:
        assert np.allclose(c.theta[:, 0], -c.theta[:, 1], atol=1e-9)
        for (rho, f), th in zip(c.points[::5], c.theta[::5]):
            p = ModuleParams.paper(rho, F3=f, F4=-f)
            assert np.max(np.abs(gradient(p, th))) < 1e-9
            h = hessian(p, th)
            assert abs(np.array([1, 1]) @ h @ np.array([1, 1])) < 1e-8 * np.abs(h).max()


def test_degenerate_curves_input_validation():
    base = ModuleParams.paper(1.0)
    with pytest.raises(ValueError):
        degenerate_curves(base, 'nope', (0.1, 1), 'F', (0, 1))
    with pytest.raises(ValueError):
        degenerate_curves(base, 'F', (0.1, 1), 'F3', (0, 1))       # both set f3y
    with pytest.raises(ValueError):
        degenerate_curves(base, 'rho', (1.0, 0.1), 'F', (0, 1))
    with pytest.raises(InvalidParameterError):
        degenerate_curves(base, 'rho', (-1.0, 1.0), 'F', (0, 1))


# ---------------------------------------------------------------------------
# operation range

def test_operation_range_fig8a_lower_branch():
    """F3 = F4 = 5: the lower branch ends at the pitchfork C1 (eq. 15) and the fold C2
    (eq. 16); both agree with where equilibria() changes its stable count."""
    p = ModuleParams.paper(0.5, F3=5.0, F4=5.0)
    r = operation_range(p, (-1.0, -1.0))
    rho_c1, rho_c2 = r
    assert r.lower.kind == BRANCH_POINT and r.lower.symmetry == 'swap'
    assert r.upper.kind == FOLD
    assert rho_c1 == pytest.approx(max(real_rhos(5.0, 15)), abs=1e-12)
    assert rho_c2 == pytest.approx(real_rhos(5.0, 16)[0], abs=1e-12)
    assert abs(bisect_stable_count(p, 0.5, 0.1) - rho_c1) < 1e-6
    assert abs(bisect_stable_count(p, 0.5, 1.2) - rho_c2) < 1e-6
    # the critical configurations: symmetric, one zero eigenvalue
    for end in (r.lower, r.upper):
        assert end.theta[0] == pytest.approx(end.theta[1], abs=1e-9)
        assert abs(end.eigenvalues[0]) < 1e-9 * end.eigenvalues[1]
    # the branch samples are stable equilibria of this branch
    for rho, t1, t2 in r.branch[1:-1]:
        q = p.with_(rho=rho)
        assert np.max(np.abs(gradient(q, (t1, t2)))) < 1e-9
        assert np.linalg.eigvalsh(hessian(q, (t1, t2)))[0] > 0


def test_operation_range_fig8a_upper_branch_and_fig8b():
    p = ModuleParams.paper(0.5, F3=5.0, F4=5.0)
    upper = operation_range(p, (1.0, 1.0), rho_bounds=(0.0, 3.0))
    assert (upper.lower.kind, upper.upper.kind) == (LIMIT, LIMIT)
    assert tuple(upper) == (0.0, 3.0)
    # L2 = 1.05 (fig. 8b): C1 becomes a fold
    q = ModuleParams.paper(0.5, L2=1.05, F3=5.0, F4=5.0)
    r = operation_range(q, (-1.0, -1.0))
    assert (r.lower.kind, r.upper.kind) == (FOLD, FOLD)
    assert abs(bisect_stable_count(q, 0.5, 0.1) - r.rho_min) < 1e-6
    assert abs(bisect_stable_count(q, 0.5, 1.2) - r.rho_max) < 1e-6


@pytest.mark.parametrize('L2', [0.5, 1.5, 2.0])
def test_operation_range_unloaded_is_exact(L2):
    p = ModuleParams.paper(0.5 * (abs(1 - L2) + 1 + L2) / 2 + 0.1, L2=L2)
    e = [e for e in equilibria(p).stable if abs(e.theta1) > 1e-3][0]
    r = operation_range(p, e.theta)
    assert r.rho_min == pytest.approx(abs(1 - L2) / 2, abs=1e-13)
    assert r.rho_max == pytest.approx((1 + L2) / 2, abs=1e-13)
    assert r.lower.kind == r.upper.kind == BRANCH_POINT
    assert r.lower.symmetry == r.upper.symmetry == 'mirror'


def test_operation_range_unloaded_equal_rods_reaches_zero():
    r = operation_range(ModuleParams.paper(0.5), (1.0, 1.0))
    assert r.lower.kind == LIMIT and r.rho_min == 0.0
    assert r.rho_max == pytest.approx(1.0, abs=1e-13)


@pytest.mark.parametrize('L2', [2.5, 3.0, 1.6])
def test_operation_range_of_the_flat_unloaded_branch(L2):
    """Found by fuzzing the CLI: the flat branch (-pi, 0) of an unloaded module reached
    its boundary line 2 rho - L2 + 1 = 0 exactly, where det H = 0, and the branch
    derivative divided by zero.  Unloaded, the flat branch is stable up to that line."""
    p = ModuleParams.paper(0.2 * (L2 - 1), L2=L2)
    flat = [e for e in equilibria(p).stable if abs(e.theta1 + math.pi) < 1e-12
            and abs(e.theta2) < 1e-12]
    assert len(flat) == 1
    r = operation_range(p, flat[0].theta)
    assert r.upper.kind == BRANCH_POINT
    assert r.rho_max == pytest.approx(abs(L2 - 1) / 2, abs=1e-12)


def test_operation_range_random_cross_check():
    """Seeded random modules: both ends agree with the exact solver's stable-count
    change (bisection) and the range is stable throughout (nearest-match march)."""
    rng = np.random.default_rng(7)
    checked = 0
    while checked < 12:
        p = ModuleParams(rho=rng.uniform(0.2, 1.2), L2=rng.uniform(0.6, 1.6),
                         f3y=rng.uniform(-25, 25), f4y=rng.uniform(-25, 25),
                         f3x=rng.uniform(-3, 3))
        for e in equilibria(p).stable:
            r = operation_range(p, e.theta)
            for end, outward in ((r.lower, -1), (r.upper, 1)):
                if end.kind == LIMIT:
                    continue
                inside = p.with_(rho=end.rho - outward * 1e-3)
                outside_rho = end.rho + outward * 1e-3
                if outside_rho <= 0:
                    continue
                outside = p.with_(rho=outside_rho)
                if equilibria(inside).num_stable == equilibria(outside).num_stable:
                    continue        # another branch changes its count at the same time
                assert abs(bisect_stable_count(p, inside.rho, outside_rho) - end.rho) < 1e-6
            theta = np.array(r.theta)
            for rho in np.linspace(p.rho, r.rho_max, 40)[1:-1]:
                es = equilibria(p.with_(rho=rho))
                best = min(es, key=lambda x: _torus_distance(x.theta, theta))
                assert best.stable
                theta = best.theta
            checked += 1


def test_operation_range_hint_and_errors():
    p = ModuleParams.paper(0.5, F3=5.0, F4=5.0)
    r = operation_range(p, (-1.0, -1.0))
    q = p.with_(rho=0.6)
    th = r.theta_at(0.6)
    r2 = operation_range(q, th, hint=r)
    assert (r2.lower, r2.upper) == (r.lower, r.upper) and isinstance(r2, OperationRange)
    # a hint for the other branch is not used
    other = operation_range(q, (1.0, 1.0), hint=r)
    assert other.lower.kind == LIMIT
    # a hint with other forces is not used
    r3 = operation_range(ModuleParams.paper(0.6, F3=6.0, F4=6.0), th, hint=r)
    assert r3.rho_min != r.rho_min
    with pytest.raises(ValueError):
        operation_range(p, (-0.05, -0.05))            # a saddle
    with pytest.raises(ValueError):
        operation_range(p, (-1.0, -1.0), rho_bounds=(0.6, 1.0))


# ---------------------------------------------------------------------------
# point C

@pytest.mark.parametrize('L2', [0.5, 1.0, 1.5])
def test_two_stable_limit_closed_form_and_degeneracy(L2):
    c = two_stable_limit(L2)
    h = math.hypot(1.0, L2)
    assert c.F3 == pytest.approx(K * L2 ** 2 / h, rel=1e-13)
    assert c.F4 == pytest.approx(K / h, rel=1e-13)
    assert c.rho == pytest.approx(L2 / (2 * h), rel=1e-13)
    assert np.max(np.abs(gradient(c.params, c.theta))) < 1e-10
    assert np.max(np.abs(hessian(c.params, c.theta))) < 1e-10      # H = 0 entirely
    push = two_stable_limit(L2, pushing=True)
    assert push.forces == pytest.approx((-c.F3, -c.F4), rel=1e-14)


@pytest.mark.parametrize('L2', [0.5, 1.0, 1.5])
def test_two_stable_limit_is_the_tip_of_the_two_stable_region(L2):
    """Independent check: along the horn axis, at relative distances 1e-3 .. 1e-7 from C,
    a local minimum exists next to theta_C on one side (so, with the far stable
    equilibrium, two stable ones) and none on the other side (a maximum instead)."""
    c = two_stable_limit(L2)
    point = np.array([c.rho, c.F3, c.F4])
    size = np.linalg.norm(point)
    far = max(equilibria(c.params).stable, key=lambda e: e.theta1)   # the other stable one
    for eps in (1e-3, 1e-5, 1e-7):
        for side in (1, -1):
            rho, f3, f4 = point + side * eps * size * c.axis
            p = ModuleParams.paper(rho, L2=L2, F3=f3, F4=f4)
            local = local_equilibria(p, c.theta, 30 * eps)
            assert len(local) == 4                     # an elliptic umbilic unfolds into 4
            minima = [f for f, ev in local if ev[0] > 0]
            maxima = [f for f, ev in local if ev[1] < 0]
            if side == 1:
                assert len(minima) == 1 and not maxima
            else:
                assert len(maxima) == 1 and not minima
            # the far stable equilibrium persists
            th = far.theta
            for _ in range(30):
                th = th - np.linalg.solve(hessian(p, th), gradient(p, th))
            assert np.linalg.eigvalsh(hessian(p, th))[0] > 0
    # at a moderate distance the exact solver agrees: two stable inside, one outside
    rho, f3, f4 = point + 1e-3 * size * c.axis
    assert equilibria(ModuleParams.paper(rho, L2=L2, F3=f3, F4=f4)).num_stable == 2
    rho, f3, f4 = point - 1e-3 * size * c.axis
    assert equilibria(ModuleParams.paper(rho, L2=L2, F3=f3, F4=f4)).num_stable == 1


@pytest.mark.parametrize('L2', [0.5, 1.0, 1.5])
def test_no_two_stable_point_beyond_C(L2):
    """Scan: no (rho, F3 > C_F3, F4 > C_F4) has two stable equilibria."""
    c = two_stable_limit(L2)
    rho = np.linspace(0.005, 2.0, 1200)
    f3 = c.F3 * np.linspace(1.0005, 1.5, 8)
    f4 = c.F4 * np.linspace(1.0005, 1.5, 8)
    R, A, B = np.meshgrid(rho, f3, f4, indexing='ij')
    b = equilibria_batch(R, L2=L2, f3y=A, f4y=B)
    assert not np.any(b.num_stable == 2)


def test_two_stable_limit_on_the_diagonal_for_equal_rods():
    """L1 = L2: C is also the largest F = F3 = F4 with a 2-stable rho (a ρ scan)."""
    c = two_stable_limit(1.0)
    assert c.F3 == pytest.approx(c.F4, rel=1e-15)
    rho = c.rho + np.linspace(0.0, 0.01, 20001)
    below = equilibria_batch(rho, f3y=c.F3 * (1 - 1e-3), f4y=c.F4 * (1 - 1e-3))
    assert np.any(below.num_stable == 2)
    rho = np.linspace(0.005, 2.0, 20001)
    above = equilibria_batch(rho, f3y=c.F3 * (1 + 1e-4), f4y=c.F4 * (1 + 1e-4))
    assert not np.any(above.num_stable == 2)
