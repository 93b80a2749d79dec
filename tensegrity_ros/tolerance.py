"""Design under tolerances: how a built module or neck behaves, sampled (issue 34).

:func:`tolerance_study` samples a design (one module, or a neck from a node parameter
file) whose parameters scatter by given tolerances, asks every sample one question
(:mod:`.core.tolerance_questions`: the operating range, a planned path, the critical
head load), and reports quantiles, event probabilities with confidence intervals,
rank-correlation sensitivities and the worst samples as replayable command lines::

    from tensegrity_ros.tolerance import module_design, tolerance_study
    design = module_design({'rho': 0.5, 'F': 5.0})
    result = tolerance_study(design, 'range', ['k=5%', 'L2=0.001'], samples=4096)
    print(result.summary()['figures']['width']['quantiles'])

Parameters are named as the CLI names them (``rho``, ``L1``, ``L2``, ``k``, ``ka`` ..,
``F``, ``F3`` ..); ``m1.k`` names module m1's springs only.  A group name tolerates
each of its fields independently (``k``: the three springs; ``F``: F3 and F4).  Without
a module prefix, load names (F, F3, F4, F3x, F4x) tolerate the head module's loads (as
the CLI's load options load the head), the others every module.

The samples run in chunks on :mod:`.tolerance_engine` (in-process, a LocalCluster or a
remote dask scheduler); the answer depends on the seed only (a sample's answer does
not depend on its chunk, nor on where or when the chunk ran).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
import json
import math
import os

import numpy as np

from .core.module.model import InvalidParameterError, PARAMETER_NAMES, STANDARD_GRAVITY
from .core.tolerance.questions import (code_fingerprint, evaluate_chunk, HeadLoad, KIND_NAMES,
                                       OperatingRange, PlannedPath, STATUS_NAMES)
from .core.tolerance.sample_statistics import (describe_figure, event_probability, noise_level,
                                               rank_correlation_tables, tally)
from .core.tolerance.sampling import (parse_spread, sample_waypoints, SAMPLERS, Tolerance,
                                      unit_samples)
from .problem import APPLY_ORDER, DEFAULT_FIELDS, PARAMETERS

QUESTIONS = ('range', 'path', 'head-load')
#: Names that load the head of a neck (as the CLI's load options).
HEAD_NAMES = ('F', 'F3', 'F4', 'F3x', 'F4x')
#: Samples per chunk by question (one module vectorised, scalar tracking, a neck):
#: each chunk takes ~0.1-1 s against dask's ~2 ms per task (benchmarks/
#: bench_tolerance.py), and the vectorised questions amortise their per-step numpy
#: overhead over the rows (a range sample with a start guess: 55 us of CPU in chunks of
#: 512, 42 in 2048, 32 in 8192, at load 8).  Larger studies get larger chunks, up to these.
CHUNK_SIZES = {'range': 8192, 'path': 8192, 'head-load': 8192, 'neck': 16}
#: Fewest samples per chunk (unless the study is smaller).
MIN_CHUNK = {'range': 2048, 'path': 2048, 'head-load': 2048, 'neck': 2}
#: Sensitivities use at most this many (valid) samples, the first ones.
SENSITIVITY_SAMPLES = 2 ** 17
#: Figures that code a kind (counted, not averaged).
CODE_FIGURES = ('lower_kind', 'upper_kind', 'jump_kind', 'collapse_kind', 'status',
                'num_stable', 'jump_leg', 'jumps', 'scalar')


class ToleranceError(InvalidParameterError):
    """A study that cannot be set up (bad tolerance, design, or question): the reason.
    (An InvalidParameterError, which the command line reports as a usage error.)"""


# ---------------------------------------------------------------------------
# The design: nominal modules at each waypoint of a command schedule

@dataclass(frozen=True)
class Design:
    """The nominal mechanism: ``stops`` (K, N, 12) parameter vectors of N modules at K
    waypoints (K = 1: no motion), module ``names``, the start ``guess`` (N x 2 angles
    or None: a module's upper stable equilibrium, a neck's upright configuration),
    ``config``: the parameter file a neck came from, if any."""

    stops: np.ndarray
    names: tuple
    guess: tuple | None = None
    g: float = STANDARD_GRAVITY
    config: str | None = None

    @property
    def modules(self):
        return len(self.names)

    def fields(self, stop=0):
        """The ModuleParams fields of every module at waypoint ``stop`` (dicts)."""
        return [dict(zip(PARAMETER_NAMES, row.tolist())) for row in self.stops[stop]]


def _vector(fields):
    return np.array([float(fields[n]) for n in PARAMETER_NAMES])


def _apply_named(fields, values, module, top):
    """Fields of one module with CLI-named ``values`` applied (loads only on the head)."""
    out = dict(fields)
    for name in APPLY_ORDER:
        if values.get(name) is None:
            continue
        if name in HEAD_NAMES and module != top:
            continue
        for f in PARAMETERS[name][0]:
            out[f] = float(values[name])
    return out


def _leg_values(leg, names):
    """A leg's changes as {module index or None (all): {CLI name: value}}."""
    out = {}
    for key, value in leg.items():
        module, name = _split_name(key, names)
        out.setdefault(module, {})[name] = float(value)
    return out


