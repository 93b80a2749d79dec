"""The offline CLI ``tensegrity`` (DESIGN.md section 6): solve, track, map, diagram.

Run in-process through ``main(argv)``; one test runs the installed console script.
"""
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tensegrity_ros.cli import main
from tensegrity_ros.core import ModuleParams, equilibria, equilibria_batch

# Fig. 8a of the paper: L1 = L2 = 1, F3 = F4 = 5.  C1 (branch point) and C2 (fold)
# are the roots of the paper's eqs. (15) and (16) at F = 5.
C1_RHO = 0.1551013762561726
C2_RHO = 0.874533441919229


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def run_json(capsys, *argv):
    code, out, err = run(capsys, *argv, '--json')
    assert code == 0, err
    return json.loads(out)


# ---------------------------------------------------------------------------
# solve

def test_solve_json_schema_and_values_match_the_core(capsys):
    doc = run_json(capsys, 'solve', '--rho', 0.75, '--F3', -10, '--F4', -10)
    eqs = doc['equilibria']
    assert len(eqs) == 6
    assert sum(e['stable'] for e in eqs) == 2
    reference = equilibria(ModuleParams(rho=0.75, f3y=-10.0, f4y=-10.0))
    assert len(reference) == 6
    for got, ref in zip(eqs, reference):
        assert {'theta1', 'theta2', 'stable', 'eigenvalues', 'energy',
                'actuator_force'} <= set(got)
        assert got['theta1'] == pytest.approx(ref.theta1, abs=1e-12)
        assert got['theta2'] == pytest.approx(ref.theta2, abs=1e-12)
        assert got['stable'] is ref.stable
        assert got['eigenvalues'] == pytest.approx(list(ref.eigenvalues), rel=1e-12)
        assert got['energy'] == pytest.approx(ref.energy, rel=1e-12)
        assert got['actuator_force'] == pytest.approx(ref.actuator_force, rel=1e-12)
        assert got['kind'] == ref.kind
    assert doc['status'] == 'ok'
    assert doc['num_stable'] == 2 and doc['num_equilibria'] == 6
    # Stable ones: y3, y4 of both signs (fig. 4a right: one up, one down).
    stable = [e for e in eqs if e['stable']]
    assert sorted(np.sign([e['theta1'] for e in stable])) == [-1, 1]


def test_solve_table_is_readable(capsys):
    code, out, err = run(capsys, 'solve', '--rho', 0.75, '--F', -10)
    assert code == 0 and err == ''
    lines = out.splitlines()
    assert lines[0].startswith('rho=0.75 ')
    assert 'F3=F4=-10' in lines[0] and '6 equilibria, 2 stable' in lines[0]
    header = lines[1].split()
    for column in ('theta1[deg]', 'theta2[deg]', 'lambda1', 'lambda2', 'kind', 'stable',
                   'energy[J]', 'actuator[N]'):
        assert column in header
    rows = [line.split() for line in lines[2:]]
    assert len(rows) == 6
    assert sum(r[header.index('stable')] == 'yes' for r in rows) == 2
    reference = equilibria(ModuleParams(rho=0.75, f3y=-10.0, f4y=-10.0))
    for row, ref in zip(rows, reference):
        assert float(row[1]) == pytest.approx(math.degrees(ref.theta1), abs=1e-3)
        assert row[header.index('kind')] == ref.kind


def test_solve_unloaded_parallelogram_and_options(capsys):
    doc = run_json(capsys, 'solve', '--rho', 1, '--L2', 1.5)
    stable = [e for e in doc['equilibria'] if e['stable']]
    assert len(stable) == 2                       # fig. 3 right: two mirrored solutions
    for e in stable:
        assert e['A3'][1] == pytest.approx(e['A4'][1], abs=1e-9)          # y3 = y4
        assert e['A3'][0] - e['A4'][0] == pytest.approx(1.0, abs=1e-9)     # x3 - x4 = rho
    doc = run_json(capsys, 'solve', '--rho', 0.6, '--k', 50, '--ka', 80, '--F', 5,
                   '--F4', 3, '--F3x', 1, '--F4x', -2, '--m1', 0.1, '--L1', 1.2)
    p = doc['params']
    assert (p['ka'], p['kb'], p['kc']) == (80.0, 50.0, 50.0)
    assert (p['f3y'], p['f4y'], p['f3x'], p['f4x']) == (5.0, 3.0, 1.0, -2.0)
    assert (p['m1'], p['L1']) == (0.1, 1.2)
    ref = equilibria(ModuleParams(rho=0.6, L1=1.2, ka=80, kb=50, kc=50, f3y=5, f4y=3,
                                  f3x=1, f4x=-2, m1=0.1))
    assert [e['theta1'] for e in doc['equilibria']] == pytest.approx([e.theta1 for e in ref])


