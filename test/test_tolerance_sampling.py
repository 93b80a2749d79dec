"""Tolerance specs, seeded samples and the statistics of a tolerance study (issue 34),
against closed forms: uniform and normal quantiles, the Clopper-Pearson bounds of 0 and
n events, Latin-hypercube strata, rank correlations of monotone and independent data."""
import math

import numpy as np
import pytest
from scipy import stats

from tensegrity_ros.core.tolerance.sample_statistics import (noise_level, proportion_interval,
                                                             quantiles, rank_correlations)
from tensegrity_ros.core.tolerance.sampling import (parse_spread, sample_waypoints, Tolerance,
                                                    unit_samples)


@pytest.mark.parametrize('text, expected', [
    ('5%', ('uniform', 0.05, True, None)),
    ('0.001', ('uniform', 0.001, False, None)),
    ('uniform:0.001', ('uniform', 0.001, False, None)),
    ('normal:0.2', ('normal', 0.2, False, None)),
    ('normal:2%:3', ('normal', 0.02, True, 3.0)),
    (' Normal : 1e-3 ', ('normal', 1e-3, False, None)),
])
def test_spread_specs(text, expected):
    distribution, spread, relative, cut = parse_spread(text)
    assert (distribution, relative, cut) == (expected[0], expected[2], expected[3])
    assert spread == pytest.approx(expected[1], rel=1e-15)


@pytest.mark.parametrize('text', ['', 'x', '-1', 'nan', 'inf', 'uniform:0.1:3', 'normal:0.1:0',
                                  'normal:0.1:x', 'gauss:0.1', '5%%'])
def test_bad_spread_specs_say_why(text):
    with pytest.raises(ValueError, match='tolerance'):
        parse_spread(text)


def test_uniform_and_normal_values_are_the_quantile_transforms():
    u = np.array([1e-3, 0.25, 0.5, 0.9])
    band = Tolerance('ka', 0.05, relative=True)
    np.testing.assert_allclose(band.values(100.0, u), 100.0 * (1 + 0.05 * (2 * u - 1)))
    normal = Tolerance('L2', 0.01, distribution='normal')
    np.testing.assert_allclose(normal.values(1.0, u), 1.0 + 0.01 * stats.norm.ppf(u))
    cut = Tolerance('L2', 0.01, distribution='normal', cut=2.0)
    v = cut.values(1.0, np.linspace(0, 1, 101))
    assert np.all(np.abs(v - 1.0) <= 0.02 + 1e-15) and np.all(np.isfinite(v))
    assert cut.bounds(1.0) == pytest.approx((0.98, 1.02))
    assert math.isinf(normal.bounds(1.0)[1])
    assert np.all(np.isfinite(normal.values(1.0, np.array([0.0, 1.0]))))   # clipped
    assert band.text() == '5%' and cut.text() == 'normal:0.01:2'


def test_same_seed_same_samples_and_every_sampler_fills_the_cube():
    for sampler in ('sobol', 'lhs', 'mc'):
        a = unit_samples(256, 3, sampler, seed=7)
        assert a.shape == (256, 3) and np.all((a >= 0) & (a < 1))
        np.testing.assert_array_equal(a, unit_samples(256, 3, sampler, seed=7))
        assert not np.array_equal(a, unit_samples(256, 3, sampler, seed=8))
    # Latin hypercube: one point in each of the n strata of every column
    lhs = unit_samples(100, 4, 'lhs', seed=1)
    for column in lhs.T:
        assert sorted(np.floor(column * 100).astype(int)) == list(range(100))
    # a scrambled Sobol' net of 2^m points: one point in each 1/2^m interval too
    sobol = unit_samples(128, 2, 'sobol', seed=1)
    for column in sobol.T:
        assert sorted(np.floor(column * 128).astype(int)) == list(range(128))
    with pytest.raises(ValueError):
        unit_samples(10, 2, 'grid')


def test_errors_carry_over_to_every_waypoint():
    nominal = np.zeros((3, 1, 12))
    nominal[:, 0, :] = [0.5, 1, 1, 100, 100, 100, 0, 5, 0, 5, 0, 0]
    nominal[1, 0, 0], nominal[2, 0, 0] = 0.1, 0.5          # rho schedule
    nominal[2, 0, 7] = 6.0                                   # F3 commanded at the end
    tols = [Tolerance('rho', 0.01, module=0), Tolerance('f3y', 0.1, relative=True)]
    unit = np.array([[1.0 - 2 ** -53, 0.75]])
    w = sample_waypoints(nominal, tols, unit)[0, :, 0, :]
    np.testing.assert_allclose(w[:, 0], [0.51, 0.11, 0.51])           # offset added
    np.testing.assert_allclose(w[:, 7], [5.25, 5.25, 6.3])            # factor 1.05
    np.testing.assert_array_equal(w[:, 1:7], nominal[:, 0, 1:7])


def test_quantiles_and_proportion_intervals():
    values = np.concatenate([np.arange(101.0), [np.nan, np.inf]])
    q = quantiles(values)
    assert q[0.01] == pytest.approx(1.0) and q[0.5] == pytest.approx(50.0)
    assert all(math.isnan(v) for v in quantiles([np.nan]).values())
    n = 200
    lo, hi = proportion_interval(0, n)            # Clopper-Pearson: (alpha/2)^(1/n)
    assert lo == 0.0 and hi == pytest.approx(1 - 0.025 ** (1 / n), rel=1e-9)
    lo, hi = proportion_interval(n, n)
    assert hi == 1.0 and lo == pytest.approx(0.025 ** (1 / n), rel=1e-9)
    lo, hi = proportion_interval(30, 100, method='wilson')
    z = stats.norm.ppf(0.975)
    centre = (0.3 + z * z / 200) / (1 + z * z / 100)
    half = z / (1 + z * z / 100) * math.sqrt(0.3 * 0.7 / 100 + z * z / 40000)
    assert (lo, hi) == pytest.approx((centre - half, centre + half), rel=1e-9)
    assert all(math.isnan(v) for v in proportion_interval(0, 0))


def test_rank_correlations():
    rng = np.random.default_rng(3)
    x = rng.random((2000, 3))
    y = np.exp(2 * x[:, 0]) - 3 * x[:, 1] ** 3                # monotone in 0, anti in 1
    r = rank_correlations(x, y)
    assert r[0] > 0.8 and r[1] < -0.3 and abs(r[2]) < noise_level(2000)
    assert rank_correlations(x, -y)[0] == pytest.approx(-r[0])
    with_nan = y.copy()
    with_nan[::2] = np.nan
    assert rank_correlations(x, with_nan)[0] == pytest.approx(r[0], abs=0.05)
    assert np.isnan(rank_correlations(x, np.ones(2000))).all()
