"""The rods in motion (docs/model.md section 5): a transient driven by an actuator ramp
(:mod:`.transient`), the snap of one module (:mod:`.module_snap`) and of a neck
(:mod:`.neck_snap`, its compiled equations :mod:`.neck_kernel`), and a mechanism driven in
real time (:mod:`.live_motion`, :mod:`.moving_module`, :mod:`.moving_neck`)."""
from .live_motion import LiveMotion
from .module_snap import (MAX_HOLD, ONSET_SPEED, RhoRamp, SETTLE_TOLERANCE, simulate_snap, Snap,
                          SnapHistory, SolverSettings)
from .moving_module import MovingModule
from .moving_neck import MovingNeck
from .neck_snap import NeckSnap, simulate_neck_snap

__all__ = ['LiveMotion', 'MAX_HOLD', 'ONSET_SPEED', 'RhoRamp', 'SETTLE_TOLERANCE',
           'simulate_snap', 'Snap', 'SnapHistory', 'SolverSettings', 'MovingModule',
           'MovingNeck', 'NeckSnap', 'simulate_neck_snap']
