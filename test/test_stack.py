"""Neck stack: N = 1 is the paper, N = 2, 3 against an independent constrained
minimisation, global statics, buckling under a head load, tracking."""
import math

import numpy as np
import pytest
from scipy.optimize import minimize

from tensegrity_ros.core import (BRANCH_POINT, equilibria, FOLD, ModuleParams, ModulePath, settle,
                                 track_module)
from tensegrity_ros.core.neck.stack import (settle_stack, Stack, stack_equilibria,
                                            stack_equilibrium_at, StackJump, StackPassage,
                                            StackPath, track_stack)

G = 9.80665


def wrapped_distance(a, b):
    d = (np.asarray(a) - np.asarray(b) + np.pi) % (2 * np.pi) - np.pi
    return float(np.max(np.abs(d)))


# -- N = 1 is exactly the one-module model -------------------------------------------------

ONE_MODULE_POINTS = [
    ModuleParams.paper(0.75, F3=-10, F4=-10),
    ModuleParams.paper(0.5, F3=5, F4=5),
    ModuleParams.paper(1.5, L2=1.5, F3=-10, F4=-10),
    ModuleParams(rho=0.6, L2=1.3, ka=80, kb=120, kc=90, f3x=1, f3y=3, f4x=-2, f4y=-4,
                 m1=0.2, m2=0.3),
    ModuleParams(rho=0.9, L1=0.8, L2=1.1, f3x=-3, f3y=2, f4x=1, f4y=6),
]


@pytest.mark.parametrize('params', ONE_MODULE_POINTS)
def test_one_module_stack_equals_the_module_solver(params):
    stack = stack_equilibria(Stack((params,)), starts=200, seed=1)
    exact = equilibria(params)
    assert len(stack) == len(exact)
    assert sum(e.stable for e in stack) == exact.num_stable
    for e in exact:
        match = min(stack, key=lambda s: wrapped_distance(s.theta[0], e.theta))
        assert wrapped_distance(match.theta[0], e.theta) < 1e-10
        assert match.stable == e.stable
        assert match.energy == pytest.approx(e.energy, abs=1e-10 * max(1.0, abs(e.energy)))
        assert match.actuator_forces[0] == pytest.approx(e.actuator_force, abs=1e-9)


@pytest.mark.numerics
def test_one_module_stack_tracks_fig8a_like_the_module():
    def stack(rho):
        return Stack((ModuleParams.paper(rho, F3=5, F4=5),))

    start = settle_stack(stack(0.5), [[-1.0, -1.0]])
    module_start = settle(ModuleParams.paper(0.5, F3=5, F4=5), [-1.0, -1.0])
    assert wrapped_distance(start.theta[0], module_start.theta) < 1e-10
    for target in (0.05, 1.2):
        by_stack = track_stack(stack(0.5), stack(target), start)
        by_module = track_module(ModuleParams.paper(0.5, F3=5, F4=5),
                                 ModuleParams.paper(target, F3=5, F4=5), module_start.theta)
        assert [j.kind for j in by_stack.jumps] == [j.kind for j in by_module.jumps]
        for a, b in zip(by_stack.jumps, by_module.jumps):
            assert a.s == pytest.approx(b.s, abs=1e-9)
        assert wrapped_distance(by_stack.final.theta[0], by_module.final.theta) < 1e-8


# -- N = 2, 3 against an independent constrained minimisation ---------------------------------

def kinematics(stack, theta):
    """Independent forward kinematics from local angles: nodes A1..A4 of every module."""
    theta = np.asarray(theta).reshape(len(stack), 2)
    a1, a2 = np.zeros(2), np.array([stack.modules[0].rho, 0.0])
    nodes = []
    for m, (t1, t2) in zip(stack.modules, theta):
        e = (a2 - a1) / np.linalg.norm(a2 - a1)
        n = np.array([-e[1], e[0]])
        a3 = a1 + m.L1 * (math.cos(t1) * e + math.sin(t1) * n)
        a4 = a2 + m.L2 * (-math.cos(t2) * e + math.sin(t2) * n)
        nodes.append((a1, a2, a3, a4))
        a1, a2 = a4, a3
    return nodes


