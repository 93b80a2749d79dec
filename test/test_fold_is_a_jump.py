"""A fold is a jump however small (issue 41): decided by the branch's own law at the
critical point (:mod:`tensegrity_ros.core.continuation.normal_form`), not by how far the
landing lies.

The module under small loads, 1e-7 .. 1e-2 k L, next to rho = L: its lower branch ends
in a fold whose snap is ~1 deg or less.  On fc2a771 the loads 1e-5 .. 1e-4 N (k L = 100
N) made the tracker list a passage there and no jump (`tensegrity track --rho 0.5
--to-rho 1.9 --F 2e-5 --theta1 -1 --theta2 -1`): the step-off along the critical mode
reached the other minimum, past s*, and took it for a buckled branch.

Checked against the quasi-static path of the overdamped mechanism (reference_paths.py,
sharing no code with the package) with its step motion capped at FINE_MOTION, so that a
snap of 0.8 deg is not taken for the branch's own fast motion next to the fold.  Every
path: the same jumps, each within LOCATION_TOL in s, landing on the same minimum, the same
final state.  The random family draws a fresh seed on every run (printed on failure).
"""
import itertools
import math

import numpy as np
import pytest

from reference_paths import angle_distance, ModuleSystem, quasi_static_path
from tensegrity_ros.core.continuation import normal_form
from tensegrity_ros.core.continuation.run_state import RunState
from tensegrity_ros.core.continuation.settings import TrackerSettings
from tensegrity_ros.core.module.model import ModuleParams
from tensegrity_ros.core.module.tracking import ModulePath, track_module

#: The reference's largest step motion (rad) on these paths (its default, 0.02, is more
#: than the snaps).
FINE_MOTION = 1e-3
LOCATION_TOL = 1e-7
#: The same minimum (rad): the tracker's landing at its event's s and the reference's
#: landing, polished by the reference's own Newton at the same s.
LANDING_TOL = 1e-6
FINAL_TOL = 1e-6
K_L = 100.0
PATHS = [(0.9, 1.1), (1.1, 0.9), (0.3, 0.005)]


def assert_reference_path(start, end, theta):
    """The tracker's path from ``theta`` against the reference's."""
    system = ModuleSystem(start, end)
    ref = quasi_static_path(system, theta, max_motion=FINE_MOTION)
    got = track_module(start, end, np.asarray(theta, dtype=float))
    message = (f'tracker {[(j.kind, j.s, j.to_theta.tolist()) for j in got.jumps]}, '
               f'reference {[(j.s, j.landing.tolist()) for j in ref.jumps]}')
    assert got.status == 'ok', got.message
    assert len(got.jumps) == len(ref.jumps), message
    for mine, theirs in zip(sorted(got.jumps, key=lambda j: j.s), ref.jumps):
        assert abs(mine.s - theirs.s) <= LOCATION_TOL, message
        landing_s = (mine.landing_params.rho - start.rho) / (end.rho - start.rho)
        theirs_there, converged = system.critical_point(theirs.landing, landing_s)
        assert converged, message
        assert angle_distance(np.ravel(mine.to_theta), theirs_there) <= LANDING_TOL, message
    assert angle_distance(np.ravel(got.final.theta), ref.final) <= FINAL_TOL, message
    return got


@pytest.mark.numerics
def test_the_issue_repro_is_a_fold_of_about_0_8_degrees():
    """`tensegrity track --rho 0.5 --to-rho 1.9 --F 2e-5 --theta1 -1 --theta2 -1`."""
    start, end = ModuleParams.paper(0.5, F3=2e-5, F4=2e-5), ModuleParams.paper(1.9, F3=2e-5,
                                                                               F4=2e-5)
    got = assert_reference_path(start, end, [-1.0, -1.0])
    (jump,) = got.jumps
    assert jump.kind == 'fold' and not got.passages
    assert 0.99996 < jump.params.rho < 0.99997
    assert math.degrees(angle_distance(jump.from_theta, jump.to_theta)) == pytest.approx(0.8,
                                                                                         abs=0.1)


