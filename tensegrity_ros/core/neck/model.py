"""The neck stack's model: its parameters, node graph and one evaluation per (state, s).

docs/model.md section 4.

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

from dataclasses import dataclass
import functools
import operator

import numpy as np
from scipy.linalg.lapack import dgeqrf as _dgeqrf, dormqr as _dormqr

from ..module.model import InvalidParameterError, ModuleParams, PARAMETER_NAMES

# numpy's C routines without their __array_function__ dispatch (~0.2 us a call on these
# small operands, as ndarray.dot against np.dot): the same routine, the same numbers.  Used
# where the small-command step calls them (a few dozen calls a command).
_vdot = getattr(np.vdot, '_implementation', np.vdot)
_concatenate = getattr(np.concatenate, '_implementation', np.concatenate)
_P = {name: i for i, name in enumerate(PARAMETER_NAMES)}
_PARAMETERS_OF = operator.attrgetter(*PARAMETER_NAMES)     # a module's parameters, in order
_FIXED = 2          # A1(0) and A2(0) are the first two entries of the node table


def _index(i, name):
    """Module i's parameter ``name`` in a stack's parameter vector (N x 12, flattened)."""
    return i * len(PARAMETER_NAMES) + _P[name]


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

        def a3(i):
            return 2 + 2 * i

        def a4(i):
            return 3 + 2 * i

        def a1(i):
            return 0 if i == 0 else a4(i - 1)

        def a2(i):
            return 1 if i == 0 else a3(i - 1)
        self.a1, self.a2, self.a3, self.a4 = a1, a2, a3, a4
        self.nodes = 2 + 2 * n
        self.n_rods = 2 * n
        self.n_chords = n - 1
        self._node_tables()
        self._element_tables()
        self._load_tables()
        self._load_maps, self._value_maps, self._scaled_tables = {}, {}, {}
        self._groups_moved = {}
        self._value_tables()

    def _node_tables(self):
        """Every node as node_base * P + node_rods @ v (P = A2(0), v the rod vectors)."""
        a1, a2, a3, a4 = self.a1, self.a2, self.a3, self.a4
        rods = np.zeros((self.nodes, self.n_rods))
        base = np.zeros(self.nodes)
        base[1] = 1.0
        for i in range(self.n):
            rods[a3(i)], base[a3(i)] = rods[a1(i)], base[a1(i)]
            rods[a3(i), 2 * i] = 1.0
            rods[a4(i)], base[a4(i)] = rods[a2(i)], base[a2(i)]
            rods[a4(i), 2 * i + 1] = 1.0
        self.node_rods, self.node_base = rods, base

    def _element_tables(self):
        """The springs and chords, their ends, parameter indices and rod maps."""
        n, rods, base = self.n, self.node_rods, self.node_base
        a1, a2, a3, a4 = self.a1, self.a2, self.a3, self.a4
        springs, self.spring_index = [], []
        for i in range(n):
            springs += [(a2(i), a3(i)), (a1(i), a4(i)), (a3(i), a4(i))]
            self.spring_index += [_index(i, 'ka'), _index(i, 'kb'), _index(i, 'kc')]
        chords = [(a3(i), a4(i)) for i in range(n - 1)]
        self.chord_index = [_index(i + 1, 'rho') for i in range(n - 1)]
        self.rod_index = [_index(i, name) for i in range(n) for name in ('L1', 'L2')]
        self.rho0_index = _index(0, 'rho')
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

    def _load_tables(self):
        """Loads: complex node forces = (forces + g * weights) @ parameters."""
        a1, a2, a3, a4 = self.a1, self.a2, self.a3, self.a4
        forces = np.zeros((self.nodes, self.n * len(PARAMETER_NAMES)), dtype=complex)
        weights = np.zeros((self.nodes, self.n * len(PARAMETER_NAMES)))
        for i in range(self.n):
            forces[a3(i), _index(i, 'f3x')] += 1.0
            forces[a3(i), _index(i, 'f3y')] += 1j
            forces[a4(i), _index(i, 'f4x')] += 1.0
            forces[a4(i), _index(i, 'f4y')] += 1j
            for node in (a1(i), a3(i)):
                weights[node, _index(i, 'm1')] -= 0.5
            for node in (a2(i), a4(i)):
                weights[node, _index(i, 'm2')] -= 0.5
        self.load_forces, self.load_weights = forces, 1j * weights

    def _value_tables(self):
        """The layout of the packed path values (see :meth:`value_map`)."""
        sizes = (('rod_loads', 2 * self.n_rods), ('k', self.n_springs),
                 ('chord', self.n_chords), ('rod', self.n_rods),
                 ('shift', len(self.element_ends)), ('weights', len(self.element_ends)),
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
