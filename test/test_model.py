"""The model of one module (docs/model.md section 1) against finite differences and physics.

Every analytic derivative in ``module.py`` is checked against central finite
differences of :func:`energy` (or of the derivative below it), and the energy
itself against an independent evaluation from the node positions.
"""
import math
import warnings

import numpy as np
import pytest

from tensegrity_ros.core import (actuator_force, energy, equilibria, equilibria_batch, gradient,
                                 hessian, InvalidParameterError, ModuleParams, node_positions,
                                 PARAMETER_NAMES, STANDARD_GRAVITY)
from tensegrity_ros.core.module.model import gradient_parameter_jacobian, parameter_gradient

H = 1e-6        # finite-difference step (central differences: error ~ H^2)


def random_params(rng, weights=True):
    k = rng.uniform(20.0, 300.0, 3)
    return ModuleParams(
        rho=rng.uniform(0.05, 2.5), L1=rng.uniform(0.3, 2.5), L2=rng.uniform(0.3, 2.5),
        ka=k[0], kb=k[1], kc=k[2],
        f3x=rng.normal(0, 20), f3y=rng.normal(0, 20), f4x=rng.normal(0, 20), f4y=rng.normal(0, 20),
        m1=rng.uniform(0, 3) if weights else 0.0, m2=rng.uniform(0, 3) if weights else 0.0)


def cases(n, seed):
    rng = np.random.default_rng(seed)
    return [(random_params(rng, weights=i % 2 == 0), rng.uniform(-math.pi, math.pi, 2))
            for i in range(n)]


def derivative_scale(p):
    """Magnitude of the energy's derivatives, for relative tolerances."""
    return (max(p.ka, p.kb, p.kc) * (p.rho + p.L1 + p.L2) ** 2
            + (abs(p.f3x) + abs(p.f3y_total) + abs(p.f4x) + abs(p.f4y_total))
            * (p.L1 + p.L2 + p.rho))


def fd_gradient(f, theta):
    out = np.zeros(2)
    for i in range(2):
        e = np.zeros(2)
        e[i] = H
        out[i] = (f(theta + e) - f(theta - e)) / (2 * H)
    return out


@pytest.mark.parametrize('p, theta', cases(40, 1))
def test_gradient_matches_finite_differences_of_energy(p, theta):
    fd = fd_gradient(lambda t: float(energy(p, t)), theta)
    assert np.allclose(gradient(p, theta), fd, rtol=0, atol=1e-8 * derivative_scale(p))


@pytest.mark.parametrize('p, theta', cases(40, 2))
def test_hessian_matches_finite_differences(p, theta):
    h = hessian(p, theta)
    assert np.allclose(h, h.T, rtol=0, atol=0)          # symmetric by construction
    fd = np.array([fd_gradient(lambda t: float(gradient(p, t)[i]), theta) for i in range(2)])
    assert np.allclose(h, fd, rtol=0, atol=1e-8 * derivative_scale(p))
    # and the second differences of the energy itself (coarser step)
    step = 1e-4
    e = lambda a, b: float(energy(p, theta + np.array([a, b])))          # noqa: E731
    d11 = (e(step, 0) - 2 * e(0, 0) + e(-step, 0)) / step ** 2
    d22 = (e(0, step) - 2 * e(0, 0) + e(0, -step)) / step ** 2
    d12 = (e(step, step) - e(step, -step) - e(-step, step) + e(-step, -step)) / (4 * step ** 2)
    assert np.allclose(h, [[d11, d12], [d12, d22]], rtol=0, atol=1e-5 * derivative_scale(p))


