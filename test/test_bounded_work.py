"""Bounded work per call (issue 10): a command whose tracking needs more than a call's time
budget goes on in the following calls and ends exactly where an unbounded run ends.

Deterministic: the budgets are counted in readings of an injected clock that advances one
unit per reading (a budget of n units is a few check points of the tracker, on any
machine); no test times anything.  The reference is the simulator with no budget.
"""
import threading

import numpy as np
import pytest

from tensegrity_ros.core import ModuleParams
from tensegrity_ros.core.numerics.bounded_work import Budget, checkpoint, Job
from tensegrity_ros.core.simulation.events import Deferred, Jump, TrackingFailure
from tensegrity_ros.core.simulation.simulator import ModuleLimits, Simulator

#: Counting clocks (check points, evaluations): `make test-numerics` runs it under other CPUs'
#: arithmetic, where the work a path takes may differ.
pytestmark = pytest.mark.numerics


class CountingClock:
    """A clock that advances one unit each time it is read."""

    def __init__(self):
        self.now = 0

    def __call__(self):
        self.now += 1
        return self.now


def counted(steps, record=None):
    """Work of ``steps`` check points; returns the sum of their indices."""
    def work():
        total = 0
        try:
            for i in range(steps):
                checkpoint()
                total += i
        finally:
            if record is not None:
                record.append('unwound')
        return total
    return work


def run_to_end(job, clock, budget):
    calls = 1
    while not job.run(clock() + budget):
        calls += 1
    return calls


# -- the job ---------------------------------------------------------------------------

def test_checkpoint_outside_a_job_does_nothing():
    assert counted(5)() == 10


def test_a_job_within_its_budget_runs_once_on_the_callers_thread():
    clock = CountingClock()
    threads = []

    def work():
        threads.append(threading.current_thread())
        return counted(3)()

    job = Job(work, clock)
    assert job.run(clock() + 100) and job.result() == 3
    assert threads == [threading.current_thread()]


def test_a_long_job_spans_calls_and_gives_the_unbounded_result():
    clock = CountingClock()
    job = Job(counted(200), clock)
    calls = run_to_end(job, clock, budget=5)
    assert job.result() == sum(range(200))
    assert 20 < calls < 200          # a few check points per call, at least one each


def test_every_call_makes_progress_even_past_its_deadline():
    clock = CountingClock()
    job = Job(counted(50), clock)
    calls = 1
    while not job.run(deadline=0):
        calls += 1
    assert job.result() == sum(range(50)) and calls <= 52


def test_an_error_of_the_work_is_raised_by_result():
    clock = CountingClock()

    def work():
        counted(30)()
        raise ValueError('injected')

    job = Job(work, clock)
    run_to_end(job, clock, budget=3)
    with pytest.raises(ValueError, match='injected'):
        job.result()


def test_cancel_unwinds_a_paused_job():
    clock = CountingClock()
    record = []
    job = Job(counted(1000, record), clock)
    assert not job.run(clock() + 3) and not job.run(clock() + 3)
    job.cancel()
    assert job.done and record == ['unwound', 'unwound']     # the inline try and the worker


def budgeted(clock, budget, steps):
    """Work of ``steps`` check points in a Budget: (spent, check points passed)."""
    def work():
        passed = 0
        with Budget(budget, clock) as spent:
            for _ in range(steps):
                checkpoint()
                passed += 1
        return spent.spent, passed
    return work


def test_a_budget_ends_its_block_at_the_first_checkpoint_past_its_deadline():
    # read at entry (1), deadline 6: the check points reading 2 .. 6 pass, the 6th ends it
    assert budgeted(CountingClock(), 5, 1000)() == (True, 5)
    assert budgeted(CountingClock(), 5, 3)() == (False, 3)
    assert budgeted(CountingClock(), None, 1000)() == (False, 1000)
    checkpoint()                    # the hook is gone after the block


def test_a_budget_inside_a_job_pauses_with_the_job_and_still_ends():
    clock = CountingClock()
    job = Job(budgeted(clock, 40, 1000), clock)
    calls = run_to_end(job, clock, budget=3)
    assert calls > 1                # the job paused at the budget's check points
    spent, passed = job.result()    # the clock is shared (the job's checks read it too)
    assert spent and 0 < passed < 40


