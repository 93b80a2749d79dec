"""One W-C module (docs/model.md sections 1-3): its model (:mod:`.model`: parameters,
energy and derivatives), every equilibrium exactly (:mod:`.polynomial_solver`, vectorised in
:mod:`.batch_solver`, entry points in :mod:`.equilibria`), their Morse type
(:mod:`.classification`), the dimensionless range the solvers are tested on
(:mod:`.supported_range`) and its stable branch followed along a path (:mod:`.tracking`,
on the generic :mod:`..continuation`)."""
from .classification import classify, Equilibrium, EquilibriumSet, hessian_eigenvalues
from .equilibria import equilibria, equilibria_batch, EquilibriumBatch
from .model import (actuator_force, energy, gradient, hessian, InvalidParameterError, ModuleParams,
                    node_positions, PARAMETER_NAMES, STANDARD_GRAVITY)
from .supported_range import check_supported, OutOfRangeError
from .tracking import (equilibrium_at, ModuleJump, ModulePath, ModuleTrack, ModuleUndecided,
                       settle, track_module)

__all__ = ['classify', 'Equilibrium', 'EquilibriumSet', 'hessian_eigenvalues', 'equilibria',
           'equilibria_batch', 'EquilibriumBatch', 'actuator_force', 'energy', 'gradient',
           'hessian', 'InvalidParameterError', 'ModuleParams', 'node_positions',
           'PARAMETER_NAMES', 'STANDARD_GRAVITY', 'check_supported', 'OutOfRangeError',
           'equilibrium_at', 'ModuleJump', 'ModulePath', 'ModuleTrack', 'ModuleUndecided',
           'settle', 'track_module']
