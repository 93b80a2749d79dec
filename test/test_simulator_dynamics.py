"""The simulator's dynamics mode, ROS-free: a fold crossing driven in ticks reports the
jump with the figures of the one-shot simulation (an independent integration of the
same profile), commands during the transient act on the moving rods, the state claims
no verified equilibrium while the rods move, and bad input changes nothing."""
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from tensegrity_ros.core import ModuleParams, simulate_snap
from tensegrity_ros.core.dynamic_simulator import DynamicSimulator
from tensegrity_ros.core.events import Jump, REFUSED
from tensegrity_ros.core.simulator import ModuleLimits, Simulator

FIG8A = ModuleParams.paper(0.5, F3=5.0, F4=5.0).with_(m1=0.05, m2=0.05)
LOWER = (-1.0, -1.0)
RATE, DAMPING = 0.1, 0.05
LIMITS = ModuleLimits(rho_min=0.05, rho_max=1.95, max_rho_rate=RATE)
TICK_NS = 50_000_000


def make(params=FIG8A, damping=DAMPING, limits=LIMITS):
    return DynamicSimulator([params], [LOWER], [limits], damping=[damping])


def run(sim, start_ns, until_ns, during=None):
    """Advance in ticks; returns (jumps, time of the last tick)."""
    jumps, now = [], start_ns
    while now < until_ns:
        now += TICK_NS
        outcome = sim.advance(now)
        jumps += outcome.of_type(Jump)
        if during is not None:
            during(sim)
    return jumps, now


def test_a_fold_crossing_reports_the_jump_with_the_one_shot_figures():
    ref = simulate_snap(FIG8A, 0.9, RATE, DAMPING, LOWER)
    sim = make()
    assert sim.command_rho(0, 0.9, 0).accepted
    seen = {'speed': 0.0, 'claimed_stable': False, 'nodes_follow_the_rods': True}

    def during(s):
        if s.moving:
            live = s.live(0)
            seen['speed'] = max(seen['speed'], abs(live.theta1_dot), abs(live.theta2_dot))
            seen['claimed_stable'] |= s.stable or s.status(0).level == 'ok'
            a3 = s.module_nodes(0)[2]          # A3 = L1 (cos theta1, sin theta1), L1 = 1
            seen['nodes_follow_the_rods'] &= bool(np.allclose(
                a3, [math.cos(live.theta1), math.sin(live.theta1)], atol=1e-12))
            seen['nodes_follow_the_rods'] &= s.head()[0][0] == pytest.approx(
                0.5 * (a3[0] + s.module_nodes(0)[3][0]))

    [jump], _ = run(sim, 0, 30 * 10**9, during)
    figures = jump.dynamics
    for key in ('onset_rho', 'peak_speed', 'peak_actuator_force', 'overshoot'):
        assert figures[key] == pytest.approx(ref.summary[key], rel=1e-6), key
    assert figures['settle_time'] == pytest.approx(ref.summary['settle_time'], rel=1e-4)
    assert jump.kind == 'fold' and jump.modules[0].rho == pytest.approx(ref.static_fold_rho)
    assert not figures['lands_elsewhere']
    final = ref.summary['final']
    assert jump.to_theta[0] == pytest.approx([final['theta1'], final['theta2']], abs=1e-6)
    assert seen['speed'] > 1.0 and not seen['claimed_stable']
    assert seen['nodes_follow_the_rods']
    # at rest: a verified stable equilibrium at the target, as the quasi-static mode holds
    params, eq = sim.module(0)
    assert params.rho == 0.9 and sim.stable and not sim.moving
    assert [eq.theta1, eq.theta2] == pytest.approx(jump.to_theta[0], abs=1e-12)
    assert sim.live(0).theta1_dot == 0.0 and sim.status(0).last_jump is not None


def test_a_command_during_the_transient_acts_on_the_moving_rods():
    sim = make()
    sim.command_rho(0, 0.9, 0)
    _, now = run(sim, 0, int(3.9e9))                 # the snap is under way (onset ~3.82 s)
    before = sim.live(0)
    assert max(abs(before.theta1_dot), abs(before.theta2_dot)) > 1.0
    assert sim.command_rho(0, 0.7, now).accepted
    after = sim.live(0)
    assert (after.rho, after.theta1_dot) == (before.rho, before.theta1_dot)
    assert after.rho_dot == -RATE                     # heading back at the speed limit
    jumps, _ = run(sim, now, 40 * 10**9)
    assert len(jumps) == 1 and jumps[0].to_theta[0][0] > 0      # still lands up
    assert sim.modules[0].rho == 0.7 and sim.stable


def test_bad_input_changes_nothing():
    sim = make()
    sim.command_rho(0, 0.9, 0)
    _, now = run(sim, 0, int(3.9e9))
    live = sim.live(0)
    for outcome in (sim.command_rho(0, math.nan, now), sim.command_rho(0, 5.0, now),
                    sim.set_parameters({0: {'m1': 0.0}}, now, 'test'),
                    sim.set_damping(0, -1.0, now),
                    sim.set_limits(0, ModuleLimits(0.05, 1.95, 0.0), now)):
        assert outcome.status == REFUSED and outcome.message
    assert sim.live(0) == live and sim.target(0) == 0.9


