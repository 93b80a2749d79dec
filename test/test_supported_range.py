"""The supported dimensionless range (core/module/supported_range.py), end to end.

At the limits of every group and at overall scales from 1e-40 to 1e40 the tracker
ends on a stable equilibrium of the exact solver, and a path with jumps gives the
same events (s, angles) as the unit-scale path: the model is scale-invariant.
"""
import math

import numpy as np
import pytest

from tensegrity_ros.core import (equilibria, InvalidParameterError, ModuleParams, settle,
                                 track_module)
from tensegrity_ros.core.module.supported_range import (check_supported, LENGTH_RATIO, LOAD_RATIO,
                                                        out_of_range_reason, OutOfRangeError,
                                                        STIFFNESS_RATIO)


def scaled(p, length, stiffness):
    force = length * stiffness
    return ModuleParams(rho=p.rho * length, L1=p.L1 * length, L2=p.L2 * length,
                        ka=p.ka * stiffness, kb=p.kb * stiffness, kc=p.kc * stiffness,
                        f3x=p.f3x * force, f3y=p.f3y * force, f4x=p.f4x * force, f4y=p.f4y * force)


def wrapped(a, b):
    d = (np.asarray(a) - np.asarray(b) + math.pi) % (2 * math.pi) - math.pi
    return float(np.max(np.abs(d)))


AT_THE_LIMITS = {
    'L2/L1 max': ModuleParams(rho=0.75, L2=LENGTH_RATIO, f3y=0.5),
    'L2/L1 min': ModuleParams(rho=0.75, L2=1 / LENGTH_RATIO, f3y=0.5),
    'rho/L1 min': ModuleParams(rho=1 / LENGTH_RATIO, f3y=0.5),
    'rho/L1 max': ModuleParams(rho=LENGTH_RATIO / 1.3, f3y=0.5),
    'kb/ka max, kc/ka min': ModuleParams(rho=0.75, kb=100 * STIFFNESS_RATIO,
                                         kc=100 / STIFFNESS_RATIO),
    'kb/ka min, kc/ka max': ModuleParams(rho=0.75, kb=100 / STIFFNESS_RATIO,
                                         kc=100 * STIFFNESS_RATIO),
    'load max': ModuleParams(rho=0.75, f3x=100 * LOAD_RATIO, f4y=-100 * LOAD_RATIO),
    'loads max, mixed': ModuleParams(rho=0.75, f3y=-100 * LOAD_RATIO, f4y=100 * LOAD_RATIO,
                                     f3x=-100 * LOAD_RATIO),
}
SCALES = [(1.0, 1.0), (1e-20, 1e20), (1e20, 1e-30), (1e-15, 1e-15), (1e15, 1e15), (1e-40, 1e-8)]


@pytest.mark.parametrize('name', AT_THE_LIMITS)
@pytest.mark.parametrize('length, stiffness', SCALES)
def test_tracking_at_the_limits_of_the_range_and_any_scale(name, length, stiffness):
    unit = AT_THE_LIMITS[name]
    assert out_of_range_reason(unit) == ''
    p = scaled(unit, length, stiffness)
    assert out_of_range_reason(p) == ''
    start = settle(p, np.random.default_rng(0).uniform(-3, 3, 2))
    end = p.with_(rho=p.rho * 1.3, f3y=-0.5 * p.f3y + 30.0 * length * stiffness)
    result = track_module(p, end, start.theta)
    assert result.status == 'ok', result.message
    assert result.final.stable
    exact = [e.theta for e in equilibria(end).stable]
    assert min(wrapped(result.final.theta, t) for t in exact) < 1e-8


@pytest.mark.parametrize('length, stiffness', SCALES)
def test_jumps_are_scale_invariant(length, stiffness):
    """Fig. 8a with a small asymmetry, both ends: the same events at every scale."""
    unit_a = ModuleParams.paper(0.5, F3=5.001, F4=5)
    unit_b = unit_a.with_(rho=0.1)
    theta = settle(unit_a, [-1.0, -1.0]).theta
    reference = track_module(unit_a, unit_b, theta)
    result = track_module(scaled(unit_a, length, stiffness), scaled(unit_b, length, stiffness),
                          theta)
    assert [j.kind for j in result.jumps] == [j.kind for j in reference.jumps] == ['fold']
    for a, b in zip(result.jumps, reference.jumps):
        assert a.s == pytest.approx(b.s, abs=1e-9)
        assert wrapped(a.from_theta, b.from_theta) < 1e-6
        assert wrapped(a.to_theta, b.to_theta) < 1e-6
    assert wrapped(result.final.theta, reference.final.theta) < 1e-9


@pytest.mark.parametrize('change, group', [
    ({'f3x': 1e10}, 'load/(k L)'),          # issue 10 item 2: F/(kL) = 1e8 on the default module
    ({'L1': 1e49}, 'L2/L1'),
    ({'ka': 1e49}, 'kb/ka'),
    ({'ka': 1e-50, 'kb': 1e50}, 'kb/ka'),
    ({'rho': 1e4}, 'rho/L1'),
    ({'kc': 1e6}, 'kc/ka'),
])
def test_outside_the_range_is_refused_with_the_group_named(change, group):
    params = ModuleParams(rho=0.75).with_(**change)
    reason = out_of_range_reason(params)
    assert reason.startswith(group)
    with pytest.raises(OutOfRangeError, match='supported'):
        check_supported(params)
    assert issubclass(OutOfRangeError, InvalidParameterError)     # the node's out_of_range path


def test_inside_the_range_passes_through():
    params = ModuleParams(rho=0.75, f3x=1e6)
    assert check_supported(params) is params
