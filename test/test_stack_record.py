"""A stack record's nodes and head (made on first use, from the rods of the tracker's last
evaluation) against forward kinematics of the record's own local angles, written here."""
import cmath
import math

from hypothesis import given, settings, strategies as st
import numpy as np

from tensegrity_ros.core.module.model import ModuleParams
from tensegrity_ros.core.simulation.simulator import Simulator

NECK = [ModuleParams(rho=r, L1=0.12, L2=0.12, ka=300.0, kb=300.0, kc=300.0, m1=0.02,
                     m2=0.02) for r in (0.09, 0.085, 0.08)]
NECK_THETA = [[0.754, 0.754], [0.813, 0.813], [0.831, 0.831]]


def forward_kinematics(modules, theta):
    """A1(0), A2(0), then A3(i), A4(i): module i stands on module i-1's top chord
    (A1(i) = A4(i-1), A2(i) = A3(i-1)); t1 is rod A1A3 from the module's x axis
    A1 -> A2, t2 rod A2A4 from its -x axis."""
    a1, a2 = 0j, complex(modules[0].rho)
    nodes = [a1, a2]
    for m, (t1, t2) in zip(modules, theta):
        frame = cmath.phase(a2 - a1)
        a3 = a1 + m.L1 * cmath.exp(1j * (frame + t1))
        a4 = a2 + m.L2 * cmath.exp(1j * (frame + math.pi - t2))
        nodes += [a3, a4]
        a1, a2 = a4, a3
    return np.array([[z.real, z.imag] for z in nodes])


@settings(max_examples=15, deadline=None, derandomize=True)
@given(st.lists(st.tuples(st.floats(-3e-3, 3e-3), st.floats(-3e-3, 3e-3),
                          st.floats(-3e-3, 3e-3)), min_size=1, max_size=4))
def test_nodes_and_head_are_those_of_the_angles(moves):
    sim = Simulator(NECK, NECK_THETA)
    for move in moves:
        sim.command_rhos({i: m.rho + d for i, (m, d) in enumerate(zip(NECK, move))}, 0)
        state = sim.state
        expected = forward_kinematics(sim.modules, state.theta)
        np.testing.assert_allclose(state.nodes, expected, rtol=0, atol=1e-12)
        a3, a4 = expected[-2], expected[-1]
        np.testing.assert_allclose(state.head_position, 0.5 * (a3 + a4), rtol=0, atol=1e-12)
        assert math.isclose(state.head_angle, math.atan2(*(a3 - a4)[::-1]), abs_tol=1e-12)
        position, angle = sim.head()
        np.testing.assert_allclose(position, 0.5 * (a3 + a4), rtol=0, atol=1e-12)
        assert angle == state.head_angle


def test_scales_carried_along_actuator_commands_equal_fresh_ones():
    """A path whose rods and springs stay still hands its scales on to its end (the next
    command's start): they are the ones computed afresh, and a design change computes new."""
    from tensegrity_ros.core.neck.stack import Stack, StackPath
    start = Stack(tuple(NECK))
    ends = [Stack(tuple(m.with_rho(m.rho + 1e-4 * k) for m in NECK)) for k in (1, 2, 3)]
    ends.append(Stack(tuple(m.with_(L1=0.13) for m in ends[-1].modules)))
    for end in ends:
        carried = StackPath(start, end)
        fresh = StackPath(Stack(start.modules), Stack(end.modules))
        assert (carried.l_ref, carried.f_ref) == (fresh.l_ref, fresh.f_ref)
        np.testing.assert_array_equal(carried.state_weights, fresh.state_weights)
        start = end
    fresh = StackPath(Stack(start.modules), Stack(start.modules))  # from the changed design
    assert (StackPath(start, start).l_ref == fresh.l_ref
            != StackPath(Stack(tuple(NECK)), start).l_ref)