@pytest.mark.parametrize('bad, text', [
    (dict(params=FIG8A.with_(m1=0.0)), 'm1'),
    (dict(limits=ModuleLimits(max_rho_rate=0.0)), 'max_rate'),
    (dict(damping=0.0), 'damping'),
])
def test_a_dynamics_mode_without_masses_speed_or_damping_is_refused(bad, text):
    with pytest.raises(ValueError, match=text):
        make(**bad)


def test_a_neck_module_without_mass_or_damping_is_refused():
    """A neck is simulated (since issue 15), but each module needs its masses and damping."""
    with pytest.raises(ValueError, match='m1'):
        DynamicSimulator([FIG8A, FIG8A.with_(m1=0.0)], [LOWER, LOWER], [LIMITS, LIMITS],
                         damping=[0.1, 0.1])
    with pytest.raises(ValueError, match='damping'):
        DynamicSimulator([FIG8A, FIG8A], [LOWER, LOWER], [LIMITS, LIMITS], damping=[0.1, 0.0])


def test_a_load_change_moves_the_rods_from_where_they_are():
    sim = make(damping=0.5)
    assert sim.set_force(0, 'a3', (0.0, 4.0), 0).accepted
    assert sim.moving and not sim.stable
    run(sim, 0, 20 * 10**9)
    params, eq = sim.module(0)
    assert params.f3y == 4.0 and sim.stable
    static = Simulator([FIG8A], [LOWER], [LIMITS], time_budget=None)
    static.set_force(0, 'a3', (0.0, 4.0), 0)
    assert [eq.theta1, eq.theta2] == pytest.approx(
        [static.state.theta1, static.state.theta2], abs=1e-9)


@settings(max_examples=8, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.integers(1, 20), st.floats(0.6, 1.0)), min_size=1, max_size=4))
def test_whatever_the_commands_no_moving_state_is_claimed_stable_and_it_ends_at_rest(steps):
    """Commands at random times (ticks of 50 ms) to random targets across the fold."""
    sim = make(damping=0.5)
    now = 0
    for ticks, rho in steps:
        assert sim.command_rho(0, rho, now).accepted
        for _ in range(ticks):
            now += TICK_NS
            for jump in sim.advance(now).of_type(Jump):
                assert jump.dynamics is not None and jump.dynamics['settled']
            assert not (sim.moving and (sim.stable or sim.status(0).level == 'ok'))
    run(sim, now, now + 30 * 10**9)
    params, eq = sim.module(0)
    assert not sim.moving and sim.stable and params.rho == steps[-1][1]
    assert sim.live(0).theta1 == eq.theta1


def test_heavy_damping_lands_where_the_quasi_static_simulator_lands():
    """The overdamped limit (DESIGN.md section 9): same jump, same landing as the tracker."""
    sim = make(damping=5.0)
    sim.command_rho(0, 0.9, 0)
    [jump], _ = run(sim, 0, 60 * 10**9)
    # one path, in one call (no wall-clock budget: a loaded machine would defer it)
    static = Simulator([FIG8A], [LOWER], [ModuleLimits(0.05, 1.95)], time_budget=None)
    [static_jump] = static.command_rho(0, 0.9, 0).of_type(Jump)
    assert (jump.kind, jump.modules[0].rho) == (static_jump.kind, static_jump.modules[0].rho)
    # the quasi-static to_theta is the landing at the fold's rho; the dynamic one is the
    # rest state at the target: compare both simulators' states at the target
    assert jump.to_theta[0] == pytest.approx(static.state.theta, abs=1e-9)
    assert sim.state.theta == pytest.approx(static.state.theta, abs=1e-9)
    assert not jump.dynamics['lands_elsewhere']
    assert jump.dynamics['onset_rho'] > static_jump.modules[0].rho     # inertia delays it


def test_a_fold_crept_across_below_the_onset_speed_is_still_a_jump():
    """Damping 20 N m s/rad: the rods never reach 1 rad/s, yet they cross the fold; the
    jump is reported when they rest (no snap figures), landing where the tracker lands."""
    sim = make(damping=20.0)
    sim.command_rho(0, 0.9, 0)
    top = {'speed': 0.0}

    def during(s):
        if s.moving:
            live = s.live(0)
            top['speed'] = max(top['speed'], abs(live.theta1_dot), abs(live.theta2_dot))

    [jump], _ = run(sim, 0, 30 * 10**9, during)
    static = Simulator([FIG8A], [LOWER], [ModuleLimits(0.05, 1.95)], time_budget=None)
    [static_jump] = static.command_rho(0, 0.9, 0).of_type(Jump)
    assert 0.1 < top['speed'] < 1.0
    assert (jump.kind, jump.modules[0].rho) == (static_jump.kind, static_jump.modules[0].rho)
    assert jump.dynamics['onset_rho'] is None and jump.dynamics['peak_speed'] is None
    assert not jump.dynamics['lands_elsewhere'] and jump.dynamics['settled']
    assert sim.state.theta == pytest.approx(static.state.theta, abs=1e-9)
