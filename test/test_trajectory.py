"""Timed actuator targets (core.trajectory) without ROS: the schedule, its end, refusals.

References: plain arithmetic for the linear schedule (a recording stand-in simulator shows
what is commanded when); the paper's fig. 8a branch point C1 (~0.155) for a jump met on
the way, whose landing must equal the tracker's on the same straight path; a stopped
path for an abort.
"""
import math

from hypothesis import given, settings, strategies as st
import numpy as np
import pytest

from tensegrity_ros.core import ModuleParams, settle, track_module
from tensegrity_ros.core.simulation.events import Jump, Outcome, refused
from tensegrity_ros.core.simulation.simulator import ModuleLimits, Simulator
from tensegrity_ros.core.simulation.trajectory import (ABORTED, CANCELED, EXECUTING, IDLE,
                                                       MotionEnded, SUCCEEDED, Trajectory,
                                                       TrajectoryPlayer)

S = 1_000_000_000
LOWER = [-1.0, -1.0]


class Recorder:
    """A stand-in simulator: actuators jump to each command, which is recorded."""

    names = ('m0', 'm1')
    pending = False

    def __init__(self, rhos=(0.5, 0.4), rho_max=2.0):
        self.rhos = list(rhos)
        self.rho_max = rho_max
        self.commands = []          # (now_ns, {index: rho}, cause)
        self.failing = False

    def goal(self, index):
        return ModuleParams.paper(self.rhos[index])

    def target(self, index):
        return None

    def rhos_refusal(self, targets):
        for rho in targets.values():
            if not math.isfinite(rho):
                return refused('non_finite', f'{rho!r} is not finite')
            if not 0.05 <= rho <= self.rho_max:
                return refused('out_of_range', f'{rho!r} outside [0.05, {self.rho_max}]')
        return None

    def command_rhos(self, targets, now_ns, cause):
        refusal = self.rhos_refusal(targets)
        if refusal is not None:
            return refusal
        self.commands.append((now_ns, dict(targets), cause))
        for i, rho in targets.items():
            self.rhos[i] = rho
        return Outcome(status='failed' if self.failing else 'ok')

    def advance(self, now_ns):
        return Outcome()

    def reset(self, modules, initial_theta):
        return Outcome()


def trajectory(points, joints=(0,), start_ns=None):
    """points: (t seconds, [rho per joint]) ..."""
    return Trajectory(joints=tuple(joints), times_ns=tuple(int(round(t * S)) for t, _ in points),
                      positions=tuple(tuple(p) for _, p in points), start_ns=start_ns)


def ended(outcome):
    return [e for e in outcome.events if isinstance(e, MotionEnded)]


