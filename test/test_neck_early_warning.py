"""Early warnings for a neck (JumpAhead): a speed-limited actuator's path is tracked ahead.

One module is warned from its exact operation range; a neck has none, so the simulator
tracks a speed-limited actuator's path to its target in advance (the other modules held)
and warns of the first jump on it.  Checked against what then happens as the actuator
moves there tick by tick (the jump's location, its kind), against the stack tracker run
on the whole path (:func:`track_stack`, not the simulator), and for bounded work with a
counting clock (no timing).
"""
import numpy as np
import pytest

from tensegrity_ros.core import ModuleParams
from tensegrity_ros.core.neck.stack import settle_stack, Stack, track_stack
from tensegrity_ros.core.simulation.events import BranchEnd, Jump, JumpAhead
from tensegrity_ros.core.simulation.simulator import ModuleLimits, Simulator

#: Counting clocks (check points): `make test-numerics` runs it under other CPUs' arithmetic,
#: where the work a path takes may differ.
pytestmark = pytest.mark.numerics


S = 1_000_000_000                    # ns per second
TICK = S // 100                      # advance() at 100 Hz
RATE = 0.01                          # m/s
#: config/neck.yaml with a heavy head: lengthening the head module (m2) from 0.08 m past
#: rho ~ 0.0964 folds the neck (see test_simulator.test_a_neck_jump_is_recorded_...).
BASE = ModuleParams(rho=0.09, L1=0.12, L2=0.12, ka=300.0, kb=300.0, kc=300.0, m1=0.02, m2=0.02)
HEAVY_HEAD = (BASE, BASE.with_(rho=0.085), BASE.with_(rho=0.08, f3y=-3.5, f4y=-3.5))
GUESS = [[0.754, 0.754], [0.813, 0.813], [0.85, 0.85]]


class CountingClock:
    """A clock that advances one unit each time it is read (a budget of n units is a
    few check points of the tracker, on any machine)."""

    def __init__(self):
        self.now = 0

    def __call__(self):
        self.now += 1
        return self.now


def simulator(rate=RATE, **budget):
    limits = [ModuleLimits(0.01, 0.2, max_rho_rate=rate)] * 3
    return Simulator(HEAVY_HEAD, GUESS, limits, **(budget or {'time_budget': None}))


def drive(sim, until_ns, start_ns=0):
    """advance() every TICK up to ``until_ns``: every event, in order, with the tick."""
    events = []
    for now in range(start_ns + TICK, until_ns + 1, TICK):
        events += [(now, e) for e in sim.advance(now).events]
    return events


def drive_to_rest(sim, calls=100_000):
    """advance() every TICK until no actuator moves and no path is pending (a bounded
    simulator's paths span many calls, and its actuators wait for them)."""
    events, now = [], 0
    while (sim.pending or any(sim.target(i) is not None for i in range(len(sim)))) and calls:
        now, calls = now + TICK, calls - 1
        events += [(now, e) for e in sim.advance(now).events]
    assert calls, 'still moving'
    return events


def test_a_speed_limited_neck_command_across_a_fold_is_warned_before_it_jumps():
    sim = simulator()
    outcome = sim.command_rho(2, 0.12, 0)
    [warning] = outcome.of_type(JumpAhead)
    assert not outcome.of_type(Jump) and sim.modules[2].rho == 0.08    # nothing moved yet
    assert isinstance(warning.end, BranchEnd)
    assert (warning.module, warning.rho, warning.cause, warning.end.kind) == \
        (2, 0.12, 'rho_cmd', 'fold')
    # the whole path by the stack tracker itself
    whole = track_stack(Stack(HEAVY_HEAD), Stack(HEAVY_HEAD).with_module(2, rho=0.12),
                        settle_stack(Stack(HEAVY_HEAD), GUESS))
    assert warning.end.rho == pytest.approx(whole.jumps[0].stack.modules[2].rho, abs=1e-12)
    np.testing.assert_allclose(warning.end.theta, whole.jumps[0].from_theta, atol=1e-12)
    # then the actuator gets there at 10 mm/s: the jump where the warning said
    events = drive(sim, 5 * S)
    [(when, jump)] = [(t, e) for t, e in events if isinstance(e, Jump)]
    assert not [e for _, e in events if isinstance(e, JumpAhead)]         # said once
    assert jump.kind == 'fold' and jump.module == 2
    assert jump.modules[2].rho == pytest.approx(warning.end.rho, abs=1e-8)
    assert when == pytest.approx((warning.end.rho - 0.08) / RATE * S, abs=TICK)
    assert sim.modules[2].rho == 0.12 and sim.target(2) is None


