"""The compiled neck flows (numba, :mod:`tensegrity_ros.core.neck.flow_kernel`) and the
numpy ones are the same equations: on the states real flows visit (landings, releases,
start settles of necks of 2..10 modules, damped ones next to flat modules among them),
the velocity agrees to rounding and the damping decision exactly; a tracker run with
them gives the same answer."""
from __future__ import annotations

import numpy as np
import pytest

from neck_path_families import paths
from tensegrity_ros.core.continuation import TrackerSettings
from tensegrity_ros.core.neck import flow_kernel as stack_flow_kernel
from tensegrity_ros.core.neck.flows import StackFlows
from tensegrity_ros.core.neck.path import StackPath
from tensegrity_ros.core.neck.stack import settle_stack, track_stack
from tensegrity_ros.core.numerics import numba_kernels

#: (the numpy side is the BLAS kernel's: run under every kernel of make test-numerics)
pytestmark = pytest.mark.numerics

#: bench_neck_paths' seed 0 paths whose flows pass modules near flat (limit family) and
#: land jumps (head loads, perfect and imperfect necks, N = 2..10)
PATHS = (18, 19, 20, 21, 22, 23, 27, 29, 36, 37, 45, 46, 47, 49, 53)


def _needs_numba():
    if stack_flow_kernel.compiled() is None:
        pytest.skip('numba is not installed (or TENSEGRITY_NO_NUMBA is set)')


def _visited_states(monkeypatch):
    """(path, y, s) of every flow velocity the numpy tracker evaluates on PATHS."""
    seen = []
    descent = StackFlows.descent

    def spy(self, y, s):
        seen.append((self, np.array(y, dtype=float), s))
        return descent(self, y, s)

    monkeypatch.setattr(StackFlows, 'descent', spy)
    family = paths(0, 9)
    for index in PATHS:
        _, start, end, theta = family[index]
        track_stack(start, end, settle_stack(start, theta))
    monkeypatch.setattr(StackFlows, 'descent', descent)
    return seen


def test_the_compiled_and_the_numpy_flows_agree(monkeypatch):
    _needs_numba()
    seen = _visited_states(monkeypatch)
    sizes, damped, checked = set(), 0, 0
    for path, y, s in seen[::7]:
        try:
            numpy = path.descent(y, s), path.damped(y, s)
        except np.linalg.LinAlgError:
            continue
        path.compile_flows()
        compiled = path.descent(y, s), path.damped(y, s)
        path.flow_kernel = None
        scale = np.max(np.abs(numpy[0]))
        # (near rest the forces cancel: their rounding, ~3e-14, is the velocity's error)
        assert np.max(np.abs(compiled[0] - numpy[0])) <= 1e-11 * scale + 1e-12, (y, s)
        assert compiled[1] == numpy[1]
        sizes.add(path.n)
        damped += numpy[1]
        checked += 1
    assert checked > 500 and damped > 10 and {2, 3, 10} <= sizes, (checked, damped, sizes)


@pytest.mark.parametrize('index', [20, 29, 36, 46])
def test_a_track_with_compiled_flows_gives_the_numpy_tracks_answer(index):
    """Jumps (kind, s to 1e-9, landing to 1e-7) and the final state of bench_neck_paths
    paths that land (limit, perfect, imperfect necks)."""
    _needs_numba()
    _, start, end, theta = paths(0, 9)[index]
    state = settle_stack(start, theta)
    compiled = TrackerSettings(compiled_flows=True)
    a = track_stack(start, end, state)
    b = track_stack(start, end, settle_stack(start, theta, compiled), compiled)
    assert (a.status, [j.kind for j in a.jumps]) == (b.status, [j.kind for j in b.jumps])
    for ja, jb in zip(a.jumps, b.jumps):
        assert ja.s == pytest.approx(jb.s, abs=1e-9)
        assert np.ravel(ja.to_theta) == pytest.approx(np.ravel(jb.to_theta), abs=1e-7)
    assert np.ravel(a.final.theta) == pytest.approx(np.ravel(b.final.theta), abs=1e-7)


def test_without_numba_the_numpy_flows_run(monkeypatch):
    """TENSEGRITY_NO_NUMBA: nothing compiles, compile_flows leaves the numpy flows, and a
    tolerance study's code fingerprint says so (a cluster's workers must agree on it: the
    two round differently)."""
    from tensegrity_ros.core.tolerance.questions import code_fingerprint
    code_fingerprint.cache_clear()
    with_numba, available = code_fingerprint(), numba_kernels.engine() != 'numpy'
    monkeypatch.setenv('TENSEGRITY_NO_NUMBA', '1')
    monkeypatch.setattr(stack_flow_kernel, '_COMPILED', [])
    code_fingerprint.cache_clear()
    try:
        assert numba_kernels.engine() == 'numpy'
        assert (code_fingerprint() != with_numba) == available
    finally:
        code_fingerprint.cache_clear()
    _, start, end, _ = paths(0, 9)[20]
    path = StackPath(start, end)
    path.compile_flows()
    assert path.flow_kernel is None
