"""TrackerSettings.stop_at_first_event: a run ends at its first jump, which is the full
run's first jump (same kind, same s), and tracks nothing past it; runs without a jump
are the full run's."""
import numpy as np
import pytest

from tensegrity_ros.core.continuation import TrackerSettings
from tensegrity_ros.core.module.model import ModuleParams
from tensegrity_ros.core.module.polynomial_solver import equilibria
from tensegrity_ros.core.module.tracking import track_module
from tensegrity_ros.core.neck.stack import settle_stack, Stack, track_stack
from tensegrity_ros.core.simulation.start_state import start_state

FIRST = TrackerSettings(stop_at_first_event=True)


def same_first_jump(full, first):
    """The first-event run ends on the full run's first jump, short of the command's end."""
    assert full.status == 'ok' and first.status == 'ok', (full.message, first.message)
    assert len(full.jumps) >= 1 and len(first.jumps) == 1
    a, b = full.jumps[0], first.jumps[0]
    assert b.kind == a.kind
    assert b.s == pytest.approx(a.s, rel=0, abs=1e-12)
    np.testing.assert_allclose(b.from_theta, a.from_theta, rtol=0, atol=1e-9)
    assert 'first event' in first.message


@pytest.mark.parametrize('rho0', [0.157, 0.5])
def test_module_stops_at_the_fold_the_full_run_jumps_at(rho0):
    """Fig. 8a's lower branch (F = 5 N) driven up to rho = 1.2: one fold on the way."""
    start, end = ModuleParams.paper(rho0, F3=5.0, F4=5.0), ModuleParams.paper(1.2, F3=5.0, F4=5.0)
    theta = start_state([start], [(-1.0, -1.0)]).theta
    full = track_module(start, end, theta)
    first = track_module(start, end, theta, FIRST)
    same_first_jump(full, first)
    # it ended on the landing, frozen just past the jump (at most 1e-3 of the command):
    # the command's end is not reached
    jump_rho = first.jumps[0].params.rho
    assert jump_rho <= first.end.rho <= jump_rho + 1e-3 * (end.rho - start.rho)


def test_module_without_a_jump_runs_to_the_end_as_the_full_run():
    start, end = ModuleParams.paper(0.1, F3=5.0, F4=5.0), ModuleParams.paper(1.2, F3=5.0, F4=5.0)
    theta = start_state([start]).theta
    full, first = track_module(start, end, theta), track_module(start, end, theta, FIRST)
    assert not full.jumps and not first.jumps and first.status == 'ok'
    np.testing.assert_array_equal(first.final.theta, full.final.theta)


def loaded_neck(load, L2):
    """Three paper modules, the head loaded (F4 1 % more than F3: no exact symmetry)."""
    modules = [ModuleParams.paper(0.6, L2=L2) for _ in range(2)]
    return Stack(tuple(modules + [ModuleParams.paper(0.6, L2=L2, F3=load, F4=1.01 * load)]))


@pytest.mark.parametrize('L2', [1.0, 1.02])
def test_neck_stops_at_the_collapse_the_full_run_jumps_at(L2):
    upright = equilibria(ModuleParams.paper(0.6, L2=L2)).stable[-1].theta
    start = settle_stack(loaded_neck(0.0, L2), np.tile(upright, (3, 1)))
    a, b = loaded_neck(0.0, L2), loaded_neck(-40.0, L2)
    full, first = track_stack(a, b, start), track_stack(a, b, start, FIRST)
    same_first_jump(full, first)
    assert [p.s for p in first.passages] == [p.s for p in full.passages
                                             if p.s < full.jumps[0].s]
    assert first.end.modules[-1].f3y > -40.0        # the head load stopped growing there


def test_nested_runs_do_not_inherit_the_setting():
    """A landing's own runs (followed back to its event, a buckled branch) read their
    events past the first one: sub_run clears the flag."""
    from tensegrity_ros.core.continuation.run_state import RunState
    from tensegrity_ros.core.module.tracking import ModulePath

    captured = []

    def nested(problem, settings):
        captured.append(settings)
    start, end = ModuleParams.paper(0.5, F3=5.0, F4=5.0), ModuleParams.paper(1.2, F3=5.0, F4=5.0)
    RunState(ModulePath(start, end), FIRST, nested).sub_run(0.2, 0.1)
    assert captured == [TrackerSettings()]