def test_no_warning_where_the_path_ahead_stays_on_its_branch():
    sim = simulator()
    assert not sim.command_rho(2, 0.09, 0).of_type(JumpAhead)
    events = drive(sim, 2 * S)
    assert not [e for _, e in events if isinstance(e, (Jump, JumpAhead))]
    assert sim.modules[2].rho == 0.09


def test_a_neck_command_without_a_speed_limit_is_reported_not_announced():
    """Applied in the same call: tracking it ahead too would double every command."""
    sim = simulator(rate=0.0)
    outcome = sim.command_rho(2, 0.12, 0)
    assert [type(e) for e in outcome.events] == [Jump]


def test_a_new_target_short_of_the_fold_drops_the_warning_it_had():
    sim = simulator()
    assert sim.command_rho(2, 0.12, 0).of_type(JumpAhead)
    events = drive(sim, S // 2)                               # at 0.085, short of 0.0964
    assert not [e for _, e in events if isinstance(e, Jump)]
    outcome = sim.command_rho(2, 0.09, S // 2)
    assert not outcome.of_type(JumpAhead)
    events = drive(sim, 3 * S, S // 2)
    assert not [e for _, e in events if isinstance(e, (Jump, JumpAhead))]
    assert sim.modules[2].rho == 0.09


def test_a_lookahead_longer_than_a_call_goes_on_in_the_next_calls_and_still_warns_first():
    """With a budget of a few clock readings the path ahead takes many calls; the
    warning comes from one of them, before the jump, with the unbounded location."""
    unbounded = simulator().command_rho(2, 0.12, 0).of_type(JumpAhead)[0]
    sim = simulator(time_budget=40, clock=CountingClock(), work_limit=10**9)
    first = sim.command_rho(2, 0.12, 0)
    assert not first.of_type(JumpAhead)                       # not done within one call
    events = drive_to_rest(sim)
    kinds = [type(e) for _, e in events if isinstance(e, (Jump, JumpAhead))]
    assert kinds == [JumpAhead, Jump]
    [warning] = [e for _, e in events if isinstance(e, JumpAhead)]
    assert warning.end.rho == unbounded.end.rho and warning.end.kind == 'fold'


@pytest.mark.parametrize('rate', [0.005, 0.01, 0.02, 0.05, 1.0])
@pytest.mark.parametrize('budget', [3, 6, 12, 40])
def test_a_warning_is_never_said_after_its_jump(rate, budget):
    """Actuators of every speed against paths ahead tracked in slices of every size:
    where the actuator reaches the fold before its path ahead is done, no warning comes
    after the fact; where one comes, it comes first and says where the jump happens."""
    sim = simulator(rate=rate, time_budget=budget, clock=CountingClock(), work_limit=10**9)
    events = [(0, e) for e in sim.command_rho(2, 0.12, 0).events] + drive_to_rest(sim)
    said = [e for _, e in events if isinstance(e, (Jump, JumpAhead))]
    assert [type(e) for e in said] in ([Jump], [JumpAhead, Jump])
    if len(said) == 2:
        assert said[1].modules[2].rho == pytest.approx(said[0].end.rho, abs=1e-8)
    assert sim.modules[2].rho == 0.12


def test_a_load_change_tracks_the_paths_ahead_again():
    """The path ahead tracked under the old load is dropped (its warning would be about
    another path); the new path ahead is warned about where the mechanism then jumps."""
    sim = simulator(time_budget=3, clock=CountingClock(), work_limit=10**9)
    assert not sim.command_rho(2, 0.12, 0).of_type(JumpAhead)
    events = [(0, e) for e in sim.set_force(2, 'a3', (0.0, -2.0), 0).events]
    events += [(0, e) for e in sim.set_force(2, 'a4', (0.0, -2.0), 0).events]
    events += drive_to_rest(sim)
    said = [e for _, e in events if isinstance(e, (Jump, JumpAhead))]
    assert [type(e) for e in said] == [JumpAhead, Jump]
    warning, jump = said
    assert warning.cause == 'rho_cmd' and warning.end.kind == jump.kind
    assert jump.modules[2].f3y == -2.0
    assert jump.modules[2].rho == pytest.approx(warning.end.rho, abs=1e-8)
