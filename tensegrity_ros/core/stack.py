"""The neck stack: N modules with coupled statics (DESIGN.md section 4).

Module i+1 sits on module i's top chord: A1(i+1) = A4(i), A2(i+1) = A3(i), and
module i+1's telescopic rod is that chord, |A3(i) - A4(i)| = rho(i+1).  Module
i+1's base frame has its origin at A4(i) and its x axis along A4(i) -> A3(i).

Coordinates (a reduced formulation).  The unknowns are the absolute angles of
the 2N rods and one Lagrange multiplier per chord (N - 1): 3N - 1 unknowns.
Every node is A2(0) or the origin plus a sum of rod vectors, so the rods are
rigid by construction, and the energy (zero-free-length springs, constant
loads) and the chord constraints are quadratic in the rod vectors: all first
and second derivatives are exact and cheap.  Equilibria are KKT points;
stability is the reduced Hessian (the Hessian of the Lagrangian on the tangent
space of the chord constraints) being positive definite.  Its eigenvalues are
taken in the Cartesian metric of the moving nodes, so that they are
stiffnesses in N/m along orthonormal node displacements, as in node
coordinates (for one module the module solver reports J/rad^2 along the angles
instead: same signs, same critical points, different units).

Every module keeps its A3A4 spring.  In a lower module it is in parallel with
the chord (a rigid length), so it has no effect on equilibria or stability;
it only loads the actuator of the module above, as a real stack of identical
modules would.  Loads are given in the base frame; a uniform rod's weight is
split exactly into half its weight at each end (a lower end resting on a
lower module loads that module).
"""
from __future__ import annotations

import cmath
import functools
import math
import operator
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg.lapack import dgeqrf as _dgeqrf, dormqr as _dormqr, dsygv as _dsygv
from scipy.optimize import root

from . import continuation as _continuation
from . import flat_crossing as _flat_crossing
from .continuation import TrackerSettings
from .module import ModuleParams, PARAMETER_NAMES, InvalidParameterError, mirror_symmetric
from .stack_fast_step import keep_final_point, whole_command_step
from .tolerances import DEFINITENESS_TOL, verified_minimum

# numpy's C routines without their __array_function__ dispatch (~0.2 us a call on these
# small operands, as ndarray.dot against np.dot): the same routine, the same numbers.  Used
# where the small-command step calls them (a few dozen calls a command).
_vdot = getattr(np.vdot, '_implementation', np.vdot)
_concatenate = getattr(np.concatenate, '_implementation', np.concatenate)
_P = {name: i for i, name in enumerate(PARAMETER_NAMES)}
_PARAMETERS_OF = operator.attrgetter(*PARAMETER_NAMES)     # a module's parameters, in order
_FIXED = 2          # A1(0) and A2(0) are the first two entries of the node table
# Landing flow near kinematic singularities: the constraint Gram matrix (entries ~1)
# is damped by up to _DAMPING once its smallest eigenvalue falls below _DAMPING_ONSET.
_DAMPING = 1e-3
_DAMPING_ONSET = 1e-2
_FRAME_SIGNS, _ANGLE_SIGNS = np.array([1.0, -1.0]), np.array([-1.0, 1.0])  # StackPath.angles_at
_BASE_AXIS = np.ones(1, dtype=complex)      # module 0's x axis A1(0) -> A2(0), as a chord
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
#: A chord constraint whose gradient is below this (times l_ref) is at a linkage limit.
LINKAGE_LIMIT_TOL = 1e-4
#: The value groups whose rates along a path the s-derivatives skip where they are still.
_RATE_GROUPS = ('rod', 'k', 'rod_loads', 'shift')


def _solve_guarded(matrix, rhs):
    """matrix^-1 rhs, or the least-squares answer where ``matrix`` (a constraint Gram
    matrix) is singular: a kinematically singular stack, rods folded flat onto a chord."""
    try:
        return np.linalg.solve(matrix, rhs)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(matrix, rhs, rcond=None)[0]


def _solve_gram(jc, rhs):
    """(J J^T)^-1 rhs, guarded as :func:`_solve_guarded`."""
    return _solve_guarded(jc @ jc.T, rhs)


@dataclass(frozen=True)
class Stack:
    """Modules bottom to top.  ``modules[i].rho`` is module i's actuator length
    (for i >= 1: the length of module i-1's top chord)."""

    modules: tuple

    def __post_init__(self):
        modules = tuple(self.modules)
        if not modules:
            raise InvalidParameterError('a stack needs at least one module')
        for i, m in enumerate(modules):
            if not isinstance(m, ModuleParams):
                raise InvalidParameterError(
                    f'module {i} must be ModuleParams, got {type(m).__name__}')
        if len({m.g for m in modules}) != 1:
            raise InvalidParameterError('all modules must use the same gravity')
        object.__setattr__(self, 'modules', modules)

    def __len__(self):
        return len(self.modules)

    def vector(self):
        """The parameters of every module (N x 12, flattened; a fresh copy)."""
        return self._vector.copy()

    @functools.cached_property
    def _vector(self):
        return np.array([_PARAMETERS_OF(m) for m in self.modules], dtype=float).ravel()

    @functools.cached_property
    def _bytes(self):
        return self._vector.tobytes()

    def from_vector(self, values):
        values = np.asarray(values, dtype=float).reshape(len(self), len(PARAMETER_NAMES))
        return Stack(tuple(ModuleParams.from_vector(v, g=self.modules[0].g) for v in values))

    def with_module(self, index, **changes):
        modules = list(self.modules)
        modules[index] = modules[index].with_(**changes)
        return Stack(tuple(modules))


