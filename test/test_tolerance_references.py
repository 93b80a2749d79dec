"""A tolerance study against references that share no code with it (issue 34):

* the unloaded module, whose operating range is known in closed form (docs/model.md section
  2 item 2, the paper's fig. 3: two stable non-flat equilibria iff |L1 - L2| < 2 rho <
  L1 + L2), with L2 normal: every sample's range and the quantiles are exact;
* a sample replayed alone by the command line (its replay command, as the report prints
  it): ``tensegrity range`` / ``tensegrity track`` give the sample's figures;
* the jump probability of a path ending next to C1 (fig. 8a/8b) against a direct loop
  over the same samples: a fixed-step continuation written here, on the energy's
  gradient and Hessian written here from docs/model.md section 1.
"""
import contextlib
from dataclasses import replace
import io
import json
import shlex

import numpy as np
import pytest
from scipy import stats

from tensegrity_ros import cli
from tensegrity_ros.core.tolerance.sample_statistics import proportion_interval
from tensegrity_ros.tolerance import module_design, neck_design, tolerance_study

Q = (0.01, 0.05, 0.5, 0.95, 0.99)


def test_unloaded_range_edges_and_their_quantiles_are_the_closed_form():
    n, mu, sigma = 512, 1.3, 0.02
    design = module_design({'rho': 0.5, 'L2': mu})
    result = tolerance_study(design, 'range', [f'L2=normal:{sigma}'], samples=n, processes=1)
    L2 = result.inputs[:, 0]
    f = result.figures
    assert np.all(f['status'] == 0)
    # each sample: the non-flat branch merges into a flat one at 2 rho = |L1 - L2|, L1 + L2
    np.testing.assert_allclose(f['rho_min'], (L2 - 1.0) / 2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(f['rho_max'], (L2 + 1.0) / 2, rtol=0, atol=1e-12)
    assert np.all(f['jumps_below'] == 0) and np.all(f['jumps_above'] == 0)  # no jump there
    # the quantiles: a scrambled Sobol' net has one point in each 1/n of the unit interval,
    # so the empirical q-quantile of L2 lies between its exact (q -+ 2/n)-quantiles
    summary = result.summary()['figures']
    for name, sign in (('rho_min', -1.0), ('rho_max', 1.0)):
        for q in Q:
            got = summary[name]['quantiles'][f'{100 * q:g}%']
            lo, hi = ((mu + sigma * stats.norm.ppf(q + d) + sign) / 2 for d in (-2 / n, 2 / n))
            assert lo <= got <= hi, (name, q, lo, got, hi)
    width = summary['width']['quantiles']['50%']
    assert width == pytest.approx(1.0, abs=1e-12)          # (L1 + L2 - (L2 - L1)) / 2 = L1


def run_cli(command):
    """``tensegrity ...`` in this process: (exit status, JSON document)."""
    argv = shlex.split(command)[1:] + ['--json']
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = cli.main(argv)
    return code, json.loads(out.getvalue())


def test_the_unloaded_branch_ends_where_it_merges_not_at_rho_0():
    """operation_range took the flat's other degeneracy, rho = 0, for the lower end of
    this branch (7 of the 512 samples above): it merges at (L2 - L1) / 2."""
    from tensegrity_ros.core import ModuleParams
    from tensegrity_ros.core.analysis import operation_range
    from tensegrity_ros.core.simulation.start_state import upper_equilibrium
    p = ModuleParams.paper(0.5, L2=1.2539027522962565)
    result = operation_range(p, upper_equilibrium(p).theta)
    assert result.rho_min == pytest.approx((p.L2 - 1.0) / 2, abs=1e-12)
    assert result.lower.kind == 'branch_point'


def test_worst_range_samples_replayed_by_tensegrity_range():
    design = module_design({'rho': 0.5, 'F': 5.0}, guess=(-1.0, -1.0))
    result = tolerance_study(design, 'range', ['k=5%', 'L2=0.001', 'F3=normal:0.2'],
                             samples=256, processes=1, worst=3)
    for w in result.summary()['worst']:
        code, doc = run_cli(w['replay'][0])
        assert code == 0
        i = w['index']
        assert doc['rho_min'] == pytest.approx(result.figures['rho_min'][i], abs=1e-12)
        assert doc['rho_max'] == pytest.approx(result.figures['rho_max'][i], abs=1e-12)
        assert doc['width'] == pytest.approx(w['value'], abs=1e-12)
        code, solved = run_cli(w['replay'][1])
        assert solved['num_stable'] == result.figures['num_stable'][i]


def test_worst_path_samples_replayed_by_tensegrity_track_leg_by_leg():
    design = module_design({'rho': 0.5, 'F': 5.0}, legs=[{'rho': 0.157}, {'rho': 1.2}],
                           guess=(-1.0, -1.0))
    result = tolerance_study(design, 'path', ['L2=normal:0.001', 'kc=2%'], samples=64,
                             processes=1, worst=2)
    for w in result.summary()['worst']:
        i = w['index']
        events, finals = [], []
        for leg, command in enumerate(w['replay']):
            code, doc = run_cli(command)
            assert code == 0
            events += [(leg, e) for e in doc['events']]
            finals.append(doc['final'])
        f = result.figures
        assert len(events) == f['jumps'][i]
        leg, first = events[0]
        assert leg == f['jump_leg'][i]
        assert first['s'] == pytest.approx(f['jump_s'][i], abs=1e-9)
        assert first['rho'] == pytest.approx(f['jump_rho'][i], abs=1e-9)
        assert first['landing']['theta1'] == pytest.approx(f['landing_theta1'][i], abs=1e-7)
        assert finals[-1]['theta1'] == pytest.approx(f['final_theta1'][i], abs=1e-7)
        assert finals[-1]['theta2'] == pytest.approx(f['final_theta2'][i], abs=1e-7)


def test_worst_neck_sample_replayed_from_its_parameter_file(tmp_path):
    design = neck_design('config/neck.yaml', legs=[{'F': -9.0}])
    result = tolerance_study(design, 'head-load', ['k=3%', 'L1=0.0005'], samples=4,
                             processes=1, worst=1)
    w = result.summary()['worst'][0]
    (tmp_path / w['config_file']).write_text(w['config'])
    command = w['replay'][0].replace(w['config_file'], str(tmp_path / w['config_file']))
    code, doc = run_cli(command)
    assert code == 0
    first = doc['events'][0]
    assert -(first['F3'] + first['F4']) == pytest.approx(w['value'], abs=1e-9)


@pytest.mark.parametrize('which', ['neck', 'module'])
def test_head_load_stopped_at_the_first_event_is_the_full_tracks(which, monkeypatch):
    """The head-load question tracks each sample only to its first jump
    (TrackerSettings.stop_at_first_event); the full track of the same samples, past the
    jump to the end load, reports the same critical load, bit for bit (seeded samples)."""
    from tensegrity_ros.core.tolerance import questions as tolerance_questions
    if which == 'neck':
        design = neck_design('config/neck.yaml', legs=[{'F': -9.0}])
        tols, n, exact = ['k=3%', 'L1=0.0005', 'L2=0.0005'], 6, False
    else:
        design = module_design({'rho': 0.8, 'F': 0.0}, legs=[{'F': -60.0}])
        tols, n, exact = ['k=5%', 'L2=0.001'], 8, True
    assert tolerance_questions.FIRST_EVENT.stop_at_first_event
    first = tolerance_study(design, 'head-load', tols, samples=n, seed=5, processes=1,
                            exact=exact).figures
    monkeypatch.setattr(tolerance_questions, 'FIRST_EVENT',
                        replace(tolerance_questions.FIRST_EVENT, stop_at_first_event=False))
    full = tolerance_study(design, 'head-load', tols, samples=n, seed=5, processes=1,
                           exact=exact).figures
    assert np.all(full['collapsed'] == 1.0)         # every sample jumps before the end load
    for name in ('critical_load', 'critical_F3', 'critical_F4', 'collapse_kind',
                 'collapsed', 'buckled_before'):
        np.testing.assert_array_equal(first[name], full[name], err_msg=name)


# -- the jump probability near C1 against a direct loop over the samples -------------------

def gradient_hessian(p, t1, t2):
    """dU/dtheta and d2U/dtheta2 of U = ka/2 |A3 - A2|^2 + kb/2 |A4 - A1|^2 + kc/2 |A4 - A3|^2
    - F3 y3 - F4 y4 (docs/model.md section 1, springs and vertical loads only), by hand."""
    rho, L1, L2, k, F3, F4 = p
    x3, y3 = L1 * np.cos(t1), L1 * np.sin(t1)
    x4, y4 = rho - L2 * np.cos(t2), L2 * np.sin(t2)
    dx3, dy3 = -y3, x3                       # d(x3, y3)/dt1
    dx4, dy4 = y4, rho - x4                  # d(x4, y4)/dt2: (L2 sin t2, L2 cos t2)
    g1 = k * ((x3 - rho) * dx3 + y3 * dy3) - k * ((x4 - x3) * dx3 + (y4 - y3) * dy3) - F3 * dy3
    g2 = k * (x4 * dx4 + y4 * dy4) + k * ((x4 - x3) * dx4 + (y4 - y3) * dy4) - F4 * dy4
    # second derivatives: d2(x3, y3)/dt1^2 = (-x3, -y3), d2(x4, y4)/dt2^2 = (rho - x4, -y4)
    h11 = (k * (dx3 ** 2 + dy3 ** 2 + (x3 - rho) * -x3 + y3 * -y3)
           + k * (dx3 ** 2 + dy3 ** 2 - (x4 - x3) * -x3 - (y4 - y3) * -y3) + F3 * y3)
    h22 = (k * (dx4 ** 2 + dy4 ** 2 + x4 * (rho - x4) + y4 * -y4)
           + k * (dx4 ** 2 + dy4 ** 2 + (x4 - x3) * (rho - x4) + (y4 - y3) * -y4) + F4 * y4)
    h12 = -k * (dx3 * dx4 + dy3 * dy4)
    return g1, g2, h11, h12, h22


def marched_jumps(L2, rho0, rho1, guess, fine_from=0.2, step=1e-4):
    """Whether the stable branch through ``guess`` at rho0 is lost before rho1, for every
    L2 (L1 = 1, k = 100, F3 = F4 = 5): natural-parameter continuation in fixed steps
    (0.01, then ``step`` below ``fine_from``), Newton from the last point, lost where
    Newton fails, the state leaps or H is no longer positive definite."""
    n = len(L2)
    t1, t2 = np.full(n, guess[0]), np.full(n, guess[1])
    lost = np.zeros(n, bool)
    rhos = np.concatenate([np.arange(rho0, fine_from, -0.01), np.arange(fine_from, rho1, -step),
                           [rho1]])
    for rho in rhos:
        p = (rho, 1.0, L2, 100.0, 5.0, 5.0)
        n1, n2 = t1.copy(), t2.copy()
        for _ in range(8):
            g1, g2, h11, h12, h22 = gradient_hessian(p, n1, n2)
            det = h11 * h22 - h12 * h12
            n1, n2 = n1 - (h22 * g1 - h12 * g2) / det, n2 - (h11 * g2 - h12 * g1) / det
        g1, g2, h11, h12, h22 = gradient_hessian(p, n1, n2)
        ok = ((np.abs(g1) + np.abs(g2) < 1e-9) & (h11 > 0) & (h11 * h22 - h12 * h12 > 0)
              & (np.abs(n1 - t1) + np.abs(n2 - t2) < 0.1))
        lost |= ~ok
        t1, t2 = np.where(lost, t1, n1), np.where(lost, t2, n2)
    return lost


def test_jump_probability_near_c1_equals_a_direct_loop_over_the_samples():
    """rho 0.5 -> 0.157 from the lower branch of fig. 8a, L2 = 1 + N(0, 0.001): C1 (a
    pitchfork at L2 = 1) is a fold at ~0.155..0.161 for L2 != 1, so some samples jump."""
    end = 0.157
    design = module_design({'rho': 0.5, 'F': 5.0}, legs=[{'rho': end}], guess=(-1.0, -1.0))
    result = tolerance_study(design, 'path', ['L2=normal:0.001'], samples=512, processes=1,
                             sampler='mc', seed=3)
    L2 = result.inputs[:, 0]
    jumped = result.figures['jumped'] == 1.0
    lost = marched_jumps(L2, 0.5, end, (-1.03, -1.03))
    # a fold within a march step of the end may be told either way by the march
    clear = ~(np.abs(result.figures['jump_rho'] - end) < 2e-4)
    np.testing.assert_array_equal(jumped[clear], lost[clear])
    assert 0.2 < jumped.mean() < 0.8
    p = result.summary()['probabilities']['jumped']
    assert p['events'] == int(jumped.sum()) and p['trials'] == 512
    assert p['interval'] == pytest.approx(list(proportion_interval(int(jumped.sum()), 512)))
    assert p['interval'][0] <= lost.mean() <= p['interval'][1]


def test_a_neck_path_sample_replayed_by_tensegrity_track_config_leg_by_leg(tmp_path):
    """Two legs of neck commands (m2's rho, then every rho with a head load): the figures
    of each sample equal `tensegrity track --config` run leg by leg from its file."""
    design = neck_design('config/neck.yaml', legs=[{'m2.rho': 0.07},
                                                   {'rho': 0.085, 'F': -2.0}])
    result = tolerance_study(design, 'path', ['k=3%', 'm1.L1=0.001'], samples=2, processes=1,
                             worst=2)
    for w in result.summary()['worst']:
        (tmp_path / w['config_file']).write_text(w['config'])
        events, final = [], None
        assert len(w['replay']) == 2
        for leg, command in enumerate(w['replay']):
            code, doc = run_cli(command.replace(w['config_file'],
                                                str(tmp_path / w['config_file'])))
            assert code == 0
            events += [(leg, e) for e in doc['events']]
            final = doc['final']
        i = w['index']
        assert len(events) == result.figures['jumps'][i]
        assert final['head']['x'] == pytest.approx(result.figures['final_head_x'][i], abs=1e-9)
        assert final['head']['angle'] == pytest.approx(result.figures['final_head_angle'][i],
                                                       abs=1e-9)
