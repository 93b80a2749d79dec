"""The offline CLI ``tensegrity`` (docs/cli.md): solve, track, map, diagram.

Run in-process through ``main(argv)``; one test runs the installed console script.
"""
import json
import math
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from installed import installed_script
from tensegrity_ros.cli import main
from tensegrity_ros.core import equilibria, equilibria_batch, ModuleParams

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
    # stack
    ['solve', '--modules', '2'],
    ['solve', '--modules', '0', '--rho', '1'],
    ['solve', '--modules', '2', '--rhos', '0.5'],
    ['solve', '--rho', '0.5', '--rhos', '0.5', '0.6'],
    ['solve', '--rhos', '0.5', '-0.6'],
    ['solve', '--modules', '2', '--rho', '0.7', '--L2', '-1'],
    ['solve', '--modules', '2', '--rho', '0.7', '--method', 'exact'],
    ['solve', '--modules', '2', '--rho', '0.7', '--method', 'newton'],
    ['solve', '--modules', '2', '--rho', '0.7', '--starts', '0'],
    ['solve', '--rho', '0.7', '--starts', '5'],
    ['solve', '--config', 'missing.yaml'],
    ['solve', '--node', 'x', '--rho', '1'],
    ['track', '--modules', '2', '--rho', '0.7', '--to-rho', '0.6', '--theta', '1', '2', '3'],
    ['track', '--rho', '0.7', '--to-rho', '0.6', '--theta', '1', '2', '3'],
    ['track', '--modules', '2', '--rho', '0.7', '--to-rho', '0.6', '--theta1', '1',
     '--theta2', '1'],
    ['track', '--modules', '2', '--rho', '0.7', '--to-rhos', '0.6'],
    ['track', '--modules', '2', '--rho', '0.7', '--to-rho', '0.6', '--to-rhos', '0.6', '0.6'],
    ['track', '--modules', '2', '--rho', '0.7', '--to-rho', '0.6', '--theta', '1', 'x', '1',
     '1'],
    # exact boundaries, range, limit
    ['map', '--x', 'rho', '0.1', '1', '10', '--y', 'm1', '0', '1', '10', '--boundaries-csv',
     'b.csv'],
    ['map', '--x', 'rho', '0.1', '1', '10', '--y', 'F', '0', '1', '10', '--boundaries'],
    ['map', '--x', 'rho', '0.1', '1', '10', '--y', 'F', '0', '1', '10', '--boundaries-csv',
     '/nonexistent-dir/b.csv'],
    ['map', '--x', 'rho', '0.1', '1', '10', '--y', 'F', '0', '1', '10', '--csv', '-',
     '--boundaries-csv', '-'],
    ['range'],
    ['range', '--rho', '0.5', '--theta1', '1'],
    ['range', '--rho', '0.5', '--rho-bounds', '0.6', '1'],
    ['range', '--rho', '0.5', '--rho-bounds', '1', '0.6'],
    ['range', '--rho', 'nan'],
    ['limit', '--L2', '-1'],
    ['limit', '--L2', '1', '--F3', '1'],
    ['limit', '--k', '0'],
    # outside the supported magnitudes (these overflowed into a traceback once)
    ['solve', '--rho', '0.72', '--L1', '5.6e99', '--L2', '1.27e6', '--F4', '1e29'],
    ['solve', '--rho', '0.88', '--L1', '1.9e-12', '--L2', '5.4e-301', '--k', '1.7e-30'],
    ['solve', '--rho', '0.5', '--F', '-1e60'],
    ['track', '--rho', '0.5', '--to-rho', '1', '--kc', '1e-60'],
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


def test_console_script_entry_point():
    script = installed_script('tensegrity')
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


