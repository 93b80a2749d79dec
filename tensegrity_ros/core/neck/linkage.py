"""A neck's linkage limits: a module folded flat onto its top chord, where the chord
constraint's gradient vanishes (a mixin of :class:`.neck.path.StackPath`; the
crossings' geometry is :mod:`.neck.flat_crossing`, what the tracker does there
:mod:`.continuation.linkage_limits`)."""
from __future__ import annotations

import numpy as np

from . import flat_crossing as _flat_crossing
from ..numerics.tolerances import DEFINITENESS_TOL

#: A chord constraint whose gradient is below this (times l_ref) is at a linkage limit.
LINKAGE_LIMIT_TOL = 1e-4


class StackLinkage:
    """The linkage-limit descriptions of :class:`.neck.path.StackPath`."""

    def linkage_limit(self, y, s):
        """A description of the linkage limit the state sits at, or '' if none.

        At a linkage limit a chord constraint's gradient (nearly) vanishes: module i's
        rods lie flat along its top chord (rho(i) + rho(i+1) = L1 + L2 for a crossed
        module).  Two branches of configurations cross there, so the equilibrium
        equations are singular although the state may be a strict minimum, and the
        chord's force grows without bound where the load pushes along the fold (see
        ``continuation.linkage_limits.through_linkage_limit``).  So a module nearly flat
        where the equations are singular to rounding at a minimum is at its limit too
        (:meth:`_unresolved`)."""
        if not self.topology.n_chords:
            return ''
        jc = self.point(y, s).constraint_jacobian(self)
        smallest = np.linalg.svd(jc, compute_uv=False)[-1]
        if smallest >= LINKAGE_LIMIT_TOL * self.l_ref and not self._unresolved(y, s, smallest):
            return ''
        i = int(np.argmin(np.linalg.norm(jc, axis=1)))
        force = abs(float(y[self.topology.n_rods + i])) * self.f_ref
        return (f'module {i} folded flat onto its top chord (its rods and chord in one '
                f'line; chord force {force:.3g} N)')

    def flatness(self, y, s):
        """How near the flattest module with a chord above it is to flat (its chord's
        gradient in the module's own angles over l_ref; inf for one module)."""
        return _flat_crossing.flatness(self, y, s)[1]

    def turned_through_base(self, a, b, s):
        """Whether a module with a chord above turned both rods through its base line
        between states ``a`` and ``b`` (see :func:`.neck.flat_crossing.turned_through_base`)."""
        return _flat_crossing.turned_through_base(self, a, b, s)

    def crossing_ways(self, y, s):
        """The ways out of a module's flat crossing next to ``y`` (see
        :func:`.neck.flat_crossing.ways_out`), or None if there is none."""
        return _flat_crossing.ways_out(self, y, s)

    def crossing_rounding(self, y, s):
        """(distance, radius, exact) of ``y`` from a module's flat crossing next to it,
        the chords' rounding radius there (both in rad) and whether the crossing is
        exact to rounding (see :func:`.neck.flat_crossing.rounding`), or None if there is
        none."""
        return _flat_crossing.rounding(self, y, s)

    def _unresolved(self, y, s, smallest):
        """Whether a chord's gradient ``smallest`` is small (< 1e-2 l_ref) and the KKT
        Jacobian singular to rounding (smallest singular value < 1e-15 of its largest)
        where the reduced Hessian passes the margin test: a KKT matrix is singular only
        where its reduced Hessian or its constraint Jacobian is, so the chords are.  A
        module driven flat under load, its chord force growing ~1/angle, is resolved
        only so far: config/neck.yaml under a -10 N head load stopped 1e-4 rad from flat,
        1.3e-9 m short of rho0 + rho1 = 0.24, chord force 8.4e4 N, the Jacobian's
        singular values 1.3e-12 and 1e5 (steps underflowed, 'newton')."""
        if smallest >= 1e-2 * self.l_ref:
            return False
        values = np.linalg.svd(self.jacobian(y, s), compute_uv=False)
        if values[-1] >= 1e-15 * values[0]:
            return False
        eigenvalues = self.eigenvalues(y, s)
        return bool(eigenvalues[0] > DEFINITENESS_TOL * abs(eigenvalues[-1]))
