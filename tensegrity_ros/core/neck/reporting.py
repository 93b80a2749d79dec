"""What a neck state means to a user: local angles, actuator forces, the base's reaction,
the head's pose (a mixin of :class:`.neck.path.StackPath`)."""
from __future__ import annotations

import cmath
import math

import numpy as np

from .model import _FIXED

_FRAME_SIGNS, _ANGLE_SIGNS = np.array([1.0, -1.0]), np.array([-1.0, 1.0])  # angles_at
_BASE_AXIS = np.ones(1, dtype=complex)      # module 0's x axis A1(0) -> A2(0), as a chord


class StackReporting:
    """The reporting methods of :class:`.neck.path.StackPath`."""

    def angles(self, y, s):
        """Local angles (N x 2): t1 of A1A3 from the module's x axis, t2 of A2A4 from -x."""
        return self.angles_at(self.point(y, s))

    def angles_at(self, p):
        # module x axes A1 -> A2 (unnormalised: angles are blind to positive scale);
        # t1 = arg(v1 conj(x)) = -arg(conj(v1) x), t2 = arg(-x conj(v2))
        frame = np.concatenate((_BASE_AXIS, p.chords(self)))
        local = p.rods.reshape(self.n, 2).conj() * (frame[:, None] * _FRAME_SIGNS)
        return np.angle(local) * _ANGLE_SIGNS

    def state_from_angles(self, theta, s):
        """Rod angles from local angles (N x 2), projected onto the constraints."""
        theta = np.asarray(theta, dtype=float).reshape(self.n, 2)
        lengths = self.at(s).rod.reshape(self.n, 2)
        phi = np.empty((self.n, 2))
        frame, chord = 0.0, complex(self.at(s).rho0)         # chord: A1(i) -> A2(i)
        for i in range(self.n):
            phi[i] = frame + theta[i, 0], frame + math.pi - theta[i, 1]
            chord = (lengths[i, 0] * cmath.exp(1j * phi[i, 0])
                     - chord - lengths[i, 1] * cmath.exp(1j * phi[i, 1]))
            frame = cmath.phase(chord)
        y = np.concatenate([phi.ravel(), np.zeros(self.topology.n_chords)])
        return self.project(y, s)

    def actuator_forces(self, y, s):
        """dU*/d rho of every module (N): the force each telescopic actuator holds.

        Module 0: dL/d rho(0) at fixed state (rho(0) moves A2(0) and every node built on
        it); module i >= 1: its rod is module i-1's chord, dL/dl = -mu l / l_ref."""
        return self.actuator_forces_at(self.point(y, s))

    def actuator_forces_at(self, p):
        forces = np.empty(self.n)
        forces[0] = (float(p.weights @ (p.diff.real * self.topology.element_base))
                     - p.values.base_load)
        if self.topology.n_chords:
            forces[1:] = -p.mu * p.values.chord / self.l_ref
        return forces

    def base_reaction(self, y, s):
        """Force (2,) and moment about A1(0) that the ground supplies at A1(0) and A2(0).

        From node statics in Cartesian coordinates: the axial forces of every rod and
        chord are the least-squares solution of the equilibrium of the moving nodes,
        and the ground balances what the springs and rods attached to the base exert."""
        top = self.topology
        x = self.nodes(y, s)
        p = self.point(y, s)
        ns = top.n_springs
        gradient = -self.loads(s)
        for (a, b), k in zip(top.element_ends[:ns], p.values.k):
            gradient[a] += k * (x[a] - x[b])
            gradient[b] -= k * (x[a] - x[b])
        rigid = top.rod_ends + top.element_ends[ns:]
        columns = np.zeros((top.nodes, 2, len(rigid)))
        for j, (a, b) in enumerate(rigid):
            columns[a, :, j] += x[a] - x[b]
            columns[b, :, j] -= x[a] - x[b]
        moving = columns[_FIXED:].reshape(-1, len(rigid))
        tension = np.linalg.lstsq(moving, -gradient[_FIXED:].ravel(), rcond=None)[0]
        support = gradient[:_FIXED] + columns[:_FIXED] @ tension
        moment = float(np.sum(x[:_FIXED, 0] * support[:, 1] - x[:_FIXED, 1] * support[:, 0]))
        return support.sum(axis=0), moment

    def total_load(self, y, s):
        """Resultant external force (2,) and its moment about A1(0), all nodes."""
        x = self.nodes(y, s)
        loads = self.loads(s)
        return loads.sum(axis=0), float(np.sum(x[:, 0] * loads[:, 1] - x[:, 1] * loads[:, 0]))

    def head_pose(self, y, s):
        """Midpoint (2,) and direction angle (rad) of the top chord A4 -> A3."""
        x = self.nodes(y, s)
        top = self.topology
        a3, a4 = x[top.a3(self.n - 1)], x[top.a4(self.n - 1)]
        d = a3 - a4
        return 0.5 * (a3 + a4), math.atan2(d[1], d[0])