def oracle_energy(stack, theta):
    total = 0.0
    for m, (a1, a2, a3, a4) in zip(stack.modules, kinematics(stack, theta)):
        total += 0.5 * (m.ka * np.sum((a3 - a2) ** 2) + m.kb * np.sum((a4 - a1) ** 2)
                        + m.kc * np.sum((a4 - a3) ** 2))
        total -= m.f3x * a3[0] + m.f3y * a3[1] + m.f4x * a4[0] + m.f4y * a4[1]
        total += 0.5 * G * (m.m1 * (a1[1] + a3[1]) + m.m2 * (a2[1] + a4[1]))
    return total


def oracle_chords(stack, theta):
    nodes = kinematics(stack, theta)
    return np.array([np.linalg.norm(nodes[i][2] - nodes[i][3]) - stack.modules[i + 1].rho
                     for i in range(len(stack) - 1)])


def oracle_minima(stack, starts, seed):
    rng = np.random.default_rng(seed)
    found = []
    for _ in range(starts):
        x0 = rng.uniform(-math.pi, math.pi, 2 * len(stack))
        result = minimize(lambda x: oracle_energy(stack, x), x0, method='SLSQP',
                          constraints=[{'type': 'eq', 'fun': lambda x: oracle_chords(stack, x)}],
                          options={'ftol': 1e-14, 'maxiter': 500})
        if not result.success or np.max(np.abs(oracle_chords(stack, result.x))) > 1e-8:
            continue
        x = (result.x + np.pi) % (2 * np.pi) - np.pi
        if all(wrapped_distance(x, f) > 1e-5 for f in found):
            found.append(x)
    return found


NECKS = [
    Stack((ModuleParams.paper(0.75), ModuleParams.paper(0.7, F3=-3, F4=-2))),
    Stack((ModuleParams(rho=0.6, L2=1.2, f3x=1.0),
           ModuleParams(rho=0.65, L1=0.9, f3y=2, f4x=-1, m1=0.1))),
    Stack((ModuleParams.paper(0.7), ModuleParams.paper(0.6),
           ModuleParams.paper(0.55, F3=-2, F4=-1))),
]


def oracle_local_minimum(stack, theta, seed):
    """SLSQP started 1e-3 away from ``theta``: does it come back (a local minimum)?

    Decided by a clear majority of five restarts (SLSQP occasionally wanders off
    even from a minimum; from a saddle most restarts leave along the unstable mode).
    """
    rng = np.random.default_rng(seed)
    back = []
    for _ in range(5):
        x0 = np.ravel(theta) + rng.normal(0, 1e-3, 2 * len(stack))
        result = minimize(lambda x: oracle_energy(stack, x), x0, method='SLSQP',
                          constraints=[{'type': 'eq', 'fun': lambda x: oracle_chords(stack, x)}],
                          options={'ftol': 1e-15, 'maxiter': 500})
        back.append(wrapped_distance(result.x, np.ravel(theta)) < 1e-4
                    and oracle_energy(stack, result.x) >= oracle_energy(stack, theta) - 1e-9)
    assert sum(back) != 2 and sum(back) != 3, 'the oracle cannot decide'
    return sum(back) >= 4


@pytest.mark.parametrize('stack', NECKS)
def test_equilibria_agree_with_independent_constrained_minimisation(stack):
    ours = stack_equilibria(stack, starts=60, seed=3)
    stable = [e for e in ours if e.stable]
    assert stable, 'a loaded neck always has a stable equilibrium'
    # every minimum the oracle reaches from random starts is a stable equilibrium of
    # ours: the multi-start search lists it, or our overdamped settle from it stays there
    for x in oracle_minima(stack, starts=30, seed=4):
        match = min(stable, key=lambda e: wrapped_distance(e.theta.ravel(), x))
        if wrapped_distance(match.theta.ravel(), x) >= 1e-5:
            match = settle_stack(stack, x.reshape(-1, 2))
        assert wrapped_distance(match.theta.ravel(), x) < 1e-5, f'not a minimum of ours: {x}'
        assert match.stable
        assert oracle_energy(stack, x) == pytest.approx(match.energy, abs=1e-7)
    # and the oracle agrees on the stability of each of ours
    for e in ours:
        assert oracle_energy(stack, e.theta) == pytest.approx(e.energy, abs=1e-8)
        assert np.max(np.abs(oracle_chords(stack, e.theta))) < 1e-10
        if abs(e.stability_margin) > 1e-3:
            assert oracle_local_minimum(stack, e.theta, seed=5) == e.stable, e.theta.ravel()


