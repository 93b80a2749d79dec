"""``tensegrity tolerance`` as a user meets it: the report (text, JSON, CSV, PNG), replay
files, and one-line refusals (status 2) of bad command lines (issue 34)."""
import contextlib
import csv
import io
import json

import numpy as np
import pytest

from tensegrity_ros import cli
from tensegrity_ros.params_file import load_stack_config

C1 = ['--rho', '0.5', '--F', '5', '--theta1', '-1', '--theta2', '-1']


def run(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(argv)
    return code, out.getvalue(), err.getvalue()


def test_range_report_as_text_json_and_csv(tmp_path):
    argv = ['tolerance', 'range', *C1, '--tol', 'k=5%', '--tol', 'L2=0.001',
            '--tol', 'F3=normal:0.2', '--samples', '256', '--processes', '1', '--worst', '2']
    code, text, _ = run(argv)
    assert code == 0
    for part in ('quantiles:', 'rho_min', 'probabilities:', 'bistable', 'clopper-pearson',
                 'sensitivity:', 'worst samples', 'tensegrity range --rho 0.5'):
        assert part in text
    code, out, err = run(argv + ['--json', '-'])
    doc = json.loads(out)                                   # strict JSON: no NaN
    assert doc['question'] == 'range' and doc['samples'] == 256 and doc['valid'] == 256
    assert list(doc['figures']['width']['quantiles']) == ['1%', '5%', '50%', '95%', '99%']
    assert doc['probabilities']['bistable']['method'] == 'clopper-pearson'
    assert set(doc['sensitivity']['figures']['width']) == {'ka', 'kb', 'kc', 'L2', 'f3y'}
    assert len(doc['worst']) == 2 and doc['worst'][0]['replay'][0].startswith('tensegrity range')
    assert doc['engine']['engine'] == 'in-process'
    path = tmp_path / 'samples.csv'
    code, _, _ = run(argv + ['--csv', str(path)])
    rows = list(csv.reader(path.open()))
    assert rows[0][:6] == ['sample', 'ka', 'kb', 'kc', 'L2', 'f3y'] and len(rows) == 257
    width = rows[0].index('width')
    assert float(rows[1][width]) == pytest.approx(doc['figures']['width']['mean'], rel=0.1)


def test_path_plots_and_wilson_interval(tmp_path):
    prefix = str(tmp_path / 'c1')
    code, text, _ = run(['tolerance', 'path', *C1, '--to', 'rho=0.157',
                         '--tol', 'L2=normal:0.001', '--samples', '128', '--processes', '1',
                         '--interval', 'wilson', '--plot', prefix, '--sampler', 'lhs'])
    assert code == 0 and '(wilson)' in text and 'jumped:' in text
    for name in ('_histograms.png', '_sensitivity.png'):
        data = open(prefix + name, 'rb').read()
        assert data[:8] == b'\x89PNG\r\n\x1a\n' and len(data) > 5000


def test_neck_head_load_writes_replayable_parameter_files(tmp_path):
    code, out, _ = run(['tolerance', 'head-load', '--config', 'config/neck.yaml',
                        '--to', 'F=-9', '--tol', 'm2.k=3%', '--samples', '3',
                        '--processes', '1', '--worst', '1', '--replay-dir', str(tmp_path),
                        '--json', '-'])
    assert code == 0
    doc = json.loads(out)
    worst = doc['worst'][0]
    assert [t['parameter'] for t in doc['tolerances']] == ['m2.ka', 'm2.kb', 'm2.kc']
    config = load_stack_config(str(tmp_path / worst['config_file']))
    params = worst['parameters']
    assert config.modules[2].params.ka == params['m2.ka']        # exactly (repr floats)
    assert config.modules[0].params.ka == 300.0
    assert config.modules[2].params.f3y == -0.5                  # the start load of the file
    assert worst['replay'][0].endswith('--to-F3 -9.0 --to-F4 -9.0')


def test_invalid_samples_are_counted_not_fatal():
    code, out, _ = run(['tolerance', 'range', '--rho', '0.5', '--F', '5', '--m2', '0.01',
                        '--tol', 'm2=normal:0.01', '--samples', '64', '--processes', '1',
                        '--json', '-'])
    doc = json.loads(out)
    assert code == 0 and 0 < doc['status']['invalid parameters'] < 64
    assert doc['valid'] == 64 - doc['status']['invalid parameters']


@pytest.mark.parametrize('argv, message', [
    (['tolerance', 'range', '--rho', '0.5'], 'at least one tolerance'),
    (['tolerance', 'range', '--rho', '0.5', '--tol', 'k'], 'NAME=SPREAD'),
    (['tolerance', 'range', '--rho', '0.5', '--tol', 'q=5%'], "unknown parameter 'q'"),
    (['tolerance', 'range', '--rho', '0.5', '--tol', 'k=5%%'], 'bad tolerance'),
    (['tolerance', 'range', '--rho', '0.5', '--tol', 'F3=5%'], 'give an absolute one'),
    (['tolerance', 'range', '--rho', '0.5', '--tol', 'k=1%', '--tol', 'ka=1%'],
     'toleranced twice'),
    (['tolerance', 'range', '--tol', 'k=5%'], 'needs rho'),
    (['tolerance', 'path', '--rho', '0.5', '--tol', 'k=5%'], 'at least one waypoint'),
    (['tolerance', 'path', '--rho', '0.5', '--tol', 'k=5%', '--to', 'rho'], 'NAME=VALUE'),
    (['tolerance', 'path', '--rho', '0.5', '--tol', 'k=5%', '--to', 'rho=-1'],
     'rho must be positive'),
    (['tolerance', 'head-load', '--rho', '0.5', '--tol', 'k=5%', '--to', 'F=-5',
      '--to', 'F=-6'], 'needs the end load'),
    (['tolerance', 'path', '--rho', '0.5', '--tol', 'k=5%', '--to', 'rho=0.4',
      '--processes', '2', '--scheduler', 'tcp://127.0.0.1:1'], 'not both'),
    (['tolerance', 'path', '--config', 'nowhere.yaml', '--tol', 'k=5%', '--to', 'rho=0.4'],
     'no such file'),
    (['tolerance', 'path', '--rho', '0.5', '--tol', 'k=5%', '--to', 'rho=0.4',
      '--theta', '1', '1'], 'for a neck'),
    (['tolerance', 'range', '--rho', '0.5', '--tol', 'k=5%', '--json', '/nowhere/x.json'],
     'does not exist'),
    (['tolerance', 'range', '--rho', '0.5', '--tol', 'k=5%', '--confidence', '1.5'],
     'between 0 and 1'),
    (['tolerance', 'path', '--rho', '0.5', '--tol', 'x.k=5%', '--to', 'rho=0.4'],
     "unknown module 'x'"),
])
def test_bad_command_lines_are_refused_in_one_line(argv, message):
    code, out, err = run(argv + ['--processes', '1'] if '--processes' not in argv
                         and '--scheduler' not in argv else argv)
    assert code == 2, (out, err)
    assert message in err and err.count('\n') == 1, err


def test_an_unreachable_scheduler_is_an_error_not_a_hang(monkeypatch):
    from tensegrity_ros.tolerance import engine
    monkeypatch.setattr(engine, 'CONNECT_TIMEOUT', 2.0)     # 30 s by default
    code, _, err = run(['tolerance', 'range', '--rho', '0.5', '--tol', 'k=5%', '--samples',
                        '8', '--scheduler', 'tcp://127.0.0.1:9'])
    assert code == 1 and 'error' in err


def test_the_same_seed_gives_the_same_report_and_another_seed_another():
    argv = ['tolerance', 'range', *C1, '--tol', 'k=5%', '--samples', '64', '--processes', '1',
            '--json', '-']
    a = json.loads(run(argv)[1])
    b = json.loads(run(argv)[1])
    c = json.loads(run(argv + ['--seed', '1'])[1])
    assert a['figures'] == b['figures'] and a['figures'] != c['figures']
    assert np.isfinite(a['figures']['width']['quantiles']['50%'])


def test_a_progress_bar_counts_the_samples():
    from tensegrity_ros.tolerance import module_design, tolerance_study
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        tolerance_study(module_design({'rho': 0.5, 'F': 5.0}), 'range', ['k=5%'], samples=2048,
                        chunk=512, processes=1, progress=True)
    assert '2048/2048' in err.getvalue() and 'samples/s' in err.getvalue()


def test_workers_running_other_code_are_refused():
    from tensegrity_ros.tolerance.engine import _check_workers, WorkerMismatch

    class Client:
        def __init__(self, answer):
            self.answer = answer

        def run(self, function):
            if isinstance(self.answer, Exception):
                raise self.answer
            return self.answer

    def mine():
        return 'abc'
    _check_workers(Client({'tcp://a': 'abc', 'tcp://b': 'abc'}), mine)
    with pytest.raises(WorkerMismatch, match='1 of 2 workers run other tensegrity_ros code'):
        _check_workers(Client({'tcp://a': 'abc', 'tcp://b': 'old'}), mine)
    with pytest.raises(WorkerMismatch, match='cannot run this tensegrity_ros code'):
        _check_workers(Client(AttributeError('no code_fingerprint')), mine)