@pytest.mark.parametrize('p, theta', cases(20, 3))
def test_design_md_formulas(p, theta):
    """The closed forms printed in docs/model.md section 1, transcribed independently."""
    t1, t2 = theta
    f3y, f4y = p.f3y_total, p.f4y_total
    g1 = p.L1 * ((p.ka + p.kc) * p.rho * math.sin(t1) - p.kc * p.L2 * math.sin(t1 + t2)
                 + p.f3x * math.sin(t1) - f3y * math.cos(t1))
    g2 = p.L2 * ((p.kb + p.kc) * p.rho * math.sin(t2) - p.kc * p.L1 * math.sin(t1 + t2)
                 - p.f4x * math.sin(t2) - f4y * math.cos(t2))
    h11 = p.L1 * ((p.ka + p.kc) * p.rho * math.cos(t1) - p.kc * p.L2 * math.cos(t1 + t2)
                  + p.f3x * math.cos(t1) + f3y * math.sin(t1))
    h22 = p.L2 * ((p.kb + p.kc) * p.rho * math.cos(t2) - p.kc * p.L1 * math.cos(t1 + t2)
                  - p.f4x * math.cos(t2) + f4y * math.sin(t2))
    h12 = -p.kc * p.L1 * p.L2 * math.cos(t1 + t2)
    force = (p.ka * (p.rho - p.L1 * math.cos(t1)) + p.kb * (p.rho - p.L2 * math.cos(t2))
             + p.kc * (p.rho - p.L1 * math.cos(t1) - p.L2 * math.cos(t2)) - p.f4x)
    tol = 1e-12 * derivative_scale(p)
    assert np.allclose(gradient(p, theta), [g1, g2], rtol=0, atol=tol)
    assert np.allclose(hessian(p, theta), [[h11, h12], [h12, h22]], rtol=0, atol=tol)
    assert float(actuator_force(p, theta)) == pytest.approx(force, abs=tol)


@pytest.mark.parametrize('p, theta', cases(20, 4))
def test_energy_from_node_positions(p, theta):
    """U from the node positions: three zero-free-length springs, loads, rod weights."""
    a1, a2, a3, a4 = node_positions(p, theta)
    assert np.allclose(a1, [0, 0]) and np.allclose(a2, [p.rho, 0])
    assert np.linalg.norm(a3 - a1) == pytest.approx(p.L1)          # rod A1A3
    assert np.linalg.norm(a4 - a2) == pytest.approx(p.L2)          # rod A2A4
    springs = 0.5 * (p.ka * np.sum((a3 - a2) ** 2) + p.kb * np.sum((a4 - a1) ** 2)
                     + p.kc * np.sum((a4 - a3) ** 2))
    loads = -(p.f3x * a3[0] + p.f3y * a3[1] + p.f4x * a4[0] + p.f4y * a4[1])
    # a uniform rod's potential is m g times the height of its centre
    weights = p.m1 * p.g * a3[1] / 2 + p.m2 * p.g * a4[1] / 2
    assert float(energy(p, theta)) == pytest.approx(springs + loads + weights,
                                                    abs=1e-12 * derivative_scale(p))


@pytest.mark.parametrize('p, theta', cases(20, 5))
def test_actuator_force_is_dU_drho(p, theta):
    fd = (float(energy(p.with_(rho=p.rho + H), theta))
          - float(energy(p.with_(rho=p.rho - H), theta))) / (2 * H)
    assert float(actuator_force(p, theta)) == pytest.approx(fd, abs=1e-8 * derivative_scale(p))


def test_actuator_force_reported_at_equilibria():
    for p, _ in cases(10, 6):
        for e in equilibria(p):
            assert e.actuator_force == pytest.approx(float(actuator_force(p, e.theta)),
                                                     abs=1e-9 * derivative_scale(p))
            assert e.energy == pytest.approx(float(energy(p, e.theta)),
                                             abs=1e-9 * derivative_scale(p))


