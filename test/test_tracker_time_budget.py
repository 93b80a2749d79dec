"""The tracker's own time budget (``TrackerSettings.time_budget``, issue 10) holds inside
nested work: landing flows, the trackers that follow a landing back, bisections.

The case that overran: the N = 3 upright paper neck under head load, brought back down its
buckled branch from -10 N per node to 1e-10 (relative) past its sideways buckling at
-6.8538 N: with a 3 s budget it ran > 300 s (every landing's back-tracker started a
budget of its own, and landed again).  Each test runs a command unbounded, then with
budgets spread over its whole work.  Deterministic: the clock is the number of the
path's evaluations so far (residual, Jacobian, energy, eigenvalues, flow velocity ...),
so a budget is an amount of work on any machine and no test times anything.  A run
must end failed, on a verified stable state (the start where nothing more was verified),
at the first check point past its budget: exactly there, counted in evaluations, and
the check points are recorded so that this needs no allowance for rounding.  (Which
code runs between two check points, so how many evaluations a run's last one comes
after its budget, does depend on rounding: an allowance of 50 held on SkylakeX, and
the Haswell kernel's run overshot one budget by 59.)  The work between two check
points is bounded too, by GRANULARITY (see there).
"""
import numpy as np
import pytest

from tensegrity_ros.core import continuation, equilibria, ModuleParams, settle, TrackerSettings
from tensegrity_ros.core.module.tracking import ModulePath
from tensegrity_ros.core.neck.stack import settle_stack, Stack, StackPath, track_stack
from tensegrity_ros.core.numerics import bounded_work
from tensegrity_ros.core.simulation.start_state import upright_guess

#: Numerically sensitive throughout: `make test-numerics` runs it under other CPUs' arithmetic.
pytestmark = pytest.mark.numerics


#: Most evaluations between two check points (a lost check point, a loop without one,
#: would run up thousands).  A check point is passed once per pass of a tracker's loop
#: and per probe of a localisation, so a stretch is at most one pass without a probe:
#: the tangent (2) and rate (1), a step's Newton (<= 25) and checks (5), then a probe's
#: Newton and bordered Newton (<= 50) or an arclength step (<= 46), or a nested run's
#: start (<= 28), ~110; these runs meet 112 at most (Haswell; Sandybridge 94, Nehalem
#: 44, SkylakeX 21: which of those a pass runs turns on rounding), hence 200.
GRANULARITY = 200

COUNTED = ('residual', 'jacobian', 'residual_s', 'energy', 'energy_s', 'eigenvalues',
           'stability', 'descent', 'project')


def counting(path_class):
    """``path_class`` with every evaluation counted in ``self.evaluations``."""
    def counted(name):
        original = getattr(path_class, name)

        def method(self, *args):
            self.evaluations += 1
            return original(self, *args)
        return method

    namespace = {name: counted(name) for name in COUNTED}
    namespace['evaluations'] = 0
    return type('Counting' + path_class.__name__, (path_class,), namespace)


class CheckPoints:
    """The tracker's check points, recorded: the path's evaluation count at each, per run
    (every module of core/continuation/ calls ``bounded_work.checkpoint`` through its
    module, so that one wrap sees them all)."""

    def __init__(self, monkeypatch, path):
        self.runs = []
        real = bounded_work.checkpoint

        def recorded():
            self.runs[-1].append(path.evaluations)
            real()
        monkeypatch.setattr(bounded_work, 'checkpoint', recorded)

    def track(self, path, y0, settings, certificate):
        """(result, evaluations used) of one run, its check points recorded."""
        path.evaluations = 0
        self.runs.append([])
        result = continuation.track(path, y0, settings, certificate)
        return result, path.evaluations


