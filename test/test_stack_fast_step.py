"""The small-command step's shortcuts (core/stack_fast_step.py, issue 14) change no answer:
a command that starts from the previous command's kept evaluation gives what a fresh
evaluation gives, and the s-rates that skip still parameter groups equal the general
formula (all groups treated as moving) and finite differences."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from tensegrity_ros.core.stack import StackPath, settle_stack, track_stack
from tensegrity_ros.core.stack_fast_step import _KEPT
from test_stack_formulations import random_stack


def without_kept(record):
    """A copy of ``record`` that carries no kept evaluation (the next command evaluates)."""
    copy = type(record)(**{name: getattr(record, name)
                           for name in record.__dataclass_fields__})
    assert _KEPT not in copy.__dict__
    return copy


def assert_same_record(a, b, rel=1e-12):
    scale = np.max(np.abs(b.eigenvalues))
    assert np.max(np.abs(a.state - b.state)) <= rel * (1.0 + np.max(np.abs(b.state)))
    assert np.max(np.abs(a.eigenvalues - b.eigenvalues)) <= rel * scale
    assert a.energy == pytest.approx(b.energy, rel=rel, abs=rel)
    assert np.max(np.abs(a.actuator_forces - b.actuator_forces)) <= rel * (
        1.0 + np.max(np.abs(b.actuator_forces)))
    assert np.max(np.abs(a.nodes - b.nodes)) <= rel
    assert a.residual <= 1e-10 * scale and b.residual <= 1e-10 * scale


@pytest.mark.parametrize('n', [1, 2, 3, 5])
def test_a_chain_of_commands_from_kept_evaluations_equals_fresh_ones(n):
    """Seeded chains of small commands (rho, loads, springs, rods; one module or all):
    every answer from the previous command's kept evaluation is the fresh answer."""
    rng = np.random.default_rng(300 + n)
    stack = random_stack(rng, n)
    state = settle_stack(stack, np.full((n, 2), 0.75))
    kept_used = 0
    for k in range(12):
        i = int(rng.integers(n))
        m = stack.modules[i]
        change = [dict(rho=m.rho + rng.uniform(-2e-3, 2e-3)),
                  dict(f3y=m.f3y + rng.uniform(-0.05, 0.05)),
                  dict(ka=m.ka * (1 + rng.uniform(-1e-3, 1e-3))),
                  dict(L2=m.L2 * (1 + rng.uniform(-1e-3, 1e-3)))][k % 4]
        end = stack.with_module(i, **change)
        kept_used += _KEPT in state.__dict__
        ours = track_stack(stack, end, state)
        fresh = track_stack(stack, end, without_kept(state))
        assert ours.status == fresh.status == 'ok' and ours.steps == fresh.steps
        assert not ours.jumps and not fresh.jumps
        assert_same_record(ours.final, fresh.final)
        stack, state = end, ours.final
    assert kept_used >= 6          # the kept evaluation was exercised, not just the fresh one


def moving_groups(rng, n, group):
    """A path that moves only one parameter group of a random stack (or all of them)."""
    start = random_stack(rng, n)
    if group == 'all':
        return start, random_stack(rng, n)
    i = int(rng.integers(n))
    m = start.modules[i]
    change = {'rho': dict(rho=m.rho + 0.01), 'loads': dict(f4x=m.f4x + 0.3, m1=m.m1 + 0.05),
              'springs': dict(kb=m.kb + 5.0), 'rods': dict(L1=m.L1 + 0.02)}[group]
    return start, start.with_module(i, **change)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2 ** 16), n=st.integers(1, 4), s=st.floats(0.0, 1.0),
       group=st.sampled_from(['rho', 'loads', 'springs', 'rods', 'all']))
def test_rates_skipping_still_groups_equal_the_general_formula(seed, n, s, group):
    """dF/ds and dE/ds with still groups skipped equal the general formula (every group
    treated as moving) to 1e-12, and central finite differences to 1e-5."""
    rng = np.random.default_rng(seed)
    start, end = moving_groups(rng, n, group)
    y = np.concatenate([rng.uniform(-np.pi, np.pi, 2 * n), rng.uniform(-1, 1, n - 1)])
    path, general = StackPath(start, end), StackPath(start, end)
    general._moving = dict.fromkeys(general._moving, True)
    f_s, e_s = path.residual_s(y, s), path.energy_s(y, s)
    f_ref, e_ref = general.residual_s(y, s), general.energy_s(y, s)
    assert np.max(np.abs(f_s - f_ref)) <= 1e-12 * max(1.0, np.max(np.abs(f_ref)))
    assert e_s == pytest.approx(e_ref, rel=1e-12, abs=1e-12)
    h = 1e-6
    fd_s = (path.residual(y, s + h) - path.residual(y, s - h)) / (2 * h)
    assert np.max(np.abs(f_s - fd_s)) < 1e-5 * max(1.0, np.max(np.abs(fd_s)))
    fd_e = (path.energy(y, s + h) - path.energy(y, s - h)) / (2 * h)
    assert e_s == pytest.approx(fd_e, abs=1e-5 * max(1.0, abs(fd_e)))


@pytest.mark.parametrize('n', [1, 3])
def test_the_kept_evaluation_is_the_fresh_one_at_the_next_start(n):
    """The point kept on a record is taken (not re-evaluated) by the next command at the
    same parameters and scales, and every quantity the step reads from it (residual,
    Jacobian, eigenvalues, and dF/ds, dE/ds of the *new* path) is the fresh one; after a
    command that changed the rod lengths (new scales) the next one evaluates afresh."""
    from tensegrity_ros.core.stack_fast_step import _start_point
    rng = np.random.default_rng(400 + n)
    stack = random_stack(rng, n)
    state = settle_stack(stack, np.full((n, 2), 0.75))
    m = stack.modules[0]
    for first_change, kept in ((dict(rho=m.rho + 1e-3), True),
                               (dict(f3y=m.f3y + 0.01, m2=m.m2 + 0.01), True),
                               (dict(L1=m.L1 * 1.001), False)):
        first = stack.with_module(0, **first_change)
        record = track_stack(stack, first, state).final
        assert _KEPT in record.__dict__
        end = first.with_module(n - 1, rho=first.modules[n - 1].rho - 1e-3)
        path = StackPath(first, end)
        # the previous command computed its own s-rates on the kept point: they must go
        path.energy_s_at(record.__dict__[_KEPT][2])
        start = _start_point(path, record.state, record)
        assert (start is record.__dict__[_KEPT][2]) == kept
        fresh = StackPath(first, end).evaluate(record.state.copy(), 0.0)
        for name in ('residual_at', 'jacobian_at', 'eigenvalues_at', 'residual_s_at',
                     'energy_s_at', 'energy_at'):
            ours, ref = getattr(path, name)(start), getattr(path, name)(fresh)
            assert np.max(np.abs(np.asarray(ours) - ref)) <= 1e-12 * max(
                1.0, np.max(np.abs(ref))), name