def _split_name(key, names):
    """(module index or None, CLI name) of ``key`` ('k', 'm1.k'), names case-insensitive."""
    module = None
    if '.' in key:
        prefix, key = key.split('.', 1)
        if prefix not in names:
            raise ToleranceError(f'unknown module {prefix!r} (modules: {", ".join(names)})')
        module = names.index(prefix)
    for known in PARAMETERS:
        if known.lower() == key.lower():
            return module, known
    raise ToleranceError(f'unknown parameter {key!r} (choose from {", ".join(PARAMETERS)})')


def _stops(first, legs, names):
    """The waypoints: ``first`` (N field dicts), then each leg's changes applied to the
    previous waypoint (a leg dict maps CLI names, optionally 'm1.'-prefixed, to values;
    unprefixed loads go to the head, anything else to every module)."""
    top = len(first) - 1
    stops = [list(first)]
    for leg in legs:
        changes = _leg_values(leg, names)
        prev = stops[-1]
        new = []
        for i, fields in enumerate(prev):
            f = _apply_named(fields, changes.get(None, {}), i, top)
            f = _apply_named(f, changes.get(i, {}), i, i)
            new.append(f)
        stops.append(new)
    return stops


def _check_stops(stops, g):
    from .core.module.model import InvalidParameterError, ModuleParams
    for k, stop in enumerate(stops):
        for i, f in enumerate(stop):
            try:
                ModuleParams(**f, g=g)
            except InvalidParameterError as exc:
                where = 'the start' if k == 0 else f'waypoint {k}'
                raise ToleranceError(f'module {i} at {where}: {exc}') from None


def module_design(values, legs=(), guess=None):
    """One module from CLI-named values (``{'rho': 0.5, 'F': 5}``; the paper's defaults
    otherwise) and a command schedule: ``legs``, one dict of changes per leg
    (``[{'rho': 0.1}, {'rho': 0.5}]``).  ``guess``: (t1, t2) start guess or None."""
    if values.get('rho') is None:
        raise ToleranceError('the design needs rho')
    fields = dict(DEFAULT_FIELDS, rho=None)
    fields = _apply_named(fields, values, 0, 0)
    stops = _stops([fields], legs, ['m0'])
    _check_stops(stops, STANDARD_GRAVITY)
    return Design(stops=np.array([[_vector(f) for f in s] for s in stops]), names=('m0',),
                  guess=None if guess is None else (tuple(float(v) for v in guess),))


def neck_design(config, node=None, values=None, legs=(), guess=None):
    """A neck (or one module) from a node parameter file, as ``track --config`` reads it;
    ``values``: CLI-named overrides (loads to the head, the rest to every module);
    ``legs`` as :func:`module_design` ('m1.rho' commands one module, 'rho' all);
    ``guess``: N x 2 angles (default: the file's initial_theta)."""
    from .params_file import ConfigError, load_stack_config
    try:
        cfg = load_stack_config(config, node)
    except (ConfigError, OSError) as exc:
        raise ToleranceError(str(exc)) from None
    names = tuple(cfg.names)
    first = [dict(zip(PARAMETER_NAMES, m.params.vector().tolist())) for m in cfg.modules]
    top = len(first) - 1
    first = [_apply_named(f, values or {}, i, top) for i, f in enumerate(first)]
    stops = _stops(first, legs, list(names))
    _check_stops(stops, STANDARD_GRAVITY)
    if guess is None:
        guess = cfg.initial_theta
    guess = np.asarray(guess, dtype=float).reshape(len(names), 2)
    return Design(stops=np.array([[_vector(f) for f in s] for s in stops]), names=names,
                  guess=tuple(tuple(float(v) for v in t) for t in guess), config=str(config))