class _Topology:
    """Index tables of the node graph of an N-module stack, in rod vectors.

    Node table: 0 = A1(0), 1 = A2(0) (fixed), 2 + 2i = A3(i), 3 + 2i = A4(i).
    Rod 2i is module i's A1A3 (length L1), rod 2i + 1 its A2A4 (L2).  Every node is
    ``node_base[k] * P + node_rods[k] @ v`` with P = A2(0) = rho(0) and v the rod
    vectors, all as complex numbers x + iy: A3(i) = A1(i) + v[2i], A4(i) = A2(i) + v[2i+1].
    Elements are the springs (ka: A2A3, kb: A1A4, kc: A3A4 of every module) and then
    the chords A3(i)A4(i), i < N - 1 (rigid: the rod of module i + 1), as Xa - Xb.
    Every parameter enters through a fixed index or a linear map of the stack's
    parameter vector (N x 12, flattened).
    """

    def __init__(self, n):
        self.n = n
        a3 = lambda i: 2 + 2 * i
        a4 = lambda i: 3 + 2 * i
        a1 = lambda i: 0 if i == 0 else a4(i - 1)
        a2 = lambda i: 1 if i == 0 else a3(i - 1)
        self.a1, self.a2, self.a3, self.a4 = a1, a2, a3, a4
        self.nodes = 2 + 2 * n
        self.n_rods = 2 * n
        self.n_chords = n - 1
        rods = np.zeros((self.nodes, self.n_rods))
        base = np.zeros(self.nodes)
        base[1] = 1.0
        for i in range(n):
            rods[a3(i)], base[a3(i)] = rods[a1(i)], base[a1(i)]
            rods[a3(i), 2 * i] = 1.0
            rods[a4(i)], base[a4(i)] = rods[a2(i)], base[a2(i)]
            rods[a4(i), 2 * i + 1] = 1.0
        self.node_rods, self.node_base = rods, base
        index = lambda i, name: i * len(PARAMETER_NAMES) + _P[name]
        springs, self.spring_index = [], []
        for i in range(n):
            springs += [(a2(i), a3(i)), (a1(i), a4(i)), (a3(i), a4(i))]
            self.spring_index += [index(i, 'ka'), index(i, 'kb'), index(i, 'kc')]
        chords = [(a3(i), a4(i)) for i in range(n - 1)]
        self.chord_index = [index(i + 1, 'rho') for i in range(n - 1)]
        self.rod_index = [index(i, name) for i in range(n) for name in ('L1', 'L2')]
        self.rho0_index = index(0, 'rho')
        self.element_ends = springs + chords
        self.rod_ends = [pair for i in range(n) for pair in ((a1(i), a3(i)), (a2(i), a4(i)))]
        ends = np.array(self.element_ends, dtype=int).reshape(-1, 2)
        self.element_rods = rods[ends[:, 0]] - rods[ends[:, 1]]          # (elements, 2N)
        self.element_rods_t = np.ascontiguousarray(self.element_rods.T)
        # complex copies for products with rod vectors (no real-to-complex cast per call)
        self.element_rods_c = self.element_rods.astype(complex)
        self.element_rods_tc = self.element_rods_t.astype(complex)
        self.node_rods_c = rods.astype(complex)
        self.element_base = base[ends[:, 0]] - base[ends[:, 1]]
        self.chord_rods = self.element_rods[len(springs):]
        self.n_springs = len(springs)
        self.mobility = rods[_FIXED:].T @ rods[_FIXED:]   # moving nodes shared by two rods
        self.identity = np.eye(self.n_rods)
        # Q of a QR of the constraint Jacobian^T applied to these: a null basis (_null_basis)
        self.trailing_columns = np.eye(self.n_rods)[:, self.n_chords:]
        self.trailing_columns.flags.writeable = False
        # K = E^T diag(w) E as one product: (w @ element_outer).reshape(2N, 2N)
        self.element_outer = np.einsum('er,eq->erq', self.element_rods,
                                       self.element_rods).reshape(len(ends), -1)
        self.angle_mask = np.concatenate([np.ones(self.n_rods), np.zeros(self.n_chords)])
        # loads: complex node forces = (forces + g * weights) @ parameters
        forces = np.zeros((self.nodes, n * len(PARAMETER_NAMES)), dtype=complex)
        weights = np.zeros((self.nodes, n * len(PARAMETER_NAMES)))
        for i in range(n):
            forces[a3(i), index(i, 'f3x')] += 1.0
            forces[a3(i), index(i, 'f3y')] += 1j
            forces[a4(i), index(i, 'f4x')] += 1.0
            forces[a4(i), index(i, 'f4y')] += 1j
            for node in (a1(i), a3(i)):
                weights[node, index(i, 'm1')] -= 0.5
            for node in (a2(i), a4(i)):
                weights[node, index(i, 'm2')] -= 0.5
        self.load_forces, self.load_weights = forces, 1j * weights
        self._load_maps, self._value_maps, self._scaled_tables = {}, {}, {}
        self._groups_moved = {}
        sizes = (('rod_loads', 2 * self.n_rods), ('k', len(springs)), ('chord', self.n_chords),
                 ('rod', self.n_rods), ('shift', len(ends)), ('weights', len(ends)),
                 ('base_load', None), ('rho0', None))
        self.value_layout, start = {}, 0
        for name, size in sizes:
            self.value_layout[name] = start if size is None else slice(start, start + size)
            start += 1 if size is None else size
        # the array groups of packed values as views, in one call (base_load, rho0: the last two)
        self.value_views = operator.itemgetter(*(self.value_layout[name] for name in (
            'rod_loads', 'k', 'chord', 'rod', 'shift', 'weights')))

    def scaled_tables(self, l_ref, f_ref):
        """(weight map, chord rods * -1 / l_ref, Jacobian coefficients, element outer
        products / l_ref, residual scales) of a path with these scales (kept: a stream of
        actuator commands shares them).  The weight map takes a state to the chords' element
        weights: multiplier j (state entry 2N + j) times f_ref / l_ref is the weight of
        element n_springs + j (None without chords).  The Jacobian coefficients are
        those of :meth:`StackPath.prediction_jacobian_at` without the stiffness block.
        The residual scales are 1 / l_ref (2N torques) then 0.5 / l_ref (N - 1 chords):
        :meth:`StackPath.residual_at` scales the whole residual in one product."""
        key = (l_ref, f_ref)
        found = self._scaled_tables.get(key)
        if found is None:
            if len(self._scaled_tables) > 16:
                self._scaled_tables.clear()
            n, size = self.n_rods, self.n_rods + self.n_chords
            weight_map = None
            chord_rods = self.chord_rods * -(1.0 / l_ref)
            coefficients = np.zeros((size, size), dtype=complex)
            if self.n_chords:
                weight_map = np.zeros((len(self.element_ends), size))
                chords = np.arange(self.n_chords)
                weight_map[self.n_springs + chords, n + chords] = f_ref / l_ref
                coefficients[n:, :n] = -1j * chord_rods
                coefficients[:n, n:] = 1j * (f_ref / l_ref) * chord_rods.T
            residual_scales = np.concatenate((np.full(n, 1.0 / l_ref),
                                              np.full(self.n_chords, 0.5 / l_ref)))
            found = (weight_map, chord_rods, coefficients, self.element_outer * (1.0 / l_ref),
                     residual_scales)
            for table in found:
                if table is not None:
                    table.flags.writeable = False      # shared by every path of these scales
            self._scaled_tables[key] = found
        return found

    def groups_moved(self, g, changed):
        """{group: whether it moves} for the value groups of :data:`_RATE_GROUPS`, when the
        parameters flagged in ``changed`` (a boolean vector, 12N) change under gravity g:
        a group moves where the value map ties it to a changed parameter.  Kept per set of
        changed parameters (a stream of actuator commands changes the same few), a copy
        returned."""
        key = (g, changed.tobytes())
        found = self._groups_moved.get(key)
        if found is None:
            if len(self._groups_moved) > 64:
                self._groups_moved.clear()
            columns = self.value_map(g)[:, changed]
            found = self._groups_moved[key] = {
                name: bool(np.any(columns[self.value_layout[name]])) for name in _RATE_GROUPS}
        return dict(found)

    def load_map(self, g):
        """Complex node forces per parameter (nodes x 12N) under gravity g."""
        return self.load_forces + g * self.load_weights

    def value_map(self, g):
        """The linear map from a parameter vector (12N) to packed path values (see
        ``value_layout``; rod loads as interleaved x, y), under gravity g."""
        found = self._value_maps.get(g)
        if found is None:
            rod_loads, base_load = self.load_maps(g)
            eye = np.eye(self.n * len(PARAMETER_NAMES))
            springs = eye[self.spring_index]
            rows = [np.stack([rod_loads.real, rod_loads.imag], axis=1).reshape(-1, len(eye)),
                    springs, eye[self.chord_index], eye[self.rod_index],
                    self.element_base[:, None] * eye[self.rho0_index],
                    np.concatenate([springs, np.zeros((self.n_chords, len(eye)))]),
                    base_load[None, :], eye[[self.rho0_index]]]
            found = self._value_maps[g] = np.concatenate(rows)
        return found

    def load_maps(self, g):
        """Per parameter under gravity g: the loads carried by every rod vector (2N x 12N,
        complex) and the x load carried by A2(0) (12N,)."""
        found = self._load_maps.get(g)
        if found is None:
            nodes = self.load_map(g)
            found = self._load_maps[g] = (self.node_rods.T @ nodes, self.node_base @ nodes.real)
        return found