@pytest.mark.parametrize('p, theta', cases(15, 7))
def test_parameter_gradient_matches_finite_differences(p, theta):
    analytic = parameter_gradient(p, theta)
    assert analytic.shape == (len(PARAMETER_NAMES),)
    v = p.vector()
    for i, name in enumerate(PARAMETER_NAMES):
        step = H * max(1.0, abs(v[i]))
        up, down = v.copy(), v.copy()
        up[i] += step
        down[i] -= step
        if name in ('m1', 'm2') and down[i] < 0:          # one-sided at a zero mass
            down[i] = v[i]
            fd = (float(energy(ModuleParams.from_vector(up), theta))
                  - float(energy(p, theta))) / step
        else:
            fd = (float(energy(ModuleParams.from_vector(up), theta))
                  - float(energy(ModuleParams.from_vector(down), theta))) / (2 * step)
        assert analytic[i] == pytest.approx(fd, abs=1e-8 * derivative_scale(p)), name


@pytest.mark.parametrize('p, theta', cases(15, 8))
def test_gradient_parameter_jacobian_matches_finite_differences(p, theta):
    analytic = gradient_parameter_jacobian(p, theta)
    assert analytic.shape == (2, len(PARAMETER_NAMES))
    v = p.vector()
    for i, name in enumerate(PARAMETER_NAMES):
        step = H * max(1.0, abs(v[i]))
        up = v.copy()
        up[i] += step
        if name in ('m1', 'm2') and v[i] - step < 0:
            fd = (gradient(ModuleParams.from_vector(up), theta) - gradient(p, theta)) / step
        else:
            down = v.copy()
            down[i] -= step
            fd = (gradient(ModuleParams.from_vector(up), theta)
                  - gradient(ModuleParams.from_vector(down), theta)) / (2 * step)
        assert np.allclose(analytic[:, i], fd, rtol=0, atol=1e-8 * derivative_scale(p)), name


def test_rod_weights_are_nodal_forces():
    rng = np.random.default_rng(9)
    for _ in range(20):
        p = random_params(rng, weights=False)
        m1, m2, g = rng.uniform(0.1, 5), rng.uniform(0.1, 5), rng.uniform(1, 20)
        weighted = p.with_(m1=m1, m2=m2, g=g)
        loaded = p.with_(f3y=p.f3y - m1 * g / 2, f4y=p.f4y - m2 * g / 2)
        assert weighted.f3y_total == pytest.approx(loaded.f3y)
        assert weighted.f4y_total == pytest.approx(loaded.f4y)
        theta = rng.uniform(-math.pi, math.pi, (5, 2))
        scale = derivative_scale(weighted)
        assert np.allclose(energy(weighted, theta), energy(loaded, theta),
                           rtol=0, atol=1e-12 * scale)
        assert np.allclose(gradient(weighted, theta), gradient(loaded, theta),
                           rtol=0, atol=1e-12 * scale)
        assert np.allclose(hessian(weighted, theta), hessian(loaded, theta),
                           rtol=0, atol=1e-12 * scale)
        a, b = equilibria(weighted), equilibria(loaded)
        assert len(a) == len(b) and a.num_stable == b.num_stable
        assert np.allclose([e.theta for e in a], [e.theta for e in b], atol=1e-9)
        batch = equilibria_batch(p.rho, L1=p.L1, L2=p.L2, ka=p.ka, kb=p.kb, kc=p.kc, f3x=p.f3x,
                                 f3y=p.f3y, f4x=p.f4x, f4y=p.f4y, m1=m1, m2=m2, g=g)
        assert batch.num_equilibria[0] == len(a) and batch.num_stable[0] == a.num_stable


def test_default_gravity_is_standard():
    assert ModuleParams(rho=1.0).g == STANDARD_GRAVITY == 9.80665
    p = ModuleParams(rho=1.0, m1=2.0, m2=4.0)
    assert p.f3y_total == pytest.approx(-STANDARD_GRAVITY)
    assert p.f4y_total == pytest.approx(-2 * STANDARD_GRAVITY)


