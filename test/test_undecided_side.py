"""A branch point whose side doubles cannot decide is reported ``undecided``, never chosen
silently; an imperfection doubles resolve is followed onto its own side, no passage.

A nearly symmetric mechanism passes a nearly perfect pitchfork.  With an imperfection
eps the branch it is on goes on smoothly to the side eps picks (the connected branch of
an imperfect pitchfork: no branch point at all); with eps = 0 it is a supercritical
pitchfork, a passage to either mirror side.  Between them lies an imperfection whose
branch structure (~eps^(2/3) in s) is below what doubles resolve: there the tracker
passes the point by its rule (the side along +psi) and must say that the side is not
decided (``Track.undecided``, ``ModuleTrack.undecided``, ``StackTrack.undecided``).

References that share no code with the tracker: the exact roots of the toy's cubic;
for the module and the neck, the side a resolvable imperfection of the same sign takes
(the connected branch is continuous in eps, so a smaller eps of one sign ends on the
same side) -- the module's by the exact solver's two minima, the neck's with the
reference's own flow (test/reference_paths.py) resting where the tracker ended.
"""
import numpy as np
import pytest

from neck_path_families import paper_neck, upright
from reference_paths import angle_distance, flow_to_rest, NeckSystem
from tensegrity_ros.core import equilibria, ModuleParams, track, track_module
from tensegrity_ros.core.neck.stack import track_stack

pytestmark = pytest.mark.numerics


class ImperfectPitchfork:
    """U = x^4 / 4 - mu(s) x^2 / 2 - eps x + stiff modes, mu = -1 + 2 s: a pitchfork at
    s = 1/2, imperfect by eps.  The minimum followed from s = 0 ends at the root of
    x^3 - x - eps of eps's sign (the largest for eps >= 0)."""

    def __init__(self, eps):
        self.size, self.eps, self.stiff = 3, eps, np.array([2.0, 4.0])

    def _mu(self, s):
        return -1.0 + 2.0 * s

    def residual(self, y, s):
        return np.concatenate([[y[0] ** 3 - self._mu(s) * y[0] - self.eps], self.stiff * y[1:]])

    def jacobian(self, y, s):
        return np.diag(np.concatenate([[3.0 * y[0] ** 2 - self._mu(s)], self.stiff]))

    def residual_s(self, y, s):
        return np.array([-2.0 * y[0], 0.0, 0.0])

    def energy(self, y, s):
        return (y[0] ** 4 / 4 - self._mu(s) * y[0] ** 2 / 2 - self.eps * y[0]
                + 0.5 * self.stiff @ y[1:] ** 2)

    def energy_s(self, y, s):
        return -y[0] ** 2

    def stability(self, y, s):
        return np.linalg.eigh(self.jacobian(y, s))

    def descent(self, y, s):
        return -self.residual(y, s)

    def project(self, y, s):
        return y

    def start(self):
        roots = np.roots([1.0, 0.0, 1.0, -self.eps])            # x^3 + x = eps at s = 0
        return np.array([roots.real[np.argmin(abs(roots.imag))], 0.0, 0.0])

    def end(self):
        roots = np.roots([1.0, 0.0, -1.0, -self.eps]).real     # x^3 - x = eps at s = 1
        return roots.max() if self.eps >= 0.0 else roots.min()


#: Imperfections doubles resolve: the side is the model's, no passage, nothing undecided.
RESOLVED = (1e-3, 1e-6, 1e-9, 1e-12, 1e-14)
#: Down to none: either the model's side or an undecided passage, never a silent choice.
BELOW = (3e-16, 1e-16, 1e-18, 1e-24, 0.0)


@pytest.mark.parametrize('eps', [s * e for e in RESOLVED for s in (1.0, -1.0)])
def test_a_resolved_imperfection_is_followed_to_its_own_side_without_a_passage(eps):
    toy = ImperfectPitchfork(eps)
    got = track(toy, toy.start())
    assert got.status == 'ok' and not got.events, got.message
    assert not got.passages and not got.undecided
    assert abs(got.state[0] - toy.end()) <= 1e-12