@functools.lru_cache(maxsize=32)
def _topology(n):
    return _Topology(n)


def _null_basis(jc, trailing_columns):
    """A basis (columns) of the null space of ``jc`` (m x n, full row rank, 0 < m < n):
    the ``trailing_columns`` (the last n - m of the n x n identity: the topology's) of the
    Q of a QR of jc^T, Q applied to them by LAPACK directly (no per-call checks, Q itself
    never formed)."""
    qr, tau, _, _ = _dgeqrf(jc.T)
    z, _, _ = _dormqr('L', 'N', qr, tau, trailing_columns, jc.shape[1])
    return z


class _Values:
    """The path's parameters at one s, or their rates along s (all linear in the
    parameter vector, so the values at s are those at 0 plus s times the rates).

    All are views of one packed array ``data`` = (the topology's value map) @ p, so
    that the values at s, or the rates, are one array operation."""

    __slots__ = ('_scales', 'data', 'k', 'chord', 'chord_squares', 'rod', 'rod_loads',
                 'base_load', 'rho0', 'shift', 'weights')

    @classmethod
    def _of_data(cls, top, data, rates=False):
        self = cls()
        self.data = data
        rod_loads, self.k, self.chord, self.rod, self.shift, self.weights = top.value_views(data)
        self.rod_loads = rod_loads.view(complex)                   # d(load work)/d(rod vector)
        self.base_load, self.rho0 = data[-2:].tolist()             # x force carried by A2(0)
        self.chord_squares = None if rates else self.chord ** 2
        return self

    @classmethod
    def of(cls, top, g, p):
        """The values of parameter vector ``p`` (N x 12, flattened)."""
        return cls._of_data(top, np.dot(top.value_map(g), p))

    @classmethod
    def of_stack(cls, stack, top):
        """The values of ``stack``, kept on it (a node's end stack is the next start)."""
        found = stack.__dict__.get('_path_values')     # frozen dataclass: not a field
        if found is None:
            found = stack.__dict__['_path_values'] = cls.of(top, stack.modules[0].g,
                                                            stack._vector)
        return found

    def scales(self, top):
        """(l_ref, f_ref, state_weights) of a path starting at these values (computed
        once per start: they depend on its rods and springs only).

        l_ref is the mean rod length; multipliers are stored in units of f_ref = max k
        l_ref, so that the state is dimensionless.  Step sizes are node displacements
        (in l_ref), as in node coordinates: a node is moved by at most the summed
        lengths of the rods that build it times max |d phi|."""
        try:
            return self._scales
        except AttributeError:
            # (Python's sum and max on a few floats: cheaper than ndarray.sum and .max)
            l_ref = sum(self.rod.tolist()) / top.n_rods
            weights = top.angle_mask * (max((top.node_rods @ self.rod).tolist()) / l_ref)
            self._scales = (l_ref, max(self.k.tolist()) * l_ref, weights)
            return self._scales

    @staticmethod
    def share_scales(one, zero):
        """Give ``one`` the scales of ``zero`` (same rods and springs: see :meth:`scales`)."""
        try:
            one._scales = zero._scales
        except AttributeError:
            pass

    @classmethod
    def difference(cls, top, one, zero):
        """one - zero: the rates along s of a straight path (no chord_squares)."""
        return cls._of_data(top, one.data - zero.data, rates=True)

    @classmethod
    def along(cls, top, zero, rate, s):
        """zero + s * rate."""
        return cls._of_data(top, zero.data + s * rate.data)


