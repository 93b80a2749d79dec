"""Numerical ground shared by every concept above it: the named tolerances for "positive
definite" (:mod:`.tolerances`), bounded work per call (:mod:`.bounded_work`) and the switch
for numba-compiled kernels (:mod:`.numba_kernels`, numba imported only when first used)."""
from .bounded_work import Budget, BudgetSpent, checkpoint, Job, OutOfTime
from .numba_kernels import compile_kernels, engine
from .tolerances import (BRANCH_POINT_CERTIFIED, DEFINITENESS_TOL, DEGENERACY_TOL,
                         MARGIN_CERTIFIED, verified_minimum)

__all__ = ['Budget', 'BudgetSpent', 'checkpoint', 'Job', 'OutOfTime', 'compile_kernels',
           'engine', 'BRANCH_POINT_CERTIFIED', 'DEFINITENESS_TOL', 'DEGENERACY_TOL',
           'MARGIN_CERTIFIED', 'verified_minimum']