# -- the simulator ---------------------------------------------------------------------

def fig8a(rho=0.5):
    return ModuleParams.paper(rho, F3=5.0, F4=5.0)


def one_module(**bounds):
    return Simulator([fig8a()], [[-1.0, -1.0]], [ModuleLimits(0.05, 1.95)], **bounds)


def paper_neck(**bounds):
    return Simulator([ModuleParams.paper(0.75)] * 3, None, **bounds)


def drive(sim, command):
    """(outcomes of the command and of the advance calls that finish it)."""
    outcomes = [command(sim)]
    while sim.pending:
        outcomes.append(sim.advance(0))
    return outcomes


def events(outcomes, kind):
    return [e for o in outcomes for e in o.of_type(kind)]


def same_jumps(a, b):
    assert [(j.kind, j.s, j.module, j.cause) for j in a] == \
        [(j.kind, j.s, j.module, j.cause) for j in b]
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x.from_theta, y.from_theta)
        np.testing.assert_array_equal(x.to_theta, y.to_theta)


@pytest.mark.parametrize('make, command', [
    (one_module, lambda sim: sim.command_rho(0, 0.1, 0)),                   # past C1
    (one_module, lambda sim: sim.command_rho(0, 1.2, 0)),                   # past C2
    (paper_neck, lambda sim: sim.set_parameters({2: {'f3y': -20.0, 'f4y': -20.0}}, 0,
                                                'head load')),
], ids=['module C1', 'module C2', 'neck head load'])
def test_a_hard_command_spans_calls_and_ends_as_an_unbounded_run(make, command):
    reference = make(time_budget=None)
    expected = command(reference)
    bounded = make(time_budget=3, clock=CountingClock(), work_limit=None)
    start_state, start_modules = bounded.state, bounded.modules
    first = command(bounded)
    assert bounded.pending                                       # out of time: goes on later
    assert bounded.state is start_state and bounded.modules == start_modules   # verified start
    [deferred] = first.of_type(Deferred)
    assert deferred.cause == expected.of_type(Jump)[0].cause
    outcomes = [first]
    while bounded.pending:
        outcomes.append(bounded.advance(0))
    assert len(outcomes) > 3 and len(events(outcomes, Deferred)) == 1
    same_jumps(events(outcomes, Jump), expected.of_type(Jump))
    assert len(expected.of_type(Jump)) == 1 and not events(outcomes, TrackingFailure)
    assert bounded.modules == reference.modules and bounded.jumps_total == 1
    np.testing.assert_array_equal(bounded.state.eigenvalues, reference.state.eigenvalues)
    for i in range(len(bounded)):
        np.testing.assert_array_equal(bounded.module(i)[1].theta, reference.module(i)[1].theta)


def test_commands_sent_meanwhile_are_merged_into_one_path_after_the_pending_one():
    sim = one_module(time_budget=3, clock=CountingClock(), work_limit=None)
    sim.command_rho(0, 0.1, 0)
    assert sim.pending
    assert not sim.set_force(0, 'a3', (0.0, 4.0), 0).events        # waits: no tracking yet
    sim.command_rho(0, 0.3, 0)
    assert sim.goal(0) == fig8a(0.3).with_(f3y=4.0)
    outcomes = drive(sim, lambda s: s.advance(0))
    assert sim.modules[0] == fig8a(0.3).with_(f3y=4.0) and sim.stable
    assert sim.jumps_total == 1 and not events(outcomes, TrackingFailure)


def test_a_path_that_works_past_the_work_limit_is_given_up_keeping_the_verified_state():
    sim = one_module(time_budget=3, clock=CountingClock(), work_limit=40)
    start_state, start_modules = sim.state, sim.modules
    outcomes = drive(sim, lambda s: s.command_rho(0, 0.1, 0))
    [failure] = events(outcomes, TrackingFailure)
    assert 'gave up after' in failure.text and failure.module == 0
    assert outcomes[-1].status == 'failed' and not events(outcomes, Jump)
    assert sim.state is start_state and sim.modules == start_modules and sim.stable
    assert sim.status(0).level == 'warn' and 'gave up' in sim.status(0).tracking
    assert not sim.pending
    finished = drive(sim, lambda s: s.command_rho(0, 0.45, 0))      # small: within budget
    assert sim.modules[0].rho == 0.45 and sim.status(0).tracking == 'ok'
    assert not events(finished, Deferred)


