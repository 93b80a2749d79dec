"""Design under tolerances: how a built module or neck behaves, sampled (issue 34).

:func:`tolerance_study` samples a design (one module, or a neck from a node parameter
file) whose parameters scatter by given tolerances, asks every sample one question
(:mod:`..core.tolerance.questions`: the operating range, a planned path, the critical
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

The samples run in chunks on :mod:`.engine` (in-process, a LocalCluster or a
remote dask scheduler); the answer depends on the seed only (a sample's answer does
not depend on its chunk, nor on where or when the chunk ran).
"""
from __future__ import annotations

import math

import numpy as np

from .design import parse_tolerances, ToleranceError
from .result import ToleranceResult
from ..core.module import PARAMETER_NAMES
from ..core.tolerance.questions import (code_fingerprint, evaluate_chunk, HeadLoad, OperatingRange,
                                        PlannedPath)
from ..core.tolerance.sampling import SAMPLERS, unit_samples

QUESTIONS = ('range', 'path', 'head-load')
#: Samples per chunk by question (one module vectorised, scalar tracking, a neck):
#: each chunk takes ~0.1-1 s against dask's ~2 ms per task (benchmarks/
#: bench_tolerance.py), and the vectorised questions amortise their per-step numpy
#: overhead over the rows (a range sample with a start guess: 55 us of CPU in chunks of
#: 512, 42 in 2048, 32 in 8192, at load 8).  Larger studies get larger chunks, up to these.
CHUNK_SIZES = {'range': 8192, 'path': 8192, 'head-load': 8192, 'neck': 16}
#: Fewest samples per chunk (unless the study is smaller).
MIN_CHUNK = {'range': 2048, 'path': 2048, 'head-load': 2048, 'neck': 2}


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
    from .engine import run_chunks
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
