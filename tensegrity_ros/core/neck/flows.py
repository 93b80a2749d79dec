"""How a neck moves at frozen parameters: the overdamped flows the tracker lands by, and the
projection onto the chord constraints (a mixin of :class:`.neck.path.StackPath`)."""
from __future__ import annotations

import numpy as np
from scipy.linalg.lapack import dpotrf as _dpotrf, dpotrs as _dpotrs, dsyevd as _dsyevd

from .model import _null_basis, _Point, _solve_gram, _solve_guarded

# Landing flow near kinematic singularities: the constraint Gram matrix (entries ~1)
# is damped by up to _DAMPING once its smallest eigenvalue falls below _DAMPING_ONSET.
_DAMPING = 1e-3
_DAMPING_ONSET = 1e-2
#: Largest Gauss-Newton step of :meth:`StackPath.project` (rad, the fastest rod): next
#: to a module folded flat the chord's gradient vanishes and the full step is unbounded
#: (4.3e4 rad seen: bench_round_commands seed 0, stream 11), which lands on an arbitrary
#: configuration, not a nearby one; shorter steps reach the arm of the chord's solution
#: set next to the state.
PROJECT_STEP = 0.1
#: A state meets the chord constraints if it misses none by more than this (times
#: l_ref): :meth:`StackPath.project` stalls at ~1e-13 where an admissible state is near,
#: and misses by 1e-5 or more past a linkage limit, where none is.
PROJECTION_TOL = 1e-9


def _cholesky(matrix):
    """The upper Cholesky factor of a symmetric positive definite ``matrix`` (LAPACK
    directly: numpy.linalg's per-call checks cost ~20 us on these small matrices, 20
    times the solve itself, and a landing flow solves ~10^4 times)."""
    factor, info = _dpotrf(matrix, lower=0, clean=0)
    if info != 0:
        raise np.linalg.LinAlgError(f'not positive definite (dpotrf info={info})')
    return factor


def _cho_solve(factor, rhs):
    """matrix^-1 rhs from :func:`_cholesky`'s factor."""
    x, info = _dpotrs(factor, rhs, lower=0)
    if info != 0:
        raise np.linalg.LinAlgError(f'dpotrs info={info}')
    return x


def _spd_solve(matrix, rhs):
    return _cho_solve(_cholesky(matrix), rhs)


def _smallest_eigenvalue(matrix):
    """The smallest eigenvalue of a small symmetric ``matrix``."""
    if matrix.shape[0] == 1:
        return float(matrix[0, 0])
    values, _, info = _dsyevd(matrix, compute_v=0)
    if info != 0:
        raise np.linalg.LinAlgError(f'dsyevd info={info}')
    return float(values[0])


def _smallest_below_onset(gram):
    """The smallest eigenvalue of the chords' Gram matrix where it is below
    ``_DAMPING_ONSET`` (the flows damp), else None.  A Cholesky factorization of gram -
    onset I that succeeds proves there is none below (to rounding, where the damping
    would add ~1e-3 (1e-16)^2: nothing), in ~1 us where the eigenvalue costs ~5 (a
    landing flow asks at every evaluation)."""
    shifted = gram - _DAMPING_ONSET * np.eye(len(gram))
    if _dpotrf(shifted, lower=0, clean=0, overwrite_a=1)[1] == 0:
        return None
    smallest = _smallest_eigenvalue(gram)
    return smallest if smallest < _DAMPING_ONSET else None