def test_reset_abandons_a_pending_path():
    sim = one_module(time_budget=3, clock=CountingClock(), work_limit=None)
    sim.command_rho(0, 0.1, 0)
    assert sim.pending
    outcomes = drive(sim, lambda s: s.reset([fig8a(0.6)], [[-1.0, -1.0]]))   # settles in slices
    assert outcomes[0].accepted and not events(outcomes, TrackingFailure)
    assert not sim.pending and sim.modules == (fig8a(0.6),) and sim.jumps_total == 0
    assert not sim.advance(0).events and sim.modules == (fig8a(0.6),)


def test_a_speed_limited_actuator_waits_while_a_path_is_pending():
    """No motion accrues while the mechanism has not followed (the published actuator
    length never steps by more than its rate allows), then it moves on at its rate."""
    tick = 10_000_000                                           # ns
    sim = Simulator([fig8a()], [[-1.0, -1.0]], [ModuleLimits(0.05, 1.95, max_rho_rate=0.1)],
                    time_budget=1, clock=CountingClock(), work_limit=None)
    sim.set_parameters({0: {'ka': 400.0}}, 0, 'stiffer a spring')
    sim.command_rho(0, 0.6, 0)
    assert sim.pending and sim.target(0) == 0.6
    now, rhos = 0, [0.5]
    while sim.modules[0].ka != 400.0:                  # the stiffening path is pending
        now += tick
        sim.advance(now)
        rhos.append(sim.goal(0).rho)
    assert rhos[:4] == [0.5] * 4                        # the actuator waited meanwhile
    for _ in range(5):
        now += tick
        sim.advance(now)
        rhos.append(sim.goal(0).rho)
    steps = np.diff(rhos)
    assert np.all(steps >= 0.0) and np.all(steps <= 0.1 * tick * 1e-9 + 1e-12)
    assert rhos[-1] > 0.5 and sim.target(0) == 0.6


def loaded_neck():
    return [ModuleParams.paper(0.75)] * 2 + [ModuleParams.paper(0.75, F3=-1.0, F4=-1.0)]


def test_a_long_reset_spans_calls_keeping_the_old_state_meanwhile():
    reference = paper_neck(time_budget=None)
    assert reference.reset(loaded_neck(), None).accepted
    sim = paper_neck(time_budget=3, clock=CountingClock(), work_limit=None)
    old_state, old_modules = sim.state, sim.modules
    first = sim.reset(loaded_neck(), None)
    assert first.accepted and sim.pending and first.of_type(Deferred)
    assert sim.state is old_state and sim.modules == old_modules
    assert sim.goal(2) == loaded_neck()[2]
    outcomes = drive(sim, lambda s: s.advance(0))
    assert not events(outcomes, TrackingFailure) and sim.modules == tuple(loaded_neck())
    np.testing.assert_array_equal(sim.state.theta, reference.state.theta)


def test_a_deferred_reset_that_finds_no_minimum_is_a_failure_keeping_the_state(monkeypatch):
    from tensegrity_ros.core import TrackingError
    import tensegrity_ros.core.simulation.mechanisms as mechanisms

    def slow_failure(modules, thetas):
        counted(50)()
        raise TrackingError('injected')

    sim = one_module(time_budget=3, clock=CountingClock(), work_limit=None)
    old_state = sim.state
    monkeypatch.setattr(mechanisms.OneModule, 'settle', lambda self, m, t: slow_failure(m, t))
    assert sim.reset([fig8a(0.6)], [[-1.0, -1.0]]).accepted and sim.pending
    outcomes = drive(sim, lambda s: s.advance(0))
    [failure] = events(outcomes, TrackingFailure)
    assert 'reset: no stable equilibrium from initial_theta: injected' in failure.text
    assert sim.state is old_state and sim.modules == (fig8a(),)
    # refused at once when the settle fails within the call's budget, as before
    sim.time_budget = None
    refused = sim.reset([fig8a(0.6)], [[-1.0, -1.0]])
    assert refused.status == 'refused' and 'injected' in refused.message