# ---------------------------------------------------------------------------
# Tolerances by CLI name

def parse_tolerances(specs, design):
    """:class:`Tolerance` objects (one per toleranced field and module) from specs
    ``'NAME=SPREAD'`` (see :func:`.core.tolerance_sampling.parse_spread`)."""
    names = list(design.names)
    top = design.modules - 1
    out, seen = [], set()
    for spec in specs:
        if isinstance(spec, Tolerance):
            out.append(spec)
            continue
        if '=' not in spec:
            raise ToleranceError(f'bad tolerance {spec!r}: expected NAME=SPREAD, e.g. k=5%')
        key, text = spec.split('=', 1)
        module, name = _split_name(key.strip(), names)
        try:
            distribution, spread, relative, cut = parse_spread(text)
        except ValueError as exc:
            raise ToleranceError(str(exc)) from None
        if module is not None:
            modules = [module]
        elif name in HEAD_NAMES:
            modules = [top]
        else:
            modules = list(range(design.modules))
        for i in modules:
            for f in PARAMETERS[name][0]:
                label = f if design.modules == 1 else f'{names[i]}.{f}'
                if (i, f) in seen:
                    raise ToleranceError(f'{label} is toleranced twice (by {spec!r})')
                seen.add((i, f))
                nominal = design.stops[0, i, PARAMETER_NAMES.index(f)]
                if relative and nominal == 0.0 and spread > 0.0:
                    raise ToleranceError(f'{spec!r}: {label} is 0, a relative tolerance of '
                                         f'it is 0 too: give an absolute one')
                out.append(Tolerance(field=f, spread=spread, distribution=distribution,
                                     relative=relative, cut=cut, module=i, label=label))
    if not out:
        raise ToleranceError('give at least one tolerance (e.g. --tol k=5%)')
    return out


def question_for(kind, design, at_rho=None, rho_bounds=None, exact=False):
    """The question object of ``kind`` ('range', 'path', 'head-load') for ``design``."""
    k = design.stops.shape[0]
    if kind == 'range':
        if design.modules != 1:
            raise ToleranceError('the operating range is for one module: a neck has no '
                                 'single rho (ask path or head-load)')
        if k != 1:
            raise ToleranceError('the operating range takes no path waypoints')
        guess = None if design.guess is None else tuple(design.guess[0])
        return OperatingRange(guess=guess, at_rho=at_rho, rho_bounds=rho_bounds, exact=exact)
    if at_rho is not None or rho_bounds is not None:
        raise ToleranceError('--at-rho and --rho-bounds are for the range question')
    if kind == 'path':
        if k < 2:
            raise ToleranceError('a path needs at least one waypoint (e.g. --to rho=0.1)')
        return PlannedPath(guess=design.guess, names=design.names, exact=exact)
    if kind == 'head-load':
        if k != 2:
            raise ToleranceError('the head-load question needs the end load (e.g. --to F=-20)')
        return HeadLoad(guess=design.guess, names=design.names, exact=exact)
    raise ToleranceError(f'unknown question {kind!r} (choose from {", ".join(QUESTIONS)})')


def chunk_size(kind, modules, samples):
    """Samples per chunk: depends on the question and the sample count only (never on
    the engine), so every engine evaluates the same chunks."""
    key = kind if modules == 1 else 'neck'
    return int(min(CHUNK_SIZES[key], max(MIN_CHUNK[key], math.ceil(samples / 16))))


# ---------------------------------------------------------------------------
# The study