def test_track_says_which_side_of_a_symmetric_pitchfork_is_undecided(capsys):
    """The unloaded module through its flat pitchfork at rho = L: no jump; the side it
    buckles to is the tracker's rule, said in an ``undecided:`` line and record.  A load
    doubles resolve (1e-9 N) picks its side: nothing undecided."""
    code, out, err = run(capsys, 'track', '--rho', 1.5, '--to-rho', 0.5, '--F', 0)
    assert code == 0, err
    [line] = [x for x in out.splitlines() if x.startswith('undecided:')]
    assert line.startswith('undecided: branch_point at s=0.500000000 rho=(1):')
    assert 'm of rho) would decide which (below what doubles resolve)' in line
    doc = run_json(capsys, 'track', '--rho', 1.5, '--to-rho', 0.5, '--F', 0)
    [record] = doc['undecided']
    assert record['kind'] == 'undecided' and record['rho'] == pytest.approx(1.0, abs=1e-9)
    assert 0.0 < record['rho_uncertainty'] < 1e-8 and record['s_uncertainty'] > 0.0
    assert doc['events'] == [] and abs(record['theta1']) < 1e-6
    assert run_json(capsys, 'track', '--rho', 1.5, '--to-rho', 0.5, '--F', 1e-9)['undecided'] == []


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


# ---------------------------------------------------------------------------
# the neck stack: solve / track with several modules (docs/model.md section 4)

ROOT = Path(__file__).resolve().parents[1]
NECK = ROOT / 'config' / 'neck.yaml'
DEFAULT = ROOT / 'config' / 'default.yaml'


def wrapped(a, b):
    d = (np.asarray(a, float) - np.asarray(b, float) + np.pi) % (2 * np.pi) - np.pi
    return float(np.max(np.abs(d)))


def _check_stack_equilibrium(e, n, rhos):
    """Schema of one stack equilibrium, and its geometry from the reported nodes."""
    assert set(e) >= {'theta', 'stable', 'eigenvalues', 'energy', 'actuator_forces', 'head'}
    assert np.shape(e['theta']) == (n, 2)
    assert len(e['eigenvalues']) == n + 1            # 4N coordinates, 3N - 1 rigid lengths
    assert e['eigenvalues'] == sorted(e['eigenvalues'])
    assert e['stable'] is (e['eigenvalues'][0] > 0)
    assert len(e['actuator_forces']) == n
    assert set(e['head']) == {'x', 'y', 'angle'}
    assert e['residual'] < 1e-8
    nodes = np.array(e['nodes'])
    assert nodes.shape == (2 + 2 * n, 2)
    for i in range(n - 1):                            # module i+1 stands on module i's chord
        chord = np.linalg.norm(nodes[2 + 2 * i] - nodes[3 + 2 * i])
        assert chord == pytest.approx(rhos[i + 1], abs=1e-9)
    a3, a4 = nodes[-2], nodes[-1]                     # the head is the top chord A4 -> A3
    assert [e['head']['x'], e['head']['y']] == pytest.approx(list(0.5 * (a3 + a4)), abs=1e-12)
    assert e['head']['angle'] == pytest.approx(math.atan2(*(a3 - a4)[::-1]), abs=1e-12)


@pytest.mark.parametrize('method', ['exact', 'multi-start'])
def test_stack_solve_with_one_module_equals_plain_solve(capsys, method):
    args = ('--rho', 0.75, '--F', -10)
    plain = run_json(capsys, 'solve', *args)
    stack = run_json(capsys, 'solve', '--modules', 1, *args, '--method', method,
                     *(('--starts', 32) if method == 'multi-start' else ()))
    assert stack['method'] == method and stack['complete'] is (method == 'exact')
    assert stack['modules'] == ['m0']
    assert stack['params'] == [plain['params']]
    assert len(stack['equilibria']) == len(plain['equilibria']) == 6
    assert stack['num_stable'] == plain['num_stable'] == 2
    energies = [e['energy'] for e in stack['equilibria']]
    assert energies == sorted(energies)
    for ref in plain['equilibria']:
        match = min(stack['equilibria'],
                    key=lambda e: wrapped(e['theta'][0], (ref['theta1'], ref['theta2'])))
        assert wrapped(match['theta'][0], (ref['theta1'], ref['theta2'])) < 1e-9
        _check_stack_equilibrium(match, 1, [0.75])
        assert match['stable'] is ref['stable']
        assert match['energy'] == pytest.approx(ref['energy'], rel=1e-9, abs=1e-9)
        assert match['actuator_forces'][0] == pytest.approx(ref['actuator_force'], abs=1e-8)
        # L1 = L2 = 1: node displacements are the angle changes, same eigenvalues
        assert match['eigenvalues'] == pytest.approx(ref['eigenvalues'], rel=1e-7, abs=1e-7)
        head = 0.5 * (np.array(ref['A3']) + np.array(ref['A4']))
        assert [match['head']['x'], match['head']['y']] == pytest.approx(list(head), abs=1e-12)


