"""Every equilibrium of one module, exactly (docs/model.md section 3): the entry points.

The work is split by concept: :mod:`.polynomial_solver` (elimination to a degree-6
polynomial, polishing, degenerate cases; the polynomial itself and its roots:
:mod:`.angle_polynomial`), :mod:`.batch_solver` (the vectorised form for maps) and
:mod:`.classification` (Morse type, the records).  This module gathers their public names
under the path tools and tests have always imported.
"""
from .batch_solver import BATCH_BLOCK, equilibria_batch, EquilibriumBatch
from .classification import (classify, DEGENERACY_TOL, Equilibrium, EquilibriumSet,
                             hessian_eigenvalues, KIND_DEGENERATE, KIND_MAXIMUM, KIND_MINIMUM,
                             KIND_SADDLE)
from .polynomial_solver import equilibria

__all__ = ['BATCH_BLOCK', 'EquilibriumBatch', 'equilibria_batch', 'DEGENERACY_TOL',
           'KIND_DEGENERATE', 'KIND_MAXIMUM', 'KIND_MINIMUM', 'KIND_SADDLE', 'Equilibrium',
           'EquilibriumSet', 'classify', 'hessian_eigenvalues', 'equilibria']
