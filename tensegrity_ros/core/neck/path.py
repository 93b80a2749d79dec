"""The neck as a path problem: :class:`StackPath`, a path of stacks the generic tracker
(:mod:`..continuation`) follows (docs/model.md section 4).

The model -- the chord-on-chord stacking, the reduced coordinates (the 2N rod angles and
one multiplier per chord), the energy, the chord constraints and the reduced Hessian whose
eigenvalues are stiffnesses in N/m -- is :mod:`.model`'s, described there once.  This
module gives it the interface the tracker needs along a path: residual, Jacobian, rates
in s, energy and stability; its overdamped flows (:mod:`.flows`), linkage limits
(:mod:`.linkage`) and what a state means to a user (:mod:`.reporting`) are mixins.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.linalg.lapack import dsygv as _dsygv

from .flows import StackFlows
from .linkage import StackLinkage
from .model import _concatenate, _null_basis, _Point, _solve_gram, _topology, _Values, _vdot, Stack
from .reporting import StackReporting
from ..module.model import InvalidParameterError, mirror_symmetric


class StackPath(StackFlows, StackLinkage, StackReporting):
    """A stack along p(s) = start + s (end - start), as a tracker PathProblem.

    State y = [absolute angles of the 2N rods (rad, from the base x axis),
    multipliers of the N - 1 chord lengths in units of f_ref = max k * l_ref].  Node positions are
    sums of rod vectors, so rods are rigid by construction; each chord is a constraint, scaled
    as (|A3 - A4|^2 - l^2) / (2 l_ref) (metres) so that its multiplier is the chord's
    compression force.  The residual is [dL/dphi / l_ref (N), constraints (m)].
    Stability eigenvalues are those of the reduced Hessian in the Cartesian metric of
    the moving nodes (a generalized symmetric eigenproblem on the constraint tangent
    space): stiffnesses in N/m along orthonormal node displacements, the same numbers
    as in node coordinates.  Every evaluation at one (y, s) is computed once.
    """

    def __init__(self, start: Stack, end: Stack):
        if len(start) != len(end):
            raise InvalidParameterError('start and end stacks differ in size')
        self.start, self.end = start, end
        self.topology = top = _topology(len(start))
        self.n = len(start)
        self.size = top.n_rods + top.n_chords
        self.p0 = start._vector                 # read only (a Stack's own vector)
        self.dp = end._vector - self.p0
        self.g = start.modules[0].g
        zero, one = _Values.of_stack(start, top), _Values.of_stack(end, top)
        self.l_ref, self.f_ref, self.state_weights = zero.scales(top)
        self.half_inv_l_ref = 0.5 / self.l_ref
        self.f_ref_per_l_ref = self.f_ref / self.l_ref
        self.inv_l_ref = 1.0 / self.l_ref
        (self.weight_map, self.chord_rods_scaled, self._jacobian_coefficients,
         self._outer_per_l_ref,
         self._residual_scales) = top.scaled_tables(self.l_ref, self.f_ref)
        self._zero_values = zero
        self._rate_values = _Values.difference(top, one, zero)
        # which parameter groups move along the path (a still group adds nothing to d/ds)
        self._moving = top.groups_moved(self.g, self.dp != 0.0)
        if not (self._moving['rod'] or self._moving['k']):
            # the scales depend on rods and springs only: the end, the next command's
            # start, has these very ones (a stream of actuator commands computes them once)
            _Values.share_scales(one, zero)
        self._values = {0.0: zero, 1.0: one}
        self._point = self._previous_point = None
        self.flow_kernel = None         # the compiled flows (compile_flows), or numpy's

    # -- parameters at s -------------------------------------------------------
    def at(self, s):
        """The parameters at s (:class:`_Values`, reused while s stays the same)."""
        values = self._values.get(s)
        if values is None:
            if len(self._values) > 3:
                self._values.clear()
            values = self._values[s] = _Values.along(self.topology, self._zero_values,
                                                     self._rate_values, s)
        return values

    def parameter_vector(self, s):
        """The stack parameters at s (N x 12, flattened), exactly the end's at s = 1."""
        return self.end._vector if s == 1.0 else self.p0 + s * self.dp

    def parameter_bytes(self, s):
        """:meth:`parameter_vector` as bytes (a record's key), kept on the end stack."""
        return self.end._bytes if s == 1.0 else self.parameter_vector(s).tobytes()

    def params(self, s):
        return self.start.from_vector(self.p0 + s * self.dp)

    def admissible(self, s):
        try:
            self.params(s)
        except ValueError:
            return False
        return True

    def loads(self, s):
        """External force on every node (nodes x 2), base frame."""
        loads = self.topology.load_map(self.g) @ (self.p0 + s * self.dp)
        return np.column_stack([loads.real, loads.imag])

    def point(self, y, s):
        """The evaluated :class:`_Point` at (y, s): the last two are kept, since a
        continuation step goes back and forth between its start and its end (the energy
        test reads both, twice; the next step's tangent starts from the end)."""
        y = np.asarray(y, dtype=float)
        key = (s, y.tobytes())
        p = self._point
        if p is not None and p.key == key:
            return p
        previous = self._previous_point
        if previous is not None and previous.key == key:
            self._point, self._previous_point = previous, p
            return previous
        # (its own copy of y: a caller may change its array in place, as project does)
        self._previous_point, self._point = p, _Point(self, y.copy(), key, self.at(s))
        return self._point

    def nodes(self, y, s):
        """All node positions (nodes x 2) including the fixed A1(0), A2(0)."""
        return self.nodes_at(self.point(y, s))

    def nodes_at(self, p):
        top = self.topology
        x = top.node_rods_c @ p.rods
        x += top.node_base * p.values.rho0
        return x.view(float).reshape(-1, 2)           # (x, y) pairs: complex memory layout

    # -- PathProblem ---------------------------------------------------------------
    def evaluate(self, y, s):
        """A fresh :class:`_Point` at (y, s) (an ndarray), without a cache lookup: for a
        caller that holds its points (the small-command step) and calls the ``*_at``
        methods.  It becomes the cached point, so a record of y after it reuses it."""
        self._previous_point = self._point
        p = self._point = _Point(self, y, (s, y.tobytes()), self.at(s))
        return p

    def residual(self, y, s):
        return self.residual_at(self.point(y, s))

    def residual_at(self, p):
        # [dL/dphi / l_ref, constraints]: the chords' squared lengths are kept on the point
        # (the energy reads them), the scaling is one product (each entry times the same
        # 1 / l_ref or 0.5 / l_ref as alone: the same numbers, ~1 us less per residual)
        top = self.topology
        if not top.n_chords:
            return p.moment.imag * self.inv_l_ref
        return np.concatenate((p.moment.imag, p.squares[top.n_springs:]
                               - p.values.chord_squares)) * self._residual_scales

    def jacobian(self, y, s):
        return self.jacobian_at(self.point(y, s))

    def jacobian_at(self, p):
        n = self.topology.n_rods
        out = np.zeros((self.size, self.size))
        np.multiply(p.hessian(self), self.inv_l_ref, out=out[:n, :n])
        if self.topology.n_chords:
            jc = out[n:, :n] = p.constraint_jacobian(self)
            np.multiply(jc.T, self.f_ref_per_l_ref, out=out[:n, n:])
        return out

    def prediction_jacobian_at(self, p):
        """:meth:`jacobian_at` at a point whose Hessian and constraint Jacobian are not
        made (Newton's prediction in a small step), in fewer operations: with u = (rods,
        chords), every entry is Re(conj(u_a) u_b c_ab) -- stiffness (E^T W E)_ab / l_ref
        in the Hessian block, -i or i times the scaled chord rods in the constraint
        blocks -- less the moments / l_ref on the diagonal.  (Equal to :meth:`jacobian_at`
        to rounding; a real view of a complex array, for a LAPACK factorization.)"""
        n, size = self.topology.n_rods, self.size
        u = _concatenate((p.rods, p.diff[self.topology.n_springs:]))
        table = self._jacobian_coefficients.copy()
        table[:n, :n] = p.weights.dot(self._outer_per_l_ref).reshape(n, n)
        table *= u.conj()[:, None]
        table *= u
        table.reshape(size * size)[:n * (size + 1):size + 1] -= p.moment.real * self.inv_l_ref
        return table.real

    def _rates(self, p):
        """At fixed state, kept in the point: (rate of the rod lengths / length, d(rod
        vectors)/ds, d(element differences)/ds, Re(conj(diff) d diff/ds)); ``None`` for
        what does not move (rigid rods; no element moves where rods and base are still:
        an actuator command to a module above the first changes chord lengths only)."""
        if p.rates is None:
            rate = self._rate_values
            if not self._moving['rod']:             # rigid rods: only the base moves
                if not self._moving['shift']:
                    p.rates = None, None, None, None
                else:
                    p.rates = None, None, rate.shift, p.diff.real * rate.shift
                return p.rates
            ratio = rate.rod / p.values.rod
            d_rods = p.rods * ratio
            d_diff = self.topology.element_rods_c.dot(d_rods)
            d_diff += rate.shift
            p.rates = ratio, d_rods, d_diff, (p.diff.conj() * d_diff).real
        return p.rates

    def residual_s(self, y, s):
        """dF/ds at fixed state (analytic: parameters move linearly along the path)."""
        return self.residual_s_at(self.point(y, s))

    def residual_s_at(self, p):
        top, rate = self.topology, self._rate_values
        ratio, _, d_diff, cross = self._rates(p)
        moving = self._moving
        n, ns = top.n_rods, top.n_springs
        d_weighted = None if d_diff is None else p.weights * d_diff
        if moving['k']:
            spring_rates = rate.weights * p.diff                  # (complex where rods are still)
            d_weighted = spring_rates if d_weighted is None else d_weighted + spring_rates
        if d_weighted is None and not moving['rod_loads']:
            out = np.zeros(self.size)       # no force moves (and the rods are still)
        else:
            out = np.empty(self.size)
            if d_weighted is None:
                d_force = -rate.rod_loads
            else:
                d_force = top.element_rods_tc.dot(d_weighted)
                if moving['rod_loads']:
                    d_force -= rate.rod_loads
            # d Im(conj(v) f) with dv = ratio v: Im(conj(v) df) + ratio Im(conj(v) f)
            d_gradient = (p.rods.conj() * d_force).imag
            if ratio is not None:
                d_gradient += ratio * p.moment.imag
            out[:n] = d_gradient * self.inv_l_ref
        chord_rates = p.values.chord * rate.chord
        if cross is None:
            np.multiply(chord_rates, -self.inv_l_ref, out=out[n:])
        else:
            out[n:] = (cross[ns:] - chord_rates) * self.inv_l_ref
        return out

    def energy(self, y, s):
        """The Lagrangian U + mu . c (equal to U on the constraint manifold)."""
        return self.energy_at(self.point(y, s))

    def energy_at(self, p):
        # U + mu . c = (1/2) w . |d|^2 - (loads' work) - mu . l^2 / (2 l_ref): the element
        # weights w are the stiffnesses and mu / l_ref (one product for springs and chords)
        v = p.values
        energy = (0.5 * p.weights.dot(p.squares) - _vdot(v.rod_loads, p.rods).real
                  - v.base_load * v.rho0)
        if self.topology.n_chords:
            energy -= self.half_inv_l_ref * p.mu.dot(v.chord_squares)
        return float(energy)

    def energy_and_rate(self, y, s):
        """(energy, energy_s) at one point, sharing their terms."""
        return self.energy(y, s), self.energy_s(y, s)

    def energy_s(self, y, s):
        """dL/ds at fixed state (the envelope theorem's side of the tracker's energy check)."""
        return self.energy_s_at(self.point(y, s))

    def energy_s_at(self, p):
        v, rate, ns = p.values, self._rate_values, self.topology.n_springs
        _, d_rods, _, cross = self._rates(p)
        moving = self._moving
        springs = 0.0 if cross is None else float(p.weights.dot(cross))
        if moving['k']:
            springs += 0.5 * float(rate.k.dot(p.squares[:ns]))
        work = rate.base_load * v.rho0 + v.base_load * rate.rho0
        if moving['rod_loads']:
            work += _vdot(rate.rod_loads, p.rods).real
        if d_rods is not None:
            work += _vdot(v.rod_loads, d_rods).real
        if not self.topology.n_chords:
            return springs - work
        return springs - work - float(p.mu.dot(v.chord * rate.chord)) / self.l_ref

    def _reduced(self, y, s):
        """(reduced Hessian, reduced metric, null basis Z, point) on the tangent space."""
        return self._reduced_at(self.point(y, s))

    def _reduced_at(self, p):
        top = self.topology
        if not top.n_chords:
            return p.hessian(self), p.metric(self), top.identity, p
        p.products(self)            # the Gram matrix and constraint Jacobian in one product
        z = _null_basis(p.constraint_jacobian(self), top.trailing_columns)
        (hessian, metric), zt = p.pair(self), z.T
        return zt.dot(hessian).dot(z), zt.dot(metric).dot(z), z, p

    def eigenvalues(self, y, s):
        return self.eigenvalues_at(self.point(y, s))

    def eigenvalues_at(self, p):
        a, b, _, _ = self._reduced_at(p)
        if self.topology.n_chords:
            # fresh C-ordered symmetric reductions: their transposes are Fortran-ordered
            # views that LAPACK may overwrite, so it copies nothing (half the call)
            values, _, info = _dsygv(a.T, b.T, 1, 'N', overwrite_a=1, overwrite_b=1)
        else:                                   # the point's own matrices: not to be overwritten
            values, _, info = _dsygv(a, b, 1, 'N')
        if info != 0:
            raise np.linalg.LinAlgError(f'reduced eigenproblem failed (dsygv info={info})')
        return values

    def stability(self, y, s):
        """Reduced-Hessian eigenvalues and the matching state-space modes (Z v, d mu)."""
        a, b, z, p = self._reduced(y, s)
        values, vectors, info = _dsygv(a, b, jobz='V')
        if info != 0:
            raise np.linalg.LinAlgError(f'reduced eigenproblem failed (dsygv info={info})')
        dphi = z @ vectors
        jc = p.constraint_jacobian(self)
        dmu = -_solve_gram(jc, jc @ (p.hessian(self) @ dphi)) / self.f_ref
        return values, np.vstack([dphi, dmu])

    def motion(self, y, s, dy):
        """The largest node displacement (over l_ref) the rod-angle change in ``dy``
        makes at (y, s), to first order: the step bound's measure of a step (see
        :meth:`motion_at`)."""
        return self.motion_at(self.point(y, s), dy)

    def motion_at(self, p, dy):
        """:meth:`motion` at the point ``p``.  The state weights bound it by the longest
        chain of rods times the largest angle change (every rod of a chain turning the
        same way); computed, it is 2 to 5 times less on the neck paths of
        test/neck_path_families.py, and so are the steps a command needs."""
        top = self.topology
        displacement = top.node_rods_c.dot(p.rods * dy[:top.n_rods])
        return max(map(abs, displacement.tolist()), default=0.0) * self.inv_l_ref

    def canonical(self, y):
        """The state with the rod angles wrapped to [-pi, pi) (for comparing states)."""
        y = np.array(y, dtype=float)
        n = self.topology.n_rods
        y[:n] = (y[:n] + math.pi) % (2.0 * math.pi) - math.pi
        return y

    def mirror(self, y, s):
        """The mirror image of ``y`` (the neck reflected about its base's perpendicular
        bisector: each module's rods swap, (t1, t2) -> (t2, t1), so absolute rod angles
        (phi1, phi2) -> (pi - phi2, pi - phi1); chord forces stay), or None where the
        stack is not mirror-symmetric at s."""
        if not mirror_symmetric(self.parameter_vector(s)):
            return None
        y = np.array(y, dtype=float)
        n = self.topology.n_rods
        y[:n] = (math.pi - y[:n].reshape(-1, 2)[:, ::-1]).ravel()
        return y

    def whole_turns_removed(self, y):
        """``y`` with every rod angle beyond [-3 pi, 3 pi] brought back to [-pi, pi] by
        whole turns, the others untouched bit for bit (``y`` itself where none is beyond).

        A landing flow can turn a rod many times (seen: 4.3e4 rad after a jump from a
        module folded flat); a state kept so loosens every later Newton stop, which is
        relative to 1 + |y| (by 4e4 there: ~4e-7 rad).  Within 3 pi it is loosened at most
        ~10-fold, and such a state is left as it is: a state 1e-11 in s past a branch
        point is sensitive to the last bit of its angles (rounding amplified by
        1 / lambda_min), so wrapping every one would move those answers."""
        n = self.topology.n_rods
        angles = np.asarray(y[:n])
        turns = np.where(np.abs(angles) > 3.0 * math.pi, np.round(angles / (2.0 * math.pi)), 0.0)
        if not turns.any():
            return y
        y = np.array(y, dtype=float)
        y[:n] -= 2.0 * math.pi * turns
        return y
