"""A critical point the branch goes through (normal_form.goes_through): no jump, no flow.

Where lambda_min dips below the margin test without the branch turning back in s (the
law along the critical mode is ``through``: an imperfect pitchfork's connected branch),
the minimum goes on.  The tracker now says so from the branch itself: the state on it
past s*, stable with a margin.  Before, it released the mechanism there and let frozen
flows come to rest (6.8 s of 6.9 s on the N = 10 neck below, with the same answer: no
jump), since a branch that moves ~0.1 rad in 1e-6 of s leaves a frozen flow's rest test
nothing near to find.

Checked against the reference's own flow (test/reference_paths.py, which shares no code
with the package): at the end of the command it rests where the tracker ended.
"""
import numpy as np
import pytest

from neck_path_families import paper_neck, upright
from reference_paths import angle_distance, flow_to_rest, NeckSystem
from tensegrity_ros.core.continuation import lander
from tensegrity_ros.core.continuation.normal_form import THROUGH
from tensegrity_ros.core.neck.stack import track_stack

pytestmark = pytest.mark.numerics


@pytest.fixture
def spied(monkeypatch):
    """The laws the lander measured, the goes_through answers and the landing flows."""
    seen = {'laws': [], 'through': [], 'flows': 0}
    law, through, landing = lander.branch_law, lander.goes_through, lander.landing_state

    def spy_law(*args, **kwargs):
        seen['laws'].append(law(*args, **kwargs))
        return seen['laws'][-1]

    def spy_through(*args, **kwargs):
        seen['through'].append(through(*args, **kwargs))
        return seen['through'][-1]

    def spy_landing(*args, **kwargs):
        seen['flows'] += 1
        return landing(*args, **kwargs)

    monkeypatch.setattr(lander, 'branch_law', spy_law)
    monkeypatch.setattr(lander, 'goes_through', spy_through)
    monkeypatch.setattr(lander, 'landing_state', spy_landing)
    return seen


def test_a_dip_of_the_nearly_symmetric_n10_neck_is_gone_through_without_a_flow(spied):
    """Ten paper modules at chord 0.6, module 0's ka 1e-9 off, head load 0 -> -10 N
    (bench_neck_paths' 'imperfect' family, N = 10, seed 4)."""
    start, end = paper_neck(10, 0.6, 0.0, 1e-9), paper_neck(10, 0.6, -10.0, 1e-9)
    got = track_stack(start, end, upright(10, 0.6))
    assert got.status == 'ok', got.message
    assert not got.jumps and not got.passages
    assert [law.law for law in spied['laws']] == [THROUGH]
    assert spied['through'][0] is not None and spied['flows'] == 0
    system = NeckSystem(start.modules, end.modules)
    final = np.ravel(got.final.theta)
    rest = flow_to_rest(system, final, 1.0).state
    assert angle_distance(final, np.ravel(rest)[:final.size]) <= 1e-8