def bounded_runs(path, y0, monkeypatch, certificate=''):
    """The unbounded run, then (budget, result, evaluations used) for budgets spread over
    0 .. 1.2 times its work (deadlines in its steps, localisations, landings, followers);
    each bounded run checked to have stopped at its first check point past its budget
    (:func:`check_stopped`), and no two check points more than GRANULARITY apart."""
    points = CheckPoints(monkeypatch, path)
    whole, total = points.track(path, y0, TrackerSettings(), certificate)
    runs = []
    for budget in sorted({int(total * f) for f in np.linspace(0.0, 1.2, 49)}):
        settings = TrackerSettings(time_budget=budget, clock=lambda: path.evaluations)
        result, used = points.track(path, y0, settings, certificate)
        check_stopped(budget, result, used, points.runs[-1])
        runs.append((budget, result, used))
    gaps = [b - a for counts in points.runs for a, b in zip([0] + counts, counts)]
    assert max(gaps) <= GRANULARITY, max(gaps)
    return whole, runs


def check_stopped(budget, result, used, counts):
    """The run passed no check point past its budget and ran to its end, or stopped at
    the first one: exactly there, no evaluation after it."""
    past = [count for count in counts if count > budget]
    if result.status == 'ok' and not past:
        return
    assert past and used == past[0], (budget, used, past[:1])


def check_bounded(runs, whole):
    """Each run ends as the whole run did, or failed on its budget, no further on."""
    assert whole.status == 'ok'
    for budget, result, used in runs:
        if result.status == 'ok':
            assert result.s == 1.0 and len(result.events) == len(whole.events)
            np.testing.assert_array_equal(result.state, whole.state)
            continue
        assert 'time budget' in result.message, (budget, result.message)
        assert result.s <= whole.s and len(result.events) <= len(whole.events)
    assert runs[-1][1].status == 'ok'


def neck(load):
    module = ModuleParams.paper(0.6)
    return Stack((module, module, module.with_(f3y=load, f4y=load)))


def test_a_neck_command_that_overran_ends_within_its_budget(monkeypatch):
    """It now ends ok (back towards the branch point by its normal form, ~4800
    evaluations); budgets short of that cut it, in its steps and in the trackers that
    follow the buckled branch away from the branch point for it."""
    critical = -6.853824673228113              # the sideways buckling (test_continuous_buckling)
    start = neck(0.0)
    down = track_stack(start, neck(-10.0), settle_stack(start, upright_guess(start.modules)))
    path = counting(StackPath)(neck(-10.0), neck(critical * (1.0 + 1e-10)))
    y0 = down.final.state
    whole, runs = bounded_runs(path, y0, monkeypatch, down.final.certificate)
    check_bounded(runs, whole)
    for budget, result, _ in runs:
        assert path.eigenvalues(result.state, result.s)[0] > 0.0 and result.events == ()
    budget, result, _ = runs[0]
    np.testing.assert_allclose(result.state, y0, atol=1e-12)   # the (polished) start kept
    assert result.s == 0.0


def test_a_module_command_across_a_fold_ends_within_its_budget(monkeypatch):
    """The paper module under 5 N loads, rho 0.5 -> 0.05 (one fold, a jump)."""
    start, end = ModuleParams.paper(0.5, F3=5, F4=5), ModuleParams.paper(0.05, F3=5, F4=5)
    theta = settle(start, [-1.0, -1.0]).theta
    path = counting(ModulePath)(start, end)
    whole, runs = bounded_runs(path, theta, monkeypatch)
    assert len(whole.events) == 1
    check_bounded(runs, whole)
    for budget, result, _ in runs:
        if result.status == 'failed':
            # a minimum of the exact solver's (near the fold its classification, with a
            # coarser tolerance, may call it degenerate: lambda_min positive suffices)
            exact = [e.theta for e in equilibria(path.params(result.s)) if e.eigenvalues[0] > 0]
            wrapped = [np.max(np.abs(np.angle(np.exp(1j * (result.state - t))))) for t in exact]
            assert min(wrapped) < 1e-8, budget
    # most budgets run out in the landing (3/4 of the work), on the verified state before it
    assert sum(r.status == 'failed' and abs(r.s - whole.events[0].s) < 1e-6
               for _, r, _ in runs) >= 30