class _Point:
    """Everything the path needs at one (state, s), computed once: rod vectors ``rods``
    (2N complex), element differences ``diff`` (elements, complex), the element
    weights (stiffnesses, then chord multipliers / l_ref), the generalized force
    ``force`` = dL/d(rod vector) (2N complex, x + iy) and its moment about each rod's
    base ``moment`` = conj(rod) force (imaginary part: dL/dphi; real part: the
    Hessian's diagonal term).  What only some callers need is made on first use."""

    __slots__ = ('key', 'values', 'rods', 'diff', 'force', 'moment', 'weights', '_y', '_n',
                 '_f_ref', '_squares', '_pair', '_jc', '_gram', '_constraints', '_mu', 'rates')

    def __init__(self, path, y, key, values):
        top = path.topology
        self.key, self.values, self._y = key, values, y
        n = self._n = top.n_rods
        rods = self.rods = values.rod * np.exp(1j * y[:n])
        # (np.dot, not @, on these small operands: the same product, half the call overhead)
        diff = self.diff = np.dot(top.element_rods_c, rods)
        diff += values.shift
        self._f_ref = path.f_ref
        # [stiffnesses, chord multipliers * f_ref / l_ref]: the multipliers enter through a
        # fixed map of the whole state (one product, no slicing and joining)
        weights = self.weights = (values.weights if path.weight_map is None
                                  else values.weights + np.dot(path.weight_map, y))
        force = self.force = np.dot(top.element_rods_tc, weights * diff)
        force -= values.rod_loads
        self.moment = rods.conj() * force
        self._squares = self._pair = self._jc = self._gram = self._constraints = None
        self._mu = self.rates = None

    def gradient(self):
        """dL/dphi (2N,): the torque of the generalized force about every rod's base."""
        return self.moment.imag

    @property
    def mu(self):
        """The chord multipliers (N - 1,), N: the chords' compression forces (kept: the
        energy, its rate and the actuator forces all read them)."""
        if self._mu is None:
            self._mu = self._y[self._n:] * self._f_ref
        return self._mu

    @property
    def squares(self):
        """|element difference|^2 (elements,)."""
        if self._squares is None:
            diff = self.diff
            self._squares = (diff.conj() * diff).real
        return self._squares

    @property
    def gram(self):
        """v_r . v_q (2N x 2N), also the dot products of the rods' angular velocities."""
        if self._gram is None:
            rods = self.rods
            self._gram = (rods[:, None] * rods.conj()).real
        return self._gram

    def hessian(self, path):
        """d2L/dphi2 (2N x 2N): (E^T W E)_rq v_r . v_q, less the moments on the diagonal
        (alone, where the metric is not made: Newton's Jacobian at a prediction)."""
        if self._pair is not None:
            return self._pair[0]
        n = path.topology.n_rods
        hessian = self.weights.dot(path.topology.element_outer).reshape(n, n)
        hessian *= self.gram
        hessian.reshape(n * n)[::n + 1] -= self.moment.real
        return hessian

    def metric(self, path):
        """J^T J of the map from rod angles to moving node coordinates: the Cartesian metric."""
        pair = self._pair
        return path.topology.mobility * self.gram if pair is None else pair[1]

    def pair(self, path):
        """(Hessian, metric), kept: each is a constant table times the rods' Gram matrix.
        (Two plain 2-D arrays, not one stacked 3-D array: products of the stacked array
        cost several times more in a stream of commands, ~10 us of a ~110 us step.)"""
        if self._pair is None:
            self._pair = self.hessian(path), path.topology.mobility * self.gram
        return self._pair

    def chords(self, path):
        return self.diff[path.topology.n_springs:]

    def constraints(self, path):
        """The chord constraints (N - 1,), m (kept: the residual and the energy use them)."""
        if self._constraints is None:
            self._constraints = ((self.squares[path.topology.n_springs:]
                                  - self.values.chord_squares) * path.half_inv_l_ref)
        return self._constraints

    def constraint_jacobian(self, path):
        """d c / d phi ((N - 1) x 2N): chord . (i v_r) / l_ref where rod r builds the chord."""
        if self._jc is None:
            chords = self.chords(path)
            self._jc = (chords.conj()[:, None] * self.rods).imag * path.chord_rods_scaled
        return self._jc

    def products(self, path):
        """Make the Gram matrix and the constraint Jacobian (if neither is made) from one
        outer product conj(u) u^T of u = (rods, chords): its rod block's real part is the
        Gram matrix, its chord-rod block's imaginary part chord . (i v_r) (the same
        products as :attr:`gram` and :meth:`constraint_jacobian` make alone: the same
        numbers, in one product where the reduced eigenproblem needs both)."""
        if self._gram is None and self._jc is None:
            n = self._n
            u = _concatenate((self.rods, self.diff[path.topology.n_springs:]))
            products = u.conj()[:, None] * u
            # (a contiguous copy: the Hessian's and the metric's products with it are
            # twice as fast as with the strided real view, ~1 us of the two)
            self._gram = products[:n, :n].real.copy()
            self._jc = products[n:, :n].imag * path.chord_rods_scaled


