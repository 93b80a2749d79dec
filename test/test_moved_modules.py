"""The core's module paths of 0.2 that docs/python_api.md promised still import, as aliases
of their new places that warn (issue 42: one release of grace)."""
import importlib
import subprocess
import sys

import pytest

from tensegrity_ros.core.moved_modules import MOVED


#: Run in a fresh interpreter: the old path must not be imported already.
CHILD = """
import importlib, sys, warnings
new = importlib.import_module(sys.argv[2])
with warnings.catch_warnings(record=True) as seen:
    warnings.simplefilter('always')
    old = importlib.import_module(sys.argv[1])
assert old is new, old
print([f'{w.category.__name__}: {w.message}' for w in seen])
"""


@pytest.mark.parametrize('old', sorted(MOVED))
def test_an_old_path_is_its_new_module_and_warns(old):
    done = subprocess.run([sys.executable, '-c', CHILD, old, MOVED[old]], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert f'DeprecationWarning: {old} moved to {MOVED[old]}' in done.stdout, done.stdout


def test_the_public_names_the_docs_show_import_from_the_new_places():
    from tensegrity_ros.core.neck.stack import settle_stack, Stack, track_stack
    from tensegrity_ros.core.simulation.simulator import ModuleLimits, Simulator
    from tensegrity_ros.core.simulation.trajectory import Trajectory, TrajectoryPlayer
    assert all(callable(x) for x in (settle_stack, Stack, track_stack, ModuleLimits, Simulator,
                                     Trajectory, TrajectoryPlayer))
    analysis = importlib.import_module('tensegrity_ros.core.analysis')
    assert callable(analysis.degenerate_curves) and callable(analysis.operation_range)
    dynamics = importlib.import_module('tensegrity_ros.core.dynamics')
    assert callable(dynamics.simulate_snap) and callable(dynamics.simulate_neck_snap)
