"""The independent references end in bounded time: past its work budget a reference says
it could not decide (reference_paths.Undecided, node_spring_flow.FlowUndecided) instead of
integrating on until pytest's timeout (issue 30: one flow leg of the reference ran > 540 s).
Undecided is not a NoRest, which the reference's own decisions catch and act on."""
import numpy as np
import pytest

from node_spring_flow import FlowUndecided, NodeSpringNeck
from reference_paths import (evaluations_spent, ModuleSystem, NoRest, quasi_static_path, Undecided,
                             work_budget)
from tensegrity_ros.core import ModuleParams

#: Numerically sensitive throughout: `make test-numerics` runs it under other CPUs' arithmetic.
pytestmark = pytest.mark.numerics


def fig8(rho):
    return ModuleParams.paper(rho, F3=5.0, F4=5.0)


def test_a_reference_path_past_its_budget_says_undecided():
    """fig. 8a's path across C1 needs a few thousand evaluations: with 500 it stops at
    the 501st, undecided, and nested calls share the outermost call's budget."""
    system = ModuleSystem(fig8(0.5), fig8(0.1))
    with work_budget(limit=500):
        with pytest.raises(Undecided, match='budget of 500'):
            quasi_static_path(system, [-1.0, -1.0])
    assert evaluations_spent() == 501
    assert not issubclass(Undecided, NoRest)
    path = quasi_static_path(system, [-1.0, -1.0])       # the default budget decides
    assert len(path.jumps) == 1 and evaluations_spent() > 500


def test_a_node_spring_flow_past_its_budget_says_undecided():
    """The stiff-spring node model released off the upright neck's equilibrium."""
    model = NodeSpringNeck([ModuleParams.paper(0.6, F3=-5.0, F4=-5.0)], 1e6)
    x0 = model.nodes_from_angles(np.array([[1.0, 1.5]]))
    with pytest.raises(FlowUndecided, match='within 20 evaluations'):
        model.flow(x0, 'node', budget=20)
    rest, _ = model.flow(x0, 'node')
    assert np.linalg.norm(model.gradient(rest)) < 1e-9