def test_stack_solve_one_module_table_says_exact(capsys):
    code, out, err = run(capsys, 'solve', '--modules', 1, '--rho', 0.75, '--F', -10)
    assert code == 0 and err == ''
    assert 'exact (polynomial elimination, complete): 6 equilibria, 2 stable' in out


@pytest.mark.parametrize('argv, rhos', [
    (('--modules', 2, '--rho', 0.7, '--F', -2, '--starts', 16), [0.7, 0.7]),
    (('--rhos', 0.7, 0.65, 0.6, '--F3', -1, '--F4', -0.5, '--F3x', 0.3, '--starts', 12),
     [0.7, 0.65, 0.6]),
], ids=['N2', 'N3'])
def test_stack_solve_json_schema(capsys, argv, rhos):
    doc = run_json(capsys, 'solve', *argv)
    n = len(rhos)
    assert doc['method'] == 'multi-start' and doc['complete'] is False
    assert 'not guaranteed complete' in doc['note']
    assert doc['modules'] == [f'm{i}' for i in range(n)]
    params = doc['params']
    assert [p['rho'] for p in params] == rhos
    # the force options load the head only
    assert all(p['f3y'] == 0.0 and p['f4y'] == 0.0 and p['f3x'] == 0.0 for p in params[:-1])
    assert params[-1]['f3y'] < 0 and params[-1]['f4y'] < 0
    eqs = doc['equilibria']
    assert doc['num_equilibria'] == len(eqs) and doc['num_stable'] == sum(e['stable'] for e in eqs)
    assert doc['num_stable'] >= 1
    energies = [e['energy'] for e in eqs]
    assert energies == sorted(energies)
    for e in eqs:
        _check_stack_equilibrium(e, n, rhos)
    # the stable equilibria are where an independent settle from them stays
    from tensegrity_ros.core.neck.stack import settle_stack, Stack
    stack = Stack(tuple(ModuleParams(**p) for p in params))
    for e in [e for e in eqs if e['stable']][:2]:
        again = settle_stack(stack, np.array(e['theta']) + 1e-3)
        assert wrapped(again.theta, e['theta']) < 1e-7


def test_stack_solve_text(capsys):
    code, out, err = run(capsys, 'solve', '--modules', 2, '--rho', 0.7, '--F', -2, '--starts', 16)
    assert code == 0 and err == ''
    lines = out.splitlines()
    assert lines[0].startswith('2 modules m0, m1 (bottom to top); rho = 0.7, 0.7 m')
    assert 'loads: m1 F3=F4=-2' in lines[0]
    assert 'multi-start search, not guaranteed complete' in lines[1]
    assert lines[2].startswith('#1  ') and 'eigenvalues[N/m]' in lines[2]
    assert lines[3].split() == ['module', 'theta1[deg]', 'theta2[deg]', 'actuator[N]']
    assert lines[4].split()[0] == 'm0' and lines[5].split()[0] == 'm1'


