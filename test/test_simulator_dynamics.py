"""The simulator's dynamics mode, ROS-free: a fold crossing driven in ticks reports the
jump with the figures of the one-shot simulation (an independent integration of the
same profile), commands during the transient act on the moving rods, the state claims
no verified equilibrium while the rods move, and bad input changes nothing."""
import math

from hypothesis import given, HealthCheck, settings, strategies as st
import numpy as np
import pytest

from tensegrity_ros.core import ModuleParams, simulate_snap
from tensegrity_ros.core.simulation.dynamic_simulator import DynamicSimulator
from tensegrity_ros.core.simulation.events import Jump, JumpAhead, REFUSED
from tensegrity_ros.core.simulation.simulator import ModuleLimits, Simulator

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
    ({'params': FIG8A.with_(m1=0.0)}, 'm1'),
    ({'limits': ModuleLimits(max_rho_rate=0.0)}, 'max_rate'),
    ({'damping': 0.0}, 'damping'),
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
    """The overdamped limit (docs/model.md section 5): same jump, same landing as the tracker."""
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


def test_an_exactly_symmetric_module_past_c1_snaps_live_and_reports_the_jump():
    """Issue 35: fig. 8a (symmetric bit for bit) ramped down through its branch point C1
    to 0.1 at 0.1 m/s: the rods used to creep on the unstable symmetric branch for ever
    (no jump, the dynamics mode never at rest); with the built-in imperfection they snap
    as the one-shot simulation does (MuJoCo: peak 33.4 rad/s) and the jump is reported
    at rest, the tracker's branch point beside it."""
    ref = simulate_snap(FIG8A, 0.1, RATE, 0.01, LOWER).summary
    sim = make(damping=0.01)
    assert sim.command_rho(0, 0.1, 0).accepted
    jumps, now = [], 0
    while (sim.moving or now == 0) and now < 120 * 10**9:
        now += TICK_NS
        jumps += sim.advance(now).of_type(Jump)
    [jump] = jumps
    assert jump.kind == 'branch_point' and jump.modules[0].rho == pytest.approx(0.1514, abs=1e-4)
    assert jump.dynamics['peak_speed'] == pytest.approx(33.4, rel=5e-3)
    assert jump.dynamics['onset_time'] == pytest.approx(ref['onset_time'], rel=1e-4)
    assert jump.dynamics['peak_speed'] == pytest.approx(ref['peak_speed'], rel=1e-5)
    assert jump.to_theta[0][0] > 1.0 and sim.stable and not jump.dynamics['lands_elsewhere']


# ---------------------------------------------------------------------------
# issue 31: bounded work, faithful state times, deferred operations that complete

class CountingClock:
    """A clock that advances one unit each time it is read: a time budget of n units is n
    readings (one per 2 ms sample of the integration, one per tracker check point), the
    same on any machine."""

    def __init__(self):
        self.now = 0

    def __call__(self):
        self.now += 1
        return self.now


def _drive(sim, until_ns, tick_ns=TICK_NS, start_ns=0, during=None):
    """advance() every tick; (jumps, every call's (now, state_time_ns, lag))."""
    jumps, calls = [], []
    for now in range(start_ns + tick_ns, until_ns + 1, tick_ns):
        jumps += sim.advance(now).of_type(Jump)
        calls.append((now, sim.state_time_ns, sim.lag))
        if during is not None:
            during(sim, now)
    return jumps, calls