# -- statics ------------------------------------------------------------------------------

def test_base_reaction_balances_every_load_force_and_moment():
    rng = np.random.default_rng(11)
    for n in (1, 2, 3):
        modules = tuple(ModuleParams(rho=rng.uniform(0.5, 0.8), L2=rng.uniform(0.9, 1.2),
                                     f3x=rng.uniform(-2, 2), f3y=rng.uniform(-3, 3),
                                     f4x=rng.uniform(-2, 2), f4y=rng.uniform(-3, 3),
                                     m1=rng.uniform(0, 0.3), m2=rng.uniform(0, 0.3))
                        for _ in range(n))
        stack = Stack(modules)
        state = settle_stack(stack, np.full((n, 2), 0.8))
        path = StackPath(stack, stack)
        force, moment = path.base_reaction(state.state, 0.0)
        load, load_moment = path.total_load(state.state, 0.0)
        assert force == pytest.approx(-load, abs=1e-9)
        assert moment == pytest.approx(-load_moment, abs=1e-9)


def test_a_head_load_with_a_horizontal_part_reaches_the_base():
    stack = Stack((ModuleParams.paper(0.7), ModuleParams.paper(0.7),
                   ModuleParams.paper(0.7).with_(f3x=1.5, f3y=-2.0)))
    state = settle_stack(stack, np.full((3, 2), 0.8))
    force, _ = StackPath(stack, stack).base_reaction(state.state, 0.0)
    assert force == pytest.approx([-1.5, 2.0], abs=1e-9)


def test_rod_weights_of_every_module_reach_the_base():
    masses = [(0.1, 0.2), (0.3, 0.1), (0.2, 0.2)]
    stack = Stack(tuple(ModuleParams.paper(0.7).with_(m1=a, m2=b) for a, b in masses))
    state = settle_stack(stack, np.full((3, 2), 0.8))
    force, _ = StackPath(stack, stack).base_reaction(state.state, 0.0)
    assert force[1] == pytest.approx(G * sum(a + b for a, b in masses), abs=1e-9)


def test_head_pose_is_the_top_chord():
    stack = Stack((ModuleParams.paper(0.7), ModuleParams.paper(0.7, F3=1)))
    state = settle_stack(stack, np.full((2, 2), 0.8))
    a3, a4 = state.nodes[-2], state.nodes[-1]
    assert state.head_position == pytest.approx(0.5 * (a3 + a4))
    assert state.head_angle == pytest.approx(math.atan2(*(a3 - a4)[::-1]))


# -- buckling under a head load -------------------------------------------------------------

def neck(n, load, rho=0.6):
    modules = [ModuleParams.paper(rho) for _ in range(n - 1)]
    return Stack(tuple(modules + [ModuleParams.paper(rho, F3=load, F4=load)]))


def critical_head_load(n, rho=0.6):
    upright = equilibria(ModuleParams.paper(rho)).stable[-1].theta      # the upper branch
    start = settle_stack(neck(n, 0.0, rho), np.tile(upright, (n, 1)))
    result = track_stack(neck(n, 0.0, rho), neck(n, -40.0, rho), start)
    assert result.status == 'ok', result.message
    assert result.final.stable
    # the first critical point: a jump, or a sideways buckling passed continuously
    first = min(result.jumps + result.passages, key=lambda event: event.s)
    return first, start


def kind_of(event):
    return event.kind if isinstance(event, StackJump) else BRANCH_POINT


@pytest.mark.numerics
@pytest.mark.parametrize('n', [1, 2, 3])
def test_critical_load_is_where_the_reduced_hessian_loses_definiteness(n):
    """The event's load against the zero of lambda_min extrapolated from tracked states
    short of it: lambda_min vanishes linearly at a branch point, like a square root at a fold."""
    jump, start = critical_head_load(n)
    load = jump.stack.modules[-1].f3y
    margins = []
    for offset in (1e-4, 1e-5):
        short = track_stack(neck(n, 0.0), neck(n, load + offset), start)
        assert short.jumps == () and short.final.stable
        margins.append(short.final.stability_margin)
    power = 1.0 if kind_of(jump) == BRANCH_POINT else 2.0
    (l1, l2), (f1, f2) = np.power(margins, power), (load + 1e-4, load + 1e-5)
    zero = f1 - l1 * (f2 - f1) / (l2 - l1)
    assert zero == pytest.approx(load, abs=4e-8)          # 1e-9 in s: the load moves 40 N over s
    # and just past the event the tracked branch is gone or unstable: the command jumps,
    # or (a supercritical branch point) passes it continuously onto a buckled minimum
    past = track_stack(neck(n, 0.0), neck(n, load - 1e-6), start)
    assert len(past.jumps) + len(past.passages) == 1 and past.final.stable