# ---------------------------------------------------------------------------
# bad arguments: exit status 2, one line on stderr, no traceback

BAD_ARGUMENTS = [
    [],
    ['frobnicate'],
    ['solve'],
    ['solve', '--rho', 'nan'],
    ['solve', '--rho', 'inf'],
    ['solve', '--rho', 'abc'],
    ['solve', '--rho', '-1'],
    ['solve', '--rho', '0'],
    ['solve', '--rho', '1', '--L2', '-1'],
    ['solve', '--rho', '1', '--L1', '0'],
    ['solve', '--rho', '1', '--k', '-5'],
    ['solve', '--rho', '1', '--kc', '0'],
    ['solve', '--rho', '1', '--m2', '-0.5'],
    ['solve', '--rho', '1', '--F3', 'NaN'],
    ['solve', '--rho', '1', '--bogus', '2'],
    ['track', '--to-rho', '1'],
    ['track', '--rho', '0.5', '--to-rho', '-1'],
    ['track', '--rho', '0.5', '--to-rho', '1', '--to-L2', 'nan'],
    ['track', '--rho', '0.5', '--to-rho', '1', '--theta1', '1'],
    ['track', '--rho', '0.5', '--to-rho', '1', '--theta1', 'x', '--theta2', '1'],
    ['map', '--x', 'zeta', '0.1', '1', '10', '--y', 'F', '0', '1', '10', '--rho', '1'],
    ['map', '--x', 'rho', '0.1', '1', '0', '--y', 'F', '0', '1', '10'],
    ['map', '--x', 'rho', '0.1', '1', '-3', '--y', 'F', '0', '1', '10'],
    ['map', '--x', 'rho', '0.1', '1', 'ten', '--y', 'F', '0', '1', '10'],
    ['map', '--x', 'rho', '0.1', '1', '2.5', '--y', 'F', '0', '1', '10'],
    ['map', '--x', 'rho', 'nan', '1', '10', '--y', 'F', '0', '1', '10'],
    ['map', '--x', 'rho', '-1', '1', '10', '--y', 'F', '0', '1', '10'],
    ['map', '--x', 'rho', '1', '0.5', '10', '--y', 'F', '0', '1', '10'],
    ['map', '--x', 'L2', '0', '1', '10', '--y', 'F', '0', '1', '10', '--rho', '1'],
    ['map', '--x', 'rho', '0.1', '1', '10', '--y', 'rho', '0.1', '1', '10'],
    ['map', '--x', 'rho', '0.1', '1', '10', '--y', 'F', '0', '1', '10', '--F3', '2'],
    ['map', '--x', 'rho', '0.1', '1', '10', '--y', 'F3', '0', '1', '10', '--F', '2', '--F3', '1'],
    ['map', '--x', 'L2', '0.1', '1', '10', '--y', 'F', '0', '1', '10'],
    ['map', '--x', 'rho', '0.1', '1', '10', '--y', 'F', '0', '1'],
    ['map', '--x', 'rho', '0.1', '1', '10', '--y', 'F', '0', '1', '10', '--jobs', '-1'],
    ['map', '--x', 'rho', '0.1', '1', '10', '--y', 'F', '0', '1', '10', '--csv',
     '/nonexistent-dir/out.csv'],
    ['map', '--x', 'rho', '0.1', '1', '10', '--y', 'F', '0', '1', '10', '--L1', '-2'],
    ['diagram', '--from-rho', '0', '--to-rho', '2', '--png', 'x.png'],
    ['diagram', '--from-rho', '1', '--to-rho', '0.5', '--png', 'x.png'],
    ['diagram', '--from-rho', '0.1', '--to-rho', '2', '--count', '0', '--png', 'x.png'],
    ['diagram', '--from-rho', '0.1', '--to-rho', '2', '--count', '1', '--png', 'x.png'],
    ['diagram', '--from-rho', '0.1', '--to-rho', '2'],
    ['diagram', '--from-rho', '0.1', '--to-rho', '2', '--png', 'x.png', '--track', '0.5'],
    ['diagram', '--from-rho', '0.1', '--to-rho', '2', '--png', 'x.png', '--track', '0.5', '-1'],
    ['diagram', '--from-rho', '0.1', '--to-rho', '2', '--png', 'x.png', '--theta1', '1',
     '--theta2', '1'],
    ['diagram', '--from-rho', '0.1', '--to-rho', '2', '--png', 'x.png', '--L2', 'inf'],
]


@pytest.mark.parametrize('argv', BAD_ARGUMENTS, ids=lambda a: ' '.join(a) or '(none)')
def test_bad_arguments_exit_2_with_one_line(capsys, argv, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, *argv)
    assert code == 2
    assert out == ''
    assert len(err.splitlines()) == 1, err
    assert 'error' in err
    assert 'Traceback' not in err
    assert not (tmp_path / 'x.png').exists()


