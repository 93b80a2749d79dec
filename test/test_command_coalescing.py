"""The coalescing rule of commands that arrive faster than they are tracked (ROS-free).

Reference: a brute-force reading of the rule written for this test -- for each key the
last command offered with it survives, survivors ordered by the position of that last
offer; everything else is coalesced.
"""
from hypothesis import given, settings, strategies as st

from tensegrity_ros.core.command_coalescing import (LatestCommands, force_key,
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
