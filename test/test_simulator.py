"""The core simulator without ROS: speed limits, jumps, hysteresis, reset, bad input,
parameter changes, one code path for one module and a neck.

References: the paper's fig. 8a (C1 ~ 0.155 a branch point, C2 ~ 0.87 a fold), plain
arithmetic for the speed limit, and the trackers (``track_module`` / ``track_stack``)
called directly on the same straight paths: the simulator must add no motion of its own.
"""
import math

from hypothesis import assume, given, settings, strategies as st
import numpy as np
import pytest

from tensegrity_ros.core import equilibria, ModuleParams, settle, track_module, TrackingError
from tensegrity_ros.core.neck.stack import settle_stack, Stack, track_stack
from tensegrity_ros.core.simulation.events import (combined, Jump, JumpAhead, Passage,
                                                   TrackingFailure, Undecided)
import tensegrity_ros.core.simulation.mechanisms as mechanisms
from tensegrity_ros.core.simulation.simulator import ModuleLimits, Simulator
from tensegrity_ros.core.simulation.start_state import upright_guess


def wrapped(a, b):
    """Largest angle difference modulo 2 pi."""
    d = ((np.asarray(a, dtype=float) - np.asarray(b, dtype=float) + math.pi) % (2 * math.pi)
         - math.pi)
    return float(np.max(np.abs(d)))


LOWER = [-1.0, -1.0]                 # fig. 8a: the lower stable branch at rho = 0.5
S = 1_000_000_000                    # ns per second
#: These tests are about what a path does, not how its work is split over calls (that
#: is test_bounded_work.py): one call tracks a whole path however loaded the machine.
UNBOUNDED = {'time_budget': None}


def fig8a(rho=0.5):
    return ModuleParams.paper(rho, F3=5.0, F4=5.0)


def fig8a_simulator(**limits):
    return Simulator([fig8a()], [LOWER], [ModuleLimits(0.05, 1.95, **limits)], **UNBOUNDED)


def finished(sim, outcome, now_ns=0):
    """``outcome`` with the events of the calls that finish its path, if it needed more
    than one call's time budget (``advance`` at the same time: no actuator moves)."""
    outcomes = [outcome]
    while sim.pending:
        outcomes.append(sim.advance(now_ns))
    return combined(outcomes)


def verified_minimum(sim):
    ev = np.asarray(sim.state.eigenvalues)
    return ev[0] > 1e-9 * abs(ev[-1])


# ---------------------------------------------------------------------------
# one module


def test_starts_in_the_basin_of_the_guess():
    sim = fig8a_simulator()
    params, eq = sim.module(0)
    assert params == fig8a() and eq.theta1 < 0 and eq.theta2 < 0
    np.testing.assert_allclose(eq.theta, settle(fig8a(), LOWER).theta, atol=0)
    assert sim.status(0).level == 'ok' and sim.status(0).num_stable == 2


def test_no_stable_start_is_a_value_error_naming_the_cause(monkeypatch):
    monkeypatch.setattr(mechanisms, 'settle', _raises_tracking_error)
    with pytest.raises(ValueError, match='no stable equilibrium from initial_theta: injected'):
        fig8a_simulator()


def test_unusable_limits_at_construction_are_a_value_error():
    with pytest.raises(ValueError, match='m0: max_rho_rate must be finite'):
        Simulator([fig8a()], [LOWER], [ModuleLimits(0.1, 1.0, max_rho_rate=math.nan)])


def test_a_command_is_the_trackers_straight_path():
    sim = fig8a_simulator()
    outcome = sim.command_rho(0, 0.3, 0)
    expected = track_module(fig8a(), fig8a(0.3), settle(fig8a(), LOWER).theta)
    assert outcome.status == 'ok' and not outcome.events
    np.testing.assert_allclose(sim.module(0)[1].theta, expected.final.theta, atol=0)
    assert sim.modules == (fig8a(0.3),)