def test_vectorised_shapes():
    p = ModuleParams(rho=0.7, f3x=1.0, f4y=-2.0)
    theta = np.random.default_rng(10).uniform(-3, 3, (4, 3, 2))
    assert energy(p, theta).shape == (4, 3)
    assert gradient(p, theta).shape == (4, 3, 2)
    assert hessian(p, theta).shape == (4, 3, 2, 2)
    assert actuator_force(p, theta).shape == (4, 3)
    assert node_positions(p, theta).shape == (4, 3, 4, 2)
    assert np.allclose(gradient(p, theta)[2, 1], gradient(p, theta[2, 1]))
    assert np.allclose(hessian(p, theta)[3, 0], hessian(p, theta[3, 0]))


def test_paper_constructor_and_vector_round_trip():
    p = ModuleParams.paper(0.75, L2=1.5, F3=-10, F4=5, k=80)
    assert ((p.L1, p.L2, p.ka, p.kb, p.kc, p.f3x, p.f3y, p.f4x, p.f4y)
            == (1, 1.5, 80, 80, 80, 0, -10, 0, 5))
    assert ModuleParams.from_vector(p.vector()) == p
    assert p.with_(rho=1.25).rho == 1.25 and p.rho == 0.75
    with pytest.raises(Exception):
        p.rho = 2.0                                          # frozen


# ---------------------------------------------------------------------------
# Validation

POSITIVE = ('rho', 'L1', 'L2', 'ka', 'kb', 'kc')
ALL_FIELDS = PARAMETER_NAMES + ('g',)
BAD_FOR_ALL = [math.nan, math.inf, -math.inf, np.nan, np.float64('inf'), 'abc', '1.5', None,
               [1.0], (1.0, 2.0), {'v': 1.0}, 1 + 2j, object()]


def valid_kwargs():
    return {'rho': 0.5, 'L1': 1.0, 'L2': 1.2, 'ka': 100.0, 'kb': 90.0, 'kc': 80.0,
            'f3x': 0.5, 'f3y': -1.0, 'f4x': 0.3, 'f4y': 2.0, 'm1': 0.1, 'm2': 0.2, 'g': 9.81}


def bad_id(value):
    """repr, but the same in every process (pytest-xdist's workers must collect the same
    ids): a bare object's repr holds its address."""
    return 'object()' if type(value) is object else repr(value)


@pytest.mark.parametrize('name', ALL_FIELDS)
@pytest.mark.parametrize('bad', BAD_FOR_ALL, ids=bad_id)
def test_non_numbers_and_non_finite_are_refused(name, bad):
    kwargs = valid_kwargs()
    kwargs[name] = bad
    with pytest.raises(InvalidParameterError) as info:
        ModuleParams(**kwargs)
    assert name in str(info.value)
    assert repr(bad) in str(info.value) or str(bad) in str(info.value)


@pytest.mark.parametrize('name', POSITIVE)
@pytest.mark.parametrize('bad', [0.0, -0.0, -1e-300, -1.0, -np.inf])
def test_lengths_and_stiffnesses_must_be_positive(name, bad):
    with pytest.raises(InvalidParameterError) as info:
        ModuleParams(**{**valid_kwargs(), name: bad})
    assert name in str(info.value)
    with pytest.raises(InvalidParameterError, match=name):
        ModuleParams(rho=0.5).with_(**{name: bad})


@pytest.mark.parametrize('name', ('m1', 'm2'))
def test_masses_must_be_non_negative(name):
    with pytest.raises(InvalidParameterError) as info:
        ModuleParams(**{**valid_kwargs(), name: -0.5})
    assert name in str(info.value) and '-0.5' in str(info.value)
    assert getattr(ModuleParams(**{**valid_kwargs(), name: 0.0}), name) == 0.0


@pytest.mark.parametrize('name, bad', [('L1', 1.5e50), ('rho', 1e99), ('kc', -2e50),
                                       ('f3y', -1e60), ('f4x', 1e51), ('m2', 3e50), ('g', 1e80),
                                       ('L2', 1e-51), ('ka', 5e-301), ('rho', 1e-60)])
