"""One module in motion, driven in real time (the ROS-free half of the node's ``dynamics``).

:class:`MovingModule` is the :class:`~.dynamics.live_motion.LiveMotion` loop with the equations
of :mod:`.dynamics`: the state is the rods' angles and rates.  ``command`` sets a new
actuator target at a given time; rho then runs towards it at the speed limit, from
wherever it is, while the rods keep their momentum.  When a snap has come to rest,
``advance`` returns its figures, the keys of :func:`~.dynamics.simulate_snap`'s summary.
"""
from __future__ import annotations

import math

import numpy as np

from . import transient
from .live_motion import LiveMotion
from .module_snap import ModuleEquations
from .transient import RhoRamp, SolverSettings, wrap
from ..module.model import InvalidParameterError, ModuleParams, node_positions
from ..module.tracking import settle


def checked_rate(max_rate):
    """An actuator speed limit (m/s): positive and finite, or InvalidParameterError."""
    if not isinstance(max_rate, (int, float)) or not 0.0 < max_rate < math.inf:
        raise InvalidParameterError(f'max_rate must be positive and finite, got {max_rate!r}')
    return float(max_rate)


class MovingModule(LiveMotion):
    """A module with rod masses ``params.m1``, ``m2``, pivot ``damping`` (N m s/rad) and an
    actuator speed limit ``max_rate`` (m/s), at rest at time ``t`` in the stable
    equilibrium whose basin holds ``theta_guess``."""

    def __init__(self, params: ModuleParams, theta_guess, damping: float, max_rate: float,
                 t: float = 0.0, settings: SolverSettings = SolverSettings()):
        start = settle(params, theta_guess)
        super().__init__(params, float(params.rho), np.array([*start.theta, 0.0, 0.0]),
                         damping, max_rate, t, settings)

    # -- what it is now ----------------------------------------------------------------
    @property
    def theta(self):
        return wrap(self.y[:2])

    @property
    def theta_dot(self):
        return self.y[2:].copy()

    @property
    def actuator_force(self):
        """Force (N) on A2 along +x now, rod 2's inertia included."""
        return float(self._system.actuator_force(np.array([self._local()]),
                                                 self.y[None, :])[0])

    @property
    def actuator_forces(self):
        """(actuator_force,): the neck's interface (:class:`~.dynamics.moving_neck.MovingNeck`)."""
        return np.array([self.actuator_force])

    @property
    def nodes(self):
        """A1..A4 now (4, 2): the node table of a one-module neck."""
        return node_positions(self.params.with_(rho=self.rho), self.theta)

    @property
    def rho_dot(self):
        """Actuator speed (m/s) now: the speed limit towards the target, 0 when there."""
        return float(self._system.ramp.rho_dot(self._local()))

    # -- the LiveMotion hooks ----------------------------------------------------------
    _checked_rate = staticmethod(checked_rate)
    _checked_damping = staticmethod(transient.checked_damping)
    _rho_of = staticmethod(float)

    def _checked_target(self, rho_target):
        try:
            target = float(rho_target)
        except (TypeError, ValueError):
            raise InvalidParameterError(f'rho target must be a number, '
                                        f'got {rho_target!r}') from None
        self.params.with_(rho=target)                 # validates (finite, positive, range)
        return target

    def _equations(self):
        return ModuleEquations(self.params.with_(rho=self.rho),
                               RhoRamp(self.rho, self.target, self.max_rate), self.damping,
                               extend_ramp=True)

    @staticmethod
    def _carried(old, t_local, y, new):
        """The angles and their rates carry on (rho'' impulses neglected, as offline)."""
        return y

    @staticmethod
    def _all_readings(system, t_local, ys):
        return ys[:, :2], ys[:, 2:], system.actuator_force(t_local, ys)[:, None]

    @staticmethod
    def _reading_splits():
        return [2, 4]

    @staticmethod
    def _fastest(system, t_local, y):
        return max(abs(float(y[2])), abs(float(y[3])))

    @staticmethod
    def _final(y):
        return {'theta1': float(wrap(y[0])), 'theta2': float(wrap(y[1])),
                'speed': float(np.max(np.abs(y[2:])))}
