"""A neck of N modules in motion, driven in real time (the node's ``dynamics`` for a neck).

:class:`MovingNeck` is the :class:`~.dynamics.live_motion.LiveMotion` loop with the equations of
:mod:`.dynamics.neck_snap` (every rod a bar pivoting at its base, m L^2 / 3 about it, damping
per pivot; rods and the chords below each upper module rigid; the actuators kinematic).
The state is the moving nodes' positions and velocities.  ``command`` takes one target
per module; every actuator runs from where it is at most at its own speed limit and all
arrive together (the slowest sets the time).  Across a new command, a parameter change
or the ramp's end the local angles and their rates carry on (as far as the rigid chords
allow, least squares), as in the offline transient; a change of rod lengths rebuilds
the nodes from the local angles.
"""
from __future__ import annotations

import numpy as np

from .live_motion import LiveMotion
from .moving_module import checked_rate
from .neck_kernel import warm_up
from .neck_snap import damping_vector, NeckEquations
from .transient import RhoRamp, SolverSettings
from ..module.model import InvalidParameterError
from ..neck.stack import settle_stack, Stack, StackPath


class MovingNeck(LiveMotion):
    """A neck ``stack`` (rod masses > 0) with pivot ``damping`` (N m s/rad, one value or
    one per module) and actuator speed limits ``max_rate`` (m/s, one or one per module),
    at rest at time ``t`` in the stable equilibrium whose basin holds ``theta_guess``
    (N x 2).  ``rho`` and ``target`` are tuples, one per module."""

    def __init__(self, stack: Stack, theta_guess, damping, max_rate, t: float = 0.0,
                 settings: SolverSettings = SolverSettings()):
        self.n = len(stack)
        warm_up()                                   # the compiled equations, now
        start = settle_stack(stack, theta_guess)
        super().__init__(stack, tuple(float(m.rho) for m in stack.modules), start, damping,
                         max_rate, t, settings)

    # -- what it is now ----------------------------------------------------------------
    def _now(self):
        """(angles (N x 2), rates (N x 2), actuator forces (N)) of the state now, computed
        once per state (a node reads every module's at every tick)."""
        key = (self.t, id(self._system), id(self.y))
        if getattr(self, '_kept', (None,))[0] != key:
            angles, rates, forces = self._system.readings(self._local(), self.y[None, :])
            self._kept = (key, angles[0].reshape(self.n, 2), rates[0].reshape(self.n, 2),
                          forces[0])
        return self._kept[1:]

    @property
    def theta(self):
        """Local angles (N x 2, rad, wrapped) now."""
        return self._now()[0].copy()

    @property
    def theta_dot(self):
        """Local angle rates (N x 2, rad/s) now."""
        return self._now()[1].copy()

    @property
    def actuator_forces(self):
        """Force (N) of every actuator now (module 0: on A2 along +x; above: along the
        chord, positive pushing apart), the rods' inertia included."""
        return self._now()[2].copy()

    @property
    def rho_dot(self):
        """Every actuator's speed (m/s) now (0 once there)."""
        return np.asarray(self._system.ramp.rho_dot(self._local()), dtype=float)

    @property
    def nodes(self):
        """Every node now ((2 + 2N) x 2: A1(0), A2(0), then A3(i), A4(i))."""
        return self._system.full(self._local(), self.y)[0]

    # -- the LiveMotion hooks ----------------------------------------------------------
    def _per_module(self, values, name):
        values = np.atleast_1d(np.asarray(values, dtype=object))
        if values.shape not in ((1,), (self.n,)):
            raise InvalidParameterError(f'{name} must have 1 or {self.n} values, '
                                        f'got {values.tolist()!r}')
        return values if len(values) == self.n else np.repeat(values, self.n)

    def _checked_rate(self, max_rate):
        return tuple(checked_rate(r) for r in self._per_module(max_rate, 'max_rate'))

    def _checked_damping(self, damping):
        return tuple(damping_vector(damping, self.n).tolist())

    @staticmethod
    def _rho_of(values):
        return tuple(float(r) for r in values)

    def _checked_target(self, rho_target):
        try:
            target = tuple(float(r) for r in rho_target)
        except (TypeError, ValueError):
            raise InvalidParameterError(f'rho targets must be {self.n} numbers, '
                                        f'got {rho_target!r}') from None
        if len(target) != self.n:
            raise InvalidParameterError(f'rho targets must be {self.n} numbers, '
                                        f'got {len(target)}')
        for m, r in zip(self.params.modules, target):
            m.with_(rho=r)                          # validates (finite, positive, range)
        return target

    def _ramp_rate(self):
        """The ramp's rate (its largest change per second) such that every actuator
        stays within its own limit and all arrive together."""
        change = np.abs(np.subtract(self.target, self.rho))
        if not np.any(change > 0.0):
            return min(self.max_rate)
        return float(np.max(change) / np.max(change / np.array(self.max_rate)))

    def _equations(self):
        start = Stack(tuple(m.with_(rho=r) for m, r in zip(self.params.modules, self.rho)))
        return NeckEquations(start, RhoRamp(self.rho, self.target, self._ramp_rate()),
                             self.damping, extend_ramp=True)

    def _carried(self, old, t_local, y, new):
        """The nodes of the local angles now (rebuilt for the new design), with node
        velocities giving the local angle rates (least squares under the new ramp)."""
        if old is None:                            # y: the StackEquilibrium to start from
            return new.start_state(y.nodes)
        before = np.nextafter(t_local, -np.inf) if t_local > 0.0 else t_local
        angles, rates = old.rates(before, y)
        y = np.array(y, dtype=float)
        if any((a.L1, a.L2) != (b.L1, b.L2) for a, b in zip(old.modules, new.modules)):
            stack = Stack(new.modules)
            path = StackPath(stack, stack)
            nodes = path.nodes(path.state_from_angles(angles.reshape(self.n, 2), 0.0), 0.0)
            y[:4 * self.n] = nodes[2:].ravel()
        return new.with_angle_rates(0.0, y, rates)

    @staticmethod
    def _all_readings(system, t_local, ys):
        return system.readings(t_local, ys)

    def _reading_splits(self):
        return [2 * self.n, 4 * self.n]

    @staticmethod
    def _fastest(system, t_local, y):
        return float(np.max(np.abs(system.rates(t_local, y)[1])))

    def _final(self, y):
        angles, rates, _ = self._now()
        return {'theta': angles.tolist(), 'speed': float(np.max(np.abs(rates)))}
