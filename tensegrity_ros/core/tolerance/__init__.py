"""The pure parts of a tolerance study (numpy; the dask front end is
:mod:`tensegrity_ros.tolerance`): a toleranced design's seeded samples (:mod:`.sampling`),
what each sample is asked and its answer as numbers (:mod:`.questions`, vectorised by
:mod:`.batch` and :mod:`.branch_batch`) and the statistics of the answers
(:mod:`.sample_statistics`)."""
from .questions import evaluate_chunk, HeadLoad, OperatingRange, PlannedPath
from .sample_statistics import proportion_interval, quantiles, rank_correlations
from .sampling import apply_tolerances, sample_waypoints, Tolerance, unit_samples

__all__ = ['evaluate_chunk', 'HeadLoad', 'OperatingRange', 'PlannedPath', 'apply_tolerances',
           'sample_waypoints', 'Tolerance', 'unit_samples', 'proportion_interval', 'quantiles',
           'rank_correlations']