def tolerance_study(design, question, tolerances, samples=1024, *, seed=0, sampler='sobol',
                    processes=None, scheduler=None, chunk=None, progress=False,
                    at_rho=None, rho_bounds=None, exact=False, confidence=0.95,
                    interval='clopper-pearson', worst=5):
    """Sample ``design`` under ``tolerances`` (specs 'k=5%' or Tolerance objects) and ask
    every sample ``question`` ('range', 'path', 'head-load', or a question object).

    ``processes=1``: in this process (no dask); None: a LocalCluster of all cores;
    ``scheduler``: the address of a running dask scheduler.  ``chunk``: samples per
    task (default :func:`chunk_size`).  Returns a :class:`ToleranceResult`."""
    if sampler not in SAMPLERS:
        raise ToleranceError(f'--sampler must be one of {", ".join(SAMPLERS)}, got {sampler!r}')
    if not (isinstance(samples, (int, np.integer)) and samples >= 1):
        raise ToleranceError(f'the sample count must be an integer >= 1, got {samples!r}')
    if processes is not None and processes < 1:
        raise ToleranceError(f'--processes must be >= 1, got {processes}')
    tols = parse_tolerances(tolerances, design)
    q = question if not isinstance(question, str) else question_for(
        question, design, at_rho=at_rho, rho_bounds=rho_bounds, exact=exact)
    size = min(chunk or chunk_size(q.name, design.modules, samples), samples)
    if size < 1:
        raise ToleranceError(f'--chunk must be >= 1, got {size}')
    unit = unit_samples(samples, len(tols), sampler, seed)
    chunks = [(q, design.stops, tols, unit[i:i + size], design.g)
              for i in range(0, samples, size)]
    from .tolerance_engine import run_chunks
    results, run = run_chunks(evaluate_chunk, chunks, processes=processes,
                              scheduler=scheduler, progress=progress,
                              sizes=[len(c[3]) for c in chunks], fingerprint=code_fingerprint)
    figures = {name: np.concatenate([r[name] for r in results]) for name in q.figures()}
    inputs = np.column_stack([t.values(design.stops[0, t.module,
                                                    PARAMETER_NAMES.index(t.field)], unit[:, j])
                              for j, t in enumerate(tols)])
    return ToleranceResult(design=design, question=q, tolerances=tuple(tols), unit=unit,
                           inputs=inputs, figures=figures, seed=seed, sampler=sampler,
                           run=run, chunk=size, confidence=confidence, interval=interval,
                           worst_count=worst)