def test_help_returns_zero(capsys):
    code, out, _ = run(capsys, '--help')
    assert code == 0 and 'solve' in out and 'diagram' in out
    code, out, _ = run(capsys, 'map', '--help')
    assert code == 0 and 'COUNT' in out


def test_console_script_entry_point(tmp_path):
    script = Path(sys.executable).with_name('tensegrity')
    if not script.exists():
        pytest.skip(f'console script not installed at {script}')
    done = subprocess.run([str(script), 'solve', '--rho', '0.75', '--F', '-10', '--json'],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    doc = json.loads(done.stdout)
    assert len(doc['equilibria']) == 6
    assert sum(e['stable'] for e in doc['equilibria']) == 2
    done = subprocess.run([str(script), 'solve', '--rho', 'nan'],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    assert len(done.stderr.splitlines()) == 1 and 'Traceback' not in done.stderr


def test_cli_does_not_import_rclpy_or_matplotlib_for_solve():
    code = ('import sys; from tensegrity_ros.cli import main; '
            'rc = main(["solve", "--rho", "0.5"]); '
            'bad = [m for m in ("rclpy", "matplotlib") if m in sys.modules]; '
            'print(bad); sys.exit(1 if bad or rc else 0)')
    done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stdout + done.stderr


# ---------------------------------------------------------------------------
# track (fig. 8a: L1 = L2 = 1, F3 = F4 = 5)

FIG8A = ('--F3', 5, '--F4', 5, '--L1', 1, '--L2', 1)
LOWER = ('--theta1', -1, '--theta2', -1)


def _track(capsys, start, end, *extra):
    return run_json(capsys, 'track', '--rho', start, '--to-rho', end, *FIG8A, *extra)


def _check_schema(doc):
    assert set(doc) >= {'events', 'final'}
    assert set(doc['final']) >= {'theta1', 'theta2', 'stable'}
    for e in doc['events']:
        assert set(e) >= {'kind', 's', 'rho', 'theta1', 'theta2', 'landing'}
        assert set(e['landing']) >= {'theta1', 'theta2'}


def test_track_branch_point_c1(capsys):
    doc = _track(capsys, 0.5, 0.1, *LOWER)
    _check_schema(doc)
    assert doc['start']['theta1'] < 0 and doc['start']['theta2'] < 0      # lower branch
    assert len(doc['events']) == 1
    event = doc['events'][0]
    assert event['kind'] == 'branch_point'
    assert event['rho'] == pytest.approx(C1_RHO, abs=1e-6)
    assert event['rho'] == pytest.approx(0.5 + event['s'] * (0.1 - 0.5), abs=1e-12)
    assert event['theta1'] < 0 and event['theta2'] < 0
    assert event['landing']['theta1'] > 0 and event['landing']['theta2'] > 0
    final = doc['final']
    assert final['stable'] is True and final['theta1'] > 0
    ref = [e for e in equilibria(ModuleParams(rho=0.1, f3y=5, f4y=5)) if e.stable]
    assert len(ref) == 1
    assert final['theta1'] == pytest.approx(ref[0].theta1, abs=1e-7)


def test_track_fold_c2(capsys):
    doc = _track(capsys, 0.5, 1.2, *LOWER)
    _check_schema(doc)
    assert [e['kind'] for e in doc['events']] == ['fold']
    event = doc['events'][0]
    assert event['rho'] == pytest.approx(C2_RHO, abs=1e-6)
    assert event['landing']['theta1'] > 0 and event['landing']['theta2'] > 0
    assert doc['final']['stable'] is True and doc['final']['theta1'] > 0
    assert doc['status'] == 'ok'


@pytest.mark.parametrize('end', [0.16, 0.87])
def test_track_stopping_short_of_the_event_has_no_event(capsys, end):
    doc = _track(capsys, 0.5, end, *LOWER)
    _check_schema(doc)
    assert doc['events'] == []
    assert doc['final']['stable'] is True
    assert doc['final']['theta1'] < 0 and doc['final']['theta2'] < 0      # still lower


def test_track_default_start_is_the_upper_branch(capsys):
    doc = _track(capsys, 0.5, 1.2)
    assert doc['start']['theta1'] > 0 and doc['events'] == []
    assert doc['final']['theta1'] > 0


def test_track_moves_forces_too(capsys):
    # Pushing to pulling at rho = 0.75 from the lower configuration: it ends up.
    doc = run_json(capsys, 'track', '--rho', 0.75, '--to-rho', 0.75, '--F', -10, '--to-F', 10,
                   '--theta1', -1, '--theta2', -1)
    _check_schema(doc)
    assert doc['final']['params']['f3y'] == 10.0 and doc['final']['params']['f4y'] == 10.0
    assert doc['final']['stable'] is True


def test_track_text_output(capsys):
    code, out, err = run(capsys, 'track', '--rho', 0.5, '--to-rho', 0.1, *FIG8A, *LOWER)
    assert code == 0, err
    assert 'event 1: branch_point' in out and 'lands at' in out
    assert out.splitlines()[-1].startswith('final:')


# ---------------------------------------------------------------------------
# map

def _read_csv(path):
    lines = Path(path).read_text().splitlines()
    return lines[0].split(','), np.array([[float(v) for v in line.split(',')]
                                          for line in lines[1:]])


def test_map_csv_matches_equilibria_batch(capsys, tmp_path):
    csv = tmp_path / 'map.csv'
    code, out, err = run(capsys, 'map', '--x', 'rho', 0.05, 1.95, 24, '--y', 'F', -10, 10, 11,
                         '--csv', csv)
    assert code == 0, err
    header, rows = _read_csv(csv)
    assert header == ['rho', 'F', 'num_stable']
    assert rows.shape == (24 * 11, 3)
    rho = np.tile(np.linspace(0.05, 1.95, 24), 11)          # x varies fastest
    force = np.repeat(np.linspace(-10, 10, 11), 24)
    assert np.allclose(rows[:, 0], rho) and np.allclose(rows[:, 1], force)
    batch = equilibria_batch(rho=rows[:, 0], f3y=rows[:, 1], f4y=rows[:, 1])
    assert np.array_equal(rows[:, 2].astype(int), batch.num_stable)
    for r, f, n in rows[::17]:
        assert equilibria(ModuleParams(rho=r, f3y=f, f4y=f)).num_stable == int(n)
    assert set(rows[:, 2].astype(int)) == {1, 2}
    assert '1 stable' in out and '2 stable' in out


def test_map_png_written(capsys, tmp_path):
    png = tmp_path / 'map.png'
    code, out, err = run(capsys, 'map', '--x', 'rho', 0.01, 4, 40, '--y', 'L2', 0.01, 4, 30,
                         '--png', png)
    assert code == 0, err
    data = png.read_bytes()
    assert data[:8] == b'\x89PNG\r\n\x1a\n' and len(data) > 5000


def test_map_other_axes_and_stdout_csv(capsys):
    code, out, err = run(capsys, 'map', '--x', 'F3x', -5, 5, 4, '--y', 'k', 50, 150, 3,
                         '--rho', 0.6, '--F4', 2, '--csv', '-')
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0] == 'F3x,k,num_stable' and len(lines) == 13
    f3x, k, n = (float(v) for v in lines[5].split(','))
    ref = equilibria(ModuleParams(rho=0.6, f3x=f3x, ka=k, kb=k, kc=k, f4y=2)).num_stable
    assert int(n) == ref
    assert 'stable' in err              # the summary goes to stderr when the CSV is on stdout


def test_map_parallel_equals_serial():
    from tensegrity_ros.figures import compute_map
    axes = (('rho', 0.05, 2.0, 37), ('L2', 0.05, 2.0, 29))
    serial = compute_map({'F': -10.0}, *axes, jobs=1, progress=False, chunk=100)
    parallel = compute_map({'F': -10.0}, *axes, jobs=2, progress=False, chunk=100)
    assert parallel.jobs == 2
    assert np.array_equal(serial.num_stable, parallel.num_stable)
    # Fig. 7: two stable at L2 = 3/2, rho = 7/10; one at rho = 3/2.
    assert equilibria(ModuleParams(rho=0.7, L2=1.5, f3y=-10, f4y=-10)).num_stable == 2
    assert equilibria(ModuleParams(rho=1.5, L2=1.5, f3y=-10, f4y=-10)).num_stable == 1


# ---------------------------------------------------------------------------
# diagram

def test_diagram_png_and_csv(capsys, tmp_path):
    png, csv = tmp_path / 'd.png', tmp_path / 'd.csv'
    code, out, err = run(capsys, 'diagram', '--from-rho', 0.05, '--to-rho', 1.5, '--count', 60,
                         *FIG8A, '--png', png, '--csv', csv, '--track', 0.5, 0.1, 0.5, *LOWER)
    assert code == 0, err
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    header = csv.read_text().splitlines()[0]
    assert header == 'branch,rho,theta1,theta2,lambda_min,stable,point'
    assert 'branch_point at rho=0.155101' in out
    assert 'fold at rho=0.874533' in out
    assert 'track rho 0.5 -> 0.1: branch_point' in out
    assert 'track rho 0.1 -> 0.5: no jump' in out
