"""The mechanism as a user drives it, ROS-free: the :class:`Simulator` (commands, speed
limits, loads, reset, time; :mod:`.simulator`) on one of two mechanisms
(:mod:`.mechanisms`: one module or a neck), started where :mod:`.start_state` says, its
events and outcomes (:mod:`.events`), commands that come faster than they are tracked
(:mod:`.command_coalescing`), timed trajectories (:mod:`.trajectory`) and the dynamics mode
(:mod:`.dynamic_simulator`, with the quasi-static path ahead :mod:`.path_ahead`)."""
from .dynamic_simulator import DynamicSimulator
from .events import Jump, Outcome, Passage, TrackingFailure
from .simulator import ModuleLimits, ModuleStatus, Simulator
from .start_state import start_state
from .trajectory import Trajectory, TrajectoryPlayer

__all__ = ['DynamicSimulator', 'Jump', 'Outcome', 'Passage', 'TrackingFailure',
           'ModuleLimits', 'ModuleStatus', 'Simulator', 'start_state', 'Trajectory',
           'TrajectoryPlayer']