def test_config_file_solve_finds_the_upright_neck(capsys):
    from tensegrity_ros.params_file import load_stack_config
    config = load_stack_config(NECK)
    doc = run_json(capsys, 'solve', '--config', NECK, '--starts', 16)
    assert doc['modules'] == ['m0', 'm1', 'm2']
    assert [p['rho'] for p in doc['params']] == [m.params.rho for m in config.modules]
    assert doc['params'][-1]['f3y'] == -0.5 and doc['params'][0]['f3y'] == 0.0
    assert doc['params'][1]['m1'] == 0.02 and doc['params'][1]['ka'] == 300.0
    upright = [e for e in doc['equilibria']
               if wrapped(e['theta'], config.initial_theta) < 0.03]
    assert len(upright) == 1 and upright[0]['stable']
    for e in doc['equilibria']:
        _check_stack_equilibrium(e, 3, [0.09, 0.085, 0.08])
    head = upright[0]['head']
    assert head['angle'] == pytest.approx(0.0, abs=1e-9)       # symmetric: the head is level
    assert head['x'] == pytest.approx(0.045, abs=1e-12)        # above the middle of the base
    # --stable-only: the same stable equilibria, numbered as in the full list
    code, out, err = run(capsys, 'solve', '--config', NECK, '--starts', 16, '--stable-only')
    assert code == 0 and err == ''
    numbers = [int(line.split()[0][1:]) for line in out.splitlines() if line.startswith('#')]
    assert numbers == [i + 1 for i, e in enumerate(doc['equilibria']) if e['stable']]


def test_config_file_track(capsys):
    doc = run_json(capsys, 'track', '--config', NECK, '--to-rhos', 0.09, 0.085, 0.07)
    assert doc['status'] == 'ok' and doc['events'] == []
    assert doc['start']['guess_source'].startswith('initial_theta of')
    assert doc['start']['stable'] and doc['final']['stable']
    assert doc['final']['rho'] == [0.09, 0.085, 0.07]
    assert np.shape(doc['final']['theta']) == (3, 2)
    assert wrapped(doc['start']['theta'][0], doc['final']['theta'][0]) < 1e-9   # m0 is held
    assert doc['final']['head']['y'] > doc['start']['head']['y']         # shorter top actuator
    # a growing head load buckles the neck sideways, continuously (a supercritical branch
    # point: listed in passages, not a jump), then it folds and lands stable
    doc = run_json(capsys, 'track', '--config', NECK, '--to-F', -30)
    assert doc['status'] == 'ok'
    assert [e['kind'] for e in doc['events']] == ['fold']
    for e in doc['events']:
        assert set(e) >= {'kind', 's', 'rho', 'theta', 'landing'}
        assert e['rho'] == [0.09, 0.085, 0.08]
        assert np.shape(e['theta']) == (3, 2) and np.shape(e['landing']['theta']) == (3, 2)
    [first] = doc['passages']
    assert first['kind'] == 'branch_point' and first['s'] < doc['events'][0]['s']
    assert first['F3'] == pytest.approx(-0.5 + first['s'] * (-30 + 0.5), abs=1e-9)
    assert first['F3'] == pytest.approx(-3.9076778, abs=1e-6)
    before = np.array(first['theta'])
    assert np.max(np.abs(before[:, 0] - before[:, 1])) < 1e-6      # symmetric before
    assert doc['final']['stable'] is True


def test_stack_track_json_schema_and_n1_equals_plain_track(capsys):
    doc = run_json(capsys, 'track', '--modules', 2, '--rho', 0.6, '--to-F', -40)
    assert set(doc) >= {'events', 'final', 'start', 'status'}
    assert doc['start']['guess_source'] == 'upright'
    assert set(doc['final']) >= {'theta', 'stable'} and np.shape(doc['final']['theta']) == (2, 2)
    assert doc['events'] and doc['events'][0]['kind'] == 'branch_point'
    for e in doc['events']:
        assert len(e['rho']) == 2 and np.shape(e['landing']['theta']) == (2, 2)
    # one module: the events of the plain track (fig. 8a, C1 from the lower branch)
    plain = _track(capsys, 0.5, 0.1, *LOWER)
    stack = run_json(capsys, 'track', '--modules', 1, '--rho', 0.5, '--to-rho', 0.1, *FIG8A,
                     '--theta', -1, -1)
    assert [e['kind'] for e in stack['events']] == [e['kind'] for e in plain['events']]
    assert stack['events'][0]['rho'] == [pytest.approx(C1_RHO, abs=1e-6)]
    assert stack['events'][0]['s'] == pytest.approx(plain['events'][0]['s'], abs=1e-9)
    assert wrapped(stack['final']['theta'][0],
                   (plain['final']['theta1'], plain['final']['theta2'])) < 1e-8


