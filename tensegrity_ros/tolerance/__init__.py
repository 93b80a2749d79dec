"""Design under tolerances (issue 34): the study (:mod:`.study`) of a design
(:mod:`.design`) under tolerances, the engine its chunks run on (:mod:`.engine`, the only
module importing dask), its answer (:mod:`.result`), the worst samples' replays
(:mod:`.replay`) and the report (:mod:`.report`).

The names below are the package's interface (``tensegrity_ros.tolerance.tolerance_study``,
docs/tolerance.md); the command line's face of it is :mod:`..cli.tolerance`.
"""
from .design import (Design, HEAD_NAMES, module_design, neck_design, parse_tolerances,
                     ToleranceError)
from .result import CODE_FIGURES, SENSITIVITY_SAMPLES, ToleranceResult, write_text_file
from .study import (chunk_size, CHUNK_SIZES, MIN_CHUNK, question_for, QUESTIONS,
                    tolerance_study)

__all__ = ['CHUNK_SIZES', 'CODE_FIGURES', 'Design', 'HEAD_NAMES', 'MIN_CHUNK', 'QUESTIONS',
           'SENSITIVITY_SAMPLES', 'ToleranceError', 'ToleranceResult', 'chunk_size',
           'module_design', 'neck_design', 'parse_tolerances', 'question_for',
           'tolerance_study', 'write_text_file']