def test_linear_between_points_from_where_the_actuator_is():
    sim = Recorder()
    player = TrajectoryPlayer(sim)
    assert player.status.state == IDLE
    player.follow(trajectory([(1.0, [1.0]), (2.0, [0.6])]), now_ns=10 * S)
    assert player.status.state == EXECUTING
    player.advance(10 * S + S // 4)
    assert sim.commands[-1][1] == {0: pytest.approx(0.5 + 0.25 * 0.5)}
    assert sim.commands[-1][2] == 'joint_trajectory'
    player.advance(10 * S + 3 * S // 2)
    # the point at 1 s is passed on the way: commanded first, then the sample at 1.5 s
    assert [c[1][0] for c in sim.commands[-2:]] == [1.0, pytest.approx(0.8)]
    outcome = player.advance(13 * S)
    assert sim.commands[-1][1] == {0: 0.6}
    assert [e.state for e in ended(outcome)] == [SUCCEEDED]
    assert player.status.state == SUCCEEDED and player.status.goal == (0.6,)
    assert 'm0 rho=0.6' in player.status.text


@given(st.lists(st.floats(0.001, 0.5), min_size=1, max_size=8),
       st.lists(st.floats(0.06, 1.9), min_size=8, max_size=8),
       st.lists(st.integers(1, 400_000_000), min_size=1, max_size=30))
@settings(max_examples=60, deadline=None)
def test_every_point_is_commanded_in_order_whatever_the_ticks(gaps, rhos, ticks):
    """The targets go through every point, in time order, and end on the last one: the
    actuator path is the trajectory's polyline, whatever the sampling."""
    times = np.cumsum(gaps)
    points = list(zip(times, [[r] for r in rhos[:len(gaps)]]))
    sim = Recorder()
    player = TrajectoryPlayer(sim)
    player.follow(trajectory(points), now_ns=0)
    now = 0
    for tick in ticks:
        now += tick
        player.advance(now)
    player.advance(int(times[-1] * S) + 1)
    commanded = [c[1][0] for c in sim.commands]
    stamps = [c[0] for c in sim.commands]
    assert stamps == sorted(stamps)
    positions = iter(commanded)
    expected = [rho for k, (_, [rho]) in enumerate(points)     # a repeat is no new command
                if k == 0 or rho != points[k - 1][1][0]]
    for rho in expected:               # a subsequence, in order
        assert any(p == rho for p in positions), (rho, commanded)
    assert commanded[-1] == points[-1][1][0]
    assert player.status.state == SUCCEEDED


def test_a_stamp_in_the_future_holds_until_then_and_time_zero_is_at_once():
    sim = Recorder()
    player = TrajectoryPlayer(sim)
    player.follow(trajectory([(0.0, [0.9]), (1.0, [0.7])], start_ns=5 * S), now_ns=2 * S)
    player.advance(4 * S)
    assert sim.commands == []
    player.advance(5 * S)
    assert sim.commands[-1][1] == {0: 0.9}


def test_a_neck_trajectory_moves_the_named_modules_together():
    sim = Recorder()
    player = TrajectoryPlayer(sim)
    player.follow(trajectory([(1.0, [0.7, 0.2])], joints=(1, 0)), now_ns=0)
    player.advance(S // 2)
    assert sim.commands[-1][1] == {1: pytest.approx(0.55), 0: pytest.approx(0.35)}


@pytest.mark.parametrize('bad, reason', [
    (Trajectory((0,), (S, S), ((0.5,), (0.6,))), 'trajectory_time'),
    (Trajectory((0,), (2 * S, S), ((0.5,), (0.6,))), 'trajectory_time'),
    (Trajectory((0,), (-1,), ((0.5,),)), 'trajectory_time'),
    (Trajectory((0,), (S,), ((0.5, 0.6),)), 'size_mismatch'),
    (Trajectory((0, 1), (S,), ((0.5,),)), 'size_mismatch'),
    (Trajectory((0, 0), (S,), ((0.5, 0.5),)), 'size_mismatch'),
    (Trajectory((0,), (S,), ((math.nan,),)), 'non_finite'),
    (Trajectory((0,), (S, 2 * S), ((0.5,), (3.0,))), 'out_of_range'),
])
def test_bad_trajectories_are_refused_with_a_reason_and_change_nothing(bad, reason):
    sim = Recorder()
    player = TrajectoryPlayer(sim)
    player.follow(trajectory([(10.0, [1.0])]), now_ns=0)
    status = player.status
    outcome = player.follow(bad, now_ns=S)
    assert not outcome.accepted and outcome.reason == reason, outcome
    assert player.status == status                   # the running one goes on
    player.advance(5 * S)
    assert sim.commands[-1][1] == {0: pytest.approx(0.75)}


def test_replaced_canceled_by_a_command_by_an_empty_trajectory_and_by_reset():
    sim = Recorder()
    player = TrajectoryPlayer(sim)
    player.follow(trajectory([(1.0, [1.0])]), now_ns=0)
    outcome = player.follow(trajectory([(1.0, [0.9])]), now_ns=0)
    assert [(e.number, e.state) for e in ended(outcome)] == [(1, CANCELED)]
    assert player.status.number == 2 and player.status.state == EXECUTING
    # a command to another module does not cancel it, one to its module does
    assert ended(player.command_rhos({1: 0.3}, S // 2, 'm1/rho_cmd')) == []
    outcome = player.command_rhos({0: 0.3}, S // 2, 'm0/rho_cmd')
    assert [e.text for e in ended(outcome)] == ['canceled by m0/rho_cmd']
    assert sim.commands[-1] == (S // 2, {0: 0.3}, 'm0/rho_cmd')
    player.follow(trajectory([(1.0, [1.0])]), now_ns=S)
    assert player.follow(Trajectory((), (), ()), now_ns=S).events[0].state == CANCELED
    player.follow(trajectory([(1.0, [1.0])]), now_ns=S)
    assert ended(player.reset((), ()))[0].text == 'canceled by reset'
    assert player.status.state == CANCELED and player.status.number == 4


def test_a_refused_step_or_a_failed_path_aborts():
    sim = Recorder()
    player = TrajectoryPlayer(sim)
    player.follow(trajectory([(1.0, [1.5])]), now_ns=0)
    sim.rho_max = 1.0                                # limits changed meanwhile
    outcome = player.advance(S)
    assert [e.state for e in ended(outcome)] == [ABORTED]
    assert 'outside' in player.status.text
    sim.rho_max = 2.0
    player.follow(trajectory([(1.0, [1.5])]), now_ns=2 * S)
    sim.failing = True
    player.advance(2 * S + S // 2)
    assert player.status.state == ABORTED


def fig8a(rho=0.5):
    return ModuleParams.paper(rho, F3=5.0, F4=5.0)


@pytest.mark.parametrize('rate', [0.0, 0.5])
def test_a_jump_on_the_way_is_reported_and_lands_where_the_tracker_lands(rate):
    """Fig. 8a: 0.5 -> 0.1 crosses the branch point C1 (~0.155); the jump comes with the
    trajectory as its cause, and the end state is the tracker's on the same path (the
    samples split it into straight pieces; a speed limit makes it late, not different)."""
    sim = Simulator([fig8a()], [LOWER], [ModuleLimits(0.05, 1.95, max_rho_rate=rate)],
                    time_budget=None)
    player = TrajectoryPlayer(sim)
    player.follow(trajectory([(0.4, [0.1])]), now_ns=0)
    events, now = [], 0
    while player.status.state == EXECUTING:
        now += S // 50
        assert now < 10 * S
        events += player.advance(now).events
    jumps = [e for e in events if isinstance(e, Jump)]
    assert [(j.kind, j.cause) for j in jumps] == [('branch_point', 'joint_trajectory')]
    assert jumps[0].modules[0].rho == pytest.approx(0.155, abs=0.005)
    assert player.status.state == SUCCEEDED and sim.modules[0].rho == 0.1
    expected = track_module(fig8a(), fig8a(0.1), settle(fig8a(), LOWER).theta)
    np.testing.assert_allclose(sim.module(0)[1].theta, expected.final.theta, atol=1e-6)
    if rate:
        assert now >= 0.8 * S                        # 0.4 m at 0.5 m/s


def test_in_the_dynamics_mode_it_succeeds_once_the_rods_rest_at_the_goal():
    """The rods move with their inertia: the trajectory's end time passes while they still
    swing; it has succeeded only when they rest at its last point."""
    from tensegrity_ros.core.simulation.dynamic_simulator import DynamicSimulator
    params = ModuleParams.paper(0.5, F3=5.0, F4=5.0).with_(m1=0.05, m2=0.05)
    sim = DynamicSimulator([params], [LOWER], [ModuleLimits(0.05, 1.95, max_rho_rate=1.0)],
                           damping=[0.5])
    player = TrajectoryPlayer(sim)
    player.follow(trajectory([(0.2, [0.6])]), now_ns=0)
    now, moving_after_end = 0, False
    while player.status.state == EXECUTING:
        now += S // 50
        assert now < 60 * S
        player.advance(now)
        moving_after_end |= now > 0.2 * S and sim.moving and player.status.state == EXECUTING
    assert player.status.state == SUCCEEDED and not sim.moving
    assert sim.modules[0].rho == 0.6 and moving_after_end