@pytest.mark.numerics
def test_critical_load_falls_as_the_neck_grows_and_n1_is_the_module_fold():
    loads = [critical_head_load(n)[0].stack.modules[-1].f3y for n in (1, 2, 3, 4)]
    magnitudes = [-f for f in loads]
    assert all(a > b for a, b in zip(magnitudes, magnitudes[1:])), magnitudes
    # the figures the node-coordinate formulation gave (README): 31.0, 18.86, 6.85, 3.67 N
    assert magnitudes == pytest.approx([31.0115, 18.8595, 6.8538, 3.6666], abs=1e-4)
    # N = 1: the module solver's tracker reports the same fold
    upright = equilibria(ModuleParams.paper(0.6)).stable[-1].theta
    module = track_module(ModuleParams.paper(0.6), ModuleParams.paper(0.6, F3=-40, F4=-40),
                          upright)
    assert module.jumps[0].kind == FOLD
    assert loads[0] == pytest.approx(module.jumps[0].params.f3y, abs=1e-7)


@pytest.mark.numerics
def test_upright_neck_buckles_sideways_continuously():
    """N = 3: a supercritical branch point, passed without a jump onto a buckled minimum
    that grows out of the upright state like sqrt(load - critical load)."""
    passage, start = critical_head_load(3)
    assert isinstance(passage, StackPassage)
    load = passage.stack.modules[-1].f3y
    # symmetric at the critical point (t1 = t2 in every module), asymmetric after
    assert np.max(np.abs(passage.theta[:, 0] - passage.theta[:, 1])) < 1e-6
    spread = []
    for beyond in (1e-2, 1e-4):
        after = track_stack(neck(3, 0.0), neck(3, load - beyond), start)
        assert after.jumps == () and after.final.stable and len(after.passages) == 1
        spread.append(np.max(np.abs(after.final.theta - passage.theta)))
    assert spread[0] > 1e-3
    assert spread[1] / spread[0] == pytest.approx(0.1, rel=0.05)       # a square root


# -- tracking a ten-module neck -----------------------------------------------------------

def test_ten_module_neck_small_command():
    stack = Stack(tuple(ModuleParams.paper(0.75) for _ in range(10)))
    start = settle_stack(stack, np.full((10, 2), 0.72))
    moved = stack.with_module(4, rho=0.76)
    result = track_stack(stack, moved, start)
    assert result.status == 'ok' and result.final.stable
    assert result.final.residual < 1e-8
    assert np.linalg.norm(result.final.nodes[2 + 2 * 3] - result.final.nodes[3 + 2 * 3]) \
        == pytest.approx(0.76, abs=1e-10)


def test_stack_refuses_bad_input():
    with pytest.raises(ValueError):
        Stack(())
    with pytest.raises(ValueError):
        settle_stack(Stack((ModuleParams.paper(0.7),)), [[0.1, 0.2, 0.3]])
    with pytest.raises(ValueError):
        settle_stack(Stack((ModuleParams.paper(0.7),)), [[math.nan, 0.2]])


def test_equilibrium_record_round_trip():
    stack = Stack((ModuleParams.paper(0.7), ModuleParams.paper(0.7)))
    state = settle_stack(stack, np.full((2, 2), 0.8))
    again = stack_equilibrium_at(stack, state.state)
    assert again.theta == pytest.approx(state.theta)
    assert again.stable