@pytest.mark.parametrize('ratio', [1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2])
def test_small_loads_next_to_rho_l_and_c1(ratio):
    """Loads ratio k L pulling up (pushing is its mirror image), F4 = F3 and F3 / 2, from
    the lower and the upper branch: through rho = L both ways, and towards C1."""
    for share, (r0, r1), theta in itertools.product([1.0, 0.5], PATHS, [-1.0, 1.0]):
        force = ratio * K_L
        start = ModuleParams.paper(r0, F3=force, F4=share * force)
        end = ModuleParams.paper(r1, F3=force, F4=share * force)
        try:
            assert_reference_path(start, end, [theta, theta])
        except AssertionError as error:
            raise AssertionError(f'F3={force!r} F4={share * force!r} rho {r0} -> {r1} '
                                 f'theta {theta}: {error}') from error


def random_small_load_path(rng):
    """A random module (L2, stiffnesses), loads 1e-7 .. 1e-2 k L in random directions,
    a random rho path about rho = (L1 + L2) / 2, a random start."""
    ratio = 10.0 ** rng.uniform(-7.0, -2.0)
    l2 = rng.uniform(0.8, 1.25)
    force = ratio * K_L * min(1.0, l2)
    a3, a4 = rng.uniform(0.0, 2.0 * math.pi, 2)
    share = rng.uniform(0.0, 1.0)
    common = {'L2': l2, 'ka': rng.uniform(70, 130), 'kb': rng.uniform(70, 130),
              'kc': rng.uniform(70, 130), 'f3x': force * math.cos(a3),
              'f3y': force * math.sin(a3), 'f4x': share * force * math.cos(a4),
              'f4y': share * force * math.sin(a4)}
    r0, r1 = 0.5 * (1.0 + l2) * rng.uniform(0.8, 1.2, 2)
    return (ModuleParams(rho=r0, **common), ModuleParams(rho=r1, **common),
            rng.uniform(-math.pi, math.pi, 2))


def test_random_small_load_paths_on_a_fresh_seed():
    """Ten random small-load paths on a seed drawn for this run."""
    seed = int(np.random.SeedSequence().entropy % 2**32)
    rng = np.random.default_rng(seed)
    for index in range(10):
        try:
            assert_reference_path(*random_small_load_path(rng))
        except AssertionError as error:
            raise AssertionError(f'seed {seed} path {index} (random_small_load_path): '
                                 f'{error}') from error


# -- the law itself ---------------------------------------------------------------------

def law_at(start, end, theta, s):
    """The branch law at the critical point of the module path nearest (theta, s)."""
    path = ModulePath(start, end)
    run = RunState(path, TrackerSettings(), None)
    run.scale = float(np.max(np.abs(path.stability(np.asarray(theta), s)[0])))
    y = np.asarray(theta, dtype=float)            # the located critical state
    _, psi = run.critical(y, s)
    return normal_form.branch_law(run, s, y, psi)


@pytest.mark.numerics
def test_a_small_fold_turns_back_with_a_converged_quadratic_law():
    """The repro's fold: the branch along the critical mode lies behind s* on both sides
    (s - s* = c2 a^2, c2 < 0), although at the step-off's amplitude one side reaches
    the other minimum past s*."""
    start, end = ModuleParams.paper(0.5, F3=2e-5, F4=2e-5), ModuleParams.paper(1.9, F3=2e-5,
                                                                               F4=2e-5)
    (jump,) = track_module(start, end, [-1.0, -1.0]).jumps
    law = law_at(start, end, jump.from_theta, jump.s)
    assert law.law == normal_form.TURNS_BACK
    assert law.quadratic < 0.0 and abs(law.linear) < abs(law.quadratic) * law.amplitude


def test_the_unloaded_pitchfork_at_rho_l_has_its_buckled_branch_ahead():
    """The unloaded paper module, flat at rho > L: going down through rho = L the
    flat state buckles onto two minima (a supercritical pitchfork, no jump)."""
    start, end = ModuleParams.paper(1.5), ModuleParams.paper(0.5)
    s_star = 0.5                                   # rho = 1
    law = law_at(start, end, [0.0, 0.0], s_star)
    assert law.law == normal_form.AHEAD


def test_fig8a_c1_is_subcritical_its_branch_behind():
    """C1 of fig. 8a (rho = 0.155, F = 5 N): the lower branch loses stability at a
    subcritical branch point, a jump (the paper's)."""
    start, end = ModuleParams.paper(0.5, F3=5.0, F4=5.0), ModuleParams.paper(0.1, F3=5.0, F4=5.0)
    (jump,) = track_module(start, end, [-1.0, -1.0]).jumps
    law = law_at(start, end, jump.from_theta, jump.s)
    assert law.law == normal_form.TURNS_BACK
