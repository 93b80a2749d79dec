"""The vectorised branch follower (core/tolerance/branch_batch.py) against the scalar reference,
sample by sample: every figure of the operating range equals operation_range's
(``tensegrity range``), every figure of a planned path track_module's (``tensegrity
track``), over designs with folds, search limits, start guesses, schedules of several
legs, moving loads, rod weights, horizontal loads, nearly and exactly symmetric samples
(which the batch hands to the scalar path).  And a sample's answer does not depend on
the other samples of its chunk."""
from hypothesis import given, settings, strategies as st
import numpy as np
import pytest

from tensegrity_ros.core.tolerance.sampling import sample_waypoints, unit_samples
from tensegrity_ros.tolerance import module_design, parse_tolerances, question_for

RANGE_CASES = [
    # lower branch of fig. 8a: folds at both ends (C1 imperfect, C2)
    ({'rho': 0.5, 'F': 5.0}, (-1.0, -1.0), ['k=5%', 'L2=0.001', 'F3=normal:0.2']),
    # its upper branch: stable over the whole search interval (limits)
    ({'rho': 0.5, 'F': 5.0}, None, ['k=5%', 'L2=0.01']),
    # fig. 7 (pushing, L2 = 3/2), both branches
    ({'rho': 0.7, 'F': -10.0, 'L2': 1.5}, None, ['k=5%', 'L2=0.01', 'F3=0.5']),
    ({'rho': 0.7, 'F': -10.0, 'L2': 1.5}, (-0.5, -0.5), ['ka=2%', 'L1=normal:0.01:3']),
    # mixed loads, horizontal loads and rod weights
    ({'rho': 1.0, 'F3': 3.0, 'F4': -2.0, 'L2': 0.8, 'F3x': 0.5, 'm1': 0.2, 'm2': 0.1}, None,
     ['k=10%', 'L1=0.05', 'F=1', 'm1=20%']),
    # nearly symmetric: ends at imperfect branch points (sharp turns)
    ({'rho': 0.5, 'F': 5.0}, (-1.0, -1.0), ['L2=normal:1e-7']),
    # exactly symmetric samples (only the shared spring factor... each spring varies,
    # but L1 = L2 and F3 = F4 stay equal only for kc): swap symmetry broken by ka, kb
    ({'rho': 0.75, 'F': -10.0}, None, ['kc=5%']),
    # unloaded: mirror symmetric, branch points at |L1 - L2| / 2 and (L1 + L2) / 2
    ({'rho': 0.5, 'L2': 1.3}, None, ['L2=0.02']),
]

PATH_CASES = [
    ({'rho': 0.5, 'F': 5.0}, [{'rho': 0.1}], (-1.0, -1.0), ['L2=normal:0.001']),
    ({'rho': 0.5, 'F': 5.0}, [{'rho': 0.1}, {'rho': 0.5}], (-1.0, -1.0),
     ['L2=normal:0.02', 'k=5%']),
    ({'rho': 0.5, 'F': 5.0}, [{'rho': 1.2}, {'rho': 0.5}, {'rho': 0.12}], (-1.0, -1.0),
     ['L2=0.02', 'F4=0.3']),
    ({'rho': 0.6}, [{'F': -40.0}], None, ['L2=0.01', 'k=5%', 'F3=0.1']),
    ({'rho': 0.7, 'F3': 2.0, 'F4': -1.0}, [{'rho': 0.2, 'F3': 8.0}, {'rho': 1.4, 'F4': -6.0}],
     None, ['L1=0.02', 'k=5%', 'F3=0.5']),
    ({'rho': 0.5, 'F': 5.0, 'm1': 0.1, 'm2': 0.1, 'F4x': 0.3}, [{'rho': 0.12, 'F4x': -0.3}],
     (-1.0, -1.0), ['m2=0.05', 'L2=0.01']),
    # ends near C1: some samples jump, some do not
    ({'rho': 0.5, 'F': 5.0}, [{'rho': 0.157}], (-1.0, -1.0), ['L2=normal:0.001']),
    # exactly symmetric path (L1 = L2, F3 = F4 throughout): the scalar path
    ({'rho': 0.5, 'F': 5.0}, [{'rho': 0.1}], (-1.0, -1.0), ['kc=1%']),
]


def sampled(kind, values, legs, guess, tols, n, seed=0):
    design = module_design(values, legs=legs, guess=guess)
    t = parse_tolerances(tols, design)
    w = sample_waypoints(design.stops, t, unit_samples(n, len(t), 'sobol', seed))
    return question_for(kind, design), question_for(kind, design, exact=True), w


def assert_same(a, b, atol):
    assert np.all(b['scalar'] == 1.0)
    for name in a:
        if name == 'scalar':            # who answered: the point of the comparison
            continue
        x, y = a[name], b[name]
        np.testing.assert_array_equal(np.isnan(x), np.isnan(y), err_msg=name)
        np.testing.assert_allclose(x, y, rtol=0, atol=atol, equal_nan=True, err_msg=name)