def test_lazy_angles_and_forces_are_those_of_a_fresh_evaluation():
    """A record's angles, actuator forces and nodes, made on first read from the tracker's
    kept evaluation, are those of a fresh path evaluated at the record's own state and
    parameters (read after later commands, so a reused evaluation would show)."""
    from tensegrity_ros.core.neck.stack import settle_stack, Stack, StackPath, track_stack
    stack = Stack(tuple(NECK))
    state = settle_stack(stack, NECK_THETA)
    records = []
    rng = np.random.default_rng(7)
    for _ in range(6):
        i = int(rng.integers(len(NECK)))
        end = stack.with_module(i, rho=stack.modules[i].rho + rng.uniform(-2e-3, 2e-3))
        state = track_stack(stack, end, state).final
        records.append((end, state))
        stack = end
    for end, record in records:
        fresh = StackPath(end, end)
        np.testing.assert_array_equal(record.theta, fresh.angles(record.state, 0.0))
        np.testing.assert_allclose(record.actuator_forces,
                                   fresh.actuator_forces(record.state, 0.0), rtol=1e-12)
        np.testing.assert_allclose(record.nodes, fresh.nodes(record.state, 0.0), rtol=0,
                                   atol=1e-15)


def test_a_record_keeps_rod_angles_within_a_turn_whatever_state_it_is_made_from():
    """Landing flows can turn rods thousands of times (seen: 4.3e4 rad after a jump from a
    module folded flat, bench_round_commands seed 0, stream 11); a kept state so large
    loosens every later Newton stop (relative to 1 + |y|).  A record made from such a
    state, or tracked from it, holds the same rods with angles within [-pi, pi], and
    angles within 3 pi are kept bit for bit."""
    from tensegrity_ros.core.neck.stack import (settle_stack, Stack, stack_equilibrium_at,
                                                track_stack)
    stack = Stack(tuple(NECK))
    settled = settle_stack(stack, NECK_THETA)
    y = settled.state
    n = 2 * len(NECK)
    assert np.all(np.abs(y[:n]) <= math.pi)
    assert np.array_equal(stack_equilibrium_at(stack, y).state, y)
    once = y.copy()
    once[:n] += 2.0 * math.pi * np.array([1.0, -1.0, 0.0, 0.0, 1.0, 0.0])
    assert np.array_equal(stack_equilibrium_at(stack, once).state, once)
    turns = np.array([6913.0, -3.0, 2.0, 0.0, -6913.0, 2.0])
    spun = y.copy()
    spun[:n] += 2.0 * math.pi * turns
    record = stack_equilibrium_at(stack, spun)
    assert np.all(np.abs(record.state[:n]) <= math.pi)
    np.testing.assert_allclose(record.state, y, rtol=0, atol=1e-11)
    np.testing.assert_allclose(record.eigenvalues, settled.eigenvalues, rtol=1e-9)
    assert record.stable
    moved = Stack(tuple(m.with_rho(m.rho + 2e-3) for m in NECK))
    for start in (spun, record):
        track = track_stack(stack, moved, start)
        assert track.status == 'ok' and not track.jumps
        assert np.all(np.abs(track.final.state[:n]) <= math.pi + 0.1)


def test_a_one_step_track_is_the_dataclass_one():
    """The small command's result is made by filling the instance dict (issue 14): it must
    equal the frozen dataclass made through its own __init__, field for field, so that a
    field added to StackTrack cannot be left out of it silently."""
    from tensegrity_ros.core.neck.stack import _one_step_track, Stack, StackTrack, track_stack
    start = Stack(tuple(NECK))
    end = start.with_module(1, rho=0.086)
    track = track_stack(start, end, np.array(NECK_THETA))
    assert track.steps == 1                     # the small-command path
    made = StackTrack(final=track.final, end=end, jumps=(), steps=1)
    assert _one_step_track(track.final, end) == made
    assert vars(_one_step_track(track.final, end)) == vars(made)