@pytest.mark.numerics
def test_branch_point_jump_then_hysteresis():
    sim = fig8a_simulator()
    outcome = sim.command_rho(0, 0.1, 0)
    [jump] = outcome.of_type(Jump)
    assert jump.kind == 'branch_point' and 0.1 < jump.modules[0].rho < 0.2     # C1
    assert np.all(jump.from_theta[0] < 0) and np.all(jump.to_theta[0] > 0)
    assert (jump.module, jump.cause, jump.count) == (0, 'rho_cmd', 1)
    upper = sim.module(0)[1].theta
    assert np.all(upper > 0)
    status = sim.status(0)
    assert status.jumps_total == 1 and status.last_jump.kind == 'branch_point'
    # back to the start: the mechanism stays on the upper branch
    back = sim.command_rho(0, 0.5, 0)
    assert not back.of_type(Jump) and np.all(sim.module(0)[1].theta > 0)
    assert not np.allclose(sim.module(0)[1].theta, settle(fig8a(), LOWER).theta)


def test_a_command_beyond_the_fold_is_warned_first_then_jumps():
    sim = fig8a_simulator()
    outcome = sim.command_rho(0, 1.2, 0)
    warning, jump = outcome.events
    assert isinstance(warning, JumpAhead) and isinstance(jump, Jump)
    assert warning.end.kind == 'fold' and 0.8 < warning.end.rho < 0.95         # C2
    assert jump.kind == 'fold' and jump.modules[0].rho == pytest.approx(warning.end.rho,
                                                                        abs=1e-8)