class StackPath:
    """A stack along p(s) = start + s (end - start), as a tracker PathProblem.

    State y = [absolute angles of the 2N rods (rad, from the base x axis),
    multipliers of the N - 1 chord lengths in units of f_ref = max k * l_ref].  Node positions are sums of rod
    vectors, so rods are rigid by construction; each chord is a constraint, scaled
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
        self._point = None

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
        """The evaluated :class:`_Point` at (y, s), reused while (y, s) stays the same."""
        y = np.asarray(y, dtype=float)
        key = (s, y.tobytes())
        p = self._point
        if p is None or p.key != key:
            p = self._point = _Point(self, y, key, self.at(s))
        return p

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

    def _unconstrained_gradient(self, p):
        """dU/dphi without the chord forces (2N,)."""
        top = self.topology
        ns = top.n_springs
        springs = top.element_rods_t[:, :ns] @ (p.weights[:ns] * p.diff[:ns])
        return (p.rods.conj() * (springs - p.values.rod_loads)).imag

    def descent(self, y, s):
        """Overdamped velocity in the Cartesian metric of the nodes: the projected force
        plus a pull back onto the chord constraints."""
        p = self.point(y, s)
        free = np.linalg.solve(p.metric(self), self._unconstrained_gradient(p))
        if not self.topology.n_chords:
            return -free
        jc, mobility_jc, gram, rate = self._damped_constraints(p)
        correction = np.linalg.solve(gram, jc @ free - rate * p.constraints(self))
        return np.concatenate([-free + mobility_jc @ correction, np.zeros_like(p.mu)])

    def _damped_constraints(self, p):
        """(constraint Jacobian, metric^-1 jc^T, their Gram matrix damped, pull rate)
        for the overdamped flows.  Damped (Levenberg): smooth through kinematic
        singularities of the stack, where rods fold flat onto a chord and the constraint
        rows degenerate."""
        jc, mobility_jc, gram, smallest = self._chord_gram(p)
        if smallest < _DAMPING_ONSET:
            gram = gram + _DAMPING * (1.0 - smallest / _DAMPING_ONSET) ** 2 * np.eye(len(jc))
        return jc, mobility_jc, gram, float(np.max(p.values.k)) * 2.0

    def _chord_gram(self, p):
        """(constraint Jacobian, metric^-1 jc^T, their Gram matrix, its smallest
        eigenvalue): whether the flows damp turns on the last."""
        jc = p.constraint_jacobian(self)
        mobility_jc = np.linalg.solve(p.metric(self), jc.T)
        gram = jc @ mobility_jc
        return jc, mobility_jc, gram, np.linalg.eigvalsh(gram)[0]

    def damped(self, y, s):
        """Whether :meth:`descent` damps its projection at ``y`` (a module so near flat
        that the Gram matrix of the chord gradients has an eigenvalue below
        ``_DAMPING_ONSET``): there it flows as a neck of slightly elastic chords, not as
        the rigid-chord model, and may pass a module through flat where the rigid
        mechanism does not (see :meth:`rigid_descent`)."""
        if not self.topology.n_chords:
            return False
        return bool(self._chord_gram(self.point(y, s))[3] < _DAMPING_ONSET)

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
        if not self.topology.n_chords:
            return -np.linalg.solve(metric, gradient)
        jc, mobility_jc, gram, rate = self._damped_constraints(p)
        z = _null_basis(jc, self.topology.trailing_columns)
        tangential = z @ np.linalg.solve(z.T @ metric @ z, z.T @ gradient)
        pull = mobility_jc @ np.linalg.solve(gram, rate * p.constraints(self))
        return np.concatenate([-tangential - pull, np.zeros_like(p.mu)])

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

    def linkage_limit(self, y, s):
        """A description of the linkage limit the state sits at, or '' if none.

        At a linkage limit a chord constraint's gradient (nearly) vanishes: module i's
        rods lie flat along its top chord (rho(i) + rho(i+1) = L1 + L2 for a crossed
        module).  Two branches of configurations cross there, so the equilibrium
        equations are singular although the state may be a strict minimum, and the
        chord's force grows without bound where the load pushes along the fold (see
        ``_Tracker.through_linkage_limit``).  So a module nearly flat where the equations
        are singular to rounding at a minimum is at its limit too (:meth:`_unresolved`)."""
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
        between states ``a`` and ``b`` (see :func:`.flat_crossing.turned_through_base`)."""
        return _flat_crossing.turned_through_base(self, a, b, s)

    def crossing_ways(self, y, s):
        """The ways out of a module's flat crossing next to ``y`` (see
        :func:`.flat_crossing.ways_out`), or None if there is none."""
        return _flat_crossing.ways_out(self, y, s)

    def crossing_rounding(self, y, s):
        """(distance, radius, exact) of ``y`` from a module's flat crossing next to it,
        the chords' rounding radius there (both in rad) and whether the crossing is
        exact to rounding (see :func:`.flat_crossing.rounding`), or None if there is
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

    # -- reporting ---------------------------------------------------------------
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


@dataclass(frozen=True)
class StackEquilibrium:
    """A verified equilibrium of a stack.

    ``theta`` (N x 2) local angles, ``nodes`` (2 + 2N, 2) every node in the base frame
    (A1(0), A2(0), then A3(i), A4(i) for each module), ``eigenvalues`` of the reduced
    Hessian (N/m, ascending), ``actuator_forces`` (N,), ``state`` the tracker state,
    ``head_position`` (2,) and ``head_angle`` the midpoint and direction of the top chord.
    The angles, forces, nodes and head are made on first use, from ``evaluation``: a
    node tracks a state per command (1 kHz) but reads them only at publish_rate.
    ``certificate`` is the tracker's (:attr:`.continuation.Track.certificate`): non-empty
    where the state is so close past a passed branch point that its positive
    definiteness was shown by the branch point's normal form, not by the margin test
    (``stable`` accepts either).
    """

    eigenvalues: np.ndarray
    energy: float
    residual: float
    state: np.ndarray
    #: The stack parameter vector (bytes) this state was verified at, so that tracking
    #: from it can reuse ``eigenvalues``.
    parameters: bytes = field(default=None, repr=False, compare=False)
    #: (path, point): the path's evaluation at ``state``, that the lazy values come from.
    evaluation: tuple = field(default=None, repr=False, compare=False)
    certificate: str = ''

    @functools.cached_property
    def theta(self):
        path, point = self.evaluation
        return path.angles_at(point)

    @functools.cached_property
    def actuator_forces(self):
        path, point = self.evaluation
        return path.actuator_forces_at(point)

    @functools.cached_property
    def nodes(self):
        path, point = self.evaluation
        return path.nodes_at(point)

    @property
    def head_position(self):
        (x3, y3), (x4, y4) = self.nodes[-2:].tolist()   # the top chord: A3(N-1), A4(N-1)
        return np.array([0.5 * (x3 + x4), 0.5 * (y3 + y4)])

    @property
    def head_angle(self):
        (x3, y3), (x4, y4) = self.nodes[-2:].tolist()
        return math.atan2(y3 - y4, x3 - x4)

    @property
    def stable(self):
        ev = self.eigenvalues
        return verified_minimum(ev, self.certificate)

    @property
    def stability_margin(self):
        return float(self.eigenvalues[0])


def _record(path, y, s, eigenvalues=None, energy=None, residual=None, certificate=''):
    y = path.whole_turns_removed(y)
    p = path.point(y, s)
    return StackEquilibrium(
        eigenvalues=path.eigenvalues_at(p) if eigenvalues is None else eigenvalues,
        energy=path.energy_at(p) if energy is None else energy,
        residual=float(np.max(np.abs(path.residual_at(p)))) if residual is None else residual,
        state=np.array(y), parameters=path.parameter_bytes(s), evaluation=(path, p),
        certificate=certificate)


def _end_record(path, y, eigenvalues, energy, residual, point):
    """The record of the small-command step's verified end: ``point`` is its evaluation
    at ``y``, s = 1, and ``y`` the step's own array (held by the point alone, so the
    record takes it without a copy).

    Made by filling the instance dict: the frozen dataclass's __init__ sets each of its
    seven fields through object.__setattr__ (2.7 us, against 0.7 here, on a ~95 us
    command); the same instance, as StackEquilibrium has no __post_init__ (a field added
    to it must be added here too)."""
    record = object.__new__(StackEquilibrium)
    record.__dict__.update(eigenvalues=eigenvalues, energy=energy, residual=residual,
                           state=y, parameters=path.end._bytes, evaluation=(path, point),
                           certificate='')
    return record


def stack_equilibrium_at(stack: Stack, state) -> StackEquilibrium:
    """The record of a tracker state of ``stack``."""
    return _record(StackPath(stack, stack), np.asarray(state, dtype=float), 0.0)


@dataclass(frozen=True)
class StackJump:
    """A jump of the stack: ``theta`` of every module before (critical) and after (landing).

    ``to_theta`` is a stable equilibrium of ``stack`` (the parameters at the jump's s),
    except where the landing minimum does not exist there (it appears only past s): then
    ``landing_stack`` (otherwise ``stack``) holds the parameters it is an equilibrium of,
    and ``landed_past`` is true."""

    kind: str
    s: float
    stack: Stack
    from_theta: np.ndarray
    to_theta: np.ndarray
    ambiguous: bool = False
    landing_stack: Stack | None = None

    @property
    def landed_past(self):
        return self.landing_stack is not None and self.landing_stack != self.stack


@dataclass(frozen=True)
class StackPassage:
    """A supercritical branch point the stack passed continuously (it buckled smoothly:
    not a jump).  ``theta`` is the critical state (every module's angles)."""

    s: float
    stack: Stack
    theta: np.ndarray


@dataclass(frozen=True)
class StackTrack:
    """Result of :func:`track_stack` (see :class:`~.tracking.ModuleTrack`); ``passages``
    lists the branch points passed continuously (:class:`StackPassage`)."""

    final: StackEquilibrium
    end: Stack
    jumps: tuple
    status: str = 'ok'
    message: str = ''
    steps: int = 0
    passages: tuple = ()


def _one_step_track(final, end):
    """``StackTrack(final=final, end=end, jumps=(), steps=1)``, made as :func:`_end_record`
    makes its record (filling the instance dict: 0.3 us against 1.0 through the frozen
    dataclass's __init__; StackTrack has no __post_init__, and a field added to it must be
    added here too)."""
    track = object.__new__(StackTrack)
    track.__dict__.update(final=final, end=end, jumps=(), status='ok', message='', steps=1,
                          passages=())
    return track


def _checked_angles(theta, n):
    theta = np.asarray(theta, dtype=float)
    if theta.shape not in ((n, 2), (2 * n,)):
        raise ValueError(f'theta must have shape ({n}, 2), got {theta.shape}')
    if not np.all(np.isfinite(theta)):
        raise ValueError('theta must be finite')
    return theta.reshape(n, 2)


def settle_stack(stack: Stack, theta_guess, settings: TrackerSettings = TrackerSettings()):
    """The stable equilibrium whose basin holds the configuration ``theta_guess`` (N x 2)."""
    path = StackPath(stack, stack)
    y0 = path.state_from_angles(_checked_angles(theta_guess, len(stack)), 0.0)
    return _record(path, _continuation.settle(path, y0, 0.0, settings), 0.0)


def track_stack(start: Stack, end: Stack, state_or_theta,
                settings: TrackerSettings = TrackerSettings()) -> StackTrack:
    """Follow the stable equilibrium of the stack from ``start`` to ``end``.

    ``state_or_theta`` is a :class:`StackEquilibrium`, a tracker state, or local
    angles (N x 2) to settle from.
    """
    path = StackPath(start, end)
    if isinstance(state_or_theta, StackEquilibrium):
        y0 = state_or_theta.state
    else:
        arr = np.asarray(state_or_theta, dtype=float)
        y0 = path.whole_turns_removed(arr) if arr.shape == (path.size,) else \
            path.state_from_angles(_checked_angles(arr, len(start)), 0.0)
    known = (state_or_theta if isinstance(state_or_theta, StackEquilibrium)
             and state_or_theta.parameters == start._bytes else None)
    quick = whole_command_step(path, y0, settings, known)
    if quick is not None:
        y1, eigenvalues, energy, residual, point, factors = quick
        final = _end_record(path, y1, eigenvalues, energy, residual, point)
        keep_final_point(final, path, point, factors)
        return _one_step_track(final, end)
    result = _continuation.track_settled(path, y0, settings,
                                         known.certificate if known else '')
    jumps = tuple(StackJump(kind=e.kind, s=e.s, stack=path.params(e.s),
                            from_theta=path.angles(e.state, e.s),
                            to_theta=path.angles(e.landing, e.landing_s), ambiguous=e.ambiguous,
                            landing_stack=path.params(e.landing_s))
                  for e in result.events)
    passages = tuple(StackPassage(s=s, stack=path.params(s), theta=path.angles(y, s))
                     for s, y in result.passages)
    reached = end if result.s == 1.0 else path.params(result.s)
    final = _record(path, result.state, result.s, certificate=result.certificate)
    return StackTrack(final=final, end=reached, jumps=jumps, status=result.status,
                      message=result.message, steps=result.steps, passages=passages)


def _angle_distance(path, a, b):
    """Largest difference of the rod angles of two states, modulo 2 pi."""
    n = path.topology.n_rods
    d = (np.asarray(a[:n]) - np.asarray(b[:n]) + math.pi) % (2.0 * math.pi) - math.pi
    return float(np.max(np.abs(d)))


def stack_equilibria(stack: Stack, starts=64, seed=0):
    """Equilibria of a stack by multi-start search (for tests and the CLI), sorted by energy.

    Newton on the KKT system from ``starts`` random configurations finds
    equilibria of every type; overdamped settles from ``starts // 4`` more
    sample the basins of the minima, so stable equilibria are not left to the
    luck of Newton.  Not guaranteed complete (there is no polynomial
    elimination for N > 1), but with enough starts it finds every equilibrium
    of a small stack.
    """
    path = StackPath(stack, stack)
    rng = np.random.default_rng(seed)
    scale = float(np.max([max(m.ka, m.kb, m.kc) for m in stack.modules]))
    found = []

    def add(y):
        if (np.all(np.isfinite(y)) and np.max(np.abs(path.residual(y, 0.0))) <= 1e-9 * scale
                and all(_angle_distance(path, y, f) >= 1e-7 for f in found)):
            found.append(y)

    for _ in range(starts):
        y0 = path.state_from_angles(rng.uniform(-math.pi, math.pi, (len(stack), 2)), 0.0)
        with np.errstate(all='ignore'):
            sol = root(lambda y: path.residual(y, 0.0), y0, jac=lambda y: path.jacobian(y, 0.0),
                       method='hybr', options={'xtol': 1e-13})
        add(sol.x)
    for _ in range(max(4, starts // 4)):
        y0 = path.state_from_angles(rng.uniform(-math.pi, math.pi, (len(stack), 2)), 0.0)
        try:
            add(_continuation.settle(path, y0, 0.0))
        except _continuation.TrackingError:
            pass
    records = [_record(path, y, 0.0) for y in found]
    return sorted(records, key=lambda r: r.energy)
