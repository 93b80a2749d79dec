"""``tensegrity snap``: flags, JSON summary, CSV history, PNG plot, bad input."""
import csv
import json

import pytest

from tensegrity_ros.cli import main
from tensegrity_ros.core import equilibria, ModuleParams

FIG8A = ('--L1', 1, '--L2', 1, '--k', 100, '--F3', 5, '--F4', 5, '--m1', 0.05, '--m2', 0.05)
LOWER = ('--theta1', -1, '--theta2', -1)
SUMMARY_KEYS = {'onset_rho', 'peak_speed', 'peak_actuator_force', 'overshoot', 'settle_time',
                'final'}


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def snap(capsys, *extra, to_rho=0.9, rate=0.1, damping=0.05):
    return run(capsys, 'snap', '--rho', 0.5, '--to-rho', to_rho, '--rate', rate,
               '--damping', damping, *FIG8A, *extra)


def test_json_summary_of_the_fig8a_fold_jump(capsys):
    code, out, err = snap(capsys, *LOWER, '--json')
    assert code == 0, err
    doc = json.loads(out)
    assert SUMMARY_KEYS <= set(doc)
    assert set(doc['final']) == {'theta1', 'theta2', 'speed'}
    assert 0.8745 < doc['onset_rho'] < 0.89                    # just after the static fold C2
    assert doc['peak_speed'] > 10.0 and doc['overshoot'] > 0.0
    assert doc['settle_time'] > 0.0 and doc['final']['speed'] < 1e-6
    [jump] = doc['quasi_static']['jumps']
    assert jump['kind'] == 'fold'
    upper = [e for e in equilibria(ModuleParams(rho=0.9, f3y=5, f4y=5, m1=0.05, m2=0.05))
             if e.stable]
    assert len(upper) == 1 and doc['final']['theta1'] == pytest.approx(upper[0].theta1, abs=1e-6)
    assert doc['lands_elsewhere'] is False


def test_text_output_names_the_onset_and_the_quasi_static_fold(capsys):
    code, out, err = snap(capsys, *LOWER)
    assert code == 0, err
    assert 'quasi-static: fold at rho=0.878' in out
    assert 'snap starts at rho=0.88' in out and 'settled' in out


def test_default_start_is_the_upper_branch_which_does_not_snap(capsys):
    code, out, err = snap(capsys, '--json', '--hold', 0.5)
    assert code == 0, err
    doc = json.loads(out)
    assert doc['onset_rho'] is None and doc['quasi_static']['jumps'] == []
    assert doc['final']['theta1'] > 0


def test_csv_history_starts_at_rest_and_ends_at_the_held_rho(capsys, tmp_path):
    path = tmp_path / 'history.csv'
    code, _, err = snap(capsys, *LOWER, '--csv', path, '--hold', 0.5)
    assert code == 0, err
    with open(path) as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == ['t', 'rho', 'theta1', 'theta2', 'theta1_dot', 'theta2_dot',
                             'actuator_force']
    assert float(rows[0]['t']) == 0.0 and float(rows[0]['theta1_dot']) == 0.0
    assert float(rows[0]['theta1']) < 0                          # the lower branch
    assert float(rows[-1]['rho']) == 0.9
    assert float(rows[-1]['t']) == pytest.approx(4.0 + 0.5)
    speeds = [abs(float(r['theta1_dot'])) for r in rows]
    assert max(speeds) > 10.0


def test_plot_writes_a_png(capsys, tmp_path):
    path = tmp_path / 'snap.png'
    code, _, err = snap(capsys, *LOWER, '--plot', path, '--hold', 0.5)
    assert code == 0, err
    assert path.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


@pytest.mark.parametrize('changes, message', [
    ({'--rate': 0}, 'rate must be positive, got 0'),
    ({'--rate': 'nan'}, "must be a finite number, got 'nan'"),
    ({'--damping': -1}, 'damping must be finite and >= 0, got -1'),
    ({'--hold': -2}, 'hold must be finite and >= 0, got -2'),
    ({'--m1': 0}, 'dynamics needs positive rod masses, got m1=0.0'),
    ({'--theta1': 1}, 'give both --theta1 and --theta2'),
    ({'--to-rho': -0.5}, 'rho must be positive, got -0.5'),
])
def test_bad_input_is_one_line_and_exit_status_2(capsys, changes, message):
    flags = {'--rho': 0.5, '--to-rho': 0.9, '--rate': 0.1, '--damping': 0.05,
             **dict(zip(FIG8A[::2], FIG8A[1::2])), **changes}
    code, out, err = run(capsys, 'snap', *[x for item in flags.items() for x in item])
    assert code == 2
    assert message in err and err.count('\n') == 1
    assert out == ''


def test_missing_rate_is_a_usage_error(capsys):
    code, _, err = run(capsys, 'snap', '--rho', 0.5, '--to-rho', 0.9, '--damping', 0.1, *FIG8A)
    assert code == 2 and '--rate' in err


def test_help_lists_the_dynamic_options(capsys):
    code, out, _ = run(capsys, 'snap', '--help')
    assert code == 0
    for flag in ('--rate', '--damping', '--hold', '--json', '--csv', '--plot', '--to-rho',
                 '--theta1', '--m1', '--m2'):
        assert flag in out