def test_speed_limit_moves_at_the_rate_and_reaches_the_target():
    rate = 0.5
    sim = fig8a_simulator(max_rho_rate=rate)
    assert sim.command_rho(0, 0.7, 0).status == 'ok'
    assert sim.modules[0].rho == 0.5 and sim.target(0) == 0.7      # nothing moved yet
    sim.advance(S // 10)                                           # 0.1 s: 0.05 m
    assert sim.modules[0].rho == pytest.approx(0.55, abs=1e-15)
    expected = track_module(fig8a(), fig8a(sim.modules[0].rho), settle(fig8a(), LOWER).theta)
    np.testing.assert_allclose(sim.module(0)[1].theta, expected.final.theta, atol=1e-9)
    sim.advance(S // 10)                                           # same time: no motion
    assert sim.modules[0].rho == pytest.approx(0.55, abs=1e-15)
    sim.advance(S)                                                 # long enough: at target
    assert sim.modules[0].rho == 0.7 and sim.target(0) is None


@settings(max_examples=25, deadline=None)
@given(st.lists(st.integers(1, 200_000_000), min_size=1, max_size=8))
def test_speed_limit_is_never_exceeded(gaps):
    rate = 0.4
    sim = fig8a_simulator(max_rho_rate=rate)
    sim.command_rho(0, 0.8, 0)
    now, rho = 0, sim.modules[0].rho
    for gap in gaps:
        now += gap
        sim.advance(now)
        new = sim.modules[0].rho
        assert 0.0 <= new - rho <= rate * gap * 1e-9 + 1e-15
        assert verified_minimum(sim)
        rho = new


def test_retarget_moves_on_from_where_the_actuator_is():
    sim = fig8a_simulator(max_rho_rate=1.0)
    sim.command_rho(0, 0.9, 0)
    sim.command_rho(0, 0.4, S // 10)                 # at 0.6 by then, now heading down
    assert sim.modules[0].rho == pytest.approx(0.6) and sim.target(0) == 0.4
    sim.advance(S)
    assert sim.modules[0].rho == 0.4


@pytest.mark.parametrize('call, reason', [
    (lambda sim: sim.command_rho(0, math.nan, 0), 'non_finite'),
    (lambda sim: sim.command_rho(0, 2.5, 0), 'out_of_range'),
    (lambda sim: sim.set_force(0, 'a3', (math.inf, 0.0), 0), 'non_finite'),
    (lambda sim: sim.set_force(0, 'a4', (0.0, -1e60), 0), 'out_of_range'),
    (lambda sim: sim.set_parameters({0: {'L1': -1.0}}, 0, 'p'), 'parameter_value'),
    (lambda sim: sim.set_parameters({0: {'rho': 0.3}}, 0, 'p'), 'parameter_value'),
    (lambda sim: sim.set_limits(0, ModuleLimits(0.6, 1.0), 0), 'parameter_value'),
    (lambda sim: sim.set_limits(0, ModuleLimits(0.1, 1.0, max_rho_rate=-1.0), 0),
     'parameter_value'),
    (lambda sim: sim.set_limits(0, ModuleLimits(1.0, 0.1), 0), 'parameter_value'),
])
def test_bad_input_is_refused_with_a_reason_and_changes_nothing(call, reason):
    sim = fig8a_simulator()
    modules, state, revision = sim.modules, sim.state, sim.revision
    outcome = call(sim)
    assert outcome.status == 'refused' and outcome.reason == reason and outcome.message
    assert sim.modules is modules and sim.state is state and sim.revision == revision


def test_parameter_change_is_tracked_and_forces_too():
    sim = fig8a_simulator()
    start, eq0 = sim.module(0)
    assert sim.set_parameters({0: {'L2': 1.05, 'kc': 80.0}}, 0, 'design').status == 'ok'
    end = start.with_(L2=1.05, kc=80.0)
    expected = track_module(start, end, eq0.theta)
    assert sim.modules[0] == end
    np.testing.assert_allclose(sim.module(0)[1].theta, expected.final.theta, atol=0)
    assert sim.set_force(0, 'a3', (1.0, -3.0), 0).status == 'ok'
    assert (sim.modules[0].f3x, sim.modules[0].f3y) == (1.0, -3.0)


def test_limits_apply_to_later_commands_and_refuse_a_stranded_actuator():
    sim = fig8a_simulator()
    assert sim.set_limits(0, ModuleLimits(0.2, 0.6), 0).status == 'ok'
    assert sim.command_rho(0, 0.7, 0).reason == 'out_of_range'
    assert 'the actuator is at rho=0.5' in sim.limits_refusal(0, 0.6, 0.9)


def test_reset_returns_to_the_start_and_clears_the_record():
    sim = fig8a_simulator(max_rho_rate=10.0)
    sim.command_rho(0, 0.1, 0)
    sim.advance(S)                                    # jumps at C1 on the way
    assert sim.jumps_total == 1
    sim.command_rho(0, 0.9, S)                        # pending motion
    assert sim.reset([fig8a()], [LOWER]).status == 'ok'
    params, eq = sim.module(0)
    assert params == fig8a() and np.all(eq.theta < 0)
    assert sim.jumps_total == 0 and sim.target(0) is None
    assert sim.status(0).last_jump is None and sim.status(0).tracking == 'ok'


def test_a_reset_without_a_stable_equilibrium_keeps_the_state(monkeypatch):
    sim = fig8a_simulator()
    state = sim.state
    monkeypatch.setattr(mechanisms, 'settle', _raises_tracking_error)
    outcome = sim.reset([fig8a(0.3)], [LOWER])
    assert outcome.status == 'refused' and 'injected' in outcome.message
    assert sim.state is state


def test_tracking_failure_keeps_the_verified_state_and_clears_on_success(monkeypatch):
    sim = fig8a_simulator()
    state = sim.state
    monkeypatch.setattr(mechanisms, 'track_module', _raises_tracking_error)
    outcome = sim.command_rho(0, 0.3, 0)
    [failure] = outcome.of_type(TrackingFailure)
    assert outcome.status == 'failed' and failure.text == 'rho_cmd: injected'
    assert sim.state is state and sim.modules[0].rho == 0.5
    status = sim.status(0)
    assert status.level == 'warn' and 'tracking stopped early' in status.message
    monkeypatch.undo()
    assert sim.command_rho(0, 0.3, 0).status == 'ok' and sim.status(0).tracking == 'ok'


def test_an_unverified_tracker_result_is_never_taken(monkeypatch):
    real = mechanisms.track_module

    def saddle(start, end, theta, **options):
        track = real(start, end, theta, **options)
        final = track.final
        import dataclasses
        ev = np.array([-1.0, final.eigenvalues[-1]])
        return dataclasses.replace(track, final=dataclasses.replace(final, eigenvalues=ev))

    sim = fig8a_simulator()
    state = sim.state
    monkeypatch.setattr(mechanisms, 'track_module', saddle)
    outcome = sim.command_rho(0, 0.3, 0)
    assert outcome.status == 'failed' and 'unstable state' in outcome.events[0].text
    assert sim.state is state


def test_a_programming_error_in_the_tracker_propagates(monkeypatch):
    monkeypatch.setattr(mechanisms, 'track_module', _raises_runtime_error)
    sim = fig8a_simulator()
    with pytest.raises(RuntimeError):
        sim.command_rho(0, 0.3, 0)


# ---------------------------------------------------------------------------
# a neck: the same calls


NECK = (ModuleParams(rho=0.09, L1=0.12, L2=0.12, ka=50.0, kb=50.0, kc=50.0),
        ModuleParams(rho=0.085, L1=0.12, L2=0.12, ka=50.0, kb=50.0, kc=50.0))
UPRIGHT = [[1.2, 1.2], [1.2, 1.2]]


def neck_simulator(**limits):
    lim = ModuleLimits(0.01, 0.2, **limits)
    return Simulator(NECK, UPRIGHT, [lim, lim], names=['base', 'top'], **UNBOUNDED)


def test_a_neck_command_is_the_stack_trackers_path():
    sim = neck_simulator()
    start = settle_stack(Stack(NECK), UPRIGHT)
    np.testing.assert_allclose(sim.state.theta, start.theta, atol=0)
    outcome = sim.command_rhos({0: 0.1, 1: 0.08}, 0)
    end = Stack((NECK[0].with_(rho=0.1), NECK[1].with_(rho=0.08)))
    expected = track_stack(Stack(NECK), end, start)
    assert outcome.status == expected.status == 'ok'
    np.testing.assert_allclose(sim.state.theta, expected.final.theta, atol=0)
    params, view = sim.module(1)
    assert params == end.modules[1] and view.theta1 == expected.final.theta[1][0]
    assert view.actuator_force == expected.final.actuator_forces[1]
    assert sim.status(1).num_equilibria is None          # exact counts: one module only


def test_neck_targets_are_refused_as_a_whole():
    sim = neck_simulator()
    modules, state = sim.modules, sim.state
    assert sim.command_rhos({0: 0.1, 1: 0.001}, 0).reason == 'out_of_range'
    assert sim.modules is modules and sim.state is state


def test_a_neck_jump_is_recorded_in_every_module():
    """config/neck.yaml with a heavy head: lengthening the head module past its fold
    snaps the neck (the sideways buckling on shortening m1 is continuous: no jump)."""
    base = ModuleParams(rho=0.09, L1=0.12, L2=0.12, ka=300.0, kb=300.0, kc=300.0,
                        m1=0.02, m2=0.02)
    modules = (base, base.with_(rho=0.085), base.with_(rho=0.08, f3y=-3.5, f4y=-3.5))
    guess = [[0.754, 0.754], [0.813, 0.813], [0.85, 0.85]]
    sim = Simulator(modules, guess)
    start = settle_stack(Stack(modules), guess)
    expected = track_stack(Stack(modules), Stack(modules).with_module(2, rho=0.12), start)
    assert [j.kind for j in expected.jumps] == ['fold']
    [jump] = finished(sim, sim.command_rho(2, 0.12, 0)).of_type(Jump)
    want = expected.jumps[0]
    assert (jump.kind, jump.module, jump.count) == ('fold', 2, 1)
    assert jump.modules[2].rho == pytest.approx(0.096427, abs=1e-6)
    assert jump.modules == want.stack.modules
    np.testing.assert_allclose(jump.to_theta, want.to_theta, atol=0)
    for i in range(3):
        status = sim.status(i)
        assert status.jumps_total == 1 and status.last_jump.params == want.stack.modules[i]
    np.testing.assert_allclose(sim.state.theta, expected.final.theta, atol=0)


@pytest.mark.numerics
def test_a_neck_buckling_sideways_continuously_is_no_jump():
    """config/neck.yaml with a heavy head: shortening the middle module passes a
    supercritical branch point: no jump, no warning, the neck turns sideways."""
    base = ModuleParams(rho=0.09, L1=0.12, L2=0.12, ka=300.0, kb=300.0, kc=300.0,
                        m1=0.02, m2=0.02)
    modules = (base, base.with_(rho=0.085), base.with_(rho=0.08, f3y=-3.5, f4y=-3.5))
    guess = [[0.754, 0.754], [0.813, 0.813], [0.85, 0.85]]
    sim = Simulator(modules, guess)
    expected = track_stack(Stack(modules), Stack(modules).with_module(1, rho=0.07),
                           settle_stack(Stack(modules), guess))
    assert expected.jumps == () and len(expected.passages) == 1
    outcome = finished(sim, sim.command_rho(1, 0.07, 0))
    assert not outcome.of_type(Jump) and not outcome.of_type(JumpAhead)
    [passage] = outcome.of_type(Passage)           # said once, for the node's INFO line
    assert (passage.module, passage.cause) == (1, 'rho_cmd')
    assert passage.modules == expected.passages[0].stack.modules
    assert all(sim.status(i).jumps_total == 0 for i in range(3))
    np.testing.assert_allclose(sim.state.theta, expected.final.theta, atol=1e-9)
    assert abs(sim.state.head_angle) > 0.05 and verified_minimum(sim)


@pytest.mark.numerics
def test_a_neck_load_ending_just_past_its_sideways_buckling_is_taken():
    """N = 3 upright paper neck, head load set to 1e-8 past its sideways buckling (-6.854 N
    per node), where lambda_min / lambda_max is 9e-11: the tracker's state is certified by
    the branch point's normal form (Track.certificate), and the simulator takes it (its
    final check alone, lambda_min > 1e-9 lambda_max, fails it: 'tracker returned an
    unstable state'); a further load goes on from it to where the stack tracker goes in
    one command."""
    modules = tuple(ModuleParams.paper(0.6) for _ in range(3))
    guess = upright_guess(modules)
    sim = Simulator(modules, guess, **UNBOUNDED)
    load = -6.853824673228113 * (1.0 + 1e-8)
    outcome = finished(sim, sim.set_parameters({2: {'f3y': load, 'f4y': load}}, 0, 'load'))
    assert outcome.status == 'ok' and not outcome.of_type(TrackingFailure)
    assert len(outcome.of_type(Passage)) == 1 and not outcome.of_type(Jump)
    assert sim.state.stable and sim.state.certificate and not verified_minimum(sim)
    outcome = finished(sim, sim.set_parameters({2: {'f3y': -10.0, 'f4y': -10.0}}, 0, 'load'))
    assert outcome.status == 'ok' and verified_minimum(sim)
    stack = Stack(modules)
    expected = track_stack(stack, stack.with_module(2, f3y=-10.0, f4y=-10.0),
                           settle_stack(stack, guess))
    np.testing.assert_allclose(sim.state.theta, expected.final.theta, atol=1e-9)


@pytest.mark.numerics
def test_a_module_rho_ending_just_past_its_buckling_is_carried_on():
    """The unloaded paper module buckles continuously at rho = L = 1 going down; rho set to
    1e-10 past it (lambda_min / lambda_max = 2e-10, below the margin test) ends on a state
    certified by the normal form: the simulator keeps it as stable (its classification
    reads 'degenerate'), and the next command goes on from it to where one command from
    the start goes.  Before, the certificate was dropped with the module's state: 'not a
    stable equilibrium', and the next command failed ('the start state is not an
    equilibrium')."""
    start = ModuleParams.paper(1.3)
    sim = Simulator([start], [[0.0, 0.0]], [ModuleLimits(0.05, 1.95)], **UNBOUNDED)
    outcome = finished(sim, sim.command_rhos({0: 1.0 - 1e-10}, 0))
    assert outcome.status == 'ok' and len(outcome.of_type(Passage)) == 1
    assert sim.stable and sim.state.certificate and not verified_minimum(sim)
    assert sim.status(0).level != 'error'
    outcome = finished(sim, sim.command_rhos({0: 0.5}, 0))
    assert outcome.status == 'ok' and not outcome.of_type(TrackingFailure)
    assert sim.stable and verified_minimum(sim) and not sim.state.certificate
    expected = track_module(start, ModuleParams.paper(0.5), [0.0, 0.0])     # one command
    np.testing.assert_allclose(sim.state.theta, expected.final.theta, atol=1e-9)


def test_a_neck_speed_limit_moves_one_module_at_its_rate():
    sim = neck_simulator(max_rho_rate=0.01)
    sim.command_rhos({0: 0.1, 1: 0.082}, 0)
    sim.advance(S // 2)                             # at most 5 mm each
    assert sim.modules[0].rho == pytest.approx(0.095) and sim.modules[1].rho == 0.082
    assert sim.target(0) == 0.1 and sim.target(1) is None
    sim.advance(2 * S)
    assert [m.rho for m in sim.modules] == [0.1, 0.082] and verified_minimum(sim)


def test_a_neck_failure_names_the_module_that_stopped(monkeypatch):
    real = mechanisms.track_stack

    def stops_halfway(start, end, state):
        import dataclasses
        track = real(start, Stack(tuple(a.with_(rho=0.5 * (a.rho + b.rho))
                                        for a, b in zip(start.modules, end.modules))), state)
        return dataclasses.replace(track, status='failed', message='injected stop')

    sim = neck_simulator()
    monkeypatch.setattr(mechanisms, 'track_stack', stops_halfway)
    outcome = sim.command_rho(1, 0.075, 0)
    [failure] = outcome.of_type(TrackingFailure)
    assert failure.module == 1 and failure.text.startswith('rho_cmd: stopped at top rho=0.08')
    assert sim.modules[1].rho == pytest.approx(0.08) and verified_minimum(sim)
    assert sim.status(1).level == 'warn' and sim.status(0).tracking == 'ok'


@settings(max_examples=15, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 1), st.one_of(
    st.floats(0.0, 0.25), st.sampled_from([math.nan, math.inf]))), min_size=1, max_size=5))
def test_any_command_sequence_leaves_a_verified_minimum(commands):
    sim = neck_simulator()
    for i, rho in commands:
        before = sim.state
        outcome = sim.command_rho(i, rho, 0)
        if not (math.isfinite(rho) and 0.01 <= rho <= 0.2):
            assert outcome.status == 'refused' and sim.state is before
        assert verified_minimum(sim) and sim.state.residual < 1e-6


def _raises_tracking_error(*args, **kwargs):
    raise TrackingError('injected')


def _raises_runtime_error(*args, **kwargs):
    raise RuntimeError('a bug')


# ---------------------------------------------------------------------------
# early warnings only where the tracker jumps (issue 10)


@pytest.mark.numerics
def test_no_early_warning_where_a_branch_merges_into_the_flat_state():
    """Unloaded paper module: the upper branch meets the flat state at rho = L = 1 (a
    supercritical pitchfork run backwards): the range ends there with a branch point, yet
    the tracker goes on along the flat state: no warning, no jump."""
    sim = Simulator([ModuleParams(rho=0.75)], [[0.7, 0.7]], [ModuleLimits(0.0, 3.0)],
                    **UNBOUNDED)
    end = sim.status(0).operation_range.upper
    assert (end.kind, end.rho) == ('branch_point', 1.0)
    outcome = sim.command_rho(0, 1.3, 0)
    assert outcome.events == () and sim.modules[0].rho == 1.3


@pytest.mark.numerics
def test_the_flat_state_buckles_smoothly_without_warning_or_jump():
    """The other way the flat state loses stability at rho = 1: a supercritical pitchfork,
    the module buckles smoothly onto the upper branch growing out of it (no jump, so no
    warning), as it would come back: the path rho 1.3 -> 0.75 -> 1.3 is reversible."""
    sim = Simulator([ModuleParams(rho=1.3)], [[0.0, 0.0]], [ModuleLimits(0.0, 3.0)],
                    **UNBOUNDED)
    end = sim.status(0).operation_range.lower
    assert (end.kind, end.rho) == ('branch_point', 1.0)
    outcome = sim.command_rho(0, 0.75, 0)
    passage, undecided = outcome.events            # a Passage, not a jump
    assert isinstance(passage, Passage) and passage.modules[0].rho == pytest.approx(1.0, abs=1e-9)
    # (the module is mirror symmetric: which side it buckles to is no model's to decide)
    assert isinstance(undecided, Undecided) and undecided.modules == passage.modules
    assert 0.0 < undecided.rho_uncertainty[0] < 1e-8 and undecided.module == 0
    upper = equilibria(ModuleParams(rho=0.75)).stable
    theta = sim.module(0)[1].theta
    assert min(wrapped(theta, e.theta) for e in upper) < 1e-9 and wrapped(theta, (0, 0)) > 0.5
    assert sim.command_rho(0, 1.3, 0).events == ()
    assert wrapped(sim.module(0)[1].theta, (0.0, 0.0)) < 1e-9


@settings(max_examples=40, deadline=None, derandomize=True)
@given(L2=st.sampled_from([1.0, 1.0, 1.3]), F=st.sampled_from([0.0, 0.0, 5.0, -5.0, 8.0]),
       rho0=st.floats(0.2, 1.8), rho1=st.floats(0.05, 2.2), branch=st.integers(0, 1))
def test_an_early_warning_is_given_exactly_where_the_tracker_jumps(L2, F, rho0, rho1, branch):
    """Symmetric and unloaded modules (pitchforks of every kind, folds): a command is
    warned about iff the path the tracker follows (``track_module``, not the simulator)
    jumps."""
    p = ModuleParams.paper(rho0, L2=L2, F3=F, F4=F)
    stable = equilibria(p).stable
    start = stable[min(branch, len(stable) - 1)]
    assume(start.eigenvalues[0] > 1e-6 * start.eigenvalues[-1])    # not at a critical point
    sim = Simulator([p], [list(start.theta)], [ModuleLimits(0.0, 4.0)], **UNBOUNDED)
    track = track_module(p, p.with_(rho=rho1), sim.module(0)[1].theta)
    warned = sim.command_rho(0, rho1, 0).of_type(JumpAhead)
    assert bool(warned) == bool(track.jumps), (warned, track.jumps)


def test_round_number_command_sequences_on_the_default_module_stay_verified():
    """What a user types at the default node (the unloaded paper module, rho 0.75 on the
    upper branch): seeded sequences of round actuator targets (0.05 .. 1.95 m) and round
    vertical loads (F3 = F4 or each on its own, -50 .. 50 N).  After every command the
    state is a verified stable equilibrium and no module status is an error; every jump
    lands on a stable equilibrium of the module at the jump, as the polynomial solver
    (no tracker code) finds it; a command fails only where it ends on a critical point
    itself (rho = 1.0 unloaded: the branch point, degenerate) and says so.  (Found so: the
    command rho = 1.0 failed with a message about a buckled state or landing that could
    not be followed back, and a state near it read ERROR.)  Seen: 41 jumps, 1 failure
    (rho = 1.0)."""
    import random
    rng = random.Random(11)
    rhos = [round(0.05 * k, 2) for k in range(1, 40)] + [1.0, 0.75, 0.5, 1.5, 0.2]
    loads = [0.0, 1.0, -1.0, 5.0, -5.0, 10.0, -10.0, 20.0, -20.0, 50.0, -50.0]
    failures = jumps = 0
    for _ in range(30):
        sim = Simulator([ModuleParams.paper(0.75)], [[0.7, 0.7]], [ModuleLimits(0.05, 1.95)])
        for _ in range(20):
            pick = rng.random()
            if pick < 0.6:
                out = sim.command_rho(0, rng.choice(rhos), 0)
            else:
                f3 = rng.choice(loads)
                f4 = f3 if pick < 0.85 else rng.choice(loads)
                out = sim.set_parameters({0: {'f3y': f3, 'f4y': f4}}, 0, 'force')
            status = sim.status(0)
            assert sim.stable and status.level != 'error', status.message
            assert out.status in ('ok', 'failed'), out
            if out.status == 'failed':
                failures += 1
                assert 'at the critical point itself' in status.message, status.message
            for jump in (e for e in out.events if isinstance(e, Jump)):
                jumps += 1
                found = [e for e in equilibria(jump.modules[0]).stable
                         if np.max(np.abs(np.angle(np.exp(1j * (e.theta - jump.to_theta[0])))))
                         < 1e-6]
                assert found, (jump.modules[0], jump.to_theta)
    assert jumps >= 20, (jumps, failures)  # they cross folds and branch points
