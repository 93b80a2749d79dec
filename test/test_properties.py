"""Invariants of the equilibrium set (docs/model.md section 2, "worth testing on every
code path"), as hypothesis properties.

Derandomized (a fixed sequence of examples), no deadline.  Where a property needs
non-degenerate equilibria to be well defined (positions of merging equilibria
are only known to the square root of the rounding), it is checked strictly on
points whose equilibria are all well-conditioned (|lambda_min| > 1e-6
|lambda_max|) and only in its rounding-proof form elsewhere.
"""
import math

from hypothesis import event, given, HealthCheck, settings, strategies as st
import numpy as np
import pytest

from tensegrity_ros.core import equilibria, equilibria_batch, gradient, ModuleParams

#: Numerically sensitive throughout: `make test-numerics` runs it under other CPUs' arithmetic.
pytestmark = pytest.mark.numerics


SETTINGS = {'derandomize': True, 'deadline': None, 'database': None,
            'suppress_health_check': [HealthCheck.too_slow, HealthCheck.filter_too_much]}
TWO_PI = 2 * math.pi
WELL_CONDITIONED = 1e-6


def torus_distance(a, b):
    d = np.abs(np.asarray(a, float) - np.asarray(b, float)) % TWO_PI
    return float(np.max(np.minimum(d, TWO_PI - d)))


def conditioning(s):
    """min over the equilibria of |lambda_min| / |lambda_max| (inf if none)."""
    return min((min(abs(v) for v in e.eigenvalues) / max(abs(v) for v in e.eigenvalues)
                for e in s if max(abs(v) for v in e.eigenvalues) > 0), default=math.inf)


def same_set(a, b, tol, transform=lambda t: t):
    """Every equilibrium of a, transformed, is one of b with the same Morse type."""
    assert len(a) == len(b)
    for e in a:
        match = min(b, key=lambda o: torus_distance(transform(e.theta), o.theta))
        assert torus_distance(transform(e.theta), match.theta) <= tol
        assert match.kind == e.kind


lengths = st.floats(0.2, 3.0)
stiffness = st.floats(1.0, 1000.0)
force = st.one_of(st.just(0.0), st.floats(-200.0, 200.0), st.floats(-1e-6, 1e-6))
mass = st.one_of(st.just(0.0), st.floats(0.0, 5.0))


@st.composite
def params(draw, weights=True):
    return ModuleParams(rho=draw(st.floats(0.01, 3.0)), L1=draw(lengths), L2=draw(lengths),
                        ka=draw(stiffness), kb=draw(stiffness), kc=draw(stiffness),
                        f3x=draw(force), f3y=draw(force), f4x=draw(force), f4y=draw(force),
                        m1=draw(mass) if weights else 0.0, m2=draw(mass) if weights else 0.0)


@st.composite
def swap_symmetric_params(draw):
    L, k = draw(lengths), draw(stiffness)
    fx, fy, m = draw(force), draw(force), draw(mass)
    kc = k if draw(st.booleans()) else draw(stiffness)          # often the paper's equal springs
    return ModuleParams(rho=draw(st.floats(0.01, 3.0)), L1=L, L2=L, ka=k, kb=k,
                        kc=kc, f3x=fx, f4x=-fx, f3y=fy, f4y=fy, m1=m, m2=m)


@settings(max_examples=2000, **SETTINGS)
@given(params())
def test_poincare_hopf(p):
    s = equilibria(p)
    if s.status == 'continuum':
        return
    kinds = [e.kind for e in s]
    assert len(s) <= 6 and s.num_stable <= 2
    event(f'{len(s)} equilibria, {s.num_stable} stable')
    if 'degenerate' not in kinds:
        # index sum on the torus (Euler characteristic 0)
        assert kinds.count('minimum') + kinds.count('maximum') - kinds.count('saddle') == 0
        assert kinds.count('minimum') >= 1 and kinds.count('maximum') >= 1


@settings(max_examples=1500, **SETTINGS)
@given(params())
def test_mirror_symmetry(p):
    """(t1, t2, f3y, f4y) -> (-t1, -t2, -f3y, -f4y) maps equilibria to equilibria
    (the vertical loads including the rod weights; f3x and f4x stay)."""
    mirrored = ModuleParams(rho=p.rho, L1=p.L1, L2=p.L2, ka=p.ka, kb=p.kb, kc=p.kc,
                            f3x=p.f3x, f4x=p.f4x, f3y=-p.f3y_total, f4y=-p.f4y_total)
    a, b = equilibria(p), equilibria(mirrored)
    assert a.status == b.status
    if a.status == 'continuum':
        return
    assert a.num_stable == b.num_stable or min(conditioning(a), conditioning(b)) < WELL_CONDITIONED
    event('well-conditioned' if min(conditioning(a), conditioning(b)) > WELL_CONDITIONED
          else 'ill-conditioned')
    if min(conditioning(a), conditioning(b)) > WELL_CONDITIONED:
        same_set(a, b, 1e-9, transform=lambda t: -t)
        for e in a:
            o = min(b, key=lambda o: torus_distance(-e.theta, o.theta))
            assert (o.energy == np.float64(e.energy)
                    or abs(o.energy - e.energy) <= 1e-9 * (1 + abs(e.energy)))
            assert np.allclose(o.eigenvalues, e.eigenvalues, rtol=1e-7,
                               atol=1e-9 * max(map(abs, e.eigenvalues)))
    # rounding-proof form
    for e in a:
        assert min(torus_distance(-e.theta, o.theta) for o in b) <= 1e-4