def test_settle_from_near_a_maximum_comes_to_rest():
    """All eigenvalues negative at the start: the overdamped flow still finds a minimum."""
    from tensegrity_ros.core import TrackerSettings
    stack = Stack((ModuleParams.paper(0.75), ModuleParams.paper(0.75),
                   ModuleParams.paper(0.75, F3=-1, F4=-1)))
    start = np.array([[-3.126, -0.002], [-3.126, -0.002], [3.139, 3.139]])    # a maximum, rounded
    path = StackPath(stack, stack)
    assert np.all(path.eigenvalues(path.state_from_angles(start, 0.0), 0.0) < 0)
    landed = settle_stack(stack, start, settings=TrackerSettings(flow_evaluations=20000))
    assert landed.stable


def test_projection_survives_dependent_constraints():
    """Found by fuzzing the CLI (solve --modules 3 --rho 1e-6 --L1=1e-6 --k=1e6): flat
    rods 1e-6 long make the constraint rows of the stack dependent and J J^T singular;
    the projection then takes the least-squares step instead of raising."""
    m = ModuleParams(rho=1e-6, L1=1e-6, L2=1.0, ka=1e6, kb=1e6, kc=1e6)
    stack = Stack((m, m))
    path = StackPath(stack, stack)
    y = path.project(path.state_from_angles(np.zeros((2, 2)), 0.0) + 1e-3, 0.0)
    assert np.all(np.isfinite(y))
    # and the multipliers of the stability modes (solve --modules 2 --rho 1e-50 --k=1e50
    # --F3x=2.5 raised there): the multi-start search runs through
    m = ModuleParams(rho=1e-50, ka=1e50, kb=1e50, kc=1e50, f3x=2.5)
    found = stack_equilibria(Stack((m, m)), starts=1)
    assert all(np.all(np.isfinite(e.theta)) for e in found)


def module_under_chord(chord):
    """Module 0 (rho 0.5, rods 1 m) under a top chord ``chord`` m long: (path, the state
    next to both rods flat pointing away from each other, projected on the chord)."""
    stack = Stack((ModuleParams.paper(0.5), ModuleParams.paper(chord)))
    path = StackPath(stack, stack)
    y = np.zeros(path.size)
    y[:4] = [math.pi - 0.1, 0.1, 0.3, 0.2]
    return path, path.project(y, 0.0)


@pytest.mark.parametrize('chord, reachable', [(2.4, True), (2.499, True), (2.6, False)])
def test_a_projection_says_whether_it_reached_the_chords(chord, reachable):
    """Module 0 (rho 0.5, rods 1 m) reaches a top chord of at most 2.5 m (both rods
    flat, pointing away from each other): a chord of 2.4 or 2.499 m is met by the
    projection of a state next to that limit; one of 2.6 m by none, and the projection
    says so (a landing does not start a flow from there)."""
    path, projected = module_under_chord(chord)
    assert path.on_constraints(projected, 0.0) == reachable
    miss = abs(float(path.point(projected, 0.0).constraints(path)[0]))
    assert (miss < 1e-12) if reachable else (miss > 0.05), miss


@pytest.mark.parametrize('chord, damped', [(2.0, False), (2.499, False), (2.4999, True)])
def test_the_elastic_flow_says_where_its_chords_give(chord, damped):
    """Module 0 (rho 0.5, rods 1 m) under a top chord of 2.0, 2.499 or 2.4999 m (of the
    2.5 m it reaches flat): only the last is near enough flat (Gram matrix of the chord
    gradient 1.1e-3, below _DAMPING_ONSET) for :meth:`descent` to damp its projection, and
    ``damped`` says so.  Where it does not, the elastic flow is the rigid one; where it
    does, they part (a landing then lets the rigid flow decide)."""
    path, y = module_under_chord(chord)
    assert path.damped(y, 0.0) == damped
    apart = np.max(np.abs(path.descent(y, 0.0) - path.rigid_descent(y, 0.0)))
    assert (apart > 1.0) if damped else (apart < 1e-12), apart
    one = Stack((ModuleParams.paper(0.5),))
    assert not StackPath(one, one).damped(np.array([0.3, 0.2]), 0.0)


def central_differences(velocity, y, s, h=1e-7):
    return np.column_stack([(velocity(y + h * e, s) - velocity(y - h * e, s)) / (2 * h)
                            for e in np.eye(len(y))])


