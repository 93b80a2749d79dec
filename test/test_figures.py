"""The paper's figures as computed by tensegrity_ros.figures (maps and diagrams).

Maps are checked against the paper's closed-form boundaries: the three lines of
fig. 3 and the degree-6 curves (15), (16) of fig. 4; diagrams against the folds
and branch points of fig. 8 (the roots of (15)/(16) at F = 5).
"""
import numpy as np
import pytest

from tensegrity_ros.cli import main
from tensegrity_ros.figures import compute_diagram, compute_map, plot_diagram, plot_map

C1_RHO = 0.1551013762561726      # eq. (15) at F = 5: branch point of fig. 8a
C2_RHO = 0.874533441919229       # eq. (16) at F = 5: fold of fig. 8a


def _positive_real_roots(coefficients):
    return sorted(r.real for r in np.roots(coefficients) if abs(r.imag) < 1e-9 and r.real > 0)


def paper_boundaries(F):
    """rho on eqs. (15) (largest root) and (16) at F4 = F (L = 1, k = 100)."""
    p15 = [64e12, 0, 48e8 * F**2, 0, 12e4 * F**4 - 16e8 * F**2, 0, F**6]
    p16 = [64e12, 0, 48e8 * F**2 - 192e12, 0, 12e4 * F**4 + 336e8 * F**2 + 192e12, 0,
           F**6 - 12e4 * F**4 + 48e8 * F**2 - 64e12]
    return _positive_real_roots(p15)[-1], _positive_real_roots(p16)[-1]


def test_fig3_unloaded_map_is_bounded_by_the_three_lines():
    result = compute_map({}, ('rho', 0.01, 4.0, 81), ('L2', 0.01, 4.0, 77), progress=False)
    rho, L2 = np.meshgrid(result.xs, result.ys)
    lines = np.stack([2 * rho - L2 - 1, 2 * rho - L2 + 1, 2 * rho + L2 - 1])
    away = np.min(np.abs(lines), axis=0) > 0.03
    inside = (np.abs(1 - L2) < 2 * rho) & (2 * rho < 1 + L2)      # |L1-L2| < 2 rho < L1+L2
    expected = np.where(inside, 2, 1)
    assert np.array_equal(result.num_stable[away], expected[away])
    assert away.sum() > 0.9 * away.size


@pytest.mark.parametrize('sign', [-1, 1], ids=['fig4a_pushing', 'fig4b_pulling'])
def test_fig4_map_boundaries_are_eqs_15_and_16(sign):
    forces = sign * np.array([0.5, 2.0, 5.0, 10.0])
    rhos = np.linspace(0.005, 2.0, 800)
    step = rhos[1] - rhos[0]
    for F in forces:
        result = compute_map({'F': F}, ('rho', 0.005, 2.0, 800), ('L2', 1.0, 1.0, 1),
                             progress=False)
        two = result.xs[result.num_stable[0] == 2]
        left, right = paper_boundaries(F)
        assert two.min() == pytest.approx(left, abs=step)
        assert two.max() == pytest.approx(right, abs=step)
        # One contiguous interval, one stable solution elsewhere (never 0 or 3).
        assert two.size == pytest.approx((two.max() - two.min()) / step + 1, abs=0.5)
        assert set(np.unique(result.num_stable)) == {1, 2}
    # The operation range shrinks as |F| grows; at F = 0 it is 1 (section 4.2).
    widths = [np.subtract(*paper_boundaries(F)[::-1]) for F in forces]
    assert all(a > b for a, b in zip(widths, widths[1:]))
    unloaded = compute_map({'F': 0.0}, ('rho', 0.005, 2.0, 400), ('L2', 1.0, 1.0, 1),
                           progress=False)
    two = unloaded.xs[unloaded.num_stable[0] == 2]
    assert two.max() - two.min() == pytest.approx(1.0, abs=0.015)


def test_fig5_slices_and_fig7_operation_range_versus_L2():
    """Fig. 5 / 7: the 2-stable region is small for L2 = 1/2, largest around L2 = 1.

    (In these F3 = 5 slices L2 = 3/2 is 2 % smaller than L2 = 1, in line with
    the fig. 7 remark that the range decreases slowly for L2 > 1.)
    """
    areas = {}
    for L2 in (0.5, 1.0, 1.5):
        result = compute_map({'F3': 5.0, 'L2': L2}, ('rho', 0.005, 2.0, 120),
                             ('F4', 0.0, 10.0, 41), progress=False)
        areas[L2] = np.mean(result.num_stable == 2)
    assert areas[0.5] < 0.5 * areas[1.0]
    assert areas[1.5] == pytest.approx(areas[1.0], rel=0.1)