@settings(max_examples=1500, **SETTINGS)
@given(swap_symmetric_params())
def test_swap_symmetry(p):
    """L1 = L2, ka = kb, f3y = f4y, f3x = -f4x: (t1, t2) -> (t2, t1) maps the set to itself."""
    s = equilibria(p)
    if s.status == 'continuum':
        return
    event('well-conditioned' if conditioning(s) > WELL_CONDITIONED else 'ill-conditioned')
    if conditioning(s) > WELL_CONDITIONED:
        same_set(s, s, 1e-9, transform=lambda t: t[::-1])
    # rounding-proof form: the swapped set is within the equilibria up to 1e-4
    for e in s:
        assert min(torus_distance(e.theta[::-1], o.theta) for o in s) <= 1e-4
    # the paper's case (equal springs, vertical loads): t1 != t2 is never stable (eq. 10)
    if p.kc == p.ka and p.f3x == 0:
        for e in s:
            if torus_distance([e.theta1], [e.theta2]) > 1e-4:
                assert not e.stable


@settings(max_examples=1500, **SETTINGS)
@given(params())
def test_tiny_residuals(p):
    s = equilibria(p)
    scale = (max(p.ka, p.kb, p.kc) * (p.rho + p.L1 + p.L2) + abs(p.f3x) + abs(p.f3y_total)
             + abs(p.f4x) + abs(p.f4y_total)) * max(p.L1, p.L2)
    for e in s:
        assert e.residual <= 1e-13
        assert np.max(np.abs(gradient(p, e.theta))) <= 1e-12 * scale
        assert e.eigenvalues[0] <= e.eigenvalues[1]
        assert -math.pi <= e.theta1 < math.pi and -math.pi <= e.theta2 < math.pi
    for i, a in enumerate(s.equilibria):                   # distinct
        for b in s.equilibria[:i]:
            assert torus_distance(a.theta, b.theta) > 1e-7


@settings(max_examples=300, **SETTINGS)
@given(st.lists(params(), min_size=1, max_size=25))
def test_batch_equals_single(points):
    """The batch is a fast path for generic rows and hands delicate rows to the
    scalar solver, so the two agree everywhere, degenerate points included."""
    names = ('rho', 'L1', 'L2', 'ka', 'kb', 'kc', 'f3x', 'f3y', 'f4x', 'f4y', 'm1', 'm2')
    b = equilibria_batch(**{n: np.array([getattr(p, n) for p in points]) for n in names})
    assert b.theta.shape == (len(points), 6, 2) and b.eigenvalues.shape == (len(points), 6, 2)
    for i, p in enumerate(points):
        s = equilibria(p)
        event('well-conditioned' if conditioning(s) > WELL_CONDITIONED else 'ill-conditioned')
        assert bool(b.continuum[i]) == (s.status == 'continuum')
        assert b.num_equilibria[i] == len(s)
        assert b.num_stable[i] == s.num_stable
        valid = b.valid[i]
        for t, ev in zip(b.theta[i][valid], b.eigenvalues[i][valid]):
            e = min(s, key=lambda e: torus_distance(t, e.theta))
            assert torus_distance(t, e.theta) <= 1e-9
            assert np.allclose(ev, e.eigenvalues, rtol=1e-7,
                               atol=1e-9 * max(map(abs, e.eigenvalues)))
        assert np.array_equal(b.stable[i][valid],
                              [min(s, key=lambda e: torus_distance(t, e.theta)).stable
                               for t in b.theta[i][valid]])


@settings(max_examples=800, **SETTINGS)
@given(params(), st.floats(1e-3, 1e3), st.floats(1e-3, 1e3))
def test_scale_invariance(p, length_factor, stiffness_factor):
    """U(c lengths, c forces) = c^2 U and U(c k, c forces) = c U: the same angles."""
    c, k = length_factor, stiffness_factor
    q = ModuleParams(rho=p.rho * c, L1=p.L1 * c, L2=p.L2 * c, ka=p.ka * k, kb=p.kb * k,
                     kc=p.kc * k, f3x=p.f3x * c * k, f3y=p.f3y_total * c * k,
                     f4x=p.f4x * c * k, f4y=p.f4y_total * c * k)
    a, b = equilibria(p), equilibria(q)
    if a.status == 'continuum' or b.status == 'continuum':
        return
    if min(conditioning(a), conditioning(b)) > WELL_CONDITIONED:
        same_set(a, b, 1e-9)
        assert a.num_stable == b.num_stable
