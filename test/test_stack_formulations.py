"""The reduced (rod-angle) stack formulation against the node-coordinate one it replaced
(test/stack_cartesian_reference.py, run by the same generic tracker): same equilibria,
eigenvalues, energies, actuator forces and jumps to 1e-10, on seeded random small
commands and on jump-crossing paths; analytic derivatives against finite differences."""
from hypothesis import given, settings, strategies as st
import numpy as np
import pytest

from stack_cartesian_reference import CartesianStackPath
from tensegrity_ros.core import continuation, ModuleParams
from tensegrity_ros.core.neck.stack import settle_stack, Stack, StackPath, track_stack

#: Numerically sensitive throughout: `make test-numerics` runs it under other CPUs' arithmetic.
pytestmark = pytest.mark.numerics


def wrapped(a, b):
    return float(np.max(np.abs((np.asarray(a) - np.asarray(b) + np.pi) % (2 * np.pi) - np.pi)))


def random_stack(rng, n):
    return Stack(tuple(ModuleParams(rho=rng.uniform(0.6, 0.8), L1=rng.uniform(0.9, 1.1),
                                    L2=rng.uniform(0.9, 1.1), ka=rng.uniform(80, 120),
                                    kb=rng.uniform(80, 120), kc=rng.uniform(80, 120),
                                    f3x=rng.uniform(-1, 1), f3y=rng.uniform(-2, 2),
                                    f4x=rng.uniform(-1, 1), f4y=rng.uniform(-2, 2),
                                    m1=rng.uniform(0, 0.2), m2=rng.uniform(0, 0.2))
                       for _ in range(n)))


def by_reference(start, end, theta):
    """The node-coordinate formulation on the generic tracker, from local angles."""
    path = CartesianStackPath(start, end)
    y = continuation.settle(path, path.state_from_angles(theta, 0.0), 0.0)
    return path, continuation.track(path, y)


def assert_same_state(new, path, y, s, mirrored=False):
    """Same state; ``mirrored``: the mirror image (t1 <-> t2) of a symmetric stack's."""
    ref_eig = path.eigenvalues(y, s)
    theta = path.angles(y, s)
    assert wrapped(new.theta, theta[:, ::-1] if mirrored else theta) < 1e-10
    assert np.max(np.abs(new.eigenvalues - ref_eig)) < 1e-10 * np.max(np.abs(ref_eig))
    assert new.energy == pytest.approx(path.energy(y, s), abs=1e-10 * max(1.0, abs(new.energy)))
    forces = path.actuator_forces(y, s)      # to 1e-10 of the forces (or of 1 N)
    assert np.max(np.abs(new.actuator_forces - forces)) < 1e-10 * max(1.0, np.max(np.abs(forces)))
    if not mirrored:
        assert np.max(np.abs(new.nodes - path.nodes(y, s))) < 1e-10


@pytest.mark.parametrize('n', [1, 2, 3])
def test_seeded_small_commands_agree_with_node_coordinates(n):
    rng = np.random.default_rng(100 + n)
    for _ in range(3):
        stack = random_stack(rng, n)
        state = settle_stack(stack, np.full((n, 2), 0.75))
        for _ in range(3):
            i = int(rng.integers(n))
            end = stack.with_module(i, rho=stack.modules[i].rho + rng.uniform(-2e-3, 2e-3),
                                    f3y=stack.modules[i].f3y + rng.uniform(-0.1, 0.1))
            ours = track_stack(stack, end, state)
            path, ref = by_reference(stack, end, state.theta)
            assert ours.status == ref.status == 'ok'
            assert not ours.jumps and not ref.events
            assert_same_state(ours.final, path, ref.state, 1.0)
            stack, state = end, ours.final


def neck(n, load, rho=0.6):
    return Stack(tuple([ModuleParams.paper(rho)] * (n - 1)
                       + [ModuleParams.paper(rho, F3=load, F4=load)]))


JUMP_PATHS = [
    # fig. 8a as a one-module stack: the lower branch ends at the fold C2
    (Stack((ModuleParams.paper(0.5, F3=5, F4=5),)), Stack((ModuleParams.paper(1.2, F3=5, F4=5),)),
     [[-1.0, -1.0]]),
    # an upright two- and three-module neck buckles under a growing head load
    (neck(2, 0.0), neck(2, -30.0), [[0.93, 0.93]] * 2),
    (neck(3, 0.0), neck(3, -15.0), [[0.93, 0.93]] * 3),
]


#: The two formulations' departures agree to this (rad).  A fold's departure is a double
#: root of the equilibrium equations: next to it the branch moves like a sqrt(s* - s)
#: (a ~ 1.2 rad on the N = 3 head-load fold, 0.5 within 1e-10 of it), and rounding pins
#: its state along the critical mode only to ~sqrt(rounding), so two localisations of one
#: fold (here 8e-13 apart in s) give departures up to ~2e-5 apart (1.7e-5 on the Haswell
#: BLAS kernel); a branch point's departure is a regular point of its branch.
DEPARTURE_TOL = {'fold': 1e-4, 'branch_point': 1e-6}


