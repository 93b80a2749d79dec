"""The answer of a tolerance study: per-sample figures, their statistics (quantiles,
probabilities, sensitivities), the worst samples with their replays, and its output
(JSON, CSV, text report, plots).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
import json
import math
import os

import numpy as np

from .design import Design
from ..core.module import PARAMETER_NAMES
from ..core.tolerance.questions import KIND_NAMES, STATUS_NAMES
from ..core.tolerance.sample_statistics import (describe_figure, event_probability, noise_level,
                                                rank_correlation_tables, tally)
from ..core.tolerance.sampling import sample_waypoints

#: Sensitivities use at most this many (valid) samples, the first ones.
SENSITIVITY_SAMPLES = 2 ** 17
#: Figures that code a kind (counted, not averaged).
CODE_FIGURES = ('lower_kind', 'upper_kind', 'jump_kind', 'collapse_kind', 'status',
                'num_stable', 'jump_leg', 'jumps', 'scalar')


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
        from .replay import replay
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
        from .report import report_text
        return report_text(self.summary())

    def plot(self, prefix):
        """PNG histograms of the figures and a sensitivity bar chart: the paths written."""
        from .report import plot_histograms, plot_sensitivity
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