@pytest.mark.parametrize('values, guess, tols', RANGE_CASES)
def test_operating_range_equals_operation_range_sample_by_sample(values, guess, tols):
    batch, exact, w = sampled('range', values, (), guess, tols, 64)
    fast = batch.evaluate(w)
    reference = exact.evaluate(w)
    assert np.all(reference['status'] == 0)
    assert_same(fast, reference, 1e-10)


@pytest.mark.parametrize('values, legs, guess, tols', PATH_CASES)
def test_planned_path_equals_track_module_sample_by_sample(values, legs, guess, tols):
    batch, exact, w = sampled('path', values, legs, guess, tols, 24)
    fast = batch.evaluate(w)
    reference = exact.evaluate(w)
    assert np.all(reference['status'] == 0)
    assert_same(fast, reference, 1e-8)       # the tracker locates events to 1e-9 in s


@pytest.mark.parametrize('values, tols', [
    ({'rho': 0.6}, ['L2=0.01', 'k=5%', 'F3=0.1']),                 # fold of the upright module
    ({'rho': 0.6, 'F': 0.5}, ['kc=5%']),                               # symmetric: scalar
])
def test_a_modules_head_load_equals_track_module(values, tols):
    batch, exact, w = sampled('head-load', values, [{'F': -40.0}], None, tols, 24)
    assert_same(batch.evaluate(w), exact.evaluate(w), 1e-8)


@pytest.mark.parametrize('kind, values, legs, guess, tols, scalar', [
    ('range', {'rho': 0.5, 'F': 5.0}, (), (-1.0, -1.0), ['k=5%', 'L2=0.001'], 0),
    ('path', {'rho': 0.5, 'F': 5.0}, [{'rho': 0.157}], (-1.0, -1.0), ['L2=normal:0.001'], 0),
    ('range', {'rho': 0.75, 'F': -10.0}, (), None, ['kc=5%'], 64),        # exact symmetry
    ('range', {'rho': 0.5, 'L2': 1.3}, (), None, ['L2=0.02'], 64),        # unloaded
])
def test_generic_samples_vectorised_and_symmetric_ones_scalar(kind, values, legs, guess, tols,
                                                              scalar):
    batch, _, w = sampled(kind, values, legs, guess, tols, 64)
    assert batch.evaluate(w)['scalar'].sum() == scalar


def test_some_samples_jump_near_c1_and_some_do_not():
    batch, _, w = sampled('path', {'rho': 0.5, 'F': 5.0}, [{'rho': 0.157}], (-1.0, -1.0),
                          ['L2=normal:0.001'], 256)
    jumped = batch.evaluate(w)['jumped']
    assert 0.2 < jumped.mean() < 0.8


@settings(max_examples=6, deadline=None, derandomize=True)
@given(rho=st.floats(0.1, 1.8), L2=st.floats(0.5, 1.6), F3=st.floats(-25, 25),
       F4=st.floats(-25, 25), F3x=st.floats(-5, 5), m2=st.floats(0, 0.5),
       guess=st.none() | st.tuples(st.floats(-3, 3), st.floats(-3, 3)),
       to_rho=st.floats(0.05, 1.9), to_F4=st.floats(-25, 25))
def test_any_design_batch_equals_scalar(rho, L2, F3, F4, F3x, m2, guess, to_rho, to_F4):
    """Property: over random designs (loads, horizontal loads, rod weights, guesses) the
    vectorised range and path equal the scalar functions sample by sample."""
    values = {'rho': rho, 'L2': L2, 'F3': F3, 'F4': F4, 'F3x': F3x, 'm2': m2}
    batch, exact, w = sampled('range', values, (), guess, ['k=5%', 'L2=0.01', 'F3=0.3'], 32)
    assert_same(batch.evaluate(w), exact.evaluate(w), 1e-10)
    legs = [{'rho': to_rho, 'F4': to_F4}]
    batch, exact, w = sampled('path', values, legs, guess, ['k=5%', 'L1=0.01'], 16)
    assert_same(batch.evaluate(w), exact.evaluate(w), 1e-8)


@pytest.mark.parametrize('kind, values, legs, guess', [
    ('range', {'rho': 0.5, 'F': 5.0}, (), (-1.0, -1.0)),
    ('path', {'rho': 0.5, 'F': 5.0}, [{'rho': 0.157}, {'rho': 1.2}], (-1.0, -1.0)),
])
def test_a_samples_answer_does_not_depend_on_its_chunk(kind, values, legs, guess):
    batch, _, w = sampled(kind, values, legs, guess, ['k=5%', 'L2=normal:0.001'], 200)
    whole = batch.evaluate(w)
    order = np.random.default_rng(0).permutation(len(w))
    pieces = [batch.evaluate(w[order[i:i + 37]]) for i in range(0, len(w), 37)]
    for name in whole:
        shuffled = np.concatenate([p[name] for p in pieces])
        back = np.empty_like(shuffled)
        back[order] = shuffled
        np.testing.assert_array_equal(back, whole[name], err_msg=name)