def test_stack_track_text(capsys):
    code, out, err = run(capsys, 'track', '--modules', 2, '--rho', 0.6, '--to-F', -40)
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0].startswith('path: 2 modules m0, m1') and lines[1].startswith('  ->  ')
    assert lines[2].startswith('start (upright): theta [deg] m0 (')
    assert lines[3].startswith('event 1: branch_point at s=')     # N = 2: subcritical
    assert lines[-1].startswith('final: theta [deg] m0 (') and 'status ok' in lines[-1]
    # config/neck.yaml: the supercritical sideways buckling is passed, then the fold jumps
    code, out, err = run(capsys, 'track', '--config', NECK, '--to-F', -30)
    assert code == 0, err
    lines = out.splitlines()
    assert lines[3].startswith('passed: branch_point at s=0.115514501 ')
    assert lines[3].endswith('buckled continuously (supercritical: no jump)')
    # a mirror-symmetric neck: which side it buckles to is not the model's to decide
    assert lines[4].startswith('undecided: branch_point at s=0.115514501 ')
    assert 'passed continuously to one side' in lines[4] and ' m of rho' not in lines[4]
    assert lines[5].startswith('event 1: fold at s=0.227085456 ')
    code, out, err = run(capsys, 'track', '--config', NECK, '--to-F', -30, '--json')
    [undecided] = json.loads(out)['undecided']
    assert undecided['kind'] == 'undecided' and 0.0 < undecided['s_uncertainty'] < 1e-8
    assert undecided['rho_uncertainty'] == [0.0, 0.0, 0.0] and len(undecided['theta']) == 3


def test_config_file_layouts(capsys, tmp_path):
    # ROS 2 also accepts a named node entry and flat 'm.key' parameter names
    text = """
tensegrity:
  ros__parameters:
    modules: [base, head]
    publish_rate: 20.0
    base.L1: 1
    base.L2: 1.2
    base.k: 150
    base.kc: 90.0
    base.rho_initial: 0.7
    base.initial_theta: [0.8, 0.8]
    base.colour: red
    head:
      k: 100
      m1: 0.1
      force_a3: [0.5, -1.0]
      force_a4: [0, -2]
      rho_initial: 0.6
"""
    path = tmp_path / 'two.yaml'
    path.write_text(text)
    doc = run_json(capsys, 'track', '--config', path, '--to-rhos', 0.7, 0.55)
    base, head = doc['start']['params']
    assert (base['L2'], base['ka'], base['kb'], base['kc']) == (1.2, 150.0, 150.0, 90.0)
    assert (head['f3x'], head['f3y'], head['f4x'], head['f4y']) == (0.5, -1.0, 0.0, -2.0)
    assert head['m1'] == 0.1 and head['rho'] == 0.6 and head['L1'] == 1.0
    assert doc['start']['guess'] == [[0.8, 0.8], [0.7, 0.7]]     # node default for head
    assert doc['status'] == 'ok' and doc['final']['rho'] == [0.7, 0.55]
    # CLI options override the file: geometry for every module, forces for the head
    code, out, err = run(capsys, 'solve', '--config', path, '--L2', 1.1, '--F4', -3,
                         '--starts', 8, '--json')
    assert code == 0
    assert "ignoring unknown parameter 'base.colour'" in err
    base, head = json.loads(out)['params']
    assert base['L2'] == head['L2'] == 1.1
    assert base['f4y'] == 0.0 and head['f4y'] == -3.0 and head['f3y'] == -1.0
    # the one-module default file is the paper's module at rho = 0.75
    doc = run_json(capsys, 'solve', '--config', DEFAULT)
    plain = run_json(capsys, 'solve', '--rho', 0.75)
    assert doc['method'] == 'exact' and len(doc['equilibria']) == len(plain['equilibria'])


