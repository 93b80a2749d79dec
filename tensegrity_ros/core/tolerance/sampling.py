"""Manufacturing tolerances and the seeded samples of a toleranced design.

A :class:`Tolerance` says how one parameter of one module scatters around its nominal
value: uniformly in a band (``half_width``) or normally (``sigma``, optionally
truncated at ``cut`` sigmas), the spread absolute (same unit as the parameter) or
relative (a fraction of the nominal value).  Every toleranced parameter of every module
is one independent dimension of the sample space.

:func:`unit_samples` draws all points of the unit hypercube up front from the seed
(``scipy.stats.qmc`` Sobol or Latin hypercube, or plain Monte Carlo): a chunked run on
any number of processes evaluates slices of the same array, so the answer does not
depend on how the chunks are scheduled.  :func:`apply_tolerances` maps them to
parameter values through each distribution's quantile function.

Numbers only (numpy/scipy); which CLI name means which field is the caller's business.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
import re
import warnings

import numpy as np
from scipy import stats
from scipy.stats import qmc

from ..module.model import PARAMETER_NAMES

#: Samplers by name: scrambled Sobol, Latin hypercube, plain Monte Carlo.
SAMPLERS = ('sobol', 'lhs', 'mc')
#: Distributions by name.
DISTRIBUTIONS = ('uniform', 'normal')
#: Unit samples are kept this far inside (0, 1): the normal quantile stays finite.
_UNIT_EDGE = 2.0 ** -53

_SPEC = re.compile(r'^\s*(?:(?P<dist>uniform|normal)\s*:\s*)?(?P<spread>[^:%\s]+)\s*'
                   r'(?P<percent>%)?\s*(?::\s*(?P<cut>[^:\s]+))?\s*$', re.IGNORECASE)


@dataclass(frozen=True)
class Tolerance:
    """How one field of one module scatters.

    ``field``: a :class:`~.module.ModuleParams` field (``'ka'``, ``'f3y'`` ...);
    ``module``: its module index (bottom = 0); ``distribution``: ``'uniform'`` (``spread``
    is the half-width of the band) or ``'normal'`` (``spread`` is sigma); ``relative``:
    the spread is a fraction of the nominal value; ``cut``: a normal distribution
    truncated at +-cut sigmas (None: not truncated).  ``label`` names the dimension in
    reports (e.g. ``'m1.ka'``).
    """

    field: str
    spread: float
    distribution: str = 'uniform'
    relative: bool = False
    cut: float | None = None
    module: int = 0
    label: str = ''

    def __post_init__(self):
        if self.distribution not in DISTRIBUTIONS:
            raise ValueError(f'distribution must be one of {DISTRIBUTIONS}, '
                             f'got {self.distribution!r}')
        if not (math.isfinite(self.spread) and self.spread >= 0.0):
            raise ValueError(f'the spread must be a finite number >= 0, got {self.spread!r}')
        if self.cut is not None:
            if self.distribution != 'normal':
                raise ValueError('only a normal distribution can be truncated')
            if not (math.isfinite(self.cut) and self.cut > 0.0):
                raise ValueError(f'the truncation must be > 0 sigmas, got {self.cut!r}')

    def width(self, nominal):
        """The absolute spread (half-width or sigma) about ``nominal``."""
        return self.spread * abs(nominal) if self.relative else self.spread

    def values(self, nominal, unit):
        """Parameter values for unit-interval samples ``unit`` (quantile transform)."""
        unit = np.clip(np.asarray(unit, dtype=float), _UNIT_EDGE, 1.0 - _UNIT_EDGE)
        width = self.width(nominal)
        if self.distribution == 'uniform':
            return nominal + width * (2.0 * unit - 1.0)
        if self.cut is None:
            return nominal + width * stats.norm.ppf(unit)
        return nominal + width * stats.truncnorm.ppf(unit, -self.cut, self.cut)

    def bounds(self, nominal):
        """The smallest and largest value the distribution can give (inf if unbounded)."""
        width = self.width(nominal)
        reach = width if self.distribution == 'uniform' else (
            math.inf if self.cut is None else width * self.cut)
        if width == 0.0:
            reach = 0.0
        return nominal - reach, nominal + reach

    def text(self):
        """The spec as the command line takes it, e.g. ``'normal:2%:3'``."""
        spread = f'{self.spread * 100:g}%' if self.relative else f'{self.spread:g}'
        out = spread if self.distribution == 'uniform' else f'normal:{spread}'
        return out + (f':{self.cut:g}' if self.cut is not None else '')


def parse_spread(text):
    """(distribution, spread, relative, cut) from a spec such as ``'5%'``, ``'0.001'``,
    ``'uniform:0.001'``, ``'normal:0.2'``, ``'normal:2%:3'`` (sigma 2 %, truncated at
    3 sigmas).  ValueError with the reason otherwise."""
    m = _SPEC.match(text)
    if not m:
        raise ValueError(f'bad tolerance {text!r}: expected [uniform:|normal:]SPREAD[%][:CUT] '
                         f'(e.g. 5%, 0.001, normal:0.2, normal:2%:3)')
    distribution = (m.group('dist') or 'uniform').lower()
    try:
        spread = float(m.group('spread'))
    except ValueError:
        raise ValueError(f'bad tolerance {text!r}: {m.group("spread")!r} is not a number') \
            from None
    relative = m.group('percent') is not None
    if relative:
        spread /= 100.0
    if not (math.isfinite(spread) and spread >= 0.0):
        raise ValueError(f'bad tolerance {text!r}: the spread must be a finite number >= 0')
    cut = None
    if m.group('cut') is not None:
        if distribution != 'normal':
            raise ValueError(f'bad tolerance {text!r}: only normal:SIGMA can be truncated '
                             f'(normal:SIGMA:CUT, CUT in sigmas)')
        try:
            cut = float(m.group('cut'))
        except ValueError:
            raise ValueError(f'bad tolerance {text!r}: the truncation {m.group("cut")!r} '
                             f'is not a number of sigmas') from None
        if not (math.isfinite(cut) and cut > 0.0):
            raise ValueError(f'bad tolerance {text!r}: the truncation must be > 0 sigmas')
    return distribution, spread, relative, cut


def unit_samples(count, dimensions, sampler='sobol', seed=0):
    """``count`` points of the unit hypercube of ``dimensions`` dimensions, shape
    (count, dimensions), all drawn here from ``seed``: the same seed gives the same
    array on every machine (numpy's and scipy's generators are platform independent).

    ``'sobol'``: scrambled Sobol' (Owen scrambling; its balance is best for a power of
    2 points, other counts are the first ``count`` points of the sequence);
    ``'lhs'``: Latin hypercube; ``'mc'``: independent uniform points."""
    if sampler not in SAMPLERS:
        raise ValueError(f'sampler must be one of {SAMPLERS}, got {sampler!r}')
    if count < 1:
        raise ValueError(f'count must be >= 1, got {count}')
    if dimensions == 0:
        return np.empty((count, 0))
    rng = np.random.default_rng(seed)
    if sampler == 'mc':
        return rng.random((count, dimensions))
    if sampler == 'lhs':
        return qmc.LatinHypercube(dimensions, rng=rng).random(count)
    with warnings.catch_warnings():       # "balance properties ... power of 2": documented
        warnings.simplefilter('ignore', UserWarning)
        return qmc.Sobol(dimensions, scramble=True, rng=rng).random(count)


def apply_tolerances(nominal, tolerances, unit):
    """Sampled module fields: ``nominal`` is a list (one per module) of dicts of
    ModuleParams fields; ``tolerances`` one :class:`Tolerance` per column of ``unit``.
    Returns a dict ``(module, field) -> array`` for every toleranced field (the
    other fields keep their nominal values)."""
    unit = np.asarray(unit, dtype=float)
    if unit.ndim != 2 or unit.shape[1] != len(tolerances):
        raise ValueError(f'unit samples must have shape (count, {len(tolerances)}), '
                         f'got {unit.shape}')
    out = {}
    for column, tol in enumerate(tolerances):
        key = (tol.module, tol.field)
        if key in out:
            raise ValueError(f'{tol.label or key} is toleranced twice')
        out[key] = tol.values(nominal[tol.module][tol.field], unit[:, column])
    return out


def sample_waypoints(nominal, tolerances, unit):
    """The sampled command schedule: ``nominal`` (K, N, 12) holds the parameter vectors
    (``PARAMETER_NAMES`` order) of N modules at K waypoints; each sample's error in a
    toleranced field (drawn at waypoint 0) carries over to every waypoint: added for an
    absolute tolerance, as a factor for a relative one (a commanded load 10 % too high at
    the start stays 10 % too high).  Returns shape (count, K, N, 12)."""
    nominal = np.asarray(nominal, dtype=float)
    unit = np.asarray(unit, dtype=float)
    out = np.broadcast_to(nominal, (len(unit),) + nominal.shape).copy()
    for column, tol in enumerate(tolerances):
        j = PARAMETER_NAMES.index(tol.field)
        base = nominal[0, tol.module, j]
        value = tol.values(base, unit[:, column])
        if tol.relative and base != 0.0:
            out[:, :, tol.module, j] = nominal[None, :, tol.module, j] * (value / base)[:, None]
        else:
            out[:, :, tol.module, j] = nominal[None, :, tol.module, j] + (value - base)[:, None]
    return out