@dataclass
class ToleranceResult:
    """The answer of a study: per-sample ``figures`` (arrays), the toleranced
    ``inputs`` (samples x tolerances), and the run; :meth:`summary` has the statistics."""

    design: Design
    question: object
    tolerances: tuple
    unit: np.ndarray
    inputs: np.ndarray
    figures: dict
    seed: int
    sampler: str
    run: object
    chunk: int
    confidence: float = 0.95
    interval: str = 'clopper-pearson'
    worst_count: int = 5
    _summary: dict = field(default=None, repr=False)

    @property
    def samples(self):
        return len(self.unit)

    @property
    def labels(self):
        return [t.label for t in self.tolerances]

    def valid(self):
        return self.figures['status'] == 0

    def summary(self):
        """Everything the report shows, JSON-ready (cached)."""
        if self._summary is None:
            self._summary = self._make_summary()
        return self._summary

    def _make_summary(self):
        ok = self.valid()
        figures, codes, probabilities = {}, {}, {}
        for name, values in self.figures.items():
            if name in CODE_FIGURES:
                codes[name] = tally(values[ok], KIND_NAMES if name.endswith('_kind') else None)
            elif name in self.question.EVENTS:
                probabilities[name] = event_probability(values[ok], self.confidence,
                                                        self.interval)
            else:
                figures[name] = describe_figure(values[ok])
        return {
            'question': self.question.name,
            'samples': self.samples, 'valid': int(ok.sum()),
            'status': tally(self.figures['status'], STATUS_NAMES),
            'seed': self.seed, 'sampler': self.sampler, 'chunk': self.chunk,
            'design': self.design_record(),
            'tolerances': [self.tolerance_record(t) for t in self.tolerances],
            'engine': self.engine_record(),
            'figures': figures, 'kinds': codes, 'probabilities': probabilities,
            'sensitivity': self.sensitivity(ok),
            'worst': self.worst(),
        }

    def sensitivity(self, ok):
        """Rank correlations of every figure with every parameter and with the size of
        its error, over the first SENSITIVITY_SAMPLES valid samples (their noise level,
        ~0.006, is far below any effect worth naming, and ranking costs n log n)."""
        used = np.nonzero(ok)[0][:SENSITIVITY_SAMPLES]
        nominal = np.array([t['nominal'] for t in map(self.tolerance_record, self.tolerances)])
        inputs = self.inputs[used]
        figures = {name: values[used] for name, values in self.figures.items()
                   if name not in CODE_FIGURES or name in ('num_stable', 'jumps')}
        signed, size = rank_correlation_tables([inputs, np.abs(inputs - nominal)], figures)
        keep = [name for name, r in signed.items() if not np.all(np.isnan(r))]
        return {'measure': 'spearman rank correlation', 'samples': int(used.size),
                'noise_level': noise_level(int(used.size)),
                'figures': {name: _by_label(self.labels, signed[name]) for name in keep},
                'error_size': {name: _by_label(self.labels, size[name]) for name in keep}}

    def engine_record(self):
        run = self.run
        return {'engine': run.engine, 'workers': run.workers, 'seconds': run.wall_seconds,
                'startup_seconds': run.startup_seconds, 'chunks': run.chunks,
                'chunk_seconds': run.chunk_seconds, 'chunk_cpu_seconds': run.chunk_cpu_seconds,
                'samples_per_second': (self.samples / run.wall_seconds
                                       if run.wall_seconds > 0 else math.inf),
                'overhead': run.overhead}

    def design_record(self):
        d = self.design
        return {'modules': list(d.names), 'config': d.config,
                'guess': None if d.guess is None else [list(t) for t in d.guess],
                'waypoints': [[dict(zip(PARAMETER_NAMES, row.tolist())) for row in stop]
                              for stop in d.stops]}

    def tolerance_record(self, t):
        nominal = float(self.design.stops[0, t.module, PARAMETER_NAMES.index(t.field)])
        lo, hi = t.bounds(nominal)
        return {'parameter': t.label, 'field': t.field, 'module': self.design.names[t.module],
                'nominal': nominal, 'distribution': t.distribution, 'spread': t.spread,
                'relative': t.relative, 'cut': t.cut, 'spec': t.text(), 'range': [lo, hi]}

    # -- worst samples and their replays ------------------------------------------------

    def worst_indices(self):
        """The worst samples: the figure ``question.WORST`` smallest first (failed
        samples first of all: they are worse than any figure)."""
        q = self.question
        values = self.figures[q.WORST]
        failed = np.nonzero(~self.valid())[0]
        ok = np.nonzero(self.valid() & np.isfinite(values))[0]
        order = ok[np.argsort(values[ok], kind='stable')]
        if q.WORST_ORDER == 'largest':
            order = order[::-1]
        return [int(i) for i in np.concatenate([failed, order])[:self.worst_count]]

    def sample_stops(self, index):
        """The waypoints (K, N, 12) of sample ``index``."""
        return sample_waypoints(self.design.stops, self.tolerances,
                                self.unit[index:index + 1])[0]

    def worst(self):
        from .tolerance_replay import replay
        out = []
        for i in self.worst_indices():
            stops = self.sample_stops(i)
            record = {'index': i, 'figure': self.question.WORST,
                      'value': _float(self.figures[self.question.WORST][i]),
                      'status': STATUS_NAMES.get(int(self.figures['status'][i]), '?'),
                      'parameters': dict(zip(self.labels, self.inputs[i].tolist()))}
            record.update(replay(self.question, self.design, stops, i))
            out.append(record)
        return out

    # -- output ---------------------------------------------------------------------------

    def write_json(self, stream):
        json.dump(_clean(self.summary()), stream, indent=2)
        stream.write('\n')

    def write_csv(self, stream):
        """One row per sample: index, the toleranced parameters, every figure."""
        writer = csv.writer(stream, lineterminator='\n')
        names = list(self.figures)
        writer.writerow(['sample'] + self.labels + names)
        cols = [self.figures[n] for n in names]
        for i in range(self.samples):
            writer.writerow([i] + [repr(float(v)) for v in self.inputs[i]]
                            + [_csv_value(c[i]) for c in cols])

    def text(self):
        """The human-readable report."""
        from .tolerance_report import report_text
        return report_text(self.summary())

    def plot(self, prefix):
        """PNG histograms of the figures and a sensitivity bar chart: the paths written."""
        from .tolerance_report import plot_histograms, plot_sensitivity
        return [plot_histograms(self, f'{prefix}_histograms.png'),
                plot_sensitivity(self.summary(), f'{prefix}_sensitivity.png')]


def _by_label(labels, r):
    return dict(zip(labels, (None if math.isnan(x) else float(x) for x in r)))


def _float(v):
    v = float(v)
    return v if math.isfinite(v) else None


def _csv_value(v):
    v = float(v)
    return '' if math.isnan(v) else repr(v)


def _clean(obj):
    """NaN and inf as null (strict JSON)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.generic):
        return _clean(obj.item())
    return obj


def write_text_file(path, text):
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    with open(path, 'w', encoding='utf-8') as f:
        f.write(text)