def test_magnitudes_outside_the_supported_range_are_refused(name, bad):
    """Beyond MAX_MAGNITUDE (or below MIN_MAGNITUDE for lengths and stiffnesses) products
    such as k L^2 leave double precision: refused with the name and the value, by the
    single and the batch form alike."""
    with pytest.raises(InvalidParameterError) as info:
        ModuleParams(**{**valid_kwargs(), name: bad})
    assert name in str(info.value) and repr(bad) in str(info.value)
    if name != 'g':
        with pytest.raises(InvalidParameterError, match=name):
            equilibria_batch(**{'rho': np.full(3, 0.5), name: np.array([1.0, bad, 1.0])})


EXTREMES = [  # (parameters, status): where one term dominates by ~1e100 the equations
    # vanish within rounding relative to it, a continuum
    ({'rho': 0.7, 'L1': 1e50, 'L2': 1e50, 'kc': 1e50, 'f4y': 1e50}, 'continuum'),
    ({'rho': 0.7, 'L1': 1e50, 'L2': 1e50, 'ka': 1e-50, 'kb': 1e-50, 'kc': 1e-50,
      'f4y': 1.0, 'f3x': -0.3}, 'ok'),
    ({'rho': 1e-50, 'L1': 1e-50, 'L2': 2e-50, 'ka': 1e-50, 'kb': 1e-50, 'kc': 1e-50,
      'f3y': -1e-50}, 'continuum'),
    ({'rho': 0.5, 'L2': 1e-50, 'kc': 1e-50, 'f3y': 1e50, 'f4y': -1e50, 'm1': 1e50}, 'ok'),
    ({'rho': 1e50, 'L1': 1e50, 'L2': 1e50, 'ka': 1e50, 'kb': 1e50, 'kc': 1e50,
      'f3y': 1e50, 'f4y': -1e50}, 'ok'),
    ({'rho': 1e-50, 'L1': 1e-50, 'L2': 1e-50, 'ka': 1e50, 'kb': 1e50, 'kc': 1e50,
      'f3y': 1e-3, 'f4x': 2e-3}, 'ok'),
]


