"""The simulator's side-effect-free command checks (what the node rejects when it reads a
command, before coalescing) against the documented rules (msg_docs/rho_cmd.md,
force_a3.md): a target must be finite and inside [rho_min, rho_max]; a force component
finite and inside the supported range (load/(k L) <= 1e4, README).  A check never changes the
state, and it agrees with what the command itself would refuse."""
import math

from hypothesis import given, settings, strategies as st

from tensegrity_ros.core import ModuleParams
from tensegrity_ros.core.simulation.simulator import ModuleLimits, Simulator

LIMITS = ModuleLimits(rho_min=0.05, rho_max=1.95)
VALUES = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                   st.floats(min_value=-0.5, max_value=2.5),
                   st.sampled_from([0.05, 1.95, 1e50, -1e50, 1.0000001e50]))


def simulator():
    return Simulator([ModuleParams.paper(0.75)], [[0.7, 0.7]], [LIMITS])


SIM = simulator()


@settings(max_examples=300, deadline=None, derandomize=True)
@given(VALUES)
def test_rho_check_follows_the_documented_rule(rho):
    before = SIM.module(0)
    refusal = SIM.rhos_refusal({0: rho})
    allowed = math.isfinite(rho) and 0.05 <= rho <= 1.95
    assert (refusal is None) == allowed
    if refusal is not None:
        assert refusal.reason == ('non_finite' if not math.isfinite(rho) else 'out_of_range')
        assert not SIM.command_rho(0, rho, 0).accepted
    assert SIM.module(0) == before


@settings(max_examples=300, deadline=None, derandomize=True)
@given(VALUES, VALUES, st.sampled_from(['a3', 'a4']))
def test_force_check_follows_the_documented_rule(fx, fy, node):
    before = SIM.module(0)
    refusal = SIM.force_refusal(0, node, (fx, fy))
    finite = math.isfinite(fx) and math.isfinite(fy)
    # the supported range: any load at most 1e4 x softest spring x shorter rod (1e6 N here,
    # with the documented relative rounding slack of 1e-12)
    allowed = finite and max(abs(fx), abs(fy)) <= 1e4 * 100.0 * 1.0 * (1.0 + 1e-12)
    assert (refusal is None) == allowed
    if refusal is not None:
        assert refusal.reason == ('non_finite' if not finite else 'out_of_range')
        assert not SIM.set_force(0, node, (fx, fy), 0).accepted
    assert SIM.module(0) == before
