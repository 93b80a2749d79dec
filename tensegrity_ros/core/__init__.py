"""ROS-free core: the model, the exact solver, stability and the tracker (numpy/scipy only)."""
from .continuation import (BRANCH_POINT, Event, FOLD, PathProblem, Track, track, TrackerSettings,
                           TrackingError, Undecided)
from .dynamics.module_snap import RhoRamp, simulate_snap, Snap, SnapHistory
from .module.equilibria import (classify, equilibria, equilibria_batch, Equilibrium,
                                EquilibriumBatch, EquilibriumSet)
from .module.model import (actuator_force, energy, gradient, hessian, InvalidParameterError,
                           ModuleParams, node_positions, PARAMETER_NAMES, STANDARD_GRAVITY)
from .module.tracking import (equilibrium_at, ModuleJump, ModulePath, ModuleTrack, ModuleUndecided,
                              settle, track_module)

__all__ = [
    'ModuleParams', 'InvalidParameterError', 'PARAMETER_NAMES', 'STANDARD_GRAVITY',
    'energy', 'gradient', 'hessian', 'actuator_force', 'node_positions',
    'Equilibrium', 'EquilibriumSet', 'EquilibriumBatch', 'equilibria', 'equilibria_batch',
    'classify',
    'PathProblem', 'TrackerSettings', 'Track', 'Event', 'TrackingError', 'track', 'Undecided',
    'FOLD', 'BRANCH_POINT',
    'ModuleJump', 'ModuleTrack', 'ModuleUndecided', 'ModulePath', 'track_module', 'settle',
    'equilibrium_at',
    'RhoRamp', 'Snap', 'SnapHistory', 'simulate_snap',
]