@pytest.mark.parametrize('kwargs, status', EXTREMES)
def test_extreme_supported_values_solve_without_overflow(kwargs, status):
    """At the ends of the supported range nothing overflows (the solver works in exactly
    rescaled constants) and what comes back is verified: residuals at rounding level and
    the index sum of a Morse function on the torus; single and batch agree."""
    p = ModuleParams(**kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        s = equilibria(p)
        b = equilibria_batch(**kwargs)
    assert s.status == status
    assert bool(b.continuum[0]) == (status == 'continuum')
    if status == 'ok':
        assert 2 <= len(s) <= 6
        assert all(e.residual <= 1e-13 and math.isfinite(e.energy) for e in s)
        kinds = [e.kind for e in s]
        if 'degenerate' not in kinds:
            assert kinds.count('minimum') + kinds.count('maximum') == kinds.count('saddle')
    assert b.num_equilibria[0] == len(s) and b.num_stable[0] == s.num_stable


def test_power_of_two_rescaling_is_exact():
    """Scaling every stiffness and force by 2^k scales all equations exactly, so the angles
    must come out bitwise the same (the solver's own rescaling relies on this)."""
    p = ModuleParams(rho=0.63, L1=1.1, L2=0.9, ka=120.0, kb=80.0, kc=95.0, f3x=3.0,
                     f3y=-7.0, f4x=-2.0, f4y=4.0)
    for k in (-60, -1, 1, 60):
        f = 2.0 ** k
        q = p.with_(ka=p.ka * f, kb=p.kb * f, kc=p.kc * f, f3x=p.f3x * f, f3y=p.f3y * f,
                    f4x=p.f4x * f, f4y=p.f4y * f)
        assert [(e.theta1, e.theta2) for e in equilibria(q)] == \
            [(e.theta1, e.theta2) for e in equilibria(p)]


def test_forces_may_have_any_sign():
    p = ModuleParams(rho=0.5, f3x=-1e6, f3y=-3.0, f4x=2e6, f4y=-1e-300)
    assert p.f3x == -1e6 and p.f4y == -1e-300


def test_message_names_parameter_and_value():
    with pytest.raises(InvalidParameterError, match=r'kb.*-3\.5'):
        ModuleParams(rho=1.0, kb=-3.5)
    with pytest.raises(InvalidParameterError, match=r'L2.*nan'):
        ModuleParams.paper(0.5, L2=float('nan'))
    with pytest.raises(InvalidParameterError, match='rho'):
        ModuleParams.paper(0.0)
    assert issubclass(InvalidParameterError, ValueError)


def test_from_vector_checks_shape_and_values():
    with pytest.raises(InvalidParameterError):
        ModuleParams.from_vector(np.ones(3))
    v = ModuleParams(rho=1.0).vector()
    v[PARAMETER_NAMES.index('kc')] = -1.0
    with pytest.raises(InvalidParameterError, match='kc'):
        ModuleParams.from_vector(v)


@pytest.mark.parametrize('name', PARAMETER_NAMES)
@pytest.mark.parametrize('bad', [math.nan, math.inf, 'abc'])
def test_batch_refuses_invalid_values(name, bad):
    values = np.full(5, 0.5, dtype=object)
    values[3] = bad
    with pytest.raises(InvalidParameterError) as info:
        equilibria_batch(**{'rho': 0.5, name: values})
    assert name in str(info.value)


@pytest.mark.parametrize('name', POSITIVE)
def test_batch_refuses_non_positive(name):
    with pytest.raises(InvalidParameterError, match=name):
        equilibria_batch(**{'rho': np.linspace(0.1, 1, 4), name: np.array([1.0, 0.5, 0.0, 2.0])})


def test_equilibria_needs_module_params():
    with pytest.raises(TypeError):
        equilibria({'rho': 1.0})


# ---------------------------------------------------------------------------
# Shapes of theta

BAD_THETA = [1.0, [1.0], [1.0, 2.0, 3.0], [[1.0, 2.0, 3.0]], np.zeros((2, 3)), np.zeros(0)]


@pytest.mark.parametrize('theta', BAD_THETA, ids=lambda t: f'shape{np.shape(t)}')
@pytest.mark.parametrize('function', [energy, gradient, hessian, actuator_force, node_positions,
                                      parameter_gradient, gradient_parameter_jacobian],
                         ids=lambda f: f.__name__)
def test_theta_of_wrong_shape_is_refused(function, theta):
    with pytest.raises(ValueError):
        function(ModuleParams(rho=0.5), theta)


@pytest.mark.parametrize('function', [parameter_gradient, gradient_parameter_jacobian],
                         ids=lambda f: f.__name__)
def test_single_point_functions_refuse_batches(function):
    with pytest.raises(ValueError):
        function(ModuleParams(rho=0.5), np.zeros((3, 2)))


@pytest.mark.parametrize('rho', [1.25, 1e-50, 1e50, np.float64(0.3), 2, 0.0, -1.0, 1e-60, 1e51,
                                 np.nan, np.inf, '0.5', None], ids=repr)
def test_with_rho_is_with_rho_changed_and_refuses_the_same(rho):
    """The actuator's cheap copy validates rho exactly as a full rebuild does."""
    p = ModuleParams(rho=0.75, L2=1.2, ka=80.0, f3y=-1.0, m1=0.1)
    try:
        expected = p.with_(rho=rho)
    except InvalidParameterError as exc:
        with pytest.raises(InvalidParameterError) as info:
            p.with_rho(rho)
        assert str(info.value) == str(exc)
        return
    moved = p.with_rho(rho)
    assert moved == expected and type(moved.rho) is float and p.rho == 0.75