def test_a_call_integrates_within_its_budget_the_simulation_lags_then_catches_up():
    """Fig. 8a's fold, 50 ms ticks, a budget of 10 clock readings a call (a counting
    clock): each call integrates at most ~10 samples of 2 ms, 20 of the 50 ms that pass,
    so the simulation falls behind: the live state holds for state_time_ns, earlier than
    the call, ``lag`` says by how much and ``lagging_calls`` counts.  With the budget back
    it catches up, and ends exactly as an unbounded simulation of the same commands (the
    integration stops only between samples; VODE never restarts there)."""
    clock = CountingClock()
    sim = DynamicSimulator([FIG8A], [LOWER], [LIMITS], damping=[DAMPING], time_budget=10,
                           clock=clock)
    ref = make()
    assert sim.command_rho(0, 0.9, 0).accepted and ref.command_rho(0, 0.9, 0).accepted
    _, calls = _drive(sim, 4 * 10**9)
    progress = np.diff([0] + [t for _, t, _ in calls])
    assert np.max(progress) <= 11 * 2_000_000             # <= ~10 samples a call
    now, state_time, lag = calls[-1]
    assert state_time < now and lag == pytest.approx((now - state_time) * 1e-9)
    assert sim.lagging_calls == len(calls)
    ref_jumps, _ = _drive(ref, state_time, tick_ns=state_time)   # one unbounded call
    assert sim.live(0) == ref.live(0)                      # the state at its own time
    sim.time_budget = None
    jumps, calls = _drive(sim, 40 * 10**9, start_ns=4 * 10**9)
    assert calls[-1][2] == 0.0 and calls[-1][1] == 40 * 10**9     # caught up
    ref_jumps, _ = _drive(ref, 40 * 10**9, start_ns=4 * 10**9)     # the same ticks
    [jump], [ref_jump] = jumps, ref_jumps
    assert jump.dynamics == ref_jump.dynamics and np.array_equal(jump.to_theta,
                                                                 ref_jump.to_theta)


def test_commands_and_changes_given_while_the_simulation_lags_act_at_their_own_time():
    """A lagging simulation (2 clock readings a call) gets a command and a load change at
    times it has not reached: they wait and act at those times, as in an unbounded one."""
    sim = DynamicSimulator([FIG8A], [LOWER], [LIMITS], damping=[0.5], time_budget=2,
                           clock=CountingClock())
    ref = make(damping=0.5)
    for s in (sim, ref):
        s.command_rho(0, 0.9, 0)
    _drive(sim, 10**9)
    assert sim.state_time_ns < 10**9
    for s in (sim, ref):
        assert s.command_rho(0, 0.7, 10**9).accepted
        assert s.set_force(0, 'a3', (0.0, 4.0), 15 * 10**8).accepted
    _drive(ref, 10**9, start_ns=0, tick_ns=10**9)
    sim.time_budget = None
    _drive(sim, 30 * 10**9, start_ns=10**9)
    _drive(ref, 30 * 10**9, start_ns=10**9)
    assert not sim.moving and sim.modules == ref.modules and sim.modules[0].f3y == 4.0
    assert sim.state.theta == pytest.approx(ref.state.theta, abs=1e-12)


def test_a_reset_that_needs_more_than_one_call_completes():
    """The issue's case: fig. 8a, rate 0.5 m/s, damping 0.5, command 0.95 and 2 s of 20 ms
    ticks (snapped); a reset whose settle overruns a budget of 1e-9 s is deferred; with
    the budget back it completes within a few ticks (it used to stay pending for ever,
    the rods in the snapped state)."""
    sim = DynamicSimulator([ModuleParams.paper(0.5, F3=5, F4=5).with_(m1=0.05, m2=0.05)],
                           [[-1.0, -1.0]], [ModuleLimits(rho_min=0.05, rho_max=1.95,
                                                         max_rho_rate=0.5)], damping=(0.5,))
    sim.command_rho(0, 0.95, 0)
    for now in range(20_000_000, 2 * 10**9 + 1, 20_000_000):
        sim.advance(now)
    assert sim.live(0).theta1 > 0                          # snapped up
    sim.time_budget = 1e-9
    assert sim.reset([FIG8A.with_(rho=0.5)], [[-1.0, -1.0]]).accepted
    assert sim.pending
    sim.time_budget = 0.05
    now, ticks = 2 * 10**9, 0
    while sim.pending and ticks < 200:
        now, ticks = now + 20_000_000, ticks + 1
        sim.advance(now)
    assert not sim.pending and ticks <= 5
    assert sim.modules[0].rho == 0.5 and sim.state.theta[0] < 0 and sim.stable
    assert not sim.moving and sim.live(0).theta1 == sim.state.theta1
    assert sim.command_rho(0, 0.6, now).accepted and sim.moving     # and it moves on