@pytest.mark.parametrize('start, end, theta', JUMP_PATHS)
def test_jumps_agree_with_node_coordinates(start, end, theta):
    first = settle_stack(start, theta)
    ours = track_stack(start, end, first)
    path, ref = by_reference(start, end, first.theta)
    assert ours.status == ref.status == 'ok'
    assert ours.jumps and [j.kind for j in ours.jumps] == [e.kind for e in ref.events]
    # the landings: each formulation freezes the parameters a little past the event (the
    # offset scales with its own |dF/ds|), so the reference landing is followed on its
    # branch to where ours landed and compared there
    raw = continuation.track(StackPath(start, end), first.state)
    # at a symmetric pitchfork both sides land on mirror images; a supercritical one is
    # passed continuously onto a side chosen by a rule in each formulation's coordinates
    mirrored = bool(ours.passages) and wrapped(
        ours.jumps[0].from_theta, path.angles(ref.events[0].state, ref.events[0].s)) > 1e-6

    def orient(theta):
        return np.asarray(theta)[:, ::-1] if mirrored else np.asarray(theta)
    for jump, mine, event in zip(ours.jumps, raw.events, ref.events):
        assert jump.s == pytest.approx(event.s, abs=1e-10)
        assert wrapped(jump.from_theta, orient(path.angles(event.state, event.s))) < \
            DEPARTURE_TOL[jump.kind]
        there = CartesianStackPath(path.params(event.landing_s), path.params(mine.landing_s))
        landed = continuation.track(there, event.landing)
        assert landed.status == 'ok' and not landed.events
        landing = there.angles(landed.state, 1.0)
        # of equal energy: the jump is flagged ambiguous by both, and either is the answer;
        # ours also flags what the node-coordinate problem has no methods to see (the
        # landing's mirror image on a mirror-symmetric neck, a flat crossing the landing
        # flow passed: StackPath.mirror, crossing_ways), as the independent reference
        # does (test_reference_tracking)
        assert jump.ambiguous or not event.ambiguous
        if jump.ambiguous and wrapped(jump.to_theta, orient(landing)) > 1e-10:
            mirrored = not mirrored
        assert wrapped(jump.to_theta, orient(landing)) < 1e-10
    assert_same_state(ours.final, path, ref.state, 1.0, mirrored)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2 ** 16), n=st.integers(1, 4), s=st.floats(0.0, 1.0))
def test_analytic_derivatives_match_finite_differences(seed, n, s):
    """Jacobian, dF/ds and dE/ds at arbitrary (non-equilibrium) states and s."""
    rng = np.random.default_rng(seed)
    path = StackPath(random_stack(rng, n), random_stack(rng, n))
    y = np.concatenate([rng.uniform(-np.pi, np.pi, 2 * n), rng.uniform(-1, 1, n - 1)])
    h = 1e-6
    fd = np.column_stack([(path.residual(y + h * e, s) - path.residual(y - h * e, s)) / (2 * h)
                          for e in np.eye(path.size)])
    assert np.max(np.abs(path.jacobian(y, s) - fd)) < 1e-5 * max(1.0, np.max(np.abs(fd)))
    fd_s = (path.residual(y, s + h) - path.residual(y, s - h)) / (2 * h)
    assert np.max(np.abs(path.residual_s(y, s) - fd_s)) < 1e-5 * max(1.0, np.max(np.abs(fd_s)))
    fd_e = (path.energy(y, s + h) - path.energy(y, s - h)) / (2 * h)
    assert path.energy_s(y, s) == pytest.approx(fd_e, abs=1e-5 * max(1.0, abs(fd_e)))
    grad = np.array([(path.energy(y + h * e, s) - path.energy(y - h * e, s)) / (2 * h)
                     for e in np.eye(path.size)])[:2 * n]
    assert np.max(np.abs(path.residual(y, s)[:2 * n] * path.l_ref - grad)) \
        < 1e-5 * max(1.0, np.max(np.abs(grad)))


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2 ** 16), n=st.integers(1, 3))
def test_stability_is_the_same_in_either_coordinates(seed, n):
    """At an equilibrium the reduced Hessian's eigenvalues (N/m) do not depend on the
    coordinates: rod angles with chords, or node positions with every rigid length."""
    rng = np.random.default_rng(seed)
    stack = random_stack(rng, n)
    state = settle_stack(stack, rng.uniform(0.5, 1.0, (n, 2)))
    ref = CartesianStackPath(stack, stack)
    y = ref.project(ref.state_from_angles(state.theta, 0.0), 0.0)
    eig = ref.eigenvalues(y, 0.0)
    assert np.max(np.abs(state.eigenvalues - eig)) < 1e-9 * np.max(np.abs(eig))
    assert state.stable


@pytest.mark.parametrize('n', [1, 2, 3])
def test_the_fast_path_takes_a_command_exactly_when_the_tracker_takes_it_in_one_step(n):
    """The one-step fast path applies the tracker's acceptance rules: it answers exactly
    the commands the generic tracker covers in one step, with the tracker's state."""
    from tensegrity_ros.core.neck.fast_step import whole_command_step
    rng = np.random.default_rng(200 + n)
    taken = declined = 0
    for size in (1e-4, 1e-3, 1e-2, 3e-2, 1e-1, 0.2):
        stack = random_stack(rng, n)
        state = settle_stack(stack, np.full((n, 2), 0.75))
        i = int(rng.integers(n))
        end = stack.with_module(i, rho=stack.modules[i].rho + size * rng.choice((-1.0, 1.0)))
        path = StackPath(stack, end)
        fast = whole_command_step(path, state.state, continuation.TrackerSettings(), state)
        full = continuation.track(StackPath(stack, end), state.state)
        one_step = full.status == 'ok' and full.steps == 1 and not full.events
        assert (fast is not None) == one_step, (n, size, full.steps)
        if fast is not None:
            assert wrapped(fast[0], full.state) < 1e-10
            assert np.max(np.abs(fast[1] - full.eigenvalues)) < 1e-10 * abs(full.eigenvalues[-1])
        taken += fast is not None
        declined += fast is None
    assert taken and declined           # both sides of the rule were exercised