def test_map_png_is_small(tmp_path):
    result = compute_map({'F': -10.0}, ('rho', 0.005, 2.0, 200), ('L2', 0.005, 2.0, 200),
                         progress=False)
    path = tmp_path / 'fig7.png'
    plot_map(result, path)
    assert 5_000 < path.stat().st_size < 300_000


def test_fig8a_diagram_events():
    diagram = compute_diagram({'F': 5.0}, 0.01, 2.0, 120)
    kinds = sorted((e.kind, e.rho) for e in diagram.events)
    assert [k for k, _ in kinds] == ['branch_point', 'fold']
    assert kinds[0][1] == pytest.approx(C1_RHO, abs=1e-7)
    assert kinds[1][1] == pytest.approx(C2_RHO, abs=1e-7)
    c1 = next(e for e in diagram.events if e.kind == 'branch_point')
    assert c1.theta[0] == pytest.approx(c1.theta[1], abs=1e-6) and c1.theta[0] < 0   # symmetric
    # Branches are curves, not scatter: neighbouring points are close on the torus.
    for br in diagram.branches:
        th = np.array(br.theta)
        if len(th) > 1:
            jumps = np.abs((np.diff(th, axis=0) + np.pi) % (2 * np.pi) - np.pi)
            assert jumps.max() < 0.35
    # Every sample's equilibria appear on exactly one branch: at most 6 branches here.
    assert len(diagram.branches) == 6
    stable_branches = [br for br in diagram.branches if any(br.stable)]
    assert len(stable_branches) == 2           # upper (everywhere) and lower (C1 .. C2)


def test_fig8b_branch_point_becomes_a_fold():
    diagram = compute_diagram({'F': 5.0, 'L2': 1.05}, 0.01, 2.0, 120)
    assert sorted(e.kind for e in diagram.events) == ['fold', 'fold']


def test_unloaded_diagram_has_pitchforks_at_the_fig3_lines():
    diagram = compute_diagram({'L2': 1.5}, 0.01, 2.0, 100)
    rhos = sorted(e.rho for e in diagram.events)
    assert [e.kind for e in diagram.events] == ['branch_point', 'branch_point']
    assert rhos == pytest.approx([0.25, 1.25], abs=1e-7)   # 2 rho = |L1 - L2|, L1 + L2


def test_diagram_png_with_track(tmp_path):
    from tensegrity_ros.figures import track_path
    diagram = compute_diagram({'F': 5.0}, 0.05, 1.5, 50)
    tracked = track_path({'F': 5.0}, [0.5, 1.2, 0.5], (-1.0, -1.0), diagram)
    assert [j[3] for j in tracked.jumps] == ['fold']
    assert tracked.jumps[0][0] == pytest.approx(C2_RHO, abs=1e-6)
    assert tracked.pieces[-1][1][-1][0] > 0                 # ends on the upper branch: hysteresis
    path = tmp_path / 'fig8a.png'
    plot_diagram(diagram, path, tracked=tracked)
    assert 10_000 < path.stat().st_size < 300_000


def test_makefile_figures_recipe_uses_the_cli():
    from pathlib import Path
    text = (Path(__file__).resolve().parents[1] / 'Makefile').read_text()
    recipe = text.split('\nfigures:', 1)[1].split('\n\n', 1)[0]
    for name in ('fig3', 'fig4a', 'fig4b', 'fig5a', 'fig5b', 'fig5c', 'fig7', 'fig8a', 'fig8b'):
        assert name in recipe
    assert 'tensegrity) map' in recipe or '$(TENSEGRITY) map' in recipe
    assert '$(TENSEGRITY) diagram' in recipe


def test_small_diagram_via_cli(tmp_path, capsys):
    png = tmp_path / 'fig8b.png'
    code = main(['diagram', '--from-rho', '0.05', '--to-rho', '1.2', '--count', '40',
                 '--F', '5', '--L2', '1.05', '--png', str(png)])
    out = capsys.readouterr().out
    assert code == 0
    assert out.count('fold at rho=') == 2
    assert png.stat().st_size > 10_000