@pytest.mark.parametrize('text', [
    'not: [a, parameter, file',
    '- 1\n- 2\n',
    'node:\n  params:\n    modules: [m0]\n',
    '/**:\n  ros__parameters:\n    modules: [m0]\n    m0.L1: -1\n',
    '/**:\n  ros__parameters:\n    modules: [m0]\n    m0.force_a3: [1]\n',
    '/**:\n  ros__parameters:\n    modules: [m0]\n    m0.k: abc\n',
    '/**:\n  ros__parameters:\n    modules: [m0, m0]\n',
    '/**:\n  ros__parameters:\n    modules: ["0bad"]\n',
    'a:\n  ros__parameters: {modules: [m0]}\nb:\n  ros__parameters: {modules: [m1]}\n',
], ids=['yaml', 'list', 'no-ros-params', 'negative', 'pair', 'string', 'repeat', 'name',
        'two-nodes'])
def test_bad_config_files_exit_2(capsys, tmp_path, text):
    path = tmp_path / 'bad.yaml'
    path.write_text(text)
    code, out, err = run(capsys, 'solve', '--config', path)
    assert code == 2 and out == ''
    assert len(err.splitlines()) == 1 and 'error' in err and 'Traceback' not in err


def test_stack_cli_does_not_import_rclpy_or_matplotlib():
    code = ('import sys; from tensegrity_ros.cli import main; '
            f'rc = main(["solve", "--config", {str(NECK)!r}, "--starts", "4", "--json"]); '
            'bad = [m for m in ("rclpy", "matplotlib") if m in sys.modules]; '
            'print(bad, file=sys.stderr); sys.exit(1 if bad or rc else 0)')
    done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]


# ---------------------------------------------------------------------------
# exact boundaries over a map; operation range; point C

def paper_polynomials(F):
    """Coefficients (in rho, highest first) of the paper's eqs. (15) and (16) at F
    (L = 1, k = 100)."""
    p15 = [64e12, 0, 48e8 * F**2, 0, 12e4 * F**4 - 16e8 * F**2, 0, F**6]
    p16 = [64e12, 0, 48e8 * F**2 - 192e12, 0, 12e4 * F**4 + 336e8 * F**2 + 192e12, 0,
           F**6 - 12e4 * F**4 + 48e8 * F**2 - 64e12]
    return p15, p16


def relative_value(coefficients, x):
    powers = x ** np.arange(len(coefficients) - 1, -1, -1)
    return abs(np.dot(coefficients, powers)) / np.dot(np.abs(coefficients), np.abs(powers))


