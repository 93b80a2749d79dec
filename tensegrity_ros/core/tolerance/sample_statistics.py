"""Statistics of a sampled design: quantiles, a proportion's confidence interval, and
rank-correlation sensitivities.

Sensitivity measure: Spearman's rank correlation of each figure with each toleranced
parameter.  Why this and not Sobol' indices: it needs no sample design of its own (any
sampler's points serve, Sobol' indices need Saltelli's N (d + 2) structured evaluations),
it is invariant under any monotone change of scale (a figure in mm or in m, a stiffness
or its logarithm), it works for a 0/1 outcome such as "jumps" as well as for a length,
and for manufacturing tolerances, which are small, each figure is a nearly monotone
function of each parameter, where the rank correlation is the natural measure of "how
much of the scatter follows this parameter".  Its limits: it misses non-monotone
effects (a parameter whose both signs of error narrow the range reads ~0), and its
noise level is ~1/sqrt(n) (values below :func:`noise_level` are not significant).

Jump probabilities carry an exact (Clopper-Pearson) binomial interval: it is valid for
independent samples (``--sampler mc``) whatever the count, including 0 or n jumps; for
Sobol' or Latin-hypercube points, which are not independent, it is the interval a plain
Monte Carlo run of the same size would have (usually wider than the true one).
"""
from __future__ import annotations

import math

import numpy as np
from scipy import stats

#: The quantiles reported for every figure.
QUANTILES = (0.01, 0.05, 0.5, 0.95, 0.99)
#: Interval methods of scipy.stats.binomtest's proportion_ci, by our name.
INTERVALS = {'clopper-pearson': 'exact', 'wilson': 'wilson'}


def quantiles(values, levels=QUANTILES):
    """{level: quantile} over the finite entries of ``values`` (linear interpolation,
    numpy's default); every value NaN when none is finite."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {q: math.nan for q in levels}
    return dict(zip(levels, (float(x) for x in np.quantile(v, levels))))


def proportion_interval(successes, trials, confidence=0.95, method='clopper-pearson'):
    """(low, high) confidence interval of a probability from ``successes`` of
    ``trials`` (scipy.stats.binomtest); (nan, nan) for no trials."""
    if method not in INTERVALS:
        raise ValueError(f'method must be one of {tuple(INTERVALS)}, got {method!r}')
    if trials == 0:
        return math.nan, math.nan
    ci = stats.binomtest(int(successes), int(trials)).proportion_ci(
        confidence_level=confidence, method=INTERVALS[method])
    return float(ci.low), float(ci.high)


def rank_correlations(inputs, figure):
    """Spearman's rank correlation of ``figure`` (n,) with each column of ``inputs``
    (n, d), over the rows where the figure is finite.  NaN where a column or the figure
    is constant there (no ranking)."""
    table = rank_correlation_tables([inputs], {'figure': figure})[0]
    return table.get('figure', np.full(np.shape(inputs)[1], math.nan))


def rank_correlation_tables(input_sets, figures):
    """For each inputs array (n, d) of ``input_sets``, {name: :func:`rank_correlations`
    of it with figure ``name``}; each figure is ranked once, the inputs once for every set
    of rows where figures are finite.  (Elementwise sums, not BLAS: a threaded BLAS dot
    product is slow on a loaded machine.)  Figures finite on fewer than 3 rows are left
    out."""
    xs = [np.asarray(x, dtype=float) for x in input_sets]
    tables = [{} for _ in xs]
    ranked_key, ranked = None, None
    for name, figure in figures.items():
        y = np.asarray(figure, dtype=float)
        keep = np.isfinite(y)
        if keep.sum() < 3:
            continue
        if ranked_key != keep.tobytes():            # the inputs ranked on these rows
            ranked_key, ranked = keep.tobytes(), [_centred_ranks(x[keep]) for x in xs]
        ry = stats.rankdata(y[keep])
        ry -= ry.mean()
        ny = math.sqrt(float(np.sum(ry * ry)))
        for table, (rx, nx) in zip(tables, ranked):
            r = np.full(rx.shape[1], math.nan)
            good = (nx > 0.0) & (ny > 0.0)
            r[good] = np.sum(rx[:, good] * ry[:, None], axis=0) / (nx[good] * ny)
            table[name] = r
    return tables


def _centred_ranks(x):
    """Column ranks of ``x`` minus their mean, and their norms."""
    rx = stats.rankdata(x, axis=0) if x.shape[1] else np.zeros(x.shape)
    rx -= rx.mean(axis=0) if x.shape[0] else 0.0
    return rx, np.sqrt(np.sum(rx * rx, axis=0))


def noise_level(count):
    """Two standard errors of a rank correlation between independent variables
    (~2 / sqrt(n - 1)): smaller correlations are not told from noise."""
    return 2.0 / math.sqrt(count - 1) if count > 1 else math.inf


def describe_figure(values):
    """Count, mean, std, min, max and :data:`QUANTILES` of the finite ``values`` (NaN
    where there are too few)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return {'count': int(v.size),
            'mean': float(v.mean()) if v.size else math.nan,
            'std': float(v.std(ddof=1)) if v.size > 1 else math.nan,
            'min': float(v.min()) if v.size else math.nan,
            'max': float(v.max()) if v.size else math.nan,
            'quantiles': {f'{100 * q:g}%': x for q, x in quantiles(v).items()}}


def tally(codes, names=None):
    """{name (or the code as text): how many} of the finite ``codes``."""
    v = np.asarray(codes, dtype=float)
    v = v[np.isfinite(v)]
    return {(names[int(c)] if names else f'{c:g}'): int((v == c).sum()) for c in np.unique(v)}


def event_probability(events, confidence=0.95, method='clopper-pearson'):
    """The probability of a 0/1 outcome (finite ``events``) with its interval."""
    v = np.asarray(events, dtype=float)
    v = v[np.isfinite(v)]
    k, n = int(v.sum()), int(v.size)
    low, high = proportion_interval(k, n, confidence, method)
    return {'events': k, 'trials': n, 'p': k / n if n else math.nan, 'interval': [low, high],
            'confidence': confidence, 'method': method}
