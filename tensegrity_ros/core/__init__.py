"""ROS-free core: the model, the exact solver, stability and the tracker (numpy/scipy only)."""
from .module import (ModuleParams, InvalidParameterError, PARAMETER_NAMES, STANDARD_GRAVITY,
                     energy, gradient, hessian, actuator_force, node_positions)
from .equilibria import (Equilibrium, EquilibriumSet, EquilibriumBatch, equilibria,
                         equilibria_batch, classify)
from .continuation import (PathProblem, TrackerSettings, Track, Event, TrackingError, track,
                           FOLD, BRANCH_POINT)
from .tracking import (ModuleJump, ModuleTrack, ModulePath, track_module, settle,
                       equilibrium_at)
from .dynamics import RhoRamp, Snap, SnapHistory, simulate_snap

__all__ = [
    'ModuleParams', 'InvalidParameterError', 'PARAMETER_NAMES', 'STANDARD_GRAVITY',
    'energy', 'gradient', 'hessian', 'actuator_force', 'node_positions',
    'Equilibrium', 'EquilibriumSet', 'EquilibriumBatch', 'equilibria', 'equilibria_batch',
    'classify',
    'PathProblem', 'TrackerSettings', 'Track', 'Event', 'TrackingError', 'track',
    'FOLD', 'BRANCH_POINT',
    'ModuleJump', 'ModuleTrack', 'ModulePath', 'track_module', 'settle', 'equilibrium_at',
    'RhoRamp', 'Snap', 'SnapHistory', 'simulate_snap',
]