@pytest.mark.parametrize('chord, damped', [(2.0, False), (2.499, False), (2.4999, True)])
def test_the_flows_jacobians_are_their_velocities_derivatives(chord, damped):
    """LSODA's corrector gets the landing flows' Jacobians from the path: the rigid flow's
    is its velocity's derivative on the chords (to finite differences' 1e-6), next to a
    module folded flat too; the elastic flow's too where it does not damp, and within 10 %
    where it does (the damping's own derivative left out).  An error in either did not
    show in any answer: LSODA's step control only made the flows slow (bench_neck_paths
    seed 1, path 12: 5 s, from 1.1)."""
    path, y = module_under_chord(chord)
    y = y + 1e-3 * np.array([1.0, 0.5, -0.7, 0.4, 0.0])
    y = path.project(y, 0.0)
    for velocity, jacobian, tol in ((path.rigid_descent, path.rigid_descent_jacobian, 1e-6),
                                    (path.descent, path.descent_jacobian,
                                     0.1 if damped else 1e-6)):
        expected = central_differences(velocity, y, 0.0)
        found = jacobian(y, 0.0)
        assert np.linalg.norm(found - expected) <= tol * np.linalg.norm(expected)
        assert not np.any(found[:, 4:]) and not np.any(found[4:])    # the multiplier


@pytest.mark.parametrize('n', [1, 2, 4])
def test_the_flows_jacobians_hold_on_random_necks(n):
    """As above, at random states of random necks (projected onto their chords) away
    from rest, where the velocity's projection turns with the state."""
    rng = np.random.default_rng(n)
    for _ in range(5):
        stack = Stack(tuple(ModuleParams(rho=rng.uniform(0.5, 0.9), L1=rng.uniform(0.8, 1.2),
                                         L2=rng.uniform(0.8, 1.2), ka=rng.uniform(60, 140),
                                         f3y=rng.uniform(-2, 2)) for _ in range(n)))
        path = StackPath(stack, stack)
        y = path.project(path.state_from_angles(rng.uniform(0.4, 1.2, (n, 2)), 0.0), 0.0)
        assert path.on_constraints(y, 0.0) and not path.damped(y, 0.0)
        for velocity, jacobian in ((path.rigid_descent, path.rigid_descent_jacobian),
                                   (path.descent, path.descent_jacobian)):
            expected = central_differences(velocity, y, 0.0)
            assert np.linalg.norm(jacobian(y, 0.0) - expected) \
                <= 1e-6 * np.linalg.norm(expected)


@pytest.mark.parametrize('n, rtol', [(3, 1e-7), (5, 1e-10)])
def test_a_flow_stops_at_the_step_its_velocity_says_it_rests(n, rtol):
    """flow_to_rest evaluates a fresh velocity, to see whether it is at rest, only after
    steps where LSODA's own estimate (speed_estimate) is within REST_CHECK_MARGIN of the
    tolerance: at every step whose velocity is within 10 tolerances the estimate is
    ten times inside that margin, so no rest is passed by."""
    from types import SimpleNamespace

    from tensegrity_ros.core.continuation.flows import flow_to_rest, speed_estimate
    from tensegrity_ros.core.continuation.settings import REST_CHECK_MARGIN
    rng = np.random.default_rng(n)
    stack = Stack(tuple(ModuleParams(rho=rng.uniform(0.5, 0.9), L1=rng.uniform(0.8, 1.2),
                                     ka=rng.uniform(60, 140), f3y=rng.uniform(-2, 2))
                        for _ in range(n)))
    path = StackPath(stack, stack)
    rest = settle_stack(stack, np.full((n, 2), 0.9)).state
    y = path.project(rest + np.concatenate([rng.uniform(-0.05, 0.05, 2 * n),
                                            np.zeros(n - 1)]), 0.0)
    scale = float(np.max(np.abs(path.eigenvalues(rest, 0.0))))
    tol, seen = 1e-10 * scale, []

    def record(solver):
        fresh = np.max(np.abs(path.rigid_descent(solver.y, 0.0)))
        seen.append((speed_estimate(solver), fresh))
    end = flow_to_rest(SimpleNamespace(scale=scale), lambda _t, v: path.rigid_descent(v, 0.0),
                       y, tol, rtol, stop=record, jac=lambda _t, v:
                       path.rigid_descent_jacobian(v, 0.0))
    assert np.max(np.abs(path.rigid_descent(end, 0.0))) <= tol
    near = [estimate for estimate, fresh in seen if fresh <= 10 * tol]
    assert near and max(near) <= 0.1 * REST_CHECK_MARGIN * tol, max(near) / tol
    # this scipy keeps LSODA's Nordsieck history where speed_estimate reads it (a private
    # array: elsewhere the estimate is 0, every step is checked, the same rests ~1/3 slower)
    assert all(estimate > 0.0 for estimate, fresh in seen if fresh > 1e3 * tol)
    assert all(abs(estimate - fresh) <= 0.5 * fresh
               for estimate, fresh in seen if fresh > 1e6 * tol)