def test_map_boundaries_csv_lies_on_eqs_15_and_16(capsys, tmp_path):
    csv, png = tmp_path / 'b.csv', tmp_path / 'b.png'
    code, out, err = run(capsys, 'map', '--x', 'rho', 0.004, 2, 40, '--y', 'F', -10, 0, 30,
                         '--boundaries', '--boundaries-csv', csv, '--png', png)
    assert code == 0, err
    assert 'boundaries: 2 curves (1 branch_point, 1 fold' in out
    lines = csv.read_text().splitlines()
    assert lines[0] == 'curve,x,y,stable_boundary,kind'
    rows = [line.split(',') for line in lines[1:]]
    assert len(rows) > 100
    kinds = {}
    for curve, x, y, flag, kind in rows:
        kinds.setdefault(kind, []).append((float(x), float(y), flag))
    assert set(kinds) == {'branch_point', 'fold'}
    for kind, which in (('branch_point', 0), ('fold', 1)):
        points = kinds[kind]
        assert all(flag == '1' for _, _, flag in points)     # both bound the 2-stable region
        for rho, F, _ in points[5::len(points) // 4]:        # a few points along each curve
            assert -10 <= F <= 0 and 0.004 <= rho <= 2
            assert relative_value(paper_polynomials(F)[which], rho) < 1e-9, (kind, rho, F)
    # the curves are where the map's count changes: F = -10 gives the fig. 4a interval
    ends = sorted(x for x, y, _ in kinds['branch_point'] + kinds['fold'] if y == -10)
    assert ends == pytest.approx([0.2149, 0.8034], abs=1e-3)
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_map_boundaries_csv_to_stdout(capsys):
    code, out, err = run(capsys, 'map', '--x', 'rho', 0.005, 4, 20, '--y', 'L2', 0.005, 4, 20,
                         '--boundaries-csv', '-')
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0] == 'curve,x,y,stable_boundary,kind'
    assert 'boundaries: 3 curves (3 branch_point' in err
    for line in lines[1::25]:                  # fig. 3: the three lines of DESIGN section 2
        _, rho, L2, flag, kind = line.split(',')
        rho, L2 = float(rho), float(L2)
        assert min(abs(2 * rho - L2 - 1), abs(2 * rho - L2 + 1), abs(2 * rho + L2 - 1)) < 1e-9


def test_range_fig8a_lower_branch(capsys):
    doc = run_json(capsys, 'range', '--rho', 0.5, *FIG8A, *LOWER)
    assert doc['rho_min'] == pytest.approx(0.1551013763, abs=1e-6)
    assert doc['rho_max'] == pytest.approx(0.8745334419, abs=1e-6)
    assert doc['rho_min'] == pytest.approx(C1_RHO, abs=1e-9)
    assert doc['rho_max'] == pytest.approx(C2_RHO, abs=1e-9)
    assert doc['lower']['kind'] == 'branch_point' and doc['lower']['symmetry'] == 'swap'
    assert doc['upper']['kind'] == 'fold'
    assert doc['start']['theta1'] < 0 and doc['start']['theta2'] < 0
    assert doc['width'] == pytest.approx(doc['rho_max'] - doc['rho_min'])
    code, out, err = run(capsys, 'range', '--rho', 0.5, *FIG8A, *LOWER)
    assert code == 0, err
    assert 'rho_min = 0.1551013763  (branch_point, swap symmetry)' in out
    assert 'rho_max = 0.8745334419  (fold)' in out
    # the upper branch is stable over the whole search interval
    doc = run_json(capsys, 'range', '--rho', 0.5, *FIG8A, '--rho-bounds', 0.05, 2)
    assert (doc['lower']['kind'], doc['upper']['kind']) == ('limit', 'limit')
    assert (doc['rho_min'], doc['rho_max']) == (0.05, 2.0)


def test_limit_point_c(capsys):
    doc = run_json(capsys, 'limit', '--L2', 1)
    assert doc['F3'] == pytest.approx(70.7106781187, abs=1e-6)
    assert doc['F4'] == pytest.approx(70.7106781187, abs=1e-6)
    # rho = L1 L2 / (2 sqrt(L1^2 + L2^2))
    assert doc['rho'] == pytest.approx(0.5 / math.sqrt(2), abs=1e-9)
    doc = run_json(capsys, 'limit', '--L2', 1, '--pushing')
    assert doc['F3'] == pytest.approx(-70.7106781187, abs=1e-6) and doc['side'] == 'pushing'
    doc = run_json(capsys, 'limit', '--L2', 1.5, '--k', 50)
    # closed form k (L2^2, L1^2) / sqrt(L1^2 + L2^2)
    assert doc['F3'] == pytest.approx(50 * 2.25 / math.sqrt(3.25), rel=1e-10)
    assert doc['F4'] == pytest.approx(50 * 1.0 / math.sqrt(3.25), rel=1e-10)
    code, out, err = run(capsys, 'limit', '--L2', 1)
    assert code == 0, err
    assert 'F3 = 70.7106781187 N, F4 = 70.7106781187 N' in out