@pytest.mark.parametrize('eps', [s * e for e in BELOW for s in (1.0, -1.0)])
def test_an_unresolved_imperfection_is_its_own_side_or_undecided(eps):
    toy = ImperfectPitchfork(eps)
    got = track(toy, toy.start())
    assert got.status == 'ok' and not got.events, got.message
    right = abs(got.state[0] - toy.end()) <= 1e-12
    assert right or got.undecided, f'eps={eps}: ended at {got.state[0]}, silently'
    for undecided in got.undecided:
        # at the branch point, uncertain by a few LAW_RESOLUTIONs in s, listed as passed
        assert abs(undecided.s - 0.5) <= 1e-9 and 1e-11 < undecided.s_uncertainty < 1e-8
        assert undecided.s in [s for s, _ in got.passages]


def test_the_perfect_pitchfork_is_a_passage_whose_side_is_undecided():
    toy = ImperfectPitchfork(0.0)
    got = track(toy, toy.start())
    assert len(got.passages) == 1 and len(got.undecided) == 1
    assert abs(abs(got.state[0]) - 1.0) <= 1e-12


def _module_side(F):
    """theta1's sign at the end of the unloaded module's path rho 1.5 -> 0.5 (through its
    flat pitchfork at rho = L) under F3 = F4 = F, and the undecided passages listed."""
    got = track_module(ModuleParams.paper(1.5, F3=F, F4=F), ModuleParams.paper(0.5, F3=F, F4=F),
                       (0.0, 0.0))
    assert got.status == 'ok' and not got.jumps, got.message
    return np.sign(got.final.theta1), got.undecided


@pytest.mark.parametrize('sign', (1.0, -1.0))
def test_the_module_through_its_flat_pitchfork_takes_the_loads_side_or_says_undecided(sign):
    # the exact solver: at rho = 0.5 the resolvable load's side is one of two minima
    reference, listed = _module_side(sign * 1e-6)
    minima = equilibria(ModuleParams.paper(0.5, F3=sign * 1e-6, F4=sign * 1e-6)).stable
    assert sorted(np.sign(m.theta1) for m in minima) == [-1.0, 1.0] and not listed
    for F in (1e-9, 1e-11, 1e-13):
        side, listed = _module_side(sign * F)
        assert side == reference and not listed, f'F={sign * F}'
    for F in (1e-12, 1e-14, 1e-15, 1e-17, 0.0):
        side, listed = _module_side(sign * F)
        assert side == reference or listed, f'F={sign * F}: the other side, silently'
        for undecided in listed:
            assert abs(undecided.params.rho - 1.0) <= 1e-8
            assert 0.0 < undecided.rho_uncertainty < 1e-7


@pytest.mark.parametrize('n', (3, 4))
def test_a_nearly_symmetric_neck_under_a_head_load_takes_its_side_or_says_undecided(n):
    """Paper necks at chord 0.6, module 0's ka off by e, head load 0 -> -10 N per node
    (bench_neck_paths' 'imperfect' family): they buckle sideways; e = 1e-14 buckled to
    the side e = 1e-6 .. 1e-12 do not, and listed a passage, silently."""
    def tracked(e):
        start, end = paper_neck(n, 0.6, 0.0, e), paper_neck(n, 0.6, -10.0, e)
        got = track_stack(start, end, upright(n, 0.6))
        assert got.status == 'ok' and not got.jumps, got.message
        return got

    for sign in (1.0, -1.0):
        reference = tracked(sign * 1e-6)
        system = NeckSystem(paper_neck(n, 0.6, 0.0, sign * 1e-6).modules,
                            paper_neck(n, 0.6, -10.0, sign * 1e-6).modules)
        final = np.ravel(reference.final.theta)
        rest = np.ravel(flow_to_rest(system, final, 1.0).state)[:final.size]
        assert angle_distance(final, rest) <= 1e-7
        for e in (1e-10, 1e-12, 1e-14, 0.0):
            got = tracked(sign * e)
            same = np.max(np.abs(got.final.theta - reference.final.theta)) <= 1e-3
            assert same or got.undecided, f'N={n}, e={sign * e}: the other side, silently'
            if e >= 1e-12:
                assert same and not got.passages and not got.undecided, f'e={sign * e}'
            for undecided in got.undecided:
                assert 0.0 < undecided.s_uncertainty < 1e-8
                assert max(undecided.rho_uncertainty) == 0.0      # (a load path: rho fixed)
