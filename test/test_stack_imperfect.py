"""Neck tracker near its branch points with a tiny asymmetry (issue 10 item 3).

The upright neck under a growing head load: N = 3 buckles continuously (a supercritical
branch point: no jump, in the perfect neck and once one module is a little asymmetric);
N = 2 snaps (subcritical: the asymmetric neck folds next to it).  Every reported jump
lands on a verified stable state of the stack at its load.
"""
import numpy as np
import pytest

from stack_cartesian_reference import CartesianStackPath
from tensegrity_ros.core import BRANCH_POINT, equilibria, FOLD, ModuleParams
from tensegrity_ros.core.neck.stack import settle_stack, Stack, track_stack

#: Numerically sensitive throughout: `make test-numerics` runs it under other CPUs' arithmetic.
pytestmark = pytest.mark.numerics


UPRIGHT = equilibria(ModuleParams.paper(0.6)).stable[-1].theta


def neck(n, load, first=None):
    modules = [ModuleParams.paper(0.6) for _ in range(n - 1)]
    modules.append(ModuleParams.paper(0.6, F3=load, F4=load))
    if first:
        modules[0] = modules[0].with_(**first)
    return Stack(tuple(modules))


def head_load_track(n, first=None, load=-40.0):
    start = settle_stack(neck(n, 0.0, first), np.tile(UPRIGHT, (n, 1)))
    result = track_stack(neck(n, 0.0, first), neck(n, load, first), start)
    assert result.status == 'ok', result.message
    for jump in result.jumps:
        assert np.max(np.abs(jump.to_theta - jump.from_theta)) > 1e-3
        if jump.kind == FOLD:      # a stable equilibrium at the fold's load next to the landing
            landed = settle_stack(jump.stack, jump.to_theta)
            assert landed.stable and np.max(np.abs(landed.theta - jump.to_theta)) < 1e-3
    assert result.final.stable
    return result


def loads(result):
    return [j.stack.modules[-1].f3y for j in result.jumps]


@pytest.mark.parametrize('ka', [100.0000001, 99.9999999])
def test_n3_asymmetric_neck_buckles_without_an_event(ka):
    perfect = head_load_track(3)
    # the sideways buckling is supercritical: passed continuously, not a jump
    assert [j.kind for j in perfect.jumps] == [FOLD] and len(perfect.passages) == 1
    assert perfect.passages[0].stack.modules[-1].f3y == pytest.approx(-6.8538247, abs=1e-6)
    imperfect = head_load_track(3, {'ka': ka})
    assert [j.kind for j in imperfect.jumps] == [FOLD] and imperfect.passages == ()
    assert loads(imperfect)[0] == pytest.approx(loads(perfect)[0], abs=1e-4)


def test_n3_perfect_neck_buckles_onto_the_imperfect_necks_minimum():
    """Past the sideways buckling (head load -10 N per node, critical -6.85 N) the perfect
    neck sits on the buckled minimum the 1e-9-imperfect neck of the matching sign follows
    (the mirror image of the other sign's), checked in node coordinates to be a stable
    equilibrium of the loaded neck."""
    perfect = head_load_track(3, load=-10.0)
    assert perfect.jumps == () and len(perfect.passages) == 1
    theta = perfect.final.theta
    assert np.max(np.abs(theta[:, 0] - theta[:, 1])) > 0.1              # buckled sideways
    matching = head_load_track(3, {'ka': 99.9999999}, load=-10.0)
    mirrored = head_load_track(3, {'ka': 100.0000001}, load=-10.0)
    assert matching.jumps == mirrored.jumps == () and matching.passages == ()
    np.testing.assert_allclose(theta, matching.final.theta, atol=1e-8)
    np.testing.assert_allclose(theta, mirrored.final.theta[:, ::-1], atol=1e-8)
    reference = CartesianStackPath(neck(3, -10.0), neck(3, -10.0))
    y = reference.state_from_angles(theta, 0.0)
    eigenvalues = reference.eigenvalues(y, 0.0)
    assert np.max(np.abs(reference.residual(y, 0.0))) < 1e-8
    assert eigenvalues[0] > 1e-3 * eigenvalues[-1]


@pytest.mark.parametrize('first', [{'ka': 100.001}, {'ka': 99.999}, {'f3x': 1e-4}])
def test_n2_asymmetric_neck_folds_next_to_the_snap(first):
    perfect = head_load_track(2)
    assert [j.kind for j in perfect.jumps] == [BRANCH_POINT]
    imperfect = head_load_track(2, first)
    assert [j.kind for j in imperfect.jumps] == [FOLD]
    assert loads(imperfect)[0] == pytest.approx(loads(perfect)[0], abs=1e-2)
    # both land on the same far branch
    np.testing.assert_allclose(imperfect.jumps[0].to_theta, perfect.jumps[0].to_theta, atol=1e-2)