class StackFlows:
    """The flows and the projection of :class:`.neck.path.StackPath`.  The metric, the
    chords' Gram matrix and the reduced metric are positive definite: they are solved
    by their Cholesky factors."""

    def _unconstrained_gradient(self, p):
        """dU/dphi without the chord forces (2N,)."""
        top = self.topology
        ns = top.n_springs
        springs = top.element_rods_t[:, :ns] @ (p.weights[:ns] * p.diff[:ns])
        return (p.rods.conj() * (springs - p.values.rod_loads)).imag

    def compile_flows(self):
        """Evaluate :meth:`descent` and :meth:`damped` by the compiled kernels of
        :mod:`.neck.flow_kernel` from now on (where numba is available)."""
        from . import flow_kernel
        self.flow_kernel = flow_kernel.compiled()
        if self.flow_kernel is not None and self.weight_map is None:
            self._no_weight_map = np.zeros((len(self.topology.element_rods_c), 0))

    def _kernel_arguments(self, y, s):
        """(y, n, n_springs, rod, shift, weights, weight map, element-rod map) of the
        compiled kernels at (y, s)."""
        values, top = self.at(s), self.topology
        weight_map = self.weight_map if self.weight_map is not None else self._no_weight_map
        return (np.asarray(y, dtype=float), top.n_rods, top.n_springs, values.rod,
                values.shift, values.weights, weight_map, top.element_rods_c), values

    def descent(self, y, s):
        """Overdamped velocity in the Cartesian metric of the nodes: the projected force
        plus a pull back onto the chord constraints."""
        if self.flow_kernel is not None:
            (y, n, ns, *common), values = self._kernel_arguments(y, s)
            out = self.flow_kernel.descent(
                y, self.size, n, ns, *common, self.topology.element_rods_t,
                values.rod_loads, self.topology.mobility, self.chord_rods_scaled,
                values.chord_squares, self.half_inv_l_ref, self._pull_rate(values),
                _DAMPING, _DAMPING_ONSET)
            if not out.size:
                raise np.linalg.LinAlgError('not positive definite (compiled descent)')
            return out
        p = self.point(y, s)
        metric = _cholesky(p.metric(self))
        free = _cho_solve(metric, self._unconstrained_gradient(p))
        if not self.topology.n_chords:
            return -free
        jc, mobility_jc, gram, rate = self._damped_constraints(p, metric)
        correction = _spd_solve(gram, jc @ free - rate * p.constraints(self))
        out = np.zeros(self.size)
        out[:len(free)] = -free + mobility_jc @ correction
        return out

    def _damped_constraints(self, p, metric):
        """(constraint Jacobian, metric^-1 jc^T, their Gram matrix damped, pull rate)
        for the overdamped flows (``metric``: the metric's Cholesky factor).  Damped
        (Levenberg): smooth through kinematic singularities of the stack, where rods fold
        flat onto a chord and the constraint rows degenerate."""
        jc, mobility_jc, gram, smallest = self._chord_gram(p, metric)
        if smallest is not None:
            gram = gram + _DAMPING * (1.0 - smallest / _DAMPING_ONSET) ** 2 * np.eye(len(jc))
        return jc, mobility_jc, gram, self._pull_rate(p.values)

    def _pull_rate(self, values):
        """The flows' rate of pull onto the chords, 2 max k (kept for the last values:
        a flow evaluates hundreds of states at one s)."""
        kept = getattr(self, '_kept_pull_rate', None)
        if kept is None or kept[0] is not values:
            kept = self._kept_pull_rate = (values, float(np.max(values.k)) * 2.0)
        return kept[1]

    def _chord_gram(self, p, metric=None):
        """(constraint Jacobian, metric^-1 jc^T, their Gram matrix, its smallest
        eigenvalue where below ``_DAMPING_ONSET``, else None): whether the flows damp."""
        jc = p.constraint_jacobian(self)
        if metric is None:
            metric = _cholesky(p.metric(self))
        mobility_jc = _cho_solve(metric, jc.T)
        gram = jc @ mobility_jc
        return jc, mobility_jc, gram, _smallest_below_onset(gram)

    def damped(self, y, s):
        """Whether :meth:`descent` damps its projection at ``y`` (a module so near flat
        that the Gram matrix of the chord gradients has an eigenvalue below
        ``_DAMPING_ONSET``): there it flows as a neck of slightly elastic chords, not as
        the rigid-chord model, and may pass a module through flat where the rigid
        mechanism does not (see :meth:`rigid_descent`)."""
        if not self.topology.n_chords:
            return False
        if self.flow_kernel is not None:
            (y, n, ns, *common), _ = self._kernel_arguments(y, s)
            found = self.flow_kernel.damped(y, n, ns, *common, self.topology.mobility,
                                            self.chord_rods_scaled, _DAMPING_ONSET)
            if found < 0:
                raise np.linalg.LinAlgError('not positive definite (compiled damped)')
            return bool(found)
        return self._chord_gram(self.point(y, s))[3] is not None

    def rigid_descent(self, y, s):
        """:meth:`descent` with the force projected exactly (through a null basis of the
        constraints, not the damped Gram inverse), so that it rests only where the
        rigid-chord model is in equilibrium; only the pull onto the constraints is damped.

        Near a module folded almost flat (the Gram matrix's smallest eigenvalue below
        ``_DAMPING_ONSET``) :meth:`descent` damps the projection too: it glides through
        the kinematic singularity as a neck of slightly elastic chords would, but rests
        there off the constraints by ~damping * chord force / rate (5e-5 m on
        config/neck.yaml), where no Newton from its projection may find the landing.
        The tracker's landing flow starts over with this one where it rested so."""
        p = self.point(y, s)
        metric = p.metric(self)
        gradient = self._unconstrained_gradient(p)
        factor = _cholesky(metric)
        if not self.topology.n_chords:
            return -_cho_solve(factor, gradient)
        jc, mobility_jc, gram, rate = self._damped_constraints(p, factor)
        z = _null_basis(jc, self.topology.trailing_columns)
        tangential = z @ _spd_solve(z.T @ metric @ z, z.T @ gradient)
        pull = mobility_jc @ _spd_solve(gram, rate * p.constraints(self))
        out = np.zeros(self.size)
        out[:len(gradient)] = -tangential - pull
        return out

    def descent_jacobian(self, y, s):
        """d(:meth:`descent`)/dy at (y, s), for LSODA's implicit corrector (which
        otherwise makes it by finite differences: one velocity per state component, a
        third of a landing flow's evaluations): see :meth:`_flow_jacobian`."""
        return self._flow_jacobian(y, s, rigid=False)

    def rigid_descent_jacobian(self, y, s):
        """d(:meth:`rigid_descent`)/dy at (y, s), as :meth:`descent_jacobian`."""
        return self._flow_jacobian(y, s, rigid=True)

    def _flow_jacobian(self, y, s, rigid):
        """The Jacobian of a flow's velocity v = -K g - rate M^-1 Jc^T G^-1 c, K the
        metric's inverse on the chords' tangent space (exact through a null basis for
        the rigid flow, by the damped Gram matrix for the elastic one): dK g = K (H_L -
        dM t) - M^-1 Jc^T G^-1 (dJc t), with t = K g the tangential velocity and H_L
        the Hessian at the multipliers G^-1 Jc M^-1 g; the pull's derivative is taken
        at c = 0 and the damping's as constant (the corrector needs only an
        approximation: to ~1e-2 of finite differences where damped, ~1e-8 elsewhere,
        on 800 states of bench_neck_paths' slowest flows).  Multipliers have zero
        velocity and enter none: their rows and columns are zero."""
        p = self.point(y, s)
        n = self.topology.n_rods
        out = np.zeros((self.size, self.size))
        metric = p.metric(self)
        factor = _cholesky(metric)
        gradient = self._unconstrained_gradient(p)
        if not self.topology.n_chords:
            velocity = _cho_solve(factor, gradient)
            out[:n, :n] = -_cho_solve(factor, self._multiplied_hessian(p, y, None)
                                      - self._turning(p, velocity)[1])
            return out
        jc, mobility_jc, damped, rate = self._damped_constraints(p, factor)
        gram = damped = _cholesky(damped)
        if rigid:
            try:
                gram = _cholesky(jc @ mobility_jc)
            except np.linalg.LinAlgError:       # at a flat crossing: damped
                pass
            z = _null_basis(jc, self.topology.trailing_columns)
            reduced = _cholesky(z.T @ metric @ z)

            def tangent(x):
                return z @ _cho_solve(reduced, z.T @ x)
        else:
            def tangent(x):
                w = _cho_solve(factor, x)
                return w - mobility_jc @ _cho_solve(gram, jc @ w)
        force = _cho_solve(gram, jc @ _cho_solve(factor, gradient))
        curvature, metric_rate = self._turning(p, tangent(gradient))
        out[:n, :n] = (mobility_jc @ _cho_solve(gram, curvature)
                       - tangent(self._multiplied_hessian(p, y, force) - metric_rate)
                       - rate * (mobility_jc @ _cho_solve(damped, jc)))
        return out

    def _multiplied_hessian(self, p, y, force):
        """d2L/dphi2 at ``p``'s angles with the chord forces ``force`` (None: none)."""
        if force is None:
            return p.hessian(self)
        at = np.array(y, dtype=float)
        at[self.topology.n_rods:] = -force / self.f_ref
        return _Point(self, at, None, p.values).hessian(self)

    def _turning(self, p, t):
        """(d(Jc t)/dphi, d(M t)/dphi) at fixed t (the rods turned, the constraint
        gradients and the metric turn with them)."""
        top, rods = self.topology, p.rods
        crossed = (rods[:, None] * rods.conj()).imag * top.mobility
        metric_rate = crossed * t
        metric_rate.reshape(-1)[::len(t) + 1] -= crossed @ t
        if not top.n_chords:
            return None, metric_rate
        moved = top.chord_rods @ (t * rods)
        curvature = (t * (p.chords(self)[:, None].conj() * rods).real
                     - (rods.conj() * moved[:, None]).real) * self.chord_rods_scaled
        return curvature, metric_rate

    def project(self, y, s):
        """Nearby admissible rod angles (Gauss-Newton in the node metric, each step at
        most ``PROJECT_STEP``) and least-squares multipliers.  Where no admissible state
        is near (past a linkage limit) the angles it returns miss the chords:
        :meth:`on_constraints` tells."""
        top = self.topology
        y = np.array(y, dtype=float)
        if not top.n_chords:
            return y
        for _ in range(50):
            p = self.point(y, s)
            c = p.constraints(self)
            if np.max(np.abs(c)) < 1e-15 * self.l_ref:
                break
            jc = p.constraint_jacobian(self)
            mobility_jc = np.linalg.solve(p.metric(self), jc.T)
            step = mobility_jc @ _solve_guarded(jc @ mobility_jc, c)
            y[:top.n_rods] -= step * min(1.0, PROJECT_STEP / max(np.max(np.abs(step)), 1e-300))
        p = self.point(y, s)
        jc = p.constraint_jacobian(self)
        y[top.n_rods:] = -_solve_gram(jc, jc @ self._unconstrained_gradient(p)) / self.f_ref
        return y

    def on_constraints(self, y, s):
        """Whether ``y`` meets every chord constraint at s to ``PROJECTION_TOL`` l_ref
        (:meth:`project` may not bring a state there: past a linkage limit no admissible
        state is near)."""
        if not self.topology.n_chords:
            return True
        c = self.point(y, s).constraints(self)
        return bool(np.max(np.abs(c)) <= PROJECTION_TOL * self.l_ref)