def symmetric_module(rng):
    """A module that is its own mirror image, with random lengths, springs and loads."""
    length, k, fy, mass = rng.uniform(0.8, 1.2), rng.uniform(50, 150), rng.uniform(-3, 3), \
        rng.uniform(0, 0.2)
    fx = rng.uniform(-1, 1)
    return ModuleParams(rho=rng.uniform(0.5, 0.9), L1=length, L2=length, ka=k, kb=k,
                        kc=rng.uniform(50, 150), f3x=fx, f3y=fy, f4x=-fx, f4y=fy,
                        m1=mass, m2=mass)


@pytest.mark.numerics
@pytest.mark.parametrize('seed', range(4))
def test_the_mirror_image_of_an_equilibrium_is_one_of_a_mirror_symmetric_stack(seed):
    """The mirror image (each module's (t1, t2) -> (t2, t1)) of a minimum of a
    mirror-symmetric stack is a minimum of one energy and the same stiffnesses; the
    image the path builds in rod angles is the one the local angles give.  A stack with
    one asymmetric parameter has no mirror (None), nor has a module path."""
    rng = np.random.default_rng(seed)
    n = 1 + seed % 3
    stack = Stack(tuple(symmetric_module(rng) for _ in range(n)))
    path = StackPath(stack, stack)
    found = settle_stack(stack, rng.uniform(0.3, 1.2, (n, 2)))
    image = path.mirror(found.state, 0.0)
    from_angles = path.state_from_angles(path.angles(found.state, 0.0)[:, ::-1], 0.0)
    rods = path.topology.n_rods
    assert np.max(np.abs(path.canonical(image - from_angles)[:rods])) < 1e-12
    assert np.max(np.abs(path.residual(image, 0.0))) < 1e-9 * path.f_ref
    assert path.energy(image, 0.0) == pytest.approx(path.energy(found.state, 0.0), rel=1e-12)
    assert np.allclose(path.eigenvalues(image, 0.0), found.eigenvalues, rtol=1e-9)
    for name, value in (('L2', 1.3), ('kb', 99.0), ('f4x', 0.5), ('m2', 0.3)):
        other = stack.with_module(n - 1, **{name: value})
        assert StackPath(other, other).mirror(found.state, 0.0) is None
    module = stack.modules[0]
    assert list(ModulePath(module, module).mirror([0.1, 0.7], 0.0)) == [0.7, 0.1]
    assert ModulePath(module, module.with_(kb=module.kb + 1.0)).mirror([0.1, 0.7], 0.5) is None


@pytest.mark.numerics
def test_a_rigid_flow_stepping_over_a_flat_crossing_stops_at_it():
    """A flow step whose ends lie on both sides of a module's flat crossing (both rods
    turned through the base line between them) is searched on its dense output: the
    flattest state in it is found, flatter than either end."""
    from tensegrity_ros.core.continuation.flows import flattest_in_step
    stack = Stack((ModuleParams.paper(0.6), ModuleParams.paper(0.6)))
    path = StackPath(stack, stack)
    a, b = np.zeros(path.size), np.zeros(path.size)
    a[:4] = [0.3, math.pi - 0.3, 0.3, 2.8]
    b[:4] = [-0.3, math.pi + 0.3, 0.3, 2.8]
    assert path.turned_through_base(a, b, 0.0)
    assert not path.turned_through_base(a, a, 0.0)

    class Step:                 # a straight step from a to b, as an LSODA dense output
        t_old, t = 0.0, 1.0

        def __call__(self, t):
            return a + t * (b - a)

    class Solver:
        def dense_output(self):
            return Step()

    flattest = flattest_in_step(Solver(), 0.0, path.flatness)
    assert path.flatness(flattest, 0.0) < 1e-6 * min(path.flatness(a, 0.0), path.flatness(b, 0.0))
    assert abs(flattest[0]) < 1e-6
