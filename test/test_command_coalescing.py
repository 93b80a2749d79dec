"""The coalescing rule of commands that arrive faster than they are tracked (ROS-free).

Reference: a brute-force reading of the rule written for this test -- for each key the
last command offered with it survives, survivors ordered by the position of that last
offer; everything else is coalesced.  The backlog (in arrival order within a time
budget, coalesced beyond it) runs on a fake clock that moves by each command's cost,
against the rule read position by position.
"""
from hypothesis import given, settings, strategies as st
import pytest

from tensegrity_ros.core.simulation.command_coalescing import (BACKLOG_BUDGET_NS, CommandBacklog,
                                                               force_key, LatestCommands,
                                                               target_key)

KEYS = st.sampled_from([target_key([0]), target_key([1]), target_key([0, 2]),
                        force_key(0, 'a3'), force_key(0, 'a4'), force_key(1, 'a3')])


def reference(offers):
    last = {}
    for position, (key, _) in enumerate(offers):
        last[key] = position
    survivors = sorted(last.values())
    return [offers[p][1] for p in survivors], len(offers) - len(survivors)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.lists(st.tuples(KEYS, st.integers()), max_size=60))
def test_every_offered_command_is_applied_or_counted(offers):
    waiting = LatestCommands()
    for key, command in offers:
        waiting.offer(key, command)
    applied, coalesced = reference(offers)
    assert waiting.take() == applied
    assert waiting.coalesced == coalesced
    assert waiting.offered == len(offers) == len(applied) + waiting.coalesced
    assert len(waiting) == 0 and waiting.take() == []


def test_a_target_key_is_the_set_of_modules_named():
    assert target_key([2, 0]) == target_key((0, 2)) != target_key([0])
    assert target_key([0]) != force_key(0, 'a3') != force_key(0, 'a4')


def test_a_later_target_of_the_same_module_replaces_and_moves_to_the_end():
    waiting = LatestCommands()
    waiting.offer(target_key([0]), 'rho 0.6')
    waiting.offer(force_key(0, 'a3'), 'force')
    waiting.offer(target_key([0]), 'rho 0.7')
    assert waiting.take() == ['force', 'rho 0.7']
    assert waiting.coalesced == 1


# ---------------------------------------------------------------------------
# CommandBacklog: in arrival order within the time budget, the latest per key beyond it


class FakeClock:
    """Time in ns that moves only when a command costs some (what it would take to track)."""

    def __init__(self, start=1_000):
        self.now = start

    def __call__(self):
        return self.now


def commands_costing(clock, offers, applied):
    """(key, command) per (key, cost_ns): applying one records its position, spends its cost."""
    def command(position, cost):
        def apply():
            applied.append(position)
            clock.now += cost
        return apply
    return [(key, command(p, cost)) for p, (key, cost) in enumerate(offers)]


def expected_work_off(offers, budget):
    """The rule read literally, position by position: a command whose turn comes before
    ``budget`` ns have passed is applied; at the first that finds it spent, the rest
    are reduced to the last of each key, in the order of those last offers."""
    elapsed = 0
    for position, (_, cost) in enumerate(offers):
        if elapsed >= budget:
            rest = offers[position:]
            last = {key: position + i for i, (key, _) in enumerate(rest)}
            survivors = sorted(last.values())
            return list(range(position)) + survivors, len(rest) - len(survivors)
        elapsed += cost
    return list(range(len(offers))), 0


def work_off(offers, budget):
    clock, applied = FakeClock(), []
    backlog = CommandBacklog(clock, budget)
    for key, command in commands_costing(clock, offers, applied):
        backlog.offer(key, command)
    backlog.work_off()
    return backlog, applied


def test_a_short_burst_is_applied_command_by_command_in_arrival_order():
    # 20 small neck commands (0.3 ms each) waiting behind one callback: 6 ms of work
    offers = [(target_key([0, 1, 2]), 300_000)] * 20
    backlog, applied = work_off(offers, BACKLOG_BUDGET_NS)
    assert applied == list(range(20))
    assert backlog.coalesced == 0 and backlog.applied == backlog.offered == 20
    assert not backlog.beyond_budget and len(backlog) == 0


def test_beyond_the_budget_only_the_latest_target_of_each_key_is_applied():
    # 40 commands of 1 ms on three keys: the turns at 0 .. 9 ms are taken in order; at
    # 10 ms the budget is spent and of the 30 left only each key's last one is applied
    keys = [target_key([0]), target_key([1]), force_key(2, 'a3')]
    offers = [(keys[i % 3], 1_000_000) for i in range(40)]
    backlog, applied = work_off(offers, 10_000_000)
    assert applied == list(range(10)) + [37, 38, 39]
    assert backlog.coalesced == 27 and backlog.applied == 13
    assert backlog.applied + backlog.coalesced == backlog.offered == 40
    assert backlog.beyond_budget


def test_a_slow_command_first_leaves_one_command_per_key_behind_it():
    """A fold (15 ms) at the head of the queue: everything behind it is coalesced to
    its key's latest, so the callback ends after at most one more command per key."""
    offers = [(force_key(0, 'a4'), 15_000_000)] + [(force_key(0, 'a4'), 15_000_000)] * 50
    backlog, applied = work_off(offers, BACKLOG_BUDGET_NS)
    assert applied == [0, 50]
    assert backlog.coalesced == 49


def test_a_lone_command_is_applied_even_with_the_budget_spent():
    backlog, applied = work_off([(target_key([0]), 1)], 0)
    assert applied == [0] and backlog.coalesced == 0 and backlog.beyond_budget


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.lists(st.tuples(KEYS, st.integers(0, 3_000_000)), max_size=60),
       st.integers(0, 20_000_000))
def test_every_offered_command_is_applied_in_order_or_coalesced(offers, budget):
    backlog, applied = work_off(offers, budget)
    expected, coalesced = expected_work_off(offers, budget)
    assert applied == expected
    assert backlog.coalesced == coalesced
    assert backlog.applied + backlog.coalesced == backlog.offered == len(offers)
    assert len(backlog) == 0


def test_a_command_that_raises_leaves_the_ones_behind_it_waiting():
    clock, applied = FakeClock(), []
    backlog = CommandBacklog(clock, BACKLOG_BUDGET_NS)

    def broken():
        raise RuntimeError('tracker bug')
    backlog.offer(target_key([0]), lambda: applied.append('first'))
    backlog.offer(target_key([0]), broken)
    backlog.offer(target_key([0]), lambda: applied.append('third'))
    with pytest.raises(RuntimeError):
        backlog.work_off()
    assert applied == ['first'] and len(backlog) == 1
    backlog.work_off()
    assert applied == ['first', 'third'] and backlog.applied == backlog.offered == 3