def test_a_module_command_beyond_its_fold_warns_at_once():
    """The early warning of the quasi-static mode (the exact operation range) for a command
    given at rest; for one given while the rods move, the same rule from the equilibrium at
    the actuator length now on the branch the rods are on (V1: none before, whereas the
    quasi-static mode warns); none once the actuator has passed the fold."""
    sim = make()
    warnings = sim.command_rho(0, 0.9, 0).of_type(JumpAhead)
    assert len(warnings) == 1 and warnings[0].end.kind == 'fold'
    fold = simulate_snap(FIG8A, 0.9, RATE, DAMPING, LOWER).static_fold_rho
    assert warnings[0].end.rho == pytest.approx(fold)
    run(sim, 0, 10**9)                              # rho = 0.6: the fold 2.8 s ahead
    [warning] = sim.command_rho(0, 0.95, 10**9).of_type(JumpAhead)
    assert warning.end.kind == 'fold' and warning.rho == 0.95
    assert warning.end.rho == pytest.approx(fold, abs=1e-9)
    run(sim, 10**9, 4 * 10**9)                      # rho = 0.9: past the fold, snapping
    assert sim.moving and sim.live(0).theta1 > 0.0
    later = list(sim.command_rho(0, 0.96, 4 * 10**9).of_type(JumpAhead))
    for now in range(4 * 10**9 + TICK_NS, 5 * 10**9, TICK_NS):
        later += sim.advance(now).of_type(JumpAhead)
    assert not later


# ---------------------------------------------------------------------------
# V1 acceptance (issues 31, 35): the snap past C1 comes to rest whatever the tick phase;
# a command given on the way warns as in the quasi-static mode

@pytest.mark.parametrize('phase_ms', [0, 1, 7, 10, 13])
def test_the_snap_past_c1_is_reported_whatever_the_phase_of_the_command(phase_ms):
    """V1 (issue 35, 2; issue 31, the node never silent): the README's fig. 8a walk-through
    in the dynamics mode (50 g rods, 0.1 m/s, damping 0.01, 20 ms ticks) with the command
    arriving between two ticks, as a real node's commands do.  The rods snap at ~5.45 s and
    rest on the upper branch within ~65 s (the one-shot simulation settles 59.57 s after
    the onset), so the jump must be reported by 120 s.  Fails at f8d033b for phases 1 and
    7 ms: the rest candidate is taken (once per held segment) while the rods creep on the
    unstable branch, and rod 2 then swings through -pi: its continuous angle ends 2 pi away
    from the candidate's, the energy 'above the rest' never falls below the threshold, the
    simulator stays 'moving' for ever (no jump, stable false, equilibrium 'in motion'),
    though the rods rest (|theta'| ~ 1e-10 rad/s).  Seen live twice with the real ros2 CLI:
    no jump 150 s after `ros2 topic pub --once /m0/rho_cmd ... 0.1`."""
    sim = make(damping=0.01)
    tick = 20_000_000
    sim.advance(tick)
    assert sim.command_rho(0, 0.1, tick + phase_ms * 1_000_000).accepted
    jumps, now = [], tick
    while not jumps and now < 120 * 10**9:
        now += tick
        jumps += sim.advance(now).of_type(Jump)
    assert jumps, (f'no jump reported in 120 s; moving={sim.moving}, live={sim.live(0)}')
    [jump] = jumps
    assert jump.kind == 'branch_point' and jump.to_theta[0][0] > 1.0
    assert not sim.moving and sim.stable


def test_a_module_command_given_on_the_way_to_a_fold_warns_as_the_quasi_static_mode():
    """V1 (issue 31, 3: early warning 'by the same rule as the quasi-static mode'): the
    actuator runs 0.5 -> 0.7 (no fold ahead); 0.5 s later, on the way, the target becomes
    0.9, beyond the fold at 0.8786 (reached ~3.8 s later).  The quasi-static simulator
    warns of it at once (JumpAhead); 8db3247's dynamics mode did too.  Fails at f8d033b:
    the dynamics mode warns only of commands given at rest (its own test asserts the
    opposite: test_a_module_command_beyond_its_fold_warns_at_once), so the jump comes
    unannounced."""
    found = {}
    for name, sim in (('quasi-static', Simulator([FIG8A], [LOWER], [LIMITS])),
                      ('dynamics', make())):
        sim.command_rho(0, 0.7, 0)
        run(sim, 0, 500_000_000)
        found[name] = [(w.end.kind, round(w.end.rho, 6))
                       for w in sim.command_rho(0, 0.9, 500_000_000).of_type(JumpAhead)]
    assert found['quasi-static'] == [('fold', round(0.8785791152895454, 6))]
    assert found['dynamics'] == found['quasi-static']
